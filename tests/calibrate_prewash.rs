//! `gtwatch calibrate --prewash-group` end to end, as a user runs it: one snapshot file holding
//! a healthy baseline taken after a compressor wash and rows of the same unit taken just before
//! it, at a fouling nobody measured. The calibration must find that fouling, keep the healthy
//! baseline healthy, say at what it ran the pre-wash rows (report, JSON, the written file's
//! header), and refuse a group the file does not hold. The true unit is the reference file with
//! its design moved (`calibrate_twin::true_unit`); how the rows inform an adaptation to a unit
//! of another make is measured in `foreign_engine::rows_before_a_wash_inform_the_grid`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::calibrate_twin::true_unit;
use gtwatch::calibrate::synthetic::{load_sweep, snapshot_csv_of, OperatingPoint, WRITTEN};
use gtwatch::diagnosis::snapshot::{diagnose_snapshots, read_snapshots};
use gtwatch::diagnosis::DiagnosisConfig;
use gtwatch::engine::{Engine, EngineConfig};
use gtwatch::health::HealthParams;
use std::collections::HashMap;

/// The fouling of the rows before the wash: compressor flow capacity and efficiency, points.
const FOULED: [f64; 6] = [2.0, 0.8, 0.0, 0.0, 0.0, 0.0];

/// A snapshot file of the true unit: 7 healthy rows (group `after`) and the same loads on
/// other days at health `before` (group `before`), the pre-wash rows first.
fn snapshots(dir: &std::path::Path, before_health: [f64; 6]) -> std::path::PathBuf {
    let file = Engine::reference().expect("reference");
    let truth = true_unit(&file);
    let after = load_sweep(&file, 7);
    // Before the wash: other days, the same loads.
    let before: Vec<OperatingPoint> = after
        .iter()
        .rev()
        .map(|p| OperatingPoint {
            t_amb_k: p.t_amb_k + 3.0,
            ..*p
        })
        .collect();
    let healthy = snapshot_csv_of(
        &truth,
        &HealthParams::HEALTHY,
        &after,
        "after",
        25.0,
        31,
        &WRITTEN,
    )
    .expect("baseline");
    let fouled = snapshot_csv_of(
        &truth,
        &HealthParams::from_array(before_health),
        &before,
        "before",
        25.0,
        32,
        &WRITTEN,
    )
    .expect("pre-wash rows");
    let input = dir.join("snapshots.csv");
    // One file, one header: the pre-wash rows first, as a historian export would list them.
    let body: String = healthy.lines().skip(1).map(|l| format!("{l}\n")).collect();
    std::fs::write(&input, format!("{fouled}{body}")).expect("write");
    input
}

/// `gtwatch calibrate` of `input` (engine.toml) with `group` the pre-wash rows, writing `out`.
fn run(input: &std::path::Path, group: &str, out: &std::path::Path) -> std::process::Output {
    let root = env!("CARGO_MANIFEST_DIR");
    std::process::Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["calibrate", "--engine"])
        .arg(format!("{root}/config/engine.toml"))
        .arg("--input")
        .arg(input)
        .args(["--group-by", "test", "--prewash-group", group, "--out"])
        .arg(out)
        .args(["--threads", "2", "--json"])
        .output()
        .expect("run gtwatch")
}

#[test]
fn cli_finds_the_fouling_a_wash_removed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = snapshots(dir.path(), FOULED);
    let out = dir.path().join("unit.toml");
    let run = |group: &str| run(&input, group, &out);
    let started = std::time::Instant::now();
    let done = run("before");
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    eprintln!(
        "calibrate --prewash-group: {:.1} s",
        started.elapsed().as_secs_f64()
    );
    let doc: serde_json::Value = serde_json::from_slice(&done.stdout).expect("one JSON document");
    let pw = &doc["calibration"]["prewash"];
    eprintln!("{pw:#}");
    assert_eq!(pw["group"], "before");
    assert_eq!(pw["rows"], 7);
    assert_eq!(pw["converged"], true, "{pw}");
    let f = &pw["fouling"];
    let (d_gc, d_ec) = (
        f["d_gc"].as_f64().expect("d_gc"),
        f["d_ec"].as_f64().expect("d_ec"),
    );
    assert!(
        (d_gc - FOULED[0]).abs() <= 0.15,
        "D_GC {d_gc:.3} for {}",
        FOULED[0]
    );
    assert!(
        (d_ec - FOULED[1]).abs() <= 0.1,
        "D_EC {d_ec:.3} for {}",
        FOULED[1]
    );
    assert_eq!(
        doc["calibration"]["baseline_fit"]["verdict"], "good",
        "{doc}"
    );
    // The written file says the pre-wash rows were not healthy, and at what they were run.
    let text = std::fs::read_to_string(&out).expect("written");
    let head: String = text.lines().take(3).collect::<Vec<_>>().join("\n");
    assert!(
        head.contains("14 operating point(s)")
            && head.contains("7 of group before taken before a wash")
            && head.contains(&format!("D_GC {d_gc:+.2}")),
        "{head}"
    );
    // On the file written, the healthy rows read healthy and the pre-wash rows their fouling.
    let calibrated = Engine::new(EngineConfig::load(&out).expect("loads")).expect("builds");
    let rows = read_snapshots(
        std::fs::read_to_string(&input).expect("read").as_bytes(),
        &HashMap::new(),
        Some("test"),
    )
    .expect("rows");
    let cfg = DiagnosisConfig {
        threads: Some(2),
        ..DiagnosisConfig::default()
    };
    let report = diagnose_snapshots(&calibrated, &rows, &cfg).expect("diagnosis");
    for g in &report.groups {
        let h = g.result.health.to_array();
        let want = if g.group == "before" {
            FOULED
        } else {
            [0.0; 6]
        };
        eprintln!("{}: {h:+.3?} {:?}", g.group, g.result.fit_quality.verdict);
        for p in 0..6 {
            assert!((h[p] - want[p]).abs() <= 0.3, "{} {p}: {h:?}", g.group);
        }
    }
    assert_eq!(report.groups.len(), 2);
    // A group the file does not hold is refused by name, and nothing is written.
    std::fs::remove_file(&out).expect("remove");
    let refused = run("bfore");
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(
        err.contains("--prewash-group bfore: no row of the input is in that group"),
        "{err}"
    );
    assert!(!out.exists());
}

/// Rows labelled "before the wash" that differ from the baseline by more than compressor
/// fouling (here the HP turbine too, as rows from long before a baseline taken after a
/// turbine overhaul would): run at a compressor fouling alone they cannot be fitted, so the
/// calibration on the healthy rows is kept, and the report says so.
#[test]
fn cli_keeps_the_baseline_when_the_rows_before_a_wash_do_not_fit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = snapshots(dir.path(), [2.0, 0.8, -2.0, 2.0, 0.0, 0.0]);
    let out = dir.path().join("unit.toml");
    let done = run(&input, "before", &out);
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    let doc: serde_json::Value = serde_json::from_slice(&done.stdout).expect("one JSON document");
    let cal = &doc["calibration"];
    let pw = &cal["prewash"];
    eprintln!("{pw:#}");
    assert!(pw["fouling"].is_null(), "{pw}");
    let why = pw["stopped"].as_str().expect("a reason");
    assert!(why.contains("do not fit beside the baseline"), "{why}");
    // The healthy rows' calibration: its residuals are the 7 healthy points'.
    assert_eq!(cal["points"].as_array().expect("points").len(), 7, "{cal}");
    assert_eq!(cal["baseline_fit"]["verdict"], "good", "{cal}");
    let text = std::fs::read_to_string(&out).expect("written");
    let head: String = text.lines().take(3).collect::<Vec<_>>().join("\n");
    assert!(
        head.contains("7 healthy operating point(s)")
            && head.contains("the 7 rows of group before (before a wash) left out"),
        "{head}"
    );
}
