//! Sim-to-real gap analysis: where the model and the plant disagree, which candidate effect of
//! the library (`engine::effects`) explains it, and how far the gap shrinks once it is added.
//!
//! 1. The baseline: Method B on the start-up with the engine as it is; its `fit_quality` and
//!    residual map say whether there is a gap and where.
//! 2. Candidates: every registry instance asked for (`all` by default), each refitted together
//!    with the health vector (its parameters as named fit parameters, bounds from the registry,
//!    a bias's bounds from the channel's readings). Scored by the shrinkage of the residual sum
//!    of squares — on a second start-up of the same unit when one is given (held out: the
//!    effect's parameters fitted on the first are kept, health refitted), else on the same
//!    data — with the Bayesian information criterion (n ln(SSR/n) + k ln n) as the tie-breaker
//!    and the penalty for extra parameters.
//! 3. Verdict: `none` when the baseline fits within noise; the best candidate when it lowers
//!    the BIC, shrinks the gap by more than the optimiser's own spread (the baseline refitted
//!    with [`SEED_REFITS`] other seeds) and either by at least [`MIN_SHRINKAGE`] or so far
//!    that the fit becomes `good` (the same yardstick as the baseline's); else `unexplained`.
//!
//! Instrument candidates (`sensor_lag:<column>`, `sensor_bias:<column>`) are tried only on
//! channels the residual map points at; engine effects always. Pure orchestration of the
//! diagnosis: no I/O. Candidates run one after another, each fit using the configured threads.

pub mod bench;
pub mod svg;
pub mod truth;

use crate::diagnosis::fit_quality::{ResidualCell, Verdict};
use crate::diagnosis::transient::diagnose_transient;
use crate::diagnosis::{DiagnosisConfig, DiagnosisError, FitParam, MethodResult};
use crate::engine::effects::{self, Channels};
use crate::engine::trace::Values;
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::recording::Recording;
use crate::signals::Signal;
use serde::Serialize;
use std::collections::BTreeMap;

/// Least shrinkage of the gap (fraction of the baseline SSR) a candidate must reach to be named.
pub const MIN_SHRINKAGE: f64 = 0.3;
/// Extra baseline fits with other optimiser seeds that measure the optimiser's own spread.
pub const SEED_REFITS: u64 = 2;
/// Bounds of a fitted sensor bias: this fraction of the channel's largest reading, either way.
const BIAS_BOUND_FRACTION: f64 = 0.05;

/// One candidate's result.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    pub effect: String,
    /// Fitted parameters: name → (value, 1σ).
    pub params: BTreeMap<String, (f64, f64)>,
    /// 1 − SSR(candidate)/SSR(baseline) on the fitted start-up.
    pub train_shrinkage: f64,
    /// The same on the held-out start-up (`None` without one).
    pub heldout_shrinkage: Option<f64>,
    /// BIC(baseline) − BIC(candidate): positive when the candidate is worth its parameters.
    pub bic_gain: f64,
    /// The score the ranking uses: held-out shrinkage when available, else train shrinkage.
    pub score: f64,
    pub health: HealthParams,
    pub fit_quality: Verdict,
    pub normalised_residual: f64,
}

/// What the analysis concludes.
#[derive(Debug, Clone, Serialize)]
pub struct GapVerdict {
    /// The winning effect's instance name, `unexplained`, or `none`.
    pub effect: String,
    /// Score margin of the winner over the runner-up (0…1; 0 for `none`/`unexplained`).
    pub confidence: f64,
    pub shrinkage: f64,
    pub health_before: HealthParams,
    pub health_after: HealthParams,
}

/// The whole analysis.
#[derive(Debug, Clone, Serialize)]
pub struct GapReport {
    pub baseline_fit_quality: Verdict,
    pub baseline_normalised_residual: f64,
    pub summary: String,
    pub localisation: Vec<ResidualCell>,
    /// How far the baseline's residual moves between fits with different optimiser seeds
    /// ((max − min)/min of the SSR over [`SEED_REFITS`] + 1 fits): a candidate must shrink
    /// the gap by more than this to be named (0 when the baseline fits).
    pub optimiser_spread: f64,
    pub candidates: Vec<Candidate>,
    pub verdict: GapVerdict,
    /// The worst signal of the baseline's residual map: measured, modelled before and after
    /// the winning effect (for the SVG; not serialised).
    #[serde(skip)]
    pub worst_signal: Option<SignalTraces>,
}

/// One signal over the start-up: measured, the baseline model, and the model with the winning
/// effect (when one is named).
#[derive(Debug, Clone)]
pub struct SignalTraces {
    pub signal: Signal,
    pub t_s: Vec<f64>,
    pub measured: Vec<f64>,
    pub before: Vec<f64>,
    /// The winner's model and its name.
    pub after: Option<(String, Vec<f64>)>,
}

/// The instance names `selection` asks for: `all`, or a comma-separated list.
pub fn select(selection: &str) -> Result<Vec<String>, String> {
    let all = effects::instance_names();
    if selection.trim() == "all" {
        return Ok(all);
    }
    selection
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            if all.iter().any(|a| a == s) {
                Ok(s.to_string())
            } else {
                Err(format!(
                    "unknown effect `{s}` (see gtwatch gap --list-effects)"
                ))
            }
        })
        .collect()
}

/// The fit parameters of one candidate instance, bounded for `rec`.
pub fn fit_params(instance: &str, rec: &Recording) -> Vec<FitParam> {
    let Some(spec) = effects::spec(instance) else {
        return Vec::new();
    };
    let channel: Option<Signal> = instance.split_once(':').and_then(|(_, c)| c.parse().ok());
    spec.params
        .iter()
        .map(|p| {
            let (lo, hi) = match (spec.name, channel) {
                ("sensor_bias", Some(s)) => {
                    let peak = rec
                        .series(s)
                        .into_iter()
                        .filter(|v| v.is_finite())
                        .fold(0.0, |m: f64, v| m.max(v.abs()));
                    let b = (BIAS_BOUND_FRACTION * peak).max(1e-6);
                    (-b, b)
                }
                ("sensor_lag", _) => (p.min, p.max.min(30.0)),
                _ => (p.min, p.max),
            };
            let name = instance.to_string();
            FitParam::effect(&name, p.name, lo, hi)
        })
        .collect()
}

/// Per-channel instruments are tried only where the residual map points at their channel (a
/// cell of that signal beyond [`CHANNEL_CELL_SIGMA`]); engine effects are always tried. This
/// keeps a full run to a dozen candidates instead of two dozen.
fn worth_trying(instance: &str, cells: &[ResidualCell]) -> bool {
    let Some((_, column)) = instance.split_once(':') else {
        return true;
    };
    cells
        .iter()
        .any(|c| c.signal.column() == column && c.norm_error > CHANNEL_CELL_SIGMA)
}

/// Norm error (σ) of a residual cell that makes its channel's instrument effects candidates.
pub const CHANNEL_CELL_SIGMA: f64 = 2.0;

fn bic(r: &MethodResult, k: usize) -> f64 {
    let n = r.residuals.max(1) as f64;
    n * (r.ssr / n).max(1e-300).ln() + k as f64 * n.ln()
}

/// Runs the analysis of `rec` (and `holdout`, a second start-up of the same unit) over the
/// candidate instances `candidates`.
pub fn analyse(
    engine: &Engine,
    rec: &Recording,
    holdout: Option<&Recording>,
    candidates: &[String],
    cfg: &DiagnosisConfig,
) -> Result<GapReport, DiagnosisError> {
    let base = diagnose_transient(engine, rec, cfg)?;
    let base_ho = match holdout {
        Some(h) => Some(diagnose_transient(engine, h, cfg)?),
        None => None,
    };
    let k_base = 6 + usize::from(cfg.fit_ambient_pressure);
    let mut out = Vec::new();
    let mut models: BTreeMap<String, Vec<Values>> = BTreeMap::new();
    let mut optimiser_spread = 0.0;
    if base.fit_quality.verdict != Verdict::Good {
        // What optimiser and noise variation alone do to the residual: refit the baseline with
        // other seeds. A candidate's shrinkage must exceed it.
        let mut ssrs = vec![base.ssr];
        for k in 1..=SEED_REFITS {
            let seeded = DiagnosisConfig {
                seed: cfg.seed.wrapping_add(k),
                ..cfg.clone()
            };
            if let Ok(r) = diagnose_transient(engine, rec, &seeded) {
                ssrs.push(r.ssr);
            }
        }
        let lo = ssrs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = ssrs.iter().copied().fold(0.0, f64::max);
        optimiser_spread = ((hi - lo) / lo.max(1e-300)).clamp(0.0, 1.0);
        for name in candidates
            .iter()
            .filter(|c| worth_trying(c, &base.localisation))
        {
            let extra = fit_params(name, rec);
            if extra.is_empty() {
                continue;
            }
            let c_cfg = DiagnosisConfig {
                extra_params: extra.clone(),
                max_model_runs: cfg.max_model_runs + 100 * extra.len(),
                ..cfg.clone()
            };
            let r = match diagnose_transient(engine, rec, &c_cfg) {
                Ok(r) => r,
                Err(_) => continue,
            };
            let params: BTreeMap<String, (f64, f64)> = r
                .params
                .iter()
                .filter(|p| p.name.starts_with("effects."))
                .map(|p| (p.name.clone(), (p.value, p.sigma)))
                .collect();
            let heldout_shrinkage = match (holdout, &base_ho) {
                (Some(h), Some(bh)) => {
                    let mut e = engine.clone();
                    for (key, (v, _)) in &params {
                        e.set_param(key, *v)?;
                    }
                    diagnose_transient(&e, h, cfg)
                        .ok()
                        .map(|rh| 1.0 - rh.ssr / bh.ssr.max(1e-300))
                }
                _ => None,
            };
            let train = 1.0 - r.ssr / base.ssr.max(1e-300);
            models.insert(name.clone(), r.model_values.clone());
            out.push(Candidate {
                effect: name.clone(),
                bic_gain: bic(&base, k_base) - bic(&r, k_base + extra.len()),
                score: heldout_shrinkage.unwrap_or(train),
                params,
                train_shrinkage: train,
                heldout_shrinkage,
                health: r.health,
                fit_quality: r.fit_quality.verdict,
                normalised_residual: r.fit_quality.normalised_residual,
            });
        }
    }
    out.sort_by(|a, b| {
        b.score
            .total_cmp(&a.score)
            .then(b.bic_gain.total_cmp(&a.bic_gain))
    });
    let verdict = if base.fit_quality.verdict == Verdict::Good {
        GapVerdict {
            effect: "none".into(),
            confidence: 0.0,
            shrinkage: 0.0,
            health_before: base.health,
            health_after: base.health,
        }
    } else {
        match out.first() {
            Some(best)
                if best.bic_gain > 0.0
                    && best.score > optimiser_spread
                    && (best.score >= MIN_SHRINKAGE || best.fit_quality == Verdict::Good) =>
            {
                GapVerdict {
                    effect: best.effect.clone(),
                    confidence: out
                        .get(1)
                        .map_or(best.score, |second| best.score - second.score.max(0.0))
                        .clamp(0.0, 1.0),
                    shrinkage: best.score,
                    health_before: base.health,
                    health_after: best.health,
                }
            }
            _ => GapVerdict {
                effect: "unexplained".into(),
                confidence: 0.0,
                shrinkage: out.first().map_or(0.0, |b| b.score.max(0.0)),
                health_before: base.health,
                health_after: base.health,
            },
        }
    };
    let worst_signal = base
        .localisation
        .iter()
        .filter(|c| c.norm_error.is_finite())
        .max_by(|a, b| a.norm_error.total_cmp(&b.norm_error))
        .filter(|_| !base.model_values.is_empty())
        .map(|c| {
            let i = c.signal.index();
            let column = |rows: &[Values]| rows.iter().map(|v| v[i]).collect::<Vec<f64>>();
            SignalTraces {
                signal: c.signal,
                t_s: rec.times().to_vec(),
                measured: column(rec.rows()),
                before: column(&base.model_values),
                after: models
                    .get(&verdict.effect)
                    .filter(|m| !m.is_empty())
                    .map(|m| (verdict.effect.clone(), column(m))),
            }
        });
    Ok(GapReport {
        baseline_fit_quality: base.fit_quality.verdict,
        baseline_normalised_residual: base.fit_quality.normalised_residual,
        summary: base.fit_quality.summary.clone(),
        localisation: base.localisation,
        optimiser_spread,
        candidates: out,
        verdict,
        worst_signal,
    })
}

/// The engine-file text with the verdict's effect adopted: `base` (an engine file's text) plus
/// an `[effects."<name>"]` table holding the fitted parameters, headed by a comment saying
/// where they came from. `None` when the verdict names no effect. The caller validates the
/// result by loading it before writing it anywhere.
pub fn adopted_engine_text(base: &str, report: &GapReport, source: &str) -> Option<String> {
    let winner = report
        .candidates
        .iter()
        .find(|c| c.effect == report.verdict.effect)?;
    let mut out = base.trim_end().to_string();
    out.push_str(&format!(
        "\n\n# Adopted by `gtwatch gap` from {source}: {} shrank the gap by {:.0} %.\n[effects.\"{}\"]\n",
        winner.effect,
        100.0 * report.verdict.shrinkage,
        winner.effect
    ));
    let prefix = format!("effects.{}.", winner.effect);
    for (key, (value, sigma)) in &winner.params {
        let name = key.strip_prefix(&prefix).unwrap_or(key);
        out.push_str(&format!("{name} = {value:.6}   # ± {sigma:.3} (1σ)\n"));
    }
    Some(out)
}

/// The registry as a list (for `gtwatch gap --list-effects`).
pub fn list_effects() -> serde_json::Value {
    let rows: Vec<serde_json::Value> = effects::REGISTRY
        .iter()
        .map(|s| {
            let instances: Vec<String> = match s.channels {
                Channels::Engine => vec![s.name.to_string()],
                ch => ch
                    .signals()
                    .into_iter()
                    .map(|sig| format!("{}:{}", s.name, sig.column()))
                    .collect(),
            };
            serde_json::json!({
                "name": s.name,
                "channels": s.channels,
                "instances": instances,
                "summary": s.summary,
                "signature": s.signature,
                "params": s.params,
            })
        })
        .collect();
    serde_json::json!({ "effects": rows })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selection_and_listing_cover_the_registry() {
        let all = select("all").expect("all");
        assert!(all.contains(&"fuel_system".to_string()));
        assert!(all.contains(&"sensor_lag:t34_k".to_string()));
        assert!(all.contains(&"sensor_bias:p2_kpa".to_string()));
        assert_eq!(
            select("fuel_system, heat_soak").expect("two"),
            vec!["fuel_system", "heat_soak"]
        );
        assert!(select("warp_drive").is_err());
        let list = list_effects();
        let names: Vec<&str> = list["effects"]
            .as_array()
            .expect("array")
            .iter()
            .map(|e| e["name"].as_str().expect("name"))
            .collect();
        for want in [
            "fuel_system",
            "sensor_lag",
            "sensor_bias",
            "heat_soak",
            "bleed_schedule",
            "vigv_schedule",
            "tip_clearance",
        ] {
            assert!(names.contains(&want), "{want} listed");
        }
    }
}
