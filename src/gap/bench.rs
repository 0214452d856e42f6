//! Blind proof of the gap analysis (`gtwatch bench gap`): "plant" start-ups with random health
//! and default noise that carry one hidden truth — an effect structurally unlike the library's
//! candidate forms, or none, or one the library does not have (`super::truth`) — analysed
//! without being told which.
//!
//! A case draws a health vector, then the truth's magnitudes across REFERENCE §5's ranges. Only
//! cases whose signature is at least [`MIN_SIGNATURE_SIGMA`] × the noise are analysed: the
//! signature is the worst cell of the residual map (the analysis's own yardstick, RMS of the
//! difference in noise σ per signal × phase) between the plant's noise-free record and the
//! core model at the true health replaying it. A draw below that is redrawn (up to
//! [`MAX_DRAWS`] times, then the case is reported as skipped); `none` cases are not filtered.
//! With `holdout`, a second start-up of the same unit (same health and hidden truth, other
//! noise) is simulated and the candidates are scored on it; without, by blocked
//! cross-validation over the one start-up.
//!
//! Library, thresholds and seeds are fixed before the cases are drawn. Pure: no I/O.

use super::truth::{self, Drawn, Hidden, PlantScale};
use super::{analyse, GapReport};
use crate::diagnosis::fit_quality::localise;
use crate::diagnosis::{DiagnosisConfig, DiagnosisError};
use crate::engine::measured_drive::{simulate_segment, DriveMode};
use crate::engine::Engine;
use crate::health::{HealthParams, HEALTH_NAMES};
use crate::optim::median;
use crate::recording::Recording;
use crate::signals::Signal;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use std::collections::BTreeMap;

pub(crate) use super::truth::{expected, input_instances, INPUT_KINDS, KINDS};

/// Least signature of an analysed case, in noise σ (worst residual cell).
pub(crate) const MIN_SIGNATURE_SIGMA: f64 = 3.0;
/// Draws of a truth's magnitudes before a case is skipped as below noise.
pub(crate) const MAX_DRAWS: usize = 8;

/// One analysed case.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Case {
    pub(crate) index: usize,
    pub(crate) kind: String,
    /// The truth's magnitude (unit per kind: see `gap::truth`).
    pub(crate) magnitude: f64,
    /// The winning candidate's magnitude in the same unit, when one won.
    pub(crate) fitted_magnitude: Option<f64>,
    /// The hidden truth as drawn (its form and every parameter; for reading a case, never
    /// given to the analysis).
    pub(crate) hidden: String,
    /// The winning candidate's fitted parameters: name → (value, 1σ) (empty when none won).
    pub(crate) fitted_params: BTreeMap<String, (f64, f64)>,
    /// The truth's signature, noise σ (worst residual cell against the core model).
    pub(crate) signature_sigma: f64,
    /// Draws of the magnitudes it took to pass [`MIN_SIGNATURE_SIGMA`].
    pub(crate) draws: usize,
    pub(crate) truth: HealthParams,
    pub(crate) verdict: String,
    /// The instruments an `ambiguous` verdict lists.
    pub(crate) verdict_aliases: Vec<String>,
    pub(crate) correct: bool,
    /// The verdict's shrinkage (the winner's score: held-out when a holdout was analysed).
    pub(crate) shrinkage: f64,
    /// The winner's shrinkage on the fitted start-up, and on the held-out one.
    pub(crate) train_shrinkage: Option<f64>,
    pub(crate) heldout_shrinkage: Option<f64>,
    pub(crate) baseline_fit_quality: String,
    /// The fit quality of the model behind `health_after` (the winner's, else the baseline's).
    pub(crate) fit_quality_after: String,
    pub(crate) error_before: f64,
    pub(crate) error_after: f64,
    pub(crate) health_before: HealthParams,
    pub(crate) health_after: HealthParams,
    /// Rank (1 = first) of the truth's expected candidate in the analysis's screen, and whether
    /// the screen passed it on to be scored (`None` for truths without a library candidate, or
    /// when the baseline fitted and nothing was screened; `false` also when the linear screen
    /// left it unfitted).
    pub(crate) expected_screen_rank: Option<usize>,
    pub(crate) expected_shortlisted: Option<bool>,
    /// The analysis's wall time, s, and the fits it ran.
    pub(crate) analysis_wall_s: f64,
    /// The analysis's wall time by stage, s.
    pub(crate) stage_wall_s: super::StageWalls,
    pub(crate) fits: usize,
}

/// A case whose truth stayed below [`MIN_SIGNATURE_SIGMA`] in every draw (not analysed).
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Skipped {
    pub(crate) index: usize,
    pub(crate) kind: String,
    /// The largest signature drawn, σ.
    pub(crate) best_signature_sigma: f64,
}

/// All cases of a run.
#[derive(Debug, Clone, Default, Serialize)]
pub(crate) struct BenchRun {
    pub(crate) cases: Vec<Case>,
    pub(crate) skipped: Vec<Skipped>,
}

/// An input-channel truth named by the verdict, or among the instruments an `ambiguous`
/// verdict lists (not merely among the instruments analysed, which are all of them).
fn input_named(kind: &str, r: &GapReport) -> bool {
    let names = input_instances(kind);
    names.contains(&r.verdict.effect.as_str())
        || (r.verdict.effect == super::AMBIGUOUS
            && r.verdict
                .aliases
                .iter()
                .any(|a| names.contains(&a.as_str())))
}

fn max_error(h: &HealthParams, truth: &HealthParams) -> f64 {
    let (a, b) = (h.to_array(), truth.to_array());
    (0..6).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}

/// The signature of a hidden truth: the worst residual cell (noise σ) between the plant's
/// noise-free record `clean` and the core model at the true health replaying it, over the
/// signals the diagnosis compares.
pub(crate) fn signature_sigma(
    engine: &Engine,
    health: &HealthParams,
    clean: &Recording,
    cfg: &DiagnosisConfig,
) -> Result<f64, DiagnosisError> {
    let model = simulate_segment(engine, health, clean, cfg.drive_mode)?;
    let signals: Vec<Signal> = cfg
        .signals
        .iter()
        .copied()
        .filter(|&s| {
            s != Signal::T1 && !(s == Signal::FuelFlow && cfg.drive_mode == DriveMode::MeasuredFuel)
        })
        .collect();
    let cells = localise(
        clean.times(),
        clean.phases(),
        clean.rows(),
        &model.measured,
        &signals,
        &engine.cfg().sensors,
        &|_, _, _| 0.0,
    );
    Ok(cells
        .iter()
        .map(|c| c.norm_error)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max))
}

/// Which cases a benchmark run draws and analyses.
#[derive(Debug, Clone, Default)]
pub(crate) struct CaseSelection {
    /// Cases drawn, cycling through [`KINDS`] (or `only` when not empty).
    pub(crate) cases: usize,
    /// Seed of the draw (health vectors, magnitudes, noise).
    pub(crate) seed: u64,
    pub(crate) only: Vec<String>,
    /// Cases before this index are drawn but not analysed (the draw is sequential, so case k
    /// is the same unit and truth whatever this is).
    pub(crate) from_case: usize,
    /// A second start-up of each unit to score on.
    pub(crate) holdout: bool,
}

/// Runs the cases of `sel` with all candidates.
pub(crate) fn run_cases(
    engine: &Engine,
    sel: &CaseSelection,
    cfg: &DiagnosisConfig,
    mut progress: impl FnMut(&Case),
) -> Result<BenchRun, DiagnosisError> {
    let CaseSelection {
        cases,
        seed,
        ref only,
        from_case,
        holdout,
    } = *sel;
    let known = |k: &str| KINDS.contains(&k) || INPUT_KINDS.contains(&k);
    if let Some(k) = only.iter().find(|k| !known(k.as_str())) {
        return Err(DiagnosisError::Config(format!(
            "unknown hidden truth {k:?}; known: {}, {}",
            KINDS.join(", "),
            INPUT_KINDS.join(", ")
        )));
    }
    let kinds: Vec<&str> = if only.is_empty() {
        KINDS.to_vec()
    } else {
        only.iter().map(String::as_str).collect()
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let candidates = crate::engine::effects::instance_names();
    let mut out = BenchRun::default();
    for index in 0..cases {
        let kind = kinds[index % kinds.len()];
        let truth = HealthParams::from_array(std::array::from_fn(|_| rng.random_range(0.0..3.0)));
        let (_, core_samples) = Hidden::None.simulate(engine, &truth)?;
        let scale = PlantScale::of(engine, &core_samples);
        // Draw magnitudes until the truth shows above noise.
        let mut accepted: Option<(Drawn, f64, usize)> = None;
        let mut best = 0.0f64;
        for draw in 1..=MAX_DRAWS {
            let d = truth::draw(kind, &mut rng, &scale).ok_or_else(|| {
                DiagnosisError::Config(format!("hidden truth {kind:?} cannot be drawn"))
            })?;
            if matches!(d.hidden, Hidden::None) {
                accepted = Some((d, 0.0, draw));
                break;
            }
            let (plant, samples) = d.hidden.simulate(engine, &truth)?;
            let clean = d.hidden.record(&plant, &samples, 0, false)?;
            let sig = signature_sigma(engine, &truth, &clean, cfg)?;
            best = best.max(sig);
            if sig >= MIN_SIGNATURE_SIGMA {
                accepted = Some((d, sig, draw));
                break;
            }
        }
        let Some((drawn, signature, draws)) = accepted else {
            out.skipped.push(Skipped {
                index,
                kind: kind.into(),
                best_signature_sigma: best,
            });
            continue;
        };
        if index < from_case {
            // Drawn all the same (the draw is sequential), so case k is the same unit and
            // truth whatever `from_case` is; only its analysis is left out.
            continue;
        }
        let (plant, samples) = drawn.hidden.simulate(engine, &truth)?;
        let rec = drawn
            .hidden
            .record(&plant, &samples, 1000 + index as u64, true)?;
        let ho = if holdout {
            Some(
                drawn
                    .hidden
                    .record(&plant, &samples, 500_000 + index as u64, true)?,
            )
        } else {
            None
        };
        let r: GapReport = analyse(engine, &rec, ho.as_ref(), &candidates, cfg)?;
        let winner = r.candidates.iter().find(|c| c.effect == r.verdict.effect);
        let mut by_screen: Vec<&super::Candidate> = r.candidates.iter().collect();
        by_screen.sort_by(|a, b| b.screen_shrinkage.total_cmp(&a.screen_shrinkage));
        let expected_at = by_screen.iter().position(|c| c.effect == expected(kind));
        let c = Case {
            index,
            kind: kind.into(),
            magnitude: drawn.magnitude,
            fitted_magnitude: winner.and_then(|w| truth::fitted_magnitude(&w.effect, &w.params)),
            hidden: format!("{:?}", drawn.hidden),
            fitted_params: winner.map(|w| w.params.clone()).unwrap_or_default(),
            signature_sigma: signature,
            draws,
            truth,
            // On a truth without an effect `ambiguous` is right too: it names nothing and says
            // an input instrument could hide behind the health.
            correct: r.verdict.effect == expected(kind)
                || (expected(kind) == "none" && r.verdict.effect == super::AMBIGUOUS)
                || input_named(kind, &r),
            verdict: r.verdict.effect.clone(),
            verdict_aliases: r.verdict.aliases.clone(),
            shrinkage: r.verdict.shrinkage,
            train_shrinkage: winner.map(|w| w.train_shrinkage),
            heldout_shrinkage: winner.and_then(|w| w.heldout_shrinkage),
            baseline_fit_quality: r.baseline_fit_quality.as_str().into(),
            fit_quality_after: r.verdict.fit_quality_after.as_str().into(),
            error_before: max_error(&r.verdict.health_before, &truth),
            error_after: max_error(&r.verdict.health_after, &truth),
            health_before: r.verdict.health_before,
            health_after: r.verdict.health_after,
            expected_screen_rank: expected_at.map(|k| k + 1),
            // A truth's candidate the linear screen left unfitted was not shortlisted either.
            expected_shortlisted: expected_at.map(|k| by_screen[k].shortlisted).or_else(|| {
                r.unscreened
                    .iter()
                    .any(|u| u.effect == expected(kind))
                    .then_some(false)
            }),
            stage_wall_s: r.stage_wall_s,
            analysis_wall_s: r.wall_s,
            fits: r.fits,
        };
        progress(&c);
        out.cases.push(c);
    }
    Ok(out)
}

fn rate(v: &[&Case], f: impl Fn(&Case) -> bool) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().filter(|c| f(c)).count() as f64 / v.len() as f64)
}

/// Per-parameter health RMSE over `cases`, percentage points.
fn health_rmse(cases: &[&Case], pick: impl Fn(&Case) -> HealthParams) -> BTreeMap<String, f64> {
    HEALTH_NAMES
        .iter()
        .enumerate()
        .map(|(i, n)| {
            let sq: f64 = cases
                .iter()
                .map(|c| (pick(c).to_array()[i] - c.truth.to_array()[i]).powi(2))
                .sum();
            (n.to_string(), (sq / cases.len().max(1) as f64).sqrt())
        })
        .collect()
}

/// The summary the acceptance asks for (rates are `null` where no case counts).
pub(crate) fn summarise(run: &BenchRun) -> serde_json::Value {
    let cases = &run.cases;
    let in_lib: Vec<&Case> = cases
        .iter()
        .filter(|c| truth::in_library(&c.kind))
        .collect();
    let nulls: Vec<&Case> = cases
        .iter()
        .filter(|c| expected(&c.kind) == "none")
        .collect();
    let outs: Vec<&Case> = cases
        .iter()
        .filter(|c| expected(&c.kind) == "unexplained")
        .collect();
    let mut confusion: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    let mut per_kind: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for c in cases {
        *confusion
            .entry(c.kind.clone())
            .or_default()
            .entry(c.verdict.clone())
            .or_default() += 1;
        let e = per_kind.entry(c.kind.clone()).or_default();
        e.0 += 1;
        e.1 += usize::from(c.correct);
    }
    let per_kind: BTreeMap<String, serde_json::Value> = per_kind
        .into_iter()
        .map(|(k, (n, ok))| {
            (
                k.clone(),
                serde_json::json!({"cases": n, "correct": ok, "expected": expected(&k)}),
            )
        })
        .collect();
    let bad: Vec<&Case> = cases.iter().filter(|c| c.error_before > 0.3).collect();
    let inputs: Vec<&Case> = cases
        .iter()
        .filter(|c| INPUT_KINDS.contains(&c.kind.as_str()))
        .collect();
    let identified: Vec<&Case> = in_lib.iter().copied().filter(|c| c.correct).collect();
    serde_json::json!({
        "cases": cases.len(),
        "skipped_below_noise": run.skipped.len(),
        "min_signature_sigma": MIN_SIGNATURE_SIGMA,
        "in_library_cases": in_lib.len(),
        "top1_identification": rate(&in_lib, |c| c.correct),
        "top1_by_kind": per_kind,
        "false_attribution_on_null": rate(&nulls, |c| super::names_effect(&c.verdict)),
        "ambiguous_on_null": rate(&nulls, |c| c.verdict == super::AMBIGUOUS),
        "unexplained_on_out_of_library": rate(&outs, |c| c.verdict == "unexplained"),
        // The verdict's shrinkage over in-library cases, always on data its fit did not see:
        // the second start-up with --holdout, else the blocked cross-validation's other fold.
        "median_shrinkage": median(in_lib.iter().map(|c| c.shrinkage).collect()),
        "median_heldout_shrinkage": median(in_lib.iter().filter_map(|c| c.heldout_shrinkage).collect()),
        "median_train_shrinkage": median(in_lib.iter().filter_map(|c| c.train_shrinkage).collect()),
        // |fitted − true| / |true| of the winning candidate's magnitude, correctly identified
        // cases.
        "median_magnitude_error": median(
            identified
                .iter()
                .filter_map(|c| c.fitted_magnitude.map(|f| ((f - c.magnitude) / c.magnitude).abs()))
                .collect()
        ),
        // Health RMSE (points) over in-library cases before and after the winning effect
        // (after = before when no effect was named), and over the correctly identified ones.
        "health_rmse_before": health_rmse(&in_lib, |c| c.health_before),
        "health_rmse_after": health_rmse(&in_lib, |c| c.health_after),
        "health_rmse_before_identified": health_rmse(&identified, |c| c.health_before),
        "health_rmse_after_identified": health_rmse(&identified, |c| c.health_after),
        // Whether the screen passed the truth's candidate on to be scored (in-library cases
        // where a screen ran).
        "expected_shortlisted": rate(
            &in_lib.iter().copied().filter(|c| c.expected_shortlisted.is_some()).collect::<Vec<_>>(),
            |c| c.expected_shortlisted == Some(true)
        ),
        "median_analysis_wall_s": median(cases.iter().map(|c| c.analysis_wall_s).collect()),
        "max_analysis_wall_s": cases.iter().map(|c| c.analysis_wall_s).fold(0.0, f64::max),
        "fit_quality_flags_bad_cases": rate(&bad, |c| c.baseline_fit_quality != "good"),
        "fit_quality_flags_clean_cases": rate(&nulls, |c| c.baseline_fit_quality != "good"),
        // In-library cases whose health after the named effect is off by more than 0.3 points:
        // how many of them the fit after the effect flags (not `good`).
        "fit_quality_flags_bad_after": rate(
            &in_lib.iter().copied().filter(|c| c.error_after > 0.3).collect::<Vec<_>>(),
            |c| c.fit_quality_after != "good"
        ),
        // Input-channel truths: the channel named, or `ambiguous` with it among the aliases;
        // and the silent failures the acceptance forbids (`none` or a good fit that names
        // nothing while the health is off by more than 0.3 points).
        "input_cases": inputs.len(),
        "input_named_or_aliased": rate(&inputs, |c| c.correct),
        "input_silent_with_health_error": inputs
            .iter()
            .filter(|c| !c.correct && c.baseline_fit_quality == "good" && c.error_before > 0.3)
            .count(),
        // A verdict that does not say the health is in doubt (not `ambiguous`) with its fit
        // called `good`, yet a health more than 0.3 points off: the assurance a plant must not
        // get.
        "input_good_after_with_health_error": inputs
            .iter()
            .filter(|c| {
                c.verdict != super::AMBIGUOUS
                    && c.fit_quality_after == "good"
                    && c.error_after > 0.3
            })
            .count(),
        "confusion": confusion,
        "skipped": run.skipped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_case_is_the_same_unit_and_start_up_whatever_the_first_analysed_case() {
        let engine = Engine::reference().expect("engine");
        let cfg = DiagnosisConfig {
            threads: Some(1),
            max_model_runs: 120,
            ..Default::default()
        };
        let selection = |from_case| CaseSelection {
            cases: 3,
            seed: 5,
            only: vec!["none".into()],
            from_case,
            holdout: false,
        };
        let all = run_cases(&engine, &selection(0), &cfg, |_| {}).expect("all cases");
        let last = run_cases(&engine, &selection(2), &cfg, |_| {}).expect("from case 2");
        assert_eq!(all.cases.len(), 3);
        assert_eq!(last.cases.len(), 1);
        let (a, b) = (&all.cases[2], &last.cases[0]);
        assert_eq!(b.index, 2);
        // The same truth drawn, and the same noisy start-up (the same health fitted to it).
        assert_eq!(a.truth, b.truth);
        assert_ne!(all.cases[1].truth, b.truth);
        assert_eq!(a.health_before, b.health_before);
    }
}
