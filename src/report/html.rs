//! The page: [`render`] turns the gathered [`ReportData`] into one self-contained HTML
//! document (inline CSS and SVG only). Pure string building.

use super::charts::{param_chart, trace_charts};
use super::{gap_section, ReportData};
use crate::chart::esc;
use crate::health::{HealthParams, HEALTH_NAMES};
use crate::time::fmt_ms;
use std::fmt::Write;

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
pub(crate) fn render(d: &ReportData) -> String {
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
        // An instrument's step the wash advice named: the health it corrects this result to.
        if let Some(c) = &r.instrument_step {
            h.push_str("<tr class=\"meta\"><td></td><td class=\"l\">corrected</td><td></td>");
            for i in 0..HEALTH_NAMES.len() {
                let _ = write!(h, "<td>{:.2} ±{:.2}</td>", c.health[i], c.sigma[i]);
            }
            let _ = write!(
                h,
                "<td></td><td class=\"l\">instrument {} from start-up {} on</td></tr>",
                esc(&c.describe()),
                c.onset_segment_id
            );
        }
    }
    h.push_str("</table>");
    if d.history.len() > 100 {
        h.push_str("<p class=\"meta\">Newest 100 shown; `gtwatch history` lists all.</p>");
    }
    h
}
