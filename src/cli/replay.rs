//! `gtwatch replay --config FILE LOG.csv`: ingest a CSV log, then run the start-up detector.

use super::common::DataSections;
use crate::ingest::{replay_file, Progress, ReplayError};
use crate::store::Store;
use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct ReplayArgs {
    /// Config file ([storage], [replay] and [detector] are used).
    #[arg(long)]
    pub config: PathBuf,
    /// Database file (overrides [storage].path).
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// Do not run the start-up detector after ingesting.
    #[arg(long)]
    pub no_detect: bool,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// CSV log files, replayed in order.
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
}

pub fn run(args: ReplayArgs) -> anyhow::Result<ExitCode> {
    let mut cfg = DataSections::load(&args.config)?;
    if let Some(db) = &args.db {
        cfg.storage.path = db.clone();
    }
    let mut store = Store::open_with(&cfg.storage.path, &cfg.storage.options())?;
    let mut failed = false;
    for log in &args.logs {
        match replay_file(&mut store, &cfg.replay, log, Progress::Auto) {
            Ok(report) => {
                for m in &report.malformed {
                    eprintln!("{}: {m}", log.display());
                }
                if report.rows_malformed > report.malformed.len() as u64 {
                    eprintln!(
                        "{}: ... {} malformed rows in all (first {} listed)",
                        log.display(),
                        report.rows_malformed,
                        report.malformed.len()
                    );
                }
                if args.json {
                    println!("{}", serde_json::to_string(&report)?);
                } else {
                    println!(
                        "{}: {} rows, {} samples new, {} already present, {} malformed, {} gaps, {:.2} s ({:.0} samples/s)",
                        log.display(),
                        report.rows_read,
                        report.samples_inserted,
                        report.samples_present,
                        report.rows_malformed,
                        report.gaps_recorded,
                        report.elapsed_s,
                        report.samples_per_s()
                    );
                }
            }
            Err(e @ ReplayError::Malformed { .. }) => {
                eprintln!("gtwatch: error: {e}");
                failed = true;
                break;
            }
            Err(e) => return Err(e).with_context(|| format!("replaying {}", log.display())),
        }
    }
    if !args.no_detect {
        let scan = crate::detect::scan(&mut store, &cfg.detector).context("start-up detection")?;
        println!(
            "detector: {} frames, {} segments written ({} closed, {} open)",
            scan.frames, scan.segments_written, scan.segments_closed, scan.segments_open
        );
    }
    Ok(if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}
