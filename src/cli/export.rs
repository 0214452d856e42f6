//! `gtwatch export --tag NAME[,NAME] --from … --to … [--resolution auto|raw|1m|1h]
//! [--out FILE]`: samples as CSV, and where retention rolled them up, the 1-minute and hourly
//! roll-ups, marked (README "Retention and roll-ups"). Must not write to the database: it
//! reads through a read-only store.

use super::common::{db_path, parse_cli_time};
use crate::query::{export_csv, rolled_up_in_range, ExportLayout, ExportRequest, Resolution};
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
    /// `auto` (default: raw samples, and the 1-minute and hourly roll-ups where retention
    /// replaced them, marked in a `resolution` column), `raw` (raw samples only, the columns
    /// without `resolution`), `1m` or `1h` (everything aggregated to that period).
    #[arg(long, value_enum, default_value_t = Resolution::Auto)]
    pub resolution: Resolution,
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
    if args.resolution == Resolution::Raw {
        let (minutes, hours) = rolled_up_in_range(&store, &args.tags, from, to)?;
        if minutes + hours > 0 {
            eprintln!(
                "warning: retention rolled up part of this range ({minutes} tag-minutes, {hours} tag-hours): their raw samples are gone and not in a raw export; --resolution auto, 1m or 1h exports them"
            );
        }
    }
    let req = ExportRequest {
        tags: args.tags.clone(),
        from_ms: from,
        to_ms: to,
        layout: args.layout,
        resolution: args.resolution,
    };
    let rows = match &args.out {
        Some(file) => {
            let f = std::fs::File::create(file)
                .with_context(|| format!("creating {}", file.display()))?;
            let mut w = std::io::BufWriter::new(f);
            let n = export_csv(&store, &req, &mut w)?;
            w.flush()?;
            n
        }
        None => {
            let stdout = std::io::stdout();
            let mut w = std::io::BufWriter::new(stdout.lock());
            let n = export_csv(&store, &req, &mut w)?;
            w.flush()?;
            n
        }
    };
    tracing::info!(rows, "export done");
    Ok(ExitCode::SUCCESS)
}
