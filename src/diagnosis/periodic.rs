//! Hidden periodicity in a fit's residual: an oscillation the model does not have (pressure
//! ripple from a combustor or a pipe resonance, a hunting governor, a pulsating transmitter
//! line), found per signal however small its amplitude against the noise.
//!
//! Why a separate test: the residual map ([`super::fit_quality`]) measures how large the
//! residual is; a ripple of one noise σ adds little to that, yet it is structure the model
//! lacks and that no health parameter can take up. A periodogram sees it: the residual in
//! noise units, less its 15 s moving mean (the slow part, which transient mismatches such as
//! a thermocouple lag leave), is Fourier-analysed between periods of 12 s and the Nyquist
//! limit; Fisher's g statistic (largest ordinate over their sum) gives the probability that
//! white noise would produce so dominant a line, and the line must also stand well above its
//! own neighbourhood (a broad bump is no oscillation).
//!
//! Pure arithmetic on given series: no I/O, no model runs.

use crate::engine::config::SensorsConfig;
use crate::engine::sensors::noise_sigma;
use crate::engine::trace::Values;
use crate::signals::Signal;
use serde::Serialize;

/// Longest period searched, s (slower structure is drift or transient mismatch).
const MAX_PERIOD_S: f64 = 12.0;
/// Window of the moving mean removed before the periodogram, s.
const DETREND_S: f64 = 15.0;
/// Fewest samples analysed.
const MIN_SAMPLES: usize = 64;
/// Largest white-noise probability of the line for it to be reported.
const MAX_P_VALUE: f64 = 1e-6;
/// The line must exceed the mean of its neighbourhood (±6 bins, less ±2) this many times.
const MIN_SHARPNESS: f64 = 4.0;
/// Smallest amplitude reported, in noise σ.
const MIN_AMPLITUDE_SIGMA: f64 = 0.3;

/// An oscillation found in one signal's residual.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Periodicity {
    /// The signal, by its CSV column name (`p34_kpa`).
    #[serde(serialize_with = "column_name")]
    pub signal: Signal,
    pub frequency_hz: f64,
    pub period_s: f64,
    /// Amplitude of the oscillation in the signal's unit (half peak-to-peak).
    pub amplitude: f64,
    /// The same in noise σ.
    pub amplitude_sigma: f64,
    /// Probability that white noise alone gives so dominant a line (Fisher's g test).
    pub p_value: f64,
}

fn column_name<S: serde::Serializer>(s: &Signal, ser: S) -> Result<S::Ok, S::Error> {
    ser.serialize_str(s.column())
}

/// The oscillations in `measured − model` (rows indexed like `t_s`) for `signals`.
pub(crate) fn find(
    t_s: &[f64],
    measured: &[Values],
    model: &[Values],
    signals: &[Signal],
    sensors: &SensorsConfig,
) -> Vec<Periodicity> {
    let n = t_s.len().min(measured.len()).min(model.len());
    signals
        .iter()
        .filter_map(|&s| one_signal(&t_s[..n], &measured[..n], &model[..n], s, sensors))
        .collect()
}

/// One signal's residual in noise units, less its moving mean: what the periodogram reads.
struct Detrended {
    r: Vec<f64>,
    /// The median sample spacing, s.
    dt: f64,
    /// The mean noise σ of the samples, in the signal's unit.
    mean_sigma: f64,
}

fn detrended(
    t_s: &[f64],
    measured: &[Values],
    model: &[Values],
    s: Signal,
    sensors: &SensorsConfig,
) -> Option<Detrended> {
    let i = s.index();
    let idx: Vec<usize> = (0..t_s.len())
        .filter(|&k| measured[k][i].is_finite() && model[k][i].is_finite() && t_s[k].is_finite())
        .collect();
    if idx.len() < MIN_SAMPLES {
        return None;
    }
    let mut gaps: Vec<f64> = idx.windows(2).map(|w| t_s[w[1]] - t_s[w[0]]).collect();
    gaps.sort_by(f64::total_cmp);
    let dt = gaps[gaps.len() / 2];
    if dt.is_nan() || dt <= 0.0 {
        return None;
    }
    // Noise σ per sample, with the floor the objective uses (10 % of the largest reading).
    let peak = idx
        .iter()
        .map(|&k| measured[k][i].abs())
        .fold(0.0, f64::max);
    let floor = noise_sigma(sensors, s, 0.1 * peak)
        .max(1e-3 * peak)
        .max(1e-12);
    let sig: Vec<f64> = idx
        .iter()
        .map(|&k| noise_sigma(sensors, s, measured[k][i]).max(floor))
        .collect();
    let r: Vec<f64> = idx
        .iter()
        .zip(&sig)
        .map(|(&k, sg)| (measured[k][i] - model[k][i]) / sg)
        .collect();
    let r = less_moving_mean(&r, ((DETREND_S / dt).round() as usize).max(3));
    let mean_sigma = sig.iter().sum::<f64>() / sig.len() as f64;
    Some(Detrended { r, dt, mean_sigma })
}

fn one_signal(
    t_s: &[f64],
    measured: &[Values],
    model: &[Values],
    s: Signal,
    sensors: &SensorsConfig,
) -> Option<Periodicity> {
    let Detrended { r, dt, mean_sigma } = detrended(t_s, measured, model, s, sensors)?;
    let n = r.len();
    let nf = n as f64;
    let j_min = ((nf * dt / MAX_PERIOD_S).ceil() as usize).max(1);
    let j_max = n.div_ceil(2).saturating_sub(1);
    if j_max < j_min + 16 {
        return None;
    }
    let power: Vec<f64> = (j_min..=j_max).map(|j| ordinate(&r, j)).collect();
    let total: f64 = power.iter().sum();
    let (best, &p_max) = power.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let m = power.len() as f64;
    let g = p_max / total;
    let p_value = (m * (1.0 - g).powf(m - 1.0)).min(1.0);
    let neighbours: Vec<f64> = (best.saturating_sub(6)..(best + 7).min(power.len()))
        .filter(|&j| j.abs_diff(best) > 2)
        .map(|j| power[j])
        .collect();
    let around = neighbours.iter().sum::<f64>() / neighbours.len().max(1) as f64;
    // r = A cos(ωk) gives an ordinate of n A²/4.
    let amplitude_sigma = 2.0 * (p_max / nf).sqrt();
    let frequency_hz = (j_min + best) as f64 / (nf * dt);
    (p_value < MAX_P_VALUE
        && p_max > MIN_SHARPNESS * around
        && amplitude_sigma >= MIN_AMPLITUDE_SIGMA)
        .then_some(Periodicity {
            signal: s,
            frequency_hz,
            period_s: 1.0 / frequency_hz,
            amplitude: amplitude_sigma * mean_sigma,
            amplitude_sigma,
            p_value,
        })
}

/// The amplitude, in noise σ, of `measured − model`'s oscillation in signal `s` at
/// `frequency_hz` (the largest of the three periodogram lines nearest it), however small and
/// whatever the test of [`find`] would say: how much of an oscillation [`find`] reported for
/// one model is left against another (`None` when the signal has too few samples).
pub(crate) fn amplitude_at(
    t_s: &[f64],
    measured: &[Values],
    model: &[Values],
    s: Signal,
    sensors: &SensorsConfig,
    frequency_hz: f64,
) -> Option<f64> {
    let n_rows = t_s.len().min(measured.len()).min(model.len());
    let Detrended { r, dt, .. } = detrended(
        &t_s[..n_rows],
        &measured[..n_rows],
        &model[..n_rows],
        s,
        sensors,
    )?;
    let n = r.len();
    let nf = n as f64;
    let j = (frequency_hz * nf * dt).round();
    if !j.is_finite() || j < 0.0 {
        return None;
    }
    let j = j as usize;
    let p = (j.saturating_sub(1)..=j + 1)
        .filter(|&k| k >= 1 && k < n.div_ceil(2))
        .map(|k| ordinate(&r, k))
        .fold(0.0, f64::max);
    Some(2.0 * (p / nf).sqrt())
}

/// `r` less its centred moving mean over `w` samples (shorter at the ends).
fn less_moving_mean(r: &[f64], w: usize) -> Vec<f64> {
    let half = w / 2;
    let mut prefix = Vec::with_capacity(r.len() + 1);
    prefix.push(0.0);
    for v in r {
        prefix.push(prefix[prefix.len() - 1] + v);
    }
    (0..r.len())
        .map(|k| {
            let a = k.saturating_sub(half);
            let b = (k + half + 1).min(r.len());
            r[k] - (prefix[b] - prefix[a]) / (b - a) as f64
        })
        .collect()
}

/// Periodogram ordinate |Σ r_k e^{−2πi jk/n}|² / n (Goertzel recurrence).
fn ordinate(r: &[f64], j: usize) -> f64 {
    let n = r.len() as f64;
    let w = 2.0 * std::f64::consts::PI * j as f64 / n;
    let c = 2.0 * w.cos();
    let (mut s1, mut s2) = (0.0, 0.0);
    for &x in r {
        let s0 = x + c * s1 - s2;
        s2 = s1;
        s1 = s0;
    }
    (s1 * s1 + s2 * s2 - c * s1 * s2) / n
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::EngineConfig;
    use crate::signals::NSIG;
    use rand::{Rng, SeedableRng};

    fn gauss(rng: &mut impl Rng) -> f64 {
        // Box–Muller.
        let (u, v): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }

    /// P34 on a start-up-like rise: white noise alone, the same with a slow lag-like bump in
    /// the residual (the kind a thermocouple lag leaves), and with a 0.2 Hz ripple of about
    /// one noise σ. Only the ripple is reported, at its frequency and amplitude.
    #[test]
    fn a_ripple_is_found_and_noise_or_a_slow_bump_is_not() {
        let cfg = EngineConfig::reference();
        let sensors = &cfg.sensors;
        let n = 600;
        let t: Vec<f64> = (0..n).map(|k| k as f64).collect();
        let level = |k: usize| 100.0 + 250.0 * (1.0 + ((k as f64 - 200.0) / 40.0).tanh());
        let row = |v: f64| {
            let mut r = [f64::NAN; NSIG];
            r[Signal::P34.index()] = v;
            r
        };
        let model: Vec<Values> = (0..n).map(|k| row(level(k))).collect();
        let sigma = |k: usize| noise_sigma(sensors, Signal::P34, level(k));
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let noise: Vec<f64> = (0..n).map(|k| sigma(k) * gauss(&mut rng)).collect();
        let with = |extra: &dyn Fn(usize) -> f64| -> Vec<Values> {
            (0..n)
                .map(|k| row(level(k) + noise[k] + extra(k)))
                .collect()
        };
        let plain = with(&|_| 0.0);
        assert_eq!(find(&t, &plain, &model, &[Signal::P34], sensors), vec![]);
        let bump = with(&|k| 4.0 * sigma(k) * (-((k as f64 - 200.0) / 15.0).powi(2)).exp());
        assert_eq!(find(&t, &bump, &model, &[Signal::P34], sensors), vec![]);
        let amp = 1.0;
        let ripple =
            with(&|k| amp * sigma(k) * (2.0 * std::f64::consts::PI * 0.2 * k as f64).sin());
        let found = find(&t, &ripple, &model, &[Signal::P34], sensors);
        assert_eq!(found.len(), 1, "{found:?}");
        let p = &found[0];
        assert!((p.frequency_hz - 0.2).abs() < 0.005, "{p:?}");
        assert!((p.amplitude_sigma - amp).abs() < 0.3, "{p:?}");
        assert!(p.p_value < 1e-10, "{p:?}");
        // Against the model with the ripple in it, none is left; against the plain model, the
        // same amplitude as `find` reported, and a sub-threshold one is still measured.
        let at = |measured: &[Values], model: &[Values]| {
            amplitude_at(&t, measured, model, Signal::P34, sensors, p.frequency_hz)
                .expect("enough samples")
        };
        assert!((at(&ripple, &model) - p.amplitude_sigma).abs() < 1e-9);
        let rippling_model: Vec<Values> = (0..n)
            .map(|k| {
                row(level(k) + amp * sigma(k) * (2.0 * std::f64::consts::PI * 0.2 * k as f64).sin())
            })
            .collect();
        assert!(
            at(&ripple, &rippling_model) < 0.2,
            "{}",
            at(&ripple, &rippling_model)
        );
        let faint = with(&|k| 0.2 * sigma(k) * (2.0 * std::f64::consts::PI * 0.2 * k as f64).sin());
        assert_eq!(find(&t, &faint, &model, &[Signal::P34], sensors), vec![]);
        let a = at(&faint, &model);
        assert!((0.05..0.45).contains(&a), "{a}");
    }
}
