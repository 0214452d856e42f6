//! The compaction task (`[storage] compact_after_hours`, default 24; 0 = off): every
//! [`PERIOD`] it has the writer archive samples older than that many hours (README "Storage
//! tiers").
//!
//! It goes through the one writer (`WriteCmd::Compact`), a few chunks per request, each chunk
//! its own transaction: the daemon keeps one writable connection, and acquisition's batches
//! are committed between two requests instead of waiting for a whole compaction. Must not
//! hold SQL.

use crate::shutdown::Shutdown;
use crate::store::{now_ms, CompactStats, WriteCmd, WriterHandle, DEFAULT_MAX_CHUNK_SAMPLES};
use std::time::Duration;

/// Time between two compactions.
pub const PERIOD: Duration = Duration::from_secs(3600);
/// Wait after start before the first one (start-up stays light; a restart loop never compacts).
pub const FIRST_DELAY: Duration = Duration::from_secs(300);
/// Chunks per writer request.
const CHUNKS_PER_REQUEST: u64 = 4;

/// The compaction task (mini-redis shape: a small struct with its own `run`).
pub struct CompactionTask {
    pub writer: WriterHandle,
    /// Samples older than this are archived.
    pub after: Duration,
    pub first_delay: Duration,
    pub period: Duration,
}

/// What the compaction task did over the daemon's run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CompactionReport {
    pub chunks: u64,
    pub samples: u64,
    pub failures: u64,
}

impl CompactionTask {
    pub fn new(writer: WriterHandle, compact_after_hours: u32) -> CompactionTask {
        CompactionTask {
            writer,
            after: Duration::from_secs(u64::from(compact_after_hours) * 3600),
            first_delay: FIRST_DELAY,
            period: PERIOD,
        }
    }

    /// Compacts every `period` until shutdown.
    pub async fn run(self, mut shutdown: Shutdown) -> CompactionReport {
        let mut report = CompactionReport::default();
        let mut wait = self.first_delay;
        loop {
            tokio::select! {
                _ = shutdown.wait() => break,
                _ = tokio::time::sleep(wait) => {}
            }
            wait = self.period;
            let before_ms = now_ms() - i64::try_from(self.after.as_millis()).unwrap_or(i64::MAX);
            let mut round = CompactStats::default();
            loop {
                let answer = tokio::select! {
                    _ = shutdown.wait() => return report,
                    a = self.writer.request(|reply| WriteCmd::Compact {
                        before_ms,
                        max_chunk_samples: DEFAULT_MAX_CHUNK_SAMPLES,
                        max_chunks: CHUNKS_PER_REQUEST,
                        reply,
                    }) => a,
                };
                match answer {
                    Ok(done) if done.chunks == 0 => break,
                    Ok(done) => {
                        round.chunks += done.chunks;
                        round.samples += done.samples;
                        round.blob_bytes += done.blob_bytes;
                    }
                    Err(e) => {
                        report.failures += 1;
                        tracing::warn!("compaction failed (retried next period): {e}");
                        break;
                    }
                }
            }
            report.chunks += round.chunks;
            report.samples += round.samples;
            if round.chunks > 0 {
                tracing::info!(
                    chunks = round.chunks,
                    samples = round.samples,
                    blob_bytes = round.blob_bytes,
                    "archived old samples"
                );
            }
        }
        report
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
        let task = tokio::spawn(
            CompactionTask {
                writer: handle.clone(),
                after: Duration::from_secs(86_400),
                first_delay: Duration::ZERO,
                period: Duration::from_secs(3600),
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
            if a.samples > 0 || tokio::time::Instant::now() > deadline {
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
    }
}
