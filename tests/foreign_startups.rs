//! Start-ups of a foreign unit, diagnosed as the product does it (Method B) on the engine file
//! adapted to its steady baseline: `tests/data/foreign/aero25_truth.toml` (GSPy's maps, inlet
//! vanes closing below 92 % speed, PR 21) run as a generator, the user's copy of
//! `config/engine_md22.toml` with its design point set from the healthy full-load row and
//! `calibrate --adapt` run on 9 healthy loads from 30 % to 100 %.
//!
//! A start-up runs from standstill through idle and a low-load hold, far below the lowest load
//! of any baseline: there the adaptation's curves are extrapolated and the model is not this
//! unit (relative corrected GG speed 0.62 at the 4 MW hold, calibrated from 0.74). Compared
//! there, a healthy start-up read D_GC at its −3 % search limit and D_EC at +5 (normalised
//! residual 614, `poor`). Method B now compares only the samples within the calibrated speeds
//! (`[adaptation.calibrated]`) and says which it left out; the start-up is still simulated
//! through the rest. Within them the adapted model still misses the unit by a few tenths of a
//! percent, which over the loading's hundreds of samples is many instrument σ: Method B weighs
//! each sample with the file's own model error (`[adaptation.model_error_by_speed]`) beside the
//! instrument's noise, as a steady diagnosis does (without it: healthy D_GC −0.50, degraded
//! D_GC 0.51 low, both `suspect`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::calibrate::adapt::AdaptSettings;
use gtwatch::calibrate::candidates::default_candidates;
use gtwatch::calibrate::synthetic::generator_baseline_csv;
use gtwatch::calibrate::{calibrate, CalibrationSettings};
use gtwatch::diagnosis::bench::synthetic_startup;
use gtwatch::diagnosis::fit_quality::Verdict;
use gtwatch::diagnosis::snapshot::{read_snapshots, Snapshot};
use gtwatch::diagnosis::transient::diagnose_transient;
use gtwatch::diagnosis::{DiagnosisConfig, MethodResult};
use gtwatch::engine::simulation::run_scenario;
use gtwatch::engine::{Engine, EngineConfig, Scenario};
use gtwatch::health::{HealthParams, HEALTH_NAMES};
use gtwatch::signals::Phase;
use std::collections::HashMap;
use std::path::PathBuf;

use crate::foreign_engine::md22_from_full_load;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The generator's healthy baseline: 9 loads from 30 % to 100 % at 6 100 rpm, days from 278
/// to 298 K, each row a 100-s average, with what such a unit measures.
fn baseline(truth: &Engine) -> Vec<Snapshot> {
    let csv = generator_baseline_csv(truth, 7).expect("snapshots");
    read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows")
}

/// The user's md22 copy: design point from the healthy full-load row (pressure ratio, power,
/// both speeds; the datasheet's exhaust flow `datasheet_flow`, kg/s, 3 % off the truth's), a
/// generator, and the unit's own start sequence and starter (which the user knows).
fn user_model_with(truth: &Engine, full: &Snapshot, datasheet_flow: f64) -> Engine {
    let md22 = md22_from_full_load(full, datasheet_flow);
    let mut cfg = md22.cfg().clone();
    cfg.sequence = truth.cfg().sequence.clone();
    cfg.starter = truth.cfg().starter.clone();
    md22.with_config(cfg).expect("user model")
}

/// The foreign unit of engine file `file` (relative to the crate), and the user's md22 copy
/// (datasheet flow `datasheet_flow`) after `calibrate --adapt` on its baseline (2 threads): the
/// truth, the calibration's report and the adapted engine.
fn adapted_unit(
    file: &str,
    datasheet_flow: f64,
) -> (Engine, gtwatch::calibrate::Calibration, Engine) {
    adapted_unit_with(file, datasheet_flow, None)
}

/// [`adapted_unit`] with the user's design GG speed written `gg_speed_rpm` (`None`: the
/// full-load row's).
fn adapted_unit_with(
    file: &str,
    datasheet_flow: f64,
    gg_speed_rpm: Option<f64>,
) -> (Engine, gtwatch::calibrate::Calibration, Engine) {
    let truth = Engine::new(EngineConfig::load(&root().join(file)).unwrap()).unwrap();
    let rows = baseline(&truth);
    let full = rows
        .iter()
        .max_by(|a, b| a.fuel_kg_s.total_cmp(&b.fuel_kg_s))
        .expect("full load");
    let mut model = user_model_with(&truth, full, datasheet_flow);
    if let Some(n) = gg_speed_rpm {
        let mut cfg = model.cfg().clone();
        cfg.design.gg_speed_rpm = n;
        model = model.with_config(cfg).unwrap();
    }
    let settings = CalibrationSettings {
        threads: Some(2),
        adapt: Some(AdaptSettings::default()),
        ..CalibrationSettings::default()
    };
    let (report, adapted) = calibrate(
        &model,
        &rows,
        &[],
        default_candidates(&model).unwrap(),
        &settings,
    )
    .expect("calibrate");
    (truth, report, adapted)
}

fn method_b(engine: &Engine, truth: &Engine, health: [f64; 6], seed: u64) -> MethodResult {
    let rec =
        synthetic_startup(truth, &HealthParams::from_array(health), seed, true).expect("start-up");
    let cfg = DiagnosisConfig {
        threads: Some(2),
        ..DiagnosisConfig::default()
    };
    diagnose_transient(engine, &rec, &cfg).expect("Method B")
}

fn show(label: &str, truth: [f64; 6], r: &MethodResult) -> [f64; 6] {
    let h = r.health.to_array();
    eprintln!(
        "{label}: {} (normalised residual {:.2}); {}",
        r.fit_quality.verdict.as_str(),
        r.fit_quality.normalised_residual,
        HEALTH_NAMES
            .iter()
            .zip(h.iter().zip(truth))
            .map(|(n, (e, t))| format!("{n} {e:+.2} (truth {t:+.1})"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    for note in &r.left_out {
        eprintln!("  left out: {note}");
    }
    h
}

/// A start-up's Method B result `r` (health `e`) on an adapted file against the truth `t`: the
/// samples below the calibrated speeds said to be left out, the fit `good`, each parameter
/// within 0.35 points.
fn within_calibrated_speeds(label: &str, r: &MethodResult, e: [f64; 6], t: [f64; 6]) {
    assert!(
        !r.left_out.is_empty(),
        "{label}: the samples below the calibrated speeds are said to be left out"
    );
    assert_eq!(r.fit_quality.verdict, Verdict::Good, "{label}");
    for i in 0..6 {
        assert!(
            (e[i] - t[i]).abs() <= 0.35,
            "{label}: {} {:+.2} against {:+.1}",
            HEALTH_NAMES[i],
            e[i],
            t[i]
        );
    }
}

/// The same unit with its design GG speed written otherwise than the full-load row's 9 695 rpm
/// (9 831, as a datasheet might give it): the default calibration still reproduces the baseline
/// within noise. Measured 2026-12-05: 0.63 σ, `good` (the compressor at 6 knots, its flow held
/// at its 2-knot fit); before a stalled component looked two knots further where one was no
/// better, 1.54 σ, `suspect` (the compressor stopped at 2 knots). About 30 s on 2 cores alone,
/// 71 s beside the suite: run by hand (`cargo test --release --test integration -- --ignored
/// gg_speed_written_otherwise`) since CI neared its 20 minutes; the same regression, a design GG
/// speed written otherwise than the rows', stays in CI on the combinator unit
/// (`foreign_engine::a_design_point_written_to_a_few_digits_calibrates_alike`, 9 800 rpm).
#[test]
#[ignore = "a measurement beside foreign_engine's few-digits test (70 s of CI's 20 minutes)"]
fn a_generator_unit_calibrates_alike_with_its_gg_speed_written_otherwise() {
    let (_, report, _) = adapted_unit_with(
        "tests/data/foreign/aero25_truth.toml",
        70.0 * 1.03,
        Some(9831.0),
    );
    let a = report.adaptation.as_ref().expect("adapted");
    eprintln!(
        "GG speed written 9 831 rpm: {} shape, RMS {:.2} σ, {}",
        a.strategy, a.rms_after, report.baseline_fit.summary
    );
    assert_eq!(
        report.baseline_fit.verdict,
        Verdict::Good,
        "{}",
        report.baseline_fit.summary
    );
}

/// 32 s on 2 cores (a calibration and three Method B fits; 85 s while the unit's start-ups
/// chattered across its compressor map's surge-end jump, when it was left out of CI).
#[test]
fn start_ups_of_a_foreign_unit_are_diagnosed_within_its_calibrated_speeds() {
    let (truth, report, adapted) =
        adapted_unit("tests/data/foreign/aero25_truth.toml", 70.0 * 1.03);
    let range = adapted
        .cfg()
        .adaptation
        .as_ref()
        .and_then(|a| a.calibrated)
        .expect("the adaptation states its calibrated speeds");
    eprintln!(
        "adapted: RMS {:.2} σ, calibrated GG speeds {:.3?}",
        report.rms_after, range.gg_speed
    );
    // The README's recipe: the calibration reproduces this baseline within noise. Measured
    // 2026-12-05: 0.79 σ, the compressor's flow curve held at its 2-knot fit while its speed
    // re-labelling and efficiency grew to 4 knots; when such a curve was left out instead, the
    // compressor stopped at 2 knots and the baseline at 1.51 σ (`suspect`).
    assert_eq!(
        report.baseline_fit.verdict,
        Verdict::Good,
        "{}",
        report.baseline_fit.summary
    );

    let healthy = [0.0; 6];
    let h0 = method_b(&adapted, &truth, healthy, 3);
    let e0 = show("healthy start-up", healthy, &h0);
    let degraded = [2.0, 0.8, 1.0, 0.6, 0.0, 0.0];
    let h1 = method_b(&adapted, &truth, degraded, 4);
    let e1 = show("degraded start-up", degraded, &h1);

    // Measured 2026-12-05: healthy within 0.17 points of zero, degraded within 0.29 of the
    // truth (D_EP; D_GC 0.05), both `good` (normalised residuals 0.80 / 0.72); on the file
    // calibrated to 1.51 σ before (see above) 0.31 and 0.21 off; with the instrument noise
    // alone in σ they read 0.50 and 0.51 off, `suspect` (1.13 / 1.27). The change from the
    // healthy start-up within 0.20 of the truth's (D_GP).
    for (label, r, e, t) in [
        ("healthy", &h0, e0, healthy),
        ("degraded", &h1, e1, degraded),
    ] {
        within_calibrated_speeds(label, r, e, t);
    }
    for i in 0..6 {
        let change = e1[i] - e0[i];
        assert!(
            (change - degraded[i]).abs() <= 0.3,
            "{}: change from the healthy start-up {change:+.2} against {:+.1}",
            HEALTH_NAMES[i],
            degraded[i]
        );
    }

    // The same file without its calibrated range compares the whole start-up: the fit is
    // `poor` (the check that the samples left out are what was wrong).
    let mut cfg = adapted.cfg().clone();
    if let Some(a) = cfg.adaptation.as_mut() {
        a.calibrated = None;
    }
    let unbounded = adapted.with_config(cfg).unwrap();
    let all = method_b(&unbounded, &truth, healthy, 3);
    show("healthy start-up, every sample compared", healthy, &all);
    assert!(all.left_out.is_empty());
    assert_eq!(all.fit_quality.verdict, Verdict::Poor);
}

/// A second foreign unit, of pyCycle's map family (`tests/data/foreign/pyc30_truth.toml`: axi5
/// compressor, lpt2269 turbines, its own VIGV schedule, PR 17, 30 MW), the same user's steps
/// (the datasheet's flow 3 % low here): Method B on the adapted file within its calibrated
/// speeds. Measured 2026-12-04 (seed 5): healthy D_GC −0.23, the degraded levels within 0.26 of
/// the truth (D_GC read low), every fit `good` (normalised residual 0.82–0.84); this unit's
/// adapted model predicts its baseline's points left out within 0.06 %, so its own error adds
/// nearly nothing to σ here.
#[test]
fn start_ups_of_a_second_foreign_unit_are_diagnosed_within_its_calibrated_speeds() {
    let (truth, report, adapted) = adapted_unit("tests/data/foreign/pyc30_truth.toml", 88.0 * 0.97);
    eprintln!("adapted: RMS {:.2} σ", report.rms_after);
    for (label, t, seed) in [
        ("healthy", [0.0; 6], 5),
        (
            "compressor and HP turbine",
            [2.0, 0.8, 1.0, 0.6, 0.0, 0.0],
            5,
        ),
        (
            "compressor and power turbine",
            [1.0, 0.0, 0.0, 0.0, 0.8, 0.6],
            5,
        ),
    ] {
        let r = method_b(&adapted, &truth, t, seed);
        let e = show(label, t, &r);
        within_calibrated_speeds(label, &r, e, t);
    }
}

/// A day of operations on the foreign unit (start, base load, normal stop, an aborted start, a hot
/// restart), as `gtwatch simulate --scenario operations` runs it. It failed twice: the breaker
/// opened at 4 MW (a load rejection: the PT overspeeds, its governor cuts the fuel and the GG ran
/// down to 6 % speed burning), and the hot restart's PT, still turning, overspeeded on idle power
/// alone while the GG held idle, then the GG dived to 500 rpm burning.
#[test]
fn a_day_of_operations_runs_on_the_foreign_unit() {
    let truth = Engine::new(
        EngineConfig::load(&root().join("tests/data/foreign/aero25_truth.toml")).unwrap(),
    )
    .unwrap();
    let cfg = truth.cfg();
    let model = truth.model(&HealthParams::HEALTHY);
    let (s, _) = run_scenario(&model, &Scenario::operations(cfg)).expect("runs to its end");
    let phases: Vec<Phase> = s.iter().map(|x| x.phase).collect();
    let count = |p: Phase| phases.windows(2).filter(|w| w[0] != p && w[1] == p).count();
    assert_eq!(count(Phase::Crank), 3, "three starts");
    assert_eq!(
        count(Phase::Steady),
        2,
        "the first start and the hot restart reach base load"
    );
    assert_eq!(count(Phase::Trip), 1, "only the aborted start trips");
    assert_eq!(count(Phase::Shutdown), 1, "one normal stop");
    let last = s.last().unwrap();
    assert!((last.stations.power_mw - cfg.sequence.base_load_mw).abs() < 0.1);
    // Burning after idle, the GG stays above its minimum-speed floor's region, and the PT never
    // overspeeds by more than 2 % (its protection would trip it at 10 %).
    let idle = cfg.sequence.idle_speed_rpm;
    let sync = cfg.design.pt_speed_rpm;
    let running = |p: Phase| {
        matches!(
            p,
            Phase::Idle
                | Phase::Synchronisation
                | Phase::Loading
                | Phase::Steady
                | Phase::Unloading
        )
    };
    for x in s.iter().filter(|x| running(x.phase)) {
        assert!(
            x.stations.n1_rpm >= 0.5 * idle,
            "GG at {:.0} rpm burning at t = {} s",
            x.stations.n1_rpm,
            x.t_s
        );
        assert!(
            x.stations.n2_rpm <= 1.02 * sync,
            "PT at {:.0} rpm at t = {} s",
            x.stations.n2_rpm,
            x.t_s
        );
    }
}
