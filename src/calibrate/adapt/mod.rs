//! Off-design adaptation to one unit (issue 22 item 1): after the design values are calibrated,
//! bend the maps away from the design point with modification curves of each component's
//! relative corrected speed (`[adaptation]`, evaluated by `maps::adapt`), fitted to all the
//! baseline's operating points at once.
//!
//! Why: design-point scalers move a whole map; a unit of another make has other speed lines
//! (another pressure ratio at 68 % speed, another efficiency fall-off, variable stators), which
//! no design value can bend. The multiple-point adaptation literature (Stamatis et al. 1990's
//! modification factors, Li & Pilidis 2010's non-linear scaling-factor functions, Tsoutsanis et
//! al. 2014's map tuning) fits such corrections; here they are smooth curves, zero at the design
//! speed by construction (so they never alias the design table), and the data decide how much
//! shape they support:
//!
//! 1. **Which curves.** Each component gets one knot at the end of its data's relative speeds
//!    furthest from the design speed, the lowest usually (a curve is then a smooth ramp from
//!    the design speed down); where the data run above the design corrected speed (a
//!    generator's PT at part load, whose speed is held while its inlet cools; any component on
//!    a cold day) the knots go there too. The Jacobian of the noise-scaled
//!    residuals over the design parameters and all eight curves (compressor speed re-labelling,
//!    flow, efficiency, (PR − 1); HPT and PT flow and efficiency) goes through the calibration's
//!    identifiability analysis (`identify`): only curves it identifies are fitted. Each
//!    component's knots are in its own corrected speed, and every curve starts at zero; where
//!    the adapted model departs from similarity (`similarity`), [`adapt`] fits again: where
//!    the compressor's healthy operating line also runs beyond its map's surge line
//!    (`surge`), from the speed re-labelling the data show (`relabel`) with the HP turbine's
//!    knots in either speed; else with the HP turbine's knots in the GG's corrected speed at
//!    the compressor inlet (`engine::config::SpeedOf`, why in its docs).
//! 2. **How many knots.** A component's knots grow one at a time (evenly spaced from each end
//!    of its speeds towards the design speed, shared between the sides by their reach
//!    (`knots`), the fitted curve re-sampled as the start) while the
//!    identifiability analysis still identifies every knot of its curves at the new count, up to
//!    [`AdaptSettings::max_knots`] and one knot fewer than the distinct speeds the data hold,
//!    and the fit at the new count lowers the data's RMS residual by [`MIN_GAIN`] (else the
//!    smaller shape is kept: a fit from the re-sampled curves can end worse than it started).
//!    The components grow together; one whose new knots are not identified beside the others'
//!    is tried again at the next step and, when none grows, alone, before it stops (the others'
//!    new knots can be what takes its information: on a foreign unit's lowest load left out,
//!    the compressor stopped at 1 knot beside the HP turbine's second, at 2.3 σ against 0.6 σ).
//!    Tried alone, a component whose new knots leave one of its curves unidentified while the
//!    others are grows on without fitting that curve: left out, or held at the shape it was
//!    fitted to (in the file, not fitted; the report says so), whichever start ends at the
//!    better fit of the data (on GSPy's generator unit the compressor's flow, +10 % at the
//!    lowest load, left out ended the compressor at 2 knots and the calibration at 1.51 σ;
//!    held, 4 knots and 0.79 σ).
//!    When nothing grows any more and the fit is still not within noise, a component the
//!    analysis stopped gets a second look: its knot more fitted, and judged by the analysis at
//!    the fitted values rather than at the re-sampled start, where a fit many σ off the data
//!    gave a verdict that flipped with the design values' last digits; and a component whose
//!    next knot fitted no better looks two knots ahead (one more knot can gain nothing where
//!    two gain much: GSPy's generator unit with its design GG speed written 9 831 rpm, 1.54 →
//!    0.63 σ).
//! 3. **Fit.** Bounded Levenberg–Marquardt over the identified design values and every knot,
//!    with a smoothness penalty (each curve's second divided difference over
//!    [`AdaptSettings::curvature_scale`] is one residual), so a knot the data barely pin cannot
//!    wiggle; started twice, from the guess and from the optimum of the same problem posed on
//!    each point's measured GG speed, where a running line nearly flat in fuel leaves the
//!    fuel-given residuals too curved for the fit to converge (see `fit_within`).
//!
//! That is [`AdaptStrategy::Grown`], the default. [`AdaptStrategy::Continuation`] keeps every
//! curve the data inform (correlated ones too), puts every knot the speeds carry at once, and
//! fits them through a sequence of smoothness scales from nearly straight curves to the final
//! one, with a weak prior towards the map: the better prediction of the healthy unit between
//! its loads, the weaker separation of degradation (see the variant's doc). A grown shape that
//! ends `poor` has the continuation tried in its place ([`adapt`]); one that ends `suspect`
//! keeps its shape (tried on GSPy's generator unit: the continuation fitted that baseline
//! within noise, 0.66 against 1.51 σ, but its healthy start-up came out `suspect` and its
//! degradation grid ranked D_GT at 0.934, below the test's floor).
//!
//! What it must not do: I/O; fit health (a baseline is healthy by definition).

mod alternatives;
mod before;
mod coverage;
mod efficiency_shape;
mod fitting;
// The calibration's "within noise" (the baseline verdict's `good` level), also `prewash`'s.
pub(in crate::calibrate) use fitting::within_noise;
// How interior loads are dealt into interleaved parts, also `ensemble`'s.
pub(in crate::calibrate) use health_error::interleaved_part;
mod growth;
mod health_error;
mod knots;
mod model_error;
mod relabel;
mod shape;
mod similarity;
mod surge;

pub use alternatives::adapt;
pub use coverage::{CoverageAdvice, ADVICE_PCT};
pub use health_error::{HealthError, PartRead, MIN_PART_POINTS};
pub use model_error::{ModelError, SignalModelError};
pub use similarity::{Similarity, DEPARTURE_PCT, SHIFT_K};
pub use surge::OperatingLine;

use super::problem::CalibrationPoint;
use super::startup::RestReading;
use super::CalibrateError;
use crate::diagnosis::fit_quality::Thresholds;
use crate::diagnosis::steady::{relative_gg_speed, relative_gg_speed_at};
use crate::engine::config::{CalibratedRange, EfficiencyShape, SpeedOf, COMPONENTS};
use crate::engine::cycle::corrected_speed;
use crate::engine::Engine;
use crate::signals::Signal;
use fitting::{
    candidates_for, fit, fit_within, identify_at, penalty_rows, rms_of, Fitted, Pass, Starts,
};
use growth::Growth;
use knots::{distinct_speeds, has_reach, knot_limit};
use rayon::ThreadPool;
use serde::Serialize;
use shape::{key, Shape};

/// Levenberg–Marquardt iterations each adaptation fit gets at least: the curves move the
/// model far (tens of noise σ) and a fit stopped early leaves the next knot count a worse start.
pub const ADAPT_MIN_ITERATIONS: usize = 100;

/// Least relative drop of the data's RMS residual a knot more must bring to be kept.
const MIN_GAIN: f64 = 0.02;

/// How the adaptation chooses its curves and fits them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum AdaptStrategy {
    /// The curves the identifiability analysis identifies at one knot (of two curves that
    /// correlate beyond 0.95 along the data's operating line, only the better-informed), knots
    /// grown one at a time while every knot stays identified and the fit gains. The shape for
    /// diagnosis: it adds no more freedom than the healthy line pins, so degradation, which
    /// moves the points off that line, is read with less cross-talk.
    #[default]
    Grown,
    /// Every curve the data inform (its 1σ alone within an eighth of its interval), correlated
    /// or not, e.g. the compressor's flow and pressure ratio beside its speed re-labelling; as
    /// many knots as the data's speeds carry (at most [`AdaptSettings::max_knots`]); fitted by
    /// continuation in the smoothness penalty: first nearly straight curves
    /// ([`CONTINUATION_SCALES`]), each fit the start of the next, relaxed to
    /// [`AdaptSettings::curvature_scale`], with a weak prior towards the map
    /// ([`CONTINUATION_PRIOR_SCALE`]). The shape for predicting the healthy unit between
    /// its calibrated loads: the correlated curves share what one alone cannot follow, and the
    /// continuation keeps the fit out of the poor optima a fit of so many values from zero
    /// ends in. What the correlated curves do off the operating line the healthy data do not
    /// say, so degradation can read with more cross-talk (measured in `tests/foreign_engine.rs`).
    Continuation,
}

/// Smoothness scales the [`AdaptStrategy::Continuation`] fits run through before the final
/// one: a curvature of 0.02 per unit speed squared costs one σ first (curves nearly straight,
/// few effective degrees of freedom), then 0.1 and 0.5.
pub const CONTINUATION_SCALES: [f64; 3] = [0.02, 0.1, 0.5];

/// Knot value that costs one noise σ in the [`AdaptStrategy::Continuation`] fits: a weak pull
/// towards the map (a 20 % correction costs what one σ of misfit does), so curves that trade a straight
/// ramp with another, unseen by the curvature penalty, stay at zero where the data do not ask
/// for them (on a unit of the model's own map family, without it, the compressor's (PR − 1)
/// curve drifted to +5 % at no gain in the fit).
pub const CONTINUATION_PRIOR_SCALE: f64 = 0.2;

/// Levenberg–Marquardt iterations each of the continuation's [`CONTINUATION_SCALES`] fits gets
/// at most: it only has to bring the curves into the final fit's basin, which then runs to
/// convergence (or [`ADAPT_MIN_ITERATIONS`]).
pub const CONTINUATION_STAGE_ITERATIONS: usize = 30;

/// Settings of the adaptation.
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptSettings {
    /// Most knots per component (the anchor at the design speed not counted).
    pub max_knots: usize,
    /// A curve's second divided difference (per unit relative speed squared) that costs one
    /// noise σ in the fit: the smoothness penalty's scale.
    pub curvature_scale: f64,
    /// How curves are chosen and fitted.
    pub strategy: AdaptStrategy,
    /// Whether the adapted model's own error in health units is estimated at the end
    /// (`[adaptation.health_error]`: three refits and three diagnoses); a calibration run only
    /// to predict a left-out point (`--validate`) does not need it.
    pub health_error: bool,
    /// Which corrected speed the HP turbine's knots are in (its own by default; [`adapt`]
    /// tries the GG's at the compressor inlet where the adapted model departs from
    /// similarity).
    pub hpt_speed_of: SpeedOf,
    /// Whether the compressor's speed re-labelling starts from the guess the data show
    /// (`relabel`) rather than from zero ([`adapt`] sets it where the fit from zero put the
    /// healthy operating line beyond the map's surge line and departs from similarity).
    pub relabel_start: bool,
    /// What shapes the turbines' efficiency away from the design point (the map's by default;
    /// [`adapt`] tries the efficiency curve alone where a turbine's curve works against the
    /// map's shape: `engine::config::EfficiencyShape`).
    pub turbine_efficiency: EfficiencyShape,
    /// Whether [`adapt`] may choose the turbines' efficiency shape on the data (else
    /// `turbine_efficiency` stands): a leave-one-out fold takes what the calibration on every
    /// point chose ([`AdaptSettings::with_efficiency_shape_of`]).
    pub choose_efficiency_shape: bool,
}

impl AdaptSettings {
    /// These settings with the turbines' efficiency shape `report` ended with, fixed (not
    /// chosen again).
    pub fn with_efficiency_shape_of(&self, report: &AdaptReport) -> AdaptSettings {
        AdaptSettings {
            turbine_efficiency: report.turbine_efficiency,
            choose_efficiency_shape: false,
            ..self.clone()
        }
    }
}

impl Default for AdaptSettings {
    fn default() -> Self {
        Self {
            // 6: on a foreign unit's 9 loads (tests/foreign_engine.rs) 4 knots left the baseline
            // itself 0.9 % off on T2 and predicted left-out loads at 0.91 % mean; 6 (the data
            // allow 6–7 there) 0.56 %, and 8 no better (0.58 %) (every growth kept, before
            // MIN_GAIN).
            max_knots: 6,
            curvature_scale: 2.0,
            strategy: AdaptStrategy::Grown,
            health_error: true,
            hpt_speed_of: SpeedOf::OwnInlet,
            relabel_start: false,
            turbine_efficiency: EfficiencyShape::Map,
            choose_efficiency_shape: true,
        }
    }
}

impl AdaptStrategy {
    /// Its name in the report and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            AdaptStrategy::Grown => "grown",
            AdaptStrategy::Continuation => "continuation",
        }
    }
}

impl AdaptSettings {
    /// The default settings with `strategy`.
    pub fn of(strategy: AdaptStrategy) -> Self {
        Self {
            strategy,
            ..Self::default()
        }
    }
}

/// One fitted curve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CurveFit {
    pub curve: String,
    /// Fractional corrections at the component's knots.
    pub values: Vec<f64>,
    /// 1σ of each value (linearised, within the fitted set).
    pub sigma: Vec<Option<f64>>,
    /// A value ended on the bound of its interval: the data want more than the interval
    /// allows (widen it with `--params` or check the data), not an identified value.
    pub at_bound: bool,
    /// Why the curve is held at the shape it was fitted to at fewer knots (in the file, not
    /// fitted at the final knots); `None` for a fitted curve.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held: Option<String>,
}

/// One component's adaptation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComponentFit {
    pub component: String,
    /// Which corrected speed the knots are in (`own_inlet`, `gg_inlet`).
    pub speed_of: SpeedOf,
    /// What shapes the efficiency away from the design point (`map`, `curve`).
    pub efficiency_shape: EfficiencyShape,
    /// Lowest and highest relative corrected speed of the data on the calibrated engine.
    pub speed_range: [f64; 2],
    /// Knot speeds chosen (the anchor 1.0 implicit).
    pub knots: Vec<f64>,
    pub curves: Vec<CurveFit>,
    /// Curves not fitted, with the reason.
    pub not_fitted: Vec<(String, String)>,
    /// Why the knot count stopped where it did.
    pub knots_reason: String,
}

/// The adaptation's report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AdaptReport {
    pub components: Vec<ComponentFit>,
    /// RMS residual (noise σ) before (design calibration only) and after the adaptation.
    pub rms_before: f64,
    pub rms_after: f64,
    /// Design keys refitted beside the curves (identified at the final knot count).
    pub design_refitted: Vec<String>,
    /// Each fit of the growing shape: knots per component, LM outcome, RMS.
    pub steps: Vec<String>,
    pub model_runs: usize,
    /// The strategy that chose and fitted the curves (`grown`, `continuation`).
    pub strategy: &'static str,
    /// When the grown shape could not reproduce the baseline (`poor`) and the continuation
    /// was tried in its place: what each reached and which is kept.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fallback: Option<String>,
    /// The adapted model's own error per signal on points left out (written as
    /// `[adaptation.model_error_pct]`).
    pub model_error: ModelError,
    /// The adapted model's own error in health units on loads left out of a refit (written
    /// as `[adaptation.health_error]`).
    pub health_error: HealthError,
    /// Where the baseline wants a healthy load more: beside interior loads the model predicts
    /// no better than [`ADVICE_PCT`] on some signal (from `model_error.by_speed`).
    pub coverage: Vec<CoverageAdvice>,
    /// The speeds the curves were fitted on (written as `[adaptation.calibrated]`; `None` when
    /// no curve was fitted).
    #[serde(skip)]
    pub calibrated: Option<CalibratedRange>,
    /// Whether the adapted model stays similar at the baseline's corrected operating points
    /// on days [`SHIFT_K`] colder and warmer (`None` when no curve was fitted).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub similarity: Option<Similarity>,
    /// Whether the adapted compressor's healthy operating line stays on its map (`None` when
    /// no curve was fitted).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub operating_line: Option<OperatingLine>,
    /// Where the first fit departed from similarity: why, and each alternative fitted with
    /// what it reached and whether it is kept (empty when it was not run again).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub retried: Vec<String>,
    /// Where a turbine's efficiency curve worked against its map's shape: the fit with the
    /// map's efficiency held, what it reached and whether it is kept (`efficiency_shape`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub efficiency_tried: Option<String>,
    /// What shapes the turbines' efficiency in the kept fit (`map`, `curve`).
    pub turbine_efficiency: EfficiencyShape,
    /// The final fit's values and shape, to refit it on part of the points
    /// (`efficiency_shape`); `None` when nothing was fitted.
    #[serde(skip)]
    fitted: Option<(Vec<String>, Shape)>,
}

/// Relative corrected speed of each component at each point, in the speed its knots are in
/// (the HP turbine's: `hpt`): from the
/// measured GG speed, T1, PT speed and T34 where the point has them, else from `engine`'s
/// solution (healthy).
fn relative_speeds(
    engine: &Engine,
    points: &[CalibrationPoint],
    hpt: SpeedOf,
) -> Result<[Vec<f64>; 3], CalibrateError> {
    let d = engine.design();
    let design_hpt = corrected_speed(d.n1_rpm, d.t3_k);
    let design_pt = corrected_speed(d.n2_rpm, d.t34_k);
    let mut out: [Vec<f64>; 3] = [Vec::new(), Vec::new(), Vec::new()];
    for p in points {
        let inp = &p.data.inputs;
        let s = p.solved_on(engine)?.stations;
        // Measured speeds and temperatures where the point has them (the model's speeds are
        // outputs, and on a foreign unit far from the truth before the adaptation).
        let n1 = p.data.measured(Signal::N1).unwrap_or(s.n1_rpm);
        let t34 = p.data.measured(Signal::T34).unwrap_or(s.t34_k);
        let gg = gg_speed(engine, p, s.n1_rpm);
        out[0].push(gg);
        // The HP turbine's knots in the GG's corrected speed at the compressor inlet are the
        // same number as the compressor's.
        out[1].push(match hpt {
            SpeedOf::GgInlet => gg,
            SpeedOf::OwnInlet => corrected_speed(n1, s.t3_k) / design_hpt,
        });
        out[2].push(corrected_speed(inp.n2_rpm, t34) / design_pt);
    }
    Ok(out)
}

/// Relative corrected GG speed of point `p`: as steady diagnosis reads a point's speed (the
/// model error along the operating line is looked up by it), from its measured GG speed;
/// `model_n1_rpm` (the healthy model's) where the point has none.
fn gg_speed(engine: &Engine, p: &CalibrationPoint, model_n1_rpm: f64) -> f64 {
    relative_gg_speed(engine, &p.data)
        .unwrap_or_else(|| relative_gg_speed_at(engine, model_n1_rpm, p.data.inputs.t_amb_k))
}

/// [`gg_speed`] of every point, solving the healthy model only where a point has no measured
/// GG speed (the other components' speeds, which need the solution, are [`relative_speeds`]).
fn gg_speeds(engine: &Engine, points: &[CalibrationPoint]) -> Result<Vec<f64>, CalibrateError> {
    points
        .iter()
        .map(|p| match relative_gg_speed(engine, &p.data) {
            Some(g) => Ok(g),
            None => Ok(gg_speed(engine, p, p.solved_on(engine)?.stations.n1_rpm)),
        })
        .collect()
}

/// What every step works on: the data, the threads, the settings.
#[derive(Clone, Copy)]
pub struct Ctx<'a> {
    pub points: &'a [CalibrationPoint],
    pub rest: &'a [RestReading],
    pub pool: &'a ThreadPool,
    pub settings: &'a AdaptSettings,
    /// Levenberg–Marquardt iterations per fit.
    pub max_iterations: usize,
}

/// [`adapt`]'s shape and fit (the grown shape; without holding; the continuation in its place).
fn adapt_shape(
    engine: &Engine,
    design_keys: &[String],
    ctx: Ctx,
) -> Result<(AdaptReport, Engine), CalibrateError> {
    let (mut grown, mut adapted) = adapt_as(engine, design_keys, ctx, true)?;
    let holds = grown
        .components
        .iter()
        .any(|c| c.curves.iter().any(|k| k.held.is_some()));
    if ctx.settings.strategy == AdaptStrategy::Grown && holds && !within_noise(grown.rms_after) {
        // Holding a curve is chosen step by step, on the better fit at that step, and the
        // growth after it is another path: on GSPy's generator unit calibrated with its
        // healthy start-up's windows (`--startup`) the path with a held compressor flow ended
        // at 3.48 σ where leaving it out reached 1.03 σ. Not within noise, the growth is run
        // again without holding and the better end kept.
        let (mut plain, other) = adapt_as(engine, design_keys, ctx, false)?;
        let line = format!(
            "the growth again with no curve held: data RMS {:.2} σ against {:.2} σ with",
            plain.rms_after, grown.rms_after
        );
        if plain.rms_after < grown.rms_after {
            plain.model_runs += grown.model_runs;
            plain.steps.push(format!("{line}: kept"));
            grown = plain;
            adapted = other;
        } else {
            grown.model_runs += plain.model_runs;
            grown.steps.push(format!("{line}: not kept"));
        }
    }
    let poor = |r: &AdaptReport| r.rms_after.powi(2) > Thresholds::default().poor_level;
    if ctx.settings.strategy != AdaptStrategy::Grown || !poor(&grown) {
        return Ok((grown, adapted));
    }
    // The grown shape is decided one knot at a time, and a fit many σ off the data can stop it
    // early (on the first foreign unit of `tests/foreign_engine.rs`, a design GG speed written
    // 9 800 rpm instead of 9 831 ended it at 1.77 σ where 9 831 reached 0.61 σ); the
    // continuation places every knot at once and has no such path. A baseline the grown shape
    // cannot reproduce is no diagnosis's basis, so the continuation is tried in its place and
    // kept when it reproduces the baseline (not `poor`) better.
    let settings = AdaptSettings {
        strategy: AdaptStrategy::Continuation,
        ..ctx.settings.clone()
    };
    let (mut continued, other) = adapt_as(
        engine,
        design_keys,
        Ctx {
            settings: &settings,
            ..ctx
        },
        true,
    )?;
    let runs = grown.model_runs + continued.model_runs;
    if !poor(&continued) && continued.rms_after < grown.rms_after {
        continued.fallback = Some(format!(
            "the grown shape ended at {:.2} σ RMS (poor: the baseline not reproduced); the \
             continuation's, at {:.2} σ, is kept",
            grown.rms_after, continued.rms_after
        ));
        continued.model_runs = runs;
        Ok((continued, other))
    } else {
        grown.fallback = Some(format!(
            "the grown shape ended at {:.2} σ RMS (poor); the continuation, tried in its place, \
             at {:.2} σ, is not kept",
            grown.rms_after, continued.rms_after
        ));
        grown.model_runs = runs;
        Ok((grown, adapted))
    }
}

/// [`adapt`] with the context's strategy alone.
fn adapt_as(
    engine: &Engine,
    design_keys: &[String],
    ctx: Ctx,
    may_hold: bool,
) -> Result<(AdaptReport, Engine), CalibrateError> {
    let rms_before = rms_of(engine, ctx)?;
    let speeds = speed_ranges(engine, ctx)?;
    let mut g = Growth::first_level(engine, design_keys, ctx, speeds)?;
    if !may_hold {
        g = g.without_holding();
    }
    if g.nothing_to_fit() {
        return g.unfitted(rms_before);
    }
    g.fit_first()?;
    if ctx.settings.strategy == AdaptStrategy::Grown {
        while g.grow()? {}
    }
    g.polish()?;
    g.finish(rms_before)
}

/// What the data's relative speeds allow, per component (order of [`COMPONENTS`]).
struct SpeedRanges {
    /// Lowest and highest relative corrected speed.
    ranges: Vec<[f64; 2]>,
    /// The most knots the speeds support (0 when they stay within 0.03 of the design speed).
    max_level: Vec<usize>,
    /// What sets each `max_level`, for the report.
    limit: Vec<String>,
}

/// Each component's range of relative speeds in the data, and the most knots those speeds
/// support.
fn speed_ranges(engine: &Engine, ctx: Ctx) -> Result<SpeedRanges, CalibrateError> {
    let speeds = relative_speeds(engine, ctx.points, ctx.settings.hpt_speed_of)?;
    let range = |v: &[f64]| {
        [
            v.iter().copied().fold(f64::INFINITY, f64::min),
            v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ]
    };
    let ranges: Vec<[f64; 2]> = speeds.iter().map(|v| range(v)).collect();
    let (max_level, limit): (Vec<usize>, Vec<String>) = speeds
        .iter()
        .zip(&ranges)
        .map(|(v, r)| {
            if !has_reach(*r) {
                return (0, String::new());
            }
            knot_limit(distinct_speeds(v, *r), *r, ctx.settings.max_knots)
        })
        .unzip();
    Ok(SpeedRanges {
        ranges,
        max_level,
        limit,
    })
}

/// `engine` with the adaptation section of `shape` (everything else of its file kept).
fn shaped(engine: &Engine, shape: &Shape) -> Result<Engine, CalibrateError> {
    let mut cfg = engine.cfg().clone();
    cfg.adaptation = shape.config();
    engine
        .with_config(cfg)
        .map_err(|e| CalibrateError::Model(e.to_string()))
}

fn report(
    shape: &Shape,
    ranges: &[[f64; 2]],
    not_fitted: [Vec<(String, String)>; 3],
    knots_reason: [String; 3],
    sigma: &[(String, Option<f64>)],
    bounds: &[(String, f64, f64)],
) -> AdaptReport {
    let components = COMPONENTS
        .iter()
        .enumerate()
        .zip(not_fitted)
        .zip(knots_reason)
        .map(|(((ci, name), not_fitted), knots_reason)| ComponentFit {
            component: name.to_string(),
            speed_of: shape.speed_of(name),
            efficiency_shape: shape.efficiency_shape(name),
            speed_range: ranges[ci],
            knots: shape.knots[ci].clone(),
            curves: shape.curves[ci]
                .iter()
                .map(|(curve, values)| {
                    let keys: Vec<String> =
                        (0..values.len()).map(|i| key(name, curve, i)).collect();
                    CurveFit {
                        curve: curve.clone(),
                        values: values.clone(),
                        sigma: keys
                            .iter()
                            .map(|k| sigma.iter().find(|(x, _)| x == k).and_then(|(_, s)| *s))
                            .collect(),
                        at_bound: keys.iter().zip(values).any(|(k, v)| {
                            bounds.iter().any(|(x, lo, hi)| {
                                x == k && ((v - lo).abs() < 1e-4 || (hi - v).abs() < 1e-4)
                            })
                        }),
                        held: None,
                    }
                })
                .chain(shape.held[ci].iter().map(|h| CurveFit {
                    curve: h.curve.clone(),
                    values: h.values.clone(),
                    sigma: vec![None; h.values.len()],
                    at_bound: false,
                    held: Some(h.reason.clone()),
                }))
                .collect(),
            not_fitted,
            knots_reason,
        })
        .collect();
    AdaptReport {
        components,
        rms_before: 0.0,
        rms_after: 0.0,
        design_refitted: Vec::new(),
        steps: Vec::new(),
        model_runs: 0,
        strategy: "",
        fallback: None,
        model_error: ModelError::default(),
        health_error: HealthError::default(),
        coverage: Vec::new(),
        calibrated: None,
        similarity: None,
        operating_line: None,
        retried: Vec::new(),
        efficiency_tried: None,
        turbine_efficiency: shape.turbine_efficiency,
        fitted: None,
    }
}
