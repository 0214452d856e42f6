//! Box bounds in physical units, the map to normalised `[0, 1]` coordinates, and reflection
//! at the faces of the unit box. Pure arithmetic; no solver logic.
//! Must not know about any problem or solver.

use super::OptimError;

/// Lower/upper bound per parameter, physical units, with `lower < upper` and both finite.
#[derive(Debug, Clone, PartialEq)]
pub struct Bounds {
    lower: Vec<f64>,
    upper: Vec<f64>,
}

impl Bounds {
    /// Validated bounds: same length, finite, `lower[i] < upper[i]`, at least one parameter.
    pub fn new(lower: Vec<f64>, upper: Vec<f64>) -> Result<Self, OptimError> {
        if lower.len() != upper.len() {
            return Err(OptimError::DimensionMismatch {
                expected: lower.len(),
                got: upper.len(),
            });
        }
        if lower.is_empty() {
            return Err(OptimError::InvalidBounds {
                index: 0,
                reason: "no parameters".into(),
            });
        }
        for (i, (&l, &u)) in lower.iter().zip(&upper).enumerate() {
            if !(l.is_finite() && u.is_finite()) {
                return Err(OptimError::InvalidBounds {
                    index: i,
                    reason: format!("bounds must be finite, got [{l}, {u}]"),
                });
            }
            if l >= u {
                return Err(OptimError::InvalidBounds {
                    index: i,
                    reason: format!("lower {l} must be < upper {u}"),
                });
            }
        }
        Ok(Self { lower, upper })
    }

    /// The same `[lower, upper]` for each of `dim` parameters.
    pub fn uniform(dim: usize, lower: f64, upper: f64) -> Result<Self, OptimError> {
        Self::new(vec![lower; dim], vec![upper; dim])
    }

    /// Number of parameters.
    pub fn dim(&self) -> usize {
        self.lower.len()
    }
    /// Lower bounds.
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }
    /// Upper bounds.
    pub fn upper(&self) -> &[f64] {
        &self.upper
    }
    /// `upper − lower` of parameter `i`.
    pub fn width(&self, i: usize) -> f64 {
        self.upper[i] - self.lower[i]
    }

    /// Physical → normalised: `(x − lower) / (upper − lower)`.
    pub fn to_unit(&self, x: &[f64]) -> Vec<f64> {
        x.iter()
            .enumerate()
            .map(|(i, &v)| (v - self.lower[i]) / self.width(i))
            .collect()
    }

    /// Normalised → physical: `lower + u (upper − lower)`. A `u` inside [0, 1] maps inside the
    /// box exactly (rounding can put `lower + 1·(upper − lower)` a hair beyond `upper`, and a
    /// result handed on as another search's start must pass [`Self::check_inside`]).
    pub fn from_unit(&self, u: &[f64]) -> Vec<f64> {
        u.iter()
            .enumerate()
            .map(|(i, &v)| {
                let x = self.lower[i] + v * self.width(i);
                if (0.0..=1.0).contains(&v) {
                    x.clamp(self.lower[i], self.upper[i])
                } else {
                    x
                }
            })
            .collect()
    }

    /// Whether `x` (physical) is finite, has the right length and lies inside the box.
    pub fn check_inside(&self, x: &[f64]) -> Result<(), OptimError> {
        if x.len() != self.dim() {
            return Err(OptimError::DimensionMismatch {
                expected: self.dim(),
                got: x.len(),
            });
        }
        for (i, &v) in x.iter().enumerate() {
            if !(v.is_finite() && v >= self.lower[i] && v <= self.upper[i]) {
                return Err(OptimError::StartOutOfBounds { index: i, value: v });
            }
        }
        Ok(())
    }
}

/// Reflect a normalised coordinate into `[0, 1]` (mirror at 0 and 1, repeatedly for far-out
/// values, i.e. a triangle wave of period 2). Identity on `[0, 1]`. A non-finite input (only
/// possible from an overflowing Lévy step) maps to the centre 0.5 rather than to NaN.
pub(crate) fn reflect_unit(v: f64) -> f64 {
    if (0.0..=1.0).contains(&v) {
        return v;
    }
    if !v.is_finite() {
        return 0.5;
    }
    let t = v.rem_euclid(2.0);
    let r = if t > 1.0 { 2.0 - t } else { t };
    r.clamp(0.0, 1.0)
}

/// [`reflect_unit`] applied to every component.
pub(crate) fn reflect_all(u: &mut [f64]) {
    for v in u {
        *v = reflect_unit(*v);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflection_is_identity_inside_and_lands_in_unit_interval() {
        for &v in &[0.0, 1e-12, 0.3, 0.5, 0.999, 1.0] {
            assert_eq!(reflect_unit(v), v);
        }
        assert!((reflect_unit(1.2) - 0.8).abs() < 1e-12);
        assert!((reflect_unit(-0.3) - 0.3).abs() < 1e-12);
        assert!((reflect_unit(2.25) - 0.25).abs() < 1e-12);
        assert!((reflect_unit(-1.75) - 0.25).abs() < 1e-12);
        assert_eq!(reflect_unit(f64::INFINITY), 0.5);
        assert_eq!(reflect_unit(f64::NAN), 0.5);
        for &v in &[1e9, -1e9, 3.7e15, -123.456, 1e300] {
            let r = reflect_unit(v);
            assert!((0.0..=1.0).contains(&r), "reflect({v}) = {r}");
        }
        for k in 0..10_000 {
            let v = -50.0 + k as f64 * 0.01;
            let r = reflect_unit(v);
            assert!((0.0..=1.0).contains(&r), "reflect({v}) = {r}");
        }
    }

    #[test]
    fn unit_map_round_trips_and_validates() {
        let b = Bounds::uniform(3, -3.0, 10.0).expect("valid");
        let x = vec![-3.0, 0.0, 10.0];
        let u = b.to_unit(&x);
        assert_eq!(u[0], 0.0);
        assert_eq!(u[2], 1.0);
        let back = b.from_unit(&u);
        for (a, c) in x.iter().zip(&back) {
            assert!((a - c).abs() < 1e-12);
        }
        assert!(Bounds::new(vec![0.0], vec![0.0]).is_err());
        assert!(Bounds::new(vec![0.0, 1.0], vec![1.0]).is_err());
        assert!(Bounds::new(vec![f64::NAN], vec![1.0]).is_err());
        assert!(b.check_inside(&[0.0, 0.0, 10.5]).is_err());
        assert!(b.check_inside(&[0.0, 0.0]).is_err());
        assert!(b.check_inside(&x).is_ok());
    }

    /// −0.00949… + 1·(0.00546… − (−0.00949…)) rounds to one ulp above the upper bound; the
    /// optimum of one search (a `u` of 1) must be a valid start for the next.
    #[test]
    fn the_unit_interval_maps_inside_the_box_despite_rounding() {
        let (lo, hi) = (-0.009491082780130784, 0.005459983480655617);
        assert!(lo + (hi - lo) > hi, "the rounding this test is about");
        let b = Bounds::new(vec![lo], vec![hi]).expect("valid");
        assert_eq!(b.from_unit(&[1.0]), vec![hi]);
        assert_eq!(b.from_unit(&[0.0]), vec![lo]);
        assert!(b.check_inside(&b.from_unit(&[1.0])).is_ok());
    }
}
