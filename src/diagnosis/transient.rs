//! Method B (paper §2.3): fit the health vector to one whole measured start-up.
//!
//! The forward model is [`simulate_segment`]: the dynamic engine model driven through the
//! segment's phases with its measured ambient and either its measured fuel flow (default,
//! open loop) or its measured GG speed / power as controller demand. The simulated, lagged
//! instrument values are compared with the measured ones by [`Objective`]. This module builds
//! the problem and runs the fit; it does no I/O.

use super::objective::Objective;
use super::{
    fit, pool_for, result_of, DiagnosisConfig, DiagnosisError, Method, MethodResult, ParamMap,
};
use crate::engine::replay::{simulate_segment, DriveMode, Segment};
use crate::engine::trace::Values;
use crate::engine::Engine;
use crate::signals::{Phase, Signal};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Signals that are operating inputs of the replay (never compared).
fn is_input(s: Signal, mode: DriveMode, fit_ambient: bool) -> bool {
    s == Signal::T1
        || (s == Signal::P1 && !fit_ambient)
        || (s == Signal::FuelFlow && mode == DriveMode::MeasuredFuel)
}

/// Samples whose P1 reading `Segment::ambient` takes as the ambient pressure (GG at rest).
fn at_rest(v: &crate::engine::trace::Values) -> bool {
    v[Signal::N1.index()].abs() < 50.0 && v[Signal::P1.index()].is_finite()
}

/// Savitzky–Golay (quadratic, 7 points) smoothing of the measured fuel flow where it is a
/// smooth function: every sample of the 7-point window finite, positive and in the same phase.
/// It keeps ramps exactly and takes ~60 % of the white noise off the model's input; steps
/// (light-off, fuel off) and phase changes are left as measured.
pub fn smooth_fuel(seg: &mut Segment) {
    const C: [f64; 7] = [-2.0, 3.0, 6.0, 7.0, 6.0, 3.0, -2.0];
    let fi = Signal::FuelFlow.index();
    let raw: Vec<f64> = seg.values.iter().map(|v| v[fi]).collect();
    for k in 3..raw.len().saturating_sub(3) {
        let win = &raw[k - 3..=k + 3];
        let same_phase = seg.phase[k - 3..=k + 3].iter().all(|p| *p == seg.phase[k]);
        if same_phase && win.iter().all(|v| v.is_finite() && *v > 0.0) {
            let s: f64 = win.iter().zip(C).map(|(v, c)| v * c).sum::<f64>() / 21.0;
            if s > 0.0 {
                seg.values[k][fi] = s;
            }
        }
    }
}

/// Method B as an optimisation problem over the free health parameters.
pub struct TransientProblem {
    engine: Engine,
    /// The segment that drives the model: the measured one, with the fuel flow smoothed when
    /// [`DiagnosisConfig::smooth_fuel`] is set.
    drive: Segment,
    mode: DriveMode,
    objective: Objective,
    params: ParamMap,
    least_squares: bool,
    runs: AtomicUsize,
}

impl TransientProblem {
    /// Builds the problem for `segment` under `cfg` (window, signals, drive mode, fixed step).
    pub fn new(
        engine: &Engine,
        segment: &Segment,
        cfg: &DiagnosisConfig,
    ) -> Result<TransientProblem, DiagnosisError> {
        if segment.len() < 2 {
            return Err(DiagnosisError::Data(
                "segment has fewer than two samples".into(),
            ));
        }
        let mut engine = engine.clone();
        if cfg.fixed_step_s > 0.0 {
            engine.set_param("solver.fixed_step_s", cfg.fixed_step_s)?;
        }
        let signals: Vec<Signal> = cfg
            .signals
            .iter()
            .copied()
            .filter(|s| !is_input(*s, cfg.drive_mode, cfg.fit_ambient_pressure))
            .collect();
        let in_window: Vec<bool> = segment
            .t_s
            .iter()
            .zip(&segment.phase)
            .map(|(&t, &p)| cfg.window.contains(t, p))
            .collect();
        let objective = Objective::new(
            &segment.t_s,
            &segment.values,
            &in_window,
            &signals,
            &engine.cfg().sensors,
            cfg.rate_weight,
        );
        if objective.len() <= cfg.free().len() {
            return Err(DiagnosisError::Data(format!(
                "only {} valid measured samples in the window for {} parameters",
                objective.len(),
                cfg.free().len()
            )));
        }
        if !segment.phase.iter().any(|p| {
            !matches!(
                p,
                Phase::Standstill | Phase::Crank | Phase::Purge | Phase::Shutdown | Phase::Trip
            )
        }) {
            return Err(DiagnosisError::Data(
                "segment never lights off: no fired start-up to diagnose".into(),
            ));
        }
        let mut drive = segment.clone();
        if cfg.smooth_fuel && cfg.drive_mode == DriveMode::MeasuredFuel {
            smooth_fuel(&mut drive);
        }
        // The replay takes the ambient pressure from P1 at rest; fitting it needs such samples.
        let ambient0 = (cfg.fit_ambient_pressure && segment.values.iter().any(at_rest))
            .then(|| segment.ambient(engine.cfg()).1);
        Ok(TransientProblem {
            engine,
            drive,
            mode: cfg.drive_mode,
            objective,
            params: ParamMap::new(cfg.free(), cfg.base, ambient0)?,
            least_squares: false,
            runs: AtomicUsize::new(0),
        })
    }

    /// The prepared objective.
    pub fn objective(&self) -> &Objective {
        &self.objective
    }

    /// The simulated instrument values for free parameters `x` (`None` if the model failed).
    pub fn simulate(&self, x: &[f64]) -> Option<Vec<Values>> {
        self.runs.fetch_add(1, Ordering::Relaxed);
        let h = self.params.health(x);
        let run = |seg: &Segment| {
            simulate_segment(&self.engine, &h, seg, self.mode)
                .ok()
                .map(|t| t.measured)
        };
        match self.params.ambient(x) {
            Some(p) => {
                // The replay reads the ambient pressure from P1 at rest: set it there.
                let mut seg = self.drive.clone();
                seg.values
                    .iter_mut()
                    .filter(|v| at_rest(v))
                    .for_each(|v| v[Signal::P1.index()] = p);
                run(&seg)
            }
            None => run(&self.drive),
        }
    }
}

impl TransientProblem {
    /// Variance inflation of the least-squares σ for correlated residuals (see
    /// [`DiagnosisProblem::sigma_inflation`]).
    fn residual_inflation(&self, r: &[f64]) -> f64 {
        // 30 samples: longer than the slowest sensor lag and the spool time constants.
        self.objective.correlation_inflation(r, 30)
    }
}

super::impl_diagnosis_problem!(TransientProblem);

/// Method B on `segment`.
pub fn diagnose_transient(
    engine: &Engine,
    segment: &Segment,
    cfg: &DiagnosisConfig,
) -> Result<MethodResult, DiagnosisError> {
    let start = Instant::now();
    let pool = pool_for(cfg)?;
    let mut problem = TransientProblem::new(engine, segment, cfg)?;
    let out = fit(&mut problem, cfg, &pool)?;
    let signals = problem.objective().signals().to_vec();
    let n_res = problem.objective().len();
    // result_of evaluates the objective and residuals once more at the result (2 runs,
    // counted); wall time includes them.
    let mut r = result_of(
        Method::Transient,
        &problem,
        &out,
        cfg,
        signals,
        n_res,
        Vec::new(),
    );
    r.wall_s = start.elapsed().as_secs_f64();
    Ok(r)
}
