//! Replays every input kept in `fuzz/regressions/<target>/` (inputs that once crashed, hung or
//! misbehaved under `cargo fuzz`, plus hand-made seeds) through the same harness the fuzz target
//! uses (`fuzz/targets.rs`). A panic here is the regression coming back.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

#[path = "../fuzz/targets.rs"]
mod targets;

use std::path::Path;

#[test]
fn every_saved_fuzz_input_is_handled_without_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/regressions");
    let mut ran = 0;
    for (name, body) in targets::TARGETS {
        let dir = root.join(name);
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        let mut files: Vec<_> = entries.filter_map(Result::ok).map(|e| e.path()).collect();
        files.sort();
        for f in files {
            let data = std::fs::read(&f).unwrap();
            eprintln!("{name}: {}", f.display());
            body(&data);
            ran += 1;
        }
    }
    // The directory ships with at least one seed per target; an empty run means it went missing.
    assert!(
        ran >= targets::TARGETS.len(),
        "only {ran} saved inputs found under {root:?}"
    );
}
