//! The third independent simulator's unit (`tests/data/foreign/indep3/`): `sim.py`, a steady
//! model of a 25 MW marine two-shaft aero-derivative written for these tests by someone who did
//! not read gtwatch's code (NASA-polynomial gas properties, an analytic 16-stage compressor map,
//! variable stator vanes closing below 95 % corrected speed that change flow, efficiency and
//! pressure ratio, a stage-8 handling bleed dumping up to 6 % overboard below 88 % corrected
//! speed, a two-stage cooled HP turbine, marine gas oil, a free PT driving a controllable-pitch
//! propeller on a combinator schedule: the lever sets both PT speed, 2 604–3 600 rpm over the
//! baseline, and pitch). PR 22, 70 kg/s, 9 500 / 3 600 rpm; full load on a hot day T54-limited.
//! Its files are in the ship's tags (aero station names: `P3_KPA` is the compressor discharge)
//! and units (°C, kPa a, kg/h, kW), each row a spot reading with its noise.
//!
//! The user's steps: `config/engine_md22.toml` with the datasheet's design point, component
//! efficiencies, cooling split, liquid fuel and `[load] mode = "measured_speed"`
//! (`tests/data/foreign/indep3_user_md22.toml`; the vane and bleed schedules not stated),
//! `gtwatch calibrate --adapt` on the 9 healthy lever positions, then `gtwatch diagnose --method
//! steady --group-by group --noisy-inputs` on a grid of 20 levels (compressor fouling, HP-turbine
//! erosion and fouling, PT fouling and erosion, random mixes of all six within ± 4).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use super::*;

/// Measured 2026-12-07 (`cargo test --release --test integration foreign_simulator::indep3:: --
/// --nocapture`, 20 s with the test below): the baseline 50.8 → 1.32 σ, `suspect` taken as
/// exact; the grid read with every parameter within 1.11 points (D_GC … D_EP 1.11 / 0.87 / 0.89
/// / 0.68 / 0.59 / 0.83), Spearman ρ 0.949 / 0.893 / 0.921 / 0.957 / 0.846 / 0.818 (ceilings
/// 0.954 / 0.968 / 0.954 / 0.968 / 0.886 / 0.886), 13 of 20 fits `good`; the rest `suspect`,
/// for an estimate better than new as the truth's random mixes are, on a −3 search limit, or
/// on the residual. Compressor fouling is read low (2.89 for 4, 4.47 for 5; 3.66 and 4.41
/// without the noise: the borrowed map's response off the healthy line). Not covered by the σ:
/// HP-turbine fouling (D_GT 1.5, D_ET 1.0) moves D_EC to −0.87 ± 0.23, called separable
/// (3.89 σ; the worst other miss 2.7 σ).
#[test]
fn a_marine_unit_on_a_controllable_pitch_propeller_of_a_third_simulator() {
    let dir = tempfile::tempdir().expect("tempdir");
    let unit = dir.path().join("unit.toml");
    let c = calibrate(&INDEP3, &INDEP3.user(), &unit);
    let (v, rms) = verdict(&c);
    eprintln!("baseline: {rms:.2} σ {v}");
    // The CDP column `P3_KPA` is mapped to p2_kpa; read also as gtwatch's own `p3_kpa` (the
    // combustor exit, 4.5 % lower) it was compared twice and the fit chased the difference.
    let signals = c["calibration"]["signals"].to_string();
    assert!(!signals.contains("p3_kpa"), "{signals}");
    assert!(rms <= 1.5, "{rms:.2} σ");

    let read = read_grid(&INDEP3, &unit, &["--noisy-inputs"]);
    read.assert_floors(&[
        (1.25, 0.9),
        (1.0, 0.85),
        (1.0, 0.88),
        (0.8, 0.9),
        (0.75, 0.8),
        (0.95, 0.75),
    ]);
    assert!(read.worst_z <= 4.2, "worst |error|/σ {:.2}", read.worst_z);
    assert!(read.separable_miss <= 1.0, "{:.2}", read.separable_miss);
    assert!(read.good >= 11, "{} of 20 fits good", read.good);
}

/// The leave-one-load-out floors on the third simulator's unit, judged against its own
/// values ([`left_out_loads`]). Measured 2026-12-07: 0.294 % mean, 1.575 % worst (power at the
/// 56.5 % lever, relative corrected GG speed 0.836, where the unit's bleed is still open and its
/// vanes closing): the 0.3 % met, its 1 % not on that load.
#[test]
fn left_out_loads_of_the_third_simulators_unit() {
    use gtwatch::calibrate::adapt::AdaptStrategy;
    left_out_loads(&INDEP3, &[(AdaptStrategy::Grown, 0.32, 1.7)]);
}
