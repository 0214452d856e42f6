//! Start-ups as calibration data: the steady stretches of a recorded start-up (idle, hold
//! points, the settled load at its end) averaged into snapshot rows, so `calibrate` can use a
//! unit's start-up records where no performance test exists, alone or beside snapshots.
//!
//! What it is for: Method A's own window detection and stability criteria
//! (`diagnosis::steady::detect_windows`) applied to a healthy recording, each window becoming
//! one [`Snapshot`] with the window's mean of every measured signal; the ambient pressure from
//! the samples at rest before the start when the recording has them (else the snapshot leaves
//! it to P1 and the model's inlet loss, as a snapshot file without an ambient column does).
//! The transient parts carry the dynamics (inertias, lags), which calibration does not fit:
//! they are not used.
//!
//! The samples at rest before the start are the one state whose truth is known without any
//! model: every pressure of the gas path is the ambient pressure. [`rest_readings`] gives each
//! pressure instrument's excess over P1 there, which over-determines its offset (the
//! calibration's `sensor_bias` candidates). Temperatures are not used: a recently run engine's
//! metal is not at ambient. What it must not do: I/O, or judge health (a baseline is healthy).

use crate::diagnosis::config::SteadyCriteria;
use crate::diagnosis::snapshot::{Snapshot, INPUTS};
use crate::diagnosis::steady::{detect_windows, finite_mean};
use crate::engine::sensors::noise_sigma;
use crate::engine::EngineConfig;
use crate::recording::Recording;
use crate::signals::Signal;

/// The steady windows of `rec` as snapshot rows, labelled `source` (the group of every row:
/// `source t=START–END s`). `line` of a row is the CSV line of its window's first sample when
/// the file holds one sample per line after its header (line 2 = sample 0). Windows without
/// fuel flow or PT speed, or without T1 and no ambient default, are left out.
pub fn startup_snapshots(
    rec: &Recording,
    cfg: &EngineConfig,
    criteria: &SteadyCriteria,
    source: &str,
) -> Vec<Snapshot> {
    let at_rest = (0..rec.len()).any(|k| rec.at_rest_with_p1(k));
    let p_amb = at_rest.then(|| {
        rec.ambient(cfg.ambient.temperature_k, cfg.ambient.pressure_kpa)
            .1
    });
    let mut out = Vec::new();
    for w in detect_windows(rec, cfg, criteria) {
        let mean = |s: Signal| {
            finite_mean(rec.rows()[w.start..w.end].iter().map(|v| v[s.index()])).map(|m| m.0)
        };
        let (Some(fuel), Some(n2)) = (mean(Signal::FuelFlow), mean(Signal::N2)) else {
            continue;
        };
        if fuel <= 0.0 {
            continue;
        }
        let values = Signal::ALL
            .iter()
            .copied()
            .filter(|s| !INPUTS.contains(s) && *s != Signal::SurgeMargin)
            .filter_map(|s| mean(s).map(|v| (s, v)))
            .collect();
        out.push(Snapshot {
            line: w.start as u64 + 2,
            group: format!("{source} t={:.0}–{:.0} s", w.t_start_s, w.t_end_s),
            time_s: Some(0.5 * (w.t_start_s + w.t_end_s)),
            t_amb_k: mean(Signal::T1).unwrap_or(cfg.ambient.temperature_k),
            p_amb_kpa: p_amb,
            n2_rpm: n2,
            fuel_kg_s: fuel,
            values,
        });
    }
    out
}

/// Pressure instruments whose reading at rest is the ambient pressure (P1's reading at rest is
/// the ambient pressure itself, so its own offset is not observable this way).
pub const REST_PRESSURES: [Signal; 3] = [Signal::P2, Signal::P34, Signal::P4];

/// What one pressure instrument read while the engine was at rest, against P1.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RestReading {
    /// The recording it comes from.
    pub source: String,
    pub signal: Signal,
    /// Mean reading minus mean P1 over the samples at rest, kPa: the instrument's offset, plus
    /// noise.
    pub excess: f64,
    /// 1σ of `excess` (both instruments' noise over the samples), kPa.
    pub sigma: f64,
    pub samples: usize,
}

/// Each [`REST_PRESSURES`] instrument's excess over P1 at rest in `rec` (none without samples
/// at rest, or for a channel not recorded then).
pub fn rest_readings(rec: &Recording, cfg: &EngineConfig, source: &str) -> Vec<RestReading> {
    let rest: Vec<usize> = (0..rec.len()).filter(|&k| rec.at_rest_with_p1(k)).collect();
    let mean_of = |s: Signal| finite_mean(rest.iter().map(|&k| rec.rows()[k][s.index()]));
    let Some((p1, n1)) = mean_of(Signal::P1) else {
        return Vec::new();
    };
    let sd1 = noise_sigma(&cfg.sensors, Signal::P1, p1) / (n1 as f64).sqrt();
    REST_PRESSURES
        .iter()
        .filter_map(|&s| {
            let (v, n) = mean_of(s)?;
            let sd = noise_sigma(&cfg.sensors, s, v) / (n as f64).sqrt();
            let sigma = (sd * sd + sd1 * sd1).sqrt();
            (sigma > 0.0).then(|| RestReading {
                source: source.to_string(),
                signal: s,
                excess: v - p1,
                sigma,
                samples: n,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::sensors::MeasurementOptions;
    use crate::engine::simulation::run_scenario;
    use crate::engine::{Engine, Scenario, Trace};
    use crate::health::HealthParams;

    #[test]
    fn a_start_up_gives_its_idle_and_load_points_with_ambient_from_rest() {
        let e = Engine::reference().expect("engine");
        let (samples, _) = run_scenario(
            &e.model(&HealthParams::HEALTHY),
            &Scenario::startup(e.cfg()),
        )
        .expect("start-up");
        let opts = MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed: 4,
        };
        let rec = Trace::from_truth(&e, &samples, Some(&opts))
            .to_recording()
            .expect("recording");
        let rows = startup_snapshots(&rec, e.cfg(), &SteadyCriteria::default(), "su.csv");
        assert!(rows.len() >= 2, "{} windows", rows.len());
        let fuels: Vec<f64> = rows.iter().map(|r| r.fuel_kg_s).collect();
        let (lo, hi) = fuels
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &f| (a.min(f), b.max(f)));
        assert!(hi > 2.0 * lo, "idle and load both present: {fuels:?}");
        for r in &rows {
            assert!(r.group.starts_with("su.csv t="), "{}", r.group);
            let p = r.p_amb_kpa.expect("ambient from the samples at rest");
            assert!((p - e.cfg().ambient.pressure_kpa).abs() < 0.2, "{p}");
            assert!(r.values.iter().any(|(s, _)| *s == Signal::T34));
            assert!(!r.values.iter().any(|(s, _)| INPUTS.contains(s)));
        }
        // Averaged over its window, a load point's P2 is within a few noise σ of the truth.
        let last = rows.last().expect("a load point");
        let (a, b) = ((last.line - 2) as usize, rec.len());
        assert!(a < b);
        let p2 = last
            .values
            .iter()
            .find(|(s, _)| *s == Signal::P2)
            .map(|(_, v)| *v)
            .expect("P2");
        let truth = samples[samples.len() - 1].stations.p2_kpa;
        assert!((p2 / truth - 1.0).abs() < 0.005, "{p2} vs {truth}");
        // At rest, unbiased transmitters read the ambient within their noise.
        let rest = rest_readings(&rec, e.cfg(), "su.csv");
        assert_eq!(rest.len(), REST_PRESSURES.len());
        for r in &rest {
            assert!(r.samples >= 5 && r.sigma > 0.0, "{r:?}");
            assert!(r.excess.abs() < 4.0 * r.sigma, "{r:?}");
        }
    }
}
