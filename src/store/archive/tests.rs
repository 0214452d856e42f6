//! The archive tier through the store: random ingest, compaction, read-back bit for bit;
//! idempotent re-ingest of archived samples; a late sample inside an archived span.

use super::super::{Sample, Store, TagInfo};
use super::CHUNK_SPAN_MS;
use crate::quality::Quality;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

type Key = (i64, i64);
/// (value bits, quality code) of every stored (tag, time).
type Contents = BTreeMap<Key, (u64, i64)>;

fn temp_store() -> (tempfile::TempDir, Store) {
    let dir = tempfile::tempdir().unwrap_or_else(|e| unreachable!("{e}"));
    let store = Store::open(&dir.path().join("t.db")).unwrap_or_else(|e| unreachable!("{e}"));
    (dir, store)
}

/// A tag for each of `names` (no unit, no signal).
fn tags_named(store: &mut Store, names: &[&str]) -> Vec<i64> {
    names
        .iter()
        .map(|n| {
            store
                .ensure_tag(&TagInfo {
                    name: (*n).into(),
                    unit: String::new(),
                    signal: None,
                })
                .unwrap_or_else(|e| unreachable!("{e}"))
        })
        .collect()
}

/// Everything the store's one read path returns, per tag.
fn contents(store: &Store, tags: &[i64]) -> Contents {
    let mut out = Contents::new();
    for &tag in tags {
        let rows = store
            .tag_samples_between(tag, i64::MIN, i64::MAX)
            .unwrap_or_else(|e| unreachable!("{e}"));
        assert!(rows.windows(2).all(|w| w[0].t_ms < w[1].t_ms), "time order");
        for s in rows {
            out.insert((tag, s.t_ms), (s.value.to_bits(), s.quality));
        }
    }
    out
}

fn random_batches(rng: &mut ChaCha8Rng, tags: &[i64], n: usize) -> Vec<Vec<Sample>> {
    let t0 = 1_700_000_000_000i64;
    let mut all = Vec::new();
    for &tag in tags {
        let mut t = t0 + rng.random_range(0..5000);
        for _ in 0..n {
            // 1 s steps with jitter, now and then a gap of up to a day.
            t += if rng.random_bool(0.002) {
                rng.random_range(60_000..86_400_000)
            } else {
                1000 + rng.random_range(-2..3)
            };
            let value = match rng.random_range(0..20) {
                0 => -0.0,
                1 => f64::from_bits(rng.random_range(1..1u64 << 52)),
                2 => rng.random_range(-1e300..1e300),
                _ => 7000.0 + rng.random_range(-50.0..50.0f64).round() / 8.0,
            };
            let quality = Quality::from_code(rng.random_range(0..=4))
                .unwrap_or_else(|| unreachable!("codes 0..4"));
            all.push(Sample {
                tag,
                t_ms: t,
                value,
                quality,
            });
        }
    }
    // Out of order, with duplicates (the first stored wins, as INSERT OR IGNORE does).
    let dups: Vec<Sample> = all.iter().step_by(17).copied().collect();
    all.extend(dups.into_iter().map(|s| Sample { value: 1.5, ..s }));
    all.shuffle(rng);
    all.chunks(977).map(<[Sample]>::to_vec).collect()
}

#[test]
fn compaction_round_trips_every_sample_bit_for_bit() {
    let (_d, mut store) = temp_store();
    let mut rng = ChaCha8Rng::seed_from_u64(2424);
    let tags = tags_named(&mut store, &["a", "b", "c"]);
    let batches = random_batches(&mut rng, &tags, 30_000);
    for b in &batches {
        store
            .insert_samples(b)
            .unwrap_or_else(|e| unreachable!("{e}"));
    }
    let before = contents(&store, &tags);
    let count = store.sample_count().unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(count as usize, before.len());
    let ranges: Vec<_> = tags
        .iter()
        .map(|&t| {
            store
                .tag_time_range(t)
                .unwrap_or_else(|e| unreachable!("{e}"))
        })
        .collect();

    let stats = store
        .compact(i64::MAX, 5000)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert!(stats.chunks > 10, "{stats:?}");
    // Only whole windows before the cutoff: with i64::MAX, all of them.
    assert_eq!(stats.samples as usize, before.len());
    let hot: i64 = store
        .conn()
        .query_row("SELECT COUNT(*) FROM samples", [], |r| r.get(0))
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(hot, 0);
    assert!(contents(&store, &tags) == before, "read back differs");
    assert_eq!(store.sample_count().ok(), Some(count));
    for (i, &t) in tags.iter().enumerate() {
        assert_eq!(store.tag_time_range(t).ok(), Some(ranges[i]));
    }

    // Replaying the same data again stores nothing twice.
    for b in &batches {
        assert_eq!(store.insert_samples(b).ok(), Some(0));
    }
    assert!(contents(&store, &tags) == before);

    // A new sample in a hole of an archived span is stored (hot), then archived again.
    let (&(tag, t), _) = before
        .iter()
        .find(|((tag, t), _)| !before.contains_key(&(*tag, t + 500)))
        .unwrap_or_else(|| unreachable!("a hole"));
    let late = Sample {
        tag,
        t_ms: t + 500,
        // (Not -0.0: the hot tier's REAL column stores an integral value as an integer, so
        // SQLite itself hands -0.0 back as +0.0. The archive keeps whatever the hot tier held.)
        value: f64::from_bits(3),
        quality: Quality::Spike,
    };
    assert_eq!(store.insert_samples(&[late]).ok(), Some(1));
    assert_eq!(store.insert_samples(&[late]).ok(), Some(0));
    let mut expected = before.clone();
    expected.insert((tag, t + 500), (3, 4));
    assert!(contents(&store, &tags) == expected);
    let again = store
        .compact(i64::MAX, 5000)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!((again.chunks, again.samples), (1, 1));
    assert!(contents(&store, &tags) == expected);
    assert_eq!(store.insert_samples(&[late]).ok(), Some(0));
    assert_eq!(store.integrity_check().ok().as_deref(), Some("ok"));
}

#[test]
fn only_whole_windows_before_the_cutoff_and_no_open_segment_are_archived() {
    let (_d, mut store) = temp_store();
    let tag = store
        .ensure_tag(&TagInfo {
            name: "x".into(),
            unit: String::new(),
            signal: None,
        })
        .unwrap_or_else(|e| unreachable!("{e}"));
    let w0 = 1_700_006_400_000i64.div_euclid(CHUNK_SPAN_MS) * CHUNK_SPAN_MS;
    let batch: Vec<Sample> = (0..3 * CHUNK_SPAN_MS / 60_000)
        .map(|i| Sample {
            tag,
            t_ms: w0 + i * 60_000,
            value: i as f64,
            quality: Quality::Good,
        })
        .collect();
    store
        .insert_samples(&batch)
        .unwrap_or_else(|e| unreachable!("{e}"));
    // Cutoff inside the second window: only the first is archived.
    let s = store
        .compact(w0 + CHUNK_SPAN_MS + 1, 100_000)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(s.chunks, 1);
    assert_eq!(s.samples as i64, CHUNK_SPAN_MS / 60_000);
    // An open segment from the middle of the third window: the second window (ending before
    // it) is archived, the third is not.
    store
        .conn()
        .execute(
            "INSERT INTO segments (start_ms, outcome, status, updated_at_ms)
             VALUES (?1, 'in_progress', 'open', 0)",
            [w0 + 2 * CHUNK_SPAN_MS + 3_600_000],
        )
        .unwrap_or_else(|e| unreachable!("{e}"));
    let s = store
        .compact(i64::MAX, 100_000)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(s.chunks, 1);
    assert_eq!(s.cutoff_ms, w0 + 2 * CHUNK_SPAN_MS + 3_600_000);
    let all = store
        .tag_samples_between(tag, i64::MIN, i64::MAX)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(all.len(), batch.len());
    assert!(all
        .iter()
        .zip(&batch)
        .all(|(a, b)| a.t_ms == b.t_ms && a.value == b.value));
    // Reads that straddle the tiers.
    let mid = store
        .tag_samples_between(
            tag,
            w0 + CHUNK_SPAN_MS - 120_000,
            w0 + CHUNK_SPAN_MS * 5 / 2,
        )
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(mid.len() as i64, 2 + CHUNK_SPAN_MS * 3 / 2 / 60_000 + 1);
    assert_eq!(
        store.next_good_sample_ms(tag, w0 + 1).ok(),
        Some(Some(w0 + 60_000))
    );
    assert_eq!(
        store.last_sample_ms(&[tag]).ok(),
        Some(batch.last().map(|s| s.t_ms))
    );
}

#[test]
fn direct_archive_ingest_keeps_the_first_of_every_sample_bit_for_bit() {
    let (_d, mut store) = temp_store();
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let tags = tags_named(&mut store, &["a", "b"]);
    let batches = random_batches(&mut rng, &tags, 20_000);
    // Some of it hot first (a live tail the replay overlaps): those stay as they are.
    let hot_part: Vec<Sample> = batches[0]
        .iter()
        .map(|s| Sample { value: 2.5, ..*s })
        .collect();
    let hot_n = store.insert_samples(&hot_part).unwrap_or(0);
    assert!(hot_n > 0);
    let mut expected = contents(&store, &tags);
    for b in &batches {
        for s in b {
            expected
                .entry((s.tag, s.t_ms))
                .or_insert((s.value.to_bits(), i64::from(s.quality.code())));
        }
    }
    let mut inserted = 0;
    for b in &batches {
        let d = store
            .insert_samples_archived(b, &[], 5000)
            .unwrap_or_else(|e| unreachable!("{e}"));
        inserted += d.inserted;
    }
    assert_eq!(inserted + hot_n, expected.len());
    assert!(contents(&store, &tags) == expected, "read back differs");
    assert_eq!(store.sample_count().ok(), Some(expected.len() as i64));
    // Every chunk within one aligned window and the size cap.
    let bad: i64 = store
        .conn()
        .query_row(
            "SELECT COUNT(*) FROM archive_chunks
             WHERE t_start_ms / ?1 != t_end_ms / ?1 OR n > 5000",
            [CHUNK_SPAN_MS],
            |r| r.get(0),
        )
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert_eq!(bad, 0);
    // Nothing twice, by either path; a compaction afterwards changes nothing either.
    for b in &batches {
        assert_eq!(
            store
                .insert_samples_archived(b, &[], 5000)
                .ok()
                .map(|d| d.inserted),
            Some(0)
        );
        assert_eq!(store.insert_samples(b).ok(), Some(0));
    }
    store
        .compact(i64::MAX, 5000)
        .unwrap_or_else(|e| unreachable!("{e}"));
    assert!(contents(&store, &tags) == expected);
    assert_eq!(store.integrity_check().ok().as_deref(), Some("ok"));
}
