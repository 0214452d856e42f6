//! Effect `sensor_lag:<column>`: a temperature channel's instrument responds more slowly than the
//! engine file says — a thermocouple in a heavier sheath, a radiation shield, a thermowell — by
//! an extra first-order lag `tau_s` on top of the configured one.
//!
//! Signature: on that channel only, the measurement trails the model during every temperature
//! change (light-off, acceleration, loading), by about `tau_s`; the residual is proportional to
//! the channel's rate of change ("lag-like") and vanishes at steady points. Without it the fit
//! absorbs the slow reading as hot-section degradation (a T34 lag moves D_GC, a T2 lag D_EC).
//! Pure: acts on the recorded series only (instrument path), no states.

use super::{Channels, Effect, EffectSpec, ParamSpec};
use crate::engine::sensors::lag_at;
use crate::signals::Signal;
use std::sync::Arc;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "sensor_lag",
    instrument: true,
    channels: Channels::Temperatures,
    summary: "extra first-order lag of one temperature instrument",
    signature: "that channel trails the model in proportion to its rate of change (lag-like \
                residual during light-off, acceleration and loading); steady points unaffected",
    params: &[ParamSpec {
        name: "tau_s",
        unit: "s",
        default: 5.0,
        min: 0.0,
        max: 60.0,
        doc: "extra time constant of the instrument",
        refinement: false,
    }],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(SensorLag {
        channel: channel.unwrap_or(Signal::T34),
        tau_s: p.first().copied().unwrap_or(5.0),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct SensorLag {
    channel: Signal,
    tau_s: f64,
}

impl Effect for SensorLag {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn instrument(&self, signal: Signal, t_s: &[f64], series: &mut [f64]) {
        if signal == self.channel && self.tau_s > 0.0 {
            let lagged = lag_at(t_s, series, self.tau_s);
            series.copy_from_slice(&lagged);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lags_only_its_channel() {
        let e = build(&[4.0], Some(Signal::T2));
        let t: Vec<f64> = (0..20).map(|k| k as f64).collect();
        let step: Vec<f64> = t.iter().map(|&x| if x >= 1.0 { 1.0 } else { 0.0 }).collect();
        let mut a = step.clone();
        e.instrument(Signal::T2, &t, &mut a);
        assert!((a[5] - (1.0 - (-4.0f64 / 4.0).exp())).abs() < 0.1, "{}", a[5]);
        let mut b = step.clone();
        e.instrument(Signal::T34, &t, &mut b);
        assert_eq!(b, step);
    }
}
