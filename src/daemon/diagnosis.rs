//! The diagnosis task: drains the queue of closed start-ups (`worker::drain_pending`) on the
//! blocking pool (a backlog on up to `[diagnosis] threads` cores, each fit on a scoped thread
//! the drain starts there, never on the async runtime), now, whenever the detector wakes it,
//! and at least every `[diagnosis] poll_interval_ms`, until shutdown. It reads through its own read-only
//! connection and sends each outcome (and the wash advice the after-result hook computes) to
//! the one writer, waiting for the commit. Shutdown cancels a running fit, which stores
//! nothing: the segment stays pending for the next start. Errors are logged and the drain
//! retried; they never stop the daemon. Must not hold diagnosis or storage logic (that is
//! `worker` and `diagnosis::assess`) or open a writable connection.

use super::blocking::{BlockingError, BlockingStore};
use crate::metrics::DurationHistogram;
use crate::optim::Cancel;
use crate::shutdown::Shutdown;
use crate::store::{ReadStore, StoreOptions, ViaWriter, WriterHandle};
use crate::worker::{drain_pending, AfterResult, DrainReport, SegmentOutcome, WorkerContext};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;

/// What the metrics endpoint reads of the diagnosis, live: start-ups diagnosed and found
/// undiagnosable, the queue of closed start-ups waiting (read at the start of each drain and
/// after each start-up) and the wall time of each start-up's diagnosis.
#[derive(Debug, Default)]
pub struct DiagnosisMeter {
    pub diagnosed: AtomicU64,
    pub undiagnosable: AtomicU64,
    pub queue: AtomicU64,
    pub durations: DurationHistogram,
}

impl DiagnosisMeter {
    /// `inner` (the after-result hook) with the meter around it: counts the outcome, records
    /// the start-up's own wall time (several may be fitted at once) and reads the queue.
    fn around(self: &Arc<Self>, inner: Option<AfterResult>) -> AfterResult {
        let meter = Arc::clone(self);
        Arc::new(move |db, segment_id, outcome, wall| {
            let counter = match outcome {
                SegmentOutcome::Diagnosed { .. } => &meter.diagnosed,
                SegmentOutcome::Undiagnosable(_) => &meter.undiagnosable,
                // Not stored and never handed to the hook (`drain_pending` returns first).
                SegmentOutcome::Cancelled => return,
            };
            meter.durations.observe(wall);
            counter.fetch_add(1, Ordering::Relaxed);
            if let Some(f) = &inner {
                f(db, segment_id, outcome, wall);
            }
            if let Ok(p) = db.read().pending_segments() {
                meter.queue.store(p.len() as u64, Ordering::Relaxed);
            }
        })
    }
}

/// The diagnosis task of the daemon (mini-redis shape: a small struct with its own `run`).
pub struct DiagnosisTask {
    /// Read read-only with `store_opts`.
    pub db_path: PathBuf,
    pub store_opts: StoreOptions,
    /// Where outcomes and advice are written.
    pub writer: WriterHandle,
    pub ctx: Arc<WorkerContext>,
    /// The detector wakes the worker through this when a segment closes.
    pub wake: Arc<Notify>,
    /// Called after each stored outcome (trends, washes, advice).
    pub after_result: Option<AfterResult>,
}

impl DiagnosisTask {
    pub fn with_after_result(mut self, f: AfterResult) -> Self {
        self.after_result = Some(f);
        self
    }

    /// Drains the queue now, then whenever woken (or every `poll_interval_ms`), until shutdown.
    pub async fn run(self, shutdown: Shutdown) -> DrainReport {
        self.run_metered(shutdown, None).await
    }

    /// [`DiagnosisTask::run`], keeping `meter` up to date.
    pub async fn run_metered(
        self,
        shutdown: Shutdown,
        meter: Option<Arc<DiagnosisMeter>>,
    ) -> DrainReport {
        let cancel = cancel_on(shutdown.clone());
        let mut store = BlockingStore::read_only(self.db_path.clone(), self.store_opts);
        let mut total = DrainReport::default();
        let mut sd = shutdown;
        let period = Duration::from_millis(self.ctx.settings.poll_interval_ms.max(100));
        while !sd.is_triggered() {
            let rep = self.drain(&mut store, &cancel, meter.as_ref()).await;
            total.diagnosed += rep.diagnosed;
            total.undiagnosable += rep.undiagnosable;
            total.cancelled |= rep.cancelled;
            tokio::select! {
                _ = sd.wait() => break,
                _ = self.wake.notified() => {}
                _ = tokio::time::sleep(period) => {}
            }
        }
        total
    }

    /// One drain of the queue on the blocking pool; a failure is logged and counts nothing.
    async fn drain(
        &self,
        store: &mut BlockingStore<ReadStore>,
        cancel: &Cancel,
        meter: Option<&Arc<DiagnosisMeter>>,
    ) -> DrainReport {
        let ctx = Arc::clone(&self.ctx);
        let c = cancel.clone();
        let after = self.after_result.clone();
        let writer = self.writer.clone();
        let meter = meter.cloned();
        let drain = move |read: &mut ReadStore| {
            let after = match meter {
                Some(m) => {
                    if let Ok(p) = read.pending_segments() {
                        m.queue.store(p.len() as u64, Ordering::Relaxed);
                    }
                    Some(m.around(after))
                }
                None => after,
            };
            let mut db = ViaWriter {
                read,
                writer: &writer,
            };
            drain_pending(&mut db, &ctx, &c, after.as_ref())
        };
        match store.run(drain).await {
            Ok(rep) => rep,
            Err(BlockingError::Panicked(e)) => {
                tracing::error!("diagnosis worker task failed: {e}");
                DrainReport::default()
            }
            Err(e) => {
                tracing::warn!("diagnosis worker: {e}");
                DrainReport::default()
            }
        }
    }
}

/// A cancel flag set when `shutdown` fires (it cancels a running fit).
fn cancel_on(mut shutdown: Shutdown) -> Cancel {
    let cancel = Cancel::new();
    let c = cancel.clone();
    tokio::spawn(async move {
        shutdown.wait().await;
        c.cancel();
    });
    cancel
}
