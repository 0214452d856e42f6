//! The plant clock (issue 11): a plant simulated faster than real time publishes its own time
//! in `plant_time_ms`, and `acquisition.timestamp_field` makes the daemon stamp samples with it.
//! Before, at `plant-sim --speedup 10` the steady phase lasted less wall time than the
//! detector's 60 s hold and no start ever completed.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use gtwatch::daemon::{self, RunOptions};
use gtwatch::plantsim::{
    spawn_plant_sim, PlantFrame, PlantModel, ScriptLevels, ScriptStep, ScriptTiming, ScriptedPlant,
    SimOptions,
};
use gtwatch::shutdown::shutdown_channel;
use gtwatch::signals::Phase;
use std::time::Duration;
use tokio::net::TcpListener;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn free_running_plant_at_speedup_completes_a_start_in_plant_time() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("clock.db");
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let endpoint = listener.local_addr().unwrap().to_string();
    let mut cfg = common::with_plant_clock(common::fast_config(&endpoint, db.clone(), 10));
    cfg.diagnosis.enabled = false;
    let schedule = vec![
        ScriptStep::Standstill { duration_s: 30.0 },
        ScriptStep::Start,
        ScriptStep::Steady { duration_s: 150.0 },
        ScriptStep::Shutdown { coast_to_rpm: 0.0 },
        ScriptStep::Standstill { duration_s: 30.0 },
    ];
    let plant = ScriptedPlant::new(
        &schedule,
        &ScriptTiming::compressed(2.0),
        ScriptLevels::default(),
        1.0,
        false,
    );
    let frames = (plant.duration_s() / plant.period_s()).ceil() as u64;
    let sim = spawn_plant_sim(
        listener,
        cfg.modbus.clone().unwrap(),
        Box::new(common::Clocked(plant)),
        // Free-running: 50 plant seconds per wall second, whatever the poller does.
        SimOptions {
            speedup: 50.0,
            tick: Some(Duration::from_millis(10)),
            lockstep: false,
        },
        Some(frames),
    )
    .unwrap();
    let (trigger, shutdown) = shutdown_channel();
    let daemon = tokio::spawn(daemon::run(cfg, shutdown, RunOptions::default()));
    let mut sim = sim;
    tokio::time::timeout(Duration::from_secs(60), sim.wait_frames(frames))
        .await
        .expect("plant finished its schedule");
    tokio::time::sleep(Duration::from_millis(800)).await;
    trigger.trigger();
    let report = daemon.await.unwrap().unwrap();
    sim.stop().await.unwrap();

    let conn = common::open_db(&db);
    let n1 = common::tag_samples(&conn, "n1_rpm");
    // Stamped in plant time: from the plant's epoch, one plant second apart (the poller sees
    // some frames twice at 10 ms polls against 20 ms frames; those are not stored twice).
    assert!(
        n1.first().unwrap().0 >= common::EPOCH_MS
            && n1.last().unwrap().0 < common::EPOCH_MS + 3_600_000
    );
    assert!(
        n1.windows(2).all(|w| w[1].0 > w[0].0),
        "strictly increasing times"
    );
    let steps: Vec<i64> = n1.windows(2).map(|w| w[1].0 - w[0].0).collect();
    let one_s = steps.iter().filter(|&&d| d == 1000).count();
    assert!(
        one_s * 10 >= steps.len() * 7,
        "most samples one plant second apart: {steps:?}"
    );
    assert!(report.poll.polls_ok > 0);
    let (outcome, start_ms): (String, i64) = conn
        .query_row(
            "SELECT outcome, start_ms FROM segments WHERE kind = 'startup' ORDER BY start_ms LIMIT 1",
            [],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .expect("a start-up segment");
    assert_eq!(outcome, "completed");
    assert!(
        start_ms >= common::EPOCH_MS + 25_000,
        "start in plant time: {start_ms}"
    );
}

/// Frames whose plant time steps back after frame 5 (a restarted simulator).
struct Backwards {
    k: usize,
    times: Vec<f64>,
}

impl PlantModel for Backwards {
    fn step(&mut self) -> PlantFrame {
        let t = self.times[self.k.min(self.times.len() - 1)];
        self.k += 1;
        PlantFrame {
            t_s: t,
            values: [0.0; gtwatch::signals::NSIG],
            phase: Phase::Standstill,
        }
    }
    fn period_s(&self) -> f64 {
        1.0
    }
    fn epoch_ms(&self) -> Option<i64> {
        Some(common::EPOCH_MS)
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plant_clock_stepping_back_is_a_gap_and_nothing_is_stored_twice() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("back.db");
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let endpoint = listener.local_addr().unwrap().to_string();
    let mut cfg = common::with_plant_clock(common::fast_config(&endpoint, db.clone(), 10));
    cfg.diagnosis.enabled = false;
    let times = vec![
        1.0, 2.0, 3.0, 4.0, 5.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0,
    ];
    let n = times.len() as u64;
    let mut sim = spawn_plant_sim(
        listener,
        cfg.modbus.clone().unwrap(),
        Box::new(Backwards { k: 0, times }),
        SimOptions {
            speedup: 1.0,
            tick: None,
            lockstep: true,
        },
        Some(n),
    )
    .unwrap();
    let (trigger, shutdown) = shutdown_channel();
    let daemon = tokio::spawn(daemon::run(cfg, shutdown, RunOptions::default()));
    tokio::time::timeout(Duration::from_secs(30), sim.wait_frames(n))
        .await
        .expect("every frame polled");
    tokio::time::sleep(Duration::from_millis(500)).await;
    trigger.trigger();
    daemon.await.unwrap().unwrap();
    sim.stop().await.unwrap();

    let conn = common::open_db(&db);
    let t: Vec<i64> = common::tag_samples(&conn, "n1_rpm")
        .into_iter()
        .map(|s| (s.0 - common::EPOCH_MS) / 1000)
        .collect();
    // Frame 1 is published before the first connection and each poll advances one frame
    // first, so the first stored reading is the plant's second 2.
    assert_eq!(
        t,
        (2..=10).collect::<Vec<i64>>(),
        "each plant second once, in order"
    );
    let gaps = common::gaps(&conn);
    assert!(
        gaps.iter()
            .any(|g| g.3.contains("backwards") && g.0 >= common::EPOCH_MS),
        "the backwards step is a recorded gap in plant time: {gaps:?}"
    );
}
