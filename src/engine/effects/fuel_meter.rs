//! Effect `fuel_meter`: the fuel-flow meter reads by a factor `1 + scale` of the fuel that
//! burns — a meter calibration, a density or heating-value assumption that drifted (the model
//! burns what the meter says; a 3 % error is as much energy as 3 points of turbine efficiency).
//!
//! The fuel flow is an *input* of the replay (measured-fuel mode): its error is never seen on
//! the fuel channel itself, only as every output being a little hot or cold for the fuel given,
//! which the health parameters absorb almost completely (see the gap analysis's aliases).
//! Signature: all gas-path temperatures, pressures and power off in the same direction, in
//! proportion to the fuel flow, from light-off to load; at rest nothing.
//! Pure: acts on the fuel delivery hook only, no states.

use super::{Channels, CoreView, Effect, EffectSpec, ParamSpec};
use crate::signals::Signal;
use std::sync::Arc;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "fuel_meter",
    instrument: true,
    channels: Channels::Engine,
    summary: "the fuel-flow meter reads a factor (1 + scale) of the fuel that burns",
    signature: "every output hot or cold for the fuel given, in proportion to the fuel flow; \
                nearly the same as a change of turbine efficiency and flow (aliased with health)",
    params: &[ParamSpec {
        name: "scale",
        unit: "fraction",
        default: 0.0,
        min: -0.1,
        max: 0.1,
        doc: "relative error of the metered fuel flow (0.02 = the meter reads 2 % high)",
        refinement: false,
    }],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], _channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(FuelMeter {
        scale: p.first().copied().unwrap_or(0.0),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct FuelMeter {
    scale: f64,
}

impl Effect for FuelMeter {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn fuel_delivered(&self, upstream_kg_s: f64, _core: &CoreView, _x: &[f64]) -> f64 {
        self.steady_fuel_burnt(upstream_kg_s)
    }

    fn steady_fuel_burnt(&self, metered_kg_s: f64) -> f64 {
        metered_kg_s / (1.0 + self.scale)
    }
}

#[cfg(test)]
mod tests {
    use crate::engine::steady::{solve, Demand, SteadyInputs};
    use crate::engine::Engine;
    use crate::health::HealthParams;

    /// A meter reading 3 % high: the engine burns 3 % less than metered, so at the same metered
    /// fuel it makes less power and runs cooler.
    #[test]
    fn a_meter_reading_high_means_less_fuel_burns() {
        let core = Engine::reference().expect("engine");
        let mut high = core.clone();
        high.set_param("effects.fuel_meter.scale", 0.03)
            .expect("scale");
        let inputs = SteadyInputs {
            t_amb_k: 288.15,
            p_amb_kpa: 101.325,
            n2_rpm: core.cfg().design.pt_speed_rpm,
            demand: Demand::FuelKgS(1.2),
        };
        let h = HealthParams::HEALTHY;
        let a = solve(&core.model(&h), &inputs, None).expect("core");
        let b = solve(&high.model(&h), &inputs, None).expect("meter");
        assert!(b.stations.power_mw < 0.98 * a.stations.power_mw, "{b:?} vs {a:?}");
        assert!(b.stations.t4_k < a.stations.t4_k);
    }
}
