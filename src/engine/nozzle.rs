//! The exhaust stack as a nozzle of fixed effective area discharging to ambient
//! ([`crate::engine::config::PressureLossLaw::Nozzle`]): the back-pressure a given corrected
//! flow needs.
//!
//! Isentropic flow from the stack's total pressure P to the ambient static pressure Pa through
//! an area A: W·√(R·T)/(A·P) = Φ(x), x = P/Pa, with
//! Φ(x) = √(2γ/(γ−1) · (x^(−2/γ) − x^(−(γ+1)/γ))) below the critical ratio
//! x* = ((γ+1)/2)^(γ/(γ−1)), and Φ(x*) beyond it (choked). In the engine's own terms the flow
//! is the corrected flow W·√T/Pa relative to its design value, so with x·Φ(x) = g(x) the law is
//! g(x) = g(x_design) · W√T/Pa / (W√T/Pa)_design, which fixes A at the design back-pressure
//! without R or the area themselves. γ is the exhaust gas's (1.33, lean combustion products at
//! 700–800 K; the ratio's sensitivity to it is second order at a stack's few percent).
//! Must not: read files, know the engine; pure arithmetic.

/// Ratio of specific heats of the exhaust gas.
pub(crate) const GAMMA: f64 = 1.33;

/// Critical (choking) total-to-static pressure ratio.
fn critical_ratio() -> f64 {
    ((GAMMA + 1.0) / 2.0).powf(GAMMA / (GAMMA - 1.0))
}

/// g(x) = x·Φ(x): the flow a pressure ratio `x` passes, in units of A·Pa/√(R·T).
fn flow(x: f64) -> f64 {
    if x <= 1.0 {
        return 0.0;
    }
    let xc = critical_ratio();
    let x_eff = x.min(xc);
    let phi = (2.0 * GAMMA / (GAMMA - 1.0)
        * (x_eff.powf(-2.0 / GAMMA) - x_eff.powf(-(GAMMA + 1.0) / GAMMA)))
    .max(0.0)
    .sqrt();
    x * phi
}

/// The stack's total-to-ambient pressure ratio that passes `rel_flow` × the design corrected
/// flow, when the design flow needs `design_ratio` (> 1; at 1 the stack has no loss and the
/// ratio stays 1). Newton's method on g from the flow-squared law's value, bracketed; exact to
/// 1e-13 in the ratio.
pub(crate) fn pressure_ratio(design_ratio: f64, rel_flow: f64) -> f64 {
    if design_ratio <= 1.0 || rel_flow <= 0.0 {
        return 1.0;
    }
    let target = flow(design_ratio) * rel_flow;
    let xc = critical_ratio();
    if target >= flow(xc) {
        // Choked: g(x) = x·Φ(x*) is linear in x.
        return target / (flow(xc) / xc);
    }
    let (mut lo, mut hi) = (1.0, xc);
    let mut x = (1.0 + (design_ratio - 1.0) * rel_flow * rel_flow).clamp(lo, hi);
    for _ in 0..60 {
        let f = flow(x) - target;
        if f > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        // g'(x) by a central difference small against the excess x − 1.
        let h = 1e-7 * (x - 1.0).max(1e-9);
        let d = (flow(x + h) - flow((x - h).max(1.0))) / (x + h - (x - h).max(1.0));
        let mut next = if d > 0.0 { x - f / d } else { 0.5 * (lo + hi) };
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if (next - x).abs() <= 1e-14 * x {
            return next;
        }
        x = next;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At the design flow the design ratio, at no flow none; the ratio rises with the flow.
    #[test]
    fn design_flow_gives_the_design_ratio() {
        for design in [1.005, 1.03, 1.08, 1.3] {
            assert!(
                (pressure_ratio(design, 1.0) - design).abs() < 1e-12,
                "{design}"
            );
            assert_eq!(pressure_ratio(design, 0.0), 1.0);
            let mut last = 1.0;
            for k in 1..=30 {
                let x = pressure_ratio(design, f64::from(k) * 0.05);
                assert!(x > last, "{design} at {k}: {x} after {last}");
                last = x;
            }
        }
        assert_eq!(pressure_ratio(1.0, 0.7), 1.0);
    }

    /// Low Mach: the excess follows the flow squared (Bernoulli), as the default law; the
    /// compressible law's excess at half flow is within a few per cent of a quarter of the
    /// design excess, and above the flow-squared law's at twice the design flow (the gas
    /// expands in the nozzle, needing more pressure).
    #[test]
    fn small_excesses_follow_the_flow_squared_law() {
        let design = 1.03;
        let half = pressure_ratio(design, 0.5) - 1.0;
        assert!((half / (0.25 * 0.03) - 1.0).abs() < 0.03, "{half}");
        let twice = pressure_ratio(design, 2.0) - 1.0;
        assert!(
            twice > 4.0 * 0.03 * 0.97 && twice < 4.0 * 0.03 * 1.1,
            "{twice}"
        );
    }

    /// The inverse holds: the ratio found passes the flow asked for, below and beyond choking.
    #[test]
    fn the_ratio_found_passes_the_flow() {
        let design = 1.05;
        for rel in [0.1, 0.6, 1.0, 1.7, 4.0, 9.0] {
            let x = pressure_ratio(design, rel);
            let back = flow(x) / flow(design);
            assert!((back / rel - 1.0).abs() < 1e-10, "{rel}: {x} passes {back}");
        }
        assert!(pressure_ratio(design, 9.0) > critical_ratio());
    }
}
