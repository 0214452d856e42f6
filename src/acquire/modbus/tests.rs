//! Tests of the Modbus poll loop: stable gap reasons, default ranges, backoff, read-only
//! function codes, and outages open at shutdown.

use super::*;
use crate::acquire::clock::{SampleClock, WallClock};
use crate::acquire::register_map::{ModbusConfig, RegisterKind, RequestSpec};
use crate::acquire::test_support::{run_poll_loop, serve, u16_field, Until};
use crate::quality::Quality;
use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio_modbus::prelude::{ExceptionCode, Request, Response};

#[test]
fn gap_reason_for_a_server_death_is_stable() {
    // Regression (issue 12 #9): one server death was stored as `I/O error: Success (os
    // error 0)`, `Operation now in progress (os error 115)` or `Connection reset by peer`.
    let texts: Vec<String> = [
        std::io::Error::from_raw_os_error(0),
        std::io::Error::from_raw_os_error(115),
        std::io::Error::from(std::io::ErrorKind::ConnectionReset),
        std::io::Error::from(std::io::ErrorKind::UnexpectedEof),
    ]
    .into_iter()
    .map(|e| ReadError::Io(e).stable_reason())
    .collect();
    assert!(
        texts.iter().all(|t| t == "I/O error: connection lost"),
        "{texts:?}"
    );
    let refused = ReadError::Io(std::io::ErrorKind::ConnectionRefused.into());
    assert_eq!(refused.stable_reason(), "I/O error: connection refused");
}

/// Issue 12 #3: the bad-value policy's default ranges apply to Modbus fields of a signal
/// when the register map sets no range of its own.
#[test]
fn default_signal_ranges_flag_modbus_values() {
    use crate::acquire::register_map::{encode_field, ByteOrder, DataType, FieldSpec};
    let f = FieldSpec {
        name: "n1_rpm".into(),
        address: 0,
        data_type: DataType::F32,
        byte_order: ByteOrder::ABCD,
        scale: 1.0,
        offset: 0.0,
        unit: "rpm".into(),
        signal: Some(crate::signals::Signal::N1),
        min: None,
        max: None,
    };
    let req = PlannedRequest {
        slave: 1,
        kind: crate::acquire::register_map::RegisterKind::Holding,
        start: 0,
        count: 2,
        fields: vec![(7, f.clone())],
    };
    let q = |v: f64| {
        let mut out = Vec::new();
        decode_request(&req, &encode_field(&f, v), 0, &mut out);
        out[0].quality
    };
    assert_eq!(q(7600.0), Quality::Good);
    assert_eq!(q(-500.0), Quality::OutOfRange);
    assert_eq!(q(1e9), Quality::OutOfRange);
    assert_eq!(q(f64::INFINITY), Quality::Bad);
}

#[test]
fn backoff_doubles_up_to_the_cap_and_resets() {
    let mut b = Backoff::new(Duration::from_millis(100), Duration::from_millis(500));
    let d: Vec<u128> = (0..5).map(|_| b.next_delay().as_millis()).collect();
    assert_eq!(d, vec![100, 200, 400, 500, 500]);
    b.reset();
    assert_eq!(b.next_delay().as_millis(), 100);
}

/// A server that records the function code of every request it receives, and answers
/// reads with zeros (and writes with success, so a write would go unnoticed otherwise).
#[derive(Clone)]
struct Recorder {
    codes: Arc<Mutex<Vec<u8>>>,
}

impl tokio_modbus::server::Service for Recorder {
    type Request = Request<'static>;
    type Response = Response;
    type Exception = ExceptionCode;
    type Future = std::future::Ready<Result<Response, ExceptionCode>>;
    fn call(&self, req: Request<'static>) -> Self::Future {
        if let Ok(mut c) = self.codes.lock() {
            c.push(req.function_code().value());
        }
        std::future::ready(Ok(match req {
            Request::ReadHoldingRegisters(_, n) => {
                Response::ReadHoldingRegisters(vec![0; n as usize])
            }
            Request::ReadInputRegisters(_, n) => Response::ReadInputRegisters(vec![0; n as usize]),
            Request::WriteSingleRegister(a, w) => Response::WriteSingleRegister(a, w),
            Request::WriteMultipleRegisters(a, w) => {
                Response::WriteMultipleRegisters(a, w.len() as u16)
            }
            Request::WriteSingleCoil(a, c) => Response::WriteSingleCoil(a, c),
            _ => return std::future::ready(Err(ExceptionCode::IllegalFunction)),
        }))
    }
}

#[tokio::test]
async fn the_poll_loop_sends_only_read_function_codes() {
    let codes = Arc::new(Mutex::new(Vec::new()));
    let (addr, server) = serve(Recorder {
        codes: Arc::clone(&codes),
    })
    .await;
    let map = ModbusConfig {
        endpoint: addr.to_string(),
        requests: vec![
            RequestSpec {
                slave_id: 1,
                register: RegisterKind::Holding,
                start_address: 0,
                count: None,
                fields: vec![u16_field("a", 0, None), u16_field("b", 1, None)],
            },
            RequestSpec {
                slave_id: 2,
                register: RegisterKind::Input,
                start_address: 10,
                count: None,
                fields: vec![u16_field("c", 10, None)],
            },
        ],
    };
    let plan = PollPlan::new(&map, &[1, 2, 3]).expect("plan");
    let cfg = AcquisitionConfig {
        poll_period_ms: 10,
        ..AcquisitionConfig::default()
    };
    let run = run_poll_loop(cfg, plan, None, Until::Samples(60), |_| {}).await;
    server.abort();
    assert!(run.stats.polls_ok >= 20, "{:?}", run.stats);
    let codes = codes.lock().expect("lock").clone();
    assert!(codes.len() >= 40);
    assert!(codes.iter().all(|&c| c == 3 || c == 4), "{codes:?}");
    assert!(codes.contains(&3) && codes.contains(&4));
}

#[tokio::test]
async fn an_outage_open_at_shutdown_is_recorded_as_a_gap() {
    // A port nobody listens on.
    let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = l.local_addr().expect("addr");
    drop(l);
    let plan = PollPlan {
        quality: crate::quality::QualityConfig::default(),
        endpoint: addr.to_string(),
        requests: vec![],
    };
    let cfg = AcquisitionConfig {
        poll_period_ms: 10,
        backoff_initial_ms: 10,
        backoff_max_ms: 40,
        ..AcquisitionConfig::default()
    };
    let until = Until::Elapsed(Duration::from_millis(200));
    let run = run_poll_loop(cfg, plan, None, until, |_| {}).await;
    let stats = &run.stats;
    assert_eq!(stats.polls_ok, 0);
    assert!(stats.failures >= 3, "{stats:?}");
    assert!(run.progress.cycles.load(Ordering::Relaxed) >= 10);
    let gaps = &run.gaps;
    assert_eq!(gaps.len(), 1, "{gaps:?}");
    let g = &gaps[0];
    assert!(g.end_ms - g.start_ms >= 150, "{g:?}");
    assert!(
        g.reason
            .starts_with(&format!("connect to {addr} failed: I/O error:")),
        "{}",
        g.reason
    );
    assert!(
        g.reason
            .ends_with("failed attempts) (still down at shutdown)"),
        "{}",
        g.reason
    );
}

/// Issue 12 fault suite, the clock jumping backwards during acquisition: the wall clock is set
/// back one hour after 20 polls and forward again two hours after 60. Stored times never go
/// backwards (nor repeat), each step is counted as a re-anchor and recorded as a `clock` gap
/// at the instant it happened, and no poll is lost.
#[tokio::test]
async fn wall_clock_stepping_back_and_forward_never_makes_times_go_backwards() {
    let codes = Arc::new(Mutex::new(Vec::new()));
    let (addr, server) = serve(Recorder {
        codes: Arc::clone(&codes),
    })
    .await;
    let map = ModbusConfig {
        endpoint: addr.to_string(),
        requests: vec![RequestSpec {
            slave_id: 1,
            register: RegisterKind::Holding,
            start_address: 0,
            count: None,
            fields: vec![u16_field("a", 0, None)],
        }],
    };
    let plan = PollPlan::new(&map, &[1]).expect("plan");
    let cfg = AcquisitionConfig {
        poll_period_ms: 10,
        ..AcquisitionConfig::default()
    };
    const HOUR_MS: i64 = 3_600_000;
    let offset = Arc::new(AtomicI64::new(0));
    let clock = SampleClock::with_wall(
        WallClock::Shifted(Arc::clone(&offset)),
        Duration::from_millis(cfg.clock_jump_threshold_ms),
    );
    let step = |n: usize| match n {
        20 => offset.store(-HOUR_MS, Ordering::Relaxed),
        60 => offset.store(HOUR_MS, Ordering::Relaxed),
        _ => {}
    };
    let run = run_poll_loop(cfg, plan, Some(clock), Until::Samples(100), step).await;
    server.abort();
    let t: Vec<i64> = run.samples.iter().map(|s| s.t_ms).collect();
    assert!(t.len() >= 100);
    assert_eq!(run.stats.samples, t.len() as u64, "every poll stored");
    assert!(
        t.windows(2).all(|w| w[0] < w[1]),
        "sample times went backwards or repeated: {t:?}"
    );
    assert_eq!(run.progress.clock_reanchors.load(Ordering::Relaxed), 2);
    let clock_gaps: Vec<&crate::store::Gap> = run
        .gaps
        .iter()
        .filter(|g| g.source == CLOCK_GAP_SOURCE)
        .collect();
    assert_eq!(clock_gaps.len(), 2, "{:?}", run.gaps);
    let (back, fwd) = (clock_gaps[0], clock_gaps[1]);
    let seconds = |reason: &str, prefix: &str| -> f64 {
        let rest = reason.strip_prefix(prefix).expect("reason names the step");
        rest.split(' ')
            .next()
            .and_then(|x| x.parse().ok())
            .expect("seconds")
    };
    let back_s = seconds(&back.reason, "wall clock stepped back ");
    let fwd_s = seconds(&fwd.reason, "wall clock stepped forward ");
    assert!((back_s - 3600.0).abs() < 1.0, "{}", back.reason);
    assert!((fwd_s - 7200.0).abs() < 1.0, "{}", fwd.reason);
    // The backward step: held just above the last time stored before it.
    assert_eq!(back.end_ms, back.start_ms + 1, "{back:?}");
    assert!(t.contains(&back.start_ms) && t.contains(&back.end_ms));
    // Two hours forward from a clock set back one: one hour past the times before the steps.
    assert!(fwd.end_ms - fwd.start_ms > HOUR_MS - 60_000, "{fwd:?}");
    assert!(t.contains(&fwd.end_ms));
    // The polls between the steps were stored, inside the two gaps' span.
    let between = t
        .iter()
        .filter(|&&x| x > back.end_ms && x < fwd.start_ms)
        .count();
    assert!(between >= 30, "{between}");
    // One line of the fault suite's tally (README, "Fault tally"); no database at this level.
    eprintln!(
        "FAULT-TALLY class=clock_step_back_and_forward injected=2 lost={} duplicated=0 \
         integrity=n/a(poll_loop_only) clock_gaps={}",
        run.stats.samples - t.len() as u64,
        clock_gaps.len()
    );
}
