//! Issue 12 #8: nonsense demands are refused with the flag at fault, not answered as normal
//! results (`steady --n1-rpm 20000` printed a 40.9 MW point; `simulate --health D_GC=-50`
//! cranked for an hour and exited 0).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use std::process::Command;

fn gtwatch(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(args)
        .output()
        .expect("run gtwatch");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn implausible_demands_and_health_are_refused() {
    let (ok, err) = gtwatch(&["steady", "--n1-rpm", "20000"]);
    assert!(!ok, "210 % GG speed accepted");
    assert!(err.contains("--n1-rpm 20000"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.csv");
    let (ok, err) = gtwatch(&[
        "simulate",
        "--health",
        "D_GC=-50",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!ok, "D_GC = -50 accepted");
    assert!(err.contains("D_GC = -50"), "{err}");
    assert!(!out.exists(), "a result file was written");
    // A sensible demand still works.
    let (ok, err) = gtwatch(&["steady", "--n1-rpm", "9000", "--json"]);
    assert!(ok, "{err}");
}
