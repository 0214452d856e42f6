//! `gtwatch bench soak [--days N] [--tags M] [--cache-mib C] [--json]`: the reliability soak
//! (issue 12, load). Pushes N simulated days of 1 Hz data for M tags through the daemon's
//! ingest path as fast as it goes (not in real time): the scripted plant (start-ups, aborted
//! and hot restarts, trips, repeated) encoded into registers, decoded as the poll loop does,
//! sent to the single SQLite writer, the start-up detector scanning every simulated hour on
//! its own connection. Reports throughput, database size per day and resident memory
//! (VmRSS from /proc/self/status) after every simulated day, so "memory flat from day 5 to the
//! end" can be checked: `rss_growth_pct_day5_to_end`.
//!
//! `--diagnose`: at the end of every simulated day the diagnosis worker's own routine
//! (`worker::diagnose_segment`, both methods, stored as the daemon stores it) runs on that day's
//! newest pending completed start-up, on its own connection, with a small optimiser budget
//! (`--diagnose-runs`, default 40 model runs per method, said in the output: the figures are
//! about memory and the loop, not accuracy). The other start-ups of the day stay pending. Memory
//! is read after the day's diagnosis, so "flat" includes the worker. Without the flag diagnosis
//! is not in the loop (its cost is per start-up, see `bench diagnosis`).
//!
//! `--compact-after-hours H` / `--raw-days N`: the daemon's compaction task
//! (`daemon::compaction`, through the same writer) runs a round every simulated hour at the
//! simulated clock: archive what is older than H hours, roll up steady samples older than N
//! days, merge minute roll-ups older than `--rollup-1m-days` into hourly ones, vacuum. The
//! file's size per day then shows whether it stays flat once retention applies
//! (`maintenance.db_growth_mib_per_day_after_retention`, `…_after_hourly`), decomposed per day
//! (`per_day[].tiers`: hot, archive, minute and hourly roll-ups, kept start-up windows).
//! Linux only (/proc). A benchmark: never used as a test.

use super::daemon::memory_kib;
use super::ingest::IngestRig;
use crate::daemon::compaction::{CompactionReport, CompactionTask};
use crate::daemon::detector_store_options;
use crate::optim::Cancel;
use crate::plantsim::{FoulingPlant, FoulingSchedule, PlantModel, ScriptedPlant};
use crate::shutdown::{shutdown_channel, Shutdown, ShutdownTrigger};
use crate::store::{StorageConfig, Store};
use crate::worker::{diagnose_segment, DiagnosisSettings, SegmentOutcome, WorkerContext};
use anyhow::bail;
use serde::Serialize;
use std::io::Write;
use std::process::ExitCode;
use std::sync::Arc;
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
    /// The plant: `scripted` (default; the demo script, about 30 start-ups, aborts, hot
    /// restarts and trips a day, not the engine model) or `fouling` (one start-up a day on the
    /// engine model, fouling day by day, as `gtwatch demo` and `bench month`; its start-ups are
    /// ones the diagnosis can fit).
    #[arg(long, value_enum, default_value_t = SoakPlant::Scripted)]
    pub plant: SoakPlant,
    /// Diagnose one start-up per simulated day (the newest completed one) as the daemon's
    /// worker does, and include it in the memory figures.
    #[arg(long)]
    pub diagnose: bool,
    /// Model runs per method of each `--diagnose` fit (the daemon's default is 400).
    #[arg(long, default_value_t = 40)]
    pub diagnose_runs: usize,
    /// Run the daemon's compaction task every simulated hour, archiving samples older than
    /// this many simulated hours (`[storage] compact_after_hours`; 0: off).
    #[arg(long, default_value_t = 0)]
    pub compact_after_hours: u32,
    /// With it, retention (`[storage] raw_days`): steady samples older than this many simulated
    /// days rolled up into 1-minute roll-ups, start-ups kept raw; then incremental vacuum. The
    /// file's size per day shows whether it stays flat once retention applies (0: off).
    #[arg(long, default_value_t = 0)]
    pub raw_days: u32,
    /// With it, the second roll-up tier (`[storage] rollup_1m_days`): 1-minute roll-ups older
    /// than this many simulated days merged into hourly roll-ups (0: off; else > --raw-days).
    #[arg(long = "rollup-1m-days", default_value_t = 0)]
    pub rollup_1m_days: u32,
    /// Print JSON only (one document on stdout; progress goes to stderr otherwise).
    #[arg(long)]
    pub json: bool,
}

/// `--plant`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SoakPlant {
    Scripted,
    Fouling,
}

/// What `--diagnose` did over the run.
#[derive(Debug, Default, Serialize)]
struct SoakDiagnosis {
    /// Model runs per method of each fit (a small budget: memory and loop, not accuracy).
    max_model_runs: usize,
    /// Days on which a pending completed start-up was found and diagnosed.
    attempted: u64,
    /// Outcomes: results stored / stored as undiagnosable (with reasons).
    diagnosed: u64,
    undiagnosable: u64,
    /// Distinct undiagnosable reasons seen (`method: reason: detail` of the first of each).
    reasons: Vec<String>,
    /// Wall time spent in the fits, s (not counted in the ingest throughput).
    wall_seconds: f64,
}

/// The state after one simulated day.
#[derive(Debug, Serialize)]
struct DayPoint {
    day: u32,
    rss_kib: u64,
    db_mib: f64,
    samples_per_s: f64,
    /// With maintenance: samples archived and rolled up so far.
    archived: u64,
    rolled_up: u64,
    /// With maintenance: minute roll-up rows merged into hours so far.
    minutes_merged: u64,
    /// With maintenance: the file decomposed (MiB).
    tiers: Option<DayTiers>,
}

/// The file after one simulated day, by tier, MiB (pages of each table with its indexes).
#[derive(Debug, Serialize)]
struct DayTiers {
    hot_mib: f64,
    archive_mib: f64,
    /// Of the archive: blob bytes of the chunks wholly older than the raw cutoff (now −
    /// raw_days), i.e. the start-up windows kept raw forever.
    startup_windows_mib: f64,
    rollups_1m_mib: f64,
    rollups_1h_mib: f64,
    free_mib: f64,
}

/// What the compaction task did over the soak (`--compact-after-hours`, `--raw-days`).
#[derive(Debug, Serialize)]
struct SoakMaintenance {
    compact_after_hours: u32,
    raw_days: u32,
    rollup_1m_days: u32,
    /// Rounds run (one per simulated hour).
    rounds: u64,
    chunks: u64,
    samples_archived: u64,
    samples_rolled_up: u64,
    /// 1-minute roll-up rows merged into hourly roll-ups.
    minutes_merged: u64,
    vacuumed_pages: u64,
    failures: u64,
    /// Wall time spent in the rounds, s (counted in the throughput: the daemon pays it too).
    wall_seconds: f64,
    /// Growth of the file from the day after retention first applies (`raw_days` + 2) to the
    /// end, MiB per day: what keeps growing (start-ups kept raw, roll-ups, archive chunks of
    /// the not-yet-retained days).
    db_growth_mib_per_day_after_retention: Option<f64>,
    /// Growth of the file from the day after the hourly merge first applies
    /// (`rollup_1m_days` + 2) to the end, MiB per day, and of its parts over the same days:
    /// what still grows once both roll-up tiers are in steady state.
    db_growth_mib_per_day_after_hourly: Option<f64>,
    growth_after_hourly: Option<TierGrowth>,
}

/// MiB per day of each part of the file between two days.
#[derive(Debug, Serialize)]
struct TierGrowth {
    from_day: u32,
    to_day: u32,
    archive: f64,
    startup_windows: f64,
    rollups_1m: f64,
    rollups_1h: f64,
    hot: f64,
    free: f64,
}

#[derive(Debug, Serialize)]
struct SoakReport {
    bench: &'static str,
    plant: SoakPlant,
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
    /// Present with `--diagnose`.
    diagnosis: Option<SoakDiagnosis>,
    /// Present with `--compact-after-hours` or `--raw-days`.
    maintenance: Option<SoakMaintenance>,
    per_day: Vec<DayPoint>,
}

pub(crate) fn run(args: BenchSoakArgs) -> anyhow::Result<ExitCode> {
    if args.days == 0 || args.days > 3650 || args.tags == 0 || args.tags > 10_000 {
        bail!("--days must be in 1 … 3650 and --tags in 1 … 10000");
    }
    if args.diagnose && !(1..=100_000).contains(&args.diagnose_runs) {
        bail!("--diagnose-runs must be in 1 … 100000");
    }
    let storage = StorageConfig {
        compact_after_hours: args.compact_after_hours,
        raw_days: args.raw_days,
        rollup_1m_days: args.rollup_1m_days,
        ..StorageConfig::default()
    };
    if let Some(p) = storage.validate().into_iter().next() {
        bail!("{}: {} (--{})", p.key, p.message, flag_of(&p.key));
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

/// The flag setting a `[storage]` key here.
fn flag_of(key: &str) -> String {
    key.trim_start_matches("storage.").replace('_', "-")
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
    let mut plant: Box<dyn PlantModel> = match args.plant {
        SoakPlant::Scripted => Box::new(ScriptedPlant::demo(1.0)),
        // 1 s idle steps: a plain 1 Hz log, 86 400 frames a day like the scripted plant.
        SoakPlant::Fouling => Box::new(
            FoulingPlant::new(
                &crate::engine::Engine::reference()?,
                FoulingSchedule::demo(args.days as usize),
                1,
                0,
            )?
            .with_idle_step(1.0),
        ),
    };
    let rows = u64::from(args.days) * ROWS_PER_DAY;
    // The simulated span ends now, so the data looks like a recent history.
    let t_start = crate::store::now_ms() - rows as i64 * 1000;
    let mut per_day = Vec::new();
    let ctx = if args.diagnose {
        Some(Arc::new(WorkerContext::load(
            None,
            DiagnosisSettings {
                max_model_runs: args.diagnose_runs,
                ..DiagnosisSettings::default()
            },
        )?))
    } else {
        None
    };
    let mut diag = ctx.as_ref().map(|_| SoakDiagnosis {
        max_model_runs: args.diagnose_runs,
        ..SoakDiagnosis::default()
    });
    let mut worker_store: Option<Store> = None;
    let mut maint = maintenance_task(&rig, args).map(Maint::new);
    let started = Instant::now();
    for k in 0..rows {
        let frame = plant.step();
        rig.push(&frame, (k % 1000) as f64 * 1e-3, t_start + k as i64 * 1000)
            .await?;
        if (k + 1) % ROWS_PER_SCAN == 0 {
            rig.scan().await?;
            if let Some(m) = maint.as_mut() {
                m.hour(t_start + (k + 1) as i64 * 1000).await?;
            }
        }
        if (k + 1) % ROWS_PER_DAY == 0 {
            let day = ((k + 1) / ROWS_PER_DAY) as u32;
            if let (Some(ctx), Some(d)) = (&ctx, diag.as_mut()) {
                let t = Instant::now();
                let (store, outcome) =
                    diagnose_newest(worker_store.take(), &rig.db_path, Arc::clone(ctx)).await?;
                worker_store = Some(store);
                d.wall_seconds += t.elapsed().as_secs_f64();
                match outcome {
                    None => {}
                    Some(SegmentOutcome::Diagnosed { .. }) => {
                        d.attempted += 1;
                        d.diagnosed += 1;
                    }
                    Some(SegmentOutcome::Undiagnosable(f)) => {
                        d.attempted += 1;
                        d.undiagnosable += 1;
                        for r in f {
                            let key =
                                format!("{}: {}", r.method.as_deref().unwrap_or("-"), r.reason);
                            if !d.reasons.iter().any(|x| x.starts_with(&key)) {
                                d.reasons.push(format!("{key}: {}", r.detail));
                            }
                        }
                    }
                    Some(SegmentOutcome::Cancelled) => bail!("diagnosis cancelled"),
                }
            }
            let (rss, _) = memory_kib()?;
            let point = DayPoint {
                day,
                rss_kib: rss,
                db_mib: db_bytes(&rig.db_path) as f64 / MIB,
                samples_per_s: rig.samples as f64
                    / (started.elapsed().as_secs_f64()
                        - diag.as_ref().map_or(0.0, |d| d.wall_seconds))
                    .max(1e-9),
                archived: maint.as_ref().map_or(0, |m| m.report.samples),
                rolled_up: maint.as_ref().map_or(0, |m| m.report.rolled_up),
                minutes_merged: maint.as_ref().map_or(0, |m| m.report.minutes_merged),
                tiers: match &maint {
                    Some(_) => Some(day_tiers(
                        &rig.db_path,
                        t_start + (k + 1) as i64 * 1000 - i64::from(args.raw_days) * 86_400_000,
                    )?),
                    None => None,
                },
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
    // The task's writer handle would keep the writer's channel open: drop it first.
    let maintenance = maint.map(|m| m.finish(args, &per_day));
    rig.close_writer().await?;
    let wall = started.elapsed().as_secs_f64();
    // Throughput is the ingest's: the time spent in `--diagnose` fits is taken out.
    let ingest_wall = (wall - diag.as_ref().map_or(0.0, |d| d.wall_seconds)).max(1e-9);
    rig.close_detector();
    drop(worker_store);
    let (rss_after_close, hwm) = memory_kib()?;
    let rss_day5 = per_day.iter().find(|p| p.day == 5).map(|p| p.rss_kib);
    let rss_end = per_day.last().map_or(rss_after_close, |p| p.rss_kib);
    let db = db_bytes(&rig.db_path) as f64 / MIB;
    let (samples, scans, closed) = (rig.samples, rig.scans, rig.segments_closed);
    Ok(SoakReport {
        bench: "soak",
        plant: args.plant,
        days: args.days,
        tags: args.tags,
        rate_hz: 1.0,
        rows,
        samples,
        wall_seconds: wall,
        rows_per_s: rows as f64 / ingest_wall,
        samples_per_s: samples as f64 / ingest_wall,
        speed_up: rows as f64 / ingest_wall,
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
        diagnosis: diag,
        maintenance,
        per_day,
    })
}

/// The compaction task's hourly rounds at the simulated clock, and what they did.
struct Maint {
    task: CompactionTask,
    report: CompactionReport,
    rounds: u64,
    wall_seconds: f64,
    _trigger: ShutdownTrigger,
    shutdown: Shutdown,
}

impl Maint {
    fn new(task: CompactionTask) -> Maint {
        let (trigger, shutdown) = shutdown_channel();
        Maint {
            task,
            report: CompactionReport::default(),
            rounds: 0,
            wall_seconds: 0.0,
            _trigger: trigger,
            shutdown,
        }
    }

    /// The daemon's hourly round, as of the simulated `now_ms`.
    async fn hour(&mut self, now_ms: i64) -> anyhow::Result<()> {
        let t = Instant::now();
        if !self
            .task
            .round_at(now_ms, &mut self.report, &mut self.shutdown)
            .await
        {
            bail!("maintenance stopped");
        }
        self.rounds += 1;
        self.wall_seconds += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// The summary; drops the task (and with it its handle on the writer).
    fn finish(self, args: &BenchSoakArgs, per_day: &[DayPoint]) -> SoakMaintenance {
        let from = args.raw_days + 2;
        let growth = per_day
            .iter()
            .find(|p| p.day == from)
            .zip(per_day.last().filter(|l| l.day > from))
            .map(|(a, b)| (b.db_mib - a.db_mib) / f64::from(b.day - a.day));
        let hourly_from = args.rollup_1m_days + 2;
        let hourly = per_day
            .iter()
            .find(|p| p.day == hourly_from)
            .zip(per_day.last().filter(|l| l.day > hourly_from))
            .filter(|_| args.rollup_1m_days > 0);
        let parts = hourly.and_then(|(a, b)| {
            let (ta, tb) = (a.tiers.as_ref()?, b.tiers.as_ref()?);
            let d = f64::from(b.day - a.day);
            Some(TierGrowth {
                from_day: a.day,
                to_day: b.day,
                archive: (tb.archive_mib - ta.archive_mib) / d,
                startup_windows: (tb.startup_windows_mib - ta.startup_windows_mib) / d,
                rollups_1m: (tb.rollups_1m_mib - ta.rollups_1m_mib) / d,
                rollups_1h: (tb.rollups_1h_mib - ta.rollups_1h_mib) / d,
                hot: (tb.hot_mib - ta.hot_mib) / d,
                free: (tb.free_mib - ta.free_mib) / d,
            })
        });
        SoakMaintenance {
            compact_after_hours: args.compact_after_hours,
            raw_days: args.raw_days,
            rollup_1m_days: args.rollup_1m_days,
            rounds: self.rounds,
            chunks: self.report.chunks,
            samples_archived: self.report.samples,
            samples_rolled_up: self.report.rolled_up,
            minutes_merged: self.report.minutes_merged,
            vacuumed_pages: self.report.vacuumed_pages,
            failures: self.report.failures,
            wall_seconds: self.wall_seconds,
            db_growth_mib_per_day_after_retention: growth.filter(|_| args.raw_days > 0),
            db_growth_mib_per_day_after_hourly: hourly
                .map(|(a, b)| (b.db_mib - a.db_mib) / f64::from(b.day - a.day)),
            growth_after_hourly: parts,
        }
    }
}

/// The daemon's compaction task on the rig's writer, as `[storage]` with `args`' settings
/// would build it (None when both are off).
fn maintenance_task(rig: &IngestRig, args: &BenchSoakArgs) -> Option<CompactionTask> {
    let storage = StorageConfig {
        compact_after_hours: args.compact_after_hours,
        raw_days: args.raw_days,
        rollup_1m_days: args.rollup_1m_days,
        ..StorageConfig::default()
    };
    CompactionTask::from_config(rig.writer()?, &storage)
}

/// The file by tier, on a read-only connection of its own; `raw_cut_ms` splits off the
/// archive chunks of the kept start-up windows.
fn day_tiers(db: &std::path::Path, raw_cut_ms: i64) -> anyhow::Result<DayTiers> {
    const MIB: f64 = 1024.0 * 1024.0;
    let b = Store::open_readonly(db)?.tier_bytes(raw_cut_ms)?;
    let m = |v: u64| v as f64 / MIB;
    Ok(DayTiers {
        hot_mib: m(b.hot),
        archive_mib: m(b.archive),
        startup_windows_mib: m(b.archive_blobs_before),
        rollups_1m_mib: m(b.rollups_1m),
        rollups_1h_mib: m(b.rollups_1h),
        free_mib: m(b.free),
    })
}

/// On the blocking pool, with the worker's connection (opened on first use): diagnoses the
/// newest pending completed start-up and stores the outcome, as the daemon's worker does.
/// `None`: nothing pending today.
async fn diagnose_newest(
    store: Option<Store>,
    db: &std::path::Path,
    ctx: Arc<WorkerContext>,
) -> anyhow::Result<(Store, Option<SegmentOutcome>)> {
    let db = db.to_path_buf();
    tokio::task::spawn_blocking(move || -> anyhow::Result<(Store, Option<SegmentOutcome>)> {
        let mut store = match store {
            Some(s) => s,
            None => Store::open_with(
                &db,
                &detector_store_options(&StorageConfig::default().options()),
            )?,
        };
        let newest = store
            .pending_segments()?
            .into_iter()
            .rev()
            .find(|s| s.outcome == "completed");
        let Some(seg) = newest else {
            return Ok((store, None));
        };
        let outcome = diagnose_segment(&mut store, &ctx, seg.id, &Cancel::new())?;
        Ok((store, Some(outcome)))
    })
    .await?
}
