//! Acceptance at small size: a log of three `simulate` start-ups with known, growing
//! degradation, one a day, replayed with `gtwatch replay` and the shipped config → one Method B
//! result per start-up within 0.5 points of its truth on every parameter, in
//! `gtwatch history --format json`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use gtwatch::engine::simulation::run_scenario;
use gtwatch::engine::{Engine, Scenario};
use gtwatch::health::{HealthParams, HEALTH_NAMES};
use std::process::Command;

fn truth(day: usize) -> HealthParams {
    let d = day as f64;
    HealthParams {
        D_GC: 1.0 + 1.0 * d,
        D_EC: 0.4 + 0.35 * d,
        D_GT: 0.5 + 0.2 * d,
        D_ET: 0.3 + 0.2 * d,
        D_GP: 0.2 + 0.1 * d,
        D_EP: 0.3 + 0.1 * d,
    }
}

#[test]
fn replayed_daily_startups_each_get_a_method_b_result_near_truth() {
    let dir = tempfile::tempdir().expect("tempdir");
    let engine = Engine::reference().expect("engine");
    let days = 3;
    let runs = (0..days)
        .map(|day| {
            let model = engine.model(&truth(day));
            let (samples, _) =
                run_scenario(&model, &Scenario::startup(engine.cfg())).expect("runs");
            (samples, 40 + day as u64)
        })
        .collect();
    let csv = dir.path().join("days.csv");
    common::write_daily_log(&engine, runs, &csv);
    let db = dir.path().join("h.db");
    let cfg = common::replay_config_text(&db);
    let cfg_path = dir.path().join("gtwatch.toml");
    std::fs::write(&cfg_path, cfg).expect("config");

    let bin = env!("CARGO_BIN_EXE_gtwatch");
    let out = Command::new(bin)
        .args(["replay", "--config"])
        .arg(&cfg_path)
        .arg(&csv)
        .output()
        .expect("replay runs");
    assert!(
        out.status.success(),
        "replay: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = Command::new(bin)
        .args(["history", "--format", "json", "--method", "B", "--config"])
        .arg(&cfg_path)
        .output()
        .expect("history runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    let rows = doc.as_array().expect("array");
    assert_eq!(rows.len(), days, "{doc:#}");
    for (day, row) in rows.iter().enumerate() {
        assert_eq!(row["method"], "B");
        let start_ms = row["start_ms"].as_i64().expect("start_ms");
        assert_eq!(
            start_ms,
            1_700_000_010_000 + 86_400_000 * day as i64,
            "{row}"
        );
        assert!(row["start_utc"]
            .as_str()
            .expect("utc")
            .starts_with("2023-11-"));
        assert!(row["fit_quality"].is_string());
        assert!(row["wash_id_before"].is_null());
        let t = truth(day).to_array();
        for (i, n) in HEALTH_NAMES.iter().enumerate() {
            let v = row["health"][n].as_f64().expect("value");
            assert!((v - t[i]).abs() < 0.5, "day {day} {n}: {v} vs {}", t[i]);
            assert!(row["sigma"][n].as_f64().is_some_and(|s| s > 0.0), "{row}");
        }
    }
}
