//! Writes a noisy synthetic start-up CSV (the `gtwatch simulate` layout) for trying `diagnose`.
use gtwatch::diagnosis::bench::synthetic_startup;
use gtwatch::engine::sensors::MeasurementOptions;
use gtwatch::engine::{sequence, Engine, Scenario, Trace};
use gtwatch::health::HealthParams;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let h: HealthParams = a[1].parse().expect("health");
    let e = Engine::reference().expect("engine");
    let _ = synthetic_startup;
    let (s, _) =
        sequence::run_scenario(&e.cfg, &e.model(&h), &Scenario::startup(&e.cfg)).expect("runs");
    let tr = Trace::from_truth(
        &e.cfg,
        &s,
        Some(&MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed: 7,
        }),
    );
    tr.write_csv(std::io::stdout().lock()).expect("write");
}
