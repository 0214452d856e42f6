//! The archive tier end to end (README "Storage tiers"):
//! - `gtwatch store compact` killed with SIGKILL at 20 seeded random moments, each on a fresh
//!   copy of one database: after each the file is sound (`PRAGMA integrity_check`) and holds
//!   exactly the original samples, bit for bit, each once (hot rows + archived chunks);
//! - the readers (the start-up list, `gtwatch segments` and `gtwatch export`, the diagnosis's
//!   recording of a start-up, a fresh detector scan) give identical results before and after
//!   compacting a stored start-up;
//! - `gtwatch store retain` killed at 20 random moments, during the minute roll-up and (another
//!   20, on a file of minute roll-ups) during the hourly merge: every minute is summarised
//!   exactly once, raw, in `rollups_1m` or in its hour's `rollups_1h` row; and 20 kills of one
//!   run doing both tiers on raw data.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;
mod retention;

use gtwatch::quality::Quality;
use gtwatch::store::{Sample, Store, TagInfo};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

const BIN: &str = env!("CARGO_BIN_EXE_gtwatch");

/// Every sample as the store reads it: (tag, t, value bits, quality).
fn contents(db: &Path) -> Vec<(i64, i64, u64, i64)> {
    let store = Store::open_readonly(db).expect("open");
    let mut out = Vec::new();
    for t in store.tags().expect("tags") {
        for s in store
            .tag_samples_between(t.id, i64::MIN, i64::MAX)
            .expect("read")
        {
            out.push((t.id, s.t_ms, s.value.to_bits(), s.quality));
        }
    }
    out
}

/// A fresh copy of `original` at `work`, `cmd` run on it and killed with SIGKILL after
/// `delay`; the file is sound afterwards (`integrity_check`).
fn killed_run(
    original: &Path,
    work: &Path,
    cmd: impl Fn(&Path) -> Command,
    delay: std::time::Duration,
) {
    copy_db(original, work);
    let mut child = cmd(work).spawn().expect("spawn");
    std::thread::sleep(delay);
    child.kill().expect("kill -9");
    let _ = child.wait();
    assert_eq!(common::integrity(work), "ok");
}

fn copy_db(from: &Path, to: &Path) {
    for suffix in ["", "-wal", "-shm"] {
        let _ = std::fs::remove_file(format!("{}{suffix}", to.display()));
    }
    std::fs::copy(from, to).expect("copy");
}

/// Four tags, a day at 1 Hz with jitter, gaps and every quality code.
fn build_db(db: &Path) {
    let mut store = Store::open(db).expect("open");
    let mut rng = ChaCha8Rng::seed_from_u64(2401);
    let mut batch = Vec::new();
    for name in ["n1_rpm", "fuel_kg_s", "power_mw", "t4_k"] {
        let tag = store
            .ensure_tag(&TagInfo {
                name: name.into(),
                unit: String::new(),
                signal: None,
            })
            .expect("tag");
        let mut t = 1_700_000_000_000i64;
        let mut v: f64 = 500.0;
        for _ in 0..86_400 {
            t += if rng.random_bool(0.001) {
                rng.random_range(10_000..3_600_000)
            } else {
                1000 + rng.random_range(-1..2)
            };
            v += rng.random_range(-1.0..1.0f64).round() * 0.125;
            let q = if rng.random_bool(0.02) {
                rng.random_range(1..=4)
            } else {
                0
            };
            batch.push(Sample {
                tag,
                t_ms: t,
                value: v,
                quality: Quality::from_code(q).expect("code"),
            });
        }
    }
    store.insert_samples(&batch).expect("insert");
    drop(store);
}

fn compact_cmd(db: &Path) -> Command {
    let mut c = Command::new(BIN);
    c.args(["store", "compact", "--older-than-days", "0"])
        .args(["--max-chunk-samples", "200", "--db"])
        .arg(db)
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    c
}

fn archived(db: &Path) -> u64 {
    Store::open_readonly(db)
        .expect("open")
        .archive_stats()
        .expect("stats")
        .samples
}

#[test]
fn compaction_survives_kill_9_at_random_moments() {
    let dir = tempfile::tempdir().expect("tempdir");
    let original = dir.path().join("original.db");
    build_db(&original);
    let want = contents(&original);
    let total = want.len() as i64;

    // An uninterrupted run: how long it takes, and that it archives everything.
    let work = dir.path().join("work.db");
    copy_db(&original, &work);
    let t = Instant::now();
    assert!(compact_cmd(&work).status().expect("run").success());
    let full = t.elapsed();
    assert_eq!(archived(&work), total as u64);
    assert!(
        contents(&work) == want,
        "uninterrupted compaction changed samples"
    );

    let mut rng = ChaCha8Rng::seed_from_u64(24_001);
    let (mut kills, mut mid, mut lost, mut duplicated) = (0u32, 0u32, 0u64, 0u64);
    for _ in 0..20 {
        let delay = full.mul_f64(rng.random_range(0.0..1.1));
        killed_run(&original, &work, compact_cmd, delay);
        kills += 1;
        let a = archived(&work);
        if a > 0 && a < total as u64 {
            mid += 1;
        }
        let count = Store::open_readonly(&work)
            .expect("open")
            .sample_count()
            .expect("count");
        duplicated += (count - total).max(0) as u64;
        lost += (total - count).max(0) as u64;
        assert!(
            contents(&work) == want,
            "samples differ after a kill at {delay:?}"
        );
        // And a rerun finishes the job.
        assert!(compact_cmd(&work).status().expect("rerun").success());
        assert_eq!(archived(&work), total as u64);
    }
    eprintln!(
        "FAULT-TALLY class=kill9_during_compaction injected={kills} lost={lost} duplicated={duplicated} integrity=ok mid_compaction={mid} full_run_ms={}",
        full.as_millis()
    );
    assert_eq!((lost, duplicated), (0, 0));
    assert!(
        mid >= 5,
        "only {mid} of {kills} kills landed mid-compaction"
    );
}

/// What the readers say about the stored start-up.
fn readers(db: &Path) -> Vec<String> {
    let run = |args: &[&str]| -> String {
        let out = Command::new(BIN).args(args).output().expect("run");
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).expect("utf8")
    };
    let d = db.to_str().expect("path");
    let store = Store::open_readonly(db).expect("open");
    let rows = store.startup_rows(None).expect("startups");
    assert_eq!(rows.len(), 1, "one stored start-up");
    let id = rows[0].info.id;
    let recording = store.segment_recording(id).expect("recording");
    let tags: Vec<String> = store
        .tags()
        .expect("tags")
        .into_iter()
        .map(|t| t.name)
        .collect();
    vec![
        format!("{rows:?}"),
        format!("{:?}", store.phase_rows(id).expect("phases")),
        format!("{recording:?}"),
        run(&["segments", "--db", d, "--format", "json"]),
        run(&[
            "export",
            "--db",
            d,
            "--tag",
            &tags.join(","),
            "--from",
            "2023-11-01",
            "--to",
            "2023-12-01",
            "--layout",
            "long",
        ]),
        run(&[
            "export",
            "--db",
            d,
            "--tag",
            &tags.join(","),
            "--from",
            "2023-11-01",
            "--to",
            "2023-12-01",
        ]),
    ]
}

#[test]
fn readers_give_identical_results_after_compaction() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("startup.db");
    common::store_startup(&db, &gtwatch::health::HealthParams::default(), 7);
    let before = readers(&db);
    let want = contents(&db);
    let out = Command::new(BIN)
        .args(["store", "compact", "--older-than-days", "0", "--db"])
        .arg(&db)
        .output()
        .expect("compact");
    assert!(out.status.success());
    let hot: i64 = common::open_db(&db)
        .query_row("SELECT COUNT(*) FROM samples", [], |r| r.get(0))
        .expect("count");
    assert_eq!(
        hot,
        0,
        "everything archived: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    let after = readers(&db);
    for (i, (b, a)) in before.iter().zip(&after).enumerate() {
        assert!(b == a, "reader {i} differs after compaction");
    }
    assert!(contents(&db) == want);

    // A detector scan from scratch over the archive finds the same start-up.
    {
        let c = rusqlite::Connection::open(&db).expect("open");
        c.execute_batch(
            "DELETE FROM segment_phases; DELETE FROM segments;
             UPDATE detector_state SET scanned_to_ms = NULL, rescan_from_ms = NULL,
                    last_fuel_off_ms = NULL;",
        )
        .expect("reset detector");
    }
    let mut store = Store::open(&db).expect("open");
    gtwatch::detect::scan(&mut store, &gtwatch::detect::DetectorConfig::default()).expect("scan");
    drop(store);
    let rescanned = readers(&db);
    // The segment (times, outcome, phases) and the diagnosis's recording of it are the same.
    assert!(
        before[0] == rescanned[0],
        "segment differs after a rescan of the archive"
    );
    assert!(
        before[1] == rescanned[1],
        "phases differ after a rescan of the archive"
    );
    assert!(
        before[2] == rescanned[2],
        "recording differs after a rescan of the archive"
    );
}
