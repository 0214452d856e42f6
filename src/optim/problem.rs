//! The optimisation problem, separate from any solver: dimension, box bounds, cost and
//! (optionally) residuals, all in physical units. No solver state and no I/O here.

use super::Bounds;

/// A bounded minimisation problem. `cost` is called from several rayon threads at once, hence
/// `Sync`; it must be deterministic for the run to be reproducible.
pub trait Problem: Sync {
    /// Number of parameters.
    fn dim(&self) -> usize;
    /// Lower/upper bound per parameter, physical units.
    fn bounds(&self) -> &Bounds;
    /// Cost at `x` (physical units, length `dim()`). Return `f64::INFINITY` for a failed
    /// evaluation (e.g. a simulation that did not converge); `NaN` is treated the same way.
    fn cost(&self, x: &[f64]) -> f64;
}

/// A problem whose cost is (a monotone function of) a sum of squared residuals, for
/// Levenberg–Marquardt refinement and least-squares uncertainty.
///
/// The residuals should be scaled so that each has (roughly) the same noise standard
/// deviation; [`super::uncertainty()`] estimates that common σ from the fit (`s² = SSR/(m−n)`).
pub trait ResidualProblem: Problem {
    /// Write the residual vector at `x` into `out` (cleared first by the implementation or the
    /// caller; implementations must leave exactly `m` entries, the same `m` at every `x`).
    /// Non-finite entries mark a failed evaluation.
    fn residuals(&self, x: &[f64], out: &mut Vec<f64>);

    /// The residual sum of squares at `x`: the cost of a plain least-squares problem (its
    /// [`Problem::cost`] can be just this).
    fn ssr(&self, x: &[f64]) -> f64 {
        let mut r = Vec::new();
        self.residuals(x, &mut r);
        r.iter().map(|v| v * v).sum()
    }
}
