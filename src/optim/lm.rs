//! Levenberg–Marquardt local refinement of a [`ResidualProblem`] inside box bounds, and the
//! finite-difference residual Jacobian it shares with [`super::uncertainty()`].
//!
//! Works in normalised `[0, 1]` coordinates so the finite-difference step and the damping are
//! comparable across parameters. Bounds: parameters sitting on a bound whose gradient pushes
//! outward are frozen for the iteration (a simple active set), and the step is then projected
//! (clamped) into the box. Damping is Marquardt's `λ · diag(JᵀJ)` (floored so insensitive
//! parameters stay regular). Minimises the residual sum of squares `SSR = Σ r²`, which is the
//! right refinement only when [`Problem::cost`](super::Problem::cost) is (a monotone function
//! of) SSR. Jacobian columns are evaluated in parallel on the caller's rayon pool; evaluation
//! order does not affect the result. No I/O, no globals, no randomness.

use super::{setting, Bounds, OptimError, ResidualProblem};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use rayon::ThreadPool;

/// Finite-difference scheme for the Jacobian.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FiniteDifference {
    /// `(r(u + h) − r(u)) / h`: n extra evaluations, error O(h).
    Forward,
    /// `(r(u + h) − r(u − h)) / 2h`: 2n extra evaluations, error O(h²); better for noisy models.
    Central,
}

/// How to difference the residuals. The step is in normalised units (fraction of the box).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JacobianOptions {
    scheme: FiniteDifference,
    step: f64,
}

impl Default for JacobianOptions {
    /// Central differences, step 1e-4 of the box width (0.0013 %-points for −3 … +10 %):
    /// large enough to rise above a simulation's solver noise, small enough for mild
    /// nonlinearity.
    fn default() -> Self {
        Self {
            scheme: FiniteDifference::Central,
            step: 1e-4,
        }
    }
}

impl JacobianOptions {
    /// Choose the scheme.
    pub fn with_scheme(mut self, s: FiniteDifference) -> Result<Self, OptimError> {
        self.scheme = s;
        Ok(self)
    }
    /// Step in normalised units, in (0, 0.1].
    pub fn with_step(mut self, h: f64) -> Result<Self, OptimError> {
        if !(h > 0.0 && h <= 0.1) {
            return Err(setting(
                "fd_step",
                "must lie in (0, 0.1] (normalised units)",
            ));
        }
        self.step = h;
        Ok(self)
    }
    /// The scheme.
    pub fn scheme(&self) -> FiniteDifference {
        self.scheme
    }
    /// The step (normalised units).
    pub fn step(&self) -> f64 {
        self.step
    }
}

/// Levenberg–Marquardt settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOptions {
    jacobian: JacobianOptions,
    max_iterations: usize,
    max_evals: Option<usize>,
    ftol: f64,
    xtol: f64,
    lambda0: f64,
}

impl Default for LmOptions {
    /// Central-difference Jacobian (step 1e-4), 50 iterations, no evaluation cap,
    /// ftol = 1e-10 (relative SSR decrease), xtol = 1e-10 (normalised step), λ₀ = 1e-3.
    fn default() -> Self {
        Self {
            jacobian: JacobianOptions::default(),
            max_iterations: 50,
            max_evals: None,
            ftol: 1e-10,
            xtol: 1e-10,
            lambda0: 1e-3,
        }
    }
}

impl LmOptions {
    /// Jacobian options.
    pub fn with_jacobian(mut self, j: JacobianOptions) -> Result<Self, OptimError> {
        self.jacobian = j;
        Ok(self)
    }
    /// Maximum LM iterations (Jacobian evaluations), > 0.
    pub fn with_max_iterations(mut self, n: usize) -> Result<Self, OptimError> {
        if n == 0 {
            return Err(setting("max_iterations", "must be > 0"));
        }
        self.max_iterations = n;
        Ok(self)
    }
    /// Cap on evaluations including the final cost evaluation (≥ 2). Refinement stops before
    /// a Jacobian or trial step that would exceed it, so `evals <= max_evals` always holds.
    pub fn with_max_evals(mut self, n: usize) -> Result<Self, OptimError> {
        if n < 2 {
            return Err(setting("max_evals", "must be >= 2"));
        }
        self.max_evals = Some(n);
        Ok(self)
    }
    /// Stop when an accepted step lowers SSR by less than this fraction (≥ 0).
    pub fn with_ftol(mut self, t: f64) -> Result<Self, OptimError> {
        if !(t.is_finite() && t >= 0.0) {
            return Err(setting("ftol", "must be finite and >= 0"));
        }
        self.ftol = t;
        Ok(self)
    }
    /// Stop when the (projected) step is shorter than this, normalised units (≥ 0).
    pub fn with_xtol(mut self, t: f64) -> Result<Self, OptimError> {
        if !(t.is_finite() && t >= 0.0) {
            return Err(setting("xtol", "must be finite and >= 0"));
        }
        self.xtol = t;
        Ok(self)
    }
    /// Initial damping λ₀ (> 0).
    pub fn with_lambda0(mut self, l: f64) -> Result<Self, OptimError> {
        if !(l.is_finite() && l > 0.0) {
            return Err(setting("lambda0", "must be finite and > 0"));
        }
        self.lambda0 = l;
        Ok(self)
    }
}

/// Why refinement stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RefineStop {
    /// Relative SSR decrease of an accepted step fell below `ftol`.
    CostChange,
    /// The projected step fell below `xtol`.
    StepSize,
    /// `max_iterations` reached.
    MaxIterations,
    /// The evaluation cap would be exceeded by the next Jacobian or trial.
    MaxEvals,
    /// No downhill step even with very strong damping: a (possibly constrained) minimum.
    NoDescent,
    /// SSR is exactly zero.
    ZeroResidual,
}

/// Result of [`refine`]. `x` in physical units.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineResult {
    /// Refined point, physical units.
    pub x: Vec<f64>,
    /// Residual sum of squares at `x`.
    pub ssr: f64,
    /// [`Problem::cost`](super::Problem::cost) at `x` (one extra evaluation, counted).
    pub cost: f64,
    /// LM iterations (Jacobians computed).
    pub iterations: usize,
    /// Residual and cost evaluations used.
    pub evals: usize,
    /// Why it stopped.
    pub stop: RefineStop,
}

/// Residuals at normalised `u`; `None` if any entry is non-finite or the length differs
/// from `m` (when given).
pub(crate) fn residuals_unit<P: ResidualProblem + ?Sized>(
    problem: &P,
    u: &[f64],
    m: Option<usize>,
) -> Option<Vec<f64>> {
    let mut out = Vec::new();
    problem.residuals(&problem.bounds().from_unit(u), &mut out);
    let ok = out.iter().all(|v| v.is_finite()) && m.is_none_or(|m| out.len() == m);
    ok.then_some(out)
}

/// Finite-difference Jacobian in normalised coordinates (m × n) at `u` with residuals `r0`.
/// Steps that would leave `[0, 1]` are taken one-sided inwards. A column whose perturbed
/// residuals fail is returned as zeros and flagged `true` in the second element. The third
/// element is the number of residual evaluations used.
pub(crate) fn jacobian_unit<P: ResidualProblem + ?Sized>(
    problem: &P,
    u: &[f64],
    r0: &[f64],
    opts: &JacobianOptions,
    pool: &ThreadPool,
) -> (DMatrix<f64>, Vec<bool>, usize) {
    let n = u.len();
    let m = r0.len();
    let h = opts.step;
    // Per column: the upper and lower abscissa; `None` means "u itself" (use r0).
    let mut plan: Vec<(Option<f64>, Option<f64>)> = Vec::with_capacity(n);
    for &uj in u {
        plan.push(match opts.scheme {
            FiniteDifference::Forward if uj + h <= 1.0 => (Some(uj + h), None),
            FiniteDifference::Forward => (None, Some(uj - h)),
            FiniteDifference::Central => (Some((uj + h).min(1.0)), Some((uj - h).max(0.0))),
        });
    }
    let mut points: Vec<Vec<f64>> = Vec::with_capacity(2 * n);
    for (j, (up, lo)) in plan.iter().enumerate() {
        for v in [up, lo].into_iter().flatten() {
            let mut p = u.to_vec();
            p[j] = *v;
            points.push(p);
        }
    }
    let evaluated: Vec<Option<Vec<f64>>> = pool.install(|| {
        points
            .par_iter()
            .map(|p| residuals_unit(problem, p, Some(m)))
            .collect()
    });
    let mut jac = DMatrix::zeros(m, n);
    let mut failed = vec![false; n];
    let mut k = 0;
    for (j, (up, lo)) in plan.iter().enumerate() {
        let mut take = |v: &Option<f64>| -> (f64, Option<&[f64]>) {
            match v {
                Some(x) => {
                    k += 1;
                    (*x, evaluated[k - 1].as_deref())
                }
                None => (u[j], Some(r0)),
            }
        };
        let (x_up, r_up) = take(up);
        let (x_lo, r_lo) = take(lo);
        match (r_up, r_lo) {
            (Some(a), Some(b)) => {
                let dx = x_up - x_lo;
                for i in 0..m {
                    jac[(i, j)] = (a[i] - b[i]) / dx;
                }
            }
            _ => failed[j] = true,
        }
    }
    (jac, failed, points.len())
}

fn ssr_of(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// Refine `x0` (physical units, inside the bounds) by bounded Levenberg–Marquardt on the
/// problem's residuals. Jacobian columns are evaluated in parallel on `pool`.
pub fn refine<P: ResidualProblem + ?Sized>(
    problem: &P,
    x0: &[f64],
    opts: &LmOptions,
    pool: &ThreadPool,
) -> Result<RefineResult, OptimError> {
    let bounds: &Bounds = problem.bounds();
    bounds.check_inside(x0)?;
    let n = problem.dim();
    let mut u: Vec<f64> = bounds
        .to_unit(x0)
        .iter()
        .map(|v| v.clamp(0.0, 1.0))
        .collect();
    let mut r = residuals_unit(problem, &u, None).ok_or(OptimError::NonFiniteResiduals)?;
    if r.is_empty() {
        return Err(OptimError::TooFewResiduals { m: 0, n });
    }
    let m = r.len();
    let mut ssr = ssr_of(&r);
    let mut evals = 1usize;
    let jac_cost = match opts.jacobian.scheme {
        FiniteDifference::Forward => n,
        FiniteDifference::Central => 2 * n,
    };
    let can_spend = |evals: usize, k: usize| opts.max_evals.is_none_or(|mx| evals + k < mx);
    let mut lambda = opts.lambda0;
    let mut iterations = 0;
    let stop = 'outer: loop {
        if ssr == 0.0 {
            break RefineStop::ZeroResidual;
        }
        if iterations >= opts.max_iterations {
            break RefineStop::MaxIterations;
        }
        // Jacobian plus at least one trial, plus the final cost evaluation.
        if !can_spend(evals, jac_cost + 1) {
            break RefineStop::MaxEvals;
        }
        let (jac, _failed, used) = jacobian_unit(problem, &u, &r, &opts.jacobian, pool);
        evals += used;
        iterations += 1;
        let jt = jac.transpose();
        let a = &jt * &jac;
        let g = &jt * DVector::from_column_slice(&r);
        // Active set: frozen where sitting on a bound and descent (−g) points outwards.
        let free: Vec<usize> = (0..n)
            .filter(|&j| !((u[j] <= 0.0 && g[j] > 0.0) || (u[j] >= 1.0 && g[j] < 0.0)))
            .collect();
        if free.is_empty() {
            break RefineStop::StepSize;
        }
        let nf = free.len();
        let max_diag = free.iter().map(|&j| a[(j, j)]).fold(0.0, f64::max);
        let floor = (max_diag * 1e-12).max(1e-300);
        loop {
            let mut ar = DMatrix::zeros(nf, nf);
            let mut gr = DVector::zeros(nf);
            for (p, &i) in free.iter().enumerate() {
                gr[p] = -g[i];
                for (q, &j) in free.iter().enumerate() {
                    ar[(p, q)] = a[(i, j)];
                }
                ar[(p, p)] += lambda * a[(i, i)].max(floor);
            }
            let delta = match ar.cholesky() {
                Some(ch) => ch.solve(&gr),
                None => {
                    lambda *= 10.0;
                    if lambda > 1e16 {
                        break 'outer RefineStop::NoDescent;
                    }
                    continue;
                }
            };
            let mut trial = u.clone();
            for (p, &j) in free.iter().enumerate() {
                trial[j] = (u[j] + delta[p]).clamp(0.0, 1.0);
            }
            let step: f64 = trial
                .iter()
                .zip(&u)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt();
            if step <= opts.xtol {
                break 'outer RefineStop::StepSize;
            }
            if !can_spend(evals, 1) {
                break 'outer RefineStop::MaxEvals;
            }
            evals += 1;
            let accepted = residuals_unit(problem, &trial, Some(m))
                .map(|rt| (ssr_of(&rt), rt))
                .filter(|(s, _)| *s < ssr);
            match accepted {
                Some((s_new, r_new)) => {
                    let rel = (ssr - s_new) / ssr;
                    u = trial;
                    r = r_new;
                    ssr = s_new;
                    lambda = (lambda / 10.0).max(1e-12);
                    if rel < opts.ftol {
                        break 'outer RefineStop::CostChange;
                    }
                    break;
                }
                None => {
                    lambda *= 10.0;
                    if lambda > 1e16 {
                        break 'outer RefineStop::NoDescent;
                    }
                }
            }
        }
    };
    let x = bounds.from_unit(&u);
    let cost = super::sanitize(problem.cost(&x));
    evals += 1;
    Ok(RefineResult {
        x,
        ssr,
        cost,
        iterations,
        evals,
        stop,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::{thread_pool, uncertainty, Problem};
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// y(t) = A exp(−k t) + c sampled at 40 points on [0, 5], residuals (model − y) / σ.
    pub(crate) struct ExpDecay {
        pub(crate) t: Vec<f64>,
        pub(crate) y: Vec<f64>,
        pub(crate) noise: f64,
        pub(crate) bounds: Bounds,
    }

    pub(crate) const TRUTH: [f64; 3] = [2.0, 0.7, 0.3];

    impl ExpDecay {
        pub(crate) fn new(noise: f64, seed: u64) -> Self {
            let t: Vec<f64> = (0..40).map(|i| i as f64 * 5.0 / 39.0).collect();
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let n = Normal::new(0.0, noise.max(1e-300)).expect("valid normal");
            let y = t
                .iter()
                .map(|&t| model(&TRUTH, t) + if noise > 0.0 { n.sample(&mut rng) } else { 0.0 })
                .collect();
            let bounds =
                Bounds::new(vec![0.0, 0.01, -1.0], vec![5.0, 3.0, 1.0]).expect("valid bounds");
            Self {
                t,
                y,
                noise,
                bounds,
            }
        }
    }

    fn model(p: &[f64], t: f64) -> f64 {
        p[0] * (-p[1] * t).exp() + p[2]
    }

    impl Problem for ExpDecay {
        fn dim(&self) -> usize {
            3
        }
        fn bounds(&self) -> &Bounds {
            &self.bounds
        }
        fn cost(&self, x: &[f64]) -> f64 {
            self.ssr(x)
        }
    }

    impl ResidualProblem for ExpDecay {
        fn residuals(&self, x: &[f64], out: &mut Vec<f64>) {
            out.clear();
            let s = if self.noise > 0.0 { self.noise } else { 1.0 };
            out.extend(
                self.t
                    .iter()
                    .zip(&self.y)
                    .map(|(&t, &y)| (model(x, t) - y) / s),
            );
        }
    }

    #[test]
    fn lm_converges_on_noise_free_exponential_decay() {
        let p = ExpDecay::new(0.0, 0);
        let pool = thread_pool(Some(2)).expect("pool");
        for scheme in [FiniteDifference::Forward, FiniteDifference::Central] {
            let opts = LmOptions::default()
                .with_jacobian(JacobianOptions::default().with_scheme(scheme).expect("ok"))
                .expect("ok");
            let r = refine(&p, &[0.5, 2.5, -0.5], &opts, &pool).expect("refine");
            for (a, b) in r.x.iter().zip(TRUTH) {
                assert!(
                    (a - b).abs() < 1e-6,
                    "{scheme:?}: {:?} stop {:?}",
                    r.x,
                    r.stop
                );
            }
            assert!(r.ssr < 1e-12 && r.cost < 1e-12);
            assert!(r.iterations < 50 && r.evals > r.iterations);
            // Identical with one thread: evaluation order cannot change the result.
            let one = thread_pool(Some(1)).expect("pool");
            assert_eq!(
                refine(&p, &[0.5, 2.5, -0.5], &opts, &one).expect("refine"),
                r
            );
        }
    }

    #[test]
    fn lm_respects_bounds_and_evaluation_cap() {
        // Unconstrained optimum c = 0.3 + 5 lies far outside c ≤ 1: LM must stop on the bound.
        let mut p = ExpDecay::new(0.0, 0);
        p.y.iter_mut().for_each(|y| *y += 5.0);
        let pool = thread_pool(Some(1)).expect("pool");
        let r = refine(&p, &[1.0, 1.0, 0.0], &LmOptions::default(), &pool).expect("refine");
        assert_eq!(r.x[2], 1.0);
        assert!(p.bounds.check_inside(&r.x).is_ok());
        let capped = LmOptions::default().with_max_evals(20).expect("ok");
        let r = refine(&p, &[1.0, 1.0, 0.0], &capped, &pool).expect("refine");
        assert!(r.evals <= 20, "evals {}", r.evals);
        assert_eq!(r.stop, RefineStop::MaxEvals);
        assert!(refine(&p, &[9.0, 1.0, 0.0], &capped, &pool).is_err());
    }

    #[test]
    fn sigma_matches_monte_carlo_spread() {
        let pool = thread_pool(Some(2)).expect("pool");
        let noise = 0.02;
        let opts = LmOptions::default();
        let fits: Vec<Vec<f64>> = (0..300)
            .map(|seed| {
                let p = ExpDecay::new(noise, seed);
                refine(&p, &[1.5, 1.0, 0.0], &opts, &pool)
                    .expect("refine")
                    .x
            })
            .collect();
        let p = ExpDecay::new(noise, 1000);
        let x = refine(&p, &[1.5, 1.0, 0.0], &opts, &pool)
            .expect("refine")
            .x;
        let u = uncertainty(&p, &x, &JacobianOptions::default(), &pool).expect("uncertainty");
        assert_eq!((u.dof, u.rank), (37, 3));
        assert!(u.identifiable.iter().all(|&b| b) && u.at_bound.iter().all(|&b| !b));
        // Residuals are scaled by the true σ, so s² ≈ 1.
        assert!((u.s2 - 1.0).abs() < 0.5, "s2 {}", u.s2);
        for j in 0..3 {
            let mean = fits.iter().map(|f| f[j]).sum::<f64>() / fits.len() as f64;
            let var =
                fits.iter().map(|f| (f[j] - mean).powi(2)).sum::<f64>() / (fits.len() - 1) as f64;
            let ratio = u.sigma[j] / var.sqrt();
            assert!((0.7..1.4).contains(&ratio), "param {j}: ratio {ratio}");
            // Unbiased to within the Monte-Carlo error.
            assert!((mean - TRUTH[j]).abs() < 4.0 * var.sqrt() / (fits.len() as f64).sqrt() + 1e-3);
        }
        // Correlations match the Monte-Carlo ones, and the matrix is symmetric.
        let c = &u.correlation;
        let mean = |j: usize| fits.iter().map(|f| f[j]).sum::<f64>() / fits.len() as f64;
        let cov = |i: usize, j: usize| {
            let (mi, mj) = (mean(i), mean(j));
            fits.iter().map(|f| (f[i] - mi) * (f[j] - mj)).sum::<f64>() / fits.len() as f64
        };
        for (i, j) in [(0, 1), (0, 2), (1, 2)] {
            let mc = cov(i, j) / (cov(i, i) * cov(j, j)).sqrt();
            assert!(
                (c[i][j] - mc).abs() < 0.15,
                "corr({i},{j}) {} vs MC {mc}",
                c[i][j]
            );
        }
        assert!(
            c[1][2].abs() > 0.5,
            "k and c are strongly correlated: {}",
            c[1][2]
        );
        for (i, row) in c.iter().enumerate() {
            assert_eq!(row[i], 1.0);
            for (j, v) in row.iter().enumerate() {
                assert!((v - c[j][i]).abs() < 1e-12);
            }
        }
    }
}
