//! `gtwatch bench sim`: wall time of one complete start-up simulation (median of repeats).
//! Must not change the model or its settings: it only times the simulation.

use crate::engine::simulation::run_scenario;
use crate::engine::{Engine, Scenario};
use crate::health::HealthParams;
use std::time::Instant;

/// Times `runs` start-up simulations of `engine` at `health` (after one warm-up run); JSON on
/// stdout.
pub(crate) fn run(engine: &Engine, health: &HealthParams, runs: usize) -> anyhow::Result<()> {
    let model = engine.model(health);
    let scenario = Scenario::startup(engine.cfg());
    let (warm, _) = run_scenario(&model, &scenario)?;
    let simulated_s = warm.last().map(|s| s.t_s).unwrap_or(0.0);
    let mut times = Vec::with_capacity(runs);
    let mut stats = None;
    for _ in 0..runs.max(1) {
        let t0 = Instant::now();
        let (s, st) = run_scenario(&model, &scenario)?;
        times.push(t0.elapsed().as_secs_f64());
        std::hint::black_box(&s);
        stats = Some(st);
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let out = serde_json::json!({
        "bench": "sim",
        "scenario": "startup",
        "runs": times.len(),
        // One simulation runs on one thread: the figure is one core's.
        "threads": 1,
        "simulated_s": simulated_s,
        "samples": warm.len(),
        "median_wall_s": median,
        "min_wall_s": times[0],
        "max_wall_s": times[times.len() - 1],
        "median_wall_ms": median * 1e3,
        "sim_to_wall_ratio": simulated_s / median,
        "integration": stats,
        "build": if cfg!(debug_assertions) { "debug" } else { "release" },
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
