//! Command-line interface: the clap command tree and dispatch to one handler per file.
//!
//! Each subcommand's args struct and handler live in `src/cli/<name>.rs`; this file only lists
//! them. Handlers return `anyhow::Result` and print a readable error chain. Must not hold
//! business logic.

mod bench;
mod calibrate;
mod check_config;
mod common;
mod demo;
mod diagnose;
mod diagnose_log;
mod diagnose_snapshots;
mod diagnose_stored;
pub(crate) mod engine_args;
mod export;
mod fleet_history;
mod fleet_worker;
mod gap;
mod history;
mod plant_sim;
mod replay;
mod report;
mod run;
mod segments;
mod simulate;
mod steady;
mod store;
mod sync;
mod wash;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// gtwatch: gas-turbine start-up monitoring and gas-path diagnosis.
#[derive(Debug, Parser)]
#[command(name = "gtwatch", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// The whole product on a built-in simulated plant: fouling, daily start-ups, diagnosis,
    /// trend and wash advice, in a couple of minutes.
    Demo(demo::DemoArgs),
    /// Simulate a start-up on the engine model and write it as CSV (and SVG).
    Simulate(simulate::SimulateArgs),
    /// Solve one steady operating point and print the station table.
    Steady(steady::SteadyArgs),
    /// Diagnose the six health parameters from a start-up CSV (Method B and/or Method A).
    Diagnose(diagnose::DiagnoseArgs),
    /// Sim-to-real gap: where the model and a start-up disagree, which effect of the library
    /// explains it, and the health once it is added (`--list-effects` lists the library).
    Gap(gap::GapArgs),
    /// Adapt an engine file's design values to one unit's healthy steady snapshots and write
    /// the calibrated engine file.
    Calibrate(calibrate::CalibrateArgs),
    /// Ingest a historical CSV log into the database (idempotent), then detect start-ups.
    Replay(replay::ReplayArgs),
    /// List detected start-ups with outcome and phase durations.
    Segments(segments::SegmentsArgs),
    /// Stored health results per start-up (Method A/B), as a table, CSV or JSON.
    History(history::HistoryArgs),
    /// Record washes and advise the next offline wash from the degradation trend.
    Wash(wash::WashArgs),
    /// Write one self-contained HTML report: health trend, washes, latest start-up, gaps, advice.
    Report(report::ReportArgs),
    /// Write stored samples as CSV.
    Export(export::ExportArgs),
    /// Run the monitoring daemon (Modbus acquisition, storage, start-up detection).
    Run(run::RunArgs),
    /// Validate a configuration file and explain every problem found.
    CheckConfig(check_config::CheckConfigArgs),
    /// Serve a simulated plant over Modbus TCP (tests and commissioning).
    PlantSim(plant_sim::PlantSimArgs),
    /// Send this unit's start-ups, results, washes, advice and start-up samples to the fleet's
    /// central PostgreSQL once (what the daemon does every `[fleet] interval_s`).
    Sync(sync::SyncArgs),
    /// The fleet's central database: `fleet status` lists units, last sync, rows per table.
    #[command(subcommand)]
    Fleet(sync::FleetCmd),
    /// The database's storage tiers: `store compact` archives old samples.
    #[command(subcommand)]
    Store(store::StoreCmd),
    /// Benchmarks that print JSON.
    #[command(subcommand)]
    Bench(bench::BenchCmd),
}

/// Entry point used by `src/main.rs`.
pub fn main() -> ExitCode {
    quiet_on_closed_stdout();
    let cli = Cli::parse();
    // The demo's own progress lines are the story; the daemon inside it logs warnings only
    // (RUST_LOG still overrides).
    init_logging(if matches!(cli.command, Command::Demo(_)) {
        "warn"
    } else {
        "info"
    });
    let result = match cli.command {
        Command::Demo(a) => demo::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Steady(a) => steady::run(a),
        Command::Diagnose(a) => diagnose::run(&a),
        Command::Gap(a) => gap::run(&a),
        Command::Calibrate(a) => calibrate::run(a),
        Command::Replay(a) => replay::run(a),
        Command::Segments(a) => segments::run(a),
        Command::History(a) => history::run(a),
        Command::Wash(a) => wash::run(a),
        Command::Report(a) => report::run(a),
        Command::Export(a) => export::run(a),
        Command::Run(a) => run::run(a),
        Command::CheckConfig(a) => check_config::run(a),
        Command::PlantSim(a) => plant_sim::run(a),
        Command::Sync(a) => sync::run_sync(&a),
        Command::Fleet(c) => sync::run_fleet(&c),
        Command::Store(c) => store::run(c),
        Command::Bench(b) => bench::run(b),
    };
    match result {
        Ok(code) => code,
        // `gtwatch segments | head`: the reader went away; that is not an error.
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gtwatch: error: {}", error_chain(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes joined by `: `, leaving out a cause whose text the message before
/// it already contains (an error that prints its source, e.g. `cannot read X: {source}`, would
/// otherwise show the OS error twice).
pub fn error_chain(e: &anyhow::Error) -> String {
    let mut out = String::new();
    let mut last = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        // Also leave out a cause that only repeats the one before it with a prefix (SQLite's
        // `attempt to write a readonly database` then `Error code 1544: attempt to write …`).
        if text.is_empty() || out.contains(&text) || (!last.is_empty() && text.contains(&last)) {
            continue;
        }
        last.clone_from(&text);
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}

/// `gtwatch replay --json | head -c 100`: `println!` panics when the reader has gone away.
/// A closed stdout is not an error: end quietly with status 0 instead of a panic message.
/// Covers every command that prints with `print!`/`println!`; commands that write through
/// `std::io::stdout()` get the `BrokenPipe` error, which [`main`] also treats as success.
fn quiet_on_closed_stdout() {
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if msg.starts_with("failed printing to stdout") && msg.contains("Broken pipe") {
            std::process::exit(0);
        }
        default_hook(info);
    }));
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            || c.downcast_ref::<csv::Error>().is_some_and(|ce| {
                matches!(ce.kind(), csv::ErrorKind::Io(io) if io.kind() == std::io::ErrorKind::BrokenPipe)
            })
            || c.downcast_ref::<serde_json::Error>()
                .and_then(|je| je.io_error_kind())
                .is_some_and(|k| k == std::io::ErrorKind::BrokenPipe)
    })
}

/// Logs to stderr; `RUST_LOG` overrides the default `info` level. When stderr is not a
/// terminal (systemd/journald, pipes) lines are plain: no colours and no timestamps, because
/// journald stamps every line itself.
pub fn init_logging(default_level: &str) {
    use std::io::IsTerminal;
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default_level));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    let _ = if std::io::stderr().is_terminal() {
        builder.try_init()
    } else {
        builder.with_ansi(false).without_time().try_init()
    };
}

/// Loads the engine from `--engine FILE`, or the built-in reference engine.
pub(crate) fn load_engine(path: Option<&std::path::Path>) -> anyhow::Result<crate::engine::Engine> {
    use anyhow::Context;
    let cfg = match path {
        Some(p) => crate::engine::EngineConfig::load(p)
            .with_context(|| format!("loading engine config {}", p.display()))?,
        None => crate::engine::EngineConfig::reference(),
    };
    Ok(crate::engine::Engine::new(cfg)?)
}
