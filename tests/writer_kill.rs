//! Killing `gtwatch run` (kill -9) while the writer's channel is full (issue 27, one writer):
//! every sample the writer acknowledged (logged "batch committed" after its commit) is on
//! disk, nothing more and nothing twice, `PRAGMA integrity_check` is ok, and the restarted
//! daemon goes on.
//!
//! The daemon runs with a channel of two commands and a batch of five samples (a commit every
//! poll). The test then takes the database's write lock from a connection of its own, as a
//! slow disk would hold the writer: the writer's commit waits for the lock, acquisition fills
//! the channel and waits for room (the daemon logs "writer channel full"), and the daemon is
//! killed right then, with samples in the channel and in the writer's buffer that were never
//! acknowledged.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use common::daemon::{config_text, set, start_sim, write_config, Daemon};
use std::time::Duration;

const POLL_MS: u64 = 10;

/// The largest `inserted_total` of the writer's "batch committed" lines: the samples it
/// acknowledged as committed.
fn acknowledged(log: &str) -> u64 {
    log.lines()
        .filter(|l| l.contains("batch committed"))
        .filter_map(|l| {
            l.split_whitespace()
                .find_map(|w| w.strip_prefix("inserted_total="))
                .and_then(|v| v.parse().ok())
        })
        .max()
        .unwrap_or(0)
}

#[test]
fn kill9_while_the_writer_channel_is_full_keeps_every_acknowledged_sample_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("plant.db");
    let rt = common::daemon::sim_runtime();
    let (sim, addr) = start_sim(&rt, POLL_MS);
    let mut t = config_text(&db, &addr, POLL_MS);
    t = set(t, "queue_capacity = 1024", "queue_capacity = 2");
    t = set(t, "batch_size = 5000", "batch_size = 5");
    // The writer waits for the test's lock instead of failing while it is held.
    t = set(t, "busy_timeout_ms = 5000", "busy_timeout_ms = 60000");
    let cfg = write_config(dir.path(), &t);
    let log_level = "info,gtwatch::store::writer=debug";

    let kills = 2 * common::long_factor();
    let mut acked_total = 0u64;
    for round in 1..=kills {
        let mut d = Daemon::start_logging(&cfg, log_level);
        d.wait_log("batch committed", 5, Duration::from_secs(30));
        // Hold the write lock: the writer's next commit waits, the channel fills up.
        let lock = rusqlite::Connection::open(&db).expect("lock connection");
        lock.busy_timeout(Duration::from_secs(30)).expect("busy");
        lock.execute_batch("BEGIN IMMEDIATE").expect("write lock");
        d.wait_log("writer channel full", 1, Duration::from_secs(30));
        std::thread::sleep(Duration::from_millis(100));
        d.assert_running();
        d.kill9();
        lock.execute_batch("ROLLBACK").expect("release");
        drop(lock);

        // Samples are never deleted: what this run acknowledged comes on top of the earlier runs'.
        let acked = acknowledged(&d.log_text());
        assert!(acked > 0, "round {round}: nothing acknowledged");
        acked_total += acked;
        let c = common::open_db(&db);
        let stored = common::sample_count(&c);
        assert_eq!(
            stored, acked_total,
            "round {round}: stored samples vs samples the writer acknowledged"
        );
        assert_eq!(common::duplicate_samples(&c), 0, "round {round}");
        assert_eq!(common::integrity(&db), "ok", "round {round}");
    }

    // The restarted daemon records the restart as a gap and goes on storing.
    let mut d = Daemon::start(&cfg);
    d.wait_log("first poll succeeded", 1, Duration::from_secs(30));
    let before = common::sample_count(&common::open_db(&db));
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    while common::sample_count(&common::open_db(&db)) <= before {
        assert!(
            std::time::Instant::now() < deadline,
            "no samples after restart"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let status = d.sigterm();
    assert!(status.success(), "exit {status}; log:\n{}", d.log_text());
    rt.block_on(sim.stop()).expect("sim stop");
    let c = common::open_db(&db);
    let duplicated = common::duplicate_samples(&c);
    assert_eq!(duplicated, 0);
    let restarts = common::gaps(&c)
        .iter()
        .filter(|g| g.3 == "daemon_restart")
        .count();
    assert_eq!(restarts, kills as usize, "{:?}", common::gaps(&c));
    let ok = common::integrity(&db);
    assert_eq!(ok, "ok");
    common::Tally {
        class: "kill9_writer_channel_full",
        injected: u64::from(kills),
        lost: 0, // asserted: every acknowledged sample is stored
        duplicated,
        integrity: &ok,
        note: format!("acknowledged_before_kills={acked_total}"),
    }
    .print();
}
