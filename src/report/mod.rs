//! `gtwatch report`: one self-contained HTML page about the unit, for a plant performance
//! engineer: the six health parameters over time with ±σ, washes and the fouling trend since the
//! last wash; the latest diagnosed start-up's measured against modelled traces with residuals;
//! data gaps and undiagnosable start-ups; the stored wash advice.
//!
//! [`gather`] reads the store (read-only queries) and re-runs the model for the latest start-up;
//! [`render`] turns the gathered [`ReportData`] into HTML (pure). The page has inline CSS and
//! inline SVG only: no script, no image, font or style sheet fetched from anywhere. Must not
//! write to the database (it never records washes or advice, unlike `wash advise`).
//!
//! The rooms: `read` (gathering from the store and the model), `html` (the page and its
//! sections), `charts` (the health and trace charts), `gap_section` (the model–plant gap table).

mod charts;
pub(crate) mod fleet;
mod gap_section;
mod html;
mod read;

pub(crate) use html::render;
pub(crate) use read::gather;

use crate::engine::Engine;
use crate::health::HealthParams;
use crate::query::QueryError;
use crate::signals::Signal;
use crate::store::{
    Gap, GapAnalysisRow, HistoryRow, RecommendationRow, Store, StoreError, WashRow,
};
use crate::time::fmt_ms;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Signals whose traces the report shows (the outputs the transient fit compares).
pub(crate) const TRACE_SIGNALS: [Signal; 8] = [
    Signal::N1,
    Signal::N2,
    Signal::P2,
    Signal::T2,
    Signal::P34,
    Signal::T34,
    Signal::T4,
    Signal::Power,
];

/// Why no report could be written.
#[derive(Debug, thiserror::Error)]
pub(crate) enum ReportError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Query(#[from] QueryError),
    #[error("writing {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// What the page is about (the header).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct ReportHeader {
    pub(crate) plant: String,
    pub(crate) db_path: String,
    pub(crate) generated_utc: String,
    pub(crate) version: String,
}

/// Measured and modelled values of one signal for the latest start-up.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct SignalTrace {
    pub(crate) signal: String,
    pub(crate) unit: String,
    pub(crate) t_s: Vec<f64>,
    pub(crate) measured: Vec<f64>,
    pub(crate) model: Vec<f64>,
    /// RMS of measured − model over the samples where both exist.
    pub(crate) rms_residual: f64,
}

/// The latest diagnosed start-up, re-simulated with its stored health.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct LatestStartup {
    pub(crate) segment_id: i64,
    pub(crate) start_utc: String,
    pub(crate) health: HealthParams,
    pub(crate) fit_quality: Option<String>,
    pub(crate) residual_level: Option<f64>,
    pub(crate) traces: Vec<SignalTrace>,
    /// Why the model could not be re-run, if it could not.
    pub(crate) problem: Option<String>,
}

/// A start-up that was not diagnosed, with the reasons.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct Undiagnosed {
    pub(crate) segment_id: i64,
    pub(crate) start_utc: String,
    pub(crate) outcome: String,
    pub(crate) reasons: Vec<String>,
}

/// A fitted fouling trend line since the last wash.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct TrendLine {
    pub(crate) param: String,
    pub(crate) rate_per_day: f64,
    pub(crate) rate_sigma_per_day: f64,
    /// End points (Unix ms, percent).
    pub(crate) from: (f64, f64),
    pub(crate) to: (f64, f64),
}

/// Everything on the page.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct ReportData {
    pub(crate) header: ReportHeader,
    pub(crate) history: Vec<HistoryRow>,
    pub(crate) washes: Vec<WashRow>,
    pub(crate) trends: Vec<TrendLine>,
    pub(crate) latest: Option<LatestStartup>,
    pub(crate) gaps: Vec<Gap>,
    pub(crate) undiagnosed: Vec<Undiagnosed>,
    /// Stored gap analyses of the period's start-ups, newest first.
    pub(crate) gap_analyses: Vec<GapAnalysisRow>,
    pub(crate) startups: usize,
    pub(crate) advice: Option<RecommendationRow>,
}

/// What `write_report` wrote.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct ReportSummary {
    pub(crate) path: PathBuf,
    pub(crate) bytes: usize,
    pub(crate) startups: usize,
    pub(crate) diagnoses: usize,
    pub(crate) washes: usize,
    pub(crate) gaps: usize,
    pub(crate) undiagnosed: usize,
    pub(crate) latest_segment: Option<i64>,
    pub(crate) advice: Option<String>,
}

/// Gathers, renders and writes `out_dir/report.html`.
pub(crate) fn write_report(
    store: &Store,
    engine: &Engine,
    header: ReportHeader,
    out_dir: &Path,
    since_ms: Option<i64>,
    until_ms: Option<i64>,
) -> Result<ReportSummary, ReportError> {
    let data = gather(store, engine, header, since_ms, until_ms)?;
    let html = render(&data);
    let write_err = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ReportError::Write { path, source }
    };
    std::fs::create_dir_all(out_dir).map_err(write_err(out_dir))?;
    let path = out_dir.join("report.html");
    std::fs::write(&path, &html).map_err(write_err(&path))?;
    Ok(ReportSummary {
        bytes: html.len(),
        startups: data.startups,
        diagnoses: data.history.len(),
        washes: data.washes.len(),
        gaps: data.gaps.len(),
        undiagnosed: data.undiagnosed.len(),
        latest_segment: data.latest.as_ref().map(|l| l.segment_id),
        advice: data.advice.map(|a| a.message),
        path,
    })
}

/// The header for a database at `db_path`, generated now.
pub(crate) fn header_now(plant: &str, db_path: &Path) -> ReportHeader {
    let now_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as i64);
    ReportHeader {
        plant: plant.to_string(),
        db_path: db_path.display().to_string(),
        generated_utc: fmt_ms(now_ms),
        version: env!("CARGO_PKG_VERSION").to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> ReportHeader {
        ReportHeader {
            plant: "GT <1>".into(),
            db_path: "/tmp/x.db".into(),
            generated_utc: "2026-01-01T00:00:00.000Z".into(),
            version: "0".into(),
        }
    }

    /// No external reference of any kind: the page must open on an air-gapped laptop.
    pub(crate) fn assert_self_contained(html: &str) {
        for bad in [
            "http:", "https:", "src=", "href=", "@import", "url(", "<script", "<img", "<link",
        ] {
            assert!(!html.contains(bad), "found '{bad}' in the report");
        }
    }

    #[test]
    fn empty_database_gives_a_page_with_empty_states() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("e.db")).unwrap();
        let engine = Engine::reference().unwrap();
        let s = write_report(&store, &engine, header(), dir.path(), None, None).unwrap();
        let html = std::fs::read_to_string(&s.path).unwrap();
        assert!(html.contains("No diagnoses yet"));
        assert!(html.contains("No wash advice yet"));
        assert!(html.contains("No diagnosed start-up yet"));
        assert!(html.contains("GT &lt;1&gt;"), "plant name escaped");
        assert_eq!(html.matches("<svg").count(), 0, "no empty axes");
        assert_self_contained(&html);
        assert_eq!(s.diagnoses, 0);
    }
}
