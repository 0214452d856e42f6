//! The detector task: scans new samples for start-up segments every
//! `daemon.detect_interval_ms` on the blocking pool, reading through its own read-only
//! connection (SQLite WAL: readers and the writer do not block each other) and sending what a
//! scan found to the one writer (`WriteCmd::Detection`, waiting for it to be committed), and
//! wakes the diagnosis worker when a scan closes a segment. Errors are counted and logged,
//! never propagated: the detector must never stop acquisition. Must not hold detection logic
//! (that is `detect`), open a writable connection or write samples.

use super::blocking::BlockingStore;
use crate::detect::{self, DetectorConfig, ScanReport};
use crate::shutdown::Shutdown;
use crate::store::{ReadStore, StoreOptions, ViaWriter, WriterHandle};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;

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

/// The detector task (mini-redis shape: a small struct with its own `run`).
pub struct DetectorTask {
    store: BlockingStore<ReadStore>,
    writer: WriterHandle,
    cfg: DetectorConfig,
    interval: Duration,
    /// Notified after a scan that closed a segment.
    wake: Arc<Notify>,
    /// Segments closed so far (the gap task yields when it moves).
    pub closed: Arc<AtomicU64>,
    /// Scans that succeeded / failed.
    pub scans_ok: u64,
    pub scans_failed: u64,
}

impl DetectorTask {
    /// Reads `db_path` read-only with `store_opts`, writes through `writer`.
    pub fn new(
        db_path: PathBuf,
        store_opts: StoreOptions,
        writer: WriterHandle,
        cfg: DetectorConfig,
        interval: Duration,
        wake: Arc<Notify>,
    ) -> DetectorTask {
        DetectorTask {
            store: BlockingStore::read_only(db_path, store_opts),
            writer,
            cfg,
            interval,
            wake,
            closed: Arc::new(AtomicU64::new(0)),
            scans_ok: 0,
            scans_failed: 0,
        }
    }

    /// One pass on the blocking pool; errors are counted and logged.
    pub async fn scan_once(&mut self) -> Option<ScanReport> {
        let cfg = self.cfg.clone();
        let writer = self.writer.clone();
        let scan = move |read: &mut ReadStore| {
            detect::scan(
                &mut ViaWriter {
                    read,
                    writer: &writer,
                },
                &cfg,
            )
        };
        match self.store.run(scan).await {
            Ok(rep) => {
                self.scans_ok += 1;
                if rep.segments_closed > 0 {
                    tracing::info!(
                        closed = rep.segments_closed,
                        open = rep.segments_open,
                        "start-up segments detected"
                    );
                    self.closed
                        .fetch_add(rep.segments_closed, Ordering::Relaxed);
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
