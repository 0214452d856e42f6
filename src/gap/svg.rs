//! The residual map as an SVG heat-map: one row per signal, one column per start-up phase, each
//! cell coloured by its normalised error (white ≤ 1 σ, through yellow, to red ≥ 10 σ) and
//! labelled with the error and its character (bias in σ or lag-like τ). Pure string building.

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
pub fn heat_map(cells: &[ResidualCell], title: &str) -> String {
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
}
