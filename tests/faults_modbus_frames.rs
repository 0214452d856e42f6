//! Issue 12, fault-injection suite: a Modbus TCP server of the test's own making that answers
//! with broken frames at the byte level: a wrong transaction id, an exception code, a frame cut
//! off mid-response (connection reset), a reply that never comes, and a connection refused.
//!
//! After each fault the real `daemon::run` must still be running, must have stored no sample
//! (there was never a valid reading), must record the outage as a gap with a stable reason,
//! and the database must pass `PRAGMA integrity_check`. Each case runs about a second (× the
//! `GTWATCH_FAULTS_LONG` factor); each prints a `FAULT-TALLY` line.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use gtwatch::acquire::modbus::PollProgress;
use gtwatch::daemon::{self, RunOptions};
use gtwatch::shutdown::shutdown_channel;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;

/// How the fake server misbehaves.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Fault {
    /// A well-formed answer under another transaction id.
    WrongTransactionId,
    /// Modbus exception 0x02 (illegal data address).
    Exception,
    /// Half of the answer, then the connection is closed.
    PartialFrame,
    /// Reads the request and never answers.
    Stall,
}

/// Serves `fault` on every request of every connection until the test ends.
async fn serve(listener: TcpListener, fault: Fault) {
    loop {
        let Ok((mut sock, _)) = listener.accept().await else {
            return;
        };
        tokio::spawn(async move {
            let mut req = [0u8; 12];
            loop {
                if sock.read_exact(&mut req).await.is_err() {
                    return;
                }
                let tid = u16::from_be_bytes([req[0], req[1]]);
                let unit = req[6];
                let fc = req[7];
                let count = u16::from_be_bytes([req[10], req[11]]) as usize;
                let mut pdu = vec![fc, (2 * count) as u8];
                pdu.extend(std::iter::repeat_n(0x11u8, 2 * count));
                let answer_tid = if fault == Fault::WrongTransactionId {
                    tid.wrapping_add(7)
                } else {
                    tid
                };
                if fault == Fault::Exception {
                    pdu = vec![fc | 0x80, 0x02];
                }
                let mut frame = Vec::new();
                frame.extend(answer_tid.to_be_bytes());
                frame.extend(0u16.to_be_bytes());
                frame.extend(((pdu.len() + 1) as u16).to_be_bytes());
                frame.push(unit);
                frame.extend(&pdu);
                match fault {
                    Fault::Stall => {
                        tokio::time::sleep(Duration::from_secs(3600)).await;
                        return;
                    }
                    Fault::PartialFrame => {
                        let _ = sock.write_all(&frame[..frame.len() / 2]).await;
                        return; // drop: the client sees EOF mid-frame
                    }
                    _ => {
                        if sock.write_all(&frame).await.is_err() {
                            return;
                        }
                    }
                }
            }
        });
    }
}

struct Outcome {
    samples: usize,
    duplicated: u64,
    gaps: Vec<(i64, i64, String, String)>,
    failures: u64,
    integrity: String,
}

/// Runs the daemon for `run_ms` against `endpoint` (a fault server, or nothing listening).
async fn run_daemon_against(endpoint: String, run_ms: u64) -> Outcome {
    let dir = tempfile::tempdir().expect("tempdir");
    let db_path = dir.path().join("faults.db");
    let mut cfg = common::fast_config(&endpoint, db_path.clone(), 20);
    cfg.diagnosis.enabled = false;
    let progress = Arc::new(PollProgress::default());
    let (trigger, shutdown) = shutdown_channel();
    let daemon = tokio::spawn(daemon::run(
        cfg,
        shutdown,
        RunOptions {
            systemd_notify: false,
            progress: Some(Arc::clone(&progress)),
            ..RunOptions::default()
        },
    ));
    tokio::time::sleep(Duration::from_millis(run_ms)).await;
    assert!(!daemon.is_finished(), "the daemon stopped on its own");
    trigger.trigger();
    tokio::time::timeout(Duration::from_secs(10), daemon)
        .await
        .expect("clean shutdown within 10 s")
        .expect("join")
        .expect("daemon ran");
    let db = common::open_db(&db_path);
    let integrity: String = db
        .query_row("PRAGMA integrity_check", [], |r| r.get(0))
        .expect("check");
    Outcome {
        samples: common::tag_samples(&db, "n1_rpm").len(),
        duplicated: common::duplicate_samples(&db),
        gaps: common::gaps(&db),
        failures: progress.failures.load(Ordering::Relaxed),
        integrity,
    }
}

async fn fault_case(fault: Fault) -> Outcome {
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let endpoint = listener.local_addr().expect("addr").to_string();
    let server = tokio::spawn(serve(listener, fault));
    let out = run_daemon_against(endpoint, 1200 * u64::from(common::long_factor())).await;
    server.abort();
    out
}

fn assert_outage(name: &str, o: &Outcome, reason_has: &[&str]) {
    assert_eq!(o.duplicated, 0, "{name}");
    assert_eq!(o.integrity, "ok", "{name}");
    assert_eq!(
        o.samples, 0,
        "{name}: a sample was stored from a broken answer"
    );
    assert!(o.failures >= 1, "{name}: no failure counted");
    assert_eq!(o.gaps.len(), 1, "{name}: {:?}", o.gaps);
    let reason = &o.gaps[0].3;
    eprintln!("{name}: {} failures, gap reason: {reason}", o.failures);
    assert!(
        reason_has.iter().any(|r| reason.contains(r)),
        "{name}: gap reason '{reason}' names none of {reason_has:?}"
    );
    // Every failed poll is one injection; there was never a valid reading to lose.
    common::Tally {
        class: &format!("modbus_{}", name.to_lowercase()),
        injected: o.failures,
        lost: 0,
        duplicated: o.duplicated,
        integrity: &o.integrity,
        note: format!("gaps={} samples_stored={}", o.gaps.len(), o.samples),
    }
    .print();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn broken_answers_are_outages_never_samples() {
    let cases = [
        (
            Fault::WrongTransactionId,
            vec!["transaction", "protocol", "read holding"],
        ),
        (Fault::Exception, vec!["exception", "Exception"]),
        (
            Fault::PartialFrame,
            vec!["read holding", "closed", "I/O", "protocol"],
        ),
        (Fault::Stall, vec!["timed out"]),
    ];
    for (fault, reasons) in cases {
        let o = fault_case(fault).await;
        let name = match fault {
            Fault::WrongTransactionId => "wrong_transaction_id",
            Fault::Exception => "exception_code",
            Fault::PartialFrame => "partial_frame_reset",
            Fault::Stall => "stall",
        };
        assert_outage(name, &o, &reasons);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn connection_refused_is_an_outage() {
    // Bind and drop: the port is then (almost certainly) closed.
    let endpoint = {
        let l = TcpListener::bind("127.0.0.1:0").await.expect("bind");
        l.local_addr().expect("addr").to_string()
    };
    let o = run_daemon_against(endpoint, 800 * u64::from(common::long_factor())).await;
    assert_outage("connection_refused", &o, &["connection refused"]);
}
