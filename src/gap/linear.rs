//! The linearised screen of instrument candidates (a score test): how far each candidate would
//! shrink the baseline's residual if the model were linear around the baseline's fit, from one
//! finite-difference Jacobian of the residuals — the health parameters' columns once, and one
//! column per candidate parameter from its neutral value (no lag, no offset).
//!
//! An instrument effect acts on one channel only and is nearly linear in its parameter (an
//! offset exactly, a lag to first order), so the prediction ranks the per-channel candidates at
//! a cost of one model run each, where a screening fit takes hundreds; the gap analysis then
//! fits only the most promising of them. Engine effects are never screened this way: they are
//! nonlinear in their parameters and always fitted.
//!
//! Pure: no I/O; the model runs are serial on the calling thread.

use crate::diagnosis::transient::TransientProblem;
use crate::diagnosis::{DiagnosisConfig, DiagnosisError, FitParam, MethodResult};
use crate::engine::Engine;
use crate::recording::Recording;
use nalgebra::{DMatrix, DVector};

/// Finite-difference step of a health parameter, % (points): well above the integrator's
/// noise, small against the −3 … +10 % box.
const HEALTH_STEP: f64 = 0.05;
/// Secant step of a candidate's parameter from its neutral value, as a fraction of its range:
/// large enough to reach the magnitudes a plant shows (a lag of several seconds), where a
/// derivative at zero would understate a lag's effect.
const PARAM_STEP_FRACTION: f64 = 0.1;

/// The baseline's residual and its Jacobian columns around the baseline's fit: the health (and
/// ambient-pressure) columns once, any further parameter's column on demand. Shared by the
/// linear screen and the alias analysis ([`super::alias`]).
pub(super) struct Linearised {
    problem: TransientProblem,
    x0: Vec<f64>,
    /// Residual at the baseline's fit with every further parameter neutral.
    pub r0: DVector<f64>,
    /// Columns of the baseline's own parameters (health, ambient), in `base.params` order.
    pub base_cols: Vec<DVector<f64>>,
    /// Names of those parameters.
    pub base_names: Vec<String>,
    /// Index of the first further parameter in the model's vector.
    first_extra: usize,
}

impl Linearised {
    /// Linearises `rec`'s baseline fit `base` under `cfg`, with `extra` parameters appended at
    /// their neutral values (0 clamped into their bounds). Errors when the baseline cannot be
    /// re-run or one of its parameters cannot be perturbed.
    pub(super) fn new(
        engine: &Engine,
        rec: &Recording,
        cfg: &DiagnosisConfig,
        base: &MethodResult,
        extra: &[FitParam],
    ) -> Result<Linearised, DiagnosisError> {
        let lin_cfg = DiagnosisConfig {
            extra_params: extra.to_vec(),
            base: base.health,
            threads: Some(1),
            ..cfg.clone()
        };
        let problem = TransientProblem::new(engine, rec, &lin_cfg)?;
        // The baseline's fitted parameters (health, ambient pressure), then every further
        // parameter at its neutral value.
        let fitted: Vec<f64> = base.params.iter().map(|p| p.value).collect();
        let neutral = extra.iter().map(|p| 0.0_f64.clamp(p.lower, p.upper));
        let x0: Vec<f64> = fitted.iter().copied().chain(neutral).collect();
        let mut lin = Linearised {
            problem,
            x0,
            r0: DVector::zeros(0),
            base_cols: Vec::new(),
            base_names: base.params.iter().map(|p| p.name.clone()).collect(),
            first_extra: fitted.len(),
        };
        lin.r0 = lin.residuals(&lin.x0).ok_or_else(|| {
            DiagnosisError::Data("the baseline's fit cannot be re-run for the linearisation".into())
        })?;
        for (j, p) in base.params.iter().enumerate() {
            let step = if p.name.starts_with("D_") {
                HEALTH_STEP
            } else {
                1e-3 * p.value.abs().max(1.0)
            };
            let col = lin
                .column_at(j, step)
                .or_else(|| lin.column_at(j, -step))
                .ok_or_else(|| {
                    DiagnosisError::Data(format!(
                        "the linearisation could not perturb {} from the baseline",
                        p.name
                    ))
                })?;
            lin.base_cols.push(col);
        }
        Ok(lin)
    }

    fn residuals(&self, x: &[f64]) -> Option<DVector<f64>> {
        let model = self.problem.simulate(x).ok()?;
        let mut r = Vec::new();
        self.problem.objective().residuals(&model, &mut r);
        r.iter()
            .all(|v| v.is_finite())
            .then(|| DVector::from_vec(r))
    }

    fn column_at(&self, j: usize, step: f64) -> Option<DVector<f64>> {
        let mut x = self.x0.clone();
        x[j] += step;
        self.residuals(&x).map(|r| (r - &self.r0) / step)
    }

    /// The secant column of further parameter `i` (in `extra` order) over `step` from neutral:
    /// d(residual)/d(parameter). `None` when the perturbed run fails.
    pub(super) fn extra_column(&self, i: usize, step: f64) -> Option<DVector<f64>> {
        self.column_at(self.first_extra + i, step)
    }

    /// The baseline's own parameters (in `base_names` order) fitted again from the baseline
    /// with further parameter `i` held at `value` (every further parameter neutral for
    /// `None`): chord (simplified Gauss–Newton) iterations with the baseline's Jacobian
    /// columns, each one model run, kept while the residual falls. `None` when the first run
    /// fails.
    ///
    /// An instrument's shift is the difference of two such re-fits, with the instrument's
    /// error and without: the baseline itself need not be the optimum of its own residual (a
    /// parameter on its limit, a fit stopped by its budget, a drift the model cannot follow),
    /// and a re-fit from it would otherwise also finish that fit and count it as the shift.
    ///
    /// Why not the projection of one column: the response of a start-up to the health is not
    /// linear over the points an instrument error moves it (a compressor column's size changes
    /// by a sixth between −0.5 and +0.5 points), so a derivative at the baseline misstates the
    /// shift by up to a third, and one taken over a small step also carries the integrator's
    /// error. The chord iterations converge on the re-fitted parameters themselves, with any
    /// fair Jacobian.
    pub(super) fn refit(&self, extra: Option<(usize, f64)>) -> Option<Vec<f64>> {
        let nb = self.first_extra;
        let mut x = self.x0.clone();
        if let Some((i, value)) = extra {
            x[self.first_extra + i] = value;
        }
        let mut r = self.residuals(&x)?;
        let mut best = (r.norm_squared(), x.clone());
        for _ in 0..REFIT_ITERATIONS {
            let (coef, _) = project(&self.base_cols, &r);
            let mut next = x.clone();
            for (k, c) in coef.iter().enumerate().take(nb) {
                next[k] -= c;
            }
            let Some(rn) = self.residuals(&next) else {
                break;
            };
            let ssr = rn.norm_squared();
            if ssr >= best.0 {
                break;
            }
            best = (ssr, next.clone());
            x = next;
            r = rn;
        }
        Some(best.1[..nb].to_vec())
    }
}

/// Chord iterations of [`Linearised::refit`]. A chord iteration shrinks its error by about
/// the Jacobian's relative error per step (a sixth or less here), so four leave a fraction of a
/// percent of the shift; the re-fit is not bounded by the health limits (it asks what the data
/// say, not what the box allows).
const REFIT_ITERATIONS: usize = 4;

/// Least-squares coefficients of `target` on `cols` and the part of `target` they leave
/// (columns scaled to unit norm internally, so the SVD's cut-off is relative to each one).
pub(super) fn project(cols: &[DVector<f64>], target: &DVector<f64>) -> (Vec<f64>, DVector<f64>) {
    if cols.is_empty() {
        return (Vec::new(), target.clone());
    }
    let norms: Vec<f64> = cols.iter().map(|c| c.norm().max(1e-300)).collect();
    let scaled: Vec<DVector<f64>> = cols.iter().zip(&norms).map(|(c, n)| c / *n).collect();
    let a = DMatrix::from_columns(&scaled);
    let Ok(delta) = a.clone().svd(true, true).solve(target, 1e-10) else {
        return (vec![0.0; cols.len()], target.clone());
    };
    let left = target - &a * &delta;
    let coef = delta.iter().zip(&norms).map(|(d, n)| d / n).collect();
    (coef, left)
}

/// Predicted shrinkage (fraction of the baseline's SSR, 0 … 1) of each candidate in
/// `candidates` (instance name and its fit parameters), in order, for the baseline fit `base`
/// of `rec` under `cfg`. A candidate whose perturbed run fails gets `None` (fit it to find
/// out). Errors only when the baseline itself cannot be re-run.
pub(crate) fn predicted_shrinkage(
    engine: &Engine,
    rec: &Recording,
    cfg: &DiagnosisConfig,
    base: &MethodResult,
    candidates: &[(String, Vec<FitParam>)],
) -> Result<Vec<Option<f64>>, DiagnosisError> {
    let extra: Vec<FitParam> = candidates
        .iter()
        .flat_map(|(_, p)| p.iter().cloned())
        .collect();
    let lin = Linearised::new(engine, rec, cfg, base, &extra)?;
    let ssr0 = lin.r0.norm_squared().max(1e-300);
    let reduction = |cols: &[DVector<f64>]| -> f64 {
        if cols.is_empty() {
            return 0.0;
        }
        ssr0 - project(cols, &lin.r0).1.norm_squared()
    };
    let base_reduction = reduction(&lin.base_cols);
    let mut offset = 0;
    Ok(candidates
        .iter()
        .map(|(_, params)| {
            let mut cols = lin.base_cols.clone();
            let mut ok = true;
            for (i, p) in params.iter().enumerate() {
                let step = PARAM_STEP_FRACTION * (p.upper - p.lower);
                match lin.extra_column(offset + i, step) {
                    Some(c) => cols.push(c),
                    None => ok = false,
                }
            }
            offset += params.len();
            ok.then(|| ((reduction(&cols) - base_reduction) / ssr0).clamp(0.0, 1.0))
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnosis::bench::synthetic_startup;
    use crate::diagnosis::transient::diagnose_transient;
    use crate::health::HealthParams;
    use crate::signals::Signal;

    /// A P2 transmitter reading 1 % of its peak high: the linear screen ranks the P2 offset
    /// first and predicts most of the gap, close to what fitting the offset achieves; an offset
    /// on a channel that reads true, and a lag on T34, predict almost nothing.
    #[test]
    fn an_offset_on_one_channel_leads_the_linear_screen() {
        let engine = Engine::reference().expect("engine");
        let truth = HealthParams {
            D_GC: 2.0,
            D_EC: 1.0,
            D_GT: -0.5,
            D_ET: 1.0,
            D_GP: 0.0,
            D_EP: 0.5,
        };
        let mut rec = synthetic_startup(&engine, &truth, 3, true).expect("start-up");
        let peak = rec
            .series(Signal::P2)
            .into_iter()
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        for k in 0..rec.len() {
            if let Some(v) = rec.value(k, Signal::P2) {
                rec.set(k, Signal::P2, v + 0.01 * peak).expect("set");
            }
        }
        let cfg = DiagnosisConfig {
            base: truth,
            max_model_runs: 120,
            lm_runs: 80,
            threads: Some(2),
            ..DiagnosisConfig::default()
        };
        let base = diagnose_transient(&engine, &rec, &cfg).expect("baseline");
        let names = ["sensor_bias:p2_kpa", "sensor_bias:t4_k", "sensor_lag:t34_k"];
        let candidates: Vec<(String, Vec<FitParam>)> = names
            .iter()
            .map(|n| (n.to_string(), crate::gap::candidates::fit_params(n, &rec)))
            .collect();
        let predicted: Vec<f64> = predicted_shrinkage(&engine, &rec, &cfg, &base, &candidates)
            .expect("linear screen")
            .into_iter()
            .map(|p| p.expect("every candidate predicted"))
            .collect();
        assert!(predicted[0] > 0.5, "P2 offset predicted {predicted:?}");
        assert!(
            predicted[1] < 0.05 && predicted[2] < 0.05,
            "channels that read true predicted {predicted:?}"
        );
        // The offset is linear in the readings: fitting it shrinks the gap as predicted.
        let with_offset = DiagnosisConfig {
            extra_params: candidates[0].1.clone(),
            base: base.health,
            ..cfg.clone()
        };
        let fitted = diagnose_transient(&engine, &rec, &with_offset).expect("refit");
        let actual = 1.0 - fitted.ssr / base.ssr;
        assert!(
            (actual - predicted[0]).abs() < 0.1,
            "fitted shrinkage {actual:.3} against predicted {:.3}",
            predicted[0]
        );
    }
}
