//! Off-design adaptation of a scaled map: smooth, bounded modification curves of relative
//! corrected speed ("modification factors", Stamatis et al. 1990; non-linear scaling-factor
//! functions, Li & Pilidis 2010), so one unit's own speed lines can be matched where a map
//! family and design-point scalers cannot.
//!
//! What it is for: evaluating, at a component's relative corrected speed `n = Nc / Nc_design`,
//! the fractional corrections the engine file's `[adaptation]` section states — corrected flow
//! × (1 + f_W(n)), efficiency × (1 + f_η(n)), (PR − 1) × (1 + f_PR(n)) and, for a compressor,
//! the speed line read: the map is looked up at `n · (1 + f_N(n))` (speed-line re-labelling,
//! which moves flow and pressure ratio together as a real speed line does).
//! What it must not do: I/O or allocation per look-up; fitting (that is `calibrate`).
//!
//! Each curve is a natural cubic spline (C², linear in its knot values, so a least-squares fit
//! is well behaved) through the file's knots **and the anchor (1, 0)**: every curve is zero at
//! the design speed by construction, so the design point the design table fixes is untouched
//! and the curves only bend the map away from it (no aliasing with the design scalers). Beyond
//! the outermost knots a curve continues with its end slope fading to zero over [`FADE_SPAN`]
//! and then holds (C¹, so the steady solver's Newton steps meet no kink, not even at the design
//! anchor; and a start-up far below the data gets a bounded correction, not an extrapolated
//! trend), and every value is clamped to ±[`MAX_FRACTION`] so no knot can turn a map inside
//! out.

/// Largest correction a curve applies, either way (fraction).
pub(crate) const MAX_FRACTION: f64 = 0.5;

/// One modification curve over relative corrected speed, zero at the design speed.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedCurve {
    /// Knot speeds, strictly increasing, the anchor 1.0 included.
    x: Vec<f64>,
    /// Values at the knots (the anchor's is 0).
    y: Vec<f64>,
    /// Second derivatives at the knots (natural spline: 0 at both ends).
    m: Vec<f64>,
}

impl SpeedCurve {
    /// The curve through `(knots[i], values[i])` and the anchor (1, 0). `None` when the inputs
    /// cannot make a curve (different lengths, no knot, a knot at the anchor, not strictly
    /// increasing, non-finite) or when every value is zero (no correction: the caller skips it).
    pub fn new(knots: &[f64], values: &[f64]) -> Option<SpeedCurve> {
        if knots.is_empty()
            || knots.len() != values.len()
            || knots.iter().chain(values).any(|v| !v.is_finite())
            || values.iter().all(|v| *v == 0.0)
        {
            return None;
        }
        let mut pts: Vec<(f64, f64)> = knots.iter().copied().zip(values.iter().copied()).collect();
        pts.push((1.0, 0.0));
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        if pts.windows(2).any(|w| w[1].0 - w[0].0 < 1e-6) {
            return None;
        }
        let (x, y): (Vec<f64>, Vec<f64>) = pts.into_iter().unzip();
        let m = natural_second_derivatives(&x, &y);
        Some(SpeedCurve { x, y, m })
    }

    /// The correction at relative speed `n` (clamped to ±[`MAX_FRACTION`]). Beyond the
    /// outermost knots the curve goes on with its end slope fading to zero over
    /// [`FADE_SPAN`] (C¹: no kink for the steady solver's Newton steps, e.g. at the design
    /// anchor) and then holds.
    #[inline]
    pub fn at(&self, n: f64) -> f64 {
        let last = self.x.len() - 1;
        // NaN goes to the low end (no correction step from it: d = 0).
        let v = if n.is_nan() || n <= self.x[0] {
            let d = if n.is_nan() { 0.0 } else { self.x[0] - n };
            self.y[0] - self.slope(0) * fade(d)
        } else if n >= self.x[last] {
            self.y[last] + self.slope(last) * fade(n - self.x[last])
        } else {
            let mut i = 0;
            while i + 1 < last && n >= self.x[i + 1] {
                i += 1;
            }
            let h = self.x[i + 1] - self.x[i];
            let a = (self.x[i + 1] - n) / h;
            let b = (n - self.x[i]) / h;
            a * self.y[i]
                + b * self.y[i + 1]
                + ((a * a * a - a) * self.m[i] + (b * b * b - b) * self.m[i + 1]) * h * h / 6.0
        };
        v.clamp(-MAX_FRACTION, MAX_FRACTION)
    }

    /// The spline's slope at end knot `i` (0 or the last).
    fn slope(&self, i: usize) -> f64 {
        let last = self.x.len() - 1;
        if i == 0 {
            let h = self.x[1] - self.x[0];
            (self.y[1] - self.y[0]) / h - h * (2.0 * self.m[0] + self.m[1]) / 6.0
        } else {
            let h = self.x[last] - self.x[last - 1];
            (self.y[last] - self.y[last - 1]) / h
                + h * (self.m[last - 1] + 2.0 * self.m[last]) / 6.0
        }
    }
}

/// Span of relative speed over which a curve's end slope fades to zero beyond its outer knots.
pub(crate) const FADE_SPAN: f64 = 0.1;

/// Distance travelled at a slope fading linearly from 1 to 0 over [`FADE_SPAN`], after `d`.
#[inline]
fn fade(d: f64) -> f64 {
    let d = d.max(0.0);
    if d < FADE_SPAN {
        d - d * d / (2.0 * FADE_SPAN)
    } else {
        FADE_SPAN / 2.0
    }
}

/// Second derivatives of the natural cubic spline through `(x, y)` (tridiagonal solve).
fn natural_second_derivatives(x: &[f64], y: &[f64]) -> Vec<f64> {
    let n = x.len();
    let mut m = vec![0.0; n];
    if n < 3 {
        return m;
    }
    // Thomas algorithm on the interior equations.
    let mut c_prime = vec![0.0; n];
    let mut d_prime = vec![0.0; n];
    for i in 1..n - 1 {
        let h0 = x[i] - x[i - 1];
        let h1 = x[i + 1] - x[i];
        let a = h0 / 6.0;
        let b = (h0 + h1) / 3.0;
        let c = h1 / 6.0;
        let d = (y[i + 1] - y[i]) / h1 - (y[i] - y[i - 1]) / h0;
        let denom = b - a * c_prime[i - 1];
        c_prime[i] = c / denom;
        d_prime[i] = (d - a * d_prime[i - 1]) / denom;
    }
    for i in (1..n - 1).rev() {
        m[i] = d_prime[i] - c_prime[i] * m[i + 1];
    }
    m
}

/// The corrections of one component: each curve absent = no correction of that quantity.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ComponentAdaptation {
    /// Corrected flow × (1 + f).
    pub flow: Option<SpeedCurve>,
    /// Isentropic efficiency × (1 + f).
    pub eff: Option<SpeedCurve>,
    /// (PR − 1) × (1 + f) (compressor only).
    pub pr: Option<SpeedCurve>,
    /// Map read at relative speed × (1 + f) (compressor only): speed-line re-labelling.
    pub speed: Option<SpeedCurve>,
    /// Whether the map's efficiency is held at its value at the design point (turbine only):
    /// the efficiency curve alone then shapes the efficiency over corrected speed, where the
    /// map family's own fall-off is not the unit's (`engine::config::EfficiencyShape`).
    pub hold_map_efficiency: bool,
}

/// The four factors at one speed (1 where a curve is absent).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Factors {
    pub flow: f64,
    pub eff: f64,
    pub pr_minus_one: f64,
    pub speed: f64,
}

impl Factors {
    pub const ONE: Factors = Factors {
        flow: 1.0,
        eff: 1.0,
        pr_minus_one: 1.0,
        speed: 1.0,
    };
}

impl ComponentAdaptation {
    /// Whether any curve is present.
    pub fn is_active(&self) -> bool {
        self.flow.is_some()
            || self.eff.is_some()
            || self.pr.is_some()
            || self.speed.is_some()
            || self.hold_map_efficiency
    }

    /// The factors at relative corrected speed `n`.
    #[inline]
    pub fn factors(&self, n: f64) -> Factors {
        let f = |c: &Option<SpeedCurve>| c.as_ref().map_or(1.0, |c| 1.0 + c.at(n));
        Factors {
            flow: f(&self.flow),
            eff: f(&self.eff),
            pr_minus_one: f(&self.pr),
            speed: f(&self.speed),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_through_knots_and_anchor_and_holds_outside() {
        let c = SpeedCurve::new(&[0.6, 0.8, 0.9], &[0.05, -0.02, 0.01]).expect("curve");
        for (x, y) in [(0.6, 0.05), (0.8, -0.02), (0.9, 0.01), (1.0, 0.0)] {
            assert!((c.at(x) - y).abs() < 1e-14, "{x}: {}", c.at(x));
        }
        // Beyond the ends: the end slope fades out over FADE_SPAN, then the value holds.
        let below = c.at(0.6 - FADE_SPAN);
        assert_eq!(c.at(0.3), below);
        assert_eq!(c.at(1.3), c.at(1.0 + FADE_SPAN));
        // C¹ at the ends: one-sided slopes agree.
        for x in [0.6, 1.0] {
            let h = 1e-6;
            let left = (c.at(x) - c.at(x - h)) / h;
            let right = (c.at(x + h) - c.at(x)) / h;
            assert!((left - right).abs() < 1e-3, "{x}: {left} vs {right}");
        }
        // Knots given in any order.
        let d = SpeedCurve::new(&[0.9, 0.6, 0.8], &[0.01, 0.05, -0.02]).expect("curve");
        assert_eq!(c, d);
    }

    #[test]
    fn a_linear_trend_is_reproduced_exactly() {
        // Values on a straight line through the anchor: the natural spline is that line.
        let line = |x: f64| 0.2 * (1.0 - x);
        let knots = [0.5, 0.7, 0.85];
        let vals: Vec<f64> = knots.iter().map(|&k| line(k)).collect();
        let c = SpeedCurve::new(&knots, &vals).expect("curve");
        // Inside the knots (the line continues past them only as far as the fade allows).
        for i in 0..=50 {
            let x = 0.5 + 0.5 * i as f64 / 50.0;
            assert!((c.at(x) - line(x)).abs() < 1e-13, "{x}");
        }
    }

    #[test]
    fn is_smooth_and_bounded() {
        let c = SpeedCurve::new(&[0.5, 0.7], &[0.45, -0.45]).expect("curve");
        let mut prev = c.at(0.5);
        for i in 1..=1000 {
            let x = 0.5 + 0.5 * i as f64 / 1000.0;
            let v = c.at(x);
            assert!(v.abs() <= MAX_FRACTION);
            // Continuous: no jump larger than the slope allows over a 0.0005 step.
            assert!((v - prev).abs() < 0.01, "{x}");
            prev = v;
        }
    }

    #[test]
    fn refuses_what_is_not_a_curve() {
        assert!(SpeedCurve::new(&[], &[]).is_none());
        assert!(
            SpeedCurve::new(&[0.8], &[0.0]).is_none(),
            "all zero: no curve"
        );
        assert!(SpeedCurve::new(&[0.8, 0.9], &[0.1]).is_none());
        assert!(SpeedCurve::new(&[0.8, 0.8], &[0.1, 0.2]).is_none());
        assert!(SpeedCurve::new(&[1.0], &[0.1]).is_none());
        assert!(SpeedCurve::new(&[0.8], &[f64::NAN]).is_none());
    }

    #[test]
    fn factors_default_to_one() {
        let a = ComponentAdaptation::default();
        assert!(!a.is_active());
        assert_eq!(a.factors(0.7), Factors::ONE);
        let b = ComponentAdaptation {
            flow: SpeedCurve::new(&[0.8], &[0.1]),
            ..Default::default()
        };
        assert!((b.factors(0.8).flow - 1.1).abs() < 1e-15);
        assert_eq!(b.factors(1.0), Factors::ONE);
    }
}
