//! Which candidate effects one gap analysis tries: the selection asked for (`--effects`), each
//! instance's fit parameters bounded for the recording, the per-channel instruments the
//! residual map points at, and of those the most promising by the linear screen
//! ([`super::linear`]); also the registry listing (`gtwatch gap --list-effects`).
//!
//! Pure: no I/O, no fits (the linear screen's model runs only).

use super::linear;
use crate::diagnosis::fit_quality::ResidualCell;
use crate::diagnosis::{DiagnosisConfig, FitParam, MethodResult};
use crate::engine::effects::{self, Channels};
use crate::engine::Engine;
use crate::recording::Recording;
use crate::signals::Signal;
use serde::Serialize;

/// Bounds of a fitted sensor bias: this fraction of the channel's largest reading, either way.
const BIAS_BOUND_FRACTION: f64 = 0.05;

/// The instance names `selection` asks for: `all`, or a comma-separated list.
pub(crate) fn select(selection: &str) -> Result<Vec<String>, String> {
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

/// The largest |value| of signal `s` in `rec` (0 when it has none): the scale a bias's bounds
/// are a fraction of.
fn peak_abs(rec: &Recording, s: Signal) -> f64 {
    rec.series(s)
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(0.0, |m: f64, v| m.max(v.abs()))
}

/// The fit parameters of one candidate instance, bounded for `rec`: its simple form's (a
/// refinement's parameters stay at their defaults).
pub(crate) fn fit_params(instance: &str, rec: &Recording) -> Vec<FitParam> {
    params_of(instance, rec, false)
}

/// The fit parameters of the instance with its refinement (empty when it has none): what the
/// analysis fits once it has named the instance.
pub(crate) fn refined_params(instance: &str, rec: &Recording) -> Vec<FitParam> {
    let has_refinement =
        effects::spec(instance).is_some_and(|s| s.params.iter().any(|p| p.refinement));
    if has_refinement {
        params_of(instance, rec, true)
    } else {
        Vec::new()
    }
}

fn params_of(instance: &str, rec: &Recording, refined: bool) -> Vec<FitParam> {
    let Some(spec) = effects::spec(instance) else {
        return Vec::new();
    };
    let channel: Option<Signal> = instance.split_once(':').and_then(|(_, c)| c.parse().ok());
    spec.params
        .iter()
        .filter(|p| refined || !p.refinement)
        .map(|p| {
            let (lo, hi) = match (spec.name, channel) {
                ("sensor_bias", Some(s)) => {
                    let b = (BIAS_BOUND_FRACTION * peak_abs(rec, s)).max(1e-6);
                    (-b, b)
                }
                ("sensor_lag", _) => (p.min, p.max.min(30.0)),
                // A fuel meter's zero offset, in kg/s: bounded by the recording's fuel flow
                // as a bias is by its channel's (an engine-free bound for any size of unit).
                ("fuel_meter_offset", _) => {
                    let b =
                        (BIAS_BOUND_FRACTION * peak_abs(rec, Signal::FuelFlow)).clamp(1e-6, p.max);
                    (-b, b)
                }
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
///
/// An instrument on one of the model's inputs (`sensor_scale:power_mw`, …) is always worth
/// trying: the model is driven by that signal, so its error never shows on its own channel
/// (a power transducer 2.4 % low left no cell on `power_mw` beyond 2 σ and was never tried).
pub(super) fn worth_trying(instance: &str, cells: &[ResidualCell]) -> bool {
    let Some((_, column)) = instance.split_once(':') else {
        return true;
    };
    if super::alias::is_input_instrument(instance) {
        return true;
    }
    cells
        .iter()
        .any(|c| c.signal.column() == column && c.norm_error > CHANNEL_CELL_SIGMA)
}

/// Norm error (σ) of a residual cell that makes its channel's instrument effects candidates.
pub(crate) const CHANNEL_CELL_SIGMA: f64 = 2.0;

/// Instrument candidates (`name:column`) fitted in the screen at most: the best of the linear
/// screen's ranking ([`linear`](super::linear)). An instrument effect that explains the gap
/// leads that ranking among its kind; fitting a dozen offsets on channels the gap merely spills
/// into costs a third of an analysis and names nothing.
pub(crate) const INSTRUMENT_SCREENS: usize = 3;
/// Least shrinkage the linear screen must predict for an instrument candidate to be fitted.
pub(crate) const LINEAR_MIN_SHRINKAGE: f64 = 0.02;

/// An instrument candidate the linear screen left out of the fitted screen.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Unscreened {
    pub(crate) effect: String,
    /// The linear screen's predicted shrinkage (fraction of the baseline's SSR).
    pub(crate) predicted_shrinkage: f64,
}

/// A candidate the analysis fits: its instance name, its fit parameters, and the linear
/// screen's prediction (instrument candidates only).
#[derive(Debug, Clone)]
pub(super) struct Trial {
    pub effect: String,
    pub params: Vec<FitParam>,
    pub predicted: Option<f64>,
}

/// Splits the candidates worth trying into those to fit (every engine effect; the instrument
/// candidates the linear screen ranks best, at most [`INSTRUMENT_SCREENS`], each predicted to
/// shrink the gap by at least [`LINEAR_MIN_SHRINKAGE`] or unpredictable) and the instrument
/// candidates left out. When the linear screen cannot run, every candidate is fitted.
pub(super) fn gate_instruments(
    engine: &Engine,
    rec: &Recording,
    cfg: &DiagnosisConfig,
    base: &MethodResult,
    names: Vec<(String, Vec<FitParam>)>,
) -> (Vec<Trial>, Vec<Unscreened>) {
    let trial = |(effect, params): (String, Vec<FitParam>), predicted| Trial {
        effect,
        params,
        predicted,
    };
    let (instruments, engine_effects): (Vec<_>, Vec<_>) =
        names.into_iter().partition(|(n, _)| n.contains(':'));
    let mut fitted: Vec<Trial> = engine_effects.into_iter().map(|c| trial(c, None)).collect();
    let Ok(pred) = linear::predicted_shrinkage(engine, rec, cfg, base, &instruments) else {
        fitted.extend(instruments.into_iter().map(|c| trial(c, None)));
        return (fitted, Vec::new());
    };
    // Unpredictable candidates first (a failed perturbation says nothing against them).
    let mut order: Vec<usize> = (0..instruments.len()).collect();
    order.sort_by(|&a, &b| {
        let key = |i: usize| pred[i].unwrap_or(f64::INFINITY);
        key(b).total_cmp(&key(a))
    });
    let mut unscreened = Vec::new();
    let mut taken = 0;
    for i in order {
        let (n, p) = &instruments[i];
        let promising = pred[i].is_none_or(|v| v >= LINEAR_MIN_SHRINKAGE);
        if promising && taken < INSTRUMENT_SCREENS {
            taken += 1;
            fitted.push(trial((n.clone(), p.clone()), pred[i]));
        } else {
            unscreened.push(Unscreened {
                effect: n.clone(),
                predicted_shrinkage: pred[i].unwrap_or(f64::NAN),
            });
        }
    }
    (fitted, unscreened)
}

/// The registry as a list (for `gtwatch gap --list-effects`).
pub(crate) fn list_effects() -> serde_json::Value {
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

    #[test]
    fn input_instruments_are_tried_without_a_residual_on_their_channel() {
        // No residual cells at all: an output's instrument is not worth a fit, an input's is
        // (its error only shows spread over the outputs), as is every engine effect.
        assert!(!worth_trying("sensor_bias:p2_kpa", &[]));
        assert!(!worth_trying("sensor_scale:t34_k", &[]));
        for input in [
            "sensor_scale:power_mw",
            "sensor_scale:torque_knm",
            "sensor_bias:p1_kpa",
        ] {
            assert!(worth_trying(input, &[]), "{input}");
        }
        assert!(worth_trying("fuel_meter", &[]));
    }
}
