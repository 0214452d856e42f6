//! Fault tests for the daemon's acquisition: the Modbus server going away and coming back, a
//! server answering later than the timeout, and garbage / out-of-range register values.
//! Each test runs real servers on 127.0.0.1 and the real `daemon::run`, for about a second.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use gtwatch::acquire::modbus::PollProgress;
use gtwatch::acquire::register_map::{ByteOrder, DataType, FieldSpec, RegisterKind, RequestSpec};
use gtwatch::daemon::{self, RunOptions, RunReport};
use gtwatch::plantsim::{spawn_plant_sim, PlantFrame, PlantModel, ScriptedPlant, SimOptions};
use gtwatch::shutdown::shutdown_channel;
use gtwatch::signals::{Phase, Signal};
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::net::TcpListener;
use tokio_modbus::prelude::{ExceptionCode, Request, Response};
use tokio_modbus::server::tcp::{accept_tcp_connection, Server};

const POLL_MS: u64 = 10;

async fn wait_polls(p: &PollProgress, n: u64) {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
    while p.polls_ok.load(Ordering::Relaxed) < n {
        assert!(
            tokio::time::Instant::now() < deadline,
            "polls stalled: {p:?}"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

fn sim_opts() -> SimOptions {
    SimOptions {
        speedup: 100.0,
        tick: Some(Duration::from_millis(POLL_MS)),
        lockstep: false,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn server_stopped_and_restarted_gives_one_gap_and_reconnection() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db_path = dir.path().join("restart.db");
    let map = common::reference_config().modbus.expect("map");
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr");
    let sim = spawn_plant_sim(
        listener,
        map.clone(),
        Box::new(ScriptedPlant::demo(1.0)),
        sim_opts(),
        None,
    )
    .expect("sim");
    let cfg = common::fast_config(&addr.to_string(), db_path.clone(), POLL_MS);
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
    wait_polls(&progress, 30).await;
    // One stop/restart cycle (× GTWATCH_FAULTS_LONG).
    let cycles = common::long_factor() as u64;
    let mut sim = sim;
    for _ in 0..cycles {
        sim.stop().await.expect("stop");
        let failures_before = progress.failures.load(Ordering::Relaxed);
        tokio::time::sleep(Duration::from_millis(400)).await;
        let during = progress.polls_ok.load(Ordering::Relaxed);
        assert!(
            progress.failures.load(Ordering::Relaxed) >= failures_before + 2,
            "{progress:?}"
        );
        // Same port again: the PLC came back.
        let listener = TcpListener::bind(addr).await.expect("rebind");
        sim = spawn_plant_sim(
            listener,
            map.clone(),
            Box::new(ScriptedPlant::demo(1.0)),
            sim_opts(),
            None,
        )
        .expect("sim again");
        wait_polls(&progress, during + 30).await;
    }
    trigger.trigger();
    let report: RunReport = daemon.await.expect("join").expect("daemon survived");
    sim.stop().await.expect("stop");

    assert!(report.poll.connects > cycles, "{report:?}");
    assert_eq!(report.poll.gaps, cycles, "{report:?}");
    let db = common::open_db(&db_path);
    let gaps = common::gaps(&db);
    assert_eq!(gaps.len() as u64, cycles, "{gaps:?}");
    let n1 = common::tag_samples(&db, "n1_rpm");
    for (start, end, source, reason) in &gaps {
        assert_eq!(source, "modbus");
        assert!(
            end - start >= 350,
            "gap {start}..{end} shorter than the outage"
        );
        assert!(
            end - start < 3000,
            "gap {start}..{end} longer than the outage"
        );
        assert!(
            reason.contains(&addr.to_string()) || reason.contains("read holding"),
            "{reason}"
        );
        // Samples on both sides of the gap, none inside it.
        assert!(n1.iter().any(|s| s.0 <= *start));
        assert!(n1.iter().any(|s| s.0 >= *end));
        assert!(n1.iter().all(|s| s.0 <= *start || s.0 >= *end));
    }
    let duplicated = common::duplicate_samples(&db);
    assert_eq!(duplicated, 0);
    let lost = common::polled_not_stored(report.poll.samples, &db);
    assert_eq!(lost, 0, "{report:?}");
    common::Tally {
        class: "modbus_server_killed_and_restarted",
        injected: cycles,
        lost,
        duplicated,
        integrity: &common::integrity(&db_path),
        note: format!(
            "gaps={} reconnects={}",
            gaps.len(),
            report.poll.connects - 1
        ),
    }
    .print();
}

/// A server that numbers every request and answers some of them late (after the client's
/// timeout). Register 0–1 carries the request number as u32.
#[derive(Clone)]
struct LateServer {
    counter: Arc<AtomicU64>,
    late: Arc<Mutex<Vec<u64>>>,
}

impl tokio_modbus::server::Service for LateServer {
    type Request = Request<'static>;
    type Response = Response;
    type Exception = ExceptionCode;
    type Future = Pin<Box<dyn Future<Output = Result<Response, ExceptionCode>> + Send>>;

    fn call(&self, req: Request<'static>) -> Self::Future {
        let Request::ReadHoldingRegisters(_, n) = req else {
            return Box::pin(async { Err(ExceptionCode::IllegalFunction) });
        };
        let id = self.counter.fetch_add(1, Ordering::SeqCst) + 1;
        let late = id % 5 == 3;
        if late {
            if let Ok(mut l) = self.late.lock() {
                l.push(id);
            }
        }
        Box::pin(async move {
            if late {
                tokio::time::sleep(Duration::from_millis(250)).await;
            }
            let mut words = vec![0u16; n as usize];
            words[0] = (id >> 16) as u16;
            words[1] = id as u16;
            Ok(Response::ReadHoldingRegisters(words))
        })
    }
}

fn field(name: &str, address: u32, ty: DataType, signal: Option<Signal>) -> FieldSpec {
    FieldSpec {
        name: name.into(),
        address,
        data_type: ty,
        byte_order: ByteOrder::ABCD,
        scale: 1.0,
        offset: 0.0,
        unit: String::new(),
        signal,
        min: None,
        max: None,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn late_replies_are_never_taken_for_the_next_answer() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db_path = dir.path().join("late.db");
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr");
    let svc = LateServer {
        counter: Arc::new(AtomicU64::new(0)),
        late: Arc::new(Mutex::new(Vec::new())),
    };
    let late = Arc::clone(&svc.late);
    let server = tokio::spawn(async move {
        let s = Server::new(listener);
        let new_service = move |_a| Ok(Some(svc.clone()));
        let on_connected = |stream, a| {
            let ns = new_service.clone();
            async move { accept_tcp_connection(stream, a, ns) }
        };
        let _ = s.serve(&on_connected, |_e| {}).await;
    });
    let mut cfg = common::fast_config(&addr.to_string(), db_path.clone(), POLL_MS);
    cfg.acquisition.request_timeout_ms = 60;
    let m = cfg.modbus.as_mut().expect("map");
    m.requests = vec![RequestSpec {
        slave_id: 1,
        register: RegisterKind::Holding,
        start_address: 0,
        count: None,
        fields: vec![
            field("request_no", 0, DataType::U32, None),
            field("n1_rpm", 2, DataType::U16, Some(Signal::N1)),
        ],
    }];
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
    wait_polls(&progress, 40 * u64::from(common::long_factor())).await;
    trigger.trigger();
    let report = daemon.await.expect("join").expect("daemon survived");
    server.abort();

    let late = late.lock().expect("lock").clone();
    assert!(late.len() >= 5, "server answered late {} times", late.len());
    assert!(
        report.poll.failures as usize >= late.len() - 1,
        "{report:?}"
    );
    let db = common::open_db(&db_path);
    let stored = common::tag_samples(&db, "request_no");
    assert!(stored.len() >= 40);
    // Every stored answer belongs to its own poll: numbers strictly increase and none of the
    // late answers was ever stored.
    for w in stored.windows(2) {
        assert!(w[1].1 > w[0].1, "request numbers not increasing: {w:?}");
    }
    for (_, v, q) in &stored {
        assert_eq!(*q, 0);
        assert!(!late.contains(&(*v as u64)), "late reply {v} was stored");
    }
    let gaps = common::gaps(&db);
    assert!(!gaps.is_empty());
    assert!(
        gaps.iter().all(|g| g.3.contains("timed out after 60 ms")),
        "{gaps:?}"
    );
    let duplicated = common::duplicate_samples(&db);
    assert_eq!(duplicated, 0);
    let lost = common::polled_not_stored(report.poll.samples, &db);
    assert_eq!(lost, 0, "{:?}", report.poll);
    common::Tally {
        class: "modbus_reply_after_timeout",
        injected: late.len() as u64,
        lost,
        duplicated,
        integrity: &common::integrity(&db_path),
        note: format!("late_replies_stored=0 gaps={}", gaps.len()),
    }
    .print();
}

/// A plant whose odd frames are garbage: NaN, infinities and absurd magnitudes.
struct GarbagePlant {
    k: u64,
}

impl PlantModel for GarbagePlant {
    fn step(&mut self) -> PlantFrame {
        self.k += 1;
        let mut v = [0.0; gtwatch::signals::NSIG];
        let good = self.k % 2 == 0;
        let set = |v: &mut [f64; gtwatch::signals::NSIG], s: Signal, good_v: f64, bad_v: f64| {
            v[s.index()] = if good { good_v } else { bad_v };
        };
        set(&mut v, Signal::N1, 9000.0, f64::NAN); // f32 NaN → bad
        set(&mut v, Signal::N2, 3600.0, f64::INFINITY); // f32 +Inf → bad
        set(&mut v, Signal::T2, 700.0, 6000.0); // u16 ×0.1 → above max
        set(&mut v, Signal::P2, 2400.0, -1.0e9); // f32 → below min
        set(&mut v, Signal::T34, 1100.0, 0.0); // u16 0 → below min (a dead channel)
        set(&mut v, Signal::P34, 400.0, 400.0);
        set(&mut v, Signal::T4, 800.0, 800.0);
        set(&mut v, Signal::P4, 104.0, 104.0);
        set(&mut v, Signal::FuelFlow, 1.5, 1.0e12); // i32 saturates → above max
        set(&mut v, Signal::Power, 30.0, f64::NEG_INFINITY); // f64 −Inf → bad
        set(&mut v, Signal::T1, 288.15, 288.15);
        set(&mut v, Signal::P1, 101.3, 101.3);
        PlantFrame {
            t_s: self.k as f64 * 0.025,
            values: v,
            phase: Phase::Steady,
        }
    }
    fn period_s(&self) -> f64 {
        0.025
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_and_out_of_range_values_are_flagged_never_good() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db_path = dir.path().join("garbage.db");
    let map = common::reference_config().modbus.expect("map");
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let sim = spawn_plant_sim(
        listener,
        map.clone(),
        Box::new(GarbagePlant { k: 0 }),
        SimOptions {
            speedup: 1.0,
            tick: Some(Duration::from_millis(25)),
            lockstep: false,
        },
        None,
    )
    .expect("sim");
    let cfg = common::fast_config(&sim.local_addr.to_string(), db_path.clone(), POLL_MS);
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
    wait_polls(&progress, 60 * u64::from(common::long_factor())).await;
    trigger.trigger();
    let report = daemon.await.expect("join").expect("daemon survived");
    sim.stop().await.expect("stop");
    assert!(report.poll.flagged > 0, "{report:?}");

    let db = common::open_db(&db_path);
    let expect_bad = ["n1_rpm", "n2_rpm", "power_mw"];
    let expect_oor = ["t2_k", "p2_kpa", "t34_k", "fuel_kg_s"];
    for (_, f) in map.fields() {
        let s = common::tag_samples(&db, &f.name);
        assert!(!s.is_empty(), "{} has samples", f.name);
        for (t, v, q) in &s {
            if *q == 0 {
                assert!(v.is_finite(), "{} good but not finite at {t}", f.name);
                assert!(
                    f.min.is_none_or(|lo| *v >= lo),
                    "{} good but {v} < min",
                    f.name
                );
                assert!(
                    f.max.is_none_or(|hi| *v <= hi),
                    "{} good but {v} > max",
                    f.name
                );
            }
        }
        let count = |q: i64| s.iter().filter(|x| x.2 == q).count();
        if expect_bad.contains(&f.name.as_str()) {
            assert!(
                count(2) > 0 && count(0) > 0,
                "{}: {:?}",
                f.name,
                (count(0), count(2))
            );
            assert_eq!(count(1), 0, "{}", f.name);
        } else if expect_oor.contains(&f.name.as_str()) {
            assert!(
                count(1) > 0 && count(0) > 0,
                "{}: {:?}",
                f.name,
                (count(0), count(1))
            );
            assert_eq!(count(2), 0, "{}", f.name);
        } else {
            assert_eq!(s.len(), count(0), "{} should be all good", f.name);
        }
    }
    let duplicated = common::duplicate_samples(&db);
    assert_eq!(duplicated, 0);
    let lost = common::polled_not_stored(report.poll.samples, &db);
    assert_eq!(lost, 0, "{:?}", report.poll);
    common::Tally {
        class: "bad_values_nan_inf_out_of_range",
        injected: report.poll.flagged,
        lost,
        duplicated,
        integrity: &common::integrity(&db_path),
        note: "stored_as_good=0".to_string(),
    }
    .print();
}

/// A server answering every read with pseudo-random words: every stored sample is either
/// flagged or plausible.
#[derive(Clone)]
struct NoiseServer {
    state: Arc<AtomicU64>,
}

impl tokio_modbus::server::Service for NoiseServer {
    type Request = Request<'static>;
    type Response = Response;
    type Exception = ExceptionCode;
    type Future = std::future::Ready<Result<Response, ExceptionCode>>;

    fn call(&self, req: Request<'static>) -> Self::Future {
        let next = || {
            // xorshift64*, deterministic per server.
            let mut x = self.state.load(Ordering::Relaxed);
            x ^= x >> 12;
            x ^= x << 25;
            x ^= x >> 27;
            self.state.store(x, Ordering::Relaxed);
            (x.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 48) as u16
        };
        std::future::ready(match req {
            Request::ReadHoldingRegisters(_, n) => Ok(Response::ReadHoldingRegisters(
                (0..n).map(|_| next()).collect(),
            )),
            Request::ReadInputRegisters(_, n) => Ok(Response::ReadInputRegisters(
                (0..n).map(|_| next()).collect(),
            )),
            _ => Err(ExceptionCode::IllegalFunction),
        })
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn random_register_garbage_is_never_stored_as_good_implausible_data() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db_path = dir.path().join("noise.db");
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr");
    let svc = NoiseServer {
        state: Arc::new(AtomicU64::new(0x9E37_79B9_7F4A_7C15)),
    };
    let server = tokio::spawn(async move {
        let s = Server::new(listener);
        let new_service = move |_a| Ok(Some(svc.clone()));
        let on_connected = |stream, a| {
            let ns = new_service.clone();
            async move { accept_tcp_connection(stream, a, ns) }
        };
        let _ = s.serve(&on_connected, |_e| {}).await;
    });
    let cfg = common::fast_config(&addr.to_string(), db_path.clone(), POLL_MS);
    let map = cfg.modbus.clone().expect("map");
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
    wait_polls(&progress, 50 * u64::from(common::long_factor())).await;
    trigger.trigger();
    let report = daemon.await.expect("join").expect("daemon survived");
    server.abort();
    let db = common::open_db(&db_path);
    let mut flagged = 0;
    for (_, f) in map.fields() {
        for (t, v, q) in common::tag_samples(&db, &f.name) {
            if q == 0 {
                assert!(v.is_finite(), "{} good but not finite at {t}", f.name);
                assert!(f.min.is_none_or(|lo| v >= lo), "{} good {v} < min", f.name);
                assert!(f.max.is_none_or(|hi| v <= hi), "{} good {v} > max", f.name);
            } else {
                flagged += 1;
            }
        }
    }
    assert!(
        flagged > 100,
        "random words should mostly be implausible ({flagged})"
    );
    let duplicated = common::duplicate_samples(&db);
    assert_eq!(duplicated, 0);
    let lost = common::polled_not_stored(report.poll.samples, &db);
    assert_eq!(lost, 0, "{:?}", report.poll);
    common::Tally {
        class: "modbus_random_register_words",
        injected: progress.polls_ok.load(Ordering::Relaxed),
        lost,
        duplicated,
        integrity: &common::integrity(&db_path),
        note: format!("flagged={flagged} implausible_stored_as_good=0"),
    }
    .print();
}
