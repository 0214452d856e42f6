//! `gtwatch run`: wires acquisition, the writer, the detector and the diagnosis worker as
//! tokio tasks.
//!
//! The shape follows mini-redis: [`run`] receives the shutdown signal as a value, so `main` maps
//! SIGTERM/SIGINT onto it and tests trigger it directly. Tasks:
//! - acquisition (`acquire::modbus::poll_loop`) → bounded channel → the single writer
//!   (`store::spawn_writer`), which batches inserts into transactions;
//! - the detector ([`DetectorTask`]) every `daemon.detect_interval_ms` on the blocking pool, with
//!   its own connection (SQLite WAL: readers and the writer do not block each other); when a
//!   scan closes a segment it wakes the worker;
//! - the diagnosis worker (`worker::DiagnosisTask`): drains the queue of closed segments on the
//!   blocking pool, one at a time; shutdown cancels a running fit (nothing half-written);
//! - systemd notification: READY=1 after the first successful poll, WATCHDOG=1 only while the
//!   poll loop makes progress, STOPPING=1 at shutdown.
//!
//! Shutdown order: stop polling (an open outage is recorded as a gap), close the channel, let
//! the writer commit its last batch, then run the detector once more over everything stored.
//! Errors in the detector or worker are logged and retried; they never stop acquisition. This
//! module holds no business logic of its own.

use crate::acquire::modbus::{poll_loop, PollPlan, PollProgress, PollStats, SourceKind};
use crate::config::Config;
use crate::detect::{self, DetectorConfig, ScanReport};
use crate::shutdown::Shutdown;
use crate::store::{
    spawn_writer, Gap, Store, StoreError, StoreOptions, TagId, TagInfo, WriteCmd, WriterStats,
};
use crate::worker::{AfterResult, DiagnosisTask, DrainReport, WorkerContext};
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{mpsc, Notify};

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
}

/// Tag ids for every register-map field, in map order (creating tags as needed).
fn ensure_tags(store: &mut Store, cfg: &Config) -> Result<Vec<TagId>, StoreError> {
    let Some(map) = &cfg.modbus else {
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

fn notify(enabled: bool, state: &[sd_notify::NotifyState]) {
    if enabled {
        if let Err(e) = sd_notify::notify(false, state) {
            tracing::debug!("sd_notify: {e}");
        }
    }
}

/// Page cache of the detector's connection, MiB. The detector reads each tag's new samples
/// once, in time order: a big cache would only hold pages it never reads again, and the
/// daemon's resident memory is budgeted (< 50 MB after a day of data).
pub const DETECTOR_CACHE_MIB: u32 = 2;

/// Connection options of the detector: those of `[storage]` with a small page cache.
pub fn detector_store_options(storage: &StoreOptions) -> StoreOptions {
    StoreOptions {
        cache_mib: storage.cache_mib.min(DETECTOR_CACHE_MIB),
        ..*storage
    }
}

/// The detector task: scans new samples every `daemon.detect_interval_ms` on the blocking pool
/// with its own connection, and wakes the diagnosis worker when a segment closes.
pub struct DetectorTask {
    pub db_path: PathBuf,
    pub store_opts: StoreOptions,
    pub cfg: DetectorConfig,
    pub interval: Duration,
    /// Notified after a scan that closed a segment.
    pub wake: Arc<Notify>,
    store: Option<Store>,
    pub scans_ok: u64,
    pub scans_failed: u64,
}

impl DetectorTask {
    pub fn new(
        db_path: PathBuf,
        store_opts: StoreOptions,
        cfg: DetectorConfig,
        interval: Duration,
        wake: Arc<Notify>,
    ) -> DetectorTask {
        DetectorTask {
            db_path,
            store_opts,
            cfg,
            interval,
            wake,
            store: None,
            scans_ok: 0,
            scans_failed: 0,
        }
    }

    /// One pass on the blocking pool. A missing connection (first use, or lost in a panicked
    /// pass) is reopened; errors are counted and logged, never propagated.
    pub async fn scan_once(&mut self) -> Option<ScanReport> {
        let store = self.store.take();
        let path = self.db_path.clone();
        let opts = self.store_opts;
        let cfg = self.cfg.clone();
        let r = tokio::task::spawn_blocking(move || {
            let mut store = match store {
                Some(s) => s,
                None => match Store::open_with(&path, &opts) {
                    Ok(s) => s,
                    Err(e) => return (None, Err(e.to_string())),
                },
            };
            let r = detect::scan(&mut store, &cfg).map_err(|e| e.to_string());
            (Some(store), r)
        })
        .await;
        let (store, r) = r.unwrap_or_else(|e| (None, Err(format!("detector task failed: {e}"))));
        self.store = store;
        match r {
            Ok(rep) => {
                self.scans_ok += 1;
                if rep.segments_closed > 0 {
                    tracing::info!(
                        closed = rep.segments_closed,
                        open = rep.segments_open,
                        "start-up segments detected"
                    );
                    self.wake.notify_one();
                }
                Some(rep)
            }
            Err(e) => {
                self.scans_failed += 1;
                tracing::warn!("detector: {e}");
                None
            }
        }
    }

    /// Scans every interval until shutdown; returns itself for the final scan.
    pub async fn run(mut self, mut shutdown: Shutdown) -> DetectorTask {
        let mut tick = tokio::time::interval(self.interval);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        tick.tick().await;
        loop {
            tokio::select! {
                biased;
                _ = shutdown.wait() => break,
                _ = tick.tick() => {
                    self.scan_once().await;
                }
            }
        }
        self
    }
}

/// Runs the daemon until `shutdown` fires. `cfg` must have passed [`Config::check`].
pub async fn run(
    cfg: Config,
    shutdown: Shutdown,
    opts: RunOptions,
) -> Result<RunReport, DaemonError> {
    let db_path: PathBuf = cfg.storage.path.clone();
    let store_opts = cfg.storage.options();
    let detector_opts = detector_store_options(&store_opts);
    let mut store = {
        let p = db_path.clone();
        tokio::task::spawn_blocking(move || Store::open_with(&p, &store_opts))
            .await
            .map_err(|e| DaemonError::Writer(e.to_string()))??
    };
    let tags = ensure_tags(&mut store, &cfg)?;
    let last_stored_ms = store.last_sample_ms(&tags)?;
    tracing::info!(
        plant = %cfg.plant.name,
        db = %db_path.display(),
        tags = tags.len(),
        "gtwatch daemon starting"
    );

    let (tx, rx) = mpsc::channel::<WriteCmd>(cfg.daemon.queue_capacity.max(1));
    let writer = spawn_writer(store, rx, cfg.storage.writer());
    if let (Some(last), Some(_)) = (last_stored_ms, &cfg.modbus) {
        // Whatever stopped the previous run (SIGTERM, kill -9, a crash, a reboot), the time
        // between its last stored sample and this run's first one had no acquisition.
        let _ = tx
            .send(WriteCmd::GapUntilNextSample(Gap {
                start_ms: last,
                end_ms: last,
                source: "daemon".to_string(),
                reason: "daemon_restart".to_string(),
            }))
            .await;
    }
    let progress = opts.progress.clone().unwrap_or_default();

    // Acquisition.
    let poller = match (&cfg.modbus, cfg.acquisition.source) {
        (Some(map), SourceKind::Modbus) => {
            let mut plan = PollPlan::new(map, &tags).map_err(DaemonError::Plan)?;
            plan.quality = cfg.quality.clone();
            let acq = cfg.acquisition.clone();
            let p = Arc::clone(&progress);
            let sd = shutdown.clone();
            let tx = tx.clone();
            Some(tokio::spawn(async move {
                poll_loop(&acq, &plan, tx, p, sd).await
            }))
        }
        _ => None,
    };
    drop(tx); // the writer ends once the poller's sender is gone

    // Detector and diagnosis tasks, then supervisor notifications until shutdown.
    let mut report = RunReport::default();
    let wake = Arc::new(Notify::new());
    let detector = tokio::spawn(
        DetectorTask::new(
            db_path.clone(),
            detector_opts,
            cfg.detector.clone(),
            Duration::from_millis(cfg.daemon.detect_interval_ms),
            Arc::clone(&wake),
        )
        .run(shutdown.clone()),
    );
    let worker = match (cfg.diagnosis.enabled, opts.worker.clone()) {
        (true, Some(ctx)) => Some(tokio::spawn(
            DiagnosisTask {
                db_path: db_path.clone(),
                store_opts: detector_opts,
                after_result: opts
                    .after_result
                    .clone()
                    .or_else(|| Some(crate::advice::hook(Arc::clone(&ctx), cfg.wash))),
                ctx,
                wake: Arc::clone(&wake),
            }
            .run(shutdown.clone()),
        )),
        _ => None,
    };
    let mut watchdog_usec = 0u64;
    let watchdog = opts.systemd_notify && sd_notify::watchdog_enabled(false, &mut watchdog_usec);
    let wd_period = Duration::from_micros((watchdog_usec / 2).max(100_000));
    let mut wd_tick = tokio::time::interval(wd_period);
    wd_tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut ready = poller.is_none();
    if ready {
        notify(opts.systemd_notify, &[sd_notify::NotifyState::Ready]);
    }
    let mut last_cycles = 0u64;
    let mut ready_check = tokio::time::interval(Duration::from_millis(50));
    let mut sd = shutdown.clone();
    loop {
        tokio::select! {
            biased;
            _ = sd.wait() => break,
            _ = ready_check.tick(), if !ready => {
                if progress.polls_ok.load(Ordering::Relaxed) > 0 {
                    ready = true;
                    tracing::info!("first poll succeeded; ready");
                    notify(opts.systemd_notify, &[sd_notify::NotifyState::Ready]);
                }
            }
            _ = wd_tick.tick(), if watchdog => {
                // Progress = the poll loop finished a cycle (a poll, or a failure it recorded).
                // A PLC outage is a recorded gap, not a daemon fault; a hung loop or a writer
                // that stopped accepting samples is, and then systemd restarts us.
                let cycles = progress.cycles.load(Ordering::Relaxed);
                if cycles != last_cycles || poller.is_none() {
                    last_cycles = cycles;
                    notify(true, &[sd_notify::NotifyState::Watchdog]);
                } else {
                    tracing::warn!("acquisition made no progress; withholding watchdog ping");
                }
            }
        }
    }
    notify(opts.systemd_notify, &[sd_notify::NotifyState::Stopping]);
    tracing::info!("shutting down: stopping acquisition");
    if let Some(p) = poller {
        report.poll = p.await.unwrap_or_else(|e| {
            tracing::error!("acquisition task failed: {e}");
            progress.snapshot()
        });
    }
    report.writer = writer
        .await
        .map_err(|e| DaemonError::Writer(e.to_string()))?
        .map_err(|e| DaemonError::Writer(e.to_string()))?;
    tracing::info!(
        inserted = report.writer.samples_inserted,
        gaps = report.writer.gaps,
        write_errors = report.writer.write_errors,
        samples_dropped = report.writer.samples_dropped,
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
    // Final scan over everything stored; segments it closes stay pending for the next start.
    match detector.await {
        Ok(mut det) => {
            report.last_scan = det.scan_once().await;
            report.scans_ok = det.scans_ok;
            report.scans_failed = det.scans_failed;
        }
        Err(e) => tracing::error!("detector task failed: {e}"),
    }
    if let Some(w) = worker {
        match w.await {
            Ok(d) => report.diagnosis = d,
            Err(e) => tracing::error!("diagnosis task failed: {e}"),
        }
    }
    Ok(report)
}
