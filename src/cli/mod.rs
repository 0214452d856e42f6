//! Command line of the `gtwatch` binary: argument parsing (clap) and dispatch to the
//! subcommand handlers. Handlers do the I/O (files, stdout); the work is in the library.

pub mod bench_diagnosis;
pub mod bench_wash;
pub mod diagnose;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// gtwatch: transient-based gas-path diagnosis for a two-shaft industrial gas turbine.
#[derive(Debug, Parser)]
#[command(name = "gtwatch", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// Top-level subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Diagnose the six health parameters from a start-up CSV (Method B and/or Method A).
    Diagnose(diagnose::DiagnoseArgs),
    /// Benchmarks that print figures (JSON with --json).
    #[command(subcommand)]
    Bench(BenchCommand),
}

/// `gtwatch bench …`
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Diagnosis accuracy on synthetic start-ups with known truth.
    Diagnosis(bench_diagnosis::BenchDiagnosisArgs),
    /// The paper's Table 3 (before/after a compressor wash) on synthetic truth.
    Wash(bench_wash::BenchWashArgs),
}

/// Parses the arguments and runs the subcommand; errors go to stderr with exit code 1.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Diagnose(a) => diagnose::run(&a),
        Command::Bench(BenchCommand::Diagnosis(a)) => bench_diagnosis::run(&a),
        Command::Bench(BenchCommand::Wash(a)) => bench_wash::run(&a),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("gtwatch: {e:#}");
            ExitCode::FAILURE
        }
    }
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
