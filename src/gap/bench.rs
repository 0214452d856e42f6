//! Blind proof of the gap analysis (`gtwatch bench gap`): "plant" start-ups from the reference
//! model with random health and default noise, then altered by a hidden effect that is
//! structurally unlike the library's candidate forms — or by none, or by one the library does
//! not have — and analysed without being told which.
//!
//! Hidden truths (magnitudes drawn across REFERENCE §5's ranges):
//! - `t34_two_path` / `t2_two_path`: a thermocouple with a junction path (2–6 s) and a shield
//!   path (10–25 s), 60/40 — against the library's single first-order `sensor_lag`;
//! - `p2_bias` / `t34_bias`: 0.8–1.5 % of full scale (2500 kPa, 1200 K);
//! - `fuel_lead`: the recorded fuel flow leads the fuel burnt by a pure delay of 0.8–3 s —
//!   against the library's Erlang-chain-plus-lag `fuel_system`;
//! - `p34_ripple`: a 0.2 Hz ripple of 1.5–3 % on P34 (not in the library: expect
//!   `unexplained`);
//! - `none`: the data as simulated (expect `none`).
//!
//! Library, thresholds and seeds are fixed before the cases are drawn. Pure: no I/O.

use super::{analyse, GapReport};
use crate::diagnosis::bench::synthetic_startup;
use crate::diagnosis::{DiagnosisConfig, DiagnosisError};
use crate::engine::Engine;
use crate::health::{HealthParams, HEALTH_NAMES};
use crate::recording::Recording;
use crate::signals::Signal;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use std::collections::BTreeMap;

/// The hidden truths, in the order cases cycle through them.
pub const KINDS: [&str; 7] = [
    "none",
    "t34_two_path",
    "p2_bias",
    "fuel_lead",
    "t2_two_path",
    "t34_bias",
    "p34_ripple",
];

/// The verdict a correct analysis gives for a hidden truth.
pub fn expected(kind: &str) -> &'static str {
    match kind {
        "t34_two_path" => "sensor_lag:t34_k",
        "t2_two_path" => "sensor_lag:t2_k",
        "p2_bias" => "sensor_bias:p2_kpa",
        "t34_bias" => "sensor_bias:t34_k",
        "fuel_lead" => "fuel_system",
        "p34_ripple" => "unexplained",
        _ => "none",
    }
}

/// One analysed case.
#[derive(Debug, Clone, Serialize)]
pub struct Case {
    pub index: usize,
    pub kind: String,
    pub magnitude: f64,
    /// The winning candidate's magnitude (τ, offset, or delay + lag), when one won.
    pub fitted_magnitude: Option<f64>,
    pub truth: HealthParams,
    pub verdict: String,
    pub correct: bool,
    pub shrinkage: f64,
    pub baseline_fit_quality: String,
    pub error_before: f64,
    pub error_after: f64,
    pub health_before: HealthParams,
    pub health_after: HealthParams,
}

fn two_path(rec: &mut Recording, s: Signal, tau1: f64, tau2: f64) -> Result<(), DiagnosisError> {
    let t = rec.times().to_vec();
    let x = rec.series(s);
    let (mut y1, mut y2) = (f64::NAN, f64::NAN);
    for k in 0..t.len() {
        if !x[k].is_finite() {
            continue;
        }
        if y1.is_nan() {
            (y1, y2) = (x[k], x[k]);
        } else {
            let dt = t[k] - t[k - 1];
            let (a1, a2) = ((-dt / tau1).exp(), (-dt / tau2).exp());
            y1 = a1 * y1 + (1.0 - a1) * x[k];
            y2 = a2 * y2 + (1.0 - a2) * x[k];
        }
        rec.set(k, s, 0.6 * y1 + 0.4 * y2)?;
    }
    Ok(())
}

fn offset(rec: &mut Recording, s: Signal, b: f64) -> Result<(), DiagnosisError> {
    for k in 0..rec.len() {
        if let Some(v) = rec.value(k, s) {
            rec.set(k, s, v + b)?;
        }
    }
    Ok(())
}

/// Alters `rec` with hidden effect `kind`; returns its magnitude (s, unit or relative).
pub fn alter(rec: &mut Recording, kind: &str, rng: &mut impl Rng) -> Result<f64, DiagnosisError> {
    Ok(match kind {
        "t34_two_path" | "t2_two_path" => {
            let s = if kind == "t34_two_path" {
                Signal::T34
            } else {
                Signal::T2
            };
            let (t1, t2) = (rng.random_range(2.0..6.0), rng.random_range(10.0..25.0));
            two_path(rec, s, t1, t2)?;
            0.6 * t1 + 0.4 * t2
        }
        "p2_bias" => {
            let b = rng.random_range(0.008..0.015) * 2500.0;
            offset(rec, Signal::P2, b)?;
            b
        }
        "t34_bias" => {
            let b = rng.random_range(0.008..0.015) * 1200.0;
            offset(rec, Signal::T34, b)?;
            b
        }
        "fuel_lead" => {
            let d = rng.random_range(0.8..3.0);
            let t = rec.times().to_vec();
            let f = rec.series(Signal::FuelFlow);
            for k in 0..t.len() {
                // The record at t shows the flow burnt at t + d.
                let tt = t[k] + d;
                let j = t.partition_point(|&x| x <= tt).clamp(1, t.len() - 1);
                let w = ((tt - t[j - 1]) / (t[j] - t[j - 1])).clamp(0.0, 1.0);
                let v = f[j - 1] + w * (f[j] - f[j - 1]);
                if v.is_finite() {
                    rec.set(k, Signal::FuelFlow, v)?;
                }
            }
            d
        }
        "p34_ripple" => {
            // 1.5–3 % of the reading: a signature of at least 3× the P34 noise.
            let a = rng.random_range(0.015..0.03);
            let t = rec.times().to_vec();
            for (k, &tt) in t.iter().enumerate() {
                if let Some(v) = rec.value(k, Signal::P34) {
                    let r = 1.0 + a * (2.0 * std::f64::consts::PI * 0.2 * tt).sin();
                    rec.set(k, Signal::P34, v * r)?;
                }
            }
            a
        }
        _ => 0.0,
    })
}

fn max_error(h: &HealthParams, truth: &HealthParams) -> f64 {
    let (a, b) = (h.to_array(), truth.to_array());
    (0..6).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}

/// Runs `cases` cases (cycling through [`KINDS`], or through `only` when not empty) with all
/// candidates.
pub fn run_cases(
    engine: &Engine,
    cases: usize,
    seed: u64,
    only: &[String],
    cfg: &DiagnosisConfig,
    mut progress: impl FnMut(&Case),
) -> Result<Vec<Case>, DiagnosisError> {
    if let Some(k) = only.iter().find(|k| !KINDS.contains(&k.as_str())) {
        return Err(DiagnosisError::Config(format!(
            "unknown hidden truth {k:?}; known: {}",
            KINDS.join(", ")
        )));
    }
    let kinds: Vec<&str> = if only.is_empty() {
        KINDS.to_vec()
    } else {
        only.iter().map(String::as_str).collect()
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let candidates = crate::engine::effects::instance_names();
    let mut out = Vec::new();
    for index in 0..cases {
        let kind = kinds[index % kinds.len()];
        let truth = HealthParams::from_array(std::array::from_fn(|_| rng.random_range(0.0..3.0)));
        let mut rec = synthetic_startup(engine, &truth, 1000 + index as u64, true)?;
        let magnitude = alter(&mut rec, kind, &mut rng)?;
        let r: GapReport = analyse(engine, &rec, None, &candidates, cfg)?;
        let fitted_magnitude = r
            .candidates
            .iter()
            .find(|c| c.effect == r.verdict.effect)
            .map(|c| c.params.values().map(|(v, _)| v).sum::<f64>());
        let c = Case {
            index,
            kind: kind.into(),
            magnitude,
            fitted_magnitude,
            truth,
            correct: r.verdict.effect == expected(kind),
            verdict: r.verdict.effect.clone(),
            shrinkage: r.verdict.shrinkage,
            baseline_fit_quality: r.baseline_fit_quality.as_str().into(),
            error_before: max_error(&r.verdict.health_before, &truth),
            error_after: max_error(&r.verdict.health_after, &truth),
            health_before: r.verdict.health_before,
            health_after: r.verdict.health_after,
        };
        progress(&c);
        out.push(c);
    }
    Ok(out)
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The summary the issue asks for.
pub fn summarise(cases: &[Case]) -> serde_json::Value {
    let in_lib: Vec<&Case> = cases
        .iter()
        .filter(|c| !matches!(c.kind.as_str(), "none" | "p34_ripple"))
        .collect();
    let rate = |v: &[&Case], f: &dyn Fn(&Case) -> bool| {
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().filter(|c| f(c)).count() as f64 / v.len() as f64
        }
    };
    let nulls: Vec<&Case> = cases.iter().filter(|c| c.kind == "none").collect();
    let outs: Vec<&Case> = cases.iter().filter(|c| c.kind == "p34_ripple").collect();
    let mut confusion: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    for c in cases {
        *confusion
            .entry(c.kind.clone())
            .or_default()
            .entry(c.verdict.clone())
            .or_default() += 1;
    }
    let rmse = |pick: &dyn Fn(&Case) -> HealthParams| -> BTreeMap<String, f64> {
        HEALTH_NAMES
            .iter()
            .enumerate()
            .map(|(i, n)| {
                let v: Vec<f64> = in_lib
                    .iter()
                    .map(|c| (pick(c).to_array()[i] - c.truth.to_array()[i]).powi(2))
                    .collect();
                (
                    n.to_string(),
                    (v.iter().sum::<f64>() / v.len().max(1) as f64).sqrt(),
                )
            })
            .collect()
    };
    let bad: Vec<&Case> = cases.iter().filter(|c| c.error_before > 0.3).collect();
    serde_json::json!({
        "cases": cases.len(),
        "top1_identification": rate(&in_lib, &|c| c.correct),
        "false_attribution_on_null": rate(&nulls, &|c| c.verdict != "none" && c.verdict != "unexplained"),
        "unexplained_on_out_of_library": rate(&outs, &|c| c.verdict == "unexplained"),
        "median_shrinkage": median(in_lib.iter().map(|c| c.shrinkage).collect()),
        "median_magnitude_error": median(
            in_lib
                .iter()
                .filter(|c| c.correct)
                .filter_map(|c| c.fitted_magnitude.map(|f| ((f - c.magnitude) / c.magnitude).abs()))
                .collect()
        ),
        "health_rmse_before": rmse(&|c| c.health_before),
        "health_rmse_after": rmse(&|c| c.health_after),
        "fit_quality_flags_bad_cases": rate(&bad, &|c| c.baseline_fit_quality != "good"),
        "fit_quality_flags_clean_cases": rate(&nulls, &|c| c.baseline_fit_quality != "good"),
        "confusion": confusion,
    })
}
