//! The start-up plot (`gtwatch simulate --plot`): five stacked charts sharing the time axis —
//! shaft speeds, temperatures, pressures, fuel flow, power — with the phase changes as vertical
//! markers, named on the top chart. One standalone SVG document drawn with [`Chart`]; the
//! caller decides where it goes.
//! Must not write files, run the model or read the store: it draws a trace it is given.

use super::{esc, Chart, Marker, Series, XAxis, BLUE, GREEN, GREY, ORANGE, RED, STYLE};
use crate::engine::trace::Trace;
use crate::signals::{Phase, Signal};
use std::fmt::Write;

const WIDTH: f64 = 1200.0;
/// The plot area's width within [`WIDTH`] (the chart's left and right margins taken off).
const PLOT_WIDTH_PX: f64 = WIDTH - 80.0;
const PANEL_HEIGHT: f64 = 270.0;
/// Height of the document's title line above the panels.
const TITLE_HEIGHT: f64 = 36.0;

/// The panels, top to bottom: axis label and signals.
const PANELS: [(&str, &[Signal]); 5] = [
    ("speed [rpm]", &[Signal::N1, Signal::N2]),
    (
        "temperature [K]",
        &[Signal::T2, Signal::T34, Signal::T4, Signal::T3],
    ),
    ("pressure [kPa]", &[Signal::P2, Signal::P34, Signal::P4]),
    ("fuel [kg/s]", &[Signal::FuelFlow]),
    ("power [MW]", &[Signal::Power]),
];

const COLOURS: [&str; 4] = [BLUE, RED, GREEN, ORANGE];

/// Contiguous runs of one phase: (phase, t_start, t_end).
fn phase_runs(trace: &Trace) -> Vec<(Phase, f64, f64)> {
    let mut runs: Vec<(Phase, f64, f64)> = Vec::new();
    for (k, &p) in trace.phase.iter().enumerate() {
        let t = trace.t_s[k];
        match runs.last_mut() {
            Some(last) if last.0 == p => last.2 = t,
            _ => runs.push((p, t, t)),
        }
    }
    runs
}

/// A marker at the start of every phase after the first; named (on the top panel only) where
/// the phase lasts long enough for its name to fit before the next marker (11 px type, about
/// 6.5 px a character, across the panel's plot width).
fn phase_markers(runs: &[(Phase, f64, f64)], named: bool) -> Vec<Marker> {
    let t0 = runs.first().map_or(0.0, |r| r.1);
    let t1 = runs.last().map_or(1.0, |r| r.2).max(t0 + 1.0);
    runs.iter()
        .skip(1)
        .map(|(p, a, b)| Marker {
            x: *a,
            label: if named
                && (b - a) / (t1 - t0) * PLOT_WIDTH_PX >= 6.5 * p.name().len() as f64 + 8.0
            {
                p.name().to_string()
            } else {
                String::new()
            },
            color: GREY,
        })
        .collect()
}

/// One panel: its signals' measured traces against time.
fn panel(trace: &Trace, label: &str, signals: &[Signal], markers: Vec<Marker>) -> Chart {
    let series = signals
        .iter()
        .zip(COLOURS)
        .map(|(s, color)| Series::Line {
            label: s.column().to_string(),
            color,
            dashed: false,
            points: trace
                .t_s
                .iter()
                .copied()
                .zip(trace.measured_series(*s))
                .collect(),
        })
        .collect();
    Chart {
        title: label.to_string(),
        y_label: label.to_string(),
        x_label: "time [s]".into(),
        x_axis: XAxis::Seconds,
        width: WIDTH,
        height: PANEL_HEIGHT,
        series,
        markers,
    }
}

/// Renders the start-up traces as an SVG document.
pub(crate) fn startup_svg(trace: &Trace, title: &str) -> String {
    let runs = phase_runs(trace);
    let height = TITLE_HEIGHT + PANEL_HEIGHT * PANELS.len() as f64;
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH:.0}" height="{height:.0}"><style>{STYLE}</style><rect width="100%" height="100%" fill="white"/><text x="16" y="24" class="title">{}</text>"#,
        esc(title)
    );
    for (k, (label, signals)) in PANELS.iter().enumerate() {
        let chart = panel(trace, label, signals, phase_markers(&runs, k == 0));
        let _ = write!(
            s,
            r#"<g transform="translate(0,{:.0})">{}</g>"#,
            TITLE_HEIGHT + PANEL_HEIGHT * k as f64,
            chart.render()
        );
    }
    s.push_str("</svg>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::simulation::run_scenario;
    use crate::engine::{Engine, Scenario};
    use crate::health::HealthParams;

    #[test]
    fn the_startup_plot_has_five_panels_every_signal_and_the_phases() {
        let engine = Engine::reference().unwrap();
        let model = engine.model(&HealthParams::HEALTHY);
        let (samples, _) = run_scenario(&model, &Scenario::startup(engine.cfg())).unwrap();
        let trace = Trace::from_truth(&engine, &samples, None);
        let svg = startup_svg(&trace, "start-up <test>");
        assert!(svg.starts_with("<svg xmlns=\"http://www.w3.org/2000/svg\""));
        assert!(svg.contains("start-up &lt;test&gt;"), "title escaped");
        assert_eq!(
            svg.matches("<svg").count(),
            6,
            "the document and five panels"
        );
        assert!(!svg.contains("no data"));
        for (_, signals) in PANELS {
            for s in signals {
                assert!(
                    svg.contains(&format!(">{}</text>", s.column())),
                    "{s:?} in a legend"
                );
            }
        }
        let runs = phase_runs(&trace);
        assert!(runs.len() > 2, "a start-up passes through several phases");
        let named = runs.iter().skip(1).any(|(p, _, _)| svg.contains(p.name()));
        assert!(named, "phase names on the top panel");
    }
}
