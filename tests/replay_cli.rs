//! End-to-end: `gtwatch replay` command-line hygiene (issue 12 #8/#9, issue 11's ignored
//! columns). Each test runs the real binary on a tiny log.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

const LOG: &str = "time,n1_rpm,fuel_kg_s,power_mw,comment\n\
                   2024-03-01T00:00:00Z,0,0,0,a\n\
                   2024-03-01T00:00:01Z,100,0.1,0,b\n\
                   2024-03-01T00:00:02Z,200,0.2,0,c\n";

fn setup(log: &str) -> (tempfile::TempDir, PathBuf, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("log.csv");
    let db = dir.path().join("sub").join("plant.db");
    let cfg = dir.path().join("gtwatch.toml");
    std::fs::write(&csv, log).expect("write csv");
    std::fs::write(
        &cfg,
        format!("[storage]\npath = {:?}\n", db.display().to_string()),
    )
    .expect("write config");
    (dir, csv, db, cfg)
}

fn gtwatch(args: &[&Path]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(args)
        .output()
        .expect("run gtwatch")
}

#[test]
fn missing_log_fails_before_creating_the_database() {
    let (dir, _csv, db, cfg) = setup(LOG);
    let missing = dir.path().join("nonexistent.csv");
    let out = gtwatch(&[Path::new("replay"), Path::new("--config"), &cfg, &missing]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("nonexistent.csv"), "{err}");
    // The OS error is printed once, not once per error in the chain.
    assert_eq!(err.matches("os error 2").count(), 1, "{err}");
    assert!(!db.exists(), "database created");
    assert!(!db.parent().expect("parent").exists(), "folder created");
}

#[test]
fn json_is_one_document_and_ignored_columns_are_named() {
    let (_dir, csv, _db, cfg) = setup(LOG);
    let out = gtwatch(&[
        Path::new("replay"),
        Path::new("--json"),
        Path::new("--config"),
        &cfg,
        &csv,
    ]);
    assert!(out.status.success(), "{out:?}");
    let doc: serde_json::Value =
        serde_json::from_slice(&out.stdout).expect("stdout is one JSON document");
    assert_eq!(doc["files"][0]["rows_read"], 3);
    assert_eq!(doc["files"][0]["ignored_columns"][0], "comment");
    assert!(doc["detector"]["frames"].as_u64().is_some(), "{doc}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("ignoring columns") && err.contains("comment"),
        "{err}"
    );
}

#[test]
fn a_log_without_detector_inputs_is_refused() {
    // Issue 11: columns not named after signals were dropped: exit 0, "detector: 0 frames".
    let (_dir, csv, db, cfg) = setup("time,GG speed,Fuel,power_mw\n2024-03-01T00:00:00Z,1,2,3\n");
    let out = gtwatch(&[Path::new("replay"), Path::new("--config"), &cfg, &csv]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("GG speed") && err.contains("n1_rpm"), "{err}");
    assert!(err.contains("fuel_kg_s"), "{err}");
    assert!(!db.exists());
    // --no-detect ingests what can be ingested.
    let out = gtwatch(&[
        Path::new("replay"),
        Path::new("--no-detect"),
        Path::new("--config"),
        &cfg,
        &csv,
    ]);
    assert!(out.status.success(), "{out:?}");
}

#[test]
fn closed_stdout_ends_quietly() {
    let (_dir, csv, _db, cfg) = setup(LOG);
    let mut child = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .arg("replay")
        .arg("--json")
        .arg("--config")
        .arg(&cfg)
        .arg(&csv)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    // Close the read end at once: every write to stdout fails with EPIPE.
    drop(child.stdout.take());
    let mut err = String::new();
    child
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut err)
        .expect("read stderr");
    let status = child.wait().expect("wait");
    assert!(status.success(), "{status:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn rows_rejected_for_their_time_set_exit_status_3() {
    let log = "time,n1_rpm,fuel_kg_s,power_mw\n\
               2024-03-01T00:00:00Z,0,0,0\n\
               3024-03-01T00:00:00Z,0,0,0\n\
               2024-03-01T00:00:01Z,0,0,0\n";
    let (_dir, csv, _db, cfg) = setup(log);
    let out = gtwatch(&[Path::new("replay"), Path::new("--config"), &cfg, &csv]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("line 3") && err.contains("implausible"),
        "{err}"
    );
}
