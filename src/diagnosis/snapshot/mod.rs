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
//! under the covariance it gives each row's values, and judged against what that noise leaves
//! the exact model (`fit_quality::spot_reading_good_level`). Pure orchestration of Method A's steady
//! problem plus a CSV reader over any `io::Read` (`read`); opens no files, never prints.

use super::fit_quality::{spot_reading_good_level, Verdict};
use super::residual_table::{Cell, ResidualTable};
use super::steady::{
    below_adaptation_note, beyond_calibration, health_error_note, input_noise_note,
    input_noise_sigma_note, model_error_note, offline_shape_note, relative_gg_speeds,
    with_input_noise, with_model_error, InputNoise, InputSigma, SteadyData, SteadyProblem,
    SteadyWindow,
};
use super::{
    fit, pool_for, result_of, DiagnosisConfig, DiagnosisError, DiagnosisProblem, Method,
    MethodResult,
};
use crate::engine::sensors::noise_sigma;
use crate::engine::steady::{solve, Demand, SteadyInputs};
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::signals::Signal;
use serde::Serialize;
use std::collections::HashMap;

mod read;
pub(crate) use read::INPUTS;
pub use read::{read_snapshots, read_snapshots_in, Snapshot};

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
            .chain(offline_shape_note(engine.cfg()))
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
            // Spot readings are judged against what their own noise leaves the exact model
            // (`fit_quality::spot_reading_good_level`), as is the level under the inputs'
            // noise of rows fitted as given.
            let spot_good = spot_reading_good_level(
                cfg.quality.good_level,
                n_res,
                problem.params().params().len(),
            );
            let mut judged = cfg.clone();
            if cfg.snapshot_input_noise {
                judged.quality.good_level = spot_good;
            }
            let mut result =
                result_of(Method::Steady, &problem, &out, &judged, signals, n_res, win);
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
            Ok((result, table, under_inputs, spot_good))
        });
        match outcome {
            Ok((mut result, residual_table, level_under_input_noise, spot_good)) => {
                result.wall_s = start.elapsed().as_secs_f64();
                result.fit_quality.summary = snapshot_words(&result.fit_quality.summary);
                if let Some(q) = level_under_input_noise {
                    if q <= spot_good {
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
mod tests;
