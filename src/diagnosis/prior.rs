//! A weak prior on the health parameters, taken by the least-squares stage of a diagnosis
//! along the combinations of them the data barely determine: there each is expected within
//! ± `health_prior_pts` of new (zero), in the same statistical sense as the data's residuals, so
//! the fit is the posterior optimum and its σ the posterior σ. Off by default (σ_p = 0).
//!
//! Why: where the measured signals barely separate two parameters' effects (a unit with no
//! pressure between or after the turbines: the HP turbine's efficiency against the power
//! turbine's capacity and efficiency), the least-squares optimum can move far along that weakly
//! determined direction to absorb a small model–plant difference. On the second blind
//! simulator's unit (`tests/data/foreign/indep2`, no P48 or P5) HP-turbine erosion of −1.4 / 1.6
//! read as D_ET 2.3 with the PT "better than new" by D_GP −2.3, D_EP −1.6. It is the gas-path
//! analysis practice of a priori health covariance (Volponi's weighted least squares, the Kalman
//! filters of Doel and of Kobayashi and Simon), restricted here to the weak directions so that
//! what the data determine stays the data's. It is a trade, so the user turns it on: on that
//! unit σ_p = 1 brought the PT's worst read from 2.7 to 1.1 points off and the compressor
//! flow's from 0.50 to 0.77.
//!
//! How: at the global stage's result the data's covariance of the health parameters is taken
//! from the least-squares stage's Jacobian (`optim::uncertainty`, (JᵀJ)⁻¹ in points² as the rows
//! weigh it). Along each of its eigen-directions with a data σ over [`WEAK_SIGMA_PTS`] (the
//! separability's "not determined"), and for each parameter the data do not inform at all, a row
//! `(uᵀx) / σ_p · c` is appended to the residual vector of the least-squares stage
//! (Levenberg–Marquardt and the uncertainty). The data's residuals are in their instruments' σ,
//! so one row weighs as one of them, times `c² =` the variance inflation for their serial
//! correlation (Method B's samples, seconds apart, are not as many independent readings) and the
//! stage's whitening scale (its whitening rescales every residual, and with it the data's
//! weight). Not the residuals' own variance: at the global result, where the rows are weighed,
//! it is mostly the misfit the least-squares stage then removes (weighed by it, the prior pulled
//! indep2's fouling of 4.5 points to 2.4). The global stage, the fit verdict and the residuals
//! reported stay the data's alone.
//!
//! What it must not do: touch the engine model or the data; change anything when off (σ_p = 0).

use crate::health::HEALTH_NAMES;
use crate::optim::{Bounds, Problem, ResidualProblem};
use serde::Serialize;

/// Default 1σ of the prior, points: none. A prior is a trade, not a free gain: on the second
/// blind simulator's unit (no P48 or P5) one of 1 point brought its PT's worst read from 2.27 to
/// 0.82 points off but its compressor fouling's from 0.51 to 0.62, and on the combinator unit of
/// `tests/foreign_engine.rs` (every instrument) it ranked D_GT at 0.949 where the data alone
/// rank it at 0.95 or better. Where the result says parameters are not identifiable, the
/// user weighs it (`--health-prior 1`).
pub const DEFAULT_HEALTH_PRIOR_PTS: f64 = 0.0;

/// Default 1σ of Method B's prior, points. A start-up's samples determine every direction on a
/// well-instrumented unit, where it adds no row (the model's twin, `bench diagnosis --cases 8
/// --seed 7`, reads identically with it); on the second blind simulator's unit, a season of 40
/// start-ups (`tests/foreign_season.rs`), it brought the PT's RMS error from 1.34 / 1.04 to 0.78
/// / 0.67 points and D_ET's from 0.56 to 0.31, D_GC's 0.24 → 0.26, 27 fits of 40 `good` (20).
pub const DEFAULT_TRANSIENT_HEALTH_PRIOR_PTS: f64 = 1.0;

/// A parameter whose posterior σ is at least this fraction of the prior's is called held by
/// the prior: at least a fifth (0.45²) of what is known of it comes from the prior, so the
/// prior has pulled its read toward new by at least a fifth of what the data alone would say.
pub const HELD_FRACTION: f64 = 0.45;

/// One prior row: a combination `Σ wᵢ·xᵢ` of health parameters (optimiser indices and
/// weights, `c / σ_p` times a unit direction).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PriorRow {
    pub(crate) weights: Vec<(usize, f64)>,
}

/// Data 1σ (points) above which a direction of the health parameters is weakly determined and
/// takes the prior: the separability's limit of "determined" (half a point at 2σ).
pub const WEAK_SIGMA_PTS: f64 = crate::diagnosis::separability::MAX_SIGMA;

/// The prior's rows for the health parameters at optimiser indices `health` (their data
/// covariance `cov`, points², in the same order; `+∞` on the diagonal of one the data do not
/// inform at all), rows scaled by `c`, prior 1σ `sigma_pts`: one row along each eigen-direction
/// of the covariance whose data σ exceeds [`WEAK_SIGMA_PTS`], and one per uninformed parameter.
/// What the data determine within that σ takes no prior: the model's twin, whose start-ups and
/// steady points determine every direction, reads identically with it. A parameter that shares a
/// weak direction is still pulled: on indep2 (no P48/P5) fouling of 4.5 points read 4.14 without
/// a prior and 3.88 with one of 1 point, its PT 1.26 / 1.03 points "better than new" → 0.69 /
/// 0.22.
pub(crate) fn weak_direction_rows(
    health: &[usize],
    cov: &[Vec<f64>],
    c: f64,
    sigma_pts: f64,
) -> Vec<PriorRow> {
    let w = c / sigma_pts;
    let informed: Vec<usize> = (0..health.len())
        .filter(|&i| {
            cov.get(i)
                .and_then(|r| r.get(i))
                .is_some_and(|v| v.is_finite())
        })
        .collect();
    let mut rows: Vec<PriorRow> = (0..health.len())
        .filter(|i| !informed.contains(i))
        .map(|i| PriorRow {
            weights: vec![(health[i], w)],
        })
        .collect();
    let k = informed.len();
    if k == 0 {
        return rows;
    }
    let m = nalgebra::DMatrix::from_fn(k, k, |a, b| cov[informed[a]][informed[b]]);
    let m = (&m + m.transpose()) * 0.5;
    let eig = m.symmetric_eigen();
    for (j, &mu) in eig.eigenvalues.iter().enumerate() {
        if mu.is_finite() && mu.max(0.0).sqrt() > WEAK_SIGMA_PTS {
            let u = eig.eigenvectors.column(j);
            rows.push(PriorRow {
                weights: (0..k).map(|a| (health[informed[a]], w * u[a])).collect(),
            });
        }
    }
    rows
}

/// A least-squares problem with prior rows appended to its residuals.
pub(crate) struct WithPrior<'a, P: ?Sized> {
    inner: &'a P,
    rows: Vec<PriorRow>,
}

impl<'a, P: ResidualProblem + ?Sized> WithPrior<'a, P> {
    pub(crate) fn new(inner: &'a P, rows: Vec<PriorRow>) -> Self {
        WithPrior { inner, rows }
    }

    /// The prior rows' residuals at `x`.
    fn push_rows(&self, x: &[f64], out: &mut Vec<f64>) {
        for r in &self.rows {
            out.push(
                r.weights
                    .iter()
                    .map(|&(i, w)| x.get(i).map_or(f64::NAN, |v| v * w))
                    .sum(),
            );
        }
    }

    /// A residual vector of the inner problem (e.g. a draw of the inputs' noise) with the
    /// prior rows at `x`, which such a draw does not move.
    pub(crate) fn extend(&self, x: &[f64], mut r: Vec<f64>) -> Vec<f64> {
        self.push_rows(x, &mut r);
        r
    }
}

impl<P: ResidualProblem + ?Sized> Problem for WithPrior<'_, P> {
    fn dim(&self) -> usize {
        self.inner.dim()
    }
    fn bounds(&self) -> &Bounds {
        self.inner.bounds()
    }
    fn cost(&self, x: &[f64]) -> f64 {
        let s = self.ssr(x);
        if s.is_finite() {
            s
        } else {
            f64::INFINITY
        }
    }
}

impl<P: ResidualProblem + ?Sized> ResidualProblem for WithPrior<'_, P> {
    fn residuals(&self, x: &[f64], out: &mut Vec<f64>) {
        self.inner.residuals(x, out);
        self.push_rows(x, out);
    }
}

/// The scale `c` of the prior rows from the variance inflation of the data's residuals for
/// their serial correlation (at least 1: never a deflation) and the ratio of the least-squares
/// stage's sum of squares to the plain residuals' at the same point (the stage's whitening
/// rescales every residual, and with it the data's weight): `None` where they give none.
pub(crate) fn row_scale(inflation: f64, whitened_over_plain: f64) -> Option<f64> {
    if !inflation.is_finite() {
        return None;
    }
    let c2 = inflation.max(1.0) * whitened_over_plain;
    (c2.is_finite() && c2 > 0.0).then(|| c2.sqrt())
}

/// What the prior did to one result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PriorReport {
    /// 1σ of the prior on each fitted health parameter, points (about zero, new).
    pub sigma_pts: f64,
    /// Fitted health parameters the data determine weakly, held toward new by the prior (their
    /// σ at least [`HELD_FRACTION`] of the prior's): their reads are the data's pulled toward
    /// zero.
    pub held: Vec<String>,
}

impl PriorReport {
    /// The report of a prior of `sigma_pts` on health parameters given as (index into
    /// [`HEALTH_NAMES`], posterior σ without the model's own error).
    pub(crate) fn of(sigma_pts: f64, health: impl Iterator<Item = (usize, f64)>) -> PriorReport {
        PriorReport {
            sigma_pts,
            held: health
                .filter(|&(_, s)| s.is_nan() || s >= HELD_FRACTION * sigma_pts)
                .filter_map(|(i, _)| HEALTH_NAMES.get(i).map(|n| n.to_string()))
                .collect(),
        }
    }

    /// One line for the text output.
    pub fn line(&self) -> String {
        let held = if self.held.is_empty() {
            "the data determine every fitted parameter well beyond it".to_string()
        } else {
            format!(
                "{} weakly determined by the data, held toward new by it (a fifth or more of what \
                 is known of them is the prior's)",
                self.held.join(", ")
            )
        };
        format!(
            "prior: ± {:.2} points about new (1σ) along what these signals determine only to more \
             than {WEAK_SIGMA_PTS} points ([diagnosis] health_prior_pts, --health-prior; Method B's \
             transient_health_prior_pts); {held}",
            self.sigma_pts
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optim::Bounds;

    /// Two parameters observed only through their sum, `y = a + b = 2` with unit noise.
    struct SumOnly {
        bounds: Bounds,
    }
    impl Problem for SumOnly {
        fn dim(&self) -> usize {
            2
        }
        fn bounds(&self) -> &Bounds {
            &self.bounds
        }
        fn cost(&self, x: &[f64]) -> f64 {
            self.ssr(x)
        }
    }
    impl ResidualProblem for SumOnly {
        fn residuals(&self, x: &[f64], out: &mut Vec<f64>) {
            out.clear();
            out.push(x[0] + x[1] - 2.0);
        }
    }

    #[test]
    fn the_prior_splits_what_only_a_sum_determines_evenly_and_keeps_the_sum() {
        let p = SumOnly {
            bounds: Bounds::new(vec![-10.0, -10.0], vec![10.0, 10.0]).expect("bounds"),
        };
        let rows = vec![
            PriorRow {
                weights: vec![(0, 1.0)],
            },
            PriorRow {
                weights: vec![(1, 1.0)],
            },
        ];
        let w = WithPrior::new(&p, rows);
        // Posterior optimum of (a + b − 2)² + a² + b²: a = b = 2/3.
        let at = |x: [f64; 2]| w.ssr(&x);
        let best = at([2.0 / 3.0, 2.0 / 3.0]);
        for x in [[1.0, 1.0], [2.0, 0.0], [0.6, 0.7], [0.7, 0.7]] {
            assert!(at(x) > best, "{x:?}");
        }
        let mut r = Vec::new();
        w.residuals(&[1.0, 0.5], &mut r);
        assert_eq!(r, vec![-0.5, 1.0, 0.5]);
        assert_eq!(w.extend(&[1.0, 0.5], vec![7.0]), vec![7.0, 1.0, 0.5]);
    }

    #[test]
    fn only_the_weakly_determined_directions_take_the_prior() {
        // Parameters at optimiser indices 0 and 2 (1 is, say, the ambient pressure): their sum
        // determined to 0.05 points, their difference only to 2; index 3 not informed at all.
        let (s_sum, s_diff) = (0.05f64, 2.0f64);
        let a = 0.5 * (s_sum * s_sum + s_diff * s_diff);
        let b = 0.5 * (s_sum * s_sum - s_diff * s_diff);
        let cov = vec![
            vec![a, b, 0.0],
            vec![b, a, 0.0],
            vec![0.0, 0.0, f64::INFINITY],
        ];
        let rows = weak_direction_rows(&[0, 2, 3], &cov, 3.0, 1.5);
        assert_eq!(rows.len(), 2, "{rows:?}");
        // The uninformed parameter alone, weight c / σ_p.
        assert_eq!(rows[0].weights, vec![(3, 2.0)]);
        // The difference, (x0 − x2)/√2, at the same weight; nothing along the sum.
        let w = &rows[1].weights;
        assert_eq!(w.len(), 2);
        assert_eq!((w[0].0, w[1].0), (0, 2));
        assert!((w[0].1.abs() - 2.0 / 2f64.sqrt()).abs() < 1e-9, "{w:?}");
        assert!((w[0].1 + w[1].1).abs() < 1e-9, "{w:?}");
        // Every direction determined within the limit: no rows.
        let tight = vec![vec![0.01, 0.0], vec![0.0, 0.02]];
        assert!(weak_direction_rows(&[0, 1], &tight, 1.0, 1.0).is_empty());
    }

    #[test]
    fn the_report_names_what_leans_on_the_prior() {
        let r = PriorReport::of(
            1.0,
            [(0, 0.05), (3, 0.5), (4, f64::INFINITY), (5, 0.44)].into_iter(),
        );
        assert_eq!(r.held, vec!["D_ET", "D_GP"]);
        assert!(
            r.line().contains("D_ET, D_GP weakly determined"),
            "{}",
            r.line()
        );
        let none = PriorReport::of(1.0, [(0, 0.05)].into_iter());
        assert!(none.line().contains("determine every fitted parameter"));
    }

    #[test]
    fn the_rows_weigh_as_the_residuals_independent_readings() {
        let c = |i, w| row_scale(i, w).expect("a scale");
        assert!((c(9.0, 1.0) - 3.0).abs() < 1e-12);
        // A whitening that halves every residual halves the rows too.
        assert!((c(9.0, 0.25) - 1.5).abs() < 1e-12);
        // An inflation under 1 is not a deflation.
        assert_eq!(c(0.5, 1.0), 1.0);
        assert!(row_scale(f64::NAN, 1.0).is_none());
        assert!(row_scale(1.0, 0.0).is_none());
    }
}
