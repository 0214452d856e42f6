//! `gtwatch bench diagnosis`: accuracy of both methods on synthetic start-ups with known truth
//! (per-parameter RMSE and maximum error, median wall time and model runs), optionally with the
//! optimiser comparison at equal budget.
//! Must not diagnose anything itself: the cases and fits are `diagnosis::bench`'s; this file prints
//! them (the flags are `cli::bench`'s).

use crate::diagnosis::bench::{bench_diagnosis, MethodStats};
use crate::diagnosis::{DiagnosisConfig, Optimiser};
use crate::engine::Engine;
use crate::health::HEALTH_NAMES;

fn row(name: &str, s: &MethodStats) {
    let f = |m: &std::collections::BTreeMap<String, f64>| {
        HEALTH_NAMES
            .iter()
            .map(|n| format!("{:7.3}", m.get(*n).copied().unwrap_or(f64::NAN)))
            .collect::<Vec<_>>()
            .join(" ")
    };
    println!("{name:22} RMSE {}", f(&s.rmse));
    println!("{:22} max  {}", "", f(&s.max_error));
    println!("{:22} |e|/σ {}", "", f(&s.z_rms));
    println!(
        "{:22} median {:.2} s, {:.0} model runs, {} cases, {} failures",
        "", s.median_wall_s, s.median_model_runs, s.cases, s.failures
    );
}

/// Runs the bench: `cases` health vectors drawn from `seed`, fitted with `cfg` (and, with
/// `compare`, with each optimiser at the same budget); JSON or text on stdout.
pub(crate) fn run(
    engine: &Engine,
    cfg: &DiagnosisConfig,
    cases: usize,
    seed: u64,
    compare: bool,
    json: bool,
) -> anyhow::Result<()> {
    let compare: Vec<Optimiser> = if compare {
        vec![
            Optimiser::Cuckoo,
            Optimiser::CuckooLm,
            Optimiser::CmaEs,
            Optimiser::De,
        ]
    } else {
        Vec::new()
    };
    let mut progress = |c: &crate::diagnosis::bench::CaseRecord| {
        eprintln!(
            "case {:3}: transient {:.1} s, steady {:.2} s{}",
            c.index,
            c.transient_wall_s,
            c.steady_wall_s,
            match (&c.transient, &c.steady) {
                (Err(e), _) | (_, Err(e)) => format!(" ({e})"),
                _ => String::new(),
            }
        )
    };
    let rep = bench_diagnosis(engine, cases, seed, cfg, &compare, &mut progress)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
        return Ok(());
    }
    println!(
        "{} cases, seed {}, optimiser {}, budget {} model runs",
        rep.cases,
        rep.seed,
        rep.optimiser.name(),
        rep.max_model_runs
    );
    println!(
        "{:22}      {}",
        "",
        HEALTH_NAMES.map(|n| format!("{n:>7}")).join(" ")
    );
    match rep.transient_one_core_median_wall_s {
        Some(w) => println!("one core (threads 1): Method B median {w:.2} s per start-up"),
        None => println!(
            "threads {}: wall times are not one core's (--threads 1 gives that figure)",
            rep.threads
                .map_or_else(|| "all cores".to_string(), |n| n.to_string())
        ),
    }
    row("Method B (transient)", &rep.transient);
    row("Method A (steady)", &rep.steady);
    for c in &rep.comparison {
        row(&format!("B with {}", c.optimiser.name()), &c.stats);
        println!("{:22} median objective {:.4}", "", c.median_objective);
    }
    Ok(())
}
