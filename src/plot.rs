//! SVG plots of a simulated or recorded start-up: the traces people would rather look at.
//!
//! Five stacked panels sharing the time axis — shaft speeds, temperatures, pressures, fuel flow,
//! power — with the phases as labelled background bands. Renders into a `String` (plotters' SVG
//! backend); the caller decides where it goes. No physics here.
//! Must not write files, run the model or read the store: it draws a trace it is given.

use crate::engine::trace::Trace;
use crate::signals::{Phase, Signal};
use plotters::prelude::*;

fn phase_colour(p: Phase) -> RGBColor {
    let palette = [
        RGBColor(240, 240, 240),
        RGBColor(222, 235, 247),
        RGBColor(198, 219, 239),
        RGBColor(254, 230, 206),
        RGBColor(253, 208, 162),
        RGBColor(229, 245, 224),
        RGBColor(199, 233, 192),
        RGBColor(239, 237, 245),
        RGBColor(218, 218, 235),
        RGBColor(255, 247, 188),
        RGBColor(254, 227, 145),
        RGBColor(252, 187, 161),
    ];
    palette[p.code() as usize % palette.len()]
}

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

/// Renders the start-up traces as an SVG document.
pub fn startup_svg(trace: &Trace, title: &str) -> Result<String, String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 1400)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(title, ("sans-serif", 24))
            .map_err(|e| e.to_string())?;
        let panels = root.split_evenly((5, 1));
        let t0 = trace.t_s.first().copied().unwrap_or(0.0);
        let t1 = trace.t_s.last().copied().unwrap_or(1.0).max(t0 + 1.0);
        let groups: [(&str, &[Signal]); 5] = [
            ("speed [rpm]", &[Signal::N1, Signal::N2]),
            (
                "temperature [K]",
                &[Signal::T2, Signal::T34, Signal::T4, Signal::T3],
            ),
            ("pressure [kPa]", &[Signal::P2, Signal::P34, Signal::P4]),
            ("fuel [kg/s]", &[Signal::FuelFlow]),
            ("power [MW]", &[Signal::Power]),
        ];
        let colours = [BLUE, RED, GREEN, MAGENTA];
        let runs = phase_runs(trace);
        for (panel, (label, signals)) in panels.iter().zip(groups) {
            let series: Vec<Vec<f64>> = signals.iter().map(|s| trace.measured_series(*s)).collect();
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for v in series.iter().flatten().filter(|v| v.is_finite()) {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
            if !lo.is_finite() {
                lo = 0.0;
                hi = 1.0;
            }
            let pad = 0.05 * (hi - lo).max(1e-6);
            let mut chart = ChartBuilder::on(panel)
                .margin(8)
                .x_label_area_size(30)
                .y_label_area_size(70)
                .build_cartesian_2d(t0..t1, (lo - pad)..(hi + pad))
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .y_desc(label)
                .x_desc("time [s]")
                .light_line_style(WHITE.mix(0.0))
                .draw()
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(runs.iter().map(|(p, a, b)| {
                    Rectangle::new([(*a, lo - pad), (*b, hi + pad)], phase_colour(*p).filled())
                }))
                .map_err(|e| e.to_string())?;
            if label.starts_with("speed") {
                chart
                    .draw_series(
                        runs.iter()
                            .filter(|(_, a, b)| b - a > 0.04 * (t1 - t0))
                            .map(|(p, a, _)| {
                                Text::new(
                                    p.name().to_string(),
                                    (*a + 2.0, hi),
                                    ("sans-serif", 12).into_font(),
                                )
                            }),
                    )
                    .map_err(|e| e.to_string())?;
            }
            for ((s, data), colour) in signals.iter().zip(&series).zip(colours) {
                chart
                    .draw_series(LineSeries::new(
                        trace
                            .t_s
                            .iter()
                            .zip(data)
                            .filter(|(_, v)| v.is_finite())
                            .map(|(t, v)| (*t, *v)),
                        colour,
                    ))
                    .map_err(|e| e.to_string())?
                    .label(s.column())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], colour));
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}
