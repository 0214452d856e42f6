//! Turbine map in map units, with the extrapolation a start-up needs.
//!
//! What it is for: `(corrected flow, efficiency) = f(relative corrected speed nc, PR)` from a
//! GasTurb file's "Min Pressure Ratio", "Max Pressure Ratio", "Mass Flow" and "Efficiency"
//! tables, with `beta = (PR − PRmin(nc)) / (PRmax(nc) − PRmin(nc))`. What it must not do:
//! allocate or do I/O in [`TurbineMap::point`], or know about engine units (`scaled`).
//!
//! # Interpolation
//! Bilinear in (nc, beta) inside the map; PRmin/PRmax linear in speed (held beyond their keys).
//! Optionally ([`TurbineMap::with_cubic_interpolation`], engine file
//! `maps.interpolation = "cubic"`) the not-a-knot tensor-product cubic spline of
//! [`super::spline`] (as GSPy/SciPy) inside the grid; the rules below act on it unchanged, since
//! they only ever read the grid at clamped coordinates.
//!
//! # Extrapolation (start-up PRs are 1.0–2, far below a map's PRmin of ~3)
//!
//! * **PR below PRmin**: nozzle (ellipse) law matched in value at PRmin,
//!   `wc(PR) = wc(PRmin) · sqrt((1 − PR⁻²) / (1 − PRmin⁻²))`. Its slope is infinite at PR = 1,
//!   which breaks Newton iterations and implicit integration, so below `PR_LINEAR` = 1.02 the
//!   flow is linear in (PR − 1), matched in value at 1.02: finite slope, zero flow at PR = 1 and
//!   *negative* (reverse) flow below 1, which keeps the model's residuals continuous if a
//!   transient briefly inverts the pressure ratio.
//! * **efficiency outside the map** (below PRmin and/or below the lowest speed line): one
//!   blade-to-gas velocity-ratio law. With `ν = U/C₀`, `C₀ ∝ sqrt(Δh_is)` and
//!   `Δh_is ∝ 1 − PR^(−1/4)` (γ ≈ 1.33), relative to the nearest map point
//!   `ν̂ = (nc / n_lowest if below the lowest line) · sqrt((1 − PRmin^(−1/4)) / (1 − PR^(−1/4)))`
//!   and `eff = eff(map point) · (2ν̂ − ν̂²)`, the classic parabola of stage efficiency over
//!   velocity ratio: equal with zero slope at the map edge, 0 at standstill, and floored at
//!   `EFF_FLOOR_PR` = 0.1 on the low-PR side. Low speed and low PR act on the same ratio, so a
//!   slowly turning PT fed a small pressure ratio (a start-up) keeps a realistic efficiency.
//! * **PR above PRmax**: choked: flow and efficiency held at their PRmax values.
//! * **speed below the lowest line** (0.6 for the JT9D maps) down to 0: flow shape of the lowest
//!   line held; efficiency from the velocity-ratio law above. This takes efficiency, and so
//!   power, to 0 at standstill while torque ∝ power/speed stays finite (stall torque), which is
//!   what a free power turbine at break-away needs.
//! * **speed above the highest line**: the highest line is held.

use super::gasturb::{GasTurbFile, MapError, MapTable};
use super::spline::CubicGrid;

/// Below this PR the flow law is linear in (PR − 1).
pub const PR_LINEAR: f64 = 1.02;
/// Floor of the efficiency below PRmin (at and above the lowest speed line).
pub const EFF_FLOOR_PR: f64 = 0.1;

/// Efficiency at relative velocity ratio ν̂ from the map-edge efficiency `e_ref`: the stage
/// parabola `e_ref (2ν̂ − ν̂²)`, equal with zero slope at ν̂ = 1, 0 at standstill, and floored at
/// [`EFF_FLOOR_PR`] on the high-ν̂ (low PR) side.
fn velocity_ratio_eff(e_ref: f64, nu: f64) -> f64 {
    let f = e_ref * (2.0 * nu - nu * nu);
    if nu > 1.0 {
        f.max(EFF_FLOOR_PR)
    } else {
        f.max(0.0)
    }
}

/// One map point in map units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurbinePoint {
    /// Corrected flow in the map's units.
    pub wc: f64,
    /// Isentropic efficiency.
    pub eff: f64,
    /// Auxiliary coordinate; outside `[0, 1]` when extrapolating in PR.
    pub beta: f64,
}

/// A turbine map ready for fast evaluation.
#[derive(Debug, Clone)]
pub struct TurbineMap {
    title: String,
    speeds: Vec<f64>,
    betas: Vec<f64>,
    wc: Vec<f64>,
    eff: Vec<f64>,
    lim_speeds_min: Vec<f64>,
    pr_min: Vec<f64>,
    lim_speeds_max: Vec<f64>,
    pr_max: Vec<f64>,
    /// The cubic interpolant, when selected.
    cubic: Option<CubicGrid>,
}

/// Linear interpolation in `xs`, held at the ends.
#[inline]
fn interp_hold(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    let n = xs.len();
    if n == 1 || x <= xs[0] {
        return ys[0];
    }
    if x >= xs[n - 1] {
        return ys[n - 1];
    }
    let k = xs.partition_point(|&v| v <= x) - 1;
    ys[k] + (x - xs[k]) * (ys[k + 1] - ys[k]) / (xs[k + 1] - xs[k])
}

#[inline]
fn dh_is(pr: f64) -> f64 {
    // PR^(-1/4) by two square roots: a libm pow was 4 % of a start-up simulation.
    1.0 - 1.0 / pr.sqrt().sqrt()
}

fn limit_row(src: &str, t: &MapTable) -> Result<(Vec<f64>, Vec<f64>), MapError> {
    let row = t.values.first().cloned().unwrap_or_default();
    if row.iter().any(|&p| p < 1.0) {
        return Err(MapError::Invalid {
            source_name: src.to_string(),
            table: t.name.clone(),
            reason: "pressure ratios must be >= 1".into(),
        });
    }
    Ok((t.col_keys.clone(), row))
}

impl TurbineMap {
    /// Build from "Min Pressure Ratio", "Max Pressure Ratio", "Mass Flow", "Efficiency".
    pub fn from_gasturb(f: &GasTurbFile) -> Result<Self, MapError> {
        let src = f.source.as_str();
        let min_t = f.require("Min Pressure Ratio")?;
        let max_t = f.require("Max Pressure Ratio")?;
        let wc_t = f.require("Mass Flow")?;
        let eff_t = f.require("Efficiency")?;
        let invalid = |table: &str, reason: String| MapError::Invalid {
            source_name: src.to_string(),
            table: table.to_string(),
            reason,
        };
        if eff_t.row_keys != wc_t.row_keys || eff_t.col_keys != wc_t.col_keys {
            return Err(invalid(
                "Efficiency",
                "speed/beta keys differ from table \"Mass Flow\"".into(),
            ));
        }
        let (n, m) = (wc_t.row_keys.len(), wc_t.col_keys.len());
        if m < 2 {
            return Err(invalid("Mass Flow", "need at least 2 beta values".into()));
        }
        if wc_t.row_keys[0] <= 0.0 {
            return Err(invalid("Mass Flow", "lowest speed must be positive".into()));
        }
        let (lim_speeds_min, pr_min) = limit_row(src, min_t)?;
        let (lim_speeds_max, pr_max) = limit_row(src, max_t)?;
        for &s in wc_t.row_keys.iter() {
            let (lo, hi) = (
                interp_hold(&lim_speeds_min, &pr_min, s),
                interp_hold(&lim_speeds_max, &pr_max, s),
            );
            if hi <= lo {
                return Err(invalid(
                    "Max Pressure Ratio",
                    format!("at speed {s} PRmax {hi} is not above PRmin {lo}"),
                ));
            }
        }
        let wc: Vec<f64> = wc_t.values.iter().flatten().copied().collect();
        let eff: Vec<f64> = eff_t.values.iter().flatten().copied().collect();
        if wc.iter().any(|&w| w <= 0.0) || eff.iter().any(|&e| e <= 0.0 || e > 1.0) {
            return Err(invalid(
                "Mass Flow/Efficiency",
                "flows must be > 0 and efficiencies in (0, 1]".into(),
            ));
        }
        debug_assert_eq!(wc.len(), n * m);
        Ok(TurbineMap {
            title: f.title.clone(),
            speeds: wc_t.row_keys.clone(),
            betas: wc_t.col_keys.clone(),
            wc,
            eff,
            lim_speeds_min,
            pr_min,
            lim_speeds_max,
            pr_max,
            cubic: None,
        })
    }

    /// The same map interpolated with not-a-knot cubic splines inside its grid (module docs).
    /// Needs 4 to 64 speed lines and β values.
    pub fn with_cubic_interpolation(mut self) -> Result<Self, MapError> {
        self.cubic = Some(CubicGrid::for_map(&self.title, &self.speeds, &self.betas)?);
        Ok(self)
    }

    pub fn title(&self) -> &str {
        &self.title
    }
    pub fn speeds(&self) -> &[f64] {
        &self.speeds
    }
    /// PRmin and PRmax at this speed (held beyond the keys).
    pub fn pr_limits(&self, nc: f64) -> (f64, f64) {
        (
            interp_hold(&self.lim_speeds_min, &self.pr_min, nc),
            interp_hold(&self.lim_speeds_max, &self.pr_max, nc),
        )
    }

    /// Bilinear (flow, efficiency) at a speed already clamped to the keys and beta in [b0, b1].
    #[inline]
    fn grid(&self, nc: f64, beta: f64) -> (f64, f64) {
        let (s, b) = (&self.speeds, &self.betas);
        let (n, m) = (s.len(), b.len());
        if let Some(grid) = &self.cubic {
            return self.grid_cubic(grid, nc, beta);
        }
        let (j, t) = if n == 1 || nc <= s[0] {
            (0, 0.0)
        } else if nc >= s[n - 1] {
            (n - 2, 1.0)
        } else {
            let j = s.partition_point(|&x| x <= nc) - 1;
            (j, (nc - s[j]) / (s[j + 1] - s[j]))
        };
        let beta = beta.clamp(b[0], b[m - 1]);
        let k = b.partition_point(|&x| x <= beta).clamp(1, m - 1) - 1;
        let u = (beta - b[k]) / (b[k + 1] - b[k]);
        let at = |v: &[f64], i: usize| {
            let a = v[i * m + k];
            a + u * (v[i * m + k + 1] - a)
        };
        if n == 1 {
            return (at(&self.wc, 0), at(&self.eff, 0));
        }
        let w = at(&self.wc, j) * (1.0 - t) + at(&self.wc, j + 1) * t;
        let e = at(&self.eff, j) * (1.0 - t) + at(&self.eff, j + 1) * t;
        (w, e)
    }

    /// The cubic interpolant's (flow, efficiency), kept out of line so the bilinear path (the
    /// simulation's hot path) stays as small as it was.
    #[inline(never)]
    fn grid_cubic(&self, grid: &CubicGrid, nc: f64, beta: f64) -> (f64, f64) {
        let (s, b) = (&self.speeds, &self.betas);
        let nc = nc.clamp(s[0], s[s.len() - 1]);
        let beta = beta.clamp(b[0], b[b.len() - 1]);
        (
            grid.eval(&self.wc, nc, beta),
            grid.eval(&self.eff, nc, beta),
        )
    }

    /// Map point at relative corrected speed `nc` and pressure ratio `pr` (allocation-free).
    pub fn point(&self, nc: f64, pr: f64) -> TurbinePoint {
        let s = &self.speeds;
        let nc = if nc.is_nan() { 0.0 } else { nc.max(0.0) };
        let nc_map = nc.clamp(s[0], s[s.len() - 1]);
        let (pr_lo, pr_hi) = self.pr_limits(nc_map);
        let beta = (pr - pr_lo) / (pr_hi - pr_lo);
        let (b0, b1) = (self.betas[0], self.betas[self.betas.len() - 1]);
        // One blade-to-gas velocity ratio ν̂ = U/C relative to the nearest map point: low speed
        // lowers it, low PR raises it, so the two extrapolations compensate rather than stack.
        let nu_speed = if nc < s[0] { nc / s[0] } else { 1.0 };
        let (wc, eff) = if pr >= pr_lo {
            let (w, e) = self.grid(nc_map, beta.clamp(b0, b1));
            (w, velocity_ratio_eff(e, nu_speed))
        } else {
            let (w_lo, e_lo) = self.grid(nc_map, b0);
            let pr_lin = PR_LINEAR.min(pr_lo);
            let ellipse = |p: f64| w_lo * ((1.0 - p.powi(-2)) / (1.0 - pr_lo.powi(-2))).sqrt();
            let w = if pr >= pr_lin {
                ellipse(pr)
            } else {
                ellipse(pr_lin) * (pr - 1.0) / (pr_lin - 1.0)
            };
            let e = if pr <= 1.0 {
                // The limit of the law as PR → 1⁺ (ν̂ → ∞), zero at standstill.
                if nu_speed > 0.0 {
                    EFF_FLOOR_PR
                } else {
                    0.0
                }
            } else {
                let nu_pr = (dh_is(pr_lo) / dh_is(pr)).sqrt();
                velocity_ratio_eff(e_lo, nu_speed * nu_pr)
            };
            (w, e)
        };
        TurbinePoint { wc, eff, beta }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::maps::gasturb::parse;
    use crate::maps::{HPT_MAP, LPT_MAP};
    use proptest::prelude::*;

    fn hpt() -> TurbineMap {
        TurbineMap::from_gasturb(&parse(HPT_MAP, "hpt.map").expect("parse")).expect("build")
    }
    fn lpt() -> TurbineMap {
        TurbineMap::from_gasturb(&parse(LPT_MAP, "lpt.map").expect("parse")).expect("build")
    }

    #[test]
    fn design_points() {
        let p = hpt().point(1.0, 5.0);
        assert!((p.eff - 0.9328).abs() < 1e-12, "{p:?}");
        assert!((p.beta - 0.4).abs() < 1e-12);
        assert!((p.wc - 30.145).abs() < 1e-9);
        let p = lpt().point(1.0, 5.0);
        assert!((p.eff - 0.9383).abs() < 1e-12, "{p:?}");
    }

    #[test]
    fn continuous_at_extrapolation_boundaries() {
        for m in [hpt(), lpt()] {
            let e = 1e-10;
            for i in 0..=50 {
                let nc = 1.3 * i as f64 / 50.0;
                for pr in [1.0, PR_LINEAR, 3.0, 8.0, 5.0] {
                    let (a, b) = (m.point(nc, pr - e), m.point(nc, pr + e));
                    assert!(
                        (a.wc - b.wc).abs() < 1e-6,
                        "wc jump nc {nc} pr {pr}: {a:?} {b:?}"
                    );
                    assert!((a.eff - b.eff).abs() < 1e-6, "eff jump nc {nc} pr {pr}");
                }
            }
            for pr in [1.01, 1.5, 2.5, 4.0, 7.0, 9.0] {
                for &nc in m.speeds() {
                    let (a, b) = (m.point(nc - 1e-10, pr), m.point(nc + 1e-10, pr));
                    assert!((a.wc - b.wc).abs() < 1e-6 && (a.eff - b.eff).abs() < 1e-6);
                }
            }
        }
    }

    #[test]
    fn flow_laws_below_pr_min() {
        let m = hpt();
        let w3 = m.point(1.0, 3.0).wc;
        let p = m.point(1.0, 2.0);
        let expect = w3 * ((1.0 - 0.25f64) / (1.0 - 1.0 / 9.0)).sqrt();
        assert!((p.wc - expect).abs() < 1e-9);
        assert_eq!(m.point(1.0, 1.0).wc, 0.0);
        assert!(m.point(1.0, 0.99).wc < 0.0);
        // Linear below 1.02: finite slope.
        let (a, b) = (m.point(1.0, 1.005).wc, m.point(1.0, 1.015).wc);
        assert!(((b - a) / 0.01 - m.point(1.0, 1.02).wc / 0.02).abs() < 1e-6);
        // Efficiency floor and its law.
        assert!((m.point(1.0, 1.0001).eff - EFF_FLOOR_PR).abs() < 1e-12);
        assert!(m.point(1.0, 2.0).eff < m.point(1.0, 3.0).eff);
        assert!(m.point(1.0, 2.0).eff > 0.8);
        // Choked above PRmax.
        assert_eq!(m.point(1.0, 12.0).wc, m.point(1.0, 8.0).wc);
        assert_eq!(m.point(1.0, 12.0).eff, m.point(1.0, 8.0).eff);
    }

    #[test]
    fn sub_idle_speed_law() {
        let m = lpt();
        let a = m.point(0.6, 4.0);
        let b = m.point(0.3, 4.0);
        assert_eq!(a.wc, b.wc);
        assert!((b.eff - a.eff * 0.75).abs() < 1e-12);
        assert_eq!(m.point(0.0, 4.0).eff, 0.0);
        // Above the highest line: held.
        assert_eq!(m.point(1.5, 4.0), m.point(1.2, 4.0));
    }

    #[test]
    fn gspy_turbine_map_builds() {
        let text = include_str!("../../config/maps/gspy_turbimap.map");
        let m = TurbineMap::from_gasturb(&parse(text, "gspy_turbimap.map").expect("parse"))
            .expect("build");
        assert_eq!(m.pr_limits(1.0), (1.15, 3.8));
        let p = m.point(1.0, 1.15 + 0.5 * (3.8 - 1.15));
        assert!((p.wc - 19.79688).abs() < 1e-9 && (p.eff - 0.93194).abs() < 1e-9);
    }

    proptest! {
        #[test]
        fn flow_non_decreasing_with_pr(nc in 0.0f64..1.3, pr in 0.9f64..9.0, d in 0.0f64..0.5) {
            for m in [hpt(), lpt()] {
                prop_assert!(m.point(nc, pr + d).wc >= m.point(nc, pr).wc - 1e-12);
                let p = m.point(nc, pr);
                prop_assert!(p.eff >= 0.0 && p.eff <= 1.0);
            }
        }
    }
}
