//! Read-side queries for the `segments` and `export` commands.
//!
//! Works on a read-only [`Store`] so it never disturbs the running daemon. Must not write.

use crate::detect::{AbortCause, Outcome, PhaseSpan};
use crate::store::{Store, StoreError};
use serde::Serialize;
use std::io::Write;

/// One start-up as listed by `gtwatch segments`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SegmentSummary {
    pub id: i64,
    pub start_ms: i64,
    pub end_ms: Option<i64>,
    pub outcome: Outcome,
    pub abort_cause: Option<AbortCause>,
    pub status: String,
    pub hot_restart: bool,
    pub has_gap: bool,
    pub phases: Vec<PhaseSpan>,
}

/// Output format of `segments`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Format {
    #[default]
    Table,
    Csv,
    Json,
}

/// Layout of `export`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum ExportLayout {
    /// One row per time stamp, one column per tag (`time,t_ms,n1_rpm,...`); empty = no sample.
    #[default]
    Wide,
    /// One row per sample: `time,t_ms,tag,value,quality`.
    Long,
}

/// Query errors.
#[derive(Debug, thiserror::Error)]
pub enum QueryError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Sql(#[from] rusqlite::Error),
    #[error("invalid value in database: {0}")]
    Corrupt(String),
    #[error("writing output: {0}")]
    Io(#[from] std::io::Error),
    #[error("{0}")]
    Csv(#[from] csv::Error),
    #[error("{0}")]
    Json(#[from] serde_json::Error),
}

/// Start-ups whose start is at or after `since_ms` (all if `None`), oldest first.
pub fn list_segments(
    _store: &Store,
    _since_ms: Option<i64>,
) -> Result<Vec<SegmentSummary>, QueryError> {
    Ok(Vec::new())
}

/// Writes segments as an aligned table, CSV or JSON.
pub fn write_segments(
    _segments: &[SegmentSummary],
    _format: Format,
    _out: &mut dyn Write,
) -> Result<(), QueryError> {
    Ok(())
}

/// Writes the samples of `tags` in `[from_ms, to_ms]` as CSV; returns the rows written.
pub fn export_csv(
    _store: &Store,
    _tags: &[String],
    _from_ms: i64,
    _to_ms: i64,
    _layout: ExportLayout,
    _out: &mut dyn Write,
) -> Result<u64, QueryError> {
    Ok(0)
}
