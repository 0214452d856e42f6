//! The metrics task (`[metrics] listen`): serves `GET /metrics` — the page of
//! `crate::metrics::Exposition` — over plain HTTP/1.1 on a tokio `TcpListener`, one short-lived
//! connection per scrape (`Connection: close`), until shutdown. The page is built at each
//! scrape from [`Live`]: the atomics the other tasks already keep (poll progress, the writer's
//! running totals, the detector's closed segments, the diagnosis meter, the gap task's
//! counters), so a scrape costs the daemon a few atomic loads and one string.
//!
//! Must never disturb acquisition: it takes no lock another task holds across an await, reads
//! no database, sends nothing to the writer; a bad request, a slow client (5 s to send its
//! request head) or a failed accept is logged and dropped. An address that cannot be bound is
//! logged at error level and the daemon runs without the endpoint. Must not hold counting logic
//! (the tasks count) or the exposition format (`crate::metrics`).

use super::diagnosis::DiagnosisMeter;
use super::gap::GapCounters;
use crate::acquire::modbus::PollProgress;
use crate::metrics::{DurationHistogram, Exposition, Snapshot, CONTENT_TYPE};
use crate::shutdown::Shutdown;
use crate::store::WriterProgress;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// Longest request head read (a scraper's is a few hundred bytes).
const MAX_HEAD: usize = 8 * 1024;
/// Time a client has to send its request head, and to take the answer.
const CLIENT_TIMEOUT: Duration = Duration::from_secs(5);

/// The live counters of the running daemon, read at each scrape.
#[derive(Clone)]
pub struct Live {
    pub poll: Arc<PollProgress>,
    pub writer: Arc<WriterProgress>,
    /// Start-up segments the detector closed (`DetectorTask::closed`).
    pub segments_closed: Arc<AtomicU64>,
    /// `None`: no diagnosis in this run.
    pub diagnosis: Option<Arc<DiagnosisMeter>>,
    pub gap: Arc<GapCounters>,
    /// `None`: no `[fleet]` in this run.
    pub sync: Option<Arc<super::SyncCounters>>,
    /// `None`: compaction and retention off in this run.
    pub compaction: Option<Arc<super::CompactionCounters>>,
}

impl Live {
    /// The counters now.
    pub fn snapshot(&self) -> Snapshot {
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        let p = &self.poll;
        let w = &self.writer;
        let d = self.diagnosis.as_deref();
        Snapshot {
            polls_ok: get(&p.polls_ok),
            polls_failed: get(&p.failures),
            connects: get(&p.connects),
            poll_gaps: get(&p.gaps),
            samples_polled: get(&p.samples),
            samples_flagged: get(&p.flagged),
            samples_written: get(&w.samples_inserted),
            gaps_written: get(&w.gaps),
            write_errors: get(&w.write_errors),
            samples_dropped: get(&w.samples_dropped),
            segments_closed: get(&self.segments_closed),
            diagnosed: d.map_or(0, |d| get(&d.diagnosed)),
            undiagnosable: d.map_or(0, |d| get(&d.undiagnosable)),
            diagnosis_queue: d.map(|d| get(&d.queue)),
            gap_stored: get(&self.gap.stored),
            gap_cancelled: get(&self.gap.cancelled),
            gap_failed: get(&self.gap.failed),
            fleet: self.sync.as_deref().map(|f| crate::metrics::FleetSnapshot {
                syncs_ok: get(&f.syncs_ok),
                syncs_failed: get(&f.syncs_failed),
                rows_sent: get(&f.rows_sent),
                last_ok_ms: get(&f.last_ok_ms),
                lag_rows: f.lag(),
            }),
            compaction: self
                .compaction
                .as_deref()
                .map(|c| crate::metrics::CompactionSnapshot {
                    runs: get(&c.runs),
                    chunks: get(&c.chunks),
                    samples_archived: get(&c.samples),
                    samples_rolled_up: get(&c.rolled_up),
                    rollup_minutes_merged: get(&c.minutes_merged),
                    pages_vacuumed: get(&c.vacuumed_pages),
                    failures: get(&c.failures),
                    last_run_ms: get(&c.last_run_ms),
                }),
        }
    }

    fn durations(&self) -> DurationHistogram {
        self.diagnosis
            .as_ref()
            .map_or_else(DurationHistogram::default, |d| d.durations.clone())
    }
}

/// The metrics task (mini-redis shape: a small struct with its own `run`).
pub struct MetricsTask {
    listener: TcpListener,
    exposition: Arc<Exposition>,
}

impl MetricsTask {
    /// Binds `addr` (port 0: any free port) and logs the bound address ("metrics endpoint
    /// listening", `addr`); `None` (logged at error level) if it cannot be bound.
    pub async fn bind(addr: SocketAddr, live: Live) -> Option<MetricsTask> {
        let listener = match TcpListener::bind(addr).await {
            Ok(l) => l,
            Err(e) => {
                tracing::error!(%addr, "metrics endpoint not started: cannot listen: {e}");
                return None;
            }
        };
        let bound = listener.local_addr().unwrap_or(addr);
        tracing::info!(addr = %bound, "metrics endpoint listening on http://{bound}/metrics");
        let durations = live.durations();
        let exposition = Arc::new(Exposition::new(move || live.snapshot(), &durations));
        Some(MetricsTask {
            listener,
            exposition,
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// Answers scrapes until shutdown, each connection in a task of its own.
    pub async fn run(self, mut shutdown: Shutdown) {
        loop {
            tokio::select! {
                biased;
                _ = shutdown.wait() => break,
                accepted = self.listener.accept() => match accepted {
                    Ok((stream, peer)) => {
                        let page = Arc::clone(&self.exposition);
                        tokio::spawn(async move {
                            if let Err(e) = serve(stream, &page).await {
                                tracing::debug!(%peer, "metrics scrape: {e}");
                            }
                        });
                    }
                    Err(e) => {
                        tracing::warn!("metrics endpoint: accept failed: {e}");
                        tokio::time::sleep(Duration::from_millis(100)).await;
                    }
                },
            }
        }
    }
}

/// One connection: reads the request head, answers it, closes.
async fn serve(mut stream: TcpStream, page: &Exposition) -> std::io::Result<()> {
    let head = tokio::time::timeout(CLIENT_TIMEOUT, read_head(&mut stream))
        .await
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::TimedOut, "request head"))??;
    let answer = respond(&head, page);
    tokio::time::timeout(CLIENT_TIMEOUT, stream.write_all(&answer))
        .await
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::TimedOut, "answer"))??;
    stream.shutdown().await
}

/// Bytes up to the end of the request head (`\r\n\r\n`), at most [`MAX_HEAD`].
async fn read_head(stream: &mut TcpStream) -> std::io::Result<String> {
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    while !buf.windows(4).any(|w| w == b"\r\n\r\n") {
        if buf.len() > MAX_HEAD {
            break;
        }
        let n = stream.read(&mut chunk).await?;
        if n == 0 {
            break;
        }
        buf.extend_from_slice(&chunk[..n]);
    }
    Ok(String::from_utf8_lossy(&buf).into_owned())
}

/// The whole HTTP answer to a request head.
fn respond(head: &str, page: &Exposition) -> Vec<u8> {
    let mut words = head.lines().next().unwrap_or("").split_whitespace();
    let (method, target) = (words.next().unwrap_or(""), words.next().unwrap_or(""));
    let path = target.split('?').next().unwrap_or("");
    let (status, ctype, body) = match (method, path) {
        ("GET", "/metrics") => match page.encode() {
            Ok(text) => ("200 OK", CONTENT_TYPE, text),
            Err(e) => {
                tracing::warn!("metrics page: {e}");
                (
                    "500 Internal Server Error",
                    "text/plain",
                    "encoding failed\n".into(),
                )
            }
        },
        ("GET", _) => ("404 Not Found", "text/plain", "try /metrics\n".into()),
        _ => ("405 Method Not Allowed", "text/plain", "GET only\n".into()),
    };
    let mut out = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\n\
         Connection: close\r\n\r\n",
        body.len()
    )
    .into_bytes();
    out.extend_from_slice(body.as_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shutdown::shutdown_channel;

    fn live() -> Live {
        Live {
            poll: Arc::default(),
            writer: Arc::default(),
            segments_closed: Arc::default(),
            diagnosis: Some(Arc::default()),
            gap: Arc::default(),
            sync: Some(Arc::default()),
            compaction: Some(Arc::default()),
        }
    }

    async fn get(addr: SocketAddr, path: &str) -> String {
        let mut s = TcpStream::connect(addr).await.expect("connect");
        s.write_all(format!("GET {path} HTTP/1.1\r\nHost: x\r\n\r\n").as_bytes())
            .await
            .expect("send");
        let mut out = String::new();
        s.read_to_string(&mut out).await.expect("read");
        out
    }

    #[tokio::test]
    async fn serves_the_live_counters_and_stops_on_shutdown() {
        let live = live();
        let task = MetricsTask::bind("127.0.0.1:0".parse().expect("addr"), live.clone())
            .await
            .expect("bind");
        let addr = task.local_addr().expect("addr");
        let (trigger, shutdown) = shutdown_channel();
        let h = tokio::spawn(task.run(shutdown));
        live.poll.polls_ok.store(41, Ordering::Relaxed);
        live.writer.samples_inserted.store(1234, Ordering::Relaxed);
        if let Some(sync) = &live.sync {
            sync.syncs_ok.store(2, Ordering::Relaxed);
            sync.rows_sent.store(35_047, Ordering::Relaxed);
        }
        if let Some(c) = &live.compaction {
            c.samples.store(777, Ordering::Relaxed);
        }
        let page = get(addr, "/metrics").await;
        assert!(
            page.contains("\ngtwatch_samples_archived_total 777\n"),
            "{page}"
        );
        assert!(page.contains("\ngtwatch_fleet_syncs_total 2\n"), "{page}");
        assert!(
            page.contains("\ngtwatch_fleet_rows_sent_total 35047\n"),
            "{page}"
        );
        assert!(
            page.contains("\ngtwatch_fleet_syncs_failed_total 0\n"),
            "{page}"
        );
        assert!(page.starts_with("HTTP/1.1 200 OK\r\n"), "{page}");
        assert!(page.contains("\ngtwatch_polls_total 41\n"), "{page}");
        assert!(
            page.contains("\ngtwatch_samples_written_total 1234\n"),
            "{page}"
        );
        assert!(page.contains("\ngtwatch_diagnosis_queue 0\n"), "{page}");
        assert!(get(addr, "/").await.starts_with("HTTP/1.1 404"));
        trigger.trigger();
        tokio::time::timeout(Duration::from_secs(5), h)
            .await
            .expect("stops")
            .expect("join");
    }
}
