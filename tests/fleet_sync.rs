//! Fleet sync (issue 25 item 1) against a real PostgreSQL server (tests/common/postgres.rs):
//! (a) three units' edge databases sync into one centre, whose rows per table then equal each
//! edge's, and a second sync sends nothing; (b) the centre crashes and restarts at seeded
//! random moments during repeated syncs (12 interruptions), and after a final sync nothing is
//! lost or doubled; (c) a centre that refuses (wrong password, a newer schema) gives a clear
//! error and the edge's high-water marks do not move.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use common::postgres::{PgServer, PG_PASSWORD, PG_USER};
use gtwatch::fleet::{sync_once, Centre, FleetConfig, FleetError};
use gtwatch::store::{FleetMark, Store};
use rand::{Rng, SeedableRng};
use std::path::Path;
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

const DAY_MS: i64 = 86_400_000;

/// One simulated start-up, as (signal index, ms from its start, value), simulated once.
fn startup_trace() -> &'static Vec<(usize, i64, f64)> {
    static TRACE: OnceLock<Vec<(usize, i64, f64)>> = OnceLock::new();
    TRACE.get_or_init(|| {
        use gtwatch::engine::sensors::MeasurementOptions;
        use gtwatch::engine::simulation::run_scenario;
        use gtwatch::engine::{Engine, Scenario, Trace};
        use gtwatch::signals::Signal;
        let engine = Engine::reference().expect("engine");
        let health = gtwatch::health::HealthParams::default();
        let (samples, _) =
            run_scenario(&engine.model(&health), &Scenario::startup(engine.cfg())).expect("runs");
        let o = MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed: 7,
        };
        let t = Trace::from_truth(&engine, &samples, Some(&o));
        let mut out = Vec::new();
        for k in 0..t.len() {
            for (i, s) in Signal::ALL.iter().enumerate() {
                let v = t.measured[k][s.index()];
                if v.is_finite() {
                    out.push((i, (t.t_s[k] * 1000.0).round() as i64, v));
                }
            }
        }
        out
    })
}

/// An edge database with `startups` detected start-ups one day apart from `t0_ms`, a Method B
/// result for each, the last two corrected for a fuel meter's step, a gap analysis of the
/// first, two washes (one confirmed) and an advice.
fn build_edge(path: &Path, startups: usize, t0_ms: i64) {
    use gtwatch::quality::Quality;
    use gtwatch::signals::Signal;
    use gtwatch::store::{Sample, TagInfo};
    let mut store = Store::open(path).expect("open");
    let ids: Vec<i64> = Signal::ALL
        .iter()
        .map(|s| store.ensure_tag(&TagInfo::for_signal(*s)).expect("tag"))
        .collect();
    for k in 0..startups {
        let batch: Vec<Sample> = startup_trace()
            .iter()
            .map(|&(i, dt, v)| Sample {
                tag: ids[i],
                t_ms: t0_ms + k as i64 * DAY_MS + dt,
                value: v,
                quality: Quality::Good,
            })
            .collect();
        store.insert_samples(&batch).expect("insert");
        gtwatch::detect::scan(&mut store, &gtwatch::detect::DetectorConfig::default())
            .expect("scan");
    }
    drop(store);
    let c = rusqlite::Connection::open(path).expect("sqlite");
    let segs: Vec<i64> = c
        .prepare("SELECT id FROM segments ORDER BY id")
        .expect("prep")
        .query_map([], |r| r.get(0))
        .expect("q")
        .collect::<Result<_, _>>()
        .expect("ids");
    assert!(segs.len() >= startups, "{} segments", segs.len());
    for (k, id) in segs.iter().enumerate() {
        c.execute(
            "INSERT INTO diagnoses (segment_id, method, d_gc, d_ec, d_gt, d_et, d_gp, d_ep,
               objective, model_runs, wall_s, model_version, created_at_ms, fit_quality)
             VALUES (?1, 'B', ?2, 0.5, 0.1, 0.0, 0.0, 0.0, 1.0, 400, 12.5, 'test', ?3, 'good')",
            rusqlite::params![id, 0.1 * k as f64, t0_ms + k as i64],
        )
        .expect("diagnosis");
        c.execute(
            "UPDATE segments SET status = 'diagnosed' WHERE id = ?1",
            [id],
        )
        .expect("diagnosed");
    }
    // The wash advice's correction of the last two start-ups (one on a unit of one): a fuel
    // meter 2.5 % high from the first of them.
    let corrected = &segs[segs.len().saturating_sub(2)..];
    for id in corrected {
        c.execute(
            "INSERT INTO instrument_corrections (segment_id, onset_segment_id, effect, unit,
               magnitude, magnitude_sigma, d_gc, d_ec, d_gt, d_et, d_gp, d_ep,
               sigma_gc, sigma_ec, sigma_gt, sigma_et, sigma_gp, sigma_ep, refreshed_ms)
             VALUES (?1, ?2, 'fuel_meter', 'fraction', 0.025, 0.002, ?3, 0.25, 0.125, 0.0,
               0.0, 0.0, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, ?4)",
            rusqlite::params![id, corrected[0], 1.5 + *id as f64, t0_ms],
        )
        .expect("correction");
    }
    c.execute(
        "INSERT INTO gap_analyses (segment_id, effect, shrinkage, confidence, baseline_fit_quality,
           normalised_residual, report_json, gtwatch_version, created_at_ms)
         VALUES (?1, 'fuel_meter', 0.1, 0.2, 'suspect', 0.9,
           '{\"verdict\": {\"health_after\": {\"D_GC\": 0.5, \"D_EC\": 0.25, \"D_GT\": 0.125,
             \"D_ET\": 0.0, \"D_GP\": 0.0, \"D_EP\": -0.25}}}', 'test', ?2)",
        rusqlite::params![segs[0], t0_ms],
    )
    .expect("gap");
    c.execute_batch(&format!(
        "INSERT INTO washes (t_ms, kind, note) VALUES ({t0_ms}, 'offline', 'recorded');
         INSERT INTO washes (t_ms, kind, note) VALUES ({}, 'offline', 'detected: step');
         INSERT INTO recommendations (t_ms, kind, message, basis)
           VALUES ({t0_ms}, 'wash_offline', 'wash in 19 days', '{{}}');",
        t0_ms + DAY_MS
    ))
    .expect("washes");
}

fn edge_counts(path: &Path) -> Vec<(String, i64)> {
    let s = Store::open_readonly(path).expect("ro");
    s.fleet_counts()
        .expect("counts")
        .into_iter()
        .map(|(t, n)| (t.to_string(), n))
        .collect()
}

fn centre_counts(centre: &mut Centre, unit: &str) -> Vec<(String, i64)> {
    [
        "segments",
        "segment_phases",
        "diagnoses",
        "gap_analyses",
        "washes",
        "recommendations",
        "samples",
        "instrument_corrections",
    ]
    .iter()
    .map(|t| (t.to_string(), centre.count(t, unit).expect("count")))
    .collect()
}

fn marks(path: &Path) -> Vec<FleetMark> {
    Store::open_readonly(path)
        .expect("ro")
        .all_fleet_marks()
        .expect("marks")
}

fn gtwatch(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .expect("run gtwatch")
}

/// `gtwatch sync --db DB --unit UNIT --postgres-url URL [extra…]`.
fn gtwatch_sync(db: &str, unit: &str, url: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["sync", "--db", db, "--unit", unit, "--postgres-url", url];
    args.extend_from_slice(extra);
    gtwatch(&args)
}

/// One sync through the library: rows read through a read-only connection, marks written
/// through the edge's own store (as `gtwatch sync` does).
fn sync_lib(path: &Path, cfg: &FleetConfig) -> Result<gtwatch::fleet::SyncReport, FleetError> {
    let mut centre = Centre::connect(&cfg.postgres_url, Duration::from_secs(5))?;
    let read = Store::open_readonly(path)?;
    let mut marks = Store::open(path)?;
    sync_once(&read, &mut marks, &mut centre, cfg, &AtomicBool::new(false))
}

/// `gtwatch fleet history` (issue 25 item 2): the centre's results of each unit, with and
/// without `--unit`, are the edge's own `gtwatch history` (segment, start, method, every
/// parameter and σ, fit quality, gap verdict).
fn fleet_history_equals_each_edges_history(url: &str, dir: &Path, units: &[&str]) {
    let json = |out: std::process::Output| -> Vec<serde_json::Value> {
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice::<serde_json::Value>(&out.stdout)
            .expect("json")
            .as_array()
            .expect("array")
            .clone()
    };
    let all = json(gtwatch(&[
        "fleet",
        "history",
        "--postgres-url",
        url,
        "--format",
        "json",
    ]));
    let key = |r: &serde_json::Value| {
        serde_json::json!([
            r["segment_id"],
            r["start_ms"],
            r["method"],
            r["health"],
            r["sigma"],
            r["fit_quality"],
            r["gap_verdict"],
            r["gap_health_after"],
            r["instrument_step"]
        ])
    };
    let mut total = 0;
    let mut corrected = 0;
    let mut corrected_lines = 0;
    for unit in units {
        let db = dir.join(format!("{unit}.db"));
        let edge = json(gtwatch(&[
            "history",
            "--db",
            db.to_str().expect("utf8"),
            "--format",
            "json",
        ]));
        let one = json(gtwatch(&[
            "fleet",
            "history",
            "--postgres-url",
            url,
            "--unit",
            unit,
            "--format",
            "json",
        ]));
        assert!(!edge.is_empty(), "{unit}: no results at the edge");
        corrected += edge
            .iter()
            .filter(|r| r["instrument_step"]["effect"] == "fuel_meter")
            .count();
        let table = gtwatch(&["history", "--db", db.to_str().expect("utf8")]);
        corrected_lines += String::from_utf8_lossy(&table.stdout)
            .matches("corrected:")
            .count();
        assert_eq!(
            one.iter().map(key).collect::<Vec<_>>(),
            edge.iter().map(key).collect::<Vec<_>>(),
            "{unit}: centre vs edge history"
        );
        assert!(one.iter().all(|r| r["unit_id"] == *unit));
        let from_all: Vec<_> = all
            .iter()
            .filter(|r| r["unit_id"] == *unit)
            .map(key)
            .collect();
        assert_eq!(from_all, one.iter().map(key).collect::<Vec<_>>());
        total += edge.len();
    }
    assert_eq!(
        all.len(),
        total,
        "the fleet history holds every unit's results once"
    );
    assert!(corrected >= units.len(), "{corrected} corrected results");
    let csv = gtwatch(&["fleet", "history", "--postgres-url", url, "--format", "csv"]);
    let text = String::from_utf8_lossy(&csv.stdout);
    assert_eq!(text.lines().count(), total + 1, "{text}");
    assert!(
        text.starts_with("unit_id,segment_id,start_utc,method,D_GC,sigma_D_GC"),
        "{text}"
    );
    assert!(
        text.lines()
            .next()
            .is_some_and(|h| h.ends_with(",gap_verdict,instrument_step,D_GC_corrected,D_EC_corrected,D_GT_corrected,D_ET_corrected,D_GP_corrected,D_EP_corrected")),
        "{text}"
    );
    assert_eq!(text.matches(",fuel_meter +2.").count(), corrected, "{text}");
    // The table: a `corrected:` line under each result the edge's history shows one under (the
    // wash advice's corrections, and a first start-up whose own gap analysis names the meter).
    let table = gtwatch(&["fleet", "history", "--postgres-url", url]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(corrected_lines > corrected, "{corrected_lines} lines");
    assert_eq!(
        text.matches("corrected:").count(),
        corrected_lines,
        "{text}"
    );
    assert!(
        text.contains("instrument fuel_meter (this start-up's gap analysis)"),
        "{text}"
    );
    assert!(
        text.contains("instrument fuel_meter +2.50 ± 0.20 % from start-up"),
        "{text}"
    );
}

/// A refresh of gt-b's wash advice that no longer corrects its first corrected start-up and
/// resizes the other: the next sync sends one row and removes one, and the centre keeps
/// exactly the edge's corrections.
fn corrections_follow_a_refresh(db_b: &Path, url: &str) {
    rusqlite::Connection::open(db_b)
        .expect("sqlite")
        .execute_batch(
            "DELETE FROM instrument_corrections
               WHERE segment_id = (SELECT MIN(segment_id) FROM instrument_corrections);
             UPDATE instrument_corrections SET magnitude = 0.027, d_gc = 2.75;",
        )
        .expect("refresh");
    let r = sync_lib(db_b, &FleetConfig::new("gt-b", url)).expect("sync");
    let c = r
        .streams
        .iter()
        .find(|s| s.table == "instrument_corrections")
        .expect("corrections");
    assert_eq!((c.sent, c.removed), (1, 1), "{c:?}");
    assert_eq!(r.total_sent(), 1, "{r:?}");
    let mut centre = Centre::connect_existing(url, Duration::from_secs(5)).expect("centre");
    let central = centre
        .query_text(
            "SELECT magnitude::text, d_gc::text FROM instrument_corrections WHERE unit_id = 'gt-b'",
        )
        .expect("corrections");
    assert_eq!(
        central,
        vec![vec![Some("0.027".to_string()), Some("2.75".to_string())]]
    );
}

#[test]
fn three_units_sync_into_one_centre_and_a_second_sync_sends_nothing() {
    let pg = PgServer::start();
    let url = pg.create_db("fleet_a");
    let dir = tempfile::tempdir().expect("tempdir");
    let units = [("gt-a", 2usize), ("gt-b", 3), ("gt-c", 1)];
    let centre_id = Centre::connect(&url, Duration::from_secs(5))
        .expect("centre")
        .id;
    for (k, (unit, n)) in units.iter().enumerate() {
        let db = dir.path().join(format!("{unit}.db"));
        build_edge(&db, *n, 1_700_000_000_000 + k as i64 * 10 * DAY_MS);
        // Before its first sync the lag (the metrics' gauge) is every row the edge holds.
        let lag = |db: &Path| {
            gtwatch::fleet::sync::sync_lag(
                &Store::open_readonly(db).unwrap(),
                &centre_id,
                unit,
                true,
            )
            .expect("lag")
        };
        let edge = edge_counts(&db);
        let expect: Vec<(&str, u64)> = gtwatch::fleet::sync::LAG_STREAMS
            .iter()
            .map(|t| {
                (
                    *t,
                    edge.iter().find(|(n, _)| n == t).expect("table").1 as u64,
                )
            })
            .collect();
        assert_eq!(lag(&db), expect, "{unit}: lag before the first sync");
        let t0 = Instant::now();
        let out = gtwatch_sync(db.to_str().expect("utf8"), unit, &url, &["--json"]);
        let wall = t0.elapsed().as_secs_f64();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        let sent: u64 = report["streams"]
            .as_array()
            .expect("streams")
            .iter()
            .map(|s| s["sent"].as_u64().expect("sent"))
            .sum();
        eprintln!(
            "FLEET-SYNC unit {unit}: {n} start-ups, {sent} rows sent in {:.2} s (sync {:.2} s wall of the command)",
            report["wall_s"].as_f64().unwrap_or(0.0),
            wall
        );
        assert!(
            lag(&db).iter().all(|(_, n)| *n == 0),
            "{unit}: lag after a sync: {:?}",
            lag(&db)
        );
        // The second sync sends nothing new.
        let again = gtwatch_sync(db.to_str().expect("utf8"), unit, &url, &["--json"]);
        assert!(again.status.success());
        let r2: serde_json::Value = serde_json::from_slice(&again.stdout).expect("json");
        for s in r2["streams"].as_array().expect("streams") {
            assert_eq!(s["sent"], 0, "second sync of {unit} sent {s}");
            assert_eq!(s["applied"], 0, "second sync of {unit} changed {s}");
        }
    }
    // A detected wash confirmed and a recorded one removed at the edge: the centre follows.
    let db_a = dir.path().join("gt-a.db");
    rusqlite::Connection::open(&db_a)
        .expect("sqlite")
        .execute_batch(
            "UPDATE washes SET note = 'confirmed; step' WHERE note LIKE 'detected:%';
             DELETE FROM washes WHERE note = 'recorded';",
        )
        .expect("confirm and reject");
    let r = sync_lib(&db_a, &FleetConfig::new("gt-a", &url)).expect("sync");
    let w = r
        .streams
        .iter()
        .find(|s| s.table == "washes")
        .expect("washes");
    assert_eq!((w.sent, w.removed), (1, 1), "{w:?}");
    assert_eq!(r.total_sent(), 1, "{r:?}");
    corrections_follow_a_refresh(&dir.path().join("gt-b.db"), &url);
    let mut centre = Centre::connect_existing(&url, Duration::from_secs(5)).expect("centre");
    let notes = centre
        .query_text("SELECT note FROM washes WHERE unit_id = 'gt-a'")
        .expect("notes");
    assert_eq!(notes, vec![vec![Some("confirmed; step".to_string())]]);
    for (unit, _) in units {
        let edge = edge_counts(&dir.path().join(format!("{unit}.db")));
        let central = centre_counts(&mut centre, unit);
        eprintln!("FLEET-SYNC counts {unit}: {central:?}");
        assert_eq!(central, edge, "unit {unit}: centre vs edge");
        assert!(edge.iter().all(|(_, n)| *n > 0), "{unit}: {edge:?}");
    }
    let out = gtwatch(&["fleet", "status", "--postgres-url", &url, "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let st: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let listed: Vec<&str> = st["units"]
        .as_array()
        .expect("units")
        .iter()
        .map(|u| u["unit_id"].as_str().expect("id"))
        .collect();
    assert_eq!(listed, vec!["gt-a", "gt-b", "gt-c"]);
    let table = gtwatch(&["fleet", "status", "--postgres-url", &url]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(text.contains("gt-b") && text.contains("samples"), "{text}");
    fleet_history_equals_each_edges_history(&url, dir.path(), &["gt-a", "gt-b", "gt-c"]);
    // The fleet report: one page naming every unit, its trend drawn, nothing loaded from
    // elsewhere.
    let out_dir = dir.path().join("fleet-report");
    let out = gtwatch(&[
        "fleet",
        "report",
        "--postgres-url",
        &url,
        "--out",
        out_dir.to_str().expect("utf8"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let page = std::fs::read_to_string(out_dir.join("fleet.html")).expect("fleet.html");
    for unit in ["gt-a", "gt-b", "gt-c"] {
        assert!(page.contains(unit), "{unit} missing from the fleet report");
    }
    assert_eq!(page.matches("<svg").count(), 3, "one trend per unit");
    assert!(
        !page.contains("http://") && !page.contains("https://") && !page.contains("src="),
        "the page refers to something outside itself"
    );
    eprintln!("{text}");
}

/// Key columns of every central row of `unit`, as text, in key order (the checksum compared).
fn central_keys(centre: &mut Centre, unit: &str) -> String {
    let q = format!(
        "SELECT (SELECT string_agg(edge_id || ':' || coalesce(end_ms, -1) || ':' || status, ',' ORDER BY edge_id) FROM segments WHERE unit_id = '{unit}'),
                (SELECT string_agg(edge_id || ':' || segment_id || ':' || d_gc, ',' ORDER BY edge_id) FROM diagnoses WHERE unit_id = '{unit}'),
                (SELECT string_agg(edge_id || ':' || note, ',' ORDER BY edge_id) FROM washes WHERE unit_id = '{unit}'),
                (SELECT count(*) || ':' || sum(t_ms) || ':' || count(DISTINCT tag) || ':' || round(sum(value)::numeric, 3) FROM samples WHERE unit_id = '{unit}')"
    );
    let rows = centre.query_text(&q).expect("keys");
    format!("{:?}", rows)
}

#[test]
fn a_centre_crashing_during_syncs_loses_and_doubles_nothing() {
    let pg = Arc::new(PgServer::start());
    let url = pg.create_db("fleet_b");
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("edge.db");
    build_edge(&db, 3, 1_700_000_000_000);
    let mut cfg = FleetConfig::new("gt-crash", &url);
    cfg.batch_rows = 400;
    // A reference centre synced without interruptions: what the crashed one must end up as.
    let ref_url = pg.create_db("fleet_ref");
    let ref_db = dir.path().join("ref.db");
    std::fs::copy(&db, &ref_db).expect("copy");
    let ref_cfg = FleetConfig::new("gt-crash", &ref_url);
    sync_lib(&ref_db, &ref_cfg).expect("reference sync");

    let done = Arc::new(AtomicBool::new(false));
    let interrupter = {
        let pg = Arc::clone(&pg);
        let done = Arc::clone(&done);
        std::thread::spawn(move || {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(25);
            for _ in 0..12 {
                std::thread::sleep(Duration::from_millis(rng.random_range(50..400)));
                pg.crash();
                std::thread::sleep(Duration::from_millis(rng.random_range(0..150)));
                pg.start_again();
            }
            done.store(true, Ordering::Relaxed);
        })
    };
    let (mut ok, mut failed) = (0u32, 0u32);
    let mut sent_total = 0u64;
    while !done.load(Ordering::Relaxed) {
        match sync_lib(&db, &cfg) {
            Ok(r) => {
                ok += 1;
                sent_total += r.total_sent();
                if r.total_sent() == 0 {
                    // Caught up: new rows at the edge keep the syncs busy.
                    let c = rusqlite::Connection::open(&db).expect("sqlite");
                    c.execute(
                        "INSERT INTO recommendations (t_ms, kind, message) VALUES (?1, 'wash_offline', 'again')",
                        [ok as i64],
                    )
                    .expect("insert");
                    let ref_c = rusqlite::Connection::open(&ref_db).expect("sqlite");
                    ref_c
                        .execute(
                            "INSERT INTO recommendations (t_ms, kind, message) VALUES (?1, 'wash_offline', 'again')",
                            [ok as i64],
                        )
                        .expect("insert");
                    // Restart the edge's marks from nothing now and then: a full re-send.
                    if ok % 3 == 0 {
                        c.execute("DELETE FROM fleet_sync", []).expect("reset");
                    }
                }
            }
            Err(_) => {
                failed += 1;
                std::thread::sleep(Duration::from_millis(20));
            }
        }
    }
    interrupter.join().expect("interrupter");
    let final_report = sync_lib(&db, &cfg).expect("final sync");
    sync_lib(&ref_db, &ref_cfg).expect("reference catch-up");
    eprintln!(
        "FLEET-CRASH 12 centre crashes: {ok} syncs completed, {failed} interrupted, {sent_total} rows sent before the final sync, which sent {}",
        final_report.total_sent()
    );
    assert!(failed >= 1, "no sync was interrupted");
    let mut centre = Centre::connect_existing(&url, Duration::from_secs(5)).expect("centre");
    let mut reference = Centre::connect_existing(&ref_url, Duration::from_secs(5)).expect("ref");
    let edge = edge_counts(&db);
    assert_eq!(centre_counts(&mut centre, "gt-crash"), edge);
    assert_eq!(centre_counts(&mut reference, "gt-crash"), edge);
    assert_eq!(
        central_keys(&mut centre, "gt-crash"),
        central_keys(&mut reference, "gt-crash")
    );
}

#[test]
fn a_refusing_centre_is_a_clear_error_and_the_marks_stay() {
    let pg = PgServer::start();
    let url = pg.create_db("fleet_c");
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("edge.db");
    build_edge(&db, 1, 1_700_000_000_000);
    let db_s = db.to_str().expect("utf8");

    // Wrong password: the command fails naming the centre and the cause, never the password.
    let wrong = pg.url_with(PG_USER, "not-the-password", "fleet_c");
    let out = gtwatch_sync(db_s, "gt-c", &wrong, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("FLEET-REFUSE wrong password: {}", err.trim());
    assert!(!out.status.success());
    assert!(
        err.contains("cannot connect to the fleet centre")
            && err.contains("password authentication failed"),
        "{err}"
    );
    assert!(!err.contains("not-the-password"), "{err}");
    assert!(marks(&db).is_empty(), "marks moved: {:?}", marks(&db));

    // A good sync, then more rows at the edge and a centre whose schema is newer.
    let cfg = FleetConfig::new("gt-c", &url);
    sync_lib(&db, &cfg).expect("first sync");
    let before = marks(&db);
    assert!(!before.is_empty());
    let c = rusqlite::Connection::open(&db).expect("sqlite");
    c.execute_batch(
        "INSERT INTO recommendations (t_ms, kind, message) VALUES (5, 'wash_offline', 'later');
         INSERT INTO washes (t_ms, kind, note) VALUES (6, 'online', 'later');",
    )
    .expect("more rows");
    let mut admin = postgres::Client::connect(&url, postgres::NoTls).expect("admin");
    admin
        .batch_execute("INSERT INTO schema_version (version) VALUES (99)")
        .expect("newer schema");
    let counts_before = {
        let centre = Centre::connect_existing(
            &pg.url_with(PG_USER, PG_PASSWORD, "fleet_c"),
            Duration::from_secs(5),
        );
        assert!(matches!(
            centre,
            Err(FleetError::SchemaTooNew { found: 99, .. })
        ));
        admin
            .query_one("SELECT count(*) FROM recommendations", &[])
            .expect("count")
            .get::<_, i64>(0)
    };
    let err = sync_lib(&db, &cfg).expect_err("newer schema refused");
    eprintln!("FLEET-REFUSE newer schema: {err}");
    assert!(
        matches!(
            err,
            FleetError::SchemaTooNew {
                found: 99,
                supported,
                ..
            } if supported == gtwatch::fleet::centre::supported_version()
        ),
        "{err}"
    );
    assert!(err.to_string().contains("upgrade gtwatch"), "{err}");
    let out = gtwatch_sync(db_s, "gt-c", &url, &[]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("schema version 99"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        marks(&db),
        before,
        "the marks moved while the centre refused"
    );
    let after: i64 = admin
        .query_one("SELECT count(*) FROM recommendations", &[])
        .expect("count")
        .get(0);
    assert_eq!(after, counts_before);
}

/// The daemon with `[fleet]`: it syncs its database into the centre (marks written through
/// its one writer); a second daemon pointed at a centre that is not there keeps running,
/// counts its failed syncs and stops at once on shutdown.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_daemon_syncs_and_a_missing_centre_does_not_hold_it() {
    use gtwatch::acquire::modbus::SourceKind;
    use gtwatch::daemon::{self, RunOptions};
    // The synchronous PostgreSQL client must not run on the async runtime.
    let (pg, url) = tokio::task::spawn_blocking(|| {
        let pg = PgServer::start();
        let url = pg.create_db("fleet_d");
        (pg, url)
    })
    .await
    .expect("pg");
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("edge.db");
    build_edge(&db, 2, 1_700_000_000_000);
    let config = |fleet_url: &str| {
        let mut c = common::reference_config();
        c.storage.path = db.clone();
        c.acquisition.source = SourceKind::None;
        c.modbus = None;
        c.diagnosis.enabled = false;
        let mut f = FleetConfig::new("gt-daemon", fleet_url);
        f.interval_s = 1;
        f.timeout_s = 2;
        c.fleet = Some(f);
        assert_eq!(c.check(), vec![], "test config is valid");
        c
    };

    let (trigger, shutdown) = gtwatch::shutdown::shutdown_channel();
    let d = tokio::spawn(daemon::run(config(&url), shutdown, RunOptions::default()));
    let edge = edge_counts(&db);
    let t0 = Instant::now();
    loop {
        let u = url.clone();
        let central = tokio::task::spawn_blocking(move || {
            Centre::connect_existing(&u, Duration::from_secs(5))
                .ok()
                .map(|mut c| centre_counts(&mut c, "gt-daemon"))
        })
        .await
        .expect("join");
        if central.as_ref() == Some(&edge) {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "{central:?} vs {edge:?}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    eprintln!("FLEET-DAEMON synced in {:.2} s", t0.elapsed().as_secs_f64());
    trigger.trigger();
    let report = d.await.expect("join").expect("daemon ran");
    assert!(report.sync.syncs_ok >= 1, "{:?}", report.sync);
    assert_eq!(report.sync.syncs_failed, 0, "{:?}", report.sync);
    let m = marks(&db);
    assert!(
        m.iter()
            .any(|m| m.stream == gtwatch::fleet::sync::SAMPLES_STREAM && m.sent == edge[6].1),
        "{m:?}"
    );

    // A centre that is not there (a closed port): failures counted, shutdown prompt.
    let closed = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        l.local_addr().expect("addr").port()
    };
    let dead = pg
        .url_with(PG_USER, PG_PASSWORD, "fleet_d")
        .replace(&pg.port.to_string(), &closed.to_string());
    let (trigger, shutdown) = gtwatch::shutdown::shutdown_channel();
    let d = tokio::spawn(daemon::run(config(&dead), shutdown, RunOptions::default()));
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let t_stop = Instant::now();
    trigger.trigger();
    let report = d.await.expect("join").expect("daemon ran");
    eprintln!(
        "FLEET-DAEMON dead centre: {:?}, shutdown in {:.2} s",
        report.sync,
        t_stop.elapsed().as_secs_f64()
    );
    assert!(report.sync.syncs_failed >= 1, "{:?}", report.sync);
    assert_eq!(report.sync.syncs_ok, 0);
    assert!(t_stop.elapsed() < Duration::from_secs(5));
    assert_eq!(marks(&db), m, "marks moved without a centre");
    drop(pg);
}
