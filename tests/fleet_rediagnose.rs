//! Distributed re-diagnosis (issue 25 item 3) against a real PostgreSQL server
//! (tests/common/postgres.rs): an edge replays a log of six start-ups and diagnoses them with a
//! small budget, syncs into the centre; `gtwatch fleet rediagnose` queues one job per start-up
//! (again: nothing more); three `gtwatch fleet worker` processes with a 2 s lease run them, one
//! `kill -9`ed while it holds a job. Every job is then done exactly once (one result per job,
//! none pending or failed, the killed worker's job finished by another after its lease ran
//! out), and every result is bit for bit the edge's own stored diagnosis under the same config
//! hash. Also the queue's SQL alone: claim, renewal, a lost lease that must not write, and
//! `SKIP LOCKED` between two claimers; gap-analysis jobs (`--gap`) whose reports are the edge
//! daemon's own; and `--retry-failed`.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

mod common;

use common::postgres::PgServer;
use gtwatch::engine::simulation::run_scenario;
use gtwatch::engine::{Engine, Scenario};
use gtwatch::fleet::rediagnose::{self, EnqueueRequest, JobKind, JobResult};
use gtwatch::fleet::regap::{self, GapJobResult};
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

/// A gap report without what depends on the machine and the moment: its wall times and the
/// thread count it ran on (the analysis itself does not depend on them).
fn without_timing(report_json: &str) -> serde_json::Value {
    let mut v: serde_json::Value = serde_json::from_str(report_json).expect("report JSON");
    let obj = v.as_object_mut().expect("a report object");
    for key in ["wall_s", "stage_wall_s", "threads"] {
        assert!(obj.remove(key).is_some(), "the report has {key}");
    }
    v
}

/// Start-ups of the gap test: the analyses are the expensive part.
const GAP_STARTUPS: usize = 2;

/// `fleet rediagnose --gap`: the edge analysed its two start-ups itself (its daemon's gap
/// step, `gap_every_n = 1`) and synced them; one worker runs the two diagnosis and two gap
/// jobs, and each stored gap report is the edge's own, every number (bar wall times and the
/// thread count), with the same verdict shown by `fleet history --config-hash` and the gap
/// jobs counted by `fleet status`.
#[test]
fn gap_jobs_store_the_edge_daemons_own_analyses() {
    let t_all = Instant::now();
    let pg = PgServer::start();
    let url = pg.create_db("fleet_regap");
    let dir = tempfile::tempdir().expect("tempdir");
    let cfg = build_edge(dir.path(), GAP_STARTUPS, 100, 1);
    let cfg_s = cfg.to_str().expect("utf8");
    sync_edge(dir.path(), &url);
    let mut centre = Centre::connect_existing(&url, Duration::from_secs(5)).expect("centre");
    let n = GAP_STARTUPS as i64;
    assert_eq!(
        count(&mut centre, "SELECT count(*) FROM gap_analyses"),
        n,
        "the edge analysed each start-up"
    );

    let doc = rediagnose(&url, cfg_s, &["--gap"]);
    assert_eq!(doc["enqueue"]["enqueued"], n, "{doc:#}");
    assert_eq!(doc["gap_enqueue"]["enqueued"], n, "{doc:#}");
    assert_eq!(doc["gap_enqueue"]["kind"], "gap", "{doc:#}");
    assert_eq!(doc["gap_queue"]["waiting"], n, "{doc:#}");
    assert_eq!(doc["queue"]["waiting"], n, "{doc:#}");
    let hash = doc["enqueue"]["config_hash"]
        .as_str()
        .expect("hash")
        .to_string();
    let again = rediagnose(&url, cfg_s, &["--gap"]);
    assert_eq!(again["gap_enqueue"]["enqueued"], 0, "{again:#}");
    assert_eq!(again["gap_enqueue"]["already_queued"], n, "{again:#}");

    let t_work = Instant::now();
    let mut w = worker(&url, "g1");
    let rep = report_of(&mut w, "g1", Duration::from_secs(300));
    eprintln!(
        "FLEET-REGAP worker: {rep}, {:.1} s",
        t_work.elapsed().as_secs_f64()
    );
    assert_eq!(rep["done"], 2 * n, "{rep:#}");
    assert_eq!(rep["gap_done"], n, "{rep:#}");
    assert_eq!(rep["failed"], 0, "{rep:#}");
    assert_results_are_the_edges(&mut centre);

    // Every gap report is the edge's own, start-up by start-up.
    let edge = centre
        .query_text(
            "SELECT segment_id, effect, report_json FROM gap_analyses
             WHERE unit_id = 'gt-redo' ORDER BY segment_id",
        )
        .expect("edge analyses");
    let redone = regap::regap_analyses(&mut centre, Some(&hash)).expect("re-analyses");
    assert_eq!(redone.len(), edge.len());
    for (e, r) in edge.iter().zip(&redone) {
        assert_eq!(e[0].as_deref(), Some(r.segment_id.to_string().as_str()));
        assert_eq!(e[1].as_deref(), Some(r.effect.as_str()));
        assert_eq!((r.holdout_segment_id, r.worker_id.as_str()), (None, "g1"));
        assert_eq!(
            without_timing(&r.report_json),
            without_timing(e[2].as_deref().expect("edge report")),
            "segment {}: the gap re-analysis differs from the edge's",
            r.segment_id
        );
    }
    eprintln!(
        "FLEET-REGAP {} gap reports equal to the edge's (effects {:?})",
        redone.len(),
        redone.iter().map(|r| r.effect.as_str()).collect::<Vec<_>>()
    );

    let out = ok(
        gtwatch(&[
            "fleet",
            "history",
            "--postgres-url",
            &url,
            "--config-hash",
            &hash,
            "--format",
            "json",
        ]),
        "fleet history",
    );
    let history: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let rows = history.as_array().expect("rows");
    assert_eq!(rows.len(), 2 * GAP_STARTUPS, "{history:#}");
    for row in rows {
        let r = redone
            .iter()
            .find(|r| serde_json::json!(r.segment_id) == row["segment_id"])
            .expect("a re-analysis of the row's start-up");
        assert_eq!(row["gap_verdict"], serde_json::json!(r.effect), "{row:#}");
    }
    let out = ok(
        gtwatch(&["fleet", "status", "--postgres-url", &url, "--json"]),
        "fleet status",
    );
    let status: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(status["rediagnosis"]["gap"]["done"], n, "{status:#}");
    assert_eq!(status["rediagnosis"]["diagnose"]["done"], n, "{status:#}");
    eprintln!("FLEET-REGAP test {:.1} s", t_all.elapsed().as_secs_f64());
}

/// `fleet rediagnose --retry-failed`: failed jobs (of a unit, of a hash, or all) go back to
/// pending with their attempts kept and their error cleared; a done one stays done. Also the
/// gap jobs' queue SQL: a claimed gap job says so, and a worker without its lease cannot store
/// its analysis.
#[test]
fn retry_failed_puts_failed_jobs_back() {
    let pg = PgServer::start();
    let url = pg.create_db("fleet_retry");
    let mut c = Centre::connect(&url, Duration::from_secs(5)).expect("centre");
    c.query_text(
        "INSERT INTO segments (unit_id, edge_id, kind, start_ms, end_ms, status)
           VALUES ('u1', 1, 'startup', 10000, 20000, 'diagnosed'),
                  ('u1', 2, 'startup', 30000, 40000, 'diagnosed'),
                  ('u2', 1, 'startup', 10000, 20000, 'diagnosed');
         INSERT INTO sample_windows (unit_id, segment_id, from_ms, end_ms)
           VALUES ('u1', 1, 0, 20000), ('u1', 2, 20000, 40000), ('u2', 1, 0, 20000);",
    )
    .expect("rows");
    let req = |hash: &str, kind: JobKind| EnqueueRequest {
        units: vec![],
        since_ms: None,
        config_hash: hash.into(),
        engine_name: "e".into(),
        engine_toml: hash.into(),
        settings_json: "{}".into(),
        kind,
    };
    for (hash, kind) in [
        ("h1", JobKind::Diagnose),
        ("h1", JobKind::Gap),
        ("h2", JobKind::Diagnose),
    ] {
        let r = rediagnose::enqueue(&mut c, &req(hash, kind)).expect("enqueue");
        assert_eq!((r.enqueued, r.kind), (3, kind), "{r:?}");
    }
    let lease = Duration::from_secs(30);
    let mut c2 = Centre::connect_existing(&url, Duration::from_secs(5)).expect("centre 2");
    let mut gap_jobs = 0;
    let mut stored = None;
    while let Some(job) = rediagnose::claim(&mut c, "w", lease).expect("claim") {
        if job.kind == JobKind::Gap && stored.is_none() {
            gap_jobs += 1;
            let result = GapJobResult {
                analysis: gtwatch::store::NewGapAnalysis {
                    segment_id: job.segment_id,
                    holdout_segment_id: None,
                    effect: "none".into(),
                    shrinkage: f64::NAN,
                    confidence: 0.0,
                    baseline_fit_quality: "good".into(),
                    normalised_residual: 0.7,
                    report_json: "{}".into(),
                },
                wall_s: 0.1,
            };
            assert!(
                !regap::complete_gap(&mut c2, &job, "other", &result).expect("complete"),
                "not the holder"
            );
            assert!(regap::complete_gap(&mut c2, &job, "w", &result).expect("complete"));
            stored = Some(job);
            continue;
        }
        gap_jobs += usize::from(job.kind == JobKind::Gap);
        assert!(rediagnose::fail(&mut c, job.id, "w", "boom").expect("fail"));
    }
    assert_eq!(gap_jobs, 3);
    let stored = stored.expect("a gap job");
    assert_eq!(
        count(
            &mut c,
            "SELECT count(*) FROM regap_analyses WHERE shrinkage IS NULL AND worker_id = 'w'"
        ),
        1
    );

    let retry = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec![
            "fleet",
            "rediagnose",
            "--postgres-url",
            &url,
            "--retry-failed",
            "--json",
        ];
        args.extend_from_slice(extra);
        let out = ok(gtwatch(&args), "retry-failed");
        serde_json::from_slice(&out.stdout).expect("json")
    };
    // u1 under h1: two start-ups × two kinds, one of them done.
    let doc = retry(&["--unit", "u1", "--config-hash", "h1"]);
    assert_eq!(doc["retried"], 3, "{doc:#}");
    assert_eq!(
        (&doc["queue"]["waiting"], &doc["gap_queue"]["waiting"]),
        (&serde_json::json!(2), &serde_json::json!(1)),
        "{doc:#}"
    );
    assert_eq!(doc["gap_queue"]["done"], 1, "{doc:#}");
    let back = c
        .query_text(
            "SELECT state, attempts, error IS NULL, lease_owner IS NULL, done_by IS NULL
             FROM rediagnosis_jobs WHERE unit_id = 'u1' AND config_hash = 'h1'
             ORDER BY id",
        )
        .expect("jobs");
    let pending = vec![
        Some("pending".to_string()),
        Some("1".to_string()),
        Some("t".to_string()),
        Some("t".to_string()),
        Some("t".to_string()),
    ];
    assert_eq!(
        back.iter().filter(|r| **r == pending).count(),
        3,
        "{back:?}"
    );
    let state_of_stored = column(
        &mut c,
        &format!(
            "SELECT state FROM rediagnosis_jobs WHERE id = {}",
            stored.id
        ),
    );
    assert_eq!(state_of_stored, vec![Some("done".to_string())]);
    // The rest: u2 under h1 (both kinds) and all three under h2.
    let doc = retry(&[]);
    assert_eq!(doc["retried"], 5, "{doc:#}");
    assert_eq!(
        (&doc["queue"]["waiting"], &doc["queue"]["failed"]),
        (&serde_json::json!(6), &serde_json::json!(0)),
        "{doc:#}"
    );
    assert_eq!(retry(&[])["retried"], 0);
    // A retried job is claimed again, its attempt counted on.
    let again = rediagnose::claim(&mut c, "w2", lease)
        .expect("claim")
        .expect("a job");
    assert_eq!(again.attempts, 2);
    let out = ok(
        gtwatch(&["fleet", "status", "--postgres-url", &url, "--json"]),
        "fleet status",
    );
    let status: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(status["rediagnosis"]["gap"]["done"], 1, "{status:#}");
    assert_eq!(status["rediagnosis"]["diagnose"]["leased"], 1, "{status:#}");
}

/// A centre of schema version 2 (made from the released 0001 and 0002 files) holding a done and
/// a failed job is upgraded to version 3 by the next connection: the jobs become diagnosis
/// jobs, a gap job of the same start-up and hash can be queued beside them, and the failed one
/// can be retried.
#[test]
fn a_version_2_centre_with_jobs_is_upgraded_to_gap_jobs() {
    let pg = PgServer::start();
    let url = pg.create_db("fleet_upgrade");
    let mut admin = postgres::Client::connect(&url, postgres::NoTls).expect("admin");
    admin
        .batch_execute(include_str!("../migrations/postgres/0001_fleet.sql"))
        .expect("0001");
    admin
        .batch_execute(include_str!("../migrations/postgres/0002_rediagnosis.sql"))
        .expect("0002");
    admin
        .batch_execute(
            "INSERT INTO schema_version (version) VALUES (1), (2);
             INSERT INTO segments (unit_id, edge_id, kind, start_ms, end_ms, status)
               VALUES ('u', 1, 'startup', 10000, 20000, 'diagnosed'),
                      ('u', 2, 'startup', 30000, 40000, 'diagnosed');
             INSERT INTO sample_windows (unit_id, segment_id, from_ms, end_ms)
               VALUES ('u', 1, 0, 20000), ('u', 2, 20000, 40000);
             INSERT INTO rediagnosis_configs (config_hash, engine_name, engine_toml, settings_json)
               VALUES ('h', 'e', 'x', '{}');
             INSERT INTO rediagnosis_jobs (unit_id, segment_id, config_hash, state, attempts)
               VALUES ('u', 1, 'h', 'done', 1), ('u', 2, 'h', 'failed', 3);",
        )
        .expect("a version 2 centre with jobs");
    let mut c = Centre::connect(&url, Duration::from_secs(5)).expect("upgrade");
    assert_eq!(c.schema_version().expect("version"), 3);
    assert_eq!(
        column(&mut c, "SELECT kind FROM rediagnosis_jobs ORDER BY id"),
        vec![Some("diagnose".to_string()), Some("diagnose".to_string())]
    );
    let req = |kind: JobKind| EnqueueRequest {
        units: vec![],
        since_ms: None,
        config_hash: "h".into(),
        engine_name: "e".into(),
        engine_toml: "x".into(),
        settings_json: "{}".into(),
        kind,
    };
    let diag = rediagnose::enqueue(&mut c, &req(JobKind::Diagnose)).expect("enqueue");
    assert_eq!((diag.enqueued, diag.already_queued), (0, 2), "{diag:?}");
    let gap = rediagnose::enqueue(&mut c, &req(JobKind::Gap)).expect("enqueue gap");
    assert_eq!((gap.enqueued, gap.already_queued), (2, 0), "{gap:?}");
    let retried =
        rediagnose::retry_failed(&mut c, &rediagnose::RetryFilter::default()).expect("retry");
    assert_eq!(retried, 1);
    let q = rediagnose::queue_counts(&mut c, Some("h"), Some(JobKind::Diagnose)).expect("q");
    assert_eq!((q.waiting, q.done, q.failed), (1, 1, 0), "{q:?}");
    let job = rediagnose::claim(&mut c, "w", Duration::from_secs(30))
        .expect("claim")
        .expect("the retried job");
    assert_eq!(
        (job.segment_id, job.kind, job.attempts),
        (2, JobKind::Diagnose, 4)
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

/// The acceptance figure of issue 25 item 3, by hand (minutes):
/// `BENCH_STARTUPS=200 BENCH_WORKERS=4 BENCH_KILL=2 BENCH_RUNS=100 cargo test --release
///  --test fleet_rediagnose bench_ -- --ignored --nocapture`.
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
