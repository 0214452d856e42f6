//! `gtwatch bench <kind>`: benchmarks that print JSON. Each kind lives in its own file.

use std::process::ExitCode;

#[derive(Debug, clap::Subcommand)]
pub enum BenchCmd {
    /// Replay ingest throughput into SQLite (synthetic CSV in a temporary directory).
    Replay(super::bench_replay::BenchReplayArgs),
}

pub fn run(cmd: BenchCmd) -> anyhow::Result<ExitCode> {
    match cmd {
        BenchCmd::Replay(a) => super::bench_replay::run(a),
    }
}
