//! Retention under `kill -9` (README "Retention and roll-ups"): `gtwatch store retain` killed
//! at random moments during the minute roll-up, during the hourly merge (on a file of minute
//! roll-ups), and during one run doing both on raw data. Every minute is summarised exactly
//! once: raw, in `rollups_1m` or in its hour's `rollups_1h` row.

use super::{build_db, common, contents, copy_db, killed_run, BIN};
use gtwatch::store::Store;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

/// (tag, minute) → (n_good, n_all, bits of min, mean, max, last) of every roll-up row.
type Rollups = std::collections::BTreeMap<(i64, i64), MinuteRow>;

/// (n_good, n_all, bits of min, mean, max, last) of one minute row.
type MinuteRow = (i64, i64, [Option<u64>; 4]);

fn rollups(db: &Path) -> Rollups {
    let conn = common::open_db(db);
    let mut st = conn
        .prepare("SELECT tag_id, t_ms, n_good, n_all, min, mean, max, last FROM rollups_1m")
        .expect("prepare");
    let rows = st
        .query_map([], |r| {
            let bits = |i: usize| -> rusqlite::Result<Option<u64>> {
                Ok(r.get::<_, Option<f64>>(i)?.map(f64::to_bits))
            };
            Ok((
                (r.get(0)?, r.get(1)?),
                (
                    r.get(2)?,
                    r.get(3)?,
                    [bits(4)?, bits(5)?, bits(6)?, bits(7)?],
                ),
            ))
        })
        .expect("query");
    rows.collect::<Result<_, _>>().expect("rows")
}

/// Two days of four tags (the first archived, the second hot) ending 8 days ago, with one
/// start-up in the first day, scanned by the detector.
fn build_retention_db(db: &Path) {
    build_db(db);
    let mut store = Store::open(db).expect("open");
    let t0 = 1_700_000_000_000i64;
    store
        .store_scan(&gtwatch::store::ScanWrite {
            records: vec![gtwatch::segment::SegmentRecord {
                start_ms: t0 + 5 * 3_600_000,
                end_ms: Some(t0 + 5 * 3_600_000 + 1_500_000),
                outcome: gtwatch::segment::Outcome::Completed,
                abort_cause: None,
                hot_restart: false,
                has_gap: false,
                phases: Vec::new(),
            }],
            keep_from: t0,
            scanned_to: t0 + 3 * 86_400_000,
            last_fuel_off_ms: None,
        })
        .expect("scan");
    store.compact(t0 + 43_200_000, 4096).expect("compact");
    drop(store);
}

/// `gtwatch store stats --json` with the policy `retain_cmd` uses.
fn stats_json(db: &Path) -> serde_json::Value {
    let out = Command::new(BIN)
        .args([
            "store",
            "stats",
            "--raw-days",
            "1",
            "--segment-margin-s",
            "600",
            "--json",
            "--db",
        ])
        .arg(db)
        .output()
        .expect("stats");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON document")
}

fn retain_cmd(db: &Path) -> Command {
    let mut c = Command::new(BIN);
    c.args([
        "store",
        "retain",
        "--raw-days",
        "1",
        "--segment-margin-s",
        "600",
    ])
    .arg("--db")
    .arg(db)
    .stdout(Stdio::null())
    .stderr(Stdio::null());
    c
}

/// `gtwatch store retain` killed with SIGKILL at 20 seeded random moments: after each the file
/// is sound, every original sample is either still raw (bit for bit) or its minute is rolled
/// up — never both, never neither — every roll-up row is the one an uninterrupted run writes,
/// and a rerun ends where an uninterrupted run ends.
#[test]
fn retention_survives_kill_9_at_random_moments() {
    let dir = tempfile::tempdir().expect("tempdir");
    let original = dir.path().join("original.db");
    build_retention_db(&original);
    let orig = contents(&original);
    let work = dir.path().join("work.db");
    copy_db(&original, &work);
    let planned = stats_json(&work);
    let t = Instant::now();
    assert!(retain_cmd(&work).status().expect("run").success());
    let full = t.elapsed();
    let want_raw = contents(&work);
    let want_roll = rollups(&work);
    // `store stats` foretold the run and accounts for its result.
    let rolled = (orig.len() - want_raw.len()) as u64;
    assert_eq!(planned["next_retention"]["samples"].as_u64(), Some(rolled));
    let after = stats_json(&work);
    assert_eq!(after["rollups"]["samples"].as_u64(), Some(rolled));
    assert_eq!(
        after["rollups"]["rows"].as_u64(),
        Some(want_roll.len() as u64)
    );
    let raw_after =
        after["hot"]["samples"].as_u64().unwrap() + after["archive"]["samples"].as_u64().unwrap();
    assert_eq!(raw_after, want_raw.len() as u64);
    assert_eq!(after["next_retention"]["samples"].as_u64(), Some(0));
    assert!(!want_roll.is_empty() && want_raw.len() < orig.len() / 2);
    assert!(want_raw.len() > 4 * 1500, "the start-up ± margin stays raw");

    let mut rng = ChaCha8Rng::seed_from_u64(24_002);
    let (mut kills, mut mid, mut lost, mut duplicated) = (0u32, 0u32, 0u64, 0u64);
    for _ in 0..20 {
        let delay = full.mul_f64(rng.random_range(0.0..1.1));
        killed_run(&original, &work, retain_cmd, delay);
        kills += 1;
        let raw: std::collections::BTreeSet<_> = contents(&work).into_iter().collect();
        let roll = rollups(&work);
        if !roll.is_empty() && roll.len() < want_roll.len() {
            mid += 1;
        }
        for (key, row) in &roll {
            assert_eq!(
                Some(row),
                want_roll.get(key),
                "roll-up {key:?} after a kill at {delay:?}"
            );
        }
        for s in &orig {
            let in_raw = raw.contains(s);
            let in_roll = roll.contains_key(&(s.0, s.1 - s.1.rem_euclid(60_000)));
            lost += u64::from(!in_raw && !in_roll);
            duplicated += u64::from(in_raw && in_roll);
        }
        assert!(
            raw.iter().all(|s| orig.binary_search(s).is_ok()),
            "a raw sample changed"
        );
        assert!(retain_cmd(&work).status().expect("rerun").success());
        assert!(
            contents(&work) == want_raw,
            "rerun after a kill at {delay:?}"
        );
        assert!(
            rollups(&work) == want_roll,
            "rerun after a kill at {delay:?}"
        );
    }
    eprintln!(
        "FAULT-TALLY class=kill9_during_retention injected={kills} lost={lost} duplicated={duplicated} integrity=ok mid_retention={mid} full_run_ms={}",
        full.as_millis()
    );
    assert_eq!((lost, duplicated), (0, 0));
    assert!(mid >= 5, "only {mid} of {kills} kills landed mid-retention");
}

/// (tag, hour) → (n_good, n_all, bits of min, mean, max, last, last_ms) of every hourly row.
type Hours = std::collections::BTreeMap<(i64, i64), (i64, i64, [Option<u64>; 4], Option<i64>)>;

fn hours(db: &Path) -> Hours {
    let conn = common::open_db(db);
    let mut st = conn
        .prepare(
            "SELECT tag_id, t_ms, n_good, n_all, min, mean, max, last, last_ms FROM rollups_1h",
        )
        .expect("prepare");
    let rows = st
        .query_map([], |r| {
            let bits = |i: usize| -> rusqlite::Result<Option<u64>> {
                Ok(r.get::<_, Option<f64>>(i)?.map(f64::to_bits))
            };
            Ok((
                (r.get(0)?, r.get(1)?),
                (
                    r.get(2)?,
                    r.get(3)?,
                    [bits(4)?, bits(5)?, bits(6)?, bits(7)?],
                    r.get(8)?,
                ),
            ))
        })
        .expect("query");
    rows.collect::<Result<_, _>>().expect("rows")
}

/// 12 tags × 6 days of 1-minute roll-ups in 2023 (none raw): random values on a 1/8 grid,
/// every 50th minute without good samples (NULLs), every 97th missing.
fn build_minutes_db(db: &Path) {
    drop(Store::open(db).expect("create the schema"));
    let mut rng = ChaCha8Rng::seed_from_u64(2408);
    let t0 = 1_700_006_400_000i64;
    let conn = rusqlite::Connection::open(db).expect("open");
    conn.execute_batch("BEGIN").expect("begin");
    for k in 0..12 {
        conn.execute(
            "INSERT INTO tags (name, unit, created_at_ms) VALUES (?1, '', 0)",
            [format!("tag{k}")],
        )
        .expect("tag");
        let tag = conn.last_insert_rowid();
        let mut st = conn
            .prepare(
                "INSERT INTO rollups_1m (tag_id, t_ms, n_good, n_all, min, mean, max, last, last_ms)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
            )
            .expect("prepare");
        for m in 0..6 * 1440i64 {
            if m % 97 == 5 {
                continue;
            }
            let t = t0 + m * 60_000;
            let n_all: i64 = rng.random_range(50..=60);
            let n_good = if m % 50 == 7 {
                0
            } else {
                n_all - rng.random_range(0..3)
            };
            let v = |rng: &mut ChaCha8Rng| f64::from(rng.random_range(-800..800i32)) / 8.0;
            let (a, b, c) = (v(&mut rng), v(&mut rng), v(&mut rng));
            let mut three = [a, b, c];
            three.sort_by(f64::total_cmp);
            let good = n_good > 0;
            st.execute(rusqlite::params![
                tag,
                t,
                n_good,
                n_all,
                good.then_some(three[0]),
                good.then_some(three[1]),
                good.then_some(three[2]),
                good.then_some(three[1]),
                good.then_some(t + 59_000),
            ])
            .expect("minute");
        }
    }
    conn.execute_batch("COMMIT").expect("commit");
}

fn merge_cmd(db: &Path) -> Command {
    let mut c = Command::new(BIN);
    c.args([
        "store",
        "retain",
        "--raw-days",
        "1",
        "--rollup-1m-days",
        "2",
    ])
    .arg("--db")
    .arg(db)
    .stdout(Stdio::null())
    .stderr(Stdio::null());
    c
}

/// The hourly merge (`store retain --rollup-1m-days`) killed with SIGKILL at 20 seeded random
/// moments on a file of minute roll-ups: after each the file is sound, every original minute
/// is either still in `rollups_1m` unchanged or its hour has the row an uninterrupted run
/// writes — never both, never neither — and a rerun ends where an uninterrupted run ends.
/// The uninterrupted run's hours are checked against sums computed here.
#[test]
fn hourly_merge_survives_kill_9_at_random_moments() {
    let dir = tempfile::tempdir().expect("tempdir");
    let original = dir.path().join("minutes.db");
    build_minutes_db(&original);
    let orig = rollups(&original);
    let work = dir.path().join("work.db");
    copy_db(&original, &work);
    let t = Instant::now();
    assert!(merge_cmd(&work).status().expect("run").success());
    let full = t.elapsed();
    assert!(rollups(&work).is_empty(), "every minute merged");
    let want = hours(&work);
    // The uninterrupted run against the minutes: counts, min, max, last exact, mean 1e-9.
    let mut by_hour: std::collections::BTreeMap<(i64, i64), Vec<&MinuteRow>> =
        std::collections::BTreeMap::new();
    for ((tag, t), row) in &orig {
        by_hour
            .entry((*tag, t - t.rem_euclid(3_600_000)))
            .or_default()
            .push(row);
    }
    assert_eq!(by_hour.len(), want.len());
    let f = |b: Option<u64>| b.map(f64::from_bits);
    for (key, minutes) in &by_hour {
        let (n_good, n_all, vals, _) = want[key];
        assert_eq!(n_good, minutes.iter().map(|m| m.0).sum::<i64>());
        assert_eq!(n_all, minutes.iter().map(|m| m.1).sum::<i64>());
        let good: Vec<_> = minutes.iter().filter(|m| m.0 > 0).collect();
        let min = good.iter().filter_map(|m| f(m.2[0])).reduce(f64::min);
        let max = good.iter().filter_map(|m| f(m.2[2])).reduce(f64::max);
        let last = good.last().and_then(|m| f(m.2[3]));
        assert_eq!(
            (f(vals[0]), f(vals[2]), f(vals[3])),
            (min, max, last),
            "{key:?}"
        );
        let sum: f64 = good
            .iter()
            .filter_map(|m| f(m.2[1]).map(|v| v * m.0 as f64))
            .sum();
        match (f(vals[1]), n_good) {
            (None, 0) => {}
            (Some(mean), n) if n > 0 => {
                let truth = sum / n as f64;
                assert!(
                    (mean - truth).abs() <= 1e-9 * truth.abs().max(1.0),
                    "{key:?}"
                );
            }
            other => panic!("{key:?}: {other:?}"),
        }
    }

    let mut rng = ChaCha8Rng::seed_from_u64(24_008);
    let (mut kills, mut mid, mut lost, mut duplicated) = (0u32, 0u32, 0u64, 0u64);
    for _ in 0..20 {
        let delay = full.mul_f64(rng.random_range(0.0..1.1));
        killed_run(&original, &work, merge_cmd, delay);
        kills += 1;
        let minutes = rollups(&work);
        let hrs = hours(&work);
        if !hrs.is_empty() && hrs.len() < want.len() {
            mid += 1;
        }
        for (key, row) in &hrs {
            assert_eq!(
                Some(row),
                want.get(key),
                "hour {key:?} after a kill at {delay:?}"
            );
        }
        for (key, row) in &minutes {
            assert_eq!(Some(row), orig.get(key), "minute {key:?} changed");
        }
        for (tag, t) in orig.keys() {
            let in_min = minutes.contains_key(&(*tag, *t));
            let in_hour = hrs.contains_key(&(*tag, t - t.rem_euclid(3_600_000)));
            lost += u64::from(!in_min && !in_hour);
            duplicated += u64::from(in_min && in_hour);
        }
        assert!(merge_cmd(&work).status().expect("rerun").success());
        assert!(
            rollups(&work).is_empty() && hours(&work) == want,
            "rerun after a kill at {delay:?}"
        );
    }
    eprintln!(
        "FAULT-TALLY class=kill9_during_hourly_merge injected={kills} lost={lost} duplicated={duplicated} integrity=ok mid_merge={mid} full_run_ms={}",
        full.as_millis()
    );
    assert_eq!((lost, duplicated), (0, 0));
    assert!(mid >= 5, "only {mid} of {kills} kills landed mid-merge");
}

/// `store retain` with both tiers (`--rollup-1m-days 2`: every minute rolled up is then merged
/// into its hour) killed with SIGKILL at 20 seeded random moments, during the minute roll-up or
/// the hourly merge: after each the file is sound, every original sample is raw (bit for bit),
/// or in its minute's row (the one a minute-only run writes), or counted in its hour's row (the
/// one an uninterrupted run writes) — each hour's `n_all` equals the samples of the hour
/// neither raw nor in a minute row — and a rerun ends where an uninterrupted run ends.
#[test]
fn retention_with_hourly_merge_survives_kill_9_at_random_moments() {
    let both = |db: &Path| {
        let mut c = retain_cmd(db);
        c.args(["--rollup-1m-days", "2"]);
        c
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let original = dir.path().join("original.db");
    build_retention_db(&original);
    let orig = contents(&original);
    let work = dir.path().join("work.db");
    // The minute rows a minute-only run writes: the only ones allowed to appear.
    copy_db(&original, &work);
    assert!(retain_cmd(&work).status().expect("run").success());
    let minute_ref = rollups(&work);
    copy_db(&original, &work);
    let t = Instant::now();
    assert!(both(&work).status().expect("run").success());
    let full = t.elapsed();
    let (want_raw, want_min, want_hours) = (contents(&work), rollups(&work), hours(&work));
    assert!(!want_hours.is_empty() && want_min.len() < minute_ref.len());
    let hour_of = |t: i64| t - t.rem_euclid(3_600_000);

    let mut rng = ChaCha8Rng::seed_from_u64(24_018);
    let (mut kills, mut mid_hourly, mut lost, mut duplicated) = (0u32, 0u32, 0u64, 0u64);
    for _ in 0..20 {
        let delay = full.mul_f64(rng.random_range(0.0..1.1));
        killed_run(&original, &work, both, delay);
        kills += 1;
        let raw: std::collections::BTreeSet<_> = contents(&work).into_iter().collect();
        let (mins, hrs) = (rollups(&work), hours(&work));
        if !hrs.is_empty() && hrs.len() < want_hours.len() {
            mid_hourly += 1;
        }
        for (key, row) in &mins {
            assert_eq!(
                Some(row),
                minute_ref.get(key),
                "minute {key:?} at {delay:?}"
            );
        }
        for (key, row) in &hrs {
            assert_eq!(Some(row), want_hours.get(key), "hour {key:?} at {delay:?}");
        }
        // Per hour: the samples neither raw nor in a minute row, which its row must count.
        let mut unaccounted: std::collections::BTreeMap<(i64, i64), i64> = Default::default();
        for s in &orig {
            let in_raw = raw.contains(s);
            let in_min = mins.contains_key(&(s.0, s.1 - s.1.rem_euclid(60_000)));
            duplicated += u64::from(in_raw && in_min);
            if !in_raw && !in_min {
                *unaccounted.entry((s.0, hour_of(s.1))).or_default() += 1;
            }
        }
        for (key, n) in &unaccounted {
            let counted = hrs.get(key).map_or(0, |h| h.1);
            lost += u64::try_from(n - counted).unwrap_or(0);
            duplicated += u64::try_from(counted - n).unwrap_or(0);
        }
        for (key, h) in &hrs {
            if !unaccounted.contains_key(key) {
                duplicated += u64::try_from(h.1).unwrap_or(0);
            }
        }
        assert!(
            raw.iter().all(|s| orig.binary_search(s).is_ok()),
            "a raw sample changed"
        );
        assert!(both(&work).status().expect("rerun").success());
        assert!(
            contents(&work) == want_raw && rollups(&work) == want_min && hours(&work) == want_hours,
            "rerun after a kill at {delay:?}"
        );
    }
    eprintln!(
        "FAULT-TALLY class=kill9_during_retention_both_tiers injected={kills} lost={lost} duplicated={duplicated} integrity=ok mid_hourly={mid_hourly} full_run_ms={}",
        full.as_millis()
    );
    assert_eq!((lost, duplicated), (0, 0));
}
