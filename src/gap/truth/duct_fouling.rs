//! Hidden truth `duct_fouling` (expected verdict `duct_loss`): a dust-caked inlet filter and a
//! heat-recovery boiler behind the exhaust, against the library's two constant multipliers on
//! the engine file's flow² loss laws.
//!
//! Form: the cake's flow is laminar (Darcy), so its extra loss grows in proportion to the flow,
//! not its square: inlet-loss multiplier `1 + a / r`, r the corrected GG speed as a fraction of
//! design (the flow's proxy), floored at 0.05 — `a` extra at design flow, far more (relative to
//! the file's loss) at low flow. The boiler's tube banks are turbulent with a Reynolds
//! dependence, loss ∝ flow^1.8: exhaust multiplier `1 + b · r^−0.2`.
//! Magnitudes: a 0.6–2.0 (a filter at 1.6–3× its clean loss), b 0.3–1.5; the magnitude
//! compared is `a` (the candidate's `inlet_scale` − 1).
//!
//! Signature: P2, P34 low and T34 high for the speed, P4 high, power low for the fuel, growing
//! with flow from light-off to load; no lag. Pure: no states, no I/O.

use crate::engine::cycle::T_STD_K;
use crate::engine::effects::{CoreView, DuctLosses, Effect};
use rand::Rng;

/// The fouled inlet filter and exhaust boiler.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct DuctFouling {
    /// Extra inlet loss at design flow, multiple of the file's loss.
    pub(crate) inlet_extra: f64,
    /// Extra exhaust back-pressure at design flow, multiple of the file's excess.
    pub(crate) exhaust_extra: f64,
}

/// Least flow proxy: keeps the laminar term finite at standstill (where the loss is nil anyway).
const R_MIN: f64 = 0.05;

impl DuctFouling {
    /// Draws a truth; returns it with its magnitude (`inlet_extra`).
    pub(crate) fn draw(rng: &mut impl Rng) -> (DuctFouling, f64) {
        let t = DuctFouling {
            inlet_extra: rng.random_range(0.6..2.0),
            exhaust_extra: rng.random_range(0.3..1.5),
        };
        (t, t.inlet_extra)
    }

    /// The multipliers at corrected speed fraction `r`.
    pub(crate) fn multipliers(&self, r: f64) -> DuctLosses {
        let r = r.max(R_MIN);
        DuctLosses {
            inlet: 1.0 + self.inlet_extra / r,
            exhaust: 1.0 + self.exhaust_extra * r.powf(-0.2),
        }
    }
}

impl Effect for DuctFouling {
    fn name(&self) -> &'static str {
        "duct_fouling"
    }

    fn duct_losses(&self, core: &CoreView, _x: &[f64], d: &mut DuctLosses) {
        let r = core.n1_rpm / (core.t_amb_k / T_STD_K).sqrt() / core.n1_design_rpm;
        let m = self.multipliers(r);
        d.inlet *= m.inlet;
        d.exhaust *= m.exhaust;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At design flow the multipliers are 1 + a and 1 + b; below it the inlet's grows as 1/r
    /// (laminar cake against the file's r²), the exhaust's slowly.
    #[test]
    fn multipliers_follow_the_laminar_and_boiler_laws() {
        let t = DuctFouling {
            inlet_extra: 1.0,
            exhaust_extra: 0.5,
        };
        let d = t.multipliers(1.0);
        assert!((d.inlet - 2.0).abs() < 1e-12 && (d.exhaust - 1.5).abs() < 1e-12);
        let h = t.multipliers(0.5);
        assert!((h.inlet - 3.0).abs() < 1e-12);
        assert!((h.exhaust - (1.0 + 0.5 * 0.5f64.powf(-0.2))).abs() < 1e-12);
        assert!(t.multipliers(0.0).inlet.is_finite());
    }
}
