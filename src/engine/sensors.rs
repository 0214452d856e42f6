//! Measurement model: what the plant's instruments would report for a true trajectory.
//!
//! Each channel is a first-order lag (exact discretisation with a first-order hold between
//! samples), then Gaussian noise (1σ relative and/or absolute) and an optional constant bias.
//! Noise is seeded: each channel draws from its own ChaCha stream of the one seed, so the same
//! seed gives byte-identical output and adding a channel never changes another channel's noise.
//! Pure: no I/O, no global RNG.

use super::config::{SensorChannel, SensorsConfig};
use crate::signals::Signal;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The sensor channel configured for a signal (`None` for model-only signals without a sensor).
pub fn channel(cfg: &SensorsConfig, s: Signal) -> Option<&SensorChannel> {
    Some(match s {
        Signal::N1 => &cfg.n1,
        Signal::N2 => &cfg.n2,
        Signal::T1 => &cfg.t1,
        Signal::P1 => &cfg.p1,
        Signal::T2 => &cfg.t2,
        Signal::P2 => &cfg.p2,
        Signal::T3 => &cfg.t3,
        Signal::P3 => &cfg.p3,
        Signal::T34 => &cfg.t34,
        Signal::P34 => &cfg.p34,
        Signal::T4 => &cfg.t4,
        Signal::P4 => &cfg.p4,
        Signal::FuelFlow => &cfg.fuel,
        Signal::Power => &cfg.power,
        Signal::Torque => &cfg.torque,
        Signal::InletDepression => &cfg.dp_inlet,
        Signal::SurgeMargin => return None,
    })
}

/// One step of the exact first-order-hold lag recursion: the output after `dt` seconds from
/// output `y` with input moving linearly from `x_prev` to `x`.
fn lag_step(y: f64, x_prev: f64, x: f64, dt: f64, tau: f64) -> f64 {
    let a = (-dt / tau).exp();
    let c = tau / dt * (1.0 - a);
    a * y + (1.0 - c) * x + (c - a) * x_prev
}

/// Applies a first-order lag with time constant `tau` to samples `x` taken every `dt`
/// (exact for a signal that is linear between samples; starts settled on the first sample).
pub fn lag(x: &[f64], dt: f64, tau: f64) -> Vec<f64> {
    if tau <= 0.0 || x.is_empty() {
        return x.to_vec();
    }
    let mut y = Vec::with_capacity(x.len());
    y.push(x[0]);
    for k in 1..x.len() {
        let prev = y[k - 1];
        y.push(lag_step(prev, x[k - 1], x[k], dt, tau));
    }
    y
}

/// [`lag`] for samples `x` taken at times `t_s` (any spacing; each step uses its own interval,
/// so the lag follows the data's own sample period). `t_s` and `x` have equal lengths.
pub fn lag_at(t_s: &[f64], x: &[f64], tau: f64) -> Vec<f64> {
    if tau <= 0.0 || x.is_empty() {
        return x.to_vec();
    }
    let mut y = Vec::with_capacity(x.len());
    y.push(x[0]);
    for k in 1..x.len() {
        let prev = y[k - 1];
        let dt = t_s.get(k).zip(t_s.get(k - 1)).map_or(0.0, |(b, a)| b - a);
        y.push(if dt > 0.0 {
            lag_step(prev, x[k - 1], x[k], dt, tau)
        } else {
            prev
        });
    }
    y
}

/// What to apply: lags are always part of the instrument; noise and bias are optional.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasurementOptions {
    pub lags: bool,
    pub noise: bool,
    pub bias: bool,
    pub seed: u64,
}

/// Measured series for one signal from its true series sampled every `dt`.
pub fn measure(
    cfg: &SensorsConfig,
    s: Signal,
    truth: &[f64],
    dt: f64,
    opts: &MeasurementOptions,
) -> Vec<f64> {
    let lagged = |tau: f64| lag(truth, dt, tau);
    measure_with(cfg, s, truth, opts, lagged)
}

/// Measured series for one signal from its true series sampled at times `t_s` (the lags use
/// the data's own sample intervals).
pub fn measure_at(
    cfg: &SensorsConfig,
    s: Signal,
    t_s: &[f64],
    truth: &[f64],
    opts: &MeasurementOptions,
) -> Vec<f64> {
    let lagged = |tau: f64| lag_at(t_s, truth, tau);
    measure_with(cfg, s, truth, opts, lagged)
}

fn measure_with(
    cfg: &SensorsConfig,
    s: Signal,
    truth: &[f64],
    opts: &MeasurementOptions,
    lagged: impl Fn(f64) -> Vec<f64>,
) -> Vec<f64> {
    let Some(ch) = channel(cfg, s) else {
        return truth.to_vec();
    };
    let mut y = if opts.lags {
        lagged(ch.tau_s)
    } else {
        truth.to_vec()
    };
    if opts.noise && (ch.noise_rel > 0.0 || ch.noise_abs > 0.0) {
        let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
        rng.set_stream(s.index() as u64 + 1);
        for v in y.iter_mut() {
            let z: f64 = StandardNormal.sample(&mut rng);
            let sigma = ((ch.noise_rel * *v).powi(2) + ch.noise_abs * ch.noise_abs).sqrt();
            *v += sigma * z;
        }
    }
    if opts.bias && ch.bias != 0.0 {
        y.iter_mut().for_each(|v| *v += ch.bias);
    }
    y
}

/// One instrument channel applied sample by sample (the live counterpart of [`measure`]): the
/// same exact first-order-hold lag recursion, noise from the channel's own seeded stream.
#[derive(Debug, Clone)]
pub struct OnlineChannel {
    ch: Option<SensorChannel>,
    dt: f64,
    prev_x: Option<f64>,
    y: f64,
    rng: ChaCha8Rng,
    opts: MeasurementOptions,
}

impl OnlineChannel {
    pub fn new(
        cfg: &SensorsConfig,
        s: Signal,
        dt: f64,
        opts: &MeasurementOptions,
    ) -> OnlineChannel {
        let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
        rng.set_stream(s.index() as u64 + 1);
        OnlineChannel {
            ch: channel(cfg, s).cloned(),
            dt,
            prev_x: None,
            y: 0.0,
            rng,
            opts: *opts,
        }
    }

    /// The reading for true value `x` at the next sample.
    pub fn sample(&mut self, x: f64) -> f64 {
        let Some(ch) = &self.ch else {
            return x;
        };
        self.y = match self.prev_x {
            Some(px) if self.opts.lags && ch.tau_s > 0.0 => {
                lag_step(self.y, px, x, self.dt, ch.tau_s)
            }
            _ => x,
        };
        self.prev_x = Some(x);
        let mut v = self.y;
        if self.opts.noise && (ch.noise_rel > 0.0 || ch.noise_abs > 0.0) {
            let z: f64 = StandardNormal.sample(&mut self.rng);
            v += ((ch.noise_rel * v).powi(2) + ch.noise_abs * ch.noise_abs).sqrt() * z;
        }
        if self.opts.bias {
            v += ch.bias;
        }
        v
    }
}

/// The 1σ noise of a channel at a reading (used to normalise residuals).
pub fn noise_sigma(cfg: &SensorsConfig, s: Signal, value: f64) -> f64 {
    channel(cfg, s)
        .map(|ch| ((ch.noise_rel * value).powi(2) + ch.noise_abs * ch.noise_abs).sqrt())
        .unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lag_step_response_matches_exponential() {
        // A ramp 0→1 over the first interval then constant: after 3τ the lag is within e^-3.
        let dt = 0.5;
        let tau = 2.0;
        let mut x = vec![0.0; 40];
        x.iter_mut().skip(1).for_each(|v| *v = 1.0);
        let y = lag(&x, dt, tau);
        assert_eq!(y[0], 0.0);
        assert!(y.windows(2).all(|w| w[1] >= w[0]));
        // Exact continuous response to the ramp-then-hold input at t = 6 s.
        let t: f64 = 6.0;
        let exact = 1.0 - tau / dt * ((-(t - dt) / tau).exp() - (-t / tau).exp());
        assert!((y[12] - exact).abs() < 1e-12, "{} vs {}", y[12], exact);
        assert_eq!(lag(&x, dt, 0.0), x);
    }

    #[test]
    fn lag_at_follows_the_data_period() {
        // Uniform times: identical to the constant-period lag.
        let x: Vec<f64> = (0..50).map(|k| (k as f64 / 7.0).sin()).collect();
        let t1: Vec<f64> = (0..50).map(|k| k as f64).collect();
        assert_eq!(lag_at(&t1, &x, 2.0), lag(&x, 1.0, 2.0));
        // The same step input at 1 Hz and 10 Hz: the lagged value at t = 4 s agrees (exact
        // response of a step held from t = 1 s), while a 1 s discretisation of 10 Hz data
        // would lag ten times too slowly.
        let step = |t: f64| if t >= 1.0 { 1.0 } else { 0.0 };
        let t10: Vec<f64> = (0..=100).map(|k| k as f64 * 0.1).collect();
        let x10: Vec<f64> = t10.iter().map(|&t| step(t)).collect();
        let x1: Vec<f64> = t1.iter().take(11).map(|&t| step(t)).collect();
        let y10 = lag_at(&t10, &x10, 2.0);
        let y1 = lag_at(&t1[..11], &x1, 2.0);
        // Both see the step as a ramp over their first interval; by t = 4 s the difference
        // is the ramp's, a few percent, far below the 1 s-vs-0.1 s mistake.
        assert!((y10[40] - y1[4]).abs() < 0.05, "{} vs {}", y10[40], y1[4]);
        let wrong = lag(&x10, 1.0, 2.0);
        assert!(
            (wrong[40] - y1[4]).abs() > 0.15,
            "{} vs {}",
            wrong[40],
            y1[4]
        );
    }

    #[test]
    fn online_channel_matches_batch_measurement() {
        let cfg = crate::engine::config::EngineConfig::reference().sensors;
        let truth: Vec<f64> = (0..300)
            .map(|k| 600.0 + 300.0 * (k as f64 / 40.0).sin())
            .collect();
        let o = MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed: 3,
        };
        let batch = measure(&cfg, Signal::T34, &truth, 1.0, &o);
        let mut ch = OnlineChannel::new(&cfg, Signal::T34, 1.0, &o);
        let online: Vec<f64> = truth.iter().map(|x| ch.sample(*x)).collect();
        for (a, b) in batch.iter().zip(&online) {
            assert!((a - b).abs() < 1e-9, "{a} vs {b}");
        }
    }

    #[test]
    fn noise_is_seeded_and_sized() {
        let cfg = crate::engine::config::EngineConfig::reference().sensors;
        let truth = vec![1000.0; 20000];
        let o = MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed: 7,
        };
        let a = measure(&cfg, Signal::T2, &truth, 1.0, &o);
        let b = measure(&cfg, Signal::T2, &truth, 1.0, &o);
        assert_eq!(a, b);
        let other = measure(
            &cfg,
            Signal::T2,
            &truth,
            1.0,
            &MeasurementOptions { seed: 8, ..o },
        );
        assert_ne!(a, other);
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        let sd = (a.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / a.len() as f64).sqrt();
        assert!((mean - 1000.0).abs() < 0.1, "{mean}");
        assert!((sd - 2.0).abs() < 0.05, "{sd}"); // T2 default 2 K
    }
}
