//! `gtwatch report --config FILE [--db FILE] [--out DIR] [--since …] [--until …] [--json]`:
//! writes `DIR/report.html`, one self-contained page (see `crate::report`). Reads the database
//! read-only; the engine (for the latest start-up's model traces) comes from the config's
//! `plant.engine_model`, else the built-in reference engine.
//!
//! Must not hold report logic.

use super::common::{db_path, parse_cli_time};
use super::diagnose_stored::worker_context;
use crate::report::{header_now, write_report};
use crate::store::Store;
use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct ReportArgs {
    /// Config file (database path, plant name, engine file).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Database file (instead of, or overriding, the config's).
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// Output folder; the page is DIR/report.html.
    #[arg(long, default_value = "gtwatch-report")]
    pub out: PathBuf,
    /// Only start-ups beginning at or after this time (2024-03-01, 2024-03-01T06:00:00Z, @EPOCH_S).
    #[arg(long)]
    pub since: Option<String>,
    /// Only start-ups beginning at or before this time.
    #[arg(long)]
    pub until: Option<String>,
    /// Print a JSON summary of what was written (one document).
    #[arg(long)]
    pub json: bool,
}

/// The plant name from the config's `[plant] name`, if any.
fn plant_name(config: Option<&PathBuf>) -> anyhow::Result<String> {
    let Some(path) = config else {
        return Ok("gas turbine".into());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading config {}", path.display()))?;
    let table: toml::Table =
        toml::from_str(&text).with_context(|| format!("config {}", path.display()))?;
    Ok(table
        .get("plant")
        .and_then(|p| p.get("name"))
        .and_then(|v| v.as_str())
        .unwrap_or("gas turbine")
        .to_string())
}

pub(super) fn run(a: ReportArgs) -> anyhow::Result<ExitCode> {
    let path = db_path(a.db.as_ref(), a.config.as_ref())?;
    let since = a.since.as_deref().map(parse_cli_time).transpose()?;
    let until = a.until.as_deref().map(parse_cli_time).transpose()?;
    let ctx = worker_context(a.config.as_deref())?;
    let store = Store::open_readonly(&path)?;
    let header = header_now(&plant_name(a.config.as_ref())?, &path);
    let s = write_report(&store, &ctx.engine, header, &a.out, since, until)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        println!(
            "wrote {} ({} KB): {} start-up(s), {} result(s), {} wash(es), {} gap(s), {} not diagnosed",
            s.path.display(),
            s.bytes / 1024,
            s.startups,
            s.diagnoses,
            s.washes,
            s.gaps,
            s.undiagnosed
        );
    }
    Ok(ExitCode::SUCCESS)
}
