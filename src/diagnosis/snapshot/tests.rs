//! Unit tests of snapshot diagnosis (the parent module): reading, the fit on the model's own
//! rows, reduced instrument sets, the inputs' noise and the verdict's words.

use super::*;
use crate::engine::trace::NSIG;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Snapshot rows from the steady model itself at `loads_mw`, with instrument noise.
fn snapshot_csv(engine: &Engine, health: &HealthParams, loads_mw: &[f64], seed: u64) -> String {
    rows_csv(engine, |_| *health, loads_mw, Some(seed))
}

/// Snapshot rows from the steady model at `loads_mw`, row `k` at `health(k)`, with instrument
/// noise drawn from `seed` (none without).
fn rows_csv(
    engine: &Engine,
    health: impl Fn(usize) -> HealthParams,
    loads_mw: &[f64],
    seed: Option<u64>,
) -> String {
    let cfg = engine.cfg();
    let sigs = [
        Signal::T1,
        Signal::P1,
        Signal::N1,
        Signal::N2,
        Signal::T2,
        Signal::P2,
        Signal::T34,
        Signal::P34,
        Signal::FuelFlow,
        Signal::Power,
    ];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed.unwrap_or(0));
    let mut csv = String::from("test");
    for s in sigs {
        csv.push(',');
        csv.push_str(s.column());
    }
    csv.push('\n');
    for (k, &load) in loads_mw.iter().enumerate() {
        let t_amb = 283.0 + 3.0 * k as f64;
        let p_amb = 100.2 - 0.3 * k as f64;
        let inputs = SteadyInputs {
            t_amb_k: t_amb,
            p_amb_kpa: p_amb,
            n2_rpm: cfg.design.pt_speed_rpm,
            demand: Demand::PowerMw(load),
        };
        let m = engine.model_at(&health(k), t_amb, p_amb);
        let sp = solve(&m, &inputs, None).expect("steady");
        let wf = sp.stations.fuel_kg_s;
        let mut v = [f64::NAN; NSIG];
        for s in Signal::ALL {
            v[s.index()] = crate::engine::gas_path::signal_value(&sp.stations, s);
        }
        v[Signal::T1.index()] = t_amb;
        v[Signal::FuelFlow.index()] = wf;
        csv.push_str(&format!("T{}", k / 4));
        for s in sigs {
            let x = v[s.index()];
            let sd = noise_sigma(&cfg.sensors, s, x) / 5.0; // an average of 25 samples
            let noisy = if seed.is_some()
                && sd > 0.0
                && !matches!(s, Signal::T1 | Signal::FuelFlow | Signal::N2)
            {
                x + Normal::new(0.0, sd).expect("normal").sample(&mut rng)
            } else {
                x
            };
            csv.push_str(&format!(",{noisy}"));
        }
        csv.push('\n');
    }
    csv
}

#[test]
fn fit_summary_speaks_of_snapshots_not_phases() {
    assert_eq!(
        snapshot_words("normalised residual 3.10, spread over signals and phases"),
        "normalised residual 3.10, spread over signals and snapshots"
    );
    let phase = crate::signals::Phase::ALL[0];
    assert_eq!(
        snapshot_words(&format!("largest: t34_k during {phase}: offset (4.0 σ)")),
        "largest: t34_k over the snapshots: offset (4.0 σ)"
    );
}

#[test]
fn reader_names_line_and_column_of_a_bad_cell() {
    let csv = "t1_k,n2_rpm,fuel_kg_s,p2_kpa\n288,3000,1.2,1500\n288,3000,abc,1500\n";
    let e = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect_err("bad cell");
    let text = e.to_string();
    assert!(
        text.contains("line 3") && text.contains("fuel_kg_s"),
        "{text}"
    );
    let csv = "t1_k,n2_rpm,p2_kpa\n288,3000,1500\n";
    let e = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect_err("no fuel");
    assert!(e.to_string().contains("fuel_kg_s"), "{e}");
    let csv = "t1_k,n2_rpm,fuel_kg_s\n288,3000,1.2\n";
    let e = read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test_id"))
        .expect_err("no group column");
    assert!(e.to_string().contains("test_id"), "{e}");
    let csv = "t1_k,n2_rpm,fuel_kg_s\n2880,3000,1.2\n";
    let e = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect_err("range");
    assert!(e.to_string().contains("plausible"), "{e}");
    // An ambient pressure in another unit names it, and what to state.
    for (v, unit) in [("1.013", "bar"), ("1013", "mbar"), ("101300", "Pa")] {
        let csv = format!("t1_k,p_amb_kpa,n2_rpm,fuel_kg_s\n288,{v},3000,1.2\n");
        let e = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect_err("unit");
        let text = e.to_string();
        assert!(
            text.contains(&format!(
                "looks like {unit}: state `--units p_amb_kpa={unit}`"
            )),
            "{v}: {text}"
        );
    }
}

#[test]
fn grouped_snapshots_recover_health_per_group() {
    let engine = Engine::reference().expect("engine");
    let truth = HealthParams::from_array([-2.0, -1.5, 1.0, -1.0, 0.5, -0.8]);
    let loads = [12.0, 17.0, 22.0, 27.0, 14.0, 19.0, 24.0, 29.0];
    let csv = snapshot_csv(&engine, &truth, &loads, 3);
    let rows = read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
    assert_eq!(rows.len(), 8);
    assert!(rows.iter().all(|r| r.p_amb_kpa.is_none()));
    let cfg = DiagnosisConfig {
        max_model_runs: 1500,
        ..DiagnosisConfig::default()
    };
    let report = diagnose_snapshots(&engine, &rows, &cfg).expect("diagnosis");
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    assert_eq!(report.groups.len(), 2);
    assert_eq!(report.groups[0].group, "T0");
    for g in &report.groups {
        assert_eq!(g.lines.len(), 4);
        let est = g.result.health.to_array();
        for (i, (&e, &t)) in est.iter().zip(truth.to_array().iter()).enumerate() {
            assert!(
                (e - t).abs() < 0.3,
                "group {} parameter {i}: {e:.3} vs truth {t:.3}",
                g.group
            );
        }
    }
    // One row alone: six readings for six parameters, refused with the reason.
    let single = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect("rows");
    let report = diagnose_snapshots(&engine, &single[..1], &cfg).expect("runs");
    assert!(report.groups.is_empty());
    assert!(
        report.failed[0].reason.contains("more averaged values"),
        "{}",
        report.failed[0].reason
    );
}

/// The inputs' noise widens the read's σ and leaves the read itself as the fit with the
/// inputs as given makes it: the same rows on a file whose fuel meter, T1 and n2 have no
/// noise read the same health, with a narrower σ; `--noisy-inputs` fits under that noise
/// instead and says so.
#[test]
fn the_inputs_noise_is_in_the_sigma_not_in_the_read() {
    let engine = Engine::reference().expect("engine");
    let truth = HealthParams::from_array([2.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
    let loads = [12.0, 15.0, 18.0, 21.0, 24.0, 27.0, 29.0, 31.0];
    // Every row one group (the helper deals them into T0 and T1 by four).
    let csv = snapshot_csv(&engine, &truth, &loads, 11).replace("\nT1,", "\nT0,");
    let rows = read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
    let mut quiet_cfg = engine.cfg().clone();
    for ch in [
        &mut quiet_cfg.sensors.fuel,
        &mut quiet_cfg.sensors.t1,
        &mut quiet_cfg.sensors.n2,
    ] {
        ch.noise_abs = 0.0;
        ch.noise_rel = 0.0;
    }
    let quiet = Engine::new(quiet_cfg).expect("engine");
    let cfg = DiagnosisConfig {
        max_model_runs: 1500,
        threads: Some(1),
        ..DiagnosisConfig::default()
    };
    let read = |e: &Engine, cfg: &DiagnosisConfig| only_group(e, &rows, cfg);
    let noisy = read(&engine, &cfg);
    let exact = read(&quiet, &cfg);
    let h = |g: &SnapshotGroup| g.result.health.to_array();
    for (a, b) in h(&noisy).iter().zip(h(&exact)) {
        assert!((a - b).abs() < 1e-9, "{:?} vs {:?}", h(&noisy), h(&exact));
    }
    for name in ["D_GC", "D_EC", "D_GT", "D_ET"] {
        let (wide, narrow) = (noisy.result.sigma[name], exact.result.sigma[name]);
        eprintln!("{name}: σ {wide:.3} with the inputs' noise, {narrow:.3} without");
        assert!(wide > 1.2 * narrow, "{name}: σ {wide:.3} vs {narrow:.3}");
    }
    assert!(noisy
        .assumptions
        .iter()
        .any(|a| a.contains("taken as given in the fit")));
    let fitted = read(
        &engine,
        &DiagnosisConfig {
            snapshot_input_noise: true,
            ..cfg.clone()
        },
    );
    assert!(fitted
        .assumptions
        .iter()
        .any(|a| a.contains("noise of the measured inputs")));
    assert!(h(&fitted)
        .iter()
        .zip(h(&noisy))
        .any(|(a, b)| (a - b).abs() > 1e-6));
}

/// The first group of `rows` diagnosed on `engine`, none failed.
fn only_group(engine: &Engine, rows: &[Snapshot], cfg: &DiagnosisConfig) -> SnapshotGroup {
    let report = diagnose_snapshots(engine, rows, cfg).expect("diagnosis");
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    report.groups[0].clone()
}

/// `csv` with each row's fuel flow scaled by `factor(row)`.
fn fuel_scaled(csv: &str, factor: impl Fn(usize) -> f64) -> String {
    let mut lines = csv.lines();
    let header = lines.next().expect("header");
    let col = header
        .split(',')
        .position(|c| c == Signal::FuelFlow.column())
        .expect("fuel column");
    let mut out = format!("{header}\n");
    for (k, line) in lines.enumerate() {
        let cells: Vec<String> = line
            .split(',')
            .enumerate()
            .map(|(i, c)| {
                if i == col {
                    (c.parse::<f64>().expect("fuel") * factor(k)).to_string()
                } else {
                    c.to_string()
                }
            })
            .collect();
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

/// Residuals that are the rows' fuel readings scattered by their meter's noise: the
/// verdict, with the inputs taken as given, is not `good`, and its summary says that under
/// the inputs' noise they are (pointing at `--noisy-inputs`); the same meter reading 3 %
/// high on every row is a bias the health absorbs (D_GT at its limit, `suspect` with small
/// residuals): no such words.
#[test]
fn a_verdict_the_inputs_noise_explains_says_so_and_a_meter_bias_does_not() {
    let engine = Engine::reference().expect("engine");
    let truth = HealthParams::from_array([2.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
    let loads = [12.0, 15.0, 18.0, 21.0, 24.0, 27.0, 29.0, 31.0];
    let csv = snapshot_csv(&engine, &truth, &loads, 5).replace("\nT1,", "\nT0,");
    let sd_rel = noise_sigma(&engine.cfg().sensors, Signal::FuelFlow, 1.5) / 1.5;
    let cfg = DiagnosisConfig {
        max_model_runs: 1500,
        threads: Some(1),
        ..DiagnosisConfig::default()
    };
    let read = |csv: &str| {
        let rows = read_snapshots(csv.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
        only_group(&engine, &rows, &cfg)
    };
    let scattered = read(&fuel_scaled(&csv, |k| {
        1.0 + SCATTER_SIGMAS * sd_rel * if k % 2 == 0 { 1.0 } else { -1.0 }
    }));
    let q = &scattered.result.fit_quality;
    eprintln!(
        "scattered: {:?} {:.2}, under the inputs' noise {:?}: {}",
        q.verdict, q.normalised_residual, scattered.level_under_input_noise, q.summary
    );
    assert_ne!(q.verdict, Verdict::Good);
    let level = scattered.level_under_input_noise.expect("judged");
    assert!(level <= q.thresholds.good_level, "{level}");
    assert!(q.summary.contains("--noisy-inputs"), "{}", q.summary);

    let biased = read(&fuel_scaled(&csv, |_| 1.03));
    let b = &biased.result.fit_quality;
    eprintln!(
        "biased: {:?} {:.2}, under the inputs' noise {:?}: {}",
        b.verdict, b.normalised_residual, biased.level_under_input_noise, b.summary
    );
    assert!(!b.summary.contains("--noisy-inputs"), "{}", b.summary);
    assert_eq!(biased.level_under_input_noise, None);
}

/// How many of its one-reading σ each row's fuel reading is off by, alternately.
const SCATTER_SIGMAS: f64 = 2.0;

#[test]
fn reduced_instrument_sets_say_what_they_separate_and_estimate_it() {
    let engine = Engine::reference().expect("engine");
    let truth = HealthParams::from_array([-2.0, -1.5, 1.0, -1.0, 0.5, -0.8]).to_array();
    let loads = [12.0, 15.0, 18.0, 21.0, 24.0, 27.0, 29.0, 31.0];
    let csv = snapshot_csv(&engine, &HealthParams::from_array(truth), &loads, 9);
    let all = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect("rows");
    let cfg = DiagnosisConfig {
        max_model_runs: 1500,
        ..DiagnosisConfig::default()
    };
    for dropped in [
        vec![Signal::T34, Signal::P34],
        vec![Signal::P34],
        vec![Signal::P2],
    ] {
        let rows: Vec<Snapshot> = all
            .iter()
            .map(|r| Snapshot {
                group: "all".into(),
                values: r
                    .values
                    .iter()
                    .filter(|(s, _)| !dropped.contains(s))
                    .copied()
                    .collect(),
                ..r.clone()
            })
            .collect();
        let report = diagnose_snapshots(&engine, &rows, &cfg).expect("diagnosis");
        assert!(report.failed.is_empty(), "{dropped:?}: {:?}", report.failed);
        let r = &report.groups[0].result;
        let sep = &r.separability;
        assert!(!sep.statement.is_empty());
        let est = r.health.to_array();
        let at = |name: &str| {
            crate::health::HEALTH_NAMES
                .iter()
                .position(|n| *n == name)
                .expect("a health name")
        };
        // What it calls separable is estimated within 0.5 points ...
        for name in &sep.separable {
            let i = at(name);
            assert!(
                (est[i] - truth[i]).abs() < 0.5,
                "{dropped:?}: {name} {:.2} vs {:.2} ({})",
                est[i],
                truth[i],
                sep.statement
            );
        }
        // ... and so is every combination it says the data determine.
        for g in &sep.confounded {
            for c in &g.determined {
                let t: f64 = c.weights.iter().map(|(n, w)| w * truth[at(n)]).sum();
                assert!((c.value - t).abs() < 0.5, "{dropped:?}: {c:?} vs {t:.2}");
            }
        }
        // Without the HPT-exit readings the hot-end parameters cannot all be separated.
        if dropped.contains(&Signal::P34) {
            assert!(
                !sep.confounded.is_empty() || !sep.not_identifiable.is_empty(),
                "{dropped:?}: {}",
                sep.statement
            );
        }
    }
}

/// An adapted file's unknown compressor slopes off the healthy line (`[adaptation.offline_shape]`)
/// widen a read's σ by about what a unit whose speed lines are steeper by that 1σ does to the
/// read, and leave the read itself and a healthy unit's σ alone.
#[test]
fn the_compressor_shape_off_the_line_widens_the_sigma_as_a_steeper_unit_moves_the_read() {
    use crate::engine::config::{
        AdaptationConfig, ComponentCurves, EngineConfig, OfflineShape,
        DEFAULT_EFFICIENCY_SLOPE_SIGMA,
    };
    // The model's own maps marked as adapted (a zero curve): the defaults apply, or none.
    let adapted = |shape: Option<OfflineShape>| {
        let mut cfg = EngineConfig::reference();
        cfg.adaptation = Some(AdaptationConfig {
            compressor: Some(ComponentCurves {
                speed_knots: vec![0.8],
                efficiency: vec![0.0],
                ..Default::default()
            }),
            offline_shape: shape,
            ..Default::default()
        });
        Engine::new(cfg).expect("adapted engine")
    };
    let with = adapted(None);
    let without = adapted(Some(OfflineShape::NONE));
    let loads = [12.0, 15.0, 18.0, 21.0, 24.0, 27.0, 29.0, 31.0];
    let cfg = DiagnosisConfig {
        max_model_runs: 1500,
        threads: Some(1),
        ..DiagnosisConfig::default()
    };
    let read = |e: &Engine, csv: &str| {
        let one_group = csv.replace("\nT1,", "\nT0,");
        let rows =
            read_snapshots(one_group.as_bytes(), &HashMap::new(), Some("test")).expect("rows");
        only_group(e, &rows, &cfg)
    };
    let d_ec = |g: &SnapshotGroup| (g.result.health.D_EC, g.result.sigma["D_EC"]);

    // A healthy unit sits on the line: nothing added.
    let healthy = rows_csv(&with, |_| HealthParams::default(), &loads, Some(5));
    let (on, off) = (read(&with, &healthy), read(&without, &healthy));
    let (h_on, h_off) = (on.result.health.to_array(), off.result.health.to_array());
    assert!(h_on.iter().zip(&h_off).all(|(a, b)| (a - b).abs() < 1e-9));
    assert!(
        (d_ec(&on).1 / d_ec(&off).1 - 1.0).abs() < 0.02,
        "healthy D_EC σ {:.3} vs {:.3}",
        d_ec(&on).1,
        d_ec(&off).1
    );

    // Fouled: the compressor runs towards choke, and its efficiency's σ widens.
    let fouled = HealthParams::from_array([3.0, 1.2, 0.0, 0.0, 0.0, 0.0]);
    let rows = rows_csv(&with, |_| fouled, &loads, None);
    let (on, off) = (read(&with, &rows), read(&without, &rows));
    let added = (d_ec(&on).1.powi(2) - d_ec(&off).1.powi(2)).sqrt();
    assert!((d_ec(&on).0 - d_ec(&off).0).abs() < 1e-9);
    assert!((d_ec(&on).0 - 1.2).abs() < 0.05, "{:?}", d_ec(&on));
    assert!(
        added > 0.2,
        "D_EC σ {:.3} vs {:.3}",
        d_ec(&on).1,
        d_ec(&off).1
    );

    // A unit whose efficiency rises along its speed lines by the σ more than the map's: at each
    // row its efficiency is higher by σ·Δ of itself, Δ the row's log pressure ratio above the
    // healthy line at its GG speed. Its read misses the truth by about what the σ added.
    let delta = |k: usize| {
        let (t_amb, p_amb) = (283.0 + 3.0 * k as f64, 100.2 - 0.3 * k as f64);
        let inputs = SteadyInputs {
            t_amb_k: t_amb,
            p_amb_kpa: p_amb,
            n2_rpm: with.cfg().design.pt_speed_rpm,
            demand: Demand::PowerMw(loads[k]),
        };
        let at = solve(&with.model_at(&fouled, t_amb, p_amb), &inputs, None).expect("fouled");
        let line_inputs = SteadyInputs {
            demand: Demand::N1Rpm(at.n1_rpm),
            ..inputs
        };
        let line = solve(
            &with.model_at(&HealthParams::default(), t_amb, p_amb),
            &line_inputs,
            None,
        )
        .expect("healthy line");
        (at.pressure_ratio / line.pressure_ratio).ln()
    };
    let deltas: Vec<f64> = (0..loads.len()).map(delta).collect();
    assert!(
        deltas.iter().all(|d| *d < -0.005),
        "towards choke: {deltas:?}"
    );
    let steeper = rows_csv(
        &with,
        |k| {
            let mut h = fouled;
            h.D_EC -= 100.0 * DEFAULT_EFFICIENCY_SLOPE_SIGMA * deltas[k];
            h
        },
        &loads,
        None,
    );
    let miss = d_ec(&read(&without, &steeper)).0 - 1.2;
    eprintln!(
        "D_EC σ {:.3} without, {:.3} with the off-line shape (added {added:.3}); a unit steeper \
         by that σ read {miss:+.3} off",
        d_ec(&off).1,
        d_ec(&on).1
    );
    assert!(
        miss.abs() > 0.8 * added && miss.abs() < 1.25 * added,
        "miss {miss:.3} vs added σ {added:.3}"
    );
}
