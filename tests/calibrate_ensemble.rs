//! `gtwatch calibrate --ensemble` and the snapshot diagnosis that reads with it, end to end as a
//! user runs them: the calibration writes three more calibrations of the unit beside `--out`
//! (each on the baseline with an interleaved third of its interior loads left out), lists them
//! in the written file's `[adaptation.ensemble]`, and `gtwatch diagnose` on that file reads each
//! group with them too and states the spread and the σ with it. The true unit is the
//! reference file with its design moved (`calibrate_twin::true_unit`); what the spread shows on
//! a unit of another make is measured in `foreign_engine::an_ensemble_states_what_the_baseline_leaves_open`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::calibrate_twin::true_unit;
use gtwatch::calibrate::synthetic::{load_sweep, snapshot_csv_of, OperatingPoint, WRITTEN};
use gtwatch::engine::Engine;
use gtwatch::health::{HealthParams, HEALTH_NAMES};
use std::path::Path;
use std::process::{Command, Output};

/// The degraded group's truth: compressor fouling and HP-turbine wear, points.
const DEGRADED: [f64; 6] = [2.0, 0.8, -0.6, 0.9, 0.0, 0.0];

fn gtwatch(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(args)
        .output()
        .expect("run gtwatch")
}

/// `gtwatch diagnose --method steady` of `input` by its `test` column on `engine`, with
/// `--json` when `json`.
fn diagnose(engine: &Path, input: &Path, json: bool) -> Output {
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "diagnose".as_ref(),
        "--engine".as_ref(),
        engine.as_os_str(),
        "--input".as_ref(),
        input.as_os_str(),
        "--group-by".as_ref(),
        "test".as_ref(),
        "--method".as_ref(),
        "steady".as_ref(),
    ];
    if json {
        args.push("--json".as_ref());
    }
    gtwatch(&args)
}

/// The healthy baseline (9 loads) and the degraded unit at the same loads on other days.
fn files(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let file = Engine::reference().expect("reference");
    let truth = true_unit(&file);
    let loads = load_sweep(&file, 9);
    let healthy = snapshot_csv_of(
        &truth,
        &HealthParams::HEALTHY,
        &loads,
        "baseline",
        25.0,
        41,
        &WRITTEN,
    )
    .expect("baseline");
    let later: Vec<OperatingPoint> = loads
        .iter()
        .map(|p| OperatingPoint {
            t_amb_k: p.t_amb_k - 4.0,
            ..*p
        })
        .collect();
    let degraded = snapshot_csv_of(
        &truth,
        &HealthParams::from_array(DEGRADED),
        &later,
        "degraded",
        25.0,
        42,
        &WRITTEN,
    )
    .expect("degraded");
    let (b, d) = (dir.join("baseline.csv"), dir.join("degraded.csv"));
    std::fs::write(&b, healthy).expect("write");
    std::fs::write(&d, degraded).expect("write");
    (b, d)
}

#[test]
fn an_ensemble_is_written_and_read_with() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (baseline, degraded) = files(dir.path());
    let engine = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/engine.toml");
    let out = dir.path().join("unit.toml");
    let cal = gtwatch(&[
        "calibrate".as_ref(),
        "--engine".as_ref(),
        engine.as_os_str(),
        "--input".as_ref(),
        baseline.as_os_str(),
        "--adapt".as_ref(),
        "--ensemble".as_ref(),
        "--threads".as_ref(),
        "2".as_ref(),
        "--json".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(
        cal.status.success(),
        "{}",
        String::from_utf8_lossy(&cal.stderr)
    );
    let doc: serde_json::Value = serde_json::from_slice(&cal.stdout).expect("one JSON document");
    let members = doc["ensemble"].as_array().expect("ensemble");
    assert_eq!(members.len(), 3, "{members:?}");
    // The interior lines (3..=9 of lines 2..=10) dealt into three parts, the ends in every one.
    let mut left: Vec<u64> = members
        .iter()
        .flat_map(|m| m["left_out_lines"].as_array().expect("lines").clone())
        .map(|l| l.as_u64().expect("line"))
        .collect();
    left.sort_unstable();
    assert_eq!(left, (3..=9).collect::<Vec<u64>>());
    for (j, m) in members.iter().enumerate() {
        let f = m["file"].as_str().expect("file");
        assert!(f.ends_with(&format!("unit.part{}.toml", j + 1)), "{f}");
        let text = std::fs::read_to_string(f).expect("member written");
        assert!(
            text.starts_with("# One of 3 calibrations of an ensemble"),
            "{text:.200}"
        );
        assert!(
            !text.contains("[adaptation.ensemble]"),
            "a member lists no ensemble"
        );
    }
    let written = std::fs::read_to_string(&out).expect("written");
    assert!(written.contains("[adaptation.ensemble]"), "{written}");

    let diag = diagnose(&out, &degraded, true);
    assert!(
        diag.status.success(),
        "{}",
        String::from_utf8_lossy(&diag.stderr)
    );
    let doc: serde_json::Value = serde_json::from_slice(&diag.stdout).expect("one JSON document");
    let g = &doc["groups"][0];
    let e = &g["ensemble"];
    assert_eq!(e["read_by"], 3, "{e}");
    for (k, name) in HEALTH_NAMES.iter().enumerate() {
        let read = g["health"][name].as_f64().expect("read");
        let sigma = g["sigma"][name].as_f64().expect("sigma");
        let spread = e["spread"][name].as_f64().expect("spread");
        let with = e["sigma_with_spread"][name]
            .as_f64()
            .expect("σ with spread");
        assert!(
            spread >= 0.0 && with >= sigma - 1e-12,
            "{name}: {spread} {with} {sigma}"
        );
        assert!((with - sigma.hypot(spread)).abs() < 1e-9, "{name}");
        // A unit of the model's own map family: the members agree, and the read is right.
        assert!(spread < 0.2, "{name}: spread {spread}");
        assert!(
            (read - DEGRADED[k]).abs() < 0.3,
            "{name}: {read} for {}",
            DEGRADED[k]
        );
    }
    // The text report says it.
    let text = diagnose(&out, &degraded, false);
    let said = String::from_utf8_lossy(&text.stdout);
    assert!(
        said.contains("calibration spread (the reads of 3 other"),
        "{said}"
    );

    // A member file gone: the diagnosis names it rather than reading without it.
    std::fs::remove_file(dir.path().join("unit.part2.toml")).expect("remove");
    let gone = diagnose(&out, &degraded, false);
    assert!(!gone.status.success());
    let err = String::from_utf8_lossy(&gone.stderr);
    assert!(
        err.contains("unit.part2.toml") && err.contains("[adaptation.ensemble]"),
        "{err}"
    );
}

#[test]
fn an_ensemble_needs_an_adaptation_a_file_and_enough_loads() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (baseline, _) = files(dir.path());
    let engine = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/engine.toml");
    let out = dir.path().join("unit.toml");
    let no_adapt = gtwatch(&[
        "calibrate".as_ref(),
        "--engine".as_ref(),
        engine.as_os_str(),
        "--input".as_ref(),
        baseline.as_os_str(),
        "--ensemble".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(!no_adapt.status.success());
    assert!(String::from_utf8_lossy(&no_adapt.stderr).contains("--adapt"));
    // Seven rows: five interior, fewer than two per part.
    let text = std::fs::read_to_string(&baseline).expect("read");
    let short: String = text.lines().take(8).map(|l| format!("{l}\n")).collect();
    let few = dir.path().join("few.csv");
    std::fs::write(&few, short).expect("write");
    let refused = gtwatch(&[
        "calibrate".as_ref(),
        "--engine".as_ref(),
        engine.as_os_str(),
        "--input".as_ref(),
        few.as_os_str(),
        "--adapt".as_ref(),
        "--ensemble".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("the baseline has 7"), "{err}");
    assert!(!out.exists(), "nothing written");
}
