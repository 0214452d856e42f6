//! The report's charts: a health parameter over time (±σ, washes, the trend since each wash)
//! and the latest start-up's measured against modelled traces with their residuals.

use super::{ReportData, SignalTrace};
use crate::chart::{Chart, Marker, Point, Series, XAxis, BLUE, GREEN, GREY, ORANGE, RED};

pub(super) fn param_chart(d: &ReportData, p: &str, title: &str) -> Chart {
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

pub(super) fn trace_charts(t: &SignalTrace) -> (Chart, Chart) {
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
