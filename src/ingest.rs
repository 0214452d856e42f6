//! Log ingest (CSV replay): ingest a historical CSV into the store as fast as possible.
//!
//! Two layouts (`layout`, detected from the header by default). Wide: one row = one time
//! stamp; each mapped column becomes one sample of its tag. Long (`tag,time,value[,status]`):
//! one row = one sample of one tag; consecutive rows with the same time form one wide row, so
//! a long file stores what its wide equivalent stores (`ingest::long`). Rows are inserted in
//! large transactions with `INSERT OR IGNORE`, so replaying the same file twice adds nothing,
//! and a replay killed half-way (kill -9) can simply be run again: everything committed stays,
//! nothing is duplicated. Malformed rows are reported by line number and skipped or rejected
//! according to `on_malformed`.
//!
//! Time stamps (`time_format`): `iso8601` — `2024-03-01T12:00:00Z`, with a UTC offset
//! (`+01:00`), fractional seconds allowed, a space instead of `T` accepted; a time without an
//! offset is local time of `time_zone` (default `UTC`; see `crate::time::LocalClock` for the
//! spring gap and the repeated autumn hour); an offset in the data always wins. `epoch_s` —
//! Unix seconds, fractions allowed. `epoch_ms` — Unix ms. A row whose time is not later than
//! the previous row's (wide) or the same tag's previous row's (long) is malformed (duplicate
//! or backwards), and so is a row stamped later than the wall clock plus `max_future_s`, and a
//! local time the zone skips; each kind is counted on its own in the report
//! (`rows_out_of_order`, `rows_implausible_time`, `rows_nonexistent_time`).
//! An empty cell means "no value": that tag gets no sample at that time; the row is fine.
//!
//! This module must not run the detector or know about Modbus; it only turns CSV into samples.

mod config;
mod long;
mod plan;
mod sink;

pub use config::{Layout, OnMalformed, ReplayConfig};
pub use plan::{plan_columns, ColumnPlan, LongFields};

use crate::quality::{QualityConfig, QualityCounts};
use crate::store::{Store, StoreError};
use crate::time::{fmt_ms, LocalClock, StampError, TimeFormat};
use plan::{csv_reader, plan_from_reader};
use serde::Serialize;
use sink::{Cell, Column, RowProblem, RowProblemKind, Sink};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How replay shows progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Progress {
    /// A bar if stderr is a terminal, otherwise periodic log lines.
    #[default]
    Auto,
    Bar,
    /// `tracing::info!` every few seconds.
    Log,
    Silent,
}

/// One malformed row.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct MalformedRow {
    /// 1-based line number in the file (the header is line 1).
    pub line: u64,
    pub reason: String,
}

impl std::fmt::Display for MalformedRow {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "line {}: {}", self.line, self.reason)
    }
}

/// What a replay did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ReplayReport {
    pub file: PathBuf,
    /// Data rows read (excluding the header), well-formed or not.
    pub rows_read: u64,
    pub rows_malformed: u64,
    /// Of the malformed rows: time equal to or before the previous row's (not stored).
    pub rows_out_of_order: u64,
    /// Of the malformed rows: time implausibly far in the future (not stored).
    pub rows_implausible_time: u64,
    /// Of the malformed rows: a local time that does not exist in `replay.time_zone` (the
    /// spring gap), not stored.
    pub rows_nonexistent_time: u64,
    /// Samples that were new.
    pub samples_inserted: u64,
    /// Samples already in the database (an earlier replay of the same data).
    pub samples_present: u64,
    /// The first `max_reported` malformed rows.
    pub malformed: Vec<MalformedRow>,
    /// Cells that are not a finite number (text, NaN, ±inf): stored with quality `bad`, the
    /// row's other cells kept. Counted in `quality.bad`; the first `max_reported` listed.
    pub bad_cells: Vec<MalformedRow>,
    /// Stored samples per quality code (see `crate::quality`).
    pub quality: QualityCounts,
    /// Archive mode (`[replay] archive`): chunks written.
    pub chunks_archived: u64,
    pub gaps_recorded: u64,
    /// Column → tag actually used.
    pub columns: Vec<(String, String)>,
    /// Header columns that were not replayed.
    pub ignored_columns: Vec<String>,
    pub first_t_ms: Option<i64>,
    pub last_t_ms: Option<i64>,
    pub elapsed_s: f64,
}

impl ReplayReport {
    /// Samples processed per second of wall time (new + already present).
    pub fn samples_per_s(&self) -> f64 {
        let n = (self.samples_inserted + self.samples_present) as f64;
        if self.elapsed_s > 0.0 {
            n / self.elapsed_s
        } else {
            0.0
        }
    }
}

/// Replay errors. Data committed before the error stays committed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error("cannot read {path}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot read CSV header: {message}")]
    Header { path: PathBuf, message: String },
    #[error("{path}: column '{column}' not found in the header (columns: {available})")]
    MissingColumn {
        path: PathBuf,
        column: String,
        available: String,
    },
    #[error("{path}: no data columns to replay (ignored: {ignored}; map them in [replay.columns], or name the CSV columns after signals such as n1_rpm)")]
    NoColumns { path: PathBuf, ignored: String },
    #[error(
        "{path}: tag '{tag}' of [replay.columns] never occurs in the tag field (tags: {available})"
    )]
    MissingTag {
        path: PathBuf,
        tag: String,
        available: String,
    },
    #[error("invalid [replay] config: {0}")]
    Config(String),
    #[error("{path}: line {line}: {reason} (on_malformed = \"stop\"; {committed} samples before it are committed)")]
    Malformed {
        path: PathBuf,
        line: u64,
        reason: String,
        committed: u64,
        report: Box<ReplayReport>,
    },
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Replays one CSV file into `store` with the default bad-value policy
/// (`QualityConfig::default()`); see [`replay_file_checked`].
pub fn replay_file(
    store: &mut Store,
    cfg: &ReplayConfig,
    path: &Path,
    progress: Progress,
) -> Result<ReplayReport, ReplayError> {
    replay_file_checked(store, cfg, &QualityConfig::default(), path, progress)
}

/// Replays one CSV file into `store`. See the module comment for layouts, formats and policy;
/// every value is classified by `quality` (`crate::quality`) and stored with its code.
pub fn replay_file_checked(
    store: &mut Store,
    cfg: &ReplayConfig,
    quality: &QualityConfig,
    path: &Path,
    progress: Progress,
) -> Result<ReplayReport, ReplayError> {
    let mut problems = cfg.validate();
    problems.extend(quality.validate());
    if !problems.is_empty() {
        return Err(ReplayError::Config(
            problems
                .iter()
                .map(|p| p.to_string())
                .collect::<Vec<_>>()
                .join("; "),
        ));
    }
    let clock = LocalClock::new(&cfg.time_zone)
        .map_err(|e| ReplayError::Config(format!("replay.time_zone: {e}")))?;
    let mut units = cfg
        .column_units()
        .map_err(|e| ReplayError::Config(format!("replay.units.{}: {}", e.key, e.reason)))?;
    if units.needs_fuel() {
        let fuel = cfg.fuel.ok_or_else(|| {
            ReplayError::Config(
                "replay.units: a fuel flow by volume is converted with the engine file's fuel, \
                 and none was given ([plant] engine_model)"
                    .into(),
            )
        })?;
        units
            .bind_fuel(&fuel)
            .map_err(|e| ReplayError::Config(format!("replay.units.{}: {}", e.key, e.reason)))?;
    }
    let started = Instant::now();
    let io_err = |source| ReplayError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io_err)?;
    let file_len = file.metadata().map_err(io_err)?.len();
    let mut rdr = csv_reader(cfg, file, 1 << 20);
    let plan = plan_from_reader(&mut rdr, cfg, path)?;
    let mut sink = Sink::new(store, cfg, quality, path, file_len, progress);
    sink.units = units;
    sink.report.ignored_columns = plan.ignored.clone();
    let reader = Reader {
        rdr,
        cfg,
        n_fields: plan.n_fields,
        time_index: plan.time_index,
        latest_ok_ms: latest_plausible_ms(cfg.max_future_s),
    };
    match plan.long {
        Some(fields) => long::replay_long(sink, reader, fields, clock, started),
        None => {
            for (index, name, info) in plan.mapped {
                sink.add_column(index, name, &info)?;
            }
            replay_wide(sink, reader, clock, started)
        }
    }
}

/// The CSV being replayed and what every row is checked against.
struct Reader<'a> {
    rdr: csv::Reader<std::io::BufReader<std::fs::File>>,
    cfg: &'a ReplayConfig,
    n_fields: usize,
    time_index: usize,
    latest_ok_ms: i64,
}

/// The next record of `reader` into `record`: `Ok(Some(line))`, `Ok(None)` at the end. A
/// structural CSV error is reported to `sink` as a malformed row (and the next record read);
/// an I/O error ends the replay after committing what came before.
fn next_record(
    reader: &mut Reader<'_>,
    sink: &mut Sink<'_>,
    record: &mut csv::ByteRecord,
) -> Result<Option<u64>, ReplayError> {
    loop {
        let line_hint = record.position().map(|p| p.line()).unwrap_or(1) + 1;
        match reader.rdr.read_byte_record(record) {
            Ok(true) => {
                sink.report.rows_read += 1;
                return Ok(Some(record.position().map(|p| p.line()).unwrap_or(0)));
            }
            Ok(false) => return Ok(None),
            Err(e) => {
                // Invalid UTF-8 cannot happen with byte records; this is an I/O error or a
                // structural CSV error. Report it as a malformed row at its line.
                let line = e.position().map(|p| p.line()).unwrap_or(line_hint);
                if let csv::ErrorKind::Io(_) = e.kind() {
                    return Err(sink.io_error(&e));
                }
                sink.report.rows_read += 1;
                sink.reject(line, RowProblem::other(format!("CSV error: {e}")))?;
            }
        }
    }
}

/// The wide layout: one row per time stamp, one replayed column per tag.
fn replay_wide(
    mut sink: Sink<'_>,
    mut reader: Reader<'_>,
    mut clock: LocalClock,
    started: Instant,
) -> Result<ReplayReport, ReplayError> {
    let mut prev_t: Option<i64> = None;
    let mut record = csv::ByteRecord::new();
    let mut cells: Vec<Cell> = Vec::with_capacity(sink.columns.len());
    while let Some(line) = next_record(&mut reader, &mut sink, &mut record)? {
        let parsed = field_count(&record, reader.n_fields)
            .and_then(|()| row_time(&record, &reader, &mut clock, prev_t))
            .and_then(|t| parse_cells(&record, &sink.columns, t, &mut cells).map(|()| t));
        match parsed {
            Ok(t) => {
                prev_t = Some(t);
                sink.row(t, line, &mut cells);
            }
            Err(problem) => {
                cells.clear();
                sink.reject(line, problem)?;
            }
        }
        sink.after_row(|| record.position().map(|p| p.byte()).unwrap_or(0))?;
    }
    sink.finish(started)
}

/// The latest plausible time stamp: the wall clock plus `max_future_s`, in epoch ms.
fn latest_plausible_ms(max_future_s: f64) -> i64 {
    let now_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
        .unwrap_or(0);
    now_ms.saturating_add((max_future_s * 1000.0).round() as i64)
}

/// A row with another number of fields than the header is malformed.
fn field_count(rec: &csv::ByteRecord, n_fields: usize) -> Result<(), RowProblem> {
    if rec.len() != n_fields {
        return Err(RowProblem::other(format!(
            "expected {n_fields} fields, found {} (truncated or extra delimiter?)",
            rec.len()
        )));
    }
    Ok(())
}

/// The row's time, placed by `clock`, checked against the wall clock and against `prev_t`
/// (the previous time of the same sequence: the file's for wide, the tag's for long).
fn row_time(
    rec: &csv::ByteRecord,
    reader: &Reader<'_>,
    clock: &mut LocalClock,
    prev_t: Option<i64>,
) -> Result<i64, RowProblem> {
    let fmt = reader.cfg.time_format;
    let t_raw = rec.get(reader.time_index).unwrap_or_default();
    let t = clock.read(t_raw, fmt).map_err(|e| match e {
        StampError::Unreadable(e) => RowProblem::other(format!(
            "time '{}' is not {}: {e}",
            String::from_utf8_lossy(t_raw),
            match fmt {
                TimeFormat::Iso8601 => "ISO 8601",
                TimeFormat::EpochS => "epoch seconds",
                TimeFormat::EpochMs => "epoch milliseconds",
            }
        )),
        StampError::Nonexistent(reason) => RowProblem {
            kind: RowProblemKind::Nonexistent,
            reason,
        },
    })?;
    if t > reader.latest_ok_ms {
        return Err(RowProblem {
            kind: RowProblemKind::Implausible,
            reason: format!(
                "time {} is implausible: later than the clock now plus replay.max_future_s",
                fmt_ms(t)
            ),
        });
    }
    if let Some(p) = prev_t {
        if t == p {
            return Err(RowProblem {
                kind: RowProblemKind::OutOfOrder,
                reason: format!("duplicate time {} (same as the previous row)", fmt_ms(t)),
            });
        }
        if t < p {
            return Err(RowProblem {
                kind: RowProblemKind::OutOfOrder,
                reason: format!(
                    "time {} goes backwards (previous row {})",
                    fmt_ms(t),
                    fmt_ms(p)
                ),
            });
        }
    }
    Ok(t)
}

/// One value cell: `None` if empty (no sample), else the value or why it is not a finite
/// number.
fn cell_value(raw: &[u8], column: &str) -> Option<Result<f64, String>> {
    let s = raw.trim_ascii();
    if s.is_empty() {
        return None;
    }
    let parsed = std::str::from_utf8(s)
        .ok()
        .and_then(|s| s.parse::<f64>().ok());
    Some(match parsed {
        None => Err(format!(
            "column '{column}': '{}' is not a number",
            String::from_utf8_lossy(&raw[..raw.len().min(80)])
        )),
        Some(v) if !v.is_finite() => {
            Err(format!("column '{column}': '{v}' is not a finite number"))
        }
        Some(v) => Ok(v),
    })
}

/// Parses a wide row's value cells into `out`.
fn parse_cells(
    rec: &csv::ByteRecord,
    columns: &[Column],
    t: i64,
    out: &mut Vec<Cell>,
) -> Result<(), RowProblem> {
    // A bad cell (text, NaN, ±inf) is stored flagged `bad` with value 0 (SQLite cannot hold
    // NaN); it never discards the good cells of its row. A row with no good cell at all is
    // malformed (reported, nothing stored).
    let first = out.len();
    let mut any_good = false;
    for (column, c) in columns.iter().enumerate() {
        let Some(parsed) = cell_value(rec.get(c.index).unwrap_or_default(), &c.name) else {
            continue;
        };
        any_good |= parsed.is_ok();
        out.push(Cell::new(column, c.tag, t, parsed));
    }
    if !any_good && out.len() > first {
        let reason = out[first].problem.clone().unwrap_or_default();
        out.truncate(first);
        return Err(RowProblem::other(reason));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
