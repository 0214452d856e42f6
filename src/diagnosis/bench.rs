//! Accuracy benchmarks of the diagnosis on synthetic truth: pure functions returning report
//! structs (the CLI prints them).
//!
//! * [`bench_diagnosis`]: N health vectors (even cases compressor fouling with
//!   D_GC = 3·D_EC, D_EC uniform in 0.3 … 2 % and the rest healthy; odd cases all six uniform in
//!   −1 … 6 %), each start-up simulated by the sequencer with the default sensor noise and lags
//!   (noise seed derived from the bench seed), diagnosed by both methods; per-parameter RMSE and
//!   maximum error, median wall time and model runs. Optionally the same Method B cases with
//!   other optimisers at the same model-run budget.
//! * [`bench_wash`]: the paper's Table 3 experiment with known truth.
//!
//! Cases run one after another; each diagnosis uses the whole thread pool.
//! Must not print, write files or open the database.

use super::steady::diagnose_steady;
use super::transient::diagnose_transient;
use super::{health_map, DiagnosisConfig, DiagnosisError, Method, MethodResult, Optimiser};
use crate::engine::sensors::MeasurementOptions;
use crate::engine::simulation::run_scenario;
use crate::engine::{Engine, Scenario, Trace};
use crate::health::{HealthParams, HEALTH_NAMES};
use crate::optim::median;
use crate::recording::Recording;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::collections::BTreeMap;

/// The health vectors of the diagnosis bench.
pub fn bench_cases(n: usize, seed: u64) -> Vec<HealthParams> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|i| {
            if i % 2 == 0 {
                let ec: f64 = rng.random_range(0.3..2.0);
                HealthParams {
                    D_GC: 3.0 * ec,
                    D_EC: ec,
                    ..HealthParams::HEALTHY
                }
            } else {
                let mut a = [0.0; 6];
                a.iter_mut().for_each(|v| *v = rng.random_range(-1.0..6.0));
                HealthParams::from_array(a)
            }
        })
        .collect()
}

/// Simulates a start-up of an engine with `truth` as the plant's instruments record it
/// (default noise and lags, no bias, sampled every `sequence.sample_period_s` of the engine
/// file), as a recording for the diagnosis.
pub fn synthetic_startup(
    engine: &Engine,
    truth: &HealthParams,
    noise_seed: u64,
    noise: bool,
) -> Result<Recording, DiagnosisError> {
    let model = engine.model(truth);
    let (samples, _) = run_scenario(&model, &Scenario::startup(engine.cfg()))?;
    let trace = Trace::from_truth(
        engine,
        &samples,
        Some(&MeasurementOptions {
            lags: true,
            noise,
            bias: false,
            seed: noise_seed,
        }),
    );
    Ok(trace.to_recording()?)
}

/// Error statistics of one method over the bench cases.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodStats {
    /// Root-mean-square error per parameter, percentage points.
    pub rmse: BTreeMap<String, f64>,
    /// Largest absolute error per parameter, percentage points.
    pub max_error: BTreeMap<String, f64>,
    /// Median wall time per diagnosis, s.
    pub median_wall_s: f64,
    /// Median model runs per diagnosis.
    pub median_model_runs: f64,
    /// Cases diagnosed.
    pub cases: usize,
    /// Cases where the method failed (counted, never hidden).
    pub failures: usize,
    /// RMS of error / reported σ per parameter (≈ 1 when the reported σ is honest).
    pub z_rms: BTreeMap<String, f64>,
}

impl MethodStats {
    fn from(truths: &[HealthParams], results: &[Option<MethodResult>]) -> MethodStats {
        let mut sq = [0.0; 6];
        let mut zsq = [0.0; 6];
        let mut mx = [0.0f64; 6];
        let mut walls = Vec::new();
        let mut runs = Vec::new();
        let mut ok = 0;
        for (t, r) in truths.iter().zip(results) {
            let Some(r) = r else { continue };
            ok += 1;
            for (i, (a, b)) in r.health.to_array().iter().zip(t.to_array()).enumerate() {
                let e = a - b;
                sq[i] += e * e;
                let sd = r.sigma.get(HEALTH_NAMES[i]).copied().unwrap_or(f64::NAN);
                zsq[i] += (e / sd).powi(2);
                mx[i] = mx[i].max(e.abs());
            }
            walls.push(r.wall_s);
            runs.push(r.model_runs as f64);
        }
        let n = ok.max(1) as f64;
        MethodStats {
            rmse: HEALTH_NAMES
                .iter()
                .zip(sq)
                .map(|(k, s)| (k.to_string(), (s / n).sqrt()))
                .collect(),
            max_error: HEALTH_NAMES
                .iter()
                .zip(mx)
                .map(|(k, m)| (k.to_string(), m))
                .collect(),
            z_rms: HEALTH_NAMES
                .iter()
                .zip(zsq)
                .map(|(k, s)| (k.to_string(), (s / n).sqrt()))
                .collect(),
            median_wall_s: median(walls).unwrap_or(f64::NAN),
            median_model_runs: median(runs).unwrap_or(f64::NAN),
            cases: ok,
            failures: results.len() - ok,
        }
    }
}

/// One bench case as reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaseRecord {
    pub index: usize,
    pub truth: BTreeMap<String, f64>,
    /// Per method: fitted health, or the error message.
    pub transient: Result<BTreeMap<String, f64>, String>,
    pub steady: Result<BTreeMap<String, f64>, String>,
    pub transient_wall_s: f64,
    pub steady_wall_s: f64,
    /// Method B's fit-quality verdict (`good` / `suspect` / `poor`; `None` when it failed):
    /// the data are the model's own twin, so anything but `good` is a false alarm.
    pub transient_fit_quality: Option<String>,
}

/// Method B with another optimiser at the same budget.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OptimiserStats {
    pub optimiser: Optimiser,
    pub stats: MethodStats,
    /// Median eq. 10 objective reached.
    pub median_objective: f64,
}

/// The diagnosis bench report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiagnosisBench {
    pub cases: usize,
    pub seed: u64,
    pub optimiser: Optimiser,
    pub max_model_runs: usize,
    /// Worker threads of each fit (`None`: all cores).
    pub threads: Option<usize>,
    /// With `threads` = 1: the median wall time of one Method B diagnosis on one core, s (the
    /// figure issue 24 sets a limit on); `None` on more threads, where it is not that figure.
    pub transient_one_core_median_wall_s: Option<f64>,
    pub transient: MethodStats,
    pub steady: MethodStats,
    /// Method B under each compared optimiser (same cases, same budget).
    pub comparison: Vec<OptimiserStats>,
    /// Share of Method B results whose fit quality is not `good` (false alarms on twin data).
    pub transient_fit_quality_not_good: Option<f64>,
    pub per_case: Vec<CaseRecord>,
}

fn as_record(r: &Result<MethodResult, DiagnosisError>) -> Result<BTreeMap<String, f64>, String> {
    r.as_ref()
        .map(|m| health_map(&m.health))
        .map_err(|e| e.to_string())
}

/// Runs the diagnosis bench. `progress` is called after each case (for a terminal display).
pub fn bench_diagnosis(
    engine: &Engine,
    cases: usize,
    seed: u64,
    cfg: &DiagnosisConfig,
    compare: &[Optimiser],
    progress: &mut dyn FnMut(&CaseRecord),
) -> Result<DiagnosisBench, DiagnosisError> {
    let truths = bench_cases(cases, seed);
    let mut tr: Vec<Option<MethodResult>> = Vec::new();
    let mut st: Vec<Option<MethodResult>> = Vec::new();
    let mut cmp: Vec<Vec<Option<MethodResult>>> = vec![Vec::new(); compare.len()];
    let mut per_case = Vec::new();
    for (i, truth) in truths.iter().enumerate() {
        let noise_seed = seed.wrapping_mul(1_000_003).wrapping_add(i as u64);
        let seg = synthetic_startup(engine, truth, noise_seed, true)?;
        let b = diagnose_transient(engine, &seg, cfg);
        let a = diagnose_steady(engine, &seg, cfg);
        let rec = CaseRecord {
            index: i,
            truth: health_map(truth),
            transient: as_record(&b),
            steady: as_record(&a),
            transient_wall_s: b.as_ref().map_or(f64::NAN, |r| r.wall_s),
            steady_wall_s: a.as_ref().map_or(f64::NAN, |r| r.wall_s),
            transient_fit_quality: b
                .as_ref()
                .ok()
                .map(|r| r.fit_quality.verdict.as_str().to_string()),
        };
        progress(&rec);
        per_case.push(rec);
        for (k, &o) in compare.iter().enumerate() {
            // The configured optimiser's run is the Method B result itself.
            let r = if o == cfg.optimiser {
                b.as_ref().ok().cloned()
            } else {
                let c = DiagnosisConfig {
                    optimiser: o,
                    ..cfg.clone()
                };
                diagnose_transient(engine, &seg, &c).ok()
            };
            cmp[k].push(r);
        }
        tr.push(b.ok());
        st.push(a.ok());
    }
    let comparison = compare
        .iter()
        .zip(&cmp)
        .map(|(&o, rs)| OptimiserStats {
            optimiser: o,
            stats: MethodStats::from(&truths, rs),
            median_objective: median(rs.iter().flatten().map(|r| r.objective).collect())
                .unwrap_or(f64::NAN),
        })
        .collect();
    let verdicts: Vec<&str> = per_case
        .iter()
        .filter_map(|c: &CaseRecord| c.transient_fit_quality.as_deref())
        .collect();
    let not_good = (!verdicts.is_empty())
        .then(|| verdicts.iter().filter(|v| **v != "good").count() as f64 / verdicts.len() as f64);
    let transient = MethodStats::from(&truths, &tr);
    Ok(DiagnosisBench {
        cases,
        seed,
        optimiser: cfg.optimiser,
        max_model_runs: cfg.max_model_runs,
        threads: cfg.threads,
        transient_one_core_median_wall_s: (cfg.threads == Some(1))
            .then_some(transient.median_wall_s),
        transient,
        steady: MethodStats::from(&truths, &st),
        comparison,
        transient_fit_quality_not_good: not_good,
        per_case,
    })
}

/// Before/after/improvement of one method (or the truth) in the wash experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WashRow {
    pub before: BTreeMap<String, f64>,
    pub after: BTreeMap<String, f64>,
    pub improvement: BTreeMap<String, f64>,
    /// Improvement D_GC / improvement D_EC.
    pub ratio_gc_ec: f64,
    /// Improvement D_GT / improvement D_ET.
    pub ratio_gt_et: f64,
    /// 1σ of the before/after results (empty for the truth).
    pub sigma_before: BTreeMap<String, f64>,
    pub sigma_after: BTreeMap<String, f64>,
}

impl WashRow {
    fn new(before: &HealthParams, after: &HealthParams) -> WashRow {
        let b = before.to_array();
        let a = after.to_array();
        let imp: Vec<f64> = b.iter().zip(a).map(|(x, y)| x - y).collect();
        WashRow {
            before: health_map(before),
            after: health_map(after),
            improvement: HEALTH_NAMES
                .iter()
                .zip(&imp)
                .map(|(k, v)| (k.to_string(), *v))
                .collect(),
            ratio_gc_ec: imp[0] / imp[1],
            ratio_gt_et: imp[2] / imp[3],
            sigma_before: BTreeMap::new(),
            sigma_after: BTreeMap::new(),
        }
    }
}

/// The wash bench report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WashBench {
    pub truth: WashRow,
    pub transient: WashRow,
    pub steady: WashRow,
    pub wall_s: BTreeMap<String, f64>,
}

/// The synthetic truth of the wash experiment: compressor fouling D_GC = 3·D_EC that the wash
/// mostly removes (5.4/1.8 → 0.9/0.3 %: improvement 4.5/1.5), HPT degradation a wash partly
/// recovers (deposits: 2.5/1.5 → 1.7/1.0 %), and a PT that nobody touched (1.0/0.8 % both
/// times).
pub fn wash_truth() -> (HealthParams, HealthParams) {
    let before = HealthParams {
        D_GC: 5.4,
        D_EC: 1.8,
        D_GT: 2.5,
        D_ET: 1.5,
        D_GP: 1.0,
        D_EP: 0.8,
    };
    let after = HealthParams {
        D_GC: 0.9,
        D_EC: 0.3,
        D_GT: 1.7,
        D_ET: 1.0,
        D_GP: 1.0,
        D_EP: 0.8,
    };
    (before, after)
}

/// Runs the wash experiment: one noisy start-up before and one after the wash (different noise
/// seeds), each diagnosed by both methods.
pub fn bench_wash(
    engine: &Engine,
    seed: u64,
    cfg: &DiagnosisConfig,
) -> Result<WashBench, DiagnosisError> {
    let (before, after) = wash_truth();
    let seg_b = synthetic_startup(engine, &before, seed.wrapping_mul(2).wrapping_add(11), true)?;
    let seg_a = synthetic_startup(engine, &after, seed.wrapping_mul(2).wrapping_add(12), true)?;
    let mut wall = BTreeMap::new();
    let mut row = |m: Method| -> Result<WashRow, DiagnosisError> {
        let run = |seg: &Recording| match m {
            Method::Transient => diagnose_transient(engine, seg, cfg),
            Method::Steady => diagnose_steady(engine, seg, cfg),
        };
        let rb = run(&seg_b)?;
        let ra = run(&seg_a)?;
        wall.insert(format!("{}_before", m.name()), rb.wall_s);
        wall.insert(format!("{}_after", m.name()), ra.wall_s);
        let mut w = WashRow::new(&rb.health, &ra.health);
        w.sigma_before = rb.sigma;
        w.sigma_after = ra.sigma;
        Ok(w)
    };
    let transient = row(Method::Transient)?;
    let steady = row(Method::Steady)?;
    Ok(WashBench {
        truth: WashRow::new(&before, &after),
        transient,
        steady,
        wall_s: wall,
    })
}
