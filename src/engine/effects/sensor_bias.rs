//! Effect `sensor_bias:<column>`: one instrument reads high or low by a constant `offset` (in
//! the channel's unit) — a drifted transmitter zero, a thermocouple of another calibration, a
//! pressure tap in the wrong place.
//!
//! Signature: a constant residual on that channel in every phase, including at rest before the
//! start where the engine's state is known exactly (ambient pressure and temperature). The
//! dangerous kind: Method A and Method B make the same error, so only the residual map shows it
//! (a 1 % P2 bias drives D_GT by ≈ 3 points).
//! Pure: acts on the recorded series only (instrument path), no states.

use super::{Channels, Effect, EffectSpec, ParamSpec};
use crate::signals::Signal;
use std::sync::Arc;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "sensor_bias",
    instrument: true,
    channels: Channels::Measured,
    summary: "constant offset of one instrument",
    signature: "a constant residual on that channel in every phase, at rest as much as at load",
    params: &[ParamSpec {
        name: "offset",
        unit: "channel unit",
        default: 0.0,
        min: -1.0e5,
        max: 1.0e5,
        doc: "what the instrument adds to the true value",
        refinement: false,
    }],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(SensorBias {
        channel: channel.unwrap_or(Signal::P2),
        offset: p.first().copied().unwrap_or(0.0),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct SensorBias {
    channel: Signal,
    offset: f64,
}

impl Effect for SensorBias {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn instrument(&self, signal: Signal, _t_s: &[f64], series: &mut [f64]) {
        if signal == self.channel {
            for v in series.iter_mut() {
                *v += self.offset;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_only_its_channel() {
        let e = build(&[2.5], Some(Signal::P2));
        let mut a = vec![100.0, 200.0];
        e.instrument(Signal::P2, &[0.0, 1.0], &mut a);
        assert_eq!(a, vec![102.5, 202.5]);
        let mut b = vec![100.0];
        e.instrument(Signal::P34, &[0.0], &mut b);
        assert_eq!(b, vec![100.0]);
    }
}
