//! The second independent simulator's unit (`tests/data/foreign/indep2/`): a 13 MW generator
//! set logged in °F, psia and lb/h without turbine pressures, its grid and its start-ups.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use super::*;

/// A unit of a second simulator nobody here wrote (`tests/data/foreign/indep2/`: its own
/// thermodynamics, maps, guide-vane schedule, cooling split and drive train, written blind to
/// gtwatch's code), as a US plant logs it: °F, psia, lb/h, electrical MW at the generator
/// terminals, and no pressure between or after the turbines. A 13 MW generator set (PT held
/// at 8 500 rpm); md22's file with the datasheet's design point
/// (`tests/data/foreign/indep2_user_md22.toml`) calibrated with `--adapt` on 9 healthy loads
/// (35–100 %, the full load a hot day's, temperature-limited), then a grid of 20 levels
/// (compressor fouling, HP-turbine fouling and erosion, PT wear, six random mixes of all six
/// parameters) diagnosed as what its rows are, spot readings (`--noisy-inputs`).
///
/// Measured 2026-12-07 (`cargo test --release --test integration foreign_simulator::indep2::a_generator
/// -- --nocapture`, 2 s): the baseline at 0.98 σ RMS, `suspect`, and 0.70 under its inputs'
/// noise, which the verdict says instead of sending the user to the curves and the cooling air;
/// the healthy baseline `good`, D_GC / D_EC / D_GT within 0.18 points; the grid's compressor
/// and HP-turbine flow read within 0.62 / 0.53 / 0.52 points (ρ 0.91 / 0.93 / 0.95, ceilings
/// 0.94 / 0.94 / 0.97), D_ET within 0.88 (ρ 0.86), and the PT's two, which these signals cannot
/// tell from the HP turbine's efficiency (no P48, no exhaust pressure), stated with σ 1.2–4
/// points and never called separable (errors up to 3.0 and 1.9; ρ 0.24 / 0.59); every error
/// within 1.85 of its σ; 16 of 20 fits `good`, the rest `suspect` with D_GP on its −3 limit.
/// Each level's full-load row (relative corrected GG speed 1.006–1.019, cold days) is left out
/// as above the calibrated speeds (the baseline's full load, a hot day, reached 0.985), and
/// the diagnosis says so.
#[test]
fn a_generator_unit_of_a_second_simulator_without_turbine_pressures() {
    let dir = tempfile::tempdir().expect("tempdir");
    let unit = dir.path().join("unit.toml");
    let c = calibrate(&INDEP2, &INDEP2.user(), &unit);
    let (v, rms) = verdict(&c);
    let fit = &c["calibration"]["baseline_fit"];
    let summary = fit["summary"].as_str().expect("summary");
    let under = fit["level_under_input_noise"]
        .as_f64()
        .expect("inputs' level");
    eprintln!("baseline: {rms:.2} σ {v}, {under:.2} under the inputs' noise: {summary}");
    assert!(rms <= 1.1, "{rms:.2} σ");
    assert!(under <= 0.8, "{under:.2} under the inputs' noise");
    if v != "good" {
        assert!(
            summary.contains("--noisy-inputs") && !summary.contains("cooling air"),
            "{summary}"
        );
    }

    let healthy = diagnose(
        &INDEP2,
        &unit,
        &INDEP2.data("baseline_noisy.csv"),
        &["--noisy-inputs"],
    );
    let g = &healthy["groups"][0];
    eprintln!(
        "healthy baseline: {} {} ± {}",
        g["fit_quality"]["verdict"], g["health"], g["sigma"]
    );
    assert_eq!(g["fit_quality"]["verdict"], "good");
    for n in HEALTH_NAMES {
        let v = g["health"][n].as_f64().expect("estimate");
        let sigma = g["sigma"][n].as_f64().expect("σ");
        // The gas generator's within 0.3 points (measured 0.18); the others, which these
        // signals do not separate, within their stated σ (D_GP −0.50 ± 1.97).
        let most = if ["D_GC", "D_EC", "D_GT"].contains(&n) {
            0.3
        } else {
            sigma
        };
        assert!(v.abs() <= most, "healthy baseline {n} {v:.3} ± {sigma:.2}");
    }

    let read = read_grid(&INDEP2, &unit, &["--noisy-inputs"]);
    read.assert_floors(&[(0.75, 0.88), (0.65, 0.9), (0.65, 0.92), (1.1, 0.8)]);
    assert!(read.worst_z <= 2.5, "worst |error|/σ {:.2}", read.worst_z);
    assert!(read.separable_miss <= 0.5, "{:.2}", read.separable_miss);
    assert!(read.good >= 14, "{} of 20 fits good", read.good);
}

/// The leave-one-load-out floors on the second simulator's unit, judged against its
/// own values ([`left_out_loads`]). Measured 2026-12-07 (`cargo test --release --test
/// integration foreign_simulator::indep2::left_out_loads_of_the_second -- --nocapture`, 8 s): the
/// default (grown) shape 0.205 % mean, 0.761 % worst (P2 at 59 % load); `--adapt-strategy
/// continuation`, not run here, 0.336 / 1.188 % (power at 75 %).
#[test]
fn left_out_loads_of_the_second_simulators_unit() {
    use gtwatch::calibrate::adapt::AdaptStrategy;
    left_out_loads(&INDEP2, &[(AdaptStrategy::Grown, 0.3, 1.0)]);
}

/// The second simulator's start-ups (`indep2/dyn.py`: the same engine in time, from standstill
/// through purge, light-off, idle, the PT's break-away and synchronisation to load, with its
/// own starter, fuel control, inertias and thermocouple lags) replayed as a user replays a
/// historian export: five days, each a start and, on four of them, a normal shutdown
/// (`indep2/startups/operations_log.csv`; truth in `operations_truth.csv`). The engine file
/// is the one the baseline's calibration writes from md22's, whose sequence speeds (purge
/// 2 300, idle 6 600 rpm) are not the unit's (2 230, 6 496) and whose dynamics are md22's:
/// what a user has before knowing better.
///
/// Measured 2026-12-07 (`cargo test --release --test integration
/// foreign_simulator::indep2::start_ups_of -- --nocapture`, 7 s): every start completed with every
/// phase (before the detector took a held speed as purge and idle, every one was an operator
/// stop in crank); each diagnosed by Method B, `suspect` (md22's dynamics), healthy starts at
/// D_GC −0.47 and −1.00; compressor fouling read as the change from the healthy start on a
/// like load: +1.49 / +0.84 for 1.5 / 0.75 and +2.88 / +1.68 for 3.0 / 1.5; HP-turbine erosion
/// D_GT −0.83 for −1.0.
#[test]
fn start_ups_of_the_second_simulators_unit_replay_detect_and_diagnose() {
    let dir = tempfile::tempdir().expect("tempdir");
    let unit = dir.path().join("unit.toml");
    calibrate(&INDEP2, &INDEP2.user(), &unit);
    let cfg_path = indep2_replay_config(dir.path(), &unit, 2);
    let log = INDEP2.data("startups/operations_log.csv");
    let b = replayed_start_ups(
        &cfg_path,
        &log,
        5,
        &[
            "crank",
            "purge",
            "light_off",
            "acceleration",
            "idle",
            "synchronisation",
            "loading",
            "steady",
        ],
    );
    let d = |seg: i64, p: &str| b[&seg][p].as_f64().expect("estimate");
    // Starts 1 and 2 are healthy (base load, 70 %); 3 and 4 fouled on like loads; 5 eroded at
    // 70 % (operations_truth.csv).
    let changes = [
        ("D_GC", d(3, "D_GC") - d(1, "D_GC"), 1.5),
        ("D_EC", d(3, "D_EC") - d(1, "D_EC"), 0.75),
        ("D_GC", d(4, "D_GC") - d(2, "D_GC"), 3.0),
        ("D_EC", d(4, "D_EC") - d(2, "D_EC"), 1.5),
        ("D_GT", d(5, "D_GT") - d(2, "D_GT"), -1.0),
    ];
    for (p, read, truth) in changes {
        eprintln!("{p}: read {read:+.2} for {truth:+.2}");
        assert!(
            (read - truth).abs() <= 0.4,
            "{p}: {read:+.2} for {truth:+.2}"
        );
    }
    for seg in [1, 2] {
        assert!(
            d(seg, "D_GC").abs() <= 1.5,
            "healthy start {seg}: D_GC {}",
            d(seg, "D_GC")
        );
    }
    // The same log handed to `diagnose --input` without a database: the detector runs over
    // the file in memory, finds the same five start-ups, and the third (`--start 3`) is fitted
    // to the same health as the stored one (the worker's settings: seed 1, 400 model runs).
    let direct = diagnose_start(&unit, &log, 3);
    let found = direct["startup"]["found"].as_array().expect("found");
    assert_eq!(found.len(), 5, "{:#}", direct["startup"]);
    assert!(found.iter().all(|f| f["outcome"] == "completed"));
    assert_eq!(found[2]["start_utc"], "2025-10-08T08:00:10Z");
    for p in ["D_GC", "D_EC", "D_GT", "D_ET", "D_GP", "D_EP"] {
        let h = direct["methods"]["transient"]["health"][p]
            .as_f64()
            .expect("estimate");
        assert!(
            (h - d(3, p)).abs() <= 0.02,
            "{p}: {h:+.3} from the file, {:+.3} stored",
            d(3, p)
        );
    }
}

/// The user's configuration for replaying the second simulator's logs (its columns and US
/// units mapped, time column `timestamp`) into `dir/u.db` with engine file `unit` and
/// `threads` for the diagnosis, written as `dir/gtwatch.toml`; the shipped file otherwise.
pub(crate) fn indep2_replay_config(dir: &Path, unit: &Path, threads: usize) -> PathBuf {
    let columns = "T1_F = \"t1_k\"\nP1_PSIA = \"p1_kpa\"\nNGG_RPM = \"n1_rpm\"\n\
                   NPT_RPM = \"n2_rpm\"\nFUEL_LBH = \"fuel_kg_s\"\nCDP_PSIA = \"p2_kpa\"\n\
                   CDT_F = \"t2_k\"\nT48_F = \"t34_k\"\nEGT_F = \"t4_k\"\nMW = \"power_mw\"";
    let units = "t1_k = \"degF\"\np1_kpa = \"psia\"\nfuel_kg_s = \"lb/h\"\n\
                 p2_kpa = \"psia\"\nt2_k = \"degF\"\nt34_k = \"degF\"\nt4_k = \"degF\"";
    replay_config(dir, unit, "timestamp", columns, units, threads, &[])
}

/// The second simulator's operations log's first two start-ups (healthy), cut into
/// `dir/healthy.csv` as a user cuts a log (the rows before 2025-10-08).
pub(crate) fn indep2_healthy_starts(dir: &Path) -> PathBuf {
    let log = INDEP2.data("startups/operations_log.csv");
    let text = std::fs::read_to_string(&log).expect("log");
    let healthy: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(i, l)| *i == 0 || l.as_bytes() < b"2025-10-08".as_slice())
        .map(|(_, l)| l)
        .collect();
    let healthy_csv = dir.join("healthy.csv");
    std::fs::write(&healthy_csv, healthy.join("\n")).expect("write");
    healthy_csv
}

/// [`calibrate_on`] the second simulator's user file, its noisy baseline and its log's healthy
/// start-ups (`--startup`, [`indep2_healthy_starts`] in `dir`), with `extra`, into `out`.
pub(crate) fn calibrate_on_indep2(dir: &Path, extra: &[&str], out: &Path) -> Value {
    let healthy = indep2_healthy_starts(dir);
    let mut args = vec!["--startup", healthy.to_str().expect("utf-8")];
    args.extend_from_slice(extra);
    calibrate_on(
        &INDEP2,
        &INDEP2.user(),
        &INDEP2.data("baseline_noisy.csv"),
        &args,
        out,
    )
}

/// `gtwatch diagnose` (Method B, the worker's settings: seed 1, 400 model runs) of start-up
/// `start` of the second simulator's log `log` (no phase column: the detector finds it).
fn diagnose_start(engine: &Path, log: &Path, start: usize) -> Value {
    let (map, units, start) = (INDEP2.map(), INDEP2.units(), start.to_string());
    gtwatch_json(&[
        "diagnose",
        "--engine",
        engine.to_str().expect("utf-8"),
        "--input",
        log.to_str().expect("utf-8"),
        "--map",
        &map,
        "--units",
        &units,
        "--method",
        "transient",
        "--start",
        &start,
        "--max-runs",
        "400",
        "--threads",
        "2",
    ])
}

/// The second simulator's unit's dynamics fitted to its own healthy start-ups. The md22 file
/// carries md22's thermocouple lags (T2 3.0, T34 2.5, T4 3.0 s) and inertias; the unit's rakes
/// lag 2 / 4 / 5 s (`indep2/dynamics.txt`). `calibrate --dynamics` on the log's first two
/// (healthy) start-ups fits them with the health held at zero; judged on the three later
/// start-ups it never saw (fouled twice, HPT eroded: `operations_truth.csv`), the compressor
/// and HPT reads come nearer the truth than with the file's dynamics, from the same steady
/// calibration.
#[test]
fn dynamics_of_the_second_simulators_unit_from_its_healthy_start_ups() {
    let dir = tempfile::tempdir().expect("tempdir");
    let log = INDEP2.data("startups/operations_log.csv");
    let healthy_csv = indep2_healthy_starts(dir.path());
    let h = healthy_csv.to_str().expect("utf-8");
    let baseline = INDEP2.data("baseline_noisy.csv");
    let (plain, dynamic) = (dir.path().join("plain.toml"), dir.path().join("dyn.toml"));
    calibrate_on(
        &INDEP2,
        &INDEP2.user(),
        &baseline,
        &["--startup", h],
        &plain,
    );
    let fit = calibrate_on(
        &INDEP2,
        &INDEP2.user(),
        &baseline,
        &["--startup", h, "--dynamics"],
        &dynamic,
    );
    let values = fit["dynamics"]["values"].as_array().expect("values");
    let value = |key: &str| {
        values
            .iter()
            .find(|v| v["key"] == key)
            .unwrap_or_else(|| panic!("{key} in {values:#?}"))
    };
    let t34 = value("sensors.t34.tau_s");
    assert!(
        t34["written"] == true && t34["value"].as_f64().expect("lag") > 3.5,
        "the T48 rake's lag (4 s) found: {t34:#}"
    );
    // Not informed by a generator whose PT is held by the grid: not written.
    assert_eq!(value("dynamics.pt_inertia_kg_m2")["written"], false);
    let written = std::fs::read_to_string(&dynamic).expect("file");
    assert!(written.contains("dynamics fitted to 2 healthy start-up(s)"));
    // Each healthy start-up's compressor and HPT read with the fitted values.
    for s in fit["dynamics"]["startups"].as_array().expect("startups") {
        let h = &s["after"]["health"];
        for i in [0, 2] {
            let v = h[i].as_f64().expect("health");
            assert!(v.abs() <= 0.4, "{}: {v:+.2}", s["source"]);
        }
    }
    // The later start-ups, with either file: (D_GC, D_EC, D_GT) against the truth.
    let truth = [
        (3, [1.5, 0.75, 0.0]),
        (4, [3.0, 1.5, 0.0]),
        (5, [0.0, 0.0, -1.0]),
    ];
    // And the parameters the run to load and the steady end read apart (`phase_split`).
    let differ = std::cell::RefCell::new(Vec::new());
    let errors = |engine: &Path| -> Vec<f64> {
        truth
            .iter()
            .flat_map(|(start, t)| {
                let d = diagnose_start(engine, &log, *start);
                let h = &d["methods"]["transient"]["health"];
                let split = &d["methods"]["transient"]["phase_split"];
                differ.borrow_mut().push(
                    split["differ"]
                        .as_array()
                        .unwrap_or_else(|| panic!("a phase split: {split:#}"))
                        .iter()
                        .map(|x| x["param"].as_str().expect("param").to_string())
                        .collect::<Vec<_>>(),
                );
                ["D_GC", "D_EC", "D_GT"]
                    .iter()
                    .zip(t)
                    .map(|(p, t)| (h[p].as_f64().expect("estimate") - t).abs())
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    let (before, after) = (errors(&plain), errors(&dynamic));
    // With the fitted dynamics too, the run to load reads the compressor apart from the steady
    // end (measured 0.6–1.5 points on indep2's start-ups; the twin's parts agree within 0.21): said, not hidden.
    let differ = differ.into_inner();
    eprintln!("read apart by the run to load and the steady end: {differ:?}");
    assert!(
        differ[3..]
            .iter()
            .filter(|d| d.iter().any(|p| p == "D_GC"))
            .count()
            >= 2,
        "{differ:?}"
    );
    let (sum_before, sum_after) = (before.iter().sum::<f64>(), after.iter().sum::<f64>());
    eprintln!("|error| D_GC, D_EC, D_GT of starts 3–5: file's dynamics {before:.2?} (sum {sum_before:.2}), fitted {after:.2?} (sum {sum_after:.2})");
    assert!(
        sum_after <= 0.7 * sum_before,
        "{sum_after:.2} against {sum_before:.2}"
    );
    assert!(
        after[8] <= 0.3,
        "HPT erosion read within 0.3: {:.2}",
        after[8]
    );
}
/// The second simulator's unit (no P48 or P5) read again with a prior of 1 point on the health
/// (`--health-prior 1`, `diagnosis::prior`): the PT's two and the HP turbine's efficiency, which
/// the data alone read up to 2.7 points off along the combinations they barely determine, come
/// within a point, at a cost on the compressor's flow. Measured 2026-12-07: worst D_GC … D_EP
/// 0.50 / 0.65 / 0.38 / 0.94 / 2.74 / 2.11 → 0.77 / 0.54 / 0.48 / 0.56 / 1.09 / 0.82; ρ D_GP
/// 0.04 → 0.51, D_EP 0.68 → 0.80.
pub(super) fn prior_on_the_unit_without_turbine_pressures(unit: &Path, without: &GridRead) {
    let with = read_grid(&INDEP2, unit, &["--noisy-inputs", "--health-prior", "1"]);
    eprintln!(
        "indep2 with a prior of 1 point: worst {:.2?}, ρ {:.2?}",
        with.worst, with.rho
    );
    assert!(
        without.worst[4] > 2.0,
        "D_GP without {:.2}",
        without.worst[4]
    );
    for (p, most) in [(3, 0.65), (4, 1.25), (5, 1.0)] {
        assert!(
            with.worst[p] <= most && with.worst[p] < 0.6 * without.worst[p],
            "{}: {:.2} with the prior, {:.2} without",
            HEALTH_NAMES[p],
            with.worst[p],
            without.worst[p]
        );
    }
    assert!(
        with.rho[4] >= 0.4 && with.rho[5] >= 0.75,
        "ρ {:.2?}",
        with.rho
    );
    // What it costs: the compressor's flow, coupled to the PT's through the weak directions.
    assert!(with.worst[0] <= 0.85, "D_GC {:.2}", with.worst[0]);
    assert!(with.good >= 16, "{} of 20 fits good", with.good);
}
