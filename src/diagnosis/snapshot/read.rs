//! Reading snapshot rows: one CSV row an averaged steady point, its inputs (T1, ambient
//! pressure, n2, fuel flow) and every other signal column present as a compared value, in the
//! file's own units (`--units`) and headers (`--map`). A cell that is not a number, a value out
//! of physical range or one whose magnitude fits another unit is an error naming its line and
//! column. Must not fit, solve or print: it only reads.

use crate::diagnosis::csv_input::{
    find_column, open_csv, parse_value, CsvError, AMBIENT_PRESSURE_COLUMN,
};
use crate::diagnosis::unit_check::{self, likely_unit};
use crate::signals::Signal;
use crate::units::{ColumnUnits, Quantity};
use std::collections::HashMap;
use std::io::Read;

/// One row of a snapshot file.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// File line (1 = header).
    pub line: u64,
    /// The `--group-by` column's value, or the line number when rows are diagnosed one by one.
    pub group: String,
    /// The row's `time_s` value, when the file has one (reporting only).
    pub time_s: Option<f64>,
    pub t_amb_k: f64,
    /// The ambient pressure column's value, when the file has one.
    pub p_amb_kpa: Option<f64>,
    pub n2_rpm: f64,
    pub fuel_kg_s: f64,
    /// Every other signal present in the row: (signal, value).
    pub values: Vec<(Signal, f64)>,
}

/// Signals that are inputs of a steady point rather than compared outputs.
pub(crate) const INPUTS: [Signal; 3] = [Signal::T1, Signal::N2, Signal::FuelFlow];

/// Reads snapshot rows. `mapping` maps canonical names (signal columns, `time_s`,
/// `p_amb_kpa`) to the file's headers (empty = canonical or short names); `group_by` names
/// the column whose value pools rows. A row without T1, n2 or a positive fuel flow, a cell
/// that is not a number, or a value out of physical range is an error naming its line and
/// column; an empty cell of a compared signal is simply not compared.
pub fn read_snapshots<R: Read>(
    reader: R,
    mapping: &HashMap<String, String>,
    group_by: Option<&str>,
) -> Result<Vec<Snapshot>, CsvError> {
    read_snapshots_in(reader, mapping, &ColumnUnits::default(), group_by)
}

/// [`read_snapshots`] of a file whose columns `units` states are not in the model's units:
/// each such value is converted as it is read, before any check.
pub fn read_snapshots_in<R: Read>(
    reader: R,
    mapping: &HashMap<String, String>,
    units: &ColumnUnits,
    group_by: Option<&str>,
) -> Result<Vec<Snapshot>, CsvError> {
    let (mut rdr, headers) = open_csv(reader)?;
    let find =
        |canonical: &str, short: Option<&str>| find_column(&headers, mapping, canonical, short);
    for (canonical, file_col) in mapping {
        if canonical != "phase" && find(canonical, None).is_none() {
            return Err(CsvError::MissingColumn(file_col.clone()));
        }
    }
    let sig_cols: Vec<(Signal, usize)> = Signal::ALL
        .iter()
        .filter(|s| !matches!(s, Signal::SurgeMargin))
        .filter_map(|&s| find(s.column(), Some(s.short())).map(|c| (s, c)))
        .collect();
    for s in INPUTS {
        if !sig_cols.iter().any(|(x, _)| *x == s) {
            let name = mapping
                .get(s.column())
                .cloned()
                .unwrap_or(s.column().into());
            return Err(CsvError::MissingColumn(name));
        }
    }
    let time_col = find("time_s", None);
    let pamb_col = find(AMBIENT_PRESSURE_COLUMN, None);
    let group_col = match group_by {
        Some(g) => Some(
            headers
                .iter()
                .position(|h| h.eq_ignore_ascii_case(g))
                .ok_or_else(|| CsvError::MissingColumn(format!("{g} (--group-by)")))?,
        ),
        None => None,
    };
    let mut out = Vec::new();
    for rec in rdr.records() {
        let rec = rec?;
        let line = rec.position().map_or(0, |p| p.line());
        let cell = |c: usize| rec.get(c).unwrap_or("");
        let err = |c: usize, reason: String| CsvError::Cell {
            line,
            column: headers.get(c).unwrap_or("?").to_string(),
            reason,
        };
        let number = |c: usize| parse_value(cell(c)).map_err(|r| err(c, r));
        let mut values = Vec::new();
        let (mut t1, mut n2, mut fuel) = (f64::NAN, f64::NAN, f64::NAN);
        let mut row: Vec<(Signal, f64)> = Vec::with_capacity(sig_cols.len());
        for &(s, c) in &sig_cols {
            row.push((s, units.to_model(s.column(), number(c)?)));
        }
        let p_amb = match pamb_col {
            Some(c) => {
                let v = units.to_model(AMBIENT_PRESSURE_COLUMN, number(c)?);
                let plausible = |k: f64| (10.0..=200.0).contains(&k);
                if v.is_finite() && !plausible(v) {
                    // The unit it most likely is, as the fired-point check names a P1's.
                    let hint = likely_unit(Quantity::Pressure, v, &plausible).map_or(
                        String::new(),
                        |(u, _)| {
                            format!(
                                " (it looks like {}: state `--units {AMBIENT_PRESSURE_COLUMN}={}` \
                                 or give kPa)",
                                u.label, u.name
                            )
                        },
                    );
                    return Err(err(
                        c,
                        format!("ambient pressure {v} kPa is not plausible{hint}"),
                    ));
                }
                v.is_finite().then_some(v)
            }
            None => None,
        };
        // A column in another unit (°C, bar, kW, …) is named as such before any range check
        // calls its values implausible. Without P1 the barometer is the inlet's reference.
        let has_p1 = row.iter().any(|(s, v)| *s == Signal::P1 && v.is_finite());
        let mut judged = row.clone();
        if let (false, Some(p)) = (has_p1, p_amb.filter(|p| (40.0..=115.0).contains(p))) {
            judged.push((Signal::P1, p));
        }
        if let Some(x) = unit_check::check_fired_point(&judged) {
            let c = sig_cols
                .iter()
                .find(|(s, _)| *s == x.signal)
                .map_or(0, |(_, c)| *c);
            return Err(err(c, x.describe()));
        }
        for (&(s, c), &(_, v)) in sig_cols.iter().zip(&row) {
            if v.is_nan() {
                continue;
            }
            if let Some(why) = implausible(s, v) {
                return Err(err(c, why));
            }
            match s {
                Signal::T1 => t1 = v,
                Signal::N2 => n2 = v,
                Signal::FuelFlow => fuel = v,
                _ => values.push((s, v)),
            }
        }
        for (s, v) in [(Signal::T1, t1), (Signal::N2, n2), (Signal::FuelFlow, fuel)] {
            let c = sig_cols
                .iter()
                .find(|(x, _)| *x == s)
                .map_or(0, |(_, c)| *c);
            if v.is_nan() {
                return Err(err(c, "a snapshot needs this input in every row".into()));
            }
            if s == Signal::FuelFlow && v <= 0.0 {
                return Err(err(c, format!("fuel flow {v} is not a fired steady point")));
            }
        }
        let time_s = match time_col {
            Some(c) => Some(number(c)?).filter(|v| v.is_finite()),
            None => None,
        };
        let group = match group_col {
            Some(c) if !cell(c).is_empty() => cell(c).to_string(),
            Some(c) => return Err(err(c, "the --group-by column is empty".into())),
            None => format!("line {line}"),
        };
        out.push(Snapshot {
            line,
            group,
            time_s,
            t_amb_k: t1,
            p_amb_kpa: p_amb,
            n2_rpm: n2,
            fuel_kg_s: fuel,
            values,
        });
    }
    if out.is_empty() {
        return Err(CsvError::Empty);
    }
    Ok(out)
}

/// Why a value cannot be a real steady reading (`None` when it can).
fn implausible(s: Signal, v: f64) -> Option<String> {
    let (lo, hi) = match s {
        Signal::T1 => (180.0, 350.0),
        Signal::T2 | Signal::T3 | Signal::T34 | Signal::T4 => (180.0, 2500.0),
        Signal::P1 | Signal::P2 | Signal::P3 | Signal::P34 | Signal::P4 => (1.0, 10_000.0),
        Signal::N1 | Signal::N2 => (0.0, 100_000.0),
        Signal::FuelFlow => (0.0, 100.0),
        Signal::Power => (-10.0, 1_000.0),
        Signal::Torque => (-100.0, 10_000.0),
        Signal::InletDepression => (-1.0, 20.0),
        Signal::SurgeMargin => return None,
    };
    (!(lo..=hi).contains(&v)).then(|| format!("{v} is outside the plausible range {lo}…{hi}"))
}
