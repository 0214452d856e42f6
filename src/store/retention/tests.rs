//! Retention against a known signal: a start-up segment inside two days of 1 Hz data (the
//! first day archived, the second hot), rolled up with `raw_days` 1 and a 600 s margin.
//! Checks the protected samples bit for bit through the read path, the roll-ups against
//! values computed here from the signal, idempotence, the file shrinking and `storage_stats`.

use super::super::{Sample, ScanWrite, Store, TagInfo};
use super::{RetentionPolicy, MINUTE_MS};
use crate::quality::Quality;
use crate::segment::{Outcome, SegmentRecord};
use std::collections::BTreeMap;

const DAY: i64 = 86_400_000;
const HOUR: i64 = 3_600_000;
/// Minute- and 6 h-aligned.
const BASE: i64 = 1_700_006_400_000;
const SEG_START: i64 = BASE + 10 * HOUR + 1234;
const SEG_END: i64 = BASE + 10 * HOUR + 30 * 60_000 + 777;
const MARGIN_S: u32 = 600;
/// A minute whose samples are all bad.
const ALL_BAD_MINUTE: i64 = BASE + 20 * HOUR;

/// Two days at 1 Hz: multiples of 1/4 (exact sums), every 7th sample bad with a huge value
/// (must not reach min/max/mean), one minute all bad, one missing minute.
fn signal(tag: i64) -> Vec<Sample> {
    (0..2 * DAY / 1000)
        .map(|i| {
            let t = BASE + i * 1000;
            let bad = i % 7 == 3 || (ALL_BAD_MINUTE..ALL_BAD_MINUTE + MINUTE_MS).contains(&t);
            Sample {
                tag,
                t_ms: t,
                value: if bad {
                    1.0e6
                } else {
                    ((i * 37) % 1001) as f64 * 0.25 - 60.0
                },
                quality: if bad { Quality::Bad } else { Quality::Good },
            }
        })
        .filter(|s| !(BASE + 30 * HOUR..BASE + 30 * HOUR + MINUTE_MS).contains(&s.t_ms))
        .collect()
}

/// The expected roll-up of one minute, from the signal itself.
#[derive(Debug, PartialEq)]
struct Expected {
    n_good: i64,
    n_all: i64,
    min: Option<f64>,
    mean: Option<f64>,
    max: Option<f64>,
    last: Option<f64>,
}

fn expected(samples: &[Sample], rolled: impl Fn(i64) -> bool) -> BTreeMap<i64, Expected> {
    let mut out = BTreeMap::new();
    let mut by_minute: BTreeMap<i64, Vec<&Sample>> = BTreeMap::new();
    for s in samples.iter().filter(|s| rolled(s.t_ms)) {
        by_minute
            .entry(s.t_ms - s.t_ms.rem_euclid(MINUTE_MS))
            .or_default()
            .push(s);
    }
    for (m, v) in by_minute {
        let good: Vec<f64> = v
            .iter()
            .filter(|s| s.quality == Quality::Good)
            .map(|s| s.value)
            .collect();
        // Sums of multiples of 1/4 below 2^40 are exact: the mean is one rounding of the truth.
        let sum: f64 = good.iter().sum();
        out.insert(
            m,
            Expected {
                n_good: good.len() as i64,
                n_all: v.len() as i64,
                min: good.iter().copied().reduce(f64::min),
                mean: (!good.is_empty()).then(|| sum / good.len() as f64),
                max: good.iter().copied().reduce(f64::max),
                last: good.last().copied(),
            },
        );
    }
    out
}

fn stored_rollups(store: &Store, tag: i64) -> BTreeMap<i64, Expected> {
    let mut st = store
        .conn()
        .prepare(
            "SELECT t_ms, n_good, n_all, min, mean, max, last FROM rollups_1m WHERE tag_id = ?1",
        )
        .unwrap_or_else(|e| unreachable!("{e}"));
    let rows = st
        .query_map([tag], |r| {
            Ok((
                r.get(0)?,
                Expected {
                    n_good: r.get(1)?,
                    n_all: r.get(2)?,
                    min: r.get(3)?,
                    mean: r.get(4)?,
                    max: r.get(5)?,
                    last: r.get(6)?,
                },
            ))
        })
        .unwrap_or_else(|e| unreachable!("{e}"));
    rows.collect::<Result<_, _>>()
        .unwrap_or_else(|e| unreachable!("{e}"))
}

fn page_count(store: &Store) -> i64 {
    store
        .conn()
        .query_row("PRAGMA page_count", [], |r| r.get(0))
        .unwrap_or_else(|e| unreachable!("{e}"))
}

fn all_rows(store: &Store, tag: i64) -> Vec<(i64, u64, i64)> {
    store
        .tag_samples_between(tag, i64::MIN, i64::MAX)
        .unwrap_or_else(|e| unreachable!("{e}"))
        .iter()
        .map(|s| (s.t_ms, s.value.to_bits(), s.quality))
        .collect()
}

#[test]
fn retention_keeps_startups_raw_and_rolls_up_steady_operation_exactly() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| unreachable!("{e}"));
    let path = dir.path().join("r.db");
    let mut store = Store::open(&path).unwrap_or_else(|e| unreachable!("{e}"));
    let auto_vacuum: i64 = store
        .conn()
        .query_row("PRAGMA auto_vacuum", [], |r| r.get(0))
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(
        auto_vacuum, 2,
        "a new file is in incremental auto-vacuum mode"
    );
    let tag = store
        .ensure_tag(&TagInfo {
            name: "x".into(),
            unit: String::new(),
            signal: None,
        })
        .unwrap_or_else(|e| unreachable!("{e}"));
    let samples = signal(tag);
    store
        .insert_samples(&samples)
        .unwrap_or_else(|e| unreachable!("{e}"));
    // The first day (with the start-up) into the archive, the second stays hot.
    let c = store
        .compact(BASE + DAY, 32_768)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert!(c.samples > 80_000, "{c:?}");
    store
        .store_scan(&ScanWrite {
            records: vec![SegmentRecord {
                start_ms: SEG_START,
                end_ms: Some(SEG_END),
                outcome: Outcome::Completed,
                abort_cause: None,
                hot_restart: false,
                has_gap: false,
                phases: Vec::new(),
            }],
            keep_from: BASE,
            scanned_to: BASE + 2 * DAY,
            last_fuel_off_ms: None,
        })
        .unwrap_or_else(|e| unreachable!("{e}"));
    let policy = RetentionPolicy {
        raw_days: 1,
        segment_margin_s: MARGIN_S,
        rollup_1m_days: 0,
    };
    let now = BASE + 4 * DAY;
    // Raw cutoff now − 1 day = BASE + 3 days, pulled back to the detector's resume point
    // (BASE + 2 days) less an hour of context.
    let cutoff = BASE + 2 * DAY - HOUR;
    let margin = i64::from(MARGIN_S) * 1000;
    let prot_from = SEG_START - margin - (SEG_START - margin).rem_euclid(MINUTE_MS);
    let prot_to = {
        let e = SEG_END + margin + 1;
        e + (MINUTE_MS - e.rem_euclid(MINUTE_MS)) % MINUTE_MS
    };
    let rolled = |t: i64| t < cutoff && !(prot_from..prot_to).contains(&t);
    let want = expected(&samples, rolled);
    let n_rolled = samples.iter().filter(|s| rolled(s.t_ms)).count() as u64;
    let kept: Vec<(i64, u64, i64)> = samples
        .iter()
        .filter(|s| !rolled(s.t_ms))
        .map(|s| (s.t_ms, s.value.to_bits(), i64::from(s.quality.code())))
        .collect();

    let before = store
        .storage_stats(now, &policy)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(before.next_retention.cutoff_ms, Some(cutoff));
    assert_eq!(before.next_retention.samples, n_rolled);
    assert_eq!(
        before.hot.samples + before.archive.samples,
        samples.len() as u64
    );
    assert_eq!(before.rollups.rows, 0);
    assert!(
        before.hot.bytes.is_some_and(|b| b > 0),
        "dbstat: {before:?}"
    );
    let pages_before = page_count(&store);

    let done = store
        .apply_retention(now, &policy)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(done.cutoff_ms, Some(cutoff));
    assert_eq!(done.samples_rolled_up, n_rolled);
    assert!(
        done.hot_deleted > 0 && done.archived_deleted > 0,
        "{done:?}"
    );
    assert!(done.chunks_rewritten > 0, "{done:?}");
    assert_eq!(done.minutes, want.len() as u64);

    // Every sample of the start-up ± margin (and after the cutoff) is still there, bit for bit.
    assert_eq!(all_rows(&store, tag), kept);
    // Whole minutes: the minute holding start − margin is kept entire, the one before is not.
    let has = |t: i64| kept.iter().any(|&(k, _, _)| k == t);
    assert!(has(BASE + 9 * HOUR + 50 * 60_000) && !has(BASE + 9 * HOUR + 50 * 60_000 - 1000));
    // The roll-ups are exactly the signal's.
    let got = stored_rollups(&store, tag);
    assert_eq!(got, want);
    let bad = &got[&ALL_BAD_MINUTE];
    assert_eq!((bad.n_good, bad.n_all, bad.mean), (0, 60, None));
    assert!(
        !got.contains_key(&(BASE + 30 * HOUR)),
        "a minute without samples has no row"
    );

    // The file shrinks once the freed pages are returned.
    let mut freed = 0;
    loop {
        let n = store
            .incremental_vacuum_step(256)
            .unwrap_or_else(|e| unreachable!("{e}"));
        if n == 0 {
            break;
        }
        freed += n;
    }
    let pages_after = page_count(&store);
    assert!(
        freed > 0 && pages_after < pages_before,
        "{pages_before} → {pages_after}"
    );

    // Stats after: tiers add up, nothing left to do.
    let after = store
        .storage_stats(now, &policy)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(after.hot.samples + after.archive.samples, kept.len() as u64);
    assert_eq!(after.rollups.samples, n_rolled);
    assert_eq!(after.rollups.rows, want.len() as u64);
    assert_eq!(after.rollups.oldest_ms, want.keys().next().copied());
    assert_eq!(after.next_retention.samples, 0);
    assert_eq!(after.next_retention.batches, 0);
    assert_eq!(after.file.page_count, pages_after as u64);
    assert_eq!(after.file.free_pages, 0);

    // A second run is a no-op, and so is replaying the original samples.
    let again = store
        .apply_retention(now, &policy)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(again.batches, 0, "{again:?}");
    let replayed = store
        .insert_samples(&samples)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(
        replayed, 0,
        "rolled-up and kept samples are both skipped on re-ingest"
    );
    assert_eq!(all_rows(&store, tag), kept);
    assert_eq!(stored_rollups(&store, tag), want);
    assert_eq!(store.integrity_check().unwrap_or_default(), "ok");
}

#[test]
fn retention_is_off_at_raw_days_0_and_before_the_detector_scanned() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| unreachable!("{e}"));
    let mut store = Store::open(&dir.path().join("o.db")).unwrap_or_else(|e| unreachable!("{e}"));
    let tag = store
        .ensure_tag(&TagInfo {
            name: "x".into(),
            unit: String::new(),
            signal: None,
        })
        .unwrap_or_else(|e| unreachable!("{e}"));
    let samples: Vec<Sample> = signal(tag).into_iter().take(5000).collect();
    store
        .insert_samples(&samples)
        .unwrap_or_else(|e| unreachable!("{e}"));
    let on = RetentionPolicy {
        raw_days: 1,
        segment_margin_s: 0,
        rollup_1m_days: 0,
    };
    let off = RetentionPolicy {
        raw_days: 0,
        segment_margin_s: 0,
        rollup_1m_days: 0,
    };
    let now = BASE + 30 * DAY;
    let none = store
        .apply_retention(now, &on)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!((none.batches, none.cutoff_ms), (0, None), "never scanned");
    store
        .store_scan(&ScanWrite {
            records: Vec::new(),
            keep_from: BASE,
            scanned_to: BASE + 2 * DAY,
            last_fuel_off_ms: None,
        })
        .unwrap_or_else(|e| unreachable!("{e}"));
    let none = store
        .apply_retention(now, &off)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(none.batches, 0);
    assert_eq!(store.sample_count().unwrap_or(0), samples.len() as i64);
    let all = store
        .apply_retention(now, &on)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(all.samples_rolled_up, samples.len() as u64);
    assert_eq!(store.sample_count().unwrap_or(-1), 0);
}

#[test]
fn bad_retention_settings_name_their_key() {
    use super::super::StorageConfig;
    let keys =
        |c: StorageConfig| -> Vec<String> { c.validate().into_iter().map(|p| p.key).collect() };
    assert!(keys(StorageConfig::default()).is_empty());
    assert_eq!(
        StorageConfig::default().raw_days,
        0,
        "raw forever by default"
    );
    assert_eq!(
        keys(StorageConfig {
            raw_days: 40_000,
            ..StorageConfig::default()
        }),
        ["storage.raw_days"]
    );
    assert_eq!(
        keys(StorageConfig {
            segment_margin_s: 8 * 86_400,
            ..StorageConfig::default()
        }),
        ["storage.segment_margin_s"]
    );
    // Rolled up before archived: refused, naming raw_days.
    assert_eq!(
        keys(StorageConfig {
            raw_days: 1,
            compact_after_hours: 48,
            ..StorageConfig::default()
        }),
        ["storage.raw_days"]
    );
    assert!(keys(StorageConfig {
        raw_days: 2,
        compact_after_hours: 48,
        ..StorageConfig::default()
    })
    .is_empty());
}

/// A raw sample that reaches an already rolled-up minute behind ingest's back (ingest itself
/// skips such samples) is merged into the minute's row: counts added, mean weighted, min,
/// max and last as if the minute had been rolled up whole.
#[test]
fn a_late_raw_sample_is_merged_into_its_minute() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| unreachable!("{e}"));
    let mut store = Store::open(&dir.path().join("m.db")).unwrap_or_else(|e| unreachable!("{e}"));
    let tag = store
        .ensure_tag(&TagInfo {
            name: "x".into(),
            unit: String::new(),
            signal: None,
        })
        .unwrap_or_else(|e| unreachable!("{e}"));
    // One minute: 1.0, 2.0, 3.0 at 0, 10, 20 s; later 10.0 at 30 s and -4.0 (bad) at 40 s.
    let first: Vec<Sample> = [(0, 1.0), (10, 2.0), (20, 3.0)]
        .iter()
        .map(|&(s, v)| Sample {
            tag,
            t_ms: BASE + s * 1000,
            value: v,
            quality: Quality::Good,
        })
        .collect();
    store
        .insert_samples(&first)
        .unwrap_or_else(|e| unreachable!("{e}"));
    store
        .store_scan(&ScanWrite {
            records: Vec::new(),
            keep_from: BASE,
            scanned_to: BASE + 2 * DAY,
            last_fuel_off_ms: None,
        })
        .unwrap_or_else(|e| unreachable!("{e}"));
    let policy = RetentionPolicy {
        raw_days: 1,
        segment_margin_s: 0,
        rollup_1m_days: 0,
    };
    let now = BASE + 10 * DAY;
    store
        .apply_retention(now, &policy)
        .unwrap_or_else(|e| unreachable!("{e}"));
    store
        .conn()
        .execute_batch(&format!(
            "INSERT INTO samples (tag_id, t_ms, value, quality) VALUES
             ({tag}, {}, 10.0, 0), ({tag}, {}, -4.0, 2)",
            BASE + 30_000,
            BASE + 40_000
        ))
        .unwrap_or_else(|e| unreachable!("{e}"));
    let done = store
        .apply_retention(now, &policy)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(done.samples_rolled_up, 2);
    let got = stored_rollups(&store, tag);
    assert_eq!(
        got.into_iter().collect::<Vec<_>>(),
        [(
            BASE,
            Expected {
                n_good: 4,
                n_all: 5,
                min: Some(1.0),
                mean: Some(4.0),
                max: Some(10.0),
                last: Some(10.0),
            }
        )]
    );
    assert_eq!(store.sample_count().unwrap_or(-1), 0);
}

mod hourly;
