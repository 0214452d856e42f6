//! Effect `bleed_schedule`: a start/handling bleed valve the model does not know, open at low
//! corrected GG speed and closing around `close_at` of design corrected speed, dumping the
//! fraction `fraction` of compressor flow overboard.
//!
//! Simple form (what the gap analysis screens): a closure over about ±2 % of speed (a tanh of
//! half-width `width` = 0.02) from the compressor's exit (`port` = 1). Its refinement, and what a
//! datasheet states: a closure spread over the speed range the schedule gives (`width`: the
//! valve is 88 % open at `close_at − width` and 2 % open at `close_at + 2·width`) and a port part
//! way along the compressor (`port`, the fraction of its stages ahead of the port — a stage-8
//! port of 16 stages is 0.5), where the bled air has had only part of the compressor's work: the
//! compressor's power is the smaller by the work the bled air did not receive.
//!
//! Signature: below the closing speed the compressor works harder for the air the combustor
//! gets — higher fuel for a given speed, hotter T34/T4, slower acceleration, a P2 lower than the
//! model — ending at the closing speed; no residual above it (steady load).
//! Pure: no states, no I/O.

use super::{Channels, CoreView, Effect, EffectSpec, ParamSpec};
use crate::engine::cycle::T_STD_K;
use crate::signals::Signal;
use std::sync::Arc;

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
        ParamSpec {
            name: "width",
            unit: "-",
            default: 0.02,
            min: 0.005,
            max: 0.15,
            doc: "half-width of the closure in corrected speed (fraction of design): 12 % of \
                  the bleed still flows at close_at + width, 2 % at close_at + 2 width",
            refinement: true,
        },
        ParamSpec {
            name: "port",
            unit: "-",
            default: 1.0,
            min: 0.0,
            max: 1.0,
            doc: "where the bleed leaves the compressor: the fraction of its stages ahead of \
                  the port (of its log pressure ratio; 1 = compressor exit)",
            refinement: true,
        },
    ],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], _channel: Option<Signal>) -> Arc<dyn Effect> {
    Arc::new(BleedSchedule {
        fraction: p.first().copied().unwrap_or(0.05),
        close_at: p.get(1).copied().unwrap_or(0.85),
        width: p.get(2).copied().unwrap_or(0.02),
        port: p.get(3).copied().unwrap_or(1.0),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct BleedSchedule {
    fraction: f64,
    close_at: f64,
    width: f64,
    port: f64,
}

impl Effect for BleedSchedule {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn bleed_fraction(&self, core: &CoreView, _x: &[f64]) -> f64 {
        let nc = core.n1_rpm / (core.t_amb_k / T_STD_K).sqrt() / core.n1_design_rpm;
        self.fraction * 0.5 * (1.0 - ((nc - self.close_at) / self.width).tanh())
    }

    fn bleed_port(&self) -> f64 {
        self.port
    }

    fn reads_gas_path(&self) -> bool {
        false // corrected GG speed only
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

    #[test]
    fn a_datasheet_schedule_spreads_the_closure_and_names_its_port() {
        // A schedule 6 % open up to 76 %, closed from 88 %: half closed at 82 %.
        let e = build(&[0.06, 0.82, 0.036, 0.5], None);
        let at = |n: f64| e.bleed_fraction(&CoreView::for_tests(n, 300.0), &[]);
        assert!((at(8_200.0) - 0.03).abs() < 1e-9);
        assert!(at(7_600.0) > 0.055 && at(7_900.0) > 0.048);
        assert!(at(8_800.0) < 0.003 && at(8_500.0) < 0.012);
        assert_eq!(e.bleed_port(), 0.5);
        // The simple form bleeds from the compressor's exit.
        assert_eq!(build(&[0.06, 0.82], None).bleed_port(), 1.0);
    }
}
