//! `gtwatch segments [--since …] [--format table|csv|json]`: list detected start-ups.
//! Must not write to the database: it reads through a read-only store.

use super::common::{db_path, parse_cli_time, FormatArgs};
use crate::query::{list_segments, write_segments};
use crate::store::Store;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct SegmentsArgs {
    /// Config file (for [storage].path).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Database file (instead of --config).
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// Only start-ups beginning at or after this time (2024-03-01, 2024-03-01T06:00:00Z, @EPOCH_S).
    #[arg(long)]
    pub since: Option<String>,
    #[command(flatten)]
    pub output: FormatArgs,
}

pub(super) fn run(args: SegmentsArgs) -> anyhow::Result<ExitCode> {
    let path = db_path(args.db.as_ref(), args.config.as_ref())?;
    let since = args.since.as_deref().map(parse_cli_time).transpose()?;
    let store = Store::open_readonly(&path)?;
    let segs = list_segments(&store, since)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    write_segments(&segs, args.output.format(), &mut out)?;
    Ok(ExitCode::SUCCESS)
}
