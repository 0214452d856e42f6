//! One sync of one edge into the centre.
//!
//! Per stream, in this order: segments (with their phases; walked by (updated_at_ms, id), so a
//! segment closed or diagnosed after it was sent is sent again and updated; segments the edge
//! no longer has — a re-scan replaced them before diagnosis — are dropped at the centre),
//! diagnoses, gap analyses, recommendations (walked by id: rows never change), washes (sent
//! whole: few rows, confirmed or rejected in place; the centre keeps exactly the edge's),
//! instrument corrections (sent whole too: each refresh of the wash advice replaces or drops
//! the rows of the start-ups it fitted), and the samples of each closed start-up window (walked by segment id, then tag id and time;
//! from 10 s before the start, the standstill context the diagnosis reads, and recorded in
//! `sample_windows` once complete). The tags (which tag is which engine signal) go first,
//! whole, so the centre can read a window as the diagnosis does.
//!
//! Each batch (at most `batch_rows` rows) is one central transaction; only after its COMMIT
//! returned does the stream's mark move at the edge (through a [`MarkSink`]). A crash or a
//! lost connection in between re-sends the batch, which the centre absorbs (`ON CONFLICT`),
//! so nothing is skipped and nothing doubled.

use super::centre::Centre;
use super::{FleetConfig, FleetError};
use crate::store::{
    ColKind, FleetColumn, FleetCursor, FleetMark, FleetRows, FleetTable, Store, StoreError,
    WriteCmd, WriterHandle, FLEET_CORRECTIONS, FLEET_DIAGNOSES, FLEET_GAP_ANALYSES,
    FLEET_PHASE_COLUMNS, FLEET_RECOMMENDATIONS, FLEET_SEGMENTS, FLEET_TAG_COLUMNS, FLEET_WASHES,
};
use postgres::types::ToSql;
use postgres::Transaction;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Where the marks are written: the edge's own store (`gtwatch sync`) or the daemon's writer.
pub trait MarkSink {
    fn save(&mut self, mark: &FleetMark) -> Result<(), StoreError>;
}

impl MarkSink for Store {
    fn save(&mut self, mark: &FleetMark) -> Result<(), StoreError> {
        self.save_fleet_mark(mark)
    }
}

/// The daemon's writer (blocking: call on the blocking pool).
impl MarkSink for WriterHandle {
    fn save(&mut self, mark: &FleetMark) -> Result<(), StoreError> {
        self.blocking_request(|reply| WriteCmd::FleetMark {
            mark: mark.clone(),
            reply,
        })
    }
}

/// What one stream sent in one sync.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct StreamReport {
    pub table: String,
    /// Rows in the batches the centre committed (washes: rows new or changed there).
    pub sent: u64,
    /// Rows the centre inserted or changed (a re-sent row counts in `sent`, not here).
    pub applied: u64,
    /// Central transactions.
    pub batches: u64,
    /// Rows the centre dropped because the edge no longer has them (segments, washes).
    pub removed: u64,
}

/// What one sync did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SyncReport {
    pub unit_id: String,
    pub centre: String,
    pub centre_id: String,
    pub streams: Vec<StreamReport>,
    pub wall_s: f64,
}

impl SyncReport {
    /// Rows sent over all streams.
    pub fn total_sent(&self) -> u64 {
        self.streams.iter().map(|s| s.sent).sum()
    }
}

/// A mark of the table's stream: the second key of "done with this window" for samples.
const WINDOW_DONE: i64 = i64::MAX;

/// The samples stream's mark. Named anew when the windows grew the standstill context before
/// each start-up (centre schema 2): an edge upgraded from a build that sent bare windows walks
/// them all again, so every window at the centre gets its context and its `sample_windows` row
/// (the re-sent rows themselves are absorbed by `ON CONFLICT`).
pub const SAMPLES_STREAM: &str = "samples.ctx";

/// The running state of one sync.
struct Run<'a> {
    edge: &'a Store,
    sink: &'a mut dyn MarkSink,
    centre: &'a mut Centre,
    cfg: &'a FleetConfig,
    stop: &'a AtomicBool,
    marks: BTreeMap<String, FleetMark>,
}

/// Sends everything new of `edge` to `centre` as `cfg.unit_id`; stops between batches when
/// `stop` is set.
pub fn sync_once(
    edge: &Store,
    sink: &mut dyn MarkSink,
    centre: &mut Centre,
    cfg: &FleetConfig,
    stop: &AtomicBool,
) -> Result<SyncReport, FleetError> {
    let t0 = Instant::now();
    centre.check_version()?;
    touch_unit(centre, &cfg.unit_id)?;
    let marks = edge
        .fleet_marks(&centre.id, &cfg.unit_id)?
        .into_iter()
        .map(|m| (m.stream.clone(), m))
        .collect();
    let mut report = SyncReport {
        unit_id: cfg.unit_id.clone(),
        centre: centre.name.clone(),
        centre_id: centre.id.clone(),
        ..SyncReport::default()
    };
    let mut run = Run {
        edge,
        sink,
        centre,
        cfg,
        stop,
        marks,
    };
    report.streams.push(run.tags()?);
    report.streams.push(run.table(&FLEET_SEGMENTS)?);
    for t in [FLEET_DIAGNOSES, FLEET_GAP_ANALYSES, FLEET_RECOMMENDATIONS] {
        report.streams.push(run.table(&t)?);
    }
    report.streams.push(run.whole(&FLEET_WASHES)?);
    report.streams.push(run.whole(&FLEET_CORRECTIONS)?);
    if cfg.send_samples {
        report.streams.push(run.samples()?);
    }
    touch_unit(run.centre, &cfg.unit_id)?;
    report.wall_s = t0.elapsed().as_secs_f64();
    Ok(report)
}

/// The streams whose lag [`sync_lag`] reports, in its order (the metrics' table labels).
pub const LAG_STREAMS: [&str; 6] = crate::metrics::SYNC_LAG_TABLES;

/// Rows of each stream in [`LAG_STREAMS`] that the edge holds above its high-water marks for
/// `centre_id` and `unit_id` (what the next sync would send; everything when there are no
/// marks). Samples: those of the closed start-up windows not yet done (the window being sent
/// counts whole, so this is at most one window over). Reads the edge only.
pub fn sync_lag(
    edge: &Store,
    centre_id: &str,
    unit_id: &str,
    send_samples: bool,
) -> Result<Vec<(&'static str, u64)>, StoreError> {
    let marks: BTreeMap<String, FleetMark> = edge
        .fleet_marks(centre_id, unit_id)?
        .into_iter()
        .map(|m| (m.stream.clone(), m))
        .collect();
    let after = |stream: &str| {
        marks
            .get(stream)
            .map_or((i64::MIN, i64::MIN), |m| (m.a, m.b))
    };
    let n = |v: i64| u64::try_from(v).unwrap_or(0);
    let mut out = Vec::with_capacity(LAG_STREAMS.len());
    for t in [
        FLEET_SEGMENTS,
        FLEET_DIAGNOSES,
        FLEET_GAP_ANALYSES,
        FLEET_RECOMMENDATIONS,
        FLEET_WASHES,
    ] {
        out.push((t.name, n(edge.fleet_count_after(&t, after(t.name))?)));
    }
    let mut samples = 0;
    if send_samples {
        let first = match marks.get(SAMPLES_STREAM) {
            None => i64::MIN,
            Some(m) if m.b == WINDOW_DONE => m.a.saturating_add(1),
            Some(m) => m.a,
        };
        for w in edge.fleet_closed_windows(first)? {
            if let Some(end) = w.end_ms {
                samples += n(edge.fleet_window_count(w.from_ms, end)?);
            }
        }
    }
    out.push(("samples", samples));
    debug_assert!(out.iter().map(|(t, _)| *t).eq(LAG_STREAMS));
    Ok(out)
}

/// Creates the unit's row or moves its last sync time to now.
fn touch_unit(centre: &mut Centre, unit_id: &str) -> Result<(), FleetError> {
    let name = centre.name.clone();
    centre
        .client
        .execute(
            "INSERT INTO units (unit_id, gtwatch_version) VALUES ($1, $2)
             ON CONFLICT (unit_id) DO UPDATE SET last_sync_at = now(),
                 gtwatch_version = EXCLUDED.gtwatch_version",
            &[&unit_id, &env!("CARGO_PKG_VERSION")],
        )
        .map(|_| ())
        .map_err(|source| FleetError::Centre {
            centre: name,
            what: "recording the unit".to_string(),
            source,
        })
}

fn pg_type(k: ColKind) -> &'static str {
    match k {
        ColKind::Int => "bigint",
        ColKind::Real => "float8",
        ColKind::Text => "text",
    }
}

/// How a batch meets rows already at the centre.
#[derive(Clone, Copy, PartialEq, Eq)]
enum OnConflict {
    Nothing,
    /// Overwrite rows whose columns differ.
    Update,
}

/// Inserts a batch in one statement (`unnest` of one array per column); returns the rows
/// inserted or changed.
fn insert_columns(
    tx: &mut Transaction<'_>,
    table: &str,
    key: &[&str],
    cols: &[(&str, ColKind)],
    unit_id: &str,
    rows: &FleetRows,
    on_conflict: OnConflict,
) -> Result<u64, postgres::Error> {
    let names: Vec<&str> = cols.iter().map(|(c, _)| *c).collect();
    let arrays: Vec<String> = cols
        .iter()
        .enumerate()
        .map(|(i, (_, k))| format!("${}::{}[]", i + 3, pg_type(*k)))
        .collect();
    let conflict = match on_conflict {
        OnConflict::Nothing => "DO NOTHING".to_string(),
        OnConflict::Update => {
            let set: Vec<String> = names
                .iter()
                .map(|c| format!("{c} = EXCLUDED.{c}"))
                .collect();
            let old: Vec<String> = names.iter().map(|c| format!("{table}.{c}")).collect();
            let new: Vec<String> = names.iter().map(|c| format!("EXCLUDED.{c}")).collect();
            format!(
                "DO UPDATE SET {} WHERE ({}) IS DISTINCT FROM ({})",
                set.join(", "),
                old.join(", "),
                new.join(", ")
            )
        }
    };
    let sql = format!(
        "INSERT INTO {table} (unit_id, edge_id, {}) SELECT $1::text, * FROM unnest($2::bigint[], {})
         ON CONFLICT ({}) {conflict}",
        names.join(", "),
        arrays.join(", "),
        key.join(", ")
    );
    let mut params: Vec<Box<dyn ToSql + Sync>> = vec![Box::new(unit_id.to_string())];
    params.push(Box::new(rows.ids.clone()));
    for c in &rows.columns {
        params.push(match c {
            FleetColumn::Int(v) => Box::new(v.clone()),
            FleetColumn::Real(v) => Box::new(v.clone()),
            FleetColumn::Text(v) => Box::new(v.clone()),
        });
    }
    let refs: Vec<&(dyn ToSql + Sync)> = params.iter().map(|p| p.as_ref()).collect();
    tx.execute(sql.as_str(), &refs)
}

impl Run<'_> {
    fn check_stop(&self) -> Result<(), FleetError> {
        if self.stop.load(Ordering::Relaxed) {
            return Err(FleetError::Stopped);
        }
        Ok(())
    }

    fn mark(&self, stream: &str, init: (i64, i64, i64)) -> FleetMark {
        self.marks.get(stream).cloned().unwrap_or(FleetMark {
            centre: self.centre.id.clone(),
            unit_id: self.cfg.unit_id.clone(),
            stream: stream.to_string(),
            a: init.0,
            b: init.1,
            c: init.2,
            sent: 0,
        })
    }

    fn save(&mut self, mark: FleetMark) -> Result<(), FleetError> {
        self.sink.save(&mark)?;
        self.marks.insert(mark.stream.clone(), mark);
        Ok(())
    }

    fn centre_err(&self, what: String) -> impl FnOnce(postgres::Error) -> FleetError {
        let centre = self.centre.name.clone();
        move |source| FleetError::Centre {
            centre,
            what,
            source,
        }
    }

    /// Runs `work` in one central transaction and commits it.
    fn in_tx<T>(
        &mut self,
        what: &str,
        work: impl FnOnce(&mut Transaction<'_>) -> Result<T, postgres::Error>,
    ) -> Result<T, FleetError> {
        let err = self.centre_err(what.to_string());
        let result = (|| {
            let mut tx = self.centre.client.transaction()?;
            let out = work(&mut tx)?;
            tx.commit()?;
            Ok(out)
        })();
        result.map_err(err)
    }

    /// A table walked by id or by (updated_at_ms, id).
    fn table(&mut self, table: &FleetTable) -> Result<StreamReport, FleetError> {
        let mut rep = StreamReport {
            table: table.name.to_string(),
            ..StreamReport::default()
        };
        let mut mark = self.mark(table.name, (i64::MIN, i64::MIN, 0));
        loop {
            self.check_stop()?;
            let rows = self
                .edge
                .fleet_rows(table, (mark.a, mark.b), self.cfg.batch_rows)?;
            let Some(last) = rows.last else { break };
            let unit = self.cfg.unit_id.clone();
            let segments = table.cursor == FleetCursor::UpdatedAt;
            let phases = if segments {
                Some(self.edge.fleet_phases(&rows.ids)?)
            } else {
                None
            };
            let applied = self.in_tx(&format!("sending {}", table.name), |tx| {
                let on = if segments {
                    OnConflict::Update
                } else {
                    OnConflict::Nothing
                };
                let key = ["unit_id", "edge_id"];
                let n = insert_columns(tx, table.name, &key, table.columns, &unit, &rows, on)?;
                if let Some(p) = &phases {
                    tx.execute(
                        "DELETE FROM segment_phases WHERE unit_id = $1 AND edge_id = ANY($2)",
                        &[&unit, &rows.ids],
                    )?;
                    let key = ["unit_id", "edge_id", "phase"];
                    insert_columns(
                        tx,
                        "segment_phases",
                        &key,
                        FLEET_PHASE_COLUMNS,
                        &unit,
                        p,
                        OnConflict::Nothing,
                    )?;
                }
                Ok(n)
            })?;
            rep.sent += rows.len() as u64;
            rep.applied += applied;
            rep.batches += 1;
            mark.a = last.0;
            mark.b = last.1;
            mark.sent += rows.len() as i64;
            self.save(mark.clone())?;
            if rows.len() < self.cfg.batch_rows {
                break;
            }
        }
        if table.cursor == FleetCursor::UpdatedAt {
            rep.removed = self.drop_missing_segments()?;
        }
        Ok(rep)
    }

    /// Drops at the centre the segments (and their phases) the edge no longer has.
    fn drop_missing_segments(&mut self) -> Result<u64, FleetError> {
        let ids = self.edge.fleet_segment_ids()?;
        let unit = self.cfg.unit_id.clone();
        self.in_tx("dropping replaced segments", |tx| {
            tx.execute(
                "DELETE FROM sample_windows WHERE unit_id = $1 AND NOT (segment_id = ANY($2))",
                &[&unit, &ids],
            )?;
            tx.execute(
                "DELETE FROM segments WHERE unit_id = $1 AND NOT (edge_id = ANY($2))",
                &[&unit, &ids],
            )
        })
    }

    /// The tags, whole (a handful of rows): upserted where new or changed, so the centre knows
    /// which tag is which engine signal (a re-diagnosis reads the samples through it).
    fn tags(&mut self) -> Result<StreamReport, FleetError> {
        self.check_stop()?;
        let rows = self.edge.fleet_tags()?;
        let unit = self.cfg.unit_id.clone();
        let n = if rows.is_empty() {
            0
        } else {
            self.in_tx("sending tags", |tx| {
                let key = ["unit_id", "edge_id"];
                insert_columns(
                    tx,
                    "tags",
                    &key,
                    FLEET_TAG_COLUMNS,
                    &unit,
                    &rows,
                    OnConflict::Update,
                )
            })?
        };
        Ok(StreamReport {
            table: "tags".to_string(),
            sent: n,
            applied: n,
            batches: u64::from(n > 0),
            removed: 0,
        })
    }

    /// A table sent whole (washes, instrument corrections): rows upserted where new or
    /// changed; the centre's extra ones (rejected or dropped at the edge) deleted.
    fn whole(&mut self, table: &FleetTable) -> Result<StreamReport, FleetError> {
        let name = table.name;
        let mut rep = StreamReport {
            table: name.to_string(),
            ..StreamReport::default()
        };
        let unit = self.cfg.unit_id.clone();
        let mut after = i64::MIN;
        let mut ids: Vec<i64> = Vec::new();
        loop {
            self.check_stop()?;
            let rows = self
                .edge
                .fleet_rows(table, (after, 0), self.cfg.batch_rows)?;
            let Some(last) = rows.last else { break };
            ids.extend_from_slice(&rows.ids);
            let n = self.in_tx(&format!("sending {name}"), |tx| {
                let key = ["unit_id", "edge_id"];
                insert_columns(
                    tx,
                    name,
                    &key,
                    table.columns,
                    &unit,
                    &rows,
                    OnConflict::Update,
                )
            })?;
            rep.sent += n;
            rep.applied += n;
            rep.batches += 1;
            after = last.0;
            if rows.len() < self.cfg.batch_rows {
                break;
            }
        }
        rep.removed = self.in_tx(&format!("dropping {name} the edge no longer has"), |tx| {
            tx.execute(
                &format!("DELETE FROM {name} WHERE unit_id = $1 AND NOT (edge_id = ANY($2))"),
                &[&unit, &ids],
            )
        })?;
        if rep.sent > 0 || rep.removed > 0 {
            let mut mark = self.mark(name, (0, 0, 0));
            mark.a = ids.last().copied().unwrap_or(0);
            mark.sent += rep.sent as i64;
            self.save(mark)?;
        }
        Ok(rep)
    }

    /// The samples of each closed start-up window, in segment-id order.
    fn samples(&mut self) -> Result<StreamReport, FleetError> {
        let mut rep = StreamReport {
            table: "samples".to_string(),
            ..StreamReport::default()
        };
        let mut mark = self.mark(SAMPLES_STREAM, (0, WINDOW_DONE, 0));
        let unit = self.cfg.unit_id.clone();
        loop {
            self.check_stop()?;
            let current = if mark.b == WINDOW_DONE {
                None
            } else {
                self.edge.fleet_window(mark.a)?
            };
            let window = match current {
                Some(w) => w,
                None => match self.edge.fleet_next_window(mark.a)? {
                    Some(w) => {
                        (mark.a, mark.b, mark.c) = (w.segment_id, i64::MIN, i64::MIN);
                        w
                    }
                    None => break,
                },
            };
            // An open start-up's samples wait until it closes.
            let Some(end_ms) = window.end_ms else { break };
            let batch = self.edge.fleet_window_samples(
                window.from_ms,
                end_ms,
                (mark.b, mark.c),
                self.cfg.batch_rows,
            )?;
            let n = batch.len();
            if n > 0 {
                let seg = vec![window.segment_id; n];
                let applied = self.in_tx("sending samples", |tx| {
                    tx.execute(
                        "INSERT INTO samples (unit_id, tag, t_ms, value, quality, segment_id)
                         SELECT $1::text, * FROM unnest($2::text[], $3::bigint[], $4::float8[],
                                                         $5::bigint[], $6::bigint[])
                         ON CONFLICT (unit_id, tag, t_ms) DO NOTHING",
                        &[
                            &unit,
                            &batch.tags,
                            &batch.t_ms,
                            &batch.values,
                            &batch.quality,
                            &seg,
                        ],
                    )
                })?;
                rep.sent += n as u64;
                rep.applied += applied;
                rep.batches += 1;
                mark.sent += n as i64;
                mark.b = batch.tag_ids[n - 1];
                mark.c = batch.t_ms[n - 1];
            }
            if n < self.cfg.batch_rows {
                // Every sample of the window is committed: say so at the centre (a crash
                // before the mark moves re-reads nothing and writes this again).
                let (seg, from, to) = (window.segment_id, window.from_ms, end_ms);
                self.in_tx("recording a complete window", |tx| {
                    tx.execute(
                        "INSERT INTO sample_windows (unit_id, segment_id, from_ms, end_ms)
                         VALUES ($1, $2, $3, $4)
                         ON CONFLICT (unit_id, segment_id) DO UPDATE
                           SET from_ms = EXCLUDED.from_ms, end_ms = EXCLUDED.end_ms,
                               completed_at = now()",
                        &[&unit, &seg, &from, &to],
                    )
                })?;
                mark.b = WINDOW_DONE;
            }
            self.save(mark.clone())?;
        }
        Ok(rep)
    }
}
