//! `gtwatch replay --config FILE LOG.csv`: ingest a CSV log, then run the start-up detector,
//! diagnose the start-ups it closed and run the gap analyses `[diagnosis]` asks for (as the
//! daemon does; `diagnose_stored::diagnose_after_replay`).
//!
//! Exit status: 0 all rows stored; 1 an error (or `on_malformed = "stop"` hit a bad row);
//! 3 replayed, but rows were rejected for their time stamps (out of order, implausible, or a
//! local time the configured zone skips; see stderr / the JSON report).
//! Must not parse CSV or detect start-ups itself: that is `ingest` and `detect`.

use super::common::DataSections;
use crate::ingest::{
    plan_columns, replay_file_checked, ColumnPlan, Progress, ReplayError, ReplayReport,
};
use crate::signals::Signal;
use crate::store::Store;
use anyhow::Context;
use std::io::Write;
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
    /// Write the samples straight into the archive tier as compressed chunks (a historical
    /// log; the same as `[replay] archive = true`): faster, smaller, and readers cannot tell.
    #[arg(long)]
    pub archive: bool,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// CSV log files, replayed in order.
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
}

/// Exit status when every file was replayed but rows were rejected for their time stamps
/// (out of order, duplicate, or implausibly far in the future): never silent.
pub(super) const EXIT_TIME_REJECTED: u8 = 3;

/// Everything `replay --json` prints: exactly one JSON document.
#[derive(Debug, serde::Serialize)]
struct JsonOutput<'a> {
    files: &'a [ReplayReport],
    /// The line of the file that stopped the replay (`on_malformed = "stop"`), if any.
    error: Option<String>,
    detector: Option<crate::detect::ScanReport>,
    /// The diagnosis and gap analyses run after the detector (absent with `--no-detect`).
    after: Option<crate::worker::gap::AfterReplay>,
}

/// The detector inputs a log must feed (unless `--no-detect`): n1, fuel flow and power, or the
/// tags `[detector]` names for them.
fn missing_detector_inputs(plan: &ColumnPlan, det: &crate::detect::DetectorConfig) -> Vec<String> {
    let need = [
        (&det.n1_tag, Signal::N1),
        (&det.fuel_tag, Signal::FuelFlow),
        (&det.power_tag, Signal::Power),
    ];
    need.iter()
        .filter(|(tag, sig)| match tag {
            Some(name) => !plan.feeds_tag(name),
            None => !plan
                .mapped
                .iter()
                .any(|(_, _, info)| info.signal == Some(*sig)),
        })
        .map(|(tag, sig)| match tag {
            Some(name) => format!("tag '{name}' ([detector] {}_tag)", detector_key(*sig)),
            None => format!("signal {}", sig.column()),
        })
        .collect()
}

fn detector_key(sig: Signal) -> &'static str {
    match sig {
        Signal::N1 => "n1",
        Signal::FuelFlow => "fuel",
        _ => "power",
    }
}

/// The replay's one line about the detector: frames, segments, and the fuel meter's zero when
/// it is a tenth of the "fuel on" threshold or more (worth a word).
fn detector_line(scan: &crate::detect::ScanReport, fuel_on_kg_s: f64) -> String {
    let mut line = format!(
        "detector: {} frames, {} segments written ({} closed, {} open)",
        scan.frames, scan.segments_written, scan.segments_closed, scan.segments_open
    );
    if let Some(z) = scan
        .fuel_zero_kg_s
        .filter(|z| z.abs() >= 0.1 * fuel_on_kg_s)
    {
        line.push_str(&format!(
            "; the fuel meter reads {z:+.4} kg/s with the GG at rest (its zero, taken off \
             before fuel on is judged)"
        ));
    }
    line
}

pub(super) fn run(args: ReplayArgs) -> anyhow::Result<ExitCode> {
    let mut cfg = DataSections::load(&args.config)?;
    if let Some(db) = &args.db {
        cfg.storage.path = db.clone();
    }
    cfg.replay.archive |= args.archive;
    // Check every log's header before the database (or its folder) is created: a missing
    // file, a missing column or a log without the detector's inputs fails here.
    for log in &args.logs {
        let plan = plan_columns(&cfg.replay, log)?;
        if !plan.ignored.is_empty() {
            eprintln!(
                "{}: ignoring columns not mapped to a tag: {} (map them in [replay.columns])",
                log.display(),
                plan.ignored.join(", ")
            );
        }
        if !args.no_detect {
            let missing = missing_detector_inputs(&plan, &cfg.detector);
            if !missing.is_empty() {
                anyhow::bail!(
                    "{}: no column feeds {} which the start-up detector needs (columns read: {}; \
                     map them in [replay.columns], or pass --no-detect to ingest anyway)",
                    log.display(),
                    missing.join(", "),
                    plan.mapped
                        .iter()
                        .map(|(_, col, info)| format!("{col} -> {}", info.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
        }
    }
    let mut store = Store::open_with(&cfg.storage.path, &cfg.storage.options())?;
    let mut failed = false;
    let mut reports: Vec<ReplayReport> = Vec::new();
    let mut stop_error: Option<String> = None;
    let mut time_rejected = false;
    for log in &args.logs {
        match replay_file_checked(&mut store, &cfg.replay, &cfg.quality, log, Progress::Auto) {
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
                if !args.json {
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
                if report.rows_out_of_order + report.rows_implausible_time > 0 {
                    eprintln!(
                        "{}: {} rows out of order and {} with implausible times were not stored (exit status 3)",
                        log.display(),
                        report.rows_out_of_order,
                        report.rows_implausible_time
                    );
                    time_rejected = true;
                }
                if report.rows_nonexistent_time > 0 {
                    eprintln!(
                        "{}: {} rows with local times that do not exist in replay.time_zone (the spring gap) were not stored (exit status 3)",
                        log.display(),
                        report.rows_nonexistent_time
                    );
                    time_rejected = true;
                }
                reports.push(report);
            }
            Err(ReplayError::Malformed {
                path,
                line,
                reason,
                committed,
                report,
            }) => {
                let e = ReplayError::Malformed {
                    path,
                    line,
                    reason,
                    committed,
                    report: report.clone(),
                };
                eprintln!("gtwatch: error: {e}");
                stop_error = Some(e.to_string());
                reports.push(*report);
                failed = true;
                break;
            }
            Err(e) => return Err(e).with_context(|| format!("replaying {}", log.display())),
        }
    }
    let mut detector = None;
    let mut after = None;
    if !args.no_detect {
        // The log is all the replay has: a start-up held open for its steady load
        // (`[detector] steady_extend_s`) closes at its last steady sample.
        let scan =
            crate::detect::scan_to_end(&mut store, &cfg.detector).context("start-up detection")?;
        let line = detector_line(&scan, cfg.detector.fuel_on_kg_s);
        if args.json {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
        detector = Some(scan);
        after = Some(super::diagnose_stored::diagnose_after_replay(
            &mut store,
            &args.config,
            args.json,
        )?);
    }
    if args.json {
        let out = JsonOutput {
            files: &reports,
            error: stop_error,
            detector,
            after,
        };
        let mut stdout = std::io::stdout().lock();
        serde_json::to_writer(&mut stdout, &out)?;
        writeln!(stdout)?;
    }
    Ok(if failed {
        ExitCode::FAILURE
    } else if time_rejected {
        ExitCode::from(EXIT_TIME_REJECTED)
    } else {
        ExitCode::SUCCESS
    })
}
