//! The gap task (issue 23 item 4): in the background, at low priority, the daemon asks the
//! sim-to-real gap question of every start-up whose Method B fit is not `good` (and, on a
//! schedule, of every n-th start-up) and stores the answer, which the report shows.
//!
//! Priority: a step starts only when no closed start-up waits for its diagnosis
//! (`worker::gap::analyse_next` checks), and a running analysis is cancelled — storing
//! nothing, redone later — as soon as the detector closes another start-up, so the diagnosis
//! of new start-ups is not delayed by more than one cancellation check. Shutdown cancels it
//! the same way. Reads through its own read-only connection; the report is written by the one
//! writer. Must not hold the analysis (`crate::gap`) or SQL (`crate::store`).

use super::blocking::{BlockingError, BlockingStore};
use crate::optim::Cancel;
use crate::shutdown::Shutdown;
use crate::store::{ReadStore, StoreOptions, ViaWriter, WriterHandle};
use crate::worker::gap::{analyse_next, GapStep};
use crate::worker::WorkerContext;
use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// How often a running analysis looks whether it must yield, and how long the task waits
/// before looking for work again after an idle step.
const YIELD_CHECK: Duration = Duration::from_millis(500);

/// What the gap task did over the daemon's run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GapTaskReport {
    pub stored: u64,
    pub cancelled: u64,
    pub failed: u64,
}

/// The gap task's [`GapTaskReport`] as it goes, for the metrics endpoint.
#[derive(Debug, Default)]
pub struct GapCounters {
    pub stored: AtomicU64,
    pub cancelled: AtomicU64,
    pub failed: AtomicU64,
}

impl GapCounters {
    fn publish(&self, r: &GapTaskReport) {
        self.stored.store(r.stored, Ordering::Relaxed);
        self.cancelled.store(r.cancelled, Ordering::Relaxed);
        self.failed.store(r.failed, Ordering::Relaxed);
    }
}

/// The gap task (mini-redis shape: a small struct with its own `run`).
pub struct GapTask {
    pub db_path: PathBuf,
    pub store_opts: StoreOptions,
    pub writer: WriterHandle,
    pub ctx: Arc<WorkerContext>,
    /// The detector's count of closed segments: a change preempts a running analysis.
    pub closed: Arc<AtomicU64>,
    /// Time between looks for work when there is none.
    pub idle_period: Duration,
    /// The report so far, published after each step.
    pub counters: Arc<GapCounters>,
}

impl GapTask {
    /// Runs analyses one at a time until shutdown.
    pub async fn run(self, mut shutdown: Shutdown) -> GapTaskReport {
        let mut store = BlockingStore::read_only(self.db_path.clone(), self.store_opts);
        let mut report = GapTaskReport::default();
        // Start-ups that cannot be analysed are not retried until the next start.
        let mut skip: HashSet<i64> = HashSet::new();
        while !shutdown.is_triggered() {
            let idle = match self.step(&mut store, &skip, shutdown.clone()).await {
                Some(GapStep::Stored {
                    segment_id,
                    analysis_id,
                    effect,
                    wall_s,
                }) => {
                    report.stored += 1;
                    tracing::info!(
                        segment_id,
                        analysis_id,
                        effect = %effect,
                        wall_s,
                        "gap analysis stored"
                    );
                    false
                }
                Some(GapStep::Cancelled { segment_id }) => {
                    report.cancelled += 1;
                    tracing::info!(segment_id, "gap analysis yielded (redone later)");
                    false
                }
                Some(GapStep::Failed { segment_id, reason }) => {
                    report.failed += 1;
                    tracing::warn!(segment_id, %reason, "gap analysis failed");
                    skip.insert(segment_id);
                    false
                }
                Some(GapStep::Idle) | None => true,
            };
            self.counters.publish(&report);
            if idle {
                tokio::select! {
                    _ = shutdown.wait() => break,
                    _ = tokio::time::sleep(self.idle_period) => {}
                }
            }
        }
        report
    }

    /// One step on the blocking pool, cancelled when shutdown fires or a segment closes.
    async fn step(
        &self,
        store: &mut BlockingStore<ReadStore>,
        skip: &HashSet<i64>,
        shutdown: Shutdown,
    ) -> Option<GapStep> {
        let cancel = Cancel::new();
        let watcher = tokio::spawn(yield_when(
            cancel.clone(),
            shutdown,
            Arc::clone(&self.closed),
        ));
        let ctx = Arc::clone(&self.ctx);
        let writer = self.writer.clone();
        let skip = skip.clone();
        let c = cancel.clone();
        let work = move |read: &mut ReadStore| {
            let mut db = ViaWriter {
                read,
                writer: &writer,
            };
            analyse_next(&mut db, &ctx, &c, &skip)
        };
        let out = store.run(work).await;
        watcher.abort();
        match out {
            Ok(step) => Some(step),
            Err(BlockingError::Panicked(e)) => {
                tracing::error!("gap task failed: {e}");
                None
            }
            Err(e) => {
                tracing::warn!("gap task: {e}");
                None
            }
        }
    }
}

/// Sets `cancel` when `shutdown` fires or `closed` moves.
async fn yield_when(cancel: Cancel, mut shutdown: Shutdown, closed: Arc<AtomicU64>) {
    let at_start = closed.load(Ordering::Relaxed);
    loop {
        tokio::select! {
            _ = shutdown.wait() => break,
            _ = tokio::time::sleep(YIELD_CHECK) => {
                if closed.load(Ordering::Relaxed) != at_start {
                    break;
                }
            }
        }
    }
    cancel.cancel();
}
