//! The first independent simulator's unit (`tests/data/foreign/indep30/`).
//!
//! The truth (`tests/data/foreign/indep30/`): `sim.py`, a steady two-shaft gas-turbine model in
//! plain Python written for these tests from textbook performance physics by someone who did
//! not read gtwatch's code — NASA-polynomial gas properties, analytic compressor speed lines and
//! efficiency island, variable guide vanes closing below 93 % corrected speed, Stodola-ellipse
//! turbines with efficiency on the blade-speed ratio, 5 % nozzle cooling mixed before the HPT
//! rotor and 3 % rotor cooling returned at the HPT exit, a pipeline compressor's cubic load.
//! 30 MW, PR 18.5, 9 950 / 5 500 rpm. Its files are in the plant's units (°C, bar a, kg/h) and
//! tag names, with 100-s-average noise; `true_D_*` columns give the health it was run at (the
//! same convention: flow capacity and efficiency × (1 − D/100)). Its README says what it is.
//!
//! The user's steps: `config/engine_md22.toml` with the datasheet's design point and cooling
//! split (`tests/data/foreign/indep30_user_md22.toml`), `gtwatch calibrate --adapt` on the 9
//! healthy loads with `--map` and `--units`, then `gtwatch diagnose --method steady --group-by
//! group` on a grid of 16 levels (compressor fouling, HP-turbine erosion, PT wear, combined).
//!
//! Measured (`cargo test --release --test integration foreign_simulator -- --nocapture`,
//! 2026-12-07): the baseline fits at 0.93 σ, `good`, with the PT's efficiency shaped by its
//! adaptation curve alone (`efficiency_shape = "curve"`, chosen by the calibration: the unit's
//! PT runs at 0.903–0.905 where md22's map falls off), and diagnoses `good` within 0.19 points
//! of healthy (md22's habit of dumping the cooling air
//! overboard instead: 1.42 σ, `suspect`, T4 missed by −2.6 σ and T34 by +1.8 σ at every load);
//! the grid is read with every parameter within 0.93 points (D_GC 0.93, D_EC 0.66, D_GT 0.77,
//! D_ET 0.38, D_GP 0.76, D_EP 0.34), Spearman ρ 0.72–0.90 (ceilings 0.82–0.93), compressor
//! fouling under-read by
//! about a fifth and PT wear over-read by about a third (how the borrowed maps' speed lines
//! respond to a flow or efficiency change off the healthy line, which a healthy baseline does
//! not show); the diagnosis says so: with the adapted model's own error in health units and
//! the snapshot inputs' noise (T1, fuel, n2: one reading's σ each, as every compared value has)
//! in the σ, no parameter is called separable on this 9-load grid, no level is read further
//! than 2.05 of its σ, and 12 of the 16 fits are `good` (6 with the PT map's own efficiency
//! shape, every parameter then within 0.84 points). Floors below are these figures with a
//! margin; they are what this version meets on an engine it was not made with, not the issue's
//! targets.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use super::*;

#[test]
fn a_unit_of_another_simulator_is_calibrated_and_its_grid_read_within_its_stated_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let user = INDEP30.user();

    // md22's habit (the cooling air overboard) against the datasheet's split.
    let text = std::fs::read_to_string(&user).expect("user file");
    let overboard_text = text
        .replace("cooling_bleed_frac = 0.0\n", "cooling_bleed_frac = 0.08\n")
        .replace("cooling_return_frac = 0.03\n", "");
    assert_ne!(overboard_text, text);
    let overboard = dir.path().join("overboard.toml");
    std::fs::write(
        &overboard,
        overboard_text.replace("../../../config/", &format!("{}/config/", root().display())),
    )
    .expect("write");
    let (v_over, rms_over) = verdict(&calibrate(&INDEP30, &overboard, &dir.path().join("o.toml")));
    let unit = dir.path().join("unit.toml");
    let (v, rms) = verdict(&calibrate(&INDEP30, &user, &unit));
    eprintln!("baseline: cooling returned {rms:.2} σ {v}; overboard {rms_over:.2} σ {v_over}");
    assert_eq!(v, "good", "the datasheet's cooling split: {rms:.2} σ");
    assert!(
        rms < 0.8 * rms_over,
        "returned {rms:.2} σ against overboard {rms_over:.2} σ"
    );
    let written = std::fs::read_to_string(&unit).expect("written");
    assert!(
        written.contains("cooling_return_frac = 0.03"),
        "kept in the written file"
    );
    // The unit's power turbine runs at 0.903–0.905 over its loads (`baseline_internal.csv`)
    // where md22's PT map falls off with speed: the calibration finds the curve alone
    // predicts the unit better and writes so.
    let pt = written
        .split("[adaptation.pt]")
        .nth(1)
        .expect("a PT adaptation");
    assert!(
        pt.split("\n[")
            .next()
            .is_some_and(|t| t.contains("efficiency_shape = \"curve\"")),
        "{pt}"
    );

    // The healthy baseline on its own calibration: `good`, each parameter within 0.3 points
    // (measured 0.19 at most, D_EP).
    let healthy = diagnose(&INDEP30, &unit, &INDEP30.data("baseline_noisy.csv"), &[]);
    let g = &healthy["groups"][0];
    eprintln!(
        "healthy baseline: {} {}",
        g["fit_quality"]["verdict"], g["health"]
    );
    assert_eq!(g["fit_quality"]["verdict"], "good");
    for n in HEALTH_NAMES {
        let v = g["health"][n].as_f64().expect("estimate");
        assert!(v.abs() <= 0.3, "healthy baseline {n} {v:.3}");
    }

    let read = read_grid(&INDEP30, &unit, &[]);
    // Measured 0.93 / 0.66 / 0.77 / 0.38 / 0.76 / 0.34 points and ρ 0.90 / 0.72 / 0.90 / 0.90 /
    // 0.80 / 0.82 (each parameter is 0 on half the levels or more: a tie no estimate repeats);
    // with the PT map's own efficiency shape 0.84 / 0.75 / 0.67 / 0.30 / 0.77 / 0.58, ρ 0.90 /
    // 0.72 / 0.87 / 0.91 / 0.82 / 0.82 and 6 of 16 `good`.
    read.assert_floors(&[
        (1.0, 0.85),
        (0.9, 0.62),
        (0.85, 0.8),
        (0.45, 0.85),
        (0.95, 0.75),
        (0.75, 0.75),
    ]);
    // Every error within 3 of its stated σ (measured 2.05), and nothing called separable
    // (1σ under 0.25 points) missed by more than twice that. Until the snapshot inputs' noise
    // was in the σ (fuel and T1 scatter D_GC's read over 9 loads by 0.21 points), D_GC
    // was called separable on 6 levels and missed there by up to 0.81 points (3.4 σ). The
    // verdict still takes the inputs as exact (12 of 16 `good`, the rest `suspect`: these rows'
    // inputs are spot readings, which `--noisy-inputs` is for).
    assert!(read.worst_z <= 3.0, "worst |error|/σ {:.2}", read.worst_z);
    assert!(read.separable_miss <= 0.5, "{:.2}", read.separable_miss);
    assert!(read.good >= 10, "{} of 16 fits good", read.good);
}

/// Measurement (ignored: a calibration in rounds, about 30 s): rows from just before an offline
/// wash (`indep30/prewash_noisy.csv`, the 9 loads fouled D_GC 2.0, D_EC 0.8) beside the
/// baseline, `calibrate --prewash-group`. Measured 2026-12-06 (before the calibration chose
/// the PT's efficiency shape, `efficiency_shape`): fouling found 1.46 / 0.59 (the
/// model responds to fouling about a third more than the unit, and the rows cannot tell that
/// from a smaller fouling), the baseline `good`; the grid's worst errors 0.79 / 0.58 / 0.47 /
/// 0.39 / 0.47 / 0.40 (0.84 / 0.75 / 0.67 / 0.30 / 0.77 / 0.58 on the baseline alone).
/// Measured 2026-12-07, the PT's efficiency shaped by its curve alone: fouling read 1.38 /
/// 0.67, but the rows beside the baseline fit at 0.97 σ against 0.93 σ without them, so the
/// calibration on the healthy rows alone is kept (and says why); the grid as on the baseline.
#[test]
#[ignore = "measurement: cargo test --release --test integration rows_before_a_wash_on -- --ignored --nocapture"]
fn rows_before_a_wash_on_another_simulators_unit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let base = std::fs::read_to_string(INDEP30.data("baseline_noisy.csv")).expect("baseline");
    let pre = std::fs::read_to_string(INDEP30.data("prewash_noisy.csv")).expect("pre-wash rows");
    let washed = dir.path().join("washed.csv");
    let rows: String = pre.lines().skip(1).map(|l| format!("{l}\n")).collect();
    std::fs::write(&washed, format!("{base}{rows}")).expect("write");
    let unit = dir.path().join("washed.toml");
    let c = calibrate_on(
        &INDEP30,
        &INDEP30.user(),
        &washed,
        &["--group-by", "group", "--prewash-group", "before_wash"],
        &unit,
    );
    eprintln!("pre-wash: {}", c["calibration"]["prewash"]);
    let (v, rms) = verdict(&c);
    eprintln!("calibration {rms:.2} σ {v}");
    let read = read_grid(&INDEP30, &unit, &[]);
    // The rows must not make the grid worse than the baseline alone reads it (the CI test's
    // floors).
    for (p, most) in [1.0, 0.9, 0.85, 0.45, 0.95, 0.75].into_iter().enumerate() {
        assert!(
            read.worst[p] <= most,
            "{}: {:.2}",
            HEALTH_NAMES[p],
            read.worst[p]
        );
    }
    assert!(read.rho.iter().all(|r| *r >= 0.6), "{:?}", read.rho);
}

/// The leave-one-load-out floors judged as the issue means them: the model calibrated
/// on the noisy baseline without one load, and that load predicted against the simulator's
/// own values (`baseline_exact.csv`, the same rows without their noise; a user has only the
/// noisy reading, which `calibrate --validate` compares with and sets beside that reading's
/// own noise). Each of the 7 interior loads in turn (30 % and 100 % left out are
/// extrapolations), both shapes.
///
/// Measured 2026-12-07 (`cargo test --release --test integration foreign_simulator::indep30::left_out
/// -- --nocapture`; the same as `calibrate --validate` on a file whose left-out row is the
/// exact one): the continuation shape 0.205 % mean, 0.818 % worst (power at 38.75 %): the
/// issue's 0.3 / 1 % met on this unit; the grown shape (the default, which reads degradation
/// with less cross-talk) 0.231 % mean, but power at 38.75 % load, where the vanes move and the
/// loads are sparsest, 1.60 % off: the 1 % not met there. Judged against the noisy
/// readings instead, the same folds read 0.31 / 1.57 % and 0.35 / 2.35 %.
///
/// CI runs the default shape; both (43 s beside the suite) by hand: `cargo test --release
/// --test integration left_out_loads_of_both_shapes -- --ignored --nocapture`.
#[test]
fn left_out_loads_predicted_against_the_simulators_own_values() {
    use gtwatch::calibrate::adapt::AdaptStrategy;
    left_out_loads(&INDEP30, &[(AdaptStrategy::Grown, 0.3, 1.8)]);
}

/// [`left_out_loads_predicted_against_the_simulators_own_values`] with the continuation shape
/// too: a measurement run by hand, for CI's 20 minutes.
#[test]
#[ignore = "measurement: cargo test --release --test integration left_out_loads_of_both_shapes -- --ignored --nocapture"]
fn left_out_loads_of_both_shapes_against_the_simulators_own_values() {
    use gtwatch::calibrate::adapt::AdaptStrategy;
    left_out_loads(
        &INDEP30,
        &[
            (AdaptStrategy::Continuation, 0.3, 1.0),
            (AdaptStrategy::Grown, 0.3, 1.8),
        ],
    );
}
