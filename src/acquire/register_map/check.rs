//! Validation of a register map: every problem is collected (not just the first), each naming
//! its `modbus.request[i].field[j]` key. Pure: no I/O, no decoding.

use super::types::{ModbusConfig, RegisterKind, RequestSpec};
use super::{FieldSpec, MAX_REGISTERS_PER_REQUEST, REQUIRED_SIGNALS};
use crate::config_problem::ConfigProblem;
use crate::signals::Signal;
use std::collections::BTreeMap;

impl ModbusConfig {
    /// Checks the map and returns every problem found (empty = valid). Key paths start with
    /// `modbus.`; request and field indices count from 0 in file order.
    pub fn check(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        check_endpoint(&self.endpoint, &mut p);
        if self.requests.is_empty() {
            p.push(ConfigProblem::new(
                "modbus.request",
                "no [[modbus.request]] blocks: nothing would be read",
            ));
        }
        // Registers claimed so far per (slave, kind): address -> (key of the field, name).
        let mut claimed: BTreeMap<(u8, RegisterKind), BTreeMap<u32, (String, String)>> =
            BTreeMap::new();
        let mut names: BTreeMap<&str, String> = BTreeMap::new();
        let mut signals: BTreeMap<Signal, String> = BTreeMap::new();
        for (ri, req) in self.requests.iter().enumerate() {
            let rkey = format!("modbus.request[{ri}]");
            check_request(req, &rkey, &mut p);
            for (fi, field) in req.fields.iter().enumerate() {
                let fkey = format!("{rkey}.field[{fi}]");
                check_field(req, field, &fkey, &mut p);
                if let Some(prev) = names.insert(field.name.as_str(), fkey.clone()) {
                    p.push(ConfigProblem::new(
                        format!("{fkey}.name"),
                        format!("tag name '{}' is already used by {prev}", field.name),
                    ));
                }
                if let Some(sig) = field.signal {
                    if let Some(prev) = signals.insert(sig, fkey.clone()) {
                        p.push(ConfigProblem::new(
                            format!("{fkey}.signal"),
                            format!("signal {} is already fed by {prev}", sig.short()),
                        ));
                    }
                }
                let table = claimed.entry((req.slave_id, req.register)).or_default();
                let mut overlap: Option<(String, String)> = None;
                for a in field.address..=field.last_address() {
                    if let Some(prev) = table.get(&a) {
                        overlap.get_or_insert_with(|| prev.clone());
                    } else {
                        table.insert(a, (fkey.clone(), field.name.clone()));
                    }
                }
                if let Some((okey, oname)) = overlap {
                    p.push(ConfigProblem::new(
                        format!("{fkey}.address"),
                        format!(
                            "registers {}–{} ({} {}, slave {}) overlap field '{oname}' ({okey})",
                            field.address,
                            field.last_address(),
                            field.data_type,
                            req.register,
                            req.slave_id
                        ),
                    ));
                }
            }
        }
        let missing: Vec<&str> = REQUIRED_SIGNALS
            .iter()
            .filter(|s| !signals.contains_key(s))
            .map(|s| s.short())
            .collect();
        if !missing.is_empty() {
            p.push(ConfigProblem::new(
                "modbus.request",
                format!(
                    "missing required tags for diagnosis: {} (add a field with signal = \"…\" for each)",
                    missing.join(", ")
                ),
            ));
        }
        p
    }
}

fn check_endpoint(endpoint: &str, p: &mut Vec<ConfigProblem>) {
    let ok = endpoint
        .rsplit_once(':')
        .is_some_and(|(host, port)| !host.is_empty() && port.parse::<u16>().is_ok_and(|p| p > 0));
    if !ok {
        p.push(ConfigProblem::new(
            "modbus.endpoint",
            format!("'{endpoint}' is not host:port (e.g. \"192.168.10.20:502\")"),
        ));
    }
}

/// If `addr` looks like 1-based Modicon notation (3xxxx / 4xxxx or 3xxxxx / 4xxxxx), a hint.
pub(super) fn modicon_hint(addr: u32, kind: RegisterKind) -> Option<String> {
    let (table, base) = match addr {
        30001..=39999 => (RegisterKind::Input, 30001),
        40001..=49999 => (RegisterKind::Holding, 40001),
        300001..=365536 => (RegisterKind::Input, 300001),
        400001..=465536 => (RegisterKind::Holding, 400001),
        _ => return None,
    };
    let zero_based = addr - base;
    let mut msg = format!(
        "{addr} looks like the 1-based Modicon notation for {table} register {} \
         ({}xxxx); addresses here are 0-based, so write {zero_based}",
        zero_based + 1,
        base / 10000 / if base > 100000 { 10 } else { 1 },
    );
    if table != kind {
        msg.push_str(&format!(
            " and check register = \"{table}\" (this request reads {kind} registers)"
        ));
    }
    Some(msg)
}

fn check_request(req: &RequestSpec, rkey: &str, p: &mut Vec<ConfigProblem>) {
    if req.slave_id == 0 {
        p.push(ConfigProblem::new(
            format!("{rkey}.slave_id"),
            "slave id 0 is the broadcast address and cannot be read; use 1–255 (255 or 1 for most TCP devices)",
        ));
    }
    if let Some(h) = modicon_hint(req.start_address, req.register) {
        p.push(ConfigProblem::new(format!("{rkey}.start_address"), h));
    } else if req.start_address > 65535 {
        p.push(ConfigProblem::new(
            format!("{rkey}.start_address"),
            format!(
                "{} is beyond the last register address 65535",
                req.start_address
            ),
        ));
    }
    if req.fields.is_empty() {
        p.push(ConfigProblem::new(
            format!("{rkey}.field"),
            "request has no fields: it would read registers and store nothing",
        ));
    }
    let count = req.register_count();
    if req.count == Some(0) {
        p.push(ConfigProblem::new(
            format!("{rkey}.count"),
            "count must be at least 1",
        ));
    } else if count > MAX_REGISTERS_PER_REQUEST {
        p.push(ConfigProblem::new(
            format!("{rkey}.count"),
            format!(
                "request spans {count} registers ({}–{}); one Modbus read may ask for at most \
                 {MAX_REGISTERS_PER_REQUEST}: split it into several requests",
                req.start_address,
                req.start_address + count - 1
            ),
        ));
    } else if req.start_address <= 65535 && req.start_address + count > 65536 {
        p.push(ConfigProblem::new(
            format!("{rkey}.count"),
            format!(
                "request {}–{} runs past register 65535",
                req.start_address,
                req.start_address + count - 1
            ),
        ));
    }
}

fn check_field(req: &RequestSpec, f: &FieldSpec, fkey: &str, p: &mut Vec<ConfigProblem>) {
    if f.name.trim().is_empty() {
        p.push(ConfigProblem::new(format!("{fkey}.name"), "empty tag name"));
    }
    let mut address_ok = true;
    if let Some(h) = modicon_hint(f.address, req.register) {
        p.push(ConfigProblem::new(format!("{fkey}.address"), h));
        address_ok = false;
    } else if f.address < req.start_address {
        p.push(ConfigProblem::new(
            format!("{fkey}.address"),
            format!(
                "address {} is before the request's start_address {}",
                f.address, req.start_address
            ),
        ));
        address_ok = false;
    }
    if address_ok {
        if let Some(count) = req.count {
            let end = req.start_address + count; // exclusive
            if f.last_address() >= end && f.address < end {
                p.push(ConfigProblem::new(
                    format!("{fkey}.type"),
                    format!(
                        "{} needs {} registers ({}–{}) but the request reads only {}–{} \
                         (count = {count}): the type is wider than the registers left",
                        f.data_type,
                        f.data_type.words(),
                        f.address,
                        f.last_address(),
                        req.start_address,
                        end.saturating_sub(1)
                    ),
                ));
            } else if f.address >= end {
                p.push(ConfigProblem::new(
                    format!("{fkey}.address"),
                    format!(
                        "address {} is outside the request's registers {}–{} (count = {count})",
                        f.address,
                        req.start_address,
                        end.saturating_sub(1)
                    ),
                ));
            }
        }
    }
    if !f.scale.is_finite() || f.scale == 0.0 {
        p.push(ConfigProblem::new(
            format!("{fkey}.scale"),
            format!("scale must be finite and non-zero (got {})", f.scale),
        ));
    }
    if !f.offset.is_finite() {
        p.push(ConfigProblem::new(
            format!("{fkey}.offset"),
            format!("offset must be finite (got {})", f.offset),
        ));
    }
    for (k, v) in [("min", f.min), ("max", f.max)] {
        if v.is_some_and(|v| !v.is_finite()) {
            p.push(ConfigProblem::new(
                format!("{fkey}.{k}"),
                "plausible-range limit must be finite",
            ));
        }
    }
    if let (Some(lo), Some(hi)) = (f.min, f.max) {
        if lo >= hi {
            p.push(ConfigProblem::new(
                format!("{fkey}.max"),
                format!("max ({hi}) must be greater than min ({lo})"),
            ));
        }
    }
    if f.signal == Some(Signal::SurgeMargin) || f.signal == Some(Signal::T3) {
        p.push(ConfigProblem::new(
            format!("{fkey}.signal"),
            format!(
                "{} is a model-only quantity, not a plant measurement",
                f.signal.map(|s| s.short()).unwrap_or_default()
            ),
        ));
    }
}
