//! Effect `tip_clearance`: the HPT's tip clearance follows the casing temperature, which lags
//! the gas; while the gas is hotter than the casing the clearance differs from the steady one
//! and the HPT efficiency with it, by `eff_pct_per_100k` per 100 K of gas-to-casing difference.
//!
//! One state, the casing temperature (normalised by 1000 K), lagging the HPT inlet gas (T3)
//! with `tau_s`; ambient at rest, equal to T3 in steady operation (no effect at steady load).
//!
//! Signature: HPT work off the model while the hot section warms (acceleration, loading):
//! T34 and the GG speed for the fuel given deviate in proportion to how far the gas is ahead of
//! the casing, fading with the casing's time constant. Pure: no I/O.

use super::{Channels, MetalNode, ComponentDeltas, Context, CoreView, Effect, EffectSpec, ParamSpec};
use crate::engine::gas_path::Stations;
use crate::signals::Signal;
use std::sync::Arc;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "tip_clearance",
    instrument: false,
    channels: Channels::Engine,
    summary: "HPT efficiency change with the casing's thermal lag (tip clearance)",
    signature: "HPT work off the model while the gas leads the casing temperature (acceleration, \
                loading), fading with the casing time constant; none at steady load",
    params: &[
        ParamSpec {
            name: "eff_pct_per_100k",
            unit: "%/100 K",
            default: -0.5,
            min: -5.0,
            max: 5.0,
            doc: "HPT efficiency change per 100 K of gas temperature above the casing",
        },
        ParamSpec {
            name: "tau_s",
            unit: "s",
            default: 200.0,
            min: 10.0,
            max: 3000.0,
            doc: "casing time constant",
        },
    ],
    build,
};

fn build(p: &[f64], _channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(TipClearance {
        per_k: p.first().copied().unwrap_or(-0.5) / 100.0 / 100.0,
        node: MetalNode {
            tau_s: p.get(1).copied().unwrap_or(200.0),
        },
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct TipClearance {
    per_k: f64,
    node: MetalNode,
}

impl Effect for TipClearance {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn n_states(&self) -> usize {
        1
    }

    fn rest_states(&self, core: &CoreView, x: &mut [f64]) {
        x[0] = MetalNode::rest(core);
    }

    fn steady_states(&self, _core: &CoreView, stations: &Stations, x: &mut [f64]) {
        x[0] = MetalNode::steady(stations);
    }

    fn component_deltas(&self, core: &CoreView, x: &[f64], d: &mut ComponentDeltas) {
        let lead_k = core.t3_k - MetalNode::temperature_k(x[0]);
        d.hpt_eff *= (1.0 + self.per_k * lead_k).clamp(0.5, 1.5);
    }

    fn derivatives(&self, ctx: &Context<'_>, x: &[f64], dx: &mut [f64]) {
        dx[0] = self.node.rate(ctx.core, x[0]);
    }
}
