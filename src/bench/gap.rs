//! `gtwatch bench gap`: the blind proof of the gap analysis (`src/gap/bench.rs`) — top-1
//! identification, confusion matrix, false attribution on null cases, "unexplained" on
//! out-of-library cases, shrinkage and health RMSE before/after. Progress on stderr, one JSON
//! document on stdout.
//! Must not hold the proof's logic: it declares its flags and prints what `gap::bench` returns.

use clap::Args;
use std::process::ExitCode;

#[derive(Debug, Args)]
pub struct BenchGapArgs {
    /// Number of cases (cycling through the hidden truths: none, T34 two-path thermocouple,
    /// P2 bias, fuel lead, heat-soak nodes, P34 ripple, smooth bleed, T2 two-path, fuel valve,
    /// T34 bias, smooth VIGV offset, clearance nodes; see `gap::truth`).
    #[arg(long, default_value_t = 14)]
    pub cases: usize,
    /// Only these hidden truths, comma-separated (e.g. `none,p34_ripple`); default all.
    #[arg(long, value_delimiter = ',')]
    pub kinds: Vec<String>,
    /// Seed of the case draw (health vectors, magnitudes, noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Analyse only the cases from this index on (0-based; the earlier ones are drawn but not
    /// analysed, so case k is the same unit and truth as in a full run): re-runs one case of a
    /// long benchmark.
    #[arg(long, default_value_t = 0)]
    pub from_case: usize,
    /// Simulate a second start-up of each unit (other noise) and score candidates on it
    /// (held-out shrinkage; about twice the fits).
    #[arg(long)]
    pub holdout: bool,
    /// Worker threads of each fit (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Sequences instead of single start-ups: each case is this many start-ups a day apart on
    /// a fouling trend, an input-channel error (fuel_scale, fuel_drift, t1_offset, p1_offset,
    /// power_scale) or a control (turbine_step, none) from the fifth on, attributed by the
    /// joint fit the wash advice uses (`gap::sequence`). 0: single start-ups.
    #[arg(long, default_value_t = 0)]
    pub sequence: usize,
    /// With `--sequence`: the instrument is repaired (reads right again) after this many
    /// start-ups with the error, so the joint fit must find where it ended too.
    #[arg(long)]
    pub repair_after: Option<usize>,
    /// With `--sequence`: the instrument's error grows across the start-ups (none at the
    /// fourth, its drawn size at the newest) instead of stepping at the fifth.
    #[arg(long)]
    pub drift: bool,
    /// With `--sequence`: the engine file the start-ups are diagnosed with (an engine
    /// calibrated to the unit, e.g. `calibrate --adapt`'s output); default the reference engine.
    #[arg(long, value_name = "FILE")]
    pub engine: Option<std::path::PathBuf>,
    /// With `--sequence`: the engine file the start-ups are simulated on (the "true" unit),
    /// when it is not the model: another maker's unit, other maps. Default: `--engine`'s.
    #[arg(long, value_name = "FILE")]
    pub plant: Option<std::path::PathBuf>,
    /// Print JSON (the only format).
    #[arg(long)]
    pub json: bool,
}

/// An engine file as `--engine`/`--plant` name it (`None`: the reference engine).
fn engine_of(path: Option<&std::path::Path>, flag: &str) -> anyhow::Result<crate::engine::Engine> {
    use anyhow::Context;
    let cfg = crate::engine::EngineConfig::load_or_reference(path)
        .with_context(|| format!("{flag}: loading the engine file"))?;
    crate::engine::Engine::new(cfg).with_context(|| format!("{flag}: building the engine model"))
}

/// The cases `a` asks for.
fn selection(a: &BenchGapArgs) -> crate::gap::bench::CaseSelection {
    crate::gap::bench::CaseSelection {
        cases: a.cases,
        seed: a.seed,
        only: a.kinds.clone(),
        from_case: a.from_case,
        holdout: a.holdout,
    }
}

pub(crate) fn run(a: BenchGapArgs) -> anyhow::Result<ExitCode> {
    if a.sequence == 0 && (a.engine.is_some() || a.plant.is_some()) {
        anyhow::bail!(
            "--engine and --plant are for --sequence runs: the single-start-up cases draw \
             effects the reference engine's library describes"
        );
    }
    let engine = engine_of(a.engine.as_deref(), "--engine")?;
    let plant = match &a.plant {
        Some(p) => engine_of(Some(p), "--plant")?,
        None => engine.clone(),
    };
    let cfg = crate::diagnosis::DiagnosisConfig {
        threads: a.threads,
        ..Default::default()
    };
    let start = std::time::Instant::now();
    if a.sequence > 0 {
        return run_sequences(&a, &engine, &plant, &cfg, start);
    }
    let run = crate::gap::bench::run_cases(&engine, &selection(&a), &cfg, |c| {
        eprintln!(
            "case {:3} {:15} → {:20} {} (signature {:.1} σ, shrinkage {:.0} %, \
                 magnitude {:.3} fitted {}, max health error {:.2} → {:.2}, screen rank {}, \
                 {:.0} s)",
            c.index,
            c.kind,
            if c.verdict_aliases.is_empty() {
                c.verdict.clone()
            } else {
                format!("{} [{}]", c.verdict, c.verdict_aliases.join(" "))
            },
            if c.correct { "ok" } else { "WRONG" },
            c.signature_sigma,
            100.0 * c.shrinkage,
            c.magnitude,
            c.fitted_magnitude
                .map_or("-".to_string(), |m| format!("{m:.3}")),
            c.error_before,
            c.error_after,
            c.expected_screen_rank
                .map_or("-".to_string(), |k| k.to_string()),
            c.analysis_wall_s
        );
    })?;
    let cases = &run.cases;
    let mut v = crate::gap::bench::summarise(&run);
    v["holdout"] = serde_json::json!(a.holdout);
    v["seed"] = serde_json::json!(a.seed);
    v["wall_s"] = serde_json::json!(start.elapsed().as_secs_f64());
    v["per_case"] = serde_json::to_value(cases)?;
    println!("{}", serde_json::to_string_pretty(&v)?);
    Ok(ExitCode::SUCCESS)
}

fn run_sequences(
    a: &BenchGapArgs,
    engine: &crate::engine::Engine,
    plant: &crate::engine::Engine,
    cfg: &crate::diagnosis::DiagnosisConfig,
    start: std::time::Instant,
) -> anyhow::Result<ExitCode> {
    use crate::gap::sequence_bench as sb;
    let run = sb::SequenceRun {
        cases: a.cases,
        start_ups: a.sequence,
        seed: a.seed,
        only: a.kinds.clone(),
        repair_after: a.repair_after,
        drift: a.drift,
    };
    let cases = sb::run_sequences(engine, plant, &run, cfg, |c| {
        eprintln!(
            "sequence {:3} {:13} magnitude {:+.3} → {:40} {} (onset {}, until {} [{}], fitted {}, \
             max health error {:.2} → {:.2}, before the onset {:.2}, as a change {:.2}, {:.0} s){}",
            c.index,
            c.kind,
            c.magnitude,
            c.verdict,
            if c.correct { "ok" } else { "WRONG" },
            c.onset.map_or("-".to_string(), |k| k.to_string()),
            c.fitted_until.map_or("-".to_string(), |k| k.to_string()),
            c.repaired_at.map_or("-".to_string(), |k| k.to_string()),
            c.fitted_magnitude
                .map_or("-".to_string(), |m| format!("{m:+.4}")),
            c.error_fitted,
            c.error_corrected,
            c.error_before_onset,
            c.change_error_corrected,
            c.wall_s,
            if c.later_steps.is_empty() {
                String::new()
            } else {
                format!(" LATER STEPS {}", c.later_steps.join(", "))
            }
        );
    })?;
    let mut v = sb::summarise(&cases);
    v["seed"] = serde_json::json!(a.seed);
    v["start_ups_per_sequence"] = serde_json::json!(a.sequence);
    v["repair_after"] = serde_json::json!(a.repair_after);
    v["drift"] = serde_json::json!(a.drift);
    // Which model diagnosed which unit (null: the reference engine; the plant null: the model's
    // own twin).
    v["engine"] = serde_json::json!(a.engine);
    v["plant"] = serde_json::json!(a.plant);
    v["wall_s"] = serde_json::json!(start.elapsed().as_secs_f64());
    v["per_case"] = serde_json::to_value(&cases)?;
    println!("{}", serde_json::to_string_pretty(&v)?);
    Ok(ExitCode::SUCCESS)
}
