//! Effect `duct_loss`: the inlet and exhaust ducts lose more (or less) pressure than the engine
//! file says — a fouled inlet filter or silencer, an exhaust stack, diverter damper or heat
//! recovery boiler with a back-pressure the design point did not assume. Two multipliers on the
//! engine file's own loss laws: `inlet_scale` on the inlet loss (ambient → compressor inlet),
//! `exhaust_scale` on the exhaust back-pressure excess (PT exit above ambient). 1 = as the file
//! says; 2 = twice the loss.
//!
//! Signature: steady level offsets that grow with the air flow (the losses scale with flow²):
//! nothing at crank, largest at load. Inlet: P2, P34 and the air flow low for the speed, T34 and
//! the fuel for the power high — a health fit reads it as compressor flow/efficiency loss.
//! Exhaust: P4 high (directly, in proportion), PT pressure ratio and power low for the fuel —
//! read as PT degradation. No lag, no kink. Pure: no states, no I/O.

use super::{Channels, CoreView, DuctLosses, Effect, EffectSpec, ParamSpec};
use crate::signals::Signal;
use std::sync::Arc;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "duct_loss",
    instrument: false,
    channels: Channels::Engine,
    summary: "inlet and exhaust pressure losses other than the engine file's (filter, stack, HRSG)",
    signature: "level offsets growing with air flow, none at crank: P2/P34 low and T34 high for \
                the speed (inlet), P4 high and power low for the fuel (exhaust)",
    params: &[
        ParamSpec {
            name: "inlet_scale",
            unit: "-",
            default: 1.5,
            min: 0.0,
            max: 6.0,
            doc: "multiplier on the engine file's inlet pressure loss",
            refinement: false,
        },
        ParamSpec {
            name: "exhaust_scale",
            unit: "-",
            default: 1.0,
            min: 0.0,
            max: 6.0,
            doc: "multiplier on the engine file's exhaust back-pressure excess",
            refinement: false,
        },
    ],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], _channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(DuctLoss {
        inlet: p.first().copied().unwrap_or(1.5),
        exhaust: p.get(1).copied().unwrap_or(1.0),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct DuctLoss {
    inlet: f64,
    exhaust: f64,
}

impl Effect for DuctLoss {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn duct_losses(&self, _core: &CoreView, _x: &[f64], d: &mut DuctLosses) {
        d.inlet *= self.inlet;
        d.exhaust *= self.exhaust;
    }
}

#[cfg(test)]
mod tests {
    use crate::engine::steady::{solve, Demand, SteadyInputs};
    use crate::engine::Engine;
    use crate::health::HealthParams;

    /// At the same power, doubling the inlet loss doubles P_amb − P1 and lowers P2; tripling the
    /// exhaust excess triples P4 − P_amb; scales of 1 are the engine file's point exactly.
    #[test]
    fn scales_multiply_the_file_losses_at_a_steady_point() {
        let core = Engine::reference().expect("engine");
        let c = core.cfg();
        let inp = SteadyInputs {
            demand: Demand::PowerMw(0.8 * c.design.power_mw),
            n2_rpm: c.design.pt_speed_rpm,
            t_amb_k: c.ambient.temperature_k,
            p_amb_kpa: c.ambient.pressure_kpa,
        };
        let h = HealthParams::HEALTHY;
        let at = |inlet: f64, exhaust: f64| {
            let mut e = core.clone();
            e.set_param("effects.duct_loss.inlet_scale", inlet).expect("inlet");
            e.set_param("effects.duct_loss.exhaust_scale", exhaust)
                .expect("exhaust");
            solve(&e.model(&h), &inp, None).expect("solves")
        };
        let p_amb = inp.p_amb_kpa;
        let base = solve(&core.model(&h), &inp, None).expect("core");
        let one = at(1.0, 1.0);
        assert!((one.p2_kpa - base.p2_kpa).abs() < 1e-9 * base.p2_kpa);
        assert!((one.p4_kpa - base.p4_kpa).abs() < 1e-9 * base.p4_kpa);
        let inlet2 = at(2.0, 1.0);
        let (d0, d2) = (p_amb - base.p1_kpa, p_amb - inlet2.p1_kpa);
        // The flow changes a little with the loss, so the ratio is near (not exactly) 2.
        assert!(d0 > 0.0 && (d2 / d0 - 2.0).abs() < 0.05, "{d0} → {d2}");
        assert!(inlet2.p2_kpa < base.p2_kpa);
        assert!(inlet2.fuel_kg_s > base.fuel_kg_s, "more fuel for the same power");
        let ex3 = at(1.0, 3.0);
        let (e0, e3) = (base.p4_kpa - p_amb, ex3.p4_kpa - p_amb);
        assert!(e0 > 0.0 && (e3 / e0 - 3.0).abs() < 0.1, "{e0} → {e3}");
        assert!(ex3.fuel_kg_s > base.fuel_kg_s);
    }
}
