//! What an adapted model's unknown compressor shape off the healthy line adds to a steady
//! read's σ (`[adaptation.offline_shape]`, see `engine::config::offline_shape` for why and for
//! the defaults).
//!
//! How: at the fitted health, each point's compressor pressure ratio is compared with the
//! healthy model's at the same GG speed and inputs (the healthy line at that corrected speed):
//! `Δ = ln PR − ln PR_healthy`. A speed line whose efficiency slope differs by `s` changes the
//! point's efficiency by `s·Δ` of itself, as a compressor-efficiency degradation of `−100 s Δ`
//! points at that point alone would; its flow slope likewise, as flow degradation. The model is
//! solved with those per-point changes at 1σ of each slope, and the residuals' change is one
//! column of the σ the inputs' noise also feeds ([`SteadyProblem::input_draws`]): the
//! linearised re-fit of each column is what that slope's error does to every parameter.
//! Points on the healthy line (a healthy unit) get nothing; the column grows with how far
//! degradation has moved the unit off it, whichever component moved it.
//!
//! What it must not do: change the fit (only its σ), I/O, or touch the model's own maps (a
//! file without adaptation curves has no term).

use super::SteadyProblem;
use crate::engine::config::EngineConfig;
use crate::engine::steady::{solve, Demand, SteadyInputs};
use crate::engine::trace::Values;
use crate::health::HealthParams;

impl SteadyProblem {
    /// The residuals' change at `x` for 1σ of each off-line slope the file states (efficiency,
    /// then flow; residual-length, whitened like the objective's). Empty when the file states
    /// none or a solve fails (the σ then goes without this part rather than fail).
    pub(super) fn offline_shape_columns(&self, x: &[f64]) -> Vec<Vec<f64>> {
        let shape = match self.engine.cfg().adaptation.as_ref() {
            Some(a) => a.offline_shape(),
            None => return Vec::new(),
        };
        if !shape.any() {
            return Vec::new();
        }
        let Ok(at) = self.points_at(x) else {
            return Vec::new();
        };
        let Ok(base) = self.solve_points(&at, |_| at.health) else {
            return Vec::new();
        };
        // Each point's log pressure ratio above the healthy line at its GG speed.
        let mut deltas = Vec::with_capacity(base.len());
        for ((solved, _), (inputs, g)) in base.iter().zip(at.inputs.iter().zip(&self.guesses)) {
            let line_inputs = SteadyInputs {
                demand: Demand::N1Rpm(solved.n1_rpm),
                ..*inputs
            };
            let m0 = at
                .engine
                .model_at(&HealthParams::HEALTHY, inputs.t_amb_k, inputs.p_amb_kpa);
            let Ok(line) = solve(&m0, &line_inputs, Some(g)) else {
                return Vec::new();
            };
            let delta = (solved.pressure_ratio / line.pressure_ratio).ln();
            if !delta.is_finite() {
                return Vec::new();
            }
            deltas.push(delta);
        }
        let rows: Vec<Values> = base.into_iter().map(|(_, v)| v).collect();
        let mut r0 = Vec::new();
        self.objective.residuals(&rows, &mut r0);
        let mut columns = Vec::new();
        let slopes = [
            (shape.efficiency_slope_sigma, 1usize),
            (shape.flow_slope_sigma, 0usize),
        ];
        for (sigma, index) in slopes {
            if sigma <= 0.0 {
                continue;
            }
            // A slope s raises the point's efficiency (flow) by s·Δ of itself: a degradation
            // of −100 s Δ points there.
            let per_point = |k: usize| {
                let mut a = at.health.to_array();
                a[index] -= 100.0 * sigma * deltas[k];
                HealthParams::from_array(a)
            };
            let Ok(solved) = self.solve_points(&at, per_point) else {
                return Vec::new();
            };
            let rows: Vec<Values> = solved.into_iter().map(|(_, v)| v).collect();
            let mut r = Vec::new();
            self.objective.residuals(&rows, &mut r);
            if r.len() != r0.len() || r.iter().any(|v| !v.is_finite()) {
                return Vec::new();
            }
            columns.push(r.iter().zip(&r0).map(|(a, b)| a - b).collect());
        }
        columns
    }
}

/// What [`SteadyProblem`] adds to the σ for the compressor's shape off the healthy line, for a
/// report's assumptions; `None` when the file has no such term.
pub(crate) fn offline_shape_note(cfg: &EngineConfig) -> Option<String> {
    let shape = cfg.adaptation.as_ref()?.offline_shape();
    shape.any().then(|| {
        format!(
            "the borrowed compressor map's slopes along its speed lines, which no healthy \
             baseline shows ([adaptation.offline_shape], 1σ of d ln η / d ln PR {:.2} and of \
             d ln W / d ln PR {:.2}): what they do to the read at each point's distance from \
             the healthy line added to the σ (none on the line; it grows as degradation moves \
             the compressor off it)",
            shape.efficiency_slope_sigma, shape.flow_slope_sigma
        )
    })
}
