//! Ingest straight into the archive tier (issue 24 item 3): a historical log's samples are
//! written as compressed chunks in the replay's own transactions, never as hot rows, so the
//! ingest rate does not fall as the `samples` B-tree grows and no compaction pass has to move
//! them afterwards.
//!
//! The same guarantees as the hot path ([`super::super::insert_samples_in`]):
//! - **Idempotent.** A (tag, time) already stored — hot, archived or rolled up — is skipped,
//!   and of two samples with the same (tag, time) in one batch the first is kept (as
//!   `INSERT OR IGNORE` keeps the first inserted), so a replay run twice stores nothing twice.
//! - **Crash-safe.** One batch (its chunks, its gaps and the detector's rescan mark) is one
//!   transaction: a crash or `kill -9` leaves the batch whole or absent, and running the
//!   replay again fills in what is absent.
//! - **Lossless.** The chunk codec is the compaction's: every value bit for bit (even `-0.0`,
//!   which the hot tier's REAL column turns into `+0.0`), every quality code.
//!
//! Chunks stay inside the aligned windows of [`CHUNK_SPAN_MS`] the compaction uses (at most
//! `max_chunk_samples` each), so a batch that covers one window per tag (the replay flushes at
//! window boundaries) gives the same chunks a compaction would.
//!
//! Must not: parse files or decide bad values (that is `ingest`); write hot rows.

use super::super::{record_gap_in, retention, Gap, Sample, Store, StoreError, TagId};
use super::codec::{self, Columns, CODEC_PCO_V1};
use super::CHUNK_SPAN_MS;
use rusqlite::{params, Connection, TransactionBehavior};

/// What one direct write did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DirectStats {
    /// Samples newly stored (the rest of the batch was already there).
    pub inserted: usize,
    /// Chunks written.
    pub chunks: u64,
    /// Bytes of their blobs.
    pub blob_bytes: u64,
}

impl Store {
    /// Stores `batch` as archive chunks and records `gaps`, in one transaction: the archive
    /// twin of [`Store::insert_samples_and_gaps`] (same idempotence, same rescan mark).
    pub fn insert_samples_archived(
        &mut self,
        batch: &[Sample],
        gaps: &[Gap],
        max_chunk_samples: usize,
    ) -> Result<DirectStats, StoreError> {
        // Immediate for the same reason as the hot path: it reads the tiers before it writes.
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let stats = archive_in(&tx, batch, max_chunk_samples.max(1))?;
        for g in gaps {
            record_gap_in(&tx, g)?;
        }
        tx.commit()?;
        Ok(stats)
    }
}

/// The batch's new samples as chunks, inside the caller's transaction.
fn archive_in(
    conn: &Connection,
    batch: &[Sample],
    max_chunk_samples: usize,
) -> Result<DirectStats, StoreError> {
    let mut order: Vec<usize> = (0..batch.len()).collect();
    // Stable: of equal (tag, time) the batch's first stays first and is the one kept.
    order.sort_by_key(|&i| (batch[i].tag, batch[i].t_ms));
    let mut stats = DirectStats::default();
    let mut rolled = retention::RolledUpMinutes::default();
    let mut min_t = i64::MAX;
    let mut start = 0;
    while start < order.len() {
        let first = &batch[order[start]];
        let window = first.t_ms.div_euclid(CHUNK_SPAN_MS);
        let mut end = start;
        while end < order.len() {
            let s = &batch[order[end]];
            if s.tag != first.tag || s.t_ms.div_euclid(CHUNK_SPAN_MS) != window {
                break;
            }
            end += 1;
        }
        let group: Vec<&Sample> = order[start..end].iter().map(|&i| &batch[i]).collect();
        let (from, to) = (group[0].t_ms, group[group.len() - 1].t_ms);
        let hot = hot_times(conn, first.tag, from, to)?;
        let old = archived_times(conn, first.tag, from, to)?;
        let mut c = Columns::default();
        for s in group {
            if c.t_ms.last() == Some(&s.t_ms)
                || hot.binary_search(&s.t_ms).is_ok()
                || old.binary_search(&s.t_ms).is_ok()
                || rolled.contains(conn, s.tag, s.t_ms)?
            {
                continue;
            }
            c.t_ms.push(s.t_ms);
            c.values.push(s.value);
            c.quality.push(s.quality.code());
        }
        if let Some(&t0) = c.t_ms.first() {
            min_t = min_t.min(t0);
        }
        stats.inserted += c.len();
        for part in split(&c, max_chunk_samples) {
            stats.blob_bytes += write_chunk(conn, first.tag, &part)?;
            stats.chunks += 1;
        }
        start = end;
    }
    // Samples older than what the detector has scanned (a late replay) make it rescan.
    if stats.inserted > 0 {
        conn.prepare_cached(
            "UPDATE detector_state SET rescan_from_ms = MIN(COALESCE(rescan_from_ms, ?1), ?1)
             WHERE id = 1 AND scanned_to_ms IS NOT NULL AND ?1 <= scanned_to_ms",
        )?
        .execute(params![min_t])?;
    }
    Ok(stats)
}

/// Times of `tag`'s hot rows in `[from, to]`, ascending.
fn hot_times(conn: &Connection, tag: TagId, from: i64, to: i64) -> Result<Vec<i64>, StoreError> {
    let mut st = conn.prepare_cached(
        "SELECT t_ms FROM samples WHERE tag_id = ?1 AND t_ms >= ?2 AND t_ms <= ?3 ORDER BY t_ms",
    )?;
    let rows = st.query_map(params![tag, from, to], |r| r.get::<_, i64>(0))?;
    Ok(rows.collect::<Result<Vec<_>, _>>()?)
}

/// Times of `tag`'s archived samples in `[from, to]`, ascending (one query and one decode of
/// the time column per overlapping chunk, not one query per sample as on the hot path).
fn archived_times(
    conn: &Connection,
    tag: TagId,
    from: i64,
    to: i64,
) -> Result<Vec<i64>, StoreError> {
    let mut st = conn.prepare_cached(
        "SELECT n, t_blob FROM archive_chunks
         WHERE tag_id = ?1 AND t_start_ms <= ?3 AND t_end_ms >= ?2 AND t_start_ms >= ?4",
    )?;
    // A chunk never spans more than one aligned window, so one overlapping the range starts
    // at most a window before it: the bound keeps the index range short however long the
    // archive already is (ingest speed must not fall as the database grows).
    let mut rows = st.query(params![tag, from, to, from.saturating_sub(CHUNK_SPAN_MS)])?;
    let mut out = Vec::new();
    while let Some(r) = rows.next()? {
        let n: i64 = r.get(0)?;
        let blob: Vec<u8> = r.get(1)?;
        let times = codec::decode_times(&blob, usize::try_from(n).unwrap_or(0))?;
        out.extend(times.into_iter().filter(|t| (from..=to).contains(t)));
    }
    out.sort_unstable();
    Ok(out)
}

/// `c` in pieces of at most `max` samples (none when empty).
fn split(c: &Columns, max: usize) -> Vec<Columns> {
    (0..c.len())
        .step_by(max)
        .map(|i| {
            let j = (i + max).min(c.len());
            Columns {
                t_ms: c.t_ms[i..j].to_vec(),
                values: c.values[i..j].to_vec(),
                quality: c.quality[i..j].to_vec(),
            }
        })
        .collect()
}

/// Inserts one chunk of `tag`; returns its blob bytes.
fn write_chunk(conn: &Connection, tag: TagId, c: &Columns) -> Result<u64, StoreError> {
    let (Some(&t0), Some(&t1)) = (c.t_ms.first(), c.t_ms.last()) else {
        return Ok(0);
    };
    let e = codec::encode(c)?;
    conn.prepare_cached(
        "INSERT INTO archive_chunks (tag_id, t_start_ms, t_end_ms, n, codec, t_blob, v_blob, q_blob)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
    )?
    .execute(params![tag, t0, t1, c.len() as i64, CODEC_PCO_V1, e.t, e.v, e.q])?;
    Ok((e.t.len() + e.v.len() + e.q.len()) as u64)
}
