//! Fault suite, restarts (issue 12 #2): a daemon stopped — cleanly (SIGTERM path) or abruptly
//! (its main task aborted mid-run without the final flush; the acquisition task it spawned
//! dies with the plant-sim, so this is weaker than a real kill -9 of the binary, which
//! `replay_kill9.rs` / `worker_kill.rs` cover for replay and diagnosis) — and started again
//! records a `daemon_restart` gap from the last stored sample to the first new one; no
//! committed sample is lost or duplicated and the database stays sound.
//! Real servers on 127.0.0.1 and the real `daemon::run`, about a second per run.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use gtwatch::acquire::modbus::PollProgress;
use gtwatch::daemon::{self, RunOptions};
use gtwatch::plantsim::{spawn_plant_sim, ScriptedPlant, SimOptions};
use gtwatch::shutdown::shutdown_channel;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;

const POLL_MS: u64 = 10;

async fn wait_polls(p: &PollProgress, n: u64) {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
    while p.polls_ok.load(Ordering::Relaxed) < n {
        assert!(
            tokio::time::Instant::now() < deadline,
            "polls stalled: {p:?}"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// Runs the daemon against a fresh plant-sim until `polls` polls succeeded, then stops it
/// cleanly (`abort = false`) or aborts its task (`abort = true`).
async fn one_run(db: &Path, polls: u64, abort: bool) {
    let map = common::reference_config().modbus.expect("map");
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr");
    let sim = spawn_plant_sim(
        listener,
        map,
        Box::new(ScriptedPlant::demo(1.0)),
        SimOptions {
            speedup: 100.0,
            tick: Some(Duration::from_millis(POLL_MS)),
            lockstep: false,
        },
        None,
    )
    .expect("sim");
    let cfg = common::fast_config(&addr.to_string(), db.to_path_buf(), POLL_MS);
    let progress = Arc::new(PollProgress::default());
    let (trigger, shutdown) = shutdown_channel();
    let daemon = tokio::spawn(daemon::run(
        cfg,
        shutdown,
        RunOptions {
            systemd_notify: false,
            progress: Some(Arc::clone(&progress)),
            ..RunOptions::default()
        },
    ));
    wait_polls(&progress, polls).await;
    if abort {
        // Let at least one flush interval pass so something is committed, then cut it off.
        tokio::time::sleep(Duration::from_millis(150)).await;
        daemon.abort();
        let _ = daemon.await;
        // Aborting the daemon's own task leaves the tasks it spawned (poller, writer) running
        // in this test's runtime; stop them so they do not keep writing beside the next run.
        trigger.trigger();
        tokio::time::sleep(Duration::from_millis(200)).await;
    } else {
        trigger.trigger();
        daemon.await.expect("join").expect("daemon ran");
    }
    sim.stop().await.expect("stop");
}

fn sample_times(db: &rusqlite::Connection) -> Vec<i64> {
    common::tag_samples(db, "n1_rpm")
        .into_iter()
        .map(|s| s.0)
        .collect()
}

async fn restart_records_a_gap(abort: bool) {
    let dir = tempfile::tempdir().expect("tempdir");
    let db_path = dir.path().join("restart.db");
    one_run(&db_path, 20, abort).await;
    // One restart (× GTWATCH_FAULTS_LONG), each after a stop of the same kind.
    let cycles = u64::from(common::long_factor());
    let mut lost = 0u64;
    for k in 1..=cycles {
        // Read what the previous run left only once nothing of it can still be committing.
        tokio::time::sleep(Duration::from_millis(300)).await;
        let before = sample_times(&common::open_db(&db_path));
        assert!(!before.is_empty(), "the previous run stored nothing");
        let last_before = *before.last().expect("last");
        one_run(&db_path, 20, abort && k < cycles).await;

        let db = common::open_db(&db_path);
        let after = sample_times(&db);
        // No committed sample lost or duplicated (the primary key forbids duplicates; count
        // them anyway), and every earlier sample is still there.
        for t in &before {
            assert!(after.binary_search(t).is_ok(), "sample {t} lost");
        }
        lost += before
            .iter()
            .filter(|t| after.binary_search(t).is_err())
            .count() as u64;
        let mut dedup = after.clone();
        dedup.dedup();
        assert_eq!(dedup.len(), after.len());
        let first_after = *after
            .iter()
            .find(|&&t| t > last_before)
            .expect("the restarted run stored samples");
        let gaps = common::gaps(&db);
        let restart: Vec<_> = gaps.iter().filter(|g| g.3 == "daemon_restart").collect();
        assert_eq!(restart.len() as u64, k, "{gaps:?}");
        let (start, end, source, _) = restart
            .iter()
            .find(|g| g.0 == last_before)
            .expect("a gap from the last stored sample");
        assert_eq!(source, "daemon");
        assert_eq!(*start, last_before, "gap starts at the last stored sample");
        assert_eq!(*end, first_after, "gap ends at the first new sample");
        assert!(end - start >= 300, "{start}..{end}");
        let ok: String = db
            .query_row("PRAGMA integrity_check", [], |r| r.get(0))
            .expect("check");
        assert_eq!(ok, "ok");
    }
    let db = common::open_db(&db_path);
    let duplicated = common::duplicate_samples(&db);
    assert_eq!(duplicated, 0);
    common::Tally {
        class: if abort {
            "daemon_abrupt_stop_then_restart"
        } else {
            "daemon_sigterm_then_restart"
        },
        injected: cycles,
        lost,
        duplicated,
        integrity: &common::integrity(&db_path),
        note: format!(
            "daemon_restart_gaps={}",
            common::gaps(&db)
                .iter()
                .filter(|g| g.3 == "daemon_restart")
                .count()
        ),
    }
    .print();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn clean_restart_records_a_daemon_restart_gap() {
    restart_records_a_gap(false).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn abrupt_stop_then_restart_records_a_daemon_restart_gap() {
    restart_records_a_gap(true).await;
}
