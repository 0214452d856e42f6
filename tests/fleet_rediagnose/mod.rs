//! Distributed re-diagnosis (issue 25 item 3) against a real PostgreSQL server
//! (tests/common/postgres.rs): an edge replays a log of six start-ups and diagnoses them with a
//! small budget, syncs into the centre; `gtwatch fleet rediagnose` queues one job per start-up
//! (again: nothing more); three `gtwatch fleet worker` processes with a 2 s lease run them, one
//! `kill -9`ed while it holds a job. Every job is then done exactly once (one result per job,
//! none pending or failed, the killed worker's job finished by another after its lease ran
//! out), and every result is bit for bit the edge's own stored diagnosis under the same config
//! hash. Also the queue's SQL alone: claim, renewal, a lost lease that must not write, and
//! `SKIP LOCKED` between two claimers (here); gap-analysis jobs (`--gap`) whose reports are
//! the edge daemon's own ([`gap`]); `--retry-failed` and a version-2 centre's upgrade
//! ([`retry`]); the acceptance benchmark, by hand ([`bench`]).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

mod bench;
mod gap;
mod retry;

use common::postgres::PgServer;
use gtwatch::engine::simulation::run_scenario;
use gtwatch::engine::{Engine, Scenario};
use gtwatch::fleet::rediagnose::{self, EnqueueRequest, JobKind, JobResult};
use gtwatch::fleet::Centre;
use gtwatch::health::HealthParams;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

const UNIT: &str = "gt-redo";
const STARTUPS: usize = 6;

fn gtwatch(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .expect("run gtwatch")
}

fn ok(out: Output, what: &str) -> Output {
    assert!(
        out.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// An edge database of `n` replayed start-ups, diagnosed with `max_model_runs` per method and
/// gap analyses only on the schedule `gap_every_n` (0: none); returns the config file. Six
/// degradation levels, each simulated once, repeat with a fresh noise seed per start-up.
fn build_edge(dir: &Path, n: usize, max_model_runs: usize, gap_every_n: u32) -> std::path::PathBuf {
    let engine = Engine::reference().expect("engine");
    let levels: Vec<_> = (0..6)
        .map(|k| {
            let d = k as f64;
            let h = HealthParams {
                D_GC: 0.5 + 0.3 * d,
                D_EC: 0.2 + 0.1 * d,
                D_GT: 0.3,
                D_ET: 0.2,
                D_GP: 0.1,
                D_EP: 0.2,
            };
            run_scenario(&engine.model(&h), &Scenario::startup(engine.cfg()))
                .expect("runs")
                .0
        })
        .collect();
    let runs = (0..n)
        .map(|day| (levels[day % levels.len()].clone(), 70 + day as u64))
        .collect();
    let csv = dir.join("days.csv");
    common::write_daily_log(&engine, runs, &csv);
    let db = dir.join("edge.db");
    let cfg = common::replay_config_text(&db)
        .replace(
            "max_model_runs = 400",
            &format!("max_model_runs = {max_model_runs}"),
        )
        .replace("gap_on_poor_fit = true", "gap_on_poor_fit = false")
        .replace("gap_on_health_step = true", "gap_on_health_step = false")
        .replace("gap_every_n = 0", &format!("gap_every_n = {gap_every_n}"));
    assert!(cfg.contains("gap_on_poor_fit = false") && cfg.contains("gap_on_health_step = false"));
    assert!(cfg.contains(&format!("gap_every_n = {gap_every_n}")));
    let cfg_path = dir.join("gtwatch.toml");
    std::fs::write(&cfg_path, cfg).expect("config");
    let t0 = Instant::now();
    ok(
        gtwatch(&[
            "replay",
            "--config",
            cfg_path.to_str().expect("utf8"),
            csv.to_str().expect("utf8"),
        ]),
        "replay",
    );
    eprintln!(
        "FLEET-REDIAGNOSE edge: {n} start-ups replayed and diagnosed in {:.1} s",
        t0.elapsed().as_secs_f64()
    );
    cfg_path
}

/// `gtwatch sync` of the edge in `dir` as [`UNIT`].
fn sync_edge(dir: &Path, url: &str) {
    let db = dir.join("edge.db");
    ok(
        gtwatch(&[
            "sync",
            "--db",
            db.to_str().expect("utf8"),
            "--unit",
            UNIT,
            "--postgres-url",
            url,
        ]),
        "sync",
    );
}

/// One value per row of a query at the centre, as text.
fn column(centre: &mut Centre, sql: &str) -> Vec<Option<String>> {
    centre
        .query_text(sql)
        .expect("query")
        .into_iter()
        .map(|mut r| r.remove(0))
        .collect()
}

fn count(centre: &mut Centre, sql: &str) -> i64 {
    column(centre, sql)[0]
        .as_deref()
        .expect("a count")
        .parse()
        .expect("a number")
}

fn worker(url: &str, id: &str) -> Child {
    worker_with(url, id, &[])
}

/// A `gtwatch fleet worker --lease-s 2 --idle-exit` process with `extra` arguments.
fn worker_with(url: &str, id: &str, extra: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args([
            "fleet",
            "worker",
            "--lease-s",
            "2",
            "--idle-exit",
            "--poll-ms",
            "200",
            "--worker-id",
            id,
            "--json",
        ])
        .args(extra)
        .env("GTWATCH_POSTGRES_URL", url)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("worker starts")
}

#[test]
fn three_workers_one_killed_do_every_job_once_with_the_edges_results() {
    let t_all = Instant::now();
    let pg = PgServer::start();
    let url = pg.create_db("fleet_redo");
    let dir = tempfile::tempdir().expect("tempdir");
    // A small budget: each start-up's two fits about a second.
    let cfg = build_edge(dir.path(), STARTUPS, 100, 0);
    let cfg_s = cfg.to_str().expect("utf8");
    sync_edge(dir.path(), &url);
    let mut centre = Centre::connect_existing(&url, Duration::from_secs(5)).expect("centre");
    let edge_results = count(
        &mut centre,
        "SELECT count(DISTINCT segment_id) FROM diagnoses",
    );
    assert_eq!(edge_results, STARTUPS as i64, "the edge diagnosed each");

    let hash = enqueue_twice(&url, cfg_s, &mut centre);

    let (killed_job, reports) = run_workers_killing_one(&url, &mut centre);

    // Exactly once: one done job and one result per start-up, nothing pending or failed.
    let q = rediagnose::queue_counts(&mut centre, Some(&hash), None).expect("queue");
    assert_eq!(
        (q.waiting, q.leased, q.done, q.failed),
        (0, 0, STARTUPS as i64, 0),
        "{q:?}"
    );
    assert_eq!(
        count(&mut centre, "SELECT count(*) FROM rediagnoses"),
        STARTUPS as i64
    );
    assert_eq!(
        count(
            &mut centre,
            "SELECT count(DISTINCT (unit_id, segment_id)) FROM rediagnoses"
        ),
        STARTUPS as i64
    );
    let done: u64 = reports
        .iter()
        .map(|r| r["done"].as_u64().expect("done"))
        .sum();
    assert_eq!(done, STARTUPS as u64, "the survivors stored every result");
    // The killed worker's job: claimed again after its lease ran out, finished by another.
    let row = centre
        .query_text(&format!(
            "SELECT done_by, attempts FROM rediagnosis_jobs WHERE id = {killed_job}"
        ))
        .expect("job");
    let done_by = row[0][0].clone().expect("done_by");
    let attempts: i32 = row[0][1].as_deref().expect("attempts").parse().expect("n");
    assert!(done_by != "w0" && attempts >= 2, "{row:?}");
    assert_eq!(
        count(
            &mut centre,
            "SELECT count(*) FROM rediagnoses WHERE worker_id = 'w0'"
        ),
        0
    );

    assert_results_are_the_edges(&mut centre);
    // `fleet history --config-hash` shows the re-diagnosis: the edges' history, row for row.
    let history = |extra: &[&str]| {
        let mut args = vec![
            "fleet",
            "history",
            "--postgres-url",
            &url,
            "--format",
            "json",
        ];
        args.extend_from_slice(extra);
        let out = ok(gtwatch(&args), "fleet history");
        serde_json::from_slice::<serde_json::Value>(&out.stdout).expect("json")
    };
    let edge = history(&[]);
    let redone = history(&["--config-hash", &hash]);
    assert_eq!(
        edge.as_array().map(Vec::len),
        Some(2 * STARTUPS),
        "{edge:#}"
    );
    assert_eq!(redone, edge);
    assert_eq!(
        history(&["--config-hash", "no-such-hash"]),
        serde_json::json!([])
    );
    eprintln!(
        "FLEET-REDIAGNOSE test {:.1} s",
        t_all.elapsed().as_secs_f64()
    );
}

/// `gtwatch fleet rediagnose --postgres-url URL --config CFG [extra] --json`, its document.
fn rediagnose(url: &str, cfg_s: &str, extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "fleet",
        "rediagnose",
        "--postgres-url",
        url,
        "--config",
        cfg_s,
    ];
    args.extend_from_slice(extra);
    args.push("--json");
    let out = ok(gtwatch(&args), "rediagnose");
    serde_json::from_slice(&out.stdout).expect("json")
}

/// `fleet rediagnose` twice: one job per start-up, then none more; the jobs' hash.
fn enqueue_twice(url: &str, cfg_s: &str, centre: &mut Centre) -> String {
    let doc = rediagnose(url, cfg_s, &["--unit", UNIT]);
    assert_eq!(doc["enqueue"]["enqueued"], STARTUPS, "{doc:#}");
    let hash = doc["enqueue"]["config_hash"]
        .as_str()
        .expect("hash")
        .to_string();
    let edge_hashes = column(centre, "SELECT DISTINCT config_hash FROM diagnoses");
    assert_eq!(
        edge_hashes,
        vec![Some(hash.clone())],
        "the job's hash is the edge's"
    );
    let doc2 = rediagnose(url, cfg_s, &[]);
    assert_eq!(doc2["enqueue"]["enqueued"], 0, "{doc2:#}");
    assert_eq!(doc2["enqueue"]["already_queued"], STARTUPS, "{doc2:#}");

    hash
}

/// Three workers; `w0` is killed -9 as soon as it holds a job. The job it held and the
/// survivors' reports.
fn run_workers_killing_one(url: &str, centre: &mut Centre) -> (String, Vec<serde_json::Value>) {
    let t_work = Instant::now();
    let mut workers: Vec<Child> = ["w0", "w1", "w2"].iter().map(|w| worker(url, w)).collect();
    let killed_job = loop {
        let held = column(
            centre,
            "SELECT id FROM rediagnosis_jobs WHERE lease_owner = 'w0' AND state = 'pending'",
        );
        if let Some(Some(id)) = held.first() {
            workers[0].kill().expect("kill -9");
            let _ = workers[0].wait();
            break id.clone();
        }
        assert!(
            t_work.elapsed() < Duration::from_secs(20),
            "w0 never claimed a job"
        );
        std::thread::sleep(Duration::from_millis(5));
    };
    eprintln!(
        "FLEET-REDIAGNOSE w0 killed -9 holding job {killed_job} after {:.2} s",
        t_work.elapsed().as_secs_f64()
    );
    let mut reports = Vec::new();
    for (i, w) in workers.iter_mut().enumerate().skip(1) {
        let deadline = Instant::now() + Duration::from_secs(45);
        loop {
            if w.try_wait().expect("wait").is_some() {
                break;
            }
            assert!(Instant::now() < deadline, "worker w{i} did not finish");
            std::thread::sleep(Duration::from_millis(50));
        }
        let out = w.wait_with_output_ref();
        assert!(out.0.success(), "w{i}: {}", out.2);
        let rep: serde_json::Value = serde_json::from_str(&out.1).expect("worker report");
        reports.push(rep);
    }
    let work_s = t_work.elapsed().as_secs_f64();
    eprintln!("FLEET-REDIAGNOSE workers: {reports:?}, all jobs in {work_s:.1} s");

    (killed_job, reports)
}

/// Every re-diagnosed estimate is bit for bit the edge's own (same hash), every method,
/// health and σ.
fn assert_results_are_the_edges(centre: &mut Centre) {
    let cmp = |cols: &str| {
        format!(
            "SELECT count(*) FROM diagnoses d
             FULL JOIN rediagnosis_estimates e
               ON e.unit_id = d.unit_id AND e.segment_id = d.segment_id
              AND e.method = d.method AND e.config_hash = d.config_hash
             WHERE d.edge_id IS NULL OR e.method IS NULL OR ({cols}) IS DISTINCT FROM ({})",
            cols.replace("d.", "e.")
        )
    };
    let differ = count(
        centre,
        &cmp(
            "d.d_gc, d.d_ec, d.d_gt, d.d_et, d.d_gp, d.d_ep, d.sigma_gc, d.sigma_ec, \
              d.sigma_gt, d.sigma_et, d.sigma_gp, d.sigma_ep, d.objective, d.residual_level, \
              d.fit_quality, d.model_runs, d.seed",
        ),
    );
    let n_estimates = count(centre, "SELECT count(*) FROM rediagnosis_estimates");
    let n_edge = count(centre, "SELECT count(*) FROM diagnoses");
    eprintln!(
        "FLEET-REDIAGNOSE {n_estimates} re-diagnosed estimates vs {n_edge} of the edge: {differ} differ; \
",
    );
    assert_eq!(n_estimates, n_edge);
    assert_eq!(
        differ, 0,
        "re-diagnosis differs from the edge's own results"
    );
}

/// `wait_with_output` on a `&mut Child` whose pipes are still attached.
trait WaitRef {
    fn wait_with_output_ref(&mut self) -> (std::process::ExitStatus, String, String);
}

impl WaitRef for Child {
    fn wait_with_output_ref(&mut self) -> (std::process::ExitStatus, String, String) {
        use std::io::Read;
        let mut out = String::new();
        let mut err = String::new();
        if let Some(mut o) = self.stdout.take() {
            o.read_to_string(&mut out).expect("stdout");
        }
        if let Some(mut e) = self.stderr.take() {
            e.read_to_string(&mut err).expect("stderr");
        }
        (self.wait().expect("wait"), out, err)
    }
}

/// The queue's SQL alone: a claimed job is skipped by a second claimer (`SKIP LOCKED` and the
/// lease), renewal keeps it, an expired lease lets another worker take it, and the first
/// worker, having lost it, can neither renew nor store a result.
#[test]
fn a_lost_lease_cannot_write_and_a_held_one_is_not_claimed_twice() {
    let pg = PgServer::start();
    let url = pg.create_db("fleet_lease");
    let mut c = Centre::connect(&url, Duration::from_secs(5)).expect("centre");
    c.query_text(
        "INSERT INTO segments (unit_id, edge_id, kind, start_ms, end_ms, status)
           VALUES ('u', 1, 'startup', 10000, 20000, 'diagnosed'),
                  ('u', 2, 'startup', 30000, 40000, 'diagnosed'),
                  ('u', 3, 'startup', 50000, 60000, 'closed');
         INSERT INTO sample_windows (unit_id, segment_id, from_ms, end_ms)
           VALUES ('u', 1, 0, 20000), ('u', 2, 20000, 40000);",
    )
    .expect("rows");
    let req = EnqueueRequest {
        units: vec![],
        since_ms: None,
        config_hash: "h1".into(),
        engine_name: "e".into(),
        engine_toml: "x".into(),
        settings_json: "{}".into(),
        kind: JobKind::Diagnose,
    };
    let r = rediagnose::enqueue(&mut c, &req).expect("enqueue");
    assert_eq!(
        (r.startups, r.enqueued, r.without_window),
        (2, 2, 1),
        "{r:?}"
    );
    assert_eq!(
        rediagnose::enqueue(&mut c, &req).expect("again").enqueued,
        0
    );
    let mut other = req.clone();
    other.engine_toml = "y".into();
    assert!(
        rediagnose::enqueue(&mut c, &other).is_err(),
        "same hash, other text"
    );

    let lease = Duration::from_millis(1000);
    let a = rediagnose::claim(&mut c, "a", lease)
        .expect("claim")
        .expect("a job");
    let mut c2 = Centre::connect_existing(&url, Duration::from_secs(5)).expect("centre 2");
    let b = rediagnose::claim(&mut c2, "b", lease)
        .expect("claim")
        .expect("another job");
    assert_ne!(a.id, b.id, "a held job is not claimed twice");
    assert!(rediagnose::claim(&mut c2, "c", lease)
        .expect("claim")
        .is_none());
    std::thread::sleep(Duration::from_millis(500));
    assert!(rediagnose::renew(&mut c, a.id, "a", lease).expect("renew"));
    assert!(!rediagnose::renew(&mut c, a.id, "b", lease).expect("renew"));
    // b's lease runs out (a's is renewed); c takes b's job; b can neither renew nor store.
    std::thread::sleep(Duration::from_millis(600));
    assert!(rediagnose::renew(&mut c, a.id, "a", lease).expect("renew"));
    let c_job = rediagnose::claim(&mut c2, "c", lease)
        .expect("claim")
        .expect("the expired job");
    assert_eq!(c_job.id, b.id);
    assert_eq!(c_job.attempts, 2);
    assert!(!rediagnose::renew(&mut c, b.id, "b", lease).expect("renew"));
    let result = JobResult {
        outcome: "undiagnosable".into(),
        estimates: vec![],
        failures_json: "[]".into(),
        wall_s: 0.1,
    };
    assert!(!rediagnose::complete(&mut c, &b, "b", &result).expect("complete"));
    assert!(rediagnose::complete(&mut c2, &c_job, "c", &result).expect("complete"));
    assert!(!rediagnose::complete(&mut c2, &c_job, "c", &result).expect("twice"));
    // a, renewed, still holds its job and stores it.
    assert!(rediagnose::complete(&mut c, &a, "a", &result).expect("complete"));
    let q = rediagnose::queue_counts(&mut c, None, None).expect("queue");
    assert_eq!((q.pending(), q.done, q.failed), (0, 2, 0), "{q:?}");
    let rows = c
        .query_text("SELECT job_id, worker_id FROM rediagnoses ORDER BY job_id")
        .expect("rows");
    assert_eq!(rows.len(), 2, "{rows:?}");
    assert!(
        rows.iter().all(|r| r[1].as_deref() != Some("b")),
        "{rows:?}"
    );
}

/// Waits for `w` to exit (panics after `limit`); its JSON report.
fn report_of(w: &mut Child, name: &str, limit: Duration) -> serde_json::Value {
    let deadline = Instant::now() + limit;
    while w.try_wait().expect("wait").is_none() {
        assert!(Instant::now() < deadline, "worker {name} did not finish");
        std::thread::sleep(Duration::from_millis(50));
    }
    let (status, out, err) = w.wait_with_output_ref();
    assert!(status.success(), "{name}: {err}");
    serde_json::from_str(&out).expect("worker report")
}

fn env_or(key: &str, default: usize) -> usize {
    std::env::var(key)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}
