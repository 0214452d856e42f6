//! The long layout of a historian export: one row per tag and time stamp,
//! `tag,time,value[,status]` (field order free, names case-insensitive).
//!
//! Each tag is its own sequence: its times must go forward (a duplicate or backwards time of a
//! tag is a malformed row, as a wide row's would be), and local times are placed by a clock of
//! its own, so a file sorted by tag and then time replays as well as one sorted by time. Rows
//! of different tags with the same time that follow one another form one wide row before they
//! reach the sink (the gap detector and the stuck check's n1 reference see what they would see
//! in the equivalent wide file). A name in the tag field maps to a tag as a wide header does
//! (`[replay.columns]`, or signal names); rows of other tags are ignored (listed in the report).
//! A value that is not a finite number, or a status other than a good one (empty, `good`,
//! `ok`, `valid`, `192`, `0xC0`), is stored flagged `bad` like a bad wide cell.
//!
//! Must not write to the store itself or know the wide layout: rows go through `Sink`.

use super::plan::{long_tag, LongFields};
use super::sink::{Cell, RowProblem, Sink};
use super::{field_count, next_record, row_time, OnMalformed, Reader, ReplayError, ReplayReport};
use crate::quality::Quality;
use crate::time::LocalClock;
use std::collections::HashMap;
use std::time::Instant;

/// A replayed tag of a long file.
struct TagState {
    /// Index in the sink's columns.
    column: usize,
    clock: LocalClock,
    prev_t: Option<i64>,
}

/// Rows of the same time that follow one another: one wide row.
#[derive(Default)]
struct Group {
    t: Option<i64>,
    line: u64,
    cells: Vec<Cell>,
}

impl Group {
    /// Hands the gathered row to the sink.
    fn emit(&mut self, sink: &mut Sink<'_>) {
        if let Some(t) = self.t.take() {
            sink.row(t, self.line, &mut self.cells);
        }
    }
}

/// Replays a long file; `zone` is the clock every tag starts from.
pub(super) fn replay_long(
    mut sink: Sink<'_>,
    mut reader: Reader<'_>,
    fields: LongFields,
    zone: LocalClock,
    started: Instant,
) -> Result<ReplayReport, ReplayError> {
    let mut tags: HashMap<Vec<u8>, Option<TagState>> = HashMap::new();
    let mut group = Group::default();
    let mut record = csv::ByteRecord::new();
    let stop = reader.cfg.on_malformed == OnMalformed::Stop;
    loop {
        let line = match next_record(&mut reader, &mut sink, &mut record) {
            Ok(Some(line)) => line,
            Ok(None) => break,
            Err(e) => {
                group.emit(&mut sink);
                return Err(e);
            }
        };
        let state = match tag_state(&mut tags, &mut sink, &record, fields, &reader, &zone) {
            Ok(Some(state)) => state,
            Ok(None) => continue,
            Err(Ok(problem)) => {
                if stop {
                    group.emit(&mut sink);
                }
                sink.reject(line, problem)?;
                continue;
            }
            Err(Err(e)) => return Err(e),
        };
        let t = match row_time(&record, &reader, &mut state.clock, state.prev_t) {
            Ok(t) => t,
            Err(problem) => {
                if stop {
                    group.emit(&mut sink);
                }
                sink.reject(line, problem)?;
                continue;
            }
        };
        state.prev_t = Some(t);
        if group.t != Some(t) {
            group.emit(&mut sink);
            group.t = Some(t);
            group.line = line;
        }
        if let Some(cell) = long_cell(&record, fields, state.column, &sink, t) {
            group.cells.push(cell);
        }
        sink.after_row(|| record.position().map(|p| p.byte()).unwrap_or(0))?;
    }
    group.emit(&mut sink);
    sink.finish(started)
}

/// The state of the row's tag (created on its first row), `None` if the tag is not replayed;
/// `Err(Ok(_))` if the row is malformed, `Err(Err(_))` if its tag cannot be created.
fn tag_state<'t>(
    tags: &'t mut HashMap<Vec<u8>, Option<TagState>>,
    sink: &mut Sink<'_>,
    record: &csv::ByteRecord,
    fields: LongFields,
    reader: &Reader<'_>,
    zone: &LocalClock,
) -> Result<Option<&'t mut TagState>, Result<RowProblem, ReplayError>> {
    field_count(record, reader.n_fields).map_err(Ok)?;
    let raw = record.get(fields.tag).unwrap_or_default().trim_ascii();
    if raw.is_empty() {
        return Err(Ok(RowProblem::other("empty tag name".into())));
    }
    if !tags.contains_key(raw) {
        let name = String::from_utf8_lossy(raw).into_owned();
        let state = match long_tag(reader.cfg, &name) {
            Some(info) => Some(TagState {
                column: sink.add_column(0, name, &info).map_err(Err)?,
                clock: zone.clone(),
                prev_t: None,
            }),
            None => {
                sink.report.ignored_columns.push(name);
                None
            }
        };
        tags.insert(raw.to_vec(), state);
    }
    Ok(tags.get_mut(raw).and_then(Option::as_mut))
}

/// Whether a status field says the value is good.
fn status_is_good(raw: &[u8]) -> bool {
    let s = raw.trim_ascii();
    s.is_empty()
        || ["good", "ok", "valid", "192", "0xc0"]
            .iter()
            .any(|g| s.eq_ignore_ascii_case(g.as_bytes()))
}

/// The row's sample, or `None` for an empty value (no sample; the row is fine).
fn long_cell(
    record: &csv::ByteRecord,
    fields: LongFields,
    column: usize,
    sink: &Sink<'_>,
    t: i64,
) -> Option<Cell> {
    let c = &sink.columns[column];
    let parsed = super::cell_value(record.get(fields.value).unwrap_or_default(), &c.name)?;
    let status = fields
        .status
        .and_then(|i| record.get(i))
        .unwrap_or_default();
    let mut cell = Cell::new(column, c.tag, t, parsed);
    if cell.problem.is_none() && !status_is_good(status) {
        // A bad status keeps its value, flagged.
        cell.sample.quality = Quality::Bad;
        cell.problem = Some(format!(
            "column '{}': status '{}' is not good",
            c.name,
            String::from_utf8_lossy(&status[..status.len().min(80)]).trim()
        ));
    }
    Some(cell)
}
