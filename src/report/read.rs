//! Reading what the report shows: the store's read-only queries over the period, the trend
//! lines since each wash, and the latest diagnosed start-up re-run through the model.

use super::{
    gap_section, LatestStartup, ReportData, ReportError, ReportHeader, SignalTrace, TrendLine,
    Undiagnosed, TRACE_SIGNALS,
};
use crate::diagnosis::transient::smooth_fuel;
use crate::engine::measured_drive::{simulate_segment, DriveMode};
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::query::list_segments;
use crate::store::{signal_unit, HistoryFilter, HistoryRow, Store, WashRow};
use crate::time::fmt_ms;
use crate::trend::{fit_rate, TrendPoint};

const MS_PER_DAY: f64 = 86_400_000.0;

/// Reads what the page shows. `since_ms`/`until_ms` limit the start-ups shown.
pub(crate) fn gather(
    store: &Store,
    engine: &Engine,
    header: ReportHeader,
    since_ms: Option<i64>,
    until_ms: Option<i64>,
) -> Result<ReportData, ReportError> {
    let history = store.history(&HistoryFilter {
        since_ms,
        until_ms,
        method: None,
    })?;
    let washes = store.washes()?;
    let segments = list_segments(store, since_ms)?;
    let segments: Vec<_> = segments
        .into_iter()
        .filter(|s| until_ms.is_none_or(|u| s.start_ms <= u))
        .collect();
    let mut undiagnosed = Vec::new();
    for s in &segments {
        let has_result = history.iter().any(|h| h.segment_id == s.id);
        let reasons: Vec<String> = store
            .undiagnosable_reasons(s.id)?
            .into_iter()
            .map(|(m, r, d)| {
                format!(
                    "{}{r}{}",
                    m.map(|m| format!("method {m}: ")).unwrap_or_default(),
                    if d.is_empty() {
                        String::new()
                    } else {
                        format!(" ({d})")
                    }
                )
            })
            .collect();
        if !has_result && !reasons.is_empty() {
            undiagnosed.push(Undiagnosed {
                segment_id: s.id,
                start_utc: fmt_ms(s.start_ms),
                outcome: s.outcome.as_str().to_string(),
                reasons,
            });
        }
    }
    let lo = since_ms
        .or(segments.first().map(|s| s.start_ms))
        .unwrap_or(0);
    let hi = until_ms.unwrap_or(i64::MAX);
    let gaps = store.gaps_between(lo, hi)?;
    let gap_analyses = store.gap_analyses_between(lo, hi, gap_section::MAX_ROWS)?;
    let trends = trend_lines(&history, &washes);
    let latest = history
        .iter()
        .filter(|h| h.method == "B")
        .max_by_key(|h| h.start_ms)
        .map(|h| latest_startup(store, engine, h))
        .transpose()?;
    let advice = store.latest_recommendation()?;
    Ok(ReportData {
        header,
        history,
        washes,
        trends,
        latest,
        gaps,
        undiagnosed,
        gap_analyses,
        startups: segments.len(),
        advice,
    })
}

/// Fouling trend lines of D_GC and D_EC (Method B) since the last wash.
fn trend_lines(history: &[HistoryRow], washes: &[WashRow]) -> Vec<TrendLine> {
    let last_wash = washes.iter().map(|w| w.t_ms).max();
    let rows: Vec<&HistoryRow> = history
        .iter()
        .filter(|h| h.method == "B" && last_wash.is_none_or(|w| h.start_ms > w))
        .collect();
    let Some(origin) = last_wash.or(rows.first().map(|r| r.start_ms)) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for p in ["D_GC", "D_EC"] {
        let pts: Vec<TrendPoint> = rows
            .iter()
            .filter_map(|r| {
                Some(TrendPoint {
                    t_days: (r.start_ms - origin) as f64 / MS_PER_DAY,
                    value: *r.health.get(p)?,
                    sigma: r.sigma.get(p).copied().unwrap_or(f64::NAN),
                })
            })
            .collect();
        if let (Ok(f), Some(last)) = (fit_rate(&pts), pts.last()) {
            let t0 = pts.first().map_or(0.0, |p| p.t_days);
            out.push(TrendLine {
                param: p.to_string(),
                rate_per_day: f.rate_per_day,
                rate_sigma_per_day: f.rate_sigma_per_day,
                from: (origin as f64 + t0 * MS_PER_DAY, f.value_at(t0)),
                to: (
                    origin as f64 + last.t_days * MS_PER_DAY,
                    f.value_at(last.t_days),
                ),
            });
        }
    }
    out
}

fn health_of(row: &HistoryRow) -> HealthParams {
    let g = |n: &str| row.health.get(n).copied().unwrap_or(0.0);
    HealthParams {
        D_GC: g("D_GC"),
        D_EC: g("D_EC"),
        D_GT: g("D_GT"),
        D_ET: g("D_ET"),
        D_GP: g("D_GP"),
        D_EP: g("D_EP"),
    }
}

/// Re-runs the model on the stored recording with the stored health, driven by the measured
/// (smoothed) fuel flow as the transient fit is.
fn latest_startup(
    store: &Store,
    engine: &Engine,
    row: &HistoryRow,
) -> Result<LatestStartup, ReportError> {
    let health = health_of(row);
    let mut out = LatestStartup {
        segment_id: row.segment_id,
        start_utc: row.start_utc.clone(),
        health,
        fit_quality: row.fit_quality.clone(),
        residual_level: row.residual_level,
        traces: Vec::new(),
        problem: None,
    };
    let rec = match store.segment_recording(row.segment_id)? {
        Some(s) => s.recording,
        None => {
            out.problem = Some("the segment is no longer in the database".into());
            return Ok(out);
        }
    };
    let mut rec = match rec {
        Ok(r) => r,
        Err(e) => {
            out.problem = Some(format!("stored samples unusable: {e}"));
            return Ok(out);
        }
    };
    let drive = {
        // As the diagnosis replayed it: the fuel meter's zero off (see `fuel_zero_removed`).
        let corrected = rec.fuel_zero_removed().0.into_owned();
        let mut d = corrected.clone();
        match smooth_fuel(&mut d) {
            Ok(()) => d,
            Err(_) => corrected,
        }
    };
    let trace = match simulate_segment(engine, &health, &drive, DriveMode::MeasuredFuel) {
        Ok(t) => t,
        Err(e) => {
            out.problem = Some(format!("the model could not be re-run: {e}"));
            return Ok(out);
        }
    };
    // Times from the segment's first sample.
    rec = rec.shifted_to_zero();
    for s in TRACE_SIGNALS {
        let i = s.index();
        let measured: Vec<f64> = rec.rows().iter().map(|r| r[i]).collect();
        let model: Vec<f64> = trace.measured.iter().map(|v| v[i]).collect();
        let (mut ss, mut n) = (0.0, 0usize);
        for (m, p) in measured.iter().zip(&model) {
            if m.is_finite() && p.is_finite() {
                ss += (m - p).powi(2);
                n += 1;
            }
        }
        out.traces.push(SignalTrace {
            signal: s.column().to_string(),
            unit: signal_unit(s).to_string(),
            t_s: rec.times().to_vec(),
            measured,
            model,
            rms_residual: if n > 0 {
                (ss / n as f64).sqrt()
            } else {
                f64::NAN
            },
        });
    }
    Ok(out)
}
