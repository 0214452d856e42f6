//! Method A's steady windows: where a measured segment holds still long enough to be one
//! operating point ([`detect_windows`], the criteria in the parent module's docs), and each
//! window's means as the point's inputs and compared values ([`average_windows`]). Pure: reads
//! the recording only; fits nothing.

use super::{InputNoise, InputSigma, SteadyData};
use crate::diagnosis::SteadyCriteria;
use crate::engine::config::EngineConfig;
use crate::engine::sensors::noise_sigma;
use crate::engine::steady::{Demand, SteadyInputs};
use crate::recording::Recording;
use crate::signals::Signal;

/// A detected steady window: sample index range `[start, end)` and times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SteadyWindow {
    pub start: usize,
    pub end: usize,
    pub t_start_s: f64,
    pub t_end_s: f64,
}

/// Mean and count of the finite values of `v` (`None` when there are none).
pub(crate) fn finite_mean(v: impl Iterator<Item = f64>) -> Option<(f64, usize)> {
    let (s, n) = v
        .filter(|x| x.is_finite())
        .fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    (n > 0).then(|| (s / n as f64, n))
}

/// Linear trend drift over the window, RMS scatter and largest deviation around it, for the
/// finite samples.
fn trend(t: &[f64], y: &[f64]) -> Option<(f64, f64, f64)> {
    let pts: Vec<(f64, f64)> = t
        .iter()
        .zip(y)
        .filter(|(_, v)| v.is_finite())
        .map(|(a, b)| (*a, *b))
        .collect();
    if pts.len() < 3 {
        return None;
    }
    let n = pts.len() as f64;
    let tm = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let ym = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - tm).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - tm) * (p.1 - ym)).sum();
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let scatter = (pts
        .iter()
        .map(|p| (p.1 - ym - b * (p.0 - tm)).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let worst = pts
        .iter()
        .map(|p| (p.1 - ym - b * (p.0 - tm)).abs())
        .fold(0.0, f64::max);
    let span = pts[pts.len() - 1].0 - pts[0].0;
    Some((b * span, scatter, worst))
}

fn window_is_steady(
    seg: &Recording,
    cfg: &EngineConfig,
    crit: &SteadyCriteria,
    a: usize,
    b: usize,
) -> bool {
    let ph = seg.phases()[a];
    if seg.phases()[a..b].iter().any(|p| *p != ph) {
        return false;
    }
    let n1_min = crit.min_n1_fraction * cfg.design.gg_speed_rpm;
    let fired = seg.rows()[a..b]
        .iter()
        .all(|v| v[Signal::FuelFlow.index()] > 0.0 && v[Signal::N1.index()] >= n1_min);
    if !fired {
        return false;
    }
    let t = &seg.times()[a..b];
    for &s in &crit.signals {
        let y: Vec<f64> = seg.rows()[a..b].iter().map(|v| v[s.index()]).collect();
        let Some((mean, _)) = finite_mean(y.iter().copied()) else {
            continue; // the plant lacks this signal
        };
        let sigma = noise_sigma(&cfg.sensors, s, mean);
        if sigma <= 0.0 {
            continue;
        }
        match trend(t, &y) {
            Some((drift, scatter, worst)) => {
                if drift.abs() > crit.max_drift_sigma * sigma
                    || scatter > crit.max_scatter_sigma * sigma
                    || worst > crit.max_deviation_sigma * sigma
                {
                    return false;
                }
            }
            None => return false,
        }
    }
    true
}

/// Finds the steady windows of `seg` (criteria in the module docs).
pub fn detect_windows(
    seg: &Recording,
    cfg: &EngineConfig,
    crit: &SteadyCriteria,
) -> Vec<SteadyWindow> {
    let n = seg.len();
    let mut out = Vec::new();
    let mut a = 0;
    while a < n {
        // Smallest end that spans min_duration_s.
        let Some(b0) =
            (a + 1..=n).find(|&b| seg.times()[b - 1] - seg.times()[a] >= crit.min_duration_s)
        else {
            break;
        };
        if !window_is_steady(seg, cfg, crit, a, b0) {
            a += 1;
            continue;
        }
        let mut b = b0;
        while b < n && window_is_steady(seg, cfg, crit, a, b + 1) {
            b += 1;
        }
        // Settling guard: skip the window's opening stretch if enough remains after it.
        let settled = (a..b)
            .find(|&k| seg.times()[k] - seg.times()[a] >= crit.settle_s)
            .filter(|&k| seg.times()[b - 1] - seg.times()[k] >= crit.min_duration_s)
            .unwrap_or(a);
        out.push(SteadyWindow {
            start: settled,
            end: b,
            t_start_s: seg.times()[settled],
            t_end_s: seg.times()[b - 1],
        });
        a = b;
    }
    out
}

/// Averages each window into a steady operating point.
pub fn average_windows(
    seg: &Recording,
    cfg: &EngineConfig,
    windows: &[SteadyWindow],
    signals: &[Signal],
) -> Vec<SteadyData> {
    let (_, p_amb) = seg.ambient(cfg.ambient.temperature_k, cfg.ambient.pressure_kpa);
    let mut out = Vec::new();
    for w in windows {
        let vals = &seg.rows()[w.start..w.end];
        let mean = |s: Signal| finite_mean(vals.iter().map(|v| v[s.index()]));
        let (Some((fuel, _)), Some((n2, _))) = (mean(Signal::FuelFlow), mean(Signal::N2)) else {
            continue; // no fuel or PT speed: cannot state the operating point
        };
        let t1 = mean(Signal::T1);
        let t_amb = t1.map_or(cfg.ambient.temperature_k, |m| m.0);
        let outputs = signals
            .iter()
            .filter(|s| !matches!(s, Signal::T1 | Signal::FuelFlow | Signal::N2))
            .filter_map(|&s| {
                let (m, n) = mean(s)?;
                let sd = noise_sigma(&cfg.sensors, s, m) / (n as f64).sqrt();
                (sd > 0.0).then_some((s, m, sd))
            })
            .collect();
        let inputs = SteadyInputs {
            t_amb_k: t_amb,
            p_amb_kpa: p_amb,
            n2_rpm: n2,
            demand: Demand::FuelKgS(fuel),
        };
        // The window's own count of fuel readings (every input is sampled with it).
        let samples = mean(Signal::FuelFlow).map_or(1, |m| m.1);
        out.push(SteadyData {
            window: *w,
            label: format!("steady window at {:.0}–{:.0} s", w.t_start_s, w.t_end_s),
            inputs,
            outputs,
            n1_hint_rpm: None,
            // The ambient pressure is the mean of P1 at rest over the record: exact here.
            input_sd: InputSigma::of(&cfg.sensors, &inputs, t1.is_some(), samples),
            input_response: Vec::new(),
            input_noise: InputNoise::Fitted,
        });
    }
    out
}
