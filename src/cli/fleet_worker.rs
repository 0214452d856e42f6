//! `gtwatch fleet rediagnose` (queue one re-diagnosis job, and with `--gap` one gap-analysis
//! job, per start-up stored at the centre, with an engine file and `[diagnosis]` settings; or
//! with `--retry-failed` put failed jobs back) and `gtwatch fleet worker` (claim and run jobs
//! until stopped, `--max-jobs` or, with `--idle-exit`, an empty queue).
//!
//! The centre's URL comes from `--postgres-url` or the environment variable
//! `GTWATCH_POSTGRES_URL` (a Kubernetes Secret, a systemd credential file read into the
//! environment), so it need not appear in a process list. Must not hold SQL or diagnosis logic
//! (`crate::fleet::rediagnose`, `crate::worker::fleet`).

use super::common::parse_cli_time;
use super::diagnose_stored::worker_context;
use crate::fleet::rediagnose::{
    enqueue, queue_by_kind, retry_failed, EnqueueRequest, JobKind, QueueByKind, RetryFilter,
};
use crate::fleet::Centre;
use crate::optim::Cancel;
use crate::worker::fleet::{default_worker_id, run_fleet_worker, FleetWorkerOptions};
use crate::worker::WorkerContext;
use anyhow::{bail, Context};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// The environment variable read when `--postgres-url` is not given.
pub const URL_ENV: &str = "GTWATCH_POSTGRES_URL";

#[derive(Debug, clap::Args)]
pub struct RediagnoseArgs {
    /// Central database (default: $GTWATCH_POSTGRES_URL).
    #[arg(long)]
    pub postgres_url: Option<String>,
    /// Only this unit (repeat for several; default every unit).
    #[arg(long = "unit")]
    pub units: Vec<String>,
    /// Only start-ups beginning at or after this time (ISO 8601, UTC unless an offset is given).
    #[arg(long, conflicts_with = "retry_failed")]
    pub since: Option<String>,
    /// Engine file (default: the config's `[plant] engine_model`, else the built-in engine).
    #[arg(long, conflicts_with = "retry_failed")]
    pub engine: Option<PathBuf>,
    /// Config file whose `[diagnosis]` settings (and `[plant] engine_model`) the jobs use
    /// (default: the default settings).
    #[arg(long, conflicts_with = "retry_failed")]
    pub config: Option<PathBuf>,
    /// Also queue one gap-analysis job per start-up: the edge's own analysis (as its daemon
    /// runs it: every candidate effect, blocked cross-validation), stored in `regap_analyses`.
    #[arg(long, conflicts_with = "retry_failed")]
    pub gap: bool,
    /// Queue nothing: put the failed jobs (of --unit, of --config-hash) back to pending, their
    /// attempts kept and their error cleared, and report how many.
    #[arg(long)]
    pub retry_failed: bool,
    /// With --retry-failed: only the jobs of this engine/config hash.
    #[arg(long, requires = "retry_failed")]
    pub config_hash: Option<String>,
    /// Print one JSON document.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct WorkerArgs {
    /// Central database (default: $GTWATCH_POSTGRES_URL).
    #[arg(long)]
    pub postgres_url: Option<String>,
    /// Lease of a claimed job, seconds; renewed every third of it while the fit runs. A killed
    /// worker's job is claimable again this long after its last renewal.
    #[arg(long, default_value_t = 60)]
    pub lease_s: u64,
    /// Stop after this many jobs.
    #[arg(long)]
    pub max_jobs: Option<u64>,
    /// Exit once no job is pending (none waiting, none leased by another worker).
    #[arg(long)]
    pub idle_exit: bool,
    /// This worker's id in the queue (default host:pid).
    #[arg(long)]
    pub worker_id: Option<String>,
    /// Threads of each fit (results do not depend on it).
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Wait between looks at an empty queue, ms.
    #[arg(long, default_value_t = 2000)]
    pub poll_ms: u64,
    /// Print the worker's report as one JSON document at the end.
    #[arg(long)]
    pub json: bool,
}

fn url(given: Option<&String>) -> anyhow::Result<String> {
    match given {
        Some(u) => Ok(u.clone()),
        None => std::env::var(URL_ENV)
            .ok()
            .filter(|u| !u.is_empty())
            .with_context(|| format!("give --postgres-url URL or set {URL_ENV}")),
    }
}

pub(super) fn run_rediagnose(args: &RediagnoseArgs) -> anyhow::Result<ExitCode> {
    let url = url(args.postgres_url.as_ref())?;
    for u in &args.units {
        crate::fleet::check_unit_id(u).map_err(|why| anyhow::anyhow!("--unit {why}"))?;
    }
    if args.retry_failed {
        return run_retry(args, &url);
    }
    let since_ms = args.since.as_deref().map(parse_cli_time).transpose()?;
    let base = worker_context(args.config.as_deref())?;
    let (ctx, engine_name) = match &args.engine {
        Some(e) => (
            WorkerContext::load(Some(e), base.settings.clone())?,
            e.display().to_string(),
        ),
        None => {
            let name = if base.engine_text == crate::engine::config::REFERENCE_ENGINE_TOML {
                "<built-in reference engine>".to_string()
            } else {
                "[plant] engine_model of the config".to_string()
            };
            (base, name)
        }
    };
    let req = EnqueueRequest {
        units: args.units.clone(),
        since_ms,
        config_hash: ctx.config_hash.clone(),
        engine_name,
        engine_toml: ctx.engine_text.clone(),
        settings_json: serde_json::to_string(&ctx.settings)?,
        kind: JobKind::Diagnose,
    };
    let mut centre = Centre::connect(&url, Duration::from_secs(30))?;
    let report = enqueue(&mut centre, &req)?;
    let gap_report = if args.gap {
        let gap_req = EnqueueRequest {
            kind: JobKind::Gap,
            ..req.clone()
        };
        Some(enqueue(&mut centre, &gap_req)?)
    } else {
        None
    };
    let queue = queue_by_kind(&mut centre, Some(req.config_hash.as_str()))?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "centre": centre.name,
                "enqueue": report,
                "gap_enqueue": gap_report,
                "queue": queue.diagnose,
                "gap_queue": queue.gap,
            }))?
        );
    } else {
        println!(
            "{} job(s) enqueued for config hash {} ({} start-up(s) with their samples at the \
             centre, {} already queued, {} without a complete window)",
            report.enqueued,
            report.config_hash,
            report.startups,
            report.already_queued,
            report.without_window
        );
        if let Some(g) = &gap_report {
            println!(
                "{} gap-analysis job(s) enqueued ({} already queued)",
                g.enqueued, g.already_queued
            );
        }
        print_queue("queue for this hash", &queue);
    }
    Ok(ExitCode::SUCCESS)
}

/// The jobs per state, diagnoses and gap analyses.
fn print_queue(title: &str, q: &QueueByKind) {
    let (queue, gap) = (&q.diagnose, &q.gap);
    println!(
        "{title}: {} waiting, {} leased, {} done, {} failed; gap analyses {} waiting, {} \
         leased, {} done, {} failed",
        queue.waiting,
        queue.leased,
        queue.done,
        queue.failed,
        gap.waiting,
        gap.leased,
        gap.done,
        gap.failed
    );
}

/// `--retry-failed`: the failed jobs of `--unit`/`--config-hash` back to pending.
fn run_retry(args: &RediagnoseArgs, url: &str) -> anyhow::Result<ExitCode> {
    let filter = RetryFilter {
        units: args.units.clone(),
        config_hash: args.config_hash.clone(),
    };
    let mut centre = Centre::connect(url, Duration::from_secs(30))?;
    let retried = retry_failed(&mut centre, &filter)?;
    let hash = filter.config_hash.as_deref();
    let queue = queue_by_kind(&mut centre, hash)?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "centre": centre.name,
                "retried": retried,
                "config_hash": filter.config_hash,
                "units": filter.units,
                "queue": queue.diagnose,
                "gap_queue": queue.gap,
            }))?
        );
    } else {
        println!("{retried} failed job(s) put back to pending");
        let title = match hash {
            Some(h) => format!("queue for config hash {h}"),
            None => "queue".to_string(),
        };
        print_queue(&title, &queue);
    }
    Ok(ExitCode::SUCCESS)
}

/// Sets `stop` on the first SIGTERM or SIGINT (a thread of its own with a small runtime).
fn stop_on_signal(stop: &Cancel) {
    let stop = stop.clone();
    std::thread::spawn(move || {
        let rt = match tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
        {
            Ok(rt) => rt,
            Err(e) => {
                tracing::error!("cannot listen for signals: {e}");
                return;
            }
        };
        rt.block_on(async {
            use tokio::signal::unix::{signal, SignalKind};
            let (Ok(mut term), Ok(mut int)) = (
                signal(SignalKind::terminate()),
                signal(SignalKind::interrupt()),
            ) else {
                tracing::error!("cannot listen for signals");
                return;
            };
            tokio::select! {
                _ = term.recv() => tracing::info!("SIGTERM received: the current job is given back"),
                _ = int.recv() => tracing::info!("SIGINT received: the current job is given back"),
            }
            stop.cancel();
        });
    });
}

pub(super) fn run_worker(args: &WorkerArgs) -> anyhow::Result<ExitCode> {
    let url = url(args.postgres_url.as_ref())?;
    if args.lease_s == 0 || args.threads == 0 {
        bail!("--lease-s and --threads must be at least 1");
    }
    let opts = FleetWorkerOptions {
        postgres_url: url,
        worker_id: args.worker_id.clone().unwrap_or_else(default_worker_id),
        lease: Duration::from_secs(args.lease_s),
        max_jobs: args.max_jobs,
        idle_exit: args.idle_exit,
        poll: Duration::from_millis(args.poll_ms.max(10)),
        threads: args.threads,
        timeout: Duration::from_secs(30),
    };
    let stop = Cancel::new();
    stop_on_signal(&stop);
    let report = run_fleet_worker(&opts, &stop)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "worker {}: {} job(s) done ({} undiagnosable, {} gap analyses), {} failed, {} lost, \
             {:.1} s fitting in {:.1} s",
            report.worker_id,
            report.done,
            report.undiagnosable,
            report.gap_done,
            report.failed,
            report.lost,
            report.fit_s,
            report.wall_s
        );
    }
    Ok(ExitCode::SUCCESS)
}
