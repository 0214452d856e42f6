//! Where the baseline's loads leave the adapted model guessing: the interior loads at which
//! the model's own error along the GG speed (`[adaptation.model_error_by_speed]`) reaches
//! [`ADVICE_PCT`] on some signal, and between which of the baseline's loads one more healthy
//! load would pin the curves there. What a plant engineer can act on: record that load and
//! calibrate again.
//!
//! Why: the curves between two baseline loads are the spline's guess, not the data's. On the
//! combinator unit of `tests/foreign_engine.rs` the grown shape and the continuation both fit
//! 8 of its 9 loads within noise (0.64 and 0.61 σ) yet predict the ninth, 38.75 % load,
//! 2.28 % and 0.95 % off at worst: the data between 30 % and 47.5 % load do not decide, and
//! the model's own error there says so (1.39 % on torque at that load, at most 0.14 % from
//! 56 % up).
//! Its advice there, a load between 38.75 % and 47.5 %, followed (a 42.5 % load added to the
//! baseline): the 47.5 % load left out is predicted at 0.22 / 0.51 % (mean / worst) instead of
//! 0.67 / 1.11 %, the 38.75 % load at 0.83 / 1.78 % instead of 0.90 / 2.28 %, and the advice
//! moves to the span below (asserted in `tests/foreign_engine.rs`).
//!
//! What it must not do: fit, solve, or do I/O (pure arithmetic on speeds and the error table).

use crate::engine::config::ModelErrorBySpeed;
use serde::Serialize;

/// A signal's error along the GG speed (%) from which a load is named: the issue's own floor
/// for a load left out of the calibration ("no signal beyond 1 %").
pub const ADVICE_PCT: f64 = 1.0;

/// Baseline speeds closer than this (relative corrected GG speed) are one load (the same
/// load on days of another temperature).
const SAME_LOAD: f64 = 0.005;

/// One place the baseline should have a load more.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoverageAdvice {
    /// Relative corrected GG speeds between which a healthy load is missing.
    pub between: [f64; 2],
    /// The file lines of the baseline rows at those two speeds.
    pub lines: [u64; 2],
    /// The interior load(s) beside the gap whose error reaches [`ADVICE_PCT`], with the
    /// worst signal and its error (%).
    pub worst_signal: String,
    pub worst_pct: f64,
}

impl CoverageAdvice {
    /// Plain words.
    pub fn describe(&self) -> String {
        format!(
            "the model's own error reaches {:.2} % on {} beside relative GG speeds {:.3}…{:.3} \
             (the loads of lines {} and {}): between them the curves rest on their shape, not \
             on data; record a healthy load there and calibrate again (meanwhile that error \
             is in the diagnosis's σ)",
            self.worst_pct,
            self.worst_signal,
            self.between[0],
            self.between[1],
            self.lines[0],
            self.lines[1]
        )
    }
}

/// The advice for a baseline whose rows (file `lines`) run at relative corrected GG `speeds`,
/// from the model's own error along the GG speed `by_speed`: for each interior load at which
/// some signal's error reaches [`ADVICE_PCT`], the wider of the two spans to its neighbouring
/// loads (one advice per span, with the worst error beside it), in order of speed.
pub fn advice(speeds: &[f64], lines: &[u64], by_speed: &ModelErrorBySpeed) -> Vec<CoverageAdvice> {
    // Distinct loads in order of speed, each with the line of its first row.
    let mut loads: Vec<(f64, u64)> = speeds
        .iter()
        .copied()
        .zip(lines.iter().copied())
        .filter(|(s, _)| s.is_finite())
        .collect();
    loads.sort_by(|a, b| a.0.total_cmp(&b.0));
    loads.dedup_by(|b, a| b.0 - a.0 < SAME_LOAD);
    let mut out: Vec<CoverageAdvice> = Vec::new();
    for (k, &at) in by_speed.speed_knots.iter().enumerate() {
        let worst = by_speed
            .pct
            .iter()
            .filter_map(|(signal, v)| v.get(k).map(|p| (signal, *p)))
            .filter(|(_, p)| p.is_finite())
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((signal, pct)) = worst else { continue };
        if pct < ADVICE_PCT {
            continue;
        }
        // The load this knot stands for, and its neighbours either side.
        let Some(i) = loads.iter().position(|(s, _)| (s - at).abs() < SAME_LOAD) else {
            continue;
        };
        if i == 0 || i + 1 >= loads.len() {
            continue;
        }
        let (lo, hi) = if loads[i].0 - loads[i - 1].0 >= loads[i + 1].0 - loads[i].0 {
            (loads[i - 1], loads[i])
        } else {
            (loads[i], loads[i + 1])
        };
        match out.iter_mut().find(|a| a.lines == [lo.1, hi.1]) {
            Some(a) if a.worst_pct < pct => {
                a.worst_pct = pct;
                a.worst_signal = signal.clone();
            }
            Some(_) => {}
            None => out.push(CoverageAdvice {
                between: [lo.0, hi.0],
                lines: [lo.1, hi.1],
                worst_signal: signal.clone(),
                worst_pct: pct,
            }),
        }
    }
    out.sort_by(|a, b| a.between[0].total_cmp(&b.between[0]));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn table(knots: &[f64], torque: &[f64]) -> ModelErrorBySpeed {
        let mut pct = BTreeMap::new();
        pct.insert("torque_knm".to_string(), torque.to_vec());
        pct.insert("n1_rpm".to_string(), vec![0.1; knots.len()]);
        ModelErrorBySpeed {
            speed_knots: knots.to_vec(),
            pct,
        }
    }

    /// The combinator unit's baseline (relative GG speeds of its 9 loads, rows 2–10) and its
    /// error along the speed: the two low interior loads beside the widest span are over 1 %.
    #[test]
    fn names_the_span_beside_the_loads_the_model_predicts_worst() {
        let speeds = [
            0.741, 0.787, 0.840, 0.866, 0.891, 0.906, 0.930, 0.948, 0.983,
        ];
        let lines: Vec<u64> = (2..=10).collect();
        let by = table(
            &[0.787, 0.840, 0.866, 0.891, 0.906, 0.930, 0.948],
            &[1.39, 1.10, 0.0, 0.0, 0.0, 0.14, 0.13],
        );
        let a = advice(&speeds, &lines, &by);
        assert_eq!(a.len(), 1, "{a:?}");
        assert_eq!(a[0].lines, [3, 4]);
        assert_eq!(a[0].between, [0.787, 0.840]);
        assert_eq!(a[0].worst_signal, "torque_knm");
        assert!((a[0].worst_pct - 1.39).abs() < 1e-12);
        assert!(a[0].describe().contains("lines 3 and 4"));
    }

    #[test]
    fn a_model_that_predicts_within_the_floor_gets_no_advice() {
        let speeds = [0.70, 0.75, 0.80, 0.85, 0.90];
        let lines = [2, 3, 4, 5, 6];
        let by = table(&[0.75, 0.80, 0.85], &[0.99, 0.5, 0.2]);
        assert!(advice(&speeds, &lines, &by).is_empty());
    }

    /// Rows of one load on other days are one load; the spans are between loads.
    #[test]
    fn rows_of_one_load_are_one_load() {
        let speeds = [0.70, 0.702, 0.80, 0.801, 0.84, 0.90];
        let lines = [2, 3, 4, 5, 6, 7];
        let by = table(&[0.80, 0.84], &[2.0, 0.1]);
        let a = advice(&speeds, &lines, &by);
        assert_eq!(a.len(), 1, "{a:?}");
        assert_eq!(a[0].lines, [2, 4]);
        assert_eq!(a[0].between, [0.70, 0.80]);
    }
}
