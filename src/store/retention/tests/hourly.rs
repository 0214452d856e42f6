//! The second roll-up tier against known truth: the same two days of 1 Hz data as the minute
//! tier's test, rolled up to minutes, then the older minutes merged into hours. Checks every
//! hourly row against aggregates computed here straight from the raw signal (means within
//! 1e-9 relative), minutes left where the hourly cutoff falls, hours without good samples,
//! an hour holding a kept start-up (partly raw), idempotence and re-ingest.

use super::super::super::{Sample, ScanWrite, Store, TagInfo};
use super::super::{RetentionPolicy, HOUR_MS, MINUTE_MS};
use super::{all_rows, expected, signal, stored_rollups, BASE, DAY, MARGIN_S, SEG_END, SEG_START};
use crate::quality::Quality;
use crate::segment::{Outcome, SegmentRecord};
use std::collections::BTreeMap;

/// An hour whose samples are all bad (NULL min/mean/max/last, n_all counted).
const ALL_BAD_HOUR: i64 = BASE + 5 * HOUR_MS;

/// One hourly row as stored.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Hour {
    n_good: i64,
    n_all: i64,
    min: Option<f64>,
    mean: Option<f64>,
    max: Option<f64>,
    last: Option<f64>,
    last_ms: Option<i64>,
}

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| unreachable!("{e}"))
}

fn stored_hours(store: &Store, tag: i64) -> BTreeMap<i64, Hour> {
    let mut st = ok(store.conn().prepare(
        "SELECT t_ms, n_good, n_all, min, mean, max, last, last_ms FROM rollups_1h
         WHERE tag_id = ?1",
    ));
    let rows = ok(st.query_map([tag], |r| {
        Ok((
            r.get(0)?,
            Hour {
                n_good: r.get(1)?,
                n_all: r.get(2)?,
                min: r.get(3)?,
                mean: r.get(4)?,
                max: r.get(5)?,
                last: r.get(6)?,
                last_ms: r.get(7)?,
            },
        ))
    }));
    ok(rows.collect::<Result<_, _>>())
}

/// The hourly aggregates of the samples `rolled` selects, computed from the raw values.
fn expected_hours(samples: &[Sample], rolled: impl Fn(i64) -> bool) -> BTreeMap<i64, Hour> {
    let mut by_hour: BTreeMap<i64, Vec<&Sample>> = BTreeMap::new();
    for s in samples.iter().filter(|s| rolled(s.t_ms)) {
        by_hour
            .entry(s.t_ms - s.t_ms.rem_euclid(HOUR_MS))
            .or_default()
            .push(s);
    }
    by_hour
        .into_iter()
        .map(|(h, v)| {
            let good: Vec<&&Sample> = v.iter().filter(|s| s.quality == Quality::Good).collect();
            let sum: f64 = good.iter().map(|s| s.value).sum();
            let hour = Hour {
                n_good: good.len() as i64,
                n_all: v.len() as i64,
                min: good.iter().map(|s| s.value).reduce(f64::min),
                mean: (!good.is_empty()).then(|| sum / good.len() as f64),
                max: good.iter().map(|s| s.value).reduce(f64::max),
                last: good.last().map(|s| s.value),
                last_ms: good.last().map(|s| s.t_ms),
            };
            (h, hour)
        })
        .collect()
}

/// Equal but for the mean, within 1e-9 relative.
fn assert_hours_match(got: &BTreeMap<i64, Hour>, want: &BTreeMap<i64, Hour>) {
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        want.keys().collect::<Vec<_>>()
    );
    for (h, w) in want {
        let g = got[h];
        assert_eq!(
            (g.n_good, g.n_all, g.min, g.max, g.last, g.last_ms),
            (w.n_good, w.n_all, w.min, w.max, w.last, w.last_ms),
            "hour {h}"
        );
        match (g.mean, w.mean) {
            (Some(a), Some(b)) => assert!(
                (a - b).abs() <= 1e-9 * b.abs().max(1e-300),
                "hour {h}: mean {a} vs {b}"
            ),
            (a, b) => assert_eq!(a, b, "hour {h}"),
        }
    }
}

/// The minute test's signal with one more hour all bad.
fn signal_with_bad_hour(tag: i64) -> Vec<Sample> {
    signal(tag)
        .into_iter()
        .map(|mut s| {
            if (ALL_BAD_HOUR..ALL_BAD_HOUR + HOUR_MS).contains(&s.t_ms) {
                s.quality = Quality::Bad;
                s.value = 1.0e6;
            }
            s
        })
        .collect()
}

fn setup(path: &std::path::Path) -> (Store, i64, Vec<Sample>) {
    let mut store = ok(Store::open(path));
    let tag = ok(store.ensure_tag(&TagInfo {
        name: "x".into(),
        unit: String::new(),
        signal: None,
    }));
    let samples = signal_with_bad_hour(tag);
    ok(store.insert_samples(&samples));
    ok(store.compact(BASE + DAY, 32_768));
    ok(store.store_scan(&ScanWrite {
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
    }));
    (store, tag, samples)
}

#[test]
fn hourly_rollups_equal_the_raw_hours_and_rerunning_changes_nothing() {
    let dir = ok(tempfile::tempdir());
    let (mut store, tag, samples) = setup(&dir.path().join("h.db"));
    // As in the minute test: raw cutoff BASE + 2 days − 1 h, the start-up ± margin kept raw.
    let now = BASE + 10 * DAY;
    let cutoff = BASE + 2 * DAY - HOUR_MS;
    let margin = i64::from(MARGIN_S) * 1000;
    let prot_from = SEG_START - margin - (SEG_START - margin).rem_euclid(MINUTE_MS);
    let prot_to = {
        let e = SEG_END + margin + 1;
        e + (MINUTE_MS - e.rem_euclid(MINUTE_MS)) % MINUTE_MS
    };
    let rolled = |t: i64| t < cutoff && !(prot_from..prot_to).contains(&t);
    let kept: Vec<(i64, u64, i64)> = samples
        .iter()
        .filter(|s| !rolled(s.t_ms))
        .map(|s| (s.t_ms, s.value.to_bits(), i64::from(s.quality.code())))
        .collect();

    // 1. Raw → minutes only.
    let minutes_only = RetentionPolicy {
        raw_days: 1,
        segment_margin_s: MARGIN_S,
        rollup_1m_days: 0,
    };
    let done = ok(store.apply_retention(now, &minutes_only));
    assert_eq!((done.hourly_batches, done.hourly_cutoff_ms), (0, None));
    assert_eq!(stored_rollups(&store, tag), expected(&samples, rolled));

    // 2. Minutes older than now − 9 days (= BASE + 1 day) → hours; the rest stay minutes.
    let policy = RetentionPolicy {
        rollup_1m_days: 9,
        ..minutes_only
    };
    let hourly_cut = BASE + DAY;
    let outlook = ok(store.retention_outlook(now, &policy));
    assert_eq!(outlook.hourly_cutoff_ms, Some(hourly_cut));
    let minutes_before = stored_rollups(&store, tag);
    let n_old = minutes_before.keys().filter(|&&m| m < hourly_cut).count() as u64;
    assert_eq!(outlook.minutes_to_merge, n_old);
    assert_eq!((outlook.samples, outlook.batches), (0, 0));
    let done = ok(store.apply_retention(now, &policy));
    assert_eq!(done.batches, 0, "no raw samples left to roll up");
    assert_eq!(done.minutes_merged, n_old);
    assert_eq!(done.hourly_batches, 1, "one tag, one day");

    let hours = stored_hours(&store, tag);
    let want = expected_hours(&samples, |t| rolled(t) && t < hourly_cut);
    assert_hours_match(&hours, &want);
    assert_eq!(done.hours, want.len() as u64);
    // The all-bad hour: counted, no values.
    let bad = hours[&ALL_BAD_HOUR];
    assert_eq!(
        (bad.n_good, bad.n_all, bad.min, bad.mean, bad.last),
        (0, 3600, None, None, None)
    );
    // The hours around the start-up summarise only their rolled-up minutes; the rest is raw.
    let seg_hour = SEG_START - SEG_START.rem_euclid(HOUR_MS);
    assert!(hours[&(seg_hour - HOUR_MS)].n_all < 3600, "{hours:?}");
    assert_eq!(all_rows(&store, tag), kept, "raw samples untouched");
    // Minutes from the hourly cutoff on are still the minute test's.
    let want_minutes = expected(&samples, |t| rolled(t) && t >= hourly_cut);
    assert_eq!(stored_rollups(&store, tag), want_minutes);
    // Every rolled-up sample is counted once, in a minute or in an hour.
    let counted: i64 = hours.values().map(|h| h.n_all).sum::<i64>()
        + want_minutes.values().map(|m| m.n_all).sum::<i64>();
    assert_eq!(
        counted,
        samples.iter().filter(|s| rolled(s.t_ms)).count() as i64
    );
    let stats = ok(store.storage_stats(now, &policy));
    assert_eq!(stats.rollups_1h.rows, want.len() as u64);
    assert_eq!(
        stats.rollups_1h.samples + stats.rollups.samples,
        counted as u64
    );
    assert_eq!(stats.next_retention.minutes_to_merge, 0);

    // 3. Idempotent: nothing to do, nothing changes; re-ingest adds nothing.
    let again = ok(store.apply_retention(now, &policy));
    assert_eq!(again.transactions(), 0, "{again:?}");
    assert_eq!(stored_hours(&store, tag), hours);
    assert_eq!(ok(store.insert_samples(&samples)), 0);
    assert_eq!(all_rows(&store, tag), kept);
    assert_eq!(stored_hours(&store, tag), hours);
    assert_eq!(ok(store.integrity_check()), "ok");
}

/// A minute row appearing in an hour already merged (a late raw minute rolled up after the
/// hour's merge) is merged into the hour's row: counts added, mean weighted, min/max/last
/// combined; the minute row goes.
#[test]
fn a_late_minute_is_merged_into_its_hour() {
    let dir = ok(tempfile::tempdir());
    let mut store = ok(Store::open(&dir.path().join("l.db")));
    let tag = ok(store.ensure_tag(&TagInfo {
        name: "x".into(),
        unit: String::new(),
        signal: None,
    }));
    // Minute 0: 1, 2, 3 (good); minute 1: one bad sample only.
    let s = |t: i64, v: f64, q: Quality| Sample {
        tag,
        t_ms: BASE + t,
        value: v,
        quality: q,
    };
    ok(store.insert_samples(&[
        s(0, 1.0, Quality::Good),
        s(10_000, 2.0, Quality::Good),
        s(20_000, 3.0, Quality::Good),
        s(MINUTE_MS, -5.0, Quality::Bad),
    ]));
    // Scanned after the insert (an insert behind the scan would ask for a rescan, which
    // holds retention back).
    ok(store.store_scan(&ScanWrite {
        records: Vec::new(),
        keep_from: BASE,
        scanned_to: BASE + 2 * DAY,
        last_fuel_off_ms: None,
    }));
    let policy = RetentionPolicy {
        raw_days: 1,
        segment_margin_s: 0,
        rollup_1m_days: 2,
    };
    let now = BASE + 10 * DAY;
    ok(store.apply_retention(now, &policy));
    assert_eq!(
        stored_hours(&store, tag).into_values().collect::<Vec<_>>(),
        [Hour {
            n_good: 3,
            n_all: 4,
            min: Some(1.0),
            mean: Some(2.0),
            max: Some(3.0),
            last: Some(3.0),
            last_ms: Some(BASE + 20_000),
        }]
    );
    // A late minute of the same hour, 10.0 and 20.0 at minute 30, behind ingest's back.
    ok(store.conn().execute(
        "INSERT INTO rollups_1m (tag_id, t_ms, n_good, n_all, min, mean, max, last, last_ms)
         VALUES (?1, ?2, 2, 3, 10.0, 15.0, 20.0, 20.0, ?3)",
        rusqlite::params![tag, BASE + 30 * MINUTE_MS, BASE + 30 * MINUTE_MS + 5_000],
    ));
    let done = ok(store.apply_retention(now, &policy));
    assert_eq!((done.minutes_merged, done.hours), (1, 1));
    assert_eq!(
        stored_hours(&store, tag).into_values().collect::<Vec<_>>(),
        [Hour {
            n_good: 5,
            n_all: 7,
            min: Some(1.0),
            mean: Some(36.0 / 5.0),
            max: Some(20.0),
            last: Some(20.0),
            last_ms: Some(BASE + 30 * MINUTE_MS + 5_000),
        }]
    );
    assert!(stored_rollups(&store, tag).is_empty());
}

#[test]
fn bad_rollup_1m_days_names_its_key() {
    use super::super::super::StorageConfig;
    let keys =
        |c: StorageConfig| -> Vec<String> { c.validate().into_iter().map(|p| p.key).collect() };
    assert_eq!(StorageConfig::default().rollup_1m_days, 0, "off by default");
    let with = |raw_days, rollup_1m_days| StorageConfig {
        raw_days,
        rollup_1m_days,
        compact_after_hours: 24,
        ..StorageConfig::default()
    };
    assert!(keys(with(7, 30)).is_empty());
    assert!(keys(with(7, 0)).is_empty());
    for bad in [with(0, 30), with(7, 7), with(7, 3), with(7, 40_000)] {
        assert_eq!(keys(bad), ["storage.rollup_1m_days"]);
    }
    let msg = with(7, 7).validate().remove(0).message;
    assert!(msg.contains("raw_days"), "{msg}");
}
