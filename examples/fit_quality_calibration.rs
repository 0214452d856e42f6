//! Calibration of the fit-quality thresholds: the residual level and worst residual cell of
//! Method B on clean start-ups and on start-ups from a "plant" with one unmodelled effect, with
//! the resulting health error. `cargo run --release --example fit_quality_calibration`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use gtwatch::diagnosis::transient::diagnose_transient;
use gtwatch::diagnosis::DiagnosisConfig;
use gtwatch::engine::sensors::MeasurementOptions;
use gtwatch::engine::simulation::run_scenario;
use gtwatch::engine::{Engine, Scenario, Trace};
use gtwatch::health::HealthParams;
use gtwatch::signals::Signal;
use rand::{Rng, SeedableRng};

fn main() {
    let cases: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(4);
    let reference = Engine::reference().expect("engine");
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    for kind in ["clean", "t34_lag", "p2_bias", "t34_bias", "fuel_system"] {
        for c in 0..cases {
            let truth =
                HealthParams::from_array(std::array::from_fn(|_| rng.random_range(0.0..3.0)));
            let mut plant = reference.clone();
            match kind {
                "t34_lag" => {
                    let tau = plant.get_param("sensors.t34.tau_s").unwrap();
                    plant
                        .set_param("sensors.t34.tau_s", tau + rng.random_range(3.0..8.0))
                        .unwrap();
                }
                "fuel_system" => {
                    plant
                        .set_param("effects.fuel_system.delay_s", rng.random_range(0.8..2.0))
                        .unwrap();
                    plant
                        .set_param("effects.fuel_system.lag_s", rng.random_range(0.2..0.8))
                        .unwrap();
                    plant
                        .set_param("control.power_kp_kg_s_per_mw", 0.01)
                        .unwrap();
                    plant
                        .set_param("control.power_ki_kg_s_per_mw_s", 0.015)
                        .unwrap();
                }
                _ => {}
            }
            let (s, _) =
                run_scenario(&plant.model(&truth), &Scenario::startup(plant.cfg())).unwrap();
            let opts = MeasurementOptions {
                lags: true,
                noise: true,
                bias: false,
                seed: 100 + c as u64,
            };
            let mut rec = Trace::from_truth(&plant, &s, Some(&opts))
                .to_recording()
                .unwrap();
            let bias_sig = match kind {
                "p2_bias" => Some((Signal::P2, 2500.0)),
                "t34_bias" => Some((Signal::T34, 1200.0)),
                _ => None,
            };
            if let Some((sig, full_scale)) = bias_sig {
                let b = rng.random_range(0.008..0.015) * full_scale;
                for k in 0..rec.len() {
                    if let Some(v) = rec.value(k, sig) {
                        rec.set(k, sig, v + b).unwrap();
                    }
                }
            }
            let r = diagnose_transient(
                &reference,
                &rec,
                &DiagnosisConfig {
                    seed: 1,
                    ..DiagnosisConfig::default()
                },
            )
            .unwrap();
            let (t, f) = (truth.to_array(), r.health.to_array());
            let err = (0..6).map(|i| (f[i] - t[i]).abs()).fold(0.0, f64::max);
            println!(
                "{kind:12} case {c}: objective/signal {:.3} normalised residual {:.3} worst cell {:.2} verdict {:8} max health error {:.3} | {}",
                r.objective / r.signals.len() as f64,
                r.fit_quality.normalised_residual,
                r.fit_quality.worst_cell_error,
                r.fit_quality.verdict.as_str(),
                err,
                r.fit_quality.summary
            );
        }
    }
}
