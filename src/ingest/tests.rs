use super::*;
use crate::quality::Quality;
use crate::signals::Signal;
use crate::store::Store;

fn setup(csv: &str) -> (tempfile::TempDir, Store, PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = Store::open(&dir.path().join("r.db")).expect("open");
    let path = dir.path().join("log.csv");
    std::fs::write(&path, csv).expect("write csv");
    (dir, store, path)
}

#[test]
fn replay_is_idempotent_and_maps_signal_columns() {
    let csv = "time,n1_rpm,power_mw,comment\n\
               2024-03-01T00:00:00Z,100,1.5,a\n\
               2024-03-01T00:00:01Z,200,,b\n\
               2024-03-01T00:00:02Z,300,2.5,c\n";
    let (_d, mut store, path) = setup(csv);
    let cfg = ReplayConfig::default();
    let r = replay_file(&mut store, &cfg, &path, Progress::Silent).expect("replay");
    assert_eq!(r.rows_read, 3);
    assert_eq!(r.samples_inserted, 5, "empty cell = no sample");
    assert_eq!(r.ignored_columns, vec!["comment".to_string()]);
    let r2 = replay_file(&mut store, &cfg, &path, Progress::Silent).expect("replay");
    assert_eq!((r2.samples_inserted, r2.samples_present), (0, 5));
    assert_eq!(store.sample_count().expect("count"), 5);
    let tag = store
        .tag_for_signal(Signal::N1)
        .expect("q")
        .expect("n1 tag");
    assert_eq!(tag.name, "n1_rpm");
    assert_eq!(tag.unit, "rpm");
}

#[test]
fn explicit_mapping_epoch_and_delimiter() {
    let csv = "ts;GG speed;Fuel;Other\n1709251200;5000;0.4;7\n1709251201;5001;0.41;8\n";
    let (_d, mut store, path) = setup(csv);
    let mut cfg = ReplayConfig {
        time_column: "ts".into(),
        time_format: TimeFormat::EpochS,
        delimiter: ";".into(),
        ..ReplayConfig::default()
    };
    cfg.columns.insert("GG speed".into(), "n1".into());
    cfg.columns.insert("Fuel".into(), "fuel_flow".into());
    cfg.columns.insert("Other".into(), "bearing_temp".into());
    assert!(cfg.validate().is_empty());
    let r = replay_file(&mut store, &cfg, &path, Progress::Silent).expect("replay");
    assert_eq!(r.samples_inserted, 6);
    let names: Vec<String> = store
        .tags()
        .expect("tags")
        .into_iter()
        .map(|t| t.name)
        .collect();
    assert!(names.contains(&"n1_rpm".to_string()));
    assert!(names.contains(&"fuel_kg_s".to_string()));
    assert!(names.contains(&"bearing_temp".to_string()));
}

const MALFORMED: &str = "time,n1_rpm,fuel_kg_s\n\
    2024-03-01T00:00:00Z,1,0.1\n\
    2024-03-01T00:00:01Z,2\n\
    2024-03-01T00:00:02Z,abc,0.1\n\
    not-a-time,4,0.1\n\
    2024-03-01T00:00:03Z,5,0.1\n\
    2024-03-01T00:00:03Z,6,0.1\n\
    2024-03-01T00:00:02Z,7,0.1\n\
    2024-03-01T00:00:04Z,8,inf\n\
    2024-03-01T00:00:05Z,9,0.1\n\
    2024-03-01T00:00:06Z,10";

#[test]
fn malformed_rows_are_reported_by_line_and_skipped() {
    let (_d, mut store, path) = setup(MALFORMED);
    let r = replay_file(
        &mut store,
        &ReplayConfig::default(),
        &path,
        Progress::Silent,
    )
    .expect("replay");
    // Issue 12 #3 changed this test: a bad cell ('abc' on line 4, 'inf' on line 9) no longer
    // discards its row. The cell is stored with quality `bad`, the row's good cell is kept,
    // and the cell is listed in `bad_cells` (it used to be a malformed row).
    let lines: Vec<u64> = r.malformed.iter().map(|m| m.line).collect();
    assert_eq!(lines, vec![3, 5, 7, 8, 11], "{:#?}", r.malformed);
    assert!(r.malformed[0].reason.contains("expected 3 fields, found 2"));
    assert!(r.malformed[1].reason.contains("not-a-time"));
    assert!(r.malformed[2].reason.contains("duplicate time"));
    assert!(r.malformed[3].reason.contains("goes backwards"));
    // The truncated last line (no newline, missing field) is malformed too.
    assert!(r.malformed[4].reason.contains("expected 3 fields"));
    let bad: Vec<u64> = r.bad_cells.iter().map(|m| m.line).collect();
    assert_eq!(bad, vec![4, 9], "{:#?}", r.bad_cells);
    assert!(r.bad_cells[0].reason.contains("'abc' is not a number"));
    assert!(r.bad_cells[1].reason.contains("finite"));
    assert_eq!(r.rows_read, 10);
    assert_eq!(r.rows_malformed, 5);
    assert_eq!(
        r.samples_inserted, 10,
        "both cells of lines 2, 4, 6, 9 and 10"
    );
    assert_eq!((r.quality.good, r.quality.bad), (8, 2));
    let n1 = store.tag_for_signal(Signal::N1).expect("q").expect("n1");
    let q: i64 = store
        .conn()
        .query_row(
            "SELECT quality FROM samples WHERE tag_id = ?1 AND t_ms = ?2",
            rusqlite::params![n1.id, 1_709_251_202_000_i64],
            |r| r.get(0),
        )
        .expect("abc cell stored");
    assert_eq!(q, Quality::Bad.code() as i64);
}

#[test]
fn stop_policy_names_the_line_and_keeps_what_came_before() {
    let (_d, mut store, path) = setup(MALFORMED);
    let cfg = ReplayConfig {
        on_malformed: OnMalformed::Stop,
        ..ReplayConfig::default()
    };
    let err = replay_file(&mut store, &cfg, &path, Progress::Silent).expect_err("must stop");
    match &err {
        ReplayError::Malformed {
            line, committed, ..
        } => {
            assert_eq!(*line, 3);
            assert_eq!(*committed, 2);
        }
        other => panic!("unexpected error {other}"),
    }
    assert!(err.to_string().contains("line 3"));
    assert_eq!(store.sample_count().expect("count"), 2);
}

#[test]
fn max_reported_limits_the_list_not_the_count() {
    let mut csv = String::from("time,n1_rpm\n");
    for i in 0..50 {
        csv.push_str(&format!("{},x\n", 1000 + i));
    }
    let (_d, mut store, path) = setup(&csv);
    let cfg = ReplayConfig {
        time_format: TimeFormat::EpochS,
        max_reported: 5,
        ..ReplayConfig::default()
    };
    let r = replay_file(&mut store, &cfg, &path, Progress::Silent).expect("replay");
    assert_eq!(r.rows_malformed, 50);
    assert_eq!(r.malformed.len(), 5);
}

#[test]
fn gaps_in_the_log_are_recorded_once() {
    let csv = "time,n1_rpm\n0,1\n1,1\n2,1\n60,1\n61,1\n";
    let (_d, mut store, path) = setup(csv);
    let cfg = ReplayConfig {
        time_format: TimeFormat::EpochS,
        ..ReplayConfig::default()
    };
    let r = replay_file(&mut store, &cfg, &path, Progress::Silent).expect("replay");
    assert_eq!(r.gaps_recorded, 1);
    replay_file(&mut store, &cfg, &path, Progress::Silent).expect("replay");
    let gaps = store.gaps_between(0, 100_000).expect("gaps");
    assert_eq!(gaps.len(), 1);
    assert_eq!((gaps[0].start_ms, gaps[0].end_ms), (2000, 60_000));
}

#[test]
fn config_problems_name_their_keys() {
    let mut cfg = ReplayConfig {
        delimiter: ";;".into(),
        time_column: String::new(),
        transaction_samples: 0,
        ..ReplayConfig::default()
    };
    cfg.columns.insert("a".into(), "n1".into());
    cfg.columns.insert("b".into(), "n1_rpm".into());
    let keys: Vec<String> = cfg.validate().into_iter().map(|p| p.key).collect();
    for k in [
        "replay.delimiter",
        "replay.time_column",
        "replay.transaction_samples",
        "replay.columns.b",
    ] {
        assert!(keys.contains(&k.to_string()), "{k} missing from {keys:?}");
    }
    let parsed: Result<ReplayConfig, _> = toml::from_str("time_colum = \"t\"");
    assert!(parsed.is_err(), "unknown keys are rejected");
    let parsed: ReplayConfig = toml::from_str(
        "on_malformed = \"stop\"\ntime_format = \"epoch_ms\"\n[columns]\nN1 = \"n1\"",
    )
    .expect("parse");
    assert_eq!(parsed.on_malformed, OnMalformed::Stop);
    assert_eq!(parsed.columns.get("N1").map(String::as_str), Some("n1"));
}

#[test]
fn missing_columns_are_clear_errors() {
    let (_d, mut store, path) = setup("when,n1_rpm\n1,2\n");
    let err = replay_file(
        &mut store,
        &ReplayConfig::default(),
        &path,
        Progress::Silent,
    )
    .expect_err("no time column");
    assert!(err.to_string().contains("column 'time' not found"), "{err}");
    let (_d2, mut store2, path2) = setup("time,foo\n2024-01-01,2\n");
    let err = replay_file(
        &mut store2,
        &ReplayConfig::default(),
        &path2,
        Progress::Silent,
    )
    .expect_err("no data columns");
    assert!(matches!(err, ReplayError::NoColumns { .. }));
}

#[test]
fn crlf_file_reports_the_right_line() {
    // Regression (issue 12 #9): with CRLF line ends every line number was one too low.
    let csv = "time,n1_rpm\r\n2024-03-01T00:00:00Z,1\r\n2024-03-01T00:00:01Z,abc\r\n\
               2024-03-01T00:00:02Z,\"3\"\r\n";
    let (_d, mut store, path) = setup(csv);
    let r = replay_file(
        &mut store,
        &ReplayConfig::default(),
        &path,
        Progress::Silent,
    )
    .expect("replay");
    let lines: Vec<u64> = r.malformed.iter().map(|m| m.line).collect();
    assert_eq!(lines, vec![3], "{:#?}", r.malformed);
    assert_eq!(r.samples_inserted, 2);
}

#[test]
fn plan_names_ignored_columns_and_needs_no_database() {
    // Regression (issue 11): columns not named after signals were dropped without a word.
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("log.csv");
    std::fs::write(
        &path,
        "time,GG speed,power_mw,Fuel\n2024-03-01T00:00:00Z,1,2,3\n",
    )
    .expect("write");
    let plan = plan_columns(&ReplayConfig::default(), &path).expect("plan");
    assert_eq!(
        plan.ignored,
        vec!["GG speed".to_string(), "Fuel".to_string()]
    );
    assert!(plan.feeds_tag("power_mw"));
    assert!(!plan.feeds_tag("n1_rpm"));
    std::fs::write(&path, "time,GG speed\n2024-03-01T00:00:00Z,1\n").expect("write");
    let err = plan_columns(&ReplayConfig::default(), &path).expect_err("nothing to replay");
    assert!(err.to_string().contains("ignored: GG speed"), "{err}");
    let missing = plan_columns(&ReplayConfig::default(), &dir.path().join("nope.csv"));
    assert!(matches!(missing, Err(ReplayError::Io { .. })));
}

#[test]
fn a_row_dated_far_in_the_future_is_reported_not_stored() {
    // Regression (issue 12 #1): one row dated +1000 years made every later row "go backwards":
    // they were dropped, and the replay still said all was well.
    let csv = "time,n1_rpm\n\
               2024-03-01T00:00:00Z,1\n\
               3024-03-01T00:00:01Z,2\n\
               2024-03-01T00:00:02Z,3\n\
               2024-03-01T00:00:01Z,4\n\
               2024-03-01T00:00:03Z,5\n";
    let (_d, mut store, path) = setup(csv);
    let r = replay_file(
        &mut store,
        &ReplayConfig::default(),
        &path,
        Progress::Silent,
    )
    .expect("replay");
    assert_eq!(r.samples_inserted, 3, "{r:#?}");
    assert_eq!(r.rows_implausible_time, 1);
    assert_eq!(r.rows_out_of_order, 1);
    assert_eq!(r.rows_malformed, 2);
    let lines: Vec<u64> = r.malformed.iter().map(|m| m.line).collect();
    assert_eq!(lines, vec![3, 5]);
    assert!(
        r.malformed[0].reason.contains("implausible"),
        "{:?}",
        r.malformed
    );
    assert_eq!(r.last_t_ms, Some(1_709_251_203_000));
}

/// Issue 12 #3: implausible values are stored flagged, never as good, and counted.
/// The stored value and quality code of `tag` at second `t` of 2024-03-01 (UTC).
fn stored_at(store: &Store, tag: &str, t: i64) -> (f64, i64) {
    store
        .conn()
        .query_row(
            "SELECT s.value, s.quality FROM samples s JOIN tags t ON t.id = s.tag_id
             WHERE t.name = ?1 AND s.t_ms = ?2",
            rusqlite::params![tag, 1_709_251_200_000_i64 + 1000 * t],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .expect("sample")
}

/// A log in the plant's units (°C, bar, kg/h, kW, a GG speed in Hz; wide and long layouts) is
/// stored in the model's units once `[replay.units]` states them, and judged after conversion
/// (every value good); a unit of the wrong kind or an unknown signal is a config problem
/// naming its key.
#[test]
fn stated_units_are_converted_before_they_are_judged_and_stored() {
    let cfg: ReplayConfig = toml::from_str(
        "[columns]\nNGG = \"n1\"\nCDT = \"t2_k\"\nCDP = \"p2_kpa\"\nFuel = \"fuel_flow\"\n\
         Load = \"power_mw\"\n[units]\nN1 = \"Hz\"\nt2_k = \"degC\"\np2_kpa = \"bara\"\n\
         fuel_kg_s = \"kg/h\"\npower_mw = \"kW\"",
    )
    .expect("parse");
    assert!(cfg.validate().is_empty(), "{:?}", cfg.validate());
    let wide = "time,NGG,CDT,CDP,Fuel,Load\n\
                2024-03-01T00:00:00Z,125,326.85,20.5,7200,30000\n\
                2024-03-01T00:00:01Z,125.5,327.85,20.6,7236,30100\n";
    let long = "time,tag,value\n\
                2024-03-01T00:00:00Z,NGG,125\n2024-03-01T00:00:00Z,CDT,326.85\n\
                2024-03-01T00:00:00Z,CDP,20.5\n2024-03-01T00:00:00Z,Fuel,7200\n\
                2024-03-01T00:00:00Z,Load,30000\n\
                2024-03-01T00:00:01Z,NGG,125.5\n2024-03-01T00:00:01Z,CDT,327.85\n\
                2024-03-01T00:00:01Z,CDP,20.6\n2024-03-01T00:00:01Z,Fuel,7236\n\
                2024-03-01T00:00:01Z,Load,30100\n";
    for csv in [wide, long] {
        let (_d, mut store, path) = setup(csv);
        let r = replay_file(&mut store, &cfg, &path, Progress::Silent).expect("replay");
        assert_eq!(r.samples_inserted, 10, "{r:?}");
        assert_eq!(
            r.quality.good, 10,
            "judged in the model's units: {:?}",
            r.quality
        );
        let v = |tag: &str, t: i64| -> f64 { stored_at(&store, tag, t).0 };
        for (tag, t, want) in [
            ("n1_rpm", 0, 7500.0),
            ("n1_rpm", 1, 7530.0),
            ("t2_k", 0, 600.0),
            ("p2_kpa", 1, 2060.0),
            ("fuel_kg_s", 0, 2.0),
            ("fuel_kg_s", 1, 2.01),
            ("power_mw", 0, 30.0),
        ] {
            assert!(
                (v(tag, t) - want).abs() < 1e-9,
                "{tag} at {t}: {}",
                v(tag, t)
            );
        }
    }
    let mut bad = cfg.clone();
    bad.units.insert("t34_k".into(), "bar".into());
    bad.units.insert("vibration".into(), "mm/s".into());
    bad.units.insert("p34_kpa".into(), "psig".into());
    bad.units.insert("p_amb_kpa".into(), "mbar".into());
    let problems = bad.validate();
    let keys: Vec<&str> = problems.iter().map(|p| p.key.as_str()).collect();
    for k in [
        "replay.units.t34_k",
        "replay.units.vibration",
        "replay.units.p34_kpa",
        "replay.units.p_amb_kpa",
    ] {
        assert!(keys.contains(&k), "{k} missing from {problems:?}");
    }
    assert!(
        problems.iter().any(|p| p.message.contains("gauge")),
        "{problems:?}"
    );
    let (_d, mut store, path) = setup(wide);
    let e = replay_file(&mut store, &bad, &path, Progress::Silent).expect_err("refused");
    assert!(e.to_string().contains("replay.units.t34_k"), "{e}");
}

/// A gas fuel metered by volume (`fuel_kg_s = "Nm3/h"`) is stored as a mass flow through the
/// engine's fuel, which the caller binds (`ReplayConfig::fuel`, from `[plant] engine_model`);
/// without one the replay is refused naming the section, never stored as a guess.
#[test]
fn a_gas_fuel_by_volume_is_stored_as_mass_with_the_engines_fuel() {
    let mut cfg: ReplayConfig = toml::from_str(
        "[columns]\nNGG = \"n1\"\nFuel = \"fuel_flow\"\n[units]\nfuel_kg_s = \"Nm3/h\"",
    )
    .expect("parse");
    assert!(cfg.validate().is_empty(), "{:?}", cfg.validate());
    let csv = "time,NGG,Fuel\n2024-03-01T00:00:00Z,7500,3600\n2024-03-01T00:00:01Z,7510,7200\n";
    let (_d, mut store, path) = setup(csv);
    let e = replay_file(&mut store, &cfg, &path, Progress::Silent).expect_err("no fuel");
    assert!(
        e.to_string().contains("replay.units") && e.to_string().contains("engine_model"),
        "{e}"
    );
    let methane = crate::thermo::Fuel::methane_with_lhv(50.0e6);
    cfg.fuel = Some(methane);
    let (_d, mut store, path) = setup(csv);
    let r = replay_file(&mut store, &cfg, &path, Progress::Silent).expect("replay");
    assert_eq!(r.quality.good, 4, "{r:?}");
    // Methane: 0.7175 kg per normal m³ (ISO 6976).
    for (t, want) in [(0, 0.7175), (1, 1.435)] {
        let v = stored_at(&store, "fuel_kg_s", t).0;
        assert!((v / want - 1.0).abs() < 5e-4, "at {t}: {v}");
    }
    let mut liquid = cfg.clone();
    liquid.fuel = Some(crate::thermo::Fuel::liquid(1.8, 300.0, None).expect("diesel"));
    let (_d, mut store, path) = setup(csv);
    let e = replay_file(&mut store, &liquid, &path, Progress::Silent).expect_err("a liquid");
    assert!(e.to_string().contains("replay.units.fuel_kg_s"), "{e}");
}

#[test]
fn implausible_values_are_flagged_not_good() {
    let csv = "time,n1_rpm,t2_k,fuel_kg_s,power_mw\n\
               2024-03-01T00:00:00Z,7600,600,2.0,31\n\
               2024-03-01T00:00:01Z,-500,1e9,-100,31\n\
               2024-03-01T00:00:02Z,7600,600,2.0,31\n\
               2024-03-01T00:00:03Z,11000,600,2.0,31\n\
               2024-03-01T00:00:04Z,7600,nan,2.0,31\n\
               2024-03-01T00:00:05Z,7600,600,2.0,31\n";
    let (_d, mut store, path) = setup(csv);
    let r = replay_file(
        &mut store,
        &ReplayConfig::default(),
        &path,
        Progress::Silent,
    )
    .expect("replay");
    assert_eq!(r.rows_malformed, 0, "{:#?}", r.malformed);
    assert_eq!(r.samples_inserted, 24);
    assert_eq!(r.quality.out_of_range, 3, "{:?}", r.quality);
    assert_eq!(r.quality.spike, 1, "{:?}", r.quality);
    assert_eq!(r.quality.bad, 1, "{:?}", r.quality);
    assert_eq!(r.quality.good, 19, "{:?}", r.quality);
    let q = |col: &str, t: i64| -> i64 { stored_at(&store, col, t).1 };
    assert_eq!(q("n1_rpm", 1), Quality::OutOfRange.code() as i64);
    assert_eq!(q("t2_k", 1), Quality::OutOfRange.code() as i64);
    assert_eq!(q("fuel_kg_s", 1), Quality::OutOfRange.code() as i64);
    assert_eq!(q("power_mw", 1), 0, "the good cell of the bad row is kept");
    assert_eq!(q("n1_rpm", 3), Quality::Spike.code() as i64);
    assert_eq!(q("t2_k", 4), Quality::Bad.code() as i64);
    assert_eq!(q("n1_rpm", 4), 0);
}

#[test]
fn quality_overrides_from_config_apply_to_replay() {
    let csv = "time,power_mw\n2024-03-01T00:00:00Z,40\n2024-03-01T00:00:01Z,50\n";
    let (_d, mut store, path) = setup(csv);
    let mut quality = crate::quality::QualityConfig::default();
    quality.limits.insert(
        "power_mw".into(),
        crate::quality::LimitOverride {
            hi: Some(45.0),
            ..Default::default()
        },
    );
    let r = replay_file_checked(
        &mut store,
        &ReplayConfig::default(),
        &quality,
        &path,
        Progress::Silent,
    )
    .expect("replay");
    assert_eq!((r.quality.good, r.quality.out_of_range), (1, 1));
}

/// A simulated, noisy start-up written as a replay log (epoch seconds), with `corrupt` applied
/// to the measured values first; replayed and scanned. Returns (outcome, start_ms, end_ms) of
/// every segment, and the replay report.
fn replay_startup(
    corrupt: impl Fn(&mut crate::engine::Trace),
) -> (Vec<(String, i64, Option<i64>)>, ReplayReport) {
    use crate::engine::sensors::MeasurementOptions;
    use crate::engine::simulation::run_scenario;
    use crate::engine::{Engine, Scenario, Trace};
    let engine = Engine::reference().expect("engine");
    let model = engine.model(&crate::health::HealthParams::default());
    let (samples, _) = run_scenario(&model, &Scenario::startup(engine.cfg())).expect("runs");
    let o = MeasurementOptions {
        lags: true,
        noise: true,
        bias: false,
        seed: 7,
    };
    let mut t = Trace::from_truth(&engine, &samples, Some(&o));
    t.t_s.iter_mut().for_each(|x| *x += 1.7e9);
    corrupt(&mut t);
    let mut csv = Vec::new();
    t.write_csv(&mut csv).expect("csv");
    let (_d, mut store, path) = setup(&String::from_utf8(csv).expect("utf8"));
    let cfg = ReplayConfig {
        time_column: "time_s".into(),
        time_format: TimeFormat::EpochS,
        ..ReplayConfig::default()
    };
    let r = replay_file(&mut store, &cfg, &path, Progress::Silent).expect("replay");
    crate::detect::scan(&mut store, &crate::detect::DetectorConfig::default()).expect("scan");
    let mut st = store
        .conn()
        .prepare("SELECT outcome, start_ms, end_ms FROM segments ORDER BY start_ms")
        .expect("prep");
    let segs = st
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .expect("q")
        .collect::<Result<Vec<_>, _>>()
        .expect("rows");
    (segs, r)
}

/// Issue 12 #3 regression, the original inputs: n1 = −500 rpm, T2 = 1e9 K, a single 1e9 rpm
/// spike and a −100 kg/s fuel value in a replayed log used to be stored as good and turn a
/// completed start into "flame_out" or "trip". Flagged now, the start is still completed, with
/// the same boundaries as the clean log.
#[test]
fn implausible_values_in_a_replayed_start_do_not_change_its_outcome() {
    let (clean, _) = replay_startup(|_| {});
    assert_eq!(clean.len(), 1, "{clean:?}");
    assert_eq!(clean[0].0, "completed");
    let n1 = Signal::N1.index();
    let (dirty, r) = replay_startup(|t| {
        let len = t.len();
        for (frac, sig, v) in [
            (0.15, n1, -500.0),
            (0.25, Signal::T2.index(), 1e9),
            (0.35, n1, 1e9),
            (0.45, Signal::FuelFlow.index(), -100.0),
            (0.55, Signal::FuelFlow.index(), -100.0),
            (0.65, n1, -500.0),
        ] {
            let k = ((len as f64 * frac) as usize).min(len - 1);
            t.measured[k][sig] = v;
        }
    });
    assert!(r.quality.out_of_range >= 6, "{:?}", r.quality);
    assert_eq!(dirty.len(), 1, "{dirty:?}");
    assert_eq!(dirty[0].0, "completed", "{dirty:?}");
    assert_eq!(dirty[0].1, clean[0].1, "same start");
}

#[test]
fn long_files_are_detected_planned_and_replayed_per_tag() {
    let csv = "Tag,time,Value,Status\n\
               n1_rpm,2024-03-01T00:00:00Z,100,Good\n\
               comment,2024-03-01T00:00:00Z,1,Good\n\
               power_mw,2024-03-01T00:00:00Z,1.5,Bad\n\
               n1_rpm,2024-03-01T00:00:01Z,200,Good\n\
               n1_rpm,2024-03-01T00:00:01Z,201,Good\n\
               power_mw,2024-03-01T00:00:01Z,2.5,\n";
    let (_d, mut store, path) = setup(csv);
    let cfg = ReplayConfig::default();
    let plan = plan_columns(&cfg, &path).expect("plan");
    assert!(plan.long.is_some());
    assert!(plan.feeds_tag("n1_rpm") && plan.feeds_tag("power_mw"));
    assert_eq!(plan.ignored, vec!["comment".to_string()]);
    let r = replay_file(&mut store, &cfg, &path, Progress::Silent).expect("replay");
    assert_eq!(r.rows_read, 6);
    assert_eq!(r.rows_out_of_order, 1, "n1 twice at 00:00:01");
    assert_eq!(r.malformed[0].line, 6);
    assert_eq!(r.samples_inserted, 4);
    assert_eq!(r.quality.bad, 1, "status Bad");
    assert_eq!(r.ignored_columns, vec!["comment".to_string()]);

    let wide = ReplayConfig {
        layout: Layout::Wide,
        ..ReplayConfig::default()
    };
    assert!(matches!(
        plan_columns(&wide, &path),
        Err(ReplayError::NoColumns { .. })
    ));
    let mapped = ReplayConfig {
        columns: [("GG_SPEED".to_string(), "n1".to_string())].into(),
        ..ReplayConfig::default()
    };
    let e = plan_columns(&mapped, &path).expect_err("tag never occurs");
    assert!(e.to_string().contains("GG_SPEED"), "{e}");
}

/// A 20-hour log at 10 s over four chunk windows, with a gap, a text cell, an implausible
/// value, a spike and a row out of order: what the bad-value policy and the gap detector meet.
fn awkward_log() -> String {
    let t0 = 1_709_251_200i64; // 2024-03-01T00:00:00Z, a chunk-window boundary.
    let mut csv = String::from("time,n1_rpm,fuel_kg_s,power_mw\n");
    for i in 0..7200i64 {
        if (3000..3010).contains(&i) {
            continue; // 100 s without rows: a gap.
        }
        let t = t0 + i * 10;
        let n1 = if i == 4000 {
            "n/a".to_string()
        } else if i == 4500 {
            "-5000".to_string()
        } else if i == 5000 {
            "9500".to_string()
        } else {
            format!("{:.3}", 7000.0 + (i as f64 * 0.01).sin() * 50.0)
        };
        csv.push_str(&format!(
            "{t},{n1},{:.4},{:.3}\n",
            1.0 + (i as f64 * 0.003).cos() * 0.1,
            20.0 + (i as f64 * 0.002).sin()
        ));
        if i == 6000 {
            csv.push_str(&format!("{},7000,1,20\n", t - 5));
        }
    }
    csv
}

/// Every stored sample (time, value bits, quality) of every tag, through the store's read path.
fn stored(store: &Store) -> Vec<(String, i64, u64, i64)> {
    let mut out = Vec::new();
    for tag in store.tags().expect("tags") {
        for s in store
            .tag_samples_between(tag.id, i64::MIN, i64::MAX)
            .expect("read")
        {
            out.push((tag.name.clone(), s.t_ms, s.value.to_bits(), s.quality));
        }
    }
    out
}

#[test]
fn replay_into_the_archive_stores_what_the_hot_replay_stores() {
    let csv = awkward_log();
    let cfg_hot = ReplayConfig {
        time_format: TimeFormat::EpochS,
        ..ReplayConfig::default()
    };
    let cfg_arc = ReplayConfig {
        archive: true,
        ..cfg_hot.clone()
    };
    let (_a, mut hot, path) = setup(&csv);
    let (_b, mut arc, _) = setup("");
    let r_hot = replay_file(&mut hot, &cfg_hot, &path, Progress::Silent).expect("hot");
    let r_arc = replay_file(&mut arc, &cfg_arc, &path, Progress::Silent).expect("archive");
    // The same report, but for the chunks.
    assert_eq!(r_hot.chunks_archived, 0);
    assert_eq!(
        ReplayReport {
            chunks_archived: 0,
            elapsed_s: 0.0,
            ..r_arc.clone()
        },
        ReplayReport {
            elapsed_s: 0.0,
            ..r_hot.clone()
        }
    );
    assert!(r_hot.quality.bad >= 1 && r_hot.quality.out_of_range >= 1);
    assert_eq!((r_hot.rows_out_of_order, r_hot.gaps_recorded), (1, 1));
    // The same samples, bit for bit, with the same quality codes, and the same gaps.
    let all = stored(&hot);
    assert_eq!(all.len() as u64, r_hot.samples_inserted);
    assert!(stored(&arc) == all, "archive replay reads back differently");
    assert_eq!(
        arc.gaps_between(i64::MIN, i64::MAX).expect("gaps"),
        hot.gaps_between(i64::MIN, i64::MAX).expect("gaps")
    );
    // None of it hot; one chunk per tag and window (20 h from a boundary: 4 windows).
    let hot_rows: i64 = arc
        .conn()
        .query_row("SELECT COUNT(*) FROM samples", [], |r| r.get(0))
        .expect("count");
    assert_eq!(hot_rows, 0);
    assert_eq!(r_arc.chunks_archived, 3 * 4, "{r_arc:?}");
    assert_eq!(arc.sample_count().expect("count") as usize, all.len());

    // Again: nothing new. Then a log that overlaps the end and goes on: only the new rows.
    let again = replay_file(&mut arc, &cfg_arc, &path, Progress::Silent).expect("again");
    assert_eq!((again.samples_inserted, again.chunks_archived), (0, 0));
    assert_eq!(again.samples_present, r_hot.samples_inserted);
    let more: String = std::iter::once("time,n1_rpm,fuel_kg_s,power_mw\n".to_string())
        .chain((7100..7300i64).map(|i| format!("{},7000,1,20\n", 1_709_251_200 + i * 10)))
        .collect();
    let more_path = path.with_file_name("more.csv");
    std::fs::write(&more_path, more).expect("write");
    let m_hot = replay_file(&mut hot, &cfg_hot, &more_path, Progress::Silent).expect("hot");
    let m_arc = replay_file(&mut arc, &cfg_arc, &more_path, Progress::Silent).expect("arc");
    assert_eq!(m_arc.samples_inserted, 3 * 100);
    assert_eq!(
        (m_arc.samples_inserted, m_arc.samples_present),
        (m_hot.samples_inserted, m_hot.samples_present)
    );
    assert!(stored(&arc) == stored(&hot));

    // Small transactions split the chunks, never the contents.
    let (_c, mut small, _) = setup("");
    let cfg_small = ReplayConfig {
        transaction_samples: 997,
        ..cfg_arc.clone()
    };
    let r_small = replay_file(&mut small, &cfg_small, &path, Progress::Silent).expect("small");
    assert!(r_small.chunks_archived > r_arc.chunks_archived);
    assert!(stored(&small) == all);
    assert_eq!(small.integrity_check().ok().as_deref(), Some("ok"));
}
