//! `gtwatch bench replay [--rows N] [--tags K] [--json]`: replay ingest throughput.
//!
//! Writes a synthetic CSV (N rows × K signal columns, 1 Hz, ISO 8601 times) to a temporary
//! directory, replays it into a fresh database, then replays it again to show the idempotent
//! pass (nothing new is added); reports samples/s for both. `--archive` replays straight into
//! the archive tier (`[replay] archive`). Run it from a release build.

use crate::ingest::{replay_file, Progress, ReplayConfig};
use crate::signals::Signal;
use crate::store::Store;
use crate::time::fmt_ms;
use anyhow::Context;
use serde::Serialize;
use std::io::Write;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct BenchReplayArgs {
    /// Rows in the synthetic CSV.
    #[arg(long, default_value_t = 200_000)]
    pub rows: u64,
    /// Data columns per row (1..=15, named after signals).
    #[arg(long, default_value_t = 10)]
    pub tags: usize,
    /// Replay straight into the archive tier (`[replay] archive = true`).
    #[arg(long)]
    pub archive: bool,
    /// Print JSON only.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Serialize)]
struct PassResult {
    samples_inserted: u64,
    samples_present: u64,
    elapsed_s: f64,
    samples_per_s: f64,
}

#[derive(Debug, Serialize)]
struct BenchResult {
    bench: &'static str,
    rows: u64,
    tags: usize,
    archive: bool,
    samples: u64,
    csv_bytes: u64,
    db_bytes: u64,
    first: PassResult,
    second_idempotent: PassResult,
    integrity_check: String,
}

fn pass(r: &crate::ingest::ReplayReport) -> PassResult {
    PassResult {
        samples_inserted: r.samples_inserted,
        samples_present: r.samples_present,
        elapsed_s: r.elapsed_s,
        samples_per_s: r.samples_per_s(),
    }
}

/// Writes the synthetic log: a slow sine on every column so values differ row to row.
pub(crate) fn write_synthetic_csv(
    path: &std::path::Path,
    rows: u64,
    tags: usize,
) -> anyhow::Result<()> {
    let f = std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
    let sigs = &Signal::ALL[..tags];
    write!(w, "time")?;
    for s in sigs {
        write!(w, ",{}", s.column())?;
    }
    writeln!(w)?;
    let t0 = 1_700_000_000_000i64;
    for i in 0..rows {
        write!(w, "{}", fmt_ms(t0 + i as i64 * 1000))?;
        for (k, _) in sigs.iter().enumerate() {
            let v = 100.0 * (k + 1) as f64 + ((i as f64) * 0.01 + k as f64).sin();
            write!(w, ",{v:.4}")?;
        }
        writeln!(w)?;
    }
    w.flush()?;
    Ok(())
}

pub(crate) fn run(args: BenchReplayArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!((1..=15).contains(&args.tags), "--tags must be 1..=15");
    let dir = tempfile_dir()?;
    let csv = dir.join("bench.csv");
    let db = dir.join("bench.db");
    write_synthetic_csv(&csv, args.rows, args.tags)?;
    let cfg = ReplayConfig {
        archive: args.archive,
        ..ReplayConfig::default()
    };
    let mut store = Store::open(&db)?;
    let first = replay_file(&mut store, &cfg, &csv, Progress::Silent)?;
    let second = replay_file(&mut store, &cfg, &csv, Progress::Silent)?;
    let integrity = store.integrity_check()?;
    drop(store);
    let size = |p: &std::path::Path| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
    let result = BenchResult {
        bench: "replay",
        rows: args.rows,
        tags: args.tags,
        archive: args.archive,
        samples: args.rows * args.tags as u64,
        csv_bytes: size(&csv),
        db_bytes: size(&db),
        first: pass(&first),
        second_idempotent: pass(&second),
        integrity_check: integrity,
    };
    let _ = std::fs::remove_dir_all(&dir);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&result)?);
    } else {
        println!(
            "replay: {} samples in {:.2} s = {:.0} samples/s; idempotent re-run {:.0} samples/s ({} new)",
            result.samples,
            result.first.elapsed_s,
            result.first.samples_per_s,
            result.second_idempotent.samples_per_s,
            result.second_idempotent.samples_inserted
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// A fresh directory under the system temp dir (removed at the end of the run).
fn tempfile_dir() -> anyhow::Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!(
        "gtwatch-bench-replay-{}-{}",
        std::process::id(),
        crate::store::now_ms()
    ));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}
