//! Read queries of the start-up list and of raw samples, for `segments`, `export`, the report
//! and the demo (`crate::query` formats them). The store owns the SQL; nothing here writes.

use super::diagnoses::{segment_row, SEGMENT_COLS};
use super::{archive, SegmentInfo, Store, StoreError};

/// One start-up as stored: the segment (the worker's [`SegmentInfo`]) and whether it was a
/// hot restart.
#[derive(Debug, Clone, PartialEq)]
pub struct StartupRow {
    pub info: SegmentInfo,
    pub hot_restart: bool,
}

/// One phase of a segment, as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct PhaseRow {
    pub phase: String,
    pub start_ms: i64,
    pub end_ms: Option<i64>,
}

/// One stored sample of a tag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleRow {
    pub t_ms: i64,
    pub value: f64,
    pub quality: i64,
}

impl Store {
    /// Start-ups beginning at or after `since_ms` (all if `None`), oldest first.
    pub fn startup_rows(&self, since_ms: Option<i64>) -> Result<Vec<StartupRow>, StoreError> {
        // Same columns as the worker's queries (SEGMENT_COLS), then hot_restart.
        let mut st = self.conn.prepare_cached(&format!(
            "SELECT {SEGMENT_COLS}, hot_restart FROM segments
             WHERE kind = 'startup' AND start_ms >= ?1 ORDER BY start_ms"
        ))?;
        let rows = st.query_map([since_ms.unwrap_or(i64::MIN)], |r| {
            Ok(StartupRow {
                info: segment_row(r)?,
                hot_restart: r.get(7)?,
            })
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// The phases of one segment in time order.
    pub fn phase_rows(&self, segment_id: i64) -> Result<Vec<PhaseRow>, StoreError> {
        let mut st = self.conn.prepare_cached(
            "SELECT phase, start_ms, end_ms FROM segment_phases WHERE segment_id = ?1
             ORDER BY start_ms, phase_code",
        )?;
        let rows = st.query_map([segment_id], |r| {
            Ok(PhaseRow {
                phase: r.get(0)?,
                start_ms: r.get(1)?,
                end_ms: r.get(2)?,
            })
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// The latest stored sample time (any quality) over `tags`, if any.
    pub fn last_sample_ms(&self, tags: &[i64]) -> Result<Option<i64>, StoreError> {
        let mut last: Option<i64> = None;
        for &t in tags {
            last = last.max(archive::time_range(&self.conn, t)?.1);
        }
        Ok(last)
    }

    /// Every stored sample of `tag_id` with `from_ms ≤ t ≤ to_ms`, in time order (any quality),
    /// from both tiers.
    pub fn tag_samples_between(
        &self,
        tag_id: i64,
        from_ms: i64,
        to_ms: i64,
    ) -> Result<Vec<SampleRow>, StoreError> {
        archive::read_samples(&self.conn, tag_id, from_ms, to_ms, false)
    }
}
