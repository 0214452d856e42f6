//! Log ingest (CSV replay): ingest a historical CSV into the store as fast as possible.
//!
//! One row = one time stamp; each mapped column becomes one sample of its tag. Rows are
//! inserted in large transactions with `INSERT OR IGNORE`, so replaying the same file twice
//! adds nothing, and a replay killed half-way (kill -9) can simply be run again: everything
//! committed stays, nothing is duplicated. Malformed rows are reported by line number and
//! skipped or rejected according to `on_malformed`.
//!
//! Time stamps (`time_format`): `iso8601` — `2024-03-01T12:00:00Z`, with a UTC offset
//! (`+01:00`), fractional seconds allowed, a space instead of `T` accepted; a time without an
//! offset is taken as UTC. `epoch_s` — Unix seconds, fractions allowed. `epoch_ms` — Unix ms.
//! A row whose time is not later than the previous row's is malformed (duplicate or backwards),
//! and so is a row stamped later than the wall clock plus `max_future_s`; both kinds are
//! counted on their own in the report (`rows_out_of_order`, `rows_implausible_time`).
//! An empty cell means "no value": that tag gets no sample at that time; the row is fine.
//!
//! This module must not run the detector or know about Modbus; it only turns CSV into samples.

use crate::config_problem::{check_range, Bounds, ConfigProblem};
use crate::quality::{Point, Quality, QualityConfig, QualityCounts, SpikeFilter, ValueChecker};
use crate::signals::Signal;
use crate::store::{Gap, Sample, Store, StoreError, TagId, TagInfo};
use crate::time::{fmt_ms, parse_time, TimeFormat};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// What to do with a malformed row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum OnMalformed {
    /// Skip it, count it, report the first `max_reported` (default).
    #[default]
    Skip,
    /// Stop with an error naming the line; rows before it stay committed.
    Stop,
}

/// `[replay]` section.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReplayConfig {
    /// Name of the time column. Default `time`.
    pub time_column: String,
    /// `iso8601` (default), `epoch_s` or `epoch_ms`.
    pub time_format: TimeFormat,
    /// Field delimiter, one ASCII character. Default `,`.
    pub delimiter: String,
    /// CSV column name → tag. The tag is a signal name (`n1`, `n1_rpm`, `fuel_flow`, …; the tag
    /// is then named by the signal's column name, e.g. `n1_rpm`) or any other tag name. Empty
    /// (default): every column whose header is a signal name is replayed, others are ignored.
    pub columns: BTreeMap<String, String>,
    /// `skip` (default) or `stop`.
    pub on_malformed: OnMalformed,
    /// How many malformed rows are listed in the report (all are counted). Default 20.
    pub max_reported: usize,
    /// Samples per transaction. Default 200 000.
    pub transaction_samples: usize,
    /// Consecutive rows further apart than this (seconds) record a gap. 0 = off. Default 10.
    pub gap_threshold_s: f64,
    /// A row stamped more than this many seconds after the wall clock is implausible: it is
    /// reported and not stored (one row dated +1000 years used to make every later row "go
    /// backwards"). Default 86 400 (one day, room for a clock set a little ahead).
    pub max_future_s: f64,
}

impl Default for ReplayConfig {
    fn default() -> Self {
        ReplayConfig {
            time_column: "time".into(),
            time_format: TimeFormat::Iso8601,
            delimiter: ",".into(),
            columns: BTreeMap::new(),
            on_malformed: OnMalformed::Skip,
            max_reported: 20,
            transaction_samples: 200_000,
            gap_threshold_s: 10.0,
            max_future_s: 86_400.0,
        }
    }
}

impl ReplayConfig {
    /// Problems with this section; keys are prefixed `replay.`.
    pub fn validate(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        if self.time_column.trim().is_empty() {
            p.push(ConfigProblem::new(
                "replay.time_column",
                "must not be empty",
            ));
        }
        if self.delimiter_byte().is_none() {
            p.push(ConfigProblem::new(
                "replay.delimiter",
                format!(
                    "must be exactly one ASCII character (got {:?})",
                    self.delimiter
                ),
            ));
        }
        check_range(
            &mut p,
            "replay.transaction_samples",
            self.transaction_samples as u64,
            Bounds {
                lo: 1,
                hi: 5_000_000,
                unit: "",
                why: "samples held in memory per transaction",
            },
        );
        check_range(
            &mut p,
            "replay.max_reported",
            self.max_reported as u64,
            Bounds {
                lo: 0,
                hi: 1_000_000,
                unit: "",
                why: "malformed rows kept in the report",
            },
        );
        if !self.gap_threshold_s.is_finite() || self.gap_threshold_s < 0.0 {
            p.push(ConfigProblem::new(
                "replay.gap_threshold_s",
                "must be a number >= 0 (0 turns gap detection off)",
            ));
        }
        if !self.max_future_s.is_finite() || !(0.0..=1e10).contains(&self.max_future_s) {
            p.push(ConfigProblem::new(
                "replay.max_future_s",
                "must be a number of seconds from 0 to 1e10",
            ));
        }
        for (col, tag) in &self.columns {
            if col.trim().is_empty() {
                p.push(ConfigProblem::new("replay.columns", "empty column name"));
            }
            if tag.trim().is_empty() {
                p.push(ConfigProblem::new(
                    format!("replay.columns.{col}"),
                    "tag name must not be empty",
                ));
            }
            if col == &self.time_column {
                p.push(ConfigProblem::new(
                    format!("replay.columns.{col}"),
                    "the time column cannot also be a data column",
                ));
            }
        }
        let mut seen: BTreeMap<String, &str> = BTreeMap::new();
        for (col, tag) in &self.columns {
            let info = tag_for_mapping(tag);
            if let Some(prev) = seen.insert(info.name.clone(), col) {
                p.push(ConfigProblem::new(
                    format!("replay.columns.{col}"),
                    format!("tag '{}' is already fed by column '{prev}'", info.name),
                ));
            }
        }
        p
    }

    /// The delimiter as a byte, if valid.
    pub fn delimiter_byte(&self) -> Option<u8> {
        let d = if self.delimiter == "\\t" {
            "\t"
        } else {
            &self.delimiter
        };
        match d.as_bytes() {
            [b] if b.is_ascii() => Some(*b),
            _ => None,
        }
    }
}

/// The tag a mapping value names: a signal's canonical tag, or a plain tag.
fn tag_for_mapping(value: &str) -> TagInfo {
    match value.parse::<Signal>() {
        Ok(sig) => TagInfo::for_signal(sig),
        Err(_) => TagInfo {
            name: value.trim().to_string(),
            unit: String::new(),
            signal: None,
        },
    }
}

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

/// Which CSV columns a replay reads, decided from the header alone (no database needed).
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnPlan {
    /// Number of header fields.
    pub n_fields: usize,
    /// Index of the time column.
    pub time_index: usize,
    /// (column index, column name, tag) for every replayed column.
    pub mapped: Vec<(usize, String, TagInfo)>,
    /// Header columns that are not replayed (neither the time column nor mapped).
    pub ignored: Vec<String>,
}

impl ColumnPlan {
    /// Whether some replayed column feeds the tag named `tag`.
    pub fn feeds_tag(&self, tag: &str) -> bool {
        self.mapped.iter().any(|(_, _, info)| info.name == tag)
    }
}

/// Reads only the header of `path` and decides which columns a replay would use. Fails like
/// [`replay_file`] would (missing file, missing time or mapped column, nothing to replay), so a
/// caller can check every log before it creates a database.
pub fn plan_columns(cfg: &ReplayConfig, path: &Path) -> Result<ColumnPlan, ReplayError> {
    let file = std::fs::File::open(path).map_err(|source| ReplayError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut rdr = csv::ReaderBuilder::new()
        .delimiter(cfg.delimiter_byte().unwrap_or(b','))
        .has_headers(true)
        .flexible(true)
        // `\n` alone ends a record; a `\r` before it is trimmed with the field. With csv's
        // default CRLF handling every line number of a CRLF file came out one too low.
        .terminator(csv::Terminator::Any(b'\n'))
        .from_reader(std::io::BufReader::new(file));
    plan_from_reader(&mut rdr, cfg, path)
}

fn plan_from_reader<R: std::io::Read>(
    rdr: &mut csv::Reader<R>,
    cfg: &ReplayConfig,
    path: &Path,
) -> Result<ColumnPlan, ReplayError> {
    let header = rdr
        .byte_headers()
        .map_err(|e| ReplayError::Header {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?
        .clone();
    let names: Vec<String> = header
        .iter()
        .map(|h| String::from_utf8_lossy(h).trim().to_string())
        .collect();
    let available = names.join(", ");
    let find = |col: &str| names.iter().position(|n| n == col);
    let time_idx = find(&cfg.time_column).ok_or_else(|| ReplayError::MissingColumn {
        path: path.to_path_buf(),
        column: cfg.time_column.clone(),
        available: available.clone(),
    })?;
    let mut ignored = Vec::new();
    let mut mapping: Vec<(usize, String, TagInfo)> = Vec::new();
    if cfg.columns.is_empty() {
        for (i, n) in names.iter().enumerate() {
            if i == time_idx {
                continue;
            }
            match n.parse::<Signal>() {
                Ok(sig) => mapping.push((i, n.clone(), TagInfo::for_signal(sig))),
                Err(_) => ignored.push(n.clone()),
            }
        }
    } else {
        for (col, tag) in &cfg.columns {
            let i = find(col).ok_or_else(|| ReplayError::MissingColumn {
                path: path.to_path_buf(),
                column: col.clone(),
                available: available.clone(),
            })?;
            mapping.push((i, col.clone(), tag_for_mapping(tag)));
        }
        for (i, n) in names.iter().enumerate() {
            if i != time_idx && !mapping.iter().any(|(j, _, _)| *j == i) {
                ignored.push(n.clone());
            }
        }
    }
    if mapping.is_empty() {
        return Err(ReplayError::NoColumns {
            path: path.to_path_buf(),
            ignored: ignored.join(", "),
        });
    }
    Ok(ColumnPlan {
        n_fields: names.len(),
        time_index: time_idx,
        mapped: mapping,
        ignored,
    })
}

struct Column {
    index: usize,
    name: String,
    tag: TagId,
    signal: Option<Signal>,
}

/// The bad-value policy's state for one column.
struct ColumnQuality {
    checker: ValueChecker,
    spikes: SpikeFilter,
}

/// A parsed cell: which column, and its sample (quality `Good`, or `Bad` if not a number).
#[derive(Debug, Clone, PartialEq)]
struct Cell {
    column: usize,
    sample: Sample,
    /// Why the cell is bad (not a finite number).
    problem: Option<String>,
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

/// Replays one CSV file into `store`. See the module comment for formats and policy; every
/// value is classified by `quality` (`crate::quality`) and stored with its code.
// TODO(issue 27): split into named stages.
#[allow(clippy::too_many_lines)]
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
    let started = Instant::now();
    let io_err = |source| ReplayError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io_err)?;
    let file_len = file.metadata().map_err(io_err)?.len();
    let mut rdr = csv::ReaderBuilder::new()
        .delimiter(cfg.delimiter_byte().unwrap_or(b','))
        .has_headers(true)
        .flexible(true)
        // `\n` alone ends a record; a `\r` before it is trimmed with the field. With csv's
        // default CRLF handling every line number of a CRLF file came out one too low.
        .terminator(csv::Terminator::Any(b'\n'))
        .buffer_capacity(1 << 20)
        .from_reader(std::io::BufReader::with_capacity(1 << 20, file));
    let plan = plan_from_reader(&mut rdr, cfg, path)?;
    let n_fields = plan.n_fields;
    let time_idx = plan.time_index;
    let mut report = ReplayReport {
        file: path.to_path_buf(),
        ignored_columns: plan.ignored.clone(),
        ..ReplayReport::default()
    };
    let mapping = plan.mapped;
    let mut columns = Vec::with_capacity(mapping.len());
    let mut col_quality = Vec::with_capacity(mapping.len());
    for (index, name, info) in mapping {
        let tag = store.ensure_tag(&info)?;
        report.columns.push((name.clone(), info.name.clone()));
        let checker = quality.checker(&[info.name.as_str(), name.as_str()], info.signal);
        col_quality.push(ColumnQuality {
            spikes: SpikeFilter::new(checker.limits()),
            checker,
        });
        columns.push(Column {
            index,
            name,
            tag,
            signal: info.signal,
        });
    }
    let n1_column = columns.iter().position(|c| c.signal == Some(Signal::N1));
    let gap_source = format!(
        "replay:{}",
        path.file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default()
    );
    let gap_threshold_ms = (cfg.gap_threshold_s * 1000.0).round() as i64;
    let latest_ok_ms = latest_plausible_ms(cfg.max_future_s);

    let bar = make_bar(progress, file_len);
    let log_progress =
        matches!(progress, Progress::Log) || (matches!(progress, Progress::Auto) && bar.is_none());
    let mut last_log = Instant::now();

    let mut batch: Vec<Sample> = Vec::with_capacity(cfg.transaction_samples + columns.len());
    let mut gaps: Vec<Gap> = Vec::new();
    let mut prev_t: Option<i64> = None;
    let mut record = csv::ByteRecord::new();
    let mut row_samples: Vec<Cell> = Vec::with_capacity(columns.len());

    loop {
        let line_hint = record.position().map(|p| p.line()).unwrap_or(1) + 1;
        let more = match rdr.read_byte_record(&mut record) {
            Ok(m) => m,
            Err(e) => {
                // Invalid UTF-8 cannot happen with byte records; this is an I/O error or a
                // structural CSV error. Report it as a malformed row at its line.
                let line = e.position().map(|p| p.line()).unwrap_or(line_hint);
                if let csv::ErrorKind::Io(_) = e.kind() {
                    drain_held(&columns, &mut col_quality, &mut batch, &mut report);
                    flush(store, &mut batch, &mut gaps, &mut report)?;
                    return Err(ReplayError::Io {
                        path: path.to_path_buf(),
                        source: std::io::Error::other(e.to_string()),
                    });
                }
                report.rows_read += 1;
                let reason = format!("CSV error: {e}");
                if cfg.on_malformed == OnMalformed::Stop {
                    drain_held(&columns, &mut col_quality, &mut batch, &mut report);
                }
                malformed(
                    store,
                    cfg,
                    path,
                    &mut batch,
                    &mut gaps,
                    &mut report,
                    line,
                    reason,
                )?;
                continue;
            }
        };
        if !more {
            break;
        }
        report.rows_read += 1;
        let line = record.position().map(|p| p.line()).unwrap_or(0);
        match parse_row(
            &record,
            n_fields,
            time_idx,
            cfg.time_format,
            &columns,
            prev_t,
            latest_ok_ms,
            &mut row_samples,
        ) {
            Ok(t) => {
                if let Some(p) = prev_t {
                    if gap_threshold_ms > 0 && t - p > gap_threshold_ms {
                        gaps.push(Gap {
                            start_ms: p,
                            end_ms: t,
                            source: gap_source.clone(),
                            reason: format!(
                                "no rows for {:.1} s (lines {} and {})",
                                (t - p) as f64 / 1000.0,
                                line.saturating_sub(1),
                                line
                            ),
                        });
                    }
                }
                prev_t = Some(t);
                report.first_t_ms.get_or_insert(t);
                report.last_t_ms = Some(t);
                let n1 = n1_column.and_then(|i| {
                    row_samples
                        .iter()
                        .find(|c| c.column == i && c.sample.quality == Quality::Good)
                        .map(|c| c.sample.value)
                        .filter(|v| {
                            crate::quality::classify_value(
                                *v,
                                col_quality[i].checker.limits().as_ref(),
                            ) == Quality::Good
                        })
                });
                for cell in row_samples.drain(..) {
                    let cq = &mut col_quality[cell.column];
                    let mut s = cell.sample;
                    if let Some(reason) = cell.problem {
                        if report.bad_cells.len() < cfg.max_reported {
                            report.bad_cells.push(MalformedRow { line, reason });
                        }
                    } else {
                        s.quality = cq.checker.check(t, s.value, n1);
                        if s.quality == Quality::OutOfRange
                            && report.bad_cells.len() < cfg.max_reported
                        {
                            report.bad_cells.push(MalformedRow {
                                line,
                                reason: format!(
                                    "column '{}': {} is outside the plausible range",
                                    columns[cell.column].name, s.value
                                ),
                            });
                        }
                    }
                    let p = Point {
                        t_ms: s.t_ms,
                        value: s.value,
                        quality: s.quality,
                    };
                    if let Some(out) = cq.spikes.push(p) {
                        report.quality.add(out.quality);
                        batch.push(Sample {
                            tag: s.tag,
                            t_ms: out.t_ms,
                            value: out.value,
                            quality: out.quality,
                        });
                    }
                }
            }
            Err(RowProblem { kind, reason }) => {
                row_samples.clear();
                match kind {
                    RowProblemKind::OutOfOrder => report.rows_out_of_order += 1,
                    RowProblemKind::Implausible => report.rows_implausible_time += 1,
                    RowProblemKind::Other => {}
                }
                if cfg.on_malformed == OnMalformed::Stop {
                    drain_held(&columns, &mut col_quality, &mut batch, &mut report);
                }
                malformed(
                    store,
                    cfg,
                    path,
                    &mut batch,
                    &mut gaps,
                    &mut report,
                    line,
                    reason,
                )?;
            }
        }
        if batch.len() >= cfg.transaction_samples {
            flush(store, &mut batch, &mut gaps, &mut report)?;
            let pos = record.position().map(|p| p.byte()).unwrap_or(0);
            if let Some(b) = &bar {
                b.set_position(pos);
            }
            if log_progress && last_log.elapsed() >= Duration::from_secs(5) {
                last_log = Instant::now();
                tracing::info!(
                    file = %path.display(),
                    percent = format!("{:.1}", 100.0 * pos as f64 / file_len.max(1) as f64),
                    rows = report.rows_read,
                    inserted = report.samples_inserted,
                    present = report.samples_present,
                    malformed = report.rows_malformed,
                    "replay progress"
                );
            }
        }
    }
    drain_held(&columns, &mut col_quality, &mut batch, &mut report);
    flush(store, &mut batch, &mut gaps, &mut report)?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    report.elapsed_s = started.elapsed().as_secs_f64();
    Ok(report)
}

/// Moves the sample each spike filter holds back into `batch` (end of file, or a stop).
fn drain_held(
    columns: &[Column],
    col_quality: &mut [ColumnQuality],
    batch: &mut Vec<Sample>,
    report: &mut ReplayReport,
) {
    for (c, cq) in columns.iter().zip(col_quality.iter_mut()) {
        if let Some(out) = cq.spikes.finish() {
            report.quality.add(out.quality);
            batch.push(Sample {
                tag: c.tag,
                t_ms: out.t_ms,
                value: out.value,
                quality: out.quality,
            });
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn malformed(
    store: &mut Store,
    cfg: &ReplayConfig,
    path: &Path,
    batch: &mut Vec<Sample>,
    gaps: &mut Vec<Gap>,
    report: &mut ReplayReport,
    line: u64,
    reason: String,
) -> Result<(), ReplayError> {
    report.rows_malformed += 1;
    match cfg.on_malformed {
        OnMalformed::Skip => {
            if report.malformed.len() < cfg.max_reported {
                report.malformed.push(MalformedRow { line, reason });
            }
            Ok(())
        }
        OnMalformed::Stop => {
            flush(store, batch, gaps, report)?;
            report.malformed.push(MalformedRow {
                line,
                reason: reason.clone(),
            });
            Err(ReplayError::Malformed {
                path: path.to_path_buf(),
                line,
                reason,
                committed: report.samples_inserted + report.samples_present,
                report: Box::new(report.clone()),
            })
        }
    }
}

fn flush(
    store: &mut Store,
    batch: &mut Vec<Sample>,
    gaps: &mut Vec<Gap>,
    report: &mut ReplayReport,
) -> Result<(), ReplayError> {
    if batch.is_empty() && gaps.is_empty() {
        return Ok(());
    }
    let n = store.insert_samples_and_gaps(batch, gaps)?;
    report.samples_inserted += n as u64;
    report.samples_present += (batch.len() - n) as u64;
    report.gaps_recorded += gaps.len() as u64;
    batch.clear();
    gaps.clear();
    Ok(())
}

fn make_bar(progress: Progress, len: u64) -> Option<indicatif::ProgressBar> {
    let want = match progress {
        Progress::Bar => true,
        Progress::Auto => std::io::stderr().is_terminal(),
        Progress::Log | Progress::Silent => false,
    };
    if !want {
        return None;
    }
    let bar = indicatif::ProgressBar::new(len);
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "{spinner} replay [{bar:40}] {bytes}/{total_bytes} {binary_bytes_per_sec} eta {eta}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    Some(bar)
}

/// What kind of problem made a row malformed (for the report's counters).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RowProblemKind {
    OutOfOrder,
    Implausible,
    Other,
}

/// Why a row is malformed.
#[derive(Debug, Clone, PartialEq, Eq)]
struct RowProblem {
    kind: RowProblemKind,
    reason: String,
}

impl RowProblem {
    fn other(reason: String) -> RowProblem {
        RowProblem {
            kind: RowProblemKind::Other,
            reason,
        }
    }
}

/// The latest plausible time stamp: the wall clock plus `max_future_s`, in epoch ms.
fn latest_plausible_ms(max_future_s: f64) -> i64 {
    let now_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
        .unwrap_or(0);
    now_ms.saturating_add((max_future_s * 1000.0).round() as i64)
}

/// Parses one row into `out`; returns its time or why it is malformed.
#[allow(clippy::too_many_arguments)]
fn parse_row(
    rec: &csv::ByteRecord,
    n_fields: usize,
    time_idx: usize,
    fmt: TimeFormat,
    columns: &[Column],
    prev_t: Option<i64>,
    latest_ok_ms: i64,
    out: &mut Vec<Cell>,
) -> Result<i64, RowProblem> {
    if rec.len() != n_fields {
        return Err(RowProblem::other(format!(
            "expected {n_fields} fields, found {} (truncated or extra delimiter?)",
            rec.len()
        )));
    }
    let t_raw = rec.get(time_idx).unwrap_or_default();
    let t = parse_time(t_raw, fmt)
        .map_err(|e| {
            format!(
                "time '{}' is not {}: {e}",
                String::from_utf8_lossy(t_raw),
                match fmt {
                    TimeFormat::Iso8601 => "ISO 8601",
                    TimeFormat::EpochS => "epoch seconds",
                    TimeFormat::EpochMs => "epoch milliseconds",
                }
            )
        })
        .map_err(RowProblem::other)?;
    if t > latest_ok_ms {
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
    // A bad cell (text, NaN, ±inf) is stored flagged `bad` with value 0 (SQLite cannot hold
    // NaN); it never discards the good cells of its row. A row with no good cell at all is
    // malformed (reported, nothing stored).
    let first = out.len();
    let mut any_good = false;
    for (column, c) in columns.iter().enumerate() {
        let raw = rec.get(c.index).unwrap_or_default();
        let s = raw.trim_ascii();
        if s.is_empty() {
            continue;
        }
        let parsed = std::str::from_utf8(s)
            .ok()
            .and_then(|s| s.parse::<f64>().ok());
        let problem = match parsed {
            None => Some(format!(
                "column '{}': '{}' is not a number",
                c.name,
                String::from_utf8_lossy(&raw[..raw.len().min(80)])
            )),
            Some(v) if !v.is_finite() => {
                Some(format!("column '{}': '{v}' is not a finite number", c.name))
            }
            Some(_) => None,
        };
        any_good |= problem.is_none();
        let (value, quality) = match (parsed, &problem) {
            (Some(v), None) => (v, Quality::Good),
            _ => (0.0, Quality::Bad),
        };
        out.push(Cell {
            column,
            sample: Sample {
                tag: c.tag,
                t_ms: t,
                value,
                quality,
            },
            problem,
        });
    }
    if !any_good && out.len() > first {
        let reason = out[first].problem.clone().unwrap_or_default();
        out.truncate(first);
        return Err(RowProblem::other(reason));
    }
    Ok(t)
}

#[cfg(test)]
mod tests;
