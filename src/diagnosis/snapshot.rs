//! Snapshot diagnosis: health from steady operating points a plant already keeps — performance
//! tests, historian hourly averages — instead of a start-up. Each CSV row is one averaged steady
//! point with its own ambient temperature (T1), ambient pressure, PT speed (n2) and fuel flow;
//! the other signal columns present are compared with the steady model. Rows are diagnosed one
//! by one, or pooled by the value of a `--group-by` column (a test id, a day): one health vector
//! with 1σ per group, and the groups in order of first appearance form a history.
//!
//! Inputs per row (what the steady solver is given): T1 → ambient temperature; the ambient
//! pressure column (`p_amb_kpa`, or the file header a mapping names for it) when present, else
//! P1 divided by the healthy model's inlet-loss ratio at that point (the inlet loss is ~1 % at
//! design, so a health-dependent flow changes that ratio by well under 0.1 %), else the engine
//! file's ambient pressure (said in [`SnapshotGroup::assumptions`]); n2; fuel flow as the demand.
//! Every other signal column present (n1, T2, P2, T34, P34, power, …) is compared. Each value's
//! 1σ is the instrument's noise σ at that value (`[sensors]`): an average of many samples is
//! more precise than that, but its instrument bias is not, so the one-sample σ is the honest
//! scale; an adapted engine file's own model error (`[adaptation.model_error_pct]`) is added to
//! it in quadrature, and a row below the adaptation's calibrated speeds is noted. The inputs
//! carry one reading's noise as the compared values do: by default the fit and its verdict take
//! them as given and their noise is added to the read's σ ([`InputNoise::SigmaOnly`]); with
//! [`DiagnosisConfig::snapshot_input_noise`] (`--noisy-inputs`: spot readings) the fit runs
//! under the covariance it gives each row's values. Pure
//! orchestration of Method A's steady problem plus a CSV reader over any `io::Read`; opens no
//! files, never prints.

use super::csv_input::{find_column, open_csv, parse_value, CsvError, AMBIENT_PRESSURE_COLUMN};
use super::fit_quality::Verdict;
use super::residual_table::{Cell, ResidualTable};
use super::steady::{
    below_adaptation_note, beyond_calibration, health_error_note, input_noise_note,
    input_noise_sigma_note, model_error_note, relative_gg_speeds, with_input_noise,
    with_model_error, InputNoise, InputSigma, SteadyData, SteadyProblem, SteadyWindow,
};
use super::unit_check::likely_unit;
use super::{fit, pool_for, result_of, DiagnosisConfig, DiagnosisError, Method, MethodResult};
use crate::engine::sensors::noise_sigma;
use crate::engine::steady::{solve, Demand, SteadyInputs};
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::signals::Signal;
use crate::units::{ColumnUnits, Quantity};
use serde::Serialize;
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
        if let Some(x) = super::unit_check::check_fired_point(&judged) {
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

/// One diagnosed group.
#[derive(Debug, Clone, Serialize)]
pub struct SnapshotGroup {
    pub group: String,
    /// File lines of the rows pooled.
    pub lines: Vec<u64>,
    /// Rows whose healthy steady solve failed, with the reason each was left out.
    pub dropped: Vec<DroppedRow>,
    /// How each row's ambient pressure was obtained, when not from the ambient column.
    pub assumptions: Vec<String>,
    pub result: MethodResult,
    /// (model − measured)/σ of every compared signal at every row used, at the fitted health.
    pub residual_table: ResidualTable,
    /// With the inputs taken as given and a fit not `good`: its normalised residual judged
    /// under the inputs' noise ([`SteadyProblem::level_under_input_noise`]), which the summary
    /// names when it is within `good` (the rows' inputs are noisier than averages').
    #[serde(skip_serializing_if = "Option::is_none")]
    pub level_under_input_noise: Option<f64>,
}

/// The residual table of a fitted snapshot group: one row per snapshot the problem kept (its
/// window's `start` is the row's index in `rows`). Empty when the model cannot be evaluated at
/// `x` (the result then carries the failure).
fn residual_table_of(problem: &SteadyProblem, x: &[f64], rows: &[Snapshot]) -> ResidualTable {
    let Ok(model) = problem.simulate(x) else {
        return ResidualTable::default();
    };
    let points: Vec<(u64, String)> = problem
        .points()
        .iter()
        .map(|p| {
            let line = rows.get(p.window.start).map_or(0, |r| r.line);
            (line, p.operating_point())
        })
        .collect();
    let cells: Vec<Cell> = problem
        .points()
        .iter()
        .zip(&model)
        .enumerate()
        .flat_map(|(i, (p, m))| {
            p.outputs.iter().map(move |&(signal, z, sd)| Cell {
                point: i,
                signal,
                value: (m[signal.index()] - z) / sd,
            })
        })
        .collect();
    ResidualTable::from_cells(&points, &cells)
}

/// The whole snapshot diagnosis: groups in order of first appearance, and those that could not
/// be diagnosed with the reason.
#[derive(Debug, Clone, Serialize)]
pub struct SnapshotReport {
    pub groups: Vec<SnapshotGroup>,
    pub failed: Vec<FailedGroup>,
}

/// A group without a result.
#[derive(Debug, Clone, Serialize)]
pub struct FailedGroup {
    pub group: String,
    pub lines: Vec<u64>,
    pub reason: String,
}

/// A snapshot row left out, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DroppedRow {
    pub line: u64,
    pub reason: String,
}

/// The file lines of `rows`.
pub fn lines_of(rows: &[DroppedRow]) -> Vec<u64> {
    rows.iter().map(|d| d.line).collect()
}

/// Why the model has no steady point for `snap`, in words a plant engineer can act on.
fn unsolved(engine: &Engine, snap: &Snapshot, e: &impl std::fmt::Display) -> String {
    let design_fuel = engine.design().fuel_kg_s.max(1e-9);
    let share = snap.fuel_kg_s / design_fuel;
    let e = e.to_string();
    let e = e.strip_prefix("steady-state solver: ").unwrap_or(&e);
    if e.contains("running point at") {
        // The solver walked the running line to its end: that is the reason, said already.
        return format!("no operating point of the model: {e}");
    }
    let hint = if share < 0.25 {
        format!(
            " (fuel {:.3} kg/s is {:.0} % of the design fuel flow: an idle or light-load point \
             the maps may not reach; leave it out or add maps that cover it)",
            snap.fuel_kg_s,
            100.0 * share
        )
    } else {
        String::new()
    };
    format!("the model has no steady point for this row: {e}{hint}")
}

/// What a verdict's summary adds when the residuals are within `good` under the inputs' noise
/// (`level`: the normalised residual under it).
fn noisy_inputs_hint(level: f64) -> String {
    format!(
        "; under the noise of the rows' inputs (fuel flow, T1, n2) the residuals are within \
         good ({level:.2}): if these rows are spot readings rather than averages, \
         --noisy-inputs fits and judges them under that noise"
    )
}

/// A fit-quality summary in a snapshot's terms: snapshots have no start-up phases, so a
/// residual cell "t34_k during steady_load" is "t34_k over the snapshots".
fn snapshot_words(summary: &str) -> String {
    let mut text = summary.replace(
        "spread over signals and phases",
        "spread over signals and snapshots",
    );
    for p in crate::signals::Phase::ALL {
        text = text.replace(&format!(" during {p}:"), " over the snapshots:");
    }
    text
}

/// The steady point of one snapshot: inputs for the solver and the compared values with 1σ,
/// or why its healthy solve fails.
pub(crate) fn steady_data(
    engine: &Engine,
    base: &HealthParams,
    snap: &Snapshot,
    index: usize,
    assumptions: &mut Vec<String>,
) -> Result<SteadyData, String> {
    let cfg = engine.cfg();
    let mut inputs = SteadyInputs {
        t_amb_k: snap.t_amb_k,
        p_amb_kpa: snap.p_amb_kpa.unwrap_or(cfg.ambient.pressure_kpa),
        n2_rpm: snap.n2_rpm,
        demand: Demand::FuelKgS(snap.fuel_kg_s),
    };
    let p1 = snap
        .values
        .iter()
        .find(|(s, _)| *s == Signal::P1)
        .map(|(_, v)| *v);
    // Every input is one reading, as every compared value is (the module docs).
    let mut input_sd = InputSigma::of(&cfg.sensors, &inputs, true, 1);
    match (snap.p_amb_kpa, p1) {
        (Some(_), _) => {}
        (None, Some(p1)) => {
            // Ambient from the measured compressor inlet pressure and the model's inlet loss.
            inputs.p_amb_kpa = p1;
            let m = engine.model_at(base, inputs.t_amb_k, inputs.p_amb_kpa);
            let sp = solve(&m, &inputs, None).map_err(|e| unsolved(engine, snap, &e))?;
            let ratio = sp.stations.p1_kpa / inputs.p_amb_kpa;
            if ratio.is_finite() && ratio > 0.5 {
                inputs.p_amb_kpa = p1 / ratio;
            }
            // P1's noise is the ambient pressure's, scaled by the same ratio.
            input_sd.p_amb_kpa = noise_sigma(&cfg.sensors, Signal::P1, p1) * inputs.p_amb_kpa / p1;
            assumptions.push(format!(
                "line {}: ambient pressure {:.2} kPa from P1 and the model's inlet loss",
                snap.line, inputs.p_amb_kpa
            ));
        }
        (None, None) => assumptions.push(format!(
            "line {}: no ambient pressure or P1; the engine file's {:.2} kPa assumed",
            snap.line, inputs.p_amb_kpa
        )),
    }
    let outputs: Vec<(Signal, f64, f64)> = snap
        .values
        .iter()
        // P1 became the ambient pressure when no ambient column exists: not also compared.
        .filter(|(s, _)| !(*s == Signal::P1 && snap.p_amb_kpa.is_none()))
        .filter_map(|&(s, v)| {
            let sd = noise_sigma(&cfg.sensors, s, v);
            (sd > 0.0).then_some((s, v, sd))
        })
        .collect();
    let t = snap.time_s.unwrap_or(snap.line as f64);
    let n1_hint_rpm = snap
        .values
        .iter()
        .find(|(s, v)| *s == Signal::N1 && *v > 0.0)
        .map(|(_, v)| *v);
    let data = SteadyData {
        label: format!("snapshot at line {}", snap.line),
        window: SteadyWindow {
            start: index,
            end: index + 1,
            t_start_s: t,
            t_end_s: t,
        },
        inputs,
        outputs,
        n1_hint_rpm,
        input_sd,
        input_response: Vec::new(),
        input_noise: InputNoise::Fitted,
    };
    let m = engine.model_at(base, inputs.t_amb_k, inputs.p_amb_kpa);
    data.solve_on(&m).map_err(|e| unsolved(engine, snap, &e))?;
    Ok(data)
}

/// Diagnoses every group of `rows` (see the module docs). The ambient pressure is an input of
/// each row, never fitted.
pub fn diagnose_snapshots(
    engine: &Engine,
    rows: &[Snapshot],
    cfg: &DiagnosisConfig,
) -> Result<SnapshotReport, DiagnosisError> {
    let mut cfg = cfg.clone();
    cfg.fit_ambient_pressure = false;
    cfg.validate()?;
    let pool = pool_for(&cfg)?;
    let mut order: Vec<String> = Vec::new();
    let mut groups: HashMap<String, Vec<(usize, &Snapshot)>> = HashMap::new();
    for (i, r) in rows.iter().enumerate() {
        if !groups.contains_key(&r.group) {
            order.push(r.group.clone());
        }
        groups.entry(r.group.clone()).or_default().push((i, r));
    }
    let mut report = SnapshotReport {
        groups: Vec::new(),
        failed: Vec::new(),
    };
    for g in order {
        let members = groups.remove(&g).unwrap_or_default();
        let lines: Vec<u64> = members.iter().map(|(_, r)| r.line).collect();
        let mut assumptions: Vec<String> = model_error_note(engine.cfg())
            .into_iter()
            .chain(health_error_note(engine.cfg()))
            .collect();
        assumptions.push(if cfg.snapshot_input_noise {
            input_noise_note()
        } else {
            input_noise_sigma_note()
        });
        let mut points = Vec::new();
        let mut dropped = Vec::new();
        for (i, r) in &members {
            match steady_data(engine, &cfg.base, r, *i, &mut assumptions) {
                Ok(p) => {
                    if let Some(reason) = beyond_calibration(engine, &p) {
                        dropped.push(DroppedRow {
                            line: r.line,
                            reason,
                        });
                        continue;
                    }
                    assumptions.extend(below_adaptation_note(engine, &p));
                    // The inputs' noise: fitted under with `--noisy-inputs`, else in the σ
                    // of a read fitted with the inputs as given (`InputNoise::SigmaOnly`).
                    let mut p = with_input_noise(engine, &cfg.base, p);
                    if !cfg.snapshot_input_noise {
                        p.input_noise = InputNoise::SigmaOnly;
                    }
                    points.push(with_model_error(engine, p));
                }
                Err(reason) => dropped.push(DroppedRow {
                    line: r.line,
                    reason,
                }),
            }
        }
        if points.is_empty() {
            // Nothing left to fit: the rows' own reasons are the group's.
            let reasons: Vec<String> = dropped
                .iter()
                .map(|d| format!("line {}: {}", d.line, d.reason))
                .collect();
            report.failed.push(FailedGroup {
                group: g,
                lines,
                reason: format!(
                    "no snapshot of the group could be diagnosed ({})",
                    reasons.join("; ")
                ),
            });
            continue;
        }
        let start = std::time::Instant::now();
        let outcome = SteadyProblem::new(engine, points, &cfg).and_then(|mut problem| {
            let out = fit(&mut problem, &cfg, &pool)?;
            let signals = problem.objective().signals().to_vec();
            let n_res = problem.objective().len();
            let win = problem
                .points()
                .iter()
                .map(|p| (p.window.t_start_s, p.window.t_end_s))
                .collect();
            let table = residual_table_of(&problem, &out.x, rows);
            let mut result = result_of(Method::Steady, &problem, &out, &cfg, signals, n_res, win);
            result.fit_quality = result.fit_quality.with_model_error(
                engine.cfg(),
                &result.signals,
                &relative_gg_speeds(engine, problem.points()),
            );
            // Only where the residuals themselves make the verdict: a health at its limit or
            // implausible (an input's bias absorbed, say) is not the inputs' noise.
            let q = &result.fit_quality;
            let under_inputs = (q.verdict != Verdict::Good
                && q.normalised_residual > q.thresholds.good_level)
                .then(|| problem.level_under_input_noise(&out.x))
                .flatten();
            Ok((result, table, under_inputs))
        });
        match outcome {
            Ok((mut result, residual_table, level_under_input_noise)) => {
                result.wall_s = start.elapsed().as_secs_f64();
                result.fit_quality.summary = snapshot_words(&result.fit_quality.summary);
                if let Some(q) = level_under_input_noise {
                    if q <= result.fit_quality.thresholds.good_level {
                        result.fit_quality.summary.push_str(&noisy_inputs_hint(q));
                    }
                }
                report.groups.push(SnapshotGroup {
                    group: g,
                    lines,
                    dropped,
                    assumptions,
                    result,
                    residual_table,
                    level_under_input_noise,
                });
            }
            Err(e) => report.failed.push(FailedGroup {
                group: g,
                lines,
                reason: if dropped.is_empty() {
                    e.to_string()
                } else {
                    format!(
                        "{e} (healthy steady solve failed on lines {:?})",
                        lines_of(&dropped)
                    )
                },
            }),
        }
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::trace::NSIG;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// Snapshot rows from the steady model itself at `loads_mw`, with instrument noise.
    fn snapshot_csv(engine: &Engine, health: &HealthParams, loads_mw: &[f64], seed: u64) -> String {
        let cfg = engine.cfg();
        let sigs = [
            Signal::T1,
            Signal::P1,
            Signal::N1,
            Signal::N2,
            Signal::T2,
            Signal::P2,
            Signal::T34,
            Signal::P34,
            Signal::FuelFlow,
            Signal::Power,
        ];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut csv = String::from("test");
        for s in sigs {
            csv.push(',');
            csv.push_str(s.column());
        }
        csv.push('\n');
        for (k, &load) in loads_mw.iter().enumerate() {
            let t_amb = 283.0 + 3.0 * k as f64;
            let p_amb = 100.2 - 0.3 * k as f64;
            let inputs = SteadyInputs {
                t_amb_k: t_amb,
                p_amb_kpa: p_amb,
                n2_rpm: cfg.design.pt_speed_rpm,
                demand: Demand::PowerMw(load),
            };
            let m = engine.model_at(health, t_amb, p_amb);
            let sp = solve(&m, &inputs, None).expect("steady");
            let wf = sp.stations.fuel_kg_s;
            let mut v = [f64::NAN; NSIG];
            for s in Signal::ALL {
                v[s.index()] = crate::engine::gas_path::signal_value(&sp.stations, s);
            }
            v[Signal::T1.index()] = t_amb;
            v[Signal::FuelFlow.index()] = wf;
            csv.push_str(&format!("T{}", k / 4));
            for s in sigs {
                let x = v[s.index()];
                let sd = noise_sigma(&cfg.sensors, s, x) / 5.0; // an average of 25 samples
                let noisy = if sd > 0.0 && !matches!(s, Signal::T1 | Signal::FuelFlow | Signal::N2)
                {
                    x + Normal::new(0.0, sd).expect("normal").sample(&mut rng)
                } else {
                    x
                };
                csv.push_str(&format!(",{noisy}"));
            }
            csv.push('\n');
        }
        csv
    }

    #[test]
    fn fit_summary_speaks_of_snapshots_not_phases() {
        assert_eq!(
            snapshot_words("normalised residual 3.10, spread over signals and phases"),
            "normalised residual 3.10, spread over signals and snapshots"
        );
        let phase = crate::signals::Phase::ALL[0];
        assert_eq!(
            snapshot_words(&format!("largest: t34_k during {phase}: offset (4.0 σ)")),
            "largest: t34_k over the snapshots: offset (4.0 σ)"
        );
    }

    #[test]
    fn reader_names_line_and_column_of_a_bad_cell() {
        let csv = "t1_k,n2_rpm,fuel_kg_s,p2_kpa\n288,3000,1.2,1500\n288,3000,abc,1500\n";
        let e = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect_err("bad cell");
        let text = e.to_string();
        assert!(
            text.contains("line 3") && text.contains("fuel_kg_s"),
            "{text}"
        );
        let csv = "t1_k,n2_rpm,p2_kpa\n288,3000,1500\n";
        let e = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect_err("no fuel");
        assert!(e.to_string().contains("fuel_kg_s"), "{e}");
        let csv = "t1_k,n2_rpm,fuel_kg_s\n288,3000,1.2\n";
        let e = read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test_id"))
            .expect_err("no group column");
        assert!(e.to_string().contains("test_id"), "{e}");
        let csv = "t1_k,n2_rpm,fuel_kg_s\n2880,3000,1.2\n";
        let e = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect_err("range");
        assert!(e.to_string().contains("plausible"), "{e}");
        // An ambient pressure in another unit names it, and what to state.
        for (v, unit) in [("1.013", "bar"), ("1013", "mbar"), ("101300", "Pa")] {
            let csv = format!("t1_k,p_amb_kpa,n2_rpm,fuel_kg_s\n288,{v},3000,1.2\n");
            let e = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect_err("unit");
            let text = e.to_string();
            assert!(
                text.contains(&format!(
                    "looks like {unit}: state `--units p_amb_kpa={unit}`"
                )),
                "{v}: {text}"
            );
        }
    }

    #[test]
    fn grouped_snapshots_recover_health_per_group() {
        let engine = Engine::reference().expect("engine");
        let truth = HealthParams::from_array([-2.0, -1.5, 1.0, -1.0, 0.5, -0.8]);
        let loads = [12.0, 17.0, 22.0, 27.0, 14.0, 19.0, 24.0, 29.0];
        let csv = snapshot_csv(&engine, &truth, &loads, 3);
        let rows = read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
        assert_eq!(rows.len(), 8);
        assert!(rows.iter().all(|r| r.p_amb_kpa.is_none()));
        let cfg = DiagnosisConfig {
            max_model_runs: 1500,
            ..DiagnosisConfig::default()
        };
        let report = diagnose_snapshots(&engine, &rows, &cfg).expect("diagnosis");
        assert!(report.failed.is_empty(), "{:?}", report.failed);
        assert_eq!(report.groups.len(), 2);
        assert_eq!(report.groups[0].group, "T0");
        for g in &report.groups {
            assert_eq!(g.lines.len(), 4);
            let est = g.result.health.to_array();
            for (i, (&e, &t)) in est.iter().zip(truth.to_array().iter()).enumerate() {
                assert!(
                    (e - t).abs() < 0.3,
                    "group {} parameter {i}: {e:.3} vs truth {t:.3}",
                    g.group
                );
            }
        }
        // One row alone: six readings for six parameters, refused with the reason.
        let single = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect("rows");
        let report = diagnose_snapshots(&engine, &single[..1], &cfg).expect("runs");
        assert!(report.groups.is_empty());
        assert!(
            report.failed[0].reason.contains("more averaged values"),
            "{}",
            report.failed[0].reason
        );
    }

    /// The inputs' noise widens the read's σ and leaves the read itself as the fit with the
    /// inputs as given makes it: the same rows on a file whose fuel meter, T1 and n2 have no
    /// noise read the same health, with a narrower σ; `--noisy-inputs` fits under that noise
    /// instead and says so.
    #[test]
    fn the_inputs_noise_is_in_the_sigma_not_in_the_read() {
        let engine = Engine::reference().expect("engine");
        let truth = HealthParams::from_array([2.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
        let loads = [12.0, 15.0, 18.0, 21.0, 24.0, 27.0, 29.0, 31.0];
        // Every row one group (the helper deals them into T0 and T1 by four).
        let csv = snapshot_csv(&engine, &truth, &loads, 11).replace("\nT1,", "\nT0,");
        let rows = read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
        let mut quiet_cfg = engine.cfg().clone();
        for ch in [
            &mut quiet_cfg.sensors.fuel,
            &mut quiet_cfg.sensors.t1,
            &mut quiet_cfg.sensors.n2,
        ] {
            ch.noise_abs = 0.0;
            ch.noise_rel = 0.0;
        }
        let quiet = Engine::new(quiet_cfg).expect("engine");
        let cfg = DiagnosisConfig {
            max_model_runs: 1500,
            threads: Some(1),
            ..DiagnosisConfig::default()
        };
        let read = |e: &Engine, cfg: &DiagnosisConfig| only_group(e, &rows, cfg);
        let noisy = read(&engine, &cfg);
        let exact = read(&quiet, &cfg);
        let h = |g: &SnapshotGroup| g.result.health.to_array();
        for (a, b) in h(&noisy).iter().zip(h(&exact)) {
            assert!((a - b).abs() < 1e-9, "{:?} vs {:?}", h(&noisy), h(&exact));
        }
        for name in ["D_GC", "D_EC", "D_GT", "D_ET"] {
            let (wide, narrow) = (noisy.result.sigma[name], exact.result.sigma[name]);
            eprintln!("{name}: σ {wide:.3} with the inputs' noise, {narrow:.3} without");
            assert!(wide > 1.2 * narrow, "{name}: σ {wide:.3} vs {narrow:.3}");
        }
        assert!(noisy
            .assumptions
            .iter()
            .any(|a| a.contains("taken as given in the fit")));
        let fitted = read(
            &engine,
            &DiagnosisConfig {
                snapshot_input_noise: true,
                ..cfg.clone()
            },
        );
        assert!(fitted
            .assumptions
            .iter()
            .any(|a| a.contains("noise of the measured inputs")));
        assert!(h(&fitted)
            .iter()
            .zip(h(&noisy))
            .any(|(a, b)| (a - b).abs() > 1e-6));
    }

    /// The first group of `rows` diagnosed on `engine`, none failed.
    fn only_group(engine: &Engine, rows: &[Snapshot], cfg: &DiagnosisConfig) -> SnapshotGroup {
        let report = diagnose_snapshots(engine, rows, cfg).expect("diagnosis");
        assert!(report.failed.is_empty(), "{:?}", report.failed);
        report.groups[0].clone()
    }

    /// `csv` with each row's fuel flow scaled by `factor(row)`.
    fn fuel_scaled(csv: &str, factor: impl Fn(usize) -> f64) -> String {
        let mut lines = csv.lines();
        let header = lines.next().expect("header");
        let col = header
            .split(',')
            .position(|c| c == Signal::FuelFlow.column())
            .expect("fuel column");
        let mut out = format!("{header}\n");
        for (k, line) in lines.enumerate() {
            let cells: Vec<String> = line
                .split(',')
                .enumerate()
                .map(|(i, c)| {
                    if i == col {
                        (c.parse::<f64>().expect("fuel") * factor(k)).to_string()
                    } else {
                        c.to_string()
                    }
                })
                .collect();
            out.push_str(&cells.join(","));
            out.push('\n');
        }
        out
    }

    /// Residuals that are the rows' fuel readings scattered by their meter's noise: the
    /// verdict, with the inputs taken as given, is not `good`, and its summary says that under
    /// the inputs' noise they are (pointing at `--noisy-inputs`); the same meter reading 3 %
    /// high on every row is a bias the health absorbs (D_GT at its limit, `suspect` with small
    /// residuals): no such words.
    #[test]
    fn a_verdict_the_inputs_noise_explains_says_so_and_a_meter_bias_does_not() {
        let engine = Engine::reference().expect("engine");
        let truth = HealthParams::from_array([2.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
        let loads = [12.0, 15.0, 18.0, 21.0, 24.0, 27.0, 29.0, 31.0];
        let csv = snapshot_csv(&engine, &truth, &loads, 5).replace("\nT1,", "\nT0,");
        let sd_rel = noise_sigma(&engine.cfg().sensors, Signal::FuelFlow, 1.5) / 1.5;
        let cfg = DiagnosisConfig {
            max_model_runs: 1500,
            threads: Some(1),
            ..DiagnosisConfig::default()
        };
        let read = |csv: &str| {
            let rows = read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
            only_group(&engine, &rows, &cfg)
        };
        let scattered = read(&fuel_scaled(&csv, |k| {
            1.0 + SCATTER_SIGMAS * sd_rel * if k % 2 == 0 { 1.0 } else { -1.0 }
        }));
        let q = &scattered.result.fit_quality;
        eprintln!(
            "scattered: {:?} {:.2}, under the inputs' noise {:?}: {}",
            q.verdict, q.normalised_residual, scattered.level_under_input_noise, q.summary
        );
        assert_ne!(q.verdict, Verdict::Good);
        let level = scattered.level_under_input_noise.expect("judged");
        assert!(level <= q.thresholds.good_level, "{level}");
        assert!(q.summary.contains("--noisy-inputs"), "{}", q.summary);

        let biased = read(&fuel_scaled(&csv, |_| 1.03));
        let b = &biased.result.fit_quality;
        eprintln!(
            "biased: {:?} {:.2}, under the inputs' noise {:?}: {}",
            b.verdict, b.normalised_residual, biased.level_under_input_noise, b.summary
        );
        assert!(!b.summary.contains("--noisy-inputs"), "{}", b.summary);
        assert_eq!(biased.level_under_input_noise, None);
    }

    /// How many of its one-reading σ each row's fuel reading is off by, alternately.
    const SCATTER_SIGMAS: f64 = 2.0;

    #[test]
    fn reduced_instrument_sets_say_what_they_separate_and_estimate_it() {
        let engine = Engine::reference().expect("engine");
        let truth = HealthParams::from_array([-2.0, -1.5, 1.0, -1.0, 0.5, -0.8]).to_array();
        let loads = [12.0, 15.0, 18.0, 21.0, 24.0, 27.0, 29.0, 31.0];
        let csv = snapshot_csv(&engine, &HealthParams::from_array(truth), &loads, 9);
        let all = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect("rows");
        let cfg = DiagnosisConfig {
            max_model_runs: 1500,
            ..DiagnosisConfig::default()
        };
        for dropped in [
            vec![Signal::T34, Signal::P34],
            vec![Signal::P34],
            vec![Signal::P2],
        ] {
            let rows: Vec<Snapshot> = all
                .iter()
                .map(|r| Snapshot {
                    group: "all".into(),
                    values: r
                        .values
                        .iter()
                        .filter(|(s, _)| !dropped.contains(s))
                        .copied()
                        .collect(),
                    ..r.clone()
                })
                .collect();
            let report = diagnose_snapshots(&engine, &rows, &cfg).expect("diagnosis");
            assert!(report.failed.is_empty(), "{dropped:?}: {:?}", report.failed);
            let r = &report.groups[0].result;
            let sep = &r.separability;
            assert!(!sep.statement.is_empty());
            let est = r.health.to_array();
            let at = |name: &str| {
                crate::health::HEALTH_NAMES
                    .iter()
                    .position(|n| *n == name)
                    .expect("a health name")
            };
            // What it calls separable is estimated within 0.5 points ...
            for name in &sep.separable {
                let i = at(name);
                assert!(
                    (est[i] - truth[i]).abs() < 0.5,
                    "{dropped:?}: {name} {:.2} vs {:.2} ({})",
                    est[i],
                    truth[i],
                    sep.statement
                );
            }
            // ... and so is every combination it says the data determine.
            for g in &sep.confounded {
                for c in &g.determined {
                    let t: f64 = c.weights.iter().map(|(n, w)| w * truth[at(n)]).sum();
                    assert!((c.value - t).abs() < 0.5, "{dropped:?}: {c:?} vs {t:.2}");
                }
            }
            // Without the HPT-exit readings the hot-end parameters cannot all be separated.
            if dropped.contains(&Signal::P34) {
                assert!(
                    !sep.confounded.is_empty() || !sep.not_identifiable.is_empty(),
                    "{dropped:?}: {}",
                    sep.statement
                );
            }
        }
    }
}
