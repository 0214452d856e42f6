//! The single writer task: owns the writable [`Store`], batches samples into transactions and
//! carries out the other tasks' typed write requests (a detector scan, a diagnosis outcome,
//! the wash advice), each in its own transaction, answering each with its result.
//!
//! Flushes when the buffer reaches `batch_size` samples or when the oldest buffered sample has
//! waited `flush_interval`; on `Flush` it commits and acknowledges; when the channel closes it
//! commits what it holds and returns its statistics. SQLite work runs on the blocking pool so
//! the async acquisition is never stalled by a commit. Every committed batch is logged at debug
//! level ("batch committed", with the newest sample time and the running total): what that
//! line reports is on disk. Must not decide what to store. The senders' side of the channel
//! (back-pressure, requests and their answers) is [`super::WriterHandle`].
//!
//! Write failures (disk full `SQLITE_FULL`, a read-only file or directory, I/O errors) do not
//! stop the writer (issue 12 #2): the failed batch stays in memory (a transaction commits all or
//! nothing, so nothing is half-written) and is retried with exponential backoff (0.25 s doubling
//! to 30 s); the cause is logged at error level once per episode and the recovery once.
//! Commands keep being received, so acquisition keeps polling. The buffer is bounded
//! (`max_buffered`, default 200 × `batch_size`): samples arriving while it is full are
//! dropped and their time span recorded as a gap (`source = "writer"`, reason
//! `writer_buffer_full: <cause>`), written once the database accepts writes again. `Flush`
//! requests are answered once their data is committed. When the channel closes during an
//! episode the writer retries for `close_retry` more (default 5 s), then returns the error.

use super::{
    insert_samples_in, record_gap_in, AdviceWrite, Gap, NewGapAnalysis, NewOutcome, Sample,
    ScanWrite, Store, StoreError,
};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

pub use super::channel::{writer_channel, WriterHandle};

/// Where the writer answers a request: its result, once committed (or the error).
pub(super) type Reply<T> = oneshot::Sender<Result<T, StoreError>>;

/// A request to the writer.
#[derive(Debug)]
pub enum WriteCmd {
    Samples(Vec<Sample>),
    Gap(Gap),
    /// Commit everything received so far, then answer.
    Flush(oneshot::Sender<()>),
    /// The daemon (re)started after data up to `start_ms` was stored: when the first new
    /// samples arrive, record a gap from `start_ms` to the earliest of them (`end_ms` of the
    /// template is ignored). Used for the `daemon_restart` gap, also after kill -9.
    GapUntilNextSample(Gap),
    /// Store one detector scan ([`Store::store_scan`]); answers with the segments written.
    Detection {
        scan: ScanWrite,
        reply: Reply<u64>,
    },
    /// Store one segment's diagnosis outcome ([`Store::store_outcome`]); answers with the ids
    /// of the results.
    Diagnosis {
        outcome: NewOutcome,
        reply: Reply<Vec<i64>>,
    },
    /// Store one refresh of the wash advice ([`Store::store_advice`]); answers with the ids of
    /// the detected washes.
    Advice {
        advice: AdviceWrite,
        reply: Reply<Vec<i64>>,
    },
    /// Store one gap analysis ([`Store::insert_gap_analysis`]); answers with its id.
    GapAnalysis {
        analysis: Box<NewGapAnalysis>,
        reply: Reply<i64>,
    },
    /// Store one fleet-sync high-water mark ([`Store::save_fleet_mark`]), sent once the
    /// centre committed the batch it covers.
    FleetMark {
        mark: super::FleetMark,
        reply: Reply<()>,
    },
    /// Archive up to `max_chunks` chunks of samples older than `before_ms`
    /// ([`Store::compact_some`], one transaction per chunk); answers with what it moved (0
    /// chunks: nothing left to archive). The daemon's compaction task sends it repeatedly, so
    /// the writer never holds the samples of acquisition back for long.
    Compact {
        before_ms: i64,
        max_chunk_samples: usize,
        max_chunks: u64,
        reply: Reply<super::CompactStats>,
    },
    /// Roll up at most `max_batches` batches of steady samples older than the policy's
    /// `raw_days`, then merge minute roll-ups older than `rollup_1m_days` into hours with the
    /// batches left ([`Store::apply_retention_some`], one transaction per batch); answers with
    /// what it did (0 transactions: nothing left).
    Retain {
        now_ms: i64,
        policy: super::RetentionPolicy,
        max_batches: u64,
        reply: Reply<super::RetainStats>,
    },
    /// Return at most `max_pages` free pages to the file system
    /// ([`Store::incremental_vacuum_step`]); answers with the pages freed (0: none left, or
    /// the file is not in `auto_vacuum = INCREMENTAL` mode).
    IncrementalVacuum {
        max_pages: u32,
        reply: Reply<u64>,
    },
}

/// Writer batching settings (from `[storage]`, see `StorageConfig::writer`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WriterConfig {
    pub batch_size: usize,
    pub flush_interval: Duration,
    /// Samples held while the database refuses writes; beyond this they are dropped and a
    /// gap is recorded. `0` = 200 × `batch_size`.
    pub max_buffered: usize,
    /// First retry delay after a failed commit (doubles up to 30 s).
    pub retry_initial: Duration,
    /// How long the writer keeps retrying after the channel closed.
    pub close_retry: Duration,
}

impl Default for WriterConfig {
    fn default() -> Self {
        super::StorageConfig::default().writer()
    }
}

impl WriterConfig {
    fn buffer_limit(&self) -> usize {
        if self.max_buffered == 0 {
            self.batch_size.saturating_mul(200).max(1)
        } else {
            self.max_buffered
        }
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
    /// Failed commit attempts (each is retried).
    pub write_errors: u64,
    /// Episodes of failing writes (first failure to recovery).
    pub write_error_episodes: u64,
    /// Samples dropped because the buffer was full during a write-error episode (each span is
    /// recorded as a gap).
    pub samples_dropped: u64,
    /// Write requests carried out (detector scans, diagnosis outcomes, wash advice).
    pub requests: u64,
    /// Write requests that failed (answered with the error; the sender logs and retries).
    pub request_errors: u64,
    /// Times a sender found the channel full and waited (back-pressure; counted by the
    /// senders' [`WriterHandle`], filled in by whoever owns it).
    pub channel_full_waits: u64,
}

/// The writer's running totals as atomics, updated after every command (and every timed
/// flush), for readers that must not wait for the writer: the daemon's metrics endpoint.
/// Mirrors the fields of [`WriterStats`] that a monitor watches.
#[derive(Debug, Default)]
pub struct WriterProgress {
    pub samples_inserted: AtomicU64,
    pub samples_duplicate: AtomicU64,
    pub gaps: AtomicU64,
    pub transactions: AtomicU64,
    pub write_errors: AtomicU64,
    pub samples_dropped: AtomicU64,
    pub requests: AtomicU64,
    pub request_errors: AtomicU64,
}

impl WriterProgress {
    fn publish(&self, s: &WriterStats) {
        let set = |a: &AtomicU64, v: u64| a.store(v, Ordering::Relaxed);
        set(&self.samples_inserted, s.samples_inserted);
        set(&self.samples_duplicate, s.samples_duplicate);
        set(&self.gaps, s.gaps);
        set(&self.transactions, s.transactions);
        set(&self.write_errors, s.write_errors);
        set(&self.samples_dropped, s.samples_dropped);
        set(&self.requests, s.requests);
        set(&self.request_errors, s.request_errors);
    }
}

struct Pending {
    samples: Vec<Sample>,
    gaps: Vec<Gap>,
    since: Option<Instant>,
    acks: Vec<oneshot::Sender<()>>,
}

impl Pending {
    fn is_empty(&self) -> bool {
        self.samples.is_empty() && self.gaps.is_empty()
    }
}

/// The state of a write-error episode.
struct Failing {
    cause: String,
    next_try: Instant,
    delay: Duration,
    /// Span of the samples dropped since the buffer filled (recorded as one gap).
    dropped: Option<(i64, i64)>,
}

const RETRY_MAX: Duration = Duration::from_secs(30);

/// Starts the writer on the current tokio runtime. It ends when every sender is dropped,
/// after a final commit, returning its statistics (or the database error that persisted
/// through the final retries).
pub fn spawn_writer(
    store: Store,
    rx: mpsc::Receiver<WriteCmd>,
    cfg: WriterConfig,
) -> tokio::task::JoinHandle<Result<WriterStats, StoreError>> {
    tokio::spawn(run_writer(store, rx, cfg))
}

struct Writer {
    store: Option<Store>,
    cfg: WriterConfig,
    stats: WriterStats,
    pending: Pending,
    failing: Option<Failing>,
    open_gap: Option<Gap>,
}

impl Writer {
    /// Tries to commit everything pending; on failure keeps it and enters/extends an episode.
    async fn flush(&mut self) -> Result<(), StoreError> {
        self.pending.since = None;
        if let Some(f) = self.failing.as_mut() {
            if let Some((a, b)) = f.dropped.take() {
                self.pending.gaps.push(Gap {
                    start_ms: a,
                    end_ms: b,
                    source: "writer".to_string(),
                    reason: format!("writer_buffer_full: {}", f.cause),
                });
            }
        }
        if self.pending.is_empty() {
            for a in self.pending.acks.drain(..) {
                let _ = a.send(());
            }
            return Ok(());
        }
        let samples = std::mem::take(&mut self.pending.samples);
        let gaps = std::mem::take(&mut self.pending.gaps);
        let store = self
            .store
            .take()
            .ok_or_else(|| StoreError::Writer("store lost".to_string()))?;
        let (store, samples, gaps, result) = tokio::task::spawn_blocking(move || {
            let mut store = store;
            let r = commit(&mut store, &samples, &gaps);
            (store, samples, gaps, r)
        })
        .await
        .map_err(|e| StoreError::Writer(e.to_string()))?;
        self.store = Some(store);
        match result {
            Ok(inserted) => {
                let inserted = inserted as u64;
                self.stats.samples_inserted += inserted;
                self.stats.samples_duplicate += samples.len() as u64 - inserted;
                self.stats.gaps += gaps.len() as u64;
                self.stats.transactions += 1;
                tracing::debug!(
                    samples = samples.len(),
                    through_ms = samples.iter().map(|s| s.t_ms).max().unwrap_or(0),
                    inserted_total = self.stats.samples_inserted,
                    "batch committed"
                );
                if let Some(f) = self.failing.take() {
                    tracing::warn!(
                        cause = %f.cause,
                        samples = samples.len(),
                        dropped = self.stats.samples_dropped,
                        "database writes work again; buffered samples committed"
                    );
                }
                for a in self.pending.acks.drain(..) {
                    let _ = a.send(());
                }
                Ok(())
            }
            Err(e) => {
                self.stats.write_errors += 1;
                // Put the batch back in front of anything that arrived meanwhile.
                let mut s = samples;
                s.append(&mut self.pending.samples);
                self.pending.samples = s;
                let mut g = gaps;
                g.append(&mut self.pending.gaps);
                self.pending.gaps = g;
                let cause = error_chain(&e);
                match self.failing.as_mut() {
                    Some(f) => {
                        f.delay = (f.delay * 2).min(RETRY_MAX);
                        f.next_try = Instant::now() + f.delay;
                        f.cause = cause;
                    }
                    None => {
                        self.stats.write_error_episodes += 1;
                        tracing::error!(
                            path = %self.store.as_ref().map(|s| s.path().display().to_string()).unwrap_or_default(),
                            cause = %cause,
                            buffered = self.pending.samples.len(),
                            "database write failed; keeping the batch and retrying with backoff"
                        );
                        self.failing = Some(Failing {
                            cause,
                            next_try: Instant::now() + self.cfg.retry_initial,
                            delay: self.cfg.retry_initial,
                            dropped: None,
                        });
                    }
                }
                Err(e)
            }
        }
    }

    /// Carries out one write request on the blocking pool, in its own transaction; pending
    /// samples stay buffered. A failure is counted and answered; it starts no episode (the
    /// sender decides whether to retry).
    async fn apply<T: Send + 'static>(
        &mut self,
        work: impl FnOnce(&mut Store) -> Result<T, StoreError> + Send + 'static,
    ) -> Result<T, StoreError> {
        let mut store = self
            .store
            .take()
            .ok_or_else(|| StoreError::Writer("store lost".to_string()))?;
        let (store, result) = tokio::task::spawn_blocking(move || {
            let r = work(&mut store);
            (store, r)
        })
        .await
        .map_err(|e| StoreError::Writer(e.to_string()))?;
        self.store = Some(store);
        self.stats.requests += 1;
        if let Err(e) = &result {
            self.stats.request_errors += 1;
            tracing::warn!(cause = %error_chain(e), "write request failed");
        }
        result
    }

    /// Answers a request with its result (a sender that gave up waiting is not an error).
    async fn answer<T: Send + 'static>(
        &mut self,
        reply: Reply<T>,
        work: impl FnOnce(&mut Store) -> Result<T, StoreError> + Send + 'static,
    ) {
        let r = self.apply(work).await;
        let _ = reply.send(r);
    }

    fn accept_samples(&mut self, batch: Vec<Sample>) {
        self.stats.samples_received += batch.len() as u64;
        if let Some(first) = batch.iter().map(|s| s.t_ms).min() {
            if let Some(g) = self.open_gap.take() {
                if first > g.start_ms {
                    self.pending.gaps.push(Gap { end_ms: first, ..g });
                }
            }
        }
        let room = self
            .cfg
            .buffer_limit()
            .saturating_sub(self.pending.samples.len());
        if let (Some(f), true) = (self.failing.as_mut(), batch.len() > room) {
            let mut batch = batch;
            let over = batch.split_off(room);
            for s in &over {
                f.dropped = Some(match f.dropped {
                    Some((a, b)) => (a.min(s.t_ms), b.max(s.t_ms)),
                    None => (s.t_ms, s.t_ms),
                });
            }
            self.stats.samples_dropped += over.len() as u64;
            self.pending.samples.extend(batch);
        } else {
            self.pending.samples.extend(batch);
        }
        self.pending.since.get_or_insert_with(Instant::now);
    }
}

/// The writer itself (what [`spawn_writer`] spawns): runs until every sender is gone, then
/// commits what it holds and returns its statistics.
pub async fn run_writer(
    store: Store,
    rx: mpsc::Receiver<WriteCmd>,
    cfg: WriterConfig,
) -> Result<WriterStats, StoreError> {
    run_writer_with_progress(store, rx, cfg, Arc::default()).await
}

/// [`run_writer`], publishing its running totals in `progress` as it goes.
pub async fn run_writer_with_progress(
    store: Store,
    mut rx: mpsc::Receiver<WriteCmd>,
    cfg: WriterConfig,
    progress: Arc<WriterProgress>,
) -> Result<WriterStats, StoreError> {
    let mut w = Writer {
        store: Some(store),
        cfg,
        stats: WriterStats::default(),
        pending: Pending {
            samples: Vec::with_capacity(cfg.batch_size.min(1 << 16)),
            gaps: Vec::new(),
            since: None,
            acks: Vec::new(),
        },
        failing: None,
        open_gap: None,
    };
    loop {
        progress.publish(&w.stats);
        // While failing, the next attempt is at the backoff time; otherwise at the flush
        // interval after the oldest buffered sample.
        let deadline = match &w.failing {
            Some(f) => Some(f.next_try),
            None => w.pending.since.map(|t| t + cfg.flush_interval),
        };
        let cmd = match deadline {
            Some(d) => match tokio::time::timeout_at(d, rx.recv()).await {
                Ok(c) => c,
                Err(_elapsed) => {
                    let _ = w.flush().await;
                    continue;
                }
            },
            None => rx.recv().await,
        };
        match cmd {
            None => {
                let give_up = Instant::now() + cfg.close_retry;
                loop {
                    let flushed = w.flush().await;
                    progress.publish(&w.stats);
                    match flushed {
                        Ok(()) => return Ok(w.stats),
                        Err(e) => {
                            let next = w.failing.as_ref().map_or(give_up, |f| f.next_try);
                            if next >= give_up {
                                tracing::error!(
                                    lost = w.pending.samples.len(),
                                    cause = %error_chain(&e),
                                    "writer stopping with samples it could not commit"
                                );
                                return Err(e);
                            }
                            tokio::time::sleep_until(next).await;
                        }
                    }
                }
            }
            Some(WriteCmd::Samples(batch)) => {
                w.accept_samples(batch);
                if w.failing.is_none() && w.pending.samples.len() >= cfg.batch_size {
                    let _ = w.flush().await;
                }
            }
            Some(WriteCmd::GapUntilNextSample(g)) => w.open_gap = Some(g),
            Some(WriteCmd::Gap(g)) => {
                w.pending.gaps.push(g);
                w.pending.since.get_or_insert_with(Instant::now);
            }
            Some(WriteCmd::Flush(ack)) => {
                // Answered once the data is committed (at once unless writes are failing).
                w.pending.acks.push(ack);
                if w.failing.is_none() {
                    let _ = w.flush().await;
                }
            }
            Some(WriteCmd::Detection { scan, reply }) => {
                w.answer(reply, move |s| s.store_scan(&scan)).await;
            }
            Some(WriteCmd::Diagnosis { outcome, reply }) => {
                w.answer(reply, move |s| s.store_outcome(&outcome)).await;
            }
            Some(WriteCmd::Advice { advice, reply }) => {
                w.answer(reply, move |s| s.store_advice(&advice)).await;
            }
            Some(WriteCmd::GapAnalysis { analysis, reply }) => {
                w.answer(reply, move |s| s.insert_gap_analysis(&analysis))
                    .await;
            }
            Some(WriteCmd::FleetMark { mark, reply }) => {
                w.answer(reply, move |s| s.save_fleet_mark(&mark)).await;
            }
            Some(WriteCmd::Compact {
                before_ms,
                max_chunk_samples,
                max_chunks,
                reply,
            }) => {
                w.answer(reply, move |s| {
                    s.compact_some(before_ms, max_chunk_samples, max_chunks)
                })
                .await;
            }
            Some(WriteCmd::Retain {
                now_ms,
                policy,
                max_batches,
                reply,
            }) => {
                w.answer(reply, move |s| {
                    s.apply_retention_some(now_ms, &policy, max_batches)
                })
                .await;
            }
            Some(WriteCmd::IncrementalVacuum { max_pages, reply }) => {
                w.answer(reply, move |s| s.incremental_vacuum_step(max_pages))
                    .await;
            }
        }
    }
}

/// The error and its sources, once each.
fn error_chain(e: &StoreError) -> String {
    let mut out = e.to_string();
    let mut src = std::error::Error::source(e);
    while let Some(s) = src {
        let t = s.to_string();
        if !out.contains(&t) {
            out.push_str(": ");
            out.push_str(&t);
        }
        src = s.source();
    }
    out
}

fn commit(store: &mut Store, samples: &[Sample], gaps: &[Gap]) -> Result<usize, StoreError> {
    // Immediate: the sample inserts read the archive's coverage before they write, and a
    // deferred transaction that read first cannot wait for another writer (SQLITE_BUSY at once).
    let tx = store
        .conn_mut()
        .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
    let n = insert_samples_in(&tx, samples)?;
    for g in gaps {
        record_gap_in(&tx, g)?;
    }
    tx.commit()?;
    Ok(n)
}
