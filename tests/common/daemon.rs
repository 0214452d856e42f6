//! The real `gtwatch run` binary as a test drives it: a process with its stderr collected
//! line by line, the in-process plant-sim it polls on 127.0.0.1, and its configuration written
//! from `config/gtwatch.toml` with lines replaced. Shared by the fault tests and the tests of
//! commands run beside a running daemon.

use gtwatch::plantsim::{spawn_plant_sim, PlantSimHandle, ScriptedPlant, SimOptions};
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The daemon process with its stderr collected line by line; killed if still running when
/// dropped (a failing test).
pub struct Daemon {
    pub child: Child,
    pub log: Arc<Mutex<Vec<String>>>,
    reader: Option<std::thread::JoinHandle<()>>,
}

impl Daemon {
    /// `gtwatch run --config cfg` logging at `info`.
    pub fn start(cfg: &Path) -> Daemon {
        Daemon::start_logging(cfg, "info")
    }

    /// `gtwatch run --config cfg` with `RUST_LOG=rust_log`.
    pub fn start_logging(cfg: &Path, rust_log: &str) -> Daemon {
        let mut child = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
            .args(["run", "--config"])
            .arg(cfg)
            .env("RUST_LOG", rust_log)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("daemon starts");
        let stderr = child.stderr.take().expect("stderr");
        let log = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&log);
        let reader = std::thread::spawn(move || {
            for line in std::io::BufReader::new(stderr)
                .lines()
                .map_while(Result::ok)
            {
                sink.lock().expect("log").push(line);
            }
        });
        Daemon {
            child,
            log,
            reader: Some(reader),
        }
    }

    /// Lines of the log containing `needle`.
    pub fn count(&self, needle: &str) -> usize {
        self.log
            .lock()
            .expect("log")
            .iter()
            .filter(|l| l.contains(needle))
            .count()
    }

    /// The whole log so far.
    pub fn log_text(&self) -> String {
        self.log.lock().expect("log").join("\n")
    }

    /// Waits until the log holds `n` lines containing `needle`.
    pub fn wait_log(&mut self, needle: &str, n: usize, within: Duration) {
        let deadline = Instant::now() + within;
        while self.count(needle) < n {
            if let Some(s) = self.child.try_wait().expect("wait") {
                panic!(
                    "daemon exited ({s}) waiting for {needle:?}; log:\n{}",
                    self.log_text()
                );
            }
            assert!(
                Instant::now() < deadline,
                "no {needle:?} (×{n}) within {within:?}; log:\n{}",
                self.log_text()
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    pub fn assert_running(&mut self) {
        assert!(
            self.child.try_wait().expect("wait").is_none(),
            "daemon died; log:\n{}",
            self.log_text()
        );
    }

    pub fn sigterm(&mut self) -> std::process::ExitStatus {
        let status = super::sigterm(&mut self.child);
        self.join_log();
        status
    }

    /// kill -9, then waits for the process and for the rest of its log.
    pub fn kill9(&mut self) {
        self.child.kill().expect("kill -9");
        self.child.wait().expect("reaped");
        self.join_log();
    }

    /// Waits until the whole log (to the process's end) has been read.
    fn join_log(&mut self) {
        if let Some(r) = self.reader.take() {
            r.join().expect("log reader");
        }
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// The reference config with one line replaced; the line must be there exactly once.
pub fn set(text: String, old: &str, new: &str) -> String {
    assert_eq!(
        text.lines().filter(|l| *l == old).count(),
        1,
        "config/gtwatch.toml: expected the line {old:?} once"
    );
    text.lines()
        .map(|l| if l == old { new } else { l })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The reference config for a test daemon: database `db`, polling `endpoint` every
/// `poll_ms` with short timeouts and backoff, committing every 50 ms, scanning every 500 ms,
/// diagnosis off.
pub fn config_text(db: &Path, endpoint: &str, poll_ms: u64) -> String {
    let mut t = include_str!("../../config/gtwatch.toml").to_string();
    t = set(
        t,
        "path = \"/var/lib/gtwatch/gtwatch.db\"",
        &format!("path = {:?}", db.display().to_string()),
    );
    t = set(t, "flush_interval_ms = 1000", "flush_interval_ms = 50");
    t = set(
        t,
        "poll_period_ms = 100",
        &format!("poll_period_ms = {poll_ms}"),
    );
    t = set(t, "connect_timeout_ms = 3000", "connect_timeout_ms = 500");
    t = set(t, "request_timeout_ms = 1000", "request_timeout_ms = 300");
    t = set(t, "backoff_initial_ms = 500", "backoff_initial_ms = 20");
    t = set(t, "backoff_max_ms = 30000", "backoff_max_ms = 200");
    t = set(t, "detect_interval_ms = 10000", "detect_interval_ms = 500");
    t = set(t, "enabled = true", "enabled = false");
    set(
        t,
        "endpoint = \"127.0.0.1:5020\"",
        &format!("endpoint = {endpoint:?}"),
    )
}

/// Writes `text` as `dir/gtwatch.toml`.
pub fn write_config(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("gtwatch.toml");
    std::fs::write(&p, text).expect("config");
    p
}

/// A plant-sim serving the reference register map on 127.0.0.1 (a free port), ticking every
/// `poll_ms` at 100× real time; its address.
pub fn start_sim(rt: &tokio::runtime::Runtime, poll_ms: u64) -> (PlantSimHandle, String) {
    rt.block_on(async {
        let map = super::reference_config().modbus.expect("map");
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
            .await
            .expect("bind");
        let addr = listener.local_addr().expect("addr").to_string();
        let sim = spawn_plant_sim(
            listener,
            map,
            Box::new(ScriptedPlant::demo(1.0)),
            SimOptions {
                speedup: 100.0,
                tick: Some(Duration::from_millis(poll_ms)),
                lockstep: false,
            },
            None,
        )
        .expect("plant-sim");
        (sim, addr)
    })
}

/// A one-thread runtime for the plant-sim.
pub fn sim_runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .expect("runtime")
}
