//! Effect `bleed_schedule`: a start/handling bleed valve the model does not know, open at low
//! corrected GG speed and closing around `close_at` of design corrected speed (a smooth closure
//! over ±2 % of speed), dumping the fraction `fraction` of compressor flow overboard.
//!
//! Signature: below the closing speed the compressor works harder for the air the combustor
//! gets — higher fuel for a given speed, hotter T34/T4, slower acceleration, a P2 lower than the
//! model — ending abruptly at the closing speed; no residual above it (steady load).
//! Pure: no states, no I/O.

use super::{Channels, CoreView, Effect, EffectSpec, ParamSpec};
use crate::engine::cycle::T_STD_K;
use crate::signals::Signal;
use std::sync::Arc;

/// Half-width of the closure in corrected-speed fraction.
const WIDTH: f64 = 0.02;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "bleed_schedule",
    instrument: false,
    channels: Channels::Engine,
    summary: "compressor bleed valve open below a corrected GG speed",
    signature: "below the closing speed: P2 low, T34/T4 high and slower acceleration for the \
                fuel; ends at the closing speed; none at load",
    params: &[
        ParamSpec {
            name: "fraction",
            unit: "-",
            default: 0.05,
            min: 0.0,
            max: 0.25,
            doc: "fraction of compressor flow bled when fully open",
            refinement: false,
        },
        ParamSpec {
            name: "close_at",
            unit: "-",
            default: 0.85,
            min: 0.4,
            max: 1.0,
            doc: "corrected GG speed (fraction of design) where the valve is half closed",
            refinement: false,
        },
    ],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], _channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(BleedSchedule {
        fraction: p.first().copied().unwrap_or(0.05),
        close_at: p.get(1).copied().unwrap_or(0.85),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct BleedSchedule {
    fraction: f64,
    close_at: f64,
}

impl Effect for BleedSchedule {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn bleed_fraction(&self, core: &CoreView, _x: &[f64]) -> f64 {
        let nc = core.n1_rpm / (core.t_amb_k / T_STD_K).sqrt() / core.n1_design_rpm;
        self.fraction * 0.5 * (1.0 - ((nc - self.close_at) / WIDTH).tanh())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn open_at_low_speed_closed_at_design() {
        let e = build(&[0.1, 0.8], None);
        let at = |n: f64| e.bleed_fraction(&CoreView::for_tests(n, 300.0), &[]);
        assert!((at(5_000.0) - 0.1).abs() < 1e-6);
        assert!((at(8_000.0) - 0.05).abs() < 1e-9);
        assert!(at(10_000.0) < 1e-6);
    }
}
