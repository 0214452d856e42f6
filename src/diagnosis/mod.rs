//! Gas-path diagnosis: fit the six health parameters to measured data (REFERENCE §4, paper
//! §2.2–3.4).
//!
//! * Method B ([`transient`]): drive the dynamic model through a whole measured start-up with
//!   the segment's operating inputs and fit the health vector to the instruments' traces.
//! * Method A ([`steady`]): detect steady windows in the same data, average them, and fit the
//!   same vector with the steady-state solver.
//!
//! Both minimise paper eq. 10 normalised per signal by its noise σ ([`objective`]) with a
//! global optimiser from [`crate::optim`] (cuckoo search by default), then (by default) refine
//! with Levenberg–Marquardt on the per-sample residual vector and report a 1σ uncertainty per
//! parameter from the residual Jacobian at the optimum ([`Optimiser`], [`fit`]).
//! [`identifiability`] computes the sensitivity matrix / Fisher information behind those σ;
//! [`assess`] decides whether a stored start-up is diagnosable and runs both methods on it;
//! [`bench`] holds the accuracy and wash benchmarks; [`csv_input`] parses a segment CSV.
//!
//! # Defaults, and why (measured with `gtwatch bench diagnosis --compare`, release, 8 cases)
//!
//! * Optimiser: cuckoo search (one population of 25 nests seeded with the healthy engine,
//!   [`DiagnosisConfig::global_runs`]; fits with extra parameters keep up to 200 runs) then
//!   Levenberg–Marquardt (≤ 200 runs). At the same 400-run budget, Method B's RMSE per
//!   parameter was 0.03–0.04 points with CS + LM (which stops early, ~290 runs), 0.2–0.6 with
//!   CMA-ES, 1.0–1.9 with DE and 0.6–3.5 with CS alone: with α = 0.01 the Lévy flights explore
//!   but do not converge in a few hundred runs, while the objective is smooth enough near the
//!   optimum for LM. Cutting the global stage from 200 runs to the first population left every
//!   estimate of `bench diagnosis --cases 8 --seed 7` within 0.0005 points (mean RMSE 0.0336
//!   either way) at ~110 instead of ~280 model runs.
//! * Drive: measured fuel (open loop), the plant's actual input. Demand mode (PID on measured
//!   n1/power) biased D_EC/D_EP by 0.1–0.3 points on one case over 3 noise seeds
//!   (controller mismatch).
//! * Weighting: noise σ combined with one sample's change (`rate_weight` 1), because the replay
//!   knows its inputs only at the samples (noise-free replay of the true engine deviates by up
//!   to 20σ in light-off/acceleration without it, < 0.4σ elsewhere).
//! * Ambient pressure fitted as a nuisance parameter (see
//!   [`DiagnosisConfig::fit_ambient_pressure`]).
//!
//! Pure: no I/O (the CSV parser takes a reader), no globals, deterministic for a given seed.
//! The one exception is `wall_s` in the results, read from a monotonic clock for reporting; it
//! never influences a computed value.

pub(crate) mod assess;
pub mod bench;
pub mod config;
pub mod csv_input;
pub mod ensemble;
pub mod fit_quality;
pub mod fuel_noise;
pub mod identifiability;
pub(crate) mod objective;
pub(crate) mod params;
pub(crate) mod periodic;
pub mod phase_split;
pub mod prior;
pub(crate) mod residual_table;
pub(crate) mod separability;
pub mod snapshot;
pub mod steady;
pub mod transient;
pub(crate) mod unit_check;

pub use config::{DiagnosisConfig, Method, Optimiser, SteadyCriteria, Window};
pub use params::{
    Applied, EvalError, FailureLog, Failures, FitParam, ParamMap, ParamTarget,
    AMBIENT_HALF_RANGE_KPA,
};

use crate::engine::{Engine, EngineError};
use crate::health::{HealthParams, HEALTH_NAMES};
use crate::optim::{
    self, refine, run, uncertainty, uncertainty_with_inputs, Budget, CmaEs, CuckooSearch,
    DifferentialEvolution, JacobianOptions, LmOptions, OptimError, ResidualProblem,
};
use crate::signals::Signal;
use rayon::ThreadPool;
use serde::Serialize;
use std::collections::BTreeMap;

/// Everything that can go wrong in a diagnosis.
#[derive(Debug, thiserror::Error)]
pub enum DiagnosisError {
    /// The optimiser was misconfigured or failed.
    #[error("optimiser: {0}")]
    Optim(#[from] OptimError),
    /// The engine model failed where it must not (e.g. on the reference segment set-up).
    #[error("engine model: {0}")]
    Engine(#[from] EngineError),
    /// The data do not allow this method (no steady window, empty window, …).
    #[error("{0}")]
    Data(String),
    /// The settings are inconsistent (a budget of 0 runs, a parameter fitted twice, …).
    #[error("diagnosis settings: {0}")]
    Config(String),
    /// Every model evaluation of the fit failed: no result.
    #[error("every one of {runs} model evaluations failed; first reasons: {reasons}")]
    AllEvaluationsFailed { runs: usize, reasons: String },
    /// The recording is unusable (see [`crate::recording::Recording`]).
    #[error(transparent)]
    Recording(#[from] crate::recording::RecordingError),
}

/// Reads an engine-file value by dotted key (through `Engine::get_param`).
pub(crate) fn engine_param(engine: &Engine, key: &str) -> Result<f64, String> {
    engine.get_param(key).map_err(|e| e.to_string())
}

/// Sets an engine-file value by dotted key (through `Engine::set_param`).
pub(crate) fn set_engine_param(engine: &mut Engine, key: &str, value: f64) -> Result<(), String> {
    engine.set_param(key, value).map_err(|e| e.to_string())
}

/// A diagnosis problem both methods provide: the optimiser's [`ResidualProblem`] plus the
/// bookkeeping the driver needs.
pub trait DiagnosisProblem: ResidualProblem {
    /// Switches the scalar cost between paper eq. 10 (`false`) and the residual sum of squares.
    fn set_least_squares(&mut self, on: bool);
    /// Model runs so far.
    fn model_runs(&self) -> usize;
    /// Paper eq. 10 at `x`.
    fn eq10(&self, x: &[f64]) -> f64;
    /// Variance inflation of the least-squares σ for correlated residuals `r` (1 = none).
    fn sigma_inflation(&self, r: &[f64]) -> f64;
    /// Residual vectors at `x` with other draws of the noise on the signals that drive the
    /// model (none when nothing measured drives it): what the σ of the inputs adds to the
    /// parameters' σ ([`crate::optim::uncertainty_with_inputs`]).
    fn input_noise_draws(&self, x: &[f64]) -> Vec<Vec<f64>>;
    /// Before the least-squares stage, at the global stage's result `x`: takes the residuals'
    /// covariance from the noise of the signals that drive the model, which that stage then
    /// fits under (generalised least squares, [`fuel_noise`]); nothing when no measured signal
    /// drives the model.
    fn prepare_least_squares(&mut self, x: &[f64], pool: &ThreadPool);
    /// The parameter map.
    fn params(&self) -> &ParamMap;
    /// The failed evaluations so far, by reason.
    fn failures(&self) -> Failures;
    /// The model's own 1σ error in health units per health parameter (order of
    /// [`HEALTH_NAMES`]), points, added in quadrature to each health parameter's σ: an adapted
    /// file's `[adaptation.health_error]` for Method A (estimated from steady reads of loads
    /// the curves were not fitted to), none for Method B, whose start-up weighs the operating
    /// range otherwise.
    fn model_health_sigma(&self) -> [f64; 6];
}

/// The optimiser-facing traits of a diagnosis problem, for a type with the fields `objective:
/// Objective`, `params: ParamMap`, `least_squares: bool`, `runs: AtomicUsize`, `failures:
/// FailureLog`, a method `simulate(&self, x) -> Result<Vec<Values>, EvalError>` and a method
/// `residual_inflation(&self, r) -> f64`, `input_draws(&self, x)`, `whiten(&self, r)` (the
/// least-squares stage's map of the residuals) and `input_covariance(&mut self, x, pool)`.
/// Method A and Method B differ only in those methods.
/// A failed evaluation (the model's error, or a non-finite model value where a measurement is
/// compared) is recorded with its reason and costs `+∞` / NaN residuals for the optimiser.
macro_rules! impl_diagnosis_problem {
    ($ty:ty) => {
        impl $ty {
            /// Model values at `x`, checked against the objective; failures are recorded.
            fn evaluate(
                &self,
                x: &[f64],
            ) -> Result<Vec<$crate::signals::Values>, $crate::diagnosis::EvalError> {
                let r = self
                    .simulate(x)
                    .and_then(|m| self.objective.check(&m).map(|()| m));
                if let Err(e) = &r {
                    self.failures.record(e);
                }
                r
            }
        }

        impl $crate::optim::Problem for $ty {
            fn dim(&self) -> usize {
                self.params.bounds().dim()
            }
            fn bounds(&self) -> &$crate::optim::Bounds {
                self.params.bounds()
            }
            fn cost(&self, x: &[f64]) -> f64 {
                if self.least_squares {
                    // The sum of squares of the residuals that stage sees; a failed run +∞.
                    let s = $crate::optim::ResidualProblem::ssr(self, x);
                    return if s.is_finite() { s } else { f64::INFINITY };
                }
                match self.evaluate(x) {
                    Ok(m) => self.objective.eq10(&m),
                    Err(_) => f64::INFINITY,
                }
            }
        }

        impl $crate::optim::ResidualProblem for $ty {
            fn residuals(&self, x: &[f64], out: &mut Vec<f64>) {
                match self.evaluate(x) {
                    Ok(m) => {
                        self.objective.residuals(&m, out);
                        // The least-squares stage (LM, σ) fits under the residuals' own
                        // covariance; the reported residuals stay plain.
                        if self.least_squares {
                            self.whiten(out);
                        }
                    }
                    Err(_) => {
                        out.clear();
                        out.resize(self.objective.len(), f64::NAN);
                    }
                }
            }
        }

        impl $crate::diagnosis::DiagnosisProblem for $ty {
            fn set_least_squares(&mut self, on: bool) {
                self.least_squares = on;
            }
            fn model_runs(&self) -> usize {
                self.runs.load(std::sync::atomic::Ordering::Relaxed)
            }
            fn eq10(&self, x: &[f64]) -> f64 {
                self.evaluate(x)
                    .map_or(f64::INFINITY, |m| self.objective.eq10(&m))
            }
            fn params(&self) -> &$crate::diagnosis::ParamMap {
                &self.params
            }
            fn model_health_sigma(&self) -> [f64; 6] {
                self.health_sigma()
            }
            fn failures(&self) -> $crate::diagnosis::Failures {
                self.failures.summary()
            }
            fn sigma_inflation(&self, r: &[f64]) -> f64 {
                self.residual_inflation(r)
            }
            fn input_noise_draws(&self, x: &[f64]) -> Vec<Vec<f64>> {
                self.input_draws(x)
            }
            fn prepare_least_squares(&mut self, x: &[f64], pool: &rayon::ThreadPool) {
                self.input_covariance(x, pool)
            }
        }
    };
}
pub(crate) use impl_diagnosis_problem;

/// The outcome of one method on one data set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodResult {
    pub method: Method,
    pub optimiser: Optimiser,
    /// Fitted health vector (fixed parameters at their given values), %.
    pub health: HealthParams,
    /// 1σ per parameter, % (0 for fixed parameters, +∞ for unidentifiable ones): the
    /// linearised least-squares σ at the optimum (Jacobian, residual variance SSR/(m−n)),
    /// inflated for the residuals' serial correlation (Method B), and in quadrature the part
    /// the noise of the measured fuel flow that drives the model adds (Method B).
    pub sigma: BTreeMap<String, f64>,
    /// Paper eq. 10 (normalised) at the result.
    pub objective: f64,
    /// Residual sum of squares at the result.
    pub ssr: f64,
    /// Number of residuals (measured samples × signals taking part).
    pub residuals: usize,
    /// Objective after the global stage alone.
    pub global_objective: f64,
    /// Model runs (simulations or steady solves of the whole data set) in total.
    pub model_runs: usize,
    /// Wall time, s (reporting only).
    pub wall_s: f64,
    /// Signals that took part.
    pub signals: Vec<Signal>,
    /// Method A: the steady windows used, (start, end) times in s.
    pub windows: Vec<(f64, f64)>,
    /// Fitted ambient pressure and its 1σ, kPa (when fitted as a nuisance parameter).
    pub ambient_kpa: Option<(f64, f64)>,
    /// The fuel meter's zero read before light-off and taken off every fuel reading before
    /// the fit (`None`: it read nothing at rest, or the data start later); see
    /// [`crate::recording::Recording::fuel_meter_zero`].
    pub fuel_meter_zero: Option<crate::recording::FuelZero>,
    /// Method B: the holes in the record (an outage, lost samples), across which the measured
    /// inputs were interpolated and after which the model's shaft speeds were set to the
    /// measured ones; see [`crate::recording::Recording::holes`].
    pub record_holes: Vec<crate::recording::Hole>,
    /// Every fitted parameter (health, ambient pressure, engine/effect values) with its 1σ,
    /// in the optimiser's order.
    pub params: Vec<FittedParam>,
    /// Model evaluations that failed during the fit, by reason.
    pub failures: Failures,
    /// Whether the fitted model reproduces the data (`good` / `suspect` / `poor`) and the
    /// numbers behind it: a health estimate from a model that does not fit is not clean.
    pub fit_quality: fit_quality::FitQuality,
    /// Which health parameters the compared signals separate, which only in combination, and
    /// which not at all (see [`separability`]).
    pub separability: separability::Separability,
    /// Residual map, signals × phases (Method B; empty for Method A).
    pub localisation: Vec<fit_quality::ResidualCell>,
    /// What the fit left out and why: on an adapted engine file, the steady windows (Method A)
    /// or the samples (Method B) whose GG runs beyond the speeds the adaptation was calibrated
    /// at (`[adaptation.calibrated]`), where its curves are extrapolated.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub left_out: Vec<String>,
    /// The prior the least-squares stage took on the health parameters and which of them the
    /// data left to it ([`prior`]); `None` when it took none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub health_prior: Option<prior::PriorReport>,
    /// The fitted model's instrument values, rows like the data's (Method B; empty for Method
    /// A). For plots (before/after traces); not serialised.
    #[serde(skip)]
    pub model_values: Vec<crate::engine::trace::Values>,
}

/// One fitted parameter as reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FittedParam {
    pub name: String,
    pub value: f64,
    /// 1σ (inflated like the health σ).
    pub sigma: f64,
    pub target: ParamTarget,
}

impl MethodResult {
    /// Health vector as name → value.
    pub fn health_map(&self) -> BTreeMap<String, f64> {
        health_map(&self.health)
    }
}

/// A health vector as name → value (ordered by name for stable JSON).
pub fn health_map(h: &HealthParams) -> BTreeMap<String, f64> {
    HEALTH_NAMES
        .iter()
        .zip(h.to_array())
        .map(|(n, v)| (n.to_string(), v))
        .collect()
}

/// What the optimisation stage found.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOutcome {
    /// Best free-parameter vector.
    pub x: Vec<f64>,
    /// Eq. 10 after the global stage.
    pub global_objective: f64,
    /// 1σ per free parameter.
    pub sigma: Vec<f64>,
    /// Correlation matrix of the free parameters (zeros where not estimated).
    pub correlation: Vec<Vec<f64>>,
    /// 1σ per free parameter from the noise of the measured inputs (added to `sigma` in
    /// quadrature once `sigma` is inflated for correlated residuals).
    pub input_sigma: Vec<f64>,
    /// Correlation of that part between the free parameters (zeros where not estimated).
    pub input_correlation: Vec<Vec<f64>>,
    /// The prior's 1σ on the health parameters, points, where the least-squares stage took
    /// one ([`prior`]).
    pub prior_pts: Option<f64>,
}

fn unit_step_jacobian(cfg: &DiagnosisConfig) -> Result<JacobianOptions, OptimError> {
    JacobianOptions::default().with_step(cfg.fd_step)
}

/// Runs the configured optimiser on `problem` and estimates the uncertainty at the result.
pub fn fit<P: DiagnosisProblem>(
    problem: &mut P,
    cfg: &DiagnosisConfig,
    pool: &ThreadPool,
) -> Result<FitOutcome, DiagnosisError> {
    cfg.validate()?;
    let n = problem.dim();
    let x0 = problem.params().project(&cfg.base);
    let lm_budget = match cfg.optimiser {
        Optimiser::CuckooLm => cfg.lm_runs.min(cfg.max_model_runs.saturating_sub(n + 2)),
        _ => 0,
    };
    let global_budget = cfg.max_model_runs.saturating_sub(lm_budget);
    // LM, not the global stage, finds the optimum of a health fit: the global stage only picks
    // LM's start (see `DiagnosisConfig::global_runs`).
    let global_budget = match cfg.optimiser {
        Optimiser::CuckooLm if cfg.extra_params.is_empty() => global_budget.min(cfg.global_runs),
        _ => global_budget,
    }
    .max(1);
    let budget = Budget::new()
        .with_max_evals(global_budget)?
        .with_stall(cfg.stall_generations.max(1), cfg.stall_tol)?;
    let cancel = cfg.cancel.clone();
    problem.set_least_squares(false);
    let global = match cfg.optimiser {
        Optimiser::Cuckoo | Optimiser::CuckooLm => {
            let mut s = CuckooSearch::new(cfg.seed).with_initial_guess(x0.clone())?;
            run(&mut s, &*problem, &budget, &cancel, pool)?
        }
        Optimiser::CmaEs => {
            let mut s = CmaEs::new(cfg.seed).with_initial_guess(x0.clone())?;
            run(&mut s, &*problem, &budget, &cancel, pool)?
        }
        Optimiser::De => {
            let mut s = DifferentialEvolution::new(cfg.seed).with_initial_guess(x0.clone())?;
            run(&mut s, &*problem, &budget, &cancel, pool)?
        }
    };
    let global_objective = global.cost;
    if !global_objective.is_finite() {
        let f = problem.failures();
        return Err(DiagnosisError::AllEvaluationsFailed {
            runs: problem.model_runs(),
            reasons: f
                .reasons
                .iter()
                .map(|(r, c)| format!("{r} (×{c})"))
                .collect::<Vec<_>>()
                .join("; "),
        });
    }
    let mut x = global.x.clone();
    // The prior's rows carry the weight of the data's residuals: each in its instrument's σ,
    // counted as often as their serial correlation says (from the plain residuals at the
    // global result, as `result_of` inflates σ).
    let plain = match cfg.health_prior_pts > 0.0 && !cancel.is_cancelled() {
        true => {
            let mut r = Vec::new();
            problem.residuals(&x, &mut r);
            let ssr: f64 = r.iter().map(|v| v * v).sum();
            ssr.is_finite().then(|| (ssr, problem.sigma_inflation(&r)))
        }
        false => None,
    };
    if !cancel.is_cancelled() {
        problem.prepare_least_squares(&x, pool);
    }
    problem.set_least_squares(true);
    let prior_rows: Vec<prior::PriorRow> = plain
        .and_then(|(ssr, inflation)| {
            // The data's covariance of the health parameters at the global result, in points²
            // as the rows weigh them: the least-squares stage's (JᵀJ)⁻¹ times c². Its sum of
            // squares there is the stage's (whitened) one, against the plain `ssr`.
            let u = uncertainty(&*problem, &x, &unit_step_jacobian(cfg).ok()?, pool).ok()?;
            let c = prior::row_scale(inflation, u.ssr / ssr)?;
            let health: Vec<usize> = problem
                .params()
                .params()
                .iter()
                .enumerate()
                .filter(|(_, p)| matches!(p.target, ParamTarget::Health(_)))
                .map(|(k, _)| k)
                .collect();
            let scale = c * c / u.s2;
            scale.is_finite().then_some(())?;
            let cov: Vec<Vec<f64>> = health
                .iter()
                .map(|&i| health.iter().map(|&j| u.covariance[i][j] * scale).collect())
                .collect();
            Some(prior::weak_direction_rows(
                &health,
                &cov,
                c,
                cfg.health_prior_pts,
            ))
        })
        .unwrap_or_default();
    let prior_pts = (!prior_rows.is_empty()).then_some(cfg.health_prior_pts);
    let posterior = prior::WithPrior::new(&*problem, prior_rows);
    // After a cancel (daemon shutdown) the refinement and the uncertainty (up to a few hundred
    // model runs more) are skipped: the caller discards a cancelled fit anyway.
    if lm_budget >= 2 && !cancel.is_cancelled() {
        let opts = LmOptions::default()
            .with_jacobian(unit_step_jacobian(cfg)?)?
            .with_max_evals(lm_budget)?
            .with_ftol(1e-6)?
            .with_xtol(1e-6)?;
        match refine(&posterior, &x, &opts, pool) {
            Ok(r) => x = r.x,
            // A failed refinement (e.g. non-finite residuals) keeps the global result.
            Err(OptimError::NonFiniteResiduals) => {}
            Err(e) => return Err(e.into()),
        }
    }
    let unknown = || {
        (
            vec![f64::INFINITY; n],
            vec![vec![0.0; n]; n],
            vec![0.0; n],
            vec![vec![0.0; n]; n],
        )
    };
    let (sigma, correlation, input_sigma, input_correlation) = if cancel.is_cancelled() {
        unknown()
    } else {
        let draws: Vec<Vec<f64>> = problem
            .input_noise_draws(&x)
            .into_iter()
            .map(|d| posterior.extend(&x, d))
            .collect();
        match uncertainty_with_inputs(&posterior, &x, &unit_step_jacobian(cfg)?, pool, &draws) {
            Ok(u) => (u.sigma, u.correlation, u.input_sigma, u.input_correlation),
            Err(OptimError::NonFiniteResiduals) | Err(OptimError::TooFewResiduals { .. }) => {
                unknown()
            }
            Err(e) => return Err(e.into()),
        }
    };
    problem.set_least_squares(false);
    Ok(FitOutcome {
        x,
        global_objective,
        sigma,
        correlation,
        input_sigma,
        input_correlation,
        prior_pts,
    })
}

/// Assembles a [`MethodResult`] after [`fit`] (the caller sets `wall_s`).
pub(crate) fn result_of<P: DiagnosisProblem>(
    method: Method,
    problem: &P,
    fit: &FitOutcome,
    cfg: &DiagnosisConfig,
    signals: Vec<Signal>,
    residuals: usize,
    windows: Vec<(f64, f64)>,
) -> MethodResult {
    let pm = problem.params();
    let mut sigma: BTreeMap<String, f64> =
        HEALTH_NAMES.iter().map(|n| (n.to_string(), 0.0)).collect();
    let objective = problem.eq10(&fit.x);
    let mut r = Vec::new();
    problem.residuals(&fit.x, &mut r);
    let ssr = r.iter().map(|v| v * v).sum();
    let inflation = problem.sigma_inflation(&r).sqrt();
    let model_health = problem.model_health_sigma();
    // The residuals' σ (inflated for their correlation), the inputs' σ and, for a health
    // parameter, the model's own error in health units, in quadrature.
    let input_part = |k: usize| fit.input_sigma.get(k).copied().unwrap_or(0.0);
    let fit_part = |k: usize, s: f64| (s * inflation).hypot(input_part(k));
    let total = |k: usize, s: f64| {
        let model = match pm.params().get(k).map(|p| &p.target) {
            Some(ParamTarget::Health(i)) => model_health.get(*i).copied().unwrap_or(0.0),
            _ => 0.0,
        };
        fit_part(k, s).hypot(model)
    };
    // Parameter k's σ in all (∞ where the fit has none).
    let total_sigma = |k: usize| fit.sigma.get(k).map_or(f64::INFINITY, |&s| total(k, s));
    for (k, (p, &s)) in pm.params().iter().zip(&fit.sigma).enumerate() {
        if let ParamTarget::Health(i) = p.target {
            sigma.insert(HEALTH_NAMES[i].to_string(), total(k, s));
        }
    }
    let params = pm
        .params()
        .iter()
        .zip(&fit.x)
        .zip(&fit.sigma)
        .enumerate()
        .map(|(k, ((p, &value), &s))| FittedParam {
            name: p.name.clone(),
            value,
            sigma: total(k, s),
            target: p.target.clone(),
        })
        .collect();
    let ambient_index = pm
        .params()
        .iter()
        .position(|p| p.target == ParamTarget::AmbientPressure);
    let health_at: Vec<(usize, usize)> = pm
        .params()
        .iter()
        .enumerate()
        .filter_map(|(k, p)| match p.target {
            ParamTarget::Health(i) => Some((k, i)),
            _ => None,
        })
        .collect();
    let health_estimates: Vec<separability::HealthEstimate> = health_at
        .iter()
        .map(|&(k, i)| separability::HealthEstimate {
            index: i,
            value: fit.x[k],
            sigma: total_sigma(k),
            // Each part's covariance with its own correlation, over the totals: the residuals'
            // ρ·σₖσₗ, the inputs' (one fuel meter moves D_GC and D_GT together) and the
            // model's own error, independent between parameters, which weakens both.
            correlation: health_at
                .iter()
                .map(|&(l, _)| {
                    let at = |m: &[Vec<f64>]| {
                        m.get(k).and_then(|row| row.get(l)).copied().unwrap_or(0.0)
                    };
                    let rho = at(&fit.correlation);
                    let residual_part =
                        |m: usize| fit.sigma.get(m).map_or(f64::INFINITY, |&s| s * inflation);
                    let cov = rho * residual_part(k) * residual_part(l)
                        + at(&fit.input_correlation) * input_part(k) * input_part(l);
                    let r = cov / (total_sigma(k) * total_sigma(l));
                    if k == l || !r.is_finite() {
                        rho
                    } else {
                        r
                    }
                })
                .collect(),
        })
        .collect();
    let signal_names: Vec<String> = signals.iter().map(|s| s.column().to_string()).collect();
    // Plausibility is judged on the whole vector (a turbine's capacity above new with its
    // efficiency loss is erosion); parameters not fitted count as new with no information.
    let mut h_all = [0.0; 6];
    let mut sigma_all = [f64::INFINITY; 6];
    for e in &health_estimates {
        if e.index < 6 {
            h_all[e.index] = e.value;
            sigma_all[e.index] = e.sigma;
        }
    }
    let below = crate::health::below_plausible_each(&h_all, &sigma_all);
    let flags = fit_quality::HealthFlags {
        at_limit: health_at
            .iter()
            .filter_map(|&(k, _)| {
                let p = &pm.params()[k];
                fit_quality::LimitHit::of(&p.name, fit.x[k], p.lower, p.upper)
            })
            .collect(),
        implausible: health_estimates
            .iter()
            .filter(|e| below.get(e.index).is_some_and(|b| *b > 0.0))
            .map(|e| fit_quality::Implausible {
                name: HEALTH_NAMES[e.index].to_string(),
                value: e.value,
                sigma: e.sigma,
            })
            .collect(),
    };
    MethodResult {
        method,
        optimiser: cfg.optimiser,
        health: pm.health(&fit.x),
        sigma,
        objective,
        ssr,
        residuals,
        global_objective: fit.global_objective,
        model_runs: problem.model_runs(),
        wall_s: 0.0,
        signals,
        windows,
        ambient_kpa: pm.ambient(&fit.x).map(|p| {
            (
                p,
                ambient_index
                    .and_then(|i| fit.sigma.get(i))
                    .copied()
                    .unwrap_or(f64::NAN)
                    * inflation,
            )
        }),
        params,
        failures: problem.failures(),
        fit_quality: fit_quality::assess(
            ssr / residuals.max(1) as f64,
            &[],
            &[],
            &flags,
            &cfg.quality,
        ),
        separability: separability::assess(&health_estimates, &signal_names),
        localisation: Vec::new(),
        fuel_meter_zero: None,
        record_holes: Vec::new(),
        left_out: Vec::new(),
        health_prior: fit.prior_pts.map(|p| {
            let sigma = |k: usize| fit.sigma.get(k).map_or(f64::INFINITY, |&s| fit_part(k, s));
            prior::PriorReport::of(p, health_at.iter().map(|&(k, i)| (i, sigma(k))))
        }),
        model_values: Vec::new(),
    }
}

/// A thread pool for `cfg.threads`.
pub fn pool_for(cfg: &DiagnosisConfig) -> Result<ThreadPool, DiagnosisError> {
    Ok(optim::thread_pool(cfg.threads)?)
}

#[cfg(test)]
mod tests {
    use super::bench::synthetic_startup;
    use super::identifiability::identifiability;
    use super::steady::{detect_windows, diagnose_steady};
    use super::transient::{diagnose_transient, TransientProblem};
    use super::*;
    use crate::engine::Engine;
    use crate::signals::Phase;

    fn truth() -> HealthParams {
        HealthParams {
            D_GC: 3.0,
            D_EC: 1.0,
            D_GT: 1.5,
            D_ET: 1.0,
            D_GP: 0.5,
            D_EP: 0.8,
        }
    }

    fn errors(h: &HealthParams, t: &HealthParams) -> [f64; 6] {
        let (a, b) = (h.to_array(), t.to_array());
        std::array::from_fn(|i| (a[i] - b[i]).abs())
    }

    fn small(cfg: DiagnosisConfig) -> DiagnosisConfig {
        DiagnosisConfig {
            max_model_runs: 300,
            lm_runs: 200,
            threads: Some(2),
            ..cfg
        }
    }

    #[test]
    fn method_b_recovers_implanted_degradation() {
        let engine = Engine::reference().expect("engine");
        let t = truth();
        let cfg = small(DiagnosisConfig::default());
        // Noise-free: every parameter within 0.05 points.
        let clean = synthetic_startup(&engine, &t, 0, false).expect("start-up");
        let r = diagnose_transient(&engine, &clean, &cfg).expect("diagnoses");
        let e = errors(&r.health, &t);
        assert!(e.iter().all(|&x| x < 0.05), "noise-free errors {e:?}");
        assert!(r.sigma.values().all(|s| s.is_finite() && *s > 0.0));
        assert!(r.model_runs > 0 && r.objective < r.global_objective + 1e-12);
        // Default noise and lags: within 0.5 points.
        let noisy = synthetic_startup(&engine, &t, 5, true).expect("start-up");
        let r = diagnose_transient(&engine, &noisy, &cfg).expect("diagnoses");
        let e = errors(&r.health, &t);
        assert!(e.iter().all(|&x| x < 0.5), "noisy errors {e:?}");
        // The ambient pressure, fitted from P1 over the whole start-up, is better than the
        // ±0.03 kPa of the rest-sample average it starts from.
        let (p, sp) = r.ambient_kpa.expect("ambient fitted by default");
        assert!(
            (p - 101.325).abs() < 0.02 && sp > 0.0 && sp < 0.02,
            "{p} ± {sp}"
        );
    }

    #[test]
    fn method_b_with_fixed_parameters_and_cuckoo_alone() {
        // Two free parameters (PT), the rest fixed at the truth: even CS alone gets close.
        let engine = Engine::reference().expect("engine");
        let t = truth();
        let clean = synthetic_startup(&engine, &t, 0, false).expect("start-up");
        let cfg = DiagnosisConfig {
            fixed: [true, true, true, true, false, false],
            base: t,
            optimiser: Optimiser::Cuckoo,
            max_model_runs: 150,
            threads: Some(2),
            ..DiagnosisConfig::default()
        };
        let r = diagnose_transient(&engine, &clean, &cfg).expect("diagnoses");
        assert_eq!(r.health.D_GC, 3.0);
        assert_eq!(r.sigma["D_GC"], 0.0);
        let e = errors(&r.health, &t);
        assert!(e[4] < 0.3 && e[5] < 0.3, "CS alone, 2 parameters: {e:?}");
    }

    #[test]
    fn method_a_recovers_and_is_deterministic() {
        let engine = Engine::reference().expect("engine");
        let t = truth();
        let clean = synthetic_startup(&engine, &t, 0, false).expect("start-up");
        let w = detect_windows(&clean, engine.cfg(), &SteadyCriteria::default());
        // The 4-min warm-up at minimum load and the base-load hold, never the load ramp.
        assert!(w.len() >= 2, "{w:?}");
        for win in &w {
            let ph = clean.phases()[win.start];
            assert!(
                matches!(
                    ph,
                    Phase::Loading | Phase::Steady | Phase::Idle | Phase::Synchronisation
                ),
                "{ph}"
            );
            let p0 = clean.rows()[win.start][Signal::Power.index()];
            let p1 = clean.rows()[win.end - 1][Signal::Power.index()];
            assert!((p1 - p0).abs() < 0.2, "window spans a ramp: {p0} → {p1}");
        }
        let cfg = DiagnosisConfig {
            threads: Some(1),
            ..DiagnosisConfig::default()
        };
        let r = diagnose_steady(&engine, &clean, &cfg).expect("diagnoses");
        let e = errors(&r.health, &t);
        assert!(e.iter().all(|&x| x < 0.05), "noise-free errors {e:?}");
        let noisy = synthetic_startup(&engine, &t, 9, true).expect("start-up");
        let r1 = diagnose_steady(&engine, &noisy, &cfg).expect("diagnoses");
        let e = errors(&r1.health, &t);
        assert!(e.iter().all(|&x| x < 0.5), "noisy errors {e:?}");
        // The ambient pressure is fitted (it moves the model, so it has a finite σ).
        let (p, sp) = r1.ambient_kpa.expect("ambient fitted by default");
        assert!(
            (p - 101.325).abs() < 0.1 && sp.is_finite() && sp > 0.0,
            "{p} ± {sp}"
        );
        // Same seed, 1 or 2 threads: the same result.
        let r2 = diagnose_steady(
            &engine,
            &noisy,
            &DiagnosisConfig {
                threads: Some(2),
                ..cfg.clone()
            },
        )
        .expect("diagnoses");
        assert_eq!(r1.health, r2.health);
        assert_eq!(r1.sigma, r2.sigma);
        // An adapted file's own error in health units: the same read, D_GC's σ widened in
        // quadrature and D_GC no longer called separable; the others as they were.
        let mut file = engine.cfg().clone();
        let mut a = crate::engine::config::AdaptationConfig::default();
        a.health_error.insert("D_GC".into(), 0.6);
        file.adaptation = Some(a);
        let adapted = Engine::new(file).expect("engine");
        let r3 = diagnose_steady(&adapted, &noisy, &cfg).expect("diagnoses");
        assert_eq!(r3.health, r1.health);
        let widened = r1.sigma["D_GC"].hypot(0.6);
        assert!((r3.sigma["D_GC"] - widened).abs() < 1e-9, "{:?}", r3.sigma);
        assert_eq!(r3.sigma["D_EC"], r1.sigma["D_EC"]);
        assert!(r1.separability.separable.contains(&"D_GC".to_string()));
        assert!(
            !r3.separability.separable.contains(&"D_GC".to_string()),
            "{:?}",
            r3.separability
        );
    }

    #[test]
    fn start_up_identifies_all_six_parameters() {
        let engine = Engine::reference().expect("engine");
        let t = truth();
        let clean = synthetic_startup(&engine, &t, 0, false).expect("start-up");
        let cfg = DiagnosisConfig::default();
        let p = TransientProblem::new(&engine, &clean, &cfg).expect("problem");
        let pool = optim::thread_pool(Some(2)).expect("pool");
        let id = identifiability(&p, &t.to_array(), cfg.fd_step, &pool).expect("computes");
        // Cramér–Rao 1σ at the default noise well below the 0.3-point target for every one.
        assert!(id.crb_sigma.iter().all(|s| *s < 0.1), "{:?}", id.crb_sigma);
        assert!(id.condition < 200.0, "condition {}", id.condition);
    }

    /// A problem whose model always fails: the fit says why instead of returning `± inf`.
    struct Failing {
        objective: objective::Objective,
        params: ParamMap,
        least_squares: bool,
        runs: std::sync::atomic::AtomicUsize,
        failures: FailureLog,
    }

    impl Failing {
        fn simulate(&self, _x: &[f64]) -> Result<Vec<crate::signals::Values>, EvalError> {
            self.runs.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            Err(EvalError::Model(
                "simulation failed at t = 3.00 s: boom".into(),
            ))
        }
        fn health_sigma(&self) -> [f64; 6] {
            [0.0; 6]
        }
        fn residual_inflation(&self, _r: &[f64]) -> f64 {
            1.0
        }
        fn input_draws(&self, _x: &[f64]) -> Vec<Vec<f64>> {
            Vec::new()
        }
        fn whiten(&self, _r: &mut [f64]) {}
        fn input_covariance(&mut self, _x: &[f64], _pool: &rayon::ThreadPool) {}
    }

    impl_diagnosis_problem!(Failing);

    #[test]
    fn a_fit_whose_every_evaluation_fails_says_why() {
        let points: Vec<Vec<(Signal, f64, f64)>> = (0..4)
            .map(|k| {
                vec![
                    (Signal::N1, 9000.0 + k as f64, 5.0),
                    (Signal::T2, 700.0, 1.0),
                ]
            })
            .collect();
        let mut p = Failing {
            objective: objective::Objective::from_points(&points),
            params: ParamMap::new(
                vec![FitParam::health(0).expect("D_GC")],
                HealthParams::HEALTHY,
                vec![0.0],
            )
            .expect("map"),
            least_squares: false,
            runs: Default::default(),
            failures: FailureLog::default(),
        };
        let cfg = DiagnosisConfig {
            max_model_runs: 20,
            threads: Some(1),
            ..DiagnosisConfig::default()
        };
        let pool = pool_for(&cfg).expect("pool");
        let e = fit(&mut p, &cfg, &pool).expect_err("nothing to fit");
        let text = e.to_string();
        assert!(
            matches!(e, DiagnosisError::AllEvaluationsFailed { runs, .. } if runs > 0),
            "{text}"
        );
        assert!(text.contains("boom"), "{text}");
        let f = p.failures();
        assert_eq!(f.count, p.model_runs());
        // A zero budget is refused before any run.
        let zero = DiagnosisConfig {
            max_model_runs: 0,
            ..cfg
        };
        let e = fit(&mut p, &zero, &pool).expect_err("zero budget");
        assert!(matches!(e, DiagnosisError::Config(_)), "{e}");
    }

    #[test]
    fn bad_data_gives_clear_errors() {
        let engine = Engine::reference().expect("engine");
        let t = truth();
        let mut seg = synthetic_startup(&engine, &t, 0, false).expect("start-up");
        // No steady window: cut the segment before the load is applied.
        let keep = seg
            .phases()
            .iter()
            .position(|p| *p == Phase::Synchronisation)
            .expect("syncs");
        seg = seg.truncated(keep).expect("still a recording");
        let cfg = DiagnosisConfig::default();
        let e = diagnose_steady(&engine, &seg, &cfg).expect_err("no windows");
        assert!(e.to_string().contains("steady"), "{e}");
        // Nothing measured in the window.
        let mut empty = seg.clone();
        for k in 0..empty.len() {
            for s in Signal::ALL {
                empty.set(k, s, f64::NAN).expect("missing is fine");
            }
        }
        assert!(TransientProblem::new(&engine, &empty, &cfg).is_err());
    }
}
