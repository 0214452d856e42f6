//! The calibration as a least-squares problem: steady snapshots against the model, at each
//! point's known health, whose design parameters are the unknowns.
//!
//! What it is for: residuals `(model − measured) / σ` per compared signal and operating point
//! (σ the instrument's one-sample noise at the reading, as the snapshot diagnosis uses), for
//! the identifiability analysis and Levenberg–Marquardt. Each evaluation sets the candidate
//! values on a copy of the engine (one design calibration) and solves every point from the
//! guess engine's solution, so evaluations are independent and order-free.
//!
//! A mechanical drive (`[load] mode = "load_law"`) adds one residual per point that measured
//! its power (or coupling torque): the PT speed the load law gives for that power against the
//! measured PT speed, reported as `n2_rpm` (the law's only trace in steady data, where the PT
//! speed is an input of the point). Its σ combines the speed's noise with the power's, carried
//! through the law at the guessed exponent. It informs `load.exponent` and, with it, the
//! design power the law is referred to.
//!
//! Pressure readings at rest ([`RestReading`]) add one residual each: the instrument's offset
//! (its `sensor_bias` effect; 0 without one) against its excess over P1 at rest.
//!
//! [`CalibrationProblem::on_gg_speed`] poses the same problem on each point's measured GG
//! speed (its fuel flow compared instead): the adaptation's second start, where the fuel-given
//! residuals are too curved to converge.
//!
//! Each point runs at the health it carries: zero on a baseline (by definition), the fouling
//! `calibrate::prewash` found for a row from before a wash.
//!
//! What it must not do: I/O, or fit health (a point's health is given to it).

use super::candidates::{offset_key, Candidate};
use super::startup::RestReading;
use super::CalibrateError;
use crate::diagnosis::snapshot::{steady_data, DroppedRow, Snapshot};
use crate::diagnosis::steady::{steady_reading, SteadyData};
use crate::engine::design::DesignCycles;
use crate::engine::load::PtLoad;
use crate::engine::sensors::noise_sigma;
use crate::engine::steady::{Demand, SteadyPoint};
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::optim::{Bounds, Problem, ResidualProblem};
use crate::signals::Signal;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// One operating point of the calibration (healthy, or from before a wash at its fouling).
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationPoint {
    /// File line of the snapshot (of a start-up window: of its first sample).
    pub line: u64,
    /// Where the point comes from: the snapshot's group (a start-up window names its file and
    /// times).
    pub source: String,
    pub data: SteadyData,
    /// The health the point was taken at: healthy on a baseline; the compressor fouling a
    /// pre-wash group carries ([`super::prewash`]), which the model is run at so the point
    /// informs the curves off the healthy operating line.
    pub health: HealthParams,
    /// With spot readings (`calibrate --noisy-inputs`), the whitening `W = L⁻¹` of the point's
    /// compared values under its inputs' noise (`L Lᵀ = I + C Cᵀ`, `C` the 1σ columns of what
    /// each input moves them by): the fit then minimises `rᵀ (I + C Cᵀ)⁻¹ r` per point, the
    /// measure its verdict reads as `level_under_input_noise`. `None`: inputs taken as exact.
    pub whiten: Option<Arc<nalgebra::DMatrix<f64>>>,
}

impl CalibrationPoint {
    /// The point's steady solution on `engine` at its own inputs and health (healthy on a
    /// baseline).
    pub fn solved_on(&self, engine: &Engine) -> Result<SteadyPoint, CalibrateError> {
        let inp = &self.data.inputs;
        let m = engine.model_at(&self.health, inp.t_amb_k, inp.p_amb_kpa);
        self.data
            .solve_on(&m)
            .map_err(|e| CalibrateError::Model(format!("line {}: steady solve: {e}", self.line)))
    }
}

/// A point's measured shaft power for the load-law residual: power W, and σ of the speed
/// residual, rpm.
#[derive(Debug, Clone, Copy, PartialEq)]
struct LawPoint {
    power_w: f64,
    sigma_rpm: f64,
}

/// A smoothness row of an adaptation curve: `Σ coef·x[index] / scale`, a residual the
/// Levenberg–Marquardt fit sees beside the data (not reported among the signals' residuals).
#[derive(Debug, Clone, PartialEq)]
pub struct SmoothnessRow {
    pub terms: Vec<(usize, f64)>,
    pub scale: f64,
}

/// Model runs a problem has made. A copy of a problem counts its own runs from zero (so
/// [`CalibrationProblem`] can be `Clone` while its counter is atomic).
#[derive(Debug, Default)]
struct RunCount(AtomicUsize);

impl Clone for RunCount {
    fn clone(&self) -> Self {
        RunCount::default()
    }
}

/// Healthy snapshots against the model with `candidates` free (the others at the engine's
/// values).
#[derive(Clone)]
pub struct CalibrationProblem {
    engine: Engine,
    points: Vec<CalibrationPoint>,
    /// Per point: its load-law residual, when the engine has a load law and the point measured
    /// power or torque.
    law: Vec<Option<LawPoint>>,
    /// Pressure readings at rest: residual (instrument offset − excess over P1)/σ each.
    rest: Vec<RestReading>,
    /// The guess engine's solution per point: every solve starts there.
    starts: Vec<SteadyPoint>,
    candidates: Vec<Candidate>,
    bounds: Bounds,
    runs: RunCount,
    /// Penalty rows appended to the least-squares residuals (adaptation curves' curvature).
    smoothness: Vec<SmoothnessRow>,
    /// Per point, when the problem is posed on the measured GG speed ([`Self::on_gg_speed`]):
    /// σ of its fuel-flow residual, kg/s; `None` for a point solved on its fuel flow.
    speed_given: Vec<Option<f64>>,
    /// The design cycles of recent evaluations' engines (most evaluations move no number the
    /// cycle reads: it is taken over, bit for bit, not solved again).
    cycles: Arc<DesignCycles>,
}

/// Points prepared from snapshot rows: the rows whose healthy solve failed (by line), and how
/// each row's ambient pressure was obtained.
#[derive(Debug, Clone, PartialEq)]
pub struct PreparedPoints {
    pub points: Vec<CalibrationPoint>,
    /// Rows whose healthy solve failed, with the reason each was left out.
    pub dropped: Vec<DroppedRow>,
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
        dropped: Vec::new(),
        assumptions: Vec::new(),
        ambient_from_p1: false,
    };
    for (i, r) in rows.iter().enumerate() {
        if r.p_amb_kpa.is_none() && r.values.iter().any(|(s, _)| *s == Signal::P1) {
            out.ambient_from_p1 = true;
        }
        match steady_data(engine, &HealthParams::HEALTHY, r, i, &mut out.assumptions) {
            Ok(data) => out.points.push(CalibrationPoint {
                line: r.line,
                source: r.group.clone(),
                data,
                health: HealthParams::HEALTHY,
                whiten: None,
            }),
            Err(reason) => out.dropped.push(DroppedRow {
                line: r.line,
                reason,
            }),
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
        rest: Vec<RestReading>,
        candidates: Vec<Candidate>,
    ) -> Result<CalibrationProblem, CalibrateError> {
        let starts = solve_all(engine, &points)?;
        let law: Vec<Option<LawPoint>> = points.iter().map(|p| law_point(engine, p)).collect();
        let m: usize = points.iter().map(|p| p.data.outputs.len()).sum::<usize>()
            + law.iter().flatten().count()
            + rest.len();
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
            law,
            rest,
            starts,
            candidates,
            bounds,
            runs: RunCount::default(),
            smoothness: Vec::new(),
            speed_given: Vec::new(),
            cycles: Arc::new(engine.design_cycles()),
        })
    }

    /// A copy of the problem (its starts, law, bounds and penalties; its own count of model
    /// runs) posed on each point's measured GG speed instead of its fuel flow:
    /// every point that measured it is solved at that speed, and its GG-speed residual is
    /// replaced by the fuel flow's, `(model − measured)/σ`, σ the fuel meter's combined with
    /// the speed's noise carried along the guess engine's running line.
    ///
    /// Why: where the running line is nearly flat in fuel (low load, closing guide vanes, a
    /// map the curves bend), the GG speed for a given fuel moves by tens of σ for a small
    /// change of a knot, and a fuel-given solve can land on another branch of a folded line:
    /// the residuals are then too curved (or broken) for Levenberg–Marquardt, which crawls.
    /// Solved at its speed, a point has one solution and its fuel flow is a smooth function
    /// of the parameters. The two are the same residual to first order; the caller polishes
    /// on the fuel-given problem, which is the one the diagnosis uses.
    pub fn on_gg_speed(&self) -> Self {
        let mut on_speed = self.clone();
        on_speed.speed_given = self
            .points
            .iter()
            .zip(&self.starts)
            .map(|(p, start)| speed_given_sigma(&self.engine, p, start))
            .collect();
        on_speed
    }

    /// The same problem whose least-squares residuals also carry `rows` (see
    /// [`SmoothnessRow`]); [`Self::residuals_at`] and [`Self::layout`] stay the data's.
    pub fn with_smoothness(mut self, rows: Vec<SmoothnessRow>) -> Self {
        self.smoothness = rows;
        self
    }

    fn penalties(&self, x: &[f64]) -> impl Iterator<Item = f64> + '_ {
        let x = x.to_vec();
        self.smoothness.iter().map(move |r| {
            r.terms
                .iter()
                .map(|&(i, c)| c * x.get(i).copied().unwrap_or(0.0))
                .sum::<f64>()
                / r.scale
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
        self.runs.0.load(Ordering::Relaxed)
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
            .with_params_cycles(&values, &self.cycles)
            .map_err(|e| CalibrateError::Model(e.to_string()))
    }

    /// The compared signal of every residual, point-major (the layout of [`Self::residuals_at`]);
    /// the readings at rest last, with the point index `points().len()`.
    pub fn layout(&self) -> Vec<(usize, Signal)> {
        self.points
            .iter()
            .zip(&self.law)
            .enumerate()
            .flat_map(|(i, (p, law))| {
                p.data
                    .outputs
                    .iter()
                    .map(move |(s, _, _)| (i, *s))
                    .chain(law.map(|_| (i, Signal::N2)))
            })
            .chain(self.rest.iter().map(|r| (self.points.len(), r.signal)))
            .collect()
    }

    /// `r` (laid out as [`Self::layout`]) with each point's compared values whitened under its
    /// inputs' noise where the point carries a whitening ([`CalibrationPoint::whiten`]): what
    /// the optimiser minimises. The residuals reported stay `r`, in each reading's σ.
    pub(crate) fn whitened(&self, mut r: Vec<f64>) -> Vec<f64> {
        let mut j = 0;
        for (p, law) in self.points.iter().zip(&self.law) {
            let n = p.data.outputs.len();
            if let (Some(w), Some(block)) = (&p.whiten, r.get(j..j + n)) {
                if w.nrows() == n {
                    let white = w.as_ref() * nalgebra::DVector::from_column_slice(block);
                    r[j..j + n].copy_from_slice(white.as_slice());
                }
            }
            j += n + usize::from(law.is_some());
        }
        r
    }

    /// Residuals `(model − measured) / σ` at `x`, point-major; an error names the point whose
    /// solve failed.
    pub fn residuals_at(&self, x: &[f64]) -> Result<Vec<f64>, CalibrateError> {
        self.runs.0.fetch_add(1, Ordering::Relaxed);
        let engine = self.engine_at(x)?;
        self.residuals_of_engine(&engine, Some(&self.starts))
    }

    /// Residuals of `engine` as it is, each point solved from `starts` (or cold).
    fn residuals_of_engine(
        &self,
        engine: &Engine,
        starts: Option<&[SteadyPoint]>,
    ) -> Result<Vec<f64>, CalibrateError> {
        let mut out = Vec::new();
        for (i, (p, &law_point)) in self.points.iter().zip(&self.law).enumerate() {
            let start = starts.and_then(|s| s.get(i));
            let inp = &p.data.inputs;
            let m = engine.model_at(&p.health, inp.t_amb_k, inp.p_amb_kpa);
            let fuel_sigma = self.speed_given.get(i).copied().flatten();
            let sp = match (fuel_sigma, p.data.n1_hint_rpm) {
                (Some(_), Some(n1)) => p.data.solve_at_speed(&m, n1, start),
                _ => p.data.solve_from(&m, start),
            }
            .map_err(|e| CalibrateError::Model(format!("line {}: steady solve: {e}", p.line)))?;
            for &(s, v, sd) in &p.data.outputs {
                match (s, fuel_sigma, inp.demand) {
                    (Signal::N1, Some(sw), Demand::FuelKgS(w)) => {
                        out.push((sp.stations.fuel_kg_s - w) / sw)
                    }
                    _ => out.push((steady_reading(&m, &sp, s) - v) / sd),
                }
            }
            if let (Some(lp), Some(law)) = (law_point, PtLoad::of(&m)) {
                let n2 = law.speed_for_power_rpm(lp.power_w / 1e6);
                out.push((n2 - inp.n2_rpm) / lp.sigma_rpm);
            }
        }
        for r in &self.rest {
            let offset = engine.get_param(&offset_key(r.signal)).unwrap_or(0.0);
            out.push((offset - r.excess) / r.sigma);
        }
        Ok(out)
    }
}

/// Residuals `(model − measured)/σ` of `engine` as it is on `points` and `rest` (the layout of
/// [`CalibrationProblem::layout`]), every point solved from the engine's own guess.
pub fn residuals_on(
    engine: &Engine,
    points: &[CalibrationPoint],
    rest: &[RestReading],
) -> Result<Vec<f64>, CalibrateError> {
    let law: Vec<Option<LawPoint>> = points.iter().map(|p| law_point(engine, p)).collect();
    let bounds = Bounds::new(vec![0.0], vec![1.0])
        .map_err(|e| CalibrateError::Data(format!("bounds: {e}")))?;
    let prob = CalibrationProblem {
        engine: engine.clone(),
        points: points.to_vec(),
        law,
        rest: rest.to_vec(),
        starts: Vec::new(),
        candidates: Vec::new(),
        bounds,
        runs: RunCount::default(),
        smoothness: Vec::new(),
        speed_given: Vec::new(),
        cycles: Arc::new(DesignCycles::default()),
    };
    let starts = solve_all(engine, points)?;
    prob.residuals_of_engine(engine, Some(&starts))
}

/// σ of point `p`'s fuel-flow residual when it is solved at its measured GG speed (see
/// [`CalibrationProblem::on_gg_speed`]): the fuel meter's one-reading σ combined with the GG
/// speed's, carried through the slope of fuel over GG speed at `start` on `engine`. `None`
/// when the point is not fuel-given or did not measure its GG speed.
fn speed_given_sigma(engine: &Engine, p: &CalibrationPoint, start: &SteadyPoint) -> Option<f64> {
    let inp = &p.data.inputs;
    let Demand::FuelKgS(_) = inp.demand else {
        return None;
    };
    let n1 = p.data.n1_hint_rpm?;
    let sd_n1 = p
        .data
        .outputs
        .iter()
        .find(|o| o.0 == Signal::N1)
        .map(|o| o.2)?;
    let m = engine.model_at(&p.health, inp.t_amb_k, inp.p_amb_kpa);
    let at = |n: f64| {
        p.data
            .solve_at_speed(&m, n, Some(start))
            .ok()
            .map(|s| s.stations.fuel_kg_s)
    };
    let dn = (0.002 * n1).max(1.0);
    let slope = (at(n1 + dn)? - at(n1 - dn)?) / (2.0 * dn);
    let sd = p.data.input_sd.demand.hypot(slope * sd_n1);
    (sd.is_finite() && sd > 0.0).then_some(sd)
}

/// Every point solved on `engine` (healthy), in the order of `points`. A solve from the
/// design point can stall far off design on an engine being adapted, so each point that fails
/// cold is solved again from the solution of the nearest point already solved (by fuel flow or
/// power demand), then from each of the others in turn.
fn solve_all(
    engine: &Engine,
    points: &[CalibrationPoint],
) -> Result<Vec<SteadyPoint>, CalibrateError> {
    let demand = |p: &CalibrationPoint| match p.data.inputs.demand {
        crate::engine::steady::Demand::PowerMw(v) => v,
        crate::engine::steady::Demand::FuelKgS(v) => v,
        crate::engine::steady::Demand::N1Rpm(v) => v,
    };
    let mut out: Vec<Option<SteadyPoint>> = vec![None; points.len()];
    let mut failed: Vec<(usize, String)> = Vec::new();
    let model_of = |p: &CalibrationPoint| {
        engine.model_at(&p.health, p.data.inputs.t_amb_k, p.data.inputs.p_amb_kpa)
    };
    for (i, p) in points.iter().enumerate() {
        match p.data.solve_on(&model_of(p)) {
            Ok(s) => out[i] = Some(s),
            Err(e) => failed.push((i, e.to_string())),
        }
    }
    // Retry the failures from solved neighbours, nearest demand first; a success becomes a
    // neighbour for the rest.
    let mut progress = true;
    while progress && !failed.is_empty() {
        progress = false;
        let mut still = Vec::new();
        for (i, err) in failed {
            let p = &points[i];
            let mut solved: Vec<usize> = (0..points.len()).filter(|&j| out[j].is_some()).collect();
            solved.sort_by(|&a, &b| {
                (demand(&points[a]) - demand(p))
                    .abs()
                    .total_cmp(&(demand(&points[b]) - demand(p)).abs())
            });
            let m = model_of(p);
            let found = solved
                .iter()
                .find_map(|&j| p.data.solve_from(&m, out[j].as_ref()).ok());
            match found {
                Some(s) => {
                    out[i] = Some(s);
                    progress = true;
                }
                None => still.push((i, err)),
            }
        }
        failed = still;
    }
    if let Some((i, e)) = failed.first() {
        return Err(CalibrateError::Data(format!(
            "line {}: healthy steady solve: {e}",
            points[*i].line
        )));
    }
    Ok(out.into_iter().flatten().collect())
}

/// The load-law residual's data of point `p` on `engine`: `None` in generator mode or when the
/// point measured neither power nor torque.
fn law_point(engine: &Engine, p: &CalibrationPoint) -> Option<LawPoint> {
    let inp = &p.data.inputs;
    let m = engine.model_at(&p.health, inp.t_amb_k, inp.p_amb_kpa);
    let law = PtLoad::of(&m)?;
    let omega = inp.n2_rpm * std::f64::consts::PI / 30.0;
    let find = |s: Signal| {
        p.data
            .outputs
            .iter()
            .find(|(x, _, _)| *x == s)
            .map(|&(_, v, sd)| (v, sd))
    };
    let (power_w, sd_w) = match (find(Signal::Power), find(Signal::Torque)) {
        (Some((v, sd)), _) => (v * 1e6, sd * 1e6),
        (None, Some((v, sd))) => (v * 1e3 * omega, sd * 1e3 * omega),
        (None, None) => return None,
    };
    let exponent = law.local_exponent(inp.n2_rpm);
    if !(power_w > 0.0 && inp.n2_rpm > 0.0 && exponent > 0.0) {
        return None;
    }
    // n = n_d (P/P_d)^(1/k): dn/n = dP/(k P), k the curve's local exponent.
    let sd_speed = noise_sigma(&engine.cfg().sensors, Signal::N2, inp.n2_rpm);
    let sd_from_power = inp.n2_rpm * sd_w / (exponent * power_w);
    let sigma_rpm = (sd_speed * sd_speed + sd_from_power * sd_from_power).sqrt();
    (sigma_rpm > 0.0).then_some(LawPoint { power_w, sigma_rpm })
}

impl Problem for CalibrationProblem {
    fn dim(&self) -> usize {
        self.candidates.len()
    }
    fn bounds(&self) -> &Bounds {
        &self.bounds
    }
    fn cost(&self, x: &[f64]) -> f64 {
        match self.residuals_at(x).map(|r| self.whitened(r)) {
            Ok(r) => r
                .iter()
                .chain(&self.penalties(x).collect::<Vec<_>>())
                .map(|v| v * v)
                .sum(),
            Err(_) => f64::INFINITY,
        }
    }
}

impl ResidualProblem for CalibrationProblem {
    fn residuals(&self, x: &[f64], out: &mut Vec<f64>) {
        out.clear();
        match self.residuals_at(x).map(|r| self.whitened(r)) {
            Ok(r) => out.extend(r),
            // A failed solve: the right length of NaN marks the evaluation as failed.
            Err(_) => out.extend(std::iter::repeat_n(f64::NAN, self.layout().len())),
        }
        out.extend(self.penalties(x));
    }
}

/// The 1σ columns of what each input of `p` (fuel flow, T1, n2, P1) moves its compared values
/// by on `engine`, in each value's σ, over `rows` rows: its compared values first, in its
/// outputs' order, and any row after them (a load law's residual) without a column. `None`
/// where no input moves any of them (inputs without noise, or a point the model cannot solve).
fn input_columns(
    engine: &Engine,
    p: &CalibrationPoint,
    rows: usize,
) -> Option<nalgebra::DMatrix<f64>> {
    use crate::diagnosis::steady::{with_input_noise, INPUTS};
    let data = with_input_noise(engine, &p.health, p.data.clone());
    let c = nalgebra::DMatrix::from_fn(rows, INPUTS, |row, k| {
        match (data.outputs.get(row), data.input_response.get(row)) {
            (Some(&(_, _, sd)), Some(col)) if sd > 0.0 => col[k] / sd,
            _ => 0.0,
        }
    });
    c.iter().any(|v| *v != 0.0).then_some(c)
}

/// Each of `points` given its whitening under its inputs' noise on `engine`
/// ([`CalibrationPoint::whiten`]; `calibrate --noisy-inputs`). The inputs' responses are those of
/// `engine` (the guesses): they move little with the design values, and a point whose
/// responses cannot be found keeps its inputs exact.
pub fn whiten_under_input_noise(engine: &Engine, points: &mut [CalibrationPoint]) {
    use nalgebra::DMatrix;
    for p in points.iter_mut() {
        let n = p.data.outputs.len();
        let Some(c) = input_columns(engine, p, n) else {
            continue;
        };
        let m = DMatrix::<f64>::identity(n, n) + &c * c.transpose();
        let w = m
            .cholesky()
            .and_then(|l| l.l().solve_lower_triangular(&DMatrix::identity(n, n)));
        p.whiten = w.filter(|w| w.iter().all(|v| v.is_finite())).map(Arc::new);
    }
}

/// The normalised residual (mean square, as the baseline's verdict reads it) of residuals `r`
/// of `engine` on `points` (laid out as [`CalibrationProblem::layout`] lays them) judged under
/// the noise of each point's measured inputs — fuel flow, T1, n2 and, where it gives the
/// ambient pressure, P1 — which the calibration takes as exact: per point `rᵀ (I + C Cᵀ)⁻¹ r`
/// over the 1σ columns `C` of what each input moves its compared values by (the snapshot
/// diagnosis's [`with_input_noise`]), summed over the points and divided by the number of
/// residuals. The inputs of one reading scatter every value of its point together; a
/// baseline of spot readings can miss `good` on that alone (the second independent
/// simulator's unit: 0.98 σ RMS, 0.70 under its inputs' noise), which no curve, cooling split
/// or map explains. A residual with no input column (a load law's speed, a reading at rest)
/// counts as it is. `None` when a point has no input noise to carry or `r` does not match.
pub(crate) fn level_under_input_noise(
    engine: &Engine,
    points: &[CalibrationPoint],
    layout: &[(usize, Signal)],
    r: &[f64],
) -> Option<f64> {
    use crate::diagnosis::steady::squares_under_columns;
    use nalgebra::DVector;
    if r.is_empty() || r.len() != layout.len() {
        return None;
    }
    let mut total = 0.0;
    let mut carried = false;
    let mut j = 0;
    while j < layout.len() {
        let i = layout[j].0;
        let end = (j..layout.len())
            .find(|&k| layout[k].0 != i)
            .unwrap_or(layout.len());
        let block = DVector::from_column_slice(&r[j..end]);
        total += match points
            .get(i)
            .and_then(|p| input_columns(engine, p, end - j))
        {
            Some(c) => {
                carried = true;
                squares_under_columns(&c, &block)?
            }
            None => block.dot(&block),
        };
        j = end;
    }
    (carried && total.is_finite()).then(|| total / r.len() as f64)
}
