//! Test-only helpers shared by the poll-loop tests (`modbus/tests.rs`, `gate_tests.rs`): a
//! Modbus server of the test's own making on 127.0.0.1 port 0, a field builder, and a poll
//! loop run until enough samples (or time) have passed, with everything it sent collected.
//! Compiled only for tests.

use crate::acquire::clock::SampleClock;
use crate::acquire::modbus::PollStats;
use crate::acquire::modbus::{poll_loop_with_clock, AcquisitionConfig, PollPlan, PollProgress};
use crate::acquire::register_map::{ByteOrder, DataType, FieldSpec};
use crate::signals::Signal;
use crate::store::{writer_channel, Gap, Sample, WriteCmd};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::task::JoinHandle;
use tokio_modbus::prelude::{ExceptionCode, Request, Response};
use tokio_modbus::server::tcp::{accept_tcp_connection, Server};
use tokio_modbus::server::Service;

/// Serves `service` on 127.0.0.1 (port 0) until the returned task is aborted.
pub(crate) async fn serve<S>(service: S) -> (SocketAddr, JoinHandle<()>)
where
    S: Service<Request = Request<'static>, Response = Response, Exception = ExceptionCode>
        + Clone
        + Send
        + Sync
        + 'static,
    S::Future: Send,
{
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr");
    let task = tokio::spawn(async move {
        let s = Server::new(listener);
        let new_service = move |_a| Ok(Some(service.clone()));
        let on_connected = |stream, a| {
            let ns = new_service.clone();
            async move { accept_tcp_connection(stream, a, ns) }
        };
        let _ = s.serve(&on_connected, |_e| {}).await;
    });
    (addr, task)
}

/// A plain u16 field (scale 1, no offset, no range of its own).
pub(crate) fn u16_field(name: &str, address: u32, signal: Option<Signal>) -> FieldSpec {
    FieldSpec {
        name: name.into(),
        address,
        data_type: DataType::U16,
        byte_order: ByteOrder::ABCD,
        scale: 1.0,
        offset: 0.0,
        unit: String::new(),
        signal,
        min: None,
        max: None,
    }
}

/// When [`run_poll_loop`] triggers the shutdown.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Until {
    /// Once at least this many samples have been sent.
    Samples(usize),
    /// After this long.
    Elapsed(Duration),
}

/// Everything one poll-loop run sent, in order, and its final tallies.
#[derive(Debug)]
pub(crate) struct PollRun {
    pub(crate) samples: Vec<Sample>,
    pub(crate) gaps: Vec<Gap>,
    pub(crate) stats: PollStats,
    pub(crate) progress: Arc<PollProgress>,
}

/// Runs the real poll loop with `clock` (`None`: the system clock) until `until`, then shuts
/// it down and drains what it sent. `on_samples` sees the running sample count after every
/// batch (a test steps a clock or a server from there).
pub(crate) async fn run_poll_loop(
    cfg: AcquisitionConfig,
    plan: PollPlan,
    clock: Option<SampleClock>,
    until: Until,
    mut on_samples: impl FnMut(usize),
) -> PollRun {
    let clock = clock
        .unwrap_or_else(|| SampleClock::new(Duration::from_millis(cfg.clock_jump_threshold_ms)));
    let (tx, mut rx) = writer_channel(1024);
    let (trigger, shutdown) = crate::shutdown::shutdown_channel();
    let progress = Arc::new(PollProgress::default());
    let p2 = Arc::clone(&progress);
    let task =
        tokio::spawn(
            async move { poll_loop_with_clock(&cfg, &plan, tx, p2, shutdown, clock).await },
        );
    let mut samples = Vec::new();
    let mut gaps = Vec::new();
    let mut take = |cmd: WriteCmd, samples: &mut Vec<Sample>| match cmd {
        WriteCmd::Samples(s) => samples.extend(s),
        WriteCmd::Gap(g) => gaps.push(g),
        _ => {}
    };
    match until {
        Until::Samples(n) => {
            while samples.len() < n {
                match rx.recv().await {
                    Some(cmd) => take(cmd, &mut samples),
                    None => break,
                }
                on_samples(samples.len());
            }
        }
        Until::Elapsed(d) => {
            let end = tokio::time::Instant::now() + d;
            while let Ok(Some(cmd)) = tokio::time::timeout_at(end, rx.recv()).await {
                take(cmd, &mut samples);
                on_samples(samples.len());
            }
        }
    }
    trigger.trigger();
    let stats = task.await.expect("join");
    while let Some(cmd) = rx.recv().await {
        take(cmd, &mut samples);
    }
    PollRun {
        samples,
        gaps,
        stats,
        progress,
    }
}
