//! Units of other simulators, end to end as a user runs gtwatch on them: every other foreign
//! unit of the tests is written by this project's own steady solver (another map family, load
//! or design, but gtwatch's thermodynamics, gas path and health scalers); these two are not.
//! The second (`tests/data/foreign/indep2/`, a generator set logged in °F, psia and lb/h) is
//! described at its tests below; the first follows.
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

use crate::ranking::{spearman, spearman_ceiling};
use gtwatch::health::HEALTH_NAMES;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// One simulator's unit as a user meets it: its files, the plant's tags as the user maps them
/// to gtwatch's signals, the plant's units, and the user's engine file.
struct Sim {
    /// Folder under `tests/data/foreign/`.
    dir: &'static str,
    map: &'static str,
    units: &'static str,
    /// The user's engine file, under `tests/data/foreign/`.
    user: &'static str,
}

/// The first independent simulator's unit (a 30 MW mechanical drive, °C and bar a).
const INDEP30: Sim = Sim {
    dir: "indep30",
    map: "t1_k=CIT_C,p1_kpa=CIP_BARA,p_amb_kpa=AMB_P_BARA,n1_rpm=NGG_RPM,n2_rpm=NPT_RPM,\
          fuel_kg_s=FUEL_KGH,p2_kpa=CDP_BARA,t2_k=CDT_C,p34_kpa=P34_BARA,t34_k=T34_C,\
          p4_kpa=EXP_BARA,t4_k=EGT_C,power_mw=PWR_MW",
    units: "t1_k=degC,p1_kpa=bar,p_amb_kpa=bar,fuel_kg_s=kg/h,p2_kpa=bar,t2_k=degC,\
            p34_kpa=bar,t34_k=degC,p4_kpa=bar,t4_k=degC",
    user: "indep30_user_md22.toml",
};

/// The second independent simulator's unit (a 13 MW generator set, °F, psia and lb/h, no
/// pressure measured between or after the turbines).
const INDEP2: Sim = Sim {
    dir: "indep2",
    map: "t1_k=T1_F,p1_kpa=P1_PSIA,p_amb_kpa=AMB_P_PSIA,n1_rpm=NGG_RPM,n2_rpm=NPT_RPM,\
          fuel_kg_s=FUEL_LBH,p2_kpa=CDP_PSIA,t2_k=CDT_F,t34_k=T48_F,t4_k=EGT_F,power_mw=MW",
    units: "t1_k=degF,p1_kpa=psia,p_amb_kpa=psia,fuel_kg_s=lb/h,p2_kpa=psia,t2_k=degF,\
            t34_k=degF,t4_k=degF",
    user: "indep2_user_md22.toml",
};

impl Sim {
    fn data(&self, file: &str) -> PathBuf {
        root().join("tests/data/foreign").join(self.dir).join(file)
    }
    fn user(&self) -> PathBuf {
        root().join("tests/data/foreign").join(self.user)
    }
    /// The tag map as one `--map` argument (the constants are wrapped for reading).
    fn map(&self) -> String {
        self.map.split_whitespace().collect()
    }
    fn units(&self) -> String {
        self.units.split_whitespace().collect()
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `gtwatch <args> --json`, parsed; panics with its stderr when it fails.
fn gtwatch_json(args: &[&str]) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(args)
        .arg("--json")
        .output()
        .expect("run gtwatch");
    assert!(
        out.status.success(),
        "gtwatch {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON document")
}

/// `gtwatch calibrate --adapt` of `engine` on `input` (the healthy baseline unless said), with
/// `extra` arguments, written to `out`: the calibration's JSON.
fn calibrate_on(sim: &Sim, engine: &Path, input: &Path, extra: &[&str], out: &Path) -> Value {
    let (map, units) = (sim.map(), sim.units());
    let mut args = vec![
        "calibrate",
        "--engine",
        engine.to_str().expect("utf-8"),
        "--input",
        input.to_str().expect("utf-8"),
        "--map",
        &map,
        "--units",
        &units,
        "--adapt",
        "--threads",
        "2",
        "--out",
        out.to_str().expect("utf-8"),
    ];
    args.extend_from_slice(extra);
    gtwatch_json(&args)
}

/// [`calibrate_on`] the healthy baseline.
fn calibrate(sim: &Sim, engine: &Path, out: &Path) -> Value {
    calibrate_on(sim, engine, &sim.data("baseline_noisy.csv"), &[], out)
}

fn verdict(calibration: &Value) -> (String, f64) {
    let c = &calibration["calibration"];
    (
        c["baseline_fit"]["verdict"]
            .as_str()
            .expect("verdict")
            .to_string(),
        c["rms_after"].as_f64().expect("rms"),
    )
}

/// The true health of each group of the grid file (its `true_D_*` columns).
fn truth(sim: &Sim) -> BTreeMap<String, [f64; 6]> {
    let text = std::fs::read_to_string(sim.data("grid_noisy.csv")).expect("grid");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let group = col("group");
    let cols: Vec<usize> = HEALTH_NAMES
        .iter()
        .map(|n| col(&format!("true_{n}")))
        .collect();
    let mut out = BTreeMap::new();
    for line in lines {
        let cells: Vec<&str> = line.split(',').collect();
        let mut h = [0.0; 6];
        for (p, &c) in cols.iter().enumerate() {
            h[p] = cells[c].parse().expect("a number");
        }
        out.insert(cells[group].to_string(), h);
    }
    out
}

/// `gtwatch diagnose --method steady` of `input` (the plant's tags and units) on `unit`, by its
/// `group` column, as the user runs it, with `extra` arguments.
fn diagnose(sim: &Sim, unit: &Path, input: &Path, extra: &[&str]) -> Value {
    let (map, units) = (sim.map(), sim.units());
    let mut args = vec![
        "diagnose",
        "--method",
        "steady",
        "--engine",
        unit.to_str().expect("utf-8"),
        "--input",
        input.to_str().expect("utf-8"),
        "--map",
        &map,
        "--units",
        &units,
        "--group-by",
        "group",
        "--threads",
        "2",
    ];
    args.extend_from_slice(extra);
    gtwatch_json(&args)
}

/// How the grid was read on an engine file: per parameter the worst error (points) and
/// Spearman ρ against the truth, the worst error in units of the stated σ, and the worst miss
/// of a parameter the diagnosis called separable.
struct GridRead {
    worst: [f64; 6],
    rho: [f64; 6],
    worst_z: f64,
    separable_miss: f64,
    /// Levels whose fit is `good`.
    good: usize,
}

impl GridRead {
    /// Each parameter's worst error at most, and its ρ at least, the pair given in
    /// [`HEALTH_NAMES`]' order (the parameters after the last pair are not held).
    fn assert_floors(&self, floors: &[(f64, f64)]) {
        for (p, &(most, least)) in floors.iter().enumerate() {
            let name = HEALTH_NAMES[p];
            assert!(
                self.worst[p] <= most,
                "{name}: worst error {:.2}",
                self.worst[p]
            );
            assert!(self.rho[p] >= least, "{name}: ρ {:.3}", self.rho[p]);
        }
    }
}

/// `gtwatch diagnose --method steady` of the grid on `unit` (with `extra` arguments), as the
/// user runs it, scored against the grid's `true_D_*` columns (each level printed).
fn read_grid(sim: &Sim, unit: &Path, extra: &[&str]) -> GridRead {
    let diag = diagnose(sim, unit, &sim.data("grid_noisy.csv"), extra);
    let truth = truth(sim);
    let groups = diag["groups"].as_array().expect("groups");
    assert_eq!(groups.len(), truth.len());
    let mut est: Vec<[f64; 6]> = Vec::new();
    let mut tru: Vec<[f64; 6]> = Vec::new();
    let mut worst = [0.0f64; 6];
    let mut worst_z = 0.0f64;
    let mut separable_miss = 0.0f64;
    let mut good = 0;
    for g in groups {
        good += usize::from(g["fit_quality"]["verdict"] == "good");
        let name = g["group"].as_str().expect("group");
        let t = truth[name];
        let mut e = [0.0; 6];
        for (p, n) in HEALTH_NAMES.iter().enumerate() {
            e[p] = g["health"][*n].as_f64().expect("estimate");
            let sigma = g["sigma"][*n].as_f64().expect("σ");
            let err = (e[p] - t[p]).abs();
            worst[p] = worst[p].max(err);
            worst_z = worst_z.max(err / sigma);
        }
        for s in g["separability"]["separable"].as_array().expect("list") {
            let p = HEALTH_NAMES
                .iter()
                .position(|n| Some(*n) == s.as_str())
                .expect("a name");
            separable_miss = separable_miss.max((e[p] - t[p]).abs());
        }
        eprintln!(
            "{name} {:8} {}",
            g["fit_quality"]["verdict"].as_str().unwrap_or("?"),
            (0..6)
                .map(|p| format!("{:+.2} ({:+.2})", e[p], t[p]))
                .collect::<Vec<_>>()
                .join(" ")
        );
        est.push(e);
        tru.push(t);
    }
    let mut rho = [0.0; 6];
    let mut ceiling = [0.0; 6];
    for p in 0..6 {
        let a: Vec<f64> = est.iter().map(|e| e[p]).collect();
        let b: Vec<f64> = tru.iter().map(|t| t[p]).collect();
        rho[p] = spearman(&a, &b);
        ceiling[p] = spearman_ceiling(&b);
    }
    eprintln!(
        "worst error {worst:.2?}, ρ {rho:.3?} (ceilings {ceiling:.3?}: healthy levels tie), worst \
         |error|/σ {worst_z:.2}, worst miss of a parameter called separable {separable_miss:.2}, \
         {good} of {} fits good",
        groups.len()
    );
    GridRead {
        worst,
        rho,
        worst_z,
        separable_miss,
        good,
    }
}

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
/// Measured 2026-12-07 (`cargo test --release --test integration foreign_simulator::left_out
/// -- --nocapture`; the same as `calibrate --validate` on a file whose left-out row is the
/// exact one): the continuation shape 0.205 % mean, 0.818 % worst (power at 38.75 %): the
/// issue's 0.3 / 1 % met on this unit; the grown shape (the default, which reads degradation
/// with less cross-talk) 0.231 % mean, but power at 38.75 % load, where the vanes move and the
/// loads are sparsest, 1.60 % off: the 1 % not met there. Judged against the noisy
/// readings instead, the same folds read 0.31 / 1.57 % and 0.35 / 2.35 %.
#[test]
fn left_out_loads_predicted_against_the_simulators_own_values() {
    use gtwatch::calibrate::adapt::AdaptStrategy;
    left_out_loads(
        &INDEP30,
        &[
            (AdaptStrategy::Continuation, 0.3, 1.0),
            (AdaptStrategy::Grown, 0.3, 1.8),
        ],
    );
}

/// Each interior load of `sim`'s baseline left out of the noisy baseline's calibration in turn
/// and predicted against the simulator's own values (`baseline_exact.csv`), per strategy, its
/// mean and worst |error| (%) over the loads held to the floors given with it.
fn left_out_loads(sim: &Sim, floors: &[(gtwatch::calibrate::adapt::AdaptStrategy, f64, f64)]) {
    use gtwatch::calibrate::adapt::AdaptSettings;
    use gtwatch::calibrate::candidates::default_candidates;
    use gtwatch::calibrate::validate::left_out;
    use gtwatch::calibrate::{calibrate, CalibrationSettings};
    use gtwatch::diagnosis::csv_input::parse_mapping;
    use gtwatch::diagnosis::snapshot::read_snapshots_in;
    use gtwatch::engine::{Engine, EngineConfig};
    use gtwatch::units::ColumnUnits;

    let engine = Engine::new(EngineConfig::load(&sim.user()).expect("user file")).expect("engine");
    let mapping = parse_mapping(&sim.map()).expect("the --map text");
    let units = ColumnUnits::parse(&sim.units()).expect("units");
    let read = |file: &str| {
        let f = std::fs::File::open(sim.data(file)).expect(file);
        read_snapshots_in(f, &mapping, &units, None).expect(file)
    };
    let (noisy, exact) = (read("baseline_noisy.csv"), read("baseline_exact.csv"));
    assert_eq!((noisy.len(), exact.len()), (9, 9));
    let cands = default_candidates(&engine).expect("candidates");
    // The interior loads: all but the lowest and highest corrected GG speed (the ends are
    // extrapolations).
    let corrected = |r: &gtwatch::diagnosis::snapshot::Snapshot| {
        let n1 = r
            .values
            .iter()
            .find(|(s, _)| *s == gtwatch::signals::Signal::N1)
            .expect("GG speed")
            .1;
        n1 / (r.t_amb_k / 288.15).sqrt()
    };
    let mut order: Vec<usize> = (0..noisy.len()).collect();
    order.sort_by(|&a, &b| corrected(&noisy[a]).total_cmp(&corrected(&noisy[b])));
    let interior = &order[1..order.len() - 1];
    for &(strategy, mean_floor, worst_floor) in floors {
        // As `calibrate --validate` does: the turbines' efficiency shape chosen once, on every
        // row, and each fold fitted with it.
        let whole = CalibrationSettings {
            threads: Some(2),
            adapt: Some(AdaptSettings {
                health_error: false,
                ..AdaptSettings::of(strategy)
            }),
            ..CalibrationSettings::default()
        };
        let (report, _) =
            calibrate(&engine, &noisy, &[], cands.clone(), &whole).expect("calibration");
        let chosen = report.adaptation.expect("adapted");
        eprintln!(
            "{strategy:?}: efficiency shape {}",
            chosen.turbine_efficiency.name()
        );
        let settings = CalibrationSettings {
            threads: Some(2),
            adapt: Some(AdaptSettings::of(strategy).with_efficiency_shape_of(&chosen)),
            ..CalibrationSettings::default()
        };
        let (mut means, mut worst) = (Vec::new(), 0.0f64);
        for k in interior.iter().copied() {
            let mut rows = noisy.clone();
            rows[k] = exact[k].clone();
            let (p, _) = left_out(&engine, &rows, k, &[], &cands, &settings).expect("row k");
            assert!(
                p.failed.is_none(),
                "{strategy:?}, line {}: {:?}",
                p.line,
                p.failed
            );
            assert_eq!(p.position.as_str(), "interior", "line {}", p.line);
            eprintln!(
                "{strategy:?}: line {} (relative GG speed {:.3?}) mean {:.3} %, worst {:.3} % \
                 ({})",
                p.line, p.gg_speed, p.mean_abs_pct, p.worst_abs_pct, p.worst_signal
            );
            means.push(p.mean_abs_pct);
            worst = worst.max(p.worst_abs_pct);
        }
        let mean = means.iter().sum::<f64>() / means.len() as f64;
        eprintln!("{strategy:?}: interior loads mean {mean:.3} %, worst {worst:.3} %");
        assert!(mean <= mean_floor, "{strategy:?}: mean {mean:.3} %");
        assert!(worst <= worst_floor, "{strategy:?}: worst {worst:.3} %");
    }
}

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
/// Measured 2026-12-07 (`cargo test --release --test integration foreign_simulator::a_generator
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
/// integration foreign_simulator::left_out_loads_of_the_second -- --nocapture`, 8 s): the
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
/// foreign_simulator::start_ups_of -- --nocapture`, 7 s): every start completed with every
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
    crate::common::gtwatch_ok(&["replay", log.to_str().expect("utf-8")], &cfg_path);
    let segs: Value = serde_json::from_slice(&crate::common::gtwatch_ok(
        &["segments", "--json"],
        &cfg_path,
    ))
    .expect("json");
    let segs = segs.as_array().expect("segments");
    assert_eq!(segs.len(), 5, "{segs:#?}");
    for s in segs {
        assert_eq!(s["outcome"], "completed", "{s:#}");
        let phases: Vec<&str> = s["phases"]
            .as_array()
            .expect("phases")
            .iter()
            .map(|p| p["phase"].as_str().expect("name"))
            .collect();
        assert_eq!(
            phases,
            [
                "crank",
                "purge",
                "light_off",
                "acceleration",
                "idle",
                "synchronisation",
                "loading",
                "steady"
            ],
            "{s:#}"
        );
    }
    let history: Value = serde_json::from_slice(&crate::common::gtwatch_ok(
        &["history", "--method", "B", "--json"],
        &cfg_path,
    ))
    .expect("json");
    let b: BTreeMap<i64, &Value> = history
        .as_array()
        .expect("rows")
        .iter()
        .map(|r| (r["segment_id"].as_i64().expect("id"), &r["health"]))
        .collect();
    assert_eq!(b.len(), 5, "one Method B result per start: {history:#}");
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
    let columns = "[replay.columns]\nT1_F = \"t1_k\"\nP1_PSIA = \"p1_kpa\"\nNGG_RPM = \"n1_rpm\"\n\
                   NPT_RPM = \"n2_rpm\"\nFUEL_LBH = \"fuel_kg_s\"\nCDP_PSIA = \"p2_kpa\"\n\
                   CDT_F = \"t2_k\"\nT48_F = \"t34_k\"\nEGT_F = \"t4_k\"\nMW = \"power_mw\"";
    let units = "[replay.units]\nt1_k = \"degF\"\np1_kpa = \"psia\"\nfuel_kg_s = \"lb/h\"\n\
                 p2_kpa = \"psia\"\nt2_k = \"degF\"\nt34_k = \"degF\"\nt4_k = \"degF\"";
    let cfg = include_str!("../config/gtwatch.toml")
        .replace(
            "path = \"/var/lib/gtwatch/gtwatch.db\"",
            &format!("path = {:?}", dir.join("u.db").display().to_string()),
        )
        .replace(
            "# engine_model = \"engine.toml\"",
            &format!("engine_model = {:?}", unit.display().to_string()),
        )
        .replace("time_column = \"time\"", "time_column = \"timestamp\"")
        .replace("[replay.columns]\n# \"GG_SPEED\" = \"n1\"", columns)
        .replace("[replay.units]\n# t2_k = \"degC\"", units)
        .replace("threads = 1", &format!("threads = {threads}"));
    assert!(cfg.contains("NGG_RPM = ") && cfg.contains("t4_k = \"degF\""));
    let cfg_path = dir.join("gtwatch.toml");
    std::fs::write(&cfg_path, cfg).expect("config");
    cfg_path
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

/// Both blind simulators' baselines are spot readings (one noisy reading per load, fuel flow
/// and T1 included). Calibrated with `--noisy-inputs`, each point is fitted under the noise of
/// its inputs (`rᵀ (I + C Cᵀ)⁻¹ r`) and judged so: both baselines `good` (0.98 and 0.93 σ
/// RMS, `suspect` and `good`, taken as exact), and the grids read by the gas generator's
/// parameters no worse than the exact-input calibration's floors (measured, release:
/// indep2 D_GC/D_EC/D_GT 0.50 / 0.65 / 0.38 against 0.62 / 0.53 / 0.52; indep30 1.06 / 0.48 /
/// 0.64 / D_ET 0.29 against 1.09 / 0.64 / 0.90 / 0.39).
#[test]
fn spot_readings_calibrated_under_their_inputs_noise() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (sim, floors) in [
        (&INDEP2, vec![(0.55, 0.9), (0.7, 0.9), (0.45, 0.9)]),
        (
            &INDEP30,
            vec![(1.15, 0.9), (0.55, 0.75), (0.7, 0.8), (0.35, 0.85)],
        ),
    ] {
        let unit = dir.path().join(format!("{}.toml", sim.dir));
        let c = calibrate_on(
            sim,
            &sim.user(),
            &sim.data("baseline_noisy.csv"),
            &["--noisy-inputs"],
            &unit,
        );
        let (v, rms) = verdict(&c);
        eprintln!("{}: {rms:.2} σ RMS, {v} under the inputs' noise", sim.dir);
        assert_eq!(v, "good", "{}", c["calibration"]["baseline_fit"]);
        let read = read_grid(sim, &unit, &["--noisy-inputs"]);
        eprintln!("{}: worst {:.2?}, ρ {:.2?}", sim.dir, read.worst, read.rho);
        read.assert_floors(&floors);
        if sim.dir == INDEP2.dir {
            prior_on_the_unit_without_turbine_pressures(&unit, &read);
        }
    }
}

/// The second simulator's unit (no P48 or P5) read again with a prior of 1 point on the health
/// (`--health-prior 1`, `diagnosis::prior`): the PT's two and the HP turbine's efficiency, which
/// the data alone read up to 2.7 points off along the combinations they barely determine, come
/// within a point, at a cost on the compressor's flow. Measured 2026-12-07: worst D_GC … D_EP
/// 0.50 / 0.65 / 0.38 / 0.94 / 2.74 / 2.11 → 0.77 / 0.54 / 0.48 / 0.56 / 1.09 / 0.82; ρ D_GP
/// 0.04 → 0.51, D_EP 0.68 → 0.80.
fn prior_on_the_unit_without_turbine_pressures(unit: &Path, without: &GridRead) {
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
