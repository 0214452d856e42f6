use gtwatch::diagnosis::identifiability::identifiability;
use gtwatch::diagnosis::transient::TransientProblem;
use gtwatch::diagnosis::*;
use gtwatch::engine::replay::Segment;
use gtwatch::engine::sensors::MeasurementOptions;
use gtwatch::engine::{sequence, Engine, Scenario, Trace};
use gtwatch::health::HealthParams;
use gtwatch::optim::{thread_pool, Problem};
use std::time::Instant;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let noise = args.get(1).map(|s| s == "noise").unwrap_or(false);
    let fixed: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0.0);
    let fd: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1e-3);
    let e = Engine::reference().unwrap();
    let truth = HealthParams {
        D_GC: 3.0,
        D_EC: 1.0,
        D_GT: 1.5,
        D_ET: 1.0,
        D_GP: 0.5,
        D_EP: 0.8,
    };
    let m = e.model(&truth);
    let (s, _) = sequence::run_scenario(&e.cfg, &m, &Scenario::startup(&e.cfg)).unwrap();
    let tr = Trace::from_truth(
        &e.cfg,
        &s,
        Some(&MeasurementOptions {
            lags: true,
            noise,
            bias: false,
            seed: 3,
        }),
    );
    let seg = Segment::from_trace(&tr);
    println!("samples {}", seg.len());
    let mut cfg = DiagnosisConfig::default();
    cfg.fixed_step_s = fixed;
    cfg.fd_step = fd;
    if let Ok(v) = std::env::var("RW") {
        cfg.rate_weight = v.parse().unwrap();
    }
    if std::env::var("LATE").is_ok() {
        cfg.window.phases = vec![
            gtwatch::signals::Phase::Idle,
            gtwatch::signals::Phase::Synchronisation,
            gtwatch::signals::Phase::Loading,
            gtwatch::signals::Phase::Steady,
        ];
    }
    if let Ok(v) = std::env::var("OPT") {
        cfg.optimiser = Optimiser::parse(&v).unwrap();
    }
    if let Ok(v) = std::env::var("RUNS") {
        cfg.max_model_runs = v.parse().unwrap();
    }
    let p = TransientProblem::new(&e, &seg, &cfg).unwrap();
    let x = truth.to_array().to_vec();
    let t0 = Instant::now();
    let c = p.cost(&x);
    println!(
        "cost at truth {c:.4} one run {:?} residuals {}",
        t0.elapsed(),
        p.objective().len()
    );
    // smoothness: cost along D_GC
    for d in [-1e-2, -1e-3, -1e-4, 0.0, 1e-4, 1e-3, 1e-2] {
        let mut y = x.clone();
        y[0] += d;
        let mut r = Vec::new();
        use gtwatch::optim::ResidualProblem;
        p.residuals(&y, &mut r);
        let ssr: f64 = r.iter().map(|v| v * v).sum();
        println!("dGC {d:+e}: eq10 {:.6} ssr {:.6}", p.cost(&y), ssr);
    }
    let pool = thread_pool(None).unwrap();
    let id = identifiability(&p, &x, fd, &pool).unwrap();
    println!(
        "crb {:.4?}\nalone {:.4?} cond {:.1}",
        id.crb_sigma, id.alone_sigma, id.condition
    );
    if args.get(4).map(|s| s == "fit").unwrap_or(false) {
        let t0 = Instant::now();
        let r = gtwatch::diagnosis::transient::diagnose_transient(&e, &seg, &cfg).unwrap();
        println!(
            "fit {:?} {} sigma {:?} obj {} glob {} runs {} {:?}",
            t0.elapsed(),
            r.health,
            r.sigma,
            r.objective,
            r.global_objective,
            r.model_runs,
            r.wall_s
        );
        let t0 = Instant::now();
        let r = gtwatch::diagnosis::steady::diagnose_steady(&e, &seg, &cfg).unwrap();
        println!(
            "steady fit {:?} {} sigma {:?} obj {} runs {} win {:?}",
            t0.elapsed(),
            r.health,
            r.sigma,
            r.objective,
            r.model_runs,
            r.windows
        );
    }
}
#[allow(dead_code)]
pub fn breakdown() {}
