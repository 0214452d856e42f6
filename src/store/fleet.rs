//! The edge side of the fleet sync (`crate::fleet`): the rows to send, read in bounded batches
//! after a high-water mark, and the marks themselves (`fleet_sync`, migration 0005).
//!
//! Rows leave as columns ([`FleetRows`]: one vector per column, typed as SQLite stores them),
//! so the centre inserts a whole batch in one statement. The column lists ([`FleetTable`]) are
//! the edge's; the centre's tables use the same names. SQL only: what to send when, and the
//! centre, are `crate::fleet`'s.

use super::{now_ms, Store, StoreError};
use rusqlite::{params, types::ValueRef};

/// How a column is typed (SQLite's storage class, and the centre's type).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColKind {
    Int,
    Real,
    Text,
}

/// One column of a batch, one entry per row (`None`: NULL).
#[derive(Debug, Clone, PartialEq)]
pub enum FleetColumn {
    Int(Vec<Option<i64>>),
    Real(Vec<Option<f64>>),
    Text(Vec<Option<String>>),
}

/// How a table is walked: after the last id sent, or after the last (updated_at_ms, id) sent
/// (rows that change: a segment closed or diagnosed is sent again), or whole every time
/// (washes: few rows, confirmed or rejected in place).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FleetCursor {
    Id,
    UpdatedAt,
    Whole,
}

/// A table the fleet sync sends: its name (the same at the centre), its key column (the
/// centre's `edge_id`), the columns after it, and how it is walked.
#[derive(Debug, Clone, Copy)]
pub struct FleetTable {
    pub name: &'static str,
    /// `id`, or `segment_id` for a table of one row per start-up.
    pub key: &'static str,
    pub columns: &'static [(&'static str, ColKind)],
    pub cursor: FleetCursor,
}

use ColKind::{Int, Real, Text};

/// Start-up segments (their phases travel with them, [`Store::fleet_phases`]).
pub const FLEET_SEGMENTS: FleetTable = FleetTable {
    name: "segments",
    key: "id",
    columns: &[
        ("kind", Text),
        ("start_ms", Int),
        ("end_ms", Int),
        ("outcome", Text),
        ("abort_cause", Text),
        ("status", Text),
        ("hot_restart", Int),
        ("has_gap", Int),
        ("updated_at_ms", Int),
    ],
    cursor: FleetCursor::UpdatedAt,
};

/// Health results.
pub const FLEET_DIAGNOSES: FleetTable = FleetTable {
    name: "diagnoses",
    key: "id",
    columns: &[
        ("segment_id", Int),
        ("method", Text),
        ("d_gc", Real),
        ("d_ec", Real),
        ("d_gt", Real),
        ("d_et", Real),
        ("d_gp", Real),
        ("d_ep", Real),
        ("sigma_gc", Real),
        ("sigma_ec", Real),
        ("sigma_gt", Real),
        ("sigma_et", Real),
        ("sigma_gp", Real),
        ("sigma_ep", Real),
        ("objective", Real),
        ("model_runs", Int),
        ("wall_s", Real),
        ("model_version", Text),
        ("seed", Int),
        ("created_at_ms", Int),
        ("residual_level", Real),
        ("fit_quality", Text),
        ("config_hash", Text),
        ("gtwatch_version", Text),
    ],
    cursor: FleetCursor::Id,
};

/// Sim-to-real gap analyses.
pub const FLEET_GAP_ANALYSES: FleetTable = FleetTable {
    name: "gap_analyses",
    key: "id",
    columns: &[
        ("segment_id", Int),
        ("holdout_segment_id", Int),
        ("effect", Text),
        ("shrinkage", Real),
        ("confidence", Real),
        ("baseline_fit_quality", Text),
        ("normalised_residual", Real),
        ("report_json", Text),
        ("gtwatch_version", Text),
        ("created_at_ms", Int),
    ],
    cursor: FleetCursor::Id,
};

/// Washes (recorded, detected, confirmed; a rejected one is deleted at the edge).
pub const FLEET_WASHES: FleetTable = FleetTable {
    name: "washes",
    key: "id",
    columns: &[("t_ms", Int), ("kind", Text), ("note", Text)],
    cursor: FleetCursor::Whole,
};

/// Health corrected for an instrument's step (migration 0009), one row per corrected
/// start-up: replaced or dropped by each refresh of the wash advice, so sent whole.
pub const FLEET_CORRECTIONS: FleetTable = FleetTable {
    name: "instrument_corrections",
    key: "segment_id",
    columns: &[
        ("onset_segment_id", Int),
        ("effect", Text),
        ("unit", Text),
        ("magnitude", Real),
        ("magnitude_sigma", Real),
        ("d_gc", Real),
        ("d_ec", Real),
        ("d_gt", Real),
        ("d_et", Real),
        ("d_gp", Real),
        ("d_ep", Real),
        ("sigma_gc", Real),
        ("sigma_ec", Real),
        ("sigma_gt", Real),
        ("sigma_et", Real),
        ("sigma_gp", Real),
        ("sigma_ep", Real),
        ("refreshed_ms", Int),
        ("also", Text),
    ],
    cursor: FleetCursor::Whole,
};

/// Wash advice.
pub const FLEET_RECOMMENDATIONS: FleetTable = FleetTable {
    name: "recommendations",
    key: "id",
    columns: &[
        ("t_ms", Int),
        ("kind", Text),
        ("message", Text),
        ("basis", Text),
    ],
    cursor: FleetCursor::Id,
};

/// Columns of a tag as the centre keeps it ([`Store::fleet_tags`]; `signal` is the signal's
/// column name, e.g. `n1_rpm`, or NULL).
pub const FLEET_TAG_COLUMNS: &[(&str, ColKind)] =
    &[("name", Text), ("unit", Text), ("signal", Text)];

/// Columns of a segment's phases (keyed by segment id and phase name).
pub const FLEET_PHASE_COLUMNS: &[(&str, ColKind)] = &[
    ("phase", Text),
    ("phase_code", Int),
    ("start_ms", Int),
    ("end_ms", Int),
];

/// One batch of rows of a table, as columns.
#[derive(Debug, Clone, PartialEq)]
pub struct FleetRows {
    /// The edge ids (for phases: the segment id of each phase).
    pub ids: Vec<i64>,
    /// One column per entry of the table's column list.
    pub columns: Vec<FleetColumn>,
    /// The cursor after the last row: (id, 0) or (updated_at_ms, id).
    pub last: Option<(i64, i64)>,
}

impl FleetRows {
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }
}

/// A start-up window whose samples are sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FleetWindow {
    pub segment_id: i64,
    pub start_ms: i64,
    /// Where its samples begin: `start_ms` less the standstill context the diagnosis reads
    /// before a start-up ([`super::CONTEXT_BEFORE_MS`]), so the centre holds everything a
    /// re-diagnosis needs.
    pub from_ms: i64,
    /// `None` while the segment is open (its samples wait until it closes).
    pub end_ms: Option<i64>,
}

/// One batch of samples of a window, as columns.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FleetSamples {
    pub tag_ids: Vec<i64>,
    pub tags: Vec<String>,
    pub t_ms: Vec<i64>,
    pub values: Vec<f64>,
    pub quality: Vec<i64>,
}

impl FleetSamples {
    pub fn len(&self) -> usize {
        self.t_ms.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t_ms.is_empty()
    }
}

/// A persistent high-water mark of one stream at one centre (table `fleet_sync`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FleetMark {
    pub centre: String,
    pub unit_id: String,
    pub stream: String,
    pub a: i64,
    pub b: i64,
    pub c: i64,
    /// Rows sent over all syncs.
    pub sent: i64,
}

fn empty_columns(cols: &[(&str, ColKind)]) -> Vec<FleetColumn> {
    cols.iter()
        .map(|(_, k)| match k {
            Int => FleetColumn::Int(Vec::new()),
            Real => FleetColumn::Real(Vec::new()),
            Text => FleetColumn::Text(Vec::new()),
        })
        .collect()
}

/// Appends column `i` of `row` (offset by `skip` leading columns) to each column vector.
fn push_row(
    columns: &mut [FleetColumn],
    row: &rusqlite::Row<'_>,
    skip: usize,
) -> Result<(), StoreError> {
    for (i, col) in columns.iter_mut().enumerate() {
        let v = row.get_ref(i + skip)?;
        match (col, v) {
            (FleetColumn::Int(c), ValueRef::Null) => c.push(None),
            (FleetColumn::Int(c), ValueRef::Integer(x)) => c.push(Some(x)),
            (FleetColumn::Real(c), ValueRef::Null) => c.push(None),
            (FleetColumn::Real(c), ValueRef::Real(x)) => c.push(Some(x)),
            (FleetColumn::Real(c), ValueRef::Integer(x)) => c.push(Some(x as f64)),
            (FleetColumn::Text(c), ValueRef::Null) => c.push(None),
            (FleetColumn::Text(c), ValueRef::Text(t)) => {
                c.push(Some(String::from_utf8_lossy(t).into_owned()));
            }
            (_, other) => {
                return Err(StoreError::Corrupt(format!(
                    "fleet sync: column {} holds {:?}, not the expected type",
                    i + skip,
                    other.data_type()
                )))
            }
        }
    }
    Ok(())
}

impl Store {
    /// Up to `limit` rows of `table` after the cursor `after` ((id, _) or (updated_at_ms, id);
    /// ignored for a table sent whole, which is read from id > `after.0`), in cursor order.
    pub fn fleet_rows(
        &self,
        table: &FleetTable,
        after: (i64, i64),
        limit: usize,
    ) -> Result<FleetRows, StoreError> {
        let cols: Vec<&str> = table.columns.iter().map(|(c, _)| *c).collect();
        let cols = cols.join(", ");
        let (name, key) = (table.name, table.key);
        let (sql, bind): (String, Vec<i64>) = match table.cursor {
            FleetCursor::Id | FleetCursor::Whole => (
                format!(
                    "SELECT {key}, {cols} FROM {name} WHERE {key} > ?1 ORDER BY {key} LIMIT ?2"
                ),
                vec![after.0, limit as i64],
            ),
            FleetCursor::UpdatedAt => (
                format!(
                    "SELECT id, {cols} FROM {name}
                     WHERE updated_at_ms > ?1 OR (updated_at_ms = ?1 AND id > ?2)
                     ORDER BY updated_at_ms, id LIMIT ?3"
                ),
                vec![after.0, after.1, limit as i64],
            ),
        };
        let mut st = self.conn.prepare_cached(&sql)?;
        let mut rows = st.query(rusqlite::params_from_iter(bind))?;
        let mut out = FleetRows {
            ids: Vec::new(),
            columns: empty_columns(table.columns),
            last: None,
        };
        let upd = table
            .columns
            .iter()
            .position(|(c, _)| *c == "updated_at_ms");
        while let Some(r) = rows.next()? {
            let id: i64 = r.get(0)?;
            push_row(&mut out.columns, r, 1)?;
            out.ids.push(id);
            out.last = Some(match (table.cursor, upd) {
                (FleetCursor::UpdatedAt, Some(u)) => (r.get(u + 1)?, id),
                _ => (id, 0),
            });
        }
        Ok(out)
    }

    /// The phases of these segments (`ids` holds each phase's segment id).
    pub fn fleet_phases(&self, segment_ids: &[i64]) -> Result<FleetRows, StoreError> {
        let mut st = self.conn.prepare_cached(
            "SELECT segment_id, phase, phase_code, start_ms, end_ms FROM segment_phases
             WHERE segment_id = ?1 ORDER BY phase_code",
        )?;
        let mut out = FleetRows {
            ids: Vec::new(),
            columns: empty_columns(FLEET_PHASE_COLUMNS),
            last: None,
        };
        for id in segment_ids {
            let mut rows = st.query([id])?;
            while let Some(r) = rows.next()? {
                out.ids.push(r.get(0)?);
                push_row(&mut out.columns, r, 1)?;
            }
        }
        Ok(out)
    }

    /// Ids of every stored segment (the centre drops the ones the edge no longer has: a
    /// re-scan replaces start-ups not yet diagnosed).
    pub fn fleet_segment_ids(&self) -> Result<Vec<i64>, StoreError> {
        let mut st = self
            .conn
            .prepare_cached("SELECT id FROM segments ORDER BY id")?;
        let ids = st.query_map([], |r| r.get(0))?;
        Ok(ids.collect::<Result<_, _>>()?)
    }

    /// The segment `id`, if it still exists.
    pub fn fleet_window(&self, id: i64) -> Result<Option<FleetWindow>, StoreError> {
        use rusqlite::OptionalExtension;
        Ok(self
            .conn
            .query_row(
                "SELECT id, start_ms, end_ms FROM segments WHERE id = ?1",
                [id],
                fleet_window_row,
            )
            .optional()?)
    }

    /// The first segment with an id above `after_id`, if any.
    pub fn fleet_next_window(&self, after_id: i64) -> Result<Option<FleetWindow>, StoreError> {
        use rusqlite::OptionalExtension;
        Ok(self
            .conn
            .query_row(
                "SELECT id, start_ms, end_ms FROM segments WHERE id > ?1 ORDER BY id LIMIT 1",
                [after_id],
                fleet_window_row,
            )
            .optional()?)
    }

    /// Up to `limit` samples (any quality) of `[start_ms, end_ms]` (a window's `from_ms` …
    /// `end_ms`) after (`after_tag`,
    /// `after_t`) in (tag id, time) order: each tag's range is read through the primary key.
    pub fn fleet_window_samples(
        &self,
        start_ms: i64,
        end_ms: i64,
        after: (i64, i64),
        limit: usize,
    ) -> Result<FleetSamples, StoreError> {
        let tags: Vec<(i64, String)> = {
            let mut st = self
                .conn
                .prepare_cached("SELECT id, name FROM tags WHERE id >= ?1 ORDER BY id")?;
            let rows = st.query_map([after.0], |r| Ok((r.get(0)?, r.get(1)?)))?;
            rows.collect::<Result<_, _>>()?
        };
        let mut out = FleetSamples::default();
        for (tag, name) in tags {
            let room = limit.saturating_sub(out.len());
            if room == 0 {
                break;
            }
            let from = if tag == after.0 {
                after.1.max(start_ms - 1)
            } else {
                start_ms - 1
            };
            let rows = super::archive::read_samples(
                &self.conn,
                tag,
                from.saturating_add(1),
                end_ms,
                false,
            )?;
            for s in rows.into_iter().take(room) {
                out.tag_ids.push(tag);
                out.tags.push(name.clone());
                out.t_ms.push(s.t_ms);
                out.values.push(s.value);
                out.quality.push(s.quality);
            }
        }
        Ok(out)
    }

    /// Every tag as the centre keeps it: (edge id, name, engineering unit, signal column name).
    pub fn fleet_tags(&self) -> Result<FleetRows, StoreError> {
        let tags = self.tags()?;
        Ok(FleetRows {
            ids: tags.iter().map(|t| t.id).collect(),
            columns: vec![
                FleetColumn::Text(tags.iter().map(|t| Some(t.name.clone())).collect()),
                FleetColumn::Text(tags.iter().map(|t| Some(t.unit.clone())).collect()),
                FleetColumn::Text(
                    tags.iter()
                        .map(|t| t.signal.map(|s| s.column().to_string()))
                        .collect(),
                ),
            ],
            last: tags.last().map(|t| (t.id, 0)),
        })
    }

    /// Rows of `table` after the cursor `after` (as [`Store::fleet_rows`] walks it): what a
    /// sync from that mark would send (the fleet sync's lag).
    pub fn fleet_count_after(
        &self,
        table: &FleetTable,
        after: (i64, i64),
    ) -> Result<i64, StoreError> {
        let (name, key) = (table.name, table.key);
        Ok(match table.cursor {
            FleetCursor::Id | FleetCursor::Whole => self.conn.query_row(
                &format!("SELECT COUNT(*) FROM {name} WHERE {key} > ?1"),
                [after.0],
                |r| r.get(0),
            )?,
            FleetCursor::UpdatedAt => self.conn.query_row(
                &format!(
                    "SELECT COUNT(*) FROM {name}
                     WHERE updated_at_ms > ?1 OR (updated_at_ms = ?1 AND id > ?2)"
                ),
                [after.0, after.1],
                |r| r.get(0),
            )?,
        })
    }

    /// Closed windows from segment id `from_id` on (inclusive), in id order.
    pub fn fleet_closed_windows(&self, from_id: i64) -> Result<Vec<FleetWindow>, StoreError> {
        let mut st = self.conn.prepare_cached(
            "SELECT id, start_ms, end_ms FROM segments WHERE id >= ?1 AND end_ms IS NOT NULL
             ORDER BY id",
        )?;
        let rows = st.query_map([from_id], fleet_window_row)?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Samples (any quality, both tiers) of every tag in `[from_ms, end_ms]`.
    pub fn fleet_window_count(&self, from_ms: i64, end_ms: i64) -> Result<i64, StoreError> {
        let mut n = 0;
        for t in self.tags()? {
            n += super::archive::count_samples(&self.conn, t.id, from_ms, end_ms)?;
        }
        Ok(n)
    }

    /// The marks kept for `centre` and `unit_id`.
    pub fn fleet_marks(&self, centre: &str, unit_id: &str) -> Result<Vec<FleetMark>, StoreError> {
        let mut st = self.conn.prepare_cached(
            "SELECT stream, mark_a, mark_b, mark_c, sent FROM fleet_sync
             WHERE centre = ?1 AND unit_id = ?2 ORDER BY stream",
        )?;
        let rows = st.query_map(params![centre, unit_id], |r| {
            Ok(FleetMark {
                centre: centre.to_string(),
                unit_id: unit_id.to_string(),
                stream: r.get(0)?,
                a: r.get(1)?,
                b: r.get(2)?,
                c: r.get(3)?,
                sent: r.get(4)?,
            })
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Every mark, of every centre (`gtwatch sync` shows them; tests compare them).
    pub fn all_fleet_marks(&self) -> Result<Vec<FleetMark>, StoreError> {
        let mut st = self.conn.prepare_cached(
            "SELECT centre, unit_id, stream, mark_a, mark_b, mark_c, sent FROM fleet_sync
             ORDER BY centre, unit_id, stream",
        )?;
        let rows = st.query_map([], |r| {
            Ok(FleetMark {
                centre: r.get(0)?,
                unit_id: r.get(1)?,
                stream: r.get(2)?,
                a: r.get(3)?,
                b: r.get(4)?,
                c: r.get(5)?,
                sent: r.get(6)?,
            })
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Writes one mark (after the centre committed what it covers).
    pub fn save_fleet_mark(&mut self, m: &FleetMark) -> Result<(), StoreError> {
        self.conn.execute(
            "INSERT INTO fleet_sync (centre, unit_id, stream, mark_a, mark_b, mark_c, sent, synced_at_ms)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)
             ON CONFLICT (centre, unit_id, stream) DO UPDATE SET mark_a = excluded.mark_a,
                 mark_b = excluded.mark_b, mark_c = excluded.mark_c, sent = excluded.sent,
                 synced_at_ms = excluded.synced_at_ms",
            params![m.centre, m.unit_id, m.stream, m.a, m.b, m.c, m.sent, now_ms()],
        )?;
        Ok(())
    }

    /// What the centre should hold of this edge, per table: the rows of each table sent and
    /// the samples inside closed start-up windows.
    pub fn fleet_counts(&self) -> Result<Vec<(&'static str, i64)>, StoreError> {
        let mut out = Vec::new();
        for t in [
            "segments",
            "segment_phases",
            "diagnoses",
            "gap_analyses",
            "washes",
            "recommendations",
        ] {
            let n: i64 = self
                .conn
                .query_row(&format!("SELECT COUNT(*) FROM {t}"), [], |r| r.get(0))?;
            out.push((t, n));
        }
        let n: i64 = self.conn.query_row(
            "SELECT COUNT(*) FROM samples s WHERE EXISTS (SELECT 1 FROM segments g
               WHERE g.end_ms IS NOT NULL AND s.t_ms BETWEEN g.start_ms - ?1 AND g.end_ms)",
            [super::CONTEXT_BEFORE_MS],
            |r| r.get(0),
        )?;
        let windows: Vec<(i64, i64)> = {
            let mut st = self
                .conn
                .prepare_cached("SELECT start_ms, end_ms FROM segments WHERE end_ms IS NOT NULL")?;
            let rows = st.query_map([], |r| {
                Ok((r.get::<_, i64>(0)? - super::CONTEXT_BEFORE_MS, r.get(1)?))
            })?;
            rows.collect::<Result<_, _>>()?
        };
        let n = n + super::archive::count_archived_in(&self.conn, &windows)?;
        out.push(("samples", n));
        let n: i64 =
            self.conn
                .query_row("SELECT COUNT(*) FROM instrument_corrections", [], |r| {
                    r.get(0)
                })?;
        out.push(("instrument_corrections", n));
        Ok(out)
    }
}

/// A [`FleetWindow`] from a `SELECT id, start_ms, end_ms FROM segments` row.
fn fleet_window_row(r: &rusqlite::Row<'_>) -> rusqlite::Result<FleetWindow> {
    let start_ms: i64 = r.get(1)?;
    Ok(FleetWindow {
        segment_id: r.get(0)?,
        start_ms,
        from_ms: start_ms - super::CONTEXT_BEFORE_MS,
        end_ms: r.get(2)?,
    })
}
