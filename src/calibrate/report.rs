//! What a calibration reports: every candidate's outcome, the residuals before and after per
//! signal and per operating point (and as a signal × point table), the baseline verdict, and
//! the builders that turn a fit into them. Must not fit or do I/O.

use super::candidates::Candidate;
use super::identify;
use super::{adapt, inlet_law, problem};
use super::{mean, rms};
use crate::diagnosis::residual_table::{Cell, ResidualTable};
use crate::engine::config::{EfficiencyShape, SpeedOf};
use serde::Serialize;

/// One candidate's outcome.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamResult {
    pub key: String,
    /// The engine file's value.
    pub guess: f64,
    /// The calibrated value (= guess when not identifiable).
    pub fitted: f64,
    /// 1σ in the key's unit (linearised at the guesses, one-sample noise): within the fitted
    /// set for an identified parameter, alone for the others (`None`: no information).
    pub sigma: Option<f64>,
    /// The realistic interval searched.
    pub lower: f64,
    pub upper: f64,
    pub identifiable: bool,
    /// `identified`, `at_bound` (fitted, but it ended on its interval's bound: the data want
    /// more than the realistic interval allows — never called identified) or
    /// `not_identifiable` (kept at the guess).
    pub status: String,
    pub reason: String,
}

/// Residuals of one signal over all points, in noise σ.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SignalResiduals {
    pub signal: String,
    pub n: usize,
    /// Mean and RMS of (model − measured)/σ before (guesses) and after calibration.
    pub mean_before: f64,
    pub mean_after: f64,
    pub rms_before: f64,
    pub rms_after: f64,
}

/// Residuals of one operating point over its signals, in noise σ.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PointResiduals {
    /// The snapshot's file line (a start-up window's: its first sample's).
    pub line: u64,
    /// The snapshot's file or group, or the start-up file and window times.
    pub source: String,
    pub rms_before: f64,
    pub rms_after: f64,
}

/// The calibration report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Calibration {
    pub params: Vec<ParamResult>,
    pub signals: Vec<SignalResiduals>,
    pub points: Vec<PointResiduals>,
    /// After calibration: (model − measured)/σ of every signal at every point.
    pub table: ResidualTable,
    /// RMS of all residuals (noise σ) before and after.
    pub rms_before: f64,
    pub rms_after: f64,
    /// Snapshot lines whose healthy solve failed (not used).
    pub dropped_lines: Vec<u64>,
    /// The same rows with the reason each was left out (`dropped_lines` stays in the report
    /// for readers of its JSON).
    pub dropped: Vec<crate::diagnosis::snapshot::DroppedRow>,
    /// How rows' ambient pressures were obtained, where not from an ambient column.
    pub assumptions: Vec<String>,
    pub lm_iterations: usize,
    pub lm_stop: String,
    /// The off-design adaptation, when asked for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adaptation: Option<adapt::AdaptReport>,
    /// Model evaluations (each one design calibration and one steady solve per point).
    pub model_runs: usize,
    /// Whether the calibrated model reproduces the healthy baseline, and what to do if not.
    pub baseline_fit: BaselineFit,
    /// What the measured inlet pressure says of the inlet loss law (`None`: the data cannot
    /// tell, e.g. no P1 or no measured ambient pressure); the calibration uses `chosen`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inlet_loss_law: Option<inlet_law::InletLawChoice>,
    /// The pre-wash rows' fouling and the rounds that found it (`--prewash-group`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prewash: Option<super::prewash::PrewashReport>,
}

/// The verdict on the calibrated model's fit to the healthy baseline, on the snapshot
/// diagnosis's scale (normalised residual = RMS² in noise σ; `good` ≤ 0.9, `poor` > 2.5): a
/// model that does not reproduce the healthy unit hands every later diagnosis that misfit, which
/// the diagnosis then labels `suspect` or `poor`, so the calibration says so first.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BaselineFit {
    pub verdict: crate::diagnosis::fit_quality::Verdict,
    /// RMS² of the residuals after calibration (noise σ).
    pub normalised_residual: f64,
    /// The verdict in words, with the worst signal and what to try.
    pub summary: String,
    /// The normalised residual judged under the noise of the rows' inputs (fuel flow, T1, n2),
    /// which the fit takes as exact ([`super::problem::level_under_input_noise`]); `None` where
    /// no input carries noise.
    pub level_under_input_noise: Option<f64>,
}

impl BaselineFit {
    /// The verdict on residuals `r1` (per signal summary `signals`) after a calibration with
    /// the adaptation `adapt` (`None`: design values only); `under_inputs`: their normalised
    /// residual under the noise of the rows' inputs.
    pub(super) fn of(
        r1: &[f64],
        signals: &[SignalResiduals],
        adapt: Option<&adapt::AdaptReport>,
        under_inputs: Option<f64>,
    ) -> Self {
        use crate::diagnosis::fit_quality::{assess, HealthFlags, Thresholds, Verdict};
        let level = rms(r1).powi(2);
        // The diagnosis's own verdict on that level (no phases, oscillations or health here).
        let verdict = assess(
            level,
            &[],
            &[],
            &HealthFlags::default(),
            &Thresholds::default(),
        )
        .verdict;
        // A shape that follows its calibration points but predicts none between them (its
        // model error, estimated on points left out) gives no diagnosis worth the name however
        // well it fits.
        let unresolving: Vec<String> = adapt
            .map(|a| {
                a.model_error
                    .unresolving()
                    .into_iter()
                    .map(|(signal, pct)| format!("{signal} {pct:.1} %"))
                    .collect()
            })
            .unwrap_or_default();
        let (verdict, summary) = if verdict == Verdict::Good && !unresolving.is_empty() {
            (
                Verdict::Suspect,
                format!(
                    "the calibrated model reproduces the healthy baseline within noise at the \
                     points it was fitted to, but predicts a point left out of the fit no better \
                     than {} at any GG speed (the model error written to \
                     [adaptation.model_error_pct] and [adaptation.model_error_by_speed]): the \
                     curves follow the points, not the unit, and a diagnosis on this file will \
                     be labelled suspect at best; calibrate on more loads, or try \
                     --adapt-strategy continuation",
                    unresolving.join(", ")
                ),
            )
        } else if verdict == Verdict::Good {
            // Resolved at some speeds, not at others: say where a diagnosis cannot lean.
            let unresolved = adapt
                .map(|a| a.model_error.unresolved_speeds())
                .unwrap_or_default();
            let words = match unresolved.first() {
                Some((lo, worst)) => {
                    let list: Vec<String> = worst
                        .iter()
                        .map(|(signal, pct)| format!("{signal} {pct:.1} %"))
                        .collect();
                    let speeds: Vec<String> =
                        unresolved.iter().map(|(k, _)| format!("{k:.3}")).collect();
                    format!(
                        "the calibrated model reproduces the healthy baseline within noise; at \
                         relative corrected GG speed {} it predicts a point left out of the fit \
                         no better than 2 % (at {lo:.3}: {}; [adaptation.model_error_by_speed]): \
                         a diagnosis resting on such loads alone will be labelled suspect, one \
                         with other loads beside them weights each load for what the model \
                         predicts there",
                        speeds.join(", "),
                        list.join(", ")
                    )
                }
                None => "the calibrated model reproduces the healthy baseline within noise".into(),
            };
            (verdict, words)
        } else {
            let worst = signals
                .iter()
                .max_by(|a, b| a.rms_after.total_cmp(&b.rms_after))
                .map_or(String::new(), |s| {
                    format!(" (worst: {} at {:.1} σ RMS)", s.signal, s.rms_after)
                });
            let tried_both = adapt.is_some_and(|a| a.fallback.is_some());
            // Within `good` under the inputs' noise: that noise is the misfit (spot readings
            // whose fuel flow, T1 and n2 the fit takes as exact), and the curves, the cooling
            // air and the maps are not where to look.
            let thresholds = Thresholds::default();
            let explained = under_inputs.filter(|q| *q <= thresholds.good_level);
            // What to check besides the curves. The cooling air is named because a file that
            // dumps it overboard where the unit returns some at the HPT exit misses T34 and T4
            // in opposite directions at every load, which no curve of corrected speed mends
            // (the independent simulator's unit: 1.42 σ overboard, 0.94 σ with its datasheet's
            // split; README, "Cooling air").
            let check = "check the data (units, instrument offsets, steadiness) and the file's \
                         cooling air against the datasheet (overboard: design.cooling_bleed_frac; \
                         returned at the HPT exit: design.cooling_return_frac)";
            let next = match (explained, adapt.map(|a| a.strategy)) {
                (Some(q), _) => format!(
                    "under the noise of the rows' inputs (fuel flow, T1, n2), which the fit \
                     takes as exact, the residuals are within good ({q:.2}): if these rows are \
                     spot readings rather than averages, that noise is the misfit, not the \
                     model; `calibrate --noisy-inputs` fits and judges them under it, and a \
                     snapshot diagnosis of such rows reads them under it with --noisy-inputs"
                ),
                (None, None) => {
                    "if the unit is of another make than the file's maps, add --adapt".into()
                }
                (None, Some(s)) if s == adapt::AdaptStrategy::Grown.name() && tried_both => {
                    format!(
                    "the --adapt-strategy continuation, tried in its place, did no better; with \
                     --adapt-max-knots below the default, raise it; else the curves of corrected \
                     speed cannot follow this unit: {check}, and the file's maps"
                )
                }
                (None, Some(s)) if s == adapt::AdaptStrategy::Grown.name() => format!(
                    "try --adapt-strategy continuation (every informed curve; --validate \
                     compares how each predicts the points left out), and {check}"
                ),
                (None, Some(_)) => format!(
                    "the curves of corrected speed cannot follow this unit; {check}, and the \
                     file's maps"
                ),
            };
            let carried = if explained.is_some() {
                String::new()
            } else {
                format!(
                    ": a diagnosis on this file carries that misfit and will be labelled {} at \
                     best",
                    verdict.as_str()
                )
            };
            (
                verdict,
                format!(
                    "the calibrated model misses the healthy baseline by {:.2} σ RMS{worst}\
                     {carried}; {next}",
                    level.sqrt(),
                ),
            )
        };
        BaselineFit {
            verdict,
            normalised_residual: level,
            summary,
            level_under_input_noise: under_inputs,
        }
    }
}

impl Calibration {
    /// The fitted values of the identified parameters and of those fitted to their bound
    /// (the best value inside the realistic interval, reported `at_bound`): what changes in
    /// the engine file.
    pub fn changes(&self) -> Vec<(String, f64)> {
        self.params
            .iter()
            .filter(|p| p.identifiable || p.status == "at_bound")
            .map(|p| (p.key.clone(), p.fitted))
            .collect()
    }

    /// The adapted model's own error to write, as `(adaptation.model_error_pct.<signal>, %)`
    /// and `(adaptation.health_error.<parameter>, points)`; empty without an adaptation or an
    /// estimate.
    pub fn model_error_values(&self) -> Vec<(String, f64)> {
        self.adaptation
            .iter()
            .flat_map(|a| &a.model_error.signals)
            .map(|s| (format!("adaptation.model_error_pct.{}", s.signal), s.pct))
            .chain(
                self.adaptation
                    .iter()
                    .flat_map(|a| &a.health_error.points)
                    .map(|(k, v)| (format!("adaptation.health_error.{k}"), *v)),
            )
            .collect()
    }

    /// The adaptation's words for the new file: which corrected speed a component's knots are
    /// in, where it is not the component's own (`adaptation.hpt.speed_of = "gg_inlet"`), and
    /// what shapes a turbine's efficiency, where not its map (`adaptation.pt.efficiency_shape =
    /// "curve"`).
    pub fn adaptation_words(&self) -> Vec<(String, String)> {
        let fitted = self
            .adaptation
            .iter()
            .flat_map(|a| &a.components)
            .filter(|c| !c.curves.is_empty());
        let mut words = Vec::new();
        for c in fitted {
            if c.speed_of != SpeedOf::OwnInlet {
                words.push((
                    format!("adaptation.{}.speed_of", c.component),
                    c.speed_of.name().to_string(),
                ));
            }
            if c.efficiency_shape != EfficiencyShape::Map {
                words.push((
                    format!("adaptation.{}.efficiency_shape", c.component),
                    c.efficiency_shape.name().to_string(),
                ));
            }
        }
        words
    }

    /// The adaptation curves to write, as `(adaptation.<component>.<curve>, values)` with each
    /// component's `speed_knots` first, then the GG speeds it was calibrated on
    /// (`adaptation.calibrated.gg_speed`) and the model error along the GG speed
    /// (`adaptation.model_error_by_speed.<speed_knots | signal>`); empty without an adaptation.
    pub fn adaptation_lists(&self) -> Vec<(String, Vec<f64>)> {
        let mut out = Vec::new();
        for c in self.adaptation.iter().flat_map(|a| &a.components) {
            if c.curves.is_empty() {
                continue;
            }
            out.push((
                format!("adaptation.{}.speed_knots", c.component),
                c.knots.clone(),
            ));
            for k in &c.curves {
                out.push((
                    format!("adaptation.{}.{}", c.component, k.curve),
                    k.values.clone(),
                ));
            }
        }
        // The GG's reach: a diagnosis leaves out what lies beyond it.
        if let Some(c) = self.adaptation.as_ref().and_then(|a| a.calibrated) {
            out.push(("adaptation.calibrated.gg_speed".into(), c.gg_speed.to_vec()));
        }
        if let Some(t) = self
            .adaptation
            .as_ref()
            .and_then(|a| a.model_error.by_speed.as_ref())
        {
            let key = |k: &str| format!("adaptation.model_error_by_speed.{k}");
            out.push((key("speed_knots"), t.speed_knots.clone()));
            for (signal, v) in &t.pct {
                out.push((key(signal), v.clone()));
            }
        }
        out
    }
}

/// Whether `x` sits on a bound of `[lower, upper]` (within 10⁻⁴ of the width).
fn on_bound(x: f64, lower: f64, upper: f64) -> bool {
    let tol = 1e-4 * (upper - lower).abs();
    (x - lower).abs() <= tol || (upper - x).abs() <= tol
}

/// One candidate's outcome: fitted at `x` with the identifiability verdict `v`.
pub(super) fn param_result(c: &Candidate, v: &identify::Verdict, x: f64) -> ParamResult {
    let at_bound = v.identifiable && on_bound(x, c.lower, c.upper);
    let reason = if at_bound {
        format!(
            "ended on its interval's bound ({x} in [{}, {}]): the data want a value \
             beyond the realistic interval. Check the data (units, an instrument \
             offset) or, if the unit really is that far from the file, widen it with \
             --params {}=LOW:HIGH",
            c.lower, c.upper, c.key
        )
    } else {
        v.reason.clone()
    };
    ParamResult {
        key: c.key.clone(),
        guess: c.guess,
        fitted: x,
        sigma: v.sigma_fraction.map(|s| s * (c.upper - c.lower)),
        lower: c.lower,
        upper: c.upper,
        identifiable: v.identifiable && !at_bound,
        status: if at_bound {
            "at_bound"
        } else if v.identifiable {
            "identified"
        } else {
            "not_identifiable"
        }
        .into(),
        reason,
    }
}

/// Residuals before (`r0`) and after (`r1`) of each signal, in the order the layout first
/// names them.
pub(super) fn signal_residuals(
    layout: &[(usize, crate::signals::Signal)],
    r0: &[f64],
    r1: &[f64],
) -> Vec<SignalResiduals> {
    let mut signals: Vec<SignalResiduals> = Vec::new();
    let mut order: Vec<crate::signals::Signal> = Vec::new();
    for (_, s) in layout {
        if !order.contains(s) {
            order.push(*s);
        }
    }
    for s in order {
        let pick = |r: &[f64]| -> Vec<f64> {
            layout
                .iter()
                .zip(r)
                .filter(|((_, x), _)| *x == s)
                .map(|(_, v)| *v)
                .collect()
        };
        let (b, a) = (pick(r0), pick(r1));
        signals.push(SignalResiduals {
            signal: s.to_string(),
            n: b.len(),
            mean_before: mean(&b),
            mean_after: mean(&a),
            rms_before: rms(&b),
            rms_after: rms(&a),
        });
    }
    signals
}

/// Residuals before (`r0`) and after (`r1`) of each point.
pub(super) fn point_residuals(
    points: &[problem::CalibrationPoint],
    layout: &[(usize, crate::signals::Signal)],
    r0: &[f64],
    r1: &[f64],
) -> Vec<PointResiduals> {
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let pick = |r: &[f64]| -> Vec<f64> {
                layout
                    .iter()
                    .zip(r)
                    .filter(|((k, _), _)| *k == i)
                    .map(|(_, v)| *v)
                    .collect()
            };
            PointResiduals {
                line: p.line,
                source: p.source.clone(),
                rms_before: rms(&pick(r0)),
                rms_after: rms(&pick(r1)),
            }
        })
        .collect()
}

/// The residuals after calibration, `r1`, as a table of every signal at every point.
pub(super) fn residual_table(
    points: &[problem::CalibrationPoint],
    layout: &[(usize, crate::signals::Signal)],
    r1: &[f64],
) -> ResidualTable {
    ResidualTable::from_cells(
        &points
            .iter()
            .map(|p| (p.line, p.data.operating_point()))
            .collect::<Vec<_>>(),
        &layout
            .iter()
            .zip(r1)
            .map(|(&(point, signal), &value)| Cell {
                point,
                signal,
                value,
            })
            .collect::<Vec<_>>(),
    )
}
