//! The unit's own dynamics from its healthy start-ups: the thermocouples' lags and the two
//! rotors' inertias, which a steady baseline cannot inform and which an engine file copied from
//! another unit carries from that unit.
//!
//! What it is for: after the steady calibration, each healthy start-up is fitted by Method B
//! with the health held at zero (a healthy unit's start-up: whatever the model misses there is
//! the model's) and the dynamic values free; the start-ups' estimates are pooled by their
//! inverse variances, their scatter against their σ stated, and a value is written only where
//! the pool determines it. On the second independent simulator's unit (an md22 file: lags 3.0 /
//! 2.5 / 3.0 s where the unit's are 2 / 4 / 5 s) the md22 lags moved its healthy start-ups'
//! compressor reads 0.3–0.5 points; the fitted ones took most of that back.
//!
//! What it must not do: I/O, or fit anything but the dynamic values (health stays zero; the
//! steady calibration owns every design value).

use super::CalibrateError;
use crate::diagnosis::fit_quality::Verdict;
use crate::diagnosis::params::FitParam;
use crate::diagnosis::transient::diagnose_transient;
use crate::diagnosis::DiagnosisConfig;
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::recording::Recording;
use crate::signals::Signal;
use serde::Serialize;

/// The temperatures whose instrument lag is fitted when a start-up measures them (the
/// pressures' and speeds' lags are a few hundredths of a second: nothing a 1 Hz record shows).
pub const LAGGED: [Signal; 3] = [Signal::T2, Signal::T34, Signal::T4];

/// A value pooled from the start-ups is written when its 1σ is at most this fraction of it.
pub const MAX_WRITTEN_SIGMA_FRAC: f64 = 0.2;

/// One dynamic value: the file's, each start-up's estimate and the pool.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DynamicValue {
    /// Dotted engine-file key (`sensors.t4.tau_s`, `dynamics.gg_inertia_kg_m2`).
    pub key: String,
    /// The file's value before.
    pub before: f64,
    /// The inverse-variance mean of the start-ups' estimates.
    pub value: f64,
    /// Its 1σ, widened by the scatter when the start-ups disagree beyond their own σ.
    pub sigma: f64,
    /// The start-ups' scatter about the mean in units of their σ (RMS; 1 when they agree as
    /// their noise says; `None` with one start-up).
    pub scatter: Option<f64>,
    /// Each fitted start-up's estimate and 1σ, in the order of [`DynamicsFit::startups`].
    pub per_startup: Vec<(f64, f64)>,
    /// Whether the value is written (1σ within [`MAX_WRITTEN_SIGMA_FRAC`] of it, not on its
    /// search limit), else why not.
    pub written: bool,
    pub why: String,
}

/// One healthy start-up diagnosed (Method B, health free) with the file's dynamic values and
/// with the written ones: what the fit changed where it matters, in the health a healthy unit
/// reads.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StartupDynamics {
    /// Where it came from (file, start number).
    pub source: String,
    pub before: HealthRead,
    pub after: HealthRead,
}

/// A diagnosis of a healthy start-up: its health (truth zero), verdict and normalised residual.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HealthRead {
    pub health: [f64; 6],
    pub verdict: Verdict,
    pub normalised_residual: f64,
}

impl HealthRead {
    fn of(r: &crate::diagnosis::MethodResult) -> HealthRead {
        HealthRead {
            health: r.health.to_array(),
            verdict: r.fit_quality.verdict,
            normalised_residual: r.fit_quality.normalised_residual,
        }
    }

    /// The largest |health| read, points.
    pub fn largest(&self) -> f64 {
        self.health.iter().fold(0.0, |m, h| m.max(h.abs()))
    }
}

/// What [`fit_dynamics`] found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DynamicsFit {
    pub values: Vec<DynamicValue>,
    /// The start-ups fitted, in the order given.
    pub startups: Vec<StartupDynamics>,
    /// The start-ups Method B could not fit, with the reason (source, reason).
    pub left_out: Vec<(String, String)>,
    pub wall_s: f64,
}

impl DynamicsFit {
    /// The values to write: (key, value) of each one written.
    pub fn changes(&self) -> Vec<(String, f64)> {
        self.values
            .iter()
            .filter(|v| v.written)
            .map(|v| (v.key.clone(), v.value))
            .collect()
    }
}

/// The dynamic values fitted for `recordings`: each measured temperature's lag (0.2–20 s) and
/// both inertias (a third to three times the file's).
pub fn dynamic_candidates(
    engine: &Engine,
    recordings: &[Recording],
) -> Result<Vec<FitParam>, CalibrateError> {
    let get = |key: &str| {
        engine
            .get_param(key)
            .map_err(|e| CalibrateError::Model(format!("{key}: {e}")))
    };
    let mut out = Vec::new();
    for s in LAGGED {
        if recordings.iter().any(|r| r.valid_count(s) > 0) {
            let key = format!("sensors.{}.tau_s", s.short().to_lowercase());
            get(&key)?;
            out.push(FitParam::engine_value(&key, 0.2, 20.0));
        }
    }
    for key in ["dynamics.gg_inertia_kg_m2", "dynamics.pt_inertia_kg_m2"] {
        let v = get(key)?;
        out.push(FitParam::engine_value(key, v / 3.0, 3.0 * v));
    }
    Ok(out)
}

/// Fits `candidates` to each healthy start-up of `recordings` (named by `sources`) with Method
/// B under `base` (its seed, budget and threads; the health held at zero), pools them, and
/// diagnoses each start-up (health free, `base`) with the file's values and with the written
/// ones. A start-up Method B cannot fit is left out with its reason; none fitted is an error.
pub fn fit_dynamics(
    engine: &Engine,
    recordings: &[Recording],
    sources: &[String],
    candidates: &[FitParam],
    base: &DiagnosisConfig,
) -> Result<DynamicsFit, CalibrateError> {
    let start = std::time::Instant::now();
    if recordings.is_empty() {
        return Err(CalibrateError::Data(
            "fitting the dynamics needs healthy start-ups (--startup)".into(),
        ));
    }
    let held = DiagnosisConfig {
        fixed: [true; 6],
        base: HealthParams::HEALTHY,
        extra_params: candidates.to_vec(),
        ..base.clone()
    };
    let mut estimates: Vec<Vec<(f64, f64)>> = vec![Vec::new(); candidates.len()];
    let mut used = Vec::new();
    let mut left_out = Vec::new();
    for (rec, source) in recordings.iter().zip(sources) {
        // A start-up Method B cannot fit (an odd start, a recording too short) is left out with
        // its reason; the others still inform the values.
        let both = diagnose_transient(engine, rec, base)
            .and_then(|before| Ok((before, diagnose_transient(engine, rec, &held)?)));
        let (before, fit) = match both {
            Ok(b) => b,
            Err(e) => {
                left_out.push((source.clone(), format!("Method B: {e}")));
                continue;
            }
        };
        for (k, c) in candidates.iter().enumerate() {
            let p = fit.params.iter().find(|p| p.name == c.name);
            estimates[k].push(p.map_or((f64::NAN, f64::NAN), |p| (p.value, p.sigma)));
        }
        used.push((rec, source, HealthRead::of(&before)));
    }
    if used.is_empty() {
        let why: Vec<String> = left_out.iter().map(|(s, e)| format!("{s}: {e}")).collect();
        return Err(CalibrateError::Data(format!(
            "no start-up could be fitted for the dynamics: {}",
            why.join("; ")
        )));
    }
    let mut values = Vec::new();
    let mut fitted = engine.clone();
    for (c, per) in candidates.iter().zip(estimates) {
        let before = engine
            .get_param(&c.name)
            .map_err(|e| CalibrateError::Model(e.to_string()))?;
        let v = pooled(c, before, per);
        if v.written {
            fitted
                .set_param(&v.key, v.value)
                .map_err(|e| CalibrateError::Model(format!("{}: {e}", v.key)))?;
        }
        values.push(v);
    }
    let mut startups = Vec::new();
    for (rec, source, before) in used {
        let after = diagnose_transient(&fitted, rec, base)
            .map_err(|e| CalibrateError::Data(format!("{source}: Method B: {e}")))?;
        startups.push(StartupDynamics {
            source: source.clone(),
            before,
            after: HealthRead::of(&after),
        });
    }
    Ok(DynamicsFit {
        values,
        startups,
        left_out,
        wall_s: start.elapsed().as_secs_f64(),
    })
}

/// The inverse-variance pool of one value's estimates `per` (value, 1σ), with its verdict.
fn pooled(c: &FitParam, before: f64, per: Vec<(f64, f64)>) -> DynamicValue {
    let usable: Vec<(f64, f64)> = per
        .iter()
        .copied()
        .filter(|(v, s)| v.is_finite() && s.is_finite() && *s > 0.0)
        .collect();
    let w_sum: f64 = usable.iter().map(|(_, s)| s.powi(-2)).sum();
    let value = usable.iter().map(|(v, s)| v * s.powi(-2)).sum::<f64>() / w_sum;
    let scatter = (usable.len() > 1).then(|| {
        let chi2: f64 = usable.iter().map(|(v, s)| ((v - value) / s).powi(2)).sum();
        (chi2 / (usable.len() - 1) as f64).sqrt()
    });
    let sigma = w_sum.sqrt().recip() * scatter.unwrap_or(1.0).max(1.0);
    let span = c.upper - c.lower;
    let at_limit = per
        .iter()
        .any(|(v, _)| (v - c.lower).abs() < 1e-3 * span || (c.upper - v).abs() < 1e-3 * span);
    let (written, why) = if usable.is_empty() {
        (false, "no start-up determined it".to_string())
    } else if sigma > MAX_WRITTEN_SIGMA_FRAC * value.abs() {
        (
            false,
            format!(
                "not determined: 1σ {:.0} % of the value (at most {:.0} % is written)",
                100.0 * sigma / value.abs(),
                100.0 * MAX_WRITTEN_SIGMA_FRAC
            ),
        )
    } else if at_limit {
        (
            false,
            format!(
                "a start-up's estimate ended on its search limit ({:.4}…{:.4}): the model \
                 needs something other than this value there",
                c.lower, c.upper
            ),
        )
    } else {
        (true, "determined".to_string())
    };
    DynamicValue {
        key: c.name.clone(),
        before,
        value,
        sigma,
        scatter,
        per_startup: per,
        written,
        why,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::sensors::MeasurementOptions;
    use crate::engine::simulation::run_scenario;
    use crate::engine::{Scenario, Trace};

    /// A twin whose thermocouples lag 4 s (T34) and 6 s (T4) where the file says 2.5 and 3 s,
    /// and whose GG is 30 % heavier: one healthy start-up finds all three, and the health it
    /// then reads is nearer zero than with the file's values.
    #[test]
    fn a_twins_lags_and_inertia_are_found_from_one_healthy_start_up() {
        let file = Engine::reference().expect("engine");
        let mut unit = file.clone();
        for (k, v) in [
            ("sensors.t34.tau_s", 4.0),
            ("sensors.t4.tau_s", 6.0),
            ("dynamics.gg_inertia_kg_m2", 52.0),
        ] {
            unit.set_param(k, v).expect("settable");
        }
        let (samples, _) = run_scenario(
            &unit.model(&HealthParams::HEALTHY),
            &Scenario::startup(unit.cfg()),
        )
        .expect("runs");
        let o = MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed: 5,
        };
        let rec = Trace::from_truth(&unit, &samples, Some(&o))
            .to_recording()
            .expect("recording");
        let recs = [rec];
        let candidates = dynamic_candidates(&file, &recs).expect("candidates");
        let base = DiagnosisConfig {
            threads: Some(2),
            ..DiagnosisConfig::default()
        };
        let fit = fit_dynamics(&file, &recs, &["twin".into()], &candidates, &base).expect("fit");
        for (key, truth) in [
            ("sensors.t34.tau_s", 4.0),
            ("sensors.t4.tau_s", 6.0),
            ("dynamics.gg_inertia_kg_m2", 52.0),
        ] {
            let v = fit.values.iter().find(|v| v.key == key).expect("fitted");
            eprintln!("{key}: {:.3} ± {:.3} for {truth}", v.value, v.sigma);
            assert!(
                v.written && (v.value - truth).abs() <= 0.1 * truth,
                "{key}: {v:?}"
            );
        }
        let s = &fit.startups[0];
        eprintln!("health read: {:?} → {:?}", s.before.health, s.after.health);
        assert!(
            s.after.largest() < s.before.largest() && s.after.largest() <= 0.2,
            "{s:?}"
        );
    }

    fn param() -> FitParam {
        FitParam::engine_value("sensors.t4.tau_s", 0.2, 20.0)
    }

    /// Start-ups that agree within their σ pool to the weighted mean with σ/√n; ones that
    /// disagree widen it by their scatter; a value on its limit or too uncertain is not written.
    #[test]
    fn estimates_pool_by_their_variances_and_scatter_widens_them() {
        let agree = pooled(&param(), 3.0, vec![(4.9, 0.2), (5.1, 0.2)]);
        assert!((agree.value - 5.0).abs() < 1e-12);
        assert!((agree.sigma - 0.2 / 2f64.sqrt()).abs() < 1e-12, "{agree:?}");
        assert!(agree.written && agree.scatter.expect("two") < 1.0);
        let weighted = pooled(&param(), 3.0, vec![(4.0, 0.1), (6.0, 0.3)]);
        assert!((weighted.value - 4.2).abs() < 1e-9, "{weighted:?}");
        let apart = pooled(&param(), 3.0, vec![(3.0, 0.1), (7.0, 0.1)]);
        assert!(apart.scatter.expect("two") > 20.0);
        assert!(apart.sigma > 1.9, "widened by the scatter: {apart:?}");
        assert!(!apart.written, "{apart:?}");
        let on_limit = pooled(&param(), 3.0, vec![(20.0, 0.5), (19.0, 0.5)]);
        assert!(!on_limit.written && on_limit.why.contains("limit"));
    }
}
