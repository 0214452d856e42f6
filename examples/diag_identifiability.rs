//! Identifiability evidence: Cramér–Rao 1σ (default instrument noise, unit-variance residuals)
//! of the six health parameters from one noise-free start-up, for Method B (whole start-up) and
//! Method A (its steady windows), and the condition number of the scaled sensitivity matrix.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing
use gtwatch::diagnosis::identifiability::identifiability;
use gtwatch::diagnosis::steady::{average_windows, detect_windows, SteadyProblem};
use gtwatch::diagnosis::transient::TransientProblem;
use gtwatch::diagnosis::{bench::synthetic_startup, DiagnosisConfig};
use gtwatch::engine::Engine;
use gtwatch::health::{HealthParams, HEALTH_NAMES};
use gtwatch::optim::thread_pool;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let e = Engine::reference()?;
    let t = HealthParams {
        D_GC: 3.0,
        D_EC: 1.0,
        D_GT: 1.5,
        D_ET: 1.0,
        D_GP: 0.5,
        D_EP: 0.8,
    };
    let seg = synthetic_startup(&e, &t, 0, false)?;
    let cfg = DiagnosisConfig::default();
    let pool = thread_pool(None)?;
    let mut x = t.to_array().to_vec();
    x.push(
        seg.ambient(e.cfg().ambient.temperature_k, e.cfg().ambient.pressure_kpa)
            .1,
    );
    let b = TransientProblem::new(&e, &seg, &cfg)?;
    let ib = identifiability(&b, &x, cfg.fd_step, &pool)?;
    let w = detect_windows(&seg, e.cfg(), &cfg.steady);
    let a = SteadyProblem::new(&e, average_windows(&seg, e.cfg(), &w, &cfg.signals), &cfg)?;
    let ia = identifiability(&a, &x, cfg.fd_step, &pool)?;
    println!(
        "{:6} {:>10} {:>10} {:>10} {:>10}",
        "", "B CRB", "B alone", "A CRB", "A alone"
    );
    for (i, n) in HEALTH_NAMES.iter().chain(["p_amb"].iter()).enumerate() {
        println!(
            "{n:6} {:10.4} {:10.4} {:10.4} {:10.4}",
            ib.crb_sigma[i], ib.alone_sigma[i], ia.crb_sigma[i], ia.alone_sigma[i]
        );
    }
    println!(
        "condition: B {:.1}, A {:.1}; {} steady windows",
        ib.condition,
        ia.condition,
        w.len()
    );
    Ok(())
}
