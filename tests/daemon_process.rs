//! The `gtwatch run` process as systemd sees it: READY=1 only after the first successful poll,
//! WATCHDOG=1 pings while polling progresses, and on SIGTERM STOPPING=1, the last batch
//! committed and exit status 0. The test plays systemd's notify socket.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use gtwatch::plantsim::{spawn_plant_sim, ScriptedPlant, SimOptions};
use std::os::unix::net::UnixDatagram;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn recv_all(sock: &UnixDatagram, for_ms: u64) -> Vec<String> {
    let deadline = Instant::now() + Duration::from_millis(for_ms);
    let mut out = Vec::new();
    let mut buf = [0u8; 512];
    while Instant::now() < deadline {
        if let Ok(n) = sock.recv(&mut buf) {
            out.push(String::from_utf8_lossy(&buf[..n]).trim().to_string());
        }
    }
    out
}

#[test]
fn run_notifies_systemd_and_stops_cleanly_on_sigterm() {
    let dir = tempfile::tempdir().expect("tempdir");
    let sock_path = dir.path().join("notify.sock");
    let sock = UnixDatagram::bind(&sock_path).expect("bind notify socket");
    sock.set_read_timeout(Some(Duration::from_millis(20)))
        .expect("timeout");
    let db = dir.path().join("run.db");

    // Reserve a port, but start the plant only later: the daemon must not be ready before.
    let rt = tokio::runtime::Runtime::new().expect("runtime");
    let std_listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = std_listener.local_addr().expect("addr");
    drop(std_listener);

    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/gtwatch.toml"),
    )
    .expect("reference config")
    .replace(
        "endpoint = \"127.0.0.1:5020\"",
        &format!("endpoint = \"{addr}\""),
    )
    .replace(
        "path = \"/var/lib/gtwatch/gtwatch.db\"",
        &format!("path = \"{}\"", db.display()),
    )
    .replace("backoff_initial_ms = 500", "backoff_initial_ms = 50")
    .replace("backoff_max_ms = 30000", "backoff_max_ms = 100");
    let cfg_path = dir.path().join("gtwatch.toml");
    std::fs::write(&cfg_path, text).expect("write config");

    // systemd sets WATCHDOG_PID to the service's pid: `exec` keeps the shell's `$$`.
    let mut child = Command::new("sh")
        .arg("-c")
        .arg("WATCHDOG_PID=$$ exec \"$0\" run --config \"$1\"")
        .arg(env!("CARGO_BIN_EXE_gtwatch"))
        .arg(&cfg_path)
        .env("NOTIFY_SOCKET", &sock_path)
        .env("WATCHDOG_USEC", "400000")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn gtwatch run");

    let before = recv_all(&sock, 600);
    assert!(
        !before.iter().any(|m| m.contains("READY=1")),
        "ready before any poll succeeded: {before:?}"
    );

    let sim = rt.block_on(async {
        let listener = tokio::net::TcpListener::bind(addr).await.expect("bind sim");
        spawn_plant_sim(
            listener,
            common::reference_config().modbus.expect("map"),
            Box::new(ScriptedPlant::demo(0.1)),
            SimOptions::default(),
            None,
        )
        .expect("sim")
    });
    let after = recv_all(&sock, 1500);
    assert!(after.iter().any(|m| m == "READY=1"), "{after:?}");
    assert!(
        after.iter().filter(|m| *m == "WATCHDOG=1").count() >= 2,
        "{after:?}"
    );

    let pid = child.id().to_string();
    let killed = Command::new("kill")
        .args(["-TERM", &pid])
        .status()
        .expect("kill");
    assert!(killed.success());
    let deadline = Instant::now() + Duration::from_secs(10);
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break s;
        }
        assert!(Instant::now() < deadline, "daemon did not stop on SIGTERM");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "exit status {status:?}");
    let stopping = recv_all(&sock, 100);
    assert!(stopping.iter().any(|m| m == "STOPPING=1"), "{stopping:?}");
    rt.block_on(sim.stop()).expect("stop sim");

    // Everything polled was committed before exit: 13 tags per poll, all stored.
    let conn = common::open_db(&db);
    let n1 = common::tag_samples(&conn, "n1_rpm");
    let total: i64 = conn
        .query_row("SELECT COUNT(*) FROM samples", [], |r| r.get(0))
        .expect("count");
    assert!(n1.len() >= 5, "{}", n1.len());
    assert_eq!(total as usize, n1.len() * 13);
}
