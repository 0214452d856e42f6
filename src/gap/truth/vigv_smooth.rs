//! Hidden truth `vigv_smooth` (expected verdict `vigv_schedule`): the compressor's inlet guide
//! vanes run a schedule the map does not assume at low corrected speed, changing both the flow
//! capacity and the efficiency there, with a smooth fade — against the library's flow-only
//! offset with a linear fade over a fixed 20 % of speed.
//!
//! Form: compressor flow × (1 + δ_w·s(n_c)), efficiency × (1 + δ_η·s(n_c)), s the quintic
//! smootherstep from 1 at `end − span` to 0 at `end` (fraction of design corrected speed).
//! Magnitudes: |δ_w| 4–10 % (either sign: vanes more closed or more open than the map
//! assumes), δ_η −0.5 … −2 % (off-schedule vanes lose efficiency either way), `end`
//! 0.82–0.95, `span` 0.1–0.3. Zero above `end`: the steady load point is the core model's.
//! Magnitude compared: δ_w in % (the candidate's `flow_delta_pct`).
//!
//! Signature: air flow, P2 and T34 off the model from crank through the warm-up, fading
//! smoothly as the speed approaches `end`; nothing at load. Pure: no states, no I/O.

use crate::engine::cycle::T_STD_K;
use crate::engine::effects::{ComponentDeltas, CoreView, Effect};
use rand::Rng;

/// The smooth vane-schedule offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct VigvSmooth {
    /// Flow change at low speed (fraction).
    pub(crate) flow_delta: f64,
    /// Efficiency change at low speed (fraction).
    pub(crate) eff_delta: f64,
    pub(crate) end: f64,
    pub(crate) span: f64,
}

impl VigvSmooth {
    /// Draws a truth; returns it with its magnitude (flow change, %).
    pub(crate) fn draw(rng: &mut impl Rng) -> (VigvSmooth, f64) {
        let size = rng.random_range(0.04..0.10);
        let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        let t = VigvSmooth {
            flow_delta: sign * size,
            eff_delta: -rng.random_range(0.005..0.02),
            end: rng.random_range(0.82..0.95),
            span: rng.random_range(0.1..0.3),
        };
        (t, 100.0 * t.flow_delta)
    }

    /// Share of the offset present at corrected speed `nc` (1 at low speed, 0 above `end`).
    pub(crate) fn share(&self, nc: f64) -> f64 {
        super::falling_smoothstep(nc, self.end, self.span)
    }
}

impl Effect for VigvSmooth {
    fn name(&self) -> &'static str {
        "vigv_smooth"
    }

    fn component_deltas(&self, core: &CoreView, _x: &[f64], d: &mut ComponentDeltas) {
        let nc = core.n1_rpm / (core.t_amb_k / T_STD_K).sqrt() / core.n1_design_rpm;
        let s = self.share(nc);
        d.compressor_flow *= 1.0 + self.flow_delta * s;
        d.compressor_eff *= 1.0 + self.eff_delta * s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Full offset at low speed, none above `end`, monotone in between, flow and efficiency
    /// together.
    #[test]
    fn offset_fades_smoothly_to_nothing_at_the_end_speed() {
        let t = VigvSmooth {
            flow_delta: -0.06,
            eff_delta: -0.01,
            end: 0.9,
            span: 0.2,
        };
        let at = |nc: f64| {
            let core = CoreView {
                t_s: 0.0,
                n1_rpm: nc * 9500.0,
                n2_rpm: 0.0,
                p2_kpa: 500.0,
                t3_k: 900.0,
                p34_kpa: 150.0,
                t_amb_k: T_STD_K,
                p_amb_kpa: 101.325,
                n1_design_rpm: 9500.0,
                fuel_design_kg_s: 2.0,
            };
            let mut d = ComponentDeltas::NONE;
            t.component_deltas(&core, &[], &mut d);
            d
        };
        assert!((at(0.5).compressor_flow - 0.94).abs() < 1e-12);
        assert!((at(0.5).compressor_eff - 0.99).abs() < 1e-12);
        assert_eq!(at(0.9), ComponentDeltas::NONE);
        assert_eq!(at(1.0), ComponentDeltas::NONE);
        let mut prev = 0.0;
        for i in 0..=400 {
            let f = at(0.5 + i as f64 / 1000.0).compressor_flow;
            assert!(f >= prev, "monotone");
            prev = f;
        }
        // Half way through the fade the share is exactly one half (smootherstep symmetry).
        assert!((t.share(0.8) - 0.5).abs() < 1e-12);
    }
}
