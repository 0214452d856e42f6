//! `gtwatch bench sim`: wall time of one complete start-up simulation (median of repeats).
//! Must not change the model or its settings: it only times the simulation.

use super::engine_args::EngineArgs;
use crate::engine::simulation::run_scenario;
use crate::engine::Scenario;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Debug, clap::Args)]
pub struct BenchSimArgs {
    #[command(flatten)]
    pub engine: EngineArgs,
    /// Number of timed runs (after one warm-up run).
    #[arg(long, default_value_t = 21)]
    pub runs: usize,
    /// Print JSON (the only format; kept for symmetry with the other benches).
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: BenchSimArgs) -> anyhow::Result<ExitCode> {
    let engine = a.engine.engine()?;
    let model = engine.model(&a.engine.health()?);
    let scenario = Scenario::startup(engine.cfg());
    let (warm, _) = run_scenario(&model, &scenario)?;
    let simulated_s = warm.last().map(|s| s.t_s).unwrap_or(0.0);
    let mut times = Vec::with_capacity(a.runs);
    let mut stats = None;
    for _ in 0..a.runs.max(1) {
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
    Ok(ExitCode::SUCCESS)
}
