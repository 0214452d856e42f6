//! Wash advice from the stored history: reads Method B results, records washes the trend
//! detects, fits the fouling trend since the last wash and stores the recommendation.
//!
//! Results whose start-up a stored gap analysis explains by an instrument's error are set aside
//! ([`SetAside`]): a step an instrument made must not move the advice.
//!
//! The one place where `trend` and `wash` (pure) meet the store; called by the diagnosis worker
//! after each stored result and by `gtwatch wash advise`. Reads through a [`Db`] and writes
//! what one refresh found (detected washes, the recommendation) as one request
//! ([`AdviceWrite`], one transaction; in the daemon through the one writer). Must not fit
//! engine models or hold arithmetic of its own beyond arranging the points.

use crate::engine::effects::is_instrument;
use crate::engine::Engine;
use crate::health::HEALTH_NAMES;
use crate::store::{
    AdviceWrite, Db, HistoryFilter, HistoryRow, NewRecommendation, NewWash, StoreError,
    DETECTED_PREFIX,
};
use crate::trend::{detect_washes, fit_rate, CompressorPoint, RateFit, TrendPoint, WashDetection};
use crate::wash::{advise, sensitivity, FoulingTrend, Sensitivity, WashAdvice, WashEconomics};
use serde::Serialize;

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
/// instrument's error (a fuel meter, an inlet thermometer, a sensor), so its health is the
/// instrument's as much as the engine's. A step such a start-up shows neither moves the fouling
/// trend nor counts as a wash.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct SetAside {
    pub(crate) segment_id: i64,
    /// Start of the start-up, Unix ms.
    pub(crate) start_ms: i64,
    /// The instrument effect the gap analysis named (e.g. `fuel_meter`, `sensor_bias:p2_kpa`).
    pub(crate) effect: String,
}

/// Everything `wash advise` shows.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct AdviceReport {
    /// Results left out of the trends because an instrument explains their start-up.
    pub(crate) set_aside: Vec<SetAside>,
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
) -> Result<AdviceReport, AdviceError> {
    let store = db.read();
    let (set_aside, rows): (Vec<HistoryRow>, Vec<HistoryRow>) = store
        .history(&HistoryFilter {
            method: Some("B".into()),
            ..HistoryFilter::default()
        })?
        .into_iter()
        .filter(|r| HEALTH_NAMES.iter().all(|p| r.value(p).is_finite()))
        .partition(|r| r.gap_verdict.as_deref().is_some_and(is_instrument));
    let set_aside: Vec<SetAside> = set_aside
        .into_iter()
        .map(|r| SetAside {
            segment_id: r.segment_id,
            start_ms: r.start_ms,
            effect: r.gap_verdict.unwrap_or_default(),
        })
        .collect();
    // Washes seen as recovery steps, unless a wash is already stored between the two results.
    let washes = store.washes()?;
    let points: Vec<CompressorPoint> = rows
        .iter()
        .map(|r| CompressorPoint {
            t_days: r.start_ms as f64 / MS_PER_DAY,
            d_gc: r.value("D_GC"),
            sigma_gc: r.sigma_of("D_GC"),
            d_ec: r.value("D_EC"),
            sigma_ec: r.sigma_of("D_EC"),
        })
        .collect();
    let mut write = AdviceWrite::default();
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
        write.washes.push(NewWash {
            t_ms: b - 1,
            kind: "offline".into(),
            note,
        });
    }
    let last_wash_ms = washes
        .iter()
        .map(|w| w.t_ms)
        .chain(write.washes.iter().map(|w| w.t_ms))
        .max();
    let since: Vec<&HistoryRow> = rows
        .iter()
        .filter(|r| last_wash_ms.is_none_or(|w| r.start_ms > w))
        .collect();
    let origin_ms = last_wash_ms.or(since.first().map(|r| r.start_ms));
    let as_of_ms = since.last().map(|r| r.start_ms);
    let trends: Vec<ParamTrend> = HEALTH_NAMES
        .iter()
        .map(|&p| {
            let pts: Vec<TrendPoint> = since
                .iter()
                .map(|r| TrendPoint {
                    t_days: (r.start_ms - origin_ms.unwrap_or(0)) as f64 / MS_PER_DAY,
                    value: r.value(p),
                    sigma: r.sigma_of(p),
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
                message: adv.summary.clone(),
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

/// The worker's after-result hook: refreshes trends and advice after each stored outcome.
/// Errors are logged, never fatal to the worker (the advice is recomputed next time).
pub(crate) fn hook(
    ctx: std::sync::Arc<crate::worker::WorkerContext>,
    econ: WashEconomics,
) -> crate::worker::AfterResult {
    std::sync::Arc::new(move |db: &mut dyn Db, segment_id: i64, _outcome| {
        match refresh(db, &ctx.engine, &econ, &WashDetection::default()) {
            Ok(r) => {
                if let Some(a) = &r.advice {
                    tracing::info!(segment_id, "wash advice: {}", a.summary);
                }
            }
            Err(e) => tracing::warn!(segment_id, "wash advice not refreshed: {e}"),
        }
    })
}
