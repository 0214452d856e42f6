//! The fleet report (`gtwatch fleet report`): one self-contained HTML page over every unit at a
//! fleet centre — the units ranked by compressor fouling rate since their last wash, each with
//! its newest advised wash, then each unit's D_GC / D_EC trend.
//!
//! Pure: builds the page from rows the caller read from the centre ([`crate::fleet`]). Must not
//! read a database or refer to anything outside the page (no scripts, fonts or images by URL).

use crate::chart::{esc, Chart, Marker, Point, Series, XAxis, BLUE, GREY, ORANGE, STYLE};
use crate::fleet::{FleetAdvice, FleetHistoryRow, FleetWash};
use crate::time::fmt_ms_rfc3339;
use crate::trend::{fit_rate, RateFit, TrendPoint};
use std::collections::BTreeSet;
use std::fmt::Write;

const MS_PER_DAY: f64 = 86_400_000.0;

/// One unit's line of the ranking.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct UnitLine {
    pub(crate) unit_id: String,
    /// Method B results since the unit's last wash.
    pub(crate) results_since_wash: usize,
    pub(crate) last_wash_ms: Option<i64>,
    pub(crate) newest_ms: Option<i64>,
    /// D_GC's fouling rate since the last wash (`None`: fewer than three results).
    pub(crate) d_gc: Option<RateFit>,
    pub(crate) d_ec: Option<RateFit>,
    /// Unix ms the unit's newest advice names for the next offline wash.
    pub(crate) advised_ms: Option<i64>,
    pub(crate) advice: Option<String>,
}

/// The advised wash time in an advice's basis: `advised_days` counted from the trend's origin,
/// which lies `age_days` before the advice.
fn advised_ms(a: &FleetAdvice) -> Option<i64> {
    let basis: serde_json::Value = serde_json::from_str(&a.basis).ok()?;
    let advised = basis["advice"]["advised_days"].as_f64()?;
    let age = basis["trend"]["age_days"].as_f64()?;
    Some(a.t_ms + ((advised - age) * MS_PER_DAY).round() as i64)
}

/// A parameter's rate since `since_ms` from a unit's Method B rows.
fn rate(rows: &[&FleetHistoryRow], param: &str, since_ms: Option<i64>) -> Option<RateFit> {
    let origin = since_ms.or(rows.first().map(|r| r.start_ms)).unwrap_or(0);
    let pts: Vec<TrendPoint> = rows
        .iter()
        .filter_map(|r| {
            let (value, sigma) = r.trend_value(param)?;
            Some(TrendPoint {
                t_days: (r.start_ms - origin) as f64 / MS_PER_DAY,
                value,
                sigma: sigma.unwrap_or(f64::NAN),
            })
        })
        .collect();
    fit_rate(&pts).ok()
}

/// Every unit's ranking line, the fastest-fouling compressor first (units without a rate last,
/// by name).
pub(crate) fn rank(
    rows: &[FleetHistoryRow],
    washes: &[FleetWash],
    advice: &[FleetAdvice],
) -> Vec<UnitLine> {
    let units: BTreeSet<&str> = rows
        .iter()
        .map(|r| r.unit_id.as_str())
        .chain(washes.iter().map(|w| w.unit_id.as_str()))
        .chain(advice.iter().map(|a| a.unit_id.as_str()))
        .collect();
    let mut lines: Vec<UnitLine> = units
        .into_iter()
        .map(|u| {
            let last_wash_ms = washes
                .iter()
                .filter(|w| w.unit_id == u)
                .map(|w| w.t_ms)
                .max();
            let since: Vec<&FleetHistoryRow> = rows
                .iter()
                .filter(|r| r.unit_id == u && r.method == "B")
                .filter(|r| last_wash_ms.is_none_or(|w| r.start_ms > w))
                .collect();
            let adv = advice.iter().find(|a| a.unit_id == u);
            UnitLine {
                unit_id: u.to_string(),
                results_since_wash: since.len(),
                last_wash_ms,
                newest_ms: since.last().map(|r| r.start_ms),
                d_gc: rate(&since, "D_GC", last_wash_ms),
                d_ec: rate(&since, "D_EC", last_wash_ms),
                advised_ms: adv.and_then(advised_ms),
                advice: adv.map(|a| a.message.clone()),
            }
        })
        .collect();
    lines.sort_by(|a, b| {
        let key = |l: &UnitLine| l.d_gc.map_or(f64::NEG_INFINITY, |f| f.rate_per_day);
        key(b).total_cmp(&key(a)).then(a.unit_id.cmp(&b.unit_id))
    });
    lines
}

fn date(ms: Option<i64>) -> String {
    ms.map_or("–".into(), |t| fmt_ms_rfc3339(t)[..10].to_string())
}

fn rate_cell(f: Option<&RateFit>) -> String {
    f.map_or("–".into(), |f| {
        format!("{:+.3} ± {:.3}", f.rate_per_day, f.rate_sigma_per_day)
    })
}

/// One unit's D_GC and D_EC (Method B) against time, its washes as markers.
fn unit_chart(unit: &str, rows: &[FleetHistoryRow], washes: &[FleetWash]) -> Chart {
    let pts = |p: &str| -> Vec<Point> {
        rows.iter()
            .filter(|r| r.unit_id == unit && r.method == "B")
            .filter_map(|r| {
                let (y, sigma) = r.trend_value(p)?;
                Some(Point {
                    x: r.start_ms as f64,
                    y,
                    sigma,
                })
            })
            .collect()
    };
    Chart {
        title: format!("{unit}: compressor fouling (Method B)"),
        y_label: "degradation, %".into(),
        x_label: "start-up date (UTC)".into(),
        x_axis: XAxis::Date,
        width: 640.0,
        height: 260.0,
        series: vec![
            Series::Markers {
                label: "D_GC".into(),
                color: BLUE,
                hollow: false,
                points: pts("D_GC"),
            },
            Series::Markers {
                label: "D_EC".into(),
                color: ORANGE,
                hollow: true,
                points: pts("D_EC"),
            },
        ],
        markers: washes
            .iter()
            .filter(|w| w.unit_id == unit)
            .map(|w| Marker {
                x: w.t_ms as f64,
                label: "wash".into(),
                color: GREY,
            })
            .collect(),
    }
}

const CSS: &str = "body{font-family:system-ui,sans-serif;margin:24px;color:#222}\
table{border-collapse:collapse;margin:12px 0}td,th{border:1px solid #ccc;padding:4px 8px;\
text-align:right}th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}\
td.msg{text-align:left;max-width:420px;font-size:13px}.meta{color:#666}";

/// The whole page.
pub(crate) fn fleet_html(
    centre: &str,
    rows: &[FleetHistoryRow],
    washes: &[FleetWash],
    advice: &[FleetAdvice],
) -> String {
    let lines = rank(rows, washes, advice);
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>gtwatch fleet report</title><style>{CSS}{STYLE}</style></head><body><h1>Fleet report</h1><p class=\"meta\">{} unit(s) at {}; {} result(s). Fouling rates are the weighted Theil–Sen slope of each unit's Method B results since its last wash, percent points per day (±1σ).</p>",
        lines.len(),
        esc(centre),
        rows.len()
    );
    h.push_str("<h2>Units by compressor fouling rate</h2><table><tr><th>unit</th><th>results since wash</th><th>last wash</th><th>newest result</th><th>D_GC rate %/day</th><th>D_EC rate %/day</th><th>next offline wash</th><th>advice</th></tr>");
    for l in &lines {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"msg\">{}</td></tr>",
            esc(&l.unit_id),
            l.results_since_wash,
            date(l.last_wash_ms),
            date(l.newest_ms),
            rate_cell(l.d_gc.as_ref()),
            rate_cell(l.d_ec.as_ref()),
            date(l.advised_ms),
            esc(l.advice.as_deref().unwrap_or("no advice yet"))
        );
    }
    h.push_str("</table><h2>Trends</h2>");
    for l in &lines {
        h.push_str(&unit_chart(&l.unit_id, rows, washes).render());
    }
    h.push_str("</body></html>\n");
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn row(unit: &str, day: i64, d_gc: f64) -> FleetHistoryRow {
        let mut health = BTreeMap::new();
        health.insert("D_GC".to_string(), d_gc);
        health.insert("D_EC".to_string(), d_gc / 3.0);
        let sigma: BTreeMap<String, f64> = health.keys().map(|k| (k.clone(), 0.05)).collect();
        FleetHistoryRow {
            unit_id: unit.into(),
            segment_id: day,
            start_ms: 1_700_000_000_000 + day * 86_400_000,
            method: "B".into(),
            health,
            sigma,
            residual_level: Some(1.0),
            fit_quality: Some("good".into()),
            gap_verdict: None,
            instrument_step: None,
            gap_health_after: None,
        }
    }

    /// Known rates: unit "b" fouls at 0.3 %/day, unit "a" at 0.1 %/day until a wash on day 5
    /// and 0.2 %/day after it; "c" has one result. Ranked b, a, c; a's rate is the one since
    /// its wash; the advised date follows from the basis.
    #[test]
    fn units_are_ranked_by_their_fouling_rate_since_the_last_wash() {
        let mut rows = Vec::new();
        for d in 0..5 {
            rows.push(row("a", d, 0.1 * d as f64));
        }
        for d in 6..12 {
            rows.push(row("a", d, 0.2 * (d - 5) as f64));
            rows.push(row("b", d, 0.3 * d as f64));
        }
        rows.push(row("c", 3, 0.5));
        let washes = vec![FleetWash {
            unit_id: "a".into(),
            t_ms: 1_700_000_000_000 + 5 * 86_400_000,
            kind: "offline".into(),
        }];
        let advice = vec![FleetAdvice {
            unit_id: "b".into(),
            t_ms: 1_700_000_000_000 + 11 * 86_400_000,
            message: "wash in 9 days".into(),
            basis: r#"{"trend":{"age_days":5.0},"advice":{"advised_days":14.0}}"#.into(),
        }];
        let lines = rank(&rows, &washes, &advice);
        let order: Vec<&str> = lines.iter().map(|l| l.unit_id.as_str()).collect();
        assert_eq!(order, vec!["b", "a", "c"]);
        let gc = |i: usize| lines[i].d_gc.map(|f| f.rate_per_day);
        assert!((gc(0).unwrap() - 0.3).abs() < 1e-9, "{:?}", gc(0));
        assert!((gc(1).unwrap() - 0.2).abs() < 1e-9, "{:?}", gc(1));
        assert_eq!(lines[1].results_since_wash, 6);
        assert!(lines[2].d_gc.is_none());
        assert_eq!(
            lines[0].advised_ms,
            Some(1_700_000_000_000 + 20 * 86_400_000)
        );
        let page = fleet_html("centre", &rows, &washes, &advice);
        assert!(page.contains("+0.300 ± "), "{page}");
        assert!(!page.contains("http://") && !page.contains("https://") && !page.contains("src="));
        assert_eq!(page.matches("<svg").count(), 3);
    }

    /// A unit whose fuel meter read high from day 9 on: its fitted D_GC fell by 3 points there
    /// (a cleaner-looking compressor) and its wash advice corrected those start-ups. The
    /// ranking and the chart use the corrected health, so its rate is the engine's 0.3 %/day,
    /// not the meter's step.
    #[test]
    fn a_unit_s_rate_uses_the_health_its_advice_corrected_for_an_instrument() {
        use crate::store::InstrumentCorrection;
        let rows: Vec<FleetHistoryRow> = (0..12)
            .map(|d| {
                let truth = 0.3 * d as f64;
                if d < 9 {
                    return row("b", d, truth);
                }
                let mut r = row("b", d, truth - 3.0);
                r.instrument_step = Some(InstrumentCorrection {
                    segment_id: d,
                    onset_segment_id: 9,
                    effect: "fuel_meter".into(),
                    unit: "fraction".into(),
                    magnitude: 0.03,
                    magnitude_sigma: 0.002,
                    health: [truth, truth / 3.0, 0.0, 0.0, 0.0, 0.0],
                    sigma: [0.05; 6],
                    also: String::new(),
                });
                r
            })
            .collect();
        let lines = rank(&rows, &[], &[]);
        let gc = lines[0].d_gc.expect("rate").rate_per_day;
        assert!((gc - 0.3).abs() < 1e-9, "{gc}");
        let fitted_only: Vec<FleetHistoryRow> = rows
            .iter()
            .cloned()
            .map(|mut r| {
                r.instrument_step = None;
                r
            })
            .collect();
        let gc = rank(&fitted_only, &[], &[])[0]
            .d_gc
            .expect("rate")
            .rate_per_day;
        assert!(gc < 0.1, "the meter's step drawn into the rate: {gc}");
    }
}
