//! `gtwatch bench replay [--rows N] [--tags K] [--json]`: replay ingest throughput.
//!
//! Writes a synthetic CSV (N rows × K signal columns, 1 Hz) to a temporary directory, replays
//! it into a fresh database, then replays it again to show the idempotent pass; reports
//! samples/s for both.

use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct BenchReplayArgs {
    /// Rows in the synthetic CSV.
    #[arg(long, default_value_t = 200_000)]
    pub rows: u64,
    /// Data columns per row (at most 15, named after signals).
    #[arg(long, default_value_t = 10)]
    pub tags: usize,
    /// Print JSON only.
    #[arg(long)]
    pub json: bool,
}

pub fn run(_args: BenchReplayArgs) -> anyhow::Result<ExitCode> {
    anyhow::bail!("bench replay: not implemented yet")
}
