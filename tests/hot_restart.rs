//! Restarts from a warm, turning engine (issue 22 item 4). `Scenario::operations` runs a start to
//! base load, a normal stop, an aborted start (trip) and a hot restart 4 minutes after the trip,
//! with the power turbine still coasting (~950 rpm) and, on an engine with heat soak, the hot
//! section still hot. Five such logs (noise seeds 1–5, each its own degraded truth) are replayed
//! with `gtwatch replay` and the shipped config: every completed start, cold or hot, gets one
//! Method B result, fit `good`, within 0.3 points of its truth on every parameter.
//!
//! The second test does the same on an engine with the `heat_soak` effect adopted, where a
//! model started cold reads the warm metal as turbine degradation.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use gtwatch::engine::simulation::run_scenario;
use gtwatch::engine::{Engine, Scenario};
use gtwatch::health::{HealthParams, HEALTH_NAMES};
use std::path::Path;
use std::process::Command;

/// Each log's truth: a different, moderately degraded engine.
fn truth(seed: u64) -> HealthParams {
    let s = seed as f64;
    HealthParams {
        D_GC: 0.5 + 0.6 * s,
        D_EC: 0.3 + 0.2 * s,
        D_GT: 1.2 - 0.15 * s,
        D_ET: 0.2 + 0.15 * s,
        D_GP: 0.6 - 0.1 * s,
        D_EP: 0.2 + 0.1 * s,
    }
}

/// One operations log per seed, a day apart, with the given engine; written as one CSV.
fn write_log(engine: &Engine, seeds: &[u64], csv: &Path) {
    let runs = seeds
        .iter()
        .map(|&seed| {
            let model = engine.model(&truth(seed));
            let (samples, _) =
                run_scenario(&model, &Scenario::operations(engine.cfg())).expect("runs");
            (samples, seed)
        })
        .collect();
    common::write_daily_log(engine, runs, csv);
}

fn run(args: &[&str], cfg: &Path) -> serde_json::Value {
    serde_json::from_slice(&common::gtwatch_ok(args, cfg)).expect("one JSON document")
}

/// Replays the log of `seeds` on `engine_file` (None: the reference engine) and checks every
/// completed start's Method B result against its truth.
fn replay_and_check(engine_file: Option<&str>, seeds: &[u64]) {
    let dir = tempfile::tempdir().expect("tempdir");
    let engine = match engine_file {
        None => Engine::reference().expect("engine"),
        Some(text) => {
            let p = dir.path().join("engine.toml");
            std::fs::write(&p, text).expect("engine file");
            let cfg = gtwatch::engine::config::EngineConfig::load(&p).expect("engine file loads");
            Engine::new(cfg).expect("engine builds")
        }
    };
    let csv = dir.path().join("ops.csv");
    write_log(&engine, seeds, &csv);
    let db = dir.path().join("h.db");
    let mut cfg = common::replay_config_text(&db);
    if engine_file.is_some() {
        cfg = cfg.replace(
            "# engine_model = \"engine.toml\"",
            "engine_model = \"engine.toml\"",
        );
        assert!(cfg.contains("\nengine_model = \"engine.toml\""));
    }
    let cfg_path = dir.path().join("gtwatch.toml");
    std::fs::write(&cfg_path, cfg).expect("config");
    let replay = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["replay", "--config"])
        .arg(&cfg_path)
        .arg(&csv)
        .output()
        .expect("replay runs");
    assert!(
        replay.status.success(),
        "replay: {}",
        String::from_utf8_lossy(&replay.stderr)
    );

    let segments = run(&["segments", "--format", "json"], &cfg_path);
    let segments = segments
        .get("segments")
        .unwrap_or(&segments)
        .as_array()
        .expect("segments array")
        .clone();
    // Per log: the first start (cold), the aborted start, the hot restart.
    assert_eq!(segments.len(), 3 * seeds.len(), "{segments:#?}");
    let completed: Vec<&serde_json::Value> = segments
        .iter()
        .filter(|s| s["outcome"] == "completed")
        .collect();
    assert_eq!(completed.len(), 2 * seeds.len(), "{segments:#?}");
    let hot = completed
        .iter()
        .filter(|s| s["hot_restart"] == true)
        .count();
    assert_eq!(hot, seeds.len(), "one hot restart per log: {segments:#?}");

    let rows = run(&["history", "--format", "json", "--method", "B"], &cfg_path);
    let rows = rows.as_array().expect("array");
    assert_eq!(
        rows.len(),
        completed.len(),
        "one Method B result per completed start, hot or cold: {rows:#?}"
    );
    let mut worst = 0.0f64;
    for (i, row) in rows.iter().enumerate() {
        let seed = seeds[i / 2];
        let kind = if i % 2 == 0 { "cold" } else { "hot" };
        assert_eq!(
            row["fit_quality"], "good",
            "seed {seed} {kind} start: {row}"
        );
        let t = truth(seed).to_array();
        for (j, n) in HEALTH_NAMES.iter().enumerate() {
            let v = row["health"][n].as_f64().expect("value");
            worst = worst.max((v - t[j]).abs());
            assert!(
                (v - t[j]).abs() <= 0.3,
                "seed {seed} {kind} start {n}: {v:.3} vs truth {:.3}",
                t[j]
            );
        }
    }
    println!(
        "{} starts ({} hot), worst |error| {worst:.3} points",
        rows.len(),
        seeds.len()
    );
}

#[test]
fn hot_restarts_of_the_operations_log_fit_like_cold_starts() {
    replay_and_check(None, &[1, 2, 3, 4, 5]);
}

#[test]
fn hot_restart_with_warm_metal_fits_on_a_heat_soak_engine() {
    let engine = format!(
        "{}\n[effects.heat_soak]\nua_kw_per_k = 1.5\ntau_s = 400.0\n",
        include_str!("../config/engine.toml")
    );
    replay_and_check(Some(&engine), &[2]);
}
