//! Blind proof of the sequence attribution (`gtwatch bench gap --sequence N`, issue 23 item 5):
//! a unit's start-ups a day apart on a compressor fouling trend, each fitted by Method B on its
//! own, with an input-channel error the tool is not told of appearing at start-up
//! [`ONSET`] — the fuel meter, T1, P1 or the power transducer, in the forms of
//! [`super::truth`]'s instrument kinds (a constant factor, a meter drifting through each
//! start-up, an offset) — or, as controls, an HP-turbine step the engine itself makes, or
//! nothing at all.
//!
//! What the daemon would do is done here: the first start-up that leaves the trend
//! ([`super::sequence::onset`]) gets the gap analysis's alias signatures
//! ([`super::alias::aliases`]), and the sequence is attributed with them
//! ([`super::sequence::attribute_steps`], the first step scored; a later one found is a false
//! alarm, since each truth has one step). A case is right when the verdict names one of the true
//! channel's instances (or is `ambiguous` with it among the candidates); on a control, when no
//! instrument is named. For named cases the corrected health of the stepped start-ups is
//! compared with the truth.
//!
//! Seeds and settings fixed before the cases are drawn. Pure: no I/O.

use super::alias::aliases;
use super::sequence::{self, SeqPoint, SequenceVerdict, Signature};
use super::truth::{self, Hidden, PlantScale};
use crate::diagnosis::transient::diagnose_transient;
use crate::diagnosis::{DiagnosisConfig, DiagnosisError};
use crate::engine::Engine;
use crate::health::{HealthBounds, HealthParams, HEALTH_NAMES};
use crate::recording::Recording;
use rand::{Rng, SeedableRng};
use serde::Serialize;

pub(crate) use super::truth::{input_instances, INPUT_KINDS};

/// Index of the first start-up with the hidden error.
pub(crate) const ONSET: usize = 4;
/// The controls: the engine's own step, and nothing.
pub(crate) const CONTROL_KINDS: [&str; 2] = ["turbine_step", "none"];

/// Whether a sequence is run on input kind `kind` by default: when its instrument is one the
/// health can hide ([`super::alias::is_input_instrument`]), which only a sequence tells apart
/// (the fuel meter's cut-off offset is named from one start-up, where idle and light-off show
/// it; `--kinds fuel_cutoff` still runs it).
fn hides_behind_health(kind: &str) -> bool {
    super::alias::is_input_instrument(truth::expected(kind))
}

/// The input kinds a sequence runs on when none are asked for: those whose instrument the
/// health can hide.
fn default_sequence_inputs() -> Vec<&'static str> {
    INPUT_KINDS
        .iter()
        .copied()
        .filter(|k| hides_behind_health(k))
        .collect()
}

/// One sequence.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct SequenceCase {
    pub(crate) index: usize,
    pub(crate) kind: String,
    pub(crate) start_ups: usize,
    /// The hidden error's magnitude (as `truth` draws it; the step in points for
    /// `turbine_step`).
    pub(crate) magnitude: f64,
    /// The first start-up that left the trend, if any.
    pub(crate) onset: Option<usize>,
    /// `instrument:<effect>`, `ambiguous:<candidates>`, `health_step:<explanation>`,
    /// `no_step`, or `not_found` (no start-up left the trend).
    pub(crate) verdict: String,
    pub(crate) correct: bool,
    /// The start-up the instrument was repaired before (it read right from there), when the
    /// run repairs it; and the one the verdict says it read right from (`None`: lasting).
    pub(crate) repaired_at: Option<usize>,
    pub(crate) fitted_until: Option<usize>,
    /// The named instrument's fitted error (its unit) and 1σ.
    pub(crate) fitted_magnitude: Option<f64>,
    pub(crate) fitted_magnitude_sigma: Option<f64>,
    /// Largest |estimate − truth| over the start-ups from [`ONSET`] on (those after a repair
    /// included), as fitted and as corrected (equal when nothing was corrected), points.
    pub(crate) error_fitted: f64,
    pub(crate) error_corrected: f64,
    /// Largest |estimate − truth| over the start-ups before [`ONSET`], where every instrument
    /// reads right: the model's own error on this unit (≈ 0 on its own twin; on another
    /// maker's unit, what the calibrated file still misses), points.
    pub(crate) error_before_onset: f64,
    /// As `error_corrected`, less the model's own error on this unit (per parameter, the mean
    /// of the corrected estimate − truth over the start-ups before [`ONSET`]): the error of the
    /// change a trend and the wash advice read, points.
    pub(crate) change_error_corrected: f64,
    /// Steps found after the first (`<verdict>@<start-up>`): false alarms, the truth has one.
    pub(crate) later_steps: Vec<String>,
    pub(crate) wall_s: f64,
}

/// The unit's true health at start-up `j`: a compressor fouling at `rate` per day, the rest
/// constant; `turbine` is added to D_GT from [`ONSET`] on for the `turbine_step` control.
fn true_health(base: [f64; 6], rate: f64, j: usize, turbine: f64) -> [f64; 6] {
    let mut h = base;
    h[0] += rate * j as f64;
    h[1] += 0.4 * rate * j as f64;
    if j >= ONSET {
        h[2] += turbine;
    }
    h
}

/// What [`run_sequences`] runs.
#[derive(Debug, Clone, Default)]
pub(crate) struct SequenceRun {
    pub(crate) cases: usize,
    /// Start-ups per sequence.
    pub(crate) start_ups: usize,
    pub(crate) seed: u64,
    /// Only these kinds (default: the five input kinds the health can hide, then the two
    /// controls).
    pub(crate) only: Vec<String>,
    /// The instrument is repaired after this many start-ups with the error (`None`: never).
    pub(crate) repair_after: Option<usize>,
    /// The instrument's error grows across the start-ups instead of stepping: none at the one
    /// before [`ONSET`], its drawn size at the newest, in equal steps a day (a meter's
    /// calibration drifting).
    pub(crate) drift: bool,
}

/// Runs `run.cases` sequences of `run.start_ups` each, cycling through the kinds: the
/// start-ups simulated on `plant`, diagnosed and attributed with `engine` (the model; the same
/// engine as `plant` for the model's own twin, else an engine file calibrated to that unit).
pub(crate) fn run_sequences(
    engine: &Engine,
    plant: &Engine,
    run: &SequenceRun,
    cfg: &DiagnosisConfig,
    mut progress: impl FnMut(&SequenceCase),
) -> Result<Vec<SequenceCase>, DiagnosisError> {
    let (only, start_ups) = (&run.only, run.start_ups);
    let known = |k: &str| INPUT_KINDS.contains(&k) || CONTROL_KINDS.contains(&k);
    if let Some(k) = only.iter().find(|k| !known(k.as_str())) {
        return Err(DiagnosisError::Config(format!(
            "unknown sequence truth {k:?}; known: {}, {}",
            INPUT_KINDS.join(", "),
            CONTROL_KINDS.join(", ")
        )));
    }
    if start_ups < ONSET + 2 {
        return Err(DiagnosisError::Config(format!(
            "a sequence needs at least {} start-ups (the error appears at start-up {})",
            ONSET + 2,
            ONSET + 1
        )));
    }
    if let Some(r) = run.repair_after {
        let least = ONSET + r.max(sequence::MIN_WINDOW) + 2;
        if r < sequence::MIN_WINDOW || start_ups < least {
            return Err(DiagnosisError::Config(format!(
                "a repair after {r} start-up(s) needs at least {} with the error and {least} \
                 start-ups in the sequence (two after the repair)",
                sequence::MIN_WINDOW
            )));
        }
    }
    let kinds: Vec<&str> = if only.is_empty() {
        default_sequence_inputs()
            .into_iter()
            .chain(CONTROL_KINDS)
            .collect()
    } else {
        only.iter().map(String::as_str).collect()
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(run.seed);
    let mut out = Vec::new();
    for index in 0..run.cases {
        let kind = kinds[index % kinds.len()];
        let c = one_sequence(engine, plant, index, kind, run, &mut rng, cfg)?;
        progress(&c);
        out.push(c);
    }
    Ok(out)
}

fn one_sequence(
    engine: &Engine,
    plant: &Engine,
    index: usize,
    kind: &str,
    run: &SequenceRun,
    rng: &mut impl Rng,
    cfg: &DiagnosisConfig,
) -> Result<SequenceCase, DiagnosisError> {
    let start_ups = run.start_ups;
    // The controls have no instrument to repair.
    let repaired_at = run
        .repair_after
        .map(|r| ONSET + r)
        .filter(|_| !CONTROL_KINDS.contains(&kind));
    let started = std::time::Instant::now();
    let base: [f64; 6] = std::array::from_fn(|i| {
        if i < 2 {
            rng.random_range(0.0..1.0)
        } else {
            rng.random_range(0.0..1.5)
        }
    });
    let rate = rng.random_range(0.1..0.3);
    let (hidden, magnitude, turbine) = match kind {
        "none" => (Hidden::None, 0.0, 0.0),
        "turbine_step" => {
            let step = -rng.random_range(1.0..2.0);
            (Hidden::None, step, step)
        }
        _ => {
            let (_, core) = Hidden::None.simulate(plant, &HealthParams::from_array(base))?;
            let scale = PlantScale::of(plant, &core);
            let d = truth::draw(kind, rng, &scale).ok_or_else(|| {
                DiagnosisError::Config(format!("hidden truth {kind:?} cannot be drawn"))
            })?;
            (d.hidden, d.magnitude, 0.0)
        }
    };
    let mut recs: Vec<Recording> = Vec::new();
    let mut fits = Vec::new();
    let mut truths = Vec::new();
    for j in 0..start_ups {
        let h = true_health(base, rate, j, turbine);
        let wrong = j >= ONSET && repaired_at.is_none_or(|m| j < m);
        let grown = if run.drift {
            hidden.scaled((j + 1 - ONSET) as f64 / (start_ups - ONSET) as f64)
        } else {
            hidden.clone()
        };
        let hid = if wrong { &grown } else { &Hidden::None };
        let (trace, samples) = hid.simulate(plant, &HealthParams::from_array(h))?;
        let noise_seed = 7_000 + 100 * index as u64 + j as u64;
        let rec = hid.record(&trace, &samples, noise_seed, true)?;
        fits.push(diagnose_transient(engine, &rec, cfg)?);
        recs.push(rec);
        truths.push(h);
    }
    let bounds = HealthBounds::default();
    let points: Vec<SeqPoint> = fits
        .iter()
        .enumerate()
        .map(|(j, f)| {
            SeqPoint::new(
                j as f64,
                f.health.to_array(),
                std::array::from_fn(|i| f.sigma.get(HEALTH_NAMES[i]).copied().unwrap_or(0.0)),
                &bounds,
            )
        })
        .collect();
    let error = |pts: &[SeqPoint]| max_error(pts.iter().zip(&truths).skip(ONSET), &[0.0; 6]);
    let error_fitted = error(&points);
    let recovers = crate::trend::RECOVERED_BY_WASH;
    // As the wash advice does: every step from the first onset on ([`sequence::attribute_steps`]),
    // each with the signatures of a gap analysis of its own onset. The truth has one step: the
    // first is scored, and any later one is a false alarm (`later_steps`).
    let signatures_at = |k: usize| -> Vec<Signature> {
        aliases(engine, &recs[k], cfg, &fits[k])
            .map(|a| {
                a.aliases
                    .iter()
                    .map(|x| Signature {
                        effect: x.effect.clone(),
                        unit: x.unit.to_string(),
                        nominal: x.nominal,
                        shift: x.health_shift.to_array(),
                        max_magnitude: x.max_magnitude,
                    })
                    .collect()
            })
            .unwrap_or_default()
    };
    // When no start-up steps away from the trend, a drift is looked for with the signatures
    // of the newest start-up's gap analysis (as the advice does with the newest stored one).
    let onset = sequence::onset(&points, recovers)
        .or_else(|| sequence::drift_onset(&points, &signatures_at(start_ups - 1)));
    let mut later_steps = Vec::new();
    let (verdict, correct, fitted, corrected, fitted_until) = match onset {
        None => ("not_found".to_string(), false, None, points.clone(), None),
        Some(k) => {
            let steps = sequence::attribute_steps(&points, k, recovers, None, signatures_at, &[]);
            let a = &steps[0];
            later_steps = steps[1..]
                .iter()
                .map(|s| format!("{}@{}", s.verdict.label(), s.onset))
                .collect();
            let names = input_instances(kind);
            let ok = match &a.verdict {
                SequenceVerdict::Instrument { effect, .. } => names.contains(&effect.as_str()),
                SequenceVerdict::Ambiguous { candidates } => {
                    candidates.iter().any(|c| names.contains(&c.as_str()))
                }
                SequenceVerdict::HealthStep { .. } | SequenceVerdict::NoStep => names.is_empty(),
            };
            let (v, fitted) = (a.verdict.label(), a.verdict.instrument_magnitude());
            let corrected = sequence::corrected_by_all(&steps, &points);
            (v, ok, fitted, corrected, a.verdict.until())
        }
    };
    // A control is right when no instrument is named (a step not found is right for `none`).
    let correct = correct || (onset.is_none() && kind == "none");
    Ok(SequenceCase {
        index,
        kind: kind.into(),
        start_ups,
        magnitude,
        onset,
        verdict,
        correct,
        repaired_at,
        fitted_until,
        fitted_magnitude: fitted.map(|f| f.0),
        fitted_magnitude_sigma: fitted.map(|f| f.1),
        error_fitted,
        error_corrected: error(&corrected),
        error_before_onset: error_before_onset(&points, &truths),
        change_error_corrected: change_error(&corrected, &truths),
        later_steps,
        wall_s: started.elapsed().as_secs_f64(),
    })
}

/// Largest |estimate − truth − `offset`| over `pairs` of a start-up's point and its truth, on
/// any parameter, points.
fn max_error<'a>(
    pairs: impl Iterator<Item = (&'a SeqPoint, &'a [f64; 6])>,
    offset: &[f64; 6],
) -> f64 {
    pairs
        .flat_map(|(p, t)| (0..6).map(move |i| (p.health[i] - t[i] - offset[i]).abs()))
        .fold(0.0, f64::max)
}

/// Largest |estimate − truth| over the start-ups before [`ONSET`] (every instrument right).
fn error_before_onset(points: &[SeqPoint], truths: &[[f64; 6]]) -> f64 {
    max_error(points.iter().zip(truths).take(ONSET), &[0.0; 6])
}

/// Largest |estimate − truth − offset| from [`ONSET`] on, the offset being the model's own
/// error on this unit: per parameter, the mean of estimate − truth over the start-ups before.
fn change_error(points: &[SeqPoint], truths: &[[f64; 6]]) -> f64 {
    let offset: [f64; 6] = std::array::from_fn(|i| {
        points
            .iter()
            .zip(truths)
            .take(ONSET)
            .map(|(p, t)| p.health[i] - t[i])
            .sum::<f64>()
            / ONSET as f64
    });
    max_error(points.iter().zip(truths).skip(ONSET), &offset)
}

/// The summary: attribution rate over input-channel sequences, false attribution on the
/// controls, and the health error before and after the correction.
pub(crate) fn summarise(cases: &[SequenceCase]) -> serde_json::Value {
    let inputs: Vec<&SequenceCase> = cases
        .iter()
        .filter(|c| INPUT_KINDS.contains(&c.kind.as_str()))
        .collect();
    let controls: Vec<&SequenceCase> = cases
        .iter()
        .filter(|c| CONTROL_KINDS.contains(&c.kind.as_str()))
        .collect();
    let rate = |v: &[&SequenceCase], f: &dyn Fn(&SequenceCase) -> bool| -> Option<f64> {
        (!v.is_empty()).then(|| v.iter().filter(|c| f(c)).count() as f64 / v.len() as f64)
    };
    let named: Vec<&SequenceCase> = inputs
        .iter()
        .copied()
        .filter(|c| c.correct && c.verdict.starts_with("instrument:"))
        .collect();
    let max = |v: &[&SequenceCase], f: &dyn Fn(&SequenceCase) -> f64| {
        v.iter().map(|c| f(c)).fold(0.0, f64::max)
    };
    let mut walls: Vec<f64> = cases.iter().map(|c| c.wall_s).collect();
    walls.sort_by(f64::total_cmp);
    let median_wall = walls.get(walls.len() / 2).copied();
    serde_json::json!({
        "sequences": cases.len(),
        "onset_index": ONSET,
        "input_sequences": inputs.len(),
        "input_attributed": rate(&inputs, &|c| c.correct),
        "input_named": rate(&inputs, &|c| c.correct && c.verdict.starts_with("instrument:")),
        "input_step_not_found": rate(&inputs, &|c| c.onset.is_none()),
        "control_sequences": controls.len(),
        "control_instrument_named": rate(&controls, &|c| c.verdict.starts_with("instrument:")),
        "named_max_error_fitted": max(&named, &|c| c.error_fitted),
        "named_max_error_corrected": max(&named, &|c| c.error_corrected),
        "named_corrected_within_0_3": rate(&named, &|c| c.error_corrected <= 0.3),
        // The model's own error where every instrument reads right (before the onset), and the
        // corrected error less it (its mean before the onset, per parameter): on another
        // maker's unit the first carries the calibrated file's misfit, the second is what a
        // trend reads.
        "max_error_before_onset": max(&cases.iter().collect::<Vec<_>>(), &|c| c.error_before_onset),
        "named_max_change_error_corrected": max(&named, &|c| c.change_error_corrected),
        "named_change_corrected_within_0_3": rate(&named, &|c| c.change_error_corrected <= 0.3),
        // Of the named instruments, those whose end (a repair, or none) is the truth's.
        "named_end_right": rate(&named, &|c| c.fitted_until == c.repaired_at),
        // Sequences (of one step) in which a second step was found: false alarms.
        "later_step_found": rate(&cases.iter().collect::<Vec<_>>(), &|c| !c.later_steps.is_empty()),
        "median_wall_s": median_wall,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The model's own error on a unit (a constant offset before the onset) is what
    /// `error_before_onset` reports and what `change_error` takes out of the later error.
    #[test]
    fn the_models_own_error_is_taken_out_of_the_change_error() {
        let truths: Vec<[f64; 6]> = (0..ONSET + 2)
            .map(|j| [0.2 * j as f64, 0.1, 0.0, 0.0, 0.0, 0.0])
            .collect();
        let bounds = HealthBounds::default();
        let points: Vec<SeqPoint> = truths
            .iter()
            .enumerate()
            .map(|(j, t)| {
                let mut h = *t;
                h[0] += 0.5;
                h[3] -= 0.4;
                if j == ONSET + 1 {
                    h[2] += 0.1;
                }
                SeqPoint::new(j as f64, h, [0.05; 6], &bounds)
            })
            .collect();
        assert!((error_before_onset(&points, &truths) - 0.5).abs() < 1e-12);
        assert!((change_error(&points, &truths) - 0.1).abs() < 1e-12);
    }

    /// The default sequence kinds are the five instruments the health can hide; the cut-off
    /// offset, which one start-up names, is not among them.
    #[test]
    fn sequences_run_by_default_on_the_instruments_the_health_can_hide() {
        assert_eq!(
            default_sequence_inputs(),
            [
                "fuel_scale",
                "fuel_drift",
                "t1_offset",
                "p1_offset",
                "power_scale"
            ]
        );
    }
}
