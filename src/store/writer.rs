//! The single writer task: owns the writable [`Store`], batches samples into transactions.
//!
//! Flushes when the buffer reaches `batch_size` samples or when the oldest buffered sample has
//! waited `flush_interval`; on `Flush` it commits and acknowledges; when the channel closes it
//! commits what it holds and returns its statistics. SQLite work runs on the blocking pool so
//! the async acquisition is never stalled by a commit. Must not decide what to store.

use super::{insert_samples_in, record_gap_in, Gap, Sample, Store, StoreError};
use std::time::Duration;
use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

/// A request to the writer.
#[derive(Debug)]
pub enum WriteCmd {
    Samples(Vec<Sample>),
    Gap(Gap),
    /// Commit everything received so far, then answer.
    Flush(oneshot::Sender<()>),
}

/// Writer batching settings (from `[storage]`, see `StorageConfig::writer`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WriterConfig {
    pub batch_size: usize,
    pub flush_interval: Duration,
}

impl Default for WriterConfig {
    fn default() -> Self {
        super::StorageConfig::default().writer()
    }
}

/// What the writer did over its lifetime.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WriterStats {
    /// Samples received.
    pub samples_received: u64,
    /// Samples that were new and were stored.
    pub samples_inserted: u64,
    /// Samples already present (same tag and time), left untouched.
    pub samples_duplicate: u64,
    pub gaps: u64,
    /// Committed transactions.
    pub transactions: u64,
}

struct Pending {
    samples: Vec<Sample>,
    gaps: Vec<Gap>,
    since: Option<Instant>,
}

impl Pending {
    fn is_empty(&self) -> bool {
        self.samples.is_empty() && self.gaps.is_empty()
    }
}

/// Starts the writer on the current tokio runtime. It ends when every sender is dropped,
/// after a final commit, returning its statistics (or the first database error).
pub fn spawn_writer(
    store: Store,
    rx: mpsc::Receiver<WriteCmd>,
    cfg: WriterConfig,
) -> tokio::task::JoinHandle<Result<WriterStats, StoreError>> {
    tokio::spawn(run_writer(store, rx, cfg))
}

async fn run_writer(
    mut store: Store,
    mut rx: mpsc::Receiver<WriteCmd>,
    cfg: WriterConfig,
) -> Result<WriterStats, StoreError> {
    let mut stats = WriterStats::default();
    let mut pending = Pending {
        samples: Vec::with_capacity(cfg.batch_size),
        gaps: Vec::new(),
        since: None,
    };
    loop {
        let deadline = pending.since.map(|t| t + cfg.flush_interval);
        let cmd = match deadline {
            Some(d) => match tokio::time::timeout_at(d, rx.recv()).await {
                Ok(c) => c,
                Err(_elapsed) => {
                    store = flush(store, &mut pending, &mut stats).await?;
                    continue;
                }
            },
            None => rx.recv().await,
        };
        match cmd {
            None => {
                store = flush(store, &mut pending, &mut stats).await?;
                drop(store);
                return Ok(stats);
            }
            Some(WriteCmd::Samples(batch)) => {
                stats.samples_received += batch.len() as u64;
                pending.samples.extend(batch);
                pending.since.get_or_insert_with(Instant::now);
                if pending.samples.len() >= cfg.batch_size {
                    store = flush(store, &mut pending, &mut stats).await?;
                }
            }
            Some(WriteCmd::Gap(g)) => {
                pending.gaps.push(g);
                pending.since.get_or_insert_with(Instant::now);
            }
            Some(WriteCmd::Flush(ack)) => {
                store = flush(store, &mut pending, &mut stats).await?;
                // The requester may have given up waiting; nothing to do then.
                let _ = ack.send(());
            }
        }
    }
}

/// Commits the pending samples and gaps in one transaction on the blocking pool.
async fn flush(
    store: Store,
    pending: &mut Pending,
    stats: &mut WriterStats,
) -> Result<Store, StoreError> {
    pending.since = None;
    if pending.is_empty() {
        return Ok(store);
    }
    let samples = std::mem::take(&mut pending.samples);
    let gaps = std::mem::take(&mut pending.gaps);
    let n_gaps = gaps.len() as u64;
    let n_samples = samples.len() as u64;
    let (store, result) = tokio::task::spawn_blocking(move || {
        let mut store = store;
        let r = commit(&mut store, &samples, &gaps);
        (store, r)
    })
    .await
    .map_err(|e| StoreError::Writer(e.to_string()))?;
    let inserted = result? as u64;
    stats.samples_inserted += inserted;
    stats.samples_duplicate += n_samples - inserted;
    stats.gaps += n_gaps;
    stats.transactions += 1;
    Ok(store)
}

fn commit(store: &mut Store, samples: &[Sample], gaps: &[Gap]) -> Result<usize, StoreError> {
    let tx = store.conn_mut().transaction()?;
    let n = insert_samples_in(&tx, samples)?;
    for g in gaps {
        record_gap_in(&tx, g)?;
    }
    tx.commit()?;
    Ok(n)
}
