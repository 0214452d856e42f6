//! Where a replay's parsed rows go, whatever the file's layout: the bad-value policy of each
//! replayed column (checker and spike filter), the gap detector, the malformed-row report and
//! the batch that is written in large `INSERT OR IGNORE` transactions (idempotent, and a
//! replay killed half-way can be run again).
//!
//! Must not read CSV or parse time stamps: the layout readers (`super::replay_wide`,
//! `super::long`) hand it rows of cells with their time.

use super::{MalformedRow, OnMalformed, Progress, ReplayConfig, ReplayError, ReplayReport};
use crate::quality::{Point, Quality, QualityConfig, SpikeFilter, ValueChecker};
use crate::signals::Signal;
use crate::store::{Gap, Sample, Store, TagId, TagInfo, CHUNK_SPAN_MS, DEFAULT_MAX_CHUNK_SAMPLES};
use crate::units::{ColumnUnits, Unit};
use std::io::IsTerminal;
use std::path::Path;
use std::time::{Duration, Instant};

/// One replayed column (wide) or tag (long).
pub(super) struct Column {
    /// Wide: the CSV field index. Long: unused (0).
    pub index: usize,
    pub name: String,
    pub tag: TagId,
    /// The unit `[replay.units]` states for its signal, when not the model's: values are
    /// converted before they are judged and stored.
    pub unit: Option<&'static Unit>,
}

/// The bad-value policy's state for one column.
struct ColumnQuality {
    checker: ValueChecker,
    spikes: SpikeFilter,
}

/// A parsed cell: which column, and its sample (quality `Good`, or `Bad` if not a number).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Cell {
    pub column: usize,
    pub sample: Sample,
    /// Why the cell is bad (not a finite number, or a bad status).
    pub problem: Option<String>,
}

impl Cell {
    /// The cell of `column` (tag `tag`) at `t_ms`: good with its value, or flagged bad with
    /// value 0 (SQLite cannot hold NaN) and the reason.
    pub(super) fn new(column: usize, tag: TagId, t_ms: i64, parsed: Result<f64, String>) -> Cell {
        let (value, quality, problem) = match parsed {
            Ok(v) => (v, Quality::Good, None),
            Err(why) => (0.0, Quality::Bad, Some(why)),
        };
        Cell {
            column,
            sample: Sample {
                tag,
                t_ms,
                value,
                quality,
            },
            problem,
        }
    }
}

/// What kind of problem made a row malformed (for the report's counters).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum RowProblemKind {
    OutOfOrder,
    Implausible,
    /// A local time the configured zone skips (spring gap).
    Nonexistent,
    Other,
}

/// Why a row is malformed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct RowProblem {
    pub kind: RowProblemKind,
    pub reason: String,
}

impl RowProblem {
    pub(super) fn other(reason: String) -> RowProblem {
        RowProblem {
            kind: RowProblemKind::Other,
            reason,
        }
    }
}

/// The replay's output side for one file.
pub(super) struct Sink<'a> {
    store: &'a mut Store,
    cfg: &'a ReplayConfig,
    quality: &'a QualityConfig,
    path: &'a Path,
    pub columns: Vec<Column>,
    col_quality: Vec<ColumnQuality>,
    n1_column: Option<usize>,
    batch: Vec<Sample>,
    gaps: Vec<Gap>,
    gap_source: String,
    gap_threshold_ms: i64,
    /// Time of the previous stored row (wide) or time group (long).
    prev_t: Option<i64>,
    /// Archive mode: the start of the chunk window the latest row opened, when the batch
    /// still holds samples of earlier windows (flushed after this row, so each window's
    /// samples become one chunk per tag).
    window_opened: Option<i64>,
    pub report: ReplayReport,
    /// `[replay.units]`, parsed (the replay refuses a config where it does not parse).
    pub units: ColumnUnits,
    file_len: u64,
    bar: Option<indicatif::ProgressBar>,
    log_progress: bool,
    last_log: Instant,
}

/// A sample the spike filter let go: counted by its quality and queued for the next batch.
fn release(report: &mut ReplayReport, batch: &mut Vec<Sample>, tag: TagId, out: Point) {
    report.quality.add(out.quality);
    batch.push(Sample {
        tag,
        t_ms: out.t_ms,
        value: out.value,
        quality: out.quality,
    });
}

impl<'a> Sink<'a> {
    pub(super) fn new(
        store: &'a mut Store,
        cfg: &'a ReplayConfig,
        quality: &'a QualityConfig,
        path: &'a Path,
        file_len: u64,
        progress: Progress,
    ) -> Sink<'a> {
        let bar = make_bar(progress, file_len);
        let log_progress = matches!(progress, Progress::Log)
            || (matches!(progress, Progress::Auto) && bar.is_none());
        Sink {
            store,
            cfg,
            quality,
            path,
            columns: Vec::new(),
            col_quality: Vec::new(),
            n1_column: None,
            batch: Vec::with_capacity(cfg.transaction_samples.min(1 << 20) + 64),
            gaps: Vec::new(),
            gap_source: format!(
                "replay:{}",
                path.file_name()
                    .map(|f| f.to_string_lossy().into_owned())
                    .unwrap_or_default()
            ),
            gap_threshold_ms: (cfg.gap_threshold_s * 1000.0).round() as i64,
            prev_t: None,
            window_opened: None,
            report: ReplayReport {
                file: path.to_path_buf(),
                ..ReplayReport::default()
            },
            units: ColumnUnits::default(),
            file_len,
            bar,
            log_progress,
            last_log: Instant::now(),
        }
    }

    /// Adds a replayed column feeding `info` (creating its tag); returns its index.
    pub(super) fn add_column(
        &mut self,
        index: usize,
        name: String,
        info: &TagInfo,
    ) -> Result<usize, ReplayError> {
        let tag = self.store.ensure_tag(info)?;
        self.report.columns.push((name.clone(), info.name.clone()));
        let checker = self
            .quality
            .checker(&[info.name.as_str(), name.as_str()], info.signal);
        self.col_quality.push(ColumnQuality {
            spikes: SpikeFilter::new(checker.limits()),
            checker,
        });
        if info.signal == Some(Signal::N1) && self.n1_column.is_none() {
            self.n1_column = Some(self.columns.len());
        }
        let unit = info
            .signal
            .and_then(|s| self.units.of(s.column()))
            .filter(|u| !u.is_identity());
        self.columns.push(Column {
            index,
            name,
            tag,
            unit,
        });
        Ok(self.columns.len() - 1)
    }

    /// Stores one well-formed row (all its cells share time `t`): records a gap before it if
    /// the previous row is too far back, classifies every value and queues the samples.
    pub(super) fn row(&mut self, t: i64, line: u64, cells: &mut Vec<Cell>) {
        if let Some(p) = self.prev_t {
            if self.gap_threshold_ms > 0 && t - p > self.gap_threshold_ms {
                self.gaps.push(Gap {
                    start_ms: p,
                    end_ms: t,
                    source: self.gap_source.clone(),
                    reason: format!(
                        "no rows for {:.1} s (lines {} and {})",
                        (t - p) as f64 / 1000.0,
                        line.saturating_sub(1),
                        line
                    ),
                });
            }
        }
        if self.cfg.archive {
            let w = |t: i64| t.div_euclid(CHUNK_SPAN_MS);
            if self.prev_t.is_some_and(|p| w(p) != w(t)) {
                self.window_opened = Some(w(t) * CHUNK_SPAN_MS);
            }
        }
        self.prev_t = Some(t);
        self.report.first_t_ms.get_or_insert(t);
        self.report.last_t_ms = Some(t);
        // Into the model's units first: the GG speed judges the other values.
        for cell in cells.iter_mut().filter(|c| c.problem.is_none()) {
            if let Some(u) = self.columns[cell.column].unit {
                cell.sample.value = self.units.convert(u, cell.sample.value);
            }
        }
        let n1 = self.n1_column.and_then(|i| {
            cells
                .iter()
                .find(|c| c.column == i && c.sample.quality == Quality::Good)
                .map(|c| c.sample.value)
                .filter(|v| {
                    crate::quality::classify_value(
                        *v,
                        self.col_quality[i].checker.limits().as_ref(),
                    ) == Quality::Good
                })
        });
        let max_reported = self.cfg.max_reported;
        for cell in cells.drain(..) {
            let cq = &mut self.col_quality[cell.column];
            let mut s = cell.sample;
            if let Some(reason) = cell.problem {
                if self.report.bad_cells.len() < max_reported {
                    self.report.bad_cells.push(MalformedRow { line, reason });
                }
            } else {
                s.quality = cq.checker.check(t, s.value, n1);
                if s.quality == Quality::OutOfRange && self.report.bad_cells.len() < max_reported {
                    self.report.bad_cells.push(MalformedRow {
                        line,
                        reason: format!(
                            "column '{}': {} is outside the plausible range",
                            self.columns[cell.column].name, s.value
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
                release(&mut self.report, &mut self.batch, s.tag, out);
            }
        }
    }

    /// A malformed row: counted, reported, and with `on_malformed = "stop"` the end of the
    /// replay (what came before is committed first).
    pub(super) fn reject(&mut self, line: u64, problem: RowProblem) -> Result<(), ReplayError> {
        match problem.kind {
            RowProblemKind::OutOfOrder => self.report.rows_out_of_order += 1,
            RowProblemKind::Implausible => self.report.rows_implausible_time += 1,
            RowProblemKind::Nonexistent => self.report.rows_nonexistent_time += 1,
            RowProblemKind::Other => {}
        }
        self.report.rows_malformed += 1;
        match self.cfg.on_malformed {
            OnMalformed::Skip => {
                if self.report.malformed.len() < self.cfg.max_reported {
                    self.report.malformed.push(MalformedRow {
                        line,
                        reason: problem.reason,
                    });
                }
                Ok(())
            }
            OnMalformed::Stop => {
                self.drain_held();
                self.flush()?;
                self.report.malformed.push(MalformedRow {
                    line,
                    reason: problem.reason.clone(),
                });
                Err(ReplayError::Malformed {
                    path: self.path.to_path_buf(),
                    line,
                    reason: problem.reason,
                    committed: self.report.samples_inserted + self.report.samples_present,
                    report: Box::new(self.report.clone()),
                })
            }
        }
    }

    /// A read error of the file: what came before is committed, then the error.
    pub(super) fn io_error(&mut self, e: &csv::Error) -> ReplayError {
        self.drain_held();
        if let Err(err) = self.flush() {
            return err;
        }
        ReplayError::Io {
            path: self.path.to_path_buf(),
            source: std::io::Error::other(e.to_string()),
        }
    }

    /// After each row: writes the batch once it is large, and shows progress (`pos`: byte
    /// offset reached in the file).
    pub(super) fn after_row(&mut self, pos: impl FnOnce() -> u64) -> Result<(), ReplayError> {
        if let Some(boundary) = self.window_opened.take() {
            // A new chunk window: the earlier windows' samples go out as whole chunks.
            self.flush_before(boundary)?;
        }
        if self.batch.len() < self.cfg.transaction_samples {
            return Ok(());
        }
        self.flush()?;
        let pos = pos();
        if let Some(b) = &self.bar {
            b.set_position(pos);
        }
        if self.log_progress && self.last_log.elapsed() >= Duration::from_secs(5) {
            self.last_log = Instant::now();
            tracing::info!(
                file = %self.path.display(),
                percent = format!("{:.1}", 100.0 * pos as f64 / self.file_len.max(1) as f64),
                rows = self.report.rows_read,
                inserted = self.report.samples_inserted,
                present = self.report.samples_present,
                malformed = self.report.rows_malformed,
                "replay progress"
            );
        }
        Ok(())
    }

    /// End of file: writes what is held and returns the report.
    pub(super) fn finish(mut self, started: Instant) -> Result<ReplayReport, ReplayError> {
        self.drain_held();
        self.flush()?;
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
        self.report.elapsed_s = started.elapsed().as_secs_f64();
        Ok(self.report)
    }

    /// Moves the sample each spike filter holds back into the batch (end of file, or a stop).
    fn drain_held(&mut self) {
        for (c, cq) in self.columns.iter().zip(self.col_quality.iter_mut()) {
            if let Some(out) = cq.spikes.finish() {
                release(&mut self.report, &mut self.batch, c.tag, out);
            }
        }
    }

    fn flush(&mut self) -> Result<(), ReplayError> {
        self.flush_before(i64::MAX)
    }

    /// Writes the batch's samples older than `boundary` (all with `i64::MAX`) and the gaps,
    /// in one transaction: as hot rows, or in archive mode as chunks. The rest stay queued.
    fn flush_before(&mut self, boundary: i64) -> Result<(), ReplayError> {
        if self.batch.is_empty() && self.gaps.is_empty() {
            return Ok(());
        }
        let kept: Vec<Sample> = if boundary == i64::MAX {
            Vec::new()
        } else {
            let (out, kept): (Vec<Sample>, Vec<Sample>) =
                self.batch.iter().partition(|s| s.t_ms < boundary);
            self.batch = out;
            kept
        };
        let n = if self.cfg.archive {
            let d = self.store.insert_samples_archived(
                &self.batch,
                &self.gaps,
                DEFAULT_MAX_CHUNK_SAMPLES,
            )?;
            self.report.chunks_archived += d.chunks;
            d.inserted
        } else {
            self.store
                .insert_samples_and_gaps(&self.batch, &self.gaps)?
        };
        self.report.samples_inserted += n as u64;
        self.report.samples_present += (self.batch.len() - n) as u64;
        self.report.gaps_recorded += self.gaps.len() as u64;
        self.batch.clear();
        self.batch.extend(kept);
        self.gaps.clear();
        Ok(())
    }
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
