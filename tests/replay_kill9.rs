//! End-to-end: `gtwatch replay` killed with SIGKILL half-way, then run again.
//!
//! Checks that the database is sound (`PRAGMA integrity_check` = ok), that what was committed
//! before the kill is still there, and that the re-run ends with exactly the samples of the
//! file, none duplicated and none altered.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::store::Store;
use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const ROWS: u64 = 250_000;
const COLS: [&str; 4] = ["n1_rpm", "fuel_kg_s", "power_mw", "t2_k"];

fn value(row: u64, col: usize) -> f64 {
    // Exactly representable in the CSV text and as f64.
    ((row * 7 + col as u64 * 13) % 10_000) as f64 / 4.0
}

fn write_csv(path: &Path) {
    let f = std::fs::File::create(path).expect("create csv");
    let mut w = std::io::BufWriter::new(f);
    writeln!(w, "t_ms,{}", COLS.join(",")).expect("write");
    for r in 0..ROWS {
        write!(w, "{}", 1_700_000_000_000u64 + r * 1000).expect("write");
        for c in 0..COLS.len() {
            write!(w, ",{}", value(r, c)).expect("write");
        }
        writeln!(w).expect("write");
    }
    w.flush().expect("flush");
}

fn count(db: &Path) -> i64 {
    match Store::open_readonly(db) {
        Ok(s) => s.sample_count().unwrap_or(0),
        Err(_) => 0,
    }
}

#[test]
fn replay_survives_kill_9_and_rerun_completes_exactly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("log.csv");
    let db = dir.path().join("plant.db");
    let cfg = dir.path().join("gtwatch.toml");
    write_csv(&csv);
    std::fs::write(
        &cfg,
        format!(
            "[storage]\npath = {:?}\n\n[replay]\ntime_column = \"t_ms\"\ntime_format = \"epoch_ms\"\ntransaction_samples = 20000\n",
            db.display().to_string()
        ),
    )
    .expect("write config");
    let bin = env!("CARGO_BIN_EXE_gtwatch");
    let run = || {
        Command::new(bin)
            .args(["replay", "--no-detect", "--config"])
            .arg(&cfg)
            .arg(&csv)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn gtwatch")
    };

    // First run: wait until some transactions are committed, then SIGKILL it.
    let mut child = run();
    let started = Instant::now();
    while count(&db) < 60_000 {
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "replay made no progress"
        );
        assert!(
            child.try_wait().expect("wait").is_none(),
            "replay finished before the kill; make the file larger"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().expect("SIGKILL"); // Child::kill sends SIGKILL on Unix
    child.wait().expect("reap");

    let total = ROWS as i64 * COLS.len() as i64;
    let store = Store::open_readonly(&db).expect("open after kill");
    assert_eq!(store.integrity_check().expect("check"), "ok");
    let committed = store.sample_count().expect("count");
    assert!(committed >= 60_000, "committed data lost: {committed}");
    assert!(committed < total, "the kill came too late to test anything");
    // Committed transactions are whole: a multiple of the transaction size.
    assert_eq!(
        committed % 20_000,
        0,
        "partial transaction visible: {committed}"
    );
    drop(store);

    // Second run completes.
    let status = run().wait().expect("rerun");
    assert!(status.success(), "rerun failed: {status}");
    let store = Store::open_readonly(&db).expect("open after rerun");
    assert_eq!(store.integrity_check().expect("check"), "ok");
    assert_eq!(store.sample_count().expect("count"), total);
    let conn =
        rusqlite::Connection::open_with_flags(&db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .expect("open");
    let dups: i64 = conn
        .query_row(
            "SELECT COUNT(*) FROM (SELECT tag_id, t_ms FROM samples GROUP BY tag_id, t_ms HAVING COUNT(*) > 1)",
            [],
            |r| r.get(0),
        )
        .expect("dups");
    assert_eq!(dups, 0);
    // Every value is the one in the file.
    for (c, name) in COLS.iter().enumerate() {
        let (n, sum): (i64, f64) = conn
            .query_row(
                "SELECT COUNT(*), SUM(s.value) FROM samples s JOIN tags t ON t.id = s.tag_id WHERE t.name = ?1",
                [name],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .expect("sum");
        let want: f64 = (0..ROWS).map(|r| value(r, c)).sum();
        assert_eq!(n, ROWS as i64, "{name}");
        assert_eq!(sum, want, "{name}");
    }
}
