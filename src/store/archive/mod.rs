//! The archive tier: old samples as compressed per-tag chunks (`archive_chunks`), in the same
//! file as the hot tier (`samples`). README "Storage tiers".
//!
//! Guarantees:
//! - **One tier per sample.** [`Store::compact`] moves one tag's chunk at a time: it inserts
//!   the chunk and deletes exactly the hot rows it holds in ONE transaction, so a crash or
//!   `kill -9` at any instant leaves either the hot rows or the chunk, never both or neither.
//! - **Readers cannot tell the tiers apart.** Every read of samples in the store goes through
//!   [`read_samples`] (or the min/max/count helpers here built on the same two tables): hot
//!   rows plus the decoded chunks overlapping the range, merged by time. Should a (tag, time)
//!   ever be in both, the hot row wins.
//! - **Ingest stays idempotent.** [`ArchivedTimes`] lets `insert_samples_in` skip a sample
//!   whose (tag, time) is already archived, exactly as `INSERT OR IGNORE` skips one already
//!   hot; a genuinely new sample inside an archived span (a late replay filling a hole) is
//!   stored hot and archived by the next compaction in a chunk of its own. So any range may
//!   be compacted, even one that can still receive rows.
//! - **What is compacted.** Whole aligned windows of [`CHUNK_SPAN_MS`] (at most
//!   `max_chunk_samples` samples per chunk) that end before the cutoff: the caller's
//!   `before_ms`, pulled back to the start of any open segment and to the detector's pending
//!   rescan, so the data the detector and the worker are still working on stays hot.

pub mod codec;
pub mod direct;

use super::segments::SampleRow;
use super::{Store, StoreError, TagId};
use codec::{Columns, Encoded, CODEC_PCO_V1};
use rusqlite::{params, Connection, OptionalExtension, TransactionBehavior};
use std::collections::HashMap;

/// Chunks cover aligned windows of this span (6 h: 21 600 samples of a 1 Hz tag).
pub const CHUNK_SPAN_MS: i64 = 6 * 3_600_000;

/// Default cap on the samples of one chunk (a faster tag's window is split).
pub const DEFAULT_MAX_CHUNK_SAMPLES: usize = 32_768;

/// What one compaction did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct CompactStats {
    /// Chunks written (one transaction each).
    pub chunks: u64,
    /// Samples moved from the hot tier into them.
    pub samples: u64,
    /// Bytes of the chunks' blobs.
    pub blob_bytes: u64,
    /// The effective cutoff (samples before it may be archived).
    pub cutoff_ms: i64,
}

/// The archive's size.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ArchiveStats {
    pub chunks: u64,
    pub samples: u64,
    pub blob_bytes: u64,
}

impl From<codec::CodecError> for StoreError {
    fn from(e: codec::CodecError) -> StoreError {
        StoreError::Corrupt(e.to_string())
    }
}

/// Decodes one `archive_chunks` row (`n, codec, t_blob, v_blob, q_blob`).
pub(super) fn decode_row(r: &rusqlite::Row<'_>) -> Result<Columns, StoreError> {
    let n: i64 = r.get(0)?;
    let codec: i64 = r.get(1)?;
    if codec != CODEC_PCO_V1 {
        return Err(StoreError::Corrupt(format!("archive codec {codec}")));
    }
    let e = Encoded {
        t: r.get(2)?,
        v: r.get(3)?,
        q: r.get(4)?,
    };
    Ok(codec::decode(&e, usize::try_from(n).unwrap_or(0))?)
}

/// Every sample of `tag` with `from ≤ t ≤ to` (only quality 0 if `good_only`), from both
/// tiers, in time order: THE read of samples.
pub(crate) fn read_samples(
    conn: &Connection,
    tag: TagId,
    from: i64,
    to: i64,
    good_only: bool,
) -> Result<Vec<SampleRow>, StoreError> {
    let sql = if good_only {
        "SELECT t_ms, value, quality FROM samples WHERE tag_id = ?1 AND t_ms BETWEEN ?2 AND ?3
           AND quality = 0 ORDER BY t_ms"
    } else {
        "SELECT t_ms, value, quality FROM samples WHERE tag_id = ?1 AND t_ms BETWEEN ?2 AND ?3
           ORDER BY t_ms"
    };
    let mut st = conn.prepare_cached(sql)?;
    let rows = st.query_map(params![tag, from, to], |r| {
        Ok(SampleRow {
            t_ms: r.get(0)?,
            value: r.get(1)?,
            quality: r.get(2)?,
        })
    })?;
    let hot: Vec<SampleRow> = rows.collect::<Result<_, _>>()?;
    let mut archived = Vec::new();
    let mut st = conn.prepare_cached(
        "SELECT n, codec, t_blob, v_blob, q_blob FROM archive_chunks
         WHERE tag_id = ?1 AND t_end_ms >= ?2 AND t_start_ms <= ?3 ORDER BY t_start_ms",
    )?;
    let mut rows = st.query(params![tag, from, to])?;
    while let Some(r) = rows.next()? {
        let c = decode_row(r)?;
        for i in 0..c.len() {
            let t = c.t_ms[i];
            if t < from || t > to || (good_only && c.quality[i] != 0) {
                continue;
            }
            archived.push(SampleRow {
                t_ms: t,
                value: c.values[i],
                quality: i64::from(c.quality[i]),
            });
        }
    }
    if archived.is_empty() {
        return Ok(hot);
    }
    Ok(merge(hot, archived))
}

/// Merges the tiers by time; a time in both keeps the hot row (cannot happen while every
/// compaction is one transaction; logged if it does).
fn merge(hot: Vec<SampleRow>, mut archived: Vec<SampleRow>) -> Vec<SampleRow> {
    // Chunks of one tag may overlap in span (a late sample archived later): sort them.
    archived.sort_by_key(|s| s.t_ms);
    let mut out = Vec::with_capacity(hot.len() + archived.len());
    let (mut i, mut j) = (0, 0);
    while i < hot.len() || j < archived.len() {
        let take_hot = match (hot.get(i), archived.get(j)) {
            (Some(h), Some(a)) if h.t_ms == a.t_ms => {
                tracing::warn!(t_ms = h.t_ms, "sample in both tiers; the hot row is used");
                j += 1;
                true
            }
            (Some(h), Some(a)) => h.t_ms < a.t_ms,
            (Some(_), None) => true,
            _ => false,
        };
        if take_hot {
            out.push(hot[i]);
            i += 1;
        } else {
            out.push(archived[j]);
            j += 1;
        }
    }
    out
}

/// The first sample time of `tag` at or after `from` (only good ones if `good_only`), in
/// either tier.
pub(crate) fn first_sample_from(
    conn: &Connection,
    tag: TagId,
    from: i64,
    good_only: bool,
) -> Result<Option<i64>, StoreError> {
    let sql = if good_only {
        "SELECT MIN(t_ms) FROM samples WHERE tag_id = ?1 AND t_ms >= ?2 AND quality = 0"
    } else {
        "SELECT MIN(t_ms) FROM samples WHERE tag_id = ?1 AND t_ms >= ?2"
    };
    let hot: Option<i64> = conn.query_row(sql, params![tag, from], |r| r.get(0))?;
    let mut st = conn.prepare_cached(
        "SELECT n, codec, t_blob, v_blob, q_blob, t_start_ms FROM archive_chunks
         WHERE tag_id = ?1 AND t_end_ms >= ?2 AND t_start_ms < ?3 ORDER BY t_start_ms",
    )?;
    let mut rows = st.query(params![tag, from, hot.unwrap_or(i64::MAX)])?;
    let mut best = hot;
    while let Some(r) = rows.next()? {
        let start: i64 = r.get(5)?;
        if best.is_some_and(|b| start >= b) {
            break;
        }
        let c = decode_row(r)?;
        let found = (0..c.len())
            .find(|&i| c.t_ms[i] >= from && (!good_only || c.quality[i] == 0))
            .map(|i| c.t_ms[i]);
        if let Some(t) = found {
            best = Some(best.map_or(t, |b| b.min(t)));
        }
    }
    Ok(best)
}

/// First and last sample time of `tag` (any quality), over both tiers.
pub(crate) fn time_range(
    conn: &Connection,
    tag: TagId,
) -> Result<(Option<i64>, Option<i64>), StoreError> {
    let (h0, h1): (Option<i64>, Option<i64>) = conn.query_row(
        "SELECT MIN(t_ms), MAX(t_ms) FROM samples WHERE tag_id = ?1",
        params![tag],
        |r| Ok((r.get(0)?, r.get(1)?)),
    )?;
    let (a0, a1): (Option<i64>, Option<i64>) = conn.query_row(
        "SELECT MIN(t_start_ms), MAX(t_end_ms) FROM archive_chunks WHERE tag_id = ?1",
        params![tag],
        |r| Ok((r.get(0)?, r.get(1)?)),
    )?;
    let min = match (h0, a0) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    };
    Ok((min, h1.max(a1)))
}

/// Samples in both tiers.
pub(crate) fn count_all(conn: &Connection) -> Result<i64, StoreError> {
    let hot: i64 = conn.query_row("SELECT COUNT(*) FROM samples", [], |r| r.get(0))?;
    let arch: i64 = conn.query_row("SELECT COALESCE(SUM(n), 0) FROM archive_chunks", [], |r| {
        r.get(0)
    })?;
    Ok(hot + arch)
}

/// Samples (any quality, both tiers) of `tag` over `[from, to]`, counted without decoding
/// values: the hot rows through the primary key, the overlapping chunks' time columns.
pub(crate) fn count_samples(
    conn: &Connection,
    tag: TagId,
    from: i64,
    to: i64,
) -> Result<i64, StoreError> {
    let hot: i64 = conn
        .prepare_cached(
            "SELECT COUNT(*) FROM samples WHERE tag_id = ?1 AND t_ms BETWEEN ?2 AND ?3",
        )?
        .query_row(params![tag, from, to], |r| r.get(0))?;
    let mut st = conn.prepare_cached(
        "SELECT n, t_blob FROM archive_chunks
         WHERE tag_id = ?1 AND t_end_ms >= ?2 AND t_start_ms <= ?3",
    )?;
    let mut rows = st.query(params![tag, from, to])?;
    let mut archived = 0i64;
    while let Some(r) = rows.next()? {
        let n: i64 = r.get(0)?;
        let blob: Vec<u8> = r.get(1)?;
        let times = codec::decode_times(&blob, usize::try_from(n).unwrap_or(0))?;
        archived += times.iter().filter(|&&t| t >= from && t <= to).count() as i64;
    }
    Ok(hot + archived)
}

/// Archived samples whose time lies in one of `windows` (inclusive), each counted once.
pub(crate) fn count_archived_in(
    conn: &Connection,
    windows: &[(i64, i64)],
) -> Result<i64, StoreError> {
    if windows.is_empty() {
        return Ok(0);
    }
    let mut st = conn.prepare_cached("SELECT n, t_blob FROM archive_chunks ORDER BY id")?;
    let mut rows = st.query([])?;
    let mut count = 0i64;
    while let Some(r) = rows.next()? {
        let n: i64 = r.get(0)?;
        let blob: Vec<u8> = r.get(1)?;
        let times = codec::decode_times(&blob, usize::try_from(n).unwrap_or(0))?;
        count += times
            .iter()
            .filter(|&&t| windows.iter().any(|&(a, b)| t >= a && t <= b))
            .count() as i64;
    }
    Ok(count)
}

/// `sql`'s single value (a `MAX(…)` over one tag's rows, `?1` the tag) for `tag`, queried once
/// per tag and kept in `cache` for the rest of an ingest transaction.
pub(super) fn tag_max_cached(
    cache: &mut HashMap<TagId, Option<i64>>,
    conn: &Connection,
    sql: &str,
    tag: TagId,
) -> Result<Option<i64>, StoreError> {
    if let Some(v) = cache.get(&tag) {
        return Ok(*v);
    }
    let v: Option<i64> = conn.prepare_cached(sql)?.query_row([tag], |r| r.get(0))?;
    cache.insert(tag, v);
    Ok(v)
}

/// During one ingest transaction: which (tag, time) pairs are already archived. Looks only at
/// chunks that can hold the time (none for live data newer than the archive).
#[derive(Default)]
pub(crate) struct ArchivedTimes {
    archive_end: HashMap<TagId, Option<i64>>,
    chunk_times: HashMap<i64, Vec<i64>>,
}

impl ArchivedTimes {
    pub(crate) fn contains(
        &mut self,
        conn: &Connection,
        tag: TagId,
        t: i64,
    ) -> Result<bool, StoreError> {
        let end = tag_max_cached(
            &mut self.archive_end,
            conn,
            "SELECT MAX(t_end_ms) FROM archive_chunks WHERE tag_id = ?1",
            tag,
        )?;
        if end.is_none_or(|e| t > e) {
            return Ok(false);
        }
        let mut st = conn.prepare_cached(
            "SELECT id, n, t_blob FROM archive_chunks
             WHERE tag_id = ?1 AND t_start_ms <= ?2 AND t_end_ms >= ?2",
        )?;
        let mut rows = st.query(params![tag, t])?;
        while let Some(r) = rows.next()? {
            let id: i64 = r.get(0)?;
            let times = match self.chunk_times.entry(id) {
                std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
                std::collections::hash_map::Entry::Vacant(e) => {
                    let n: i64 = r.get(1)?;
                    let blob: Vec<u8> = r.get(2)?;
                    e.insert(codec::decode_times(&blob, usize::try_from(n).unwrap_or(0))?)
                }
            };
            if times.binary_search(&t).is_ok() {
                return Ok(true);
            }
        }
        Ok(false)
    }
}

/// Archives one chunk of `tag`'s hot samples before `cutoff`, in one transaction. `None` when
/// the tag has no whole window left before the cutoff.
fn compact_one(
    conn: &mut Connection,
    tag: TagId,
    cutoff: i64,
    max_chunk_samples: usize,
) -> Result<Option<(u64, u64)>, StoreError> {
    let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
    let first: Option<i64> = tx
        .prepare_cached("SELECT MIN(t_ms) FROM samples WHERE tag_id = ?1 AND t_ms < ?2")?
        .query_row(params![tag, cutoff], |r| r.get(0))?;
    let Some(first) = first else {
        return Ok(None);
    };
    let window_end = first
        .div_euclid(CHUNK_SPAN_MS)
        .saturating_mul(CHUNK_SPAN_MS)
        .saturating_add(CHUNK_SPAN_MS);
    if window_end > cutoff {
        return Ok(None);
    }
    let mut c = Columns::default();
    {
        let mut st = tx.prepare_cached(
            "SELECT t_ms, value, quality FROM samples WHERE tag_id = ?1 AND t_ms >= ?2
               AND t_ms < ?3 ORDER BY t_ms LIMIT ?4",
        )?;
        let mut rows = st.query(params![
            tag,
            first,
            window_end,
            max_chunk_samples.max(1) as i64
        ])?;
        while let Some(r) = rows.next()? {
            c.t_ms.push(r.get(0)?);
            c.values.push(r.get(1)?);
            let q: i64 = r.get(2)?;
            c.quality.push(
                u8::try_from(q).map_err(|_| StoreError::Corrupt(format!("quality code {q}")))?,
            );
        }
    }
    let (Some(&t0), Some(&t1)) = (c.t_ms.first(), c.t_ms.last()) else {
        return Ok(None);
    };
    let e = codec::encode(&c)?;
    let bytes = (e.t.len() + e.v.len() + e.q.len()) as u64;
    tx.prepare_cached(
        "INSERT INTO archive_chunks (tag_id, t_start_ms, t_end_ms, n, codec, t_blob, v_blob, q_blob)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
    )?
    .execute(params![tag, t0, t1, c.len() as i64, CODEC_PCO_V1, e.t, e.v, e.q])?;
    let deleted = tx
        .prepare_cached("DELETE FROM samples WHERE tag_id = ?1 AND t_ms >= ?2 AND t_ms <= ?3")?
        .execute(params![tag, t0, t1])?;
    if deleted != c.len() {
        // Dropping the transaction rolls it back: nothing moved.
        return Err(StoreError::Corrupt(format!(
            "compaction of tag {tag} at {t0}: read {} rows, deleted {deleted}",
            c.len()
        )));
    }
    tx.commit()?;
    Ok(Some((c.len() as u64, bytes)))
}

impl Store {
    /// The effective compaction cutoff for `before_ms`: no later than the start of an open
    /// segment or the detector's pending rescan.
    pub fn compaction_cutoff(&self, before_ms: i64) -> Result<i64, StoreError> {
        let open: Option<i64> = self.conn.query_row(
            "SELECT MIN(start_ms) FROM segments WHERE status = 'open' OR end_ms IS NULL",
            [],
            |r| r.get(0),
        )?;
        let rescan: Option<i64> = self
            .conn
            .query_row(
                "SELECT rescan_from_ms FROM detector_state WHERE id = 1",
                [],
                |r| r.get(0),
            )
            .optional()?
            .flatten();
        Ok([Some(before_ms), open, rescan]
            .into_iter()
            .flatten()
            .min()
            .unwrap_or(before_ms))
    }

    /// Moves every whole window of hot samples older than `before_ms` (see
    /// [`Store::compaction_cutoff`]) into the archive, one tag-chunk per transaction.
    pub fn compact(
        &mut self,
        before_ms: i64,
        max_chunk_samples: usize,
    ) -> Result<CompactStats, StoreError> {
        self.compact_some(before_ms, max_chunk_samples, u64::MAX)
    }

    /// [`Store::compact`], stopping after `max_chunks` chunks (the daemon's writer does a few
    /// at a time between batches of samples).
    pub fn compact_some(
        &mut self,
        before_ms: i64,
        max_chunk_samples: usize,
        max_chunks: u64,
    ) -> Result<CompactStats, StoreError> {
        let cutoff = self.compaction_cutoff(before_ms)?;
        let mut stats = CompactStats {
            cutoff_ms: cutoff,
            ..CompactStats::default()
        };
        let tags: Vec<TagId> = self.tags()?.into_iter().map(|t| t.id).collect();
        for tag in tags {
            while stats.chunks < max_chunks {
                match compact_one(&mut self.conn, tag, cutoff, max_chunk_samples)? {
                    Some((n, bytes)) => {
                        stats.chunks += 1;
                        stats.samples += n;
                        stats.blob_bytes += bytes;
                    }
                    None => break,
                }
            }
        }
        Ok(stats)
    }

    /// The archive's size.
    pub fn archive_stats(&self) -> Result<ArchiveStats, StoreError> {
        Ok(self.conn.query_row(
            "SELECT COUNT(*), COALESCE(SUM(n), 0),
                    COALESCE(SUM(length(t_blob) + length(v_blob) + length(q_blob)), 0)
             FROM archive_chunks",
            [],
            |r| {
                Ok(ArchiveStats {
                    chunks: r.get::<_, i64>(0)?.max(0) as u64,
                    samples: r.get::<_, i64>(1)?.max(0) as u64,
                    blob_bytes: r.get::<_, i64>(2)?.max(0) as u64,
                })
            },
        )?)
    }

    /// Returns freed pages to the file system if the file uses `auto_vacuum = INCREMENTAL`
    /// (`PRAGMA incremental_vacuum`); otherwise the pages stay free inside the file and new
    /// hot rows reuse them. Returns whether the file was shrunk this way.
    pub fn incremental_vacuum(&mut self) -> Result<bool, StoreError> {
        let mode: i64 = self
            .conn
            .query_row("PRAGMA auto_vacuum", [], |r| r.get(0))?;
        if mode != 2 {
            return Ok(false);
        }
        let mut st = self.conn.prepare("PRAGMA incremental_vacuum")?;
        let mut rows = st.query([])?;
        while rows.next()?.is_some() {}
        Ok(true)
    }

    /// `VACUUM`: rewrites the whole file without its free pages (needs as much free disk as
    /// the file, and the write lock throughout: for `gtwatch store compact --vacuum`, not the
    /// daemon).
    pub fn vacuum(&mut self) -> Result<(), StoreError> {
        // A file made before auto_vacuum = INCREMENTAL switches to it here: the mode of an
        // existing file changes only with a VACUUM (README "Storage tiers").
        // In WAL mode VACUUM writes the new pages to the WAL: checkpoint so the file shrinks now.
        self.conn
            .execute_batch("PRAGMA auto_vacuum = INCREMENTAL; VACUUM;")?;
        self.conn
            .query_row("PRAGMA wal_checkpoint(TRUNCATE)", [], |_| Ok(()))?;
        Ok(())
    }

    /// Bytes of the file in use (pages minus free pages) and the file's pages in total.
    pub fn used_bytes(&self) -> Result<(u64, u64), StoreError> {
        let page: i64 = self.conn.query_row("PRAGMA page_size", [], |r| r.get(0))?;
        let count: i64 = self.conn.query_row("PRAGMA page_count", [], |r| r.get(0))?;
        let free: i64 = self
            .conn
            .query_row("PRAGMA freelist_count", [], |r| r.get(0))?;
        Ok((
            ((count - free) * page).max(0) as u64,
            (count * page).max(0) as u64,
        ))
    }
}

#[cfg(test)]
mod tests;
