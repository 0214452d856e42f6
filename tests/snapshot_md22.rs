//! Snapshot diagnosis acceptance on the second engine (issue 10): `config/engine_md22.toml`, a
//! mechanical-drive unit whose PT speed follows a cube-law load, instrumented as such units are
//! — shaft torque instead of electrical power, no HPT-exit pressure (P34) — diagnosed from steady
//! snapshots at 9 loads for each of 40 degradation levels. Compressor (D_GC, D_EC) and HP-turbine
//! (D_GT, D_ET) degradation grow separately and together; the power turbine stays healthy.
//!
//! Checks: the estimates of the four compressor and HP-turbine parameters rank the truth over
//! the levels where each is degraded (Spearman ρ ≥ 0.98 per parameter) and every level lies
//! within 0.3 points of the truth; the diagnosis states that this instrument set separates D_EC
//! and D_GT, and gives D_GC and D_ET the σ the inputs' one-reading noise leaves them (0.3 and
//! about 1 point). The PT parameters are healthy in the truth and are fitted, not assumed: without P34 the
//! HPT efficiency trades against them (D_ET has the largest 1σ of the four, 0.1–0.2 points at
//! `AVERAGING` = 25, and then misses 0.3 points on 2 of 40 levels, by up to 0.48).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::calibrate::synthetic::{snapshot_csv_of, OperatingPoint};
use gtwatch::diagnosis::snapshot::{diagnose_snapshots, read_snapshots};
use gtwatch::diagnosis::DiagnosisConfig;
use gtwatch::engine::{Engine, EngineConfig};
use gtwatch::health::{HealthParams, HEALTH_NAMES};
use gtwatch::signals::Signal;
use std::collections::HashMap;
use std::path::PathBuf;

use crate::ranking;
use ranking::spearman;

fn md22() -> Engine {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/engine_md22.toml");
    Engine::new(EngineConfig::load(&path).expect("md22 loads")).expect("md22 calibrates")
}

/// Samples behind each averaged row: the instrument noise of a row is the one-sample σ over
/// √100, a 100-s steady window at 1 Hz (performance-test points are 10–15 min averages,
/// historian hourly averages hold 3600 samples; the instruments' bias does not average out, and
/// there is none here).
const AVERAGING: f64 = 100.0;

/// What the unit measures besides the inputs (T1, ambient pressure, n2, fuel flow).
const INSTRUMENTS: [Signal; 7] = [
    Signal::N1,
    Signal::P1,
    Signal::T2,
    Signal::P2,
    Signal::T34,
    Signal::T4,
    Signal::Torque,
];

/// 9 loads from 40 % to 100 % of design power, ambient 275–300 K and 99–102 kPa (each level
/// sees its own weather: the rows are shuffled through the ambient range by the level index).
fn loads(level: usize, design_mw: f64) -> Vec<OperatingPoint> {
    (0..9)
        .map(|k| {
            let j = (k + 4 * level) % 9;
            OperatingPoint {
                t_amb_k: 275.0 + 25.0 * j as f64 / 8.0,
                p_amb_kpa: 99.0 + 3.0 * ((j * 5) % 9) as f64 / 8.0,
                power_mw: design_mw * (0.4 + 0.6 * k as f64 / 8.0),
            }
        })
        .collect()
}

/// Level `i` of 40: levels 0–13 compressor fouling alone (D_GC up to 4, D_EC 0.4·D_GC), 14–27
/// HP-turbine wear alone (D_GT to −2, i.e. flow capacity up, D_ET up to 3), 28–39 both together
/// at magnitudes half a step between the single-component ones, so no two degraded levels tie.
fn truth(i: usize) -> [f64; 6] {
    let path = i / 14;
    let j = (i % 14) as f64 + if path == 2 { 0.5 } else { 1.0 };
    let c = [4.0 * j / 14.0, 1.6 * j / 14.0];
    let t = [-2.0 * j / 14.0, 3.0 * j / 14.0];
    match path {
        0 => [c[0], c[1], 0.0, 0.0, 0.0, 0.0],
        1 => [0.0, 0.0, t[0], t[1], 0.0, 0.0],
        _ => [c[0], c[1], t[0], t[1], 0.0, 0.0],
    }
}

#[test]
fn torque_instrumented_mechanical_drive_ranks_and_sizes_gg_degradation() {
    let engine = md22();
    let design_mw = engine.cfg().design.power_mw;
    let mut csv = String::new();
    let levels = 40;
    for i in 0..levels {
        let text = snapshot_csv_of(
            &engine,
            &HealthParams::from_array(truth(i)),
            &loads(i, design_mw),
            &format!("level{i:02}"),
            AVERAGING,
            1000 + i as u64,
            &INSTRUMENTS,
        )
        .expect("snapshots");
        let body = if i == 0 {
            text.as_str()
        } else {
            text.split_once('\n').map_or("", |(_, b)| b)
        };
        csv.push_str(body);
    }
    assert!(csv.lines().next().is_some_and(|h| h.contains("torque_knm")
        && !h.contains("p34_kpa")
        && !h.contains("power_mw")));
    let rows = read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
    assert_eq!(rows.len(), 9 * levels);
    // The PT speed follows the load: 40 % load runs the PT at 0.4^(1/3) = 74 % speed.
    let n2: Vec<f64> = rows.iter().take(9).map(|r| r.n2_rpm).collect();
    let (lo, hi) = n2
        .iter()
        .fold((f64::MAX, 0.0f64), |(l, h), &x| (l.min(x), h.max(x)));
    assert!(lo < 0.76 * hi, "PT speeds {n2:?}");

    let cfg = DiagnosisConfig {
        max_model_runs: 1500,
        threads: Some(2),
        ..DiagnosisConfig::default()
    };
    let report = diagnose_snapshots(&engine, &rows, &cfg).expect("diagnosis");
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    assert_eq!(report.groups.len(), levels);

    let est: Vec<[f64; 6]> = report
        .groups
        .iter()
        .map(|g| g.result.health.to_array())
        .collect();
    let sep = &report.groups[levels - 1].result.separability;
    eprintln!("separability: {}", sep.statement);
    let mut worst = [0.0f64; 6];
    for (i, e) in est.iter().enumerate() {
        let t = truth(i);
        for p in 0..6 {
            worst[p] = worst[p].max((e[p] - t[p]).abs());
        }
        eprintln!(
            "level {i:2} truth {:?} est {:.2?} quality {:?} sigma {:.2?}",
            t,
            e,
            report.groups[i].result.fit_quality.verdict,
            report.groups[i].result.sigma.values().collect::<Vec<_>>()
        );
    }
    // Ranking: over the levels where the parameter is degraded (its own sweep and the combined
    // one, 26–28 distinct values). Where it is held at zero while the other component degrades,
    // 14 tied truths leave nothing to rank: the 0.3-point bound checks those levels instead.
    for p in 0..4 {
        let degraded: Vec<usize> = (0..levels).filter(|&i| truth(i)[p] != 0.0).collect();
        let e: Vec<f64> = degraded.iter().map(|&i| est[i][p]).collect();
        let t: Vec<f64> = degraded.iter().map(|&i| truth(i)[p]).collect();
        let rho = spearman(&e, &t);
        let rho_all = spearman(
            &est.iter().map(|e| e[p]).collect::<Vec<_>>(),
            &(0..levels).map(|i| truth(i)[p]).collect::<Vec<_>>(),
        );
        eprintln!(
            "{}: Spearman {rho:.4} over its {} degraded levels ({rho_all:.4} over all 40, ties \
             included), worst error {:.3} points",
            HEALTH_NAMES[p],
            degraded.len(),
            worst[p]
        );
        assert!(rho >= 0.98, "{}: Spearman {rho}", HEALTH_NAMES[p]);
        assert!(
            worst[p] <= 0.3,
            "{}: worst error {} points",
            HEALTH_NAMES[p],
            worst[p]
        );
    }
    // The compressor's efficiency and the HP turbine's capacity are what this instrument set
    // separates. D_GC and D_ET are read within 0.3 points above, but their σ carries one
    // reading's noise of the inputs (T1 0.5 K, the fuel meter's 0.5 %; these rows average
    // 100): D_GC just over the 0.25-point limit, D_ET (no P34 here, so fuel and turbine
    // efficiency trade) about a point.
    for name in ["D_EC", "D_GT"] {
        assert!(
            sep.separable.iter().any(|n| n == name),
            "{name} should be separable: {}",
            sep.statement
        );
    }
    let sigma = &report.groups[levels - 1].result.sigma;
    assert!(sigma["D_GC"] <= 0.35, "D_GC σ {}", sigma["D_GC"]);
    assert!(sigma["D_ET"] <= 1.3, "D_ET σ {}", sigma["D_ET"]);
}
