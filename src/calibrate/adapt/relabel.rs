//! The first guess of the compressor's speed re-labelling curve: at which of the map's speed
//! lines the unit runs where it does, read from the data before any curve is fitted.
//!
//! Why: along a healthy operating line the compressor's speed re-labelling, flow and
//! efficiency curves nearly trade one for another (the baseline measures the GG speed, P2 and
//! T2, not the air flow), so where the fit starts decides where on the map it ends. From zero
//! the fit of a foreign unit whose compressor gives at 83 % corrected speed what the borrowed
//! map gives at 91 % (`tests/foreign_ambient.rs`) re-labelled the speed line by 4 % and made
//! up the rest with flow +41 % and efficiency +15 %: the adapted operating line ran beyond the
//! map's surge line (β −0.3, surge margin −13 %), where its flat speed lines amplify what the
//! curves do off the healthy line. The unit's own answer is a re-labelling: the model before
//! the adaptation, given each point's fuel or power, runs its GG at `n_model` where the unit
//! runs at `n_meas`; reading the map at `n_meas · (1 + f)` with `f = n_model / n_meas − 1`
//! puts the point on the speed line that carries it, mid-map. That is the guess; the fit then
//! moves every curve from there.
//!
//! What it must not do: fit, or choose which curves are fitted (the identifiability analysis
//! does).

use super::super::problem::CalibrationPoint;
use crate::diagnosis::steady::relative_gg_speed;
use crate::engine::Engine;
use crate::maps::SpeedCurve;
use crate::signals::Signal;

/// Largest guess either way: the fit's own interval for a speed knot is ±0.30 around it.
pub(super) const RELABEL_GUESS_LIMIT: f64 = 0.3;

/// Smallest weight a point's speed must give the knot to count in the guess (its distance
/// from the design speed, where every curve is pinned to zero, relative to the knot's).
const MIN_WEIGHT: f64 = 0.05;

/// The least-squares value at the single knot `knot` of a speed re-labelling curve that puts
/// each point of `points` (with a measured GG speed, solvable on `engine`) on the speed line
/// `engine` runs it at: `None` when no point informs the knot.
pub(super) fn relabel_guess(
    engine: &Engine,
    points: &[CalibrationPoint],
    knot: f64,
) -> Option<f64> {
    // The curve with the knot's value 1 is the knot's basis: the correction at any speed is
    // the knot value times it (the spline is linear in its knot values).
    let basis = SpeedCurve::new(&[knot], &[1.0])?;
    let mut num = 0.0;
    let mut den = 0.0;
    for p in points {
        let Some(n_meas) = p.data.measured(Signal::N1) else {
            continue;
        };
        let Some(speed) = relative_gg_speed(engine, &p.data) else {
            continue;
        };
        let g = basis.at(speed);
        if g.abs() < MIN_WEIGHT || n_meas <= 0.0 {
            continue;
        }
        let Ok(solved) = p.solved_on(engine) else {
            continue;
        };
        let y = solved.stations.n1_rpm / n_meas - 1.0;
        num += g * y;
        den += g * g;
    }
    (den > 0.0).then(|| num / den)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::calibrate::problem::prepare;
    use crate::calibrate::synthetic::generator_baseline_csv;
    use crate::diagnosis::snapshot::read_snapshots;
    use crate::engine::config::{AdaptationConfig, ComponentCurves};
    use std::collections::HashMap;

    /// The reference file's points on a unit of the same file whose compressor reads its map
    /// `relabel` above its own speed at the knot (a straight ramp to the design speed).
    fn points_of(model: &Engine, knot: f64, relabel: f64) -> Vec<CalibrationPoint> {
        let mut cfg = model.cfg().clone();
        cfg.adaptation = Some(AdaptationConfig {
            compressor: Some(ComponentCurves {
                speed_knots: vec![knot],
                speed: vec![relabel],
                ..ComponentCurves::default()
            }),
            ..AdaptationConfig::default()
        });
        let truth = model.with_config(cfg).expect("truth");
        let csv = generator_baseline_csv(&truth, 3).expect("rows");
        let rows = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect("read");
        let prepared = prepare(model, &rows);
        assert!(prepared.dropped.is_empty(), "{:?}", prepared.dropped);
        prepared.points
    }

    #[test]
    fn the_guess_reads_the_speed_line_a_unit_runs_on() {
        let model = Engine::reference().expect("engine");
        let knot = 0.85;
        for relabel in [0.06, -0.04] {
            let points = points_of(&model, knot, relabel);
            let guess = relabel_guess(&model, &points, knot).expect("a guess");
            // The re-labelling is read from the GG speed alone, and the rest of the state
            // differs a little between the two speeds (the HP turbine's map is read at the
            // unit's speed, not the line's), so the guess is a start in the right basin, not
            // the answer: measured +0.087 for +0.06, −0.041 for −0.04.
            assert!(
                (guess - relabel).abs() < 0.5 * relabel.abs(),
                "relabel {relabel}: guess {guess:.4}"
            );
        }
        // The unit that is the file reads no re-labelling (noise only).
        let points = points_of(&model, knot, 0.0);
        let guess = relabel_guess(&model, &points, knot).expect("a guess");
        assert!(guess.abs() < 0.005, "guess {guess:.4}");
    }
}
