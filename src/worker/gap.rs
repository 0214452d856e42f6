//! The gap question inside the loop (issue 23 item 4): one step of the daemon's background gap
//! analysis. It picks the oldest start-up that needs one — its Method B fit stored as not
//! `good` or refused as `residual_too_high`, or every n-th start-up on a schedule
//! (`[diagnosis] gap_on_poor_fit`, `gap_every_n`) — runs `gap::analyse` on it with the worker's
//! engine and fit settings, and writes the report through [`Db`]. It yields to the diagnosis
//! queue: nothing starts while a closed start-up waits for its diagnosis, and a cancelled
//! analysis (shutdown, or a new start-up closing) stores nothing and is redone later.
//!
//! Must not hold SQL (the store's) or the analysis itself (`crate::gap`), and must not decide
//! when it runs (the daemon's gap task does).

use super::WorkerContext;
use crate::optim::Cancel;
use crate::store::{Db, GapSelection, NewGapAnalysis, StoreError};
use std::collections::HashSet;

/// What one step did.
#[derive(Debug, Clone, PartialEq)]
pub enum GapStep {
    /// Nothing to do (or start-ups wait for their diagnosis first).
    Idle,
    /// An analysis was stored.
    Stored {
        segment_id: i64,
        analysis_id: i64,
        effect: String,
        wall_s: f64,
    },
    /// Cancelled before it finished: nothing stored.
    Cancelled { segment_id: i64 },
    /// The start-up cannot be analysed (no recording, the analysis failed): the caller skips it
    /// until the daemon restarts.
    Failed { segment_id: i64, reason: String },
}

/// The selection the settings ask for, `None` when the daemon runs no gap analysis.
pub fn selection(ctx: &WorkerContext) -> Option<GapSelection> {
    let s = &ctx.settings;
    (s.gap_on_poor_fit || s.gap_every_n > 0).then_some(GapSelection {
        not_good: s.gap_on_poor_fit,
        every_n: s.gap_every_n,
    })
}

/// Analyses the next start-up that needs it (skipping `skip`), if the diagnosis queue is empty.
pub fn analyse_next(
    db: &mut impl Db,
    ctx: &WorkerContext,
    cancel: &Cancel,
    skip: &HashSet<i64>,
) -> Result<GapStep, StoreError> {
    let Some(sel) = selection(ctx) else {
        return Ok(GapStep::Idle);
    };
    if !db.read().pending_segments()?.is_empty() {
        return Ok(GapStep::Idle);
    }
    let ids = db.read().segments_for_gap(sel, skip.len() + 1)?;
    let Some(segment_id) = ids.into_iter().find(|id| !skip.contains(id)) else {
        return Ok(GapStep::Idle);
    };
    let failed = |reason: String| Ok(GapStep::Failed { segment_id, reason });
    let recording = match db.read().segment_recording(segment_id)? {
        Some(r) => match r.recording {
            Ok(rec) => rec,
            Err(e) => return failed(format!("the segment cannot be analysed: {e}")),
        },
        None => return failed("the segment is gone".into()),
    };
    let candidates = match crate::gap::select("all") {
        Ok(c) => c,
        Err(e) => return failed(e),
    };
    let cfg = ctx.settings.fit_config(cancel);
    let result = crate::gap::analyse(&ctx.engine, &recording, None, &candidates, &cfg);
    // A cancelled analysis (finished early or failed for it) stores nothing.
    if cancel.is_cancelled() {
        return Ok(GapStep::Cancelled { segment_id });
    }
    let report = match result {
        Ok(r) => r,
        Err(e) => return failed(e.to_string()),
    };
    let report_json = match serde_json::to_string(&report) {
        Ok(j) => j,
        Err(e) => return failed(e.to_string()),
    };
    let analysis_id = db.write_gap_analysis(NewGapAnalysis {
        segment_id,
        holdout_segment_id: None,
        effect: report.verdict.effect.clone(),
        shrinkage: report.verdict.shrinkage,
        confidence: report.verdict.confidence,
        baseline_fit_quality: report.baseline_fit_quality.as_str().into(),
        normalised_residual: report.baseline_normalised_residual,
        report_json,
    })?;
    Ok(GapStep::Stored {
        segment_id,
        analysis_id,
        effect: report.verdict.effect,
        wall_s: report.wall_s,
    })
}
