//! Identifiability of the health parameters from a data set: the sensitivity (Jacobian) of the
//! noise-normalised residuals with respect to each parameter, the Fisher information
//! `F = JᵀJ` (residuals are in noise-σ units, so F is the information of a unit-variance
//! Gaussian model), the Cramér–Rao 1σ bound per parameter `√(F⁻¹)ᵢᵢ`, the 1σ if that parameter
//! alone were fitted `1/√Fᵢᵢ`, and the condition number of the column-scaled Jacobian. A large
//! ratio between the joint and the alone σ means the parameter is confounded with others.
//! Used to justify (or refute) a parameter that a data set cannot reveal. Pure: no I/O.

use super::DiagnosisError;
use crate::optim::lm::jacobian_unit;
use crate::optim::{FiniteDifference, JacobianOptions, ResidualProblem};
use nalgebra::DMatrix;
use rayon::ThreadPool;
use serde::Serialize;

/// Identifiability of the free parameters at one point.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Identifiability {
    /// Cramér–Rao 1σ per parameter with all parameters fitted jointly, % (∞ if singular).
    pub crb_sigma: Vec<f64>,
    /// 1σ per parameter if it were the only one fitted, %.
    pub alone_sigma: Vec<f64>,
    /// Euclidean norm of each sensitivity column, noise σ per % (√Fᵢᵢ).
    pub sensitivity: Vec<f64>,
    /// Condition number of the Jacobian with unit-norm columns.
    pub condition: f64,
    /// Correlation matrix implied by F⁻¹.
    pub correlation: Vec<Vec<f64>>,
}

/// Computes the identifiability of `problem`'s parameters at `x` (physical units, %).
/// `step` is the central-difference step as a fraction of the box.
pub fn identifiability<P: ResidualProblem + ?Sized>(
    problem: &P,
    x: &[f64],
    step: f64,
    pool: &ThreadPool,
) -> Result<Identifiability, DiagnosisError> {
    let b = problem.bounds();
    let u = b.to_unit(x);
    let mut r0 = Vec::new();
    problem.residuals(x, &mut r0);
    if r0.iter().any(|v| !v.is_finite()) {
        return Err(DiagnosisError::Data(
            "residuals are not finite at the point".into(),
        ));
    }
    let opts = JacobianOptions::default()
        .with_scheme(FiniteDifference::Central)?
        .with_step(step)?;
    let (ju, _failed, _) = jacobian_unit(problem, &u, &r0, &opts, pool);
    let n = x.len();
    // Unit → physical: dr/dx = dr/du / width.
    let mut j = ju.clone();
    for c in 0..n {
        let w = b.width(c);
        for r in 0..j.nrows() {
            j[(r, c)] /= w;
        }
    }
    let f: DMatrix<f64> = j.transpose() * &j;
    let sensitivity: Vec<f64> = (0..n).map(|i| f[(i, i)].sqrt()).collect();
    let alone_sigma = sensitivity
        .iter()
        .map(|s| if *s > 0.0 { 1.0 / s } else { f64::INFINITY })
        .collect();
    let (crb_sigma, correlation) = match f.clone().try_inverse() {
        Some(inv) => {
            let sd: Vec<f64> = (0..n).map(|i| inv[(i, i)].max(0.0).sqrt()).collect();
            let corr = (0..n)
                .map(|i| {
                    (0..n)
                        .map(|k| inv[(i, k)] / (sd[i] * sd[k]).max(1e-300))
                        .collect()
                })
                .collect();
            (sd, corr)
        }
        None => (vec![f64::INFINITY; n], vec![vec![0.0; n]; n]),
    };
    let mut js = j.clone();
    for c in 0..n {
        let norm = sensitivity[c].max(1e-300);
        for r in 0..js.nrows() {
            js[(r, c)] /= norm;
        }
    }
    let sv = js.singular_values();
    let smax = sv.iter().cloned().fold(0.0, f64::max);
    let smin = sv.iter().cloned().fold(f64::INFINITY, f64::min);
    let condition = if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    Ok(Identifiability {
        crb_sigma,
        alone_sigma,
        sensitivity,
        condition,
        correlation,
    })
}
