//! Read-side queries for the `segments` and `export` commands.
//!
//! Works on a read-only store (`ReadStore`) so it never disturbs the running daemon; the SQL is
//! the store's (`store/segments.rs`), this module only shapes and formats. Must not write.

use crate::segment::{AbortCause, Outcome, PhaseSpan};
use crate::signals::Phase;
use crate::store::{Store, StoreError};
use crate::time::fmt_ms;
use serde::Serialize;
use std::io::Write;

mod export;
pub(crate) use export::{export_csv, rolled_up_in_range, ExportRequest, Resolution};

/// One start-up as listed by `gtwatch segments`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct SegmentSummary {
    pub(crate) id: i64,
    pub(crate) start_ms: i64,
    pub(crate) end_ms: Option<i64>,
    pub(crate) outcome: Outcome,
    pub(crate) abort_cause: Option<AbortCause>,
    pub(crate) status: String,
    pub(crate) hot_restart: bool,
    pub(crate) has_gap: bool,
    pub(crate) phases: Vec<PhaseSpan>,
}

/// Output format of `segments`, `history`, `fleet history` and `wash advise`.
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
pub(crate) enum QueryError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Sql(#[from] rusqlite::Error),
    #[error("invalid value in database: {0}")]
    Corrupt(String),
    #[error("writing output")]
    Io(#[from] std::io::Error),
    #[error("writing CSV")]
    Csv(#[from] csv::Error),
    #[error("writing JSON")]
    Json(#[from] serde_json::Error),
}

/// Start-ups whose start is at or after `since_ms` (all if `None`), oldest first.
pub(crate) fn list_segments(
    store: &Store,
    since_ms: Option<i64>,
) -> Result<Vec<SegmentSummary>, QueryError> {
    let mut out = Vec::new();
    for row in store.startup_rows(since_ms)? {
        let hot_restart = row.hot_restart;
        let row = row.info;
        let id = row.id;
        let outcome = Outcome::parse(&row.outcome).ok_or_else(|| {
            QueryError::Corrupt(format!("segment {id}: outcome '{}'", row.outcome))
        })?;
        let abort_cause = match &row.abort_cause {
            Some(c) => Some(
                AbortCause::parse(c)
                    .ok_or_else(|| QueryError::Corrupt(format!("segment {id}: cause '{c}'")))?,
            ),
            None => None,
        };
        let spans = store
            .phase_rows(id)?
            .into_iter()
            .map(|p| {
                let phase = p
                    .phase
                    .parse::<Phase>()
                    .map_err(|e| QueryError::Corrupt(format!("segment {id}: {e}")))?;
                Ok(PhaseSpan {
                    phase,
                    start_ms: p.start_ms,
                    end_ms: p.end_ms,
                })
            })
            .collect::<Result<Vec<_>, QueryError>>()?;
        let (start_ms, end_ms, status, has_gap) =
            (row.start_ms, row.end_ms, row.status, row.has_gap);
        out.push(SegmentSummary {
            id,
            start_ms,
            end_ms,
            outcome,
            abort_cause,
            status,
            hot_restart,
            has_gap,
            phases: spans,
        });
    }
    Ok(out)
}

/// Phases shown as duration columns, in start-up order.
const PHASE_COLUMNS: [Phase; 8] = Phase::STARTUP;

impl SegmentSummary {
    /// Duration of a phase in seconds (`None` if absent or still running).
    pub(crate) fn phase_s(&self, phase: Phase) -> Option<f64> {
        self.phases
            .iter()
            .find(|p| p.phase == phase)
            .and_then(|p| p.end_ms.map(|e| (e - p.start_ms) as f64 / 1000.0))
    }

    fn cells(&self) -> Vec<String> {
        let opt = |v: Option<f64>| v.map(|x| format!("{x:.1}")).unwrap_or_default();
        let mut c = vec![
            self.id.to_string(),
            fmt_ms(self.start_ms),
            self.end_ms.map(fmt_ms).unwrap_or_default(),
            self.outcome.as_str().to_string(),
            self.abort_cause
                .map(|c| c.as_str().to_string())
                .unwrap_or_default(),
            self.status.clone(),
            if self.hot_restart { "yes" } else { "no" }.to_string(),
            if self.has_gap { "yes" } else { "no" }.to_string(),
            opt(self.end_ms.map(|e| (e - self.start_ms) as f64 / 1000.0)),
        ];
        c.extend(PHASE_COLUMNS.iter().map(|p| opt(self.phase_s(*p))));
        c
    }
}

fn header() -> Vec<String> {
    let mut h: Vec<String> = [
        "id",
        "start",
        "end",
        "outcome",
        "cause",
        "status",
        "hot_restart",
        "data_gap",
        "duration_s",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    h.extend(PHASE_COLUMNS.iter().map(|p| format!("{}_s", p.name())));
    h
}

/// Writes segments as an aligned table, CSV or JSON. Times are ISO 8601 UTC; durations in s.
pub(crate) fn write_segments(
    segments: &[SegmentSummary],
    format: Format,
    out: &mut dyn Write,
) -> Result<(), QueryError> {
    match format {
        Format::Json => {
            serde_json::to_writer_pretty(&mut *out, segments)?;
            writeln!(out)?;
        }
        Format::Csv => {
            let mut w = csv::Writer::from_writer(out);
            w.write_record(header())?;
            for s in segments {
                w.write_record(s.cells())?;
            }
            w.flush()?;
        }
        Format::Table => {
            let mut rows = vec![header()];
            rows.extend(segments.iter().map(|s| s.cells()));
            let n = rows[0].len();
            let widths: Vec<usize> = (0..n)
                .map(|i| rows.iter().map(|r| r[i].len()).max().unwrap_or(0))
                .collect();
            for r in &rows {
                let line: Vec<String> = r
                    .iter()
                    .zip(&widths)
                    .map(|(c, w)| format!("{c:<w$}"))
                    .collect();
                writeln!(out, "{}", line.join("  ").trim_end())?;
            }
            if segments.is_empty() {
                writeln!(out, "(no start-ups)")?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quality::Quality;
    use crate::signals::Signal;
    use crate::store::{Sample, TagInfo};

    #[test]
    fn export_wide_and_long() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("q.db");
        let mut store = Store::open(&path).expect("open");
        let a = store
            .ensure_tag(&TagInfo::for_signal(Signal::N1))
            .expect("tag");
        let b = store
            .ensure_tag(&TagInfo::for_signal(Signal::Power))
            .expect("tag");
        let s = |tag, t_ms, value| Sample {
            tag,
            t_ms,
            value,
            quality: Quality::Good,
        };
        store
            .insert_samples(&[
                s(a, 0, 1.0),
                s(a, 1000, 2.0),
                s(b, 1000, 5.5),
                s(a, 9000, 3.0),
            ])
            .expect("insert");
        drop(store);
        let ro = Store::open_readonly(&path).expect("ro");
        let tags = vec!["n1_rpm".to_string(), "power_mw".to_string()];
        let mut out = Vec::new();
        let req = |to_ms, layout| ExportRequest {
            tags: tags.clone(),
            from_ms: 0,
            to_ms,
            layout,
            resolution: Resolution::Raw,
        };
        let n = export_csv(&ro, &req(5000, ExportLayout::Wide), &mut out).expect("export");
        assert_eq!(n, 2);
        let text = String::from_utf8(out).expect("utf8");
        assert_eq!(
            text,
            "time,t_ms,n1_rpm,power_mw\n\
             1970-01-01T00:00:00.000Z,0,1,\n\
             1970-01-01T00:00:01.000Z,1000,2,5.5\n"
        );
        let mut out = Vec::new();
        let n = export_csv(&ro, &req(9000, ExportLayout::Long), &mut out).expect("export");
        assert_eq!(n, 4);
        let text = String::from_utf8(out).expect("utf8");
        assert!(text.starts_with("time,t_ms,tag,value,quality\n"));
        assert!(text.contains("1970-01-01T00:00:01.000Z,1000,power_mw,5.5,0\n"));
        let nope = ExportRequest {
            tags: vec!["nope".into()],
            ..req(1, ExportLayout::Wide)
        };
        assert!(export_csv(&ro, &nope, &mut Vec::new()).is_err());
    }

    #[test]
    fn segments_render_in_all_formats() {
        let seg = SegmentSummary {
            id: 1,
            start_ms: 0,
            end_ms: Some(120_000),
            outcome: Outcome::Aborted,
            abort_cause: Some(AbortCause::Trip),
            status: "closed".into(),
            hot_restart: true,
            has_gap: false,
            phases: vec![
                PhaseSpan {
                    phase: Phase::Crank,
                    start_ms: 0,
                    end_ms: Some(40_000),
                },
                PhaseSpan {
                    phase: Phase::Purge,
                    start_ms: 40_000,
                    end_ms: Some(120_000),
                },
            ],
        };
        let mut t = Vec::new();
        write_segments(std::slice::from_ref(&seg), Format::Table, &mut t).expect("table");
        let t = String::from_utf8(t).expect("utf8");
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), 2);
        assert!(lines[0].starts_with("id  start"));
        assert!(
            lines[1].contains("aborted") && lines[1].contains("trip") && lines[1].contains("80.0")
        );
        let mut c = Vec::new();
        write_segments(std::slice::from_ref(&seg), Format::Csv, &mut c).expect("csv");
        let c = String::from_utf8(c).expect("utf8");
        assert!(c.lines().nth(1).expect("row").starts_with("1,1970-01-01T00:00:00.000Z,1970-01-01T00:02:00.000Z,aborted,trip,closed,yes,no,120.0,40.0,80.0"));
        let mut j = Vec::new();
        write_segments(&[seg], Format::Json, &mut j).expect("json");
        let v: serde_json::Value = serde_json::from_slice(&j).expect("json parse");
        assert_eq!(v[0]["abort_cause"], "trip");
        assert_eq!(v[0]["phases"][1]["phase"], "purge");
    }
}
