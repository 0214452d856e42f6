//! Cuckoo search (Yang & Deb 2009) as a [`Solver`] state machine, REFERENCE §4 / paper §2.2.
//!
//! One generation:
//!
//! 1. **Lévy flights.** Every nest `i` proposes
//!    `x_new = x_i + α · L ⊙ (x_i − x_best)` with an independent Mantegna Lévy step `L`
//!    (β = 1.5, σ_u ≈ 0.6966 in the Γ form — see [`super::levy`] for why not the paper's
//!    eq. 9 value 0.857) per component, `α` = 0.01 by default *in normalised units*. This is the
//!    step of Yang & Deb's reference code, whose extra `⊙ N(0,1)` factor we leave out because
//!    `L` is already sign-symmetric. The proposal replaces the nest only if it is better (greedy).
//!    The best nest itself would propose itself (`x_i − x_best = 0`); it is not re-evaluated, to
//!    save an expensive evaluation per generation.
//! 2. **Discovery.** Each nest is discovered with probability `pa` (default 0.25) and proposes a
//!    biased random walk `x_new = x_i + r (x_j − x_k)` with `r ~ U(0,1)` and random distinct
//!    nests `j ≠ k`; again greedy replacement (as in the reference code), so the best nest is
//!    never lost. Only discovered nests are evaluated, so a generation costs ≈ `n (1 + pa)`
//!    evaluations rather than `2n`.
//!
//! **On α.** The default α = 0.01 is the reference value. Because the Lévy step is scaled by
//! `x_i − x_best`, it shrinks as the nests converge, and with α = 0.01 the flights barely
//! move: convergence comes mostly from the random walk and is slow. Measured on the 6-D sphere
//! (box −3…10, 20 seeds): after 3000 evaluations the median best cost is 1.2 with α = 0.01 but
//! 6e-5 with α = 0.3; after 6000, α = 0.3 reaches < 1e-6 on every seed. The intended use is
//! cuckoo search for the basin followed by [`super::refine`], which makes α matter less; tune it
//! with [`CuckooSearch::with_alpha`] if cuckoo search must converge on its own.
//!
//! Coordinates are normalised to `[0, 1]` and proposals are *reflected* into the box
//! ([`super::bounds::reflect_unit`]), never clipped. All random numbers of a generation are
//! drawn on the calling thread before the (parallel) evaluation, from a `ChaCha8Rng` seeded
//! explicitly, so results do not depend on the thread count. No I/O, no globals.

use super::bounds::reflect_all;
use super::levy::Levy;
use super::{setting, Evaluator, OptimError, Problem, Solver, StepOutcome};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Cuckoo search configuration and state. Build with [`CuckooSearch::new`] and `with_*`.
#[derive(Debug, Clone)]
pub struct CuckooSearch {
    seed: u64,
    nests: usize,
    pa: f64,
    alpha: f64,
    levy: Levy,
    initial_guess: Option<Vec<f64>>,
    state: Option<State>,
}

#[derive(Debug, Clone)]
struct State {
    rng: ChaCha8Rng,
    pop: Vec<Vec<f64>>,
    cost: Vec<f64>,
    best: usize,
}

impl CuckooSearch {
    /// Defaults: 25 nests, pa = 0.25, α = 0.01, β = 1.5, random initial nests.
    #[allow(clippy::expect_used)] // Levy::new(1.5) is a constant valid index
    pub fn new(seed: u64) -> Self {
        Self {
            seed,
            nests: 25,
            pa: 0.25,
            alpha: 0.01,
            levy: Levy::new(1.5).expect("1.5 is a valid Lévy index"),
            initial_guess: None,
            state: None,
        }
    }

    /// Number of nests (≥ 3, so the random walk has two distinct partners besides itself).
    pub fn with_nests(mut self, n: usize) -> Result<Self, OptimError> {
        if n < 3 {
            return Err(setting("nests", "need at least 3 nests"));
        }
        self.nests = n;
        Ok(self)
    }

    /// Discovery probability `pa` in `[0, 1]`.
    pub fn with_discovery_probability(mut self, pa: f64) -> Result<Self, OptimError> {
        if !(0.0..=1.0).contains(&pa) {
            return Err(setting("pa", "discovery probability must lie in [0, 1]"));
        }
        self.pa = pa;
        Ok(self)
    }

    /// Lévy step scale `α` in normalised units (> 0, finite).
    pub fn with_alpha(mut self, alpha: f64) -> Result<Self, OptimError> {
        if !(alpha.is_finite() && alpha > 0.0) {
            return Err(setting("alpha", "must be finite and > 0"));
        }
        self.alpha = alpha;
        Ok(self)
    }

    /// Lévy index β in (1, 2].
    pub fn with_beta(mut self, beta: f64) -> Result<Self, OptimError> {
        self.levy = Levy::new(beta)?;
        Ok(self)
    }

    /// Seed one nest with a start point in physical units (checked against the bounds in
    /// `init`, where the problem is known).
    pub fn with_initial_guess(mut self, x: Vec<f64>) -> Result<Self, OptimError> {
        if x.iter().any(|v| !v.is_finite()) {
            return Err(setting("initial_guess", "must be finite"));
        }
        self.initial_guess = Some(x);
        Ok(self)
    }

    #[allow(clippy::expect_used)] // the Solver trait calls init before step
    fn state_mut(&mut self) -> &mut State {
        self.state
            .as_mut()
            .expect("Solver::init must be called before step")
    }
}

impl State {
    fn update_best(&mut self) {
        // Lowest cost, first index on ties: deterministic.
        let mut b = 0;
        for i in 1..self.cost.len() {
            if self.cost[i] < self.cost[b] {
                b = i;
            }
        }
        self.best = b;
    }

    /// Greedy replacement of `idx[k]` by `cand[k]` where strictly better.
    fn accept(&mut self, idx: &[usize], cand: Vec<Vec<f64>>, costs: &[f64]) {
        for ((&i, c), &f) in idx.iter().zip(cand).zip(costs) {
            if f < self.cost[i] {
                self.pop[i] = c;
                self.cost[i] = f;
            }
        }
        self.update_best();
    }
}

impl Solver for CuckooSearch {
    fn name(&self) -> &'static str {
        "cuckoo"
    }

    fn init<P: Problem + ?Sized>(&mut self, eval: &mut Evaluator<'_, P>) -> Result<(), OptimError> {
        let dim = eval.dim();
        let bounds = eval.problem().bounds();
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let mut pop: Vec<Vec<f64>> = (0..self.nests)
            .map(|_| (0..dim).map(|_| rng.random::<f64>()).collect())
            .collect();
        if let Some(g) = &self.initial_guess {
            bounds.check_inside(g)?;
            pop[0] = bounds.to_unit(g);
        }
        let cost = eval.eval_unit(&pop);
        let mut state = State {
            rng,
            pop,
            cost,
            best: 0,
        };
        state.update_best();
        self.state = Some(state);
        Ok(())
    }

    fn step<P: Problem + ?Sized>(&mut self, eval: &mut Evaluator<'_, P>) -> StepOutcome {
        let (alpha, pa, levy, nests) = (self.alpha, self.pa, self.levy, self.nests);
        let st = self.state_mut();

        // 1. Lévy flights towards/away from the best nest.
        let best = st.pop[st.best].clone();
        let mut idx = Vec::with_capacity(nests);
        let mut cand = Vec::with_capacity(nests);
        for i in 0..nests {
            let x = &st.pop[i];
            let mut y: Vec<f64> = x
                .iter()
                .zip(&best)
                .map(|(&xi, &bi)| xi + alpha * levy.sample(&mut st.rng) * (xi - bi))
                .collect();
            reflect_all(&mut y);
            if y != *x {
                idx.push(i);
                cand.push(y);
            }
        }
        let costs = eval.eval_unit(&cand);
        st.accept(&idx, cand, &costs);

        // 2. Discovery: a fraction pa of nests takes a biased random walk.
        let mut idx = Vec::new();
        let mut cand = Vec::new();
        for i in 0..nests {
            if st.rng.random::<f64>() >= pa {
                continue;
            }
            let j = st.rng.random_range(0..nests);
            let mut k = st.rng.random_range(0..nests - 1);
            if k >= j {
                k += 1;
            }
            let r: f64 = st.rng.random();
            let mut y: Vec<f64> = (0..st.pop[i].len())
                .map(|d| st.pop[i][d] + r * (st.pop[j][d] - st.pop[k][d]))
                .collect();
            reflect_all(&mut y);
            if y != st.pop[i] {
                idx.push(i);
                cand.push(y);
            }
        }
        let costs = eval.eval_unit(&cand);
        st.accept(&idx, cand, &costs);
        StepOutcome::Continue
    }

    fn best(&self) -> (&[f64], f64) {
        match &self.state {
            Some(st) => (&st.pop[st.best], st.cost[st.best]),
            None => (&[], f64::INFINITY),
        }
    }
}
