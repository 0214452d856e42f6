//! Wash advice from the stored history: reads Method B results, records washes the trend
//! detects, fits the fouling trend since the last wash and stores the recommendation.
//!
//! Results whose start-up a stored gap analysis explains by an instrument's error stay in the
//! joint fit of the start-ups since the last wash, which names and sizes an instrument's step
//! once for all the start-ups it moved; one that no step corrects is set aside ([`SetAside`]):
//! a step an instrument made must not move the advice.
//!
//! The one place where `trend` and `wash` (pure) meet the store; called by the diagnosis worker
//! after each stored result and by `gtwatch wash advise`. Reads through a [`Db`] and writes
//! what one refresh found (detected washes, the recommendation, the health corrected for an
//! instrument's step) as one request
//! ([`AdviceWrite`], one transaction; in the daemon through the one writer). Must not fit
//! engine models or hold arithmetic of its own beyond arranging the points.

use crate::diagnosis::fit_quality::Verdict;
use crate::engine::effects::is_instrument;
use crate::engine::Engine;
use crate::gap::sequence::SeqPoint;
use crate::health::{HealthBounds, HEALTH_NAMES};
use crate::store::{
    AdviceWrite, Db, HistoryFilter, HistoryRow, NewRecommendation, NewWash, StoreError, WashRow,
    DETECTED_PREFIX,
};
use crate::trend::{detect_washes, fit_rate, CompressorPoint, RateFit, TrendPoint, WashDetection};
use crate::wash::{advise, sensitivity, FoulingTrend, Sensitivity, WashAdvice, WashEconomics};
use serde::Serialize;

mod step;

use step::{attribute_since, corrections_write, explained_washes};
pub(crate) use step::{step_line, StepAttribution};

const MS_PER_DAY: f64 = 86_400_000.0;

/// Why no advice could be made.
#[derive(Debug, thiserror::Error)]
pub(crate) enum AdviceError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("engine model at base load: {0}")]
    Engine(#[from] crate::engine::EngineError),
}

/// One parameter's trend since the last wash.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct ParamTrend {
    pub(crate) param: &'static str,
    /// `None` with `reason` when it could not be fitted (too few results, …).
    pub(crate) fit: Option<RateFit>,
    pub(crate) reason: Option<String>,
}

/// A Method B result the trends leave out: its start-up's newest gap analysis names an
/// instrument's error (a fuel meter, an inlet thermometer, a sensor), and the joint fit of the
/// start-ups since the last wash names no instrument's step that corrects it, so its health is
/// the instrument's as much as the engine's. A step such a start-up shows neither moves the fouling
/// trend nor counts as a wash.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct SetAside {
    pub(crate) segment_id: i64,
    /// Start of the start-up, Unix ms.
    pub(crate) start_ms: i64,
    /// The instrument effect the gap analysis named (e.g. `fuel_meter`, `sensor_bias:p2_kpa`),
    /// or the instrument an `ambiguous` verdict doubted (see [`HistoryRow::gap_doubted`]).
    pub(crate) effect: String,
}

/// A result the trends leave out because its fit is `poor`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct PoorFit {
    pub(crate) segment_id: i64,
    /// Start of the start-up, Unix ms.
    pub(crate) start_ms: i64,
    /// The verdict of its newest gap analysis, if one is stored (what the model lacked).
    pub(crate) gap_verdict: Option<String>,
}

/// Everything `wash advise` shows.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct AdviceReport {
    /// Results left out of the trends because an instrument explains their start-up.
    pub(crate) set_aside: Vec<SetAside>,
    /// Results left out of the trends because their fit is `poor`: the model does not describe
    /// that start-up (an unmodelled effect, a bad recording), so its health is not the
    /// engine's, and one such start-up would read as a step in every parameter.
    pub(crate) poor_fits: Vec<PoorFit>,
    /// The steps since the last firm wash and what explains each, oldest first (none when no
    /// start-up left the trend).
    pub(crate) steps: Vec<StepAttribution>,
    /// Detected washes (ids) that the step's instrument explains: ignored by the trends, left
    /// for the operator to reject.
    pub(crate) washes_explained: Vec<i64>,
    /// Unix ms of the last wash (recorded or detected), if any.
    pub(crate) last_wash_ms: Option<i64>,
    /// Washes detected (and recorded as such) by this refresh.
    pub(crate) detected_now: Vec<i64>,
    /// Method B results since the last wash.
    pub(crate) results_since_wash: usize,
    /// Trend of each health parameter, days counted from the last wash (or the first result).
    pub(crate) trends: Vec<ParamTrend>,
    pub(crate) sensitivity: Sensitivity,
    /// `None` when D_GC or D_EC has no trend yet.
    pub(crate) advice: Option<WashAdvice>,
    /// Unix ms advised for the next offline wash, when there is advice.
    pub(crate) advised_ms: Option<i64>,
    /// Unix ms the trend is evaluated at (the newest result's start).
    pub(crate) as_of_ms: Option<i64>,
    /// Unix ms of day 0 of the trends: the last wash, else the first result since.
    pub(crate) origin_ms: Option<i64>,
}

/// Recomputes trends and advice from the store, recording detected washes and the new
/// recommendation (deterministic: "now" is the newest result's time, not the wall clock).
pub(crate) fn refresh(
    db: &mut dyn Db,
    engine: &Engine,
    econ: &WashEconomics,
    detection: &WashDetection,
    bounds: &HealthBounds,
) -> Result<AdviceReport, AdviceError> {
    let store = db.read();
    let TrendRows {
        rows,
        explained,
        poor_fits,
    } = trend_rows(store.history(&HistoryFilter {
        method: Some("B".into()),
        ..HistoryFilter::default()
    })?);
    // Washes seen as recovery steps, unless a wash is already stored between the two results.
    let washes = store.washes()?;
    // The steps since the last wash an operator recorded or confirmed, each attributed by a
    // joint fit of those start-ups: an instrument's step is corrected before the trend and
    // wash detection see it (a fuel meter reading high looks like a cleaner compressor).
    let firm_ms = washes
        .iter()
        .filter(|w| !w.is_detected())
        .map(|w| w.t_ms)
        .max();
    let Attributed {
        rows,
        set_aside,
        basis_from,
        steps,
        corrected,
    } = attribute_keeping_explained(store, rows, &explained, firm_ms, &washes, bounds)?;
    // The corrected health of those start-ups, for `history` (written with the advice).
    let corrections = corrections_write(
        &rows[basis_from..],
        &corrected,
        &steps,
        &store.instrument_corrections()?,
    );
    let seen: Vec<SeqPoint> = rows[..basis_from]
        .iter()
        .map(|r| seq_point(r, bounds))
        .chain(corrected)
        .collect();
    // Detected washes the instrument's step explains are not washes.
    let explained = explained_washes(&washes, &rows, basis_from, &steps);
    let washes: Vec<WashRow> = washes
        .into_iter()
        .filter(|w| !explained.contains(&w.id))
        .collect();
    let write_washes = detected_washes(&rows, &seen, &washes, detection);
    let mut write = AdviceWrite {
        washes: write_washes,
        corrections,
        ..AdviceWrite::default()
    };
    let last_wash_ms = washes
        .iter()
        .map(|w| w.t_ms)
        .chain(write.washes.iter().map(|w| w.t_ms))
        .max();
    let since_from = rows
        .iter()
        .position(|r| last_wash_ms.is_none_or(|w| r.start_ms > w))
        .unwrap_or(rows.len());
    let since = &rows[since_from..];
    let seen = &seen[since_from..];
    let origin_ms = last_wash_ms.or(since.first().map(|r| r.start_ms));
    let as_of_ms = since.last().map(|r| r.start_ms);
    let trends: Vec<ParamTrend> = HEALTH_NAMES
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            let pts: Vec<TrendPoint> = since
                .iter()
                .zip(seen)
                .map(|(r, s)| TrendPoint {
                    t_days: (r.start_ms - origin_ms.unwrap_or(0)) as f64 / MS_PER_DAY,
                    value: s.health[i],
                    sigma: s.sigma[i],
                })
                .collect();
            match fit_rate(&pts) {
                Ok(f) => ParamTrend {
                    param: p,
                    fit: Some(f),
                    reason: None,
                },
                Err(e) => ParamTrend {
                    param: p,
                    fit: None,
                    reason: Some(e.to_string()),
                },
            }
        })
        .collect();
    let sens = sensitivity(engine)?;
    let (advice, advised_ms) = match (&trends[0].fit, &trends[1].fit, as_of_ms, origin_ms) {
        (Some(gc), Some(ec), Some(now), Some(origin)) => {
            let age_days = (now - origin) as f64 / MS_PER_DAY;
            let trend = FoulingTrend {
                age_days,
                d_gc_now: gc.value_at(age_days),
                d_ec_now: ec.value_at(age_days),
                d_gc_rate: gc.rate_per_day,
                d_gc_rate_sigma: gc.rate_sigma_per_day,
                d_ec_rate: ec.rate_per_day,
                d_ec_rate_sigma: ec.rate_sigma_per_day,
            };
            let adv = advise(&trend, &sens, econ);
            let ms = adv
                .advised_days
                .map(|d| origin + (d * MS_PER_DAY).round() as i64);
            let basis = serde_json::json!({
                "trend": trend,
                "advice": &adv,
                "sensitivity": &sens,
                "economics": econ,
                "results": since.len(),
                "last_wash_ms": last_wash_ms,
            });
            write.recommendation = Some(NewRecommendation {
                t_ms: now,
                kind: "wash_offline".into(),
                // The stored message is what the report shows: a step an instrument made (or may
                // have made) is part of what the advice rests on.
                message: steps.iter().fold(adv.summary.clone(), |m, st| {
                    format!("{m} {}.", step_line(st))
                }),
                basis: basis.to_string(),
            });
            (Some(adv), ms)
        }
        _ => (None, None),
    };
    let detected_now = if write == AdviceWrite::default() {
        Vec::new()
    } else {
        db.write_advice(write)?
    };
    Ok(AdviceReport {
        set_aside,
        poor_fits,
        steps,
        washes_explained: explained,
        last_wash_ms,
        detected_now,
        results_since_wash: since.len(),
        trends,
        sensitivity: sens,
        advice,
        advised_ms,
        as_of_ms,
        origin_ms,
    })
}

/// The Method B results the trends may use, and those they leave out.
struct TrendRows {
    /// Those the trends may use, the start-ups in `explained` included.
    rows: Vec<HistoryRow>,
    /// The start-ups of `rows` a stored gap analysis explains by an instrument's error.
    explained: Vec<SetAside>,
    poor_fits: Vec<PoorFit>,
}

/// Splits the stored results: those whose fit is `poor` are left out (the model does not
/// describe the start-up), unless a gap analysis explains them by an instrument, which is
/// noted in `explained`; the rest may feed the trends.
fn trend_rows(history: Vec<HistoryRow>) -> TrendRows {
    let mut out = TrendRows {
        rows: Vec::new(),
        explained: Vec::new(),
        poor_fits: Vec::new(),
    };
    let complete = |r: &HistoryRow| HEALTH_NAMES.iter().all(|p| r.value(p).is_finite());
    for r in history.into_iter().filter(complete) {
        if let Some(effect) = instrument_explaining(&r) {
            out.explained.push(SetAside {
                segment_id: r.segment_id,
                start_ms: r.start_ms,
                effect: effect.to_string(),
            });
            out.rows.push(r);
        } else if r.fit_quality.as_deref() == Some(Verdict::Poor.as_str()) {
            out.poor_fits.push(PoorFit {
                segment_id: r.segment_id,
                start_ms: r.start_ms,
                gap_verdict: r.gap_verdict,
            });
        } else {
            out.rows.push(r);
        }
    }
    out
}

/// The rows the trends use, those set aside, and the steps since the last firm wash with the
/// health of the start-ups from `rows[basis_from]` on as the trends see it.
struct Attributed {
    rows: Vec<HistoryRow>,
    set_aside: Vec<SetAside>,
    basis_from: usize,
    steps: Vec<StepAttribution>,
    corrected: Vec<SeqPoint>,
}

/// The steps since the last firm wash (`firm_ms`), attributed by the joint fit of those
/// start-ups ([`attribute_since`]) with the start-ups their own gap analysis explains by an
/// instrument (`explained`) kept in it, so an instrument's step over several start-ups is named
/// and sized once for all of them, even when one of them alone was `ambiguous`. An explained
/// start-up that no step names an instrument for is then set aside (its health is the
/// instrument's as much as the engine's) and the fit made again without it; a start-up before
/// the firm wash is never in a joint fit, so an explained one is set aside at once.
fn attribute_keeping_explained(
    store: &crate::store::Store,
    rows: Vec<HistoryRow>,
    explained: &[SetAside],
    firm_ms: Option<i64>,
    washes: &[WashRow],
    bounds: &HealthBounds,
) -> Result<Attributed, StoreError> {
    let after_firm = |r: &HistoryRow| firm_ms.is_none_or(|w| r.start_ms > w);
    let explained_by = |id: i64| explained.iter().find(|e| e.segment_id == id);
    let mut aside: Vec<i64> = rows
        .iter()
        .filter(|r| explained_by(r.segment_id).is_some() && !after_firm(r))
        .map(|r| r.segment_id)
        .collect();
    // At most three fits: all; without the explained start-ups no step corrected; and, should
    // that fit leave some of the rest uncorrected, without every explained start-up (what the
    // advice did before it kept them, and where this always ends: none is left to uncover).
    let mut refits = 0;
    loop {
        let kept: Vec<HistoryRow> = rows
            .iter()
            .filter(|r| !aside.contains(&r.segment_id))
            .cloned()
            .collect();
        let basis_from = kept.iter().position(after_firm).unwrap_or(kept.len());
        let since = &kept[basis_from..];
        let (steps, corrected) = attribute_since(store, since, washes, bounds)?;
        let uncovered: Vec<i64> = since
            .iter()
            .enumerate()
            .filter(|(j, r)| {
                explained_by(r.segment_id).is_some()
                    && !steps.iter().any(|s| {
                        s.corrected && s.attribution.corrected_range(since.len()).contains(j)
                    })
            })
            .map(|(_, r)| r.segment_id)
            .collect();
        if uncovered.is_empty() {
            let set_aside = explained
                .iter()
                .filter(|e| aside.contains(&e.segment_id))
                .cloned()
                .collect();
            return Ok(Attributed {
                rows: kept,
                set_aside,
                basis_from,
                steps,
                corrected,
            });
        }
        if refits == 0 {
            aside.extend(uncovered);
        } else {
            aside.extend(explained.iter().map(|e| e.segment_id));
        }
        refits += 1;
    }
}

/// The instrument error a start-up's newest gap analysis explains it by, if any: the effect it
/// names, or the candidate an `ambiguous` verdict doubted when that is an instrument (every
/// explanation then left is an instrument's: the doubted one and the input instruments hidden
/// behind the health, so the health is not the engine's either way).
fn instrument_explaining(r: &HistoryRow) -> Option<&str> {
    match (r.gap_verdict.as_deref(), r.gap_doubted.as_deref()) {
        (Some(v), _) if is_instrument(v) => Some(v),
        (Some(crate::gap::AMBIGUOUS), Some(d)) if is_instrument(d) => Some(d),
        _ => None,
    }
}

pub(super) fn seq_point(r: &HistoryRow, bounds: &HealthBounds) -> SeqPoint {
    SeqPoint::new(
        r.start_ms as f64 / MS_PER_DAY,
        std::array::from_fn(|i| r.value(HEALTH_NAMES[i])),
        std::array::from_fn(|i| r.sigma_of(HEALTH_NAMES[i])),
        bounds,
    )
}

/// Washes the trend shows as compressor recovery steps (on the health as `seen`), unless a
/// wash is already stored between the two results.
fn detected_washes(
    rows: &[HistoryRow],
    seen: &[SeqPoint],
    washes: &[WashRow],
    detection: &WashDetection,
) -> Vec<NewWash> {
    let points: Vec<CompressorPoint> = seen
        .iter()
        .map(|p| CompressorPoint {
            t_days: p.t_days,
            d_gc: p.health[0],
            sigma_gc: p.sigma[0],
            d_ec: p.health[1],
            sigma_ec: p.sigma[1],
        })
        .collect();
    let mut out = Vec::new();
    for k in detect_washes(&points, detection) {
        let (a, b) = (rows[k - 1].start_ms, rows[k].start_ms);
        if washes.iter().any(|w| w.t_ms > a && w.t_ms <= b) {
            continue;
        }
        let note =
            format!(
            "{DETECTED_PREFIX} D_GC recovered from {:.2} to {:.2} % between start-ups {} and {}",
            points[k - 1].d_gc, points[k].d_gc, rows[k - 1].segment_id, rows[k].segment_id
        );
        // Stamped just before the start-up that first shows the recovery.
        out.push(NewWash {
            t_ms: b - 1,
            kind: "offline".into(),
            note,
        });
    }
    out
}

/// The worker's after-result hook: refreshes trends and advice after each stored outcome.
/// Errors are logged, never fatal to the worker (the advice is recomputed next time).
pub(crate) fn hook(
    ctx: std::sync::Arc<crate::worker::WorkerContext>,
    econ: WashEconomics,
) -> crate::worker::AfterResult {
    std::sync::Arc::new(move |db: &mut dyn Db, segment_id: i64, _outcome, _wall| {
        match refresh(
            db,
            &ctx.engine,
            &econ,
            &WashDetection::default(),
            &ctx.settings.bounds(),
        ) {
            Ok(r) => {
                if let Some(a) = &r.advice {
                    tracing::info!(segment_id, "wash advice: {}", a.summary);
                }
            }
            Err(e) => tracing::warn!(segment_id, "wash advice not refreshed: {e}"),
        }
    })
}

#[cfg(test)]
mod tests;
