//! CMA-ES (Hansen's (μ/μ_w, λ) evolution strategy, parameters from "The CMA Evolution
//! Strategy: A Tutorial", 2016) as a [`Solver`] state machine, with optional IPOP restarts
//! (population doubled on each restart). The comparison optimiser for cuckoo search.
//!
//! Works in `[0, 1]` coordinates. Bounds by *reflection with repair*: a sampled point is
//! reflected into the box and the reflected point is used both for evaluation and in the
//! mean/covariance update (so the distribution learns from what was evaluated).
//! Eigendecomposition of C with nalgebra every generation (cheap for dim ≈ 6). All random
//! numbers are drawn before the parallel evaluation from an explicitly seeded `ChaCha8Rng`.
//! No I/O, no globals.

use super::bounds::reflect_all;
use super::de::argmin;
use super::{setting, Evaluator, OptimError, Problem, Solver, StepOutcome};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// CMA-ES configuration and state.
#[derive(Debug, Clone)]
pub struct CmaEs {
    seed: u64,
    sigma0: f64,
    lambda: Option<usize>,
    restarts: bool,
    tol_x: f64,
    initial_guess: Option<Vec<f64>>,
    state: Option<State>,
}

#[derive(Debug, Clone)]
struct State {
    rng: ChaCha8Rng,
    dim: usize,
    lambda: usize,
    weights: Vec<f64>,
    mueff: f64,
    cc: f64,
    cs: f64,
    c1: f64,
    cmu: f64,
    damps: f64,
    chi_n: f64,
    mean: DVector<f64>,
    sigma: f64,
    pc: DVector<f64>,
    ps: DVector<f64>,
    c: DMatrix<f64>,
    b: DMatrix<f64>,
    d: DVector<f64>,
    gen_evals: usize,
    best_x: Vec<f64>,
    best_f: f64,
    /// Restart bookkeeping: best of the current run, and generations without improvement.
    run_best: f64,
    flat_gens: usize,
    restarts_done: usize,
}

impl CmaEs {
    /// Defaults: σ₀ = 0.3 (normalised units), λ = 4 + ⌊3 ln n⌋, IPOP restarts on,
    /// tol_x = 1e-11, start mean at the box centre (or the initial guess).
    pub fn new(seed: u64) -> Self {
        Self {
            seed,
            sigma0: 0.3,
            lambda: None,
            restarts: true,
            tol_x: 1e-11,
            initial_guess: None,
            state: None,
        }
    }

    /// Initial step size in normalised units, in (0, 1].
    pub fn with_sigma0(mut self, s: f64) -> Result<Self, OptimError> {
        if !(s > 0.0 && s <= 1.0) {
            return Err(setting("sigma0", "must lie in (0, 1]"));
        }
        self.sigma0 = s;
        Ok(self)
    }

    /// Offspring per generation (≥ 4).
    pub fn with_lambda(mut self, l: usize) -> Result<Self, OptimError> {
        if l < 4 {
            return Err(setting("lambda", "need at least 4 offspring"));
        }
        self.lambda = Some(l);
        Ok(self)
    }

    /// IPOP restarts when a run converges (otherwise the solver reports convergence).
    pub fn with_restarts(mut self, on: bool) -> Result<Self, OptimError> {
        self.restarts = on;
        Ok(self)
    }

    /// Convergence threshold on `σ · max(√eig(C))` in normalised units (> 0).
    pub fn with_tol_x(mut self, t: f64) -> Result<Self, OptimError> {
        if !(t.is_finite() && t > 0.0) {
            return Err(setting("tol_x", "must be finite and > 0"));
        }
        self.tol_x = t;
        Ok(self)
    }

    /// Start the mean at this point (physical units; checked in `init`).
    pub fn with_initial_guess(mut self, x: Vec<f64>) -> Result<Self, OptimError> {
        if x.iter().any(|v| !v.is_finite()) {
            return Err(setting("initial_guess", "must be finite"));
        }
        self.initial_guess = Some(x);
        Ok(self)
    }
}

impl State {
    fn new(rng: ChaCha8Rng, dim: usize, lambda: usize, mean: Vec<f64>, sigma: f64) -> Self {
        let n = dim as f64;
        let mu = lambda / 2;
        let raw: Vec<f64> = (1..=mu)
            .map(|i| ((lambda as f64 + 1.0) / 2.0).ln() - (i as f64).ln())
            .collect();
        let sum: f64 = raw.iter().sum();
        let weights: Vec<f64> = raw.iter().map(|w| w / sum).collect();
        let mueff = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
        let cc = (4.0 + mueff / n) / (n + 4.0 + 2.0 * mueff / n);
        let cs = (mueff + 2.0) / (n + mueff + 5.0);
        let c1 = 2.0 / ((n + 1.3).powi(2) + mueff);
        let cmu = (1.0 - c1).min(2.0 * (mueff - 2.0 + 1.0 / mueff) / ((n + 2.0).powi(2) + mueff));
        let damps = 1.0 + 2.0 * (((mueff - 1.0) / (n + 1.0)).sqrt() - 1.0).max(0.0) + cs;
        let chi_n = n.sqrt() * (1.0 - 1.0 / (4.0 * n) + 1.0 / (21.0 * n * n));
        Self {
            rng,
            dim,
            lambda,
            weights,
            mueff,
            cc,
            cs,
            c1,
            cmu,
            damps,
            chi_n,
            mean: DVector::from_vec(mean),
            sigma,
            pc: DVector::zeros(dim),
            ps: DVector::zeros(dim),
            c: DMatrix::identity(dim, dim),
            b: DMatrix::identity(dim, dim),
            d: DVector::from_element(dim, 1.0),
            gen_evals: 0,
            best_x: Vec::new(),
            best_f: f64::INFINITY,
            run_best: f64::INFINITY,
            flat_gens: 0,
            restarts_done: 0,
        }
    }

    /// Start a fresh run (IPOP): doubled population, random mean, keep the global best and rng.
    fn restart(&mut self, sigma0: f64) {
        let mean: Vec<f64> = (0..self.dim).map(|_| self.rng.random::<f64>()).collect();
        let rng = self.rng.clone();
        let mut fresh = State::new(rng, self.dim, self.lambda * 2, mean, sigma0);
        fresh.best_x = std::mem::take(&mut self.best_x);
        fresh.best_f = self.best_f;
        fresh.restarts_done = self.restarts_done + 1;
        *self = fresh;
    }

    fn converged(&self, tol_x: f64) -> bool {
        let spread = self.sigma * self.d.max();
        // Stuck: no improvement of this run's best in 10 + 30 n / λ generations.
        let stuck_limit = 10 + (30 * self.dim).div_ceil(self.lambda);
        spread < tol_x || !spread.is_finite() || self.flat_gens > stuck_limit
    }
}

impl Solver for CmaEs {
    fn name(&self) -> &'static str {
        "cmaes"
    }

    fn init<P: Problem + ?Sized>(&mut self, eval: &mut Evaluator<'_, P>) -> Result<(), OptimError> {
        let dim = eval.dim();
        let bounds = eval.problem().bounds();
        let mean = match &self.initial_guess {
            Some(g) => {
                bounds.check_inside(g)?;
                bounds.to_unit(g)
            }
            None => vec![0.5; dim],
        };
        let lambda = self
            .lambda
            .unwrap_or(4 + (3.0 * (dim as f64).ln()).floor() as usize);
        let rng = ChaCha8Rng::seed_from_u64(self.seed);
        let mut st = State::new(rng, dim, lambda, mean.clone(), self.sigma0);
        // Evaluate the start mean so `best` is defined before the first generation.
        let f0 = eval.eval_unit(std::slice::from_ref(&mean))[0];
        st.best_x = mean;
        st.best_f = f0;
        self.state = Some(st);
        Ok(())
    }

    #[allow(clippy::expect_used)] // the Solver trait calls init before step
    fn step<P: Problem + ?Sized>(&mut self, eval: &mut Evaluator<'_, P>) -> StepOutcome {
        let (tol_x, restarts, sigma0) = (self.tol_x, self.restarts, self.sigma0);
        let st = self
            .state
            .as_mut()
            .expect("Solver::init must be called before step");
        let n = st.dim;
        // Sample (all random numbers first), reflect, repair.
        let bd = &st.b * DMatrix::from_diagonal(&st.d);
        let mut xs: Vec<Vec<f64>> = Vec::with_capacity(st.lambda);
        for _ in 0..st.lambda {
            let z = DVector::from_fn(n, |_, _| st.rng.sample::<f64, _>(StandardNormal));
            let x = &st.mean + st.sigma * (&bd * z);
            let mut x: Vec<f64> = x.iter().copied().collect();
            reflect_all(&mut x);
            xs.push(x);
        }
        let costs = eval.eval_unit(&xs);
        st.gen_evals += st.lambda;

        let mut order: Vec<usize> = (0..st.lambda).collect();
        order.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]).then(a.cmp(&b)));
        let ib = argmin(&costs);
        if costs[ib] < st.best_f {
            st.best_f = costs[ib];
            st.best_x = xs[ib].clone();
        }
        if costs[ib] < st.run_best {
            st.run_best = costs[ib];
            st.flat_gens = 0;
        } else {
            st.flat_gens += 1;
        }

        // Mean update.
        let old = st.mean.clone();
        let mut mean = DVector::zeros(n);
        for (k, &w) in st.weights.iter().enumerate() {
            mean += w * DVector::from_column_slice(&xs[order[k]]);
        }
        st.mean = mean;
        let dm = (&st.mean - &old) / st.sigma;

        // C^{-1/2} = B D^{-1} Bᵀ.
        let dinv = DMatrix::from_diagonal(&st.d.map(|v| 1.0 / v));
        let c_inv_sqrt = &st.b * dinv * st.b.transpose();
        st.ps =
            (1.0 - st.cs) * &st.ps + (st.cs * (2.0 - st.cs) * st.mueff).sqrt() * (c_inv_sqrt * &dm);
        let gen = (st.gen_evals / st.lambda) as f64;
        let hsig_norm = st.ps.norm() / (1.0 - (1.0 - st.cs).powf(2.0 * gen)).sqrt() / st.chi_n;
        let hsig = if hsig_norm < 1.4 + 2.0 / (n as f64 + 1.0) {
            1.0
        } else {
            0.0
        };
        st.pc = (1.0 - st.cc) * &st.pc + hsig * (st.cc * (2.0 - st.cc) * st.mueff).sqrt() * &dm;

        // Covariance update: rank one + rank μ.
        let mut rank_mu = DMatrix::zeros(n, n);
        for (k, &w) in st.weights.iter().enumerate() {
            let y = (DVector::from_column_slice(&xs[order[k]]) - &old) / st.sigma;
            rank_mu += w * &y * y.transpose();
        }
        let rank_one = &st.pc * st.pc.transpose();
        let c_old = st.c.clone();
        st.c = (1.0 - st.c1 - st.cmu) * c_old.clone()
            + st.c1 * (rank_one + (1.0 - hsig) * st.cc * (2.0 - st.cc) * c_old)
            + st.cmu * rank_mu;
        // Keep C exactly symmetric.
        st.c = (&st.c + st.c.transpose()) * 0.5;

        // Step size; capped because the whole box is only 1 wide.
        st.sigma *= ((st.cs / st.damps) * (st.ps.norm() / st.chi_n - 1.0)).exp();
        st.sigma = st.sigma.min(1.0);

        let eig = SymmetricEigen::new(st.c.clone());
        st.b = eig.eigenvectors;
        st.d = eig.eigenvalues.map(|v| v.max(1e-30).sqrt());

        if st.converged(tol_x) {
            if restarts {
                st.restart(sigma0);
            } else {
                return StepOutcome::Converged;
            }
        }
        StepOutcome::Continue
    }

    fn best(&self) -> (&[f64], f64) {
        match &self.state {
            Some(st) => (&st.best_x, st.best_f),
            None => (&[], f64::INFINITY),
        }
    }
}
