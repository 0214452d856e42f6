//! Effect `sensor_scale:<column>`: one instrument reads a factor `1 + scale` of the true value —
//! a transducer ratio (power, torque), a span error, a thermocouple average with one element
//! failed (reads low in proportion, not by a constant).
//!
//! Signature: a residual on that channel proportional to its reading: zero at rest (for
//! channels that read zero there) and largest at load — where a constant offset
//! (`sensor_bias`) is the same at rest as at load. On power (an output in measured-fuel mode)
//! it is nearly a change of power-turbine health.
//! Pure: acts on the recorded series only (instrument path), no states.

use super::{Channels, Effect, EffectSpec, ParamSpec};
use crate::signals::Signal;
use std::sync::Arc;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "sensor_scale",
    instrument: true,
    channels: Channels::Measured,
    summary: "one instrument reads a factor (1 + scale) of the true value",
    signature: "a residual on that channel in proportion to its reading, largest at load",
    params: &[ParamSpec {
        name: "scale",
        unit: "fraction",
        default: 0.0,
        min: -0.1,
        max: 0.1,
        doc: "relative error of the reading (−0.016 = reads 1.6 % low)",
        refinement: false,
    }],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(SensorScale {
        channel: channel.unwrap_or(Signal::Power),
        scale: p.first().copied().unwrap_or(0.0),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct SensorScale {
    channel: Signal,
    scale: f64,
}

impl Effect for SensorScale {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn instrument(&self, signal: Signal, _t_s: &[f64], series: &mut [f64]) {
        if signal == self.channel {
            for v in series.iter_mut() {
                *v *= 1.0 + self.scale;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_only_its_channel() {
        let e = build(&[-0.02], Some(Signal::Power));
        let mut a = vec![0.0, 10.0];
        e.instrument(Signal::Power, &[0.0, 1.0], &mut a);
        assert_eq!(a, vec![0.0, 9.8]);
        let mut b = vec![100.0];
        e.instrument(Signal::P34, &[0.0], &mut b);
        assert_eq!(b, vec![100.0]);
    }
}
