//! Issue 25 item 4, acceptance: a real Prometheus server (the Debian package `prometheus`;
//! `.ci/run` installs it when missing) scrapes a running `gtwatch run` every second through
//! `[metrics] listen`, and the series it stored match the daemon's own counters:
//!
//! - while the plant is polled, every value Prometheus stored lies between the daemon's own
//!   `/metrics` values read just before and just after that scrape's time stamp (this test
//!   reads the endpoint every 100 ms and keeps what it read);
//! - once the plant-sim is stopped the sample counters stand still: Prometheus's latest value
//!   of polls, samples polled, samples written and segments equals the endpoint's, and samples
//!   written equals the database's sample count, exactly.
//!
//! Without the `prometheus` binary on PATH the test fails and says how to install it.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use common::daemon::{config_text, sim_runtime, start_sim, write_config, Daemon};
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

const POLL_MS: u64 = 50;
/// Series compared while they move (all counters of the acquisition and the writer).
const MOVING: [&str; 4] = [
    "gtwatch_polls_total",
    "gtwatch_samples_polled_total",
    "gtwatch_samples_written_total",
    "gtwatch_connects_total",
];

/// The `prometheus` server binary on PATH, or a failure saying how to get it.
fn prometheus_binary() -> PathBuf {
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join("prometheus"))
            .find(|p| p.is_file())
    });
    match found {
        Some(p) => p,
        None => panic!(
            "this test needs a real Prometheus server and `prometheus` is not on PATH: install \
             the Debian package (`apt-get install -y --no-install-recommends prometheus`, as \
             .ci/run does) and run it again"
        ),
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .expect("bind")
        .local_addr()
        .expect("addr")
        .port()
}

fn now_ms() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .expect("clock")
        .as_millis() as i64
}

/// `GET path` over HTTP/1.0 (no chunked answer); (status code, body), or `None` if the
/// server cannot be reached.
fn http_get(port: u16, path: &str) -> Option<(u16, String)> {
    let mut s = TcpStream::connect(("127.0.0.1", port)).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(5))).ok()?;
    write!(s, "GET {path} HTTP/1.0\r\nHost: 127.0.0.1:{port}\r\n\r\n").ok()?;
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).ok()?;
    let text = String::from_utf8_lossy(&raw).into_owned();
    let (head, body) = text.split_once("\r\n\r\n")?;
    let code = head.split_whitespace().nth(1)?.parse().ok()?;
    Some((code, body.to_string()))
}

/// Value of one series without labels in an exposition page.
fn page_value(page: &str, series: &str) -> Option<f64> {
    page.lines()
        .find_map(|l| l.strip_prefix(series)?.strip_prefix(' '))
        .and_then(|v| v.split_whitespace().next()?.parse().ok())
}

/// The Prometheus server as a child process, killed if still running when dropped.
struct Prometheus {
    child: Child,
    port: u16,
}

impl Prometheus {
    fn start(dir: &Path, target_port: u16) -> Prometheus {
        let bin = prometheus_binary();
        let cfg = dir.join("prometheus.yml");
        std::fs::write(
            &cfg,
            format!(
                "global:\n  scrape_interval: 1s\n  scrape_timeout: 1s\n\
                 scrape_configs:\n  - job_name: gtwatch\n    static_configs:\n      \
                 - targets: ['127.0.0.1:{target_port}']\n"
            ),
        )
        .expect("prometheus.yml");
        let port = free_port();
        let child = Command::new(bin)
            .arg(format!("--config.file={}", cfg.display()))
            .arg(format!(
                "--storage.tsdb.path={}",
                dir.join("tsdb").display()
            ))
            .arg(format!("--web.listen-address=127.0.0.1:{port}"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(dir.join("prometheus.log")).expect("log"))
            .spawn()
            .expect("prometheus starts");
        Prometheus { child, port }
    }

    /// `data.result` of an API call.
    fn api(&self, path: &str) -> Option<serde_json::Value> {
        let (code, body) = http_get(self.port, path)?;
        if code != 200 {
            return None;
        }
        let v: serde_json::Value = serde_json::from_str(&body).ok()?;
        (v["status"] == "success").then(|| v["data"].clone())
    }

    /// The latest stored sample of `series`: (its scrape's time stamp ms, value). A range
    /// selector returns the raw samples with their own time stamps (an instant query would
    /// stamp the value with the query's time).
    fn latest(&self, series: &str) -> Option<(i64, f64)> {
        let data = self.api(&format!("/api/v1/query?query={series}%5B10s%5D"))?;
        let sample = data["result"].as_array()?.first()?["values"]
            .as_array()?
            .last()?
            .clone();
        let t = (sample[0].as_f64()? * 1000.0).round() as i64;
        Some((t, sample[1].as_str()?.parse().ok()?))
    }

    fn target_health(&self) -> Option<String> {
        let data = self.api("/api/v1/targets")?;
        Some(
            data["activeTargets"].as_array()?.first()?["health"]
                .as_str()?
                .to_string(),
        )
    }

    fn stop(&mut self) {
        common::sigterm(&mut self.child);
    }
}

impl Drop for Prometheus {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Reads the daemon's endpoint every 100 ms and keeps (request sent, answer read, page), in
/// ms, until dropped.
struct Recorder {
    pages: Arc<Mutex<Vec<(i64, i64, String)>>>,
    stop: Arc<std::sync::atomic::AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Recorder {
    fn start(port: u16) -> Recorder {
        let pages = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let (p, s) = (Arc::clone(&pages), Arc::clone(&stop));
        let thread = std::thread::spawn(move || {
            while !s.load(std::sync::atomic::Ordering::Relaxed) {
                let sent = now_ms();
                if let Some((200, body)) = http_get(port, "/metrics") {
                    // The values were read between these two times.
                    p.lock().expect("pages").push((sent, now_ms(), body));
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        });
        Recorder {
            pages,
            stop,
            thread: Some(thread),
        }
    }

    /// The daemon's values of `series` surely read before and surely read after the scrape
    /// Prometheus stamped `t_ms` (the scrape's start; it reads the value within the scrape
    /// timeout, 1 s).
    fn bracket(&self, series: &str, t_ms: i64) -> Option<(f64, f64)> {
        let pages = self.pages.lock().expect("pages");
        let before = pages.iter().rev().find(|(_, done, _)| *done <= t_ms)?;
        let after = pages.iter().find(|(sent, _, _)| *sent >= t_ms + 1000)?;
        Some((
            page_value(&before.2, series)?,
            page_value(&after.2, series)?,
        ))
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn wait_for<T>(what: &str, within: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + within;
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(Instant::now() < deadline, "{what}: not within {within:?}");
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
fn prometheus_scrapes_the_daemon_and_stores_its_counters() {
    prometheus_binary();
    let dir = tempfile::tempdir().expect("tempdir");
    let rt = sim_runtime();
    let (sim, endpoint) = start_sim(&rt, POLL_MS);
    let metrics_port = free_port();
    let db = dir.path().join("gt.db");
    let text = format!(
        "{}\n\n[metrics]\nlisten = \"127.0.0.1:{metrics_port}\"\n",
        config_text(&db, &endpoint, POLL_MS)
    );
    let mut daemon = Daemon::start(&write_config(dir.path(), &text));
    daemon.wait_log("metrics endpoint listening", 1, Duration::from_secs(30));
    let recorder = Recorder::start(metrics_port);
    let mut prom = Prometheus::start(dir.path(), metrics_port);

    // Prometheus reports the target up and has stored a few moving scrapes.
    let health = wait_for("target up", Duration::from_secs(60), || {
        prom.target_health().filter(|h| h == "up")
    });
    assert_eq!(health, "up");
    wait_for("gtwatch_polls_total > 20", Duration::from_secs(30), || {
        prom.latest("gtwatch_polls_total")
            .filter(|(_, v)| *v > 20.0)
    });

    // While moving: each stored value lies between the daemon's own readings around it.
    for round in 0..3 {
        for series in MOVING {
            let (t, v) = wait_for(series, Duration::from_secs(10), || prom.latest(series));
            let (lo, hi) = wait_for("readings after the scrape", Duration::from_secs(10), || {
                recorder.bracket(series, t)
            });
            assert!(
                lo <= v && v <= hi,
                "round {round}: Prometheus stored {series} = {v} at {t}, the daemon read \
                 {lo} before and {hi} after"
            );
        }
        std::thread::sleep(Duration::from_millis(1100));
    }
    daemon.assert_running();

    // Standing still: the plant-sim stops, polls fail, nothing new is stored.
    rt.block_on(sim.stop()).expect("sim stops");
    let written = wait_for(
        "samples_written stands still",
        Duration::from_secs(30),
        || {
            let page = http_get(metrics_port, "/metrics")?.1;
            let a = page_value(&page, "gtwatch_samples_written_total")?;
            std::thread::sleep(Duration::from_millis(2500));
            let page = http_get(metrics_port, "/metrics")?.1;
            let b = page_value(&page, "gtwatch_samples_written_total")?;
            (a == b && a > 0.0).then_some(b)
        },
    );
    let page = http_get(metrics_port, "/metrics").expect("endpoint").1;
    std::thread::sleep(Duration::from_millis(2500));
    for series in [
        "gtwatch_polls_total",
        "gtwatch_samples_polled_total",
        "gtwatch_samples_written_total",
        "gtwatch_segments_total",
    ] {
        let own = page_value(&page, series).expect(series);
        let (_, stored) = prom.latest(series).expect(series);
        assert_eq!(stored, own, "{series}: Prometheus {stored}, daemon {own}");
    }
    let failed = prom.latest("gtwatch_polls_failed_total").expect("failed");
    assert!(
        failed.1 > 0.0,
        "the stopped plant shows as failed polls: {failed:?}"
    );
    let conn = common::open_db(&db);
    let in_db: i64 = conn
        .query_row("SELECT COUNT(*) FROM samples", [], |r| r.get(0))
        .expect("count");
    assert_eq!(
        in_db as f64, written,
        "samples in the database against gtwatch_samples_written_total"
    );

    drop(recorder);
    prom.stop();
    let status = daemon.sigterm();
    assert!(
        status.success(),
        "daemon exit {status}; log:\n{}",
        daemon.log_text()
    );
}
