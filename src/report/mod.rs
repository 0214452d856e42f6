//! `gtwatch report`: one self-contained HTML page about the unit, for a plant performance
//! engineer: the six health parameters over time with ±σ, washes and the fouling trend since the
//! last wash; the latest diagnosed start-up's measured against modelled traces with residuals;
//! data gaps and undiagnosable start-ups; the stored wash advice.
//!
//! [`gather`] reads the store (read-only queries) and re-runs the model for the latest start-up;
//! [`render`] turns the gathered [`ReportData`] into HTML (pure). The page has inline CSS and
//! inline SVG only: no script, no image, font or style sheet fetched from anywhere. Must not
//! write to the database (it never records washes or advice, unlike `wash advise`).

use crate::chart::{esc, Chart, Marker, Point, Series, XAxis, BLUE, GREEN, GREY, ORANGE, RED};
use crate::diagnosis::transient::smooth_fuel;
mod gap_section;

use crate::engine::measured_drive::{simulate_segment, DriveMode};
use crate::engine::Engine;
use crate::health::{HealthParams, HEALTH_NAMES};
use crate::query::{list_segments, QueryError};
use crate::signals::Signal;
use crate::store::{
    signal_unit, Gap, GapAnalysisRow, HistoryFilter, HistoryRow, RecommendationRow, Store,
    StoreError, WashRow,
};
use crate::time::fmt_ms;
use crate::trend::{fit_rate, TrendPoint};
use serde::Serialize;
use std::fmt::Write;
use std::path::{Path, PathBuf};

const MS_PER_DAY: f64 = 86_400_000.0;

/// Signals whose traces the report shows (the outputs the transient fit compares).
pub const TRACE_SIGNALS: [Signal; 8] = [
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
pub enum ReportError {
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
pub struct ReportHeader {
    pub plant: String,
    pub db_path: String,
    pub generated_utc: String,
    pub version: String,
}

/// Measured and modelled values of one signal for the latest start-up.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SignalTrace {
    pub signal: String,
    pub unit: String,
    pub t_s: Vec<f64>,
    pub measured: Vec<f64>,
    pub model: Vec<f64>,
    /// RMS of measured − model over the samples where both exist.
    pub rms_residual: f64,
}

/// The latest diagnosed start-up, re-simulated with its stored health.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LatestStartup {
    pub segment_id: i64,
    pub start_utc: String,
    pub health: HealthParams,
    pub fit_quality: Option<String>,
    pub residual_level: Option<f64>,
    pub traces: Vec<SignalTrace>,
    /// Why the model could not be re-run, if it could not.
    pub problem: Option<String>,
}

/// A start-up that was not diagnosed, with the reasons.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Undiagnosed {
    pub segment_id: i64,
    pub start_utc: String,
    pub outcome: String,
    pub reasons: Vec<String>,
}

/// A fitted fouling trend line since the last wash.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrendLine {
    pub param: String,
    pub rate_per_day: f64,
    pub rate_sigma_per_day: f64,
    /// End points (Unix ms, percent).
    pub from: (f64, f64),
    pub to: (f64, f64),
}

/// Everything on the page.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReportData {
    pub header: ReportHeader,
    pub history: Vec<HistoryRow>,
    pub washes: Vec<WashRow>,
    pub trends: Vec<TrendLine>,
    pub latest: Option<LatestStartup>,
    pub gaps: Vec<Gap>,
    pub undiagnosed: Vec<Undiagnosed>,
    /// Stored gap analyses of the period's start-ups, newest first.
    pub gap_analyses: Vec<GapAnalysisRow>,
    pub startups: usize,
    pub advice: Option<RecommendationRow>,
}

/// What `write_report` wrote.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReportSummary {
    pub path: PathBuf,
    pub bytes: usize,
    pub startups: usize,
    pub diagnoses: usize,
    pub washes: usize,
    pub gaps: usize,
    pub undiagnosed: usize,
    pub latest_segment: Option<i64>,
    pub advice: Option<String>,
}

/// Reads what the page shows. `since_ms`/`until_ms` limit the start-ups shown.
pub fn gather(
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
        let mut d = rec.clone();
        match smooth_fuel(&mut d) {
            Ok(()) => d,
            Err(_) => rec.clone(),
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

const CSS: &str = r#"
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;margin:24px;color:#222;max-width:1320px}
h1{font-size:22px;margin:0 0 4px}h2{font-size:18px;margin:28px 0 8px;border-bottom:1px solid #ccc;padding-bottom:4px}
.meta{color:#555;font-size:13px}.advice{background:#f3f7fb;border-left:4px solid #1f5fa8;padding:10px 14px;font-size:15px}
.warn{background:#fff5e6;border-left:4px solid #d9731a;padding:8px 12px}
.grid2{display:flex;flex-wrap:wrap;gap:8px}.stack{display:flex;flex-direction:column}
table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ddd;padding:3px 8px;text-align:right}th{background:#f4f4f4}
td.l,th.l{text-align:left}
"#;

const PARAM_TITLES: [&str; 6] = [
    "D_GC compressor flow capacity",
    "D_EC compressor efficiency",
    "D_GT HP-turbine flow capacity",
    "D_ET HP-turbine efficiency",
    "D_GP power-turbine flow capacity",
    "D_EP power-turbine efficiency",
];

/// The page (pure): its sections in order.
pub fn render(d: &ReportData) -> String {
    let mut h = String::new();
    head(&mut h, d);
    advice_section(&mut h, d);
    health_section(&mut h, d);
    latest_section(&mut h, d);
    undiagnosed_section(&mut h, d);
    h.push_str(&gap_section::render(&d.gap_analyses));
    gaps_section(&mut h, d);
    washes_section(&mut h, d);
    h.push_str("</body></html>\n");
    h
}

/// The document head, title and the line of what the page covers.
fn head(h: &mut String, d: &ReportData) {
    let _ = write!(
        h,
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>gtwatch report: {}</title><style>{CSS}{}svg text{{font-family:inherit}}</style></head><body>",
        esc(&d.header.plant),
        crate::chart::STYLE
    );
    let span = match (d.history.first(), d.history.last()) {
        (Some(a), Some(b)) => format!("{} to {}", date(a.start_ms), date(b.start_ms)),
        _ => "no diagnoses yet".into(),
    };
    let _ = write!(
        h,
        "<h1>gtwatch report: {}</h1><div class=\"meta\">Database {} · start-ups {} · diagnoses {} ({}) · generated {} by gtwatch {}</div>",
        esc(&d.header.plant),
        esc(&d.header.db_path),
        d.startups,
        d.history.len(),
        esc(&span),
        esc(&d.header.generated_utc),
        esc(&d.header.version)
    );
}

/// Advice first: it is what the page is for (and a warning when the latest fit is not good).
fn advice_section(h: &mut String, d: &ReportData) {
    h.push_str("<h2>Wash advice</h2>");
    match &d.advice {
        Some(a) => {
            let _ = write!(
                h,
                "<div class=\"advice\">{}</div><div class=\"meta\">Stored {} (as of the start-up of that time).</div>",
                esc(&a.message),
                esc(&fmt_ms(a.t_ms))
            );
        }
        None => h.push_str(
            "<div class=\"warn\">No wash advice yet: it needs at least three diagnosed start-ups since the last wash.</div>",
        ),
    }
    if let Some(l) = &d.latest {
        if l.fit_quality.as_deref().is_some_and(|q| q != "good") {
            let _ = write!(
                h,
                "<div class=\"warn\">The latest start-up's fit is <b>{}</b> (residual level {}): its health estimate is less trustworthy than σ suggests.</div>",
                esc(l.fit_quality.as_deref().unwrap_or("")),
                l.residual_level.map_or("–".into(), |v| format!("{v:.2}"))
            );
        }
    }
}

/// The health parameters over time: one chart each, the fouling rates, the history table.
fn health_section(h: &mut String, d: &ReportData) {
    h.push_str("<h2>Health parameters over time</h2>");
    if d.history.is_empty() {
        h.push_str("<p class=\"warn\">No diagnoses yet: the charts appear once a start-up has been diagnosed.</p>");
    } else {
        h.push_str("<p class=\"meta\">Percent, positive = degraded. Dots: Method B (transient) with ±1σ bars; squares: Method A (steady-state). Dashed vertical lines: washes (recorded or detected in the trend). Dashed line: fouling trend since the last wash.</p><div class=\"grid2\">");
        for (i, p) in HEALTH_NAMES.iter().enumerate() {
            h.push_str(&param_chart(d, p, PARAM_TITLES[i]).render());
        }
        h.push_str("</div>");
        if !d.trends.is_empty() {
            h.push_str("<table><tr><th class=\"l\">parameter</th><th>fouling rate since the last wash, points/day</th><th>±1σ</th></tr>");
            for t in &d.trends {
                let _ = write!(
                    h,
                    "<tr><td class=\"l\">{}</td><td>{:+.3}</td><td>{:.3}</td></tr>",
                    esc(&t.param),
                    t.rate_per_day,
                    t.rate_sigma_per_day
                );
            }
            h.push_str("</table>");
        }
        h.push_str(&history_table(d));
    }
}

/// The latest diagnosed start-up, measured against the model.
fn latest_section(h: &mut String, d: &ReportData) {
    h.push_str("<h2>Latest diagnosed start-up: measured against model</h2>");
    match &d.latest {
        None => h.push_str("<p class=\"warn\">No diagnosed start-up yet.</p>"),
        Some(l) => {
            let _ = write!(
                h,
                "<p class=\"meta\">Segment {} starting {}; model run with the stored Method B health ({}) on the stored samples, driven by the measured fuel flow. Fit quality: {}. Orange: model; blue: measured (drawn over the model); below each, the residual (measured − model).</p>",
                l.segment_id,
                esc(&l.start_utc),
                esc(&health_text(&l.health)),
                esc(l.fit_quality.as_deref().unwrap_or("–"))
            );
            if let Some(p) = &l.problem {
                let _ = write!(h, "<p class=\"warn\">{}</p>", esc(p));
            }
            h.push_str("<div class=\"grid2\">");
            for t in &l.traces {
                let (trace, resid) = trace_charts(t);
                let _ = write!(
                    h,
                    "<div class=\"stack\">{}{}</div>",
                    trace.render(),
                    resid.render()
                );
            }
            h.push_str("</div>");
        }
    }
}

/// The start-ups that were not diagnosed, and why.
fn undiagnosed_section(h: &mut String, d: &ReportData) {
    h.push_str("<h2>Start-ups not diagnosed</h2>");
    if d.undiagnosed.is_empty() {
        h.push_str("<p class=\"meta\">None: every closed start-up has a result.</p>");
    } else {
        h.push_str("<table><tr><th>segment</th><th class=\"l\">start (UTC)</th><th class=\"l\">outcome</th><th class=\"l\">why not diagnosed</th></tr>");
        for u in &d.undiagnosed {
            let _ = write!(
                h,
                "<tr><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
                u.segment_id,
                esc(&u.start_utc),
                esc(&u.outcome),
                esc(&u.reasons.join("; "))
            );
        }
        h.push_str("</table>");
    }
}

/// The recorded data gaps (the first 200).
fn gaps_section(h: &mut String, d: &ReportData) {
    h.push_str("<h2>Data gaps</h2>");
    if d.gaps.is_empty() {
        h.push_str("<p class=\"meta\">None recorded in this period.</p>");
    } else {
        let total: f64 = d
            .gaps
            .iter()
            .map(|g| (g.end_ms - g.start_ms) as f64 / 1000.0)
            .sum();
        let _ = write!(
            h,
            "<p class=\"meta\">{} gap(s), {:.0} s in all.</p><table><tr><th class=\"l\">from (UTC)</th><th class=\"l\">to (UTC)</th><th>duration, s</th><th class=\"l\">source</th><th class=\"l\">reason</th></tr>",
            d.gaps.len(),
            total
        );
        for g in d.gaps.iter().take(200) {
            let _ = write!(
                h,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{:.1}</td><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
                esc(&fmt_ms(g.start_ms)),
                esc(&fmt_ms(g.end_ms)),
                (g.end_ms - g.start_ms) as f64 / 1000.0,
                esc(&g.source),
                esc(&g.reason)
            );
        }
        h.push_str("</table>");
        if d.gaps.len() > 200 {
            let _ = write!(
                h,
                "<p class=\"meta\">… and {} more (see the v_gaps view).</p>",
                d.gaps.len() - 200
            );
        }
    }
}

/// The washes, recorded or detected.
fn washes_section(h: &mut String, d: &ReportData) {
    h.push_str("<h2>Washes</h2>");
    if d.washes.is_empty() {
        h.push_str("<p class=\"meta\">None recorded or detected.</p>");
    } else {
        h.push_str("<table><tr><th class=\"l\">time (UTC)</th><th class=\"l\">kind</th><th class=\"l\">source</th><th class=\"l\">note</th></tr>");
        for w in &d.washes {
            let _ = write!(
                h,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
                esc(&fmt_ms(w.t_ms)),
                esc(&w.kind),
                if w.is_detected() { "detected in the trend" } else { "recorded by the operator" },
                esc(&w.note)
            );
        }
        h.push_str("</table>");
    }
}

fn date(ms: i64) -> String {
    fmt_ms(ms).get(..10).unwrap_or("").to_string()
}

fn health_text(h: &HealthParams) -> String {
    HEALTH_NAMES
        .iter()
        .zip(h.to_array())
        .map(|(n, v)| format!("{n} {v:.2}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn param_chart(d: &ReportData, p: &str, title: &str) -> Chart {
    let pts = |m: &str| -> Vec<Point> {
        d.history
            .iter()
            .filter(|h| h.method == m)
            .filter_map(|h| {
                Some(Point {
                    x: h.start_ms as f64,
                    y: *h.health.get(p)?,
                    sigma: h.sigma.get(p).copied(),
                })
            })
            .collect()
    };
    let mut series = vec![
        Series::Markers {
            label: "Method B".into(),
            color: BLUE,
            hollow: false,
            points: pts("B"),
        },
        Series::Markers {
            label: "Method A".into(),
            color: GREY,
            hollow: true,
            points: pts("A"),
        },
    ];
    if let Some(t) = d.trends.iter().find(|t| t.param == p) {
        series.push(Series::Line {
            label: format!("trend {:+.3}/day", t.rate_per_day),
            color: ORANGE,
            dashed: true,
            points: vec![t.from, t.to],
        });
    }
    let markers = d
        .washes
        .iter()
        .map(|w| Marker {
            x: w.t_ms as f64,
            label: if w.is_detected() {
                "wash (detected)".into()
            } else {
                "wash".into()
            },
            color: GREEN,
        })
        .collect();
    Chart {
        title: title.into(),
        y_label: format!("{p}, %"),
        x_label: "start-up date (UTC)".into(),
        x_axis: XAxis::Date,
        width: 430.0,
        height: 260.0,
        series,
        markers,
    }
}

fn trace_charts(t: &SignalTrace) -> (Chart, Chart) {
    let line =
        |v: &[f64]| -> Vec<(f64, f64)> { t.t_s.iter().copied().zip(v.iter().copied()).collect() };
    let resid: Vec<(f64, f64)> = t
        .t_s
        .iter()
        .zip(t.measured.iter().zip(&t.model))
        .map(|(&x, (m, p))| (x, m - p))
        .collect();
    let trace = Chart {
        title: format!("{} ({})", t.signal, t.unit),
        y_label: t.unit.clone(),
        x_label: "time from segment start, s".into(),
        x_axis: XAxis::Seconds,
        width: 430.0,
        height: 220.0,
        // The model first, the measurement over it: otherwise the smooth model line hides
        // the noisy measurement completely where they agree.
        series: vec![
            Series::Line {
                label: "model".into(),
                color: ORANGE,
                dashed: false,
                points: line(&t.model),
            },
            Series::Line {
                label: "measured".into(),
                color: BLUE,
                dashed: false,
                points: line(&t.measured),
            },
        ],
        markers: vec![],
    };
    let res = Chart {
        title: format!("residual, RMS {:.3} {}", t.rms_residual, t.unit),
        y_label: t.unit.clone(),
        x_label: "time from segment start, s".into(),
        x_axis: XAxis::Seconds,
        width: 430.0,
        height: 150.0,
        series: vec![Series::Line {
            label: String::new(),
            color: RED,
            dashed: false,
            points: resid,
        }],
        markers: vec![],
    };
    (trace, res)
}

fn history_table(d: &ReportData) -> String {
    let mut h = String::from("<h2>Results</h2><table><tr><th>segment</th><th class=\"l\">start (UTC)</th><th>method</th>");
    for n in HEALTH_NAMES {
        let _ = write!(h, "<th>{n} ±σ</th>");
    }
    h.push_str("<th>residual level</th><th class=\"l\">fit</th></tr>");
    for r in d.history.iter().rev().take(100) {
        let _ = write!(
            h,
            "<tr><td>{}</td><td class=\"l\">{}</td><td>{}</td>",
            r.segment_id,
            esc(&r.start_utc),
            esc(&r.method)
        );
        for n in HEALTH_NAMES {
            let v = r.health.get(n).map_or("–".into(), |v| format!("{v:.2}"));
            let s = r
                .sigma
                .get(n)
                .map_or(String::new(), |s| format!(" ±{s:.2}"));
            let _ = write!(h, "<td>{v}{s}</td>");
        }
        let _ = write!(
            h,
            "<td>{}</td><td class=\"l\">{}</td></tr>",
            r.residual_level.map_or("–".into(), |v| format!("{v:.2}")),
            esc(r.fit_quality.as_deref().unwrap_or("–"))
        );
    }
    h.push_str("</table>");
    if d.history.len() > 100 {
        h.push_str("<p class=\"meta\">Newest 100 shown; `gtwatch history` lists all.</p>");
    }
    h
}

/// Gathers, renders and writes `out_dir/report.html`.
pub fn write_report(
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
pub fn header_now(plant: &str, db_path: &Path) -> ReportHeader {
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
