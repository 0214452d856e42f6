//! Not-a-knot cubic spline interpolation on a fixed grid, in one axis and as a tensor product on
//! a (speed, β) grid: the smoother map interpolation an engine file may select
//! (`maps.interpolation = "cubic"`), the same interpolant as SciPy's
//! `RegularGridInterpolator(method="cubic")` that GSPy uses.
//!
//! What it is for: map look-ups that agree with peers who interpolate their maps with cubic
//! splines. What it must not do: allocate or do I/O when evaluating (the weights are computed
//! once, when a map is built).
//!
//! A spline through values `v_k` at knots `x_k` is linear in the values, so the second
//! derivatives at the knots are `M = W v` with `W` computed once per axis; evaluating at `t` in
//! knot interval `j` (the first or last interval beyond the ends: the end cubics are continued)
//! is `a v_j + b v_{j+1} + ((a³ − a) M_j + (b³ − b) M_{j+1}) h² / 6` with `h = x_{j+1} − x_j`,
//! `a = (x_{j+1} − t)/h`, `b = 1 − a`. End conditions: not-a-knot (the third derivative is
//! continuous at the second and the second-to-last knot), SciPy's default.

use nalgebra::DMatrix;

/// Most knots a cubic axis may have (evaluation keeps its row values on the stack).
pub(crate) const MAX_KNOTS: usize = 64;

/// One axis of knots with its value → second-derivative weights.
#[derive(Debug, Clone)]
pub(crate) struct SplineAxis {
    x: Vec<f64>,
    /// `n × n`, row-major: `M_j = Σ_k w[j n + k] v_k`.
    w: Vec<f64>,
}

impl SplineAxis {
    /// The axis for strictly increasing knots `x`; `None` with fewer than 4 knots (a
    /// not-a-knot cubic needs 4), more than [`MAX_KNOTS`], or knots that are not increasing.
    pub(crate) fn new(x: &[f64]) -> Option<SplineAxis> {
        let n = x.len();
        if !(4..=MAX_KNOTS).contains(&n) || x.windows(2).any(|p| p[1] <= p[0]) {
            return None;
        }
        let h: Vec<f64> = x.windows(2).map(|p| p[1] - p[0]).collect();
        let mut a = DMatrix::<f64>::zeros(n, n);
        let mut b = DMatrix::<f64>::zeros(n, n);
        // Not-a-knot at both ends: M'''  continuous at x_1 and x_{n-2}.
        a[(0, 0)] = h[1];
        a[(0, 1)] = -(h[0] + h[1]);
        a[(0, 2)] = h[0];
        a[(n - 1, n - 3)] = h[n - 2];
        a[(n - 1, n - 2)] = -(h[n - 3] + h[n - 2]);
        a[(n - 1, n - 1)] = h[n - 3];
        for i in 1..n - 1 {
            a[(i, i - 1)] = h[i - 1];
            a[(i, i)] = 2.0 * (h[i - 1] + h[i]);
            a[(i, i + 1)] = h[i];
            b[(i, i - 1)] = 6.0 / h[i - 1];
            b[(i, i)] = -6.0 / h[i - 1] - 6.0 / h[i];
            b[(i, i + 1)] = 6.0 / h[i];
        }
        let w = a.lu().solve(&b)?;
        let mut flat = Vec::with_capacity(n * n);
        for j in 0..n {
            for k in 0..n {
                flat.push(w[(j, k)]);
            }
        }
        Some(SplineAxis {
            x: x.to_vec(),
            w: flat,
        })
    }

    /// Number of knots.
    pub(crate) fn len(&self) -> usize {
        self.x.len()
    }

    /// The spline through `v(k)` at the knots, evaluated at `t` (end cubics continued outside).
    #[inline]
    pub(crate) fn eval(&self, t: f64, v: impl Fn(usize) -> f64) -> f64 {
        let x = &self.x;
        let n = x.len();
        let j = if t <= x[1] {
            0
        } else if t >= x[n - 2] {
            n - 2
        } else {
            x.partition_point(|&xk| xk <= t) - 1
        };
        let (mut mj, mut mj1) = (0.0, 0.0);
        for k in 0..n {
            let vk = v(k);
            mj += self.w[j * n + k] * vk;
            mj1 += self.w[(j + 1) * n + k] * vk;
        }
        let h = x[j + 1] - x[j];
        let a = (x[j + 1] - t) / h;
        let b = 1.0 - a;
        a * v(j) + b * v(j + 1) + ((a * a * a - a) * mj + (b * b * b - b) * mj1) * h * h / 6.0
    }
}

/// Tensor-product cubic spline on a (row key, column key) grid of values stored row-major.
#[derive(Debug, Clone)]
pub(crate) struct CubicGrid {
    rows: SplineAxis,
    cols: SplineAxis,
}

impl CubicGrid {
    /// The grid of a map's speed lines × β keys, or the map error naming the map: what
    /// `with_cubic_interpolation` of the compressor and turbine maps need.
    pub(crate) fn for_map(
        title: &str,
        speeds: &[f64],
        betas: &[f64],
    ) -> Result<CubicGrid, super::gasturb::MapError> {
        CubicGrid::new(speeds, betas).ok_or_else(|| super::gasturb::MapError::Invalid {
            source_name: title.to_string(),
            table: "Mass Flow".into(),
            reason: format!(
                "cubic interpolation needs 4 to {MAX_KNOTS} speed lines and beta values"
            ),
        })
    }

    /// `None` unless both axes have 4 ..= [`MAX_KNOTS`] increasing keys.
    pub(crate) fn new(row_keys: &[f64], col_keys: &[f64]) -> Option<CubicGrid> {
        Some(CubicGrid {
            rows: SplineAxis::new(row_keys)?,
            cols: SplineAxis::new(col_keys)?,
        })
    }

    /// The interpolant of `values` (`rows × cols`, row-major) at (`r`, `c`).
    #[inline]
    pub(crate) fn eval(&self, values: &[f64], r: f64, c: f64) -> f64 {
        let (n, m) = (self.rows.len(), self.cols.len());
        let mut along = [0.0; MAX_KNOTS];
        for (i, slot) in along.iter_mut().enumerate().take(n) {
            *slot = self.cols.eval(c, |k| values[i * m + k]);
        }
        self.rows.eval(r, |i| along[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reproduces_cubics_and_knots() {
        // A not-a-knot spline reproduces any cubic exactly, also outside the knots.
        let x = [0.0, 0.3, 0.5, 1.1, 1.2, 2.0];
        let f = |t: f64| 1.0 - 2.0 * t + 0.7 * t * t - 0.4 * t * t * t;
        let ax = SplineAxis::new(&x).expect("axis");
        for i in 0..=40 {
            let t = -0.5 + 3.0 * i as f64 / 40.0;
            let s = ax.eval(t, |k| f(x[k]));
            assert!((s - f(t)).abs() < 1e-10, "t {t}: {s} vs {}", f(t));
        }
        // Interpolates arbitrary data at the knots.
        let v = [3.0, -1.0, 2.0, 2.5, 0.0, 7.0];
        for (k, &xk) in x.iter().enumerate() {
            assert!((ax.eval(xk, |i| v[i]) - v[k]).abs() < 1e-12);
        }
        assert!(SplineAxis::new(&[0.0, 1.0, 2.0]).is_none());
        assert!(SplineAxis::new(&[0.0, 1.0, 1.0, 2.0]).is_none());
    }

    #[test]
    fn tensor_product_reproduces_bicubic() {
        let r = [0.5, 0.7, 0.8, 0.9, 1.0, 1.1];
        let c = [0.0, 0.2, 0.4, 0.5, 0.8, 1.0];
        let f = |a: f64, b: f64| (1.0 + a - a * a * a) * (2.0 - b + 0.3 * b * b * b);
        let mut v = Vec::new();
        for &a in &r {
            for &b in &c {
                v.push(f(a, b));
            }
        }
        let g = CubicGrid::new(&r, &c).expect("grid");
        for (a, b) in [(0.55, 0.1), (0.93, 0.77), (1.0, 0.5), (0.61, 0.99)] {
            assert!((g.eval(&v, a, b) - f(a, b)).abs() < 1e-10);
        }
    }
}
