//! The adaptation's growth (steps 1–3 of the parent module): the curves the data identify at
//! one knot, their fit, then one knot more per component while every knot stays identified
//! and the fit gains (a curve whose new knots are not identified while the component's others
//! are is left out or held at its fit, whichever fits better, and the others grow on), and the
//! report; or, with
//! [`AdaptStrategy::Continuation`], every curve the data inform at every knot their speeds
//! carry, fitted through a sequence of smoothness scales. Must not do I/O.
//!
//! The rooms: this file holds the state ([`Growth`]), the first level and its fit, the
//! closing polish; `grow` one growth step and how it is judged; `second_look` the look a
//! stalled component gets when nothing grows any more; `finish` the report with the model's
//! own error in signal and health units.

mod finish;
mod grow;
mod second_look;

use super::super::CalibrateError;
use super::health_error::{self, HealthError};
use super::knots::{knots, SIDE_REACH};
use super::model_error::{self, ModelError};
use super::relabel::{relabel_guess, RELABEL_GUESS_LIMIT};
use super::shape::{key, Shape};
use super::{
    candidates_for, fit, fit_within, identify_at, report, rms_of, shaped, within_noise,
    AdaptReport, AdaptSettings, AdaptStrategy, Ctx, Fitted, Pass, SpeedRanges, Starts,
    ADAPT_MIN_ITERATIONS, CONTINUATION_SCALES, CONTINUATION_STAGE_ITERATIONS, MIN_GAIN,
};
use crate::engine::config::{curves_of, CalibratedRange, COMPONENTS};
use crate::engine::Engine;
pub(super) use finish::with_health_error;

/// Times a growth's fit that stopped on its iteration limit, no better than the shape before,
/// goes on before the knots are judged (each as many iterations again).
const MAX_EXTENSIONS: usize = 2;

/// Why a curve stops being fitted: the identifiability analysis does not resolve it at `knots`
/// beside its component's other curves (the report's words for a curve left out or held).
fn unresolved_at(knots: usize) -> String {
    format!("not identified beside the component's other curves at {knots} knot(s)")
}

/// The adaptation in progress: the shape fitted so far, the engine with it, and what the
/// report will say.
pub(super) struct Growth<'a> {
    ctx: Ctx<'a>,
    ranges: Vec<[f64; 2]>,
    /// The most knots each component's speeds support.
    max_level: Vec<usize>,
    /// What sets each component's most knots (for the report).
    limit: Vec<String>,
    shape: Shape,
    current: Engine,
    /// The design values still free beside the curves (identified at the last pass).
    design_free: Vec<String>,
    /// Every design value the calibration offered (for the closing polish).
    design_all: Vec<String>,
    runs: usize,
    steps: Vec<String>,
    not_fitted: [Vec<(String, String)>; 3],
    knots_reason: [String; 3],
    /// Knots per component, and whether a component has stopped growing.
    level: Vec<usize>,
    frozen: [bool; 3],
    /// σ of the keys at the last accepted growth's identifiability pass.
    last_sigma: Vec<(String, Option<f64>)>,
    /// Components stopped while the fit is not within noise, whose second look
    /// ([`Self::second_look`]) is still to come, each with the knots it is to look at more:
    /// one where the identifiability analysis stopped it at a growth's start, two where its
    /// next knot was fitted and no better.
    stalled: Vec<(usize, usize)>,
    /// Whether a curve not identified at more knots may be held at its fit (else it is left
    /// out, as before holding was tried; see [`super::adapt`]).
    may_hold: bool,
}

impl<'a> Growth<'a> {
    /// Level 1: every curve of every component with a speed range, one knot at its furthest
    /// speed; the curves (and design values) the data do not identify are dropped.
    pub(super) fn first_level(
        engine: &Engine,
        design_keys: &[String],
        ctx: Ctx<'a>,
        speeds: SpeedRanges,
    ) -> Result<Self, CalibrateError> {
        let SpeedRanges {
            ranges,
            max_level,
            limit,
        } = speeds;
        let continuation = ctx.settings.strategy == AdaptStrategy::Continuation;
        let mut not_fitted: [Vec<(String, String)>; 3] = Default::default();
        let mut knots_reason: [String; 3] = Default::default();
        let mut shape = Shape {
            hpt_speed_of: ctx.settings.hpt_speed_of,
            turbine_efficiency: ctx.settings.turbine_efficiency,
            knots: Default::default(),
            curves: Default::default(),
            held: Default::default(),
        };
        for (ci, name) in COMPONENTS.iter().enumerate() {
            if max_level[ci] == 0 {
                knots_reason[ci] = format!(
                    "the data's relative speeds ({:.3}…{:.3}) stay within {SIDE_REACH} of the \
                     design speed, where every curve is pinned to 0: no knot to fit",
                    ranges[ci][0], ranges[ci][1]
                );
                continue;
            }
            shape.knots[ci] = knots(ranges[ci], 1);
            shape.curves[ci] = curves_of(name)
                .iter()
                .map(|c| (c.to_string(), vec![0.0]))
                .collect();
        }
        let base = shaped(engine, &shape)?;
        let mut keys: Vec<String> = design_keys.to_vec();
        keys.extend(shape.keys());
        let cands = candidates_for(&base, &keys)?;
        let pass = identify_at(&base, &cands, ctx)?;
        // Keep the identified curves.
        for (ci, name) in COMPONENTS.iter().enumerate() {
            let mut kept = Vec::new();
            for (curve, values) in std::mem::take(&mut shape.curves[ci]) {
                let k = key(name, &curve, 0);
                match keys.iter().position(|x| *x == k) {
                    Some(j) if pass.identified[j] => kept.push((curve, values)),
                    Some(j) if continuation && pass.informed[j] => kept.push((curve, values)),
                    Some(j) => not_fitted[ci].push((curve, pass.reasons[j].clone())),
                    None => {}
                }
            }
            shape.curves[ci] = kept;
            if *name == "compressor" && ctx.settings.relabel_start {
                // Start the speed re-labelling where the unit's points sit on the map's speed
                // lines (why: `relabel`).
                let knot = shape.knots[ci].first().copied();
                if let (Some((_, values)), Some(k)) = (
                    shape.curves[ci].iter_mut().find(|(c, _)| c == "speed"),
                    knot,
                ) {
                    if let Some(f) = relabel_guess(engine, ctx.points, k) {
                        values[0] = f.clamp(-RELABEL_GUESS_LIMIT, RELABEL_GUESS_LIMIT);
                    }
                }
            }
            if shape.curves[ci].is_empty() && max_level[ci] > 0 {
                shape.knots[ci].clear();
                knots_reason[ci] =
                    "no curve of this component is identifiable from these data".into();
            } else if continuation && max_level[ci] > 0 {
                // Every knot the data's speeds carry at once; the penalty's continuation, not
                // a growth, decides how much shape they take.
                shape = shape.resampled(ci, knots(ranges[ci], max_level[ci]));
                knots_reason[ci] = format!(
                    "{} knot(s): {}; fitted by continuation in the smoothness penalty",
                    max_level[ci], limit[ci]
                );
            }
        }
        let design_free: Vec<String> = design_keys
            .iter()
            .filter(|k| pass.identifies(&keys, k))
            .cloned()
            .collect();
        let current = shaped(&base, &shape)?;
        Ok(Self {
            ctx,
            ranges,
            max_level,
            limit,
            shape,
            current,
            design_free,
            design_all: design_keys.to_vec(),
            runs: pass.runs,
            steps: Vec::new(),
            not_fitted,
            knots_reason,
            level: Vec::new(),
            frozen: [false; 3],
            last_sigma: Vec::new(),
            stalled: Vec::new(),
            may_hold: true,
        })
    }

    /// The growth with every curve not identified at more knots left out, none held.
    pub(super) fn without_holding(mut self) -> Self {
        self.may_hold = false;
        self
    }

    /// No curve is identifiable at one knot: the adaptation has nothing to fit.
    pub(super) fn nothing_to_fit(&self) -> bool {
        self.shape.keys().is_empty()
    }

    /// The report and the engine as they are, when [`Self::nothing_to_fit`].
    pub(super) fn unfitted(self, rms_before: f64) -> Result<(AdaptReport, Engine), CalibrateError> {
        let mut r = report(
            &self.shape,
            &self.ranges,
            self.not_fitted,
            self.knots_reason,
            &[],
            &[],
        );
        r.rms_before = rms_before;
        r.rms_after = rms_of(&self.current, self.ctx)?;
        r.model_runs = self.runs;
        r.strategy = self.ctx.settings.strategy.name();
        Ok((r, self.current))
    }

    /// Fits the first shape: one knot per component ([`AdaptStrategy::Grown`]), or every
    /// knot through the continuation's smoothness scales, then at the settings' own
    /// ([`AdaptStrategy::Continuation`]).
    pub(super) fn fit_first(&mut self) -> Result<(), CalibrateError> {
        let mut all: Vec<String> = self.design_free.clone();
        all.extend(self.shape.keys());
        if self.ctx.settings.strategy == AdaptStrategy::Continuation {
            for scale in CONTINUATION_SCALES {
                let settings = AdaptSettings {
                    curvature_scale: scale,
                    ..self.ctx.settings.clone()
                };
                let ctx = Ctx {
                    settings: &settings,
                    ..self.ctx
                };
                let cands = candidates_for(&self.current, &all)?;
                let Fitted {
                    engine: fitted,
                    runs: n,
                    step,
                    ..
                } = fit_within(
                    &self.current,
                    cands,
                    &self.shape,
                    ctx,
                    CONTINUATION_STAGE_ITERATIONS,
                    Starts::Guess,
                )?;
                self.runs += n;
                self.steps.push(format!(
                    "knots {:?}, smoothness scale {scale}: {step}",
                    self.shape.levels()
                ));
                self.current = fitted;
                self.shape.read_back(&self.current);
            }
        }
        let cands = candidates_for(&self.current, &all)?;
        let Fitted {
            engine: fitted,
            runs: n,
            step,
            ..
        } = fit(&self.current, cands, &self.shape, self.ctx)?;
        self.runs += n;
        self.steps.push(match self.ctx.settings.strategy {
            AdaptStrategy::Grown => format!("1 knot per component: {step}"),
            AdaptStrategy::Continuation => format!(
                "knots {:?}, smoothness scale {}: {step}",
                self.shape.levels(),
                self.ctx.settings.curvature_scale
            ),
        });
        self.current = fitted;
        self.shape.read_back(&self.current);
        self.level = (0..3).map(|ci| self.shape.knots[ci].len()).collect();
        Ok(())
    }

    /// Takes `fitted` (the fit of `shape`) as the adaptation so far, with the σ of `keys` from
    /// the identifiability `pass` that accepted it.
    fn adopt(&mut self, fitted: Engine, shape: Shape, keys: &[String], pass: &Pass) {
        self.current = fitted;
        self.shape = shape;
        self.shape.read_back(&self.current);
        self.last_sigma = keys
            .iter()
            .cloned()
            .zip(pass.sigma.iter().copied())
            .collect();
    }

    /// Freezes each component that has as many knots as its speeds support.
    fn freeze_full(&mut self) {
        for ci in 0..3 {
            if !self.shape.curves[ci].is_empty()
                && self.level[ci] >= self.max_level[ci]
                && !self.frozen[ci]
            {
                self.knots_reason[ci] = format!("{} knot(s): {}", self.level[ci], self.limit[ci]);
                self.frozen[ci] = true;
            }
        }
    }

    /// The curves of the current shape that `next` no longer fits (left out or held), per
    /// component.
    fn dropped_curves(&self, next: &Shape) -> Vec<(usize, String)> {
        let mut out = Vec::new();
        for ci in 0..3 {
            for (curve, _) in &self.shape.curves[ci] {
                if !next.curves[ci].iter().any(|(c, _)| c == curve) {
                    out.push((ci, curve.clone()));
                }
            }
        }
        out
    }

    /// The closing fit of [`AdaptStrategy::Grown`]: every design value the calibration offered
    /// freed again beside the final knots, kept where it lowers the data's RMS by
    /// [`MIN_GAIN`].
    ///
    /// Why: a design value the identifiability analysis stops identifying as knots are added
    /// stays at the value of the step that dropped it, fitted to a coarser shape. Its
    /// direction is one the diagnosis's health spans (a uniform efficiency change is D_EC,
    /// D_ET or D_EP), so the diagnosis then reads the healthy baseline itself as degraded: on
    /// GSPy's generator unit with its constant inlet loss the baseline read D_EC −0.75 and D_ET
    /// +0.68 (noise σ alone), 0.00 after this fit (data RMS 1.12 → 1.02 σ). Fitted beside
    /// the final knots such a value is not identified apart from them, which only says the
    /// data cannot split it from the curves; the fit needs no such split.
    pub(super) fn polish(&mut self) -> Result<(), CalibrateError> {
        if self.ctx.settings.strategy != AdaptStrategy::Grown
            || self.design_all.iter().all(|k| self.design_free.contains(k))
        {
            return Ok(());
        }
        let mut all: Vec<String> = self.design_all.clone();
        all.extend(self.shape.keys());
        let Fitted {
            engine: fitted,
            runs: n,
            step,
            ..
        } = fit(
            &self.current,
            candidates_for(&self.current, &all)?,
            &self.shape,
            self.ctx,
        )?;
        self.runs += n;
        let (rms_old, rms_new) = (rms_of(&self.current, self.ctx)?, rms_of(&fitted, self.ctx)?);
        if rms_new < rms_old * (1.0 - MIN_GAIN) {
            self.current = fitted;
            self.shape.read_back(&self.current);
            self.design_free = self.design_all.clone();
            // The σ of the last growth's pass were of fewer keys: `finish` takes a pass now.
            self.last_sigma.clear();
            self.steps.push(format!(
                "every design value freed beside the final knots: {step}; data RMS \
                 {rms_old:.2} → {rms_new:.2} σ"
            ));
        } else {
            self.steps.push(format!(
                "every design value freed beside the final knots: data RMS {rms_old:.2} → \
                 {rms_new:.2} σ, less than {:.0} % better, not kept",
                100.0 * MIN_GAIN
            ));
        }
        Ok(())
    }
}
