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
//! (`tests/data/foreign/indep3_user_md22.toml`; the handling bleed stated as the datasheet gives
//! it, its schedule and its stage-8 port; the vane schedule not),
//! `gtwatch calibrate --adapt` on the 9 healthy lever positions, then `gtwatch diagnose --method
//! steady --group-by group --noisy-inputs` on a grid of 20 levels (compressor fouling, HP-turbine
//! erosion and fouling, PT fouling and erosion, random mixes of all six within ± 4).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use super::*;

/// Measured 2026-12-08 (`cargo test --release --test integration foreign_simulator::indep3:: --
/// --nocapture`, 38 s with the test below): the baseline 50.7 → 1.23 σ, `suspect` taken as
/// exact; the grid read with every parameter within 0.99 points (D_GC … D_EP 0.99 / 0.80 / 0.77
/// / 0.50 / 0.58 / 0.77), Spearman ρ 0.949 / 0.893 / 0.888 / 0.950 / 0.886 / 0.829 (ceilings
/// 0.954 / 0.968 / 0.954 / 0.968 / 0.886 / 0.886), 13 of 20 fits `good`; the rest `suspect`,
/// for an estimate better than new as the truth's random mixes are, on a −3 search limit, or
/// on the residual. Compressor fouling is read low (3.01 for 4, 4.73 for 5: the borrowed map's
/// response off the healthy line). The worst miss 3.17 σ, 2.58 σ once the compressor's
/// unknown slopes off the line are in the σ (`[adaptation.offline_shape]`, 2026-12-08).
/// Without the bleed stated (the file before 2026-12-08): within 1.12 / 0.88 / 0.89 / 0.67 /
/// 0.60 / 0.84, HP-turbine fouling moving D_EC to −0.87 ± 0.23, called separable (3.86 σ).
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
    assert!(rms <= 1.35, "{rms:.2} σ");

    let read = read_grid(&INDEP3, &unit, &["--noisy-inputs"]);
    read.assert_floors(&[
        (1.1, 0.92),
        (0.95, 0.85),
        (0.9, 0.85),
        (0.65, 0.92),
        (0.7, 0.85),
        (0.9, 0.78),
    ]);
    assert!(read.worst_z <= 3.0, "worst |error|/σ {:.2}", read.worst_z);
    // The compressor's efficiency read off the healthy line (fouling moves it towards choke,
    // HP-turbine wear towards surge) misses by what the borrowed map's slope along its speed
    // lines gets wrong: without `[adaptation.offline_shape]` in the σ D_EC's misses were 1.38 σ
    // RMS, with it 1.10 (its σ 0.43–0.58 for fouling of 3–5 points instead of 0.26–0.30). The
    // rest is not the slope: pure efficiency loss (level 12) and HP-turbine efficiency (13)
    // move the compressor little and read D_EC 0.40 and 0.62 off at σ 0.27–0.29.
    assert!(
        read.rms_z[1] <= 1.2,
        "D_EC: RMS |error|/σ {:.2}",
        read.rms_z[1]
    );
    assert!(read.separable_miss <= 0.7, "{:.2}", read.separable_miss);
    assert!(read.good >= 11, "{} of 20 fits good", read.good);
}

/// The leave-one-load-out floors on the third simulator's unit, judged against its own
/// values ([`left_out_loads`]). Measured 2026-12-08: 0.278 % mean, 1.282 % worst (power at the
/// 56.5 % lever, relative corrected GG speed 0.836, where the unit's bleed is still open and its
/// vanes closing): the 0.3 % met, its 1 % not on that load. Without the bleed stated
/// 0.294 / 1.575 %; stated at the compressor's exit (`port = 1`, the effect's simple form)
/// 0.367 / 1.927 %.
#[test]
fn left_out_loads_of_the_third_simulators_unit() {
    use gtwatch::calibrate::adapt::AdaptStrategy;
    left_out_loads(&INDEP3, &[(AdaptStrategy::Grown, 0.3, 1.45)]);
}

/// The user's replay configuration for the third simulator's logs (its tags, °C, kg/h and kW
/// mapped; time column `TIMESTAMP`) into `dir/u.db` with engine file `unit`, the gap analyses
/// off (a test of detection and diagnosis), and one `[detector]` key of the steady load
/// (`steady_hold_s` or `steady_extend_s`) where given; written as `dir/gtwatch.toml`.
fn indep3_replay_config(dir: &Path, unit: &Path, steady: Option<(&str, f64)>) -> PathBuf {
    let columns = "T2_C = \"t1_k\"\nP2_KPA = \"p1_kpa\"\nNGG_RPM = \"n1_rpm\"\n\
                   NPT_RPM = \"n2_rpm\"\nWF_KGH = \"fuel_kg_s\"\nP3_KPA = \"p2_kpa\"\n\
                   T3_C = \"t2_k\"\nP54_KPA = \"p34_kpa\"\nT54_C = \"t34_k\"\nT8_C = \"t4_k\"\n\
                   SHP_KW = \"power_mw\"";
    let units = "t1_k = \"degC\"\nfuel_kg_s = \"kg/h\"\nt2_k = \"degC\"\n\
                 t34_k = \"degC\"\nt4_k = \"degC\"\npower_mw = \"kW\"";
    let steady = steady.map(|(key, v)| {
        let default = match key {
            "steady_hold_s" => "steady_hold_s = 60.0",
            _ => "steady_extend_s = 0.0",
        };
        (default, format!("{key} = {v:.1}"))
    });
    let mut edits = vec![
        ("gap_on_poor_fit = true", "gap_on_poor_fit = false"),
        ("gap_on_health_step = true", "gap_on_health_step = false"),
    ];
    if let Some((default, written)) = &steady {
        edits.push((default, written));
    }
    replay_config(dir, unit, "TIMESTAMP", columns, units, 2, &edits)
}

/// The third simulator's start-ups (`indep3/dyn.py`, by the same blind hand: an air starter,
/// purge and light-off at 22 % speed, ground idle at 44 % carrying the zero-pitch propeller, a
/// five-minute warm-up, the bridge's lever ramp along the combinator, and a hot section whose
/// casings soak heat for minutes: three lumped zones of 200–320 kJ/K, 50–80 s at rated flow).
/// Its five-day operations log (`indep3/startups/operations_log.csv`, six voyages, the fourth
/// and fifth a hot restart 15 min apart; truth per voyage in `operations_voyages.csv`)
/// replayed with the steady calibration of the user's file, which states the datasheet's
/// inertias, starter, sequence speeds (light-off at the purge speed) and thermocouple lags.
///
/// Measured 2026-12-08 (`cargo test --release --test integration
/// foreign_simulator::indep3::start_ups -- --nocapture`, 24 s): every voyage found completed
/// with every phase and one Method B result each, `suspect` or `good`. With the detector's
/// defaults (steady load found 60 s after the lever ramp, the start-up closed there) the casings
/// are still soaking and the fuel 1 % above its settled value: Method B reads compressor
/// fouling 1.8–2.4 points low (mean 2.06), the healthy voyages "better than new" by 2.4 and
/// 1.9 points (flagged so). Held open 240 s more while the load holds (`[detector]
/// steady_extend_s = 240`), 0.7–1.2 low (mean 0.89; `steady_hold_s = 300` reads the same,
/// 0.90, but a unit whose load never holds five minutes would complete no start-up); 540 s,
/// 0.35–0.93 (mean 0.59; `GTWATCH_INDEP3_STEADY=steady_extend_s=540`). With the gap analyses on
/// and a 300 s hold (137 s, 2026-12-07) voyage 4's names `heat_soak`, the library's candidate
/// for the effect the model lacks. The fouling's growth is read alike every way (voyage 6
/// against voyage 1: +3.4 to +3.5 for +3.0).
#[test]
fn start_ups_of_a_unit_whose_hot_section_soaks_read_nearer_held_longer() {
    let dir = tempfile::tempdir().expect("tempdir");
    let unit = dir.path().join("unit.toml");
    calibrate(&INDEP3, &INDEP3.user(), &unit);
    // D_GC of each voyage, by the segment id its start-up gets (voyages in order).
    let truth: BTreeMap<i64, f64> = truth_in(&INDEP3, "startups/operations_voyages.csv", "voyage")
        .into_iter()
        .map(|(v, h)| (v.parse().expect("voyage number"), h[0]))
        .collect();
    let log = INDEP3.data("startups/operations_log.csv");
    let mut mean_miss = Vec::new();
    let variants: Vec<Option<(&str, f64)>> = match std::env::var("GTWATCH_INDEP3_STEADY") {
        // `key=value,…` to measure other holds by hand, e.g. `steady_hold_s=300`.
        Ok(list) => std::iter::once(None)
            .chain(list.split(',').map(|kv| {
                let (k, v) = kv.split_once('=').expect("key=value");
                let key = match k {
                    "steady_hold_s" => "steady_hold_s",
                    "steady_extend_s" => "steady_extend_s",
                    other => panic!("GTWATCH_INDEP3_STEADY: {other} is no [detector] key here"),
                };
                Some((key, v.parse().expect("a number")))
            }))
            .collect(),
        Err(_) => vec![None, Some(("steady_extend_s", 240.0))],
    };
    for (i, hold) in variants.into_iter().enumerate() {
        let sub = dir.path().join(format!("variant{i}"));
        std::fs::create_dir_all(&sub).expect("dir");
        let cfg_path = indep3_replay_config(&sub, &unit, hold);
        let b = replayed_start_ups(
            &cfg_path,
            &log,
            6,
            &[
                "crank",
                "purge",
                "light_off",
                "acceleration",
                "idle",
                "loading",
                "steady",
            ],
        );
        let gc: BTreeMap<i64, f64> = b
            .iter()
            .map(|(s, h)| (*s, h["D_GC"].as_f64().expect("D_GC")))
            .collect();
        let misses: Vec<f64> = gc.iter().map(|(s, v)| v - truth[s]).collect();
        let mean = misses.iter().map(|m| m.abs()).sum::<f64>() / misses.len() as f64;
        let growth = gc[&6] - gc[&1];
        eprintln!(
            "steady hold {hold:?}: D_GC misses {misses:+.2?} (mean |miss| {mean:.2}), voyage 6 \
             against 1 {growth:+.2} for {:+.2}",
            truth[&6] - truth[&1]
        );
        assert!(
            (growth - (truth[&6] - truth[&1])).abs() <= 1.0,
            "{growth:+.2}"
        );
        mean_miss.push(mean);
    }
    assert!(
        mean_miss[1] <= 1.1,
        "held 240 s more: mean |miss| {:.2}",
        mean_miss[1]
    );
    assert!(
        mean_miss[1] <= mean_miss[0] - 0.9,
        "held 240 s more {:.2} against closed at once {:.2}",
        mean_miss[1],
        mean_miss[0]
    );
}
