//! `gtwatch run`: the daemon as a supervisor of small tasks, each a struct with
//! `run(self, shutdown)` (the mini-redis shape: the shutdown signal is a value, so `main` maps
//! SIGTERM/SIGINT onto it and tests trigger it directly):
//! - [`writer`]: the one owner of the writable connection. Every other task sends it typed
//!   requests over one bounded channel (a `WriterHandle` each): samples and gaps, which it
//!   batches into transactions, and a detector scan, a diagnosis outcome or the wash advice,
//!   each committed in its own transaction and answered. It ends once every sender has;
//! - [`acquisition`]: the Modbus poll loop → the writer; a full channel slows it (counted and
//!   logged), it never drops a sample for it;
//! - [`detector`]: scans for start-ups every `daemon.detect_interval_ms` and wakes the worker
//!   when a scan closes a segment;
//! - [`diagnosis`]: drains the queue of closed segments, one at a time; shutdown cancels a
//!   running fit (nothing half-written);
//! - [`supervisor`]: systemd readiness, watchdog and stopping notifications;
//! - [`sync`]: with `[fleet]`, the fleet sync to a central PostgreSQL every `interval_s`; a
//!   centre that is down or refusing is logged, counted and retried, never waited for;
//! - [`compaction`]: with `[storage] compact_after_hours` > 0 (default 24) or `raw_days` > 0,
//!   has the writer archive older samples every hour (`WriteCmd::Compact`, a few chunks per
//!   request), roll up steady samples older than `raw_days` and merge minute roll-ups older
//!   than `rollup_1m_days` into hours (`WriteCmd::Retain`) and return
//!   freed pages to the file system (`WriteCmd::IncrementalVacuum`);
//! - [`metrics`]: with `[metrics] listen`, the Prometheus endpoint, reading the other tasks'
//!   live counters at each scrape.
//!
//! The detector and the worker read through read-only connections of their own
//! (`blocking::BlockingStore`, on the blocking pool, reopened when lost) and write only
//! through the writer, so no two connections of the daemon ever wait for each other's lock.
//!
//! [`run`] opens the store, starts the tasks and, once shutdown fires, stops them in order:
//! stop polling (an open outage is recorded as a gap), have the writer commit what it holds,
//! run the detector once more over everything stored, wait for the worker, then close the
//! channel and let the writer finish. Errors in the detector or worker are logged and retried;
//! they never stop acquisition. This module holds no business logic of its own.

pub(crate) mod acquisition;
mod blocking;
pub(crate) mod compaction;
pub(crate) mod detector;
pub(crate) mod diagnosis;
pub(crate) mod gap;
pub(crate) mod metrics;
pub(crate) mod supervisor;
pub(crate) mod sync;
pub(crate) mod writer;

pub use acquisition::AcquisitionTask;
pub use compaction::{CompactionCounters, CompactionReport, CompactionTask};
pub use detector::{detector_store_options, DetectorTask, DETECTOR_CACHE_MIB};
pub use diagnosis::{DiagnosisMeter, DiagnosisTask};
pub use gap::{GapCounters, GapTask, GapTaskReport};
pub use metrics::{Live, MetricsTask};
pub use supervisor::Supervisor;
pub use sync::{SyncCounters, SyncTask, SyncTaskReport};
pub use writer::WriterTask;

use crate::acquire::modbus::{PollProgress, PollStats};
use crate::acquire::register_map::ModbusConfig;
use crate::config::Config;
use crate::detect::ScanReport;
use crate::shutdown::Shutdown;
use crate::store::{
    writer_channel, Gap, Store, StoreError, TagId, TagInfo, WriteCmd, WriterHandle, WriterProgress,
    WriterStats,
};
use crate::worker::{AfterResult, DrainReport, WorkerContext};
use blocking::{BlockingError, BlockingStore};
use std::path::PathBuf;
use std::sync::atomic::AtomicU64;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;
use tokio::task::JoinHandle;

/// Daemon failures that stop it (anything else is logged and survived).
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    #[error("opening the database: {0}")]
    Store(#[from] StoreError),
    #[error("register map: {0}")]
    Plan(String),
    #[error("writer task failed: {0}")]
    Writer(String),
}

/// Options that are not configuration: how the daemon talks to its supervisor.
#[derive(Clone, Default)]
pub struct RunOptions {
    /// Send sd_notify messages (READY, WATCHDOG, STOPPING). Off in tests.
    pub systemd_notify: bool,
    /// Shared progress counters (benchmarks and tests watch them); created if `None`.
    pub progress: Option<Arc<PollProgress>>,
    /// The diagnosis worker's engine and settings; `None`: no diagnosis in this run.
    pub worker: Option<Arc<WorkerContext>>,
    /// Called after each stored diagnosis outcome (trends, washes, advice).
    pub after_result: Option<AfterResult>,
    /// The compaction task's timing instead of [`compaction::FIRST_DELAY`] and
    /// [`compaction::PERIOD`] (`bench daemon --maintain-days`, which must see rounds within a
    /// minute).
    pub compaction_timing: Option<CompactionTiming>,
}

/// When the compaction task runs: its first round after `first_delay`, then every `period`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CompactionTiming {
    pub first_delay: std::time::Duration,
    pub period: std::time::Duration,
}

/// What the daemon did, returned at shutdown.
#[derive(Debug, Clone, Default)]
pub struct RunReport {
    pub poll: PollStats,
    pub writer: WriterStats,
    /// Detector scans that succeeded / failed.
    pub scans_ok: u64,
    pub scans_failed: u64,
    /// The final scan at shutdown.
    pub last_scan: Option<ScanReport>,
    /// What the diagnosis worker did.
    pub diagnosis: DrainReport,
    /// What the background gap analysis did.
    pub gap: GapTaskReport,
    /// What the fleet sync did (`[fleet]`).
    pub sync: SyncTaskReport,
    /// What the compaction task archived, rolled up and vacuumed (`[storage]
    /// compact_after_hours`, `raw_days`).
    pub compaction: CompactionReport,
}

/// Runs the daemon until `shutdown` fires. `cfg` must have passed [`Config::check`].
pub async fn run(
    cfg: Config,
    shutdown: Shutdown,
    opts: RunOptions,
) -> Result<RunReport, DaemonError> {
    let opened = open_store(&cfg).await?;
    tracing::info!(
        plant = %cfg.plant.name,
        db = %cfg.storage.path.display(),
        tags = opened.tags.len(),
        "gtwatch daemon starting"
    );
    let (tx, rx) = writer_channel(cfg.daemon.queue_capacity);
    let writer_progress = Arc::new(WriterProgress::default());
    let writer = tokio::spawn(
        WriterTask {
            store: opened.store,
            rx,
            cfg: cfg.storage.writer(),
            progress: Arc::clone(&writer_progress),
        }
        .run(shutdown.clone()),
    );
    record_restart(&tx, &cfg, opened.last_stored_ms).await;
    let progress = opts.progress.clone().unwrap_or_default();
    let tasks = Running::start(&cfg, &opts, &opened.tags, tx, &progress, &shutdown, writer)?;
    let metrics = match cfg.metrics.addr() {
        Some(addr) => MetricsTask::bind(addr, tasks.live(&progress, writer_progress))
            .await
            .map(|m| tokio::spawn(m.run(shutdown.clone()))),
        None => None,
    };
    Supervisor {
        systemd_notify: opts.systemd_notify,
        progress: Arc::clone(&progress),
        acquiring: tasks.acquisition.is_some(),
    }
    .run(shutdown)
    .await;
    let report = tasks.stop(&progress).await;
    if let Some(m) = metrics {
        if let Err(e) = m.await {
            tracing::error!("metrics task failed: {e}");
        }
    }
    report
}

/// The writable store the writer will own, with what the start needs from it.
struct Opened {
    store: Store,
    /// Tag ids of the register map's fields, in map order.
    tags: Vec<TagId>,
    /// Time of the newest stored sample of those tags (the previous run's last).
    last_stored_ms: Option<i64>,
}

/// Opens the store (on the blocking pool), creates the register map's tags and finds the
/// previous run's last sample.
async fn open_store(cfg: &Config) -> Result<Opened, DaemonError> {
    let mut blocking = BlockingStore::writable(cfg.storage.path.clone(), cfg.storage.options());
    let map = cfg.modbus.clone();
    let (tags, last_stored_ms) = blocking
        .run(move |store| {
            let tags = ensure_tags(store, map.as_ref())?;
            let last = store.last_sample_ms(&tags)?;
            Ok::<_, StoreError>((tags, last))
        })
        .await
        .map_err(|e| match e {
            BlockingError::Open(e) | BlockingError::Work(e) => DaemonError::Store(e),
            BlockingError::Panicked(e) => DaemonError::Writer(e.to_string()),
        })?;
    let store = blocking
        .into_store()
        .ok_or_else(|| DaemonError::Writer("the store connection was lost at start".into()))?;
    Ok(Opened {
        store,
        tags,
        last_stored_ms,
    })
}

/// Whatever stopped the previous run (SIGTERM, kill -9, a crash, a reboot), the time between
/// its last stored sample and this run's first one had no acquisition: a gap.
async fn record_restart(tx: &WriterHandle, cfg: &Config, last_stored_ms: Option<i64>) {
    if let (Some(last), Some(_)) = (last_stored_ms, &cfg.modbus) {
        let _ = tx
            .send(WriteCmd::GapUntilNextSample(Gap {
                start_ms: last,
                end_ms: last,
                source: "daemon".to_string(),
                reason: "daemon_restart".to_string(),
            }))
            .await;
    }
}

/// The running tasks.
struct Running {
    acquisition: Option<JoinHandle<PollStats>>,
    writer: JoinHandle<Result<WriterStats, StoreError>>,
    /// The daemon's own sender: flushes at shutdown, then dropped so the writer can end.
    tx: WriterHandle,
    /// How long the shutdown waits for the writer to commit what it holds.
    flush_timeout: Duration,
    detector: JoinHandle<DetectorTask>,
    diagnosis: Option<JoinHandle<DrainReport>>,
    gap: Option<JoinHandle<GapTaskReport>>,
    sync: Option<JoinHandle<SyncTaskReport>>,
    compaction: Option<JoinHandle<CompactionReport>>,
    /// Live counters of the detector, the diagnosis and the gap task (the metrics read them).
    segments_closed: Arc<AtomicU64>,
    diagnosis_meter: Option<Arc<DiagnosisMeter>>,
    gap_counters: Arc<GapCounters>,
    sync_counters: Option<Arc<SyncCounters>>,
    compaction_counters: Option<Arc<CompactionCounters>>,
}

impl Running {
    /// Spawns acquisition, the detector and the diagnosis worker, each with a clone of `tx`.
    fn start(
        cfg: &Config,
        opts: &RunOptions,
        tags: &[TagId],
        tx: WriterHandle,
        progress: &Arc<PollProgress>,
        shutdown: &Shutdown,
        writer: JoinHandle<Result<WriterStats, StoreError>>,
    ) -> Result<Running, DaemonError> {
        let acquisition =
            AcquisitionTask::from_config(cfg, tags, tx.clone(), Arc::clone(progress))?
                .map(|task| tokio::spawn(task.run(shutdown.clone())));
        let db_path: PathBuf = cfg.storage.path.clone();
        let task_opts = detector_store_options(&cfg.storage.options());
        let wake = Arc::new(Notify::new());
        let det = DetectorTask::new(
            db_path.clone(),
            task_opts,
            tx.clone(),
            cfg.detector.clone(),
            Duration::from_millis(cfg.daemon.detect_interval_ms),
            Arc::clone(&wake),
        );
        let closed = Arc::clone(&det.closed);
        let segments_closed = Arc::clone(&det.closed);
        let detector = tokio::spawn(det.run(shutdown.clone()));
        let gap_counters = Arc::new(GapCounters::default());
        let gap = match (cfg.diagnosis.enabled, opts.worker.clone()) {
            (true, Some(ctx)) if crate::worker::gap::selection(&ctx).is_some() => {
                Some(tokio::spawn(
                    GapTask {
                        db_path: db_path.clone(),
                        store_opts: task_opts,
                        writer: tx.clone(),
                        idle_period: Duration::from_millis(
                            ctx.settings.poll_interval_ms.clamp(100, 10_000),
                        ),
                        ctx,
                        closed,
                        counters: Arc::clone(&gap_counters),
                    }
                    .run(shutdown.clone()),
                ))
            }
            _ => None,
        };
        let sync_counters = cfg
            .fleet
            .as_ref()
            .map(|_| Arc::new(SyncCounters::default()));
        let sync = cfg
            .fleet
            .clone()
            .zip(sync_counters.clone())
            .map(|(fleet, counters)| {
                tokio::spawn(
                    SyncTask {
                        db_path: db_path.clone(),
                        store_opts: task_opts,
                        writer: tx.clone(),
                        cfg: fleet,
                        counters,
                    }
                    .run(shutdown.clone()),
                )
            });
        let mut compaction_task = CompactionTask::from_config(tx.clone(), &cfg.storage);
        if let (Some(task), Some(timing)) = (compaction_task.as_mut(), opts.compaction_timing) {
            task.first_delay = timing.first_delay;
            task.period = timing.period;
        }
        let compaction_counters = compaction_task
            .as_ref()
            .map(|task| Arc::clone(&task.counters));
        let compaction = compaction_task.map(|task| tokio::spawn(task.run(shutdown.clone())));
        let diagnosis_meter = match (cfg.diagnosis.enabled, &opts.worker) {
            (true, Some(_)) => Some(Arc::new(DiagnosisMeter::default())),
            _ => None,
        };
        let diagnosis = match (cfg.diagnosis.enabled, opts.worker.clone()) {
            (true, Some(ctx)) => Some(tokio::spawn(
                DiagnosisTask {
                    db_path,
                    store_opts: task_opts,
                    writer: tx.clone(),
                    after_result: opts
                        .after_result
                        .clone()
                        .or_else(|| Some(crate::advice::hook(Arc::clone(&ctx), cfg.wash))),
                    ctx,
                    wake,
                }
                .run_metered(shutdown.clone(), diagnosis_meter.clone()),
            )),
            _ => None,
        };
        Ok(Running {
            acquisition,
            writer,
            tx,
            flush_timeout: cfg.storage.writer().close_retry,
            detector,
            diagnosis,
            gap,
            sync,
            compaction,
            segments_closed,
            diagnosis_meter,
            gap_counters,
            sync_counters,
            compaction_counters,
        })
    }

    /// The live counters the metrics endpoint reads.
    fn live(&self, poll: &Arc<PollProgress>, writer: Arc<WriterProgress>) -> Live {
        Live {
            poll: Arc::clone(poll),
            writer,
            segments_closed: Arc::clone(&self.segments_closed),
            diagnosis: self.diagnosis_meter.clone(),
            gap: Arc::clone(&self.gap_counters),
            sync: self.sync_counters.clone(),
            compaction: self.compaction_counters.clone(),
        }
    }

    /// After shutdown: stop acquisition, have the writer commit what it holds, scan once more,
    /// wait for the diagnosis worker, then let the writer finish.
    async fn stop(self, progress: &PollProgress) -> Result<RunReport, DaemonError> {
        let mut report = RunReport::default();
        tracing::info!("shutting down: stopping acquisition");
        if let Some(p) = self.acquisition {
            report.poll = p.await.unwrap_or_else(|e| {
                tracing::error!("acquisition task failed: {e}");
                progress.snapshot()
            });
        }
        // Everything acquisition sent is committed before the final scan reads it (bounded:
        // a writer in a write-error episode answers only once the database takes writes).
        match tokio::time::timeout(self.flush_timeout, self.tx.flush()).await {
            Ok(Ok(())) => {}
            Ok(Err(e)) => tracing::warn!("final flush: {e}"),
            Err(_) => tracing::warn!("final flush: the writer did not commit in time"),
        }
        // Final scan over everything stored; segments it closes stay pending for the next start.
        match self.detector.await {
            Ok(mut det) => {
                report.last_scan = det.scan_once().await;
                report.scans_ok = det.scans_ok;
                report.scans_failed = det.scans_failed;
            }
            Err(e) => tracing::error!("detector task failed: {e}"),
        }
        if let Some(w) = self.diagnosis {
            match w.await {
                Ok(d) => report.diagnosis = d,
                Err(e) => tracing::error!("diagnosis task failed: {e}"),
            }
        }
        if let Some(g) = self.gap {
            match g.await {
                Ok(r) => report.gap = r,
                Err(e) => tracing::error!("gap task failed: {e}"),
            }
        }
        if let Some(s) = self.sync {
            match s.await {
                Ok(r) => report.sync = r,
                Err(e) => tracing::error!("fleet sync task failed: {e}"),
            }
        }
        if let Some(c) = self.compaction {
            match c.await {
                Ok(r) => report.compaction = r,
                Err(e) => tracing::error!("compaction task failed: {e}"),
            }
        }
        let channel_full_waits = self.tx.channel_full_waits();
        drop(self.tx);
        report.writer = self
            .writer
            .await
            .map_err(|e| DaemonError::Writer(e.to_string()))?
            .map_err(|e| DaemonError::Writer(e.to_string()))?;
        report.writer.channel_full_waits = channel_full_waits;
        log_totals(&report);
        Ok(report)
    }
}

/// The writer's and the poll loop's totals, logged at shutdown.
fn log_totals(report: &RunReport) {
    tracing::info!(
        inserted = report.writer.samples_inserted,
        gaps = report.writer.gaps,
        write_errors = report.writer.write_errors,
        samples_dropped = report.writer.samples_dropped,
        requests = report.writer.requests,
        request_errors = report.writer.request_errors,
        channel_full_waits = report.writer.channel_full_waits,
        store_lock_waits = crate::store::lock_waits().waits,
        "last batch committed"
    );
    tracing::info!(
        polled = report.poll.samples,
        flagged = report.poll.flagged,
        stuck = report.poll.stuck,
        spike = report.poll.spike,
        out_of_range_or_bad = report
            .poll
            .flagged
            .saturating_sub(report.poll.stuck + report.poll.spike),
        "polled samples by quality code"
    );
}

/// Tag ids for every register-map field, in map order (creating tags as needed).
fn ensure_tags(store: &mut Store, map: Option<&ModbusConfig>) -> Result<Vec<TagId>, StoreError> {
    let Some(map) = map else {
        return Ok(Vec::new());
    };
    map.fields()
        .map(|(_, f)| {
            store.ensure_tag(&TagInfo {
                name: f.name.clone(),
                unit: f.unit.clone(),
                signal: f.signal,
            })
        })
        .collect()
}
