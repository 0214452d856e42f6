//! The noise of a steady point's *inputs*: the fuel flow (or other demand), T1, n2 and — where
//! it gives the ambient pressure — P1 that the steady solve is given as measured. Their σ
//! ([`InputSigma`]) and what each moves the point's compared values by ([`with_input_noise`]),
//! from which the objective takes the covariance of the point's residuals, and what a fit's
//! residuals amount to under that noise ([`SteadyProblem::level_under_input_noise`]). Pure:
//! model solves only, no I/O; it does not fit anything.

use super::{steady_reading, SteadyData, SteadyProblem};
use crate::engine::config::SensorsConfig;
use crate::engine::sensors::noise_sigma;
use crate::engine::steady::{demand_value, with_value, Demand, SteadyInputs, SteadyPoint};
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::signals::Signal;
use nalgebra::{DMatrix, DVector};

/// 1σ of what a steady point's solve is given as measured, in the inputs' units; 0 where the
/// value is assumed (the engine file's ambient) or has no instrument noise configured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InputSigma {
    pub t_amb_k: f64,
    pub p_amb_kpa: f64,
    pub n2_rpm: f64,
    /// Of the demand, in its unit (fuel kg/s, power MW or GG speed rpm).
    pub demand: f64,
}

impl InputSigma {
    /// The instruments' σ (`[sensors]`) at `inputs`, divided by √`samples` (a window mean of
    /// that many readings; 1 for one reading). `t1_measured`: the ambient temperature is a T1
    /// reading (else the engine file's, exact). The ambient pressure's σ is the caller's.
    pub fn of(
        sensors: &SensorsConfig,
        inputs: &SteadyInputs,
        t1_measured: bool,
        samples: usize,
    ) -> InputSigma {
        let k = (samples.max(1) as f64).sqrt();
        let (signal, value) = match inputs.demand {
            Demand::FuelKgS(f) => (Signal::FuelFlow, f),
            Demand::PowerMw(p) => (Signal::Power, p),
            Demand::N1Rpm(n) => (Signal::N1, n),
        };
        InputSigma {
            t_amb_k: if t1_measured {
                noise_sigma(sensors, Signal::T1, inputs.t_amb_k) / k
            } else {
                0.0
            },
            p_amb_kpa: 0.0,
            n2_rpm: noise_sigma(sensors, Signal::N2, inputs.n2_rpm) / k,
            demand: noise_sigma(sensors, signal, value) / k,
        }
    }

    /// The inputs moved by `d` × σ in input `k` (0 T1, 1 ambient pressure, 2 n2, 3 demand), with
    /// that σ; `None` for `k` > 3.
    fn moved(&self, inputs: &SteadyInputs, k: usize, d: f64) -> Option<(SteadyInputs, f64)> {
        let mut out = *inputs;
        let sd = match k {
            0 => {
                out.t_amb_k += d * self.t_amb_k;
                self.t_amb_k
            }
            1 => {
                out.p_amb_kpa += d * self.p_amb_kpa;
                self.p_amb_kpa
            }
            2 => {
                out.n2_rpm += d * self.n2_rpm;
                self.n2_rpm
            }
            3 => {
                out.demand = with_value(out.demand, demand_value(out.demand) + d * self.demand);
                self.demand
            }
            _ => return None,
        };
        Some((out, sd))
    }
}

/// Inputs of a steady point whose noise is carried ([`InputSigma`]'s fields, in this order).
pub const INPUTS: usize = 4;

/// `data` with what the noise of its measured inputs does to each compared value
/// ([`SteadyData::input_response`]): the model is driven by the fuel flow, T1 and n2 a row
/// states, and those readings carry their instruments' noise as every compared one does. A
/// fuel meter's 0.5 % moves the model's GG speed by about a tachometer's σ on the reference
/// engine at part load, by several times it where the running line is flatter (md22: 1.5 % of
/// fuel per 100 rpm), and every other value with it — all of one point's values in one
/// direction. Compared at the instruments' σ alone, the reference engine's own noisy snapshots
/// were fitted `poor` (`tests/snapshot_input_noise.rs`) and the health's σ did not cover its
/// error. Each input is moved by its σ (the other way if the model has no point there) and the
/// compared values' changes at `base`'s health are its column; the fit then runs under the
/// covariance those columns give each point's residuals (generalised least squares,
/// [`crate::diagnosis::objective::Objective::with_shared_errors`]). Unchanged when no input has
/// a σ or the point does not solve.
pub(crate) fn with_input_noise(
    engine: &Engine,
    base: &HealthParams,
    mut data: SteadyData,
) -> SteadyData {
    let solved = |inputs: &SteadyInputs, start: Option<&SteadyPoint>| {
        let m = engine.model_at(base, inputs.t_amb_k, inputs.p_amb_kpa);
        let at = SteadyData {
            inputs: *inputs,
            ..data.clone()
        };
        let p = at.solve_from(&m, start).ok()?;
        let v: Vec<f64> = data
            .outputs
            .iter()
            .map(|(s, _, _)| steady_reading(&m, &p, *s))
            .collect();
        Some((p, v))
    };
    let Some((p0, v0)) = solved(&data.inputs, None) else {
        return data;
    };
    let mut response = vec![[0.0; INPUTS]; data.outputs.len()];
    let mut any = false;
    for k in 0..INPUTS {
        for d in [1.0, -1.0] {
            let Some((inputs, sd)) = data.input_sd.moved(&data.inputs, k, d) else {
                break;
            };
            if !(sd > 0.0 && sd.is_finite()) {
                break;
            }
            if let Some((_, v)) = solved(&inputs, Some(&p0)) {
                for ((col, a), b) in response.iter_mut().zip(&v).zip(&v0) {
                    let dv = d * (a - b);
                    if dv.is_finite() {
                        col[k] = dv;
                        any = true;
                    }
                }
                break;
            }
        }
    }
    if any {
        data.input_response = response;
    }
    data
}

/// What [`with_input_noise`] adds, for a report's assumptions.
pub(crate) fn input_noise_note() -> String {
    "fitted under the covariance the noise of the measured inputs (fuel flow, T1, n2; P1 where \
     it gives the ambient pressure; [sensors]) gives each point's compared values"
        .into()
}

/// What [`InputNoise::SigmaOnly`](super::InputNoise::SigmaOnly) adds, for a report's
/// assumptions.
pub(crate) fn input_noise_sigma_note() -> String {
    "inputs (fuel flow, T1, n2; P1 where it gives the ambient pressure) taken as given in the \
     fit; what their instruments' noise ([sensors]) moves the read by is in its σ"
        .into()
}

/// `rᵀ (I + C Cᵀ)⁻¹ r`: the sum of squares of residuals `r` (in σ) judged under shared errors
/// whose 1σ columns are `C` (Woodbury: one k×k solve for k columns); `None` where `I + CᵀC`
/// does not factor or the result is not a finite non-negative number.
pub(crate) fn squares_under_columns(c: &DMatrix<f64>, r: &DVector<f64>) -> Option<f64> {
    let ctr = c.transpose() * r;
    let inner = DMatrix::<f64>::identity(c.ncols(), c.ncols()) + c.transpose() * c;
    let solved = inner.cholesky()?.solve(&ctr);
    let q = r.dot(r) - ctr.dot(&solved);
    (q.is_finite() && q >= 0.0).then_some(q)
}

impl SteadyProblem {
    /// The normalised residual (mean square, as the fit's verdict reads it) at `x` judged under
    /// the noise of the inputs taken as given ([`super::InputNoise::SigmaOnly`]):
    /// `rᵀ (I + C Cᵀ)⁻¹ r / m` over their 1σ columns `C` (Woodbury: one k×k solve). `None` without such inputs or where
    /// the model cannot be evaluated. What `--noisy-inputs` would judge, linearised: a verdict
    /// whose residuals this explains is the inputs' noise (spot readings rather than averages),
    /// not the model's misfit; a meter's bias, common to every row, is not explained by it.
    pub fn level_under_input_noise(&self, x: &[f64]) -> Option<f64> {
        if self.input_columns.is_empty() {
            return None;
        }
        let r = self.objective_residuals(x)?;
        let m = r.len();
        let k = self.input_columns.len();
        if m == 0 || self.input_columns.iter().any(|c| c.len() != m) {
            return None;
        }
        let c = DMatrix::from_fn(m, k, |i, j| self.input_columns[j][i]);
        squares_under_columns(&c, &DVector::from_column_slice(&r)).map(|q| q / m as f64)
    }
}
