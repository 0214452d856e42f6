//! Synthetic steady snapshots with known truth: the rows a plant historian would export, made
//! with the steady model of a given engine and health plus instrument noise. Used by the
//! calibration twin test and to write `examples/baseline_snapshots.csv`
//! (`cargo run --example baseline_snapshots`) and the foreign generator unit's baseline.
//!
//! What it is for: one CSV text in the snapshot layout (`diagnosis::snapshot`), canonical
//! column names, with T1, ambient pressure, n2 and fuel flow as exact inputs and the other
//! signals noisy (1σ = the engine file's instrument noise divided by `averaging` — a row is
//! the mean of that many squared samples' worth). What it must not do: I/O; deterministic for a
//! seed.

use crate::diagnosis::steady::steady_reading;
use crate::engine::load;
use crate::engine::sensors::noise_sigma;
use crate::engine::steady::{Demand, SteadyInputs};
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::signals::Signal;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// One operating point to write.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatingPoint {
    pub t_amb_k: f64,
    pub p_amb_kpa: f64,
    pub power_mw: f64,
}

/// The compared signals written (besides the inputs T1, ambient pressure, n2 and fuel).
pub const WRITTEN: [Signal; 7] = [
    Signal::N1,
    Signal::T2,
    Signal::P2,
    Signal::T34,
    Signal::P34,
    Signal::Power,
    Signal::P1,
];

/// The example unit of `examples/baseline_snapshots.csv`: the engine file's design values
/// moved as a real unit differs from its datasheet (compressor −1.2 points, HPT +1.0, PT −0.8
/// points of design efficiency; air flow +2.5 %; pressure ratio −2 %; inlet loss +30 %,
/// exhaust back-pressure excess −20 %). Keys and values, to give `Engine::with_params`.
pub fn example_unit(engine: &Engine) -> Result<Vec<(String, f64)>, String> {
    let v = |k: &str| engine.get_param(k).map_err(|e| e.to_string());
    Ok(vec![
        (
            "design.compressor_efficiency".into(),
            v("design.compressor_efficiency")? - 0.012,
        ),
        (
            "design.hpt_efficiency".into(),
            v("design.hpt_efficiency")? + 0.010,
        ),
        (
            "design.pt_efficiency".into(),
            v("design.pt_efficiency")? - 0.008,
        ),
        (
            "design.exhaust_flow_kg_s".into(),
            v("design.exhaust_flow_kg_s")? * 1.025,
        ),
        (
            "design.pressure_ratio".into(),
            v("design.pressure_ratio")? * 0.98,
        ),
        (
            "design.inlet_loss_frac".into(),
            v("design.inlet_loss_frac")? * 1.3,
        ),
        (
            "design.exhaust_back_pressure_ratio".into(),
            1.0 + (v("design.exhaust_back_pressure_ratio")? - 1.0) * 0.8,
        ),
    ])
}

/// `n` operating points from 35 % to 100 % of the design power, ambient temperature swinging
/// 278–298 K and pressure 99.5–101.5 kPa (deterministic).
pub fn load_sweep(engine: &Engine, n: usize) -> Vec<OperatingPoint> {
    let design = engine.cfg().design.power_mw;
    (0..n)
        .map(|k| {
            let f = if n > 1 {
                k as f64 / (n - 1) as f64
            } else {
                1.0
            };
            OperatingPoint {
                t_amb_k: 278.0 + 20.0 * ((k * 7) % n.max(1)) as f64 / n.max(1) as f64,
                p_amb_kpa: 99.5 + 2.0 * ((k * 3) % n.max(1)) as f64 / n.max(1) as f64,
                power_mw: design * (0.35 + 0.6 * f),
            }
        })
        .collect()
}

/// What a generator unit's baseline carries besides its inputs (T1, ambient pressure, PT
/// speed, fuel flow): [`generator_baseline_csv`].
pub const GENERATOR_WRITTEN: [Signal; 9] = [
    Signal::N1,
    Signal::P1,
    Signal::T2,
    Signal::P2,
    Signal::T34,
    Signal::P34,
    Signal::T4,
    Signal::P4,
    Signal::Power,
];

/// The healthy steady baseline of `truth` run as a generator: 9 loads from 30 % to 100 % of
/// its design power at its design PT speed, days from 278 to 298 K and 99 to 102 kPa in a
/// shuffled order, each row a 100-s average of the [`GENERATOR_WRITTEN`] signals with
/// instrument noise (`seed`), group `baseline`. The baseline of the foreign generator unit
/// (`tests/foreign_startups.rs`, `cargo run --example foreign_baseline`).
pub fn generator_baseline_csv(truth: &Engine, seed: u64) -> Result<String, String> {
    generator_rows_csv(truth, &HealthParams::HEALTHY, "baseline", seed, 4)
}

/// [`generator_baseline_csv`]'s loads at `health`, group `group`, the days shuffled by
/// `shuffle` (4: the baseline's; another pairs the loads with other days).
pub fn generator_rows_csv(
    truth: &Engine,
    health: &HealthParams,
    group: &str,
    seed: u64,
    shuffle: usize,
) -> Result<String, String> {
    let design_mw = truth.cfg().design.power_mw;
    let points: Vec<OperatingPoint> = (0..9)
        .map(|k| {
            let j = (k * shuffle) % 9;
            OperatingPoint {
                t_amb_k: 278.0 + 20.0 * j as f64 / 8.0,
                p_amb_kpa: 99.0 + 3.0 * ((j * 5) % 9) as f64 / 8.0,
                power_mw: design_mw * (0.3 + 0.7 * k as f64 / 8.0),
            }
        })
        .collect();
    let n2 = vec![truth.cfg().design.pt_speed_rpm; points.len()];
    snapshot_csv_at_speeds(
        truth,
        health,
        &points,
        &n2,
        group,
        100.0,
        seed,
        &GENERATOR_WRITTEN,
    )
}

/// Snapshot CSV text of `engine` at `health` over `points`; `group` fills a `test` column.
/// Writes the [`WRITTEN`] signals. An error names the point whose steady solve failed.
pub fn snapshot_csv(
    engine: &Engine,
    health: &HealthParams,
    points: &[OperatingPoint],
    group: &str,
    averaging: f64,
    seed: u64,
) -> Result<String, String> {
    snapshot_csv_of(engine, health, points, group, averaging, seed, &WRITTEN)
}

/// [`snapshot_csv`] writing the compared signals `written` (the unit's instrument set: e.g.
/// torque instead of power, no P34). The PT speed of each point is the design speed for a
/// generator drive, and the load law's speed for the point's power on a mechanical drive
/// (`[load] mode = "load_law"`), as that unit would run.
pub fn snapshot_csv_of(
    engine: &Engine,
    health: &HealthParams,
    points: &[OperatingPoint],
    group: &str,
    averaging: f64,
    seed: u64,
    written: &[Signal],
) -> Result<String, String> {
    let rows = Rows {
        group,
        averaging,
        seed,
        written,
    };
    write_rows(engine, health, points, None, &rows)
}

/// [`snapshot_csv_of`] with the PT speed of each point given (`n2_rpm[k]` for `points[k]`):
/// a load whose speed follows a schedule of its own (a controllable-pitch propeller's
/// combinator, a compressor with recycle), each point solved at that speed for its power.
#[allow(clippy::too_many_arguments)] // the row layout's four settings beside the points
pub fn snapshot_csv_at_speeds(
    engine: &Engine,
    health: &HealthParams,
    points: &[OperatingPoint],
    n2_rpm: &[f64],
    group: &str,
    averaging: f64,
    seed: u64,
    written: &[Signal],
) -> Result<String, String> {
    if n2_rpm.len() != points.len() {
        return Err(format!(
            "{} PT speeds for {} points",
            n2_rpm.len(),
            points.len()
        ));
    }
    let rows = Rows {
        group,
        averaging,
        seed,
        written,
    };
    write_rows(engine, health, points, Some(n2_rpm), &rows)
}

/// How rows are written: group label, averaging, noise seed, compared signals.
struct Rows<'a> {
    group: &'a str,
    averaging: f64,
    seed: u64,
    written: &'a [Signal],
}

fn write_rows(
    engine: &Engine,
    health: &HealthParams,
    points: &[OperatingPoint],
    speeds: Option<&[f64]>,
    rows: &Rows,
) -> Result<String, String> {
    let Rows {
        group,
        averaging,
        seed,
        written,
    } = *rows;
    let cfg = engine.cfg();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut csv = String::from("test,t1_k,p_amb_kpa,n2_rpm,fuel_kg_s");
    for s in written {
        csv.push(',');
        csv.push_str(s.column());
    }
    csv.push('\n');
    for (k, p) in points.iter().enumerate() {
        let m = engine.model_at(health, p.t_amb_k, p.p_amb_kpa);
        let inputs = SteadyInputs {
            t_amb_k: p.t_amb_k,
            p_amb_kpa: p.p_amb_kpa,
            n2_rpm: speeds.map_or(cfg.design.pt_speed_rpm, |s| s[k]),
            demand: Demand::PowerMw(p.power_mw),
        };
        // The engine file's load mode sets the PT speed (a load law: its speed for this power),
        // unless the speeds are given.
        let load = if speeds.is_some() {
            None
        } else {
            cfg.load.as_ref()
        };
        let (sp, _) =
            load::solve(&m, load, &inputs, None).map_err(|e| format!("point {k} ({p:?}): {e}"))?;
        csv.push_str(&format!(
            "{group},{},{},{},{}",
            p.t_amb_k, p.p_amb_kpa, sp.stations.n2_rpm, sp.stations.fuel_kg_s
        ));
        for &s in written {
            // What the unit's instruments read (an offset the engine file states included).
            let x = steady_reading(&m, &sp, s);
            let sd = noise_sigma(&cfg.sensors, s, x) / averaging.max(1.0).sqrt();
            let noisy = match Normal::new(0.0, sd) {
                Ok(n) if sd > 0.0 => x + n.sample(&mut rng),
                _ => x,
            };
            csv.push_str(&format!(",{noisy:.6}"));
        }
        csv.push('\n');
    }
    Ok(csv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_read_back_as_snapshots_with_the_truth_inside_the_noise() {
        let e = Engine::reference().expect("engine");
        let pts = load_sweep(&e, 5);
        assert!((pts[4].power_mw - 0.95 * 31.4).abs() < 1e-9);
        let csv = snapshot_csv(&e, &HealthParams::HEALTHY, &pts, "a", 25.0, 1).expect("csv");
        let rows = crate::diagnosis::snapshot::read_snapshots(
            csv.as_bytes(),
            &Default::default(),
            Some("test"),
        )
        .expect("rows");
        assert_eq!(rows.len(), 5);
        assert_eq!(rows[0].p_amb_kpa, Some(pts[0].p_amb_kpa));
        assert_eq!(rows[0].values.len(), WRITTEN.len());
        let again = snapshot_csv(&e, &HealthParams::HEALTHY, &pts, "a", 25.0, 1).expect("csv");
        assert_eq!(csv, again);
    }
}
