//! The calibration as a least-squares problem: healthy steady snapshots against the healthy
//! model whose design parameters are the unknowns.
//!
//! What it is for: residuals `(model − measured) / σ` per compared signal and operating point
//! (σ the instrument's one-sample noise at the reading, as the snapshot diagnosis uses), for
//! the identifiability analysis and Levenberg–Marquardt. Each evaluation sets the candidate
//! values on a copy of the engine (one design calibration) and solves every point from the
//! guess engine's solution, so evaluations are independent and order-free. What it must not
//! do: I/O, or fit health (health is 0 by definition of a baseline).

use super::candidates::Candidate;
use super::CalibrateError;
use crate::diagnosis::snapshot::{steady_data, Snapshot};
use crate::diagnosis::steady::{steady_value, SteadyData};
use crate::engine::steady::{solve, SteadyPoint};
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::optim::{Bounds, Problem, ResidualProblem};
use crate::signals::Signal;
use std::sync::atomic::{AtomicUsize, Ordering};

/// One healthy operating point of the calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationPoint {
    /// File line of the snapshot (of a start-up window: of its first sample).
    pub line: u64,
    /// Where the point comes from: the snapshot's group (a start-up window names its file and
    /// times).
    pub source: String,
    pub data: SteadyData,
}

/// Healthy snapshots against the model with `candidates` free (the others at the engine's
/// values).
pub struct CalibrationProblem {
    engine: Engine,
    points: Vec<CalibrationPoint>,
    /// The guess engine's solution per point: every solve starts there.
    starts: Vec<SteadyPoint>,
    candidates: Vec<Candidate>,
    bounds: Bounds,
    runs: AtomicUsize,
}

/// Points prepared from snapshot rows: the rows whose healthy solve failed (by line), and how
/// each row's ambient pressure was obtained.
#[derive(Debug, Clone, PartialEq)]
pub struct PreparedPoints {
    pub points: Vec<CalibrationPoint>,
    pub dropped_lines: Vec<u64>,
    pub assumptions: Vec<String>,
    /// Whether some row's ambient pressure came from P1 through the model's inlet loss (which
    /// the data then cannot inform).
    pub ambient_from_p1: bool,
}

/// Turns snapshot rows into operating points on the guess engine (the snapshot diagnosis's
/// own per-row preparation).
pub fn prepare(engine: &Engine, rows: &[Snapshot]) -> PreparedPoints {
    let mut out = PreparedPoints {
        points: Vec::new(),
        dropped_lines: Vec::new(),
        assumptions: Vec::new(),
        ambient_from_p1: false,
    };
    for (i, r) in rows.iter().enumerate() {
        if r.p_amb_kpa.is_none() && r.values.iter().any(|(s, _)| *s == Signal::P1) {
            out.ambient_from_p1 = true;
        }
        match steady_data(engine, &HealthParams::HEALTHY, r, i, &mut out.assumptions) {
            Some(data) => out.points.push(CalibrationPoint {
                line: r.line,
                source: r.group.clone(),
                data,
            }),
            None => out.dropped_lines.push(r.line),
        }
    }
    out
}

impl CalibrationProblem {
    /// The problem over `points` with `candidates` free. Needs more compared values than
    /// candidates, and every candidate's guess inside its interval.
    pub fn new(
        engine: &Engine,
        points: Vec<CalibrationPoint>,
        candidates: Vec<Candidate>,
    ) -> Result<CalibrationProblem, CalibrateError> {
        let mut starts = Vec::with_capacity(points.len());
        for p in &points {
            let m = engine.model_at(
                &HealthParams::HEALTHY,
                p.data.inputs.t_amb_k,
                p.data.inputs.p_amb_kpa,
            );
            let s = solve(&m, &p.data.inputs, None).map_err(|e| {
                CalibrateError::Data(format!("line {}: healthy steady solve: {e}", p.line))
            })?;
            starts.push(s);
        }
        let m: usize = points.iter().map(|p| p.data.outputs.len()).sum();
        if m <= candidates.len() {
            return Err(CalibrateError::Data(format!(
                "{} snapshot(s) give {m} compared values for {} candidate parameters: more \
                 operating points are needed",
                points.len(),
                candidates.len()
            )));
        }
        let bounds = Bounds::new(
            candidates.iter().map(|c| c.lower).collect(),
            candidates.iter().map(|c| c.upper).collect(),
        )
        .map_err(|e| CalibrateError::Data(format!("candidate intervals: {e}")))?;
        Ok(CalibrationProblem {
            engine: engine.clone(),
            points,
            starts,
            candidates,
            bounds,
            runs: AtomicUsize::new(0),
        })
    }

    /// The candidates, in the order of the parameter vector.
    pub fn candidates(&self) -> &[Candidate] {
        &self.candidates
    }

    /// The operating points.
    pub fn points(&self) -> &[CalibrationPoint] {
        &self.points
    }

    /// The candidates' guesses (the start of the fit).
    pub fn guesses(&self) -> Vec<f64> {
        self.candidates.iter().map(|c| c.guess).collect()
    }

    /// Model evaluations so far.
    pub fn runs(&self) -> usize {
        self.runs.load(Ordering::Relaxed)
    }

    /// The engine with the candidates at `x`.
    pub fn engine_at(&self, x: &[f64]) -> Result<Engine, CalibrateError> {
        let values: Vec<(String, f64)> = self
            .candidates
            .iter()
            .zip(x)
            .map(|(c, v)| (c.key.clone(), *v))
            .collect();
        self.engine
            .with_params(&values)
            .map_err(|e| CalibrateError::Model(e.to_string()))
    }

    /// The compared signal of every residual, point-major (the layout of [`Self::residuals_at`]).
    pub fn layout(&self) -> Vec<(usize, Signal)> {
        self.points
            .iter()
            .enumerate()
            .flat_map(|(i, p)| p.data.outputs.iter().map(move |(s, _, _)| (i, *s)))
            .collect()
    }

    /// Residuals `(model − measured) / σ` at `x`, point-major; an error names the point whose
    /// solve failed.
    pub fn residuals_at(&self, x: &[f64]) -> Result<Vec<f64>, CalibrateError> {
        self.runs.fetch_add(1, Ordering::Relaxed);
        let engine = self.engine_at(x)?;
        let mut out = Vec::new();
        for (p, start) in self.points.iter().zip(&self.starts) {
            let inp = &p.data.inputs;
            let m = engine.model_at(&HealthParams::HEALTHY, inp.t_amb_k, inp.p_amb_kpa);
            let sp = solve(&m, inp, Some(start)).map_err(|e| {
                CalibrateError::Model(format!("line {}: steady solve: {e}", p.line))
            })?;
            for &(s, v, sd) in &p.data.outputs {
                out.push((steady_value(&sp, s) - v) / sd);
            }
        }
        Ok(out)
    }
}

impl Problem for CalibrationProblem {
    fn dim(&self) -> usize {
        self.candidates.len()
    }
    fn bounds(&self) -> &Bounds {
        &self.bounds
    }
    fn cost(&self, x: &[f64]) -> f64 {
        match self.residuals_at(x) {
            Ok(r) => r.iter().map(|v| v * v).sum(),
            Err(_) => f64::INFINITY,
        }
    }
}

impl ResidualProblem for CalibrationProblem {
    fn residuals(&self, x: &[f64], out: &mut Vec<f64>) {
        out.clear();
        match self.residuals_at(x) {
            Ok(r) => out.extend(r),
            // A failed solve: the right length of NaN marks the evaluation as failed.
            Err(_) => out.extend(std::iter::repeat_n(f64::NAN, self.layout().len())),
        }
    }
}
