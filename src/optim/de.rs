//! Differential evolution (Storn & Price 1997) as a [`Solver`] state machine: the comparison
//! global optimiser for cuckoo search at equal evaluation budgets.
//!
//! Strategies: `DE/rand/1/bin` (default; robust, explores) and `DE/current-to-best/1/bin`
//! (faster on smooth unimodal costs, greedier). Defaults: population `max(8, 5·dim)`,
//! F = 0.6, CR = 0.9. Selection is greedy one-to-one. Works in `[0, 1]` coordinates and
//! reflects mutants into the box. All random numbers of a generation are drawn before the
//! parallel evaluation from an explicitly seeded `ChaCha8Rng`. No I/O, no globals.

use super::bounds::reflect_all;
use super::{setting, Evaluator, OptimError, Problem, Solver, StepOutcome};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Mutation strategy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeStrategy {
    /// `v = x_r1 + F (x_r2 − x_r3)`.
    Rand1Bin,
    /// `v = x_i + F (x_best − x_i) + F (x_r1 − x_r2)`.
    CurrentToBest1Bin,
}

/// Differential evolution configuration and state.
#[derive(Debug, Clone)]
pub struct DifferentialEvolution {
    seed: u64,
    population: Option<usize>,
    f: f64,
    cr: f64,
    strategy: DeStrategy,
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

impl DifferentialEvolution {
    /// Defaults: population `max(8, 5·dim)`, F = 0.6, CR = 0.9, `DE/rand/1/bin`.
    pub fn new(seed: u64) -> Self {
        Self {
            seed,
            population: None,
            f: 0.6,
            cr: 0.9,
            strategy: DeStrategy::Rand1Bin,
            initial_guess: None,
            state: None,
        }
    }

    /// Population size (≥ 5, so that three distinct partners besides `i` exist).
    pub fn with_population(mut self, n: usize) -> Result<Self, OptimError> {
        if n < 5 {
            return Err(setting("population", "need at least 5 members"));
        }
        self.population = Some(n);
        Ok(self)
    }

    /// Differential weight F in (0, 2].
    pub fn with_f(mut self, f: f64) -> Result<Self, OptimError> {
        if !(f > 0.0 && f <= 2.0) {
            return Err(setting("f", "differential weight must lie in (0, 2]"));
        }
        self.f = f;
        Ok(self)
    }

    /// Crossover probability CR in [0, 1].
    pub fn with_cr(mut self, cr: f64) -> Result<Self, OptimError> {
        if !(0.0..=1.0).contains(&cr) {
            return Err(setting("cr", "crossover probability must lie in [0, 1]"));
        }
        self.cr = cr;
        Ok(self)
    }

    /// Mutation strategy.
    pub fn with_strategy(mut self, s: DeStrategy) -> Result<Self, OptimError> {
        self.strategy = s;
        Ok(self)
    }

    /// Seed one member with a start point in physical units (checked in `init`).
    pub fn with_initial_guess(mut self, x: Vec<f64>) -> Result<Self, OptimError> {
        if x.iter().any(|v| !v.is_finite()) {
            return Err(setting("initial_guess", "must be finite"));
        }
        self.initial_guess = Some(x);
        Ok(self)
    }
}

/// `count` distinct indices from `0..n`, all different from `exclude`.
fn distinct<R: Rng>(rng: &mut R, n: usize, exclude: usize, count: usize) -> [usize; 3] {
    let mut out = [usize::MAX; 3];
    let mut k = 0;
    while k < count {
        let c = rng.random_range(0..n);
        if c != exclude && !out[..k].contains(&c) {
            out[k] = c;
            k += 1;
        }
    }
    out
}

impl Solver for DifferentialEvolution {
    fn name(&self) -> &'static str {
        "de"
    }

    fn init<P: Problem + ?Sized>(&mut self, eval: &mut Evaluator<'_, P>) -> Result<(), OptimError> {
        let dim = eval.dim();
        let np = self.population.unwrap_or((5 * dim).max(8));
        let bounds = eval.problem().bounds();
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let mut pop: Vec<Vec<f64>> = (0..np)
            .map(|_| (0..dim).map(|_| rng.random::<f64>()).collect())
            .collect();
        if let Some(g) = &self.initial_guess {
            bounds.check_inside(g)?;
            pop[0] = bounds.to_unit(g);
        }
        let cost = eval.eval_unit(&pop);
        let best = argmin(&cost);
        self.state = Some(State {
            rng,
            pop,
            cost,
            best,
        });
        Ok(())
    }

    #[allow(clippy::expect_used)] // the Solver trait calls init before step
    fn step<P: Problem + ?Sized>(&mut self, eval: &mut Evaluator<'_, P>) -> StepOutcome {
        let (f, cr, strategy) = (self.f, self.cr, self.strategy);
        let st = self
            .state
            .as_mut()
            .expect("Solver::init must be called before step");
        let np = st.pop.len();
        let dim = st.pop[0].len();
        let mut trials = Vec::with_capacity(np);
        for i in 0..np {
            let xi = &st.pop[i];
            let mutant: Vec<f64> = match strategy {
                DeStrategy::Rand1Bin => {
                    let [a, b, c] = distinct(&mut st.rng, np, i, 3);
                    (0..dim)
                        .map(|d| st.pop[a][d] + f * (st.pop[b][d] - st.pop[c][d]))
                        .collect()
                }
                DeStrategy::CurrentToBest1Bin => {
                    let [a, b, _] = distinct(&mut st.rng, np, i, 2);
                    let xb = &st.pop[st.best];
                    (0..dim)
                        .map(|d| xi[d] + f * (xb[d] - xi[d]) + f * (st.pop[a][d] - st.pop[b][d]))
                        .collect()
                }
            };
            let jrand = st.rng.random_range(0..dim);
            let mut trial: Vec<f64> = (0..dim)
                .map(|d| {
                    if d == jrand || st.rng.random::<f64>() < cr {
                        mutant[d]
                    } else {
                        xi[d]
                    }
                })
                .collect();
            reflect_all(&mut trial);
            trials.push(trial);
        }
        let costs = eval.eval_unit(&trials);
        for (i, (t, c)) in trials.into_iter().zip(costs).enumerate() {
            // `<=` lets the population drift across plateaus (standard DE selection).
            if c <= st.cost[i] && c.is_finite() {
                st.pop[i] = t;
                st.cost[i] = c;
            }
        }
        st.best = argmin(&st.cost);
        StepOutcome::Continue
    }

    fn best(&self) -> (&[f64], f64) {
        match &self.state {
            Some(st) => (&st.pop[st.best], st.cost[st.best]),
            None => (&[], f64::INFINITY),
        }
    }
}

/// Index of the lowest cost, first on ties.
pub(crate) fn argmin(cost: &[f64]) -> usize {
    let mut b = 0;
    for i in 1..cost.len() {
        if cost[i] < cost[b] {
            b = i;
        }
    }
    b
}
