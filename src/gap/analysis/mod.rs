//! The analysis itself, as a sequence of named stages ([`analyse`]): the baseline and its
//! aliases, the first batch (seed refits, the baseline's folds or held-out start-up, the
//! screen), the screen's ranking, the shortlist's scoring, the leader's refit (and its
//! refinement, where its effect has one) and the verdict. The stages' rooms: `batch`, `scoring`,
//! `leader`, `verdict`; this file holds the run's state and its helpers.

mod batch;
mod leader;
mod scoring;
mod verdict;

use super::candidates::{
    fit_params, gate_instruments, refined_params, worth_trying, Trial, Unscreened,
};
use super::{
    alias, Candidate, GapReport, GapVerdict, Scoring, SignalTraces, StageWalls, AMBIGUOUS,
    CV_BLOCK_S, MIN_SHRINKAGE, SCREEN_BUDGET, SEED_REFITS, SHORTLIST, SHORTLIST_RATIO,
};
use crate::diagnosis::config::Blocks;
use crate::diagnosis::fit_quality::Verdict;
use crate::diagnosis::transient::{
    diagnose_transient, objective_for, sample_speeds, within_calibration,
};
use crate::diagnosis::{DiagnosisConfig, DiagnosisError, FitParam, MethodResult};
use crate::engine::trace::Values;
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::recording::Recording;
use crate::signals::Signal;
use std::collections::BTreeMap;
use std::time::Instant;

fn bic(r: &MethodResult, k: usize) -> f64 {
    let n = r.residuals.max(1) as f64;
    n * (r.ssr / n).max(1e-300).ln() + k as f64 * n.ln()
}

/// BIC decrease a refinement must bring to be kept: "very strong" evidence on the usual scale
/// (a difference above 10), so a refinement is not kept for the noise it fits.
const REFINEMENT_BIC_GAIN: f64 = 10.0;

/// Where the refinement of `effect` starts, from the simple form's `fit`: for each start, the
/// refinement's parameters and values (the effect's `refinement_starts`, else its defaults).
fn refinement_starts(effect: &str, fit: &MethodResult) -> Vec<Vec<(String, f64)>> {
    let Some(spec) = crate::engine::effects::spec(effect) else {
        return Vec::new();
    };
    let fitted = effect_params(fit);
    let key = |p: &str| format!("effects.{effect}.{p}");
    let simple: Vec<f64> = spec
        .params
        .iter()
        .map(|p| fitted.get(&key(p.name)).map_or(p.default, |&(v, _)| v))
        .collect();
    let refinement: Vec<_> = spec.params.iter().filter(|p| p.refinement).collect();
    let starts = match spec.refinement_starts {
        Some(f) => f(&simple),
        None => vec![refinement.iter().map(|p| p.default).collect()],
    };
    starts
        .into_iter()
        .map(|values| refinement.iter().map(|p| key(p.name)).zip(values).collect())
        .collect()
}

/// Whether a fitted value of `params` lies on its interval's bound (within half a percent of
/// the interval).
fn on_a_bound(fit: &MethodResult, params: &[FitParam]) -> bool {
    params.iter().any(|p| {
        let margin = 0.005 * (p.upper - p.lower);
        fit.params
            .iter()
            .find(|q| q.name == p.name)
            .is_some_and(|q| q.value <= p.lower + margin || q.value >= p.upper - margin)
    })
}

/// `cfg` restricted to one fold of the blocked cross-validation.
fn fold_cfg(cfg: &DiagnosisConfig, parity: u8) -> DiagnosisConfig {
    let mut c = cfg.clone();
    c.window.blocks = Some(Blocks {
        length_s: CV_BLOCK_S,
        parity,
    });
    c
}

/// One fit on one fold: its result and its sum of squares on the other fold.
struct FoldFit {
    fit: MethodResult,
    test_ssr: f64,
}

fn fit_fold(
    engine: &Engine,
    rec: &Recording,
    cfg: &DiagnosisConfig,
    parity: u8,
) -> Result<FoldFit, DiagnosisError> {
    let fit = diagnose_transient(engine, rec, &fold_cfg(cfg, parity))?;
    let test_ssr = objective_for(engine, rec, &fold_cfg(cfg, 1 - parity)).ssr(&fit.model_values);
    Ok(FoldFit { fit, test_ssr })
}

/// What one candidate job returns: a fit on the whole start-up (holdout scoring) with the
/// held-out start-up's SSR after the health refit, or a fit on one fold.
enum CandidateFit {
    Whole {
        fit: MethodResult,
        heldout_ssr: Option<f64>,
    },
    Fold(FoldFit),
}

/// Model runs of a full candidate fit with `extra` effect parameters: the baseline's budget and
/// 100 more per parameter.
fn candidate_runs(cfg: &DiagnosisConfig, extra: usize) -> usize {
    cfg.max_model_runs + 100 * extra
}

/// `engine` with the effect parameters of `fit` set (the start of a refit from it).
fn with_effect_params(engine: &Engine, fit: &MethodResult) -> Result<Engine, DiagnosisError> {
    let mut e = engine.clone();
    for (key, (v, _)) in effect_params(fit) {
        e.set_param(&key, v)?;
    }
    Ok(e)
}

/// The effect parameters of a fit: name → (value, 1σ).
fn effect_params(r: &MethodResult) -> BTreeMap<String, (f64, f64)> {
    r.params
        .iter()
        .filter(|p| p.name.starts_with("effects."))
        .map(|p| (p.name.clone(), (p.value, p.sigma)))
        .collect()
}

fn mean_health(a: &HealthParams, b: &HealthParams) -> HealthParams {
    let (a, b) = (a.to_array(), b.to_array());
    HealthParams::from_array(std::array::from_fn(|i| 0.5 * (a[i] + b[i])))
}

fn worse(a: Verdict, b: Verdict) -> Verdict {
    let rank = |v: Verdict| match v {
        Verdict::Good => 0,
        Verdict::Suspect => 1,
        Verdict::Poor => 2,
    };
    if rank(a) >= rank(b) {
        a
    } else {
        b
    }
}

/// Runs `jobs` on `threads` worker threads, each fit single-threaded (a fit's result does not
/// depend on its thread count, so the order of completion changes nothing), results in order.
///
/// Plain scoped threads take the jobs in the order given from a shared counter, so the longest
/// jobs, listed first, start first and the workers finish together. Not a rayon pool: a fit
/// runs on its own one-thread pool, and a rayon worker waiting for another pool steals its own
/// pool's queued jobs meanwhile, which nests fits on one core and left the second idle (1.3 of
/// 2 cores used in a measured analysis).
fn in_parallel<J: Sync, R: Send>(
    threads: usize,
    jobs: &[J],
    run: impl Fn(&J) -> R + Sync + Send,
) -> Result<Vec<R>, DiagnosisError> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let next = AtomicUsize::new(0);
    let workers = threads.clamp(1, jobs.len().max(1));
    let mut done: Vec<(usize, R)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                scope.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(job) = jobs.get(i) else { break };
                        mine.push((i, run(job)));
                    }
                    mine
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .map_err(|_| DiagnosisError::Config("a gap analysis worker panicked".into()))
            })
            .collect::<Result<Vec<_>, _>>()
            .map(|v| v.into_iter().flatten().collect())
    })?;
    done.sort_by_key(|(i, _)| *i);
    Ok(done.into_iter().map(|(_, r)| r).collect())
}

/// Runs the analysis of `rec` (and `holdout`, a second start-up of the same unit) over the
/// candidate instances `candidates`. Without a holdout the candidates are scored by blocked
/// cross-validation ([`Scoring::BlockedCv`]). The fits after the baseline run in parallel on
/// `cfg.threads` workers (all cores by default).
///
/// The stages, in order: the baseline fit and its aliases; the first batch (seed refits, the
/// baseline's folds or held-out start-up, the screen); the shortlist's scoring; the leader's
/// refit (cross-validation only); the verdict.
pub(crate) fn analyse(
    engine: &Engine,
    rec: &Recording,
    holdout: Option<&Recording>,
    candidates: &[String],
    cfg: &DiagnosisConfig,
) -> Result<GapReport, DiagnosisError> {
    let start = Instant::now();
    // Ordinary least squares throughout: the question here is whether a slow pattern in the
    // residuals is an unmodelled effect or a wrong instrument, and the fuel meter's noise
    // covariance (Method B's default) would discount exactly such patterns as the meter's slow
    // noise. Measured with it on: a fuel meter drifting 0 → 2.6 % through the start-up was
    // named a power-transducer ratio (`bench gap --kinds fuel_drift,…`, 8 of 10 input truths
    // named or aliased against 9), and the two-node casings' D_ET came out 0.2 points worse.
    let plain = DiagnosisConfig {
        fuel_noise_covariance: false,
        ..cfg.clone()
    };
    let cfg = &plain;
    let threads = cfg
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let single = DiagnosisConfig {
        threads: Some(1),
        ..cfg.clone()
    };
    let scoring = if holdout.is_some() {
        Scoring::Holdout
    } else {
        Scoring::BlockedCv
    };
    let base = diagnose_transient(engine, rec, cfg)?;
    // Input instruments the health may be hiding (one model run per parameter; a baseline that
    // cannot be linearised has no alias analysis, which the report shows as an empty list).
    let aliases = alias::aliases(engine, rec, &single, &base).unwrap_or_default();
    let baseline_wall = start.elapsed().as_secs_f64();
    let run = Run {
        engine,
        rec,
        holdout,
        cfg,
        single,
        threads,
        scoring,
        k_base: 6 + usize::from(cfg.fit_ambient_pressure),
        base,
    };
    // Candidates are fitted where the residual shows a gap; a fit within noise whose health is
    // implausible is a question for the aliases, which refitting cannot answer.
    let mut fitted = if run.base.fit_quality.residual_verdict == Verdict::Good {
        Fitted::none()
    } else {
        run.fit_candidates(candidates)?
    };
    fitted.stages.baseline = baseline_wall;
    // The shortlist first, by score; then the rest of the screen, by its shrinkage.
    fitted.candidates.sort_by(|a, b| {
        b.shortlisted
            .cmp(&a.shortlisted)
            .then(b.score.total_cmp(&a.score))
            .then(b.bic_gain.total_cmp(&a.bic_gain))
    });
    match scoring {
        Scoring::BlockedCv => run.refit_leader(&mut fitted)?,
        Scoring::Holdout => run.refine_holdout_leader(&mut fitted),
    }
    for c in &mut fitted.candidates {
        c.model_error = model_error_of(engine, rec, &c.effect);
    }
    let verdict = run.verdict(
        &fitted.candidates,
        &aliases,
        fitted.optimiser_spread,
        &fitted.models,
    );
    let worst_signal = run.worst_signal(&verdict, &fitted.models);
    let base = run.base;
    Ok(GapReport {
        baseline_fit_quality: base.fit_quality.verdict,
        baseline_normalised_residual: base.fit_quality.normalised_residual,
        fuel_meter_zero: base.fuel_meter_zero,
        summary: base.fit_quality.summary.clone(),
        localisation: base.localisation,
        optimiser_spread: fitted.optimiser_spread,
        scoring,
        candidates: fitted.candidates,
        unscreened: fitted.unscreened,
        verdict,
        aliases,
        fits: fitted.fits,
        threads,
        wall_s: start.elapsed().as_secs_f64(),
        stage_wall_s: fitted.stages,
        worst_signal,
    })
}

/// One analysis: its inputs, settings and baseline fit, which every stage reads.
struct Run<'a> {
    engine: &'a Engine,
    rec: &'a Recording,
    holdout: Option<&'a Recording>,
    cfg: &'a DiagnosisConfig,
    /// `cfg` on one thread (the fits run in parallel, each on one thread).
    single: DiagnosisConfig,
    threads: usize,
    scoring: Scoring,
    /// Parameters of the baseline fit (the health, and the ambient pressure when fitted).
    k_base: usize,
    base: MethodResult,
}

/// What fitting the candidates gives.
struct Fitted {
    candidates: Vec<Candidate>,
    unscreened: Vec<Unscreened>,
    /// Model values of each candidate fitted on the whole start-up, by name.
    models: BTreeMap<String, Vec<Values>>,
    /// The screen's fit of each candidate (the start of the leader's full refit).
    screened: BTreeMap<String, MethodResult>,
    /// Held-out scoring: each shortlisted candidate's fit on the whole start-up (the leader's
    /// refinement starts there); empty under cross-validation.
    whole: BTreeMap<String, MethodResult>,
    optimiser_spread: f64,
    /// Fits run so far, the baseline's included.
    fits: usize,
    stages: StageWalls,
    /// When the last stage ended (the leader's refit is timed from here).
    lap: Instant,
}

impl Fitted {
    /// Nothing fitted: the baseline alone.
    fn none() -> Self {
        Self {
            candidates: Vec::new(),
            unscreened: Vec::new(),
            models: BTreeMap::new(),
            screened: BTreeMap::new(),
            whole: BTreeMap::new(),
            optimiser_spread: 0.0,
            fits: 1,
            stages: StageWalls::default(),
            lap: Instant::now(),
        }
    }
}

/// A job of the first batch.
#[derive(Clone, Copy)]
enum BaseJob {
    Seed(u64),
    Holdout,
    Fold(u8),
    Screen(usize),
}

/// What a job of the first batch returns.
enum BaseOut {
    Fit(Result<FoldFit, DiagnosisError>),
    Screen(Option<MethodResult>),
}

/// The first batch's results.
struct FirstBatch {
    /// Fits the batch ran.
    jobs: usize,
    optimiser_spread: f64,
    /// The baseline's SSR on data its fits did not see (held-out start-up or other fold).
    base_test: f64,
    /// The baseline fitted on the held-out start-up, or on each fold.
    base_folds: Vec<MethodResult>,
    /// Each candidate's screen fit (`None` where its model failed on the data).
    screens: Vec<Option<MethodResult>>,
}

/// A shortlist job: the candidate's index and the fold (`None`: the whole start-up).
type ScoreJob = (usize, Option<u8>);
impl Run<'_> {
    /// Fits the candidates worth trying: the first batch, the screen's ranking, the
    /// shortlist's scoring.
    fn fit_candidates(&self, candidates: &[String]) -> Result<Fitted, DiagnosisError> {
        let mut lap = Instant::now();
        // The candidates worth trying, with their fit parameters.
        let names: Vec<(String, Vec<FitParam>)> = candidates
            .iter()
            .filter(|c| worth_trying(c, &self.base.localisation))
            .map(|c| (c.clone(), fit_params(c, self.rec)))
            .filter(|(_, extra)| !extra.is_empty())
            .collect();
        // Instrument candidates: only the most promising by the linear screen are fitted.
        let (names, unscreened) =
            gate_instruments(self.engine, self.rec, &self.single, &self.base, names);
        let first = self.first_batch(&names)?;
        let mut stages = StageWalls {
            screen: lap.elapsed().as_secs_f64(),
            ..StageWalls::default()
        };
        lap = Instant::now();
        let (shortlist, mut candidates) = self.rank_screen(&names, &first.screens);
        let jobs = self.scoring_jobs(&shortlist, first.base_folds.len());
        let done = self.score_shortlist(&names, &first, &jobs)?;
        let fits =
            1 + first.jobs + jobs.len() + usize::from(self.holdout.is_some()) * shortlist.len();
        stages.scoring = lap.elapsed().as_secs_f64();
        lap = Instant::now();
        let mut by_name: BTreeMap<usize, Vec<CandidateFit>> = BTreeMap::new();
        for (&(i, _), r) in jobs.iter().zip(done) {
            // A candidate whose model fails on the data is no explanation of it.
            match r {
                Ok(f) => by_name.entry(i).or_default().push(f),
                Err(_) => {
                    by_name.insert(i, Vec::new());
                }
            }
        }
        let mut models = BTreeMap::new();
        let mut whole = BTreeMap::new();
        for (i, results) in by_name {
            let screen = self.shrinkage(first.screens[i].as_ref()).unwrap_or(0.0);
            let candidate = match (self.scoring, results.as_slice()) {
                (Scoring::Holdout, [CandidateFit::Whole { fit, heldout_ssr }]) => {
                    models.insert(names[i].effect.clone(), fit.model_values.clone());
                    whole.insert(names[i].effect.clone(), fit.clone());
                    self.holdout_candidate(&names[i], screen, fit, *heldout_ssr, first.base_test)
                }
                (Scoring::BlockedCv, [CandidateFit::Fold(a), CandidateFit::Fold(b)]) => {
                    self.cv_candidate(&names[i], screen, [a, b], &first)
                }
                _ => continue,
            };
            candidates.push(candidate);
        }
        let mut screened = BTreeMap::new();
        for (i, fit) in first.screens.into_iter().enumerate() {
            if let Some(fit) = fit {
                screened.insert(names[i].effect.clone(), fit);
            }
        }
        Ok(Fitted {
            candidates,
            unscreened,
            models,
            screened,
            whole,
            optimiser_spread: first.optimiser_spread,
            fits,
            stages,
            lap,
        })
    }

    /// 1 − SSR(fit)/SSR(baseline) of a fit (`None` without one).
    fn shrinkage(&self, fit: Option<&MethodResult>) -> Option<f64> {
        fit.map(|f| 1.0 - f.ssr / self.base.ssr.max(1e-300))
    }

    /// A screen fit's configuration: a reduced budget, from the baseline's health.
    fn screen_cfg(&self, extra: &[FitParam]) -> DiagnosisConfig {
        DiagnosisConfig {
            extra_params: extra.to_vec(),
            base: self.base.health,
            max_model_runs: (candidate_runs(self.cfg, extra.len()) as f64 * SCREEN_BUDGET).ceil()
                as usize,
            lm_runs: (self.cfg.lm_runs as f64 * SCREEN_BUDGET).ceil() as usize,
            ..self.single.clone()
        }
    }

    /// A full candidate fit's configuration, from `start`.
    fn cand_cfg(&self, extra: &[FitParam], start: HealthParams) -> DiagnosisConfig {
        DiagnosisConfig {
            extra_params: extra.to_vec(),
            base: start,
            max_model_runs: candidate_runs(self.cfg, extra.len()),
            ..self.single.clone()
        }
    }
}

/// The leader `best` takes `fit` (its refit on the whole start-up, or its refinement): the
/// effect's parameters, health and fit quality, and its model values in `models`.
fn take_fit(best: &mut Candidate, fit: &MethodResult, models: &mut BTreeMap<String, Vec<Values>>) {
    models.insert(best.effect.clone(), fit.model_values.clone());
    best.params = effect_params(fit);
    best.health = fit.health;
    best.fit_quality = fit.fit_quality.verdict;
    best.normalised_residual = fit.fit_quality.normalised_residual;
}

/// The parameter that sizes instrument candidate `effect` against the model's own error:
/// `scale` of a `sensor_scale:<column>`, `offset` of a `sensor_bias:<column>` (`None` for any
/// other effect).
fn instrument_param(effect: &str) -> Option<&'static str> {
    match effect.split_once(':')?.0 {
        "sensor_scale" => Some("scale"),
        "sensor_bias" => Some("offset"),
        _ => None,
    }
}

/// The adapted engine file's own error on the channel of instrument candidate `effect`
/// (`sensor_scale:<column>`, `sensor_bias:<column>`) over the samples of `rec` Method B
/// compares, in the candidate parameter's unit: the mean over those samples of the file's
/// error at each one's GG speed (`[adaptation.model_error_by_speed]`, else
/// `model_error_pct`), as a fraction of the reading for a scale, in the channel's unit for an
/// offset. `None` for another kind of effect, or a file without a stated error there.
pub(crate) fn model_error_of(engine: &Engine, rec: &Recording, effect: &str) -> Option<f64> {
    let scale = instrument_param(effect)? == "scale";
    let signal = effect.split_once(':')?.1.parse::<Signal>().ok()?;
    let adaptation = engine.cfg().adaptation.as_ref()?;
    let within = within_calibration(engine, rec);
    let i = signal.index();
    let (mut error, mut n) = (0.0, 0usize);
    for ((v, rel), compared) in rec
        .rows()
        .iter()
        .zip(sample_speeds(engine, rec))
        .zip(within)
    {
        let z = v[i];
        if !compared || !z.is_finite() || z == 0.0 {
            continue;
        }
        let fraction = adaptation.model_error_fraction(signal, rel);
        error += if scale { fraction } else { fraction * z.abs() };
        n += 1;
    }
    (n > 0 && error > 0.0).then(|| error / n as f64)
}

impl Candidate {
    /// Whether the candidate is an instrument's error no larger than the adapted file's own error
    /// on that channel ([`Candidate::model_error`]): such an instrument cannot be told from the
    /// model's own miss, which the fit's σ already carries. On a unit of another make the adapted
    /// model reads the GG speed a few tenths of a percent off at base load, and a tachometer
    /// "reading 0.41 % low" was named where the file's stated error was 0.25–0.5 %. False for every
    /// file without a stated error.
    pub(crate) fn within_model_error(&self) -> bool {
        let Some(error) = self.model_error else {
            return false;
        };
        let Some(param) = instrument_param(&self.effect) else {
            return false;
        };
        self.params
            .get(&format!("effects.{}.{param}", self.effect))
            .is_some_and(|&(value, _)| value.abs() <= error)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::effects::Effect;
    use crate::gap::truth::clearance_nodes::ClearanceNodes;
    use crate::gap::truth::vigv_smooth::VigvSmooth;
    use crate::gap::truth::Hidden;
    use std::sync::Arc;

    /// The analysis of one noisy start-up of a unit with `effect` hidden inside it, among
    /// `candidates`; asserts the verdict names `expected`, the health after is within 0.3 points
    /// of `truth` on every parameter and the fit after is `good`. Returns the named candidate.
    fn analyse_hidden(
        effect: Arc<dyn Effect>,
        truth: HealthParams,
        noise_seed: u64,
        candidates: [&str; 2],
        expected: &str,
        holdout: bool,
    ) -> Candidate {
        let engine = Engine::reference().expect("engine");
        let hidden = Hidden::Plant {
            effect,
            plant_params: &[],
        };
        let (plant, samples) = hidden.simulate(&engine, &truth).expect("simulates");
        let rec = hidden
            .record(&plant, &samples, noise_seed, true)
            .expect("records");
        // A second start-up of the same unit, other noise: scored on it, not by folds.
        let second = holdout.then(|| {
            hidden
                .record(&plant, &samples, noise_seed + 1, true)
                .expect("records")
        });
        let candidates = candidates.map(str::to_string);
        let r = analyse(
            &engine,
            &rec,
            second.as_ref(),
            &candidates,
            &DiagnosisConfig::default(),
        )
        .expect("analyses");
        assert_eq!(r.verdict.effect, expected, "{:?}", r.verdict);
        let (got, want) = (r.verdict.health_after.to_array(), truth.to_array());
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            assert!((g - w).abs() < 0.3, "parameter {i}: {g:.2} against {w:.2}");
        }
        assert_eq!(
            r.verdict.fit_quality_after,
            Verdict::Good,
            "{:?}",
            r.verdict
        );
        r.candidates
            .into_iter()
            .find(|c| c.effect == expected)
            .expect("the named candidate")
    }

    /// An instrument's error no larger than the adapted file's own error on that channel is not
    /// told from it; beyond it, or on a file that states none, or for another kind of effect,
    /// it is.
    #[test]
    fn an_instrument_within_the_models_own_error_is_not_told_from_it() {
        let engine = Engine::reference().expect("engine");
        let rec =
            crate::diagnosis::bench::synthetic_startup(&engine, &HealthParams::HEALTHY, 3, true)
                .expect("start-up");
        let mut cfg = engine.cfg().clone();
        let mut adaptation = crate::engine::config::AdaptationConfig::default();
        adaptation.model_error_pct.insert("n1_rpm".into(), 0.4);
        cfg.adaptation = Some(adaptation);
        let adapted = engine.with_config(cfg).expect("adapted");
        // A candidate of `effect` fitted at `value` of its parameter `param`.
        let candidate = |e: &Engine, effect: &str, param: &str, value: f64| Candidate {
            effect: effect.into(),
            params: BTreeMap::from([(format!("effects.{effect}.{param}"), (value, 0.001))]),
            screen_shrinkage: 0.1,
            shortlisted: true,
            predicted_shrinkage: None,
            train_shrinkage: 0.1,
            heldout_shrinkage: None,
            bic_gain: 100.0,
            score: 0.1,
            health: HealthParams::HEALTHY,
            fit_quality: Verdict::Good,
            normalised_residual: 0.8,
            model_error: model_error_of(e, &rec, effect),
        };
        let n1 = "sensor_scale:n1_rpm";
        let scale = candidate(&adapted, n1, "scale", -0.0039);
        assert!((scale.model_error.expect("stated") - 0.004).abs() < 1e-12);
        assert!(scale.within_model_error());
        assert!(!candidate(&adapted, n1, "scale", -0.0045).within_model_error());
        assert!(!candidate(&engine, n1, "scale", -0.0039).within_model_error());
        // An offset: 0.4 % of the GG speed's mean reading over the start-up.
        let n1_mean = {
            let v: Vec<f64> = rec
                .series(Signal::N1)
                .into_iter()
                .filter(|z| z.is_finite() && *z != 0.0)
                .collect();
            v.iter().map(|z| z.abs()).sum::<f64>() / v.len() as f64
        };
        let bias = "sensor_bias:n1_rpm";
        assert!(candidate(&adapted, bias, "offset", 0.0039 * n1_mean).within_model_error());
        assert!(!candidate(&adapted, bias, "offset", 0.0041 * n1_mean).within_model_error());
        // No stated error on T34; and a lag is no magnitude.
        assert!(!candidate(&adapted, "sensor_scale:t34_k", "scale", 0.001).within_model_error());
        assert!(model_error_of(&adapted, &rec, "sensor_lag:n1_rpm").is_none());
    }

    /// The 40-case benchmark's case 11: a casing of two time constants, and the unit's health.
    fn casing_of_case_11() -> (ClearanceNodes, HealthParams) {
        let casing = ClearanceNodes {
            per_k: -1.81 / 100.0 / 100.0,
            tau_shell_s: 85.0,
            tau_flange_s: 1491.0,
            w_shell: 0.567,
        };
        let truth = HealthParams {
            D_GC: 0.36,
            D_EC: 0.13,
            D_GT: 1.35,
            D_ET: 2.36,
            D_GP: 0.42,
            D_EP: 0.72,
        };
        (casing, truth)
    }

    /// A casing whose flanges lag with 1 491 s, twice the record, beside a shell of 85 s (the
    /// 40-case benchmark's case 11): the library's single-node `tip_clearance` is named, but
    /// what one node cannot follow of the slow tail is still acting at the end of the record,
    /// where it looks like HPT efficiency, and D_ET came out 1.70 points low. Refined with its
    /// second node once named, the casing's two nodes are found and the health is right.
    #[test]
    fn a_named_tip_clearance_is_refined_to_the_casings_two_nodes() {
        case_11_is_refined(false);
    }

    /// Case 11 analysed (scored on a second start-up when `holdout`): `tip_clearance` named,
    /// the health right, the second node kept.
    fn case_11_is_refined(holdout: bool) {
        let (casing, truth) = casing_of_case_11();
        let named = analyse_hidden(
            Arc::new(casing),
            truth,
            1011,
            ["tip_clearance", "heat_soak"],
            "tip_clearance",
            holdout,
        );
        let share = named.params["effects.tip_clearance.node2_share"].0;
        assert!(share > 0.2, "the second node kept: {:?}", named.params);
    }

    /// The same casing scored on a second start-up (`gap --holdout`): the refinement follows
    /// the held-out scoring too (before, the named effect kept its single node there and the
    /// health stayed as far off as without the refinement). 44 s beside the suite: a
    /// measurement run by hand (`cargo test --release --lib with_a_held_out -- --ignored`) for
    /// CI's 20 minutes; the refinement itself stays in CI
    /// (`a_named_tip_clearance_is_refined_to_the_casings_two_nodes`).
    #[test]
    #[ignore = "measurement: cargo test --release --lib with_a_held_out -- --ignored"]
    fn with_a_held_out_startup_the_named_casing_is_refined_too() {
        case_11_is_refined(true);
    }

    /// Vanes off the map's schedule at low speed that also cost efficiency, fading smoothly
    /// over a quarter of the speed range (the 40-case benchmark's case 10): the library's
    /// flow-only `vigv_schedule` with its fixed linear fade was named but left the health 0.61
    /// points off, `suspect`. Refined with the efficiency change and the fade's width once
    /// named, the efficiency change is found and the health is right.
    #[test]
    fn a_named_vane_schedule_is_refined_with_its_efficiency_change() {
        let vanes = VigvSmooth {
            flow_delta: 0.099,
            eff_delta: -0.0125,
            end: 0.928,
            span: 0.243,
        };
        let truth = HealthParams {
            D_GC: 1.2,
            D_EC: 0.6,
            D_GT: 0.4,
            D_ET: 1.1,
            D_GP: 0.8,
            D_EP: 0.3,
        };
        let named = analyse_hidden(
            Arc::new(vanes),
            truth,
            1010,
            ["vigv_schedule", "bleed_schedule"],
            "vigv_schedule",
            false,
        );
        let eff = named.params["effects.vigv_schedule.eff_delta_pct"].0;
        assert!(
            (eff + 1.25).abs() < 0.4,
            "efficiency change {eff:.2} % against -1.25 %"
        );
    }
}
