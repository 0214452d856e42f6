//! `gtwatch bench month [--days N] [--seed S] [--threads N] [--keep DIR] [--json]`: a month of plant data
//! through the product the way a plant engineer replays a historian export.
//!
//! Writes a 1 Hz CSV log of the fouling plant (one start-up a day, noise and sensor lags, an
//! offline wash midway; `time` column in ISO 8601, the shipped `[replay]` defaults) as one
//! file a day, then replays the days in order with the shipped configuration into a fresh
//! database, timing each day's ingest (the rate must not fall as the database grows): start-up
//! detection, diagnosis of every start-up (Method B and A), wash advice. Reports the time of
//! each stage and every Method B result against the implanted truth. Then compacts the whole
//! month into the archive tier (`Store::compact`) and reports the bytes per stored sample
//! before and after, and the compaction time (README "Storage tiers"). Release build only.

use crate::detect::{scan, DetectorConfig};
use crate::engine::Engine;
use crate::health::HEALTH_NAMES;
use crate::ingest::{replay_file, Progress, ReplayConfig};
use crate::plantsim::fouling::{day_of, DAY_S};
use crate::plantsim::{FoulingPlant, FoulingSchedule, PlantModel};
use crate::signals::Signal;
use crate::store::{HistoryFilter, StorageConfig, Store};
use crate::time::fmt_ms;
use anyhow::Context;
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Debug, clap::Args)]
pub struct BenchMonthArgs {
    /// Plant days (one start-up each).
    #[arg(long, default_value_t = 30)]
    pub days: usize,
    /// Seed of the sensor noise and the diagnosis.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Keep the log, config and database in DIR (default: a temporary directory).
    #[arg(long)]
    pub keep: Option<PathBuf>,
    /// `[diagnosis] threads` of the replay's configuration: cores the diagnosis of the backlog
    /// uses (default: the shipped configuration's, 1).
    #[arg(long)]
    pub threads: Option<usize>,
    /// After compaction, apply retention as `[storage] raw_days = N` would once the month is
    /// N days old (steady samples older than N days before the log's end rolled up into
    /// 1-minute roll-ups, start-ups kept raw), vacuum, and report the file then.
    #[arg(long)]
    pub raw_days: Option<u32>,
    /// Replay straight into the archive tier (`[replay] archive = true`) instead of hot rows
    /// and a compaction afterwards.
    #[arg(long)]
    pub archive: bool,
    /// Print JSON only.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Serialize)]
struct DayResult {
    day: usize,
    start_utc: String,
    /// |estimate − truth| over the six parameters, points.
    max_abs_error: f64,
    /// (estimate − truth)/σ per parameter, in `HEALTH_NAMES` order: whether the reported σ
    /// says how far off an estimate may be.
    z: [f64; 6],
    d_gc: f64,
    d_gc_truth: f64,
}

#[derive(Debug, Serialize)]
struct MonthResult {
    bench: &'static str,
    days: usize,
    /// `[diagnosis] threads` of the replay.
    diagnosis_threads: usize,
    /// Replayed straight into the archive tier (`--archive`).
    archive_ingest: bool,
    rows: u64,
    samples_inserted: u64,
    /// Rows the replay refused (malformed, out of order, implausible or nonexistent times):
    /// 0 unless the plant log is wrong.
    rows_refused: u64,
    csv_bytes: u64,
    db_bytes: u64,
    generate_s: f64,
    ingest_s: f64,
    /// Samples stored per second over the whole replay, millions.
    ingest_msps: f64,
    /// The first, the last and the slowest day's rate, millions of samples per second.
    ingest_first_day_msps: f64,
    ingest_last_day_msps: f64,
    ingest_slowest_day_msps: f64,
    detect_s: f64,
    diagnose_s: f64,
    startups_found: usize,
    method_b_results: usize,
    max_abs_error: f64,
    /// The reported σ against the actual errors, over every day's six parameters: the RMS of
    /// (estimate − truth)/σ (1 for an honest σ) and the share within 2σ (0.95).
    z_rms: f64,
    within_two_sigma: f64,
    storage: StorageResult,
    /// With `--raw-days`: what retention did after compaction, and the file then.
    retention: Option<RetentionResult>,
    per_day: Vec<DayResult>,
    ingest_per_day: Vec<DayIngest>,
}

/// The replay of one day's log.
#[derive(Debug, Serialize)]
struct DayIngest {
    day: usize,
    samples_inserted: u64,
    elapsed_s: f64,
    /// Millions of samples stored per second.
    msps: f64,
}

/// The replay of every day's log, in order.
struct Ingest {
    days: Vec<DayIngest>,
    samples_inserted: u64,
    rows_refused: u64,
    elapsed_s: f64,
}

impl Ingest {
    fn msps(&self) -> f64 {
        self.samples_inserted as f64 / self.elapsed_s.max(1e-9) / 1e6
    }
}

/// Replays `logs` (one per day, in order) into `store` as `gtwatch replay` would, one after
/// the other, timing each.
/// RMS of the finite (estimate − truth)/σ over all days and parameters, and the share of them
/// within 2 (NaN, NaN without any).
fn z_stats(days: &[DayResult]) -> (f64, f64) {
    let z: Vec<f64> = days
        .iter()
        .flat_map(|d| d.z)
        .filter(|v| v.is_finite())
        .collect();
    if z.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let n = z.len() as f64;
    let rms = (z.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    let within = z.iter().filter(|v| v.abs() <= 2.0).count() as f64 / n;
    (rms, within)
}

fn ingest_days(store: &mut Store, cfg: &ReplayConfig, logs: &[PathBuf]) -> anyhow::Result<Ingest> {
    let mut out = Ingest {
        days: Vec::with_capacity(logs.len()),
        samples_inserted: 0,
        rows_refused: 0,
        elapsed_s: 0.0,
    };
    for (day, log) in logs.iter().enumerate() {
        let rep = replay_file(store, cfg, log, Progress::Silent)?;
        out.samples_inserted += rep.samples_inserted;
        out.rows_refused += rep.rows_malformed
            + rep.rows_out_of_order
            + rep.rows_implausible_time
            + rep.rows_nonexistent_time;
        out.elapsed_s += rep.elapsed_s;
        out.days.push(DayIngest {
            day,
            samples_inserted: rep.samples_inserted,
            elapsed_s: rep.elapsed_s,
            msps: rep.samples_inserted as f64 / rep.elapsed_s.max(1e-9) / 1e6,
        });
    }
    Ok(out)
}

/// Retention applied to the compacted month (`--raw-days`).
#[derive(Debug, Serialize)]
struct RetentionResult {
    raw_days: u32,
    segment_margin_s: u32,
    stats: crate::store::RetainStats,
    retain_s: f64,
    /// The file's size after retention and `VACUUM`, and per sample the month stored.
    file_bytes: u64,
    file_bytes_per_sample: f64,
    /// Samples still stored raw (hot and archive tiers).
    samples_raw: i64,
}

/// Applies retention to everything older than `raw_days` before `end_ms`, then vacuums.
fn retain_and_measure(
    store: &mut Store,
    end_ms: i64,
    policy: crate::store::RetentionPolicy,
    samples_stored: i64,
) -> anyhow::Result<RetentionResult> {
    let t = Instant::now();
    let stats = store.apply_retention(end_ms, &policy)?;
    let retain_s = t.elapsed().as_secs_f64();
    store.vacuum()?;
    let file_bytes = store.used_bytes()?.1;
    Ok(RetentionResult {
        raw_days: policy.raw_days,
        segment_margin_s: policy.segment_margin_s,
        stats,
        retain_s,
        file_bytes,
        file_bytes_per_sample: file_bytes as f64 / samples_stored.max(1) as f64,
        samples_raw: store.sample_count()?,
    })
}

/// The database's size per stored sample before and after compacting the month.
#[derive(Debug, Serialize)]
struct StorageResult {
    samples: i64,
    /// Pages in use (page count − free pages) × page size, per sample, after the replay.
    bytes_per_sample_hot: f64,
    compact_s: f64,
    chunks: u64,
    samples_archived: u64,
    /// The chunks' blobs alone, per archived sample.
    blob_bytes_per_sample: f64,
    /// Pages in use per sample after compaction (the freed pages are reused by new rows).
    bytes_per_sample_compacted: f64,
    vacuum_s: f64,
    /// The file's size after `VACUUM`, per sample.
    file_bytes_per_sample_vacuumed: f64,
    /// Every sample read back from both tiers equals the one stored before, bit for bit.
    read_back_identical: bool,
}

/// A digest of every sample of every tag as the store reads it (both tiers: tag, time, value
/// bits, quality, in the store's order), and how many: read one tag and one day at a time, so
/// a year (450 M samples) is compared without holding it in memory.
fn samples_digest(store: &Store) -> anyhow::Result<(u64, u64)> {
    const DAY_MS: i64 = 86_400_000;
    // FNV-1a over the fields' bytes: order-sensitive, so a moved or changed sample shows.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut n = 0u64;
    let mut eat = |x: u64| {
        for b in x.to_le_bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    };
    for t in store.tags()? {
        let (Some(first), Some(last)) = store.tag_time_range(t.id)? else {
            continue;
        };
        let mut from = first;
        while from <= last {
            let to = from.saturating_add(DAY_MS);
            for s in store.tag_samples_between(t.id, from, to - 1)? {
                eat(t.id as u64);
                eat(s.t_ms as u64);
                eat(s.value.to_bits());
                eat(s.quality as u64);
                n += 1;
            }
            from = to;
        }
    }
    Ok((h, n))
}

/// Compacts everything before `before_ms`, then vacuums, measuring each step.
fn compact_and_measure(store: &mut Store, before_ms: i64) -> anyhow::Result<StorageResult> {
    let before = samples_digest(store)?;
    let samples = store.sample_count()?;
    let per = |bytes: u64| bytes as f64 / samples.max(1) as f64;
    let hot = store.used_bytes()?.0;
    let t = Instant::now();
    let c = store.compact(before_ms, crate::store::DEFAULT_MAX_CHUNK_SAMPLES)?;
    let compact_s = t.elapsed().as_secs_f64();
    let compacted = store.used_bytes()?.0;
    let t = Instant::now();
    store.vacuum()?;
    let vacuum_s = t.elapsed().as_secs_f64();
    let vacuumed = store.used_bytes()?.1;
    let after = samples_digest(store)?;
    Ok(StorageResult {
        samples,
        bytes_per_sample_hot: per(hot),
        compact_s,
        chunks: c.chunks,
        samples_archived: c.samples,
        blob_bytes_per_sample: c.blob_bytes as f64 / c.samples.max(1) as f64,
        bytes_per_sample_compacted: per(compacted),
        vacuum_s,
        file_bytes_per_sample_vacuumed: per(vacuumed),
        read_back_identical: before == after,
    })
}

/// The sections of the configuration file the month's replay reads, as the command line
/// loads and checks them.
pub(crate) struct Sections {
    pub(crate) storage: StorageConfig,
    pub(crate) replay: ReplayConfig,
    pub(crate) detector: DetectorConfig,
}

/// What the month borrows from the command line, so that it runs exactly what `gtwatch
/// replay` runs: loading a configuration file's sections, and diagnosing every pending
/// start-up after a replay (then the gap analyses the configuration asks for).
pub(crate) struct Commands<'a> {
    pub(crate) load_sections: &'a dyn Fn(&Path) -> anyhow::Result<Sections>,
    pub(crate) diagnose_after_replay:
        &'a dyn Fn(&mut Store, &Path) -> anyhow::Result<crate::worker::gap::AfterReplay>,
    /// The wash advice as `gtwatch wash advise` refreshes and shows it.
    pub(crate) advise: &'a dyn Fn(&mut Store, &Path) -> anyhow::Result<crate::advice::AdviceReport>,
}

/// The columns a plant log carries: every signal the plant records (the surge margin is the
/// model's, not an instrument's).
pub(crate) fn log_columns() -> Vec<Signal> {
    Signal::ALL
        .iter()
        .copied()
        .filter(|s| *s != Signal::SurgeMargin)
        .collect()
}

/// A new plant log at `path` with its header (`time` and `cols`' column names) written.
pub(crate) fn create_log(
    path: &Path,
    cols: &[Signal],
) -> anyhow::Result<std::io::BufWriter<std::fs::File>> {
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
    );
    write!(w, "time")?;
    for s in cols {
        write!(w, ",{}", s.column())?;
    }
    writeln!(w)?;
    Ok(w)
}

/// Writes the plant's 1 Hz log up to `end_s` into `dir`, one file a day (`month-dNNNN.csv`,
/// each with its header). Returns the files in order and the rows written.
fn write_daily_logs(
    mut plant: FoulingPlant,
    dir: &Path,
    epoch_ms: i64,
    end_s: f64,
) -> anyhow::Result<(Vec<PathBuf>, u64)> {
    let cols = log_columns();
    let mut rows = 0u64;
    let mut logs: Vec<PathBuf> = Vec::new();
    let mut w: Option<std::io::BufWriter<std::fs::File>> = None;
    loop {
        let f = plant.step();
        if f.t_s >= end_s {
            break;
        }
        // A new file when the plant's day passes the files written (the first frame too).
        let day = (f.t_s / DAY_S).floor().max(0.0) as usize;
        if day >= logs.len() {
            if let Some(mut old) = w.take() {
                old.flush()?;
            }
            let path = dir.join(format!("month-d{day:04}.csv"));
            w = Some(create_log(&path, &cols)?);
            logs.push(path);
        }
        let Some(out) = w.as_mut() else {
            anyhow::bail!("no open log file");
        };
        write!(
            out,
            "{}",
            fmt_ms(epoch_ms + (f.t_s * 1000.0).round() as i64)
        )?;
        for s in &cols {
            write!(out, ",{:.4}", f.get(*s))?;
        }
        writeln!(out)?;
        rows += 1;
    }
    if let Some(mut last) = w.take() {
        last.flush()?;
    }
    Ok((logs, rows))
}

pub(crate) fn run(a: BenchMonthArgs, commands: &Commands) -> anyhow::Result<ExitCode> {
    let dir = a.keep.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("gtwatch-bench-month-{}", std::process::id()))
    });
    std::fs::create_dir_all(&dir)?;
    let db = dir.join("month.db");
    for suffix in ["", "-wal", "-shm"] {
        let _ = std::fs::remove_file(dir.join(format!("month.db{suffix}")));
    }
    // Day 0 is 2016-01-04T00:00:00Z, so that even ten simulated years end before today's clock:
    // the replay refuses time stamps in the future (`replay.max_future_s`), and a bench whose
    // end depended on the date it runs would not be repeatable.
    let epoch_ms: i64 = 1_451_865_600_000;
    let engine = Engine::reference()?;
    // A month keeps the demo's schedule (one wash midway: its figures stay comparable); longer
    // runs wash every 30 days, as a plant would, so that health stays in a real engine's range.
    let schedule = if a.days <= 60 {
        FoulingSchedule::demo(a.days)
    } else {
        FoulingSchedule::periodic(a.days)
    };

    // 1. The log, one file a day as historians export it: the replay of each is timed, so the
    //    ingest rate is seen day by day as the database grows.
    let t = Instant::now();
    let plant = FoulingPlant::new(&engine, schedule.clone(), a.seed, epoch_ms)?.with_idle_step(1.0);
    let end_s = a.days as f64 * DAY_S;
    let (logs, rows) = write_daily_logs(plant, &dir, epoch_ms, end_s)?;
    let generate_s = t.elapsed().as_secs_f64();

    // 2. The shipped configuration, pointed at this database.
    let shipped = include_str!("../../config/gtwatch.toml");
    let mut cfg_text = shipped.replacen(
        "path = \"/var/lib/gtwatch/gtwatch.db\"",
        &format!("path = \"{}\"", db.display()),
        1,
    );
    if let Some(n) = a.threads {
        // The shipped file sets the key once, in `[diagnosis]`.
        anyhow::ensure!(
            cfg_text.matches("\nthreads = 1\n").count() == 1,
            "the shipped configuration no longer sets `threads = 1` once"
        );
        cfg_text = cfg_text.replacen("\nthreads = 1\n", &format!("\nthreads = {n}\n"), 1);
    }
    let cfg_path = dir.join("gtwatch.toml");
    std::fs::write(&cfg_path, cfg_text)?;
    let sections = (commands.load_sections)(&cfg_path)?;
    let mut store = Store::open_with(&db, &sections.storage.options())?;

    // 3. Ingest, detect, diagnose: what `gtwatch replay` does, timed per stage.
    let replay_cfg = ReplayConfig {
        archive: a.archive || sections.replay.archive,
        ..sections.replay.clone()
    };
    let ingest = ingest_days(&mut store, &replay_cfg, &logs)?;
    let t = Instant::now();
    let s = scan(&mut store, &sections.detector).context("start-up detection")?;
    let detect_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    (commands.diagnose_after_replay)(&mut store, &cfg_path)?;
    let diagnose_s = t.elapsed().as_secs_f64();
    let _ = s;
    let end_ms = epoch_ms + (end_s * 1000.0) as i64;
    let storage = compact_and_measure(&mut store, end_ms)?;
    let retention = match a.raw_days {
        None => None,
        Some(raw_days) => {
            let policy = crate::store::RetentionPolicy {
                raw_days,
                ..sections.storage.retention()
            };
            Some(retain_and_measure(
                &mut store,
                end_ms,
                policy,
                storage.samples,
            )?)
        }
    };

    // 4. Results against the truth.
    let segments = crate::query::list_segments(&store, None)?;
    let history = store.history(&HistoryFilter {
        method: Some("B".into()),
        ..HistoryFilter::default()
    })?;
    let mut per_day = Vec::new();
    for h in &history {
        let Some(day) = day_of(h.start_ms, epoch_ms) else {
            continue;
        };
        let truth = schedule.health_on(day).to_array();
        let err = HEALTH_NAMES
            .iter()
            .enumerate()
            .map(|(i, n)| (h.health.get(*n).copied().unwrap_or(f64::NAN) - truth[i]).abs())
            .fold(0.0f64, f64::max);
        let z = std::array::from_fn(|i| {
            let n = HEALTH_NAMES[i];
            let e = h.health.get(n).copied().unwrap_or(f64::NAN) - truth[i];
            e / h.sigma.get(n).copied().unwrap_or(f64::NAN)
        });
        per_day.push(DayResult {
            day,
            start_utc: h.start_utc.clone(),
            max_abs_error: err,
            z,
            d_gc: h.health.get("D_GC").copied().unwrap_or(f64::NAN),
            d_gc_truth: truth[0],
        });
    }
    let (z_rms, within_two_sigma) = z_stats(&per_day);
    let result = MonthResult {
        bench: "month",
        days: a.days,
        diagnosis_threads: a.threads.unwrap_or(1),
        archive_ingest: replay_cfg.archive,
        rows,
        samples_inserted: ingest.samples_inserted,
        rows_refused: ingest.rows_refused,
        csv_bytes: logs
            .iter()
            .map(|l| std::fs::metadata(l).map(|m| m.len()).unwrap_or(0))
            .sum(),
        db_bytes: std::fs::metadata(&db).map(|m| m.len()).unwrap_or(0),
        generate_s,
        ingest_s: ingest.elapsed_s,
        ingest_msps: ingest.msps(),
        ingest_first_day_msps: ingest.days.first().map_or(0.0, |d| d.msps),
        ingest_last_day_msps: ingest.days.last().map_or(0.0, |d| d.msps),
        ingest_slowest_day_msps: ingest
            .days
            .iter()
            .map(|d| d.msps)
            .fold(f64::INFINITY, f64::min),
        detect_s,
        diagnose_s,
        startups_found: segments.len(),
        method_b_results: history.len(),
        max_abs_error: per_day.iter().map(|d| d.max_abs_error).fold(0.0, f64::max),
        z_rms,
        within_two_sigma,
        storage,
        retention,
        per_day,
        ingest_per_day: ingest.days,
    };
    drop(store);
    if a.keep.is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    }
    let mut out = std::io::stdout().lock();
    if a.json {
        serde_json::to_writer(&mut out, &result)?;
        writeln!(out)?;
    } else {
        serde_json::to_writer_pretty(&mut out, &result)?;
        writeln!(out)?;
    }
    Ok(ExitCode::SUCCESS)
}
