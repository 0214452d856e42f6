//! Any power-turbine load (issue 22 item 2), through the binary as a user runs it:
//! - `steady --n2-rpm` holds the given PT speed exactly in every load mode (generator, load law,
//!   table, measured speed), and without it a load curve sets the speed;
//! - Method B on a unit whose load the engine file does not know: the truth runs `config/
//!   engine_md22.toml` on a tabulated load curve (not the file's cube law), the diagnosis runs the
//!   same file with `[load] mode = "measured_speed"` (the PT follows the measured speed). It must
//!   find the truth's health and fit `good`; the file with the wrong (cube-law) load must not
//!   claim a good fit. A second truth holds the PT at a set speed (a pitch-controlled load) and
//!   is diagnosed the same way.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `config/engine_md22.toml` with its `[load]` section replaced by `load` and its maps found
/// from `dir`, written to `dir/name`.
fn md22_with_load(dir: &Path, name: &str, load: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("config/engine_md22.toml")).expect("md22");
    let original = "mode = \"load_law\"\nexponent = 3.0\n";
    assert!(text.contains(original), "md22's [load] section moved");
    let maps = root().join("config/maps");
    let text = text
        .replace(original, load)
        .replace("\"maps/", &format!("\"{}/", maps.display()));
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write engine file");
    path
}

/// A tabulated load absorbing more than the cube law at part speed (a propeller curve of
/// another pitch): nothing in the engine file describes it.
const TABLE_LOAD: &str = "mode = \"table\"\nspeed_rpm = [2000.0, 3000.0, 4000.0, 5000.0, \
                          6000.0, 7000.0]\npower_mw = [1.5, 5.0, 10.5, 17.0, 24.0, 31.0]\n";
const MEASURED: &str = "mode = \"measured_speed\"\n";
const LAW: &str = "mode = \"load_law\"\nexponent = 3.0\n";
const GENERATOR: &str = "mode = \"generator\"\n";

fn gtwatch(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(args)
        .output()
        .expect("run gtwatch");
    assert!(
        out.status.success(),
        "gtwatch {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8")
}

fn json(args: &[&str]) -> serde_json::Value {
    serde_json::from_str(&gtwatch(args)).expect("one JSON document")
}

#[test]
fn steady_holds_a_given_pt_speed_in_every_load_mode() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, load) in [
        ("gen.toml", GENERATOR),
        ("law.toml", LAW),
        ("table.toml", TABLE_LOAD),
        ("measured.toml", MEASURED),
    ] {
        let engine = md22_with_load(dir.path(), name, load);
        let e = engine.to_str().expect("path");
        let held = json(&[
            "steady",
            "--engine",
            e,
            "--fuel-kg-s",
            "1.0",
            "--n2-rpm",
            "5123",
            "--json",
        ]);
        assert_eq!(held["n2_rpm"].as_f64(), Some(5123.0), "{name}: {held}");
        let free = json(&["steady", "--engine", e, "--fuel-kg-s", "1.0", "--json"]);
        let n2 = free["n2_rpm"].as_f64().expect("n2");
        let power = free["power_mw"].as_f64().expect("power");
        match load {
            // A load curve sets the speed: the engine's power equals the curve's there.
            LAW | TABLE_LOAD => {
                let curve = free["load_power_mw"].as_f64().expect("load power");
                assert!((power / curve - 1.0).abs() < 1e-6, "{name}: {free}");
                assert!(
                    (n2 - 6500.0).abs() > 50.0,
                    "{name}: the load moved the PT: {n2}"
                );
                let at_held = held["load_power_mw"].as_f64().expect("load power");
                let engine_at_held = held["power_mw"].as_f64().expect("power");
                assert!((at_held - engine_at_held).abs() > 0.1, "{name}: {held}");
            }
            // Generator and measured speed: the design speed, no load curve.
            _ => {
                assert_eq!(n2, 6500.0, "{name}");
                assert!(free["load_power_mw"].is_null(), "{name}: {free}");
            }
        }
    }
}

/// Health of one method of a `diagnose --json` document, and its fit verdict.
fn method(doc: &serde_json::Value, m: &str) -> ([f64; 6], String) {
    let v = &doc["methods"][m];
    let h = &v["health"];
    let names = ["D_GC", "D_EC", "D_GT", "D_ET", "D_GP", "D_EP"];
    let mut out = [0.0; 6];
    for (o, n) in out.iter_mut().zip(names) {
        *o = h[n]
            .as_f64()
            .unwrap_or_else(|| panic!("{m}: no {n} in {v}"));
    }
    let verdict = v["fit_quality"]["verdict"]
        .as_str()
        .expect("verdict")
        .to_string();
    (out, verdict)
}

/// `gtwatch diagnose --method transient` of `csv` with `engine`: health and fit verdict.
fn method_b(csv: &Path, engine: &Path) -> ([f64; 6], String) {
    let doc = json(&[
        "diagnose",
        "--input",
        csv.to_str().expect("path"),
        "--engine",
        engine.to_str().expect("path"),
        "--method",
        "transient",
        "--json",
    ]);
    method(&doc, "transient")
}

#[test]
fn method_b_follows_the_measured_pt_speed_of_an_unknown_load() {
    let dir = tempfile::tempdir().expect("tempdir");
    let table = md22_with_load(dir.path(), "table.toml", TABLE_LOAD);
    let held = md22_with_load(dir.path(), "held.toml", MEASURED);
    let law = md22_with_load(dir.path(), "law.toml", LAW);
    let truth = [2.0, 1.5, 0.0, 0.0, 0.0, 0.0];
    let mut worst: f64 = 0.0;
    // The unit on a load curve, and the unit whose load holds the PT at its set speed.
    for (engine, seed) in [(&table, "3"), (&held, "4")] {
        let csv = dir.path().join(format!("start-{seed}.csv"));
        gtwatch(&[
            "simulate",
            "--engine",
            engine.to_str().expect("path"),
            "--health",
            "D_GC=2,D_EC=1.5",
            "--noise",
            "--seed",
            seed,
            "--out",
            csv.to_str().expect("path"),
        ]);
        let (h, verdict) = method_b(&csv, &held);
        let err = h
            .iter()
            .zip(truth)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "truth {}: health {h:?}, max error {err:.3}, {verdict}",
            engine.display()
        );
        assert_eq!(verdict, "good", "{}: {h:?}", engine.display());
        assert!(err < 0.2, "{}: {h:?} vs {truth:?}", engine.display());
        worst = worst.max(err);
    }
    eprintln!("worst error with the measured PT speed: {worst:.3} points");
    // The cube law of the original file is the wrong load for the table unit: no good fit.
    let (h, verdict) = method_b(&dir.path().join("start-3.csv"), &law);
    assert_ne!(verdict, "good", "the wrong load fitted: {h:?}");
}
