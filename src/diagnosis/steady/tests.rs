//! Tests of Method A's steady windows, points and problem.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use super::*;
use crate::engine::config::{AdaptationConfig, ModelErrorBySpeed};
use crate::engine::sensors::noise_sigma;

/// A steady point "snapshot at line 7" at ambient `t_amb_k` comparing `outputs`.
fn point(t_amb_k: f64, outputs: Vec<(Signal, f64, f64)>) -> SteadyData {
    SteadyData {
        label: "snapshot at line 7".into(),
        window: SteadyWindow {
            start: 0,
            end: 1,
            t_start_s: 0.0,
            t_end_s: 0.0,
        },
        inputs: SteadyInputs {
            t_amb_k,
            p_amb_kpa: 101.325,
            n2_rpm: 3000.0,
            demand: Demand::FuelKgS(1.0),
        },
        outputs,
        n1_hint_rpm: None,
        input_sd: InputSigma::default(),
        input_response: Vec::new(),
        input_noise: InputNoise::Fitted,
    }
}

/// The adapted model's own error widens each compared value's σ in quadrature, by signal;
/// a file without one leaves the instrument σ as it is.
/// Each input's σ gives a column of what it moves the compared values by; no input σ, no
/// columns; a window mean's input σ is a reading's over √n.
#[test]
fn input_noise_adds_what_each_input_moves_to_the_sigma() {
    let engine = Engine::reference().expect("engine");
    let m = engine.model_at(&HealthParams::HEALTHY, 288.15, 101.325);
    let inputs = SteadyInputs {
        t_amb_k: 288.15,
        p_amb_kpa: 101.325,
        n2_rpm: 3600.0,
        demand: Demand::PowerMw(10.0),
    };
    let sp = solve(&m, &inputs, None).expect("solves");
    let fuel = sp.fuel_kg_s;
    let n1 = steady_reading(&m, &sp, Signal::N1);
    let t34 = steady_reading(&m, &sp, Signal::T34);
    let sensors = &engine.cfg().sensors;
    let sd = |s: Signal, v: f64| noise_sigma(sensors, s, v);
    let mut data = point(
        288.15,
        vec![
            (Signal::N1, n1, sd(Signal::N1, n1)),
            (Signal::T34, t34, sd(Signal::T34, t34)),
        ],
    );
    data.inputs = SteadyInputs {
        demand: Demand::FuelKgS(fuel),
        ..inputs
    };
    data.inputs.n2_rpm = 3600.0;
    let base = HealthParams::HEALTHY;
    assert!(
        with_input_noise(&engine, &base, data.clone())
            .input_response
            .is_empty(),
        "no input σ, no response"
    );
    data.input_sd = InputSigma::of(sensors, &data.inputs, true, 1);
    let noisy = with_input_noise(&engine, &base, data.clone());
    assert_eq!(
        noisy.outputs, data.outputs,
        "the instruments' σ stay as they are"
    );
    // What the fuel meter's σ alone moves the GG speed by, solved directly: the demand's column.
    let moved = SteadyInputs {
        demand: Demand::FuelKgS(fuel + data.input_sd.demand),
        ..data.inputs
    };
    let dn1 = steady_reading(
        &m,
        &solve(&m, &moved, Some(&sp)).expect("solves"),
        Signal::N1,
    ) - n1;
    // At 10 MW on the reference engine the fuel meter's σ moves the GG speed by about the
    // tachometer's own σ (on a flatter running line, by several times it).
    assert!(
        dn1.abs() > 0.5 * sd(Signal::N1, n1),
        "fuel moves n1 by {dn1:.1} rpm"
    );
    let r = &noisy.input_response;
    assert!(
        (r[0][3] - dn1).abs() < 0.01 * dn1.abs(),
        "{r:?} against {dn1:.2}"
    );
    // T1 moves the exhaust temperature; every input moves something.
    assert!(r[1][0].abs() > 0.1, "{r:?}");
    for k in 0..INPUTS {
        let any = r.iter().any(|col| col[k] != 0.0);
        assert_eq!(any, k != 1, "input {k} (no ambient-pressure σ here): {r:?}");
    }
    // A window mean of 100 readings: the inputs' σ a tenth of one reading's.
    let mean = InputSigma::of(sensors, &data.inputs, true, 100);
    let one = InputSigma::of(sensors, &data.inputs, true, 1);
    assert!((mean.demand * 10.0 - one.demand).abs() < 1e-12);
    assert_eq!(InputSigma::of(sensors, &data.inputs, false, 1).t_amb_k, 0.0);
}

#[test]
fn model_error_adds_to_the_instrument_sigma() {
    let mut cfg = EngineConfig::reference();
    let data = || {
        point(
            288.15,
            vec![(Signal::N1, 10000.0, 3.0), (Signal::T34, 1000.0, 3.0)],
        )
    };
    let engine = |cfg: &EngineConfig| Engine::new(cfg.clone()).expect("engine");
    assert_eq!(
        with_model_error(&engine(&cfg), data()).outputs,
        data().outputs
    );
    assert!(model_error_note(&cfg).is_none());
    let mut a = AdaptationConfig::default();
    a.model_error_pct.insert("n1_rpm".into(), 0.04);
    cfg.adaptation = Some(a.clone());
    let out = with_model_error(&engine(&cfg), data()).outputs;
    // 0.04 % of 10 000 rpm is 4 rpm; with the instrument's 3 rpm, 5 rpm.
    assert!((out[0].2 - 5.0).abs() < 1e-9, "{:?}", out[0]);
    assert_eq!(out[1].2, 3.0);
    assert!(model_error_note(&cfg).is_some_and(|n| n.contains("n1_rpm 0.04 %")));

    // Along the operating line: the point's own GG speed picks the error, linear between
    // knots (0.08 % and 0 either side of it: 0.04 %); beyond them the end segment's line where
    // it rises outward, else the end value. T34 has no row, so its average (here none) holds.
    let rel = relative_gg_speed(&engine(&cfg), &data()).expect("has a GG speed");
    let table = |knots: Vec<f64>, n1: Vec<f64>| ModelErrorBySpeed {
        speed_knots: knots,
        pct: [("n1_rpm".to_string(), n1)].into_iter().collect(),
    };
    a.model_error_pct.insert("n1_rpm".into(), 0.5);
    a.model_error_by_speed = Some(table(vec![rel - 0.05, rel + 0.05], vec![0.08, 0.0]));
    cfg.adaptation = Some(a.clone());
    let out = with_model_error(&engine(&cfg), data()).outputs;
    assert!((out[0].2 - 5.0).abs() < 1e-9, "{:?}", out[0]);
    assert_eq!(out[1].2, 3.0);
    a.model_error_by_speed = Some(table(vec![rel + 0.05, rel + 0.1], vec![0.04, 0.08]));
    cfg.adaptation = Some(a.clone());
    let out = with_model_error(&engine(&cfg), data()).outputs;
    assert!(
        (out[0].2 - 5.0).abs() < 1e-9,
        "held below the knots: {:?}",
        out[0]
    );
    a.model_error_by_speed = Some(table(vec![rel + 0.05, rel + 0.1], vec![0.02, 0.0]));
    cfg.adaptation = Some(a);
    let out = with_model_error(&engine(&cfg), data()).outputs;
    assert!(
        (out[0].2 - 5.0).abs() < 1e-9,
        "extended below the knots: {:?}",
        out[0]
    );
}

/// A point below the lowest speed the adaptation was fitted at is said to extrapolate; one
/// within its range, or an engine without an adaptation, says nothing.
#[test]
fn a_point_below_the_adapted_speeds_is_noted() {
    let mut cfg = EngineConfig::reference();
    let plain = Engine::new(cfg.clone()).expect("reference engine");
    cfg.adaptation = Some(AdaptationConfig {
        compressor: Some(crate::engine::config::ComponentCurves {
            speed_knots: vec![0.8],
            efficiency: vec![-0.01],
            ..Default::default()
        }),
        ..Default::default()
    });
    let adapted = Engine::new(cfg).expect("adapted engine");
    let d = adapted.design();
    let at = |rel: f64| point(d.t1_k, vec![(Signal::N1, rel * d.n1_rpm, 5.0)]);
    let note = below_adaptation_note(&adapted, &at(0.7)).expect("below the knots");
    assert!(note.contains("line 7") && note.contains("0.700"), "{note}");
    assert!(below_adaptation_note(&adapted, &at(0.85)).is_none());
    assert!(below_adaptation_note(&plain, &at(0.7)).is_none());
}
