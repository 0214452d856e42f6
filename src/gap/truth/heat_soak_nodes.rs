//! Hidden truth `heat_soak_nodes` (expected verdict `heat_soak`): the hot section's metal as
//! three conducting nodes instead of the library's single lumped node.
//!
//! Form: a combustor liner node L and an HPT node H (nozzle, shroud, disc rim) take heat from
//! the combustor gas through their own conductances; an outer casing node C touches no gas and
//! warms only by conduction from L and H:
//! - C_L dT_L/dt = hA_L (T3 − T_L) − k_LC (T_L − T_C)
//! - C_H dT_H/dt = hA_H (T3 − T_H) − k_HC (T_H − T_C)
//! - C_C dT_C/dt = k_LC (T_L − T_C) + k_HC (T_H − T_C)
//!
//! and the gas gives Q = hA_L (T3 − T_L) + hA_H (T3 − T_H). No loss to ambient, so at steady
//! load every node reaches T3 and nothing is exchanged (the steady point is the core model's).
//! The gas-side time constants (L 20–90 s, H 60–300 s) and the casing's conduction time
//! constant (300–1500 s) differ, so the absorbed heat decays as a sum of three exponentials,
//! not the lumped node's one.
//!
//! Magnitude: the total metal heat capacity C_L + C_H + C_C, kJ/K, drawn so that warming all
//! metal from ambient to the start's final T3 takes 1–5 % of the fuel heat burnt during the
//! start (REFERENCE §5). The candidate's counterpart is its capacity UA·τ.
//!
//! Signature: T34, T4, P34 and the GG speed low for the fuel given during light-off and
//! acceleration, relaxing over minutes through loading; nothing at steady load.
//! Pure: no I/O.

use super::PlantScale;
use crate::engine::effects::{Context, CoreView, Effect};
use crate::engine::gas_path::Stations;
use rand::Rng;

/// Node temperatures are stored normalised by this, K.
const T_SCALE_K: f64 = 1000.0;

/// The three-node metal model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct HeatSoakNodes {
    /// Heat capacities of liner, HPT and casing nodes, J/K.
    pub(crate) cap_j_per_k: [f64; 3],
    /// Gas-to-liner and gas-to-HPT conductances, W/K.
    pub(crate) ha_w_per_k: [f64; 2],
    /// Liner-to-casing and HPT-to-casing conductances, W/K.
    pub(crate) k_w_per_k: [f64; 2],
}

impl HeatSoakNodes {
    /// Draws a truth for a start that burns `scale.fuel_heat_j` and raises T3 by
    /// `scale.t3_rise_k`; returns it with its magnitude (total capacity, kJ/K).
    pub(crate) fn draw(rng: &mut impl Rng, scale: &PlantScale) -> (HeatSoakNodes, f64) {
        let fraction = rng.random_range(0.01..0.05);
        let total = fraction * scale.fuel_heat_j / scale.t3_rise_k.max(100.0);
        let share_l = rng.random_range(0.15..0.3);
        let share_h = rng.random_range(0.25..0.4);
        let cap = [
            share_l * total,
            share_h * total,
            (1.0 - share_l - share_h) * total,
        ];
        let tau_l = rng.random_range(20.0..90.0);
        let tau_h = rng.random_range(60.0..300.0);
        let tau_c = rng.random_range(300.0..1500.0);
        // The casing's conduction time constant C_C/(k_LC + k_HC), split between its two
        // neighbours.
        let split = rng.random_range(0.3..0.7);
        let k_total = cap[2] / tau_c;
        let truth = HeatSoakNodes {
            cap_j_per_k: cap,
            ha_w_per_k: [cap[0] / tau_l, cap[1] / tau_h],
            k_w_per_k: [split * k_total, (1.0 - split) * k_total],
        };
        (truth, total / 1e3)
    }

    /// Heat flows (gas→L, gas→H, L→C, H→C), W, at gas temperature `t3_k` and node states `x`.
    fn flows(&self, t3_k: f64, x: &[f64]) -> [f64; 4] {
        let [tl, th, tc] = [x[0], x[1], x[2]].map(|v| v * T_SCALE_K);
        [
            self.ha_w_per_k[0] * (t3_k - tl),
            self.ha_w_per_k[1] * (t3_k - th),
            self.k_w_per_k[0] * (tl - tc),
            self.k_w_per_k[1] * (th - tc),
        ]
    }
}

impl Effect for HeatSoakNodes {
    fn name(&self) -> &'static str {
        "heat_soak_nodes"
    }

    fn n_states(&self) -> usize {
        3
    }

    fn rest_states(&self, core: &CoreView, x: &mut [f64]) {
        x.fill(core.t_amb_k / T_SCALE_K);
    }

    fn steady_states(&self, _core: &CoreView, stations: &Stations, x: &mut [f64]) {
        x.fill(stations.t3_k / T_SCALE_K);
    }

    fn heat_to_metal_w(&self, core: &CoreView, x: &[f64]) -> f64 {
        let q = self.flows(core.t3_k, x);
        q[0] + q[1]
    }

    fn derivatives(&self, ctx: &Context<'_>, x: &[f64], dx: &mut [f64]) {
        let [q_l, q_h, q_lc, q_hc] = self.flows(ctx.core.t3_k, x);
        let c = self.cap_j_per_k.map(|c| c.max(1.0) * T_SCALE_K);
        dx[0] = (q_l - q_lc) / c[0];
        dx[1] = (q_h - q_hc) / c[1];
        dx[2] = (q_lc + q_hc) / c[2];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn core(t3_k: f64) -> CoreView {
        CoreView {
            t_s: 0.0,
            n1_rpm: 9000.0,
            n2_rpm: 3600.0,
            p2_kpa: 2000.0,
            t3_k,
            p34_kpa: 500.0,
            t_amb_k: 288.15,
            p_amb_kpa: 101.325,
            n1_design_rpm: 9500.0,
            fuel_design_kg_s: 2.0,
        }
    }

    /// Held at a constant gas temperature, every node converges to it, heat flows in while
    /// the metal is colder, and the energy the gas gave equals what the metal stored.
    #[test]
    fn nodes_converge_to_the_gas_temperature_and_conserve_energy() {
        let scale = PlantScale {
            fuel_heat_j: 2.0e10,
            t3_rise_k: 1100.0,
        };
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let (t, mag) = HeatSoakNodes::draw(&mut rng, &scale);
        let total: f64 = t.cap_j_per_k.iter().sum();
        assert!((total / 1e3 - mag).abs() < 1e-9);
        assert!((0.01..0.05).contains(&(total * 1100.0 / 2.0e10)));
        let c = core(1400.0);
        let mut x = [0.0; 3];
        t.rest_states(&c, &mut x);
        let stations = Stations::default();
        let (mut absorbed, mut stored0) = (0.0, 0.0);
        for (i, v) in x.iter().enumerate() {
            stored0 += t.cap_j_per_k[i] * v * T_SCALE_K;
        }
        let dt = 1.0;
        let mut first_q = None;
        for _ in 0..20_000 {
            let q = t.heat_to_metal_w(&c, &x);
            first_q.get_or_insert(q);
            assert!(q >= -1e-6, "metal colder than the gas takes heat");
            let ctx = Context {
                core: &c,
                stations: &stations,
                metered_fuel_kg_s: 0.0,
            };
            let mut dx = [0.0; 3];
            t.derivatives(&ctx, &x, &mut dx);
            absorbed += q * dt;
            for k in 0..3 {
                x[k] += dt * dx[k];
            }
        }
        assert!(first_q.expect("ran") > 0.0);
        for v in x {
            assert!(
                (v * T_SCALE_K - 1400.0).abs() < 0.5,
                "node at {} K",
                v * T_SCALE_K
            );
        }
        let stored: f64 = (0..3)
            .map(|i| t.cap_j_per_k[i] * x[i] * T_SCALE_K)
            .sum::<f64>()
            - stored0;
        assert!(
            (absorbed / stored - 1.0).abs() < 1e-3,
            "{absorbed} vs {stored}"
        );
        assert!(t.heat_to_metal_w(&c, &x).abs() < 1e-3 * first_q.expect("ran"));
    }

    use rand::SeedableRng;
}
