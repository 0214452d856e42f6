//! The queue's administration: `fleet rediagnose --retry-failed`, the gap jobs' queue SQL, and
//! the upgrade of a centre of schema version 2 that holds jobs.

use super::common::postgres::PgServer;
use super::{column, count, gtwatch, ok};
use gtwatch::fleet::rediagnose::{self, EnqueueRequest, JobKind};
use gtwatch::fleet::regap::{self, GapJobResult};
use gtwatch::fleet::Centre;
use std::time::Duration;

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
/// a failed job is read as it is (its history without corrections), then upgraded to the
/// newest version by the next edge connection: the jobs become diagnosis jobs, a gap job of
/// the same start-up and hash can be queued beside them, and the failed one can be retried.
#[test]
fn a_version_2_centre_with_jobs_is_upgraded_to_gap_jobs() {
    let pg = PgServer::start();
    let url = pg.create_db("fleet_upgrade");
    let mut admin = postgres::Client::connect(&url, postgres::NoTls).expect("admin");
    admin
        .batch_execute(include_str!("../../migrations/postgres/0001_fleet.sql"))
        .expect("0001");
    admin
        .batch_execute(include_str!(
            "../../migrations/postgres/0002_rediagnosis.sql"
        ))
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
               VALUES ('u', 1, 'h', 'done', 1), ('u', 2, 'h', 'failed', 3);
             INSERT INTO diagnoses (unit_id, edge_id, segment_id, method, d_gc)
               VALUES ('u', 7, 1, 'B', 1.5);
             INSERT INTO units (unit_id, gtwatch_version) VALUES ('u', 'old');",
        )
        .expect("a version 2 centre with jobs");
    // Read as it is (no upgrade): its history has no corrections table to join.
    let mut old = Centre::connect_existing(&url, Duration::from_secs(5)).expect("read");
    assert!(!old.has_corrections().expect("version"));
    let rows = gtwatch::fleet::fleet_history(&mut old, &Default::default()).expect("history");
    assert_eq!(rows.len(), 1, "{rows:?}");
    assert_eq!(
        (rows[0].health.get("D_GC"), &rows[0].instrument_step),
        (Some(&1.5), &None)
    );
    let status = gtwatch::fleet::fleet_status(&mut old).expect("status");
    assert_eq!(status.len(), 1, "{status:?}");
    let count = |t: &str| {
        status[0]
            .counts
            .iter()
            .find(|(n, _)| n == t)
            .map(|(_, n)| *n)
    };
    assert_eq!(
        (count("diagnoses"), count("instrument_corrections")),
        (Some(1), Some(0))
    );
    drop(old);
    let mut c = Centre::connect(&url, Duration::from_secs(5)).expect("upgrade");
    assert_eq!(
        c.schema_version().expect("version"),
        gtwatch::fleet::centre::supported_version()
    );
    assert!(c.has_corrections().expect("version"));
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
