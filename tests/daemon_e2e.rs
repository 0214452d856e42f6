//! End-to-end: in-process plant-sim (port 0, sped up) → `daemon::run` → SQLite → detector.
//!
//! The scripted plant publishes its true phase in the register `phase_truth`, which the daemon
//! stores like any other tag; the detector's segments and phase boundaries are compared with
//! that truth, sample by sample. The plant runs 100× faster than real time (one plant second
//! per 10 ms poll) and publishes its own clock, which the daemon stamps the samples with
//! (`acquisition.timestamp_field`), so the detector works in plant seconds with its own
//! thresholds.
//!
//! The plant runs in lock-step with the poller (one frame per poll of the first request): with
//! a free-running plant the poller sees repeated and skipped frames under CPU load. Stamping
//! in plant time matters as much: with wall-clock stamps a scheduling stall of half a second on
//! a loaded CI machine was 50 plant seconds — a data gap to the detector, which then missed
//! the start-up it fell into. The fault tests use the free-running (speedup) mode.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use gtwatch::daemon::{self, RunOptions};
use gtwatch::plantsim::{spawn_plant_sim, ScriptLevels, ScriptedPlant, SimOptions};
use gtwatch::shutdown::shutdown_channel;
use gtwatch::signals::Phase;
use std::time::Duration;
use tokio::net::TcpListener;

/// Plant seconds per wall second.
const SPEEDUP: f64 = 100.0;
const POLL_MS: u64 = 10;

/// One start in the truth: the first sample index of each phase, in order.
#[derive(Debug)]
struct TruthStart {
    phases: Vec<(Phase, usize)>,
}

/// Splits the stored truth into starts (each begins at a transition into Crank).
fn truth_starts(truth: &[(i64, f64, i64)]) -> Vec<TruthStart> {
    let mut starts: Vec<TruthStart> = Vec::new();
    let mut prev: Option<Phase> = None;
    for (i, &(_, v, _)) in truth.iter().enumerate() {
        let ph = Phase::from_code(v as u16).expect("phase code");
        if prev != Some(ph) {
            if ph == Phase::Crank {
                starts.push(TruthStart { phases: Vec::new() });
            }
            if let Some(s) = starts.last_mut() {
                if !s.phases.iter().any(|(p, _)| *p == ph) {
                    s.phases.push((ph, i));
                }
            }
        }
        prev = Some(ph);
    }
    starts
}

#[derive(Debug)]
struct DetectedSegment {
    start_ms: i64,
    end_ms: Option<i64>,
    outcome: String,
    abort_cause: Option<String>,
    hot_restart: bool,
    phases: Vec<(String, i64)>,
}

fn detected(db: &rusqlite::Connection) -> Vec<DetectedSegment> {
    let mut st = db
        .prepare(
            "SELECT id, start_ms, outcome, abort_cause, hot_restart, end_ms FROM segments
             WHERE kind = 'startup' ORDER BY start_ms",
        )
        .expect("prepare");
    type Row = (i64, i64, String, Option<String>, i64, Option<i64>);
    let segs: Vec<Row> = st
        .query_map([], |r| {
            Ok((
                r.get(0)?,
                r.get(1)?,
                r.get(2)?,
                r.get(3)?,
                r.get(4)?,
                r.get(5)?,
            ))
        })
        .expect("query")
        .collect::<Result<_, _>>()
        .expect("rows");
    segs.into_iter()
        .map(|(id, start_ms, outcome, abort_cause, hot, end_ms)| {
            let mut ps = db
                .prepare(
                    "SELECT phase, start_ms FROM segment_phases WHERE segment_id = ?1
                     ORDER BY start_ms",
                )
                .expect("prepare");
            let phases = ps
                .query_map([id], |r| Ok((r.get(0)?, r.get(1)?)))
                .expect("query")
                .collect::<Result<_, _>>()
                .expect("rows");
            DetectedSegment {
                start_ms,
                end_ms,
                outcome,
                abort_cause,
                hot_restart: hot != 0,
                phases,
            }
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn detector_finds_every_simulated_start_within_two_samples() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db_path = dir.path().join("e2e.db");
    let plant = ScriptedPlant::new(
        &common::e2e_schedule(),
        &common::e2e_timing(),
        ScriptLevels::default(),
        1.0,
        false,
    );
    let total_frames = plant.duration_s().ceil() as u64 + 1;
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let endpoint = listener.local_addr().expect("addr").to_string();
    let mut cfg =
        common::with_plant_clock(common::fast_config(&endpoint, db_path.clone(), POLL_MS));
    let mut sim = spawn_plant_sim(
        listener,
        cfg.modbus.clone().expect("map"),
        Box::new(common::Clocked(plant)),
        SimOptions {
            speedup: SPEEDUP,
            tick: Some(Duration::from_millis(POLL_MS)),
            lockstep: true,
        },
        Some(total_frames),
    )
    .expect("plant-sim");

    // Samples are stamped in plant seconds (one per frame); the script's phases are short.
    let d = &mut cfg.detector;
    d.steady_hold_s = 6.0;
    d.trip_fuel_cut_s = 3.0;
    d.hot_restart_window_s = 40.0;
    d.max_sample_gap_s = 5.0;
    d.resume_margin_s = 60.0;
    assert_eq!(cfg.check(), vec![]);

    let (trigger, shutdown) = shutdown_channel();
    let daemon = tokio::spawn(daemon::run(cfg, shutdown, RunOptions::default()));
    sim.wait_frames(total_frames).await;
    tokio::time::sleep(Duration::from_millis(100)).await;
    trigger.trigger();
    let report = daemon.await.expect("join").expect("daemon ran");
    sim.stop().await.expect("stop sim");
    assert!(
        report.poll.polls_ok as f64 > 0.8 * total_frames as f64,
        "{report:?}"
    );
    assert_eq!(report.poll.gaps, 0, "{report:?}");
    // Graceful shutdown flushed the last batch: everything polled was committed.
    assert_eq!(
        report.writer.samples_received, report.poll.samples,
        "{report:?}"
    );
    assert_eq!(
        report.writer.samples_inserted, report.poll.samples,
        "{report:?}"
    );

    let db = common::open_db(&db_path);
    let truth = common::tag_samples(&db, "phase_truth");
    let times: Vec<i64> = truth.iter().map(|t| t.0).collect();
    let index_of = |t_ms: i64| times.partition_point(|&x| x < t_ms);
    let starts = truth_starts(&truth);
    assert_eq!(starts.len(), 4, "truth has four starts: {starts:?}");
    let segs = detected(&db);
    assert_eq!(
        segs.len(),
        4,
        "detector segments: {segs:#?}\ntruth: {starts:?}"
    );

    let expect = [
        ("completed", false),
        ("aborted", false),
        ("completed", false),
        ("completed", true),
    ];
    for (k, ((seg, truth), (outcome, hot))) in segs.iter().zip(&starts).zip(expect).enumerate() {
        assert_eq!(seg.outcome, outcome, "segment {k}: {seg:#?}");
        assert_eq!(seg.hot_restart, hot, "segment {k}: {seg:#?}");
        if outcome == "aborted" {
            assert_eq!(seg.abort_cause.as_deref(), Some("trip"), "segment {k}");
        }
        let crank_idx = truth.phases[0].1;
        assert!(
            index_of(seg.start_ms).abs_diff(crank_idx) <= 2,
            "segment {k} starts at sample {} but the crank begins at {crank_idx}",
            index_of(seg.start_ms)
        );
        // Every phase of the start, as the truth has it, is found within 2 samples.
        for (phase, tidx) in &truth.phases {
            if matches!(
                phase,
                Phase::Unloading | Phase::Shutdown | Phase::Standstill
            ) {
                continue;
            }
            if *phase == Phase::Trip {
                // An aborted start ends at the fuel cut.
                let end = seg.end_ms.expect("aborted segment is closed");
                assert!(
                    index_of(end).abs_diff(*tidx) <= 2,
                    "segment {k}: ends at sample {}, trip at {tidx}",
                    index_of(end)
                );
                continue;
            }
            let found = seg.phases.iter().find(|(p, _)| p == phase.name());
            let Some((_, t)) = found else {
                panic!(
                    "segment {k}: phase {phase} not detected; detected {:?}",
                    seg.phases
                );
            };
            let didx = index_of(*t);
            assert!(
                didx.abs_diff(*tidx) <= 2,
                "segment {k}: {phase} detected at sample {didx}, truth {tidx}\n\
                 truth {:?}\ndetected {:?}",
                truth.phases,
                seg.phases
                    .iter()
                    .map(|(p, t)| (p.clone(), index_of(*t)))
                    .collect::<Vec<_>>()
            );
        }
    }
}
