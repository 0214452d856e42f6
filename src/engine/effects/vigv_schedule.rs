//! Effect `vigv_schedule`: the compressor's variable inlet guide vanes follow a schedule that
//! differs from the one the map assumes at low corrected speed, changing the compressor's flow
//! capacity there by up to `flow_delta_pct`, fading in linearly below `below` (fraction of
//! design corrected speed) over 20 % of speed.
//!
//! Signature: during crank, light-off and early acceleration the air flow — and with it P2,
//! T34 and the acceleration for the fuel given — differs from the model; at high speed and at
//! load no residual. A fit without it reads the low-speed mismatch as compressor flow
//! degradation (D_GC).
//! Pure: no states, no I/O.

use super::{Channels, ComponentDeltas, CoreView, Effect, EffectSpec, ParamSpec};
use crate::engine::cycle::T_STD_K;
use crate::signals::Signal;
use std::sync::Arc;

/// Span of corrected speed over which the offset fades in, fraction of design.
const FADE: f64 = 0.2;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "vigv_schedule",
    instrument: false,
    channels: Channels::Engine,
    summary: "compressor flow-capacity offset at low corrected speed (VIGV schedule)",
    signature: "air flow, P2 and T34 off the model at low corrected GG speed (crank to early \
                acceleration); none at high speed and load",
    params: &[
        ParamSpec {
            name: "flow_delta_pct",
            unit: "%",
            default: -3.0,
            min: -15.0,
            max: 15.0,
            doc: "compressor flow change at the low-speed end of the fade",
            refinement: false,
        },
        ParamSpec {
            name: "below",
            unit: "-",
            default: 0.85,
            min: 0.4,
            max: 1.0,
            doc: "corrected GG speed (fraction of design) below which the offset appears",
            refinement: false,
        },
    ],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], _channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(VigvSchedule {
        flow_delta: p.first().copied().unwrap_or(-3.0) / 100.0,
        below: p.get(1).copied().unwrap_or(0.85),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct VigvSchedule {
    flow_delta: f64,
    below: f64,
}

impl Effect for VigvSchedule {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn component_deltas(&self, core: &CoreView, _x: &[f64], d: &mut ComponentDeltas) {
        let nc = core.n1_rpm / (core.t_amb_k / T_STD_K).sqrt() / core.n1_design_rpm;
        let s = ((self.below - nc) / FADE).clamp(0.0, 1.0);
        d.compressor_flow *= 1.0 + self.flow_delta * s;
    }
}
