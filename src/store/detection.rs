//! The detector's SQL: its persistent progress (`detector_state`), where a scan resumes, the
//! good samples it reads, and writing the segments it found in one transaction.
//!
//! The rules (what a start-up is, where to resume) live in `crate::detect`; this module only
//! stores and fetches. Must not hold detection logic.

use super::{now_ms, StoreError, TagId};
use crate::segment::SegmentRecord;
use rusqlite::{params, OptionalExtension};

/// What one detector scan writes ([`super::Store::store_scan`]): the segments it found, the
/// time from which stored segments not found again are stale, and its new progress.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanWrite {
    pub records: Vec<SegmentRecord>,
    pub keep_from: i64,
    pub scanned_to: i64,
    pub last_fuel_off_ms: Option<i64>,
}

/// Persistent detector progress (table `detector_state`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ResumeState {
    pub scanned_to_ms: Option<i64>,
    pub rescan_from_ms: Option<i64>,
    pub last_fuel_off_ms: Option<i64>,
}

fn read_state(conn: &rusqlite::Connection) -> Result<ResumeState, StoreError> {
    Ok(conn.query_row(
        "SELECT scanned_to_ms, rescan_from_ms, last_fuel_off_ms FROM detector_state WHERE id = 1",
        [],
        |r| {
            Ok(ResumeState {
                scanned_to_ms: r.get(0)?,
                rescan_from_ms: r.get(1)?,
                last_fuel_off_ms: r.get(2)?,
            })
        },
    )?)
}

/// Where the machine must restart so that no start is seen only in part.
fn resume_point(conn: &rusqlite::Connection, st: &ResumeState) -> Result<Option<i64>, StoreError> {
    let Some(scanned) = st.scanned_to_ms else {
        return Ok(None); // never scanned: from the beginning
    };
    let mut from = scanned;
    if let Some(r) = st.rescan_from_ms {
        from = from.min(r);
    }
    let open: Option<i64> = conn.query_row(
        "SELECT MIN(start_ms) FROM segments WHERE kind = 'startup' AND status = 'open'",
        [],
        |r| r.get(0),
    )?;
    if let Some(o) = open {
        from = from.min(o);
    }
    // A (not yet diagnosed) segment spanning the resume point is found again from its start.
    let spanning: Option<i64> = conn.query_row(
        "SELECT MIN(start_ms) FROM segments WHERE kind = 'startup' AND status != 'diagnosed'
           AND start_ms < ?1 AND (end_ms IS NULL OR end_ms >= ?1)",
        params![from],
        |r| r.get(0),
    )?;
    if let Some(s) = spanning {
        from = from.min(s);
    }
    Ok(Some(from))
}

/// Where the machine restarts: `margin_ms` before the resume point, moved back to the start of
/// any stored segment that holds it (a machine started inside a crank would see a phantom
/// start there), with a minute of context before that start for its onset.
fn warm_point(
    conn: &rusqlite::Connection,
    resume_ms: i64,
    margin_ms: i64,
) -> Result<i64, StoreError> {
    let mut warm = resume_ms.saturating_sub(margin_ms);
    for _ in 0..16 {
        let inside: Option<i64> = conn.query_row(
            "SELECT MIN(start_ms) FROM segments WHERE kind = 'startup'
               AND start_ms <= ?1 AND (end_ms IS NULL OR end_ms >= ?1)",
            params![warm],
            |r| r.get(0),
        )?;
        match inside {
            Some(s) => warm = s.saturating_sub(60_000),
            None => break,
        }
    }
    Ok(warm)
}

/// The last fuel-off (first good fuel sample at or below the threshold after one above it)
/// within `window_ms` before `before_ms`, from the stored samples: the same answer however the
/// data arrived and wherever earlier scans stopped.
fn last_fuel_off_before(
    conn: &rusqlite::Connection,
    fuel: TagId,
    before_ms: i64,
    window_ms: i64,
    threshold: f64,
) -> Result<Option<i64>, StoreError> {
    // Both tiers, through the one read of samples: the good fuel samples of the window.
    let good = super::archive::read_samples(
        conn,
        fuel,
        before_ms.saturating_sub(window_ms),
        before_ms.saturating_sub(1),
        true,
    )?;
    let Some(on) = good
        .iter()
        .rev()
        .find(|s| s.value > threshold)
        .map(|s| s.t_ms)
    else {
        return Ok(None);
    };
    Ok(good.iter().map(|s| s.t_ms).find(|&t| t > on))
}

/// Reads one tag's samples in `[from, to)`, time-ordered.
fn read_tag(
    conn: &rusqlite::Connection,
    tag: TagId,
    from: i64,
    to: i64,
) -> Result<Vec<(i64, f64)>, StoreError> {
    if to <= from {
        return Ok(Vec::new());
    }
    // Only good samples: a flagged (bad or out-of-range) value must never steer the detector.
    Ok(super::archive::read_samples(conn, tag, from, to - 1, true)?
        .into_iter()
        .map(|s| (s.t_ms, s.value))
        .collect())
}

/// Inserts or updates a segment keyed by its start time; a diagnosed segment is left alone.
/// Returns its id, or `None` if it was left alone.
fn upsert_segment(
    tx: &rusqlite::Transaction<'_>,
    rec: &SegmentRecord,
) -> Result<Option<i64>, StoreError> {
    let end = rec.end_ms.unwrap_or(i64::MAX);
    let gap_in_span: bool = tx.query_row(
        "SELECT EXISTS(SELECT 1 FROM gaps WHERE start_ms <= ?2 AND end_ms >= ?1)",
        params![rec.start_ms, end],
        |r| r.get(0),
    )?;
    let status = if rec.is_open() { "open" } else { "closed" };
    let existing: Option<(i64, String)> = tx
        .query_row(
            "SELECT id, status FROM segments WHERE kind = 'startup' AND start_ms = ?1",
            params![rec.start_ms],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .optional()?;
    let id = match existing {
        Some((_, s)) if s == "diagnosed" => return Ok(None),
        Some((id, _)) => {
            tx.execute(
                "UPDATE segments SET end_ms = ?2, outcome = ?3, abort_cause = ?4, status = ?5,
                        hot_restart = ?6, has_gap = ?7, updated_at_ms = ?8 WHERE id = ?1",
                params![
                    id,
                    rec.end_ms,
                    rec.outcome.as_str(),
                    rec.abort_cause.map(|c| c.as_str()),
                    status,
                    rec.hot_restart,
                    rec.has_gap || gap_in_span,
                    now_ms()
                ],
            )?;
            tx.execute(
                "DELETE FROM segment_phases WHERE segment_id = ?1",
                params![id],
            )?;
            id
        }
        None => {
            tx.execute(
                "INSERT INTO segments (kind, start_ms, end_ms, outcome, abort_cause, status,
                                       hot_restart, has_gap, updated_at_ms)
                 VALUES ('startup', ?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
                params![
                    rec.start_ms,
                    rec.end_ms,
                    rec.outcome.as_str(),
                    rec.abort_cause.map(|c| c.as_str()),
                    status,
                    rec.hot_restart,
                    rec.has_gap || gap_in_span,
                    now_ms()
                ],
            )?;
            tx.last_insert_rowid()
        }
    };
    let mut ins = tx.prepare_cached(
        "INSERT OR REPLACE INTO segment_phases (segment_id, phase, phase_code, start_ms, end_ms)
         VALUES (?1, ?2, ?3, ?4, ?5)",
    )?;
    for p in &rec.phases {
        ins.execute(params![
            id,
            p.phase.name(),
            p.phase.code(),
            p.start_ms,
            p.end_ms
        ])?;
    }
    Ok(Some(id))
}

impl super::Store {
    /// The detector's persistent progress.
    pub fn detector_state(&self) -> Result<ResumeState, StoreError> {
        read_state(&self.conn)
    }

    /// Where a scan must resume so that no start is seen only in part (`None`: never scanned).
    pub fn detector_resume_point(&self, st: &ResumeState) -> Result<Option<i64>, StoreError> {
        resume_point(&self.conn, st)
    }

    /// The latest end (or start, if still open) of the start-up segments stored with a start
    /// before `before_ms`: a segment the detector finds before its resume point is new only
    /// if it starts after this.
    pub fn last_segment_end_before(&self, before_ms: i64) -> Result<Option<i64>, StoreError> {
        Ok(self.conn.query_row(
            "SELECT MAX(COALESCE(end_ms, start_ms)) FROM segments
               WHERE kind = 'startup' AND start_ms < ?1",
            params![before_ms],
            |r| r.get(0),
        )?)
    }

    /// `margin_ms` before `resume_ms`, moved out of any stored segment (see `warm_point`).
    pub fn detector_warm_point(&self, resume_ms: i64, margin_ms: i64) -> Result<i64, StoreError> {
        warm_point(&self.conn, resume_ms, margin_ms)
    }

    /// The last fuel-off within `window_ms` before `before_ms`, from the stored samples.
    pub fn last_fuel_off_before(
        &self,
        fuel: TagId,
        before_ms: i64,
        window_ms: i64,
        threshold: f64,
    ) -> Result<Option<i64>, StoreError> {
        last_fuel_off_before(&self.conn, fuel, before_ms, window_ms, threshold)
    }

    /// Good samples of a tag in `[from, to)`, time-ordered.
    pub fn good_samples(
        &self,
        tag: TagId,
        from: i64,
        to: i64,
    ) -> Result<Vec<(i64, f64)>, StoreError> {
        read_tag(&self.conn, tag, from, to)
    }

    /// Time of the first good sample of a tag at or after `from` (the detector jumps over empty
    /// stretches with it instead of walking fixed chunks up to a far-away stamp).
    pub fn next_good_sample_ms(&self, tag: TagId, from: i64) -> Result<Option<i64>, StoreError> {
        super::archive::first_sample_from(&self.conn, tag, from, true)
    }

    /// First and last sample time of a tag (any quality).
    pub fn tag_time_range(&self, tag: TagId) -> Result<(Option<i64>, Option<i64>), StoreError> {
        super::archive::time_range(&self.conn, tag)
    }

    /// Writes one scan's result in one transaction: the segments found (inserted or updated by
    /// start time; diagnosed ones left alone), deletes not-yet-diagnosed segments from
    /// `keep_from` on that were not found again, and advances the detector's progress.
    /// Returns how many segments were written.
    pub fn store_scan(&mut self, scan: &ScanWrite) -> Result<u64, StoreError> {
        let ScanWrite {
            records,
            keep_from,
            scanned_to,
            last_fuel_off_ms,
        } = scan;
        // IMMEDIATE: the write lock up front, waiting up to the busy timeout. A deferred
        // transaction that reads first fails at once (SQLITE_BUSY) when another connection
        // wrote meanwhile (a command writing beside the daemon's writer).
        let tx = self
            .conn
            .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        let mut kept: Vec<i64> = Vec::new();
        for rec in records {
            if let Some(id) = upsert_segment(&tx, rec)? {
                kept.push(id);
            }
        }
        {
            let mut stale = tx.prepare(
                "SELECT id FROM segments WHERE kind = 'startup' AND start_ms >= ?1 AND status != 'diagnosed'
                   AND id NOT IN (SELECT segment_id FROM diagnoses)
                   AND id NOT IN (SELECT segment_id FROM undiagnosable)",
            )?;
            let ids: Vec<i64> = stale
                .query_map(params![keep_from], |r| r.get(0))?
                .collect::<Result<_, _>>()?;
            for id in ids.into_iter().filter(|id| !kept.contains(id)) {
                tx.execute("DELETE FROM segments WHERE id = ?1", params![id])?;
            }
        }
        tx.execute(
            "UPDATE detector_state SET scanned_to_ms = MAX(COALESCE(scanned_to_ms, ?1), ?1),
                    rescan_from_ms = NULL, last_fuel_off_ms = ?2, updated_at_ms = ?3 WHERE id = 1",
            params![scanned_to, last_fuel_off_ms, now_ms()],
        )?;
        tx.commit()?;
        Ok(kept.len() as u64)
    }
}
