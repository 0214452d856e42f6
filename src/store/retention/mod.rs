//! Retention: steady operation older than `[storage] raw_days` becomes 1-minute roll-ups
//! (`rollups_1m`, view `samples_1m`), while start-up segments ± `segment_margin_s` keep every
//! raw sample forever (issue 24 item 2, README "Storage tiers").
//!
//! Guarantees:
//! - **One transaction per batch.** A batch is one tag's samples in one *eligible span* (whole
//!   minutes older than the cutoff and outside every protected interval) ∩ one aligned archive
//!   window ([`CHUNK_SPAN_MS`]). Its roll-ups are inserted and its raw samples deleted (hot
//!   rows; archive chunks rewritten without them) in ONE `IMMEDIATE` transaction, checked to
//!   remove exactly the samples it summarised: `kill -9` at any instant leaves a minute either
//!   raw or rolled up, never both or neither.
//! - **Exact roll-ups.** Computed from what the store's one read path
//!   ([`archive::read_samples`]) returns, over whole minutes: only good samples (quality 0)
//!   count in `min`/`mean`/`max`/`last`/`n_good`; `n_all` counts every sample.
//! - **Idempotent.** A second run finds nothing to do. Ingest skips a sample whose minute is
//!   already rolled up (like a duplicate), so a replayed old log does not count twice.
//! - **Archive chunks are rewritten, not dropped:** a chunk overlapping an eligible span is
//!   replaced by the chunks of its samples before and after that span (lossless), so a 6 h
//!   window holding a start-up keeps the start-up's samples bit for bit.
//! - **The cutoff** is `now − raw_days`, pulled back to the compaction cutoff (open segment,
//!   pending rescan) and to where the detector would resume: data the detector has not
//!   scanned is never rolled up (a start-up in it is not known yet), nor the hour before where
//!   the detector resumes. No detector progress at
//!   all (`scanned_to_ms` NULL) means no retention.
//!
//! - **The second tier** ([`hourly`]): minute roll-ups older than `rollup_1m_days` are merged
//!   into hourly roll-ups (`rollups_1h`, view `samples_1h`) after the minute tier's batches,
//!   with the same one-transaction-per-batch guarantee.
//!
//! Must not: decide the policy (the caller gives [`RetentionPolicy`]), hold the write lock for
//! more than one batch, or read samples except through the archive's read path.

mod hourly;
pub use hourly::{combine, RollupTier, HOUR_MS};

use super::archive::{self, codec, CHUNK_SPAN_MS};
use super::{Store, StoreError, TagId};
use rusqlite::{params, Connection, OptionalExtension, TransactionBehavior};
use std::collections::{BTreeSet, HashMap};

/// One minute, the roll-up period.
pub const MINUTE_MS: i64 = 60_000;

/// Raw data kept before the detector's resume point (the context it re-reads on resuming).
const DETECTOR_CONTEXT_MS: i64 = 3_600_000;

/// Free pages returned to the file system per `incremental_vacuum` step (16 MiB of 4 KiB
/// pages): one short write transaction each.
pub const VACUUM_STEP_PAGES: u32 = 4096;

/// What to keep raw: from `[storage]` (`raw_days`, `segment_margin_s`, `rollup_1m_days`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct RetentionPolicy {
    /// Steady operation stays raw this many days; 0 = raw forever (retention off).
    pub raw_days: u32,
    /// Samples within this many seconds of a start-up segment stay raw forever.
    pub segment_margin_s: u32,
    /// 1-minute roll-ups older than this many days are merged into hourly roll-ups; 0 =
    /// minute roll-ups are kept forever.
    pub rollup_1m_days: u32,
}

/// What one retention run (or part of one) did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct RetainStats {
    /// Batches done (one transaction each).
    pub batches: u64,
    /// Raw samples summarised and deleted.
    pub samples_rolled_up: u64,
    /// Of those, from the hot tier.
    pub hot_deleted: u64,
    /// Of those, from archive chunks.
    pub archived_deleted: u64,
    /// Roll-up rows written (minutes × tags).
    pub minutes: u64,
    /// Archive chunks rewritten without the rolled-up samples.
    pub chunks_rewritten: u64,
    /// The effective cutoff (None: retention off or the detector has not scanned yet).
    pub cutoff_ms: Option<i64>,
    /// Hourly merges done (one transaction each: one tag's minute rows of one day at most).
    pub hourly_batches: u64,
    /// Minute roll-up rows merged into hourly rows (and deleted).
    pub minutes_merged: u64,
    /// Hourly rows written (or merged into).
    pub hours: u64,
    /// Minute rows older than this are merged (None: `rollup_1m_days` 0).
    pub hourly_cutoff_ms: Option<i64>,
}

impl RetainStats {
    /// Transactions done, both tiers (0: nothing left to do).
    pub fn transactions(&self) -> u64 {
        self.batches + self.hourly_batches
    }
}

/// What the next retention run would do (for `gtwatch store stats`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct RetentionOutlook {
    pub cutoff_ms: Option<i64>,
    /// Batches (transactions) rolling up raw samples it would take.
    pub batches: u64,
    /// Raw samples it would roll up (hot + archived).
    pub samples: u64,
    /// Minute rows older than this would be merged into hours (None: `rollup_1m_days` 0).
    pub hourly_cutoff_ms: Option<i64>,
    /// Hourly merges (transactions) it would take.
    pub hourly_batches: u64,
    /// Minute roll-up rows it would merge into hourly rows (those existing now; the minutes
    /// the same run rolls up first are not counted).
    pub minutes_to_merge: u64,
}

/// A half-open time range `[from, to)` in Unix ms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct Span {
    pub from: i64,
    pub to: i64,
}

/// One unit of work: `tag`'s samples in `span`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Batch {
    tag: TagId,
    span: Span,
}

/// One period's roll-up of one tag (a minute in `rollups_1m`, an hour in `rollups_1h`): only
/// good samples count in `n_good`, `min`, `mean`, `max`, `last`; `n_all` counts every sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rollup {
    /// Start of the period, Unix ms.
    pub t_ms: i64,
    pub n_good: i64,
    pub n_all: i64,
    pub min: Option<f64>,
    pub mean: Option<f64>,
    pub max: Option<f64>,
    pub last: Option<f64>,
    pub last_ms: Option<i64>,
}

impl Rollup {
    /// The period starting at `t_ms` before anything is added to it.
    pub(crate) fn empty(t_ms: i64) -> Rollup {
        Rollup {
            t_ms,
            n_good: 0,
            n_all: 0,
            min: None,
            mean: None,
            max: None,
            last: None,
            last_ms: None,
        }
    }
}

/// The start of the `period`-ms period holding `t` (periods aligned to the Unix epoch).
pub fn floor_to(t: i64, period: i64) -> i64 {
    t.saturating_sub(t.rem_euclid(period))
}

fn floor_minute(t: i64) -> i64 {
    floor_to(t, MINUTE_MS)
}

fn ceil_minute(t: i64) -> i64 {
    floor_minute(t.saturating_add(MINUTE_MS - 1))
}

/// The aligned archive window holding `t`.
fn window_of(t: i64) -> Span {
    let from = t.saturating_sub(t.rem_euclid(CHUNK_SPAN_MS));
    Span {
        from,
        to: from.saturating_add(CHUNK_SPAN_MS),
    }
}

/// The effective cutoff (whole minutes), or None when nothing may be rolled up.
fn cutoff(store: &Store, now_ms: i64, policy: &RetentionPolicy) -> Result<Option<i64>, StoreError> {
    if policy.raw_days == 0 {
        return Ok(None);
    }
    let raw = now_ms.saturating_sub(i64::from(policy.raw_days).saturating_mul(86_400_000));
    let state = store.detector_state()?;
    if state.scanned_to_ms.is_none() {
        return Ok(None);
    }
    // The detector re-reads some context before where it resumes: keep that raw too.
    let resume = store
        .detector_resume_point(&state)?
        .map(|r| r.saturating_sub(DETECTOR_CONTEXT_MS));
    let c = [
        Some(store.compaction_cutoff(raw)?),
        resume,
        state.scanned_to_ms,
    ]
    .into_iter()
    .flatten()
    .min()
    .unwrap_or(raw);
    Ok(Some(floor_minute(c)))
}

/// Whole-minute spans before `cutoff` outside every segment ± margin, in time order.
fn eligible_spans(conn: &Connection, cutoff: i64, margin_s: u32) -> Result<Vec<Span>, StoreError> {
    let margin = i64::from(margin_s) * 1000;
    let mut protected: Vec<Span> = Vec::new();
    let mut st = conn.prepare_cached("SELECT start_ms, end_ms FROM segments")?;
    let mut rows = st.query([])?;
    while let Some(r) = rows.next()? {
        let start: i64 = r.get(0)?;
        let end: Option<i64> = r.get(1)?;
        protected.push(Span {
            from: floor_minute(start.saturating_sub(margin)),
            to: end.map_or(i64::MAX, |e| {
                ceil_minute(e.max(start).saturating_add(margin).saturating_add(1))
            }),
        });
    }
    protected.sort();
    let mut out = Vec::new();
    let mut cur = i64::MIN;
    for p in protected {
        if cur >= cutoff {
            break;
        }
        if p.from > cur {
            out.push(Span {
                from: cur,
                to: p.from.min(cutoff),
            });
        }
        cur = cur.max(p.to);
    }
    if cur < cutoff {
        out.push(Span {
            from: cur,
            to: cutoff,
        });
    }
    Ok(out)
}

/// Every batch with something to do: hot rows or archive chunks overlapping an eligible span.
fn plan(conn: &Connection, eligible: &[Span], cutoff: i64) -> Result<Vec<Batch>, StoreError> {
    let mut batches = BTreeSet::new();
    let tags: Vec<TagId> = {
        let mut st = conn.prepare_cached("SELECT id FROM tags ORDER BY id")?;
        let rows = st.query_map([], |r| r.get(0))?;
        rows.collect::<Result<_, _>>()?
    };
    let clip = |e: &Span, w: Span| Span {
        from: e.from.max(w.from),
        to: e.to.min(w.to),
    };
    for tag in tags {
        let mut first = conn.prepare_cached(
            "SELECT MIN(t_ms) FROM samples WHERE tag_id = ?1 AND t_ms >= ?2 AND t_ms < ?3",
        )?;
        for e in eligible {
            let mut cur = e.from;
            while cur < e.to {
                let t: Option<i64> = first.query_row(params![tag, cur, e.to], |r| r.get(0))?;
                let Some(t) = t else { break };
                let span = clip(e, window_of(t));
                batches.insert(Batch { tag, span });
                cur = span.to;
            }
        }
        let mut st = conn.prepare_cached(
            "SELECT t_start_ms, t_end_ms FROM archive_chunks WHERE tag_id = ?1 AND t_start_ms < ?2
             ORDER BY t_start_ms",
        )?;
        let mut rows = st.query(params![tag, cutoff])?;
        while let Some(r) = rows.next()? {
            let (t0, t1): (i64, i64) = (r.get(0)?, r.get(1)?);
            let w = window_of(t0);
            let mut k = eligible.partition_point(|e| e.to <= t0);
            while let Some(e) = eligible.get(k) {
                if e.from > t1 {
                    break;
                }
                let span = clip(e, w);
                if span.from < span.to {
                    batches.insert(Batch { tag, span });
                }
                k += 1;
            }
        }
    }
    Ok(batches.into_iter().collect())
}

/// The roll-ups of time-ordered samples, one per minute that holds any.
pub fn rollups(rows: &[super::SampleRow]) -> Vec<Rollup> {
    let mut out: Vec<Rollup> = Vec::new();
    let mut sum = 0.0f64;
    for s in rows {
        let minute = floor_minute(s.t_ms);
        if out.last().is_none_or(|r| r.t_ms != minute) {
            finish_mean(out.last_mut(), sum);
            sum = 0.0;
            out.push(Rollup::empty(minute));
        }
        let Some(r) = out.last_mut() else { continue };
        r.n_all += 1;
        if s.quality == 0 {
            r.n_good += 1;
            sum += s.value;
            r.min = Some(r.min.map_or(s.value, |m| m.min(s.value)));
            r.max = Some(r.max.map_or(s.value, |m| m.max(s.value)));
            r.last = Some(s.value);
            r.last_ms = Some(s.t_ms);
        }
    }
    finish_mean(out.last_mut(), sum);
    out
}

/// Sets the mean of a period just closed from the sum of its good values.
fn finish_mean(r: Option<&mut Rollup>, sum: f64) {
    if let Some(r) = r {
        if r.n_good > 0 {
            r.mean = Some(sum / r.n_good as f64);
        }
    }
}

/// Inserts a roll-up row into `tier`'s table; should the period already have one (a minute
/// cannot while ingest skips rolled-up minutes; an hour can, when a minute of it was rolled
/// up after the hour was merged), the two are merged (counts added, mean weighted, later last).
fn insert_rollup(
    conn: &Connection,
    tier: RollupTier,
    tag: TagId,
    r: &Rollup,
) -> Result<(), StoreError> {
    let sql = match tier {
        RollupTier::Minute => INSERT_ROLLUP_1M,
        RollupTier::Hour => INSERT_ROLLUP_1H,
    };
    conn.prepare_cached(sql)?.execute(params![
        tag, r.t_ms, r.n_good, r.n_all, r.min, r.mean, r.max, r.last, r.last_ms
    ])?;
    Ok(())
}

/// The two roll-up tables' inserts: the same statement but for the table name.
macro_rules! insert_rollup_sql {
    ($table:literal) => {
        concat!(
            "INSERT INTO ",
            $table,
            " (tag_id, t_ms, n_good, n_all, min, mean, max, last, last_ms)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)
         ON CONFLICT (tag_id, t_ms) DO UPDATE SET
           n_good = n_good + excluded.n_good,
           n_all = n_all + excluded.n_all,
           min = min(coalesce(min, excluded.min), coalesce(excluded.min, min)),
           max = max(coalesce(max, excluded.max), coalesce(excluded.max, max)),
           mean = CASE WHEN n_good + excluded.n_good = 0 THEN NULL
                  ELSE (coalesce(mean, 0) * n_good + coalesce(excluded.mean, 0) * excluded.n_good)
                       / (n_good + excluded.n_good) END,
           last = CASE WHEN excluded.last_ms > coalesce(last_ms, excluded.last_ms - 1)
                  THEN excluded.last ELSE last END,
           last_ms = CASE WHEN excluded.last_ms > coalesce(last_ms, excluded.last_ms - 1)
                     THEN excluded.last_ms ELSE last_ms END"
        )
    };
}
const INSERT_ROLLUP_1M: &str = insert_rollup_sql!("rollups_1m");
const INSERT_ROLLUP_1H: &str = insert_rollup_sql!("rollups_1h");

/// Samples of one chunk, split around a span.
#[derive(Default)]
struct Split {
    before: codec::Columns,
    after: codec::Columns,
    inside: usize,
}

fn split_chunk(c: &codec::Columns, span: Span) -> Split {
    let mut s = Split::default();
    for i in 0..c.len() {
        let t = c.t_ms[i];
        let part = if t < span.from {
            &mut s.before
        } else if t >= span.to {
            &mut s.after
        } else {
            s.inside += 1;
            continue;
        };
        part.t_ms.push(t);
        part.values.push(c.values[i]);
        part.quality.push(c.quality[i]);
    }
    s
}

fn insert_chunk(conn: &Connection, tag: TagId, c: &codec::Columns) -> Result<(), StoreError> {
    let (Some(&t0), Some(&t1)) = (c.t_ms.first(), c.t_ms.last()) else {
        return Ok(());
    };
    let e = codec::encode(c)?;
    conn.prepare_cached(
        "INSERT INTO archive_chunks (tag_id, t_start_ms, t_end_ms, n, codec, t_blob, v_blob, q_blob)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
    )?
    .execute(params![
        tag,
        t0,
        t1,
        c.len() as i64,
        codec::CODEC_PCO_V1,
        e.t,
        e.v,
        e.q
    ])?;
    Ok(())
}

/// Rewrites every chunk of `tag` overlapping `span` without the samples inside it; returns
/// (chunks rewritten, samples removed).
fn rewrite_chunks(conn: &Connection, tag: TagId, span: Span) -> Result<(u64, u64), StoreError> {
    let mut found: Vec<(i64, codec::Columns)> = Vec::new();
    {
        let mut st = conn.prepare_cached(
            "SELECT n, codec, t_blob, v_blob, q_blob, id FROM archive_chunks
             WHERE tag_id = ?1 AND t_end_ms >= ?2 AND t_start_ms < ?3",
        )?;
        let mut rows = st.query(params![tag, span.from, span.to])?;
        while let Some(r) = rows.next()? {
            found.push((r.get(5)?, archive::decode_row(r)?));
        }
    }
    let mut removed = 0u64;
    for (id, c) in &found {
        let s = split_chunk(c, span);
        conn.prepare_cached("DELETE FROM archive_chunks WHERE id = ?1")?
            .execute([id])?;
        insert_chunk(conn, tag, &s.before)?;
        insert_chunk(conn, tag, &s.after)?;
        removed += s.inside as u64;
    }
    Ok((found.len() as u64, removed))
}

/// One batch in one IMMEDIATE transaction.
fn run_batch(conn: &mut Connection, b: Batch, stats: &mut RetainStats) -> Result<(), StoreError> {
    let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
    let rows = archive::read_samples(&tx, b.tag, b.span.from, b.span.to - 1, false)?;
    let ups = rollups(&rows);
    for r in &ups {
        insert_rollup(&tx, RollupTier::Minute, b.tag, r)?;
    }
    let hot = tx
        .prepare_cached("DELETE FROM samples WHERE tag_id = ?1 AND t_ms >= ?2 AND t_ms < ?3")?
        .execute(params![b.tag, b.span.from, b.span.to])? as u64;
    let (chunks, archived) = rewrite_chunks(&tx, b.tag, b.span)?;
    if hot + archived != rows.len() as u64 {
        // Dropping the transaction rolls it back: nothing changed.
        return Err(StoreError::Corrupt(format!(
            "retention of tag {} at {}: read {} samples, deleted {hot} hot and {archived} archived",
            b.tag,
            b.span.from,
            rows.len()
        )));
    }
    tx.commit()?;
    stats.batches += 1;
    stats.samples_rolled_up += rows.len() as u64;
    stats.hot_deleted += hot;
    stats.archived_deleted += archived;
    stats.minutes += ups.len() as u64;
    stats.chunks_rewritten += chunks;
    Ok(())
}

/// Samples of `tag` in `span`, both tiers, counted without decoding values.
fn count_in(conn: &Connection, b: &Batch) -> Result<u64, StoreError> {
    let hot: i64 = conn
        .prepare_cached(
            "SELECT COUNT(*) FROM samples WHERE tag_id = ?1 AND t_ms >= ?2 AND t_ms < ?3",
        )?
        .query_row(params![b.tag, b.span.from, b.span.to], |r| r.get(0))?;
    let mut n = hot.max(0) as u64;
    let mut st = conn.prepare_cached(
        "SELECT n, t_blob FROM archive_chunks WHERE tag_id = ?1 AND t_end_ms >= ?2
           AND t_start_ms < ?3",
    )?;
    let mut rows = st.query(params![b.tag, b.span.from, b.span.to])?;
    while let Some(r) = rows.next()? {
        let len: i64 = r.get(0)?;
        let blob: Vec<u8> = r.get(1)?;
        let times = codec::decode_times(&blob, usize::try_from(len).unwrap_or(0))?;
        n += times
            .iter()
            .filter(|&&t| t >= b.span.from && t < b.span.to)
            .count() as u64;
    }
    Ok(n)
}

impl Store {
    /// Rolls up every eligible sample (see the module comment): [`Store::apply_retention_some`]
    /// without a limit.
    pub fn apply_retention(
        &mut self,
        now_ms: i64,
        policy: &RetentionPolicy,
    ) -> Result<RetainStats, StoreError> {
        self.apply_retention_some(now_ms, policy, u64::MAX)
    }

    /// Rolls up at most `max_batches` batches (one transaction each), then, with the batches
    /// left, merges old minute roll-ups into hours ([`hourly`]);
    /// [`RetainStats::transactions`] `== 0` in the answer: nothing left to do.
    pub fn apply_retention_some(
        &mut self,
        now_ms: i64,
        policy: &RetentionPolicy,
        max_batches: u64,
    ) -> Result<RetainStats, StoreError> {
        let cut = cutoff(self, now_ms, policy)?;
        let hourly_cut = hourly::cutoff(now_ms, policy, cut);
        let mut stats = RetainStats {
            cutoff_ms: cut,
            hourly_cutoff_ms: hourly_cut,
            ..RetainStats::default()
        };
        if let Some(cut) = cut {
            let eligible = eligible_spans(&self.conn, cut, policy.segment_margin_s)?;
            let work = plan(&self.conn, &eligible, cut)?;
            for b in work
                .into_iter()
                .take(usize::try_from(max_batches).unwrap_or(usize::MAX))
            {
                run_batch(&mut self.conn, b, &mut stats)?;
            }
        }
        let left = max_batches.saturating_sub(stats.batches);
        if let (Some(hcut), true) = (hourly_cut, left > 0) {
            for b in hourly::plan(&self.conn, hcut)?
                .into_iter()
                .take(usize::try_from(left).unwrap_or(usize::MAX))
            {
                hourly::run_batch(&mut self.conn, b, &mut stats)?;
            }
        }
        Ok(stats)
    }

    /// What [`Store::apply_retention`] would do now (reads only).
    pub fn retention_outlook(
        &self,
        now_ms: i64,
        policy: &RetentionPolicy,
    ) -> Result<RetentionOutlook, StoreError> {
        let cut = cutoff(self, now_ms, policy)?;
        let hourly_cut = hourly::cutoff(now_ms, policy, cut);
        let mut out = RetentionOutlook {
            cutoff_ms: cut,
            hourly_cutoff_ms: hourly_cut,
            ..RetentionOutlook::default()
        };
        if let Some(cut) = cut {
            let eligible = eligible_spans(&self.conn, cut, policy.segment_margin_s)?;
            let work = plan(&self.conn, &eligible, cut)?;
            for b in &work {
                out.samples += count_in(&self.conn, b)?;
            }
            out.batches = work.len() as u64;
        }
        if let Some(hcut) = hourly_cut {
            let work = hourly::plan(&self.conn, hcut)?;
            for b in &work {
                out.minutes_to_merge += hourly::count_minutes(&self.conn, b)?;
            }
            out.hourly_batches = work.len() as u64;
        }
        Ok(out)
    }

    /// Frees at most `max_pages` free pages back to the file system (`PRAGMA
    /// incremental_vacuum(N)`, one short transaction) if the file uses `auto_vacuum =
    /// INCREMENTAL`; returns how many pages the file shrank by (0: nothing left or not
    /// incremental).
    pub fn incremental_vacuum_step(&mut self, max_pages: u32) -> Result<u64, StoreError> {
        let mode: i64 = self
            .conn
            .query_row("PRAGMA auto_vacuum", [], |r| r.get(0))?;
        if mode != 2 {
            return Ok(0);
        }
        let before: i64 = self.conn.query_row("PRAGMA page_count", [], |r| r.get(0))?;
        {
            let mut st = self
                .conn
                .prepare(&format!("PRAGMA incremental_vacuum({})", max_pages.max(1)))?;
            let mut rows = st.query([])?;
            while rows.next()?.is_some() {}
        }
        let after: i64 = self.conn.query_row("PRAGMA page_count", [], |r| r.get(0))?;
        Ok((before - after).max(0) as u64)
    }
}

/// During one ingest transaction: which (tag, minute) are already rolled up, into a minute
/// row or into an hour's row. Looks at the tables only for times not after a tag's newest
/// roll-up (never for live data).
#[derive(Default)]
pub(crate) struct RolledUpMinutes {
    newest: HashMap<TagId, Option<i64>>,
    newest_hour: HashMap<TagId, Option<i64>>,
}

impl RolledUpMinutes {
    pub(crate) fn contains(
        &mut self,
        conn: &Connection,
        tag: TagId,
        t: i64,
    ) -> Result<bool, StoreError> {
        let newest = archive::tag_max_cached(
            &mut self.newest,
            conn,
            "SELECT MAX(t_ms) FROM rollups_1m WHERE tag_id = ?1",
            tag,
        )?;
        let minute = floor_minute(t);
        if newest.is_some_and(|n| minute <= n) {
            let found: Option<i64> = conn
                .prepare_cached("SELECT 1 FROM rollups_1m WHERE tag_id = ?1 AND t_ms = ?2")?
                .query_row(params![tag, minute], |r| r.get(0))
                .optional()?;
            if found.is_some() {
                return Ok(true);
            }
        }
        // An hour merged from minute rows no longer says which minutes it summarised: a sample
        // in it is taken as summarised (a replayed old log adds nothing twice).
        let newest_hour = archive::tag_max_cached(
            &mut self.newest_hour,
            conn,
            "SELECT MAX(t_ms) FROM rollups_1h WHERE tag_id = ?1",
            tag,
        )?;
        let hour = t.saturating_sub(t.rem_euclid(HOUR_MS));
        if newest_hour.is_none_or(|n| hour > n) {
            return Ok(false);
        }
        let found: Option<i64> = conn
            .prepare_cached("SELECT 1 FROM rollups_1h WHERE tag_id = ?1 AND t_ms = ?2")?
            .query_row(params![tag, hour], |r| r.get(0))
            .optional()?;
        Ok(found.is_some())
    }
}

#[cfg(test)]
mod tests;
