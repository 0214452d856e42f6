//! The compaction task (`[storage] compact_after_hours`, default 24; 0 = off): every
//! [`PERIOD`] it has the writer archive samples older than that many hours, then, with
//! `[storage] raw_days` > 0, roll up steady samples older than that into 1-minute roll-ups
//! (retention) and, with `rollup_1m_days` > 0, merge minute roll-ups older than that into
//! hourly ones, then return freed pages to the file system in bounded steps (README "Storage
//! tiers").
//!
//! It goes through the one writer (`WriteCmd::Compact`, `WriteCmd::Retain`,
//! `WriteCmd::IncrementalVacuum`), a few chunks, batches or pages per request, each its own
//! transaction: the daemon keeps one writable connection, and acquisition's batches are
//! committed between two requests instead of waiting for a whole compaction. Must not hold
//! SQL.

use crate::shutdown::Shutdown;
use crate::store::{
    now_ms, RetentionPolicy, StorageConfig, WriteCmd, WriterHandle, DEFAULT_MAX_CHUNK_SAMPLES,
    VACUUM_STEP_PAGES,
};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Time between two compactions.
pub const PERIOD: Duration = Duration::from_secs(3600);
/// Wait after start before the first one (start-up stays light; a restart loop never compacts).
pub const FIRST_DELAY: Duration = Duration::from_secs(300);
/// Chunks per writer request.
const CHUNKS_PER_REQUEST: u64 = 4;
/// Retention batches (one tag's 6 h window each) per writer request.
const RETAIN_BATCHES_PER_REQUEST: u64 = 4;

/// The compaction task (mini-redis shape: a small struct with its own `run`).
pub struct CompactionTask {
    pub writer: WriterHandle,
    /// Samples older than this are archived (None: compaction off).
    pub after: Option<Duration>,
    /// Retention (None: off).
    pub retention: Option<RetentionPolicy>,
    pub first_delay: Duration,
    pub period: Duration,
    /// The task's [`CompactionReport`] as it goes, for the metrics endpoint.
    pub counters: Arc<CompactionCounters>,
}

/// What the compaction task did over the daemon's run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CompactionReport {
    pub chunks: u64,
    pub samples: u64,
    /// Raw samples replaced by roll-ups.
    pub rolled_up: u64,
    /// 1-minute roll-up rows merged into hourly roll-ups.
    pub minutes_merged: u64,
    /// Pages returned to the file system.
    pub vacuumed_pages: u64,
    pub failures: u64,
}

/// The compaction task's totals as it goes (the metrics endpoint reads them at each scrape).
#[derive(Debug, Default)]
pub struct CompactionCounters {
    /// Maintenance runs finished (compaction, retention and vacuum, each period).
    pub runs: AtomicU64,
    pub chunks: AtomicU64,
    pub samples: AtomicU64,
    pub rolled_up: AtomicU64,
    pub minutes_merged: AtomicU64,
    pub vacuumed_pages: AtomicU64,
    pub failures: AtomicU64,
    /// Unix ms when the last run finished (0: none yet).
    pub last_run_ms: AtomicU64,
}

impl CompactionCounters {
    fn publish(&self, r: &CompactionReport) {
        self.chunks.store(r.chunks, Ordering::Relaxed);
        self.samples.store(r.samples, Ordering::Relaxed);
        self.rolled_up.store(r.rolled_up, Ordering::Relaxed);
        self.minutes_merged
            .store(r.minutes_merged, Ordering::Relaxed);
        self.vacuumed_pages
            .store(r.vacuumed_pages, Ordering::Relaxed);
        self.failures.store(r.failures, Ordering::Relaxed);
    }
}

/// What one writer request did: `units` samples archived or rolled up (and minute rows
/// merged), or pages freed (0: nothing left), and for compaction the chunks written, for
/// retention the minute rows merged into hours.
struct Done {
    units: u64,
    chunks: u64,
    merged: u64,
}

/// One kind of repeated writer request: how to ask, and how much an answer did (0: done).
enum Step {
    Compact(i64),
    Retain(i64, RetentionPolicy),
    Vacuum,
}

impl CompactionTask {
    /// The task for `[storage]`, or None when both compaction and retention are off.
    pub fn from_config(writer: WriterHandle, storage: &StorageConfig) -> Option<CompactionTask> {
        let after = (storage.compact_after_hours > 0)
            .then(|| Duration::from_secs(u64::from(storage.compact_after_hours) * 3600));
        let retention = (storage.raw_days > 0).then(|| storage.retention());
        (after.is_some() || retention.is_some()).then_some(CompactionTask {
            writer,
            after,
            retention,
            first_delay: FIRST_DELAY,
            period: PERIOD,
            counters: Arc::default(),
        })
    }

    /// Compacts, retains and vacuums every `period` until shutdown.
    pub async fn run(self, mut shutdown: Shutdown) -> CompactionReport {
        let mut report = CompactionReport::default();
        let mut wait = self.first_delay;
        loop {
            tokio::select! {
                _ = shutdown.wait() => break,
                _ = tokio::time::sleep(wait) => {}
            }
            wait = self.period;
            if !self.round_at(now_ms(), &mut report, &mut shutdown).await {
                return report;
            }
        }
        report
    }

    /// One maintenance round as of `now` (Unix ms): archive what is older than `after`,
    /// apply retention, vacuum; `report` accumulates. False on shutdown. The daemon's clock
    /// gives `now`; `bench soak` gives its simulated one.
    pub async fn round_at(
        &self,
        now: i64,
        report: &mut CompactionReport,
        shutdown: &mut Shutdown,
    ) -> bool {
        let mut steps = Vec::new();
        if let Some(after) = self.after {
            steps.push(Step::Compact(
                now - i64::try_from(after.as_millis()).unwrap_or(i64::MAX),
            ));
        }
        if let Some(policy) = self.retention {
            steps.push(Step::Retain(now, policy));
        }
        steps.push(Step::Vacuum);
        for step in steps {
            let going_on = self.repeat(&step, report, shutdown).await;
            self.counters.publish(report);
            if !going_on {
                return false;
            }
        }
        self.counters.runs.fetch_add(1, Ordering::Relaxed);
        self.counters
            .last_run_ms
            .store(u64::try_from(now_ms()).unwrap_or(0), Ordering::Relaxed);
        true
    }

    /// Sends `step` until an answer says nothing is left; false on shutdown.
    async fn repeat(
        &self,
        step: &Step,
        report: &mut CompactionReport,
        shutdown: &mut Shutdown,
    ) -> bool {
        let mut done_total = 0u64;
        let mut chunks = 0u64;
        let mut merged = 0u64;
        loop {
            let answer = tokio::select! {
                _ = shutdown.wait() => return false,
                a = self.request(step) => a,
            };
            match answer {
                Ok(Done { units: 0, .. }) => break,
                Ok(d) => {
                    done_total += d.units;
                    chunks += d.chunks;
                    merged += d.merged;
                }
                Err(e) => {
                    report.failures += 1;
                    tracing::warn!("storage maintenance failed (retried next period): {e}");
                    break;
                }
            }
        }
        match step {
            Step::Compact(_) => {
                report.samples += done_total;
                report.chunks += chunks;
                if done_total > 0 {
                    tracing::info!(chunks, samples = done_total, "archived old samples");
                }
            }
            Step::Retain(..) => {
                let samples = done_total.saturating_sub(merged);
                report.rolled_up += samples;
                report.minutes_merged += merged;
                if done_total > 0 {
                    tracing::info!(
                        samples,
                        minutes_merged = merged,
                        "rolled up old steady samples"
                    );
                }
            }
            Step::Vacuum => report.vacuumed_pages += done_total,
        }
        true
    }

    /// One request and what it did.
    async fn request(&self, step: &Step) -> Result<Done, crate::store::StoreError> {
        match *step {
            Step::Compact(before_ms) => {
                let done = self
                    .writer
                    .request(|reply| WriteCmd::Compact {
                        before_ms,
                        max_chunk_samples: DEFAULT_MAX_CHUNK_SAMPLES,
                        max_chunks: CHUNKS_PER_REQUEST,
                        reply,
                    })
                    .await?;
                Ok(Done {
                    units: if done.chunks == 0 {
                        0
                    } else {
                        done.samples.max(1)
                    },
                    chunks: done.chunks,
                    merged: 0,
                })
            }
            Step::Retain(now_ms, policy) => {
                let done = self
                    .writer
                    .request(|reply| WriteCmd::Retain {
                        now_ms,
                        policy,
                        max_batches: RETAIN_BATCHES_PER_REQUEST,
                        reply,
                    })
                    .await?;
                // A batch may roll up nothing countable (a minute row merged into an
                // existing hour still counts one): units > 0 while there was work.
                Ok(Done {
                    units: if done.transactions() == 0 {
                        0
                    } else {
                        (done.samples_rolled_up + done.minutes_merged).max(1)
                    },
                    chunks: 0,
                    merged: done.minutes_merged,
                })
            }
            Step::Vacuum => {
                let pages = self
                    .writer
                    .request(|reply| WriteCmd::IncrementalVacuum {
                        max_pages: VACUUM_STEP_PAGES,
                        reply,
                    })
                    .await?;
                Ok(Done {
                    units: pages,
                    chunks: 0,
                    merged: 0,
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quality::Quality;
    use crate::shutdown::shutdown_channel;
    use crate::store::{spawn_writer, writer_channel, Sample, Store, TagInfo, WriterConfig};

    /// The task archives old samples through the writer, keeps recent ones hot, and stops on
    /// shutdown; the writer keeps taking samples meanwhile.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn the_task_archives_old_samples_through_the_writer() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| unreachable!("{e}"));
        let path = dir.path().join("c.db");
        let mut store = Store::open(&path).unwrap_or_else(|e| unreachable!("{e}"));
        let tag = store
            .ensure_tag(&TagInfo {
                name: "x".into(),
                unit: String::new(),
                signal: None,
            })
            .unwrap_or_else(|e| unreachable!("{e}"));
        let now = now_ms();
        let old: Vec<Sample> = (0..20_000i64)
            .map(|i| Sample {
                tag,
                t_ms: now - 10 * 86_400_000 + i * 10_000,
                value: i as f64 * 0.5,
                quality: Quality::Good,
            })
            .collect();
        store
            .insert_samples(&old)
            .unwrap_or_else(|e| unreachable!("{e}"));
        let (handle, rx) = writer_channel(16);
        let writer = spawn_writer(store, rx, WriterConfig::default());
        let (trigger, shutdown) = shutdown_channel();
        let counters = Arc::new(CompactionCounters::default());
        let task = tokio::spawn(
            CompactionTask {
                writer: handle.clone(),
                after: Some(Duration::from_secs(86_400)),
                retention: None,
                first_delay: Duration::ZERO,
                period: Duration::from_secs(3600),
                counters: Arc::clone(&counters),
            }
            .run(shutdown),
        );
        let fresh = Sample {
            tag,
            t_ms: now,
            value: 1.0,
            quality: Quality::Good,
        };
        handle
            .send(WriteCmd::Samples(vec![fresh]))
            .await
            .unwrap_or_else(|e| unreachable!("{e}"));
        let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
        let archived = loop {
            let a = Store::open_readonly(&path)
                .and_then(|s| s.archive_stats())
                .unwrap_or_else(|e| unreachable!("{e}"));
            // The task publishes its counters after each step: wait for that, not only for the
            // first chunk in the file (shutdown between the two left the report empty under
            // load).
            let published = counters.samples.load(Ordering::Relaxed) > 0;
            if (a.samples > 0 && published) || tokio::time::Instant::now() > deadline {
                break a;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        };
        trigger.trigger();
        let report = task.await.unwrap_or_else(|e| unreachable!("{e}"));
        handle.flush().await.unwrap_or_else(|e| unreachable!("{e}"));
        drop(handle);
        let _ = writer.await;
        assert!(archived.samples > 0, "nothing archived");
        let s = Store::open_readonly(&path).unwrap_or_else(|e| unreachable!("{e}"));
        let all = s
            .tag_samples_between(tag, i64::MIN, i64::MAX)
            .unwrap_or_else(|e| unreachable!("{e}"));
        assert_eq!(all.len(), old.len() + 1);
        assert!(all
            .iter()
            .zip(&old)
            .all(|(a, b)| a.t_ms == b.t_ms && a.value == b.value));
        assert_eq!(report.failures, 0);
        // The metrics read the same totals the task reports.
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        assert_eq!(get(&counters.samples), report.samples);
        assert_eq!(get(&counters.chunks), report.chunks);
        assert!(report.samples > 0 && report.chunks > 0);
        // Shutdown may come before the period's vacuum step ends: at most one run finished.
        assert!(get(&counters.runs) <= 1);
    }

    /// With `raw_days`, the task rolls up old steady samples through the writer (compaction
    /// off here), keeps a start-up's samples raw, with `rollup_1m_days` merges the minute rows
    /// into hours (counted for the metrics), and leaves nothing for a second run.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn the_task_rolls_up_old_steady_samples_through_the_writer() {
        use crate::segment::{Outcome, SegmentRecord};
        use crate::store::{RetentionPolicy, ScanWrite};
        let dir = tempfile::tempdir().unwrap_or_else(|e| unreachable!("{e}"));
        let path = dir.path().join("r.db");
        let mut store = Store::open(&path).unwrap_or_else(|e| unreachable!("{e}"));
        let tag = store
            .ensure_tag(&TagInfo {
                name: "x".into(),
                unit: String::new(),
                signal: None,
            })
            .unwrap_or_else(|e| unreachable!("{e}"));
        let now = now_ms();
        let t0 = (now - 10 * 86_400_000) / 60_000 * 60_000;
        let old: Vec<Sample> = (0..7200i64)
            .map(|i| Sample {
                tag,
                t_ms: t0 + i * 1000,
                value: i as f64,
                quality: Quality::Good,
            })
            .collect();
        store
            .insert_samples(&old)
            .unwrap_or_else(|e| unreachable!("{e}"));
        // A start-up in the second half hour; the detector has scanned everything.
        store
            .store_scan(&ScanWrite {
                records: vec![SegmentRecord {
                    start_ms: t0 + 1_800_000,
                    end_ms: Some(t0 + 1_860_000),
                    outcome: Outcome::Completed,
                    abort_cause: None,
                    hot_restart: false,
                    has_gap: false,
                    phases: Vec::new(),
                }],
                keep_from: t0,
                scanned_to: now,
                last_fuel_off_ms: None,
            })
            .unwrap_or_else(|e| unreachable!("{e}"));
        let (handle, rx) = writer_channel(16);
        let writer = spawn_writer(store, rx, WriterConfig::default());
        let (trigger, shutdown) = shutdown_channel();
        let policy = RetentionPolicy {
            raw_days: 1,
            segment_margin_s: 60,
            rollup_1m_days: 2,
        };
        let counters = Arc::new(CompactionCounters::default());
        let task = tokio::spawn(
            CompactionTask {
                writer: handle.clone(),
                after: None,
                retention: Some(policy),
                first_delay: Duration::ZERO,
                period: Duration::from_secs(3600),
                counters: Arc::clone(&counters),
            }
            .run(shutdown),
        );
        // 120 minutes, 4 of them kept raw: 116 minute rows, merged into hours.
        let minutes = 116u64;
        // Kept raw: [t0 + 29 min, t0 + 33 min): the segment ± 60 s is [29:00, 32:00], and
        // the sample at 32:00 keeps its whole minute.
        let kept = 240usize;
        let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
        loop {
            let n = Store::open_readonly(&path)
                .and_then(|s| s.sample_count())
                .unwrap_or_else(|e| unreachable!("{e}"));
            let merged = counters.minutes_merged.load(Ordering::Relaxed);
            if (n as usize == kept && merged == minutes) || tokio::time::Instant::now() > deadline {
                break;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        trigger.trigger();
        let report = task.await.unwrap_or_else(|e| unreachable!("{e}"));
        handle.flush().await.unwrap_or_else(|e| unreachable!("{e}"));
        drop(handle);
        let _ = writer.await;
        assert_eq!(report.rolled_up, (old.len() - kept) as u64);
        assert_eq!(report.minutes_merged, minutes);
        assert_eq!(report.failures, 0);
        let mut s = Store::open(&path).unwrap_or_else(|e| unreachable!("{e}"));
        let rows = s
            .tag_samples_between(tag, i64::MIN, i64::MAX)
            .unwrap_or_else(|e| unreachable!("{e}"));
        assert_eq!(rows.len(), kept);
        assert_eq!(rows[0].t_ms, t0 + 29 * 60_000);
        let outlook = s
            .storage_stats(now, &policy)
            .unwrap_or_else(|e| unreachable!("{e}"));
        assert_eq!(outlook.rollups.rows, 0);
        assert!((2..=3).contains(&outlook.rollups_1h.rows), "{outlook:?}");
        assert_eq!(outlook.rollups_1h.samples, (old.len() - kept) as u64);
        let again = s
            .apply_retention(now, &policy)
            .unwrap_or_else(|e| unreachable!("{e}"));
        assert_eq!(again.transactions(), 0);
    }
}
