//! End-to-end: `gtwatch diagnose` on a CSV written in the `gtwatch simulate` layout.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::engine::sensors::MeasurementOptions;
use gtwatch::engine::{Engine, Scenario, Trace};
use gtwatch::health::HealthParams;
use std::process::Command;

fn write_startup(path: &std::path::Path, h: &HealthParams) {
    let e = Engine::reference().expect("engine");
    let (s, _) =
        gtwatch::engine::simulation::run_scenario(&e.model(h), &Scenario::startup(e.cfg()))
            .expect("start-up runs");
    let opts = MeasurementOptions {
        lags: true,
        noise: true,
        bias: false,
        seed: 4,
    };
    let tr = Trace::from_truth(&e, &s, Some(&opts));
    let f = std::fs::File::create(path).expect("create csv");
    tr.write_csv(std::io::BufWriter::new(f)).expect("write csv");
}

/// The lines of the CSV file `path` with `column`'s data cells replaced where `f(file line,
/// value)` gives a new text (the header is line 1) — an instrument error written by another
/// program.
fn alter_column(
    path: &std::path::Path,
    column: &str,
    f: impl Fn(usize, f64) -> Option<String>,
) -> Vec<String> {
    let text = std::fs::read_to_string(path).expect("csv");
    let header: Vec<&str> = text.lines().next().expect("header").split(',').collect();
    let col = header
        .iter()
        .position(|h| *h == column)
        .unwrap_or_else(|| panic!("no column {column}"));
    text.lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                return l.to_string();
            }
            let mut cells: Vec<String> = l.split(',').map(str::to_string).collect();
            let v: f64 = cells[col].parse().expect("number");
            if let Some(new) = f(i + 1, v) {
                cells[col] = new;
            }
            cells.join(",")
        })
        .collect()
}

#[test]
fn diagnose_prints_json_and_rejects_bad_rows() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("startup.csv");
    let truth = HealthParams {
        D_GC: 3.0,
        D_EC: 1.0,
        ..HealthParams::HEALTHY
    };
    write_startup(&csv, &truth);
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["diagnose", "--input"])
        .arg(&csv)
        .args(["--method", "steady", "--seed", "3", "--json"])
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let st = &v["methods"]["steady"];
    let gc = st["health"]["D_GC"].as_f64().expect("D_GC");
    let ec = st["health"]["D_EC"].as_f64().expect("D_EC");
    assert!((gc - 3.0).abs() < 0.5 && (ec - 1.0).abs() < 0.5, "{st}");
    assert!(st["sigma"]["D_GC"].as_f64().expect("sigma") > 0.0);
    assert!(st["model_runs"].as_u64().expect("runs") > 0);
    assert!(st["objective"].as_f64().is_some() && st["wall_s"].as_f64().is_some());
    assert!(v["methods"].get("transient").is_none());
    assert_eq!(
        st["fit_quality"]["verdict"], "good",
        "{}",
        st["fit_quality"]
    );
    assert!(
        st["fit_quality"]["normalised_residual"]
            .as_f64()
            .expect("number")
            < 0.9
    );

    // A malformed cell is reported with its line and column.
    let text = std::fs::read_to_string(&csv).expect("read");
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[5].split(',').map(String::from).collect();
    cells[2] = "fast".into();
    lines[5] = cells.join(",");
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, lines.join("\n")).expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["diagnose", "--input"])
        .arg(&bad)
        .output()
        .expect("runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("line 6, column 'n1_rpm'"), "{err}");
}

/// Issue 12 items 6 and 8: unusable data and a zero budget give a clear error and a failing
/// exit status, never `0.000 ± inf` (or `± 2.0 %`) with exit 0, and never a hang.
#[test]
fn diagnose_refuses_unusable_data_and_zero_budget() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("startup.csv");
    write_startup(&csv, &HealthParams::HEALTHY);
    let text = std::fs::read_to_string(&csv).expect("read");
    let lines: Vec<&str> = text.lines().collect();
    let header = lines[0];
    let n1_col = header
        .split(',')
        .position(|h| h == "n1_rpm")
        .expect("n1 column");
    let diagnose = |path: &std::path::Path, extra: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
            .args(["diagnose", "--input"])
            .arg(path)
            .args(extra)
            .output()
            .expect("runs");
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    // Constant n1 (the GG never turns).
    let flat: Vec<String> = std::iter::once(header.to_string())
        .chain(lines[1..].iter().map(|l| {
            let mut c: Vec<&str> = l.split(',').collect();
            c[n1_col] = "0";
            c.join(",")
        }))
        .collect();
    let p = dir.path().join("flat.csv");
    std::fs::write(&p, flat.join("\n")).expect("write");
    let (ok, err) = diagnose(&p, &["--method", "transient"]);
    assert!(
        !ok && err.contains("not a start-up") && err.contains("never rises"),
        "{err}"
    );
    // Only the steady rows (the GG turning from the first sample).
    let steady: Vec<&str> = std::iter::once(header)
        .chain(
            lines[1..]
                .iter()
                .copied()
                .filter(|l| l.contains(",steady,")),
        )
        .collect();
    assert!(steady.len() > 10);
    let p = dir.path().join("steady.csv");
    std::fs::write(&p, steady.join("\n")).expect("write");
    let (ok, err) = diagnose(&p, &["--method", "transient"]);
    assert!(!ok && err.contains("not at rest"), "{err}");
    // A zero budget.
    let (ok, err) = diagnose(&csv, &["--max-runs", "0"]);
    assert!(
        !ok && err.contains("--max-runs") && err.contains("at least 1"),
        "{err}"
    );
    // P1 = 0 on one row.
    let p1_col = header
        .split(',')
        .position(|h| h == "p1_kpa")
        .expect("p1 column");
    let mut zero: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let mut c: Vec<&str> = lines[7].split(',').collect();
    c[p1_col] = "0";
    zero[7] = c.join(",");
    let p = dir.path().join("p1.csv");
    std::fs::write(&p, zero.join("\n")).expect("write");
    let (ok, err) = diagnose(&p, &[]);
    assert!(
        !ok && err.contains("line 8") && err.contains("p1_kpa = 0"),
        "{err}"
    );
}

/// Snapshot rows (a historian export with its own column names) from the steady model: day,
/// inlet temperature, barometric pressure, speeds, compressor-exit and HPT-exit readings, fuel
/// and power at five loads per day.
fn write_snapshots(path: &std::path::Path, days: &[(&str, HealthParams)]) {
    use gtwatch::engine::steady::{solve, Demand, SteadyInputs};
    let e = Engine::reference().expect("engine");
    let mut text = String::from("day,T_inlet,P_baro,NGG,NPT,T_cdp,P_cdp,T_egt,P_hpt,FUEL,MW\n");
    for (day, h) in days {
        for (k, load) in [14.0, 18.0, 22.0, 26.0, 30.0].iter().enumerate() {
            let (t, p) = (279.0 + 4.0 * k as f64, 100.6 - 0.25 * k as f64);
            let m = e.model_at(h, t, p);
            let inputs = SteadyInputs {
                t_amb_k: t,
                p_amb_kpa: p,
                n2_rpm: e.cfg().design.pt_speed_rpm,
                demand: Demand::PowerMw(*load),
            };
            let s = solve(&m, &inputs, None).expect("steady").stations;
            text.push_str(&format!(
                "{day},{t},{p},{},{},{},{},{},{},{},{}\n",
                s.n1_rpm, s.n2_rpm, s.t2_k, s.p2_kpa, s.t34_k, s.p34_kpa, s.fuel_kg_s, s.power_mw
            ));
        }
    }
    std::fs::write(path, text).expect("write snapshots");
}

#[test]
fn diagnose_steady_snapshots_per_group_with_a_column_map() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("snapshots.csv");
    let later = HealthParams {
        D_GC: 2.0,
        D_EC: 1.5,
        ..HealthParams::HEALTHY
    };
    write_snapshots(
        &csv,
        &[("2026-01-10", HealthParams::HEALTHY), ("2026-06-10", later)],
    );
    let map = "t1_k=T_inlet,p_amb_kpa=P_baro,n1_rpm=NGG,n2_rpm=NPT,t2_k=T_cdp,p2_kpa=P_cdp,\
               t34_k=T_egt,p34_kpa=P_hpt,fuel_kg_s=FUEL,power_mw=MW";
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["diagnose", "--method", "steady", "--input"])
        .arg(&csv)
        .args(["--group-by", "day", "--map", map, "--json"])
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    assert_eq!(v["method"], "steady_snapshots");
    let groups = v["groups"].as_array().expect("groups");
    assert_eq!(groups.len(), 2);
    for (g, truth) in groups.iter().zip([HealthParams::HEALTHY, later]) {
        assert_eq!(g["lines"].as_array().expect("lines").len(), 5);
        for (name, t) in gtwatch::health::HEALTH_NAMES.iter().zip(truth.to_array()) {
            let est = g["health"][*name].as_f64().expect("health value");
            assert!(
                (est - t).abs() < 0.3,
                "{} {name}: {est:.3} vs {t}",
                g["group"]
            );
        }
        assert_eq!(g["fit_quality"]["verdict"], "good");
        // The residual table: one row per snapshot, every value within noise.
        let table = &g["residual_table"];
        let rows = table["rows"].as_array().expect("rows");
        assert_eq!(rows.len(), 5, "{table}");
        let columns = table["signals"].as_array().expect("signals");
        assert!(columns.iter().any(|c| c == "p2_kpa"), "{table}");
        for r in rows {
            for v in r["values"].as_array().expect("values") {
                assert!(v.as_f64().expect("value").abs() < 4.0, "{table}");
            }
        }
    }
    // A wrong P2 reading on one row (file line 4, +3 %) is where the table shows it.
    let altered = alter_column(&csv, "P_cdp", |line, v| {
        (line == 4).then(|| format!("{}", v * 1.03))
    });
    let bad = dir.path().join("bad_p2.csv");
    std::fs::write(&bad, altered.join("\n")).expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["diagnose", "--method", "steady", "--input"])
        .arg(&bad)
        .args(["--group-by", "day", "--map", map, "--json"])
        .output()
        .expect("runs");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    let table = &v["groups"][0]["residual_table"];
    let p2 = table["signals"]
        .as_array()
        .expect("signals")
        .iter()
        .position(|c| c == "p2_kpa")
        .expect("p2 column");
    let mut worst = (0u64, 0usize, 0.0f64);
    for r in table["rows"].as_array().expect("rows") {
        for (j, v) in r["values"].as_array().expect("values").iter().enumerate() {
            let v = v.as_f64().unwrap_or(0.0).abs();
            if v > worst.2 {
                worst = (r["line"].as_u64().expect("line"), j, v);
            }
        }
    }
    assert_eq!(
        (worst.0, worst.1),
        (4, p2),
        "largest residual {worst:?} in {table}"
    );
    // One row alone has fewer readings than parameters: said, not guessed.
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["diagnose", "--method", "steady", "--snapshots", "--input"])
        .arg(&csv)
        .args(["--map", map, "--json"])
        .output()
        .expect("runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("more averaged values than parameters"),
        "{err}"
    );
}

/// A compressor far from new (D_GC 13 %, beyond the default +10 % search limit): the estimate
/// ends on the limit, which the result says (fit quality not `good`, `at_limit` names D_GC,
/// the text output flags the line); with the interval widened (`--fit-param D_GC=-3:20`) the
/// same data give 13 % with nothing at a limit. Out-of-range intervals are refused by name.
#[test]
fn health_estimate_at_its_search_limit_is_flagged_and_limits_can_be_widened() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("startup.csv");
    let truth = HealthParams {
        D_GC: 13.0,
        D_EC: 1.0,
        ..HealthParams::HEALTHY
    };
    write_startup(&csv, &truth);
    let diagnose = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_gtwatch"))
            .args(["diagnose", "--input"])
            .arg(&csv)
            .args(["--method", "steady", "--seed", "3"])
            .args(extra)
            .output()
            .expect("runs")
    };
    let json = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec!["--json"];
        args.extend_from_slice(extra);
        let out = diagnose(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice::<serde_json::Value>(&out.stdout).expect("json")["methods"]["steady"]
            .clone()
    };
    let st = json(&[]);
    let q = &st["fit_quality"];
    assert_ne!(q["verdict"], "good", "{q}");
    let hits = q["at_limit"].as_array().expect("at_limit");
    assert!(
        hits.iter()
            .any(|h| h["name"] == "D_GC" && h["side"] == "upper" && h["limit"] == 10.0),
        "{q}"
    );
    assert!(
        q["summary"]
            .as_str()
            .expect("summary")
            .contains("--fit-param D_GC=LOW:HIGH"),
        "{q}"
    );
    let text = String::from_utf8_lossy(&diagnose(&[]).stdout).to_string();
    assert!(text.contains("AT ITS UPPER SEARCH LIMIT +10 %"), "{text}");

    let wide = json(&["--fit-param", "D_GC=-3:20"]);
    let gc = wide["health"]["D_GC"].as_f64().expect("D_GC");
    assert!((gc - 13.0).abs() < 0.5, "{wide}");
    assert!(
        wide["fit_quality"]["at_limit"]
            .as_array()
            .expect("at_limit")
            .is_empty(),
        "{wide}"
    );
    for bad in ["D_GC=2:20", "d_ec=-3:45"] {
        let out = diagnose(&["--fit-param", bad]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success()
                && err.contains(bad)
                && (err.contains("must") || err.contains("beyond")),
            "{bad}: {err}"
        );
    }
}

/// A column in another unit is refused with the unit it most likely is: T1 in °C in a start-up
/// (Windows line ends, so the line named must still be the file's), P2 in bar in snapshots.
#[test]
fn a_column_in_the_wrong_unit_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("startup.csv");
    write_startup(&csv, &HealthParams::HEALTHY);
    let celsius = alter_column(&csv, "t1_k", |_, v| Some(format!("{:.3}", v - 273.15)));
    let bad = dir.path().join("t1_celsius.csv");
    std::fs::write(&bad, celsius.join("\r\n")).expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["diagnose", "--input"])
        .arg(&bad)
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("'t1_k'") && err.contains("looks like °C"),
        "{err}"
    );
    assert!(
        err.contains("--units t1_k=degC"),
        "how to state the unit is said: {err}"
    );
    // The line named is the file line of the value quoted.
    let line: usize = err
        .split("line ")
        .nth(1)
        .and_then(|r| r.split(',').next())
        .and_then(|n| n.parse().ok())
        .expect("a line number");
    let quoted = err
        .split("'t1_k': ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .expect("value");
    assert!(celsius[line - 1].contains(quoted), "line {line}: {err}");

    let snaps = dir.path().join("snapshots.csv");
    write_snapshots(&snaps, &[("2026-01-10", HealthParams::HEALTHY)]);
    let bar = alter_column(&snaps, "P_cdp", |_, v| Some(format!("{:.4}", v / 100.0)));
    let bad = dir.path().join("p2_bar.csv");
    std::fs::write(&bad, bar.join("\n")).expect("write");
    let map = "t1_k=T_inlet,p_amb_kpa=P_baro,n1_rpm=NGG,n2_rpm=NPT,t2_k=T_cdp,p2_kpa=P_cdp,\
               t34_k=T_egt,p34_kpa=P_hpt,fuel_kg_s=FUEL,power_mw=MW";
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["diagnose", "--method", "steady", "--input"])
        .arg(&bad)
        .args(["--group-by", "day", "--map", map])
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("line 2, column 'P_cdp'") && err.contains("looks like bar"),
        "{err}"
    );
}

/// Snapshots of a mildly fouled reference engine (D_GC 1.5, D_EC 0.8) written to `dir`.
fn mild_snapshots(dir: &std::path::Path) -> std::path::PathBuf {
    let snaps = dir.join("snapshots.csv");
    let mild = HealthParams {
        D_GC: 1.5,
        D_EC: 0.8,
        ..HealthParams::HEALTHY
    };
    write_snapshots(&snaps, &[("2026-01-10", mild)]);
    snaps
}

/// `gtwatch diagnose --method steady --json` of `file` with the snapshot columns mapped, and
/// `units` stated when given.
fn run_mapped(file: &std::path::Path, units: Option<&str>) -> std::process::Output {
    let map = "t1_k=T_inlet,p_amb_kpa=P_baro,n1_rpm=NGG,n2_rpm=NPT,t2_k=T_cdp,p2_kpa=P_cdp,\
               t34_k=T_egt,p34_kpa=P_hpt,fuel_kg_s=FUEL,power_mw=MW";
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_gtwatch"));
    cmd.args(["diagnose", "--method", "steady", "--json", "--input"])
        .arg(file)
        .args(["--group-by", "day", "--map", map]);
    if let Some(u) = units {
        cmd.args(["--units", u]);
    }
    cmd.output().expect("runs")
}

/// Each of two reads' six parameters within `tolerance` points of the other's.
fn assert_same_health(a: &[f64; 6], b: &[f64; 6], tolerance: f64) {
    for p in 0..6 {
        assert!(
            (a[p] - b[p]).abs() < tolerance,
            "parameter {p}: {} vs {}",
            a[p],
            b[p]
        );
    }
}

/// The first group's six health estimates of a `--json` diagnosis.
fn health_of(out: &std::process::Output) -> [f64; 6] {
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let g = &v["groups"][0]["health"];
    ["D_GC", "D_EC", "D_GT", "D_ET", "D_GP", "D_EP"].map(|p| g[p].as_f64().expect("health"))
}

/// A file in the plant's own units (°C, bar, mbar, kg/h, kW, an n1 in rad/s) is read once each
/// column's unit is stated (`--units`): the same health as the file in the model's units, to
/// the digits written; a unit of the wrong kind, or a gauge pressure, is refused naming the
/// column.
#[test]
fn a_file_in_the_plants_own_units_is_read_once_they_are_stated() {
    let dir = tempfile::tempdir().expect("tempdir");
    let snaps = mild_snapshots(dir.path());
    let plant = dir.path().join("plant_units.csv");
    let mut lines = std::fs::read_to_string(&snaps)
        .expect("csv")
        .lines()
        .map(str::to_string)
        .collect::<Vec<_>>();
    for (column, f) in [
        ("T_inlet", (|v| v - 273.15) as fn(f64) -> f64),
        ("T_cdp", |v| v - 273.15),
        ("T_egt", |v| (v - 273.15) * 1.8 + 32.0),
        ("P_baro", |v| v * 10.0),
        ("P_cdp", |v| v / 100.0),
        ("P_hpt", |v| v / 6.894_757_293_168),
        ("NGG", |v| v * std::f64::consts::PI / 30.0),
        ("FUEL", |v| v * 3600.0),
        ("MW", |v| v * 1000.0),
    ] {
        std::fs::write(&plant, lines.join("\n")).expect("write");
        lines = alter_column(&plant, column, |_, v| Some(format!("{:.10}", f(v))));
    }
    std::fs::write(&plant, lines.join("\n")).expect("write");
    let units = "T1=degC,t2_k=C,t34_k=degF,p_amb_kpa=mbar,p2_kpa=bara,p34_kpa=psia,n1_rpm=rad/s,\
                 fuel_kg_s=kg/h,power_mw=kW";
    let run = run_mapped;
    let own = run(&snaps, None);
    assert!(
        own.status.success(),
        "{}",
        String::from_utf8_lossy(&own.stderr)
    );
    // Unstated, the first column out of place is named with the unit to state.
    let unstated = run(&plant, None);
    let err = String::from_utf8_lossy(&unstated.stderr);
    assert!(!unstated.status.success(), "{err}");
    assert!(
        err.contains("--units p_amb_kpa=") || err.contains("--units t1_k=degC"),
        "{err}"
    );
    let stated = run(&plant, Some(units));
    assert!(
        stated.status.success(),
        "{}",
        String::from_utf8_lossy(&stated.stderr)
    );
    let (a, b) = (health_of(&own), health_of(&stated));
    assert_same_health(&a, &b, 1e-3);
    assert!(
        (a[0] - 1.5).abs() < 0.2,
        "the diagnosis itself is right: {a:?}"
    );
    for (bad, says) in [
        ("t2_k=bar", "'bar' is a unit of an absolute pressure"),
        ("p2_kpa=barg", "gauge pressure"),
        ("n1_rpm=%", "design speed"),
        ("t2_k=kelvinish", "unknown unit"),
    ] {
        let out = run(&plant, Some(bad));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{bad}: {err}");
        assert!(
            err.contains("--units: unit of '") && err.contains(says),
            "{bad}: {err}"
        );
    }
}

/// A gas fuel metered by volume: the same snapshots with the fuel in normal m³/h
/// (`--units fuel_kg_s=Nm3/h`) read as in kg/s, the engine file's methane converting them at
/// ISO 6976's 0.7175 kg/m³ (the built-in engine burns methane).
#[test]
fn a_gas_fuel_metered_by_volume_is_read_with_the_engines_fuel() {
    let dir = tempfile::tempdir().expect("tempdir");
    let snaps = mild_snapshots(dir.path());
    let by_volume = dir.path().join("nm3.csv");
    let lines = alter_column(&snaps, "FUEL", |_, v| {
        Some(format!("{:.10}", v * 3600.0 / 0.7175))
    });
    std::fs::write(&by_volume, lines.join("\n")).expect("write");
    let (own, stated) = (
        run_mapped(&snaps, None),
        run_mapped(&by_volume, Some("fuel_kg_s=Nm3/h")),
    );
    for out in [&own, &stated] {
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let (a, b) = (health_of(&own), health_of(&stated));
    eprintln!("kg/s {a:?}, Nm3/h {b:?}");
    assert_same_health(&a, &b, 0.02);
    assert!(
        (a[0] - 1.5).abs() < 0.2,
        "the diagnosis itself is right: {a:?}"
    );
}

/// A row the model has no steady point for (fuel 1 % of design, below the lowest fuel the
/// model's running line reaches) is left out with that reason, by file line (header = line 1),
/// in JSON and text; the group is still diagnosed.
#[test]
fn a_row_without_a_steady_point_is_left_out_with_its_reason() {
    let dir = tempfile::tempdir().expect("tempdir");
    let snaps = dir.path().join("snapshots.csv");
    write_snapshots(&snaps, &[("2026-01-10", HealthParams::HEALTHY)]);
    let idle = alter_column(&snaps, "FUEL", |line, _| {
        (line == 3).then(|| "0.01".to_string())
    });
    let csv = dir.path().join("idle.csv");
    std::fs::write(&csv, idle.join("\n")).expect("write");
    let map = "t1_k=T_inlet,p_amb_kpa=P_baro,n1_rpm=NGG,n2_rpm=NPT,t2_k=T_cdp,p2_kpa=P_cdp,\
               t34_k=T_egt,p34_kpa=P_hpt,fuel_kg_s=FUEL,power_mw=MW";
    let run = |json: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_gtwatch"));
        c.args(["diagnose", "--method", "steady", "--input"])
            .arg(&csv)
            .args(["--group-by", "day", "--map", map]);
        if json {
            c.arg("--json");
        }
        c.output().expect("runs")
    };
    let out = run(true);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    let g = &v["groups"][0];
    assert_eq!(g["dropped_lines"], serde_json::json!([3]), "{g}");
    let reason = g["dropped"][0]["reason"].as_str().expect("reason");
    assert!(
        reason.contains("fuel 0.010 kg/s is below the model's lowest running point at"),
        "{reason}"
    );
    let text = String::from_utf8_lossy(&run(false).stdout).to_string();
    assert!(
        text.contains("line 3 not used: no operating point of the model: fuel 0.010 kg/s"),
        "{text}"
    );
}

/// Runs `gtwatch diagnose --json` (both methods) on `path`; the methods' JSON.
fn diagnose_json(path: &std::path::Path) -> serde_json::Value {
    diagnose_document(path)["methods"].clone()
}

/// Runs `gtwatch diagnose --json` (both methods) on `path`; its whole JSON document.
fn diagnose_document(path: &std::path::Path) -> serde_json::Value {
    diagnose_document_with(path, &[])
}

/// [`diagnose_document`] with `extra` arguments.
fn diagnose_document_with(path: &std::path::Path, extra: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["diagnose", "--input"])
        .arg(path)
        .args(extra)
        .args(["--seed", "3", "--json"])
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON document")
}

/// A noisy start-up of a fouled engine (D_GC 2, D_EC 0.8) written to a temporary folder, and
/// its diagnosis: the folder (kept alive by the caller), the file, the methods' JSON.
fn fouled_startup() -> (tempfile::TempDir, std::path::PathBuf, serde_json::Value) {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("startup.csv");
    let truth = HealthParams {
        D_GC: 2.0,
        D_EC: 0.8,
        ..HealthParams::HEALTHY
    };
    write_startup(&csv, &truth);
    let clean = diagnose_json(&csv);
    (dir, csv, clean)
}

/// A fuel meter with a zero offset, as another program would write it: the reading at rest
/// (before light-off, no fuel flowing) is the offset, and it is in every reading. Before, an
/// offset of +0.02 kg/s lit the model's combustor in a standing engine and every Method B run
/// failed ("step size underflow in phase standstill"), and Method A burnt 7 % too much fuel at
/// idle (fit `poor`, normalised residual 486). Now the zero is read at rest, reported, and taken
/// off: each method gives the health of the meter without the offset.
#[test]
fn a_fuel_meter_zero_offset_is_read_at_rest_and_taken_off() {
    let (dir, csv, clean) = fouled_startup();
    assert!(clean["transient"]["fuel_meter_zero"].is_null(), "{clean}");
    // A deterministic ±0.003 kg/s of the meter's own noise at every reading (rest included).
    let wobble = |line: usize| 0.003 * (((line * 7919) % 13) as f64 / 6.0 - 1.0);
    let cases: [(&str, f64, bool); 3] = [
        ("high", 0.02, false),
        ("low", -0.015, false),
        ("noisy", 0.01, true),
    ];
    for (name, offset, noisy) in cases {
        let lines = alter_column(&csv, "fuel_kg_s", |line, v| {
            let w = if noisy { wobble(line) } else { 0.0 };
            Some(format!("{:.6}", v + offset + w))
        });
        let path = dir.path().join(format!("{name}.csv"));
        std::fs::write(&path, lines.join("\n")).expect("write");
        let m = diagnose_json(&path);
        for method in ["transient", "steady"] {
            let z = m[method]["fuel_meter_zero"]["kg_s"]
                .as_f64()
                .unwrap_or_else(|| panic!("{name} {method}: no zero reported: {}", m[method]));
            assert!(
                (z - offset).abs() < 0.004,
                "{name} {method}: zero {z} for {offset}"
            );
            for p in ["D_GC", "D_EC", "D_GT", "D_ET", "D_GP", "D_EP"] {
                let got = m[method]["health"][p].as_f64().expect("health");
                let want = clean[method]["health"][p].as_f64().expect("health");
                // Exact offsets: the clean fit to the CSV's six decimals; the noisy meter
                // within its noise.
                let tol = if noisy { 0.2 } else { 0.02 };
                assert!(
                    (got - want).abs() < tol,
                    "{name} {method} {p}: {got:.3} against {want:.3} without the offset"
                );
            }
        }
    }
}

/// A start-up with 30 s of samples lost in the middle (an outage of the historian, 100–129 s,
/// from light-off into idle), as another program would export it. The model's fuel is
/// interpolated across the hole, which is not what the engine burnt, and its PT, heavy and
/// lightly loaded before the breaker closes, carried the difference for minutes: the fit's
/// normalised residual rose from 0.73 to 2.08 on this record (another seed: 0.71 to 1.74, n2
/// off by +64 rpm through idle). Now the hole is reported and the model's shaft speeds are set
/// to the measured ones after it: the fit is as close as on the whole record.
#[test]
fn a_hole_in_the_record_is_reported_and_the_shafts_resynchronised_after_it() {
    let (dir, csv, clean) = fouled_startup();
    assert_eq!(clean["transient"]["record_holes"], serde_json::json!([]));
    let text = std::fs::read_to_string(&csv).expect("csv");
    let kept: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(i, l)| {
            let t: f64 = l
                .split(',')
                .next()
                .and_then(|c| c.parse().ok())
                .unwrap_or(-1.0);
            *i == 0 || !(100.0..130.0).contains(&t)
        })
        .map(|(_, l)| l)
        .collect();
    assert_eq!(kept.len() + 30, text.lines().count(), "30 samples dropped");
    let holed = dir.path().join("holed.csv");
    std::fs::write(&holed, kept.join("\n")).expect("write");
    let m = diagnose_json(&holed);
    let holes = m["transient"]["record_holes"].as_array().expect("holes");
    assert_eq!(holes.len(), 1, "{holes:?}");
    assert_eq!(holes[0]["from_s"].as_f64(), Some(99.0));
    assert_eq!(holes[0]["to_s"].as_f64(), Some(130.0));
    let residual = |v: &serde_json::Value| {
        v["transient"]["fit_quality"]["normalised_residual"]
            .as_f64()
            .expect("residual")
    };
    assert!(
        residual(&m) < residual(&clean) + 0.3,
        "normalised residual {:.2} with the hole against {:.2} without",
        residual(&m),
        residual(&clean)
    );
    for p in ["D_GC", "D_EC", "D_GT", "D_ET", "D_GP", "D_EP"] {
        let got = m["transient"]["health"][p].as_f64().expect("health");
        let want = clean["transient"]["health"][p].as_f64().expect("health");
        assert!(
            (got - want).abs() < 0.1,
            "{p}: {got:.3} with the hole against {want:.3} without"
        );
    }
}

/// The fouled start-up as a historian exports it: no phase column, ISO 8601 time stamps in a
/// `timestamp` column. The start-up detector finds it in memory and labels its phases, and
/// both methods read the health they read from the simulator's own labels.
#[test]
fn a_start_up_without_phase_labels_is_found_and_diagnosed() {
    let (dir, csv, clean) = fouled_startup();
    let text = std::fs::read_to_string(&csv).expect("csv");
    let header: Vec<&str> = text.lines().next().expect("header").split(',').collect();
    let (t_col, phase_col) = (
        header.iter().position(|h| *h == "time_s").expect("time"),
        header.iter().position(|h| *h == "phase").expect("phase"),
    );
    let t0 = 1_750_000_000_000_i64; // 2025-06-15T15:06:40Z
    let log: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let cells: Vec<&str> = l.split(',').collect();
            let mut out: Vec<String> = Vec::new();
            for (c, cell) in cells.iter().enumerate() {
                if c == phase_col {
                    continue;
                }
                out.push(match (i, c == t_col) {
                    (0, true) => "timestamp".to_string(),
                    (_, true) if i > 0 => {
                        let ms = t0 + (cell.parse::<f64>().expect("t") * 1000.0).round() as i64;
                        gtwatch::time::fmt_ms_rfc3339(ms)
                    }
                    _ => (*cell).to_string(),
                });
            }
            out.join(",")
        })
        .collect();
    let path = dir.path().join("historian.csv");
    std::fs::write(&path, log.join("\n")).expect("write");
    let v = diagnose_document(&path);
    let found = v["startup"]["found"].as_array().expect("found");
    assert_eq!(found.len(), 1, "{:#}", v["startup"]);
    assert_eq!(found[0]["outcome"], "completed");
    assert_eq!(
        found[0]["phases"]
            .as_array()
            .expect("phases")
            .last()
            .expect("one"),
        "steady"
    );
    assert!(found[0]["start_utc"]
        .as_str()
        .expect("utc")
        .starts_with("2025-06-15T15:0"));
    for m in ["transient", "steady"] {
        for p in ["D_GC", "D_EC", "D_GT", "D_ET", "D_GP", "D_EP"] {
            let (a, b) = (
                v["methods"][m]["health"][p].as_f64().expect("from the log"),
                clean[m]["health"][p].as_f64().expect("from the labels"),
            );
            assert!(
                (a - b).abs() <= 0.15,
                "{m} {p}: {a:+.3} unlabelled, {b:+.3} labelled"
            );
        }
    }
    // `--method steady` alone: the detected start-up's windows (Method A), not the rows as
    // snapshots (whose rows at rest failed the unit check).
    let steady = diagnose_document_with(&path, &["--method", "steady"]);
    assert_eq!(steady["startup"]["chosen"], 1, "{steady:#}");
    assert_eq!(
        steady["methods"]["steady"]["health"],
        v["methods"]["steady"]["health"]
    );
    // A start that is not there, and --start on a file that carries its phases.
    let refused = |file: &std::path::Path, why: &str| {
        let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
            .args(["diagnose", "--input"])
            .arg(file)
            .args(["--start", "2", "--method", "transient"])
            .output()
            .expect("runs");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(why), "{err}");
    };
    refused(&path, "holds 1 start-up(s)");
    refused(&csv, "carries its phases");
}

/// `--phases` restricts what Method B compares: on the twin the steady phase alone, and the
/// loading with it, read the fouling the whole start-up reads, from fewer residuals, and the
/// result says what was left out; a phase that is not a start-up's is refused by name.
#[test]
fn method_b_compares_only_the_phases_asked_for() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("startup.csv");
    let truth = HealthParams {
        D_GC: 2.0,
        D_EC: 1.0,
        ..HealthParams::HEALTHY
    };
    write_startup(&csv, &truth);
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_gtwatch"))
            .args([
                "diagnose",
                "--method",
                "transient",
                "--threads",
                "2",
                "--json",
            ])
            .arg("--input")
            .arg(&csv)
            .args(extra)
            .output()
            .expect("runs")
    };
    let result = |extra: &[&str]| -> serde_json::Value {
        let out = run(extra);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        v["methods"]["transient"].clone()
    };
    let all = result(&[]);
    let late = result(&["--phases", "loading,steady"]);
    let steady = result(&["--phases", "steady"]);
    let n = |r: &serde_json::Value| r["residuals"].as_u64().expect("residuals");
    assert!(
        n(&steady) < n(&late) && n(&late) < n(&all),
        "{} {} {}",
        n(&steady),
        n(&late),
        n(&all)
    );
    let notes = |r: &serde_json::Value| r["left_out"].to_string();
    assert!(
        notes(&steady).contains("only the samples of the phase(s) steady compared"),
        "{}",
        notes(&steady)
    );
    assert!(
        notes(&late).contains("phase(s) loading, steady"),
        "{}",
        notes(&late)
    );
    assert!(!notes(&all).contains("--phases"), "{}", notes(&all));
    // Without --phases the run to load and the steady end are read apart too, and on the
    // model's own twin they agree; with --phases the user's choice stands alone.
    let split = &all["phase_split"];
    assert_eq!(split["differ"], serde_json::json!([]), "{split:#}");
    for part in ["to_load", "steady"] {
        let gc = split[part]["health"]["D_GC"].as_f64().expect("D_GC");
        assert!((gc - 2.0).abs() < 0.5, "{part}: D_GC {gc:.2}");
    }
    assert_eq!(split["steady"]["phases"], serde_json::json!(["steady"]));
    assert!(steady["phase_split"].is_null());
    for r in [&all, &late, &steady] {
        let gc = r["health"]["D_GC"].as_f64().expect("D_GC");
        assert!((gc - 2.0).abs() < 0.5, "D_GC {gc:.2} against 2.0");
    }
    let out = run(&["--phases", "steady,cruise"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--phases: `cruise` is not a start-up phase"),
        "{err}"
    );
}
