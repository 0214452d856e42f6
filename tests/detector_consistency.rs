//! Start-up detection on `simulate` output with the shipped `config/gtwatch.toml`: every normal
//! start completes, and the segments do not depend on how the data arrives (one file, many
//! 10-second files, live batches scanned every 10 s).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::config::Config;
use gtwatch::detect::{scan, DetectorConfig};
use gtwatch::engine::sensors::MeasurementOptions;
use gtwatch::engine::simulation::run_scenario;
use gtwatch::engine::{Engine, Scenario, Trace};
use gtwatch::health::HealthParams;
use gtwatch::ingest::{replay_file, Progress, ReplayConfig};
use gtwatch::quality::Quality;
use gtwatch::signals::Signal;
use gtwatch::store::{Sample, Store, TagInfo};
use gtwatch::time::TimeFormat;
use std::path::Path;

fn shipped() -> Config {
    let text = include_str!("../config/gtwatch.toml");
    Config::parse(text, "config/gtwatch.toml").expect("shipped config parses")
}

fn replay_cfg() -> ReplayConfig {
    ReplayConfig {
        time_column: "time_s".into(),
        time_format: TimeFormat::EpochS,
        ..shipped().replay
    }
}

fn trace(scenario: fn(&gtwatch::engine::EngineConfig) -> Scenario, seed: u64) -> Trace {
    let engine = Engine::reference().expect("engine");
    let model = engine.model(&HealthParams::HEALTHY);
    let (samples, _) = run_scenario(&model, &scenario(engine.cfg())).expect("runs");
    let o = MeasurementOptions {
        lags: true,
        noise: true,
        bias: false,
        seed,
    };
    Trace::from_truth(&engine, &samples, Some(&o))
}

/// Rows `[from, to)` of a trace as CSV, times shifted by `shift_s`.
fn write_rows(t: &Trace, from: usize, to: usize, shift_s: f64, path: &Path) {
    let mut part = t.clone();
    part.t_s = t.t_s[from..to].iter().map(|x| x + shift_s).collect();
    part.phase = t.phase[from..to].to_vec();
    part.measured = t.measured[from..to].to_vec();
    part.truth = t.truth[from..to].to_vec();
    let f = std::fs::File::create(path).expect("create csv");
    part.write_csv(std::io::BufWriter::new(f))
        .expect("write csv");
}

/// (start_ms, end_ms, outcome, abort_cause, hot_restart) of every stored start-up.
type SegRow = (i64, Option<i64>, String, Option<String>, bool);

fn segments(db: &Path) -> Vec<SegRow> {
    let c = rusqlite::Connection::open(db).expect("open");
    let mut st = c
        .prepare("SELECT start_ms, end_ms, outcome, abort_cause, hot_restart FROM segments ORDER BY start_ms")
        .expect("prepare");
    st.query_map([], |r| {
        Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?))
    })
    .expect("query")
    .collect::<Result<_, _>>()
    .expect("rows")
}

#[test]
fn noisy_simulated_startups_complete_with_the_shipped_config() {
    let det = shipped().detector;
    let dir = tempfile::tempdir().expect("tempdir");
    for seed in 1..=4 {
        let t = trace(Scenario::startup, seed);
        let csv = dir.path().join(format!("s{seed}.csv"));
        write_rows(&t, 0, t.len(), 1.7e9, &csv);
        let db = dir.path().join(format!("s{seed}.db"));
        let mut store = Store::open(&db).expect("open");
        replay_file(&mut store, &replay_cfg(), &csv, Progress::Silent).expect("replay");
        scan(&mut store, &det).expect("scan");
        let segs = segments(&db);
        assert_eq!(segs.len(), 1, "seed {seed}: {segs:?}");
        assert_eq!(segs[0].2, "completed", "seed {seed}: {segs:?}");
    }
}

/// Ends at base load, resumes (after a gap) at standstill: no zero-length segment at the gap,
/// no hot restart across it.
#[test]
fn log_ending_at_load_then_resuming_at_standstill_adds_no_segment() {
    let det = shipped().detector;
    let dir = tempfile::tempdir().expect("tempdir");
    let t = trace(Scenario::startup, 5);
    let a = dir.path().join("a.csv");
    write_rows(&t, 0, t.len(), 1.7e9, &a);
    // The next day: 10 s at standstill, then the first seconds of a start.
    let b = dir.path().join("b.csv");
    write_rows(&t, 0, 20, 1.7e9 + 86_400.0, &b);
    for scan_between in [false, true] {
        let db = dir.path().join(format!("ab{scan_between}.db"));
        let mut store = Store::open(&db).expect("open");
        replay_file(&mut store, &replay_cfg(), &a, Progress::Silent).expect("replay a");
        if scan_between {
            scan(&mut store, &det).expect("scan");
        }
        replay_file(&mut store, &replay_cfg(), &b, Progress::Silent).expect("replay b");
        scan(&mut store, &det).expect("scan");
        let segs = segments(&db);
        // Day 1's start, and day 2's start (cut off by the end of the file b) from its onset.
        assert_eq!(segs.len(), 2, "scan between: {scan_between}: {segs:?}");
        assert_eq!(segs[0].2, "completed", "{segs:?}");
        assert_eq!(segs[1].0, segs[0].0 + 86_400_000, "{segs:?}");
        assert!(!segs[1].4, "a start a day later is not hot: {segs:?}");
    }
}

fn live_insert(store: &mut Store, t: &Trace, from: usize, to: usize, shift_s: f64) {
    let ids: Vec<i64> = Signal::ALL
        .iter()
        .map(|s| store.ensure_tag(&TagInfo::for_signal(*s)).expect("tag"))
        .collect();
    let mut batch = Vec::new();
    for k in from..to {
        let t_ms = ((t.t_s[k] + shift_s) * 1000.0).round() as i64;
        for (i, id) in ids.iter().enumerate() {
            let v = t.measured[k][Signal::ALL[i].index()];
            if v.is_finite() {
                batch.push(Sample {
                    tag: *id,
                    t_ms,
                    value: v,
                    quality: Quality::Good,
                });
            }
        }
    }
    store.insert_samples(&batch).expect("insert");
}

/// The operations day (start, stop, tripped start, hot restart) gives the same segments whether
/// replayed as one file, as 10-second files (each replay followed by a scan, as
/// `gtwatch replay` does), or inserted live and scanned every 10 s as the daemon does.
#[test]
fn same_segments_however_the_data_arrives() {
    let det: DetectorConfig = shipped().detector;
    let dir = tempfile::tempdir().expect("tempdir");
    let t = trace(Scenario::operations, 7);
    let shift = 1.7e9;

    let one_db = dir.path().join("one.db");
    let csv = dir.path().join("all.csv");
    write_rows(&t, 0, t.len(), shift, &csv);
    let mut one = Store::open(&one_db).expect("open");
    replay_file(&mut one, &replay_cfg(), &csv, Progress::Silent).expect("replay");
    scan(&mut one, &det).expect("scan");
    let reference = segments(&one_db);
    let completed = reference.iter().filter(|s| s.2 == "completed").count();
    let aborted = reference.iter().filter(|s| s.2 == "aborted").count();
    assert_eq!((completed, aborted), (2, 1), "{reference:?}");

    // Rows per 10 s of data.
    let dt = t.t_s[1] - t.t_s[0];
    let step = ((10.0 / dt).round() as usize).max(1);

    let chunks_db = dir.path().join("chunks.db");
    let mut chunks = Store::open(&chunks_db).expect("open");
    let live_db = dir.path().join("live.db");
    let mut live = Store::open(&live_db).expect("open");
    let mut from = 0;
    let mut k = 0;
    while from < t.len() {
        let to = (from + step).min(t.len());
        let p = dir.path().join(format!("c{k}.csv"));
        write_rows(&t, from, to, shift, &p);
        replay_file(&mut chunks, &replay_cfg(), &p, Progress::Silent).expect("replay chunk");
        scan(&mut chunks, &det).expect("scan");
        std::fs::remove_file(&p).expect("rm");
        live_insert(&mut live, &t, from, to, shift);
        scan(&mut live, &det).expect("scan");
        from = to;
        k += 1;
    }
    assert_eq!(segments(&chunks_db), reference, "10-second files");
    assert_eq!(segments(&live_db), reference, "live");
}
