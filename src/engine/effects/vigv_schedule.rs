//! Effect `vigv_schedule`: the compressor's variable inlet guide vanes follow a schedule that
//! differs from the one the map assumes at low corrected speed, changing the compressor's flow
//! capacity there by up to `flow_delta_pct`, fading in linearly below `below` (fraction of
//! design corrected speed) over 20 % of speed.
//!
//! Refinement (fitted only once the gap analysis has named this effect): vanes off their
//! schedule also cost efficiency (`eff_delta_pct`, with the same fade), and the schedule's
//! fade may span another width of speed (`fade`); at their defaults (0 %, 0.2) the simple form.
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

/// Span of corrected speed over which the offset fades in, fraction of design (the simple
/// form's; the refinement fits `fade`).
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
        ParamSpec {
            name: "eff_delta_pct",
            unit: "%",
            default: 0.0,
            min: -5.0,
            max: 5.0,
            doc: "compressor efficiency change at the low-speed end of the fade",
            refinement: true,
        },
        ParamSpec {
            name: "fade",
            unit: "-",
            default: FADE,
            min: 0.05,
            max: 0.5,
            doc: "span of corrected GG speed (fraction of design) over which the offsets fade in",
            refinement: true,
        },
    ],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], _channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(VigvSchedule {
        flow_delta: p.first().copied().unwrap_or(-3.0) / 100.0,
        below: p.get(1).copied().unwrap_or(0.85),
        eff_delta: p.get(2).copied().unwrap_or(0.0) / 100.0,
        fade: p.get(3).copied().unwrap_or(FADE),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct VigvSchedule {
    flow_delta: f64,
    below: f64,
    eff_delta: f64,
    fade: f64,
}

impl Effect for VigvSchedule {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn reads_gas_path(&self) -> bool {
        false // corrected GG speed only
    }

    fn component_deltas(&self, core: &CoreView, _x: &[f64], d: &mut ComponentDeltas) {
        let nc = core.n1_rpm / (core.t_amb_k / T_STD_K).sqrt() / core.n1_design_rpm;
        let s = ((self.below - nc) / self.fade).clamp(0.0, 1.0);
        d.compressor_flow *= 1.0 + self.flow_delta * s;
        d.compressor_eff *= 1.0 + self.eff_delta * s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn deltas(p: &[f64], nc: f64) -> ComponentDeltas {
        let e = build(p, None);
        let mut d = ComponentDeltas::NONE;
        e.component_deltas(&CoreView::for_tests(nc * 10_000.0, 300.0), &[], &mut d);
        d
    }

    /// The simple form: flow only, fading in linearly over 20 % of speed below `below`; the
    /// refinement at its defaults is that form exactly; with an efficiency change and another
    /// fade, both offsets follow the same share.
    #[test]
    fn the_refinement_adds_efficiency_and_a_fade_width() {
        let simple = |nc| deltas(&[-6.0, 0.9], nc);
        assert_eq!(simple(0.95).compressor_flow, 1.0);
        assert!((simple(0.8).compressor_flow - (1.0 - 0.03)).abs() < 1e-12);
        assert!((simple(0.6).compressor_flow - (1.0 - 0.06)).abs() < 1e-12);
        for nc in [0.5, 0.75, 0.85, 0.95] {
            assert_eq!(simple(nc), deltas(&[-6.0, 0.9, 0.0, FADE], nc), "at {nc}");
            assert_eq!(simple(nc).compressor_eff, 1.0);
        }
        let refined = |nc| deltas(&[-6.0, 0.9, -2.0, 0.1], nc);
        let d = refined(0.85);
        assert!((d.compressor_flow - (1.0 - 0.03)).abs() < 1e-12);
        assert!((d.compressor_eff - (1.0 - 0.01)).abs() < 1e-12);
        assert!((refined(0.8).compressor_eff - (1.0 - 0.02)).abs() < 1e-12);
        assert_eq!(refined(0.95).compressor_eff, 1.0);
    }
}
