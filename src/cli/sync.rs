//! `gtwatch sync` (one fleet sync of this unit's database to the central PostgreSQL) and
//! `gtwatch fleet status` (the units at a centre, their last sync and rows per table);
//! `gtwatch fleet history` is in `fleet_history`, `fleet rediagnose` and `fleet worker` in
//! `fleet_worker`.
//! Must not hold SQL or decide what is sent (`crate::fleet` does).

use crate::config::Config;
use crate::fleet::rediagnose::{queue_by_kind, QueueByKind};
use crate::fleet::{fleet_status, sync_once, Centre, FleetConfig, SyncReport, UnitStatus};
use crate::store::Store;
use anyhow::{bail, Context};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

#[derive(Debug, clap::Args)]
pub struct SyncArgs {
    /// Config file: its `[fleet]` section and `[storage].path`.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Database file (instead of --config; needs --unit and --postgres-url).
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// This unit's id in the fleet (overrides `fleet.unit_id`).
    #[arg(long)]
    pub unit: Option<String>,
    /// Central database (overrides `fleet.postgres_url`).
    #[arg(long)]
    pub postgres_url: Option<String>,
    /// Rows per batch (overrides `fleet.batch_rows`, default 5000).
    #[arg(long)]
    pub batch_rows: Option<usize>,
    /// Do not send start-up samples.
    #[arg(long)]
    pub no_samples: bool,
    /// Print one JSON document.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Subcommand)]
pub enum FleetCmd {
    /// The units at a centre: last sync and rows per table; the re-diagnosis queue per kind
    /// and state.
    Status(StatusArgs),
    /// Every unit's health results at the centre (as `history` shows one unit's).
    History(super::fleet_history::FleetHistoryArgs),
    /// One self-contained HTML page: units ranked by fouling rate, washes due, every trend.
    Report(super::fleet_history::FleetReportArgs),
    /// Queue a re-diagnosis (and with --gap a gap analysis) of every start-up stored at the
    /// centre (one job per unit, start-up, engine/config hash and kind; queuing again adds
    /// nothing), or with --retry-failed put failed jobs back.
    Rediagnose(super::fleet_worker::RediagnoseArgs),
    /// Claim queued re-diagnosis and gap-analysis jobs under a lease and run them (any number
    /// of workers).
    Worker(super::fleet_worker::WorkerArgs),
}

#[derive(Debug, clap::Args)]
pub struct StatusArgs {
    /// Central database, e.g. postgresql://gtwatch:secret@127.0.0.1:5432/fleet.
    #[arg(long)]
    pub postgres_url: String,
    /// Print one JSON document.
    #[arg(long)]
    pub json: bool,
}

/// The database and `[fleet]` settings the arguments name.
fn settings(args: &SyncArgs) -> anyhow::Result<(PathBuf, FleetConfig)> {
    let (db, fleet) = match &args.config {
        Some(path) => {
            let cfg = Config::load(path)?;
            (args.db.clone().unwrap_or(cfg.storage.path), cfg.fleet)
        }
        None => match &args.db {
            Some(db) => (db.clone(), None),
            None => bail!("give --config FILE, or --db FILE --unit ID --postgres-url URL"),
        },
    };
    let mut fleet = match (fleet, &args.unit, &args.postgres_url) {
        (Some(f), _, _) => f,
        (None, Some(u), Some(url)) => FleetConfig::new(u, url),
        (None, _, _) => bail!(
            "no [fleet] section in the config: give --unit ID and --postgres-url URL, or add [fleet]"
        ),
    };
    if let Some(u) = &args.unit {
        fleet.unit_id.clone_from(u);
    }
    if let Some(url) = &args.postgres_url {
        fleet.postgres_url.clone_from(url);
    }
    if let Some(n) = args.batch_rows {
        fleet.batch_rows = n;
    }
    if args.no_samples {
        fleet.send_samples = false;
    }
    let problems = fleet.validate();
    if !problems.is_empty() {
        let list: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
        bail!("{}", list.join("; "));
    }
    Ok((db, fleet))
}

pub(super) fn run_sync(args: &SyncArgs) -> anyhow::Result<ExitCode> {
    let (db, fleet) = settings(args)?;
    let mut store =
        Store::open(&db).with_context(|| format!("opening the database {}", db.display()))?;
    let mut centre = Centre::connect(&fleet.postgres_url, Duration::from_secs(fleet.timeout_s))?;
    // The same connection reads the rows and writes the marks: a store the command owns.
    let read = Store::open_readonly(&db)?;
    let report = sync_once(
        &read,
        &mut store,
        &mut centre,
        &fleet,
        &AtomicBool::new(false),
    )?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_report(&report);
    }
    Ok(ExitCode::SUCCESS)
}

fn print_report(r: &SyncReport) {
    println!("unit {} → {} (centre {})", r.unit_id, r.centre, r.centre_id);
    println!(
        "{:<22} {:>10} {:>10} {:>8} {:>8}",
        "table", "sent", "new", "batches", "removed"
    );
    for s in &r.streams {
        println!(
            "{:<22} {:>10} {:>10} {:>8} {:>8}",
            s.table, s.sent, s.applied, s.batches, s.removed
        );
    }
    println!("{} rows sent in {:.2} s", r.total_sent(), r.wall_s);
}

pub(super) fn run_fleet(cmd: &FleetCmd) -> anyhow::Result<ExitCode> {
    match cmd {
        FleetCmd::History(a) => super::fleet_history::run(a),
        FleetCmd::Report(a) => super::fleet_history::run_report(a),
        FleetCmd::Rediagnose(a) => super::fleet_worker::run_rediagnose(a),
        FleetCmd::Worker(a) => super::fleet_worker::run_worker(a),
        FleetCmd::Status(a) => {
            let mut centre = Centre::connect_existing(&a.postgres_url, Duration::from_secs(30))?;
            let units = fleet_status(&mut centre)?;
            let queue = rediagnosis_queue(&mut centre)?;
            if a.json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&serde_json::json!({
                        "centre": centre.name,
                        "centre_id": centre.id,
                        "units": units,
                        "rediagnosis": queue,
                    }))?
                );
            } else {
                print_status(&units);
                if let Some(q) = &queue {
                    print_queue(q);
                }
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// The queue's jobs per kind and state (all hashes), `None` on a centre older than the gap
/// jobs, which this read-only connection does not upgrade.
fn rediagnosis_queue(centre: &mut Centre) -> anyhow::Result<Option<QueueByKind>> {
    if !centre.has_gap_jobs()? {
        return Ok(None);
    }
    Ok(Some(queue_by_kind(centre, None)?))
}

fn print_queue(q: &QueueByKind) {
    for (kind, c) in [("diagnose", &q.diagnose), ("gap", &q.gap)] {
        println!(
            "re-diagnosis jobs ({kind}): {} waiting, {} leased, {} done, {} failed",
            c.waiting, c.leased, c.done, c.failed
        );
    }
}

fn print_status(units: &[UnitStatus]) {
    let Some(first) = units.first() else {
        println!("no units have synced to this centre yet");
        return;
    };
    let mut head = format!("{:<20} {:<24}", "unit", "last sync (UTC)");
    for (t, _) in &first.counts {
        head.push_str(&format!(" {t:>15}"));
    }
    println!("{head}");
    for u in units {
        let mut line = format!(
            "{:<20} {:<24}",
            u.unit_id,
            crate::time::fmt_ms_rfc3339(u.last_sync_ms)
        );
        for (_, n) in &u.counts {
            line.push_str(&format!(" {n:>15}"));
        }
        println!("{line}");
    }
}
