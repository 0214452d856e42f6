//! The diagnosis settings: which method, which optimiser, the window of the start-up, the
//! steady-window criteria of Method A, and [`DiagnosisConfig`] (budget, seed, threads, fitted
//! and fixed parameters, fit-quality thresholds, cancellation). Plain data with validation; no
//! I/O. Must not run a diagnosis.

use super::fit_quality;
use super::params::FitParam;
use super::DiagnosisError;
use crate::engine::measured_drive::DriveMode;
use crate::health::{HealthBounds, HealthParams};
use crate::optim::Cancel;
use crate::signals::{Phase, Signal};
use serde::Serialize;

/// Which method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Method B: the whole start-up.
    Transient,
    /// Method A: averaged steady windows.
    Steady,
}

impl Method {
    /// `transient` / `steady`.
    pub fn name(self) -> &'static str {
        match self {
            Method::Transient => "transient",
            Method::Steady => "steady",
        }
    }
}

/// The optimisation strategy. All are run under the same model-run budget
/// ([`DiagnosisConfig::max_model_runs`]), so they can be compared at equal cost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Optimiser {
    /// Cuckoo search alone (the paper).
    Cuckoo,
    /// Cuckoo search, then Levenberg–Marquardt on the residuals (default: measured best, see
    /// the crate's bench figures in `bench`).
    CuckooLm,
    /// CMA-ES alone.
    CmaEs,
    /// Differential evolution (rand/1/bin) alone.
    De,
}

impl Optimiser {
    /// Short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Optimiser::Cuckoo => "cuckoo",
            Optimiser::CuckooLm => "cuckoo_lm",
            Optimiser::CmaEs => "cmaes",
            Optimiser::De => "de",
        }
    }
    /// Parses the short name.
    pub fn parse(s: &str) -> Option<Optimiser> {
        [
            Optimiser::Cuckoo,
            Optimiser::CuckooLm,
            Optimiser::CmaEs,
            Optimiser::De,
        ]
        .into_iter()
        .find(|o| o.name().eq_ignore_ascii_case(s.trim()))
    }
}

/// Which samples of the segment take part in Method B's objective.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Window {
    /// Phases whose samples count (the model is still run through the whole segment).
    pub phases: Vec<Phase>,
    /// Only samples at or after this time, s (segment time axis).
    pub t_from_s: Option<f64>,
    /// Only samples at or before this time, s.
    pub t_to_s: Option<f64>,
    /// Only every other block of this many seconds (blocked cross-validation: the gap analysis
    /// fits on one set of blocks and scores on the other); `None` = every sample.
    pub blocks: Option<Blocks>,
}

/// Alternate blocks of the time axis: block `floor(t / length_s)` is in the fold when its
/// parity is `parity` (0 or 1). Blocks longer than the residuals' correlation keep the two
/// folds nearly independent while each still samples every phase of a start-up.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Blocks {
    pub length_s: f64,
    pub parity: u8,
}

impl Blocks {
    /// Whether time `t` is in this fold.
    pub fn contains(&self, t: f64) -> bool {
        let b = (t / self.length_s).floor();
        b.is_finite() && (b.rem_euclid(2.0) as u8) == self.parity % 2
    }

    /// The other fold.
    pub fn complement(self) -> Blocks {
        Blocks {
            parity: (self.parity + 1) % 2,
            ..self
        }
    }
}

impl Default for Window {
    /// Every phase of a start-up with the engine turning ([`Phase::STARTUP`]: crank to steady).
    fn default() -> Self {
        Window {
            phases: Phase::STARTUP.to_vec(),
            t_from_s: None,
            t_to_s: None,
            blocks: None,
        }
    }
}

impl Window {
    /// Whether sample (t, phase) is inside.
    pub fn contains(&self, t: f64, phase: Phase) -> bool {
        self.phases.contains(&phase)
            && self.t_from_s.is_none_or(|a| t >= a)
            && self.t_to_s.is_none_or(|b| t <= b)
            && self.blocks.is_none_or(|b| b.contains(t))
    }
}

/// Stability criteria for Method A's steady windows (see [`steady::detect_windows`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SteadyCriteria {
    /// Signals that must be stable.
    pub signals: Vec<Signal>,
    /// Minimum window length, s.
    pub min_duration_s: f64,
    /// Drift allowed over the window (least-squares slope × duration), in noise σ.
    pub max_drift_sigma: f64,
    /// Scatter allowed around the linear trend (RMS), in noise σ.
    pub max_scatter_sigma: f64,
    /// Largest deviation of any sample from the trend, in noise σ.
    pub max_deviation_sigma: f64,
    /// GG speed must be at least this fraction of design (fired, above idle transients).
    pub min_n1_fraction: f64,
    /// Settling guard: the first part of a window this long is not averaged (when at least
    /// `min_duration_s` remains), because a window opens as soon as the drift falls inside the
    /// noise band, i.e. still on the tail of the preceding transient, s.
    pub settle_s: f64,
}

impl Default for SteadyCriteria {
    /// n1, P2, T2, T34 and power stable; ≥ 20 s; drift ≤ 2σ; scatter ≤ 1.5σ;
    /// every sample within 4.5σ of the trend; n1 ≥ 60 % design; first 30 s of a window not averaged.
    fn default() -> Self {
        SteadyCriteria {
            signals: vec![
                Signal::N1,
                Signal::P2,
                Signal::T2,
                Signal::T34,
                Signal::Power,
            ],
            min_duration_s: 20.0,
            max_drift_sigma: 2.0,
            max_scatter_sigma: 1.5,
            max_deviation_sigma: 4.5,
            min_n1_fraction: 0.6,
            settle_s: 30.0,
        }
    }
}

/// Settings of a diagnosis. `Default` is the documented default of `gtwatch diagnose`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiagnosisConfig {
    /// Output signals compared with the model. Operating inputs (T1; P1 unless the ambient
    /// pressure is fitted; fuel flow when it drives the model) are dropped automatically;
    /// signals the data lack are skipped.
    pub signals: Vec<Signal>,
    /// Method B's window.
    pub window: Window,
    /// Method B's drive: measured fuel (default) or speed/power demand.
    pub drive_mode: DriveMode,
    /// Method B's allowance for model timing error, as a multiple of a sample's change to its
    /// neighbour, combined with the noise σ (see [`objective::Objective::new`]).
    pub rate_weight: f64,
    /// Smooth the measured fuel flow before it drives the model (Method B, measured-fuel
    /// mode; see [`transient::smooth_fuel`]).
    pub smooth_fuel: bool,
    /// Method B's least-squares stage fits under the residuals' covariance from the fuel
    /// meter's slow noise (measured-fuel mode; see [`super::fuel_noise`]). Off: ordinary least
    /// squares, as the gap analysis fits (the covariance would discount the slow patterns it
    /// looks for) and for comparison.
    pub fuel_noise_covariance: bool,
    /// Snapshots: each row's measured inputs (fuel flow, T1, n2; P1 where it gives the ambient
    /// pressure) carry one reading's instrument noise, and the fit runs under the covariance it
    /// gives the row's compared values (see [`super::steady::with_input_noise`]). Off (the
    /// default): the fit and its verdict take a row's inputs as given, as a performance test's or
    /// a historian's averages nearly are, and their noise is in the read's σ only
    /// ([`super::steady::InputNoise::SigmaOnly`]); on for spot readings. Method A's windows
    /// always carry their inputs' noise (window means of the same record, σ/√n).
    pub snapshot_input_noise: bool,
    /// Method A's stability criteria.
    pub steady: SteadyCriteria,
    /// Optimisation strategy.
    pub optimiser: Optimiser,
    /// Model runs for the optimisation (global + local), per method. The uncertainty estimate
    /// costs 2 × (free parameters) + 1 more runs, reported in `model_runs`.
    pub max_model_runs: usize,
    /// Of those, the runs reserved for Levenberg–Marquardt ([`Optimiser::CuckooLm`]).
    pub lm_runs: usize,
    /// With [`Optimiser::CuckooLm`] and no extra fitted parameters: the most runs the global
    /// stage takes before Levenberg–Marquardt starts from its best point (default 25: the
    /// healthy engine and 24 random nests, one cuckoo population). On `bench diagnosis --cases
    /// 8 --seed 7` the global stage's 200 runs before and these 25 led LM to the same optimum
    /// (estimates within 0.0005 points, the same RMSE) at half the model runs. Fits with extra
    /// parameters (engine or effect values) keep the whole global budget.
    pub global_runs: usize,
    /// Global stage stops early after this many generations without relative improvement
    /// above `stall_tol`.
    pub stall_generations: usize,
    /// Relative improvement tolerance of the stall rule.
    pub stall_tol: f64,
    /// Seed of the global optimiser.
    pub seed: u64,
    /// Worker threads (`None` = all cores).
    pub threads: Option<usize>,
    /// Finite-difference step of the LM/uncertainty Jacobian, fraction of the −3 … +10 % box.
    pub fd_step: f64,
    /// Fixed integrator step for Method B's simulations, s (0 = the engine's adaptive
    /// integrator). A fixed step makes the simulated traces a smooth function of the health
    /// parameters, which the finite-difference Jacobian needs.
    pub fixed_step_s: f64,
    /// Fit the ambient pressure as a nuisance parameter, with the compressor inlet pressure P1
    /// compared as an output over the whole segment. Without it the ambient pressure comes from
    /// the few samples at rest before the start (`Recording::ambient`), and the noise of that
    /// average (≈ 0.03 % for 10 samples) was measured to be the largest single error source of
    /// both methods (0.1 points on D_EP, 0.1 on D_GC).
    pub fit_ambient_pressure: bool,
    /// Parameters held at `base` (not fitted), by index into [`HEALTH_NAMES`].
    pub fixed: [bool; 6],
    /// Values of the fixed parameters (and the start nest of the global search).
    pub base: HealthParams,
    /// Further fitted parameters: engine-file values or effect parameters
    /// ([`FitParam::engine_value`], [`FitParam::effect`]), started at the engine's values and
    /// appended after the health parameters and the ambient pressure. Empty by default.
    pub extra_params: Vec<FitParam>,
    /// Search interval of each health parameter, percent (default −3 … +10 for all six).
    #[serde(skip_serializing_if = "HealthBounds::is_default")]
    pub health_bounds: HealthBounds,
    /// 1σ of the prior on each fitted health parameter about new, points, taken by the
    /// least-squares stage of a steady diagnosis (Method A, snapshots; see [`super::prior`]);
    /// 0: none (least squares on the data alone, the default).
    #[serde(skip_serializing_if = "is_no_prior")]
    pub health_prior_pts: f64,
    /// The same for Method B; default [`super::prior::DEFAULT_TRANSIENT_HEALTH_PRIOR_PTS`].
    #[serde(skip_serializing_if = "is_no_prior")]
    pub transient_health_prior_pts: f64,
    /// Thresholds of the `fit_quality` verdict.
    #[serde(default)]
    pub quality: fit_quality::Thresholds,
    /// Cooperative cancellation of the optimiser (the daemon ties it to its shutdown); checked
    /// between generations of the global stage.
    #[serde(skip)]
    pub cancel: Cancel,
}

/// A prior's σ of 0 (none) is left out of the serialised settings, as before the key existed.
pub(crate) fn is_no_prior(p: &f64) -> bool {
    *p == 0.0
}

impl Default for DiagnosisConfig {
    fn default() -> Self {
        DiagnosisConfig {
            signals: vec![
                Signal::N1,
                Signal::N2,
                Signal::P1,
                Signal::T2,
                Signal::P2,
                Signal::T34,
                Signal::P34,
                Signal::T4,
                Signal::P4,
                Signal::Power,
                Signal::FuelFlow,
            ],
            window: Window::default(),
            drive_mode: DriveMode::MeasuredFuel,
            rate_weight: 1.0,
            smooth_fuel: true,
            fuel_noise_covariance: true,
            snapshot_input_noise: false,
            steady: SteadyCriteria::default(),
            optimiser: Optimiser::CuckooLm,
            max_model_runs: 400,
            lm_runs: 200,
            global_runs: 25,
            stall_generations: 30,
            stall_tol: 1e-4,
            seed: 1,
            threads: None,
            fd_step: 1e-3,
            fixed_step_s: 0.0,
            fit_ambient_pressure: true,
            fixed: [false; 6],
            base: HealthParams::HEALTHY,
            extra_params: Vec::new(),
            health_bounds: HealthBounds::default(),
            health_prior_pts: super::prior::DEFAULT_HEALTH_PRIOR_PTS,
            transient_health_prior_pts: super::prior::DEFAULT_TRANSIENT_HEALTH_PRIOR_PTS,
            quality: fit_quality::Thresholds::default(),
            cancel: Cancel::new(),
        }
    }
}

impl DiagnosisConfig {
    /// Indices of the fitted health parameters.
    pub fn free(&self) -> Vec<usize> {
        (0..6).filter(|&i| !self.fixed[i]).collect()
    }

    /// Number of fitted parameters besides the ambient pressure.
    pub fn n_fitted(&self) -> usize {
        self.free().len() + self.extra_params.len()
    }

    /// Refuses settings that cannot give a result (issue 12 item 8: `--max-runs 0`).
    pub fn validate(&self) -> Result<(), DiagnosisError> {
        if self.max_model_runs == 0 {
            return Err(DiagnosisError::Config(
                "max_model_runs (--max-runs) must be at least 1".into(),
            ));
        }
        if self.global_runs == 0 {
            return Err(DiagnosisError::Config(
                "global_runs must be at least 1".into(),
            ));
        }
        if self.threads == Some(0) {
            return Err(DiagnosisError::Config("threads must be at least 1".into()));
        }
        for (key, v) in [
            ("health_prior_pts (--health-prior)", self.health_prior_pts),
            (
                "transient_health_prior_pts (--transient-health-prior)",
                self.transient_health_prior_pts,
            ),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(DiagnosisError::Config(format!(
                    "{key} must be a number of points ≥ 0 (0: no prior), not {v}"
                )));
            }
        }
        if let Some(b) = self.window.blocks {
            if !(b.length_s.is_finite() && b.length_s > 0.0) {
                return Err(DiagnosisError::Config(format!(
                    "window block length must be a positive number of seconds, not {}",
                    b.length_s
                )));
            }
        }
        if !(self.fd_step.is_finite() && self.fd_step > 0.0) {
            return Err(DiagnosisError::Config(format!(
                "fd_step must be a positive number, not {}",
                self.fd_step
            )));
        }
        self.health_bounds
            .check()
            .map_err(|e| DiagnosisError::Config(format!("health bounds: {e}")))?;
        if !(self.rate_weight.is_finite() && self.rate_weight >= 0.0) {
            return Err(DiagnosisError::Config(format!(
                "rate_weight must be a non-negative number, not {}",
                self.rate_weight
            )));
        }
        Ok(())
    }
}
