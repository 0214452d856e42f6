//! `gtwatch bench steady`: in-process time per off-design steady operating point, so the model
//! can be compared with peers' cycle programs (issue 10 item 7).
//!
//! The points are a deterministic grid across the load range (power demand from `--min-load`
//! to 100 % of the engine file's design power) and ambient temperatures from 258 to 313 K, at
//! the design PT speed and ISO pressure. Each point is solved and timed on its own, twice:
//! `cold` starts from the design point (as a single snapshot with no neighbour would), `warm`
//! from the previous point of the sweep (as a load line or a batch of snapshots is solved).
//! The JSON goes to stdout only; nothing else is printed there.

use crate::engine::steady::{solve_with_stats, SolveStats};
use crate::engine::{Demand, Engine, SteadyInputs, SteadyPoint};
use crate::health::HealthParams;
use std::time::Instant;

/// Ambient temperatures of the grid, K.
const AMBIENTS_K: [f64; 4] = [258.15, 273.15, 288.15, 313.15];

/// Times and solver effort of one pass over the points.
struct Pass {
    seconds: Vec<f64>,
    stats: Vec<SolveStats>,
    failed: usize,
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

fn summary(pass: &Pass) -> serde_json::Value {
    let mut t = pass.seconds.clone();
    t.sort_by(f64::total_cmp);
    let mut iters: Vec<f64> = pass
        .stats
        .iter()
        .map(|s| f64::from(s.newton_iterations))
        .collect();
    iters.sort_by(f64::total_cmp);
    let n = pass.stats.len().max(1) as f64;
    let mean =
        |f: fn(&SolveStats) -> u32| pass.stats.iter().map(|s| f64::from(f(s))).sum::<f64>() / n;
    serde_json::json!({
        "points_solved": pass.seconds.len(),
        "points_failed": pass.failed,
        "median_us": percentile(&t, 0.5) * 1e6,
        "p90_us": percentile(&t, 0.9) * 1e6,
        "min_us": percentile(&t, 0.0) * 1e6,
        "max_us": percentile(&t, 1.0) * 1e6,
        "newton_iterations_median": percentile(&iters, 0.5),
        "newton_iterations_mean": mean(|s| s.newton_iterations),
        "newton_iterations_max": percentile(&iters, 1.0),
        "evaluations_mean": mean(|s| s.evaluations),
        "continuation_steps_mean": mean(|s| s.continuation_steps),
    })
}

/// Solves about `points` operating points of `engine` at `health` from `min_load` (fraction
/// of design power, in (0, 1)) to full load, cold and warm; JSON on stdout. `false` when a
/// point failed to solve.
pub(crate) fn run(
    engine: &Engine,
    health: &HealthParams,
    points: usize,
    min_load: f64,
) -> anyhow::Result<bool> {
    let model = engine.model(health);
    let cfg = engine.cfg();
    let loads = (points.max(AMBIENTS_K.len()) / AMBIENTS_K.len()).max(2);
    let mut inputs = Vec::with_capacity(loads * AMBIENTS_K.len());
    for &t_amb_k in &AMBIENTS_K {
        for i in 0..loads {
            let load = 1.0 - (1.0 - min_load) * i as f64 / (loads - 1) as f64;
            inputs.push(SteadyInputs {
                t_amb_k,
                p_amb_kpa: 101.325,
                n2_rpm: cfg.design.pt_speed_rpm,
                demand: Demand::PowerMw(load * cfg.design.power_mw),
            });
        }
    }
    // Warm-up: one solve so first-touch costs are not timed.
    solve_with_stats(&model, &inputs[0], None)?;

    let run_pass = |warm: bool| -> Pass {
        let mut pass = Pass {
            seconds: Vec::with_capacity(inputs.len()),
            stats: Vec::with_capacity(inputs.len()),
            failed: 0,
        };
        let mut prev: Option<SteadyPoint> = None;
        for inp in &inputs {
            let guess = if warm { prev.as_ref() } else { None };
            let t0 = Instant::now();
            let r = solve_with_stats(&model, inp, guess);
            let dt = t0.elapsed().as_secs_f64();
            match r {
                Ok((p, s)) => {
                    std::hint::black_box(&p);
                    pass.seconds.push(dt);
                    pass.stats.push(s);
                    prev = Some(p);
                }
                Err(e) => {
                    tracing::warn!("bench steady: {inp:?}: {e}");
                    pass.failed += 1;
                    prev = None;
                }
            }
        }
        pass
    };
    let cold = run_pass(false);
    let warm = run_pass(true);
    let out = serde_json::json!({
        "bench": "steady",
        "engine": cfg.name,
        "points": inputs.len(),
        "load_range": [min_load, 1.0],
        "ambient_k": AMBIENTS_K,
        "demand": "power at the design PT speed",
        "cold_from_design_point": summary(&cold),
        "warm_from_previous_point": summary(&warm),
        "build": if cfg!(debug_assertions) { "debug" } else { "release" },
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(cold.failed + warm.failed == 0)
}
