//! The signal × operating-point residual table: for each steady point (a snapshot row, a
//! start-up's steady window) and each compared signal, (model − measured)/σ at the fitted
//! parameters. Where the RMS and the verdict say *that* a model misses, this table says *where*:
//! one signal off at every load is an instrument or a design value; every signal off at the
//! lowest loads is the off-design shape of the maps.
//!
//! Built by snapshot diagnosis and calibration from values they already have; renders as a
//! fixed-width text table. Pure: no I/O, no model runs.

use crate::signals::Signal;
use serde::Serialize;

/// One operating point's row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualRow {
    /// The snapshot's file line (a start-up window's: its first sample's).
    pub line: u64,
    /// What the point is: its group, or a start-up file and window times.
    pub label: String,
    /// (model − measured)/σ per signal of [`ResidualTable::signals`]; `None` where the point has
    /// no measurement of it.
    pub values: Vec<Option<f64>>,
}

/// Residuals in noise σ, signals as columns, operating points as rows.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct ResidualTable {
    /// Column names (CSV names, e.g. `t34_k`).
    pub signals: Vec<String>,
    pub rows: Vec<ResidualRow>,
}

/// One residual: at row `point`, of `signal`, (model − measured)/σ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    pub point: usize,
    pub signal: Signal,
    pub value: f64,
}

impl ResidualTable {
    /// The table of `cells` over points described by `points` (line, label), columns in the
    /// order signals first appear. Cells of points outside `points` are ignored.
    pub fn from_cells(points: &[(u64, String)], cells: &[Cell]) -> ResidualTable {
        let mut order: Vec<Signal> = Vec::new();
        for c in cells {
            if c.point < points.len() && !order.contains(&c.signal) {
                order.push(c.signal);
            }
        }
        let mut rows: Vec<ResidualRow> = points
            .iter()
            .map(|(line, label)| ResidualRow {
                line: *line,
                label: label.clone(),
                values: vec![None; order.len()],
            })
            .collect();
        for c in cells {
            let col = order.iter().position(|s| *s == c.signal);
            if let (Some(row), Some(col)) = (rows.get_mut(c.point), col) {
                row.values[col] = Some(c.value);
            }
        }
        ResidualTable {
            signals: order.iter().map(|s| s.column().to_string()).collect(),
            rows,
        }
    }

    /// Fixed-width text: a header of signal names, one line per point (`-` where a signal is
    /// not measured), values in σ with sign.
    pub fn render(&self) -> String {
        let width = self
            .signals
            .iter()
            .map(|s| s.len())
            .max()
            .unwrap_or(0)
            .max(8);
        let label_w = self
            .rows
            .iter()
            .map(|r| r.label.chars().count())
            .max()
            .unwrap_or(0)
            .clamp(5, 40);
        let mut out = format!("{:>6}  {:<label_w$}", "line", "point");
        for s in &self.signals {
            out.push_str(&format!(" {s:>width$}"));
        }
        out.push('\n');
        for r in &self.rows {
            let label: String = r.label.chars().take(label_w).collect();
            out.push_str(&format!("{:>6}  {:<label_w$}", r.line, label));
            for v in &r.values {
                match v {
                    Some(v) => out.push_str(&format!(" {v:>+width$.2}")),
                    None => out.push_str(&format!(" {:>width$}", "-")),
                }
            }
            out.push('\n');
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_land_in_their_row_and_column_and_missing_ones_show_as_dashes() {
        let points = vec![(2, "day 1".to_string()), (3, "day 1".to_string())];
        let cells = [
            Cell {
                point: 0,
                signal: Signal::T34,
                value: 1.5,
            },
            Cell {
                point: 1,
                signal: Signal::P2,
                value: -0.25,
            },
            Cell {
                point: 1,
                signal: Signal::T34,
                value: 3.0,
            },
            Cell {
                point: 7,
                signal: Signal::N1,
                value: 9.0,
            },
        ];
        let t = ResidualTable::from_cells(&points, &cells);
        assert_eq!(t.signals, vec!["t34_k", "p2_kpa"]);
        assert_eq!(t.rows[0].values, vec![Some(1.5), None]);
        assert_eq!(t.rows[1].values, vec![Some(3.0), Some(-0.25)]);
        let text = t.render();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        assert!(lines[0].contains("t34_k") && lines[0].contains("p2_kpa"));
        assert!(lines[1].trim_start().starts_with('2') && lines[1].contains("+1.50"));
        assert!(lines[1].trim_end().ends_with('-'), "{text}");
        assert!(lines[2].contains("+3.00") && lines[2].contains("-0.25"));
    }
}
