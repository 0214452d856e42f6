//! Hidden truth `clearance_nodes` (expected verdict `tip_clearance`): the HPT tip clearance
//! follows a casing whose metal has two time constants — a thin shell that follows the gas
//! within a minute and heavy flanges and rails that take many minutes — against the library's
//! single casing node.
//!
//! Form: shell and flange nodes each lag the combustor gas T3 (τ_shell 20–90 s, τ_flange
//! 300–1500 s); the casing temperature is their mix w·T_shell + (1 − w)·T_flange (w 0.3–0.7)
//! and the HPT efficiency changes by k per 100 K of gas above the casing,
//! η × (1 + k·(T3 − T_casing)/100 K), k −0.5 … −2 %/100 K (the clearance opens while the
//! casing lags). In steady operation both nodes reach T3: no effect at steady load.
//! Magnitude compared: k in %/100 K (the candidate's `eff_pct_per_100k`).
//!
//! Signature: HPT work low while the hot section warms: T34 high and the GG slow for the fuel
//! given, with a fast part fading within a minute or two and a slow tail over the warm-up and
//! loading; nothing at steady load. Pure: no I/O.

use crate::engine::effects::{lag_rate, ComponentDeltas, Context, CoreView, Effect};
use crate::engine::gas_path::Stations;
use rand::Rng;

/// Node temperatures are stored normalised by this, K.
const T_SCALE_K: f64 = 1000.0;

/// Two-time-constant casing and its clearance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ClearanceNodes {
    /// Efficiency change per kelvin of gas above the casing (fraction per K).
    pub(crate) per_k: f64,
    pub(crate) tau_shell_s: f64,
    pub(crate) tau_flange_s: f64,
    /// Weight of the shell in the casing temperature.
    pub(crate) w_shell: f64,
}

impl ClearanceNodes {
    /// Draws a truth; returns it with its magnitude (%/100 K).
    pub(crate) fn draw(rng: &mut impl Rng) -> (ClearanceNodes, f64) {
        let pct = -rng.random_range(0.5..2.0);
        let t = ClearanceNodes {
            per_k: pct / 100.0 / 100.0,
            tau_shell_s: rng.random_range(20.0..90.0),
            tau_flange_s: rng.random_range(300.0..1500.0),
            w_shell: rng.random_range(0.3..0.7),
        };
        (t, pct)
    }

    /// Casing temperature, K, from the node states.
    pub(crate) fn casing_k(&self, x: &[f64]) -> f64 {
        (self.w_shell * x[0] + (1.0 - self.w_shell) * x[1]) * T_SCALE_K
    }
}

impl Effect for ClearanceNodes {
    fn name(&self) -> &'static str {
        "clearance_nodes"
    }

    fn n_states(&self) -> usize {
        2
    }

    fn rest_states(&self, core: &CoreView, x: &mut [f64]) {
        x.fill(core.t_amb_k / T_SCALE_K);
    }

    fn steady_states(&self, _core: &CoreView, stations: &Stations, x: &mut [f64]) {
        x.fill(stations.t3_k / T_SCALE_K);
    }

    fn component_deltas(&self, core: &CoreView, x: &[f64], d: &mut ComponentDeltas) {
        let lead_k = core.t3_k - self.casing_k(x);
        d.hpt_eff *= (1.0 + self.per_k * lead_k).clamp(0.5, 1.5);
    }

    fn derivatives(&self, ctx: &Context<'_>, x: &[f64], dx: &mut [f64]) {
        let gas = ctx.core.t3_k / T_SCALE_K;
        dx[0] = lag_rate(gas, x[0], self.tau_shell_s);
        dx[1] = lag_rate(gas, x[1], self.tau_flange_s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At a constant gas temperature the efficiency loss falls fast at first (the shell) and
    /// then slowly (the flanges), reaching none once the casing is at the gas temperature.
    #[test]
    fn loss_decays_with_two_time_constants_to_none() {
        let t = ClearanceNodes {
            per_k: -1.0 / 100.0 / 100.0,
            tau_shell_s: 30.0,
            tau_flange_s: 600.0,
            w_shell: 0.5,
        };
        let core = CoreView {
            t_s: 0.0,
            n1_rpm: 9000.0,
            n2_rpm: 3600.0,
            p2_kpa: 2000.0,
            t3_k: 1300.0,
            p34_kpa: 500.0,
            t_amb_k: 300.0,
            p_amb_kpa: 101.325,
            n1_design_rpm: 9500.0,
            fuel_design_kg_s: 2.0,
        };
        let st = Stations::default();
        let ctx = Context {
            core: &core,
            stations: &st,
            metered_fuel_kg_s: 1.0,
        };
        let loss = |x: &[f64]| {
            let mut d = ComponentDeltas::NONE;
            t.component_deltas(&core, x, &mut d);
            1.0 - d.hpt_eff
        };
        let mut x = [0.0; 2];
        t.rest_states(&core, &mut x);
        assert!((loss(&x) - 0.10).abs() < 1e-12, "1 %/100 K × 1000 K");
        let mut at = Vec::new();
        for i in 0..=6000 {
            if i % 100 == 0 {
                at.push(loss(&x));
            }
            let mut dx = [0.0; 2];
            t.derivatives(&ctx, &x, &mut dx);
            x[0] += dx[0];
            x[1] += dx[1];
        }
        // After 100 s the shell is nearly at the gas: its half of the loss is gone, the
        // flanges' half has decayed by e^(−100/600).
        assert!(
            (at[1] - 0.05 * (-100.0f64 / 600.0).exp()).abs() < 0.003,
            "{}",
            at[1]
        );
        // The slow tail: still a tenth of the first-minute loss after 10 minutes...
        assert!(at[6] > 0.01, "{}", at[6]);
        // ...and nearly none after an hour.
        assert!(at[60] < 0.001, "{}", at[60]);
    }
}
