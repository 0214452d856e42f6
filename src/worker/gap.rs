//! The gap question inside the loop (issue 23 item 4): one step of the daemon's background gap
//! analysis. It picks the oldest start-up that needs one — its Method B fit stored as not
//! `good` or refused as `residual_too_high`, its health stepping away from the unit's own
//! trend since the last wash (`trend::steps_against_trend`; a step that persists once; a poor
//! fit that carries on an analysed one is not analysed again), or every n-th start-up on a
//! schedule (`[diagnosis] gap_on_poor_fit`, `gap_on_health_step`, `gap_every_n`) — runs `gap::analyse` on it with the worker's
//! engine and fit settings ([`analyse_startup`], which the fleet's gap jobs run too), and
//! writes the report through [`Db`]. It yields to the diagnosis
//! queue: nothing starts while a closed start-up waits for its diagnosis, and a cancelled
//! analysis (shutdown, or a new start-up closing) stores nothing and is redone later.
//!
//! Must not hold SQL (the store's) or the analysis itself (`crate::gap`), and must not decide
//! when it runs (the daemon's gap task does).

use super::WorkerContext;
use crate::health::HEALTH_NAMES as NAMES;
use crate::optim::Cancel;
use crate::recording::Recording;
use crate::store::{
    Db, GapSelection, HistoryFilter, HistoryRow, NewGapAnalysis, Store, StoreError,
};
use crate::trend::{departures, same_step, steps_of, Departure, HealthStep, TrendPoint};
use std::collections::HashSet;

/// What one step did.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum GapStep {
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
pub(crate) fn selection(ctx: &WorkerContext) -> Option<GapSelection> {
    let s = &ctx.settings;
    (s.gap_on_poor_fit || s.gap_on_health_step || s.gap_every_n > 0).then_some(GapSelection {
        not_good: s.gap_on_poor_fit,
        every_n: s.gap_every_n,
    })
}

/// Milliseconds per day.
const MS_PER_DAY: f64 = 86_400_000.0;

fn trend_points(row: &HistoryRow) -> [TrendPoint; 6] {
    let t_days = row.start_ms as f64 / MS_PER_DAY;
    NAMES.map(|n| TrendPoint {
        t_days,
        value: row.value(n),
        sigma: row.sigma_of(n),
    })
}

/// Every Method B result, oldest first: what [`health_steps`] and [`covered_poor_fits`] walk.
pub(crate) fn method_b_history(read: &Store) -> Result<Vec<HistoryRow>, StoreError> {
    read.history(&HistoryFilter {
        method: Some("B".into()),
        ..HistoryFilter::default()
    })
}

/// The trend each Method B result is judged against, walked oldest first: the good results on
/// the trend since the same wash. [`health_steps`] and [`covered_poor_fits`] share it, so a
/// step and a persisting misfit are measured from the same trend.
#[derive(Default)]
struct TrendWalk {
    window: Vec<[TrendPoint; 6]>,
    since_wash: Option<i64>,
}

/// One result as [`TrendWalk::judge`] saw it.
struct Judged {
    /// A wash came between it and the result before: what the caller carried is over.
    washed: bool,
    /// Its fit is `good`.
    good: bool,
    departures: [Option<Departure>; 6],
    /// Its steps away from the trend (a compressor that recovers is a wash, not a step).
    steps: Vec<HealthStep>,
}

impl TrendWalk {
    /// `row` against the trend before it. A good result without a step joins the trend; a
    /// stepped or poorly fitting one is left out of what the next are judged against.
    fn judge(&mut self, row: &HistoryRow) -> Judged {
        let washed = row.wash_id_before != self.since_wash;
        if washed {
            self.window.clear();
            self.since_wash = row.wash_id_before;
        }
        let points = trend_points(row);
        let departures = departures(&self.window, &points);
        let steps = steps_of(&departures, crate::trend::RECOVERED_BY_WASH);
        let good = row.fit_quality.as_deref() == Some("good");
        if good && steps.is_empty() {
            self.window.push(points);
        }
        Judged {
            washed,
            good,
            departures,
            steps,
        }
    }
}

/// Start-ups whose `good` Method B health steps away from the trend of the good results
/// before them since the same wash, oldest first, with their steps (`rows`:
/// [`method_b_history`]).
///
/// A step that persists is listed once: a start-up that departs from the trend as the last
/// stepped one did (every parameter's offset within tolerance of its offset, `trend::same_step`)
/// carries on that step — a fuel meter that reads 3 % high from one day on shifts the health of
/// every start-up after — and the analysis of the step's first start-up stands for it, where
/// re-analysing each would cost the gap task an analysis a day and tell nothing new.
pub(crate) fn health_steps(rows: &[HistoryRow]) -> Vec<(i64, Vec<HealthStep>)> {
    let mut out = Vec::new();
    let mut walk = TrendWalk::default();
    let mut last_step: Option<[Option<Departure>; 6]> = None;
    for row in rows {
        let j = walk.judge(row);
        if j.washed {
            last_step = None;
        }
        if !j.good {
            continue;
        }
        if j.steps.is_empty() {
            // Back on the trend: a step seen after this is a new one.
            last_step = None;
            continue;
        }
        if !last_step.is_some_and(|then| same_step(&j.departures, &then)) {
            out.push((row.segment_id, j.steps));
        }
        last_step = Some(j.departures);
    }
    out
}

/// Residual levels within this factor of each other count as the same misfit.
const SAME_MISFIT_RATIO: f64 = 1.5;

/// The first poor fit of a run whose analysis named a cause: what the next poor fits of the
/// run are compared with.
struct ExplainedMisfit {
    departures: [Option<Departure>; 6],
    residual_level: f64,
}

/// Start-ups whose Method B fit is not `good` but which carry on the misfit of the poor fit
/// before them, whose analysis named its cause: no good fit between them, every parameter's
/// offset from the trend of the good results since the wash within tolerance of the analysed
/// one's (`trend::same_step`), and a residual level within [`SAME_MISFIT_RATIO`] of it
/// (`rows`: [`method_b_history`]).
///
/// A fuel meter that reads 3 % high from one day on spoils the fit of every start-up after;
/// the analysis of the first names it, and re-analysing each would cost the gap task an
/// analysis a day (a year's replay, hundreds) and tell nothing new. A run whose first analysis
/// named nothing (`none`, `unexplained`, `ambiguous`) covers nothing: each is analysed. A
/// second effect on top changes the residual or the health and is analysed, as is the misfit
/// again after a good fit or a wash.
pub(crate) fn covered_poor_fits(rows: &[HistoryRow]) -> HashSet<i64> {
    let mut covered = HashSet::new();
    let mut walk = TrendWalk::default();
    let mut explained: Option<ExplainedMisfit> = None;
    for row in rows {
        let j = walk.judge(row);
        // A wash, or a good fit, ends the run.
        if j.washed || j.good {
            explained = None;
        }
        if j.good {
            continue;
        }
        let alike = |e: &ExplainedMisfit| {
            row.residual_level.is_some_and(|r| {
                r > 0.0 && (r / e.residual_level).max(e.residual_level / r) <= SAME_MISFIT_RATIO
            }) && same_step(&j.departures, &e.departures)
        };
        if explained.as_ref().is_some_and(alike) {
            covered.insert(row.segment_id);
            continue;
        }
        explained = row
            .gap_verdict
            .as_deref()
            .filter(|v| crate::gap::names_effect(v))
            .and(row.residual_level)
            .filter(|r| *r > 0.0)
            .map(|residual_level| ExplainedMisfit {
                departures: j.departures,
                residual_level,
            });
    }
    covered
}

/// The next start-up to analyse (oldest first), outside `skip`.
fn next_segment(
    read: &Store,
    ctx: &WorkerContext,
    sel: GapSelection,
    skip: &HashSet<i64>,
) -> Result<Option<i64>, StoreError> {
    // Both selections below walk the Method B history: read once, and only for them.
    let history = if sel.not_good || ctx.settings.gap_on_health_step {
        method_b_history(read)?
    } else {
        Vec::new()
    };
    // A poor fit that carries on an analysed one is left out, unless the schedule picks it.
    let covered: HashSet<i64> = if sel.not_good {
        covered_poor_fits(&history)
            .into_iter()
            .filter(|id| sel.every_n == 0 || id % i64::from(sel.every_n) != 0)
            .collect()
    } else {
        HashSet::new()
    };
    let mut ids: Vec<i64> = read
        .segments_for_gap(sel, skip.len() + covered.len() + 1)?
        .into_iter()
        .filter(|id| !covered.contains(id))
        .collect();
    if ctx.settings.gap_on_health_step {
        for (id, _) in health_steps(&history) {
            if !skip.contains(&id) && read.gap_analyses(id)?.is_empty() {
                ids.push(id);
                break;
            }
        }
    }
    ids.sort_unstable();
    Ok(ids.into_iter().find(|id| !skip.contains(id)))
}

/// Analyses the next start-up that needs it (skipping `skip`), if the diagnosis queue is empty.
pub(crate) fn analyse_next(
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
    let Some(segment_id) = next_segment(db.read(), ctx, sel, skip)? else {
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
    let gap = match analyse_startup(ctx, segment_id, &recording, cancel, ctx.settings.threads) {
        Ok(Some(g)) => g,
        // A cancelled analysis (finished early or failed for it) stores nothing.
        Ok(None) => return Ok(GapStep::Cancelled { segment_id }),
        Err(why) => return failed(why),
    };
    let effect = gap.row.effect.clone();
    let analysis_id = db.write_gap_analysis(gap.row)?;
    Ok(GapStep::Stored {
        segment_id,
        analysis_id,
        effect,
        wall_s: gap.wall_s,
    })
}

/// One start-up's analysis as the daemon makes it: the row to store and the analysis's wall
/// time.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct StartupGap {
    pub(crate) row: NewGapAnalysis,
    pub(crate) wall_s: f64,
}

/// The daemon's gap analysis of start-up `segment_id`: `gap::analyse` with the context's
/// engine and fit settings (its fits on `threads` threads; the result does not depend on
/// them), every candidate of the library, and no held-out start-up (blocked
/// cross-validation). `Ok(None)` when `cancel` stopped it; `Err` when it cannot be made. The
/// fleet's gap jobs (`worker::fleet`) run this very function, so their reports are the edge's.
pub(crate) fn analyse_startup(
    ctx: &WorkerContext,
    segment_id: i64,
    recording: &Recording,
    cancel: &Cancel,
    threads: usize,
) -> Result<Option<StartupGap>, String> {
    let candidates = crate::gap::select("all")?;
    let mut cfg = ctx.settings.fit_config(cancel);
    cfg.threads = Some(threads.max(1));
    let result = crate::gap::analyse(&ctx.engine, recording, None, &candidates, &cfg);
    if cancel.is_cancelled() {
        return Ok(None);
    }
    let report = result.map_err(|e| e.to_string())?;
    let report_json = serde_json::to_string(&report).map_err(|e| e.to_string())?;
    Ok(Some(StartupGap {
        row: NewGapAnalysis {
            segment_id,
            holdout_segment_id: None,
            effect: report.verdict.effect.clone(),
            shrinkage: report.verdict.shrinkage,
            confidence: report.verdict.confidence,
            baseline_fit_quality: report.baseline_fit_quality.as_str().into(),
            normalised_residual: report.baseline_normalised_residual,
            report_json,
        },
        wall_s: report.wall_s,
    }))
}

/// One analysis [`analyse_until_idle`] stored.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub(crate) struct GapDone {
    pub(crate) segment_id: i64,
    pub(crate) analysis_id: i64,
    pub(crate) effect: String,
    pub(crate) wall_s: f64,
}

/// What [`analyse_until_idle`] did.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub(crate) struct GapRun {
    pub(crate) stored: Vec<GapDone>,
    /// Start-ups that could not be analysed, with the reason (skipped for the rest of the run).
    pub(crate) failed: Vec<(i64, String)>,
    /// Whether `cancel` ended the run before the selection was exhausted.
    pub(crate) cancelled: bool,
}

/// The daemon's gap task without the daemon: [`analyse_next`] step after step, in the calling
/// thread, until nothing is selected any more (or `cancel` is set). A start-up that fails is
/// skipped, as the task skips it until the daemon restarts. Used after `gtwatch replay`'s
/// diagnosis, so a replayed log is asked the same gap questions a live unit is; the selection is
/// [`analyse_next`]'s, not repeated here.
pub(crate) fn analyse_until_idle(
    db: &mut impl Db,
    ctx: &WorkerContext,
    cancel: &Cancel,
) -> Result<GapRun, StoreError> {
    let mut run = GapRun::default();
    let mut skip: HashSet<i64> = HashSet::new();
    loop {
        match analyse_next(db, ctx, cancel, &skip)? {
            GapStep::Idle => return Ok(run),
            GapStep::Stored {
                segment_id,
                analysis_id,
                effect,
                wall_s,
            } => run.stored.push(GapDone {
                segment_id,
                analysis_id,
                effect,
                wall_s,
            }),
            GapStep::Cancelled { .. } => {
                run.cancelled = true;
                return Ok(run);
            }
            GapStep::Failed { segment_id, reason } => {
                skip.insert(segment_id);
                run.failed.push((segment_id, reason));
            }
        }
    }
}

/// What the work after a replay did (`gtwatch replay`, `gtwatch bench month|gap-month`): the
/// diagnosis of the pending start-ups, then the gap analyses the settings ask for.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub(crate) struct AfterReplay {
    pub(crate) diagnosed: u64,
    pub(crate) undiagnosable: u64,
    /// Wall time of the diagnosis of the pending start-ups, s.
    pub(crate) diagnose_s: f64,
    /// `None` when the settings ask for no gap analysis.
    pub(crate) gap: Option<GapRun>,
    /// Wall time of the gap analyses, s.
    pub(crate) gap_s: f64,
}
