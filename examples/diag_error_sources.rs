//! Error sources of the diagnosis: the wash bench's after-wash start-up (noise seed 14) diagnosed
//! with the noise of one channel at a time removed. Showed that the rest-sample ambient pressure
//! (P1 noise) dominated both methods' error before the ambient pressure was fitted.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing
use gtwatch::diagnosis::bench::wash_truth;
use gtwatch::diagnosis::steady::diagnose_steady;
use gtwatch::diagnosis::transient::diagnose_transient;
use gtwatch::diagnosis::DiagnosisConfig;
use gtwatch::engine::sensors::MeasurementOptions;
use gtwatch::engine::{Engine, Scenario, Trace};
use gtwatch::signals::Signal;
fn main() {
    let e = Engine::reference().expect("engine");
    let (_, a) = wash_truth();
    let (s, _) =
        gtwatch::engine::simulation::run_scenario(&e.model(&a), &Scenario::startup(e.cfg()))
            .expect("runs");
    let tr = Trace::from_truth(
        &e,
        &s,
        Some(&MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed: 14,
        }),
    );
    let clean = Trace::from_truth(
        &e,
        &s,
        Some(&MeasurementOptions {
            lags: true,
            noise: false,
            bias: false,
            seed: 14,
        }),
    );
    let cfg = DiagnosisConfig::default();
    for fix in [
        vec![],
        vec![Signal::P1],
        vec![Signal::T1],
        vec![Signal::FuelFlow],
        vec![Signal::Power],
        vec![Signal::T4],
        vec![Signal::P4],
        vec![Signal::T34, Signal::P34],
    ] {
        let mut seg = tr.to_recording().expect("recording");
        for k in 0..seg.len() {
            for s in &fix {
                seg.set(k, *s, clean.measured[k][s.index()]).expect("valid");
            }
        }
        let r = diagnose_transient(&e, &seg, &cfg).expect("b");
        let st = diagnose_steady(&e, &seg, &cfg).expect("a");
        let err = |h: gtwatch::health::HealthParams| {
            h.to_array()
                .iter()
                .zip(a.to_array())
                .map(|(x, y)| format!("{:+.3}", x - y))
                .collect::<Vec<_>>()
                .join(" ")
        };
        println!(
            "noise-free {:?}: B {}   A {}",
            fix,
            err(r.health),
            err(st.health)
        );
    }
}
