//! Which noise source limits Method B? Diagnose the same truth with noise switched per channel.
use gtwatch::diagnosis::steady::diagnose_steady;
use gtwatch::diagnosis::transient::diagnose_transient;
use gtwatch::diagnosis::*;
use gtwatch::engine::replay::Segment;
use gtwatch::engine::sensors::MeasurementOptions;
use gtwatch::engine::{sequence, Engine, Scenario, Trace};
use gtwatch::health::HealthParams;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let e = Engine::reference().unwrap();
    let truth = HealthParams {
        D_GC: 3.0,
        D_EC: 1.0,
        D_GT: 1.5,
        D_ET: 1.0,
        D_GP: 0.5,
        D_EP: 0.8,
    };
    let (s, _) =
        sequence::run_scenario(&e.cfg, &e.model(&truth), &Scenario::startup(&e.cfg)).unwrap();
    let mut gen = e.cfg.clone();
    if a.iter().any(|x| x == "nofuel") {
        gen.sensors.fuel.noise_rel = 0.0;
    }
    if a.iter().any(|x| x == "onlyfuel") {
        let f = gen.sensors.fuel.clone();
        let z = |c: &mut gtwatch::engine::config::SensorChannel| {
            c.noise_rel = 0.0;
            c.noise_abs = 0.0;
        };
        z(&mut gen.sensors.n1);
        z(&mut gen.sensors.n2);
        z(&mut gen.sensors.t1);
        z(&mut gen.sensors.p1);
        z(&mut gen.sensors.t2);
        z(&mut gen.sensors.p2);
        z(&mut gen.sensors.p3);
        z(&mut gen.sensors.t34);
        z(&mut gen.sensors.p34);
        z(&mut gen.sensors.t4);
        z(&mut gen.sensors.p4);
        z(&mut gen.sensors.power);
        gen.sensors.fuel = f;
    }
    let mut cfg = DiagnosisConfig::default();
    cfg.max_model_runs = 400;
    if let Ok(v) = std::env::var("RW") {
        cfg.rate_weight = v.parse().unwrap();
    }
    if std::env::var("NOSMOOTH").is_ok() {
        cfg.smooth_fuel = false;
    }
    if std::env::var("DEMAND").is_ok() {
        cfg.drive_mode = gtwatch::engine::replay::DriveMode::Demand;
    }
    for seed in 1..=3u64 {
        let tr = Trace::from_truth(
            &gen,
            &s,
            Some(&MeasurementOptions {
                lags: true,
                noise: true,
                bias: false,
                seed,
            }),
        );
        let seg = Segment::from_trace(&tr);
        let b = diagnose_transient(&e, &seg, &cfg).unwrap();
        let st = diagnose_steady(&e, &seg, &cfg).unwrap();
        let err = |h: HealthParams| {
            h.to_array()
                .iter()
                .zip(truth.to_array())
                .map(|(x, y)| format!("{:+.3}", x - y))
                .collect::<Vec<_>>()
                .join(" ")
        };
        println!(
            "seed {seed}: B {}  ({:.1}s, obj {:.3})   A {}",
            err(b.health),
            b.wall_s,
            b.objective,
            err(st.health)
        );
    }
}
