//! The Modbus register map: which registers hold which tag, and how to turn words into values.
//!
//! Modelled on Telegraf's Modbus input ("request" style) so plant engineers recognise it: each
//! `[[modbus.request]]` reads one block of holding or input registers from one slave, starting
//! at a 0-based address; each `[[modbus.request.field]]` names a tag at an absolute 0-based
//! register address with a data type, byte order, scale and offset
//! (`value = raw × scale + offset`), unit, optional engine signal and optional plausible range.
//!
//! Decoding and encoding are pure functions (the plant simulator uses [`encode_field`], the
//! inverse of [`decode_field`]). Validation collects every problem instead of stopping at the
//! first. This module does no I/O and knows nothing about the network or the database.
//!
//! Byte orders (the four-letter names describe the bytes of a 32-bit value A B C D, most
//! significant first, as they appear on the wire, first register first):
//! - `ABCD`: big-endian words in big-endian order (Modbus convention). 0x12345678 → [0x1234, 0x5678]
//! - `CDAB`: word-swapped. 0x12345678 → [0x5678, 0x1234]
//! - `BADC`: byte-swapped inside each word. 0x12345678 → [0x3412, 0x7856]
//! - `DCBA`: fully little-endian. 0x12345678 → [0x7856, 0x3412]
//!
//! For 64-bit values the same rule extends to four words (`ABCD` = ABCDEFGH, `CDAB` = GHEFCDAB,
//! `BADC` = BADCFEHG, `DCBA` = HGFEDCBA); for 16-bit values `ABCD`/`CDAB` read the word as is
//! and `BADC`/`DCBA` swap its two bytes.

use crate::config_problem::ConfigProblem;
use crate::signals::Signal;
use serde::{Deserialize, Deserializer, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// Most registers one read request (function 3 or 4) may ask for (Modbus application protocol).
pub const MAX_REGISTERS_PER_REQUEST: u32 = 125;

/// Engine signals the diagnosis cannot do without (REFERENCE §3: n1, T2, P2, T34, P34 + fuel).
pub const REQUIRED_SIGNALS: [Signal; 6] = [
    Signal::N1,
    Signal::T2,
    Signal::P2,
    Signal::T34,
    Signal::P34,
    Signal::FuelFlow,
];

/// Name of the extra field through which the plant simulator publishes its true phase code.
pub const PHASE_TRUTH_FIELD: &str = "phase_truth";

/// Name of the extra field through which the plant simulator publishes its own clock (Unix epoch
/// milliseconds of the frame; use type `f64`, which holds every such millisecond exactly). A
/// daemon with `acquisition.timestamp_field` naming it stamps samples in plant time, which a
/// simulated plant running faster than real time needs (see `acquire::modbus::poll_loop`).
pub const PLANT_TIME_FIELD: &str = "plant_time_ms";

/// Which Modbus table a request reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegisterKind {
    /// Holding registers, function code 3 (the 4xxxx table in 1-based notation).
    Holding,
    /// Input registers, function code 4 (the 3xxxx table in 1-based notation).
    Input,
}

impl RegisterKind {
    /// First address of this table in the 1-based Modicon notation (40001 / 30001).
    pub fn modicon_base(self) -> u32 {
        match self {
            RegisterKind::Holding => 40001,
            RegisterKind::Input => 30001,
        }
    }
}

impl fmt::Display for RegisterKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            RegisterKind::Holding => "holding",
            RegisterKind::Input => "input",
        })
    }
}

/// Data type of a field; decides how many registers it occupies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DataType {
    U16,
    I16,
    U32,
    I32,
    F32,
    F64,
}

impl DataType {
    /// Number of 16-bit registers the type occupies.
    pub fn words(self) -> u32 {
        match self {
            DataType::U16 | DataType::I16 => 1,
            DataType::U32 | DataType::I32 | DataType::F32 => 2,
            DataType::F64 => 4,
        }
    }
}

impl fmt::Display for DataType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DataType::U16 => "u16",
            DataType::I16 => "i16",
            DataType::U32 => "u32",
            DataType::I32 => "i32",
            DataType::F32 => "f32",
            DataType::F64 => "f64",
        })
    }
}

/// Byte order of a multi-byte value across registers (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ByteOrder {
    #[default]
    ABCD,
    CDAB,
    BADC,
    DCBA,
}

impl ByteOrder {
    fn words_reversed(self) -> bool {
        matches!(self, ByteOrder::CDAB | ByteOrder::DCBA)
    }
    fn bytes_swapped(self) -> bool {
        matches!(self, ByteOrder::BADC | ByteOrder::DCBA)
    }
}

/// The `[modbus]` section: where the PLC is and what to read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModbusConfig {
    /// PLC or gateway as `host:port` (Modbus TCP default port 502).
    pub endpoint: String,
    /// The read requests, executed in this order every poll.
    #[serde(rename = "request", default)]
    pub requests: Vec<RequestSpec>,
}

/// One read request: a contiguous block of registers of one kind from one slave.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RequestSpec {
    /// Modbus unit / slave id, 1–255 (0 is broadcast and cannot be read).
    pub slave_id: u8,
    /// `holding` (function 3) or `input` (function 4).
    pub register: RegisterKind,
    /// First register of the block, 0-based (Modicon 40001 is holding address 0).
    pub start_address: u32,
    /// Number of registers to read; default: up to the end of the last field.
    #[serde(default)]
    pub count: Option<u32>,
    /// The tags decoded from this block.
    #[serde(rename = "field", default)]
    pub fields: Vec<FieldSpec>,
}

/// One tag inside a request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldSpec {
    /// Tag name as stored in the database (unique across the map).
    pub name: String,
    /// Absolute 0-based register address of the field's first register.
    pub address: u32,
    /// Data type: u16, i16, u32, i32, f32, f64.
    #[serde(rename = "type")]
    pub data_type: DataType,
    /// ABCD (default), CDAB, BADC or DCBA.
    #[serde(default)]
    pub byte_order: ByteOrder,
    /// Engineering value = raw × scale + offset.
    #[serde(default = "one")]
    pub scale: f64,
    #[serde(default)]
    pub offset: f64,
    /// Engineering unit of the scaled value (informational; stored with the tag).
    #[serde(default)]
    pub unit: String,
    /// Engine signal this tag feeds (n1, n2, T1, P1, T2, P2, T34, P34, T4, P4, fuel_flow, power);
    /// absent for free extra tags.
    #[serde(default, deserialize_with = "de_signal")]
    pub signal: Option<Signal>,
    /// Plausible range of the scaled value; outside it the sample is flagged OutOfRange.
    #[serde(default)]
    pub min: Option<f64>,
    #[serde(default)]
    pub max: Option<f64>,
}

fn one() -> f64 {
    1.0
}

fn de_signal<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Signal>, D::Error> {
    let s: Option<String> = Option::deserialize(d)?;
    s.map(|s| s.parse::<Signal>().map_err(serde::de::Error::custom))
        .transpose()
}

impl FieldSpec {
    /// Last register the field occupies (inclusive).
    pub fn last_address(&self) -> u32 {
        self.address + self.data_type.words() - 1
    }
}

impl RequestSpec {
    /// Number of registers the request reads: `count` if given, else up to the last field's end.
    pub fn register_count(&self) -> u32 {
        self.count.unwrap_or_else(|| {
            self.fields
                .iter()
                .map(|f| (f.last_address() + 1).saturating_sub(self.start_address))
                .max()
                .unwrap_or(0)
        })
    }
}

impl ModbusConfig {
    /// All fields in poll order, with the index of their request.
    pub fn fields(&self) -> impl Iterator<Item = (usize, &FieldSpec)> {
        self.requests
            .iter()
            .enumerate()
            .flat_map(|(i, r)| r.fields.iter().map(move |f| (i, f)))
    }

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
fn modicon_hint(addr: u32, kind: RegisterKind) -> Option<String> {
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

/// Quality of one decoded value, before it becomes a stored sample quality.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadingStatus {
    /// Finite and inside the plausible range.
    Good,
    /// Finite but outside the configured plausible range.
    OutOfRange,
    /// NaN or infinite (a float register holding garbage); never usable.
    NotFinite,
}

/// A decoded, scaled field value and its status.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    pub value: f64,
    pub status: ReadingStatus,
}

/// Reorders the field's registers into the value's big-endian bytes (first `2 × words` valid).
fn canonical_bytes(words: &[u16], order: ByteOrder) -> [u8; 8] {
    let mut out = [0u8; 8];
    let n = words.len().min(4);
    for i in 0..n {
        let w = if order.words_reversed() {
            words[n - 1 - i]
        } else {
            words[i]
        };
        let [hi, lo] = w.to_be_bytes();
        let (a, b) = if order.bytes_swapped() {
            (lo, hi)
        } else {
            (hi, lo)
        };
        out[2 * i] = a;
        out[2 * i + 1] = b;
    }
    out
}

/// Inverse of [`canonical_bytes`]: big-endian value bytes to registers in wire order.
fn words_from_canonical(bytes: &[u8], order: ByteOrder) -> Vec<u16> {
    let n = bytes.len() / 2;
    let mut words = vec![0u16; n];
    for i in 0..n {
        let (a, b) = (bytes[2 * i], bytes[2 * i + 1]);
        let w = if order.bytes_swapped() {
            u16::from_be_bytes([b, a])
        } else {
            u16::from_be_bytes([a, b])
        };
        let slot = if order.words_reversed() { n - 1 - i } else { i };
        words[slot] = w;
    }
    words
}

/// Error decoding registers: fewer words than the type needs.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{data_type} needs {needed} registers, got {got}")]
pub struct ShortRead {
    pub data_type: DataType,
    pub needed: usize,
    pub got: usize,
}

/// Decodes the raw (unscaled) value of `ty` from its registers in wire order.
pub fn decode_raw(words: &[u16], ty: DataType, order: ByteOrder) -> Result<f64, ShortRead> {
    let needed = ty.words() as usize;
    if words.len() < needed {
        return Err(ShortRead {
            data_type: ty,
            needed,
            got: words.len(),
        });
    }
    let b = canonical_bytes(&words[..needed], order);
    Ok(match ty {
        DataType::U16 => f64::from(u16::from_be_bytes([b[0], b[1]])),
        DataType::I16 => f64::from(i16::from_be_bytes([b[0], b[1]])),
        DataType::U32 => f64::from(u32::from_be_bytes([b[0], b[1], b[2], b[3]])),
        DataType::I32 => f64::from(i32::from_be_bytes([b[0], b[1], b[2], b[3]])),
        DataType::F32 => f64::from(f32::from_be_bytes([b[0], b[1], b[2], b[3]])),
        DataType::F64 => f64::from_be_bytes(b),
    })
}

/// Encodes a raw (unscaled) value into registers in wire order. Integers are rounded and
/// saturated to the type's range (NaN becomes 0).
pub fn encode_raw(raw: f64, ty: DataType, order: ByteOrder) -> Vec<u16> {
    let bytes: Vec<u8> = match ty {
        DataType::U16 => (raw.round() as u16).to_be_bytes().to_vec(),
        DataType::I16 => (raw.round() as i16).to_be_bytes().to_vec(),
        DataType::U32 => (raw.round() as u32).to_be_bytes().to_vec(),
        DataType::I32 => (raw.round() as i32).to_be_bytes().to_vec(),
        DataType::F32 => (raw as f32).to_be_bytes().to_vec(),
        DataType::F64 => raw.to_be_bytes().to_vec(),
    };
    words_from_canonical(&bytes, order)
}

/// Scales a raw value and classifies it against the field's plausible range.
pub fn scale_and_classify(field: &FieldSpec, raw: f64) -> Reading {
    let value = raw * field.scale + field.offset;
    let status = if !value.is_finite() {
        ReadingStatus::NotFinite
    } else if field.min.is_some_and(|lo| value < lo) || field.max.is_some_and(|hi| value > hi) {
        ReadingStatus::OutOfRange
    } else {
        ReadingStatus::Good
    };
    Reading { value, status }
}

/// Decodes one field from the registers of its request (`block` starts at `start_address`).
pub fn decode_field(
    field: &FieldSpec,
    start_address: u32,
    block: &[u16],
) -> Result<Reading, ShortRead> {
    let from = field.address.saturating_sub(start_address) as usize;
    let words = block.get(from..).unwrap_or(&[]);
    let raw = decode_raw(words, field.data_type, field.byte_order)?;
    Ok(scale_and_classify(field, raw))
}

/// Encodes an engineering value into the field's registers (inverse of [`decode_field`]).
pub fn encode_field(field: &FieldSpec, value: f64) -> Vec<u16> {
    let raw = (value - field.offset) / field.scale;
    encode_raw(raw, field.data_type, field.byte_order)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ORDERS: [ByteOrder; 4] = [
        ByteOrder::ABCD,
        ByteOrder::CDAB,
        ByteOrder::BADC,
        ByteOrder::DCBA,
    ];

    fn field(name: &str, address: u32, ty: DataType) -> FieldSpec {
        FieldSpec {
            name: name.into(),
            address,
            data_type: ty,
            byte_order: ByteOrder::ABCD,
            scale: 1.0,
            offset: 0.0,
            unit: String::new(),
            signal: None,
            min: None,
            max: None,
        }
    }

    /// (type, order, wire words, expected raw value), all hand-computed.
    fn vectors() -> Vec<(DataType, ByteOrder, Vec<u16>, f64)> {
        use ByteOrder::*;
        use DataType::*;
        vec![
            // u16 0x1234 = 4660; the byte-swapping orders read 0x3412.
            (U16, ABCD, vec![0x1234], 4660.0),
            (U16, CDAB, vec![0x1234], 4660.0),
            (U16, BADC, vec![0x3412], 4660.0),
            (U16, DCBA, vec![0x3412], 4660.0),
            // i16 -300 = 0xFED4.
            (I16, ABCD, vec![0xFED4], -300.0),
            (I16, CDAB, vec![0xFED4], -300.0),
            (I16, BADC, vec![0xD4FE], -300.0),
            (I16, DCBA, vec![0xD4FE], -300.0),
            // u32 0x12345678 = 305419896.
            (U32, ABCD, vec![0x1234, 0x5678], 305_419_896.0),
            (U32, CDAB, vec![0x5678, 0x1234], 305_419_896.0),
            (U32, BADC, vec![0x3412, 0x7856], 305_419_896.0),
            (U32, DCBA, vec![0x7856, 0x3412], 305_419_896.0),
            // i32 -2 = 0xFFFFFFFE.
            (I32, ABCD, vec![0xFFFF, 0xFFFE], -2.0),
            (I32, CDAB, vec![0xFFFE, 0xFFFF], -2.0),
            (I32, BADC, vec![0xFFFF, 0xFEFF], -2.0),
            (I32, DCBA, vec![0xFEFF, 0xFFFF], -2.0),
            // i32 -123456789 = 0xF8A432EB.
            (I32, ABCD, vec![0xF8A4, 0x32EB], -123_456_789.0),
            (I32, CDAB, vec![0x32EB, 0xF8A4], -123_456_789.0),
            (I32, BADC, vec![0xA4F8, 0xEB32], -123_456_789.0),
            (I32, DCBA, vec![0xEB32, 0xA4F8], -123_456_789.0),
            // f32 -12.5 = 0xC1480000.
            (F32, ABCD, vec![0xC148, 0x0000], -12.5),
            (F32, CDAB, vec![0x0000, 0xC148], -12.5),
            (F32, BADC, vec![0x48C1, 0x0000], -12.5),
            (F32, DCBA, vec![0x0000, 0x48C1], -12.5),
            // f32 1234.5678 ≈ 0x449A522B (f32 rounding: 1234.5677490234375).
            (F32, ABCD, vec![0x449A, 0x522B], 1_234.567_749_023_437_5),
            (F32, DCBA, vec![0x2B52, 0x9A44], 1_234.567_749_023_437_5),
            // f64 1.5 = 0x3FF8000000000000.
            (F64, ABCD, vec![0x3FF8, 0, 0, 0], 1.5),
            (F64, CDAB, vec![0, 0, 0, 0x3FF8], 1.5),
            (F64, BADC, vec![0xF83F, 0, 0, 0], 1.5),
            (F64, DCBA, vec![0, 0, 0, 0xF83F], 1.5),
            // f64 -2.25 = 0xC002000000000000; and 0x40934A4560000000 = 1234.5677490234375.
            (F64, ABCD, vec![0xC002, 0, 0, 0], -2.25),
            (F64, CDAB, vec![0x0000, 0x0000, 0x0000, 0xC002], -2.25),
            (
                F64,
                ABCD,
                vec![0x4093, 0x4A45, 0x6000, 0x0000],
                1_234.567_749_023_437_5,
            ),
            (
                F64,
                CDAB,
                vec![0x0000, 0x6000, 0x4A45, 0x4093],
                1_234.567_749_023_437_5,
            ),
            (
                F64,
                BADC,
                vec![0x9340, 0x454A, 0x0060, 0x0000],
                1_234.567_749_023_437_5,
            ),
            (
                F64,
                DCBA,
                vec![0x0000, 0x0060, 0x454A, 0x9340],
                1_234.567_749_023_437_5,
            ),
        ]
    }

    #[test]
    fn every_type_and_byte_order_decodes_hand_computed_words() {
        for (ty, order, words, want) in vectors() {
            let got = decode_raw(&words, ty, order).expect("enough words");
            assert_eq!(got, want, "{ty} {order:?} {words:04X?}");
        }
    }

    #[test]
    fn encode_is_the_inverse_of_decode() {
        for (ty, order, words, want) in vectors() {
            assert_eq!(encode_raw(want, ty, order), words, "{ty} {order:?}");
        }
        // Distinct bytes make every permutation visible: 0x0102030405060708 as f64 bits.
        let v = f64::from_bits(0x0102_0304_0506_0708);
        let expect = [
            vec![0x0102, 0x0304, 0x0506, 0x0708],
            vec![0x0708, 0x0506, 0x0304, 0x0102],
            vec![0x0201, 0x0403, 0x0605, 0x0807],
            vec![0x0807, 0x0605, 0x0403, 0x0201],
        ];
        for (order, words) in ORDERS.iter().zip(expect) {
            assert_eq!(encode_raw(v, DataType::F64, *order), words, "{order:?}");
            assert_eq!(
                decode_raw(&words, DataType::F64, *order).map(f64::to_bits),
                Ok(0x0102_0304_0506_0708)
            );
        }
    }

    #[test]
    fn integer_encoding_rounds_and_saturates() {
        assert_eq!(
            encode_raw(70000.0, DataType::U16, ByteOrder::ABCD),
            vec![0xFFFF]
        );
        assert_eq!(encode_raw(-5.0, DataType::U16, ByteOrder::ABCD), vec![0]);
        assert_eq!(
            encode_raw(-40000.0, DataType::I16, ByteOrder::ABCD),
            vec![0x8000]
        );
        assert_eq!(encode_raw(2.6, DataType::I16, ByteOrder::ABCD), vec![3]);
        assert_eq!(
            encode_raw(f64::NAN, DataType::U32, ByteOrder::ABCD),
            vec![0, 0]
        );
    }

    #[test]
    fn short_reads_are_errors() {
        assert_eq!(
            decode_raw(&[1], DataType::F32, ByteOrder::ABCD),
            Err(ShortRead {
                data_type: DataType::F32,
                needed: 2,
                got: 1
            })
        );
        let f = field("x", 11, DataType::F64);
        assert!(decode_field(&f, 10, &[0, 0, 0]).is_err());
        assert!(decode_field(&f, 10, &[0, 0, 0, 0, 0]).is_ok());
    }

    #[test]
    fn scale_offset_and_range() {
        let mut f = field("t2", 10, DataType::U16);
        f.scale = 0.1;
        f.offset = 273.15;
        f.min = Some(250.0);
        f.max = Some(900.0);
        // 0x0FA0 = 4000 → 400.0 + 273.15
        let r = decode_field(&f, 8, &[0, 0, 0x0FA0]).expect("decode");
        assert!((r.value - 673.15).abs() < 1e-9);
        assert_eq!(r.status, ReadingStatus::Good);
        // 0xFFFF = 65535 → 6553.5 + 273.15: a classic "sensor fault" fill value, out of range.
        let r = decode_field(&f, 10, &[0xFFFF]).expect("decode");
        assert_eq!(r.status, ReadingStatus::OutOfRange);
        let r = decode_field(&f, 10, &[0]).expect("decode");
        assert_eq!(r.status, ReadingStatus::Good); // 273.15 ≥ 250
        f.offset = 0.0;
        let r = decode_field(&f, 10, &[0]).expect("decode");
        assert_eq!(r.status, ReadingStatus::OutOfRange); // 0 < 250
                                                         // Encoding goes back through scale and offset.
        f.offset = 273.15;
        assert_eq!(encode_field(&f, 673.15), vec![4000]);
    }

    #[test]
    fn nan_and_infinity_are_not_finite_for_both_float_widths() {
        let f32f = field("x", 0, DataType::F32);
        let f64f = field("y", 0, DataType::F64);
        for order in ORDERS {
            let mut a = f32f.clone();
            a.byte_order = order;
            let mut b = f64f.clone();
            b.byte_order = order;
            for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let r = decode_field(&a, 0, &encode_field(&a, v)).expect("decode");
                assert_eq!(r.status, ReadingStatus::NotFinite, "f32 {order:?} {v}");
                let r = decode_field(&b, 0, &encode_field(&b, v)).expect("decode");
                assert_eq!(r.status, ReadingStatus::NotFinite, "f64 {order:?} {v}");
            }
        }
        // 0x7FC0_0000 is the canonical f32 quiet NaN, 0x7F80_0000 +Inf.
        assert_eq!(
            decode_field(&f32f, 0, &[0x7FC0, 0]).map(|r| r.status),
            Ok(ReadingStatus::NotFinite)
        );
        assert_eq!(
            decode_field(&f32f, 0, &[0x7F80, 0]).map(|r| r.status),
            Ok(ReadingStatus::NotFinite)
        );
        // A huge but finite f32 scaled into overflow is also not finite.
        let mut big = f32f.clone();
        big.scale = 1e300;
        assert_eq!(
            decode_field(&big, 0, &encode_raw(3.0e38, DataType::F32, ByteOrder::ABCD))
                .map(|r| r.status),
            Ok(ReadingStatus::NotFinite)
        );
    }

    fn good_map() -> ModbusConfig {
        let sig = |name: &str, address: u32, s: Signal| FieldSpec {
            signal: Some(s),
            ..field(name, address, DataType::F32)
        };
        ModbusConfig {
            endpoint: "127.0.0.1:502".into(),
            requests: vec![RequestSpec {
                slave_id: 1,
                register: RegisterKind::Holding,
                start_address: 0,
                count: None,
                fields: vec![
                    sig("n1_rpm", 0, Signal::N1),
                    sig("t2_k", 2, Signal::T2),
                    sig("p2_kpa", 4, Signal::P2),
                    sig("t34_k", 6, Signal::T34),
                    sig("p34_kpa", 8, Signal::P34),
                    sig("fuel_kg_s", 10, Signal::FuelFlow),
                ],
            }],
        }
    }

    fn keys(p: &[ConfigProblem]) -> Vec<String> {
        p.iter().map(|p| p.key.clone()).collect()
    }

    #[test]
    fn good_map_has_no_problems() {
        let m = good_map();
        assert_eq!(m.check(), vec![]);
        assert_eq!(m.requests[0].register_count(), 12);
    }

    #[test]
    fn every_problem_is_reported_not_just_the_first() {
        let mut m = good_map();
        m.endpoint = "plc".into();
        let r = &mut m.requests[0];
        r.slave_id = 0;
        r.fields[1].address = 1; // overlaps n1 (0–1)
        r.fields[2].scale = 0.0;
        r.fields[3].min = Some(5.0);
        r.fields[3].max = Some(1.0);
        r.fields.pop(); // drop fuel flow
        r.fields.push(field("spare", 200, DataType::U16)); // spans 0–200 → 201 registers
        let p = m.check();
        assert_eq!(
            keys(&p),
            vec![
                "modbus.endpoint",
                "modbus.request[0].slave_id",
                "modbus.request[0].count",
                "modbus.request[0].field[1].address",
                "modbus.request[0].field[2].scale",
                "modbus.request[0].field[3].max",
                "modbus.request",
            ],
            "{p:#?}"
        );
        assert_eq!(
            p[3].message,
            "registers 1–2 (f32 holding, slave 0) overlap field 'n1_rpm' (modbus.request[0].field[0])"
        );
        assert_eq!(
            p[2].message,
            "request spans 201 registers (0–200); one Modbus read may ask for at most 125: \
             split it into several requests"
        );
        assert_eq!(
            p[6].message,
            "missing required tags for diagnosis: fuel_flow (add a field with signal = \"…\" for each)"
        );
    }

    #[test]
    fn modicon_addresses_get_a_specific_hint() {
        let mut m = good_map();
        m.requests[0].start_address = 40001;
        for (i, f) in m.requests[0].fields.iter_mut().enumerate() {
            f.address = 40001 + 2 * i as u32;
        }
        let p = m.check();
        assert_eq!(p[0].key, "modbus.request[0].start_address");
        assert_eq!(
            p[0].message,
            "40001 looks like the 1-based Modicon notation for holding register 1 (4xxxx); \
             addresses here are 0-based, so write 0"
        );
        assert_eq!(p[1].key, "modbus.request[0].field[0].address");
        // 3xxxx on a holding request also says the table looks wrong.
        assert_eq!(
            modicon_hint(30011, RegisterKind::Holding).as_deref(),
            Some(
                "30011 looks like the 1-based Modicon notation for input register 11 (3xxxx); \
                 addresses here are 0-based, so write 10 and check register = \"input\" \
                 (this request reads holding registers)"
            )
        );
        assert_eq!(
            modicon_hint(400101, RegisterKind::Holding).as_deref(),
            Some(
                "400101 looks like the 1-based Modicon notation for holding register 101 (4xxxx); \
                 addresses here are 0-based, so write 100"
            )
        );
        assert_eq!(modicon_hint(29999, RegisterKind::Holding), None);
        assert_eq!(modicon_hint(40000, RegisterKind::Holding), None);
    }

    #[test]
    fn type_wider_than_the_registers_of_the_request() {
        let mut m = good_map();
        m.requests[0].count = Some(11); // fuel flow f32 at 10 needs 10–11
        let p = m.check();
        assert_eq!(keys(&p), vec!["modbus.request[0].field[5].type"]);
        assert_eq!(
            p[0].message,
            "f32 needs 2 registers (10–11) but the request reads only 0–10 (count = 11): \
             the type is wider than the registers left"
        );
    }

    #[test]
    fn overlap_across_requests_of_same_slave_and_table_only() {
        let mut m = good_map();
        let mut second = RequestSpec {
            slave_id: 1,
            register: RegisterKind::Holding,
            start_address: 4,
            count: None,
            fields: vec![field("extra", 5, DataType::U16)],
        };
        m.requests.push(second.clone());
        let p = m.check();
        assert_eq!(keys(&p), vec!["modbus.request[1].field[0].address"]);
        assert!(
            p[0].message.contains("overlap field 'p2_kpa'"),
            "{}",
            p[0].message
        );
        // Input registers are a different table: no overlap.
        second.register = RegisterKind::Input;
        m.requests[1] = second.clone();
        assert_eq!(m.check(), vec![]);
        // Another slave: no overlap either.
        second.register = RegisterKind::Holding;
        second.slave_id = 2;
        m.requests[1] = second;
        assert_eq!(m.check(), vec![]);
    }

    #[test]
    fn duplicate_names_and_signals() {
        let mut m = good_map();
        let mut dup = m.requests[0].fields[0].clone();
        dup.address = 20;
        m.requests[0].fields.push(dup);
        let p = m.check();
        assert_eq!(
            p,
            vec![
                ConfigProblem::new(
                    "modbus.request[0].field[6].name",
                    "tag name 'n1_rpm' is already used by modbus.request[0].field[0]"
                ),
                ConfigProblem::new(
                    "modbus.request[0].field[6].signal",
                    "signal n1 is already fed by modbus.request[0].field[0]"
                ),
            ]
        );
    }

    #[test]
    fn toml_round_trip_and_signal_names() {
        let text = r#"
endpoint = "10.0.0.5:502"
[[request]]
slave_id = 1
register = "input"
start_address = 0
[[request.field]]
name = "t2_k"
address = 0
type = "u16"
byte_order = "BADC"
scale = 0.1
signal = "T2"
"#;
        let m: ModbusConfig = toml::from_str(text).expect("parse");
        assert_eq!(m.requests[0].fields[0].signal, Some(Signal::T2));
        assert_eq!(m.requests[0].fields[0].byte_order, ByteOrder::BADC);
        let bad = text.replace("\"T2\"", "\"T9\"");
        let e = toml::from_str::<ModbusConfig>(&bad).expect_err("bad signal");
        assert!(e.to_string().contains("unknown signal 'T9'"), "{e}");
        let bad = text.replace("scale = 0.1", "scale = 0.1\nbyteorder = \"ABCD\"");
        let e = toml::from_str::<ModbusConfig>(&bad).expect_err("unknown key");
        assert!(e.to_string().contains("unknown field `byteorder`"), "{e}");
    }
}
