//! A foreign generator unit calibrated and diagnosed as a plant engineer would, with its full
//! instrument set and with the few instruments many units have.
//!
//! The truth (`tests/data/foreign/pycgen_truth.toml`) is made unlike the model and unlike the
//! other foreign units: pyCycle's map family, a generator (the PT held at 6 100 rpm), an inlet
//! loss that is a constant fraction (md22 assumes one ∝ flow²), 6 % cooling air, its own VIGV
//! schedule, PR 18.5 / 30 MW; the plant meters electrical power, not torque. The user copies
//! `config/engine_md22.toml`, sets its design point from the healthy full-load row, runs
//! `calibrate --adapt` on 9 healthy loads (35–100 %, days from 268 to 303 K), then diagnoses a
//! grid of compressor, HP-turbine and PT degradation at the same loads on other days.
//!
//! What it asserts. With the full set (N1, P1, T2, P2, T34, P34, T4, power): the baseline fitted
//! within noise, the inlet's constant law read from the data, the interior loads left out
//! predicted well within the floors (0.2 / 0.6 % against 0.3 / 1 %), every level of
//! the grid within 0.4 points on all six parameters and called `good`. With N1, T2, P2, T4 and power only (no P1, no HP-turbine exit
//! station), six health parameters are more than these signals separate: every level is then
//! read within 0.5 points on what the diagnosis calls separable, and any parameter further off
//! is named by the diagnosis as not identifiable or confounded (or the fit is not `good`): a
//! miss is never presented as a plain, good value. The calibration's own error in health units
//! (`[adaptation.health_error]`) says which: within 0.2 points on every parameter with the full
//! set, half a point or more on D_ET, D_GP and D_EP with the five.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::calibrate::adapt::{AdaptSettings, AdaptStrategy};
use gtwatch::calibrate::candidates::default_candidates;
use gtwatch::calibrate::synthetic::{snapshot_csv_at_speeds, OperatingPoint};
use gtwatch::calibrate::validate::{left_out, Position};
use gtwatch::calibrate::{calibrate, Calibration, CalibrationSettings};
use gtwatch::diagnosis::fit_quality::AT_LIMIT_FRACTION;
use gtwatch::diagnosis::snapshot::{diagnose_snapshots, read_snapshots, Snapshot};
use gtwatch::diagnosis::MethodResult;
use gtwatch::engine::config::PressureLossLaw;
use gtwatch::engine::{Engine, EngineConfig};
use gtwatch::health::{HealthParams, HEALTH_BOUNDS, HEALTH_NAMES};
use gtwatch::signals::Signal;
use std::collections::HashMap;
use std::path::PathBuf;

use crate::foreign_engine::{diagnosis_cfg, md22_from_full_load};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

const TRUTH: &str = "tests/data/foreign/pycgen_truth.toml";
const DESIGN_MW: f64 = 30.0;
const SYNC_RPM: f64 = 6100.0;
/// Samples behind each averaged row (a 100-s steady window at 1 Hz).
const AVERAGING: f64 = 100.0;

/// The full instrument set besides the inputs (T1, ambient pressure, n2, fuel flow).
const FULL: [Signal; 8] = [
    Signal::N1,
    Signal::P1,
    Signal::T2,
    Signal::P2,
    Signal::T34,
    Signal::P34,
    Signal::T4,
    Signal::Power,
];

/// What many units measure: no inlet pressure, nothing between the turbines.
const FEW: [Signal; 5] = [
    Signal::N1,
    Signal::T2,
    Signal::P2,
    Signal::T4,
    Signal::Power,
];

/// The grid: label and health (percent, positive = degraded) of each level.
const GRID: [(&str, [f64; 6]); 8] = [
    ("healthy", [0.0; 6]),
    ("fouled 2", [2.0, 0.8, 0.0, 0.0, 0.0, 0.0]),
    ("fouled 4", [4.0, 1.6, 0.0, 0.0, 0.0, 0.0]),
    ("hpt 1", [0.0, 0.0, -1.0, 1.5, 0.0, 0.0]),
    ("hpt 2", [0.0, 0.0, -2.0, 3.0, 0.0, 0.0]),
    ("pt 1", [0.0, 0.0, 0.0, 0.0, -1.0, 1.5]),
    ("pt 2", [0.0, 0.0, 0.0, 0.0, -2.0, 3.0]),
    ("mixed", [2.0, 0.8, -1.0, 1.5, 0.0, 1.0]),
];

fn truth() -> Engine {
    Engine::new(EngineConfig::load(&root().join(TRUTH)).expect("truth loads")).expect("truth")
}

/// 9 loads from 35 % to 100 %, days from 268 to 303 K and 98 to 103 kPa, shuffled by `level`
/// (the baseline is level 0).
fn loads(level: usize) -> Vec<OperatingPoint> {
    (0..9)
        .map(|k| {
            let j = (4 * k + level) % 9;
            OperatingPoint {
                t_amb_k: 268.0 + 35.0 * j as f64 / 8.0,
                p_amb_kpa: 98.0 + 5.0 * ((j * 5) % 9) as f64 / 8.0,
                power_mw: DESIGN_MW * (0.35 + 0.65 * k as f64 / 8.0),
            }
        })
        .collect()
}

fn rows(truth: &Engine, health: [f64; 6], level: usize, written: &[Signal]) -> Vec<Snapshot> {
    let pts = loads(level);
    let n2 = vec![SYNC_RPM; pts.len()];
    let group = GRID[level.saturating_sub(1)].0;
    let group = if level == 0 { "baseline" } else { group };
    let csv = snapshot_csv_at_speeds(
        truth,
        &HealthParams::from_array(health),
        &pts,
        &n2,
        group,
        AVERAGING,
        700 + level as u64,
        written,
    )
    .expect("snapshots");
    read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows")
}

/// The user's md22 copy, its design point from the healthy full-load row (the metered power);
/// the air flow is the datasheet's (3 % off the truth).
fn user_model(full_load: &Snapshot) -> Engine {
    md22_from_full_load(full_load, 88.0 * 1.03)
}

fn settings() -> CalibrationSettings {
    CalibrationSettings {
        threads: Some(2),
        adapt: Some(AdaptSettings::of(AdaptStrategy::Grown)),
        ..CalibrationSettings::default()
    }
}

/// The adapted file's own error in health units, points, by parameter.
fn health_error(report: &Calibration) -> HashMap<String, f64> {
    let a = report.adaptation.as_ref().expect("adapted");
    assert_eq!(a.health_error.parts.len(), 3, "{}", a.health_error.note);
    // A read that ended on its search limit (the default health bounds) is named as such, in
    // the part and in the note: the error stated for it is a floor.
    for part in &a.health_error.parts {
        for (name, v) in &part.health {
            let (lo, hi) = HEALTH_BOUNDS;
            let tol = AT_LIMIT_FRACTION * (hi - lo);
            let on_limit = *v <= lo + tol || *v >= hi - tol;
            assert_eq!(
                on_limit,
                part.at_limit.contains(name),
                "lines {:?}: {name} {v:+.3}, at_limit {:?}",
                part.diagnosed_lines,
                part.at_limit
            );
        }
        if !part.at_limit.is_empty() {
            assert!(
                a.health_error.note.contains("search limit"),
                "{}",
                a.health_error.note
            );
        }
    }
    a.health_error
        .points
        .iter()
        .map(|(k, v)| (k.clone(), *v))
        .collect()
}

/// The baseline with `written` instruments, the user's model, and its adapted calibration.
fn calibrated(written: &[Signal]) -> (Engine, Vec<Snapshot>, Engine, Calibration, Engine) {
    let truth = truth();
    let base = rows(&truth, [0.0; 6], 0, written);
    assert_eq!(base.len(), 9, "every load of the baseline solved");
    let full = base
        .iter()
        .max_by(|a, b| a.fuel_kg_s.total_cmp(&b.fuel_kg_s))
        .expect("full load");
    let model = user_model(full);
    let cands = default_candidates(&model).expect("candidates");
    let (report, adapted) = calibrate(&model, &base, &[], cands, &settings()).expect("calibrate");
    eprintln!(
        "calibration ({} signals): RMS {:.2} → {:.2} σ, fit {:?}, {} model runs",
        written.len(),
        report.rms_before,
        report.rms_after,
        report.baseline_fit.verdict,
        report.model_runs
    );
    if let Some(a) = &report.adaptation {
        if let Some(sim) = &a.similarity {
            eprintln!("  {}", sim.describe());
        }
        if let Some(line) = &a.operating_line {
            eprintln!("  {}", line.describe());
        }
        if let Some(line) = &a.efficiency_tried {
            eprintln!("  {line}");
        }
        eprintln!(
            "  its error in health units: {:?} ({})",
            a.health_error.points, a.health_error.note
        );
        for h in &a.health_error.parts {
            let f = |m: &std::collections::BTreeMap<String, f64>| {
                m.iter()
                    .map(|(k, v)| format!("{k} {v:+.2}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            eprintln!(
                "    healthy lines {:?} read {} ({}), its σ {}",
                h.diagnosed_lines,
                f(&h.health),
                h.fit,
                f(&h.sigma)
            );
        }
    }
    (truth, base, model, report, adapted)
}

/// Each grid level's rows (other days than the baseline's) diagnosed on `adapted`.
fn grid_results(truth: &Engine, adapted: &Engine, written: &[Signal]) -> Vec<MethodResult> {
    let mut all = Vec::new();
    for (i, (_, health)) in GRID.iter().enumerate() {
        all.extend(rows(truth, *health, i + 1, written));
    }
    let report = diagnose_snapshots(adapted, &all, &diagnosis_cfg()).expect("diagnosis");
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    assert_eq!(report.groups.len(), GRID.len());
    report
        .groups
        .iter()
        .zip(&GRID)
        .map(|(g, (label, truth))| {
            assert_eq!(g.group, *label);
            let r = &g.result;
            let sigma: Vec<f64> = HEALTH_NAMES.iter().map(|n| r.sigma[*n]).collect();
            eprintln!(
                "{label:>9}: truth {truth:+.1?} est {:+.2?} ± {sigma:.2?} {:?} (residual {:.2}); {}",
                r.health.to_array(),
                r.fit_quality.verdict,
                r.fit_quality.normalised_residual,
                r.separability.statement
            );
            r.clone()
        })
        .collect()
}

#[test]
fn a_generator_of_another_map_family_is_calibrated_and_diagnosed() {
    let (truth, base, model, report, adapted) = calibrated(&FULL);
    // Every parameter is read on loads the curves did not see within a few tenths: the
    // adapted model's own error in health units stays well below the half point the wash
    // advice acts on.
    let he = health_error(&report);
    assert!(he.values().all(|v| *v <= 0.2), "{he:?}");
    // Within noise, and the inlet's constant loss read from P1 at 9 points.
    assert_eq!(
        format!("{:?}", report.baseline_fit.verdict),
        "Good",
        "{:?}",
        report.baseline_fit
    );
    assert!(
        report.rms_after <= 0.6,
        "RMS after {:.2} σ",
        report.rms_after
    );
    let law = report
        .inlet_loss_law
        .as_ref()
        .expect("the inlet law judged");
    assert_eq!(law.chosen, PressureLossLaw::Constant, "{}", law.summary());

    // The interior loads left out in turn (the whole calibration re-run on the other 8):
    // measured 2026-12-05 0.102 % mean, 0.349 % worst (the 7 interior loads; the two ends,
    // extrapolations, 0.28 / 0.82 % and 0.24 / 0.51 %); with the noise seeds 800 and 900
    // 0.102 / 0.352 % and 0.123 / 0.387 %. Asserted well inside the floors (0.3 / 1 %);
    // before the design values' identifiability was judged again at the fitted values, 0.276 /
    // 0.893 %.
    let cands = default_candidates(&model).expect("candidates");
    let mut means = Vec::new();
    let mut worst = 0.0f64;
    for k in 0..base.len() {
        let (p, _) = left_out(&model, &base, k, &[], &cands, &settings()).expect("row k");
        assert!(p.failed.is_none(), "{:?}", p.failed);
        eprintln!(
            "left out line {} ({}, GG {:.3?}): mean {:.3} %, worst {:.3} %",
            p.line,
            p.position.as_str(),
            p.gg_speed,
            p.mean_abs_pct,
            p.worst_abs_pct
        );
        if p.position == Position::Interior {
            means.push(p.mean_abs_pct);
            worst = worst.max(p.worst_abs_pct);
        }
    }
    let mean = means.iter().sum::<f64>() / means.len() as f64;
    assert!(means.len() >= 6, "{} interior loads", means.len());
    assert!(
        mean <= 0.2 && worst <= 0.6,
        "interior loads left out: mean {mean:.3} %, worst {worst:.3} %"
    );

    // The grid on other days: every level within 0.4 points on all six, every fit good.
    let results = grid_results(&truth, &adapted, &FULL);
    for (r, (label, t)) in results.iter().zip(&GRID) {
        let est = r.health.to_array();
        for p in 0..6 {
            assert!(
                (est[p] - t[p]).abs() <= 0.4,
                "{label} {}: {:+.2} against {:+.1}",
                HEALTH_NAMES[p],
                est[p],
                t[p]
            );
        }
        assert_eq!(
            format!("{:?}", r.fit_quality.verdict),
            "Good",
            "{label}: {}",
            r.fit_quality.summary
        );
    }
}

#[test]
fn with_few_instruments_a_miss_is_named_not_presented_as_good() {
    let (truth, _, _, report, adapted) = calibrated(&FEW);
    // Without the HP-turbine exit station the curves can trade the turbines' efficiencies and
    // the PT's capacity against each other: healthy loads the curves did not see read them
    // off by more than the 1σ a separable parameter may have (0.25 points; measured 1.13 / 2.35
    // / 1.56 for D_ET / D_GP / D_EP, with the noise seeds 800 and 900 0.79–2.45), which the
    // file states and the diagnosis adds to their σ, while the compressor and the HP turbine's
    // capacity stay within a few tenths.
    let he = health_error(&report);
    assert!(
        ["D_ET", "D_GP", "D_EP"].iter().all(|k| he[*k] >= 0.5),
        "{he:?}"
    );
    assert!(
        ["D_GC", "D_EC", "D_GT"].iter().all(|k| he[*k] <= 0.25),
        "{he:?}"
    );
    assert_eq!(
        format!("{:?}", report.baseline_fit.verdict),
        "Good",
        "{:?}",
        report.baseline_fit
    );
    // Without P1 the inlet's law cannot be judged: the file's is kept, and said.
    assert!(report
        .inlet_loss_law
        .as_ref()
        .is_none_or(|l| l.chosen == l.file_law));

    let results = grid_results(&truth, &adapted, &FEW);
    let mut named = 0;
    for (r, (label, t)) in results.iter().zip(&GRID) {
        let est = r.health.to_array();
        let sep = &r.separability;
        let flagged = |name: &str| {
            sep.not_identifiable.iter().any(|n| n == name)
                || sep
                    .confounded
                    .iter()
                    .any(|g| g.members.iter().any(|m| m == name))
        };
        let good = format!("{:?}", r.fit_quality.verdict) == "Good";
        for p in 0..6 {
            let err = (est[p] - t[p]).abs();
            let name = HEALTH_NAMES[p];
            if sep.separable.iter().any(|n| n == name) {
                // What the diagnosis calls separable is read right.
                assert!(
                    err <= 0.5,
                    "{label} {name} (separable): {:+.2} against {:+.1}",
                    est[p],
                    t[p]
                );
            } else if err > 0.5 {
                // A parameter further off is named (or the fit is not good).
                assert!(
                    flagged(name) || !good,
                    "{label} {name}: {:+.2} against {:+.1}, neither named nor doubted: {}",
                    est[p],
                    t[p],
                    sep.statement
                );
                named += 1;
            }
        }
        // The compressor is what these signals carry: D_EC separable wherever the compressor
        // runs on its healthy line. Fouling moves it off, where the borrowed map's slope along
        // its speed lines is not known ([adaptation.offline_shape]): there D_EC's σ widens
        // (0.27 and 0.47 points at fouling of 2 and 4) and the read lies within it. D_GC's σ
        // has the snapshot inputs' noise in it (one T1 reading's 0.5 K is 0.09 % of corrected
        // speed): about 0.3 points, at the separability limit, and the read within it.
        if t[0] == 0.0 {
            assert!(
                sep.separable.iter().any(|n| n == "D_EC"),
                "{label}: D_EC not separable: {}",
                sep.statement
            );
        } else {
            let ec = r.sigma["D_EC"];
            assert!(
                ec <= 0.6 && (est[1] - t[1]).abs() <= ec,
                "{label}: D_EC {:+.2} ± {ec:.2} against {:+.1}",
                est[1],
                t[1]
            );
        }
        let gc = r.sigma["D_GC"];
        assert!(
            gc <= 0.5 && (est[0] - t[0]).abs() <= gc,
            "{label}: D_GC {:+.2} ± {gc:.2} against {:+.1}",
            est[0],
            t[0]
        );
    }
    eprintln!("{named} estimate(s) beyond 0.5 points, each named");
}
