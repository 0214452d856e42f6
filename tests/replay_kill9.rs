//! End-to-end: `gtwatch replay` killed with SIGKILL half-way, then run again.
//!
//! Checks that the database is sound (`PRAGMA integrity_check` = ok), that what was committed
//! before the kill is still there, and that the re-run ends with exactly the samples of the
//! file, none duplicated and none altered. A second test interrupts the replay of a smaller
//! file with SIGTERM and kill -9 alternately at seeded random moments (from start-up to the
//! last commit), each time into a fresh database: after each the database is sound and holds
//! only samples of the file, and a rerun gives a database identical, sample for sample, to
//! that of an uninterrupted replay.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

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
    write_csv_rows(path, ROWS);
}

fn write_csv_rows(path: &Path, rows: u64) {
    let f = std::fs::File::create(path).expect("create csv");
    let mut w = std::io::BufWriter::new(f);
    writeln!(w, "t_ms,{}", COLS.join(",")).expect("write");
    for r in 0..rows {
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
    common::Tally {
        class: "replay_kill9_mid_transaction",
        injected: 1,
        lost: 0, // asserted: every committed transaction kept, rerun = the whole file
        duplicated: dups as u64,
        integrity: "ok",
        note: format!("committed_at_kill={committed} total={total}"),
    }
    .print();
}

/// One stored sample: (tag name, t_ms, value bits, quality).
type Stored = (String, i64, u64, i64);

/// Every sample as (tag name, t_ms, value bits, quality), in key order.
fn dump(db: &Path) -> Vec<Stored> {
    let conn =
        rusqlite::Connection::open_with_flags(db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .expect("open");
    // Killed before the schema was created: nothing stored.
    let tables: i64 = conn
        .query_row(
            "SELECT COUNT(*) FROM sqlite_master WHERE name IN ('samples', 'tags')",
            [],
            |r| r.get(0),
        )
        .expect("schema");
    if tables < 2 {
        return Vec::new();
    }
    let mut st = conn
        .prepare(
            "SELECT t.name, s.t_ms, s.value, s.quality FROM samples s JOIN tags t ON t.id = s.tag_id
             ORDER BY t.name, s.t_ms",
        )
        .expect("prepare");
    st.query_map([], |r| {
        Ok((
            r.get::<_, String>(0)?,
            r.get(1)?,
            r.get::<_, f64>(2)?.to_bits(),
            r.get(3)?,
        ))
    })
    .expect("query")
    .collect::<Result<Vec<_>, _>>()
    .expect("rows")
}

#[test]
fn replay_interrupted_by_sigterm_and_kill_9_at_random_moments_ends_identical() {
    interrupted_at_random_moments(false);
}

/// The same with `[replay] archive = true`: the samples go straight into archive chunks, and
/// an interrupted replay leaves whole chunks or none (read back through the store's one read
/// path, which merges the tiers).
#[test]
fn archive_replay_interrupted_at_random_moments_ends_identical() {
    interrupted_at_random_moments(true);
}

/// Every sample through the store's read path (both tiers), as [`dump`] gives it.
fn dump_read_path(db: &Path) -> Vec<Stored> {
    if dump(db).is_empty() && !has_chunks(db) {
        return Vec::new();
    }
    let store = Store::open_readonly(db).expect("open");
    let mut tags = store.tags().expect("tags");
    tags.sort_by(|a, b| a.name.cmp(&b.name));
    let mut out = Vec::new();
    for t in tags {
        for s in store
            .tag_samples_between(t.id, i64::MIN, i64::MAX)
            .expect("read")
        {
            out.push((t.name.clone(), s.t_ms, s.value.to_bits(), s.quality));
        }
    }
    out
}

/// Removes a database and its journal files, so a replay starts from nothing.
fn remove_database(db: &Path) {
    for suffix in ["", "-wal", "-shm", "-journal"] {
        let mut name = db.as_os_str().to_owned();
        name.push(suffix);
        let _ = std::fs::remove_file(std::path::PathBuf::from(name));
    }
}

fn has_chunks(db: &Path) -> bool {
    let conn =
        rusqlite::Connection::open_with_flags(db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .expect("open");
    conn.query_row(
        "SELECT COUNT(*) FROM sqlite_master WHERE name = 'archive_chunks'",
        [],
        |r| r.get::<_, i64>(0),
    )
    .expect("schema")
        > 0
        && conn
            .query_row("SELECT COUNT(*) FROM archive_chunks", [], |r| {
                r.get::<_, i64>(0)
            })
            .expect("chunks")
            > 0
}

fn interrupted_at_random_moments(archive: bool) {
    const SMALL_ROWS: u64 = 50_000;
    let dump: fn(&Path) -> Vec<Stored> = if archive { dump_read_path } else { dump };
    // Six rounds (× GTWATCH_FAULTS_LONG), alternately SIGTERM and kill -9.
    let rounds: usize = 6 * common::long_factor() as usize;
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("log.csv");
    write_csv_rows(&csv, SMALL_ROWS);
    let config = |db: &Path| {
        let cfg = db.with_extension("toml");
        std::fs::write(
            &cfg,
            format!(
                "[storage]\npath = {:?}\n\n[replay]\ntime_column = \"t_ms\"\ntime_format = \"epoch_ms\"\ntransaction_samples = 20000\narchive = {archive}\n",
                db.display().to_string()
            ),
        )
        .expect("write config");
        cfg
    };
    let bin = env!("CARGO_BIN_EXE_gtwatch");
    let replay = |cfg: &Path| {
        Command::new(bin)
            .args(["replay", "--no-detect", "--config"])
            .arg(cfg)
            .arg(&csv)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn gtwatch")
    };

    // The reference: one uninterrupted replay. A second one, warm (the first also pages in a
    // freshly linked binary and the log), is timed to place the interruptions: timing the cold
    // one put most of them after the warm reruns had finished.
    let reference_db = dir.path().join("reference.db");
    let status = replay(&config(&reference_db)).wait().expect("reference");
    assert!(status.success());
    let warm_db = dir.path().join("warm.db");
    let t0 = Instant::now();
    let status = replay(&config(&warm_db)).wait().expect("warm reference");
    assert!(status.success());
    let full_ms = t0.elapsed().as_millis().max(50) as u64;
    let reference = dump(&reference_db);
    assert!(
        dump(&warm_db) == reference,
        "two uninterrupted replays differ"
    );
    assert_eq!(reference.len() as u64, SMALL_ROWS * COLS.len() as u64);

    // xorshift64, fixed seed: the same moments on every run (relative to this machine's speed).
    let mut seed: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut interrupted_mid_way = 0;
    let want: std::collections::HashSet<&Stored> = reference.iter().collect();
    for round in 0..rounds {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let mut delay_ms = 5 + seed % full_ms;
        let db = dir.path().join(format!("interrupted{round}.db"));
        let cfg = config(&db);
        // The warm run's time places the moment, but the tests beside this one change the
        // machine's speed from run to run: a replay that has already finished when its moment
        // comes was not interrupted, so it is started again from nothing with half the delay
        // (at most three times) rather than counted as a round that hit nothing.
        let mut attempt = 0;
        let (mut child, still_running) = loop {
            let mut child = replay(&cfg);
            std::thread::sleep(Duration::from_millis(delay_ms));
            let still_running = child.try_wait().expect("wait").is_none();
            attempt += 1;
            if still_running || attempt > 3 {
                break (child, still_running);
            }
            child.wait().expect("reap");
            remove_database(&db);
            delay_ms /= 2;
        };
        let signal = if round % 2 == 0 { "TERM" } else { "KILL" };
        let ok = Command::new("kill")
            .args([&format!("-{signal}"), &child.id().to_string()])
            .status()
            .expect("kill");
        assert!(ok.success() || !still_running);
        child.wait().expect("reap");
        let what = format!("round {round}: SIG{signal} after {delay_ms} ms");
        // Sound after the interruption; whatever is stored is exactly from the file.
        if db.exists() {
            assert_eq!(common::integrity(&db), "ok", "{what}");
            let stored = dump(&db);
            assert!(
                stored.iter().all(|s| want.contains(s)),
                "{what}: a stored sample is not in the file"
            );
            if still_running && stored.len() < reference.len() {
                interrupted_mid_way += 1;
            }
        } else if still_running {
            interrupted_mid_way += 1;
        }
        // The rerun completes, and the result is the uninterrupted run's, sample for sample.
        let status = replay(&cfg).wait().expect("rerun");
        assert!(status.success(), "{what}: rerun failed: {status}");
        assert_eq!(common::integrity(&db), "ok", "{what}");
        assert!(
            dump(&db) == reference,
            "{what}: rerun differs from the uninterrupted replay"
        );
    }
    assert!(
        interrupted_mid_way >= 2,
        "only {interrupted_mid_way} of {rounds} interruptions hit a running replay"
    );
    let classes = if archive {
        [
            ("archive_replay_sigterm_random_moment", 0),
            ("archive_replay_kill9_random_moment", 1),
        ]
    } else {
        [
            ("replay_sigterm_random_moment", 0),
            ("replay_kill9_random_moment", 1),
        ]
    };
    for (class, parity) in classes {
        common::Tally {
            class,
            injected: (0..rounds).filter(|r| r % 2 == parity).count() as u64,
            lost: 0, // asserted: each rerun equals the uninterrupted replay sample for sample
            duplicated: 0,
            integrity: "ok",
            note: format!("interrupted_mid_way={interrupted_mid_way}_of_{rounds}"),
        }
        .print();
    }
}
