//! Standard analytic test problems (sphere, Rosenbrock, Rastrigin) with a known, shifted
//! optimum inside a box, for tests and benches of the solvers. Pure functions; no I/O.
//!
//! The optimum is moved to `shift` (cost 0 there) so that no solver is favoured by starting at
//! the box centre.

use super::{Bounds, OptimError, Problem, ResidualProblem};

/// Which analytic function.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// `Σ z²`.
    Sphere,
    /// `Σ 100 (z_{i+1} − z_i²)² + (1 − z_i)²` with `z = x − shift + 1` (minimum at `shift`).
    Rosenbrock,
    /// `10 n + Σ (z² − 10 cos 2πz)`, many local minima on an integer lattice around `shift`.
    Rastrigin,
}

/// A test problem with its known minimiser.
#[derive(Debug, Clone, PartialEq)]
pub struct TestFunction {
    kind: Kind,
    bounds: Bounds,
    shift: Vec<f64>,
}

impl TestFunction {
    /// Generic constructor; `shift` (the minimiser) must lie inside the bounds.
    pub fn new(kind: Kind, bounds: Bounds, shift: Vec<f64>) -> Result<Self, OptimError> {
        bounds.check_inside(&shift)?;
        Ok(Self {
            kind,
            bounds,
            shift,
        })
    }

    /// Sphere in `[lo, hi]^dim` with minimiser `(s, …, s)`.
    pub fn sphere(dim: usize, lo: f64, hi: f64, s: f64) -> Result<Self, OptimError> {
        Self::new(Kind::Sphere, Bounds::uniform(dim, lo, hi)?, vec![s; dim])
    }

    /// Rosenbrock in `[lo, hi]^dim` with minimiser `(s, …, s)`.
    pub fn rosenbrock(dim: usize, lo: f64, hi: f64, s: f64) -> Result<Self, OptimError> {
        Self::new(
            Kind::Rosenbrock,
            Bounds::uniform(dim, lo, hi)?,
            vec![s; dim],
        )
    }

    /// Rastrigin in `[lo, hi]^dim` with minimiser `(s, …, s)`.
    pub fn rastrigin(dim: usize, lo: f64, hi: f64, s: f64) -> Result<Self, OptimError> {
        Self::new(Kind::Rastrigin, Bounds::uniform(dim, lo, hi)?, vec![s; dim])
    }

    /// The known minimiser (cost 0).
    pub fn minimiser(&self) -> &[f64] {
        &self.shift
    }

    /// Which function.
    pub fn kind(&self) -> Kind {
        self.kind
    }
}

impl Problem for TestFunction {
    fn dim(&self) -> usize {
        self.shift.len()
    }
    fn bounds(&self) -> &Bounds {
        &self.bounds
    }
    fn cost(&self, x: &[f64]) -> f64 {
        let mut r = Vec::new();
        self.residuals(x, &mut r);
        match self.kind {
            // Rastrigin is not a sum of squares of these "residuals"; computed directly.
            Kind::Rastrigin => x
                .iter()
                .zip(&self.shift)
                .map(|(v, s)| {
                    let z = v - s;
                    z * z - 10.0 * (2.0 * std::f64::consts::PI * z).cos() + 10.0
                })
                .sum(),
            _ => r.iter().map(|v| v * v).sum(),
        }
    }
}

/// Sphere and Rosenbrock are sums of squares; Rastrigin's residuals here are `z` (its quadratic
/// envelope), useful only for exercising code paths.
impl ResidualProblem for TestFunction {
    fn residuals(&self, x: &[f64], out: &mut Vec<f64>) {
        out.clear();
        let z: Vec<f64> = x.iter().zip(&self.shift).map(|(v, s)| v - s).collect();
        match self.kind {
            Kind::Sphere | Kind::Rastrigin => out.extend_from_slice(&z),
            Kind::Rosenbrock => {
                let z: Vec<f64> = z.iter().map(|v| v + 1.0).collect();
                for i in 0..z.len().saturating_sub(1) {
                    out.push(10.0 * (z[i + 1] - z[i] * z[i]));
                    out.push(1.0 - z[i]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimum_is_zero_at_shift_and_positive_elsewhere() {
        for f in [
            TestFunction::sphere(6, -3.0, 10.0, 2.0),
            TestFunction::rosenbrock(6, -3.0, 10.0, 2.0),
            TestFunction::rastrigin(6, -3.0, 10.0, 2.0),
        ] {
            let f = f.expect("valid");
            assert!(f.cost(f.minimiser()).abs() < 1e-12);
            assert!(f.cost(&[2.5; 6]) > 0.1);
            assert!(f.cost(&[-1.0, 0.0, 4.0, 2.0, 2.0, 2.0]) > 1.0);
        }
        // Rastrigin's local minimum at shift + 1 in one coordinate costs ≈ 1.
        let r = TestFunction::rastrigin(6, -3.0, 10.0, 2.0).expect("valid");
        let mut x = vec![2.0; 6];
        x[0] = 3.0;
        assert!((r.cost(&x) - 1.0).abs() < 1e-9);
        assert!(TestFunction::sphere(6, -3.0, 10.0, 11.0).is_err());
    }
}
