//! Unit tests of the `[adaptation]` section: its checks, defaults and what the curves move.

use crate::engine::config::{EngineConfig, REFERENCE_ENGINE_TOML};
use crate::engine::steady::{solve, Demand, SteadyInputs};
use crate::engine::Engine;
use crate::health::HealthParams;

fn with(section: &str) -> Result<EngineConfig, String> {
    let text = format!("{REFERENCE_ENGINE_TOML}\n{section}\n");
    EngineConfig::from_toml_str(&text, "x.toml").map_err(|e| e.to_string())
}

#[test]
fn malformed_sections_name_the_key() {
    for (section, key) in [
        (
            "[adaptation.compressor]\nspeed_knots = [0.8, 0.7]\nflow = [0.1, 0.1]",
            "adaptation.compressor.speed_knots",
        ),
        (
            "[adaptation.compressor]\nspeed_knots = [0.8, 1.0]\nflow = [0.1, 0.1]",
            "adaptation.compressor.speed_knots",
        ),
        (
            "[adaptation.hpt]\nspeed_knots = [0.8]\nflow = [0.1, 0.1]",
            "adaptation.hpt.flow",
        ),
        (
            "[adaptation.pt]\nspeed_knots = [0.8]\npressure_ratio = [0.1]",
            "adaptation.pt.pressure_ratio",
        ),
        (
            "[adaptation.pt]\nspeed_knots = [0.8]\nflow = [0.9]",
            "adaptation.pt.flow",
        ),
        (
            // The GG's corrected speed is for the HP turbine's knots only.
            "[adaptation.pt]\nspeed_knots = [0.8]\nflow = [0.01]\nspeed_of = \"gg_inlet\"",
            "adaptation.pt.speed_of",
        ),
        (
            // The map's efficiency is held for a turbine's only.
            "[adaptation.compressor]\nspeed_knots = [0.8]\nflow = [0.01]\n\
             efficiency_shape = \"curve\"",
            "adaptation.compressor.efficiency_shape",
        ),
        (
            "[adaptation.pt]\nspeed_knots = [0.8]\nflow = [0.01]\n\
             efficiency_shape = \"flat\"",
            "efficiency_shape",
        ),
        (
            "[adaptation.model_error_pct]\nn1 = 0.3",
            "adaptation.model_error_pct.n1",
        ),
        (
            "[adaptation.model_error_pct]\nt34_k = -0.3",
            "adaptation.model_error_pct.t34_k",
        ),
        (
            "[adaptation.model_error_pct]\nt34_k = 30.0",
            "adaptation.model_error_pct.t34_k",
        ),
        (
            "[adaptation.health_error]\nD_XX = 0.3",
            "adaptation.health_error.D_XX",
        ),
        (
            "[adaptation.health_error]\nD_GC = -0.3",
            "adaptation.health_error.D_GC",
        ),
        (
            "[adaptation.health_error]\nD_GC = 12.0",
            "adaptation.health_error.D_GC",
        ),
        (
            "[adaptation.model_error_by_speed]\nspeed_knots = [0.8, 0.7]\nn1_rpm = [1, 1]",
            "adaptation.model_error_by_speed.speed_knots",
        ),
        (
            "[adaptation.model_error_by_speed]\nspeed_knots = [0.7, 0.8]\nn1_rpm = [1]",
            "adaptation.model_error_by_speed.n1_rpm",
        ),
        (
            "[adaptation.model_error_by_speed]\nspeed_knots = [0.7, 0.8]\nn1 = [1, 1]",
            "adaptation.model_error_by_speed.n1",
        ),
        (
            "[adaptation.model_error_by_speed]\nspeed_knots = [0.7, 0.8]\nt4_k = [1, 30]",
            "adaptation.model_error_by_speed.t4_k",
        ),
        (
            "[adaptation.calibrated]\ngg_speed = [0.9, 0.8]",
            "adaptation.calibrated.gg_speed",
        ),
        (
            "[adaptation.calibrated]\ngg_speed = [0.0, 0.8]",
            "adaptation.calibrated.gg_speed",
        ),
        ("[adaptation.calibrated]\ngg_speed = [0.8]", "gg_speed"),
        (
            "[adaptation.offline_shape]\nefficiency_slope_sigma = -0.1",
            "adaptation.offline_shape.efficiency_slope_sigma",
        ),
        (
            "[adaptation.offline_shape]\nflow_slope_sigma = 3.0",
            "adaptation.offline_shape.flow_slope_sigma",
        ),
        (
            "[adaptation.offline_shape]\nslope_sigma = 0.1",
            "slope_sigma",
        ),
    ] {
        let err = with(section).expect_err(section);
        assert!(err.contains(key), "{section}: {err}");
    }
}

/// The off-line slopes' σ: the defaults where the file has curves and states none, the
/// file's own where it does (a key left out at its default), none for the model's own maps.
#[test]
fn the_offline_shape_defaults_only_for_a_file_with_curves() {
    use crate::engine::config::OfflineShape;
    let curves = "[adaptation.compressor]\nspeed_knots = [0.8]\nflow = [0.01]\n";
    let shape = |text: &str| {
        with(text)
            .expect("loads")
            .adaptation
            .map(|a| a.offline_shape())
    };
    assert_eq!(shape(curves), Some(OfflineShape::default()));
    let own = shape(&format!(
        "{curves}[adaptation.offline_shape]\nefficiency_slope_sigma = 0.1"
    ))
    .expect("adapted");
    assert_eq!(own.efficiency_slope_sigma, 0.1);
    assert_eq!(
        own.flow_slope_sigma,
        crate::engine::config::DEFAULT_FLOW_SLOPE_SIGMA
    );
    assert_eq!(
        shape("[adaptation.health_error]\nD_GC = 0.2"),
        Some(OfflineShape::NONE)
    );
}

#[test]
fn a_point_beyond_the_calibrated_speeds_is_named_with_its_side() {
    let cfg = with("[adaptation.calibrated]\ngg_speed = [0.78, 0.998]").expect("loads");
    let range = cfg.adaptation.and_then(|a| a.calibrated).expect("range");
    assert_eq!(range.gg_speed, [0.78, 0.998]);
    // Within the range and its margin: diagnosed.
    for rel in [
        0.78,
        0.9,
        0.998,
        0.998 + super::CALIBRATED_MARGIN * 0.9,
        0.776,
    ] {
        assert!(range.beyond(rel).is_none(), "{rel}");
    }
    let above = range.beyond(1.01).expect("above");
    assert!(
        above.contains("1.010 is above the highest") && above.contains("0.780…0.998"),
        "{above}"
    );
    let below = range.beyond(0.7).expect("below");
    assert!(below.contains("below the lowest"), "{below}");
}

#[test]
fn the_design_point_stays_and_part_load_moves() {
    let plain = Engine::new(EngineConfig::reference()).expect("reference");
    let cfg = with(
        "[adaptation.compressor]\nspeed_knots = [0.7, 0.85]\nspeed = [0.05, 0.02]\n\
         efficiency = [-0.02, -0.01]",
    )
    .expect("loads");
    let adapted = Engine::new(cfg).expect("adapted");
    assert_eq!(plain.design(), adapted.design());
    let inp = |mw: f64| SteadyInputs {
        t_amb_k: 288.15,
        p_amb_kpa: 101.325,
        n2_rpm: 3600.0,
        demand: Demand::PowerMw(mw),
    };
    let h = HealthParams::HEALTHY;
    let a = solve(&plain.model(&h), &inp(31.4), None).expect("design");
    let b = solve(&adapted.model(&h), &inp(31.4), None).expect("design");
    assert!((a.stations.n1_rpm / b.stations.n1_rpm - 1.0).abs() < 1e-6);
    let a = solve(&plain.model(&h), &inp(10.0), None).expect("part load");
    let b = solve(&adapted.model(&h), &inp(10.0), None).expect("part load");
    // The speed line read is re-labelled upwards: the same flow at a lower speed.
    assert!(b.stations.n1_rpm < a.stations.n1_rpm - 50.0, "{a:?} {b:?}");
}
