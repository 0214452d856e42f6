//! Another simulator's engine, calibrated as a user would: GSPy's published `turboshaft_2spool`
//! off-design points (`tests/data/reference/gspy_turboshaft_2spool/`, fuel 2.5 → 1.8 kg/s, the
//! PT held at 4 100 rpm like a generator's), turned into the snapshot CSV a plant would export,
//! and `config/engine_md22.toml` with its design point set from GSPy's design row, calibrated
//! with `--adapt` on them. Nothing here comes from gtwatch's own simulator: maps, gas model and
//! solver are GSPy's.
//!
//! The PT of such a unit runs *above* its design corrected speed at part load (speed held while
//! the PT inlet cools: 1.02–1.07 here), so the adaptation must put knots there: with knots
//! below the design speed only, the PT got no curve at all and the baseline fitted at 0.99 σ
//! RMS, `suspect` (2026-11-29); with them, 0.90 σ, `good`.
//!
//! The second test degrades such a unit: gtwatch's emulation of GSPy's engine
//! (`config/gspy_turboshaft_2spool.toml`, GSPy's maps and design) as the truth, a generator's
//! constant PT speed, 9 loads over a 20 K span of days, 20 levels of compressor, HP-turbine and
//! PT degradation diagnosed on md22 adapted to its healthy loads. Fouling and cold days take
//! the GG above the highest corrected speed the baseline reached; those snapshots are left out
//! with the reason (`[adaptation.calibrated]`), which took the worst level error from 1.7 to
//! 0.26 points (see the test).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::calibrate::adapt::{AdaptSettings, AdaptStrategy};
use gtwatch::calibrate::candidates::default_candidates;
use gtwatch::calibrate::synthetic::{snapshot_csv_at_speeds, OperatingPoint};
use gtwatch::calibrate::validate::{left_out, Position};
use gtwatch::calibrate::{calibrate, Calibration, CalibrationSettings};
use gtwatch::diagnosis::snapshot::{diagnose_snapshots, read_snapshots, Snapshot};
use gtwatch::engine::config::PressureLossLaw;
use gtwatch::engine::{Engine, EngineConfig};
use gtwatch::health::{HealthParams, HEALTH_NAMES};
use gtwatch::signals::Signal;
use std::collections::HashMap;
use std::path::PathBuf;

use crate::foreign_engine::diagnosis_cfg;
use crate::ranking::Rank;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// GSPy's rows, each column name → value, and whether it is the design row.
fn gspy_rows() -> Vec<(bool, HashMap<String, f64>)> {
    let path =
        root().join("tests/data/reference/gspy_turboshaft_2spool/turboshaft_2spool_output.csv");
    let mut rd = csv::Reader::from_path(&path).expect("GSPy reference");
    let header: Vec<String> = rd.headers().unwrap().iter().map(str::to_string).collect();
    rd.records()
        .map(|rec| {
            let rec = rec.unwrap();
            let m = header
                .iter()
                .zip(rec.iter())
                .filter_map(|(k, v)| v.trim().parse::<f64>().ok().map(|x| (k.clone(), x)))
                .collect();
            (rec.get(1) == Some("DP"), m)
        })
        .collect()
}

/// GSPy's off-design rows as a plant's snapshot CSV in gtwatch's column names (GSPy's stations
/// 2, 3, 45, 5 are gtwatch's 1, 2, 34, 4; pressures Pa → kPa, power W → MW).
fn snapshots() -> Vec<Snapshot> {
    read_snapshots(gspy_csv().as_bytes(), &HashMap::new(), Some("test")).expect("rows")
}

/// The CSV text of [`snapshots`].
fn gspy_csv() -> String {
    let mut csv = String::from(
        "test,t1_k,p_amb_kpa,p1_kpa,n2_rpm,fuel_kg_s,n1_rpm,t2_k,p2_kpa,t34_k,p34_kpa,t4_k,power_mw\n",
    );
    for (_, r) in gspy_rows().iter().filter(|(dp, _)| !dp) {
        csv.push_str(&format!(
            "gspy,{},{},{},{},{},{},{},{},{},{},{},{}\n",
            r["T2"],
            r["Pta"] / 1e3,
            r["P2"] / 1e3,
            r["N_pt"],
            r["WF"],
            r["N_gg"],
            r["T3"],
            r["P3"] / 1e3,
            r["T45"],
            r["P45"] / 1e3,
            r["T5"],
            r["PW_PT"] / 1e6,
        ));
    }
    csv
}

/// The user's md22 copy with GSPy's design row as its design point (pressure ratio, PT power,
/// both speeds, PT flow) and a generator load.
fn user_model() -> Engine {
    let (_, dp) = gspy_rows().into_iter().find(|(dp, _)| *dp).expect("DP row");
    let md22 = EngineConfig::load(&root().join("config/engine_md22.toml")).expect("md22");
    let mut cfg = md22;
    cfg.design.pressure_ratio = dp["P3"] / dp["P2"];
    cfg.design.power_mw = dp["PW_PT"] / 1e6;
    cfg.design.gg_speed_rpm = dp["N_gg"];
    cfg.design.pt_speed_rpm = dp["N_pt"];
    cfg.design.exhaust_flow_kg_s = dp["W45"];
    cfg.load = None;
    Engine::new(cfg).expect("user model")
}

fn calibrated(model: &Engine, rows: &[Snapshot]) -> (Calibration, Engine) {
    let settings = CalibrationSettings {
        threads: Some(2),
        adapt: Some(AdaptSettings::of(AdaptStrategy::Grown)),
        ..CalibrationSettings::default()
    };
    let cands = default_candidates(model).expect("candidates");
    let (report, adapted) = calibrate(model, rows, &[], cands, &settings).expect("calibrate");
    if let Some(sim) = report
        .adaptation
        .as_ref()
        .and_then(|a| a.similarity.as_ref())
    {
        eprintln!("  {}", sim.describe());
    }
    if let Some(line) = report
        .adaptation
        .as_ref()
        .and_then(|a| a.operating_line.as_ref())
    {
        eprintln!("  {}", line.describe());
    }
    (report, adapted)
}

#[test]
fn md22_adapted_to_gspys_turboshaft_fits_it_and_predicts_its_interior_points() {
    let rows = snapshots();
    assert_eq!(rows.len(), 8);
    let model = user_model();
    let (report, adapted) = calibrated(&model, &rows);
    let a = report.adaptation.as_ref().expect("adapted");
    eprintln!(
        "in health units: {:.3?} ({})",
        a.health_error.points, a.health_error.note
    );
    let pt = a
        .components
        .iter()
        .find(|c| c.component == "pt")
        .expect("pt");
    eprintln!(
        "PT speeds {:.3?}, knots {:.3?}, curves {:?} ({}); RMS {:.2} → {:.2} σ",
        pt.speed_range,
        pt.knots,
        pt.curves
            .iter()
            .map(|c| format!("{} {:+.4?}", c.curve, c.values))
            .collect::<Vec<_>>(),
        pt.knots_reason,
        a.rms_before,
        a.rms_after
    );
    // The PT runs above its design corrected speed at every part load: its curves live there.
    assert!(pt.speed_range[0] > 1.01, "{:?}", pt.speed_range);
    assert!(
        !pt.curves.is_empty() && pt.knots.iter().all(|k| *k > 1.0),
        "PT knots {:?}",
        pt.knots
    );
    // GSPy's inlet holds its pressure ratio. Its 8 points lie near full load, where the two
    // laws differ little: measured χ² 9.02 for md22's flow-squared law against 0.00 for a
    // constant loss, just past the 9 that changes the file's law (then 0.80 σ; 0.90 σ with
    // md22's law, 0.99 σ with no PT curve). So close to the line either law may be chosen;
    // the generator unit below, 40–100 % load, decides it by χ² 35.
    let law = report
        .inlet_loss_law
        .as_ref()
        .expect("P1 and ambient measured");
    eprintln!("{}", law.summary());
    assert_eq!(adapted.cfg().design.inlet_loss_law, law.chosen);
    assert!(a.rms_after <= 0.93, "adapted RMS {:.2} σ", a.rms_after);

    // The healthy baseline diagnoses good, every parameter near zero (measured within 0.15).
    let cfg = diagnosis_cfg();
    let diag = diagnose_snapshots(&adapted, &rows, &cfg).expect("diagnosis");
    let g = &diag.groups[0];
    let h = g.result.health.to_array();
    let q = format!("{:?}", g.result.fit_quality.verdict).to_lowercase();
    eprintln!("baseline {h:+.3?} {q}");
    assert_eq!(q, "good");
    for (p, v) in h.iter().enumerate() {
        assert!(v.abs() <= 0.3, "baseline {} = {v:.3}", HEALTH_NAMES[p]);
    }

    // Each interior point left out of the calibration, predicted by the others'.
    let mut means = Vec::new();
    let settings = CalibrationSettings {
        threads: Some(2),
        adapt: Some(AdaptSettings::of(AdaptStrategy::Grown)),
        ..CalibrationSettings::default()
    };
    let cands = default_candidates(&model).expect("candidates");
    for k in 1..rows.len() - 1 {
        // `calibrate --validate`'s fold: the calibration without row k, the row predicted.
        let (p, _) = left_out(&model, &rows, k, &[], &cands, &settings).expect("row k");
        assert!(p.failed.is_none(), "line {}: {:?}", p.line, p.failed);
        assert_eq!(p.position, Position::Interior, "line {}", p.line);
        let (mean, worst) = (p.mean_abs_pct, p.worst_abs_pct);
        eprintln!(
            "left out line {}: mean {mean:.3} %, worst {worst:.3} %",
            rows[k].line
        );
        assert!(
            mean <= 0.3 && worst <= 1.0,
            "line {}: mean {mean:.3} %, worst {worst:.3} %",
            rows[k].line
        );
        means.push(mean);
    }
    eprintln!(
        "interior points left out: mean {:.3} %",
        means.iter().sum::<f64>() / means.len() as f64
    );
}

/// What a generator unit measures besides the inputs (T1, ambient pressure, n2, fuel flow).
const INSTRUMENTS: [Signal; 8] = [
    Signal::N1,
    Signal::P1,
    Signal::T2,
    Signal::P2,
    Signal::T34,
    Signal::P34,
    Signal::T4,
    Signal::Power,
];

/// 9 loads from 40 % to 100 % of GSPy's design power, ambient 278–298 K and 99–102 kPa (in an
/// order shuffled by `level`), the PT held at GSPy's 4 100 rpm by the grid.
fn generator_loads(design_mw: f64, level: usize) -> Vec<OperatingPoint> {
    (0..9)
        .map(|k| {
            let j = (k + 4 * level) % 9;
            OperatingPoint {
                t_amb_k: 278.0 + 20.0 * j as f64 / 8.0,
                p_amb_kpa: 99.0 + 3.0 * ((j * 5) % 9) as f64 / 8.0,
                power_mw: design_mw * (0.4 + 0.6 * k as f64 / 8.0),
            }
        })
        .collect()
}

/// Levels of the generator grid.
const GRID_LEVELS: usize = 20;

/// Level `i` of [`GRID_LEVELS`]: 0–4 compressor fouling (D_GC to 4, D_EC 0.4·D_GC), 5–9
/// HP-turbine wear (D_GT to −2, D_ET to 3), 10–14 power-turbine erosion (D_GP to 2, D_EP to
/// 1.5), 15–19 all three at magnitudes between the single ones: each parameter degraded on 10
/// levels and healthy on the other 10.
fn generator_grid(i: usize) -> [f64; 6] {
    let path = i / 5;
    let j = ((i % 5) as f64 + if path == 3 { 0.5 } else { 1.0 }) / 5.0;
    let c = [4.0 * j, 1.6 * j];
    let t = [-2.0 * j, 3.0 * j];
    let p = [2.0 * j, 1.5 * j];
    match path {
        0 => [c[0], c[1], 0.0, 0.0, 0.0, 0.0],
        1 => [0.0, 0.0, t[0], t[1], 0.0, 0.0],
        2 => [0.0, 0.0, 0.0, 0.0, p[0], p[1]],
        _ => [c[0], c[1], t[0], t[1], p[0], p[1]],
    }
}

/// A generator unit made by gtwatch's emulation of GSPy's engine (`config/
/// gspy_turboshaft_2spool.toml`: GSPy's maps and design, the PT held at 4 100 rpm), 9 healthy
/// loads from 40 % to 100 % on days from 278 to 298 K, md22 adapted to them; then
/// [`GRID_LEVELS`] levels of compressor, HP-turbine and PT degradation at the same loads on
/// other days, diagnosed on it. At part load the PT always runs above its design corrected
/// speed (its curves live there), and fouled or on a cold day the GG runs above the speeds the
/// baseline covered (those snapshots are left out).
#[test]
fn md22_adapted_to_a_generator_unit_diagnoses_its_degradation() {
    let truth = Engine::new(
        EngineConfig::load(&root().join("config/gspy_turboshaft_2spool.toml")).expect("GSPy file"),
    )
    .expect("truth");
    let design_mw = 48.4;
    let rows_at = |health: [f64; 6], level: usize, group: &str| {
        let pts = generator_loads(design_mw, level);
        let n2 = vec![4100.0; pts.len()];
        let csv = snapshot_csv_at_speeds(
            &truth,
            &HealthParams::from_array(health),
            &pts,
            &n2,
            group,
            100.0,
            700 + level as u64,
            &INSTRUMENTS,
        )
        .expect("snapshots");
        read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows")
    };
    let healthy = rows_at([0.0; 6], 0, "healthy");
    let (report, adapted) = calibrated(&user_model(), &healthy);
    let a = report.adaptation.as_ref().expect("adapted");
    for c in &a.components {
        eprintln!(
            "{} speeds {:.3?} knots {:.3?} ({})",
            c.component, c.speed_range, c.knots, c.knots_reason
        );
    }
    eprintln!("RMS {:.2} → {:.2} σ", a.rms_before, a.rms_after);
    eprintln!(
        "in health units: {:.3?} ({})",
        a.health_error.points, a.health_error.note
    );
    for p in &a.health_error.parts {
        eprintln!(
            "  lines {:?}: {:+.2?} {}",
            p.diagnosed_lines, p.health, p.fit
        );
    }
    // GSPy's inlet holds its pressure ratio, and from 40 to 100 % load the measured P1 says so
    // decisively (χ² 35.5 for md22's flow-squared law, 0.1 for a constant loss).
    let law = report
        .inlet_loss_law
        .as_ref()
        .expect("P1 and ambient measured");
    eprintln!("{}", law.summary());
    assert_eq!(law.chosen, PressureLossLaw::Constant, "{}", law.summary());
    assert!(
        law.chi2_constant + 20.0 < law.chi2_flow_squared,
        "{}",
        law.summary()
    );

    let cfg = diagnosis_cfg();
    let base = diagnose_snapshots(&adapted, &healthy, &cfg).expect("baseline");
    let b = base.groups[0].result.health.to_array();
    let bq = format!("{:?}", base.groups[0].result.fit_quality.verdict).to_lowercase();
    eprintln!("baseline {b:+.3?} {bq}");

    let mut rows = Vec::new();
    for i in 0..GRID_LEVELS {
        rows.extend(rows_at(generator_grid(i), i + 1, &format!("level{i:02}")));
    }
    let diag = diagnose_snapshots(&adapted, &rows, &cfg).expect("grid");
    assert!(diag.failed.is_empty(), "{:?}", diag.failed);
    let est: Vec<[f64; 6]> = diag
        .groups
        .iter()
        .map(|g| g.result.health.to_array())
        .collect();
    let verdicts: Vec<String> = diag
        .groups
        .iter()
        .map(|g| format!("{:?}", g.result.fit_quality.verdict).to_lowercase())
        .collect();
    let worst = print_levels(&diag, &est, &verdicts);
    let truths: Vec<[f64; 6]> = (0..GRID_LEVELS).map(generator_grid).collect();
    let column = |v: &[[f64; 6]], p: usize| v.iter().map(|x| x[p]).collect::<Vec<f64>>();
    let good = verdicts.iter().filter(|q| *q == "good").count();
    let ranks: Vec<Rank> = (0..6)
        .map(|p| Rank::of(&column(&est, p), &column(&truths, p)))
        .collect();
    for (p, name) in HEALTH_NAMES.iter().enumerate() {
        eprintln!("{name}: {}, worst error {:.3}", ranks[p], worst[p]);
    }
    eprintln!("{good} of {GRID_LEVELS} fits good");
    let pt = a
        .components
        .iter()
        .find(|c| c.component == "pt")
        .expect("pt");
    assert!(pt.knots.iter().any(|k| *k > 1.0), "PT knots {:?}", pt.knots);
    assert_eq!(bq, "good");
    assert!(b.iter().all(|v| v.abs() <= 0.3), "baseline {b:?}");
    // Measured 2026-11-29: ρ 0.936 for D_GC, D_GT and D_ET, each level within 0.23 points of
    // the truth: the ceiling of this grid, each parameter healthy on 10 of its 20 levels (ties
    // no estimate can repeat), so every pair of levels the truth orders is ordered right; D_GP
    // 0.934 (one pair misordered, within 0.27); D_EC 0.81 (within 0.39), D_EP 0.85 (up to 0.86
    // off); 19 of 20 fits good (data RMS 1.02 σ). With md22's flow-squared inlet loss kept
    // (GSPy's inlet holds its pressure ratio: P1 residuals from +1.3 σ at 40 % load to −1.0 σ
    // at full load) the adaptation ended at 1.48 σ and 15 of 20 were good; with the constant
    // law but no closing fit of every design value, the baseline itself read D_EC −0.57 and
    // D_ET +0.65. Most levels leave one or two of their 9 loads out: fouling and the colder
    // days push the GG above the highest corrected speed of the healthy baseline (its full load
    // fell on a warm day). Fitted there, on curves extrapolated past the design anchor, the GG
    // speed was missed by 7–10 σ at the top loads and the 15-level grid before it read D_GC
    // 5.7 for 4 and −1.1 for a healthy compressor (worst errors 1.72 / 0.35 / 1.05 / 0.56 /
    // 0.70 / 1.29 points, ρ ≤ 0.84, 9 of 15 good). Not met: D_EP (the PT efficiency a
    // generator's power and exhaust temperature carry) reads HP-turbine wear as up to −0.75 ±
    // 0.17 and is then called good; D_EC, which reads the healthy levels at +0.16…+0.36
    // (the baseline's own +0.20 and noise) and the lightest fouling at +0.20 for 0.32.
    for (p, floor) in [0.9, 0.75, 0.9, 0.9, 0.9, 0.8].iter().enumerate() {
        assert!(ranks[p].rho >= *floor, "{}: {}", HEALTH_NAMES[p], ranks[p]);
    }
    assert!(good >= 18, "{good} of {GRID_LEVELS} fits good");
    // Every pair of levels the truth orders ordered right on D_GC, D_GT and D_ET; on D_GP one
    // pair 0.2 points apart (1.4 read 1.14, 1.2 read 1.17).
    for (p, most) in [(0, 0), (2, 0), (3, 0), (4, 1)] {
        assert!(
            ranks[p].misordered <= most,
            "{}: {}",
            HEALTH_NAMES[p],
            ranks[p]
        );
    }
    for (p, w) in worst.iter().enumerate().take(5) {
        assert!(*w <= 0.4, "{}: worst error {w:.3}", HEALTH_NAMES[p]);
    }
    // What is left out is said, with why: loads above the calibrated GG speeds (fouled, or
    // full load on a colder day) and below them (the lowest load on a warmer day).
    let left_out: Vec<&str> = diag
        .groups
        .iter()
        .flat_map(|g| &g.dropped)
        .map(|d| d.reason.as_str())
        .collect();
    assert!(!left_out.is_empty());
    assert!(
        left_out
            .iter()
            .all(|r| r.contains("the adapted model was calibrated at (0.")),
        "{left_out:?}"
    );
    assert!(left_out.iter().any(|r| r.contains("above the highest")));
    // Where a level is read more than a point off, the fit says it does not fit.
    for (i, e) in est.iter().enumerate() {
        let t = generator_grid(i);
        let err = (0..6).map(|p| (e[p] - t[p]).abs()).fold(0.0, f64::max);
        assert!(
            err <= 1.0 || verdicts[i] == "poor",
            "level {i}: off by {err:.2} points, fit {}",
            verdicts[i]
        );
    }
}

/// Prints each level of the generator grid (truth, estimate ± 1σ, verdict, loads left out);
/// returns each parameter's worst error over the levels.
fn print_levels(
    diag: &gtwatch::diagnosis::snapshot::SnapshotReport,
    est: &[[f64; 6]],
    verdicts: &[String],
) -> [f64; 6] {
    let mut worst = [0.0f64; 6];
    for (i, e) in est.iter().enumerate() {
        let t = generator_grid(i);
        for p in 0..6 {
            worst[p] = worst[p].max((e[p] - t[p]).abs());
        }
        let sd: Vec<f64> = HEALTH_NAMES
            .iter()
            .map(|n| {
                diag.groups[i]
                    .result
                    .sigma
                    .get(*n)
                    .copied()
                    .unwrap_or(f64::NAN)
            })
            .collect();
        eprintln!(
            "level {i:2} truth {t:.2?} est {e:+.2?} ±{sd:.2?} {} ({} of 9 loads left out: \
             beyond the calibrated GG speeds {:?})",
            verdicts[i],
            diag.groups[i].dropped.len(),
            diag.groups[i]
                .dropped
                .iter()
                .map(|d| d.reason.split(" is ").next().unwrap_or(""))
                .collect::<Vec<_>>()
        );
    }
    worst
}

/// As a user runs it: md22's file copied with GSPy's design row typed into `[design]` and a
/// generator load, `gtwatch calibrate --adapt` on GSPy's points writes the GG speeds it was
/// calibrated on (`[adaptation.calibrated]`), and `gtwatch diagnose` leaves out a snapshot whose
/// GG runs faster than any of them (here GSPy's full-load row with its GG speed 2 % up), naming
/// the line and why, while it diagnoses the others.
#[test]
fn cli_writes_the_calibrated_speeds_and_diagnosis_leaves_out_a_snapshot_beyond_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = root();
    let (_, dp) = gspy_rows().into_iter().find(|(dp, _)| *dp).expect("DP row");
    let md22 = std::fs::read_to_string(root.join("config/engine_md22.toml")).expect("md22");
    let maps = format!("\"{}/", root.join("config/maps").display());
    let mut section = String::new();
    let mut text = String::new();
    for line in md22.lines() {
        if line.starts_with('[') {
            section = line.split(']').next().unwrap_or("").to_string();
        }
        let key = line.split('=').next().unwrap_or("").trim();
        let typed = match (section.as_str(), key) {
            ("[design", "pressure_ratio") => Some(dp["P3"] / dp["P2"]),
            ("[design", "power_mw") => Some(dp["PW_PT"] / 1e6),
            ("[design", "gg_speed_rpm") => Some(dp["N_gg"]),
            ("[design", "pt_speed_rpm") => Some(dp["N_pt"]),
            ("[design", "exhaust_flow_kg_s") => Some(dp["W45"]),
            _ => None,
        };
        let line = match typed {
            Some(v) => format!("{key} = {v}"),
            None if section == "[load" && key == "mode" => "mode = \"generator\"".into(),
            None if section == "[load" && key == "exponent" => String::new(),
            None => line.replace("\"maps/", &maps),
        };
        text.push_str(&line);
        text.push('\n');
    }
    let unit = dir.path().join("unit.toml");
    std::fs::write(&unit, text).expect("write unit");
    let baseline = dir.path().join("gspy.csv");
    std::fs::write(&baseline, gspy_csv()).expect("write csv");
    let adapted = dir.path().join("adapted.toml");
    let cal = gtwatch(&[
        "calibrate".as_ref(),
        "--engine".as_ref(),
        unit.as_os_str(),
        "--input".as_ref(),
        baseline.as_os_str(),
        "--out".as_ref(),
        adapted.as_os_str(),
        "--adapt".as_ref(),
        "--threads".as_ref(),
        "2".as_ref(),
    ]);
    let said = String::from_utf8_lossy(&cal.stdout);
    assert!(
        said.contains("calibrated on relative corrected GG speeds 0.901…1.000"),
        "{said}"
    );
    // The inlet loss law the measured P1 shows is said, and written where it changed (on these
    // points a close call: see the first test).
    assert!(said.contains("design.inlet_loss_law: "), "{said}");
    let changed = said.contains("design.inlet_loss_law: constant (the file said flow_squared)");
    let written = std::fs::read_to_string(&adapted).expect("adapted file");
    let cfg = EngineConfig::load(&adapted).expect("the written file loads");
    assert_eq!(
        cfg.design.inlet_loss_law,
        if changed {
            PressureLossLaw::Constant
        } else {
            PressureLossLaw::FlowSquared
        }
    );
    let range = cfg
        .adaptation
        .as_ref()
        .and_then(|a| a.calibrated)
        .expect("[adaptation.calibrated]");
    assert!(written.contains("[adaptation.calibrated]"), "{written}");
    eprintln!("calibrated GG speeds {:.3?}", range.gg_speed);
    assert!(
        range.gg_speed[0] < 0.92 && range.gg_speed[1] > 0.99,
        "{range:?}"
    );

    // The full-load row again with its GG 2 % faster: beyond the calibrated speeds.
    let mut csv = gspy_csv();
    let full = csv.lines().nth(1).expect("full-load row").to_string();
    let n1 = dp["N_gg"];
    csv.push_str(&full.replace(&format!(",{n1},"), &format!(",{},", n1 * 1.02)));
    csv.push('\n');
    assert_eq!(csv.lines().count(), 10, "the row was edited: {csv}");
    let grid = dir.path().join("check.csv");
    std::fs::write(&grid, &csv).expect("write");
    let run = gtwatch(&[
        "diagnose".as_ref(),
        "--engine".as_ref(),
        adapted.as_os_str(),
        "--input".as_ref(),
        grid.as_os_str(),
        "--method".as_ref(),
        "steady".as_ref(),
        "--group-by".as_ref(),
        "test".as_ref(),
        "--json".as_ref(),
    ]);
    let doc: serde_json::Value = serde_json::from_slice(&run.stdout).expect("one JSON document");
    let g = &doc["groups"][0];
    assert_eq!(g["dropped_lines"], serde_json::json!([10]), "{g}");
    let reason = g["dropped"][0]["reason"].as_str().unwrap_or("");
    assert!(reason.contains("above the highest"), "{reason}");
    assert_eq!(g["lines"].as_array().map(Vec::len), Some(9), "{g}");
}

/// Runs the gtwatch binary with `args`; its output, once it has succeeded.
fn gtwatch(args: &[&std::ffi::OsStr]) -> std::process::Output {
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(args)
        .output()
        .expect("run gtwatch");
    assert!(
        run.status.success(),
        "gtwatch {args:?}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    run
}
