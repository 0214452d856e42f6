//! `gtwatch store …`, the storage tiers' admin commands (README "Storage tiers"):
//! - `compact --db FILE [--older-than-days N] [--max-chunk-samples N] [--vacuum]` moves old
//!   samples from the hot tier into the archive tier, one tag-chunk per transaction;
//! - `retain --db FILE [--raw-days N] [--segment-margin-s N] [--rollup-1m-days N] [--json]`
//!   runs retention once (steady samples older than `raw_days` → 1-minute roll-ups; minute
//!   roll-ups older than `rollup_1m_days` → hourly roll-ups), one batch per transaction,
//!   then returns freed pages in bounded `incremental_vacuum` steps;
//! - `stats --db FILE [--json]` prints rows, bytes and span per tier and what retention would
//!   do next (reads only);
//! - `vacuum --db FILE` rewrites the file without free pages and switches it to
//!   `auto_vacuum = INCREMENTAL` (stop the daemon first).
//!
//! `compact` and `retain` are safe to interrupt at any moment, even with `kill -9`, and safe
//! beside a running daemon (ordinary short transactions). Must not hold SQL.

use super::common::db_path;
use super::common::DataSections;
use crate::store::{
    now_ms, RetentionPolicy, StorageConfig, Store, StoreStats, TierStats, DEFAULT_MAX_CHUNK_SAMPLES,
};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Debug, clap::Subcommand)]
pub enum StoreCmd {
    /// Archive samples older than a cutoff in compressed per-tag chunks (lossless).
    Compact(CompactArgs),
    /// Roll up steady samples older than raw_days into 1-minute roll-ups (start-ups ± margin
    /// stay raw), then shrink the file if it is in incremental auto-vacuum mode.
    Retain(RetainArgs),
    /// Rows, bytes and time span per storage tier, the file's pages, and what retention
    /// would do next.
    Stats(StatsArgs),
    /// Rewrite the file without its free pages and switch it to incremental auto-vacuum (the
    /// daemon must be stopped).
    Vacuum(VacuumArgs),
}

/// Where the database and the retention policy come from.
#[derive(Debug, clap::Args)]
pub struct PolicyArgs {
    /// Config file (for [storage] path, raw_days, segment_margin_s, rollup_1m_days).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Database file (instead of --config).
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// Keep steady operation raw this many days (default: the config's [storage] raw_days,
    /// else 0 = off).
    #[arg(long)]
    pub raw_days: Option<u32>,
    /// Keep samples within this many seconds of a start-up raw forever (default: the
    /// config's [storage] segment_margin_s, else 600).
    #[arg(long)]
    pub segment_margin_s: Option<u32>,
    /// Merge 1-minute roll-ups older than this many days into hourly roll-ups (default: the
    /// config's [storage] rollup_1m_days, else 0 = keep minute roll-ups forever).
    #[arg(long = "rollup-1m-days")]
    pub rollup_1m_days: Option<u32>,
}

#[derive(Debug, clap::Args)]
pub struct RetainArgs {
    #[command(flatten)]
    pub policy: PolicyArgs,
    /// Print one JSON document.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct StatsArgs {
    #[command(flatten)]
    pub policy: PolicyArgs,
    /// Print one JSON document.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct VacuumArgs {
    /// Config file (for [storage].path).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Database file (instead of --config).
    #[arg(long)]
    pub db: Option<PathBuf>,
}

#[derive(Debug, clap::Args)]
pub struct CompactArgs {
    /// Config file (for [storage].path).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Database file (instead of --config).
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// Archive samples older than this many days (0: everything up to now, except open
    /// start-ups).
    #[arg(long, default_value_t = 1.0)]
    pub older_than_days: f64,
    /// At most this many samples per chunk.
    #[arg(long, default_value_t = DEFAULT_MAX_CHUNK_SAMPLES)]
    pub max_chunk_samples: usize,
    /// Then rewrite the file without its free pages (`VACUUM`; not beside a running daemon).
    #[arg(long)]
    pub vacuum: bool,
}

pub(super) fn run(cmd: StoreCmd) -> anyhow::Result<ExitCode> {
    match cmd {
        StoreCmd::Compact(a) => compact(&a),
        StoreCmd::Retain(a) => retain(&a),
        StoreCmd::Stats(a) => stats(&a),
        StoreCmd::Vacuum(a) => vacuum(&a),
    }
}

/// The database and the policy: the config's `[storage]` (validated) overridden by flags.
fn policy_of(args: &PolicyArgs) -> anyhow::Result<(PathBuf, RetentionPolicy)> {
    let storage = match &args.config {
        Some(cfg) => DataSections::load(cfg)?.storage,
        None => StorageConfig::default(),
    };
    let storage = StorageConfig {
        raw_days: args.raw_days.unwrap_or(storage.raw_days),
        segment_margin_s: args.segment_margin_s.unwrap_or(storage.segment_margin_s),
        rollup_1m_days: args.rollup_1m_days.unwrap_or(storage.rollup_1m_days),
        ..storage
    };
    if let Some(p) = storage.validate().into_iter().find(|p| {
        p.key == "storage.raw_days" && args.raw_days.is_some()
            || p.key == "storage.segment_margin_s" && args.segment_margin_s.is_some()
            || p.key == "storage.rollup_1m_days"
                && (args.rollup_1m_days.is_some() || args.raw_days.is_some())
    }) {
        anyhow::bail!("{}: {}", p.key, p.message);
    }
    let path = db_path(args.db.as_ref(), args.config.as_ref())?;
    Ok((path, storage.retention()))
}

fn retain(args: &RetainArgs) -> anyhow::Result<ExitCode> {
    let (path, policy) = policy_of(&args.policy)?;
    if policy.raw_days == 0 {
        anyhow::bail!(
            "storage.raw_days is 0 (keep raw samples forever): give --raw-days N or a config whose [storage] raw_days is > 0"
        );
    }
    let mut store = Store::open(&path)?;
    let started = Instant::now();
    let done = store.apply_retention(now_ms(), &policy)?;
    let retain_s = started.elapsed().as_secs_f64();
    let mut vacuumed_pages = 0u64;
    loop {
        let n = store.incremental_vacuum_step(crate::store::VACUUM_STEP_PAGES)?;
        if n == 0 {
            break;
        }
        vacuumed_pages += n;
    }
    let file = store.storage_stats(now_ms(), &policy)?.file;
    if args.json {
        let out = serde_json::json!({
            "policy": policy,
            "retained": done,
            "retain_s": retain_s,
            "vacuumed_pages": vacuumed_pages,
            "file": file,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        match done.cutoff_ms {
            Some(c) => println!("cutoff {}", crate::time::fmt_ms(c)),
            None => println!("nothing to roll up yet: the detector has not scanned this database"),
        }
        println!(
            "rolled up {} samples ({} hot, {} archived) into {} minute rows in {} transactions ({} chunks rewritten) in {retain_s:.1} s",
            done.samples_rolled_up, done.hot_deleted, done.archived_deleted, done.minutes, done.batches, done.chunks_rewritten
        );
        if let Some(h) = done.hourly_cutoff_ms {
            println!(
                "merged {} minute rows before {} into {} hourly rows in {} transactions",
                done.minutes_merged,
                crate::time::fmt_ms(h),
                done.hours,
                done.hourly_batches
            );
        }
        println!(
            "file: {} pages of {} bytes ({} free; {} returned to the file system)",
            file.page_count, file.page_size, file.free_pages, vacuumed_pages
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn stats(args: &StatsArgs) -> anyhow::Result<ExitCode> {
    let (path, policy) = policy_of(&args.policy)?;
    let store = Store::open_readonly(&path)?;
    let s = store.storage_stats(now_ms(), &policy)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        print_stats(&s);
    }
    Ok(ExitCode::SUCCESS)
}

fn tier_line(name: &str, t: &TierStats) {
    let opt = |v: Option<i64>| v.map_or_else(|| "-".to_string(), crate::time::fmt_ms);
    let bytes = t.bytes.map_or_else(|| "?".to_string(), |b| b.to_string());
    let per = t
        .bytes_per_sample
        .map_or_else(|| "-".to_string(), |b| format!("{b:.2}"));
    println!(
        "{name:<9} {:>12} {:>14} {:>14} {:>8} {:>20} {:>20}",
        t.rows,
        t.samples,
        bytes,
        per,
        opt(t.oldest_ms),
        opt(t.newest_ms)
    );
}

fn print_stats(s: &StoreStats) {
    println!(
        "{:<9} {:>12} {:>14} {:>14} {:>8} {:>20} {:>20}",
        "tier", "rows", "samples", "bytes", "B/sample", "oldest", "newest"
    );
    tier_line("hot", &s.hot);
    tier_line("archive", &s.archive);
    tier_line("rollups", &s.rollups);
    tier_line("rollups1h", &s.rollups_1h);
    println!(
        "file: {} bytes ({} pages of {}), {} free pages, auto_vacuum {}",
        s.file.file_bytes,
        s.file.page_count,
        s.file.page_size,
        s.file.free_pages,
        s.file.auto_vacuum
    );
    if s.policy.raw_days == 0 {
        println!("retention: off (raw_days 0: every raw sample is kept)");
        return;
    }
    match s.next_retention.cutoff_ms {
        None => println!(
            "retention: raw_days {}, nothing to do until the detector has scanned the data",
            s.policy.raw_days
        ),
        Some(c) => println!(
            "retention: raw_days {}, segment margin {} s; next run rolls up {} samples before {} ({} transactions)",
            s.policy.raw_days,
            s.policy.segment_margin_s,
            s.next_retention.samples,
            crate::time::fmt_ms(c),
            s.next_retention.batches
        ),
    }
    if let Some(h) = s.next_retention.hourly_cutoff_ms {
        println!(
            "hourly: rollup_1m_days {}; next run merges {} minute rows before {} into hours ({} transactions)",
            s.policy.rollup_1m_days,
            s.next_retention.minutes_to_merge,
            crate::time::fmt_ms(h),
            s.next_retention.hourly_batches
        );
    } else {
        println!("hourly: off (rollup_1m_days 0: 1-minute roll-ups are kept forever)");
    }
}

fn vacuum(args: &VacuumArgs) -> anyhow::Result<ExitCode> {
    let path = db_path(args.db.as_ref(), args.config.as_ref())?;
    let mut store = Store::open(&path)?;
    let before = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    let t = Instant::now();
    store.vacuum()?;
    let after = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    println!(
        "vacuumed in {:.1} s: {before} → {after} bytes; auto_vacuum incremental from now on",
        t.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}

fn compact(args: &CompactArgs) -> anyhow::Result<ExitCode> {
    if !(args.older_than_days >= 0.0 && args.older_than_days.is_finite()) {
        anyhow::bail!("--older-than-days must be a number ≥ 0");
    }
    let path = db_path(args.db.as_ref(), args.config.as_ref())?;
    let mut store = Store::open(&path)?;
    let before_ms = now_ms() - (args.older_than_days * 86_400_000.0) as i64;
    let started = Instant::now();
    let stats = store.compact(before_ms, args.max_chunk_samples.max(1))?;
    let compact_s = started.elapsed().as_secs_f64();
    let shrunk = store.incremental_vacuum()?;
    let vacuum_s = if args.vacuum {
        let t = Instant::now();
        store.vacuum()?;
        Some(t.elapsed().as_secs_f64())
    } else {
        None
    };
    let archive = store.archive_stats()?;
    let (used_bytes, file_bytes) = store.used_bytes()?;
    let out = serde_json::json!({
        "compacted": stats,
        "compact_s": compact_s,
        "incremental_vacuum": shrunk,
        "vacuum_s": vacuum_s,
        "archive": archive,
        "samples": store.sample_count()?,
        "used_bytes": used_bytes,
        "file_bytes": file_bytes,
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(ExitCode::SUCCESS)
}
