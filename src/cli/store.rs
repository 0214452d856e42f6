//! `gtwatch store compact --db FILE [--older-than-days N] [--max-chunk-samples N] [--vacuum]`:
//! moves old samples from the hot tier into the archive tier (README "Storage tiers").
//! One tag-chunk per transaction: safe to interrupt at any moment, even with `kill -9`.

use super::common::db_path;
use crate::store::{now_ms, Store, DEFAULT_MAX_CHUNK_SAMPLES};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Debug, clap::Subcommand)]
pub enum StoreCmd {
    /// Archive samples older than a cutoff in compressed per-tag chunks (lossless).
    Compact(CompactArgs),
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
    }
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
