//! Effect `inlet_temperature`: the compressor-inlet thermometer T1 reads `offset_k` above the
//! air the engine breathes — sun or a hot wall on the sensor, a radiation shield missing.
//!
//! T1 is an *input* of the model (the ambient the replay runs in, and every corrected speed and
//! flow), so its error is not seen on its own channel: the model runs at the wrong ambient and
//! the outputs are all slightly off, in a way the health parameters absorb almost completely
//! (see the gap analysis's aliases). The effect corrects the ambient the model is given.
//! Signature: outputs off as for a warmer or colder day, from rest to load: T2 and T34 most,
//! the GG speed against power.
//! Pure: acts on the model's ambient only, no states.

use super::{Channels, Effect, EffectSpec, ParamSpec};
use crate::signals::Signal;
use std::sync::Arc;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "inlet_temperature",
    instrument: true,
    channels: Channels::Engine,
    summary: "the inlet thermometer T1 reads offset_k above the air the engine breathes",
    signature: "outputs off as on a warmer or colder day, from rest to load (T2, T34 most); \
                nearly the same as a change of compressor health (aliased with health)",
    params: &[ParamSpec {
        name: "offset_k",
        unit: "K",
        default: 0.0,
        min: -10.0,
        max: 10.0,
        doc: "what the T1 instrument adds to the true inlet temperature",
        refinement: false,
    }],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], _channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(InletTemperature {
        offset_k: p.first().copied().unwrap_or(0.0),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct InletTemperature {
    offset_k: f64,
}

impl Effect for InletTemperature {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn true_ambient(&self, t_amb_k: f64, p_amb_kpa: f64) -> (f64, f64) {
        (t_amb_k - self.offset_k, p_amb_kpa)
    }
}

#[cfg(test)]
mod tests {
    use crate::engine::Engine;
    use crate::health::HealthParams;

    /// The model is given the measured T1; with the effect it runs at T1 − offset.
    #[test]
    fn the_model_runs_at_the_true_inlet_temperature() {
        let mut e = Engine::reference().expect("engine");
        let h = HealthParams::HEALTHY;
        assert_eq!(e.model_at(&h, 300.0, 101.0).consts.t_amb_k, 300.0);
        e.set_param("effects.inlet_temperature.offset_k", 2.5)
            .expect("offset");
        let m = e.model_at(&h, 300.0, 101.0);
        assert!((m.consts.t_amb_k - 297.5).abs() < 1e-12);
        assert_eq!(m.consts.p_amb_kpa, 101.0);
    }
}
