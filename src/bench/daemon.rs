//! `gtwatch bench daemon`: CPU and memory of the monitoring daemon, printed as JSON.
//!
//! Two modes:
//! - live (default): an in-process plant-sim serves `--tags` f32 tags; the real daemon
//!   (`daemon::run`: poll loop, writer, detector) polls it at `--rate-hz` for `--seconds`.
//!   CPU is the process's utime+stime delta (from /proc/self/stat) over wall time, as percent
//!   of one core — an upper bound for the daemon, since the simulator runs in the same process.
//! - `--day`: pushes `--hours` (default 24) of `--tags` × `--rate-hz` samples through the
//!   daemon's ingest path (decode → writer channel → SQLite writer, detector scans every
//!   simulated hour) as fast as it goes, then reports resident memory.
//!
//! With `--diagnose-startups N` (live mode) N simulated start-ups are stored first and the
//! diagnosis worker fits them while the daemon polls; the report's `jitter` is the spacing of
//! the stored n1 time stamps minus the poll period (always reported). `store_lock_waits` is how
//! often any connection of the process waited for a database lock while the daemon ran (the
//! one-writer daemon should never wait: `store::lock_waits`), `channel_full_waits` how often a
//! sender waited for room in the writer's channel. With `--readers` (live mode) the real
//! `gtwatch diagnose --segment` and `gtwatch report` run as separate processes against the live
//! database from half-way through the measurement; their exit status, wall time and any "database is locked"
//! are reported under `readers`.
//!
//! Memory is VmRSS / VmHWM from /proc/self/status. Linux only. Must not be used as a test.

use super::ingest::IngestRig;
use crate::acquire::modbus::PollProgress;
use crate::acquire::register_map::{
    ByteOrder, DataType, FieldSpec, ModbusConfig, RegisterKind, RequestSpec,
};
use crate::config::{Config, DaemonConfig, PlantConfig};
use crate::daemon::{self, RunOptions};
use crate::detect::{self, DetectorConfig};
use crate::plantsim::{spawn_plant_sim, PlantModel, ScriptedPlant, SimOptions};
use crate::shutdown::shutdown_channel;
use crate::signals::Signal;
use crate::store::{StorageConfig, Store, TagInfo};
use anyhow::{bail, Context};
use serde::Serialize;
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Debug, clap::Args)]
pub struct BenchDaemonArgs {
    /// Number of tags (f32 each; the first 12 feed the engine signals).
    #[arg(long, default_value_t = 50)]
    pub tags: usize,
    /// Poll rate, Hz.
    #[arg(long, default_value_t = 10.0)]
    pub rate_hz: f64,
    /// Live mode: measured duration, s (after a 3 s warm-up).
    #[arg(long, default_value_t = 30)]
    pub seconds: u64,
    /// Push a simulated span of data through the ingest path at full speed instead.
    #[arg(long)]
    pub day: bool,
    /// `--day` mode: simulated hours.
    #[arg(long, default_value_t = 24.0)]
    pub hours: f64,
    /// SQLite page cache, MiB (as `[storage].cache_mib`).
    #[arg(long, default_value_t = 16)]
    pub cache_mib: u32,
    /// Print JSON only.
    #[arg(long)]
    pub json: bool,
    /// Live mode: store this many simulated start-ups first, so the diagnosis worker fits them
    /// (one after the other) while the daemon polls; reports the poll jitter.
    #[arg(long, default_value_t = 0)]
    pub diagnose_startups: usize,
    /// Live mode: meanwhile run `gtwatch diagnose --segment` (with --diagnose-startups) and
    /// `gtwatch report` against the live database, as separate processes.
    #[arg(long)]
    pub readers: bool,
    /// Live mode: the daemon's background gap analysis also runs on every n-th diagnosed
    /// start-up (`[diagnosis] gap_every_n`; 0: only on fits that are not good).
    #[arg(long, default_value_t = 0)]
    pub gap_every: u32,
    /// Live mode: store this many days of old 1 Hz samples (14 tags, ending two days ago)
    /// first, and run the compaction task with `compact_after_hours = 24` and `raw_days = 1`
    /// from 1 s after the start, every 5 s: the jitter is then measured while the daemon
    /// archives, rolls up and vacuums them (0: off; the daemon's default timing, nothing to do
    /// within a run).
    #[arg(long, default_value_t = 0)]
    pub maintain_days: u32,
}

/// Process CPU time (user + system), s. /proc/self/stat fields 14 and 15, in USER_HZ (100 on
/// every Linux architecture's user-space ABI).
fn cpu_seconds() -> anyhow::Result<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").context("/proc/self/stat")?;
    // The command name (field 2) may contain spaces: split after its closing parenthesis.
    let rest = stat
        .rsplit_once(')')
        .map(|(_, r)| r)
        .context("malformed /proc/self/stat")?;
    let f: Vec<&str> = rest.split_whitespace().collect();
    // `rest` starts at field 3 (state); utime is field 14, stime 15.
    let utime: f64 = f.get(11).context("utime")?.parse()?;
    let stime: f64 = f.get(12).context("stime")?.parse()?;
    Ok((utime + stime) / 100.0)
}

/// (VmRSS, VmHWM) in KiB.
pub(super) fn memory_kib() -> anyhow::Result<(u64, u64)> {
    let status = std::fs::read_to_string("/proc/self/status").context("/proc/self/status")?;
    let get = |key: &str| -> anyhow::Result<u64> {
        let line = status
            .lines()
            .find(|l| l.starts_with(key))
            .with_context(|| format!("{key} missing"))?;
        Ok(line.split_whitespace().nth(1).context("value")?.parse()?)
    };
    Ok((get("VmRSS:")?, get("VmHWM:")?))
}

/// A register map of `tags` f32 fields in holding-register requests of ≤ 60 fields.
pub(crate) fn bench_map(tags: usize, endpoint: &str) -> ModbusConfig {
    const SIGNALS: [Signal; 12] = [
        Signal::N1,
        Signal::N2,
        Signal::T1,
        Signal::P1,
        Signal::T2,
        Signal::P2,
        Signal::T34,
        Signal::P34,
        Signal::T4,
        Signal::P4,
        Signal::FuelFlow,
        Signal::Power,
    ];
    let mut requests = Vec::new();
    for chunk_start in (0..tags).step_by(60) {
        let start_address = (chunk_start * 2) as u32;
        let fields = (chunk_start..tags.min(chunk_start + 60))
            .map(|i| {
                let signal = SIGNALS.get(i).copied();
                FieldSpec {
                    name: signal.map_or_else(|| format!("x{i:03}"), |s| s.column().to_string()),
                    address: (i * 2) as u32,
                    data_type: DataType::F32,
                    byte_order: ByteOrder::ABCD,
                    scale: 1.0,
                    offset: 0.0,
                    unit: String::new(),
                    signal,
                    min: Some(-1.0e6),
                    max: Some(1.0e6),
                }
            })
            .collect();
        requests.push(RequestSpec {
            slave_id: 1,
            register: RegisterKind::Holding,
            start_address,
            count: None,
            fields,
        });
    }
    ModbusConfig {
        endpoint: endpoint.to_string(),
        requests,
    }
}

#[derive(Debug, Serialize)]
struct LiveReport {
    mode: &'static str,
    tags: usize,
    rate_hz: f64,
    seconds: f64,
    cpu_seconds: f64,
    cpu_percent_of_one_core: f64,
    rss_kib: u64,
    hwm_kib: u64,
    polls_ok: u64,
    poll_failures: u64,
    samples: u64,
    samples_per_s: f64,
    /// Start-ups diagnosed during the run (with `--diagnose-startups`).
    diagnosed: u64,
    /// Background gap analyses stored / yielded (cancelled) during the run.
    gap_stored: u64,
    gap_cancelled: u64,
    /// Poll jitter: spacing of the stored n1 time stamps minus the poll period, ms.
    jitter: Jitter,
    /// Database locks any connection of this process waited for while the daemon ran.
    store_lock_waits: u64,
    /// Time spent waiting for them, ms.
    store_lock_waited_ms: u64,
    /// Times a sender waited for room in the writer's channel.
    channel_full_waits: u64,
    /// Write requests the writer carried out (scans, outcomes, advice) and how many failed.
    writer_requests: u64,
    writer_request_errors: u64,
    /// With `--readers`: the read-only commands run against the live database.
    readers: Vec<ReaderRun>,
    /// With `--maintain-days`: what the compaction task did during the run.
    maintenance: Option<LiveMaintenance>,
    note: &'static str,
}

/// The compaction task's work during a live run (`--maintain-days`).
#[derive(Debug, Serialize)]
struct LiveMaintenance {
    days_prefilled: u32,
    samples_prefilled: u64,
    chunks: u64,
    samples_archived: u64,
    samples_rolled_up: u64,
    vacuumed_pages: u64,
    failures: u64,
}

/// One read-only command run beside the daemon (`--readers`).
#[derive(Debug, Serialize)]
struct ReaderRun {
    command: String,
    success: bool,
    wall_s: f64,
    /// Whether its output mentions "database is locked".
    locked: bool,
    /// The first line it printed (what it did).
    first_line: String,
}

/// Starts the read-only commands against the live database `db` (see `--readers`), each
/// watched by a task that reports how it went once it exits.
fn start_readers(
    db: &std::path::Path,
    out: &std::path::Path,
    segment: Option<i64>,
) -> anyhow::Result<Vec<tokio::task::JoinHandle<anyhow::Result<ReaderRun>>>> {
    let exe = std::env::current_exe().context("the gtwatch binary")?;
    let mut runs: Vec<Vec<String>> = Vec::new();
    if let Some(id) = segment {
        runs.push(vec!["diagnose".into(), "--segment".into(), id.to_string()]);
    }
    runs.push(vec![
        "report".into(),
        "--out".into(),
        out.display().to_string(),
    ]);
    runs.into_iter()
        .map(|args| {
            let command = args.join(" ");
            let t0 = Instant::now();
            let child = tokio::process::Command::new(&exe)
                .args(&args)
                .arg("--db")
                .arg(db)
                .stdin(std::process::Stdio::null())
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .kill_on_drop(true)
                .spawn()
                .with_context(|| format!("starting gtwatch {command}"))?;
            Ok(tokio::spawn(reader_run(command, t0, child)))
        })
        .collect()
}

/// Waits for one read-only command and reports how it went.
async fn reader_run(
    command: String,
    t0: Instant,
    child: tokio::process::Child,
) -> anyhow::Result<ReaderRun> {
    let out = child.wait_with_output().await?;
    let wall_s = t0.elapsed().as_secs_f64();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if !out.status.success() {
        tracing::warn!(%command, "read-only command failed: {}", text.trim());
    }
    Ok(ReaderRun {
        command,
        success: out.status.success(),
        wall_s,
        locked: text.contains("database is locked"),
        first_line: text
            .lines()
            .next()
            .unwrap_or_default()
            .chars()
            .take(160)
            .collect(),
    })
}

/// The reports of the read-only commands (each waited for).
async fn finish_readers(
    started: Vec<tokio::task::JoinHandle<anyhow::Result<ReaderRun>>>,
) -> anyhow::Result<Vec<ReaderRun>> {
    let mut runs = Vec::new();
    for h in started {
        runs.push(h.await??);
    }
    Ok(runs)
}

#[derive(Debug, Default, Serialize)]
struct Jitter {
    intervals: usize,
    period_ms: u64,
    mean_abs_ms: f64,
    p99_abs_ms: f64,
    max_abs_ms: f64,
    /// Intervals longer than twice the period (a missed poll).
    over_2x_period: usize,
}

/// The tags of every engine signal in `store` (created where missing), in `Signal::ALL`'s order.
fn signal_tag_ids(store: &mut Store) -> anyhow::Result<Vec<i64>> {
    Ok(Signal::ALL
        .iter()
        .map(|s| store.ensure_tag(&TagInfo::for_signal(*s)))
        .collect::<Result<Vec<_>, _>>()?)
}

/// Stores `n` noisy simulated start-ups (one a day, in 2023) and detects them.
fn prefill_startups(
    path: &std::path::Path,
    n: usize,
    opts: &crate::store::StoreOptions,
) -> anyhow::Result<()> {
    use crate::engine::sensors::MeasurementOptions;
    use crate::engine::{Engine, Scenario, Trace};
    use crate::quality::Quality;
    use crate::store::Sample;
    let engine = Engine::reference()?;
    let h = crate::health::HealthParams {
        D_GC: 2.0,
        D_EC: 0.7,
        D_GT: 0.5,
        D_ET: 0.4,
        D_GP: 0.3,
        D_EP: 0.3,
    };
    let (samples, _) = crate::engine::simulation::run_scenario(
        &engine.model(&h),
        &Scenario::startup(engine.cfg()),
    )?;
    let mut store = Store::open_with(path, opts)?;
    let ids = signal_tag_ids(&mut store)?;
    for day in 0..n {
        let o = MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed: 100 + day as u64,
        };
        let t = Trace::from_truth(&engine, &samples, Some(&o));
        let mut batch = Vec::new();
        for k in 0..t.len() {
            let t_ms =
                1_700_000_000_000 + day as i64 * 86_400_000 + (t.t_s[k] * 1000.0).round() as i64;
            for (i, sig) in Signal::ALL.iter().enumerate() {
                let v = t.measured[k][sig.index()];
                if v.is_finite() {
                    batch.push(Sample {
                        tag: ids[i],
                        t_ms,
                        value: v,
                        quality: Quality::Good,
                    });
                }
            }
        }
        store.insert_samples(&batch)?;
    }
    detect::scan(&mut store, &DetectorConfig::default())?;
    Ok(())
}

/// Stores `days` days of 1 Hz steady samples for the engine signals' tags, ending two days
/// before now (old enough to be archived and rolled up), and returns how many.
fn prefill_old_days(
    path: &std::path::Path,
    days: u32,
    opts: &crate::store::StoreOptions,
) -> anyhow::Result<u64> {
    use crate::quality::Quality;
    use crate::store::Sample;
    let mut store = Store::open_with(path, opts)?;
    let ids = signal_tag_ids(&mut store)?;
    let seconds = i64::from(days) * 86_400;
    let t0 = crate::store::now_ms() - (seconds + 2 * 86_400) * 1000;
    let mut total = 0u64;
    for hour in 0..seconds / 3600 {
        let mut batch = Vec::with_capacity(3600 * ids.len());
        for k in hour * 3600..(hour + 1) * 3600 {
            for (i, id) in ids.iter().enumerate() {
                // A slow swing and a little quantised noise: steady operation, not constants.
                let noise = ((k * 7919 + i as i64 * 104_729) % 13) as f64 * 0.01;
                let value = 100.0 * (i + 1) as f64 + (k as f64 / 900.0).sin() + noise;
                batch.push(Sample {
                    tag: *id,
                    t_ms: t0 + k * 1000,
                    value: f64::from(value as f32),
                    quality: Quality::Good,
                });
            }
        }
        total += batch.len() as u64;
        store.insert_samples(&batch)?;
    }
    Ok(total)
}

/// Jitter of the stored n1 time stamps at or after `from_ms`.
fn poll_jitter(path: &std::path::Path, from_ms: i64, period_ms: u64) -> anyhow::Result<Jitter> {
    let store = crate::store::Store::open_readonly(path)?;
    let tag = store.tag_by_name("n1_rpm")?.id;
    let ts: Vec<i64> = store
        .tag_samples_between(tag, from_ms, i64::MAX)?
        .into_iter()
        .map(|s| s.t_ms)
        .collect();
    let mut dev: Vec<f64> = ts
        .windows(2)
        .map(|w| ((w[1] - w[0]) as f64 - period_ms as f64).abs())
        .collect();
    if dev.is_empty() {
        return Ok(Jitter {
            period_ms,
            ..Jitter::default()
        });
    }
    let over = ts
        .windows(2)
        .filter(|w| w[1] - w[0] > 2 * period_ms as i64)
        .count();
    let mean = dev.iter().sum::<f64>() / dev.len() as f64;
    dev.sort_by(f64::total_cmp);
    let p99 = dev[((dev.len() as f64 * 0.99) as usize).min(dev.len() - 1)];
    Ok(Jitter {
        intervals: dev.len(),
        period_ms,
        mean_abs_ms: mean,
        p99_abs_ms: p99,
        max_abs_ms: dev[dev.len() - 1],
        over_2x_period: over,
    })
}

#[derive(Debug, Serialize)]
struct DayReport {
    mode: &'static str,
    tags: usize,
    rate_hz: f64,
    simulated_hours: f64,
    samples: u64,
    wall_seconds: f64,
    samples_per_s: f64,
    detector_scans: u64,
    segments_closed: u64,
    rss_kib_after: u64,
    hwm_kib: u64,
    db_mib: f64,
    cache_mib: u32,
}

pub(crate) fn run(args: BenchDaemonArgs) -> anyhow::Result<ExitCode> {
    if args.tags == 0 || !(args.rate_hz > 0.0 && args.rate_hz <= 100.0) {
        bail!("--tags must be ≥ 1 and --rate-hz in (0, 100]");
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let json = if args.day {
        let r = rt.block_on(day(&args))?;
        serde_json::to_string_pretty(&r)?
    } else {
        let r = rt.block_on(live(&args))?;
        serde_json::to_string_pretty(&r)?
    };
    println!("{json}");
    Ok(ExitCode::SUCCESS)
}

async fn live(args: &BenchDaemonArgs) -> anyhow::Result<LiveReport> {
    let dir = tempfile_dir()?;
    let period_ms = (1000.0 / args.rate_hz).round() as u64;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
    let addr = listener.local_addr()?;
    let map = bench_map(args.tags, &addr.to_string());
    let sim = spawn_plant_sim(
        listener,
        map.clone(),
        Box::new(ScriptedPlant::demo(period_ms as f64 / 1000.0)),
        SimOptions::default(),
        None,
    )?;
    let mut cfg = Config {
        plant: PlantConfig {
            name: "bench".into(),
            engine_model: None,
        },
        storage: StorageConfig {
            path: dir.path().join("bench.db"),
            cache_mib: args.cache_mib,
            compact_after_hours: 24,
            raw_days: u32::from(args.maintain_days > 0),
            ..StorageConfig::default()
        },
        replay: Default::default(),
        quality: Default::default(),
        detector: DetectorConfig::default(),
        acquisition: Default::default(),
        modbus: Some(map),
        daemon: DaemonConfig::default(),
        diagnosis: crate::worker::DiagnosisSettings {
            gap_every_n: args.gap_every,
            ..Default::default()
        },
        wash: Default::default(),
        metrics: Default::default(),
        fleet: None,
    };
    cfg.acquisition.poll_period_ms = period_ms;
    let problems = cfg.check();
    if !problems.is_empty() {
        bail!("bench config: {problems:?}");
    }
    let worker = if args.diagnose_startups > 0 {
        prefill_startups(
            &cfg.storage.path,
            args.diagnose_startups,
            &cfg.storage.options(),
        )?;
        Some(Arc::new(crate::worker::WorkerContext::load(
            None,
            cfg.diagnosis.clone(),
        )?))
    } else {
        None
    };
    let samples_prefilled = if args.maintain_days > 0 {
        prefill_old_days(
            &cfg.storage.path,
            args.maintain_days,
            &cfg.storage.options(),
        )?
    } else {
        0
    };
    let db_path = cfg.storage.path.clone();
    let progress = Arc::new(PollProgress::default());
    let waits_before = crate::store::lock_waits();
    let (trigger, shutdown) = shutdown_channel();
    let task = tokio::spawn(daemon::run(
        cfg,
        shutdown,
        RunOptions {
            systemd_notify: false,
            progress: Some(Arc::clone(&progress)),
            worker,
            compaction_timing: (args.maintain_days > 0).then_some(daemon::CompactionTiming {
                first_delay: Duration::from_secs(1),
                period: Duration::from_secs(5),
            }),
            ..RunOptions::default()
        },
    ));
    tokio::time::sleep(Duration::from_secs(3)).await;
    let measure_from_ms = crate::store::now_ms();
    let (c0, t0, s0) = (
        cpu_seconds()?,
        Instant::now(),
        progress.samples.load(Ordering::Relaxed),
    );
    // Readers start half-way, when the worker has stored results for the report to show.
    let half = Duration::from_secs(args.seconds) / 2;
    tokio::time::sleep(half).await;
    let readers = if args.readers {
        let segment = (args.diagnose_startups > 0).then_some(1);
        start_readers(&db_path, &dir.path().join("report"), segment)?
    } else {
        Vec::new()
    };
    tokio::time::sleep(Duration::from_secs(args.seconds).saturating_sub(half)).await;
    let (c1, wall, s1) = (
        cpu_seconds()?,
        t0.elapsed().as_secs_f64(),
        progress.samples.load(Ordering::Relaxed),
    );
    let (rss, hwm) = memory_kib()?;
    let readers = finish_readers(readers).await?;
    trigger.trigger();
    let report = task.await?.context("daemon")?;
    let waits = crate::store::lock_waits();
    sim.stop().await?;
    let jitter = poll_jitter(&db_path, measure_from_ms, period_ms)?;
    Ok(LiveReport {
        mode: "live",
        tags: args.tags,
        rate_hz: args.rate_hz,
        seconds: wall,
        cpu_seconds: c1 - c0,
        cpu_percent_of_one_core: 100.0 * (c1 - c0) / wall,
        rss_kib: rss,
        hwm_kib: hwm,
        polls_ok: report.poll.polls_ok,
        poll_failures: report.poll.failures,
        samples: s1 - s0,
        samples_per_s: (s1 - s0) as f64 / wall,
        diagnosed: report.diagnosis.diagnosed,
        gap_stored: report.gap.stored,
        gap_cancelled: report.gap.cancelled,
        jitter,
        store_lock_waits: waits.waits - waits_before.waits,
        store_lock_waited_ms: waits.waited_ms - waits_before.waited_ms,
        channel_full_waits: report.writer.channel_full_waits,
        writer_requests: report.writer.requests,
        writer_request_errors: report.writer.request_errors,
        readers,
        maintenance: (args.maintain_days > 0).then_some(LiveMaintenance {
            days_prefilled: args.maintain_days,
            samples_prefilled,
            chunks: report.compaction.chunks,
            samples_archived: report.compaction.samples,
            samples_rolled_up: report.compaction.rolled_up,
            vacuumed_pages: report.compaction.vacuumed_pages,
            failures: report.compaction.failures,
        }),
        note: "CPU includes the in-process plant-sim server",
    })
}

async fn day(args: &BenchDaemonArgs) -> anyhow::Result<DayReport> {
    let mut rig = IngestRig::new(args.tags, args.cache_mib, "day.db")?;
    let period_s = 1.0 / args.rate_hz;
    let mut plant = ScriptedPlant::demo(period_s);
    let frames = (args.hours * 3600.0 * args.rate_hz).round() as u64;
    let period_ms = (1000.0 * period_s).round() as i64;
    let t_start = crate::store::now_ms() - frames as i64 * period_ms;
    let scan_every = (3600.0 * args.rate_hz) as u64;
    let started = Instant::now();
    for k in 0..frames {
        let frame = plant.step();
        rig.push(&frame, k as f64 * 1e-3, t_start + k as i64 * period_ms)
            .await?;
        if (k + 1) % scan_every == 0 {
            rig.scan().await?;
        }
    }
    rig.close_writer().await?;
    let wall = started.elapsed().as_secs_f64();
    let (rss, hwm) = memory_kib()?;
    let db_bytes = std::fs::metadata(&rig.db_path)
        .map(|m| m.len())
        .unwrap_or(0);
    rig.close_detector();
    Ok(DayReport {
        mode: "day",
        tags: args.tags,
        rate_hz: args.rate_hz,
        simulated_hours: args.hours,
        samples: rig.samples,
        wall_seconds: wall,
        samples_per_s: rig.samples as f64 / wall,
        detector_scans: rig.scans,
        segments_closed: rig.segments_closed,
        rss_kib_after: rss,
        hwm_kib: hwm,
        db_mib: db_bytes as f64 / (1024.0 * 1024.0),
        cache_mib: args.cache_mib,
    })
}

/// A temporary directory removed on drop (under $TMPDIR).
pub(super) fn tempfile_dir() -> anyhow::Result<TempDir> {
    let base = std::env::temp_dir().join(format!(
        "gtwatch-bench-{}-{}",
        std::process::id(),
        crate::store::now_ms()
    ));
    std::fs::create_dir_all(&base).with_context(|| format!("creating {}", base.display()))?;
    Ok(TempDir(base))
}

pub(super) struct TempDir(std::path::PathBuf);

impl TempDir {
    pub(super) fn path(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
