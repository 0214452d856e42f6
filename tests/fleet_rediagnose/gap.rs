//! Gap-analysis jobs (`fleet rediagnose --gap`): a worker's report is the edge daemon's own.

use super::common::postgres::PgServer;
use super::{
    assert_results_are_the_edges, build_edge, count, gtwatch, ok, rediagnose, report_of, sync_edge,
    worker,
};
use gtwatch::fleet::regap;
use gtwatch::fleet::Centre;
use std::time::{Duration, Instant};

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
