//! Acceptance of the effect seam (issue 8): a start-up of a "plant" whose fuel burns 1.2 s +
//! 0.4 s after it is metered. Diagnosed with the core model alone, the health estimate absorbs
//! the mismatch; with the `fuel_system` effect enabled and its two parameters fitted alongside
//! health (named fit parameters), the health comes back within 0.1 points and the effect's
//! parameters near their true values.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::diagnosis::fit_quality::Verdict;
use gtwatch::diagnosis::transient::diagnose_transient;
use gtwatch::diagnosis::{DiagnosisConfig, FitParam};
use gtwatch::engine::sensors::MeasurementOptions;
use gtwatch::engine::simulation::run_scenario;
use gtwatch::engine::{Engine, Scenario, Trace};
use gtwatch::health::{HealthParams, HEALTH_NAMES};
use gtwatch::recording::Recording;

const LAG_S: f64 = 0.4;
const DELAY_S: f64 = 1.2;

fn truth() -> HealthParams {
    HealthParams {
        D_GC: 2.0,
        D_EC: 1.0,
        D_GT: 0.4,
        D_ET: 0.8,
        D_GP: 0.3,
        D_EP: 0.6,
    }
}

/// The plant: the reference engine with the fuel-system effect and a power loop tuned for it.
fn plant() -> Engine {
    let mut e = Engine::reference().expect("engine");
    e.set_param("effects.fuel_system.lag_s", LAG_S)
        .expect("lag");
    e.set_param("effects.fuel_system.delay_s", DELAY_S)
        .expect("delay");
    e.set_param("control.power_kp_kg_s_per_mw", 0.01)
        .expect("kp");
    e.set_param("control.power_ki_kg_s_per_mw_s", 0.015)
        .expect("ki");
    e
}

fn recorded_startup() -> Recording {
    let e = plant();
    let (s, _) =
        run_scenario(&e.model(&truth()), &Scenario::startup(e.cfg())).expect("plant start-up runs");
    let opts = MeasurementOptions {
        lags: true,
        noise: true,
        bias: false,
        seed: 11,
    };
    Trace::from_truth(&e, &s, Some(&opts))
        .to_recording()
        .expect("recording")
}

fn worst_error(h: &HealthParams) -> (f64, &'static str) {
    let (t, f) = (truth().to_array(), h.to_array());
    (0..6)
        .map(|i| ((f[i] - t[i]).abs(), HEALTH_NAMES[i]))
        .fold((0.0, ""), |a, b| if b.0 > a.0 { b } else { a })
}

#[test]
fn fitting_the_fuel_system_effect_recovers_health_where_the_core_model_cannot() {
    let rec = recorded_startup();
    let cfg = DiagnosisConfig {
        seed: 5,
        ..DiagnosisConfig::default()
    };

    // Core model alone: the fuel path's 1.6 s shows up as degradation.
    let core = Engine::reference().expect("engine");
    let without = diagnose_transient(&core, &rec, &cfg).expect("diagnoses");
    let (err_without, which) = worst_error(&without.health);
    eprintln!(
        "core model: {:?}, worst error {err_without:.3} ({which}), ssr {:.1}",
        without.health, without.ssr
    );
    assert_ne!(
        without.fit_quality.verdict,
        Verdict::Good,
        "the core model's misfit is flagged: {:?}",
        without.fit_quality
    );
    assert!(
        err_without > 0.1,
        "without the effect the worst error is only {err_without:.3} ({which}): {:?}",
        without.health
    );

    // The effect enabled, its parameters fitted with health.
    let cfg_fx = DiagnosisConfig {
        extra_params: vec![
            FitParam::effect("fuel_system", "lag_s", 0.0, 3.0),
            FitParam::effect("fuel_system", "delay_s", 0.0, 3.0),
        ],
        max_model_runs: 600,
        ..cfg
    };
    let with = diagnose_transient(&core, &rec, &cfg_fx).expect("diagnoses with the effect");
    let (err_with, which) = worst_error(&with.health);
    eprintln!(
        "with fuel_system: {:?}, worst error {err_with:.3} ({which}), ssr {:.1}, params {:?}",
        with.health,
        with.ssr,
        with.params
            .iter()
            .filter(|p| p.name.starts_with("effects."))
            .map(|p| (p.name.as_str(), p.value, p.sigma))
            .collect::<Vec<_>>()
    );
    assert!(
        err_with < 0.1,
        "with the effect the worst error is {err_with:.3} ({which}): {:?}",
        with.health
    );
    let fitted = |name: &str| {
        with.params
            .iter()
            .find(|p| p.name == name)
            .unwrap_or_else(|| panic!("{name} reported"))
            .value
    };
    let total = fitted("effects.fuel_system.lag_s") + fitted("effects.fuel_system.delay_s");
    assert!(
        (total - (LAG_S + DELAY_S)).abs() < 0.3,
        "fitted delay + lag {total:.2} s, true {}",
        LAG_S + DELAY_S
    );
    assert!(
        with.ssr < without.ssr,
        "the effect explains part of the residual"
    );
}
