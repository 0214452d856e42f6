//! `gtwatch bench soak [--days N] [--tags M] [--cache-mib C] [--json]`: the reliability soak
//! (issue 12, load). Pushes N simulated days of 1 Hz data for M tags through the daemon's
//! ingest path as fast as it goes (not in real time): the scripted plant (start-ups, aborted
//! and hot restarts, trips, repeated) encoded into registers, decoded as the poll loop does,
//! sent to the single SQLite writer, the start-up detector scanning every simulated hour on
//! its own connection. Reports throughput, database size per day and resident memory
//! (VmRSS from /proc/self/status) after every simulated day, so "memory flat from day 5 to the
//! end" can be checked: `rss_growth_pct_day5_to_end`.
//!
//! Diagnosis is not part of the soak (its cost is per start-up, see `bench diagnosis`).
//! Linux only (/proc). A benchmark: never used as a test.

use super::bench_daemon::memory_kib;
use super::bench_ingest::IngestRig;
use crate::plantsim::{PlantModel, ScriptedPlant};
use anyhow::bail;
use serde::Serialize;
use std::io::Write;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Debug, clap::Args)]
pub struct BenchSoakArgs {
    /// Simulated days of 1 Hz data.
    #[arg(long, default_value_t = 30)]
    pub days: u32,
    /// Number of tags (f32 each; the first 12 feed the engine signals).
    #[arg(long, default_value_t = 50)]
    pub tags: usize,
    /// SQLite page cache of the writer, MiB (as `[storage].cache_mib`).
    #[arg(long, default_value_t = 16)]
    pub cache_mib: u32,
    /// Print JSON only (one document on stdout; progress goes to stderr otherwise).
    #[arg(long)]
    pub json: bool,
}

/// The state after one simulated day.
#[derive(Debug, Serialize)]
struct DayPoint {
    day: u32,
    rss_kib: u64,
    db_mib: f64,
    samples_per_s: f64,
}

#[derive(Debug, Serialize)]
struct SoakReport {
    bench: &'static str,
    days: u32,
    tags: usize,
    rate_hz: f64,
    /// Polls (rows of `tags` samples) pushed.
    rows: u64,
    samples: u64,
    wall_seconds: f64,
    rows_per_s: f64,
    samples_per_s: f64,
    /// Simulated time over wall time (1 Hz rows per second).
    speed_up: f64,
    detector_scans: u64,
    segments_closed: u64,
    /// Resident memory after day 5 (null for fewer than 5 days) and after the last day, KiB,
    /// both measured in the same state (running, just after a detector scan).
    rss_kib_day5: Option<u64>,
    rss_kib_end: u64,
    /// Resident memory once the writer and the detector connection are closed, KiB.
    rss_kib_after_close: u64,
    /// (end − day 5) / day 5, percent: the soak criterion is < 5.
    rss_growth_pct_day5_to_end: Option<f64>,
    /// Peak resident memory (VmHWM), KiB.
    hwm_kib: u64,
    /// Database plus WAL at the end, MiB, and per simulated day.
    db_mib: f64,
    db_mib_per_day: f64,
    cache_mib: u32,
    per_day: Vec<DayPoint>,
}

pub fn run(args: BenchSoakArgs) -> anyhow::Result<ExitCode> {
    if args.days == 0 || args.days > 3650 || args.tags == 0 || args.tags > 10_000 {
        bail!("--days must be in 1 … 3650 and --tags in 1 … 10000");
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let report = rt.block_on(soak(&args))?;
    let mut out = std::io::stdout().lock();
    if args.json {
        serde_json::to_writer(&mut out, &report)?;
    } else {
        serde_json::to_writer_pretty(&mut out, &report)?;
    }
    writeln!(out)?;
    Ok(ExitCode::SUCCESS)
}

fn db_bytes(path: &std::path::Path) -> u64 {
    ["", "-wal"]
        .iter()
        .map(|suffix| {
            let mut p = path.as_os_str().to_owned();
            p.push(suffix);
            std::fs::metadata(std::path::PathBuf::from(p))
                .map(|m| m.len())
                .unwrap_or(0)
        })
        .sum()
}

async fn soak(args: &BenchSoakArgs) -> anyhow::Result<SoakReport> {
    const MIB: f64 = 1024.0 * 1024.0;
    const ROWS_PER_DAY: u64 = 86_400;
    const ROWS_PER_SCAN: u64 = 3_600;
    let mut rig = IngestRig::new(args.tags, args.cache_mib, "soak.db")?;
    let mut plant = ScriptedPlant::demo(1.0);
    let rows = u64::from(args.days) * ROWS_PER_DAY;
    // The simulated span ends now, so the data looks like a recent history.
    let t_start = crate::store::now_ms() - rows as i64 * 1000;
    let mut per_day = Vec::new();
    let started = Instant::now();
    for k in 0..rows {
        let frame = plant.step();
        rig.push(&frame, (k % 1000) as f64 * 1e-3, t_start + k as i64 * 1000)
            .await?;
        if (k + 1) % ROWS_PER_SCAN == 0 {
            rig.scan().await?;
        }
        if (k + 1) % ROWS_PER_DAY == 0 {
            let day = ((k + 1) / ROWS_PER_DAY) as u32;
            let (rss, _) = memory_kib()?;
            let point = DayPoint {
                day,
                rss_kib: rss,
                db_mib: db_bytes(&rig.db_path) as f64 / MIB,
                samples_per_s: rig.samples as f64 / started.elapsed().as_secs_f64(),
            };
            if !args.json {
                eprintln!(
                    "day {day}: rss {} KiB, db {:.1} MiB, {:.0} samples/s",
                    point.rss_kib, point.db_mib, point.samples_per_s
                );
            }
            per_day.push(point);
        }
    }
    rig.close_writer().await?;
    let wall = started.elapsed().as_secs_f64();
    rig.close_detector();
    let (rss_after_close, hwm) = memory_kib()?;
    let rss_day5 = per_day.iter().find(|p| p.day == 5).map(|p| p.rss_kib);
    let rss_end = per_day.last().map_or(rss_after_close, |p| p.rss_kib);
    let db = db_bytes(&rig.db_path) as f64 / MIB;
    let (samples, scans, closed) = (rig.samples, rig.scans, rig.segments_closed);
    Ok(SoakReport {
        bench: "soak",
        days: args.days,
        tags: args.tags,
        rate_hz: 1.0,
        rows,
        samples,
        wall_seconds: wall,
        rows_per_s: rows as f64 / wall,
        samples_per_s: samples as f64 / wall,
        speed_up: rows as f64 / wall,
        detector_scans: scans,
        segments_closed: closed,
        rss_kib_day5: rss_day5,
        rss_kib_end: rss_end,
        rss_kib_after_close: rss_after_close,
        rss_growth_pct_day5_to_end: rss_day5
            .map(|d5| (rss_end as f64 - d5 as f64) / d5 as f64 * 100.0),
        hwm_kib: hwm,
        db_mib: db,
        db_mib_per_day: db / f64::from(args.days),
        cache_mib: args.cache_mib,
        per_day,
    })
}
