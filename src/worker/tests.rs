use super::*;
use crate::daemon::DiagnosisTask;
use crate::detect::{scan, DetectorConfig};
use crate::engine::sensors::MeasurementOptions;
use crate::engine::simulation::run_scenario;
use crate::engine::{Scenario, Trace};
use crate::health::HealthParams;
use crate::quality::Quality;
use crate::shutdown::shutdown_channel;
use crate::signals::Signal;
use crate::store::StoreOptions;
use crate::store::{HistoryFilter, Sample, TagInfo};
use std::time::Duration;
use tokio::sync::Notify;

fn truth() -> HealthParams {
    HealthParams {
        D_GC: 3.0,
        D_EC: 1.0,
        D_GT: 1.5,
        D_ET: 1.0,
        D_GP: 0.5,
        D_EP: 0.8,
    }
}

/// A noisy simulated start-up of an engine with `truth()` stored at 1 Hz, detected.
fn stored_startup(dir: &std::path::Path) -> Store {
    let engine = Engine::reference().expect("engine");
    let model = engine.model(&truth());
    let (samples, _) = run_scenario(&model, &Scenario::startup(engine.cfg())).expect("runs");
    let o = MeasurementOptions {
        lags: true,
        noise: true,
        bias: false,
        seed: 5,
    };
    let t = Trace::from_truth(&engine, &samples, Some(&o));
    let mut store = Store::open(&dir.join("w.db")).expect("open");
    let ids: Vec<i64> = Signal::ALL
        .iter()
        .map(|s| store.ensure_tag(&TagInfo::for_signal(*s)).expect("tag"))
        .collect();
    let mut batch = Vec::new();
    for k in 0..t.len() {
        let t_ms = 1_700_000_000_000 + (t.t_s[k] * 1000.0).round() as i64;
        for (i, s) in Signal::ALL.iter().enumerate() {
            let v = t.measured[k][s.index()];
            if v.is_finite() {
                batch.push(Sample {
                    tag: ids[i],
                    t_ms,
                    value: v,
                    quality: Quality::Good,
                });
            }
        }
    }
    store.insert_samples(&batch).expect("insert");
    scan(&mut store, &DetectorConfig::default()).expect("scan");
    store
}

fn ctx() -> WorkerContext {
    WorkerContext::load(
        None,
        DiagnosisSettings {
            threads: 2,
            max_model_runs: 300,
            ..DiagnosisSettings::default()
        },
    )
    .expect("context")
}

#[test]
fn worker_diagnoses_a_stored_startup_and_shutdown_leaves_it_pending() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = stored_startup(dir.path());
    let pending = store.pending_segments().expect("pending");
    assert_eq!(pending.len(), 1, "{pending:?}");
    let seg = pending[0].id;
    drop(store);

    // Shutdown while the fit runs: nothing written, the segment still pending. It comes at a
    // third of what a drain of the same start-up takes on this machine (the faster of two
    // probes on a copy, so that tests running beside the probe do not stretch it): a fixed
    // delay raced the fit once Method B took about a second (diagnosed 1 on CI).
    let probe = || {
        let probe = tempfile::tempdir().expect("tempdir");
        let mut s = stored_startup(probe.path());
        let t = std::time::Instant::now();
        let rep = drain_pending(&mut s, &ctx(), &Cancel::new(), None).expect("probe drain");
        assert_eq!(rep.diagnosed, 1, "{rep:?}");
        t.elapsed()
    };
    let span = probe().min(probe());
    let task_ctx = Arc::new(ctx());
    let ctx = ctx();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let db_path = dir.path().join("w.db");
    let rep = rt.block_on(async move {
        // The daemon's shape: the task reads read-only and writes through the one writer.
        let (tx, rx) = crate::store::writer_channel(16);
        let writer = crate::store::spawn_writer(
            Store::open(&db_path).expect("writer's store"),
            rx,
            crate::store::WriterConfig::default(),
        );
        let task = DiagnosisTask {
            db_path,
            store_opts: StoreOptions::default(),
            writer: tx,
            ctx: task_ctx,
            wake: Arc::new(Notify::new()),
            after_result: None,
        };
        let (trigger, shutdown) = shutdown_channel();
        let h = tokio::spawn(task.run(shutdown));
        tokio::time::sleep(span / 3).await;
        trigger.trigger();
        let rep = tokio::time::timeout(Duration::from_secs(60), h)
            .await
            .expect("worker stops soon after shutdown")
            .expect("join");
        writer.await.expect("join").expect("writer");
        rep
    });
    assert!(rep.cancelled, "{rep:?}");
    assert_eq!(rep.diagnosed, 0);
    let mut store = Store::open(&dir.path().join("w.db")).expect("reopen");
    assert_eq!(store.pending_segments().expect("pending").len(), 1);
    assert!(store
        .history(&HistoryFilter::default())
        .expect("h")
        .is_empty());

    // Restart: the pending segment is diagnosed, Method B within 0.5 points of the truth.
    let calls = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let c2 = Arc::clone(&calls);
    let after: AfterResult = Arc::new(move |_s, id, _o, _w| {
        assert_eq!(id, seg);
        c2.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    });
    let rep = drain_pending(&mut store, &ctx, &Cancel::new(), Some(&after)).expect("drain");
    assert_eq!(rep.diagnosed, 1, "{rep:?}");
    assert_eq!(calls.load(std::sync::atomic::Ordering::SeqCst), 1);
    assert!(store.pending_segments().expect("pending").is_empty());
    let h = store
        .history(&HistoryFilter {
            method: Some("B".into()),
            ..HistoryFilter::default()
        })
        .expect("history");
    assert_eq!(h.len(), 1, "{h:?}");
    let t = truth().to_array();
    for (i, n) in HEALTH_NAMES.iter().enumerate() {
        let got = h[0].health[*n];
        assert!((got - t[i]).abs() < 0.5, "{n}: {got} vs {}", t[i]);
        assert!(h[0].sigma.contains_key(*n));
    }
    assert_eq!(h[0].segment_id, seg);
    assert!(h[0].fit_quality.is_some());
    let status: String = store.segment(seg).expect("seg").expect("exists").status;
    assert_eq!(status, "diagnosed");
}

#[test]
fn aborted_segment_is_stored_as_undiagnosable_with_its_reason() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut store = stored_startup(dir.path());
    let seg = store.pending_segments().expect("pending")[0].id;
    store
        .conn_mut()
        .execute(
            "UPDATE segments SET outcome = 'aborted', abort_cause = 'trip' WHERE id = ?1",
            [seg],
        )
        .expect("update");
    let rep = drain_pending(&mut store, &ctx(), &Cancel::new(), None).expect("drain");
    assert_eq!(rep.undiagnosable, 1);
    let r = store.undiagnosable_reasons(seg).expect("reasons");
    assert_eq!(r.len(), 1);
    assert_eq!(r[0].1, "aborted");
    assert!(r[0].2.contains("trip"), "{r:?}");
    assert!(store.pending_segments().expect("pending").is_empty());
}

#[test]
fn fnv1a_known_values() {
    // FNV-1a 64 of "a" followed by the separator byte 0xff.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in [b'a', 0xff] {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    assert_eq!(fnv1a(&[b"a"]), h);
    assert_ne!(fnv1a(&[b"ab"]), fnv1a(&[b"a", b"b"]));
}

/// Issue 12 #3: a segment whose required signals are mostly flagged is never diagnosed; it is
/// stored undiagnosable with the `low_quality` reason naming the signal.
#[test]
fn low_quality_segment_is_stored_undiagnosable() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut store = stored_startup(dir.path());
    let seg = store.pending_segments().expect("pending")[0].id;
    // Flag every third fuel sample as out of range (33 % bad < 90 % good).
    store
        .conn_mut()
        .execute(
            "UPDATE samples SET quality = 1 WHERE (t_ms / 1000) % 3 = 0 AND tag_id =
               (SELECT id FROM tags WHERE signal = 'fuel_kg_s')",
            [],
        )
        .expect("flag");
    let rep = drain_pending(&mut store, &ctx(), &Cancel::new(), None).expect("drain");
    assert_eq!(rep.undiagnosable, 1);
    let r = store.undiagnosable_reasons(seg).expect("reasons");
    assert_eq!(r.len(), 1, "{r:?}");
    assert_eq!(r[0].1, "low_quality");
    assert!(r[0].2.contains("fuel_kg_s"), "{r:?}");
}

/// The daemon's gap step (issue 23 item 4): nothing is analysed while a start-up waits for its
/// diagnosis; a cancelled analysis stores nothing; a diagnosed start-up on the schedule
/// (`gap_every_n = 1`) is analysed and stored once.
#[test]
fn gap_step_analyses_a_diagnosed_startup_once() {
    use super::gap::{analyse_next, GapStep};
    use std::collections::HashSet;
    let dir = tempfile::tempdir().expect("tempdir");
    let mut store = stored_startup(dir.path());
    let ctx = WorkerContext::load(
        None,
        DiagnosisSettings {
            threads: 2,
            max_model_runs: 120,
            gap_every_n: 1,
            ..DiagnosisSettings::default()
        },
    )
    .expect("context");
    let none = HashSet::new();
    let step = analyse_next(&mut store, &ctx, &Cancel::new(), &none).expect("step");
    assert_eq!(step, GapStep::Idle, "the diagnosis queue comes first");
    drain_pending(&mut store, &ctx, &Cancel::new(), None).expect("drain");
    let seg = store
        .history(&HistoryFilter::default())
        .expect("history")
        .first()
        .expect("a result")
        .segment_id;
    let cancelled = Cancel::new();
    cancelled.cancel();
    let step = analyse_next(&mut store, &ctx, &cancelled, &none).expect("step");
    assert_eq!(step, GapStep::Cancelled { segment_id: seg });
    assert!(store.gap_analyses(seg).expect("rows").is_empty());
    let verdict = match analyse_next(&mut store, &ctx, &Cancel::new(), &none).expect("step") {
        GapStep::Stored {
            segment_id, effect, ..
        } => {
            assert_eq!(segment_id, seg);
            effect
        }
        other => panic!("not stored: {other:?}"),
    };
    assert_eq!(store.gap_analyses(seg).expect("rows").len(), 1);
    // `history` shows the verdict beside the start-up's results.
    let rows = store.history(&HistoryFilter::default()).expect("history");
    assert!(rows
        .iter()
        .all(|r| r.gap_verdict.as_deref() == Some(verdict.as_str())));
    let step = analyse_next(&mut store, &ctx, &Cancel::new(), &none).expect("step");
    assert_eq!(step, GapStep::Idle, "analysed once");
    // The schedule off and the fit good: nothing selected.
    let mut skip = HashSet::new();
    skip.insert(seg);
    let step = analyse_next(&mut store, &ctx, &Cancel::new(), &skip).expect("step");
    assert_eq!(step, GapStep::Idle);
}

/// `days` noisy simulated start-ups, one a day (each at its own health, noise seed 40 + day),
/// stored at 1 Hz in `db` and detected: `days` closed segments pending diagnosis.
fn stored_daily_startups(db: &std::path::Path, days: usize) -> Store {
    let engine = Engine::reference().expect("engine");
    let mut store = Store::open(db).expect("open");
    let ids: Vec<i64> = Signal::ALL
        .iter()
        .map(|s| store.ensure_tag(&TagInfo::for_signal(*s)).expect("tag"))
        .collect();
    for day in 0..days {
        let d = day as f64;
        let health = HealthParams {
            D_GC: 1.0 + d,
            D_EC: 0.4 + 0.35 * d,
            D_GT: 0.5 + 0.2 * d,
            D_ET: 0.3 + 0.2 * d,
            D_GP: 0.2 + 0.1 * d,
            D_EP: 0.3 + 0.1 * d,
        };
        let model = engine.model(&health);
        let (samples, _) = run_scenario(&model, &Scenario::startup(engine.cfg())).expect("runs");
        let o = MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed: 40 + day as u64,
        };
        let t = Trace::from_truth(&engine, &samples, Some(&o));
        let t0_ms = 1_700_000_000_000 + 86_400_000 * day as i64;
        let mut batch = Vec::new();
        for k in 0..t.len() {
            for (i, s) in Signal::ALL.iter().enumerate() {
                let v = t.measured[k][s.index()];
                if v.is_finite() {
                    batch.push(Sample {
                        tag: ids[i],
                        t_ms: t0_ms + (t.t_s[k] * 1000.0).round() as i64,
                        value: v,
                        quality: Quality::Good,
                    });
                }
            }
        }
        store.insert_samples(&batch).expect("insert");
    }
    scan(&mut store, &DetectorConfig::default()).expect("scan");
    store
}

/// Every stored number of the diagnosis but wall times, creation times and the configuration
/// hash (which holds `threads`): rows in id order, floats as bits.
type Stored = (
    Vec<(
        i64,
        i64,
        String,
        Vec<Option<u64>>,
        i64,
        Option<String>,
        Option<i64>,
    )>,
    Vec<(i64, Option<String>, String, String)>,
    Vec<(i64, String)>,
);

fn stored_outcomes(store: &mut Store) -> Stored {
    let c = store.conn_mut();
    let mut st = c
        .prepare(
            "SELECT id, segment_id, method, d_gc, d_ec, d_gt, d_et, d_gp, d_ep, sigma_gc,
                    sigma_ec, sigma_gt, sigma_et, sigma_gp, sigma_ep, objective, residual_level,
                    model_runs, fit_quality, seed
             FROM diagnoses ORDER BY id",
        )
        .expect("prepare");
    let diagnoses = st
        .query_map([], |r| {
            let nums = (3..17)
                .map(|i| r.get::<_, Option<f64>>(i).map(|v| v.map(f64::to_bits)))
                .collect::<Result<Vec<_>, _>>()?;
            Ok((
                r.get(0)?,
                r.get(1)?,
                r.get(2)?,
                nums,
                r.get(17)?,
                r.get(18)?,
                r.get(19)?,
            ))
        })
        .expect("query")
        .collect::<Result<Vec<_>, _>>()
        .expect("rows");
    let mut st = c
        .prepare("SELECT segment_id, method, reason, detail FROM undiagnosable ORDER BY id")
        .expect("prepare");
    let reasons = st
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))
        .expect("query")
        .collect::<Result<Vec<_>, _>>()
        .expect("rows");
    let mut st = c
        .prepare("SELECT id, status FROM segments ORDER BY id")
        .expect("prepare");
    let segments = st
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .expect("query")
        .collect::<Result<Vec<_>, _>>()
        .expect("rows");
    (diagnoses, reasons, segments)
}

fn small_ctx(threads: usize) -> WorkerContext {
    WorkerContext::load(
        None,
        DiagnosisSettings {
            threads,
            max_model_runs: 120,
            ..DiagnosisSettings::default()
        },
    )
    .expect("context")
}

/// Issue 24 item 4: a backlog diagnosed on 2 cores (two start-ups fitted at once) stores
/// exactly what one-at-a-time diagnosis on 1 core stores — every health value, σ, objective,
/// fit quality, reason and row id — and the after-result hook sees every outcome, in the same
/// order. A cancel mid-backlog stores a prefix of the queue and leaves the rest pending.
#[test]
fn backlog_on_two_cores_stores_what_one_core_stores() {
    let dir = tempfile::tempdir().expect("tempdir");
    let base = dir.path().join("base.db");
    let mut store = stored_daily_startups(&base, 4);
    let pending: Vec<i64> = store
        .pending_segments()
        .expect("pending")
        .iter()
        .map(|s| s.id)
        .collect();
    assert_eq!(pending.len(), 4, "{pending:?}");
    // The second start-up tripped: a reason, not a result, in the middle of the queue.
    store
        .conn_mut()
        .execute(
            "UPDATE segments SET outcome = 'aborted', abort_cause = 'trip' WHERE id = ?1",
            [pending[1]],
        )
        .expect("update");
    store
        .conn_mut()
        .execute_batch("PRAGMA wal_checkpoint(TRUNCATE)")
        .expect("checkpoint");
    drop(store);

    let run = |name: &str, threads: usize| {
        let path = dir.path().join(name);
        std::fs::copy(&base, &path).expect("copy");
        let mut store = Store::open(&path).expect("open");
        let seen = Arc::new(std::sync::Mutex::new(Vec::new()));
        let s2 = Arc::clone(&seen);
        let after: AfterResult = Arc::new(move |_db, id, outcome, _wall| {
            let kind = match outcome {
                SegmentOutcome::Diagnosed { .. } => "diagnosed",
                SegmentOutcome::Undiagnosable(_) => "undiagnosable",
                SegmentOutcome::Cancelled => "cancelled",
            };
            s2.lock().expect("lock").push((id, kind));
        });
        let t = std::time::Instant::now();
        let rep = drain_pending(
            &mut store,
            &small_ctx(threads),
            &Cancel::new(),
            Some(&after),
        )
        .expect("drain");
        eprintln!(
            "{threads} thread(s): {rep:?} in {:.1} s",
            t.elapsed().as_secs_f64()
        );
        assert_eq!((rep.diagnosed, rep.undiagnosable), (3, 1), "{rep:?}");
        assert!(store.pending_segments().expect("pending").is_empty());
        let seen = seen.lock().expect("lock").clone();
        (stored_outcomes(&mut store), seen)
    };
    let (one, seen_one) = run("one.db", 1);
    let (two, seen_two) = run("two.db", 2);
    assert_eq!(
        one.0.iter().filter(|d| d.2 == "B").count(),
        3,
        "a Method B result per completed start-up: {:?}",
        one.0
    );
    assert_eq!(one.1.len(), 1, "{:?}", one.1);
    assert_eq!(one.1[0].2, "aborted");
    assert_eq!(one, two, "stored outcomes differ between 1 and 2 threads");
    assert_eq!(seen_one.len(), 4);
    assert_eq!(
        seen_one.iter().map(|s| s.0).collect::<Vec<_>>(),
        pending,
        "the hook sees the queue in order"
    );
    assert_eq!(seen_one, seen_two);

    // Cancelled while two fits run: what is stored is a prefix of the queue (never a later
    // start-up before an earlier one), the rest stays pending, the drain says cancelled.
    let path = dir.path().join("cancel.db");
    std::fs::copy(&base, &path).expect("copy");
    let mut store = Store::open(&path).expect("open");
    let cancel = Cancel::new();
    let c2 = cancel.clone();
    let t = std::time::Instant::now();
    let rep = std::thread::scope(|s| {
        s.spawn(move || {
            std::thread::sleep(Duration::from_millis(300));
            c2.cancel();
        });
        drain_pending(&mut store, &small_ctx(2), &cancel, None).expect("drain")
    });
    assert!(rep.cancelled, "{rep:?}");
    assert!(
        t.elapsed() < Duration::from_secs(20),
        "cancel took {:?}",
        t.elapsed()
    );
    let left: Vec<i64> = store
        .pending_segments()
        .expect("pending")
        .iter()
        .map(|s| s.id)
        .collect();
    assert!(!left.is_empty(), "cancelled before the backlog was done");
    assert!(pending.ends_with(&left), "{left:?} of {pending:?}");
    let done = pending.len() - left.len();
    assert_eq!(
        (rep.diagnosed + rep.undiagnosable) as usize,
        done,
        "{rep:?}"
    );
}

/// A unit's engine file naming its maps relative to itself: the context's text carries the
/// maps, so a fleet worker building the job's context from that text alone (no file beside
/// it, another working directory) computes the same hash and the same engine; and a changed
/// map is another configuration (its hash changes), as a changed number is.
#[test]
fn a_context_carries_its_map_files_so_a_fleet_job_needs_none() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("hpc.map"), crate::maps::HPC_MAP).expect("write map");
    let text = crate::engine::config::REFERENCE_ENGINE_TOML
        .replace("compressor_file = \"\"", "compressor_file = \"hpc.map\"");
    let file = dir.path().join("unit.toml");
    std::fs::write(&file, &text).expect("write engine");
    let settings = DiagnosisSettings::default();
    let edge = WorkerContext::load(Some(&file), settings.clone()).expect("edge context");
    assert!(
        !edge.engine_text.contains("hpc.map"),
        "the map is in the text"
    );
    let centre = WorkerContext::from_text(edge.engine_text.clone(), "job", settings.clone())
        .expect("the job's text alone builds");
    assert_eq!(centre.config_hash, edge.config_hash);
    assert_eq!(centre.engine.design(), edge.engine.design());
    // The same engine file, its map file changed (here only by a trailing line): another
    // hash, where it used to cover the file's text alone.
    let other_map = format!("{}\n", crate::maps::HPC_MAP);
    std::fs::write(dir.path().join("hpc.map"), other_map).expect("rewrite map");
    let changed = WorkerContext::load(Some(&file), settings).expect("changed map");
    assert_ne!(changed.config_hash, edge.config_hash);
}
