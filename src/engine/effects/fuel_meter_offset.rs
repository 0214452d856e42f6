//! Effect `fuel_meter_offset`: the fuel-flow meter reads `offset_kg_s` more than the fuel that
//! burns whenever fuel flows — a zero offset the meter's zero reading cannot show, because the
//! control system's low-flow cut-off (or a shut-off valve's own signal) shows exactly 0 while
//! no fuel flows (when the meter shows its offset at rest, `Recording::fuel_meter_zero` reads
//! and removes it before any model runs).
//!
//! Why it is its own effect beside [`super::fuel_meter`]'s scale: an offset is a larger share of
//! the fuel the lower the flow — 0.008 kg/s is 12 % of a 0.07-kg/s idle and 0.5 % at full load —
//! so it shows most at light-off and idle, where health barely acts, and a scale (or the health
//! vector) cannot take it up: the diagnosis then bends the health to the idle's misfit.
//!
//! The offset fades in over the first `2·|offset|` of metered flow (so no flow reads as none
//! burnt, and the fuel burnt never falls below half the metered flow): continuous in the
//! metered flow and in the parameter, for the fits. Signature: every output hot or cold for the
//! fuel given, most at light-off and idle and fading with load; at rest nothing.
//! Pure: acts on the fuel delivery hook only, no states.

use super::{Channels, CoreView, Effect, EffectSpec, ParamSpec};
use crate::signals::Signal;
use std::sync::Arc;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "fuel_meter_offset",
    instrument: true,
    channels: Channels::Engine,
    summary: "the fuel-flow meter reads a fixed offset above the fuel that burns while fuel flows",
    signature: "every output hot or cold for the fuel given, most at light-off and idle and \
                fading with load (a zero offset the meter's reading at rest does not show)",
    params: &[ParamSpec {
        name: "offset_kg_s",
        unit: "kg/s",
        default: 0.0,
        min: -0.2,
        max: 0.2,
        doc: "metered minus burnt fuel flow while fuel flows (0.005 = the meter reads 5 g/s high)",
        refinement: false,
    }],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], _channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(FuelMeterOffset {
        offset_kg_s: p.first().copied().unwrap_or(0.0),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct FuelMeterOffset {
    offset_kg_s: f64,
}

impl FuelMeterOffset {
    /// The fuel that burns for a metered flow: the offset taken off in full above `2·|offset|`
    /// of metered flow, in proportion below it.
    fn burnt(&self, metered_kg_s: f64) -> f64 {
        let band = 2.0 * self.offset_kg_s.abs();
        if metered_kg_s <= 0.0 || band == 0.0 {
            return metered_kg_s;
        }
        let w = (metered_kg_s / band).min(1.0);
        (metered_kg_s - self.offset_kg_s * w).max(0.0)
    }
}

impl Effect for FuelMeterOffset {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn fuel_delivered(&self, upstream_kg_s: f64, _core: &CoreView, _x: &[f64]) -> f64 {
        self.burnt(upstream_kg_s)
    }

    fn steady_fuel_burnt(&self, metered_kg_s: f64) -> f64 {
        self.burnt(metered_kg_s)
    }
}

#[cfg(test)]
mod tests {
    use super::FuelMeterOffset;

    #[test]
    fn the_offset_is_taken_off_while_fuel_flows_and_never_at_rest() {
        let high = FuelMeterOffset { offset_kg_s: 0.008 };
        assert_eq!(high.burnt(0.0), 0.0);
        assert!((high.burnt(1.6) - 1.592).abs() < 1e-12);
        assert!((high.burnt(0.068) - 0.060).abs() < 1e-12);
        // In the fade band: half the metered flow burns at its top, continuously.
        assert!((high.burnt(0.016) - 0.008).abs() < 1e-12);
        assert!((high.burnt(0.008) - 0.004).abs() < 1e-12);
        let low = FuelMeterOffset {
            offset_kg_s: -0.005,
        };
        assert_eq!(low.burnt(0.0), 0.0);
        assert!((low.burnt(1.0) - 1.005).abs() < 1e-12);
        // Continuous in the metered flow across the band's edge.
        let edge = 2.0 * 0.008;
        assert!((high.burnt(edge - 1e-9) - high.burnt(edge + 1e-9)).abs() < 1e-8);
    }
}
