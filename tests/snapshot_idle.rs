//! Idle and light-load snapshots (issue 22 item 3): a healthy unit's steady points from idle to
//! part load, written by the model itself, are each solved — down to the idle point below the
//! fold of the running line, where fuel flow is not monotone in GG speed and continuation in
//! the fuel demand alone stalls — and diagnose as healthy; a row whose fuel flow is below
//! anything the model runs at is refused with that reason and its file line (header = line 1),
//! in the report and in the JSON of `gtwatch diagnose`.
//!
//! Truth: each row is solved at a given GG speed (an N1 demand, which has no fold), so the
//! fuel-demand solve the diagnosis does must find the same point by another route.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::diagnosis::snapshot::{diagnose_snapshots, read_snapshots};
use gtwatch::diagnosis::steady::steady_reading;
use gtwatch::diagnosis::DiagnosisConfig;
use gtwatch::engine::steady::{solve, Demand, SteadyInputs};
use gtwatch::engine::{Engine, EngineConfig};
use gtwatch::health::HealthParams;
use gtwatch::signals::Signal;
use std::collections::HashMap;
use std::path::PathBuf;

fn md22_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/engine_md22.toml")
}

fn md22() -> Engine {
    Engine::new(EngineConfig::load(&md22_path()).expect("md22 loads")).expect("md22 calibrates")
}

const WRITTEN: [Signal; 8] = [
    Signal::N1,
    Signal::P1,
    Signal::T2,
    Signal::P2,
    Signal::T34,
    Signal::P34,
    Signal::T4,
    Signal::Torque,
];

/// GG speeds of the rows: idle below the fold (4 100 rpm, fuel ≈ 0.088 kg/s; the running
/// line's fuel flow has a local maximum near 4 400 rpm and a minimum near 4 650 rpm at ISO),
/// inside the fold (4 330 rpm: its fuel flow has three running points, the measured GG speed
/// says which), then light and part load. The PT runs at 6 500 rpm.
const N1_RPM: [f64; 8] = [
    4100.0, 4330.0, 5400.0, 6000.0, 6800.0, 7600.0, 8300.0, 8900.0,
];

/// A noise-free healthy row per speed (`averaging` → ∞: what the instruments read exactly),
/// then one row with a fuel flow no running point of the model has.
fn csv(engine: &Engine) -> (String, Vec<f64>) {
    let mut text = String::from("test,t1_k,p_amb_kpa,n2_rpm,fuel_kg_s");
    for s in WRITTEN {
        text.push(',');
        text.push_str(s.column());
    }
    text.push('\n');
    let mut fuels = Vec::new();
    for (k, &n1) in N1_RPM.iter().enumerate() {
        let (t, p) = (283.0 + 2.0 * k as f64, 100.5 + 0.2 * k as f64);
        let m = engine.model_at(&HealthParams::HEALTHY, t, p);
        let inputs = SteadyInputs {
            t_amb_k: t,
            p_amb_kpa: p,
            n2_rpm: 6500.0,
            demand: Demand::N1Rpm(n1),
        };
        let sp = solve(&m, &inputs, None).expect("N1 solve");
        fuels.push(sp.fuel_kg_s);
        text.push_str(&format!("a,{t},{p},6500,{}", sp.fuel_kg_s));
        for s in WRITTEN {
            text.push_str(&format!(",{}", steady_reading(&m, &sp, s)));
        }
        text.push('\n');
    }
    // Below light-load range: a copy of the idle row with a tenth of its fuel (file line 10).
    let idle = text.lines().nth(1).expect("idle row").to_string();
    let mut cells: Vec<String> = idle.split(',').map(str::to_string).collect();
    cells[4] = format!("{}", fuels[0] / 10.0);
    text.push_str(&cells.join(","));
    text.push('\n');
    (text, fuels)
}

#[test]
fn idle_snapshots_are_solved_and_a_row_below_the_model_is_refused_by_line() {
    let engine = md22();
    let (text, fuels) = csv(&engine);
    // The idle row's fuel is below the running line's local minimum near the fold.
    assert!(fuels[0] < 0.0914, "idle fuel {}", fuels[0]);
    // The fold row's fuel has another running point: the solver alone lands on it.
    let m = engine.model_at(&HealthParams::HEALTHY, 285.0, 100.7);
    let alone = SteadyInputs {
        t_amb_k: 285.0,
        p_amb_kpa: 100.7,
        n2_rpm: 6500.0,
        demand: Demand::FuelKgS(fuels[1]),
    };
    let other = solve(&m, &alone, None).expect("fuel solve");
    assert!(
        (other.n1_rpm - N1_RPM[1]).abs() > 200.0,
        "fuel {} has one running point only, at {} rpm",
        fuels[1],
        other.n1_rpm
    );
    let rows = read_snapshots(text.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
    assert_eq!(rows.len(), 9);
    assert_eq!(
        rows[0].line, 2,
        "the first data row is file line 2 (header = 1)"
    );
    let cfg = DiagnosisConfig {
        max_model_runs: 1500,
        threads: Some(2),
        ..DiagnosisConfig::default()
    };
    let report = diagnose_snapshots(&engine, &rows, &cfg).expect("diagnosis");
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    let g = &report.groups[0];
    assert_eq!(g.lines, (2..=10).collect::<Vec<u64>>());
    assert_eq!(g.dropped.len(), 1, "{:?}", g.dropped);
    assert_eq!(g.dropped[0].line, 10);
    assert!(
        g.dropped[0]
            .reason
            .contains("is below the model's lowest running point at"),
        "{}",
        g.dropped[0].reason
    );
    // Diagnosed one by one, the refused row's group fails with the row's own reason.
    let single = read_snapshots(text.as_bytes(), &HashMap::new(), None).expect("rows");
    let alone = diagnose_snapshots(&engine, &single[8..], &cfg).expect("runs");
    assert!(alone.groups.is_empty());
    assert_eq!(alone.failed[0].lines, vec![10]);
    assert!(
        alone.failed[0]
            .reason
            .contains("line 10: no operating point of the model: fuel"),
        "{}",
        alone.failed[0].reason
    );
    // Every other row, idle included, is in the fit, and the healthy unit is found healthy.
    assert_eq!(
        g.residual_table.rows.len(),
        8,
        "{:?}",
        g.residual_table.rows
    );
    for (name, v) in gtwatch::health::HEALTH_NAMES
        .iter()
        .zip(g.result.health.to_array())
    {
        assert!(v.abs() < 0.05, "{name} {v:.4} (truth 0)");
    }
}

/// The CLI says the same: JSON `lines` and `dropped_lines` are file lines (header = line 1),
/// each dropped row with its reason, and the text speaks of snapshots.
#[test]
fn cli_lists_the_refused_row_by_file_line_and_speaks_of_snapshots() {
    let engine = md22();
    let (text, _) = csv(&engine);
    let dir = std::env::temp_dir().join(format!("gtwatch-idle-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let input = dir.join("idle.csv");
    std::fs::write(&input, text).expect("write");
    let run = |json: bool| {
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_gtwatch"));
        cmd.args(["diagnose", "--method", "steady", "--group-by", "test"])
            .arg("--engine")
            .arg(md22_path())
            .arg("--input")
            .arg(&input);
        if json {
            cmd.arg("--json");
        }
        let out = cmd.output().expect("runs");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).expect("utf-8")
    };
    let doc: serde_json::Value = serde_json::from_str(&run(true)).expect("json");
    let g = &doc["groups"][0];
    assert_eq!(g["lines"], serde_json::json!([2, 3, 4, 5, 6, 7, 8, 9, 10]));
    assert_eq!(g["dropped_lines"], serde_json::json!([10]));
    assert!(g["dropped"][0]["reason"]
        .as_str()
        .is_some_and(|r| r.contains("lowest running point")));
    assert!(g.get("steady_windows_s").is_none(), "{g}");
    let out = run(false);
    assert!(out.contains("line 10 not used"), "{out}");
    assert!(out.contains("steady snapshots (Method A)"), "{out}");
    for word in ["start-up", "steady window", "steady point at"] {
        assert!(!out.contains(word), "{word:?} in:\n{out}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Calibration poses every point as the diagnosis does: where one fuel flow has several running
/// points, the one at the row's measured GG speed. On the true engine's own rows (the fold row
/// included, whose fuel flow alone lands the solver on another running point, see above) every
/// calibration residual is zero, so a calibration neither fits nor reports a branch the
/// diagnosis would not use. (It solved each point from the design point before: the fold row
/// then read hundreds of σ off on the engine that made it.)
#[test]
fn calibration_solves_each_row_on_the_running_point_of_its_gg_speed() {
    use gtwatch::calibrate::problem::{prepare, residuals_on};
    // The rows hold the PT at 6 500 rpm at every power, which md22's load law would not: in
    // generator mode calibration compares the measured values only (no load-law residual), and
    // the steady points, whose PT speed is an input, are the same.
    let md22 = md22();
    let mut cfg = md22.cfg().clone();
    cfg.load = None;
    let engine = md22.with_config(cfg).expect("generator");
    let (text, _) = csv(&engine);
    let rows = read_snapshots(text.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
    let prep = prepare(&engine, &rows);
    assert_eq!(prep.points.len(), 8, "{:?}", prep.dropped);
    let r = residuals_on(&engine, &prep.points, &[]).expect("residuals");
    assert_eq!(r.len(), 8 * 8, "8 rows × 8 compared signals");
    let worst = r.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    assert!(worst < 0.01, "worst residual {worst:.3} σ: {r:.3?}");
}
