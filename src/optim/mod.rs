//! Pure, reusable bounded optimisation: global search (cuckoo search, differential evolution,
//! CMA-ES), Levenberg–Marquardt refinement and least-squares uncertainty.
//!
//! Built for fitting the six gas-path health parameters, where one objective evaluation is a
//! ~10 ms engine simulation: evaluations are expensive (a budget of a few thousand), the
//! objective is mildly nonlinear and a little noisy, the dimension is small and the constraints
//! are a box. This module must not do I/O, keep globals, read clocks or depend on scheduling:
//! a run is a pure function of (problem, solver configuration, seed, budget).
//!
//! # Design (in the style of argmin)
//!
//! * A [`Problem`] states the dimension, the box [`Bounds`] and the cost in physical units.
//!   A [`ResidualProblem`] additionally exposes the residual vector, for [`refine`] and
//!   [`uncertainty()`].
//! * A solver ([`CuckooSearch`], [`DifferentialEvolution`], [`CmaEs`]) is a small state machine
//!   behind the [`Solver`] trait: `init` evaluates the first population, `step` runs one
//!   generation. Solvers work in coordinates normalised to `[0, 1]` per parameter and *reflect*
//!   at the bounds ([`bounds::reflect_unit`]); they never clip, so no probability mass piles up
//!   on the faces of the box.
//! * Solver configuration uses validating builders: `with_*` returns `Result<Self, OptimError>`.
//! * [`run`] drives a solver under a [`Budget`] (evaluations, generations, stall, target) and a
//!   [`Cancel`] flag checked between generations, and returns an [`OptimResult`].
//! * Every generation's candidates are evaluated in parallel on a caller-supplied
//!   `rayon::ThreadPool` ([`thread_pool`] builds one). All random numbers are drawn on the
//!   calling thread *before* the parallel evaluation and results are collected in order, so a
//!   run is bit-identical for 1 or N threads.
//! * [`Evaluator`] enforces the evaluation budget exactly: once it is exhausted, candidates are
//!   not evaluated and get cost `+∞`, which no solver ever accepts. So `evals <= max_evals`
//!   always holds, which makes comparisons "at equal budget" honest. A `NaN` cost from the
//!   problem is treated as `+∞` (a failed simulation), never propagated.
//!
//! # Usage
//!
//! ```
//! use gtwatch::optim::test_functions::TestFunction;
//! use gtwatch::optim::{refine, run, thread_pool, uncertainty, Budget, Cancel, CuckooSearch};
//! use gtwatch::optim::{JacobianOptions, LmOptions};
//!
//! let problem = TestFunction::sphere(6, -3.0, 10.0, 1.7).expect("valid test problem");
//! let pool = thread_pool(Some(2)).expect("thread pool"); // `None` = all cores
//! let mut cs = CuckooSearch::new(42).with_nests(25).expect("nests >= 3");
//! let budget = Budget::new().with_max_evals(2500).expect("> 0").with_stall(50, 1e-9).expect("ok");
//! let global = run(&mut cs, &problem, &budget, &Cancel::new(), &pool).expect("run");
//! assert!(global.evals <= 2500 && global.history.len() == global.generations + 1);
//! let lm = LmOptions::default().with_max_evals(500).expect("ok");
//! let local = refine(&problem, &global.x, &lm, &pool).expect("refine");
//! assert!(local.cost < 1e-12 && local.cost <= global.cost);
//! // Sphere's 6 residuals cannot give a 6-parameter uncertainty (needs m > n): a clear error.
//! assert!(uncertainty(&problem, &local.x, &JacobianOptions::default(), &pool).is_err());
//! ```
//!
//! For a [`ResidualProblem`] with more residuals than parameters, `uncertainty` then reports
//! 1σ per parameter, the covariance and the correlation matrix at `local.x`.

pub(crate) mod bounds;
pub(crate) mod cmaes;
pub(crate) mod cuckoo;
pub(crate) mod de;
pub(crate) mod levy;
pub(crate) mod lm;
pub(crate) mod problem;
pub(crate) mod stats;
pub mod test_functions;
pub(crate) mod uncertainty;

pub use bounds::Bounds;
pub use cmaes::CmaEs;
pub use cuckoo::CuckooSearch;
pub use de::{DeStrategy, DifferentialEvolution};
pub use lm::{refine, FiniteDifference, JacobianOptions, LmOptions, RefineResult, RefineStop};
pub use problem::{Problem, ResidualProblem};
pub use stats::median;
pub use uncertainty::{uncertainty, uncertainty_with_inputs, Uncertainty};

use rayon::prelude::*;
use rayon::ThreadPool;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Everything that can go wrong when configuring or running an optimisation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OptimError {
    /// A configuration value is out of range; names the setting and the reason.
    #[error("invalid optimiser setting `{name}`: {reason}")]
    InvalidSetting { name: &'static str, reason: String },
    /// Lower/upper bounds are inconsistent.
    #[error("invalid bounds for parameter {index}: {reason}")]
    InvalidBounds { index: usize, reason: String },
    /// A vector has the wrong length for the problem.
    #[error("dimension mismatch: expected {expected}, got {got}")]
    DimensionMismatch { expected: usize, got: usize },
    /// A start point lies outside the bounds or is not finite.
    #[error("start point component {index} = {value} is outside the bounds or not finite")]
    StartOutOfBounds { index: usize, value: f64 },
    /// The budget has neither an evaluation nor a generation limit, so a run might never end.
    #[error("budget is unbounded: set max_evals or max_generations")]
    UnboundedBudget,
    /// The residual vector is too short for the number of parameters (needs m > n).
    #[error("need more residuals than parameters for least squares: m = {m}, n = {n}")]
    TooFewResiduals { m: usize, n: usize },
    /// The residual vector at the start point is not finite, so least squares cannot start.
    #[error("residuals are not finite at the start point")]
    NonFiniteResiduals,
    /// The rayon thread pool could not be built.
    #[error("cannot build thread pool: {0}")]
    ThreadPool(String),
}

/// Build a rayon pool for candidate evaluation: `Some(n)` threads, or `None` for all cores.
pub fn thread_pool(threads: Option<usize>) -> Result<ThreadPool, OptimError> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        if n == 0 {
            return Err(OptimError::InvalidSetting {
                name: "threads",
                reason: "must be at least 1".into(),
            });
        }
        builder = builder.num_threads(n);
    }
    builder
        .build()
        .map_err(|e| OptimError::ThreadPool(e.to_string()))
}

/// Stopping rules for [`run`]; any combination. At least one of `max_evals` or
/// `max_generations` must be set (checked by [`run`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Budget {
    /// Hard cap on objective evaluations, including the initial population (never exceeded).
    pub max_evals: Option<usize>,
    /// Cap on generations (calls to [`Solver::step`]).
    pub max_generations: Option<usize>,
    /// Stop when the best cost improved by no more than `stall_tol · max(|f_old|, 1e-300)`
    /// (relative) over this many generations.
    pub stall_generations: Option<usize>,
    /// Relative improvement tolerance for the stall rule (default 0 = any improvement counts).
    pub stall_tol: f64,
    /// Stop as soon as the best cost is `<= target_cost`.
    pub target_cost: Option<f64>,
}

impl Budget {
    /// An empty budget; add limits with the `with_*` builders.
    pub fn new() -> Self {
        Self::default()
    }

    /// Cap the number of objective evaluations (must be > 0).
    pub fn with_max_evals(mut self, n: usize) -> Result<Self, OptimError> {
        if n == 0 {
            return Err(setting("max_evals", "must be > 0"));
        }
        self.max_evals = Some(n);
        Ok(self)
    }

    /// Cap the number of generations (must be > 0).
    pub fn with_max_generations(mut self, n: usize) -> Result<Self, OptimError> {
        if n == 0 {
            return Err(setting("max_generations", "must be > 0"));
        }
        self.max_generations = Some(n);
        Ok(self)
    }

    /// Stop after `generations` generations with relative improvement `<= tol` (tol >= 0).
    pub fn with_stall(mut self, generations: usize, tol: f64) -> Result<Self, OptimError> {
        if generations == 0 {
            return Err(setting("stall_generations", "must be > 0"));
        }
        if !(tol.is_finite() && tol >= 0.0) {
            return Err(setting("stall_tol", "must be finite and >= 0"));
        }
        self.stall_generations = Some(generations);
        self.stall_tol = tol;
        Ok(self)
    }

    /// Stop once the best cost reaches `target` (must be finite).
    pub fn with_target_cost(mut self, target: f64) -> Result<Self, OptimError> {
        if !target.is_finite() {
            return Err(setting("target_cost", "must be finite"));
        }
        self.target_cost = Some(target);
        Ok(self)
    }

    fn is_bounded(&self) -> bool {
        self.max_evals.is_some() || self.max_generations.is_some()
    }
}

pub(crate) fn setting(name: &'static str, reason: &str) -> OptimError {
    OptimError::InvalidSetting {
        name,
        reason: reason.to_string(),
    }
}

/// Cooperative cancellation: a cloneable flag that [`run`] checks between generations.
/// Passed in as a value (like mini-redis' shutdown) so callers and tests drive it.
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A fresh, un-cancelled flag.
    pub fn new() -> Self {
        Self::default()
    }
    /// Request that the run stop after the current generation.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::SeqCst);
    }
    /// Whether cancellation was requested.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }
}

/// Two flags are equal when they are the same flag.
impl PartialEq for Cancel {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

/// Why a run stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// The evaluation budget is used up.
    MaxEvals,
    /// The generation limit was reached.
    MaxGenerations,
    /// No sufficient improvement over `stall_generations`.
    Stalled,
    /// The best cost reached `target_cost`.
    TargetReached,
    /// The [`Cancel`] flag was set.
    Cancelled,
    /// The solver reports it cannot make progress (e.g. CMA-ES step size collapsed).
    SolverConverged,
}

/// What one [`Solver::step`] reports to the driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepOutcome {
    /// Keep going.
    Continue,
    /// The solver has converged or degenerated; further steps are pointless.
    Converged,
}

/// Result of [`run`]. `x` is in physical units.
#[derive(Debug, Clone, PartialEq)]
pub struct OptimResult {
    /// Best point found, physical units.
    pub x: Vec<f64>,
    /// Its cost.
    pub cost: f64,
    /// Objective evaluations used (including the initial population).
    pub evals: usize,
    /// Generations run (calls to [`Solver::step`]).
    pub generations: usize,
    /// Why the run stopped.
    pub stop_reason: StopReason,
    /// Best cost after initialisation (`history[0]`) and after each generation.
    pub history: Vec<f64>,
}

/// Evaluates batches of candidates given in normalised `[0, 1]` coordinates, in parallel,
/// counting evaluations and enforcing the evaluation cap.
pub struct Evaluator<'a, P: Problem + ?Sized> {
    problem: &'a P,
    pool: &'a ThreadPool,
    evals: usize,
    max_evals: Option<usize>,
}

impl<'a, P: Problem + ?Sized> Evaluator<'a, P> {
    /// An evaluator over `problem` using `pool`, with an optional hard evaluation cap.
    pub fn new(problem: &'a P, pool: &'a ThreadPool, max_evals: Option<usize>) -> Self {
        Self {
            problem,
            pool,
            evals: 0,
            max_evals,
        }
    }

    /// The problem being evaluated.
    pub fn problem(&self) -> &'a P {
        self.problem
    }

    /// Problem dimension.
    pub fn dim(&self) -> usize {
        self.problem.dim()
    }

    /// Evaluations so far.
    pub fn evals(&self) -> usize {
        self.evals
    }

    /// Evaluations still allowed (`usize::MAX` without a cap).
    pub fn remaining(&self) -> usize {
        self.max_evals
            .map_or(usize::MAX, |m| m.saturating_sub(self.evals))
    }

    /// Cost of each unit-coordinate candidate, in order. Candidates beyond the remaining budget
    /// are not evaluated and get `+∞`; `NaN` costs become `+∞`.
    pub fn eval_unit(&mut self, candidates: &[Vec<f64>]) -> Vec<f64> {
        let n_eval = candidates.len().min(self.remaining());
        let problem = self.problem;
        let bounds = problem.bounds();
        let mut costs: Vec<f64> = self.pool.install(|| {
            candidates[..n_eval]
                .par_iter()
                .map(|u| sanitize(problem.cost(&bounds.from_unit(u))))
                .collect()
        });
        self.evals += n_eval;
        costs.resize(candidates.len(), f64::INFINITY);
        costs
    }
}

/// A failed evaluation (NaN) counts as infinitely bad.
pub(crate) fn sanitize(c: f64) -> f64 {
    if c.is_nan() {
        f64::INFINITY
    } else {
        c
    }
}

/// A population-based optimiser as a state machine. Coordinates are normalised to `[0, 1]`.
pub trait Solver {
    /// Short name for reports ("cuckoo", "de", "cmaes").
    fn name(&self) -> &'static str;
    /// Create and evaluate the initial population; resets any previous state.
    fn init<P: Problem + ?Sized>(&mut self, eval: &mut Evaluator<'_, P>) -> Result<(), OptimError>;
    /// Run one generation.
    fn step<P: Problem + ?Sized>(&mut self, eval: &mut Evaluator<'_, P>) -> StepOutcome;
    /// Best point so far in normalised `[0, 1]` coordinates, and its cost.
    fn best(&self) -> (&[f64], f64);
}

/// Drive `solver` on `problem` until a [`Budget`] rule fires or `cancel` is set (checked
/// between generations). Deterministic for a given solver seed, independent of the pool size.
pub fn run<S: Solver, P: Problem + ?Sized>(
    solver: &mut S,
    problem: &P,
    budget: &Budget,
    cancel: &Cancel,
    pool: &ThreadPool,
) -> Result<OptimResult, OptimError> {
    if !budget.is_bounded() {
        return Err(OptimError::UnboundedBudget);
    }
    let mut eval = Evaluator::new(problem, pool, budget.max_evals);
    solver.init(&mut eval)?;
    let mut history = vec![solver.best().1];
    let mut generations = 0usize;
    let stop_reason = loop {
        let best = solver.best().1;
        if budget.target_cost.is_some_and(|t| best <= t) {
            break StopReason::TargetReached;
        }
        if eval.remaining() == 0 {
            break StopReason::MaxEvals;
        }
        if budget.max_generations.is_some_and(|g| generations >= g) {
            break StopReason::MaxGenerations;
        }
        if let Some(k) = budget.stall_generations {
            if generations >= k {
                let old = history[generations - k];
                // From +inf to finite is progress; +inf to +inf is none.
                let stalled = if old.is_finite() {
                    old - best <= budget.stall_tol * old.abs().max(1e-300)
                } else {
                    !best.is_finite()
                };
                if stalled {
                    break StopReason::Stalled;
                }
            }
        }
        if cancel.is_cancelled() {
            break StopReason::Cancelled;
        }
        let outcome = solver.step(&mut eval);
        generations += 1;
        history.push(solver.best().1);
        if outcome == StepOutcome::Converged {
            break StopReason::SolverConverged;
        }
    };
    let (u, cost) = solver.best();
    Ok(OptimResult {
        x: problem.bounds().from_unit(u),
        cost,
        evals: eval.evals(),
        generations,
        stop_reason,
        history,
    })
}

#[cfg(test)]
mod tests {
    use super::test_functions::TestFunction;
    use super::*;
    use std::sync::atomic::AtomicUsize;

    const SEEDS: u64 = 20;

    fn pool(n: usize) -> ThreadPool {
        thread_pool(Some(n)).expect("thread pool")
    }

    fn evals(n: usize) -> Budget {
        Budget::new().with_max_evals(n).expect("positive")
    }

    /// Final results over seeds 0..SEEDS.
    fn runs<S: Solver>(mk: impl Fn(u64) -> S, f: &TestFunction, n: usize) -> Vec<OptimResult> {
        let p = pool(1);
        (0..SEEDS)
            .map(|seed| run(&mut mk(seed), f, &evals(n), &Cancel::new(), &p).expect("run"))
            .collect()
    }

    /// CS for `n − lm` evaluations, then LM with the remaining `lm` evaluations.
    fn cs_lm(f: &TestFunction, n: usize, lm: usize) -> Vec<(f64, usize)> {
        let p = pool(1);
        let opts = LmOptions::default().with_max_evals(lm).expect("lm budget");
        (0..SEEDS)
            .map(|seed| {
                let g = run(
                    &mut CuckooSearch::new(seed),
                    f,
                    &evals(n - lm),
                    &Cancel::new(),
                    &p,
                )
                .expect("run");
                let r = refine(f, &g.x, &opts, &p).expect("refine");
                (r.cost.min(g.cost), g.evals + r.evals)
            })
            .collect()
    }

    fn count(rs: &[OptimResult], ok: impl Fn(&OptimResult) -> bool) -> usize {
        rs.iter().filter(|r| ok(r)).count()
    }

    fn median(mut v: Vec<f64>) -> f64 {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }

    fn sphere() -> TestFunction {
        TestFunction::sphere(6, -3.0, 10.0, 1.7).expect("valid")
    }
    fn rosenbrock() -> TestFunction {
        TestFunction::rosenbrock(6, -3.0, 10.0, 1.7).expect("valid")
    }
    /// Rastrigin on a smaller box (5^6 ≈ 15 600 local minima) so that a few thousand
    /// evaluations give a measurable global-basin rate.
    fn rastrigin() -> TestFunction {
        TestFunction::rastrigin(6, -2.0, 3.0, 0.4).expect("valid")
    }
    fn in_global_basin(r: &OptimResult) -> bool {
        r.x.iter().all(|v| (v - 0.4).abs() < 0.5)
    }

    /// Sphere whose cost sets a cancel flag once `after` evaluations have been made.
    struct CancelAfter {
        inner: TestFunction,
        seen: AtomicUsize,
        after: usize,
        cancel: Cancel,
    }
    impl Problem for CancelAfter {
        fn dim(&self) -> usize {
            self.inner.dim()
        }
        fn bounds(&self) -> &Bounds {
            self.inner.bounds()
        }
        fn cost(&self, x: &[f64]) -> f64 {
            if self.seen.fetch_add(1, Ordering::SeqCst) + 1 >= self.after {
                self.cancel.cancel();
            }
            self.inner.cost(x)
        }
    }

    /// Sphere that "fails" (NaN) in half of the box.
    struct HalfNan(TestFunction);
    impl Problem for HalfNan {
        fn dim(&self) -> usize {
            self.0.dim()
        }
        fn bounds(&self) -> &Bounds {
            self.0.bounds()
        }
        fn cost(&self, x: &[f64]) -> f64 {
            if x[0] > 5.0 {
                f64::NAN
            } else {
                self.0.cost(x)
            }
        }
    }

    fn check_deterministic<S: Solver>(mk: impl Fn(u64) -> S) {
        let f = TestFunction::rastrigin(6, -3.0, 10.0, 1.7).expect("valid");
        let b = evals(1500);
        let c = Cancel::new();
        let a1 = run(&mut mk(9), &f, &b, &c, &pool(1)).expect("run");
        let a2 = run(&mut mk(9), &f, &b, &c, &pool(1)).expect("run");
        let b2 = run(&mut mk(9), &f, &b, &c, &pool(2)).expect("run");
        let other = run(&mut mk(10), &f, &b, &c, &pool(1)).expect("run");
        // PartialEq on f64 fields: bit-identical apart from signed zeros, and no NaN here.
        assert_eq!(a1, a2);
        assert_eq!(a1, b2);
        assert_ne!(a1.x, other.x);
        // Re-running the same solver object re-initialises it from its seed.
        let mut s = mk(9);
        let _ = run(&mut s, &f, &b, &c, &pool(2)).expect("run");
        assert_eq!(run(&mut s, &f, &b, &c, &pool(1)).expect("run"), a1);
    }

    #[test]
    fn same_seed_is_bit_identical_for_1_and_2_threads() {
        check_deterministic(CuckooSearch::new);
        check_deterministic(DifferentialEvolution::new);
        check_deterministic(CmaEs::new);
    }

    #[test]
    fn cancellation_stops_within_one_generation() {
        let cancel = Cancel::new();
        let p = CancelAfter {
            inner: sphere(),
            seen: AtomicUsize::new(0),
            after: 200,
            cancel: cancel.clone(),
        };
        let b = evals(100_000);
        let r = run(&mut CuckooSearch::new(1), &p, &b, &cancel, &pool(2)).expect("run");
        assert_eq!(r.stop_reason, StopReason::Cancelled);
        // One CS generation costs at most 2 × 25 evaluations.
        assert!(r.evals >= 200 && r.evals < 200 + 50, "evals {}", r.evals);
        assert_eq!(r.history.len(), r.generations + 1);
        // Cancelled before starting: only the initial population is evaluated.
        let r = run(
            &mut DifferentialEvolution::new(1),
            &sphere(),
            &b,
            &cancel,
            &pool(1),
        )
        .expect("run");
        assert_eq!((r.generations, r.evals), (0, 30));
        assert_eq!(r.stop_reason, StopReason::Cancelled);
    }

    #[test]
    fn budget_rules_are_enforced() {
        let f = sphere();
        let c = Cancel::new();
        let p = pool(2);
        // The evaluation cap is exact, even mid-generation.
        for r in [
            run(&mut CuckooSearch::new(3), &f, &evals(777), &c, &p),
            run(&mut DifferentialEvolution::new(3), &f, &evals(777), &c, &p),
            run(&mut CmaEs::new(3), &f, &evals(777), &c, &p),
        ] {
            let r = r.expect("run");
            assert_eq!(r.evals, 777);
            assert_eq!(r.stop_reason, StopReason::MaxEvals);
            // The best cost never gets worse.
            assert!(r.history.windows(2).all(|w| w[1] <= w[0]));
            assert_eq!(r.cost, *r.history.last().expect("non-empty"));
            assert!((f.cost(&r.x) - r.cost).abs() <= 1e-12 * r.cost.max(1.0));
        }
        let g = Budget::new().with_max_generations(7).expect("positive");
        let r = run(&mut CuckooSearch::new(3), &f, &g, &c, &p).expect("run");
        assert_eq!(
            (r.generations, r.stop_reason),
            (7, StopReason::MaxGenerations)
        );
        let t = evals(100_000).with_target_cost(1e-3).expect("finite");
        let r = run(&mut CmaEs::new(3), &f, &t, &c, &p).expect("run");
        assert_eq!(r.stop_reason, StopReason::TargetReached);
        assert!(r.cost <= 1e-3 && r.evals < 100_000);
        // A stall rule with a huge tolerance fires after exactly k generations.
        let st = evals(100_000).with_stall(5, 1e6).expect("valid");
        let r = run(&mut DifferentialEvolution::new(3), &f, &st, &c, &p).expect("run");
        assert_eq!((r.generations, r.stop_reason), (5, StopReason::Stalled));
        assert_eq!(
            run(&mut CuckooSearch::new(3), &f, &Budget::new(), &c, &p),
            Err(OptimError::UnboundedBudget)
        );
        assert!(Budget::new().with_max_evals(0).is_err());
        assert!(Budget::new().with_stall(3, f64::NAN).is_err());
        assert!(Budget::new().with_target_cost(f64::INFINITY).is_err());
        assert!(thread_pool(Some(0)).is_err());
        // Initial guesses are checked against the bounds.
        let bad = CuckooSearch::new(1)
            .with_initial_guess(vec![11.0; 6])
            .expect("finite");
        assert!(matches!(
            run(&mut bad.clone(), &f, &evals(100), &c, &p),
            Err(OptimError::StartOutOfBounds { index: 0, .. })
        ));
    }

    #[test]
    fn initial_guess_is_used() {
        let f = sphere();
        let c = Cancel::new();
        let p = pool(1);
        let g = Budget::new().with_max_generations(1).expect("positive");
        for r in [
            run(
                &mut CuckooSearch::new(1)
                    .with_initial_guess(vec![1.7; 6])
                    .expect("ok"),
                &f,
                &g,
                &c,
                &p,
            ),
            run(
                &mut DifferentialEvolution::new(1)
                    .with_initial_guess(vec![1.7; 6])
                    .expect("ok"),
                &f,
                &g,
                &c,
                &p,
            ),
            run(
                &mut CmaEs::new(1).with_initial_guess(vec![1.7; 6]).expect("ok"),
                &f,
                &g,
                &c,
                &p,
            ),
        ] {
            assert!(r.expect("run").history[0] < 1e-20);
        }
    }

    #[test]
    fn failed_evaluations_are_infinite_not_nan() {
        let f = HalfNan(sphere());
        let p = pool(2);
        for r in [
            run(
                &mut CuckooSearch::new(5),
                &f,
                &evals(1500),
                &Cancel::new(),
                &p,
            ),
            run(
                &mut DifferentialEvolution::new(5),
                &f,
                &evals(1500),
                &Cancel::new(),
                &p,
            ),
            run(&mut CmaEs::new(5), &f, &evals(1500), &Cancel::new(), &p),
        ] {
            let r = r.expect("run");
            assert!(r.cost.is_finite() && r.x[0] <= 5.0);
            assert!(r.history.iter().all(|h| !h.is_nan()));
        }
    }

    // Success rates over seeds 0..20, 6-D, thresholds set just below what was measured
    // (measured values in comments; see the module report in the commit history).

    #[test]
    fn sphere_success_rates_and_ordering() {
        let f = sphere();
        let cs = runs(CuckooSearch::new, &f, 3000);
        let de = runs(DifferentialEvolution::new, &f, 3000);
        let ctb = runs(
            |s| {
                DifferentialEvolution::new(s)
                    .with_strategy(DeStrategy::CurrentToBest1Bin)
                    .expect("strategy")
            },
            &f,
            3000,
        );
        let cma = runs(CmaEs::new, &f, 3000);
        // CMA-ES: 20/20 below 1e-6 (worst measured 4e-20).
        assert_eq!(count(&cma, |r| r.cost < 1e-6), 20);
        // DE/current-to-best: 20/20 below 1e-6 (worst measured 2.3e-13).
        assert_eq!(count(&ctb, |r| r.cost < 1e-6), 20);
        // Cuckoo search with the reference α = 0.01 converges slowly: median 1.2, worst 3.3.
        assert_eq!(count(&cs, |r| r.cost < 5.0), 20);
        let med = |rs: &[OptimResult]| median(rs.iter().map(|r| r.cost).collect());
        // Robust ordering (orders of magnitude apart): CMA-ES < DE/rand < CS at 3000 evals.
        assert!(med(&cma) < med(&de) && med(&de) < med(&cs));
        // CS with α = 0.3 reaches 1e-6 in 6000 evaluations on every seed (worst 7.5e-9).
        let cs3 = runs(
            |s| CuckooSearch::new(s).with_alpha(0.3).expect("alpha"),
            &f,
            6000,
        );
        assert_eq!(count(&cs3, |r| r.cost < 1e-6), 20);
        // CS (2700) + LM (≤ 300) at the same total budget: exact on every seed.
        let hybrid = cs_lm(&f, 3000, 300);
        assert!(hybrid.iter().all(|&(c, e)| c < 1e-12 && e <= 3000));
    }

    #[test]
    fn rosenbrock_success_rates() {
        let f = rosenbrock();
        let cma = runs(CmaEs::new, &f, 3000);
        let cs = runs(CuckooSearch::new, &f, 3000);
        // CMA-ES: measured 19/20 below 1e-4.
        assert!(count(&cma, |r| r.cost < 1e-4) >= 17);
        // CS alone never gets there in 3000 (median 166); CS 2000 + LM ≤ 1000 does on 15/20
        // (the misses sit in Rosenbrock's known local minimum, cost 3.97, or on a bound).
        assert_eq!(count(&cs, |r| r.cost < 1e-4), 0);
        let hybrid = cs_lm(&f, 3000, 1000);
        assert!(hybrid.iter().all(|&(_, e)| e <= 3000));
        assert!(hybrid.iter().filter(|&&(c, _)| c < 1e-6).count() >= 12);
    }

    #[test]
    fn rastrigin_global_basin_rates() {
        let f = rastrigin();
        let cs3 = runs(
            |s| CuckooSearch::new(s).with_alpha(0.3).expect("alpha"),
            &f,
            6000,
        );
        let cma = runs(
            |s| CmaEs::new(s).with_restarts(false).expect("restarts"),
            &f,
            6000,
        );
        let cs = runs(CuckooSearch::new, &f, 6000);
        // Hard at this budget for every method: measured CMA-ES (no restarts) 5/20,
        // CS α = 0.3 2/20, CS default 0/20 but median cost 4.6 (≈ 4–5 coordinates one
        // lattice cell off).
        assert!(count(&cma, in_global_basin) >= 3);
        assert!(count(&cs3, in_global_basin) >= 1);
        assert!(median(cs.iter().map(|r| r.cost).collect()) < 6.0);
    }
}
