//! `gtwatch bench <kind>`: benchmarks that print JSON. Each kind lives in its own file of
//! `crate::bench`; this file declares the flags of the kinds that take the command line's
//! shared arguments (engine file, fit settings), loads what they name and dispatches.
//! Must not hold benchmark logic itself.

use super::diagnose::FitArgs;
use super::engine_args::EngineArgs;
use crate::bench;
use clap::Args;
use std::process::ExitCode;

#[derive(Debug, clap::Subcommand)]
pub enum BenchCmd {
    /// Replay ingest throughput into SQLite (synthetic CSV in a temporary directory).
    Replay(bench::replay::BenchReplayArgs),
    /// Wall time of one complete start-up simulation (median of repeated runs).
    Sim(BenchSimArgs),
    /// Diagnosis accuracy on synthetic start-ups with known truth (Method B and Method A).
    Diagnosis(BenchDiagnosisArgs),
    /// The paper's Table 3 (before/after a compressor wash) on synthetic truth.
    Wash(BenchWashArgs),
    /// A month of 1 Hz plant data replayed: ingest, detection and diagnosis times, accuracy.
    Month(bench::month::BenchMonthArgs),
    /// Issue 23's acceptance: a replayed month with an instrument step and a poorly fitting
    /// start-up; gap analyses stored unasked, the advice, and the diagnosis latency.
    GapMonth(bench::gap_month::BenchGapMonthArgs),
    /// Blind proof of the gap analysis: hidden effects unlike the library's forms.
    Gap(bench::gap::BenchGapArgs),
    /// Daemon CPU (live polling of a simulated plant) or memory after a simulated day (--day).
    Daemon(bench::daemon::BenchDaemonArgs),
    /// Reliability soak: N days × M tags of 1 Hz data through writer and detector at full
    /// speed; throughput and resident memory per simulated day.
    Soak(bench::soak::BenchSoakArgs),
    /// In-process time per off-design steady operating point (median, p90) and Newton
    /// iterations, over a grid across the load range and ambient temperatures.
    Steady(BenchSteadyArgs),
}

/// `gtwatch bench diagnosis`
#[derive(Debug, Clone, Args)]
pub struct BenchDiagnosisArgs {
    /// Number of health vectors.
    #[arg(long, default_value_t = 20)]
    pub cases: usize,
    /// Also run Method B with cuckoo alone, cuckoo + LM, CMA-ES and DE at the same budget.
    #[arg(long)]
    pub compare: bool,
    /// Engine TOML (default: the built-in reference engine).
    #[arg(long)]
    pub engine: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// `gtwatch bench wash`
#[derive(Debug, Clone, Args)]
pub struct BenchWashArgs {
    /// Engine TOML (default: the built-in reference engine).
    #[arg(long)]
    pub engine: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

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

#[derive(Debug, clap::Args)]
pub struct BenchSteadyArgs {
    #[command(flatten)]
    pub engine: EngineArgs,
    /// Number of operating points (load levels × ambient temperatures, rounded to the grid).
    #[arg(long, default_value_t = 400)]
    pub points: usize,
    /// Lowest load, fraction of design power.
    #[arg(long, default_value_t = 0.2)]
    pub min_load: f64,
    /// Print JSON (the only format; kept for symmetry with the other benches).
    #[arg(long)]
    pub json: bool,
}

pub(super) fn run(cmd: BenchCmd) -> anyhow::Result<ExitCode> {
    match cmd {
        BenchCmd::Replay(a) => bench::replay::run(a),
        BenchCmd::Sim(a) => {
            let (engine, health) = a.engine.load()?;
            bench::sim::run(&engine, &health, a.runs)?;
            Ok(ExitCode::SUCCESS)
        }
        BenchCmd::Diagnosis(a) => {
            let engine = super::load_engine(a.engine.as_deref())?;
            let cfg = a.fit.config()?;
            bench::diagnosis::run(&engine, &cfg, a.cases, a.fit.seed, a.compare, a.json)?;
            Ok(ExitCode::SUCCESS)
        }
        BenchCmd::Wash(a) => {
            let engine = super::load_engine(a.engine.as_deref())?;
            let cfg = a.fit.config()?;
            bench::wash::run(&engine, &cfg, a.fit.seed, a.json)?;
            Ok(ExitCode::SUCCESS)
        }
        BenchCmd::Daemon(a) => bench::daemon::run(a),
        BenchCmd::Month(a) => with_commands(|c| bench::month::run(a, c)),
        BenchCmd::GapMonth(a) => with_commands(|c| bench::gap_month::run(a, c)),
        BenchCmd::Gap(a) => bench::gap::run(a),
        BenchCmd::Soak(a) => bench::soak::run(a),
        BenchCmd::Steady(a) => {
            anyhow::ensure!(
                a.min_load > 0.0 && a.min_load < 1.0,
                "--min-load must be in (0, 1), got {}",
                a.min_load
            );
            let (engine, health) = a.engine.load()?;
            let solved = bench::steady::run(&engine, &health, a.points, a.min_load)?;
            Ok(if solved {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            })
        }
    }
}

/// `gtwatch bench month|gap-month`, with the configuration loaded, the start-ups diagnosed
/// (and gap-analysed) as `gtwatch replay` does and the advice refreshed as `gtwatch wash advise`
/// does.
fn with_commands(
    f: impl FnOnce(&bench::month::Commands) -> anyhow::Result<ExitCode>,
) -> anyhow::Result<ExitCode> {
    let load_sections = |path: &std::path::Path| {
        let s = super::common::DataSections::load(path)?;
        Ok(bench::month::Sections {
            storage: s.storage,
            replay: s.replay,
            detector: s.detector,
        })
    };
    let diagnose_after_replay = |store: &mut crate::store::Store, config: &std::path::Path| {
        super::diagnose_stored::diagnose_after_replay(store, config, true)
    };
    let advise = |store: &mut crate::store::Store, config: &std::path::Path| {
        let ctx = super::diagnose_stored::worker_context(Some(config))?;
        let econ = super::diagnose_stored::wash_economics(Some(config))?;
        Ok(crate::advice::refresh(
            store,
            &ctx.engine,
            &econ,
            &crate::trend::WashDetection::default(),
            &ctx.settings.bounds(),
        )?)
    };
    f(&bench::month::Commands {
        load_sections: &load_sections,
        diagnose_after_replay: &diagnose_after_replay,
        advise: &advise,
    })
}
