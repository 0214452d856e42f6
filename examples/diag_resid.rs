use gtwatch::engine::replay::{simulate_segment, DriveMode, Segment};
use gtwatch::engine::sensors::{noise_sigma, MeasurementOptions};
use gtwatch::engine::{sequence, Engine, Scenario, Trace};
use gtwatch::health::HealthParams;
use gtwatch::signals::{Phase, Signal};
use std::collections::BTreeMap;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let fixed: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(0.0);
    let mode = if args.get(2).map(|s| s == "demand").unwrap_or(false) {
        DriveMode::Demand
    } else {
        DriveMode::MeasuredFuel
    };
    let mut e = Engine::reference().unwrap();
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
            noise: false,
            bias: false,
            seed: 3,
        }),
    );
    let seg = Segment::from_trace(&tr);
    if fixed > 0.0 {
        e.cfg.solver.fixed_step_s = fixed;
    }
    let t0 = std::time::Instant::now();
    let sim = simulate_segment(&e, &truth, &seg, mode).unwrap();
    println!("run {:?}", t0.elapsed());
    let sigs = [
        Signal::N1,
        Signal::N2,
        Signal::T2,
        Signal::P2,
        Signal::T34,
        Signal::P34,
        Signal::T4,
        Signal::P4,
        Signal::Power,
        Signal::FuelFlow,
    ];
    let mut tab: BTreeMap<(u16, String), (f64, f64, usize)> = BTreeMap::new();
    for k in 0..seg.len() {
        for s in sigs {
            let z = seg.values[k][s.index()];
            let mm = sim.measured[k][s.index()];
            let sg = noise_sigma(&e.cfg.sensors, s, z)
                .max(noise_sigma(
                    &e.cfg.sensors,
                    s,
                    0.1 * 9500.0 * if s == Signal::N1 { 1.0 } else { 0.0 },
                ))
                .max(1e-9);
            let r = (z - mm) / sg;
            let ent = tab
                .entry((seg.phase[k].code(), format!("{:?}", seg.phase[k])))
                .or_insert((0.0, 0.0, 0));
            let _ = ent;
            let e2 = tab
                .entry((
                    seg.phase[k].code() * 100 + s.index() as u16,
                    format!("{:?} {}", seg.phase[k], s.short()),
                ))
                .or_insert((0.0, 0.0, 0));
            e2.0 += r * r;
            e2.1 = e2.1.max(r.abs());
            e2.2 += 1;
        }
    }
    for (k, v) in tab {
        if v.2 > 0 && v.0 > 0.0 {
            println!(
                "{:40} rms {:8.3} max {:8.3} n {}",
                k.1,
                (v.0 / v.2 as f64).sqrt(),
                v.1,
                v.2
            );
        }
    }
    let _ = Phase::Crank;
}
