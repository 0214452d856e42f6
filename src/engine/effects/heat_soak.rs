//! Effect `heat_soak`: the hot section's metal (combustor liner, HPT casing and discs, lumped
//! into one node) takes heat from the gas while it warms up and gives it back when the gas
//! cools. A cold start loses part of the fuel's heat into the metal; a hot restart does not.
//!
//! One state, the metal temperature Tm (normalised by 1000 K), starting at ambient:
//! Q = UA·(T3 − Tm) leaves the combustor gas, and the metal follows with dTm/dt = (T3 − Tm)/τ
//! (heat capacity UA·τ). In steady operation Tm = T3 and nothing is exchanged.
//!
//! Signature: during light-off and acceleration the gas path runs cooler than the model (T34,
//! T4 low, the GG accelerates late for the fuel given), fading over minutes after loading;
//! at steady load no residual. Without it a cold start reads as turbine degradation.
//! Pure: no I/O.

use super::{Channels, MetalNode, Context, CoreView, Effect, EffectSpec, ParamSpec};
use crate::engine::gas_path::Stations;
use crate::signals::Signal;
use std::sync::Arc;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "heat_soak",
    instrument: false,
    channels: Channels::Engine,
    summary: "heat exchange between the combustor gas and a lumped hot-section metal node",
    signature: "gas path cooler than the model during light-off and acceleration (T34, T4 low, \
                late GG acceleration), fading over minutes; no residual at steady load",
    params: &[
        ParamSpec {
            name: "ua_kw_per_k",
            unit: "kW/K",
            default: 0.5,
            min: 0.0,
            max: 5.0,
            doc: "gas-to-metal heat transfer conductance",
            refinement: false,
        },
        ParamSpec {
            name: "tau_s",
            unit: "s",
            default: 300.0,
            min: 10.0,
            max: 3000.0,
            doc: "time constant of the metal node (heat capacity = UA·τ)",
            refinement: false,
        },
    ],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], _channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(HeatSoak {
        ua_w_per_k: p.first().copied().unwrap_or(0.5) * 1e3,
        node: MetalNode {
            tau_s: p.get(1).copied().unwrap_or(300.0),
        },
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct HeatSoak {
    ua_w_per_k: f64,
    node: MetalNode,
}

impl Effect for HeatSoak {
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

    fn heat_to_metal_w(&self, core: &CoreView, x: &[f64]) -> f64 {
        self.ua_w_per_k * (core.t3_k - MetalNode::temperature_k(x[0]))
    }

    fn derivatives(&self, ctx: &Context<'_>, x: &[f64], dx: &mut [f64]) {
        dx[0] = self.node.rate(ctx.core, x[0]);
    }
}

#[cfg(test)]
mod tests {
    use crate::engine::simulation::run_scenario;
    use crate::engine::{Engine, Scenario};
    use crate::health::HealthParams;
    use crate::signals::Phase;

    /// A cold start with heat soak runs the hot section cooler during acceleration and ends at
    /// the same steady point.
    #[test]
    fn cold_metal_cools_the_gas_during_the_start_only() {
        let mut soak = Engine::reference().expect("engine");
        soak.set_param("effects.heat_soak.ua_kw_per_k", 1.0)
            .expect("ua");
        let core = Engine::reference().expect("engine");
        let h = HealthParams::HEALTHY;
        let run = |e: &Engine| {
            run_scenario(&e.model(&h), &Scenario::startup(e.cfg()))
                .expect("runs")
                .0
        };
        let (a, b) = (run(&soak), run(&core));
        let accel = |s: &[crate::engine::TruthSample]| {
            s.iter()
                .find(|x| x.phase == Phase::Acceleration && x.stations.n1_rpm > 6000.0)
                .map(|x| x.t_s)
                .expect("accelerates")
        };
        assert!(accel(&a) > accel(&b), "the soaked start accelerates later");
        let (ea, eb) = (a.last().expect("end"), b.last().expect("end"));
        assert!((ea.stations.power_mw / eb.stations.power_mw - 1.0).abs() < 0.01);
    }
}
