//! The adaptation's fits and identifiability passes: one Levenberg–Marquardt fit of design
//! values and knots with the shape's penalty rows (started twice where the fuel-given problem
//! is too curved), one identifiability pass at an engine's values, and the data's RMS. The
//! steps that decide *what* to fit (growth, the model error, the error in health units) call
//! these. Must not do I/O, nor choose a shape.

use super::super::candidates::{candidate, Candidate};
use super::super::identify::{identify, MAX_SIGMA_FRACTION};
use super::super::problem::{CalibrationProblem, SmoothnessRow};
use super::super::CalibrateError;
use super::shape::Shape;
use super::{AdaptSettings, AdaptStrategy, Ctx, ADAPT_MIN_ITERATIONS, CONTINUATION_PRIOR_SCALE};
use crate::diagnosis::fit_quality::Thresholds;
use crate::engine::Engine;
use crate::optim::lm::jacobian_unit;
use crate::optim::{refine, JacobianOptions, LmOptions, Problem, RefineResult, RefineStop};

/// What one identifiability pass says of the candidates `cands` at `engine`.
pub(super) struct Pass {
    pub(super) identified: Vec<bool>,
    /// Carries information alone (1σ alone within [`MAX_SIGMA_FRACTION`] of its interval),
    /// identified or dropped only for correlating with another candidate.
    pub(super) informed: Vec<bool>,
    pub(super) sigma: Vec<Option<f64>>,
    pub(super) reasons: Vec<String>,
    pub(super) runs: usize,
}

impl Pass {
    /// Whether the pass over `keys` (its candidates, in order) identifies `key`.
    pub(super) fn identifies(&self, keys: &[String], key: &str) -> bool {
        keys.iter()
            .position(|x| x == key)
            .is_some_and(|j| self.identified[j])
    }
}

/// Whether a fit at data RMS `rms` (noise σ) reproduces its data within noise (the baseline
/// verdict's `good` level), where more shape is not needed.
pub(in crate::calibrate) fn within_noise(rms: f64) -> bool {
    rms.powi(2) <= Thresholds::default().good_level
}

pub(super) fn identify_at(
    engine: &Engine,
    cands: &[Candidate],
    ctx: Ctx,
) -> Result<Pass, CalibrateError> {
    let prob = CalibrationProblem::new(
        engine,
        ctx.points.to_vec(),
        ctx.rest.to_vec(),
        cands.to_vec(),
    )?;
    let x0 = prob.guesses();
    let r0 = prob.residuals_at(&x0)?;
    let u0 = prob.bounds().to_unit(&x0);
    let jac_opts = JacobianOptions::default()
        .with_step(1e-3)
        .map_err(|e| CalibrateError::Optim(e.to_string()))?;
    let (jac, failed, _) = jacobian_unit(&prob, &u0, &r0, &jac_opts, ctx.pool);
    let names: Vec<String> = cands.iter().map(|c| c.key.clone()).collect();
    let verdicts = identify(&jac, &names);
    Ok(Pass {
        identified: verdicts
            .iter()
            .zip(&failed)
            .map(|(v, f)| v.identifiable && !f)
            .collect(),
        informed: verdicts
            .iter()
            .zip(&failed)
            .map(|(v, f)| {
                !f && (v.identifiable || v.sigma_fraction.is_some_and(|s| s <= MAX_SIGMA_FRACTION))
            })
            .collect(),
        sigma: verdicts
            .iter()
            .zip(cands)
            .map(|(v, c)| v.sigma_fraction.map(|s| s * (c.upper - c.lower)))
            .collect(),
        reasons: verdicts.into_iter().map(|v| v.reason).collect(),
        runs: prob.runs(),
    })
}

/// Candidates for `keys` on `engine`, intervals around its current values.
pub(super) fn candidates_for(
    engine: &Engine,
    keys: &[String],
) -> Result<Vec<Candidate>, CalibrateError> {
    keys.iter().map(|k| candidate(engine, k)).collect()
}

/// The penalty rows of a fit of `keys` on `shape`: its smoothness, and with the continuation
/// strategy its prior towards the map.
pub(super) fn penalty_rows(
    shape: &Shape,
    keys: &[String],
    settings: &AdaptSettings,
) -> Vec<SmoothnessRow> {
    let mut rows = shape.smoothness(keys, settings.curvature_scale);
    if settings.strategy == AdaptStrategy::Continuation {
        rows.extend(shape.prior(keys, CONTINUATION_PRIOR_SCALE));
    }
    rows
}

/// LM over `cands` on `engine` with the shape's smoothness rows; the engine at the optimum.
pub(super) fn fit(
    engine: &Engine,
    cands: Vec<Candidate>,
    shape: &Shape,
    ctx: Ctx,
) -> Result<Fitted, CalibrateError> {
    fit_within(
        engine,
        cands,
        shape,
        ctx,
        ctx.max_iterations.max(ADAPT_MIN_ITERATIONS),
        match ctx.settings.strategy {
            AdaptStrategy::Grown => Starts::GuessAndSpeed,
            AdaptStrategy::Continuation => Starts::Guess,
        },
    )
}

/// Where a fit starts (see `fit_within`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Starts {
    /// From the guess and from the GG-speed fit's optimum; the lower cost is kept.
    GuessAndSpeed,
    /// From the guess only.
    Guess,
}

/// [`fit`] stopped after `iterations` Levenberg–Marquardt iterations at most.
///
/// With [`Starts::GuessAndSpeed`] (every fit of [`AdaptStrategy::Grown`]) the fit has two
/// starts, and the one ending with the lower least-squares cost is kept: the guess itself,
/// and the optimum of the same problem posed on each point's measured GG speed
/// ([`CalibrationProblem::on_gg_speed`]), from which the fuel-given problem is then refined.
/// Why: where a unit's running line is nearly flat in fuel (at low load, where the maps the
/// curves bend differ most), the fuel-given residuals are so curved that Levenberg–Marquardt
/// crawls: on the foreign unit of `tests/foreign_engine.rs` the fits ended on their 100
/// iterations at 2–5 σ where the same shape reaches 1 σ, the growth then decided on fits that
/// had stopped short, and the calibrations left out of the leave-one-load-out ended at data
/// RMS 2–3 σ against 0.6 σ. Posed on the GG speed, every point has one smooth solution and the
/// fit converges in a few iterations. Neither start is always the better (over those nine
/// calibrations the GG-speed start won 19 fits, the guess 10, 21 tied), so both are run.
/// The continuation keeps the one start its stages lead to.
pub(super) fn fit_within(
    engine: &Engine,
    cands: Vec<Candidate>,
    shape: &Shape,
    ctx: Ctx,
    iterations: usize,
    starts: Starts,
) -> Result<Fitted, CalibrateError> {
    let keys: Vec<String> = cands.iter().map(|c| c.key.clone()).collect();
    let rows = penalty_rows(shape, &keys, ctx.settings);
    let prob = CalibrationProblem::new(engine, ctx.points.to_vec(), ctx.rest.to_vec(), cands)?
        .with_smoothness(rows);
    let jac_opts = JacobianOptions::default()
        .with_step(1e-3)
        .map_err(|e| CalibrateError::Optim(e.to_string()))?;
    let opts = LmOptions::default()
        .with_jacobian(jac_opts)
        .and_then(|o| o.with_max_iterations(iterations))
        .and_then(|o| o.with_ftol(1e-8))
        .and_then(|o| o.with_xtol(1e-7))
        .map_err(|e| CalibrateError::Optim(e.to_string()))?;
    let mut out = refine(&prob, &prob.guesses(), &opts, ctx.pool)
        .map_err(|e| CalibrateError::Optim(e.to_string()))?;
    let mut start = String::from("the guess");
    let mut runs_on_speed = 0;
    if starts == Starts::GuessAndSpeed {
        // The second start only ever adds a candidate: where it cannot be run (a point that
        // will not solve at its measured speed on the guess), the guess's fit stands.
        let second = || -> Result<(RefineResult, usize), String> {
            let on_speed = prob.on_gg_speed();
            let from = refine(&on_speed, &on_speed.guesses(), &opts, ctx.pool)
                .map_err(|e| e.to_string())?;
            let polished = refine(&prob, &from.x, &opts, ctx.pool).map_err(|e| e.to_string())?;
            let iterations = from.iterations + polished.iterations;
            Ok((
                RefineResult {
                    iterations,
                    ..polished
                },
                on_speed.runs(),
            ))
        };
        match second() {
            Ok((r, n)) => {
                runs_on_speed = n;
                if r.ssr < out.ssr {
                    out = r;
                    start = "the GG-speed fit".into();
                }
            }
            Err(e) => start = format!("the guess (the GG-speed start could not run: {e})"),
        }
    }
    let penalties = match ctx.settings.strategy {
        AdaptStrategy::Grown => "smoothness",
        AdaptStrategy::Continuation => "smoothness and prior",
    };
    let step = format!(
        "{} free ({} knots): {} LM iteration(s) from {start}, stop {:?}, RMS {:.2} σ \
         ({penalties} included)",
        keys.len(),
        shape.keys().len(),
        out.iterations,
        out.stop,
        (out.ssr / prob.layout().len().max(1) as f64).sqrt()
    );
    Ok(Fitted {
        engine: prob.engine_at(&out.x)?,
        runs: prob.runs() + runs_on_speed,
        step,
        at_limit: out.stop == RefineStop::MaxIterations,
    })
}

/// A fit's result: the engine at its optimum, the model runs it took, its line for the report's
/// steps, and whether it stopped on its iteration limit (short of the optimum).
pub(super) struct Fitted {
    pub(super) engine: Engine,
    pub(super) runs: usize,
    pub(super) step: String,
    pub(super) at_limit: bool,
}

pub(super) fn rms_of(engine: &Engine, ctx: Ctx) -> Result<f64, CalibrateError> {
    let r = super::super::residuals_of(engine, ctx.points, ctx.rest)?;
    Ok(super::super::rms(&r))
}
