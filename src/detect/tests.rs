use super::machine::tests::{empty_script, frames, hot_restart_script, push_start, T0_MS};
use super::*;
use crate::quality::Quality;
use crate::store::{Gap, Sample, TagInfo};

struct Db {
    _dir: tempfile::TempDir,
    store: Store,
    tags: [TagId; 4],
}

fn db() -> Db {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut store = Store::open(&dir.path().join("d.db")).expect("open");
    let mut tags = [0; 4];
    for (i, sig) in [Signal::N1, Signal::FuelFlow, Signal::Power, Signal::N2]
        .into_iter()
        .enumerate()
    {
        tags[i] = store.ensure_tag(&TagInfo::for_signal(sig)).expect("tag");
    }
    Db {
        _dir: dir,
        store,
        tags,
    }
}

fn insert(db: &mut Db, fr: &[Frame]) {
    let mut batch = Vec::new();
    for f in fr {
        for (tag, v) in [
            (db.tags[0], f.n1),
            (db.tags[1], f.fuel),
            (db.tags[2], f.power),
            (db.tags[3], f.n2.unwrap_or(0.0)),
        ] {
            batch.push(Sample {
                tag,
                t_ms: f.t_ms,
                value: v,
                quality: Quality::Good,
            });
        }
    }
    db.store.insert_samples(&batch).expect("insert");
}

#[derive(Debug, PartialEq)]
struct Row {
    start_ms: i64,
    end_ms: Option<i64>,
    outcome: String,
    status: String,
    hot: bool,
    gap: bool,
    phases: Vec<(String, i64, Option<i64>)>,
}

fn rows(store: &Store) -> Vec<Row> {
    let conn = store.conn();
    let mut stmt = conn
        .prepare("SELECT id, start_ms, end_ms, outcome, status, hot_restart, has_gap FROM segments ORDER BY start_ms")
        .expect("prepare");
    let segs: Vec<(i64, Row)> = stmt
        .query_map([], |r| {
            Ok((
                r.get(0)?,
                Row {
                    start_ms: r.get(1)?,
                    end_ms: r.get(2)?,
                    outcome: r.get(3)?,
                    status: r.get(4)?,
                    hot: r.get(5)?,
                    gap: r.get(6)?,
                    phases: Vec::new(),
                },
            ))
        })
        .expect("query")
        .collect::<Result<_, _>>()
        .expect("rows");
    segs.into_iter()
        .map(|(id, mut row)| {
            let mut p = conn
                .prepare("SELECT phase, start_ms, end_ms FROM segment_phases WHERE segment_id = ?1 ORDER BY start_ms, phase_code")
                .expect("prepare");
            row.phases = p
                .query_map([id], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
                .expect("q")
                .collect::<Result<_, _>>()
                .expect("phases");
            row
        })
        .collect()
}

#[test]
fn scan_without_input_tags_does_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut store = Store::open(&dir.path().join("e.db")).expect("open");
    let r = scan(&mut store, &DetectorConfig::default()).expect("scan");
    assert_eq!(r, ScanReport::default());
}

/// A daemon restart in the middle of a start: the start is found whole, once, with the same
/// boundaries as a single pass over all data; scanning again changes nothing.
#[test]
fn restart_mid_start_finds_whole_segment_once() {
    let (s, _k1, _trip, k2) = hot_restart_script();
    let end = k2.at_load as i64 + 300;
    let all = frames(&s, end, 21, true);
    let cfg = DetectorConfig::default();

    let mut one = db();
    insert(&mut one, &all);
    scan(&mut one.store, &cfg).expect("scan");
    let reference = rows(&one.store);
    assert_eq!(reference.len(), 2);
    assert!(reference
        .iter()
        .all(|r| r.outcome == "completed" && r.status == "closed"));

    // Incremental: stop in several places inside both starts (each stop = a daemon restart:
    // a fresh scan call with nothing in memory).
    let mut inc = db();
    let cuts = [
        100usize,
        180,
        400,
        700,
        k2.crank as usize + 50,
        k2.at_idle as usize + 5,
        all.len(),
    ];
    let mut prev = 0;
    for c in cuts {
        insert(&mut inc, &all[prev..c.min(all.len())]);
        scan(&mut inc.store, &cfg).expect("scan");
        prev = c.min(all.len());
        let open: i64 = inc
            .store
            .conn()
            .query_row(
                "SELECT COUNT(*) FROM segments WHERE status = 'open'",
                [],
                |r| r.get(0),
            )
            .expect("count");
        assert!(open <= 1);
    }
    assert_eq!(rows(&inc.store), reference);
    // Idempotent: nothing new, nothing changes.
    let r = scan(&mut inc.store, &cfg).expect("scan");
    assert_eq!(r.frames, 0);
    assert_eq!(rows(&inc.store), reference);
}

#[test]
fn late_older_samples_trigger_a_rescan() {
    let mut s = empty_script();
    let k = push_start(&mut s, 30.0, 0.0);
    let all = frames(&s, k.at_load as i64 + 300, 22, true);
    let cfg = DetectorConfig::default();
    let mut d = db();
    // The second half arrives first (e.g. live data), then a replay fills in the past.
    let half = all.len() / 2;
    insert(&mut d, &all[half..]);
    scan(&mut d.store, &cfg).expect("scan");
    insert(&mut d, &all[..half]);
    scan(&mut d.store, &cfg).expect("scan");
    let got = rows(&d.store);
    assert_eq!(got.len(), 1, "{got:?}");
    assert_eq!(got[0].outcome, "completed");
    assert_eq!(got[0].start_ms, T0_MS + 30_000);
}

#[test]
fn recorded_gap_marks_segment() {
    let mut s = empty_script();
    let k = push_start(&mut s, 30.0, 0.0);
    let all = frames(&s, k.at_load as i64 + 300, 23, true);
    let mut d = db();
    insert(&mut d, &all);
    d.store
        .record_gap(&Gap {
            start_ms: T0_MS + 300_000,
            end_ms: T0_MS + 302_000,
            source: "modbus".into(),
            reason: "timeout".into(),
        })
        .expect("gap");
    scan(&mut d.store, &DetectorConfig::default()).expect("scan");
    let got = rows(&d.store);
    assert_eq!(got.len(), 1);
    assert!(got[0].gap);
    assert!(!got[0].hot);
    assert!(got[0].end_ms.is_some());
}

/// Regression (issue 12 #1): one far-future sample (year 3000, or i64::MAX) made the scan walk
/// 6-hour chunks up to it (minutes, or forever). It must finish and still find the start.
#[test]
fn far_future_sample_does_not_stall_the_scan() {
    let (s, _k1, _trip, k2) = hot_restart_script();
    let end = k2.at_load as i64 + 300;
    let all = frames(&s, end, 21, true);
    let cfg = DetectorConfig::default();
    let mut reference = db();
    insert(&mut reference, &all);
    scan(&mut reference.store, &cfg).expect("scan");
    let want = rows(&reference.store);
    for far in [T0_MS + 1000 * 365 * 86_400_000, i64::MAX] {
        let mut d = db();
        insert(&mut d, &all);
        let last = all.last().expect("frames");
        insert(&mut d, &[Frame { t_ms: far, ..*last }]);
        let r = scan(&mut d.store, &cfg).expect("scan");
        assert!(r.frames >= all.len() as u64, "far = {far}: {r:?}");
        let got = rows(&d.store);
        assert_eq!(got.len(), want.len(), "far = {far}");
        assert_eq!(got[0], want[0], "far = {far}");
    }
}
