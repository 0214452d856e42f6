//! The one SVG writer: a small line-chart writer (the HTML report's charts, the gap analysis's
//! before/after traces, the simulated start-up's panels in [`startup`]): axes with ticks and
//! units, lines, points with ±σ bars, vertical event markers, a legend. Output is a
//! self-contained `<svg>` string (no scripts, no external references), escaped where it carries
//! text.
//!
//! Pure string building: no I/O.

pub(crate) mod startup;

use std::fmt::Write;

/// The style rules the charts' classes need, for a page (inside `<style>`) or a standalone
/// SVG document (inside `<svg><style>`).
pub(crate) const STYLE: &str =
    "svg text{font-family:sans-serif}svg .title{font-size:14px;font-weight:600}\
svg .tick{font-size:11px;fill:#444}svg .axis{font-size:12px;fill:#333}\
svg .legend{font-size:12px;fill:#333}svg .marker{font-size:11px}svg .grid{stroke:#e6e6e6}\
svg .frame{fill:none;stroke:#999}svg .zero{stroke:#999;stroke-dasharray:2 2}\
svg .empty{font-size:14px;fill:#888}";

/// Colours used consistently across charts.
pub(crate) const BLUE: &str = "#1f5fa8";
pub(crate) const ORANGE: &str = "#d9731a";
pub(crate) const GREEN: &str = "#2a8a3e";
pub(crate) const RED: &str = "#c0392b";
pub(crate) const GREY: &str = "#777777";

/// How the x axis is labelled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum XAxis {
    /// Unix milliseconds, labelled as dates (YYYY-MM-DD).
    Date,
    /// Seconds, labelled as numbers.
    Seconds,
}

/// A point with an optional symmetric error bar.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Point {
    pub(crate) x: f64,
    pub(crate) y: f64,
    pub(crate) sigma: Option<f64>,
}

/// One series.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Series {
    Line {
        label: String,
        color: &'static str,
        dashed: bool,
        points: Vec<(f64, f64)>,
    },
    Markers {
        label: String,
        color: &'static str,
        /// Hollow squares instead of filled circles.
        hollow: bool,
        points: Vec<Point>,
    },
}

/// A vertical marker line (e.g. a wash) with a short label.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Marker {
    pub(crate) x: f64,
    pub(crate) label: String,
    pub(crate) color: &'static str,
}

/// A chart to render.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Chart {
    pub(crate) title: String,
    pub(crate) y_label: String,
    pub(crate) x_label: String,
    pub(crate) x_axis: XAxis,
    pub(crate) width: f64,
    pub(crate) height: f64,
    pub(crate) series: Vec<Series>,
    pub(crate) markers: Vec<Marker>,
}

const LEFT: f64 = 64.0;
const RIGHT: f64 = 16.0;
const TOP: f64 = 28.0;
const BOTTOM: f64 = 58.0;

/// Escapes text for XML content and attributes.
pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// "Nice" tick positions covering `[lo, hi]`, about `n` of them.
pub(crate) fn ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return vec![lo];
    }
    let raw = (hi - lo) / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() * step;
    let mut out = Vec::new();
    let mut t = first;
    while t <= hi + step * 1e-9 && out.len() < 50 {
        out.push(if t.abs() < step * 1e-9 { 0.0 } else { t });
        t += step;
    }
    out
}

fn fmt_tick(v: f64, axis: XAxis, span: f64) -> String {
    match axis {
        XAxis::Date => crate::time::fmt_ms(v as i64)
            .get(..10)
            .unwrap_or("")
            .to_string(),
        XAxis::Seconds => fmt_num(v, span),
    }
}

fn fmt_num(v: f64, span: f64) -> String {
    if span >= 20.0 {
        format!("{v:.0}")
    } else if span >= 2.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

impl Chart {
    fn bounds(&self) -> Option<(f64, f64, f64, f64)> {
        let mut xs = Vec::new();
        let mut ys = Vec::new();
        for s in &self.series {
            match s {
                Series::Line { points, .. } => {
                    for &(x, y) in points {
                        xs.push(x);
                        ys.push(y);
                    }
                }
                Series::Markers { points, .. } => {
                    for p in points {
                        xs.push(p.x);
                        ys.push(p.y - p.sigma.unwrap_or(0.0));
                        ys.push(p.y + p.sigma.unwrap_or(0.0));
                    }
                }
            }
        }
        xs.extend(self.markers.iter().map(|m| m.x));
        xs.retain(|v| v.is_finite());
        ys.retain(|v| v.is_finite());
        let (x0, x1) = min_max(&xs)?;
        let (y0, y1) = min_max(&ys)?;
        let xpad = if x1 > x0 { 0.03 * (x1 - x0) } else { 1.0 };
        let ypad = if y1 > y0 { 0.08 * (y1 - y0) } else { 0.5 };
        Some((x0 - xpad, x1 + xpad, y0 - ypad, y1 + ypad))
    }

    /// The `<svg>` element. A chart with no finite data says so instead of drawing axes.
    ///
    /// Drawn in layers, back to front: the grid and ticks, the frame, the markers, the series,
    /// then the axis labels and the legend.
    pub(crate) fn render(&self) -> String {
        let (w, h) = (self.width, self.height);
        let mut s = String::new();
        let _ = write!(
            s,
            r#"<svg width="{w}" height="{h}" viewBox="0 0 {w} {h}" role="img" aria-label="{}">"#,
            esc(&self.title)
        );
        let _ = write!(
            s,
            r#"<text x="{LEFT}" y="18" class="title">{}</text>"#,
            esc(&self.title)
        );
        let Some((x0, x1, y0, y1)) = self.bounds() else {
            let _ = write!(
                s,
                r#"<text x="{}" y="{}" class="empty" text-anchor="middle">no data</text></svg>"#,
                w / 2.0,
                h / 2.0
            );
            return s;
        };
        let area = Area {
            x0,
            x1,
            y0,
            y1,
            pw: w - LEFT - RIGHT,
            ph: h - TOP - BOTTOM,
        };
        area.y_grid(&mut s);
        area.x_grid(&mut s, self.x_axis);
        area.frame(&mut s);
        for m in &self.markers {
            area.marker(&mut s, m);
        }
        for series in &self.series {
            area.series(&mut s, series);
        }
        self.axis_labels(&mut s, &area);
        self.legend(&mut s);
        s.push_str("</svg>");
        s
    }

    /// The x and y axis labels.
    fn axis_labels(&self, s: &mut String, area: &Area) {
        let _ = write!(
            s,
            r#"<text x="{:.1}" y="{:.1}" class="axis" text-anchor="middle">{}</text>"#,
            LEFT + area.pw / 2.0,
            self.height - 22.0,
            esc(&self.x_label)
        );
        let _ = write!(
            s,
            r#"<text transform="translate(14,{:.1}) rotate(-90)" class="axis" text-anchor="middle">{}</text>"#,
            TOP + area.ph / 2.0,
            esc(&self.y_label)
        );
    }

    /// The legend along the bottom: each labelled series' symbol and label.
    fn legend(&self, s: &mut String) {
        let mut lx = LEFT;
        let ly = self.height - 6.0;
        for series in &self.series {
            let (label, color, kind) = match series {
                Series::Line {
                    label,
                    color,
                    dashed,
                    ..
                } => (label, *color, if *dashed { "dash" } else { "line" }),
                Series::Markers {
                    label,
                    color,
                    hollow,
                    ..
                } => (label, *color, if *hollow { "square" } else { "dot" }),
            };
            if label.is_empty() {
                continue;
            }
            legend_symbol(s, kind, color, lx, ly);
            let _ = write!(
                s,
                r#"<text x="{:.1}" y="{ly:.1}" class="legend">{}</text>"#,
                lx + 18.0,
                esc(label)
            );
            lx += 26.0 + 6.5 * label.chars().count() as f64;
        }
    }
}

/// A legend entry's symbol (`dot`, `square`, `dash` or a line) at (`lx`, `ly`).
fn legend_symbol(s: &mut String, kind: &str, color: &str, lx: f64, ly: f64) {
    match kind {
        "dot" => {
            let _ = write!(
                s,
                r#"<circle cx="{:.1}" cy="{:.1}" r="3.6" fill="{color}"/>"#,
                lx + 6.0,
                ly - 4.0
            );
        }
        "square" => {
            let _ = write!(
                s,
                r#"<rect x="{:.1}" y="{:.1}" width="7" height="7" fill="white" stroke="{color}"/>"#,
                lx + 2.5,
                ly - 7.5
            );
        }
        _ => {
            let _ = write!(
                s,
                r#"<line x1="{lx:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{color}" stroke-width="2"{}/>"#,
                ly - 4.0,
                lx + 14.0,
                ly - 4.0,
                if kind == "dash" {
                    r#" stroke-dasharray="4 3""#
                } else {
                    ""
                }
            );
        }
    }
}

/// The plotting area of a chart with data: its data bounds and its size in pixels.
struct Area {
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    /// Width and height of the plotting area, px.
    pw: f64,
    ph: f64,
}

impl Area {
    fn sx(&self, x: f64) -> f64 {
        LEFT + (x - self.x0) / (self.x1 - self.x0) * self.pw
    }

    fn sy(&self, y: f64) -> f64 {
        TOP + (1.0 - (y - self.y0) / (self.y1 - self.y0)) * self.ph
    }

    /// Horizontal grid lines and the y ticks.
    fn y_grid(&self, s: &mut String) {
        for t in ticks(self.y0, self.y1, 5) {
            let y = self.sy(t);
            let _ = write!(
                s,
                r#"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" class="grid"/><text x="{:.1}" y="{:.1}" class="tick" text-anchor="end">{}</text>"#,
                LEFT + self.pw,
                LEFT - 6.0,
                y + 4.0,
                fmt_num(t, self.y1 - self.y0)
            );
        }
    }

    /// The x ticks' positions: whole days on a date axis.
    fn x_ticks(&self, axis: XAxis) -> Vec<f64> {
        let (x0, x1) = (self.x0, self.x1);
        match axis {
            XAxis::Date => {
                // Whole days.
                let day = 86_400_000.0;
                let span_days = (x1 - x0) / day;
                let step = ticks(0.0, span_days.max(1.0), 6)
                    .get(1)
                    .copied()
                    .unwrap_or(1.0)
                    .max(1.0)
                    .round();
                let mut v = Vec::new();
                let mut t = (x0 / day).ceil() * day;
                while t <= x1 && v.len() < 40 {
                    v.push(t);
                    t += step * day;
                }
                v
            }
            XAxis::Seconds => ticks(x0, x1, 8),
        }
    }

    /// Vertical grid lines and the x ticks.
    fn x_grid(&self, s: &mut String, axis: XAxis) {
        for t in self.x_ticks(axis) {
            let x = self.sx(t);
            let _ = write!(
                s,
                r#"<line x1="{x:.1}" y1="{TOP}" x2="{x:.1}" y2="{:.1}" class="grid"/><text x="{x:.1}" y="{:.1}" class="tick" text-anchor="middle">{}</text>"#,
                TOP + self.ph,
                TOP + self.ph + 16.0,
                fmt_tick(t, axis, self.x1 - self.x0)
            );
        }
    }

    /// The frame, and the zero line when zero is inside the y range.
    fn frame(&self, s: &mut String) {
        let (pw, ph) = (self.pw, self.ph);
        let _ = write!(
            s,
            r#"<rect x="{LEFT}" y="{TOP}" width="{pw:.1}" height="{ph:.1}" class="frame"/>"#
        );
        if self.y0 < 0.0 && self.y1 > 0.0 {
            let y = self.sy(0.0);
            let _ = write!(
                s,
                r#"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" class="zero"/>"#,
                LEFT + pw
            );
        }
    }

    /// A vertical marker line with its label.
    fn marker(&self, s: &mut String, m: &Marker) {
        let x = self.sx(m.x);
        let _ = write!(
            s,
            r#"<line x1="{x:.1}" y1="{TOP}" x2="{x:.1}" y2="{:.1}" stroke="{}" stroke-width="1.5" stroke-dasharray="5 3"/><text x="{:.1}" y="{:.1}" class="marker" fill="{}">{}</text>"#,
            TOP + self.ph,
            m.color,
            x + 3.0,
            TOP + 12.0,
            m.color,
            esc(&m.label)
        );
    }

    /// One series: a polyline, or points with their ±σ bars.
    fn series(&self, s: &mut String, series: &Series) {
        match series {
            Series::Line {
                color,
                dashed,
                points,
                ..
            } => {
                let d: Vec<String> = points
                    .iter()
                    .filter(|(x, y)| x.is_finite() && y.is_finite())
                    .map(|&(x, y)| format!("{:.1},{:.1}", self.sx(x), self.sy(y)))
                    .collect();
                if d.len() >= 2 {
                    let _ = write!(
                        s,
                        r#"<polyline points="{}" fill="none" stroke="{color}" stroke-width="1.3"{}/>"#,
                        d.join(" "),
                        if *dashed {
                            r#" stroke-dasharray="6 4""#
                        } else {
                            ""
                        }
                    );
                }
            }
            Series::Markers {
                color,
                hollow,
                points,
                ..
            } => {
                for p in points.iter().filter(|p| p.x.is_finite() && p.y.is_finite()) {
                    self.point(s, p, color, *hollow);
                }
            }
        }
    }

    /// One point: its ±σ bar (when it has one), then a hollow square or a filled circle.
    fn point(&self, s: &mut String, p: &Point, color: &str, hollow: bool) {
        let (x, y) = (self.sx(p.x), self.sy(p.y));
        if let Some(sg) = p.sigma.filter(|v| v.is_finite() && *v > 0.0) {
            let _ = write!(
                s,
                r#"<line x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}" stroke="{color}" stroke-width="1"/>"#,
                self.sy(p.y - sg),
                self.sy(p.y + sg)
            );
        }
        if hollow {
            let _ = write!(
                s,
                r#"<rect x="{:.1}" y="{:.1}" width="7" height="7" fill="white" stroke="{color}" stroke-width="1.4"/>"#,
                x - 3.5,
                y - 3.5
            );
        } else {
            let _ = write!(
                s,
                r#"<circle cx="{x:.1}" cy="{y:.1}" r="3.6" fill="{color}"/>"#
            );
        }
    }
}

fn min_max(v: &[f64]) -> Option<(f64, f64)> {
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (lo.is_finite() && hi.is_finite()).then_some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        assert_eq!(
            ticks(0.0, 1.0, 5),
            vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
        );
        let t = ticks(-0.37, 1.42, 5);
        assert!(t.first().unwrap() >= &-0.37 && t.last().unwrap() <= &1.42);
        assert!(t.len() >= 3);
    }

    #[test]
    fn chart_escapes_text_and_says_when_empty() {
        let c = Chart {
            title: "D_GC <flow> & more".into(),
            y_label: "%".into(),
            x_label: "date".into(),
            x_axis: XAxis::Date,
            width: 400.0,
            height: 200.0,
            series: vec![],
            markers: vec![],
        };
        let svg = c.render();
        assert!(svg.contains("D_GC &lt;flow&gt; &amp; more"));
        assert!(svg.contains("no data"));
        let c = Chart {
            series: vec![Series::Markers {
                label: "B".into(),
                color: BLUE,
                hollow: false,
                points: vec![
                    Point {
                        x: 0.0,
                        y: 1.0,
                        sigma: Some(0.1),
                    },
                    Point {
                        x: 86_400_000.0,
                        y: 1.2,
                        sigma: None,
                    },
                ],
            }],
            ..c
        };
        let svg = c.render();
        assert_eq!(
            svg.matches("<circle").count(),
            3,
            "two points and a legend dot"
        );
        assert!(!svg.contains("no data"));
    }
}
