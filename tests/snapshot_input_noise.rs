//! Snapshots whose *inputs* are noisy (issue 22 item 3; the guide's "every signal can be wrong,
//! including those that drive the model"): one reading per row of a fouled unit, every column
//! with its instrument's configured noise — the fuel flow, T1 and n2 that the steady solve is
//! given as well as the compared values. The fuel meter's 0.5 % moves the model's GG speed by
//! about the tachometer's σ and every other value with it, all of one row's values in one
//! direction. Taken as exact (the default's fit and verdict, right for averaged rows), the
//! model's own twin is fitted `poor` on such rows. With `--noisy-inputs` (`snapshot_input_noise`)
//! the fit runs under the covariance that noise gives each row: never `poor`, and the σ covers
//! the error. By default that noise is still in the read's σ (the fit taking the inputs as
//! given): it covers the error too.
//!
//! Truth: the reference engine at D_GC 2, D_EC 1, nine loads from 6 to 14 MW at nine
//! ambient temperatures, noise drawn per seed; the diagnosis is told nothing of the truth.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::diagnosis::fit_quality::Verdict;
use gtwatch::diagnosis::snapshot::{diagnose_snapshots, read_snapshots, SnapshotReport};
use gtwatch::diagnosis::steady::steady_reading;
use gtwatch::diagnosis::DiagnosisConfig;
use gtwatch::engine::sensors::noise_sigma;
use gtwatch::engine::steady::{solve, Demand, SteadyInputs};
use gtwatch::engine::Engine;
use gtwatch::health::HealthParams;
use gtwatch::signals::Signal;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::collections::HashMap;

const COMPARED: [Signal; 7] = [
    Signal::N1,
    Signal::P1,
    Signal::T2,
    Signal::P2,
    Signal::T34,
    Signal::P34,
    Signal::Power,
];

fn truth() -> HealthParams {
    HealthParams {
        D_GC: 2.0,
        D_EC: 1.0,
        ..HealthParams::HEALTHY
    }
}

/// Nine single-reading snapshots of the fouled unit, every value (inputs included) with one
/// draw of its instrument's noise.
fn csv(engine: &Engine, seed: u64) -> String {
    let sensors = &engine.cfg().sensors;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut noisy = |s: Signal, v: f64| {
        let e: f64 = StandardNormal.sample(&mut rng);
        v + noise_sigma(sensors, s, v) * e
    };
    let mut text = String::from("test,p_amb_kpa,t1_k,n2_rpm,fuel_kg_s");
    for s in COMPARED {
        text.push(',');
        text.push_str(s.column());
    }
    text.push('\n');
    for k in 0..9 {
        let t = 283.0 + k as f64;
        let p_amb = 101.325;
        let m = engine.model_at(&truth(), t, p_amb);
        let inputs = SteadyInputs {
            t_amb_k: t,
            p_amb_kpa: p_amb,
            n2_rpm: 3600.0,
            demand: Demand::PowerMw(6.0 + k as f64),
        };
        let sp = solve(&m, &inputs, None).expect("truth solves");
        text.push_str(&format!(
            "a,{p_amb},{},{},{}",
            noisy(Signal::T1, t),
            noisy(Signal::N2, 3600.0),
            noisy(Signal::FuelFlow, sp.fuel_kg_s)
        ));
        for s in COMPARED {
            let v = noisy(s, steady_reading(&m, &sp, s));
            text.push_str(&format!(",{v}"));
        }
        text.push('\n');
    }
    text
}

/// The diagnosis settings of these tests: rows fitted as spot readings (`--noisy-inputs`).
fn spot_readings() -> DiagnosisConfig {
    DiagnosisConfig {
        max_model_runs: 1500,
        threads: Some(2),
        snapshot_input_noise: true,
        ..DiagnosisConfig::default()
    }
}

#[test]
fn noisy_inputs_are_carried_into_the_fit_and_its_sigma() {
    let engine = Engine::reference().expect("engine");
    let cfg = spot_readings();
    let exact = DiagnosisConfig {
        snapshot_input_noise: false,
        ..cfg.clone()
    };
    let truth = truth().to_array();
    let mut poor_when_exact = 0;
    let mut good = 0;
    let mut z2 = [0.0f64; 2];
    let mut z2_given = [0.0f64; 2];
    let seeds = 1..=6u64;
    let n = seeds.clone().count() as f64;
    for seed in seeds {
        let rows = read_snapshots(csv(&engine, seed).as_bytes(), &HashMap::new(), Some("test"))
            .expect("rows");
        let plain = diagnose_snapshots(&engine, &rows, &exact).expect("diagnosis");
        let q = scored(&plain, seed, "inputs as given", "taken as given in the fit");
        poor_when_exact += usize::from(q.verdict == Verdict::Poor);
        accumulate(&q, &truth, n, &mut z2_given);
        let report = diagnose_snapshots(&engine, &rows, &cfg).expect("diagnosis");
        let q = scored(
            &report,
            seed,
            "inputs' noise fitted",
            "noise of the measured inputs",
        );
        // The model is the truth's: its noisy snapshots are never said not to fit.
        assert_ne!(q.verdict, Verdict::Poor, "seed {seed}: {q:?}");
        if q.verdict == Verdict::Good {
            good += 1;
        }
        accumulate(&q, &truth, n, &mut z2);
    }
    // The σ covers the error (its RMS in σ units near 1, not 2 or 3), in both modes; and not
    // by far more than the error (a σ that covered it tenfold would say nothing).
    for (j, name) in ["D_GC", "D_EC"].iter().enumerate() {
        println!(
            "{name}: RMS error {:.2} σ fitted under the inputs' noise, {:.2} σ inputs as given",
            z2[j].sqrt(),
            z2_given[j].sqrt()
        );
        assert!(
            z2[j].sqrt() < 1.6,
            "{name}: RMS error {:.2} σ",
            z2[j].sqrt()
        );
        assert!(
            (0.3..1.6).contains(&z2_given[j].sqrt()),
            "{name}, inputs as given: RMS error {:.2} σ",
            z2_given[j].sqrt()
        );
    }
    // Judged against what spot readings' own noise leaves the exact model (χ², the 99 %
    // level: `fit_quality::spot_reading_good_level`); against `good` up to 0.9, set for
    // start-ups and averaged rows, 3 of these 6 were `suspect` (1.17, 1.04, 0.99).
    assert_eq!(good, 6, "{good} of 6 fits good");
    assert!(
        poor_when_exact >= 1,
        "the defect this guards against shows without the option"
    );
}

/// What the spot readings' tolerance must still see: the same rows with the compressor
/// discharge pressure scattered by three of its σ more than its stated noise (0.75 % high and
/// low on alternate rows) are not `good` under `--noisy-inputs`, on any of the draws. (The
/// same reading 1 % high on every row is not seen in the residual at all, whatever the level:
/// the health absorbs it, 1.17 as without it on the first draw; `gtwatch gap`'s alias check
/// is what names such a bias.)
#[test]
fn a_transmitter_noisier_than_stated_is_not_good_under_the_inputs_noise() {
    let engine = Engine::reference().expect("engine");
    let cfg = spot_readings();
    for seed in 1..=3u64 {
        let text = csv(&engine, seed);
        let mut lines = text.lines();
        let header = lines.next().expect("header");
        let col = header
            .split(',')
            .position(|c| c == Signal::P2.column())
            .expect("P2 column");
        let mut biased = format!("{header}\n");
        for (k, line) in lines.enumerate() {
            let factor = if k % 2 == 0 { 1.0075 } else { 0.9925 };
            let cells: Vec<String> = line
                .split(',')
                .enumerate()
                .map(|(i, c)| {
                    if i == col {
                        (c.parse::<f64>().expect("P2") * factor).to_string()
                    } else {
                        c.to_string()
                    }
                })
                .collect();
            biased.push_str(&cells.join(","));
            biased.push('\n');
        }
        let rows = read_snapshots(biased.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
        let report = diagnose_snapshots(&engine, &rows, &cfg).expect("diagnosis");
        let q = &report.groups[0].result.fit_quality;
        eprintln!(
            "seed {seed}, P2 ±0.75 %: {:?} {:.2} (good up to {:.2})",
            q.verdict, q.normalised_residual, q.thresholds.good_level
        );
        assert_ne!(q.verdict, Verdict::Good, "seed {seed}: {q:?}");
    }
}

/// One diagnosis of the seed's rows: its read, σ and verdict, after checking it was made in
/// `mode` (its assumptions say `says`) and printing it.
#[derive(Debug)]
struct Scored {
    verdict: Verdict,
    normalised_residual: f64,
    health: [f64; 6],
    sigma: [f64; 2],
    label: String,
}

fn scored(report: &SnapshotReport, seed: u64, mode: &str, says: &str) -> Scored {
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    let g = &report.groups[0];
    assert!(
        g.assumptions.iter().any(|a| a.contains(says)),
        "{:?}",
        g.assumptions
    );
    let r = &g.result;
    let q = Scored {
        verdict: r.fit_quality.verdict,
        normalised_residual: r.fit_quality.normalised_residual,
        health: r.health.to_array(),
        sigma: [r.sigma["D_GC"], r.sigma["D_EC"]],
        label: format!("seed {seed}, {mode}"),
    };
    println!(
        "{}: {:?} {:.2}, D_GC {:.3} ± {:.3}, D_EC {:.3} ± {:.3}",
        q.label, q.verdict, q.normalised_residual, q.health[0], q.sigma[0], q.health[1], q.sigma[1]
    );
    q
}

/// Adds the squared errors of D_GC and D_EC in units of their σ (over `n` seeds) to `z2`; each
/// within 3 σ.
fn accumulate(q: &Scored, truth: &[f64; 6], n: f64, z2: &mut [f64; 2]) {
    for (j, name) in ["D_GC", "D_EC"].iter().enumerate() {
        let z = (q.health[j] - truth[j]) / q.sigma[j];
        assert!(z.abs() < 3.0, "{}: {name} off by {z:.2} σ", q.label);
        z2[j] += z * z / n;
    }
}

/// The CLI's `--noisy-inputs` turns it on and says so among the assumptions.
#[test]
fn cli_noisy_inputs_flag_is_honoured() {
    let engine = Engine::reference().expect("engine");
    let dir = std::env::temp_dir().join(format!("gtwatch-noisy-inputs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let input = dir.join("spot.csv");
    std::fs::write(&input, csv(&engine, 1)).expect("write");
    let run = |flag: bool| -> serde_json::Value {
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_gtwatch"));
        cmd.args([
            "diagnose",
            "--method",
            "steady",
            "--group-by",
            "test",
            "--json",
        ])
        .arg("--input")
        .arg(&input);
        if flag {
            cmd.arg("--noisy-inputs");
        }
        let out = cmd.output().expect("runs");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).expect("one JSON document")
    };
    let says = |doc: &serde_json::Value| {
        doc["groups"][0]["assumptions"]
            .to_string()
            .contains("noise of the measured inputs")
    };
    let on = run(true);
    let off = run(false);
    assert!(says(&on), "{on}");
    assert!(!says(&off), "{off}");
    assert_ne!(
        on["groups"][0]["fit_quality"]["normalised_residual"],
        off["groups"][0]["fit_quality"]["normalised_residual"]
    );
    std::fs::remove_dir_all(&dir).ok();
}
