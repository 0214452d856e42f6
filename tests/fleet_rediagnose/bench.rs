//! The acceptance benchmark of issue 25 item 3 (ignored; run by hand).

use super::common::postgres::PgServer;
use super::{
    assert_results_are_the_edges, build_edge, column, count, env_or, rediagnose, report_of,
    sync_edge, worker, worker_with,
};
use gtwatch::fleet::Centre;
use std::process::Child;
use std::time::{Duration, Instant};

/// The acceptance figure of issue 25 item 3, by hand (minutes):
/// `BENCH_STARTUPS=200 BENCH_WORKERS=4 BENCH_KILL=2 BENCH_RUNS=100 cargo test --release
///  --test integration fleet_rediagnose::bench::bench_ -- --ignored --nocapture`.
/// An edge of `BENCH_STARTUPS` start-ups diagnosed with `BENCH_RUNS` model runs per method is
/// synced; one worker runs a quarter of the jobs alone (its throughput); then the queue is
/// emptied and refilled, `BENCH_WORKERS` workers run it all while `BENCH_KILL` of them are
/// `kill -9`ed mid-job at evenly spaced moments. Every job done exactly once and every result
/// the edge's own are asserted; the figures are printed as one `FLEET-BENCH {json}` line.
#[test]
#[ignore = "a benchmark of minutes: run by hand (see its doc)"]
fn bench_rediagnose_workers_killed_mid_run() {
    let n = env_or("BENCH_STARTUPS", 200);
    let k = env_or("BENCH_WORKERS", 4);
    let kill = env_or("BENCH_KILL", 2).min(k.saturating_sub(1));
    let runs = env_or("BENCH_RUNS", 100);
    let single = env_or("BENCH_SINGLE_JOBS", n.div_ceil(4));
    let pg = PgServer::start();
    let url = pg.create_db("fleet_bench");
    let dir = tempfile::tempdir().expect("tempdir");
    let t_edge = Instant::now();
    let cfg = build_edge(dir.path(), n, runs, 0);
    let edge_s = t_edge.elapsed().as_secs_f64();
    let cfg_s = cfg.to_str().expect("utf8");
    sync_edge(dir.path(), &url);
    let mut centre = Centre::connect_existing(&url, Duration::from_secs(5)).expect("centre");
    let enqueue = |centre: &mut Centre| {
        let doc = rediagnose(&url, cfg_s, &[]);
        assert_eq!(doc["enqueue"]["enqueued"], n, "{doc:#}");
        let _ = centre;
        doc["enqueue"]["config_hash"]
            .as_str()
            .expect("hash")
            .to_string()
    };

    // One worker alone.
    enqueue(&mut centre);
    let t1 = Instant::now();
    let mut solo = worker_with(&url, "solo", &["--max-jobs", &single.to_string()]);
    let solo_rep = report_of(&mut solo, "solo", Duration::from_secs(3600));
    let one_s = t1.elapsed().as_secs_f64();
    assert_eq!(solo_rep["done"], single);
    centre
        .query_text("TRUNCATE rediagnosis_estimates, rediagnoses, rediagnosis_jobs")
        .expect("empty the queue");

    // K workers, `kill` of them killed -9 mid-job.
    let hash = enqueue(&mut centre);
    let t2 = Instant::now();
    let names: Vec<String> = (0..k).map(|i| format!("w{i}")).collect();
    let mut workers: Vec<Child> = names.iter().map(|w| worker(&url, w)).collect();
    let mut killed: Vec<(String, String)> = Vec::new();
    for (i, name) in names.iter().enumerate().take(kill) {
        let at = (i + 1) * n / (kill + 1);
        loop {
            let done = count(
                &mut centre,
                "SELECT count(*) FROM rediagnosis_jobs WHERE state = 'done'",
            );
            let held = column(
                &mut centre,
                &format!(
                    "SELECT id FROM rediagnosis_jobs WHERE lease_owner = '{name}' AND state = 'pending'"
                ),
            );
            if done as usize >= at {
                if let Some(Some(id)) = held.first() {
                    workers[i].kill().expect("kill -9");
                    let _ = workers[i].wait();
                    eprintln!(
                        "FLEET-BENCH {name} killed -9 holding job {id} at {done} done, {:.1} s",
                        t2.elapsed().as_secs_f64()
                    );
                    killed.push((name.clone(), id.clone()));
                    break;
                }
            }
            assert!(t2.elapsed() < Duration::from_secs(3600), "no kill moment");
            std::thread::sleep(Duration::from_millis(10));
        }
    }
    let reports: Vec<serde_json::Value> = workers
        .iter_mut()
        .zip(&names)
        .skip(kill)
        .map(|(w, name)| report_of(w, name, Duration::from_secs(3600)))
        .collect();
    let k_s = t2.elapsed().as_secs_f64();

    let q = rediagnose::queue_counts(&mut centre, Some(&hash), None).expect("queue");
    assert_eq!(
        (q.waiting, q.leased, q.done, q.failed),
        (0, 0, n as i64, 0),
        "{q:?}"
    );
    assert_eq!(
        count(
            &mut centre,
            "SELECT count(DISTINCT (unit_id, segment_id)) FROM rediagnoses"
        ),
        n as i64
    );
    assert_eq!(
        count(&mut centre, "SELECT count(*) FROM rediagnoses"),
        n as i64
    );
    for (name, job) in &killed {
        let row = centre
            .query_text(&format!(
                "SELECT done_by, attempts FROM rediagnosis_jobs WHERE id = {job}"
            ))
            .expect("job");
        assert!(row[0][0].as_deref() != Some(name.as_str()), "{row:?}");
    }
    assert_results_are_the_edges(&mut centre);
    let sum = |key: &str| -> f64 { reports.iter().map(|r| r[key].as_f64().unwrap_or(0.0)).sum() };
    let survivors_done = sum("done").max(1.0);
    let retried = count(
        &mut centre,
        "SELECT count(*) FROM rediagnosis_jobs WHERE attempts > 1",
    );
    let doc = serde_json::json!({
        "startups": n,
        "max_model_runs": runs,
        "edge_replay_and_diagnosis_s": edge_s,
        "one_worker": {
            "jobs": single,
            "wall_s": one_s,
            "jobs_per_s": single as f64 / one_s,
            "fit_s_per_job": solo_rep["fit_s"].as_f64().unwrap_or(0.0) / single as f64,
            "cpu_s_per_job": solo_rep["cpu_s"].as_f64().unwrap_or(0.0) / single as f64,
        },
        "workers": k,
        "killed": kill,
        "wall_s": k_s,
        "jobs_per_s": n as f64 / k_s,
        "speedup_vs_one": (n as f64 / k_s) / (single as f64 / one_s),
        // Of the workers that ran to the end (the killed ones report nothing).
        "fit_s_per_job": sum("fit_s") / survivors_done,
        "cpu_s_per_job": sum("cpu_s") / survivors_done,
        "jobs_claimed_more_than_once": retried,
        "cores": std::thread::available_parallelism().map_or(0, |c| c.get()),
        // Other work on the machine shows here (the figures assume it had the cores).
        "loadavg_at_end": std::fs::read_to_string("/proc/loadavg").unwrap_or_default().trim(),
    });
    eprintln!("FLEET-BENCH {doc}");
}
