//! Method A (paper §3.4): detect steady windows in a measured segment, average them, and fit the
//! health vector with the steady-state solver.
//!
//! Steady-window criteria ([`detect_windows`], settings in [`SteadyCriteria`]):
//! 1. one phase label throughout, with flame (fuel > 0) and n1 ≥ `min_n1_fraction` × design;
//! 2. for every stability signal (default n1, P2, T2, T34, power) present in the data, the
//!    least-squares linear trend over the window drifts by at most `max_drift_sigma` noise σ
//!    from start to end, and the RMS scatter around that trend is at most
//!    `max_scatter_sigma` σ and no sample deviates from it by more than `max_deviation_sigma` σ
//!    (σ = the instrument's 1σ noise at the window mean; the last rule stops a long window
//!    from swallowing the first samples of a ramp);
//! 3. at least `min_duration_s` long. Windows are grown greedily from the earliest admissible
//!    start and do not overlap.
//!
//! Each window becomes one steady operating point: ambient T1 (window mean) and the ambient
//! pressure of the segment (fitted as a nuisance parameter by default, with P1 compared), PT speed n2 and fuel flow (window means) as the solver's inputs
//! (`Demand::FuelKgS`), and the window means of the compared outputs with a 1σ of
//! σ_noise / √N (the standard error of a mean of N independent samples). Pure: no I/O.

mod input_noise;
mod offline_shape;
mod windows;

pub(crate) use offline_shape::offline_shape_note;
pub(crate) use windows::finite_mean;
pub use windows::{average_windows, detect_windows, SteadyWindow};

pub(crate) use input_noise::{
    input_noise_note, input_noise_sigma_note, squares_under_columns, with_input_noise,
};
pub use input_noise::{InputSigma, INPUTS};

use super::objective::Objective;
use super::{
    fit, pool_for, result_of, DiagnosisConfig, DiagnosisError, EvalError, FailureLog, Method,
    MethodResult, ParamMap,
};
use crate::engine::config::EngineConfig;
use crate::engine::cycle::corrected_speed;
use crate::engine::steady::{solve, Demand, SteadyInputs, SteadyPoint};
use crate::engine::trace::{Values, NSIG};
use crate::engine::{Engine, Model};
use crate::health::HealthParams;
use crate::recording::Recording;
use crate::signals::Signal;
use std::borrow::Cow;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// One averaged steady operating point.
#[derive(Debug, Clone, PartialEq)]
pub struct SteadyData {
    pub window: SteadyWindow,
    /// What the point is, in messages: "steady window at 600–660 s", "snapshot at line 7".
    pub label: String,
    pub inputs: SteadyInputs,
    /// Compared outputs: (signal, window mean, 1σ of the mean).
    pub outputs: Vec<(Signal, f64, f64)>,
    /// The measured GG speed, rpm, when it says which running point the demand means: near
    /// idle one fuel flow can have several (the running line folds), and the healthy solve
    /// then starts on the one at this speed. `None`: the solver's own choice (Method A).
    pub n1_hint_rpm: Option<f64>,
    /// 1σ of the measured values the solve is given ([`SteadyData::inputs`]), on the same
    /// footing as the outputs' (one reading, or a window mean's): see [`with_input_noise`].
    pub input_sd: InputSigma,
    /// Per compared value (as [`SteadyData::outputs`]), its change per 1σ of each input
    /// ([`InputSigma`]'s order), from [`with_input_noise`]; empty: inputs taken as exact.
    pub input_response: Vec<[f64; INPUTS]>,
    /// Where that response is carried: the fit's covariance, or the parameters' σ alone.
    pub input_noise: InputNoise,
}

/// Where the noise of a point's measured inputs ([`SteadyData::input_response`]) is carried.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InputNoise {
    /// In the covariance the fit runs under (generalised least squares): Method A's window
    /// means, snapshots with `--noisy-inputs`.
    #[default]
    Fitted,
    /// In the health parameters' σ only: the fit takes the inputs as exact (a snapshot's
    /// default, so the read is the one least squares gives), and what each input's σ would
    /// move the read by, linearised, is added to the σ of the read
    /// ([`crate::optim::uncertainty_with_inputs`]). A snapshot's fuel flow and T1 are
    /// instruments like the compared ones (0.5 K at the compressor face is 0.09 % of corrected
    /// speed, more than a tachometer's σ): on the independent simulator's unit
    /// (`tests/foreign_simulator/`, 24 draws of its noise on one level of 9 loads) the
    /// inputs' noise scattered D_GC's read by 0.21 points (fuel 0.15, T1 0.11), the compared
    /// values' by 0.07, where the fit stated 0.14 for all of it. The fit's verdict still takes
    /// the inputs as exact: judged under their noise, a foreign unit's level read 0.74 points
    /// off was called `good`, and an input's error must not pass for a fit.
    SigmaOnly,
}

impl SteadyData {
    /// The measured value of compared signal `s`, `None` when the data have none.
    pub fn measured(&self, s: Signal) -> Option<f64> {
        self.outputs
            .iter()
            .find(|(x, _, _)| *x == s)
            .map(|&(_, v, _)| v)
    }

    /// The healthy (or `m`'s) steady point of this data, started at the measured GG speed's
    /// running point when there is a hint (see [`SteadyData::n1_hint_rpm`]).
    pub fn solve_on(&self, m: &Model) -> Result<SteadyPoint, crate::engine::EngineError> {
        self.solve_from(m, None)
    }

    /// [`SteadyData::solve_on`] with the solver started at `start` (a nearby solution): with a
    /// hint, the running point at the measured GG speed is solved from `start` and the demand
    /// from there, so where the running line folds (one fuel flow, several GG speeds) the
    /// branch the unit ran on is the one found; without one, or when that fails, the demand
    /// from `start`.
    pub fn solve_from(
        &self,
        m: &Model,
        start: Option<&SteadyPoint>,
    ) -> Result<SteadyPoint, crate::engine::EngineError> {
        if let Some(n1) = self.n1_hint_rpm {
            if let Ok(s) = self
                .solve_at_speed(m, n1, start)
                .and_then(|on_speed| solve(m, &self.inputs, Some(&on_speed)))
            {
                return Ok(s);
            }
        }
        solve(m, &self.inputs, start)
    }

    /// The running point of this data's ambient and PT speed at GG speed `n1_rpm` (the demand
    /// replaced by the speed), the solver started at `start`.
    pub fn solve_at_speed(
        &self,
        m: &Model,
        n1_rpm: f64,
        start: Option<&SteadyPoint>,
    ) -> Result<SteadyPoint, crate::engine::EngineError> {
        let at_speed = SteadyInputs {
            demand: Demand::N1Rpm(n1_rpm),
            ..self.inputs
        };
        solve(m, &at_speed, start)
    }

    /// The operating point in words, for tables: measured power (else torque, else GG speed)
    /// and the demand (fuel flow, power or speed).
    pub fn operating_point(&self) -> String {
        let value = |s: Signal| self.outputs.iter().find(|o| o.0 == s).map(|o| o.1);
        let load = match (
            value(Signal::Power),
            value(Signal::Torque),
            value(Signal::N1),
        ) {
            (Some(p), _, _) => format!("{p:.2} MW, "),
            (None, Some(q), _) => format!("{q:.1} kN·m, "),
            (None, None, Some(n)) => format!("n1 {n:.0} rpm, "),
            _ => String::new(),
        };
        let demand = match self.inputs.demand {
            Demand::FuelKgS(f) => format!("fuel {f:.3} kg/s"),
            Demand::PowerMw(p) => format!("demand {p:.2} MW"),
            Demand::N1Rpm(n) => format!("demand n1 {n:.0} rpm"),
        };
        format!("{load}{demand}")
    }
}

/// The model's value of a signal at a steady point (the engine's one station → signal mapping).
pub fn steady_value(p: &SteadyPoint, s: Signal) -> f64 {
    crate::engine::gas_path::signal_value(&p.stations, s)
}

/// What the instrument of `s` reads at a steady point of model `m`: the station value through
/// the instrument path of the model's effects (an adopted or calibrated sensor offset shifts
/// it; a lag leaves a steady value as it is).
pub fn steady_reading(m: &Model, p: &SteadyPoint, s: Signal) -> f64 {
    let mut v = [steady_value(p, s)];
    m.effects.instrument(s, &[0.0], &mut v);
    v[0]
}

/// Every signal's [`steady_reading`] of `p`, indexed like a trace row.
pub(crate) fn steady_readings(m: &Model, p: &SteadyPoint) -> Values {
    let mut v = [f64::NAN; NSIG];
    for s in Signal::ALL {
        v[s.index()] = steady_reading(m, p, s);
    }
    v
}

/// `data` with the adapted model's own error (`[adaptation.model_error_pct]`, estimated by
/// `calibrate --adapt` on operating points left out of its fit) added in quadrature to each
/// compared value's instrument σ: where the model predicts a signal no better than that, the
/// fit weights it for what the model can do (an averaged GG speed is far more precise than a
/// map predicts it), and the fit's verdict and σ carry it. Calibration itself does not call
/// this: its residuals are what the model error is estimated from.
/// Where the file states the error along the operating line
/// (`[adaptation.model_error_by_speed]`), each point gets it at its own measured GG speed: the
/// low loads, where a borrowed map is bent furthest, are weighted for how little the model
/// predicts there, the others for how well.
pub(crate) fn with_model_error(engine: &Engine, mut data: SteadyData) -> SteadyData {
    if let Some(a) = &engine.cfg().adaptation {
        let rel = relative_gg_speed(engine, &data);
        for (s, v, sd) in &mut data.outputs {
            *sd = sd.hypot(a.model_error_fraction(*s, rel) * v.abs());
        }
    }
    data
}

/// [`relative_gg_speed`] of each of `points`.
pub(crate) fn relative_gg_speeds(engine: &Engine, points: &[SteadyData]) -> Vec<Option<f64>> {
    points
        .iter()
        .map(|p| relative_gg_speed(engine, p))
        .collect()
}

/// The relative corrected GG speed of `data` (its measured GG speed at its ambient over the
/// design's), `None` when it has no GG speed.
pub(crate) fn relative_gg_speed(engine: &Engine, data: &SteadyData) -> Option<f64> {
    let n1 = data.measured(Signal::N1)?;
    Some(relative_gg_speed_at(engine, n1, data.inputs.t_amb_k))
}

/// The relative corrected GG speed of a GG speed `n1_rpm` at inlet temperature `t1_k`.
pub(crate) fn relative_gg_speed_at(engine: &Engine, n1_rpm: f64, t1_k: f64) -> f64 {
    let d = engine.design();
    corrected_speed(n1_rpm, t1_k) / corrected_speed(d.n1_rpm, d.t1_k)
}

/// Why `data` is left out of a steady diagnosis on an adapted model: its measured GG speed
/// lies beyond the speeds the adaptation was calibrated on (`[adaptation.calibrated]`), where
/// the curves are extrapolated and the model's own error is not known (`None` within them, or
/// when the file states no range).
pub(crate) fn beyond_calibration(engine: &Engine, data: &SteadyData) -> Option<String> {
    let range = engine.cfg().adaptation.as_ref()?.calibrated?;
    range.beyond(relative_gg_speed(engine, data)?)
}

/// Relative corrected GG speed below the adaptation's lowest compressor knot by more than this
/// is said to be an extrapolation of the curves.
const BELOW_KNOTS_MARGIN: f64 = 0.01;

/// A note when `data` (measured GG speed at its ambient) runs below the lowest speed the
/// engine's adaptation was fitted at (its lowest compressor knot is the calibration's lowest
/// speed): the curves hold their end value there, and a stated model error was measured
/// between calibrated points, not below them.
pub(crate) fn below_adaptation_note(engine: &Engine, data: &SteadyData) -> Option<String> {
    let lowest = engine
        .cfg()
        .adaptation
        .as_ref()?
        .compressor
        .as_ref()?
        .speed_knots
        .first()
        .copied()?;
    let rel = relative_gg_speed(engine, data)?;
    (rel < lowest - BELOW_KNOTS_MARGIN).then(|| {
        format!(
            "{}: relative corrected GG speed {rel:.3} is below the adaptation's lowest knot \
             {lowest:.3} (the lowest speed it was calibrated at): the curves are extrapolated \
             there, and the model's own error is not known",
            data.label
        )
    })
}

/// What [`with_model_error`] adds, for a report's assumptions; `None` when the file states no
/// model error above 0.
pub(crate) fn model_error_note(cfg: &EngineConfig) -> Option<String> {
    let a = cfg.adaptation.as_ref()?;
    let list: Vec<String> = a
        .model_error_pct
        .iter()
        .filter(|(_, v)| **v > 0.0)
        .map(|(k, v)| format!("{k} {v:.2} %"))
        .collect();
    if list.is_empty() {
        return None;
    }
    let by_speed = a.model_error_by_speed.as_ref().map_or(String::new(), |t| {
        let ranges: Vec<String> = t
            .pct
            .iter()
            .filter(|(_, v)| v.iter().any(|x| *x > 0.0))
            .map(|(k, v)| {
                let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = v.iter().copied().fold(0.0, f64::max);
                format!("{k} {lo:.2}–{hi:.2} %")
            })
            .collect();
        format!(
            "; each point's at its own GG speed ([adaptation.model_error_by_speed], relative \
             corrected speed {:.3}–{:.3}): {}",
            t.speed_knots.first().copied().unwrap_or(0.0),
            t.speed_knots.last().copied().unwrap_or(0.0),
            ranges.join(", ")
        )
    });
    Some(format!(
        "the adapted model's own error ([adaptation.model_error_pct]) added to each instrument \
         σ: {}{by_speed}",
        list.join(", ")
    ))
}

/// What [`SteadyProblem`] adds to the health σ from `[adaptation.health_error]`, for a
/// report's assumptions; `None` when the file states none above 0.
pub(crate) fn health_error_note(cfg: &EngineConfig) -> Option<String> {
    let a = cfg.adaptation.as_ref()?;
    let list: Vec<String> = a
        .health_error
        .iter()
        .filter(|(_, v)| **v > 0.0)
        .map(|(k, v)| format!("{k} {v:.2}"))
        .collect();
    (!list.is_empty()).then(|| {
        format!(
            "the adapted model's own error in health units ([adaptation.health_error], \
             points) added to each parameter's σ: {}",
            list.join(", ")
        )
    })
}

/// A [`SteadyProblem`] at one parameter vector ([`SteadyProblem::points_at`]).
struct PointsAt<'a> {
    engine: Cow<'a, Engine>,
    health: HealthParams,
    inputs: Vec<SteadyInputs>,
}

/// Method A as an optimisation problem.
pub struct SteadyProblem {
    engine: Engine,
    points: Vec<SteadyData>,
    /// Healthy solutions, the Newton start of every solve (keeps evaluations independent).
    guesses: Vec<SteadyPoint>,
    objective: Objective,
    /// The residuals' change per 1σ of each input of each [`InputNoise::SigmaOnly`] point
    /// (noise units, residual-length; empty when none): the inputs' part of the σ.
    input_columns: Vec<Vec<f64>>,
    params: ParamMap,
    least_squares: bool,
    runs: AtomicUsize,
    failures: FailureLog,
}

impl SteadyProblem {
    /// Builds the problem; windows whose healthy steady solve fails are dropped.
    pub fn new(
        engine: &Engine,
        points: Vec<SteadyData>,
        cfg: &DiagnosisConfig,
    ) -> Result<SteadyProblem, DiagnosisError> {
        let mut kept = Vec::new();
        let mut guesses = Vec::new();
        for p in points {
            let m = engine.model_at(&cfg.base, p.inputs.t_amb_k, p.inputs.p_amb_kpa);
            if let Ok(g) = p.solve_on(&m) {
                kept.push(p);
                guesses.push(g);
            }
        }
        let pts: Vec<Vec<(Signal, f64, f64)>> = kept.iter().map(|p| p.outputs.clone()).collect();
        let ambient0 = if cfg.fit_ambient_pressure {
            kept.first().map(|p| p.inputs.p_amb_kpa)
        } else {
            None
        };
        // Each point's values share its inputs' errors: fitted under that covariance, or
        // (`InputNoise::SigmaOnly`) carried into the parameters' σ alone.
        let kept_ref = &kept;
        let response = |mode: InputNoise| {
            move |k: usize, s: Signal| {
                let p = &kept_ref[k];
                if p.input_noise != mode {
                    return Vec::new();
                }
                p.outputs
                    .iter()
                    .position(|o| o.0 == s)
                    .and_then(|i| p.input_response.get(i))
                    .map_or_else(Vec::new, |r| r.to_vec())
            }
        };
        let objective = Objective::from_points(&pts);
        let input_columns = objective.point_columns(response(InputNoise::SigmaOnly));
        let objective = objective.with_shared_errors(response(InputNoise::Fitted));
        if objective.len() <= cfg.n_fitted() {
            return Err(DiagnosisError::Data(format!(
                "Method A needs more averaged values than parameters: {} steady point(s) give {} values for {} parameters",
                kept.len(),
                objective.len(),
                cfg.n_fitted()
            )));
        }
        Ok(SteadyProblem {
            engine: engine.clone(),
            points: kept,
            guesses,
            objective,
            input_columns,
            params: ParamMap::for_diagnosis(
                &cfg.free(),
                cfg.base,
                &cfg.health_bounds,
                ambient0,
                &cfg.extra_params,
                engine,
            )?,
            least_squares: false,
            runs: AtomicUsize::new(0),
            failures: FailureLog::default(),
        })
    }

    /// The steady operating points used.
    pub fn points(&self) -> &[SteadyData] {
        &self.points
    }

    /// The objective's residuals (noise units, whitened) at `x`, without counting a model run
    /// or logging a failure: for what is derived from the fit (the inputs' draws, the residual
    /// under their noise). `None` where the model cannot be evaluated.
    pub(crate) fn objective_residuals(&self, x: &[f64]) -> Option<Vec<f64>> {
        let model = self.simulate(x).ok()?;
        let mut r = Vec::new();
        self.objective.residuals(&model, &mut r);
        Some(r)
    }

    /// Model values at every point, as rows indexed like a trace, or why a solve failed.
    pub fn simulate(&self, x: &[f64]) -> Result<Vec<Values>, EvalError> {
        self.runs.fetch_add(1, Ordering::Relaxed);
        let at = self.points_at(x)?;
        let solved = self.solve_points(&at, |_| at.health)?;
        Ok(solved.into_iter().map(|(_, v)| v).collect())
    }

    /// The problem at `x`: the engine its engine-file parameters make (the problem's own when
    /// it fits none), the health, and each point's inputs with the fitted ambient pressure.
    fn points_at(&self, x: &[f64]) -> Result<PointsAt<'_>, EvalError> {
        let applied = self.params.apply(x);
        let engine = if self.params.touches_engine() {
            Cow::Owned(self.params.engine_for(&self.engine, &applied)?)
        } else {
            Cow::Borrowed(&self.engine)
        };
        let inputs = self
            .points
            .iter()
            .map(|p| SteadyInputs {
                p_amb_kpa: applied.ambient_kpa.unwrap_or(p.inputs.p_amb_kpa),
                ..p.inputs
            })
            .collect();
        Ok(PointsAt {
            engine,
            health: applied.health,
            inputs,
        })
    }

    /// Every point solved on `at`'s engine, point `k` at health `health(k)` (each from its
    /// healthy guess): its solution and its readings, or why a solve failed.
    fn solve_points(
        &self,
        at: &PointsAt,
        health: impl Fn(usize) -> HealthParams,
    ) -> Result<Vec<(SteadyPoint, Values)>, EvalError> {
        let mut out = Vec::with_capacity(self.points.len());
        for (k, ((p, g), inputs)) in self
            .points
            .iter()
            .zip(&self.guesses)
            .zip(&at.inputs)
            .enumerate()
        {
            let m = at
                .engine
                .model_at(&health(k), inputs.t_amb_k, inputs.p_amb_kpa);
            let sp = solve(&m, inputs, Some(g))
                .map_err(|e| EvalError::Model(format!("{}: {e}", p.label)))?;
            out.push((sp, steady_readings(&m, &sp)));
        }
        Ok(out)
    }

    /// The prepared objective.
    pub fn objective(&self) -> &Objective {
        &self.objective
    }
}

impl SteadyProblem {
    /// The adapted file's `[adaptation.health_error]` (see
    /// [`DiagnosisProblem::model_health_sigma`]).
    fn health_sigma(&self) -> [f64; 6] {
        let a = self.engine.cfg().adaptation.as_ref();
        std::array::from_fn(|i| a.map_or(0.0, |a| a.health_error_pts(i)))
    }
    /// Variance inflation of the least-squares σ for correlated residuals (see
    /// [`DiagnosisProblem::sigma_inflation`]).
    fn residual_inflation(&self, _r: &[f64]) -> f64 {
        1.0 // window means are independent
    }
    fn input_draws(&self, x: &[f64]) -> Vec<Vec<f64>> {
        // Fitted inputs' noise is in the residuals' covariance (`with_input_noise`): the fit's
        // own σ carries it. Inputs taken as exact in the fit (`InputNoise::SigmaOnly`): each
        // one's 1σ column is a draw, scaled by √(columns) so that the mean square over the
        // draws is the sum over the inputs, the linearised variance they add.
        // An adapted file's unknown compressor shape off the healthy line is two columns more
        // (`offline_shape`), whichever way the inputs are taken.
        let offline = self.offline_shape_columns(x);
        if self.input_columns.is_empty() && offline.is_empty() {
            return Vec::new();
        }
        let Some(r) = self.objective_residuals(x) else {
            return Vec::new();
        };
        let scale = ((self.input_columns.len() + offline.len()) as f64).sqrt();
        self.input_columns
            .iter()
            .chain(&offline)
            .map(|c| r.iter().zip(c).map(|(a, b)| a - scale * b).collect())
            .collect()
    }
    fn whiten(&self, _r: &mut [f64]) {
        // The objective's residuals are whitened already (`Objective::with_shared_errors`).
    }
    fn input_covariance(&mut self, _x: &[f64], _pool: &rayon::ThreadPool) {}
}

super::impl_diagnosis_problem!(SteadyProblem);

/// Method A on `segment`.
pub fn diagnose_steady(
    engine: &Engine,
    segment: &Recording,
    cfg: &DiagnosisConfig,
) -> Result<MethodResult, DiagnosisError> {
    let start = Instant::now();
    cfg.validate()?;
    let pool = pool_for(cfg)?;
    // The fuel flow is each window's input: a meter's zero offset would be burnt with it.
    let (segment, fuel_zero) = segment.fuel_zero_removed();
    let segment: &Recording = &segment;
    let windows = detect_windows(segment, engine.cfg(), &cfg.steady);
    if windows.is_empty() {
        return Err(DiagnosisError::Data(
            "no steady window found (see SteadyCriteria)".into(),
        ));
    }
    // On an adapted file a window beyond the calibrated GG speeds (a start-up's idle or
    // low-load hold below the baseline's lowest load) is left out, as a snapshot is.
    let mut left_out = Vec::new();
    let points: Vec<SteadyData> = average_windows(segment, engine.cfg(), &windows, &cfg.signals)
        .into_iter()
        .filter(|d| match beyond_calibration(engine, d) {
            Some(reason) => {
                left_out.push(format!("{}: {reason}", d.label));
                false
            }
            None => true,
        })
        .map(|d| with_model_error(engine, with_input_noise(engine, &cfg.base, d)))
        .collect();
    if points.is_empty() {
        return Err(DiagnosisError::Data(format!(
            "no steady window within the adapted model's calibrated speeds: {}",
            left_out.join("; ")
        )));
    }
    let mut problem = SteadyProblem::new(engine, points, cfg)?;
    let out = fit(&mut problem, cfg, &pool)?;
    let signals = problem.objective().signals().to_vec();
    let n_res = problem.objective().len();
    let win: Vec<(f64, f64)> = problem
        .points()
        .iter()
        .map(|p| (p.window.t_start_s, p.window.t_end_s))
        .collect();
    let mut r = result_of(Method::Steady, &problem, &out, cfg, signals, n_res, win);
    r.fit_quality = r.fit_quality.with_model_error(
        engine.cfg(),
        &r.signals,
        &relative_gg_speeds(engine, problem.points()),
    );
    r.fuel_meter_zero = fuel_zero;
    r.left_out = left_out;
    r.wall_s = start.elapsed().as_secs_f64();
    Ok(r)
}

#[cfg(test)]
mod tests;
