//! Hidden truth `bleed_smooth` (expected verdict `bleed_schedule`): a handling-bleed valve whose
//! opening follows a smooth schedule in corrected GG speed, against the library's narrow
//! tanh step (±2 % of speed).
//!
//! Form: bleed fraction b(n_c) = f · s(n_c), with s the quintic "smootherstep" (C²) that falls
//! from 1 (fully open) at `close_at − span` to 0 (closed) at `close_at`, span 8–18 % of design
//! corrected speed — the valve closes gradually over the whole idle-to-load range, not at one
//! speed. Fully closed above `close_at`, so the steady load point is the core model's.
//! Magnitudes: f 3–12 % of compressor flow, `close_at` 0.80–0.92 of design corrected speed
//! (the reference start idles at 0.72). The magnitude compared with the candidate is `f`
//! (the candidate's `fraction`).
//!
//! Signature: from light-off through the warm-up P2 lower and T34/T4 higher than the model for
//! the fuel given, the GG accelerating more slowly; the difference fades out gradually as the
//! speed rises towards `close_at`; nothing at steady load.
//! Pure: no states, no I/O.

use crate::engine::cycle::T_STD_K;
use crate::engine::effects::{CoreView, Effect};
use rand::Rng;

/// The smooth bleed schedule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BleedSmooth {
    /// Bleed fraction fully open.
    pub(crate) fraction: f64,
    /// Corrected speed (fraction of design) where the valve is closed.
    pub(crate) close_at: f64,
    /// Corrected-speed span of the closure.
    pub(crate) span: f64,
}

impl BleedSmooth {
    /// Draws a truth; returns it with its magnitude (`fraction`).
    pub(crate) fn draw(rng: &mut impl Rng) -> (BleedSmooth, f64) {
        let t = BleedSmooth {
            fraction: rng.random_range(0.03..0.12),
            close_at: rng.random_range(0.80..0.92),
            span: rng.random_range(0.08..0.18),
        };
        (t, t.fraction)
    }

    /// Valve opening (0 closed … 1 open) at corrected speed `nc` (fraction of design).
    pub(crate) fn opening(&self, nc: f64) -> f64 {
        super::falling_smoothstep(nc, self.close_at, self.span)
    }
}

impl Effect for BleedSmooth {
    fn name(&self) -> &'static str {
        "bleed_smooth"
    }

    fn bleed_fraction(&self, core: &CoreView, _x: &[f64]) -> f64 {
        let nc = core.n1_rpm / (core.t_amb_k / T_STD_K).sqrt() / core.n1_design_rpm;
        self.fraction * self.opening(nc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bounded by the open fraction, monotone non-increasing in speed, smooth (no step larger
    /// than its slope allows), closed above `close_at`.
    #[test]
    fn schedule_is_monotone_bounded_and_smooth() {
        let t = BleedSmooth {
            fraction: 0.08,
            close_at: 0.86,
            span: 0.12,
        };
        let core = |n: f64| CoreView {
            t_s: 0.0,
            n1_rpm: n * 9500.0,
            n2_rpm: 0.0,
            p2_kpa: 500.0,
            t3_k: 900.0,
            p34_kpa: 150.0,
            t_amb_k: T_STD_K,
            p_amb_kpa: 101.325,
            n1_design_rpm: 9500.0,
            fuel_design_kg_s: 2.0,
        };
        let mut prev = f64::INFINITY;
        let mut steepest: f64 = 0.0;
        for i in 0..=1000 {
            let n = i as f64 / 1000.0;
            let b = t.bleed_fraction(&core(n), &[]);
            assert!((0.0..=0.08 + 1e-12).contains(&b), "{n}: {b}");
            assert!(b <= prev + 1e-15, "monotone at {n}");
            if prev.is_finite() {
                steepest = steepest.max((prev - b) / 1e-3);
            }
            prev = b;
        }
        assert!((t.bleed_fraction(&core(0.5), &[]) - 0.08).abs() < 1e-12);
        assert_eq!(t.bleed_fraction(&core(0.86), &[]), 0.0);
        assert_eq!(t.bleed_fraction(&core(1.0), &[]), 0.0);
        // Smootherstep's largest slope is 15/8 per span, here 1.25 per unit speed; the
        // library's tanh step peaks at f/(2·0.02) = 2 for the same f, and the drawn spans
        // (up to 0.18) make the truth gentler still.
        assert!((steepest - 0.08 * 1.875 / 0.12).abs() < 0.01, "{steepest}");
        assert!(steepest < 0.7 * 0.08 / (2.0 * 0.02));
    }
}
