//! Linearised least-squares uncertainty at an optimum: covariance `s² (JᵀJ)⁻¹` with
//! `s² = SSR / (m − n)`, reported as 1σ per parameter in physical units plus the correlation
//! matrix. Pure; the finite-difference Jacobian is evaluated in parallel on the caller's pool.
//!
//! Rank deficiency is reported, never hidden: the inverse is an SVD pseudo-inverse that drops
//! singular values below `1e-9 · s_max` (below that a finite-difference Jacobian is noise), and
//! every parameter that loads on a dropped direction (or whose Jacobian column could not be
//! evaluated) is marked not identifiable, with σ = +∞ and zero correlations. No NaN leaves
//! this module.

use super::lm::{jacobian_unit, residuals_unit};
use super::{JacobianOptions, OptimError, ResidualProblem};
use rayon::ThreadPool;

/// Relative singular-value cut-off for the pseudo-inverse.
const RCOND: f64 = 1e-9;

/// Parameter uncertainty at a least-squares optimum, physical units.
#[derive(Debug, Clone, PartialEq)]
pub struct Uncertainty {
    /// 1σ per parameter (`+∞` where not identifiable).
    pub sigma: Vec<f64>,
    /// Covariance matrix (n × n, row-major rows); `+∞` on the diagonal and 0 off it for
    /// parameters that are not identifiable.
    pub covariance: Vec<Vec<f64>>,
    /// Correlation matrix (n × n); 1 on the diagonal, 0 for non-identifiable parameters.
    pub correlation: Vec<Vec<f64>>,
    /// Whether each parameter is determined by the data (full rank in its direction).
    pub identifiable: Vec<bool>,
    /// Whether each parameter sits on a bound (the linear estimate is then only indicative).
    pub at_bound: Vec<bool>,
    /// Residual variance estimate `SSR / (m − n)`.
    pub s2: f64,
    /// Residual sum of squares at `x`.
    pub ssr: f64,
    /// Degrees of freedom `m − n`.
    pub dof: usize,
    /// Numerical rank of J.
    pub rank: usize,
    /// Residual evaluations used.
    pub evals: usize,
    /// 1σ per parameter from the noise of the problem's inputs (0 without input draws; `+∞`
    /// where not identifiable): the spread of the linearised re-fits to the residual vectors
    /// the caller computed at `x` with other draws of that noise. Not part of `covariance`.
    pub input_sigma: Vec<f64>,
    /// Correlation of that part between parameters (one input, the fuel meter, moves several
    /// parameters together); 1 on the diagonal, 0 where either part is 0 or not identifiable.
    pub input_correlation: Vec<Vec<f64>>,
}

/// Uncertainty of the parameters `x` (physical units) of `problem`, from the residual
/// Jacobian at `x`. Needs more residuals than parameters and finite residuals at `x`.
pub fn uncertainty<P: ResidualProblem + ?Sized>(
    problem: &P,
    x: &[f64],
    opts: &JacobianOptions,
    pool: &ThreadPool,
) -> Result<Uncertainty, OptimError> {
    uncertainty_with_inputs(problem, x, opts, pool, &[])
}

/// [`uncertainty`], plus the part of the parameters' uncertainty that comes from noise on the
/// problem's *inputs* (errors in variables), which the residuals cannot show: an input error
/// the parameters absorb leaves no residual behind. `input_draws` are residual vectors at `x`
/// computed with independent draws of the input noise (same data otherwise); each one's
/// linearised re-fit `(JᵀJ)⁺ Jᵀ (r_j − r)` is a sample of the parameters' error, and their
/// mean square is the input part of the variance (`input_sigma`). Draws of the wrong length or
/// with non-finite entries are skipped.
pub fn uncertainty_with_inputs<P: ResidualProblem + ?Sized>(
    problem: &P,
    x: &[f64],
    opts: &JacobianOptions,
    pool: &ThreadPool,
    input_draws: &[Vec<f64>],
) -> Result<Uncertainty, OptimError> {
    let bounds = problem.bounds();
    bounds.check_inside(x)?;
    let n = problem.dim();
    let u: Vec<f64> = bounds
        .to_unit(x)
        .iter()
        .map(|v| v.clamp(0.0, 1.0))
        .collect();
    let r = residuals_unit(problem, &u, None).ok_or(OptimError::NonFiniteResiduals)?;
    let m = r.len();
    if m <= n {
        return Err(OptimError::TooFewResiduals { m, n });
    }
    let (jac, failed, used) = jacobian_unit(problem, &u, &r, opts, pool);
    let ssr: f64 = r.iter().map(|v| v * v).sum();
    let dof = m - n;
    let s2 = ssr / dof as f64;

    // The draws' scores Jᵀ(r_j − r) before the SVD takes J.
    let scores = input_scores(&jac, &r, input_draws);

    // J = U S Vᵀ  ⇒  (JᵀJ)⁺ = V S⁻² Vᵀ over the kept singular values.
    let svd = jac.svd(false, true);
    let v_t = svd.v_t.ok_or(OptimError::NonFiniteResiduals)?;
    let s = &svd.singular_values;
    let s_max = s.iter().cloned().fold(0.0, f64::max);
    let keep: Vec<bool> = s
        .iter()
        .map(|&v| s_max > 0.0 && v > RCOND * s_max)
        .collect();
    let rank = keep.iter().filter(|&&k| k).count();
    let mut identifiable: Vec<bool> = failed.iter().map(|f| !f).collect();
    for (k, &kept) in keep.iter().enumerate() {
        if !kept {
            for (j, id) in identifiable.iter_mut().enumerate() {
                if v_t[(k, j)].abs() > 1e-6 {
                    *id = false;
                }
            }
        }
    }
    let mut cov_unit = vec![vec![0.0; n]; n];
    for (k, &kept) in keep.iter().enumerate() {
        if kept {
            let w = 1.0 / (s[k] * s[k]);
            for i in 0..n {
                for j in 0..n {
                    cov_unit[i][j] += w * v_t[(k, i)] * v_t[(k, j)];
                }
            }
        }
    }
    // Scale to physical units: x = lower + u · width.
    let mut covariance = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in 0..n {
            covariance[i][j] = if !identifiable[i] || !identifiable[j] {
                if i == j {
                    f64::INFINITY
                } else {
                    0.0
                }
            } else {
                s2 * cov_unit[i][j] * bounds.width(i) * bounds.width(j)
            };
        }
    }
    let sigma: Vec<f64> = (0..n).map(|i| covariance[i][i].max(0.0).sqrt()).collect();
    let spread = input_spread(&cov_unit, &scores, &identifiable);
    let input_sigma = (0..n)
        .map(|i| {
            if identifiable[i] {
                spread[i][i].max(0.0).sqrt() * bounds.width(i)
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let input_correlation = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| {
                    let scale = (spread[i][i] * spread[j][j]).sqrt();
                    if i == j {
                        1.0
                    } else if identifiable[i] && identifiable[j] && scale > 0.0 {
                        (spread[i][j] / scale).clamp(-1.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect();
    let mut correlation = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in 0..n {
            correlation[i][j] = if i == j {
                1.0
            } else if identifiable[i] && identifiable[j] && sigma[i] > 0.0 && sigma[j] > 0.0 {
                (covariance[i][j] / (sigma[i] * sigma[j])).clamp(-1.0, 1.0)
            } else {
                0.0
            };
        }
    }
    let at_bound = u.iter().map(|&v| v <= 0.0 || v >= 1.0).collect();
    Ok(Uncertainty {
        sigma,
        covariance,
        correlation,
        identifiable,
        at_bound,
        s2,
        ssr,
        dof,
        rank,
        evals: used + 1,
        input_sigma,
        input_correlation,
    })
}

/// The score `Jᵀ (r_j − r)` of each usable input draw (draws of the wrong length or with
/// non-finite entries are skipped).
fn input_scores(jac: &nalgebra::DMatrix<f64>, r: &[f64], draws: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = jac.ncols();
    draws
        .iter()
        .filter(|d| d.len() == r.len() && d.iter().all(|v| v.is_finite()))
        .map(|d| {
            let mut score = vec![0.0; n];
            for (i, (a, b)) in d.iter().zip(r).enumerate() {
                let diff = a - b;
                for (j, sj) in score.iter_mut().enumerate() {
                    *sj += jac[(i, j)] * diff;
                }
            }
            score
        })
        .collect()
}

/// The mean product of the linearised re-fits `B s_j` over the draws' `scores`, parameter by
/// parameter (unit scale; `B = (JᵀJ)⁺`, columns of parameters that are not identifiable left
/// out): the input part's covariance. Zeros without any draw.
fn input_spread(bread: &[Vec<f64>], scores: &[Vec<f64>], identifiable: &[bool]) -> Vec<Vec<f64>> {
    let n = bread.len();
    let mut acc = vec![vec![0.0; n]; n];
    for score in scores {
        let g: Vec<f64> = (0..n)
            .map(|i| {
                (0..n)
                    .filter(|&k| identifiable[k])
                    .map(|k| bread[i][k] * score[k])
                    .sum()
            })
            .collect();
        for (i, row) in acc.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += g[i] * g[j];
            }
        }
    }
    if !scores.is_empty() {
        let m = scores.len() as f64;
        acc.iter_mut().flatten().for_each(|v| *v /= m);
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::super::{thread_pool, Bounds, Problem};
    use super::*;

    /// Residuals depend on x0 + x1 only: x0 and x1 are not separately identifiable.
    struct Degenerate(Bounds);
    impl Problem for Degenerate {
        fn dim(&self) -> usize {
            3
        }
        fn bounds(&self) -> &Bounds {
            &self.0
        }
        fn cost(&self, x: &[f64]) -> f64 {
            self.ssr(x)
        }
    }
    impl ResidualProblem for Degenerate {
        fn residuals(&self, x: &[f64], out: &mut Vec<f64>) {
            out.clear();
            for i in 0..10 {
                let t = i as f64;
                out.push(x[0] + x[1] - 1.0 + 0.01 * (t * 1.3).sin());
                out.push(x[2] * t - 2.0 + 0.01 * (t * 0.7).cos());
            }
        }
    }

    #[test]
    fn rank_deficiency_gives_infinite_sigma_never_nan() {
        let p = Degenerate(Bounds::uniform(3, -5.0, 5.0).expect("valid"));
        let pool = thread_pool(Some(1)).expect("pool");
        let u = uncertainty(&p, &[0.5, 0.5, 0.2], &JacobianOptions::default(), &pool)
            .expect("uncertainty");
        assert_eq!(u.rank, 2);
        assert_eq!(u.identifiable, vec![false, false, true]);
        assert!(u.sigma[0].is_infinite() && u.sigma[1].is_infinite());
        assert!(u.sigma[2].is_finite() && u.sigma[2] > 0.0);
        let all = u.covariance.iter().chain(&u.correlation).flatten();
        assert!(all.clone().all(|v| !v.is_nan()));
        assert_eq!(u.correlation[0][2], 0.0);
        assert_eq!(u.correlation[1][1], 1.0);
    }

    /// z = θ·u measured against an input u that carries noise of σ_u: the input part of θ's σ
    /// from draws of that noise is the analytic θ·σ_u/√Σu² (within the draws' own sampling
    /// error), and without draws it is 0.
    struct Scaled {
        bounds: Bounds,
        u: Vec<f64>,
        z: Vec<f64>,
    }
    impl Problem for Scaled {
        fn dim(&self) -> usize {
            1
        }
        fn bounds(&self) -> &Bounds {
            &self.bounds
        }
        fn cost(&self, x: &[f64]) -> f64 {
            self.ssr(x)
        }
    }
    impl ResidualProblem for Scaled {
        fn residuals(&self, x: &[f64], out: &mut Vec<f64>) {
            out.clear();
            out.extend(self.u.iter().zip(&self.z).map(|(u, z)| z - x[0] * u));
        }
    }

    /// A straight line `x0 + x1·t` through 11 points.
    struct Line(Bounds);
    impl Problem for Line {
        fn dim(&self) -> usize {
            2
        }
        fn bounds(&self) -> &Bounds {
            &self.0
        }
        fn cost(&self, x: &[f64]) -> f64 {
            self.ssr(x)
        }
    }
    impl ResidualProblem for Line {
        fn residuals(&self, x: &[f64], out: &mut Vec<f64>) {
            out.clear();
            for i in 0..11 {
                let t = f64::from(i);
                out.push(x[0] + x[1] * t - (1.0 + 0.5 * t) + 0.01 * (t * 1.7).sin());
            }
        }
    }

    /// An input error that moves both parameters together (its draws shift the residuals
    /// along `v0 + v1·t`) is correlated between them as `v` says, with each one's σ `|vᵢ|`.
    #[test]
    fn the_inputs_part_carries_its_own_correlation() {
        let p = Line(Bounds::uniform(2, -5.0, 5.0).expect("valid"));
        let pool = thread_pool(Some(1)).expect("pool");
        let x = [1.0, 0.5];
        let mut r = Vec::new();
        p.residuals(&x, &mut r);
        for (v, sign) in [([0.3, 0.1], 1.0), ([0.2, -0.05], -1.0)] {
            let draws: Vec<Vec<f64>> = [1.0, -1.0, 2.0f64.sqrt(), -(2.0f64.sqrt())]
                .iter()
                .map(|e| {
                    r.iter()
                        .enumerate()
                        .map(|(i, ri)| ri + e * (v[0] + v[1] * i as f64))
                        .collect()
                })
                .collect();
            let u = uncertainty_with_inputs(&p, &x, &JacobianOptions::default(), &pool, &draws)
                .expect("uncertainty");
            // The draws' mean square is 1.5.
            for (vi, si) in v.iter().zip(&u.input_sigma) {
                let want = vi.abs() * 1.5f64.sqrt();
                assert!((si / want - 1.0).abs() < 1e-4, "{u:?}");
            }
            assert!((u.input_correlation[0][1] - sign).abs() < 1e-6, "{u:?}");
            assert_eq!(u.input_correlation[1][0], u.input_correlation[0][1]);
            assert_eq!(u.input_correlation[0][0], 1.0);
        }
        let none = uncertainty(&p, &x, &JacobianOptions::default(), &pool).expect("none");
        assert_eq!(none.input_correlation, vec![vec![1.0, 0.0], vec![0.0, 1.0]]);
    }

    #[test]
    fn input_noise_adds_the_analytic_sigma_of_an_errors_in_variables_fit() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let (theta, sigma_u) = (2.0, 0.05);
        let u: Vec<f64> = (0..40).map(|i| 1.0 + 0.1 * f64::from(i)).collect();
        let z: Vec<f64> = u.iter().map(|v| theta * v).collect();
        let p = Scaled {
            bounds: Bounds::uniform(1, 0.0, 5.0).expect("valid"),
            u: u.clone(),
            z: z.clone(),
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let draws: Vec<Vec<f64>> = (0..2000)
            .map(|_| {
                u.iter()
                    .zip(&z)
                    .map(|(v, zz)| {
                        let e: f64 = StandardNormal.sample(&mut rng);
                        zz - theta * (v + sigma_u * e)
                    })
                    .collect()
            })
            .collect();
        let pool = thread_pool(Some(1)).expect("pool");
        let o = JacobianOptions::default();
        let with = uncertainty_with_inputs(&p, &[theta], &o, &pool, &draws).expect("with");
        let analytic = theta * sigma_u / u.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(
            (with.input_sigma[0] / analytic - 1.0).abs() < 0.05,
            "input σ {} against {analytic}",
            with.input_sigma[0]
        );
        let without = uncertainty(&p, &[theta], &o, &pool).expect("without");
        assert_eq!(without.input_sigma, vec![0.0]);
        // A draw of the wrong length or with a NaN is skipped, not averaged in.
        let bad = vec![vec![0.0; 3], vec![f64::NAN; u.len()]];
        let skipped = uncertainty_with_inputs(&p, &[theta], &o, &pool, &bad).expect("bad");
        assert_eq!(skipped.input_sigma, vec![0.0]);
    }

    #[test]
    fn rejects_too_few_residuals_and_bad_points() {
        let p =
            super::super::test_functions::TestFunction::sphere(6, -3.0, 10.0, 1.7).expect("valid");
        let pool = thread_pool(Some(1)).expect("pool");
        let o = JacobianOptions::default();
        assert_eq!(
            uncertainty(&p, &[1.7; 6], &o, &pool),
            Err(OptimError::TooFewResiduals { m: 6, n: 6 })
        );
        assert!(uncertainty(&p, &[11.0; 6], &o, &pool).is_err());
        assert!(JacobianOptions::default().with_step(0.0).is_err());
    }
}
