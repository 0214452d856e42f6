//! The bad-value policy on the Modbus path: a test server whose T34 register freezes while n1
//! moves, with one spike, polled by the real poll loop.

use crate::acquire::modbus::{AcquisitionConfig, PollPlan};
use crate::acquire::register_map::{ModbusConfig, RegisterKind, RequestSpec};
use crate::acquire::test_support::{run_poll_loop, serve, u16_field, Until};
use crate::quality::Quality;
use crate::signals::Signal;
use crate::store::Sample;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use tokio_modbus::prelude::{ExceptionCode, Request, Response};

/// Poll k: n1 = 3000 + 10 k rpm; T34 = 700 + k K, except 1300 K at k = 10 (a spike), then
/// frozen at 720 K from k = 20.
fn t34_at(k: u64) -> u16 {
    match k {
        10 => 1300,
        k if k >= 20 => 720,
        k => 700 + k as u16,
    }
}

#[derive(Clone)]
struct Plant {
    polls: Arc<AtomicU64>,
}

impl tokio_modbus::server::Service for Plant {
    type Request = Request<'static>;
    type Response = Response;
    type Exception = ExceptionCode;
    type Future = std::future::Ready<Result<Response, ExceptionCode>>;
    fn call(&self, req: Request<'static>) -> Self::Future {
        std::future::ready(match req {
            Request::ReadHoldingRegisters(0, 2) => {
                let k = self.polls.fetch_add(1, Ordering::SeqCst);
                let n1 = (3000 + 10 * k).min(60_000) as u16;
                Ok(Response::ReadHoldingRegisters(vec![n1, t34_at(k)]))
            }
            _ => Err(ExceptionCode::IllegalFunction),
        })
    }
}

#[tokio::test]
async fn stuck_and_spiking_register_is_stored_flagged() {
    let plant = Plant {
        polls: Arc::new(AtomicU64::new(0)),
    };
    let (addr, server) = serve(plant).await;
    let field = |name: &str, address, signal| u16_field(name, address, Some(signal));
    let map = ModbusConfig {
        endpoint: addr.to_string(),
        requests: vec![RequestSpec {
            slave_id: 1,
            register: RegisterKind::Holding,
            start_address: 0,
            count: None,
            fields: vec![field("n1", 0, Signal::N1), field("t34", 1, Signal::T34)],
        }],
    };
    let mut plan = PollPlan::new(&map, &[1, 2]).expect("plan");
    plan.quality.stuck_after_s = 0.2;
    let cfg = AcquisitionConfig {
        poll_period_ms: 10,
        ..AcquisitionConfig::default()
    };
    let run = run_poll_loop(cfg, plan, None, Until::Samples(2 * 120), |_| {}).await;
    server.abort();
    let (got, stats) = (run.samples, run.stats);
    let t34: Vec<Sample> = got.iter().filter(|s| s.tag == 2).copied().collect();
    let n1: Vec<Sample> = got.iter().filter(|s| s.tag == 1).copied().collect();
    // Every polled value is stored (the held one released at shutdown), none twice.
    assert_eq!(t34.len(), n1.len());
    assert!(t34.windows(2).all(|w| w[0].t_ms < w[1].t_ms));
    let spikes: Vec<&Sample> = t34.iter().filter(|s| s.quality == Quality::Spike).collect();
    assert_eq!(spikes.len(), 1, "{t34:?}");
    assert_eq!(spikes[0].value, 1300.0);
    assert!(n1.iter().all(|s| s.quality == Quality::Good));
    // Frozen at 720 K from poll 20; n1 has moved > 500 rpm after 50 polls and the freeze is
    // older than 0.2 s after ~20 polls: stuck from then on, never good again.
    let frozen: Vec<&Sample> = t34.iter().filter(|s| s.value == 720.0).collect();
    let first_stuck = frozen
        .iter()
        .position(|s| s.quality == Quality::Stuck)
        .expect("stuck flagged");
    assert!(first_stuck >= 20, "flagged too early: {first_stuck}");
    assert!(frozen[first_stuck..]
        .iter()
        .all(|s| s.quality == Quality::Stuck));
    let n_stuck = t34.iter().filter(|s| s.quality == Quality::Stuck).count() as u64;
    assert_eq!(stats.stuck, n_stuck);
    assert_eq!(stats.spike, 1);
    assert_eq!(stats.flagged, n_stuck + 1);
    assert_eq!(stats.samples, got.len() as u64);
}
