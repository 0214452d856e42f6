//! Foreign engines (issue 22 item 6): a "true" unit made differently from the engine file that
//! is calibrated to it — GSPy's map family instead of md22's, variable inlet guide vanes closing
//! at low speed, another design point, a controllable-pitch-propeller load whose PT speed
//! follows a combinator schedule (`tests/data/foreign/aero25_truth.toml`). The user's steps:
//! copy `config/engine_md22.toml`, set its design point from the healthy full-load row, run
//! `gtwatch calibrate --adapt` on 9 healthy loads from 30 % to 100 %, then diagnose.
//!
//! What the issue asks (floors): on loads left out of the calibration (leave-one-load-out, the
//! whole calibration re-run on the other 8) mean |error| ≤ 0.3 % and no signal beyond 1 %; the
//! healthy baseline `good` within 0.3 points; a degradation grid ranked at Spearman ρ ≥ 0.95,
//! cross-talk |ρ| ≤ 0.3, each level within 0.5 points, every fit `good`.
//!
//! What this version reaches and asserts (measured figures in the README, "Calibrating to your
//! unit"; every load is left out in turn, about 5 s a grown calibration): the issue's floors on
//! the loads from 56 % to 91 % (0.23 % / 0.55 % at worst); on the others, the floors this
//! version meets (0.48 % mean over all nine, 2.40 % worst: the lowest and the full load, left
//! out, are extrapolations, 0.95 % and 0.89 % mean; 38.75 % and 47.5 %, where the vanes close,
//! 0.90 % and 0.67 %), and at most a third / half of the design calibration's; the healthy
//! baseline `good` within 0.3 points of zero; the grid ranked at ρ ≥ 0.95 for all four
//! parameters (D_GC, D_EC and D_ET at this grid's ceiling, 0.982: every pair of levels the
//! truth orders ordered right; [`spearman_ceiling`], [`misordered_pairs`]), every level within 0.5 points on all six (the healthy PT's too), and no level
//! off by more than 0.5 points called `good`. The rank floor needs the adapted model's own
//! error (`[adaptation.model_error_pct]` and `[adaptation.model_error_by_speed]`, estimated by
//! the calibration on interior points left out) in the diagnosis's σ: without it D_GT ranked
//! at 0.89 (compressor fouling read as up to −0.9 points of D_GT); and the snapshots whose GG
//! runs beyond the calibrated speeds (`[adaptation.calibrated]`) left out. Not met yet: the 0.3 % / 1 % floors over all nine
//! loads; the cross-talk as a rank; and `good` fits on the whole grid (10 of 15): curves of
//! speed alone follow the operating line, not how the unit's maps differ across it, where
//! degradation moves the points. Nor is the grid's reading a property of the unit: calibrations
//! of the same unit on a load more, each within noise, read it with 4 to 15 of 15 `good`, and
//! one reads fouling 0.77 points off and calls it `good` (the ignored test
//! [`a_baseline_with_a_load_more_reads_the_grid_honestly`] reproduces it). Rows from before a
//! compressor wash beside the baseline narrow it (the ignored measurement
//! [`rows_before_a_wash_inform_the_grid`]: worst errors 0.24–0.53 over the same baselines).
//!
//! A second foreign unit (`tests/data/foreign/pyc30_truth.toml`: pyCycle's map family, its own
//! VIGV schedule, PR 17, 30 MW), with the same settings, meets the floors but one:
//! leave-one-load-out over all 9 loads 0.18 % mean (≤ 0.3 %), interior loads within 1 % (not
//! the extrapolated lowest load, 1.3 %: asserted ≤ 1.5 %); the grid ranked at ρ 0.982 for all
//! four (the ceiling: no pair misordered), every level within 0.5 points, no compressor cross-talk; every fit `good` (15 of 15).
//!
//! A third, the first with fixed inlet vanes (`tests/data/foreign/aero25_novigv_truth.toml`),
//! is one the adaptation follows at its calibration points (0.73 σ RMS) but predicts poorly
//! between them (2.5–5.6 % model error on six signals): the test asserts that the calibration
//! and every diagnosis on it say so; held to one knot a component it is not fitted at all
//! (19.5 σ), and that is said too.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::calibrate::adapt::{AdaptSettings, AdaptStrategy};
use gtwatch::calibrate::candidates::default_candidates;
use gtwatch::calibrate::synthetic::{snapshot_csv_at_speeds, OperatingPoint};
use gtwatch::calibrate::validate::left_out;
use gtwatch::calibrate::{calibrate, Calibration, CalibrationSettings};
use gtwatch::diagnosis::snapshot::{diagnose_snapshots, read_snapshots, Snapshot};
use gtwatch::diagnosis::DiagnosisConfig;
use gtwatch::engine::{Engine, EngineConfig};
use gtwatch::health::{HealthParams, HEALTH_NAMES};
use gtwatch::signals::Signal;
use std::collections::HashMap;
use std::path::PathBuf;

use crate::ranking;
use ranking::{spearman, Rank};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A foreign unit: its engine file, and the power its combinator schedule calls 100 %.
#[derive(Debug, Clone, Copy)]
struct Unit {
    file: &'static str,
    design_mw: f64,
}

/// GSPy maps, VIGVs closing below 92 %, PR 21, 25 MW.
const AERO25: Unit = Unit {
    file: "tests/data/foreign/aero25_truth.toml",
    design_mw: 25.0,
};

/// pyCycle maps, VIGVs closing below 90 %, PR 17, 30 MW.
const PYC30: Unit = Unit {
    file: "tests/data/foreign/pyc30_truth.toml",
    design_mw: 30.0,
};

/// AERO25 with fixed inlet vanes: a part-load running line nearly flat in fuel.
const AERO25_FIXED_VANES: Unit = Unit {
    file: "tests/data/foreign/aero25_novigv_truth.toml",
    design_mw: 25.0,
};

fn truth_engine() -> Engine {
    unit_engine(AERO25)
}

fn unit_engine(unit: Unit) -> Engine {
    let path = root().join(unit.file);
    Engine::new(EngineConfig::load(&path).expect("truth loads")).expect("truth calibrates")
}

/// What the unit measures besides the inputs (T1, ambient pressure, n2, fuel flow).
const INSTRUMENTS: [Signal; 8] = [
    Signal::N1,
    Signal::P1,
    Signal::T2,
    Signal::P2,
    Signal::T34,
    Signal::P34,
    Signal::T4,
    Signal::Torque,
];

/// Samples behind each averaged row (a 100-s steady window at 1 Hz).
const AVERAGING: f64 = 100.0;

const DESIGN_N2: f64 = 6100.0;

/// 9 loads from 30 % to 100 %, ambient 278–298 K and 99–102 kPa, shuffled by `level`; the PT
/// speed of the propeller's combinator schedule for each.
fn loads(level: usize) -> (Vec<OperatingPoint>, Vec<f64>) {
    loads_of(AERO25.design_mw, level)
}

fn loads_of(design_mw: f64, level: usize) -> (Vec<OperatingPoint>, Vec<f64>) {
    let pts: Vec<OperatingPoint> = (0..9)
        .map(|k| {
            let j = (k + 4 * level) % 9;
            OperatingPoint {
                t_amb_k: 278.0 + 20.0 * j as f64 / 8.0,
                p_amb_kpa: 99.0 + 3.0 * ((j * 5) % 9) as f64 / 8.0,
                power_mw: design_mw * (0.3 + 0.7 * k as f64 / 8.0),
            }
        })
        .collect();
    let n2 = pts
        .iter()
        .map(|p| combinator_n2(p.power_mw / design_mw))
        .collect();
    (pts, n2)
}

/// The propeller's combinator schedule: PT speed (rpm) at load fraction `f` of the design
/// power, 70 % at 30 % load rising to 100 % (a table, not P ∝ n^k).
fn combinator_n2(f: f64) -> f64 {
    DESIGN_N2 * (0.70 + 0.30 * ((f - 0.3) / 0.7).clamp(0.0, 1.0).powf(0.8))
}

fn rows_of(truth: &Engine, health: [f64; 6], level: usize, group: &str) -> Vec<Snapshot> {
    rows_at(truth, loads(level), health, level, group)
}

fn rows_at(
    truth: &Engine,
    (pts, n2): (Vec<OperatingPoint>, Vec<f64>),
    health: [f64; 6],
    level: usize,
    group: &str,
) -> Vec<Snapshot> {
    let csv = snapshot_csv_at_speeds(
        truth,
        &HealthParams::from_array(health),
        &pts,
        &n2,
        group,
        AVERAGING,
        500 + level as u64,
        &INSTRUMENTS,
    )
    .expect("snapshots");
    read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows")
}

/// The user's md22 copy with its design point set from the healthy full-load row (power from
/// torque × speed); the air flow is the datasheet's (3 % off the truth, which nobody knows).
fn user_model(full_load: &Snapshot) -> Engine {
    user_model_with(full_load, 70.0 * 1.03)
}

fn user_model_with(full_load: &Snapshot, datasheet_flow: f64) -> Engine {
    md22_from_full_load(full_load, datasheet_flow)
}

/// What a user does first with a foreign unit: `config/engine_md22.toml` copied, its design
/// point set from the healthy full-load row `full` — pressure ratio P2/P1 (P2 over the ambient
/// pressure where P1 is not measured), the power (metered, else torque × PT speed), both
/// speeds — and the datasheet's exhaust flow `datasheet_flow` (kg/s). The PT speed is measured
/// in every row (a propeller on a combinator, a generator): no load law.
pub(crate) fn md22_from_full_load(full: &Snapshot, datasheet_flow: f64) -> Engine {
    let path = root().join("config/engine_md22.toml");
    let md22 = Engine::new(EngineConfig::load(&path).expect("md22")).expect("md22");
    let v = |s: Signal| full.values.iter().find(|(x, _)| *x == s).map(|(_, v)| *v);
    let omega = full.n2_rpm * std::f64::consts::PI / 30.0;
    let p1 = v(Signal::P1)
        .or(full.p_amb_kpa)
        .expect("P1 or the ambient pressure");
    let power = v(Signal::Power)
        .or_else(|| v(Signal::Torque).map(|t| t * omega / 1e3))
        .expect("power or torque");
    let mut cfg = md22.cfg().clone();
    cfg.design.pressure_ratio = v(Signal::P2).expect("P2") / p1;
    cfg.design.power_mw = power;
    cfg.design.gg_speed_rpm = v(Signal::N1).expect("N1");
    cfg.design.pt_speed_rpm = full.n2_rpm;
    cfg.design.exhaust_flow_kg_s = datasheet_flow;
    cfg.load = None;
    md22.with_config(cfg).expect("user model")
}

/// Design values only (`None`), or with the adaptation of `strategy`.
fn settings(adapt: Option<AdaptStrategy>) -> CalibrationSettings {
    CalibrationSettings {
        threads: Some(2),
        adapt: adapt.map(AdaptSettings::of),
        ..CalibrationSettings::default()
    }
}

fn calibrated(model: &Engine, rows: &[Snapshot], adapt: Option<AdaptStrategy>) -> Engine {
    let cands = default_candidates(model).expect("candidates");
    let started = std::time::Instant::now();
    let (report, engine) = calibrate(model, rows, &[], cands, &settings(adapt)).expect("calibrate");
    eprintln!(
        "  calibration on {} points{}: {:.1} s wall, {} model runs",
        rows.len(),
        adapt.map_or(String::new(), |s| format!(" with adaptation ({s:?})")),
        started.elapsed().as_secs_f64(),
        report.model_runs
    );
    if let Some(law) = &report.inlet_loss_law {
        eprintln!("  {}", law.summary());
    }
    if adapt.is_some() {
        if let Some(a) = &report.adaptation {
            for c in &a.components {
                eprintln!(
                    "  {} knots {:.3?} curves {:?} ({})",
                    c.component,
                    c.knots,
                    c.curves
                        .iter()
                        .map(|k| format!("{} {:+.4?}", k.curve, k.values))
                        .collect::<Vec<_>>(),
                    c.knots_reason
                );
            }
            for st in &a.steps {
                eprintln!("  step: {st}");
            }
            eprintln!(
                "  design refitted {:?}; adaptation RMS {:.2} -> {:.2} σ, dropped {:?}",
                a.design_refitted, a.rms_before, a.rms_after, report.dropped_lines
            );
            for c in &a.coverage {
                eprintln!("  coverage: {}", c.describe());
            }
            if let Some(sim) = &a.similarity {
                eprintln!("  {}", sim.describe());
            }
            if let Some(line) = &a.operating_line {
                eprintln!("  {}", line.describe());
            }
            if let Some(line) = &a.efficiency_tried {
                eprintln!("  {line}");
            }
        }
    }
    engine
}

/// The adaptation settings of `strategy` with the turbines' efficiency shape the calibration
/// on all of `rows` chooses, fixed: what `calibrate --validate` fits each fold with.
fn chosen(model: &Engine, rows: &[Snapshot], strategy: AdaptStrategy) -> AdaptSettings {
    let cands = default_candidates(model).expect("candidates");
    let adapt = AdaptSettings {
        health_error: false,
        ..AdaptSettings::of(strategy)
    };
    let whole = CalibrationSettings {
        adapt: Some(adapt.clone()),
        ..settings(None)
    };
    let (report, _) = calibrate(model, rows, &[], cands, &whole).expect("calibrate");
    let a = report.adaptation.expect("adapted");
    eprintln!(
        "efficiency shape on all {} rows ({}): {}",
        rows.len(),
        strategy.name(),
        a.turbine_efficiency.name()
    );
    AdaptSettings::of(strategy).with_efficiency_shape_of(&a)
}

/// Load `k` of `rows` left out: `model` calibrated to the others with design values only and
/// with the adaptation `adapt` (from [`chosen`]), each's (mean, worst) |error| in % over the
/// measured signals of row `k` (printed with `label`).
fn leave_out(
    model: &Engine,
    rows: &[Snapshot],
    k: usize,
    label: &str,
    adapt: &AdaptSettings,
) -> [[f64; 2]; 2] {
    let cands = default_candidates(model).expect("candidates");
    let mut cells = [[f64::NAN; 2]; 2];
    for (m, adapt) in [None, Some(adapt)].into_iter().enumerate() {
        // `calibrate --validate`'s own fold: the calibration without row k, the row predicted.
        let started = std::time::Instant::now();
        let fold = CalibrationSettings {
            adapt: adapt.cloned(),
            ..settings(None)
        };
        let adapt = adapt.map(|a| a.strategy);
        let (p, runs) = left_out(model, rows, k, &[], &cands, &fold).expect("row k exists");
        if let Some(why) = &p.failed {
            panic!("left-out row {k} (adapt {adapt:?}): {why}");
        }
        eprintln!(
            "{label}left out line {} ({}, relative GG speed {:.3?}; adapt {adapt:?}, {:.1} s, {runs} \
             model runs): mean {:.3} %, worst {:.3} % {:?}",
            p.line,
            p.position.as_str(),
            p.gg_speed,
            started.elapsed().as_secs_f64(),
            p.mean_abs_pct,
            p.worst_abs_pct,
            p.errors
                .iter()
                .map(|e| format!("{} {:+.3}", e.signal, e.pct))
                .collect::<Vec<_>>()
        );
        cells[m] = [p.mean_abs_pct, p.worst_abs_pct];
    }
    cells
}

/// The first foreign unit: its truth engine, its 9 healthy rows, and the user's md22 copy with
/// the design point set from the full-load row.
fn first_unit() -> (Engine, Vec<Snapshot>, Engine) {
    let truth = truth_engine();
    let rows = rows_of(&truth, [0.0; 6], 0, "healthy");
    let full = rows
        .iter()
        .max_by(|a, b| a.n2_rpm.total_cmp(&b.n2_rpm))
        .expect("full load");
    let model = user_model(full);
    (truth, rows, model)
}

/// Which of `n` loads to leave out in turn: every one, or the ones `GTWATCH_FOREIGN_FOLDS`
/// lists (indices from 0, the lowest load, comma-separated) to re-run a few by hand.
fn left_out_loads(n: usize) -> Vec<usize> {
    let Ok(list) = std::env::var("GTWATCH_FOREIGN_FOLDS") else {
        return (0..n).collect();
    };
    let folds: Vec<usize> = list
        .split(',')
        .map(|x| {
            x.trim()
                .parse()
                .expect("GTWATCH_FOREIGN_FOLDS: indices like 0,8")
        })
        .collect();
    assert!(
        folds.iter().all(|&k| k < n),
        "GTWATCH_FOREIGN_FOLDS: indices below {n}"
    );
    folds
}

#[test]
fn adapted_md22_predicts_left_out_loads_of_a_foreign_unit() {
    let (_, rows, model) = first_unit();
    assert_eq!(rows.len(), 9);
    // Every load in turn (≈ 5 s a calibration since parameters are set in one batch): per
    // left-out load k, [design only, adapted] × [mean, worst].
    let grown = chosen(&model, &rows, AdaptStrategy::Grown);
    let folds: Vec<(usize, [[f64; 2]; 2])> = left_out_loads(rows.len())
        .into_iter()
        .map(|k| (k, leave_out(&model, &rows, k, "", &grown)))
        .collect();
    let mean_of = |m: usize| folds.iter().map(|(_, c)| c[m][0]).sum::<f64>() / folds.len() as f64;
    let worst_of = |m: usize| folds.iter().map(|(_, c)| c[m][1]).fold(0.0, f64::max);
    eprintln!("left-out load | design only: mean / worst % | adapted: mean / worst %");
    for (k, [a, b]) in &folds {
        eprintln!(
            "{:>10} | {:6.3} / {:6.3} | {:6.3} / {:6.3}",
            format!("line {}", rows[*k].line),
            a[0],
            a[1],
            b[0],
            b[1]
        );
    }
    eprintln!(
        "all loads: design only mean {:.3} %, worst {:.3} %; adapted mean {:.3} %, worst {:.3} %",
        mean_of(0),
        worst_of(0),
        mean_of(1),
        worst_of(1)
    );
    // The floors (mean ≤ 0.3 %, no signal beyond 1 %) hold on the loads from 56 % to
    // 91 % (measured 0.23 % / 0.55 % at worst, 2026-11-29). Not yet on the others: the lowest
    // and the full load, left out, are extrapolations of the curves (0.95 % / 2.40 % and
    // 0.89 % / 1.51 %), and 38.75 % and 47.5 %, where the vanes close and the loads are
    // sparsest, 0.90 % / 2.28 % and 0.67 % / 1.11 %: floors here are what this version meets.
    for (k, cells) in &folds {
        let [mean, worst] = cells[1];
        let (mean_floor, worst_floor) = if (3..=7).contains(k) {
            (0.3, 1.0)
        } else {
            (1.1, 2.5)
        };
        assert!(
            mean <= mean_floor && worst <= worst_floor,
            "load {k} left out: adapted mean {mean:.3} %, worst {worst:.3} %"
        );
    }
    if folds.len() == rows.len() {
        // Over all nine: measured 0.48 % mean (the 0.3 % not met).
        assert!(mean_of(1) <= 0.55, "adapted mean {:.3} %", mean_of(1));
    }
    assert!(
        mean_of(1) < mean_of(0) / 3.0,
        "adapted mean {:.3} % against design-only {:.3} %",
        mean_of(1),
        mean_of(0)
    );
    assert!(
        worst_of(1) < worst_of(0) / 2.0,
        "adapted worst {:.3} % against design-only {:.3} %",
        worst_of(1),
        worst_of(0)
    );
}

/// The coverage advice of the adapted calibration on the first unit's 9 loads
/// (`AdaptReport::coverage`).
fn coverage_of(
    model: &Engine,
    rows: &[Snapshot],
) -> Vec<gtwatch::calibrate::adapt::CoverageAdvice> {
    let cands = default_candidates(model).expect("candidates");
    let (report, _) = calibrate(
        model,
        rows,
        &[],
        cands,
        &settings(Some(AdaptStrategy::Grown)),
    )
    .expect("calibrate");
    let c = report.adaptation.expect("adapted").coverage;
    for a in &c {
        eprintln!("coverage: {}", a.describe());
    }
    c
}

/// The adapted calibration names where the baseline wants a healthy load more
/// (`AdaptReport::coverage`: beside interior loads the model's own error along the GG speed
/// reaches 1 % on some signal): on this unit the span between 38.75 % and 47.5 % load (torque
/// 1.39 %). That following the advice helps is
/// [`following_the_coverage_advice_helps`]'s measurement.
#[test]
fn the_calibration_names_where_the_baseline_wants_a_load_more() {
    let (_, rows, model) = first_unit();
    let advice = coverage_of(&model, &rows);
    assert_eq!(advice.len(), 1, "{advice:?}");
    assert_eq!(advice[0].lines, [rows[1].line, rows[2].line], "{advice:?}");
    assert!(advice[0].worst_pct >= 1.0);
}

/// Following the coverage advice helps: with a 42.5 % load added, the 47.5 % load left out is
/// predicted within the floors (measured 0.22 / 0.51 % against 0.67 / 1.11 % without
/// it) and the advice moves to the span below. A measurement (45 s of CI's 20 minutes beside
/// the suite; run by hand: `cargo test --release --test integration following_the_coverage --
/// --ignored --nocapture`).
#[test]
#[ignore = "measurement: cargo test --release --test integration following_the_coverage -- --ignored --nocapture"]
fn following_the_coverage_advice_helps() {
    let (truth, rows, model) = first_unit();
    let advice = coverage_of(&model, &rows);
    assert_eq!(advice.len(), 1, "{advice:?}");

    // The advice followed: a healthy load at 42.5 % on a mid-range day.
    let f = 0.425;
    let (mut pts, mut n2) = loads(0);
    pts.push(OperatingPoint {
        t_amb_k: 288.0,
        p_amb_kpa: 100.5,
        power_mw: AERO25.design_mw * f,
    });
    n2.push(combinator_n2(f));
    let more = rows_at(&truth, (pts, n2), [0.0; 6], 0, "healthy");
    assert_eq!(more.len(), 10);
    let grown = |rows: &[Snapshot]| chosen(&model, rows, AdaptStrategy::Grown);
    let before = leave_out(&model, &rows, 2, "9 loads: ", &grown(&rows))[1];
    let after = leave_out(&model, &more, 2, "10 loads: ", &grown(&more))[1];
    eprintln!(
        "47.5 % left out: {:.3} / {:.3} % on 9 loads, {:.3} / {:.3} % with the 42.5 % load",
        before[0], before[1], after[0], after[1]
    );
    assert!(after[0] <= 0.3 && after[1] <= 1.0, "{after:?}");
    assert!(after[0] < before[0] && after[1] < before[1]);
    let moved = coverage_of(&model, &more);
    assert!(
        moved.iter().all(|a| a.lines != advice[0].lines),
        "{moved:?}"
    );
}

/// `calibrate --adapt --adapt-strategy continuation` on the same unit: every curve the data
/// inform (the compressor's flow and pressure ratio too), all knots at once, fitted through a
/// sequence of smoothness scales. Every load left out in turn, it meets the issue's
/// leave-one-load-out floors (mean ≤ 0.3 %, no signal beyond 1 %) on the loads from 38.75 % to
/// 91 %, and within 1 % on the full load, where the grown shape does not; not on the lowest
/// load, an extrapolation (2.5 % mean). Its healthy baseline diagnoses `good` within 0.3
/// points; what the correlated curves do off the operating line the healthy data do not pin,
/// so the degradation grid is read with more cross-talk than on the grown shape (floors below
/// are what it meets; no miss is called good).
///
/// 36 s alone, 69 s beside the suite: run by hand (`cargo test --release --test integration
/// foreign_engine::continuation -- --ignored --nocapture`) since CI neared its 20 minutes. The
/// continuation as the grown shape's stand-in stays in CI
/// (`a_foreign_unit_the_adaptation_cannot_fit_is_said_to_be_unfit`).
#[test]
#[ignore = "measurement (69 s of CI's 20 minutes): cargo test --release --test integration foreign_engine::continuation -- --ignored --nocapture"]
fn continuation_predicts_left_out_loads_of_a_foreign_unit_within_the_floors() {
    let (truth, rows, model) = first_unit();
    let mut means = Vec::new();
    let mut worst = 0.0f64;
    let continuation = chosen(&model, &rows, AdaptStrategy::Continuation);
    for k in left_out_loads(rows.len()) {
        let cells = leave_out(&model, &rows, k, "continuation ", &continuation);
        eprintln!(
            "continuation: line {} | design only {:.3} / {:.3} % | adapted {:.3} / {:.3} %",
            rows[k].line, cells[0][0], cells[0][1], cells[1][0], cells[1][1]
        );
        let [mean, w] = cells[1];
        // Measured 2026-11-29: 38.75–91 % within 0.28 % / 0.95 %; the full load 0.39 % /
        // 0.80 %; the lowest load 2.51 % / 3.94 %.
        let (mean_floor, worst_floor) = match k {
            0 => (2.8, 4.5),
            8 => (0.45, 1.0),
            _ => (0.3, 1.0),
        };
        assert!(
            mean <= mean_floor && w <= worst_floor,
            "continuation, load {k} left out: mean {mean:.3} %, worst {w:.3} %"
        );
        means.push(mean);
        worst = worst.max(w);
    }
    let mean = means.iter().sum::<f64>() / means.len() as f64;
    eprintln!("continuation: adapted mean {mean:.3} %, worst {worst:.3} %");

    let (adapted, cfg, baseline, quality) =
        adapted_baseline(&model, &rows, AdaptStrategy::Continuation);
    eprintln!("continuation: healthy baseline {baseline:.3?} quality {quality}");
    assert_eq!(quality, "good");
    assert!(baseline.iter().all(|v| v.abs() <= 0.3), "{baseline:?}");
    let (est, verdicts) = grid_estimates(&truth, AERO25, &adapted, &cfg);
    let rho = grid_ranks(&est, &verdicts).map(|r| r.rho);
    // Measured 0.975 / 0.96 / 0.63 / 0.97 (the grown shape: 0.975 / 0.93 / 0.89 / 0.98): the HP
    // turbine's flow reads compressor fouling as up to −1.3 points of D_GT.
    for (p, floor) in [(0, 0.9), (1, 0.85), (2, 0.55), (3, 0.9)] {
        assert!(rho[p] >= floor, "{}: ρ {:.3}", HEALTH_NAMES[p], rho[p]);
    }
    assert_no_miss_called_good(&est, &verdicts);
}

#[test]
fn adapted_md22_diagnoses_a_foreign_unit() {
    let (truth, rows, model) = first_unit();
    // The healthy baseline diagnoses good at ≈ 0 on the model adapted to all 9 loads.
    let (adapted, cfg, baseline, baseline_quality) =
        adapted_baseline(&model, &rows, AdaptStrategy::Grown);
    eprintln!("healthy baseline: {baseline:.3?} quality {baseline_quality}");

    // A grid of degradation at all 9 loads: compressor fouling, HP-turbine wear, both.
    let (est, verdicts) = grid_estimates(&truth, AERO25, &adapted, &cfg);
    let ranks = grid_ranks(&est, &verdicts);
    let rho = ranks.map(|r| r.rho);
    // The rank floor, ρ ≥ 0.95 for all four, and each level within 0.5 points: met
    // with the adapted model's own error (estimated by the calibration on interior points left
    // out) added to each instrument σ at each point's own GG speed
    // ([adaptation.model_error_by_speed]). With no model error D_GT ranked at 0.89 (the
    // averaged GG speed, far more precise than the map predicts it off the healthy operating
    // line, pulled compressor fouling into HPT flow); with one average error for every load,
    // the low loads, where the borrowed map is bent furthest and predicts worst, pulled the
    // levels up to 0.62 points off (D_GC), then 0.30; with the snapshots beyond the calibrated
    // GG speeds left out ([adaptation.calibrated]: a fouled GG runs faster than the healthy
    // one did), 0.26 at worst, and the healthy power turbine within 0.45 (+0.51 before). Not
    // met yet: every fit good (10 of 15; the others' residuals 1.1–1.9, honest: off the
    // healthy line the model misses by more than on it); the cross-talk as a rank (D_ET
    // leaks about −0.03 points per point of D_GC: small, but nearly monotone, so ρ = −0.9).
    // The unit's inlet loss goes with its flow squared, as md22's: the law is kept.
    assert_eq!(
        adapted.cfg().design.inlet_loss_law,
        gtwatch::engine::config::PressureLossLaw::FlowSquared
    );
    let a = adapted.cfg().adaptation.as_ref().expect("adapted");
    assert!(
        a.model_error_pct.get("n1_rpm").is_some_and(|v| *v > 0.05),
        "the GG speed's model error is estimated: {:?}",
        a.model_error_pct
    );
    let profile = a.model_error_by_speed.as_ref().expect("a profile");
    let n1 = &profile.pct["n1_rpm"];
    assert!(
        n1[0] > 2.0 * n1[n1.len() - 1],
        "predicted worse at the lowest interior load than at the highest: {n1:?}"
    );
    for p in 0..4 {
        assert!(rho[p] >= 0.95, "{}: ρ {:.3}", HEALTH_NAMES[p], rho[p]);
    }
    // Measured 2026-11-29: D_GC, D_EC and D_ET at this grid's ceiling (0.982: each is healthy on
    // 5 of the 15 levels), every pair of levels the truth orders ordered right; D_GT 0.960, two
    // pairs misordered (compressor fouling read as −0.14…−0.26 of D_GT, the lightest combined
    // level's −0.2 read −0.19).
    for (p, most) in [(0, 0), (1, 0), (2, 2), (3, 0)] {
        assert!(
            ranks[p].misordered <= most,
            "{}: {}",
            HEALTH_NAMES[p],
            ranks[p]
        );
    }
    for (i, e) in est.iter().enumerate() {
        for p in 0..6 {
            let err = (e[p] - grid(i)[p]).abs();
            assert!(err <= 0.5, "level {i} {}: error {err:.2}", HEALTH_NAMES[p]);
        }
    }
    assert_eq!(
        baseline_quality, "good",
        "the healthy baseline on the adapted model"
    );
    for (p, v) in baseline.iter().enumerate() {
        assert!(v.abs() <= 0.3, "baseline {} = {v:.3}", HEALTH_NAMES[p]);
    }
    assert_no_miss_called_good(&est, &verdicts);
}

/// Prints each level of the grid, each parameter's Spearman ρ and worst error and the
/// cross-talk; returns the ranks of D_GC, D_EC, D_GT and D_ET (each parameter is healthy on 5
/// of the 15 levels, a tie no estimate repeats, so a perfect order reaches 0.982, not 1).
fn grid_ranks(est: &[[f64; 6]], verdicts: &[String]) -> [Rank; 4] {
    let levels = LEVELS;
    let mut worst = [0.0f64; 6];
    let mut good = 0;
    for (i, e) in est.iter().enumerate() {
        let t = grid(i);
        for p in 0..6 {
            worst[p] = worst[p].max((e[p] - t[p]).abs());
        }
        let q = &verdicts[i];
        good += usize::from(q == "good");
        eprintln!("level {i:2} truth {t:?} est {e:+.2?} {q}");
    }
    let column = |v: &[[f64; 6]], p: usize| v.iter().map(|x| x[p]).collect::<Vec<f64>>();
    let truths: Vec<[f64; 6]> = (0..levels).map(grid).collect();
    let ranks: [Rank; 4] = std::array::from_fn(|p| Rank::of(&column(est, p), &column(&truths, p)));
    for (p, r) in ranks.iter().enumerate() {
        eprintln!(
            "{}: {r}, worst error {:.3} points",
            HEALTH_NAMES[p], worst[p]
        );
    }
    // The power turbine is healthy on every level: its estimates are cross-talk only.
    for p in 4..6 {
        eprintln!(
            "{} (truth 0 on every level): worst error {:.3} points",
            HEALTH_NAMES[p], worst[p]
        );
    }
    // Cross-talk: a compressor estimate against the turbine truth over the compressor-free
    // levels, and the reverse.
    let turbine_only: Vec<usize> = (0..levels).filter(|&i| grid(i)[0] == 0.0).collect();
    let compressor_only: Vec<usize> = (0..levels).filter(|&i| grid(i)[2] == 0.0).collect();
    let pick =
        |idx: &[usize], v: &[[f64; 6]], p: usize| idx.iter().map(|&i| v[i][p]).collect::<Vec<_>>();
    let cross_c = spearman(
        &pick(&turbine_only, est, 0),
        &pick(&turbine_only, &truths, 3),
    );
    let cross_t = spearman(
        &pick(&compressor_only, est, 3),
        &pick(&compressor_only, &truths, 0),
    );
    eprintln!(
        "cross-talk: D_GC vs D_ET truth on turbine-only levels {cross_c:.3}; D_ET vs D_GC truth \
         on compressor-only levels {cross_t:.3}; {good} of {levels} fits good"
    );
    ranks
}

/// A fit that misses the plant (a level off by more than 0.5 points) must not be called good.
fn assert_no_miss_called_good(est: &[[f64; 6]], verdicts: &[String]) {
    for (i, q) in verdicts.iter().enumerate() {
        let err = (0..4)
            .map(|p| (est[i][p] - grid(i)[p]).abs())
            .fold(0.0, f64::max);
        assert!(
            err <= 0.5 || q != "good",
            "level {i}: error {err:.2} points called good"
        );
    }
}

/// The model adapted to all of `rows` (a healthy baseline), the diagnosis settings of these
/// tests, and the baseline diagnosed on it: its health and fit verdict.
fn adapted_baseline(
    model: &Engine,
    rows: &[Snapshot],
    strategy: AdaptStrategy,
) -> (Engine, DiagnosisConfig, [f64; 6], String) {
    let adapted = calibrated(model, rows, Some(strategy));
    eprintln!("{}", model_error_text(&adapted));
    let cfg = diagnosis_cfg();
    let report = diagnose_snapshots(&adapted, rows, &cfg).expect("diagnosis");
    let g = &report.groups[0];
    let baseline = g.result.health.to_array();
    let quality = format!("{:?}", g.result.fit_quality.verdict).to_lowercase();
    (adapted, cfg, baseline, quality)
}

/// The [`LEVELS`] levels of [`grid`] made by `truth` at the 9 loads of `unit`, diagnosed on
/// `adapted`: each level's health estimate and fit verdict.
fn grid_estimates(
    truth: &Engine,
    unit: Unit,
    adapted: &Engine,
    cfg: &DiagnosisConfig,
) -> (Vec<[f64; 6]>, Vec<String>) {
    let all: Vec<usize> = (0..LEVELS).collect();
    grid_estimates_at(truth, unit, adapted, cfg, &all)
}

/// [`grid_estimates`] on the grid's levels `levels` only, in that order.
fn grid_estimates_at(
    truth: &Engine,
    unit: Unit,
    adapted: &Engine,
    cfg: &DiagnosisConfig,
    levels: &[usize],
) -> (Vec<[f64; 6]>, Vec<String>) {
    let rows_all = grid_rows(truth, unit, levels);
    let report = diagnose_snapshots(adapted, &rows_all, cfg).expect("diagnosis");
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    for g in &report.groups {
        let q = &g.result.fit_quality;
        eprintln!(
            "  {}: residual {:.2} (worst cell {:.2}), residual verdict {:?}, at limit {}, \
             implausible {}; {}",
            g.group,
            q.normalised_residual,
            q.worst_cell_error,
            q.residual_verdict,
            q.at_limit.len(),
            q.implausible.len(),
            q.summary
        );
    }
    report
        .groups
        .iter()
        .map(|g| {
            (
                g.result.health.to_array(),
                format!("{:?}", g.result.fit_quality.verdict).to_lowercase(),
            )
        })
        .unzip()
}

/// The snapshots of the grid's levels `levels` made by `truth` at the 9 loads of `unit`, each
/// level its own group (`level07`).
fn grid_rows(truth: &Engine, unit: Unit, levels: &[usize]) -> Vec<Snapshot> {
    let mut rows = Vec::new();
    for &i in levels {
        let loads = loads_of(unit.design_mw, i + 1);
        rows.extend(rows_at(
            truth,
            loads,
            grid(i),
            i + 1,
            &format!("level{i:02}"),
        ));
    }
    rows
}

/// Levels of the degradation grid.
const LEVELS: usize = 15;

/// Level `i` of 15: 0–4 compressor fouling (D_GC to 4, D_EC 0.4·D_GC), 5–9 HP-turbine wear
/// (D_GT to −2, D_ET to 3), 10–14 both at magnitudes between the single ones.
fn grid(i: usize) -> [f64; 6] {
    let path = i / 5;
    let j = (i % 5) as f64 + if path == 2 { 0.5 } else { 1.0 };
    let c = [4.0 * j / 5.0, 1.6 * j / 5.0];
    let t = [-2.0 * j / 5.0, 3.0 * j / 5.0];
    match path {
        0 => [c[0], c[1], 0.0, 0.0, 0.0, 0.0],
        1 => [0.0, 0.0, t[0], t[1], 0.0, 0.0],
        _ => [c[0], c[1], t[0], t[1], 0.0, 0.0],
    }
}

/// A second foreign unit, of another map family again (pyCycle's axi5 compressor and lpt2269
/// turbines, tests/data/reference/pycycle_maps/), with the settings tuned on the first: each
/// load left out of an adapted calibration, the healthy baseline and the degradation grid
/// diagnosed on the model adapted to all 9 loads.
#[test]
fn adapted_md22_fits_a_second_foreign_unit() {
    second_unit(AdaptStrategy::Grown);
}

/// The same with `--adapt-strategy continuation`: on this unit it meets the same floors (the
/// first unit's price, D_GT read worse, is not paid here).
#[test]
fn continuation_fits_a_second_foreign_unit() {
    second_unit(AdaptStrategy::Continuation);
}

/// The second unit's checks with the adaptation of `strategy`.
fn second_unit(strategy: AdaptStrategy) {
    let truth = unit_engine(PYC30);
    let rows = rows_at(&truth, loads_of(PYC30.design_mw, 0), [0.0; 6], 0, "healthy");
    let full = rows
        .iter()
        .max_by(|a, b| a.n2_rpm.total_cmp(&b.n2_rpm))
        .expect("full load");
    // The datasheet's flow 3 % off the truth's 88 kg/s, as for the first unit.
    let model = user_model_with(full, 88.0 * 0.97);
    // Every load left out in turn (measured 2026-11-29: grown 0.18 % mean, 0.19 % before the
    // closing fit of every design value; continuation 0.18 %).
    let left_out = left_out_loads(rows.len());
    // Per left-out load k: [design only, adapted] × [mean, worst].
    let mut table: Vec<(usize, [[f64; 2]; 2])> = Vec::new();
    let adapt = chosen(&model, &rows, strategy);
    for k in left_out {
        let cells = leave_out(&model, &rows, k, "pyc30 ", &adapt);
        table.push((k, cells));
    }
    eprintln!("pyc30 left-out line | design only: mean / worst % | adapted: mean / worst %");
    for (k, c) in &table {
        eprintln!(
            "{:>10} | {:6.3} / {:6.3} | {:6.3} / {:6.3}",
            rows[*k].line, c[0][0], c[0][1], c[1][0], c[1][1]
        );
    }
    let mean_of = |m: usize| table.iter().map(|(_, c)| c[m][0]).sum::<f64>() / table.len() as f64;
    let interior = |k: usize| k > 0 && k + 1 < rows.len();
    let worst_of = |m: usize, only_interior: bool| {
        table
            .iter()
            .filter(|(k, _)| !only_interior || interior(*k))
            .map(|(_, c)| c[m][1])
            .fold(0.0, f64::max)
    };
    eprintln!(
        "pyc30 {} loads left out: design only mean {:.3} %, adapted mean {:.3} %, worst {:.3} % \
         (interior {:.3} %)",
        table.len(),
        mean_of(0),
        mean_of(1),
        worst_of(1, false),
        worst_of(1, true)
    );
    // The floors on this unit: mean ≤ 0.3 %, and no signal beyond 1 % on the interior
    // loads (the lowest and the full load, left out, are extrapolations: 1.5 % there).
    assert!(mean_of(1) <= 0.3, "adapted mean {:.3} %", mean_of(1));
    assert!(mean_of(1) < mean_of(0) / 5.0);
    assert!(worst_of(1, true) <= 1.0);
    assert!(worst_of(1, false) <= 1.5);

    let (adapted, cfg, baseline, quality) = adapted_baseline(&model, &rows, strategy);
    eprintln!("pyc30 healthy baseline: {baseline:.3?} quality {quality}");
    assert_eq!(quality, "good");
    assert!(baseline.iter().all(|v| v.abs() <= 0.3), "{baseline:?}");

    // The same degradation grid as the first unit's, at all 9 loads.
    let levels = LEVELS;
    let (est, verdicts) = grid_estimates(&truth, PYC30, &adapted, &cfg);
    let truths: Vec<[f64; 6]> = (0..levels).map(grid).collect();
    let column = |v: &[[f64; 6]], p: usize| v.iter().map(|x| x[p]).collect::<Vec<f64>>();
    let mut good = 0;
    for (i, e) in est.iter().enumerate() {
        let q = &verdicts[i];
        good += usize::from(q == "good");
        eprintln!("pyc30 level {i:2} truth {:?} est {e:+.2?} {q}", truths[i]);
    }
    for p in 0..4 {
        let rank = Rank::of(&column(&est, p), &column(&truths, p));
        let worst = (0..levels)
            .map(|i| (est[i][p] - truths[i][p]).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "pyc30 {}: {rank}, worst error {worst:.3} points",
            HEALTH_NAMES[p]
        );
        // The floors: ρ ≥ 0.95, each level within 0.5 points. Measured 2026-11-29, grown
        // and continuation alike: every pair of levels the truth orders ordered right (ρ 0.982,
        // the ceiling of this grid).
        assert!(rank.rho >= 0.95, "{}: {rank}", HEALTH_NAMES[p]);
        assert_eq!(rank.misordered, 0, "{}: {rank}", HEALTH_NAMES[p]);
        assert!(worst <= 0.5, "{}: worst {worst:.3}", HEALTH_NAMES[p]);
    }
    // Cross-talk: the compressor estimate on the turbine-only levels stays near zero.
    for i in (0..levels).filter(|&i| truths[i][0] == 0.0) {
        assert!(est[i][0].abs() <= 0.3, "level {i}: D_GC {:.3}", est[i][0]);
    }
    eprintln!("pyc30: {good} of {levels} fits good");
    // The issue asks every fit `good`: measured 15 of 15, grown and continuation alike, since
    // a snapshot whose GG runs faster or slower than any the calibration saw is left out
    // (`[adaptation.calibrated]`; 12 of 15 before, the rest `suspect` on their residual at the
    // largest degradations, where fouling took the full load beyond the calibrated speeds).
    assert_eq!(good, levels, "{good} of {levels} fits good");
}

/// A user writes the design point from the full-load row into the copied engine file to a few
/// digits, not to the last: the calibration must not hang on them. Each written form of the
/// first unit's design pressure ratio, power and GG speed (the file as a user edits it, loaded
/// as `gtwatch calibrate` loads it) is calibrated with the grown adaptation, and each must
/// reproduce the healthy baseline (`good`) and state the adapted model's own error (at least
/// three interior loads left out). Before the growth's second look, four decimals (20.9291,
/// 24.9893 MW, 9 831.37 rpm) stopped the compressor and the HP turbine at one knot (5.16 σ,
/// `poor`), where the full digits grew five (0.62 σ); and before the model error was estimated
/// with the design values held, two decimals (20.93, 24.99 MW, 9 831.4 rpm) grew the
/// compressor to six knots and left every fold out, so the file stated no model error at all;
/// and the datasheet's round 9 800 rpm ended the grown shape at 1.77 σ (`poor`), where the
/// continuation, now tried in its place, reproduces the baseline at 0.69 σ.
///
/// CI writes the round 9 800 rpm only (69 s beside the suite for all three); all three by hand:
/// `GTWATCH_FEW_DIGITS_ALL=1 cargo test --release --test integration few_digits -- --nocapture`.
#[test]
fn a_design_point_written_to_a_few_digits_calibrates_alike() {
    let (_, rows, model) = first_unit();
    let exact = model.cfg().design.clone();
    let md22 = std::fs::read_to_string(root().join("config/engine_md22.toml")).expect("md22");
    let maps = root().join("config/maps");
    let dir = tempfile::tempdir().expect("dir");
    let fmt = |v: f64, d: usize| format!("{v:.d$}");
    // The pressure ratio, the power and the GG speed as written.
    // CI writes the datasheet's round GG speed; the digits' forms too with
    // `GTWATCH_FEW_DIGITS_ALL=1` (each a calibration of 20 s beside the suite).
    let mut forms = vec![(2, "9800".to_string())];
    if std::env::var("GTWATCH_FEW_DIGITS_ALL").is_ok() {
        forms.insert(0, (2, fmt(exact.gg_speed_rpm, 1)));
        forms.insert(0, (4, fmt(exact.gg_speed_rpm, 2)));
    }
    for (digits, gg_speed) in forms {
        let mut in_load = false;
        let mut text = String::new();
        for line in md22.lines() {
            if line.starts_with('[') {
                // A propeller on a combinator: the PT speed is measured, no load law.
                in_load = line.starts_with("[load]");
            }
            if in_load {
                continue;
            }
            let key = line.split('=').next().unwrap_or("").trim();
            let written = match key {
                _ if line.starts_with('#') => None,
                "pressure_ratio" => Some(fmt(exact.pressure_ratio, digits)),
                "power_mw" => Some(fmt(exact.power_mw, digits)),
                "gg_speed_rpm" => Some(gg_speed.clone()),
                "pt_speed_rpm" => Some(fmt(exact.pt_speed_rpm, 0)),
                "exhaust_flow_kg_s" => Some(fmt(exact.exhaust_flow_kg_s, 1)),
                _ => None,
            };
            text += &match written {
                Some(v) => format!("{key} = {v}\n"),
                None => format!(
                    "{}\n",
                    line.replace("\"maps/", &format!("\"{}/", maps.display()))
                ),
            };
        }
        let path = dir.path().join(format!("engine_{digits}_{gg_speed}.toml"));
        std::fs::write(&path, &text).expect("write");
        let written = Engine::new(EngineConfig::load(&path).expect("the written file loads"))
            .expect("builds");
        assert!(written.cfg().load.is_none());
        let cands = default_candidates(&written).expect("candidates");
        let (report, _) = calibrate(
            &written,
            &rows,
            &[],
            cands,
            &settings(Some(AdaptStrategy::Grown)),
        )
        .expect("calibrate");
        let a = report.adaptation.as_ref().expect("adapted");
        eprintln!(
            "{digits} decimals (PR {}), GG {gg_speed} rpm: {} shape{}, RMS {:.2} σ, {:?}, knots \
             {:?}; model error from {} folds: {}",
            fmt(exact.pressure_ratio, digits),
            a.strategy,
            a.fallback
                .as_ref()
                .map_or(String::new(), |f| format!(" ({f})")),
            report.rms_after,
            report.baseline_fit.verdict,
            a.components
                .iter()
                .map(|c| c.knots.len())
                .collect::<Vec<_>>(),
            a.model_error.folds,
            a.model_error.note
        );
        assert_eq!(
            format!("{:?}", report.baseline_fit.verdict),
            "Good",
            "{digits} decimals, GG {gg_speed} rpm: {}",
            report.baseline_fit.summary
        );
        assert!(
            a.model_error.folds >= 3,
            "{digits} decimals, GG {gg_speed} rpm: {}",
            a.model_error.note
        );
    }
}

/// The unit with fixed inlet vanes, its 9 healthy rows, and the user's md22 copy calibrated
/// to them with the grown adaptation of at most `max_knots` knots per component: the
/// calibration and the adapted engine.
fn fixed_vanes_calibrated(max_knots: usize) -> (Engine, Vec<Snapshot>, Calibration, Engine) {
    let truth = unit_engine(AERO25_FIXED_VANES);
    let rows = rows_at(&truth, loads_of(25.0, 0), [0.0; 6], 0, "healthy");
    let full = rows
        .iter()
        .max_by(|a, b| a.n2_rpm.total_cmp(&b.n2_rpm))
        .expect("full load");
    let model = user_model(full);
    let cands = default_candidates(&model).expect("candidates");
    let settings = CalibrationSettings {
        adapt: Some(AdaptSettings {
            max_knots,
            ..AdaptSettings::of(AdaptStrategy::Grown)
        }),
        ..settings(None)
    };
    let (report, adapted) = calibrate(&model, &rows, &[], cands, &settings).expect("calibrate");
    let fit = &report.baseline_fit;
    eprintln!(
        "fixed vanes, at most {max_knots} knot(s): RMS {:.2} -> {:.2} σ; baseline fit {:?}: {}",
        report.rms_before, report.rms_after, fit.verdict, fit.summary
    );
    if let Some(a) = &report.adaptation {
        for c in &a.components {
            eprintln!(
                "  {} knots {:.3?} ({})",
                c.component, c.knots, c.knots_reason
            );
        }
        for c in &a.coverage {
            eprintln!("  coverage: {}", c.describe());
        }
    }
    eprintln!("  {}", model_error_text(&adapted));
    (truth, rows, report, adapted)
}

/// The model error an adapted engine file states, on average, along the GG speed and in
/// health units.
fn model_error_text(adapted: &Engine) -> String {
    let a = adapted.cfg().adaptation.as_ref();
    format!(
        "model error: {:.3?}\n  along the GG speed: {:.3?}\n  in health units: {:.3?}",
        a.map(|a| &a.model_error_pct),
        a.and_then(|a| a.model_error_by_speed.as_ref()),
        a.map(|a| &a.health_error)
    )
}

/// The diagnosis settings of these tests.
pub(crate) fn diagnosis_cfg() -> DiagnosisConfig {
    DiagnosisConfig {
        max_model_runs: 1500,
        threads: Some(2),
        ..DiagnosisConfig::default()
    }
}

/// A third foreign unit, aero25 with fixed inlet vanes: its part-load running line is nearly
/// flat in fuel. The adaptation follows its 9 calibration points (0.73 σ RMS) but predicts the
/// low loads poorly between them: its model error on points left out is 3.6–9.7 % on six
/// signals at relative GG speeds 0.75–0.82, 0.4 % or less from 0.89 up. With one average error
/// (2.5–5.6 %) for every load, the grid read up to 2.3 points off at residuals of 0.1–0.2, and
/// the rule then was to call every diagnosis on the file unresolved. Weighted by the error at
/// each point's own GG speed, the high loads carry the diagnosis: the grid reads within 0.52
/// points (0.29 since snapshots beyond the calibrated GG speeds are left out), and only a
/// diagnosis resting on the poorly predicted loads alone is said to be unresolved. The calibration names those speeds.
#[test]
fn a_foreign_unit_predicted_at_some_loads_only_is_diagnosed_by_those() {
    let (truth, rows, report, adapted) = fixed_vanes_calibrated(AdaptSettings::default().max_knots);
    let fit = &report.baseline_fit;
    assert!(
        report.rms_after <= 1.5,
        "RMS after {:.2} σ",
        report.rms_after
    );
    let error = &report.adaptation.as_ref().expect("adapted").model_error;
    let unresolved = error.unresolved_speeds();
    let knots = &error.by_speed.as_ref().expect("a profile").speed_knots;
    assert!(
        !unresolved.is_empty() && unresolved.len() < knots.len(),
        "some speeds resolved, some not: {unresolved:?} of {knots:?}"
    );
    assert!(
        fit.summary.contains("model_error_by_speed"),
        "{}",
        fit.summary
    );
    // The three lowest loads alone (rows are by load, lowest first): not resolved.
    let cfg = diagnosis_cfg();
    let low = diagnose_snapshots(&adapted, &rows[..3], &cfg).expect("diagnosis");
    let q = &low.groups[0].result.fit_quality;
    eprintln!(
        "fixed vanes, three lowest loads: {:?}: {}",
        q.verdict, q.summary
    );
    assert_ne!(format!("{:?}", q.verdict), "Good");
    assert!(!q.model_error_beyond.is_empty());
    // All nine: the healthy baseline near zero, every level of the grid within 0.4 points
    // (2.26 points off before the profile, 0.52 with it, 0.29 since snapshots beyond the
    // calibrated GG speeds are left out), no miss called good.
    let baseline = diagnose_snapshots(&adapted, &rows, &cfg).expect("diagnosis");
    let b = baseline.groups[0].result.health.to_array();
    eprintln!("fixed vanes, healthy baseline {b:+.2?}");
    for (p, v) in b.iter().enumerate().take(4) {
        assert!(v.abs() <= 0.3, "baseline {} = {v:.3}", HEALTH_NAMES[p]);
    }
    let levels: Vec<usize> = (0..LEVELS).collect();
    let (est, verdicts) = grid_estimates_at(&truth, AERO25_FIXED_VANES, &adapted, &cfg, &levels);
    for (e, (&i, q)) in est.iter().zip(levels.iter().zip(&verdicts)) {
        let err = (0..4)
            .map(|p| (e[p] - grid(i)[p]).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "level {i:2} truth {:?} est {e:+.2?} {q}: off by {err:.2}",
            grid(i)
        );
        assert!(err <= 0.4, "level {i}: off by {err:.2}");
        assert!(
            err <= 0.5 || q != "good",
            "level {i}: off by {err:.2} called good"
        );
    }
}

/// A unit the adaptation cannot follow must be said to be one: the unit with fixed vanes,
/// its adaptation held to one knot per component (md22's maps bent by straight ramps of speed
/// miss its flat part-load running line by several σ), gets a calibration whose baseline
/// verdict is not `good` and says what to try, and a healthy baseline whose diagnosis is not
/// `good` (19.5 σ RMS, `poor`, measured 2026-11-28; the continuation, tried in the grown
/// shape's place when it is `poor`, held to one knot too, does no better, and the verdict says
/// both were tried). The calibration reports the misfit the diagnosis will see (each point solved on the running
/// point of its measured GG speed): before, it fitted one branch of a folded running line and
/// reported another.
#[test]
fn a_foreign_unit_the_adaptation_cannot_fit_is_said_to_be_unfit() {
    let (_, rows, report, adapted) = fixed_vanes_calibrated(1);
    let fit = &report.baseline_fit;
    assert_ne!(format!("{:?}", fit.verdict), "Good", "{}", fit.summary);
    assert!(fit.summary.contains("continuation"), "{}", fit.summary);
    let a = report.adaptation.as_ref().expect("adapted");
    assert!(a.fallback.is_some(), "the continuation is tried");
    eprintln!("fixed vanes, one knot: {:?}", a.fallback);
    let cfg = diagnosis_cfg();
    let baseline = diagnose_snapshots(&adapted, &rows, &cfg).expect("diagnosis");
    let q = format!("{:?}", baseline.groups[0].result.fit_quality.verdict).to_lowercase();
    eprintln!("fixed vanes, one knot: healthy baseline {q}");
    assert_ne!(q, "good");
    // Its degradation grid is not re-run: every level was `poor` with estimates on their
    // limits (measured 2026-11-28); the grid above is the one whose residuals could mislead.
}

/// The numbers of environment variable `name` (comma-separated; empty: none), else `default`.
fn env_numbers(name: &str, default: Vec<f64>) -> Vec<f64> {
    std::env::var(name).map_or(default, |v| {
        v.split(',')
            .filter(|x| !x.trim().is_empty())
            .map(|x| x.trim().parse().expect("numbers like 0.34375,0.425"))
            .collect()
    })
}

/// The first unit's 9 healthy loads and one more at each load fraction of `extra` (the k-th on
/// a 283 + 5k K, 101 − 0.5k kPa day).
fn healthy_with_loads(truth: &Engine, extra: &[f64]) -> Vec<Snapshot> {
    let (mut pts, mut n2) = loads(0);
    for (i, f) in extra.iter().enumerate() {
        pts.push(OperatingPoint {
            t_amb_k: 283.0 + 5.0 * i as f64,
            p_amb_kpa: 101.0 - 0.5 * i as f64,
            power_mw: AERO25.design_mw * f,
        });
        n2.push(combinator_n2(*f));
    }
    rows_at(truth, (pts, n2), [0.0; 6], 0, "healthy")
}

/// A known defect, kept as a test that reproduces it (run with `--ignored`): the healthy
/// baseline fixes the curves along the healthy operating line only, and degradation is read
/// off it, where calibrations that fit the same unit equally well differ — by a scale the
/// residuals cannot see, since a model whose sensitivity to fouling is off fits the degraded
/// points at another, wrong health. One healthy load more than the 9, on a 283 K day
/// (`GTWATCH_FOREIGN_EXTRA_LOADS`: load fractions, comma-separated; empty: the 9 loads alone),
/// measured 2026-12-06 (`cargo test --release --test integration a_baseline_with_a_load_more
/// -- --ignored --nocapture`), each
/// baseline fitted within noise and read `good` within 0.15 points:
///
/// | baseline | fit | grid `good` | worst error (D_GC…D_ET) | D_GT ρ | a miss called `good` |
/// |---|---|---|---|---|---|
/// | the 9 loads | 0.62 σ | 10 of 15 | 0.26 | 0.960 | no |
/// | + 34.4 % | 0.59 σ | 4 of 15 | 0.52 | 0.877 | no |
/// | + 42.5 % | 0.72 σ | 15 of 15 | 0.77 (D_GC 4.77 for 4.0) | 0.982 | **yes** |
/// | + 60 % | 0.62 σ | 9 of 15 | 0.41 | 0.949 | no |
///
/// Fixing it needs information off the healthy line (rows from before a compressor wash,
/// `calibrate --prewash-group`: [`rows_before_a_wash_inform_the_grid`] reads these baselines'
/// grids within 0.24–0.53 points, still once calling 0.53 `good`) or a measure of this
/// uncertainty in the diagnosis: with `calibrate --ensemble` the read carries the spread of
/// calibrations on parts of the baseline ([`an_ensemble_states_what_the_baseline_leaves_open`]:
/// this 0.77 miss is read ± 0.82). No verdict promises that a `good` fit on an adapted foreign
/// unit is within 0.5 points; the σ with the spread says how far it may be.
#[test]
#[ignore = "known defect (issue 22): a baseline with a 42.5 % load more reads compressor fouling 0.77 points off and calls it good"]
fn a_baseline_with_a_load_more_reads_the_grid_honestly() {
    let (truth, _, model) = first_unit();
    let extra = env_numbers("GTWATCH_FOREIGN_EXTRA_LOADS", vec![0.425]);
    let more = healthy_with_loads(&truth, &extra);
    let (adapted, cfg, baseline, quality) = adapted_baseline(&model, &more, AdaptStrategy::Grown);
    eprintln!(
        "healthy baseline on {} loads: {baseline:.3?} {quality}",
        more.len()
    );
    assert_eq!(quality, "good");
    assert!(baseline.iter().all(|v| v.abs() <= 0.3), "{baseline:?}");
    let (est, verdicts) = grid_estimates(&truth, AERO25, &adapted, &cfg);
    grid_ranks(&est, &verdicts);
    assert_no_miss_called_good(&est, &verdicts);
}

/// Rows from before a compressor wash beside the healthy baseline (`calibrate --prewash-group`,
/// `calibrate::prewash`): the same unit fouled by D_GC 2, D_EC 0.8 (`GTWATCH_FOREIGN_FOULED`
/// to change it) at the 9 loads on other days, its fouling found with the calibration, then
/// the grid read on it. `GTWATCH_FOREIGN_EXTRA_LOADS` adds healthy loads as in
/// [`a_baseline_with_a_load_more_reads_the_grid_honestly`]. A measurement (about 30–60 s; run
/// with `--ignored --nocapture`), figures in the README ("Rows from before a wash"): it
/// asserts that the fouling is found and the baseline stays healthy; the grid is printed.
#[test]
#[ignore = "a measurement of the pre-wash calibration on the combinator unit (30–60 s)"]
fn rows_before_a_wash_inform_the_grid() {
    let (truth, _, model) = first_unit();
    let extra = env_numbers("GTWATCH_FOREIGN_EXTRA_LOADS", Vec::new());
    let fouled = env_numbers("GTWATCH_FOREIGN_FOULED", vec![2.0, 0.8]);
    let healthy = healthy_with_loads(&truth, &extra);
    let before = [fouled[0], fouled[1], 0.0, 0.0, 0.0, 0.0];
    let mut all = healthy.clone();
    all.extend(rows_at(&truth, loads(3), before, 3, "prewash"));
    let settings = CalibrationSettings {
        prewash_group: Some("prewash".into()),
        ..settings(Some(AdaptStrategy::Grown))
    };
    let cands = default_candidates(&model).expect("candidates");
    let started = std::time::Instant::now();
    let (report, adapted) = calibrate(&model, &all, &[], cands, &settings).expect("calibrate");
    eprintln!(
        "calibration on {} healthy and 9 pre-wash rows: {:.1} s wall, {} model runs",
        healthy.len(),
        started.elapsed().as_secs_f64(),
        report.model_runs
    );
    let pw = report.prewash.as_ref().expect("a pre-wash report");
    for line in pw.describe() {
        eprintln!("{line}");
    }
    // Where the kept calibration misses: each point's RMS (noise σ) and the table's worst cell.
    for (p, row) in report.points.iter().zip(&report.table.rows) {
        let (worst, at) = row
            .values
            .iter()
            .zip(&report.table.signals)
            .filter_map(|(v, s)| v.map(|v| (v, s.as_str())))
            .fold(
                (0.0f64, ""),
                |m, (v, s)| if v.abs() > m.0.abs() { (v, s) } else { m },
            );
        eprintln!(
            "  {} line {}: {} RMS {:.2} σ, worst {at} {worst:+.2}",
            p.source, p.line, row.label, p.rms_after
        );
    }
    let Some(found) = pw.fouling else {
        // Kept the healthy rows' calibration (measured with D_GC 3.5, D_EC 1.3: 1.34 σ with
        // the pre-wash rows, 0.62 without); the 2-point default is adopted.
        assert!(std::env::var("GTWATCH_FOREIGN_FOULED").is_ok(), "{pw:?}");
        return;
    };
    assert!(
        (found.d_gc - before[0]).abs() <= 0.15 && (found.d_ec - before[1]).abs() <= 0.15,
        "{found:?} for {before:?}"
    );
    let cfg = diagnosis_cfg();
    let b = diagnose_snapshots(&adapted, &healthy, &cfg).expect("diagnosis");
    let baseline = b.groups[0].result.health.to_array();
    let quality = format!("{:?}", b.groups[0].result.fit_quality.verdict).to_lowercase();
    eprintln!("healthy baseline: {baseline:.3?} {quality}");
    assert_eq!(quality, "good");
    assert!(baseline.iter().all(|v| v.abs() <= 0.3), "{baseline:?}");
    let (est, verdicts) = grid_estimates(&truth, AERO25, &adapted, &cfg);
    grid_ranks(&est, &verdicts);
    for (i, q) in verdicts.iter().enumerate() {
        let err = (0..4)
            .map(|p| (est[i][p] - grid(i)[p]).abs())
            .fold(0.0, f64::max);
        if err > 0.5 && q == "good" {
            eprintln!("level {i}: {err:.2} points off, called good");
        }
    }
}

/// The grid read with an ensemble (`calibrate --ensemble`, `diagnosis::ensemble`): the
/// calibration on the whole baseline and three on it with an interleaved third of the interior
/// loads left out; each level's read, the spread of the members' reads about it and the σ with
/// it, against the truth. `GTWATCH_FOREIGN_EXTRA_LOADS` as in
/// [`a_baseline_with_a_load_more_reads_the_grid_honestly`] (default: the 42.5 % load whose
/// baseline reads compressor fouling 0.77 points off and calls it good). A measurement (1–2
/// min; run with `--ignored --nocapture`), figures in the README ("Calibrations that fit
/// alike: --ensemble"); it asserts that no level of D_GC…D_ET is off by more than 2.5 times its
/// σ with the spread.
#[test]
#[ignore = "a measurement of the ensemble's spread on the combinator unit (1–2 min)"]
fn an_ensemble_states_what_the_baseline_leaves_open() {
    use gtwatch::diagnosis::ensemble::ensemble_read;
    let (truth, _, model) = first_unit();
    let extra = env_numbers("GTWATCH_FOREIGN_EXTRA_LOADS", vec![0.425]);
    let baseline = healthy_with_loads(&truth, &extra);
    let cfg = diagnosis_cfg();
    let s = settings(Some(AdaptStrategy::Grown));
    let cands = default_candidates(&model).expect("candidates");
    let started = std::time::Instant::now();
    let (_, whole) = calibrate(&model, &baseline, &[], cands.clone(), &s).expect("calibrate");
    let members =
        gtwatch::calibrate::ensemble::members(&model, &baseline, &[], &cands, &s).expect("members");
    eprintln!(
        "{} loads: the whole and {} members calibrated in {:.1} s",
        baseline.len(),
        members.len(),
        started.elapsed().as_secs_f64()
    );
    let all: Vec<usize> = (0..LEVELS).collect();
    let rows = grid_rows(&truth, AERO25, &all);
    let main = diagnose_snapshots(&whole, &rows, &cfg).expect("diagnosis");
    let reads: Vec<_> = members
        .iter()
        .map(|m| diagnose_snapshots(&m.engine, &rows, &cfg).expect("member diagnosis"))
        .collect();
    let (mut worst_ratio, mut stated_good, mut misses) = (0.0f64, 0, Vec::new());
    let mut worst_alone = 0.0f64;
    for (i, g) in main.groups.iter().enumerate() {
        let member_reads = reads
            .iter()
            .enumerate()
            .map(|(j, r)| {
                let read = r
                    .groups
                    .iter()
                    .find(|x| x.group == g.group)
                    .map(|x| x.result.clone())
                    .ok_or_else(|| "not read".to_string());
                (format!("part{}", j + 1), read)
            })
            .collect();
        let e = ensemble_read(&g.result, member_reads);
        let t = grid(i);
        let h = g.result.health.to_array();
        let verdict = format!("{:?}", g.result.fit_quality.verdict).to_lowercase();
        let mut cells = Vec::new();
        for (k, name) in HEALTH_NAMES.iter().enumerate().take(4) {
            let err = h[k] - t[k];
            let sd = e.sigma_with_spread[*name];
            let ratio = err.abs() / sd;
            worst_ratio = worst_ratio.max(ratio);
            worst_alone = worst_alone.max(err.abs() / g.result.sigma[*name]);
            if err.abs() > 0.5 && verdict == "good" && err.abs() > 2.0 * sd {
                misses.push(format!("level {i} {name} {err:+.2} ± {sd:.2}"));
            }
            cells.push(format!(
                "{name} {err:+.2} (spread {:.2}, σ {sd:.2})",
                e.spread[*name]
            ));
        }
        if verdict == "good" {
            stated_good += 1;
        }
        eprintln!("level {i:2} {verdict}: {}", cells.join(", "));
    }
    eprintln!(
        "worst |error| / σ with the spread: {worst_ratio:.2} (/ the file's σ alone: \
         {worst_alone:.2}); {stated_good} of {LEVELS} fits good; misses over 0.5 points called \
         good and beyond 2 σ: {misses:?}"
    );
    assert!(worst_ratio <= 2.5, "an error beyond 2.5 σ with the spread");
}
