//! Calibration to one unit's healthy baseline (issue 10 item 2): from steady snapshots across
//! the load range (the CSV `gtwatch diagnose --method steady --input` reads) and/or the steady
//! windows of recorded start-ups ([`startup`]), and an engine file
//! whose design values are guesses, fit the design parameters the data can identify and keep
//! the others at their guesses, saying why.
//!
//! Steps ([`calibrate`]):
//! 1. every snapshot becomes a healthy steady operating point exactly as in the snapshot
//!    diagnosis (`diagnosis::snapshot`), compared signals scaled by their one-sample noise σ;
//! 2. the Jacobian of those residuals with respect to the candidates ([`candidates`], each
//!    within its realistic interval) at the guesses feeds the identifiability analysis
//!    ([`identify`]): a parameter is fitted when its 1σ is at most an eighth of its interval
//!    and it correlates with no other fitted one at |ρ| ≥ 0.95;
//! 3. bounded Levenberg–Marquardt (`optim::lm`) fits the identified set;
//! 4. with [`CalibrationSettings::adapt`], the off-design adaptation ([`adapt`]): modification
//!    curves of each component's corrected speed, as many as the data identify, fitted with the
//!    identified design values beside them;
//! 5. the report gives every candidate's guess, fitted value, 1σ and reason, and the
//!    residuals before and after per signal and per operating point.
//!
//! A baseline by definition has health 0, so after calibration the health the diagnosis finds
//! on the same data is ≈ 0 (tests/calibrate_twin.rs). Rows taken before a compressor wash may
//! join it ([`CalibrationSettings::prewash_group`], [`prewash`]): their fouling is found with
//! the calibration, and they show the adaptation the unit off its healthy operating line.
//! Pure: no I/O (`edit` rewrites text the CLI reads and writes).

pub mod adapt;
pub mod candidates;
pub mod dynamics;
pub(crate) mod edit;
pub mod ensemble;
pub(crate) mod identify;
pub mod inlet_law;
pub mod prewash;
pub mod problem;
mod rejudge;
mod report;
pub mod startup;
pub mod synthetic;
pub mod validate;

use crate::diagnosis::snapshot::lines_of;
use crate::diagnosis::snapshot::Snapshot;
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::optim::lm::jacobian_unit;
use crate::optim::{refine, thread_pool, JacobianOptions, LmOptions};
use candidates::Candidate;
use problem::{prepare, CalibrationProblem, PreparedPoints};
use rayon::ThreadPool;
use startup::RestReading;

use rejudge::rejudge;
use report::{param_result, point_residuals, residual_table, signal_residuals};
pub use report::{BaselineFit, Calibration, ParamResult, PointResiduals, SignalResiduals};

/// Why a calibration could not run.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    #[error("parameter `{key}`: {reason}")]
    Param { key: String, reason: String },
    #[error("{0}")]
    Data(String),
    #[error("engine model: {0}")]
    Model(String),
    #[error("{path}: {reason}")]
    File { path: String, reason: String },
    #[error("optimiser: {0}")]
    Optim(String),
}

/// Settings of a calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationSettings {
    /// Levenberg–Marquardt iterations at most.
    pub max_iterations: usize,
    /// Threads for the Jacobian columns (`None` = all cores).
    pub threads: Option<usize>,
    /// Off-design adaptation after the design values ([`adapt`]); `None` = design values only.
    pub adapt: Option<adapt::AdaptSettings>,
    /// The group of rows taken before a compressor wash, at a fouling the calibration finds
    /// ([`prewash`]); `None`: every row is healthy.
    pub prewash_group: Option<String>,
    /// The rows are spot readings: each point is fitted under its inputs' noise
    /// ([`problem::whiten_under_input_noise`]) rather than with its inputs taken as exact.
    pub noisy_inputs: bool,
}

impl CalibrationSettings {
    /// These settings with the turbines' efficiency shape `report`'s adaptation ended with,
    /// fixed (not chosen again); as they are where either has no adaptation.
    pub fn with_efficiency_shape_of(&self, report: &Calibration) -> CalibrationSettings {
        match (&self.adapt, &report.adaptation) {
            (Some(a), Some(r)) => CalibrationSettings {
                adapt: Some(a.with_efficiency_shape_of(r)),
                ..self.clone()
            },
            _ => self.clone(),
        }
    }
}

impl Default for CalibrationSettings {
    fn default() -> Self {
        Self {
            max_iterations: 30,
            threads: None,
            adapt: None,
            prewash_group: None,
            noisy_inputs: false,
        }
    }
}

/// Residuals `(model − measured)/σ` of `engine` as it is on `points` and `rest` (the layout of
/// [`CalibrationProblem::residuals_at`] with no candidate).
pub(crate) fn residuals_of(
    engine: &Engine,
    points: &[problem::CalibrationPoint],
    rest: &[RestReading],
) -> Result<Vec<f64>, CalibrateError> {
    problem::residuals_on(engine, points, rest)
}

pub(crate) fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.iter().sum::<f64>() / v.len() as f64
}

/// Calibrates `engine` (the guesses) to the healthy snapshots `rows` and the pressure readings
/// at rest `rest` (which inform instrument offsets only) over `candidates`.
/// Returns the report and the calibrated engine.
///
/// The steps: the points solved on the healthy model; which candidates the data identify (the
/// Jacobian at the guesses); the fit of the identified set; the off-design adaptation when
/// asked for; the report of the residuals before and after. With
/// [`CalibrationSettings::prewash_group`], that group's fouling is found with the calibration
/// ([`prewash`]).
pub fn calibrate(
    engine: &Engine,
    rows: &[Snapshot],
    rest: &[RestReading],
    candidates: Vec<Candidate>,
    settings: &CalibrationSettings,
) -> Result<(Calibration, Engine), CalibrateError> {
    match &settings.prewash_group {
        None => calibrate_at(engine, rows, rest, candidates, settings, None),
        Some(group) => {
            prewash::calibrate_with_prewash(engine, rows, rest, candidates, settings, group)
        }
    }
}

/// [`calibrate`] with the rows of the group `fouled` names run at its health (every other row
/// healthy).
fn calibrate_at(
    engine: &Engine,
    rows: &[Snapshot],
    rest: &[RestReading],
    candidates: Vec<Candidate>,
    settings: &CalibrationSettings,
    fouled: Option<(&str, HealthParams)>,
) -> Result<(Calibration, Engine), CalibrateError> {
    if candidates.is_empty() {
        return Err(CalibrateError::Data("no candidate parameter to fit".into()));
    }
    let mut prepared = solvable_points(engine, rows, settings.noisy_inputs)?;
    if let Some((group, health)) = fouled {
        for p in prepared.points.iter_mut().filter(|p| p.source == group) {
            p.health = health;
        }
    }
    // The inlet loss law the measured P1 shows, before anything is fitted with the file's.
    let inlet_loss_law = inlet_law::choose(engine, &prepared.points, prepared.ambient_from_p1);
    let with_law;
    let mut candidates = candidates;
    let engine = match &inlet_loss_law {
        Some(c) if c.changed() => {
            // The new law with the loss its fit measured, as the engine's value and as the
            // first guess of the design calibration (which refits it where identified).
            let range = crate::engine::config::param_range("design.inlet_loss_frac");
            let frac = range.map_or(c.frac, |r| c.frac.clamp(r.min, r.max));
            let mut cfg = engine.cfg().clone();
            cfg.design.inlet_loss_law = c.chosen;
            cfg.design.inlet_loss_frac = frac;
            with_law = engine
                .with_config(cfg)
                .map_err(|e| CalibrateError::Model(e.to_string()))?;
            for cand in candidates
                .iter_mut()
                .filter(|k| k.key == "design.inlet_loss_frac")
            {
                cand.guess = frac.clamp(cand.lower, cand.upper);
            }
            &with_law
        }
        _ => engine,
    };
    let pool = thread_pool(settings.threads).map_err(|e| CalibrateError::Optim(e.to_string()))?;
    let jac_opts = JacobianOptions::default()
        .with_step(1e-3)
        .map_err(|e| CalibrateError::Optim(e.to_string()))?;
    let full = CalibrationProblem::new(
        engine,
        prepared.points.clone(),
        rest.to_vec(),
        candidates.clone(),
    )?;
    let x0 = full.guesses();
    let r0 = full.residuals_at(&x0)?;
    let mut verdicts = identifiability(&full, &candidates, (&x0, &r0), &jac_opts, &pool, &prepared);
    // Fit the identified set (the others stay at their guesses in the engine).
    let mut chosen: Vec<usize> = (0..candidates.len())
        .filter(|&j| verdicts[j].identifiable)
        .collect();
    let mut fitted = x0.clone();
    let mut lm = if chosen.is_empty() {
        LmFit {
            iterations: 0,
            stop: "nothing identifiable to fit".to_string(),
            runs: 0,
        }
    } else {
        let sub = CalibrationProblem::new(
            engine,
            prepared.points.clone(),
            rest.to_vec(),
            chosen.iter().map(|&j| candidates[j].clone()).collect(),
        )?;
        fit_identified(&sub, &chosen, &mut fitted, settings, jac_opts, &pool)?
    };
    let mut runs = lm.runs;
    let mut rejudge_note = None;
    if !chosen.is_empty() {
        let rejudged = rejudge(
            engine,
            &prepared,
            rest,
            &candidates,
            (&chosen, &fitted),
            (settings, jac_opts, &pool),
        )?;
        runs += rejudged.runs;
        rejudge_note = rejudged.note;
        if let Some(r) = rejudged.adopted {
            verdicts = r.verdicts;
            chosen = r.chosen;
            fitted = r.fitted;
            lm = r.lm;
        }
    }
    let mut calibrated = full.engine_at(&fitted)?;
    let mut adaptation = None;
    if let Some(ad) = &settings.adapt {
        let design_keys: Vec<String> = chosen.iter().map(|&j| candidates[j].key.clone()).collect();
        let ctx = adapt::Ctx {
            points: &prepared.points,
            rest,
            pool: &pool,
            settings: ad,
            max_iterations: settings.max_iterations,
        };
        let (rep, adapted) = adapt::adapt(&calibrated, &design_keys, ctx)?;
        // The design values refitted beside the curves.
        for (j, c) in candidates.iter().enumerate() {
            if let Ok(v) = adapted.get_param(&c.key) {
                fitted[j] = v;
            }
        }
        runs += rep.model_runs;
        calibrated = adapted;
        adaptation = Some(rep);
    }
    let r1 = residuals_of(&calibrated, &prepared.points, rest)?;
    let layout = full.layout();
    let signals = signal_residuals(&layout, &r0, &r1);
    let baseline_fit = baseline_verdict(
        settings.noisy_inputs,
        (&full, &calibrated),
        &r1,
        &signals,
        adaptation.as_ref(),
    );
    let report = Calibration {
        params: candidates
            .iter()
            .zip(&verdicts)
            .zip(&fitted)
            .map(|((c, v), &x)| param_result(c, v, x))
            .collect(),
        signals,
        points: point_residuals(full.points(), &layout, &r0, &r1),
        table: residual_table(full.points(), &layout, &r1),
        rms_before: rms(&r0),
        rms_after: rms(&r1),
        dropped_lines: lines_of(&prepared.dropped),
        dropped: prepared.dropped,
        assumptions: prepared
            .assumptions
            .into_iter()
            .chain(rejudge_note)
            .collect(),
        lm_iterations: lm.iterations,
        lm_stop: lm.stop,
        adaptation,
        model_runs: full.runs() + runs,
        baseline_fit,
        inlet_loss_law,
        prewash: None,
    };
    Ok((report, calibrated))
}

/// The verdict on the calibrated residuals `r1` of `prob`'s points on `calibrated`: spot
/// readings fitted under their inputs' noise (`noisy_inputs`) are judged under it too (the
/// measure the fit minimised); otherwise as they are, with that level beside them.
fn baseline_verdict(
    noisy_inputs: bool,
    (prob, calibrated): (&CalibrationProblem, &Engine),
    r1: &[f64],
    signals: &[SignalResiduals],
    adaptation: Option<&adapt::AdaptReport>,
) -> BaselineFit {
    if noisy_inputs {
        BaselineFit::of(&prob.whitened(r1.to_vec()), signals, adaptation, None)
    } else {
        let under_inputs =
            problem::level_under_input_noise(calibrated, prob.points(), &prob.layout(), r1);
        BaselineFit::of(r1, signals, adaptation, under_inputs)
    }
}

/// The snapshots solved on the healthy model; an error when none could be.
fn solvable_points(
    engine: &Engine,
    rows: &[Snapshot],
    noisy_inputs: bool,
) -> Result<PreparedPoints, CalibrateError> {
    let mut prepared = prepare(engine, rows);
    if noisy_inputs {
        problem::whiten_under_input_noise(engine, &mut prepared.points);
    }
    if prepared.points.is_empty() {
        return Err(CalibrateError::Data(format!(
            "no snapshot could be solved on the healthy model (lines {:?}; first: {})",
            lines_of(&prepared.dropped),
            prepared
                .dropped
                .first()
                .map_or(String::new(), |d| d.reason.clone())
        )));
    }
    Ok(prepared)
}

/// Which candidates the data identify, from the Jacobian at the guesses `x0` (residuals `r0`):
/// a candidate whose model failed when varied is not, nor the inlet loss when the ambient
/// pressure was derived from P1 through it.
fn identifiability(
    full: &CalibrationProblem,
    candidates: &[Candidate],
    (x0, r0): (&[f64], &[f64]),
    jac_opts: &JacobianOptions,
    pool: &ThreadPool,
    prepared: &PreparedPoints,
) -> Vec<identify::Verdict> {
    let u0 = crate::optim::Problem::bounds(full).to_unit(x0);
    let (jac, failed, _) = jacobian_unit(full, &u0, r0, jac_opts, pool);
    let names: Vec<String> = candidates.iter().map(|c| c.key.clone()).collect();
    let mut verdicts = identify::identify(&jac, &names);
    for (j, v) in verdicts.iter_mut().enumerate() {
        if failed[j] {
            v.identifiable = false;
            v.sigma_fraction = None;
            v.reason = "the model failed when it was varied within its interval".into();
        }
        if prepared.ambient_from_p1 && names[j] == "design.inlet_loss_frac" {
            v.identifiable = false;
            v.reason = "the ambient pressure was derived from P1 through this loss (no \
                        ambient-pressure column), so the data cannot inform it"
                .into();
        }
    }
    verdicts
}

/// The Levenberg–Marquardt fit of the identified set: its iterations, why it stopped, and its
/// model runs.
struct LmFit {
    iterations: usize,
    stop: String,
    runs: usize,
}

/// Fits `sub` (the identified candidates, `chosen` indices into the full set) and writes the
/// fitted values into `fitted`.
fn fit_identified(
    sub: &CalibrationProblem,
    chosen: &[usize],
    fitted: &mut [f64],
    settings: &CalibrationSettings,
    jac_opts: JacobianOptions,
    pool: &ThreadPool,
) -> Result<LmFit, CalibrateError> {
    let opts = LmOptions::default()
        .with_jacobian(jac_opts)
        .and_then(|o| o.with_max_iterations(settings.max_iterations.max(1)))
        .and_then(|o| o.with_ftol(1e-8))
        .and_then(|o| o.with_xtol(1e-7))
        .map_err(|e| CalibrateError::Optim(e.to_string()))?;
    let out = refine(sub, &sub.guesses(), &opts, pool)
        .map_err(|e| CalibrateError::Optim(e.to_string()))?;
    for (k, &j) in chosen.iter().enumerate() {
        fitted[j] = out.x[k];
    }
    Ok(LmFit {
        iterations: out.iterations,
        stop: format!("{:?}", out.stop),
        runs: sub.runs(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnosis::fit_quality::Verdict;

    fn signal(name: &str, rms_after: f64) -> SignalResiduals {
        SignalResiduals {
            signal: name.into(),
            n: 4,
            mean_before: 0.0,
            mean_after: 0.0,
            rms_before: 0.0,
            rms_after,
        }
    }

    /// The baseline verdict uses the snapshot diagnosis's scale (RMS² against 0.9 and 2.5),
    /// names the worst signal and says what to try next.
    #[test]
    fn the_baseline_fit_says_when_the_calibrated_model_misses_the_unit() {
        let within = BaselineFit::of(&[0.5, -0.8, 0.6], &[signal("t4_k", 0.7)], None, None);
        assert_eq!(within.verdict, Verdict::Good);
        let off = [3.0, -2.5, 2.0];
        let signals = [signal("n1_rpm", 4.0), signal("t4_k", 1.0)];
        let poor = BaselineFit::of(&off, &signals, None, None);
        assert_eq!(poor.verdict, Verdict::Poor);
        assert!((poor.normalised_residual - rms(&off).powi(2)).abs() < 1e-12);
        assert!(
            poor.summary.contains("n1_rpm at 4.0 σ") && poor.summary.contains("add --adapt"),
            "{}",
            poor.summary
        );
        let suspect = BaselineFit::of(&[1.2, -1.2], &signals, None, None);
        assert_eq!(suspect.verdict, Verdict::Suspect);
        assert!(!suspect.summary.contains("--noisy-inputs"));
        // The same residuals, which the inputs' noise explains: still `suspect` (the rows are
        // fitted with their inputs as given), but the summary says what the misfit is instead
        // of sending the user to the curves, the cooling air and the maps.
        let inputs = BaselineFit::of(&[1.2, -1.2], &signals, None, Some(0.6));
        assert_eq!(inputs.verdict, Verdict::Suspect);
        assert_eq!(inputs.level_under_input_noise, Some(0.6));
        assert!(
            inputs.summary.contains("within good (0.60)")
                && inputs.summary.contains("--noisy-inputs")
                && !inputs.summary.contains("add --adapt"),
            "{}",
            inputs.summary
        );
        // Not explained by them (above 0.9): the advice as before.
        let model = BaselineFit::of(&[1.2, -1.2], &signals, None, Some(1.3));
        assert!(model.summary.contains("add --adapt"), "{}", model.summary);
        assert!(
            !model.summary.contains("--noisy-inputs"),
            "{}",
            model.summary
        );
    }
}
