//! Commands that write while the daemon runs (issue 27, one writer): `gtwatch wash record`,
//! `confirm`, `reject` and `advise` against the database a running `gtwatch run` is
//! acquiring into. Each command's write is one short transaction that waits for the daemon's
//! writer instead of failing: every command succeeds (or refuses for its own reason), no output
//! and no daemon log line says "database is locked", every wash lands, and the daemon's samples
//! keep landing without a hole.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use common::daemon::{config_text, set, start_sim, write_config, Daemon};
use std::path::Path;
use std::process::Output;
use std::time::{Duration, Instant};

const POLL_MS: u64 = 10;

fn gtwatch(args: &[&str], db: &Path) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(args)
        .arg("--db")
        .arg(db)
        .output()
        .expect("gtwatch runs")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Runs a command that must succeed, and never mention a locked database.
fn ok(args: &[&str], db: &Path) -> String {
    let o = gtwatch(args, db);
    let t = text(&o);
    assert!(o.status.success(), "gtwatch {args:?} failed: {t}");
    assert!(!t.contains("locked"), "gtwatch {args:?}: {t}");
    t
}

fn n1_times(db: &Path) -> Vec<i64> {
    common::tag_samples(&common::open_db(db), "n1_rpm")
        .into_iter()
        .map(|s| s.0)
        .collect()
}

#[test]
fn wash_commands_write_beside_a_running_daemon() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("plant.db");
    let rt = common::daemon::sim_runtime();
    let (sim, addr) = start_sim(&rt, POLL_MS);
    // Small batches: the daemon's writer commits every poll, so the commands meet it often.
    let t = set(
        config_text(&db, &addr, POLL_MS),
        "batch_size = 5000",
        "batch_size = 20",
    );
    let cfg = write_config(dir.path(), &t);
    let mut d = Daemon::start(&cfg);
    d.wait_log("first poll succeeded", 1, Duration::from_secs(30));
    let deadline = Instant::now() + Duration::from_secs(30);
    while n1_times(&db).len() < 20 {
        assert!(Instant::now() < deadline, "no samples stored");
        std::thread::sleep(Duration::from_millis(20));
    }
    let t_from = gtwatch::store::now_ms();

    // Operator washes, one after the other while the daemon commits.
    let records = 10 * common::long_factor() as usize;
    for i in 0..records {
        let at = format!("@{}", 1_700_000_000 + i as i64 * 86_400);
        let out = ok(
            &[
                "wash",
                "record",
                "--at",
                &at,
                "--kind",
                "offline",
                "--note",
                &format!("op{i}"),
            ],
            &db,
        );
        assert!(out.contains("recorded"), "{out}");
    }
    // Two washes "detected by the trend", written by another connection: one confirmed, one
    // rejected; an operator's wash cannot be rejected or confirmed (refused, not locked).
    let c = rusqlite::Connection::open(&db).expect("open");
    c.busy_timeout(Duration::from_secs(10)).expect("busy");
    let mut detected = Vec::new();
    for k in 0..2 {
        c.execute(
            "INSERT INTO washes (t_ms, kind, note) VALUES (?1, 'offline', 'detected: test')",
            [1_800_000_000_000_i64 + k],
        )
        .expect("detected wash");
        detected.push(c.last_insert_rowid());
    }
    drop(c);
    ok(&["wash", "confirm", &detected[0].to_string()], &db);
    ok(&["wash", "reject", &detected[1].to_string()], &db);
    for refused in [["wash", "reject", "1"], ["wash", "confirm", "1"]] {
        let o = gtwatch(&refused, &db);
        let t = text(&o);
        assert!(!o.status.success(), "{refused:?}: {t}");
        assert!(
            t.contains("operator") || t.contains("not a detected"),
            "{t}"
        );
        assert!(!t.contains("locked"), "{refused:?}: {t}");
    }
    ok(&["wash", "advise"], &db);
    let t_to = gtwatch::store::now_ms();

    // Samples kept landing while the commands wrote.
    let deadline = Instant::now() + Duration::from_secs(30);
    while !n1_times(&db).iter().any(|&t| t > t_to + 200) {
        assert!(Instant::now() < deadline, "no samples after the commands");
        std::thread::sleep(Duration::from_millis(20));
    }
    d.assert_running();
    let status = d.sigterm();
    assert!(status.success(), "exit {status}; log:\n{}", d.log_text());
    rt.block_on(sim.stop()).expect("sim stop");
    let log = d.log_text();
    assert!(!log.contains("locked"), "daemon log:\n{log}");
    assert!(!log.contains("write failed"), "daemon log:\n{log}");

    let c = common::open_db(&db);
    let notes: Vec<String> = c
        .prepare("SELECT note FROM washes ORDER BY id")
        .expect("prepare")
        .query_map([], |r| r.get(0))
        .expect("query")
        .collect::<Result<_, _>>()
        .expect("washes");
    let mut want: Vec<String> = (0..records).map(|i| format!("op{i}")).collect();
    want.push("confirmed;  test".into());
    assert_eq!(notes, want);
    assert!(
        common::gaps(&c).iter().all(|g| g.1 < t_from || g.0 > t_to),
        "{:?}",
        common::gaps(&c)
    );
    let times = n1_times(&db);
    let during: Vec<i64> = times
        .iter()
        .copied()
        .filter(|&t| t >= t_from && t <= t_to)
        .collect();
    assert!(!during.is_empty());
    let longest = during.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0);
    assert!(
        longest < 2_000,
        "a {longest} ms hole in the samples while commands wrote"
    );
    assert_eq!(common::duplicate_samples(&c), 0);
    assert_eq!(common::integrity(&db), "ok");
}
