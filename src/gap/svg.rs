//! The gap analysis as an SVG document: the residual map as a heat-map (one row per signal, one
//! column per start-up phase, each cell coloured by its normalised error — white ≤ 1 σ, through
//! yellow, to red ≥ 10 σ — and labelled with the error and its character, bias in σ or
//! lag-like τ), and below it the worst signal measured against the model before and after the
//! winning effect. Pure string building.
//! Must not write files or run the analysis: it draws a result it is given.

use super::{GapReport, SignalTraces};
use crate::chart::{Chart, Series, XAxis, BLUE, GREY, ORANGE};
use crate::diagnosis::fit_quality::ResidualCell;
use crate::signals::{Phase, Signal};
use std::fmt::Write;

const CELL_W: f64 = 110.0;
const CELL_H: f64 = 34.0;
const LEFT: f64 = 90.0;
const TOP: f64 = 60.0;

/// Colour of a normalised error: white at ≤ 1, yellow at ~3, red at ≥ 10 (log scale).
fn colour(e: f64) -> String {
    let x = (e.max(1.0).ln() / 10f64.ln()).clamp(0.0, 1.0);
    let (r, g, b) = if x < 0.5 {
        let u = x / 0.5;
        (255.0, 255.0, 255.0 * (1.0 - u))
    } else {
        let u = (x - 0.5) / 0.5;
        (255.0, 255.0 * (1.0 - u), 0.0)
    };
    format!("rgb({:.0},{:.0},{:.0})", r, g, b)
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The heat-map of `cells` with `title` above it.
pub(crate) fn heat_map(cells: &[ResidualCell], title: &str) -> String {
    let mut signals: Vec<Signal> = Vec::new();
    let mut phases: Vec<Phase> = Vec::new();
    for c in cells {
        if !signals.contains(&c.signal) {
            signals.push(c.signal);
        }
        if !phases.contains(&c.phase) {
            phases.push(c.phase);
        }
    }
    let w = LEFT + CELL_W * phases.len() as f64 + 20.0;
    let h = TOP + CELL_H * signals.len() as f64 + 40.0;
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" font-family="sans-serif" font-size="11">"#
    );
    let _ = write!(
        s,
        r##"<text x="10" y="20" font-size="14">{}</text><text x="10" y="38" fill="#555">normalised error per signal and phase (σ of the instrument noise); white ≤ 1 σ, red ≥ 10 σ</text>"##,
        esc(title)
    );
    for (j, p) in phases.iter().enumerate() {
        let _ = write!(
            s,
            r#"<text x="{:.0}" y="{:.0}" text-anchor="middle">{}</text>"#,
            LEFT + CELL_W * (j as f64 + 0.5),
            TOP - 6.0,
            p
        );
    }
    for (i, sig) in signals.iter().enumerate() {
        let y = TOP + CELL_H * i as f64;
        let _ = write!(
            s,
            r#"<text x="{:.0}" y="{:.0}" text-anchor="end">{}</text>"#,
            LEFT - 6.0,
            y + CELL_H * 0.6,
            sig.column()
        );
        for (j, p) in phases.iter().enumerate() {
            let x = LEFT + CELL_W * j as f64;
            let Some(c) = cells.iter().find(|c| c.signal == *sig && c.phase == *p) else {
                let _ = write!(
                    s,
                    r##"<rect x="{x:.0}" y="{y:.0}" width="{CELL_W:.0}" height="{CELL_H:.0}" fill="#eee" stroke="#fff"/>"##
                );
                continue;
            };
            let note = match c.lag_like_s {
                Some(tau) if c.lag_share > 0.5 && tau.abs() > 0.3 => format!("lag {tau:.1} s"),
                _ => format!("bias {:+.1} σ", c.bias_sigma),
            };
            let _ = write!(
                s,
                r##"<rect x="{x:.0}" y="{y:.0}" width="{CELL_W:.0}" height="{CELL_H:.0}" fill="{}" stroke="#fff"/><text x="{:.0}" y="{:.0}" text-anchor="middle">{:.1} σ</text><text x="{:.0}" y="{:.0}" text-anchor="middle" fill="#444" font-size="9">{}</text>"##,
                colour(c.norm_error),
                x + CELL_W / 2.0,
                y + 14.0,
                c.norm_error,
                x + CELL_W / 2.0,
                y + 27.0,
                esc(&note)
            );
        }
    }
    s.push_str("</svg>\n");
    s
}

/// Width and height an `<svg width="…" height="…"` element declares.
fn size_of(svg: &str) -> (f64, f64) {
    let attr = |name: &str| {
        let key = format!("{name}=\"");
        svg.find(&key)
            .and_then(|i| {
                let rest = &svg[i + key.len()..];
                rest.find('"').and_then(|j| rest[..j].parse::<f64>().ok())
            })
            .unwrap_or(0.0)
    };
    (attr("width"), attr("height"))
}

/// The worst signal measured, modelled before and after the winning effect.
pub(crate) fn traces_chart(tr: &SignalTraces) -> String {
    let t0 = tr.t_s.first().copied().unwrap_or(0.0);
    let line = |label: String, color, dashed, ys: &[f64]| Series::Line {
        label,
        color,
        dashed,
        points: tr
            .t_s
            .iter()
            .zip(ys)
            .filter(|(_, y)| y.is_finite())
            .map(|(t, y)| (t - t0, *y))
            .collect(),
    };
    let mut series = vec![
        line("measured".into(), GREY, false, &tr.measured),
        line("model before".into(), ORANGE, true, &tr.before),
    ];
    if let Some((name, after)) = &tr.after {
        series.push(line(format!("model with {name}"), BLUE, false, after));
    }
    Chart {
        title: format!("{}: measured against the model", tr.signal.column()),
        y_label: tr.signal.column().to_string(),
        x_label: "time since the segment start, s".into(),
        x_axis: XAxis::Seconds,
        width: 900.0,
        height: 320.0,
        series,
        markers: Vec::new(),
    }
    .render()
}

/// The whole document: heat-map, then the worst signal's traces (when the report has them).
pub(crate) fn document(report: &GapReport, title: &str) -> String {
    let map = heat_map(&report.localisation, title);
    let (mw, mh) = size_of(&map);
    let chart = report.worst_signal.as_ref().map(traces_chart);
    let (cw, ch) = chart.as_deref().map_or((0.0, 0.0), size_of);
    let (w, h) = (mw.max(cw), mh + ch);
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}"><style>{}</style>"#,
        crate::chart::STYLE
    );
    s.push_str(map.trim_end());
    if let Some(c) = chart {
        let _ = write!(s, r#"<g transform="translate(0,{mh:.0})">{c}</g>"#);
    }
    s.push_str("</svg>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_row_per_signal_one_column_per_phase() {
        let cell = |signal, phase, e| ResidualCell {
            signal,
            phase,
            samples: 10,
            norm_error: e,
            bias: 0.0,
            bias_sigma: 0.0,
            shift_s: None,
            lag_like_s: Some(4.0),
            lag_share: 0.9,
        };
        let svg = heat_map(
            &[
                cell(Signal::T34, Phase::Acceleration, 6.0),
                cell(Signal::P2, Phase::Acceleration, 0.8),
                cell(Signal::T34, Phase::Loading, 2.0),
            ],
            "t <gap>",
        );
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert_eq!(svg.matches(">t34_k<").count(), 1);
        assert_eq!(svg.matches(">acceleration<").count(), 1);
        assert!(svg.contains("6.0 σ") && svg.contains("lag 4.0 s"));
        assert!(svg.contains("t &lt;gap&gt;"));
        assert_eq!(colour(0.5), "rgb(255,255,255)");
        assert_eq!(colour(100.0), "rgb(255,0,0)");
        // P2 has no loading cell: a grey placeholder.
        assert!(svg.contains("#eee"));
    }

    #[test]
    fn the_document_stacks_the_map_and_the_worst_signal() {
        let t_s: Vec<f64> = (0..50).map(f64::from).collect();
        let tr = SignalTraces {
            signal: Signal::T34,
            measured: t_s.iter().map(|t| 300.0 + 5.0 * t).collect(),
            before: t_s.iter().map(|t| 300.0 + 5.5 * t).collect(),
            after: Some((
                "sensor_lag:t34_k".into(),
                t_s.iter().map(|t| 300.0 + 5.05 * t).collect(),
            )),
            t_s,
        };
        let chart = traces_chart(&tr);
        assert_eq!(size_of(&chart), (900.0, 320.0));
        assert!(chart.contains("model with sensor_lag:t34_k") && chart.contains("model before"));
        assert_eq!(chart.matches("<polyline").count(), 3, "three lines drawn");
        let report = GapReport {
            baseline_fit_quality: crate::diagnosis::fit_quality::Verdict::Suspect,
            baseline_normalised_residual: 1.4,
            fuel_meter_zero: None,
            summary: String::new(),
            localisation: Vec::new(),
            optimiser_spread: 0.0,
            scoring: crate::gap::Scoring::BlockedCv,
            candidates: Vec::new(),
            unscreened: Vec::new(),
            fits: 1,
            threads: 1,
            wall_s: 0.0,
            stage_wall_s: Default::default(),
            verdict: crate::gap::GapVerdict {
                effect: "sensor_lag:t34_k".into(),
                confidence: 0.5,
                shrinkage: 0.6,
                health_before: Default::default(),
                health_after: Default::default(),
                fit_quality_after: crate::diagnosis::fit_quality::Verdict::Good,
                aliases: Vec::new(),
                doubted: None,
            },
            aliases: Default::default(),
            worst_signal: Some(tr),
        };
        let doc = document(&report, "t");
        assert!(doc.starts_with("<svg xmlns") && doc.trim_end().ends_with("</svg>"));
        assert!(doc.contains("<style>") && doc.contains("translate(0,"));
        assert_eq!(doc.matches("<svg").count(), 3, "outer, map, chart");
    }
}
