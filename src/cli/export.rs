//! `gtwatch export --tag NAME[,NAME] --from … --to … [--out FILE]`: samples as CSV.
//! Must not write to the database: it reads through a read-only store.

use super::common::{db_path, parse_cli_time};
use crate::query::{export_csv, ExportLayout};
use crate::store::Store;
use anyhow::Context;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// Config file (for [storage].path).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Database file (instead of --config).
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// Tag names, comma-separated or repeated (e.g. n1_rpm,fuel_kg_s).
    #[arg(long = "tag", value_delimiter = ',', required = true)]
    pub tags: Vec<String>,
    /// Start time, inclusive (2024-03-01, 2024-03-01T06:00:00Z, @EPOCH_S).
    #[arg(long)]
    pub from: String,
    /// End time, inclusive.
    #[arg(long)]
    pub to: String,
    /// `wide` (default: one row per time, one column per tag) or `long` (one row per sample).
    #[arg(long, value_enum, default_value_t = ExportLayout::Wide)]
    pub layout: ExportLayout,
    /// Output file (default: stdout).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub(super) fn run(args: ExportArgs) -> anyhow::Result<ExitCode> {
    let path = db_path(args.db.as_ref(), args.config.as_ref())?;
    let from = parse_cli_time(&args.from)?;
    let to = parse_cli_time(&args.to)?;
    anyhow::ensure!(from <= to, "--from must not be after --to");
    let store = Store::open_readonly(&path)?;
    let rows = match &args.out {
        Some(file) => {
            let f = std::fs::File::create(file)
                .with_context(|| format!("creating {}", file.display()))?;
            let mut w = std::io::BufWriter::new(f);
            let n = export_csv(&store, &args.tags, from, to, args.layout, &mut w)?;
            w.flush()?;
            n
        }
        None => {
            let stdout = std::io::stdout();
            let mut w = std::io::BufWriter::new(stdout.lock());
            let n = export_csv(&store, &args.tags, from, to, args.layout, &mut w)?;
            w.flush()?;
            n
        }
    };
    tracing::info!(rows, "export done");
    Ok(ExitCode::SUCCESS)
}
