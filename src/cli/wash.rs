//! `gtwatch wash record|advise|confirm|reject`: the operator's wash log and the advice.
//!
//! `advise` recomputes the trends and the advice from the stored history (recording washes the
//! trend detects and the new recommendation) and explains it in plain words, or prints one JSON
//! document with `--format json`. The arithmetic is `crate::advice` / `trend` / `wash`.
//!
//! These commands write while the daemon may be running: each write is one short transaction
//! (`record` and `confirm` one statement, `reject` its check and delete together, `advise` all
//! it found at once), which waits for the daemon's writer to finish its current commit instead
//! of failing with "database is locked". Must not hold wash or trend arithmetic of its own or
//! keep a transaction open across anything slow.

use super::common::{db_path, parse_cli_time, FormatArgs};
use super::diagnose_stored::{wash_economics, worker_context};
use crate::query::Format;
use crate::store::Store;
use crate::time::fmt_ms_rfc3339;
use crate::trend::WashDetection;
use anyhow::{bail, Context};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct WashArgs {
    #[command(subcommand)]
    pub cmd: WashCmd,
}

/// Where the database and the engine come from.
#[derive(Debug, Clone, clap::Args)]
pub struct DbArgs {
    /// Config file ([storage].path, [plant] engine_model, [wash] prices).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Database file (instead of --config's).
    #[arg(long)]
    pub db: Option<PathBuf>,
}

#[derive(Debug, clap::Subcommand)]
pub enum WashCmd {
    /// Record a wash done on the unit.
    Record {
        #[command(flatten)]
        db: DbArgs,
        /// When (2024-03-01, 2024-03-01T06:00:00Z, @EPOCH_S).
        #[arg(long)]
        at: String,
        #[arg(long, value_enum)]
        kind: WashKind,
        /// Free text.
        #[arg(long, default_value = "")]
        note: String,
    },
    /// Confirm a wash the trend detected.
    Confirm {
        #[command(flatten)]
        db: DbArgs,
        id: i64,
    },
    /// Reject (delete) a wash the trend detected.
    Reject {
        #[command(flatten)]
        db: DbArgs,
        id: i64,
    },
    /// Recompute trends and advise the next offline wash.
    Advise {
        #[command(flatten)]
        db: DbArgs,
        #[command(flatten)]
        output: FormatArgs,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum WashKind {
    Online,
    Offline,
}

fn open(db: &DbArgs) -> anyhow::Result<Store> {
    let path = db_path(db.db.as_ref(), db.config.as_ref())?;
    if !path.is_file() {
        bail!("database {} does not exist", path.display());
    }
    Store::open(&path).with_context(|| format!("opening {}", path.display()))
}

/// Runs `gtwatch wash …`.
pub(super) fn run(a: WashArgs) -> anyhow::Result<ExitCode> {
    match a.cmd {
        WashCmd::Record { db, at, kind, note } => {
            let t = parse_cli_time(&at)?;
            let mut store = open(&db)?;
            let kind = match kind {
                WashKind::Online => "online",
                WashKind::Offline => "offline",
            };
            let id = store.record_wash(t, kind, &note)?;
            println!("wash {id} recorded: {kind} at {}", fmt_ms_rfc3339(t));
        }
        WashCmd::Confirm { db, id } => {
            if !open(&db)?.confirm_wash(id)? {
                bail!("wash {id} is not a detected wash awaiting confirmation");
            }
            println!("wash {id} confirmed");
        }
        WashCmd::Reject { db, id } => match open(&db)?.reject_detected_wash(id)? {
            Some(w) if w.is_detected() => println!("detected wash {id} rejected"),
            Some(_) => bail!("wash {id} was recorded by an operator, not detected"),
            None => bail!("no wash {id}"),
        },
        WashCmd::Advise { db, output } => {
            let format = output.format();
            let ctx = worker_context(db.config.as_deref())?;
            let econ = wash_economics(db.config.as_deref())?;
            let mut store = open(&db)?;
            let r = crate::advice::refresh(
                &mut store,
                &ctx.engine,
                &econ,
                &WashDetection::default(),
                &ctx.settings.bounds(),
            )?;
            match format {
                Format::Json => println!("{}", serde_json::to_string_pretty(&r)?),
                _ => {
                    println!(
                        "last wash: {}; {} Method B results since",
                        r.last_wash_ms
                            .map_or("none recorded".into(), fmt_ms_rfc3339),
                        r.results_since_wash
                    );
                    for a in &r.set_aside {
                        println!(
                            "set aside: start-up {} at {} (its gap analysis explains it by an instrument error: {})",
                            a.segment_id,
                            fmt_ms_rfc3339(a.start_ms),
                            a.effect
                        );
                    }
                    for p in &r.poor_fits {
                        println!(
                            "left out: start-up {} at {} (its fit is poor: the model does not describe it, so its health is not the engine's{})",
                            p.segment_id,
                            fmt_ms_rfc3339(p.start_ms),
                            p.gap_verdict
                                .as_deref()
                                .map_or(String::new(), |v| format!("; gap analysis: {v}"))
                        );
                    }
                    for step in &r.steps {
                        println!("{}", crate::advice::step_line(step));
                    }
                    for id in &r.washes_explained {
                        println!("detected wash {id} is the instrument's step, not a wash: reject it with `gtwatch wash reject {id}`");
                    }
                    for id in &r.detected_now {
                        println!("detected a wash (id {id}): confirm or reject it with `gtwatch wash confirm|reject {id}`");
                    }
                    println!(
                        "{:<6} {:>12} {:>12} {:>10}",
                        "param", "rate %/day", "±1σ", "now %"
                    );
                    for t in &r.trends {
                        match &t.fit {
                            Some(f) => {
                                let age = r
                                    .as_of_ms
                                    .zip(r.origin_ms)
                                    .map_or(f.t_ref_days, |(n, o)| (n - o) as f64 / 86_400_000.0);
                                println!(
                                    "{:<6} {:>12.4} {:>12.4} {:>10.2}",
                                    t.param,
                                    f.rate_per_day,
                                    f.rate_sigma_per_day,
                                    f.value_at(age)
                                )
                            }
                            None => println!(
                                "{:<6} {}",
                                t.param,
                                t.reason.as_deref().unwrap_or("no trend")
                            ),
                        }
                    }
                    match (&r.advice, r.advised_ms) {
                        (Some(a), Some(ms)) => {
                            println!("\nnext offline wash: {}", fmt_ms_rfc3339(ms));
                            println!("{}", a.summary);
                        }
                        (Some(a), None) => println!("\n{}", a.summary),
                        _ => println!("\nno advice yet: D_GC and D_EC need at least 3 results since the last wash"),
                    }
                }
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
