//! Compressor map in map units, with the extrapolation a start-up from cranking needs.
//!
//! What it is for: `(corrected flow, pressure ratio, efficiency) = f(relative corrected speed
//! nc, beta)` and its inverse `beta(nc, PR)`, from a GasTurb file's "Mass Flow", "Efficiency",
//! "Pressure Ratio" and "Surge Line" tables. What it must not do: allocate or do I/O in
//! [`CompressorMap::point`] / [`CompressorMap::beta_for_pr`] (called millions of times), or
//! know about engine units (that is `scaled`).
//!
//! # Conventions
//!
//! `nc` is relative corrected speed (1.0 = map design), `beta` the auxiliary coordinate along a
//! speed line, 0 at the surge end and 1 at the choke end, so PR falls with beta. A file whose PR
//! *rises* with beta (e.g. the GSPy sample map, GasTurb's own convention with β = 1 on the
//! surge side) is flipped on reading: `beta = b_min + b_max − beta_file`.
//!
//! Two β conventions therefore exist, and every API says which it takes:
//! * **the file's β** — the column keys of the map file, as GasTurb and GSP/GSPy read them. The
//!   engine file's `maps.compressor_design_beta` is in this convention (so a peer's design β is
//!   entered as the peer states it); [`CompressorMap::beta_from_file`] converts it.
//! * **gtwatch's internal β** (surge end low) — what [`CompressorMap::point`],
//!   [`CompressorMap::beta_for_pr`], the steady solver's unknown and the station table's
//!   `compressor_beta` use. For a map whose PR already falls with β (the embedded JT9D HPC map)
//!   both conventions are the same number.
//!
//! # Interpolation
//!
//! Bilinear in (nc, beta): linear along each speed line between beta keys, linear between the
//! two neighbouring speed lines. Continuous everywhere, monotone where the data are.
//!
//! Optionally ([`CompressorMap::with_cubic_interpolation`], engine file
//! `maps.interpolation = "cubic"`): the not-a-knot tensor-product cubic spline of
//! [`super::spline`] (SciPy's `RegularGridInterpolator(method="cubic")`, as GSPy uses) inside
//! the grid. Outside the grid the extrapolation rules below apply to the bilinear values plus
//! the cubic-minus-bilinear difference at the nearest grid point, so the map stays continuous
//! at the grid edge. [`CompressorMap::beta_for_pr`] then refines the bilinear inverse by Newton
//! steps.
//!
//! # Extrapolation (continuous everywhere)
//!
//! * **beta outside the keys**: PR and efficiency continue linearly with the end-segment slope;
//!   the PR slope is forced to be at least 10 % of the speed line's mean slope in the
//!   decreasing direction, so PR stays *strictly decreasing* in beta and
//!   [`CompressorMap::beta_for_pr`] has a solution for every PR (≥ 1, and below) at every speed.
//!   Flow continues linearly but is never negative; efficiency is clamped to `[0.05, 0.95]`.
//! * **below the lowest speed line** (0.5 for the HPC map) down to nc = 0: the affinity laws from
//!   the lowest line, `wc ∝ nc`, `(PR − 1) ∝ nc²`, and efficiency reduced smoothly,
//!   `eff = eff(n0, beta) · (1 − 0.5 ((n0 − nc)/n0)²)`. nc is clamped to ≥ 0.02 internally: at
//!   nc = 0 the speed line degenerates to the single point (wc 0, PR 1), beta loses its meaning
//!   and the inverse `beta_for_pr` would be singular; at 0.02 (≈ 190 rpm on a 9 500 rpm spool,
//!   below any cranking speed) the line still has a finite PR range.
//! * **above the highest speed line**: linear extrapolation from the last two lines, bounded at
//!   `n_max + min(0.10, n_max − n_prev)` (one line spacing: 1.075 for the HPC map); faster is
//!   treated as that speed. The bound is one spacing rather than a fixed 0.10 because
//!   extrapolating the HPC map's top two lines (1.025, 1.05) further makes PR *rise* with beta
//!   (their choke ends diverge faster than their surge ends), which would break `beta_for_pr`.
//! * **surge line** below its lowest point follows the same affinity law,
//!   `PR − 1 ∝ wc²`; above its highest point it continues linearly.
//!
//! # Inverse
//!
//! The dynamic model reads the compressor at the pressure ratio its volumes hold
//! ([`CompressorMap::beta_for_pr`], [`CompressorMap::wc_at_pr`]), so the inverse must be a
//! continuous function of PR. Real low-speed lines often rise from their surge end before they
//! fall (a positive-slope hump: the GSPy sample map's 0.45–0.6 lines, pyCycle's 0.9–0.95):
//! there PR is not invertible, and taking the crossing nearest surge made the flow jump by a
//! quarter where PR passes the surge end's value. A start-up whose working line runs there
//! chattered across the jump (600 000 rejected steps for a 680 s start-up on a GSPy-map
//! engine). For the inverse only, each stored line's PR is lifted from its choke end toward
//! surge so it falls at least at the extrapolation's least slope (a hump becomes a steep
//! falling stretch; a line that already falls is untouched, as every line of the embedded and
//! md22 maps does), and with the cubic interpolation the lifted stretch keeps the bilinear
//! inverse. [`CompressorMap::point`] is the map's own data everywhere.

use super::gasturb::{GasTurbFile, MapError, MapTable};
use super::spline::CubicGrid;

/// Lower bound of nc used internally (see module docs).
pub const NC_MIN: f64 = 0.02;
/// At most this far above the highest speed line the map is extrapolated (and at most one
/// speed-line spacing, see module docs).
pub const NC_EXTRAP_ABOVE: f64 = 0.10;
/// Efficiency bounds applied to every result.
pub const EFF_MIN: f64 = 0.05;
pub const EFF_MAX: f64 = 0.95;

/// One map point in map units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompressorPoint {
    /// Corrected flow in the map's units.
    pub wc: f64,
    /// Total pressure ratio.
    pub pr: f64,
    /// Isentropic efficiency.
    pub eff: f64,
}

/// A compressor map ready for fast evaluation.
#[derive(Debug, Clone)]
pub struct CompressorMap {
    title: String,
    speeds: Vec<f64>,
    betas: Vec<f64>,
    /// `[line * m + k]` values, m = betas.len().
    wc: Vec<f64>,
    pr: Vec<f64>,
    eff: Vec<f64>,
    /// PR as [`CompressorMap::beta_for_pr`] inverts it: `pr` where the line falls with beta; a
    /// line that rises from its surge end (a positive-slope hump) is lifted there to fall with
    /// its extrapolation slope (module docs, "Inverse").
    pr_inv: Vec<f64>,
    /// Per line, one past the highest beta key whose `pr_inv` is lifted above `pr` (0: none):
    /// below that key the cubic map keeps the bilinear inverse.
    lifted: Vec<usize>,
    /// Extrapolation slopes per line: below the first and above the last beta key.
    slope_lo: Vec<[f64; 3]>,
    slope_hi: Vec<[f64; 3]>,
    surge_wc: Vec<f64>,
    surge_pr: Vec<f64>,
    flipped: bool,
    /// The cubic interpolant, when selected.
    cubic: Option<CubicGrid>,
}

/// How a corrected speed maps onto the stored speed lines: `value = c0·line[j] + c1·line[j+1]`,
/// then flow × `wc_f`, `PR − 1` × `pr_f`, efficiency × `eff_f`.
#[derive(Debug, Clone, Copy)]
struct Blend {
    j: usize,
    c0: f64,
    c1: f64,
    wc_f: f64,
    pr_f: f64,
    eff_f: f64,
}

fn check_grid(source: &str, base: &MapTable, t: &MapTable) -> Result<(), MapError> {
    if t.row_keys != base.row_keys || t.col_keys != base.col_keys {
        return Err(MapError::Invalid {
            source_name: source.to_string(),
            table: t.name.clone(),
            reason: format!(
                "speed/beta keys differ from table \"{}\" (all speed-line tables must share one grid)",
                base.name
            ),
        });
    }
    Ok(())
}

impl CompressorMap {
    /// Build from the "Mass Flow", "Efficiency", "Pressure Ratio" and "Surge Line" tables.
    pub fn from_gasturb(f: &GasTurbFile) -> Result<Self, MapError> {
        let src = f.source.as_str();
        let wc_t = f.require("Mass Flow")?;
        let eff_t = f.require("Efficiency")?;
        let pr_t = f.require("Pressure Ratio")?;
        let surge_t = f.require("Surge Line")?;
        check_grid(src, wc_t, eff_t)?;
        check_grid(src, wc_t, pr_t)?;
        let invalid = |table: &str, reason: String| MapError::Invalid {
            source_name: src.to_string(),
            table: table.to_string(),
            reason,
        };
        let n = wc_t.row_keys.len();
        let m = wc_t.col_keys.len();
        if n < 2 || m < 2 {
            return Err(invalid(
                "Mass Flow",
                format!("need at least 2 speed lines and 2 beta values, found {n} x {m}"),
            ));
        }
        if wc_t.row_keys[0] <= 0.0 {
            return Err(invalid(
                "Mass Flow",
                format!("lowest speed must be positive, found {}", wc_t.row_keys[0]),
            ));
        }
        // Orientation: PR should fall with beta; flip files where it rises.
        let rise: f64 = pr_t.values.iter().map(|r| r[m - 1] - r[0]).sum();
        let flipped = rise > 0.0;
        let (b0, b1) = (wc_t.col_keys[0], wc_t.col_keys[m - 1]);
        let mut betas: Vec<f64> = wc_t.col_keys.clone();
        if flipped {
            betas = wc_t.col_keys.iter().rev().map(|b| b0 + b1 - b).collect();
        }
        let flat = |t: &MapTable| -> Vec<f64> {
            t.values
                .iter()
                .flat_map(|row| {
                    let row: Vec<f64> = if flipped {
                        row.iter().rev().copied().collect()
                    } else {
                        row.clone()
                    };
                    row
                })
                .collect()
        };
        let wc = flat(wc_t);
        let pr = flat(pr_t);
        let eff = flat(eff_t);
        for (i, &s) in wc_t.row_keys.iter().enumerate() {
            for k in 0..m {
                let (w, p, e) = (wc[i * m + k], pr[i * m + k], eff[i * m + k]);
                if w <= 0.0 || p <= 0.0 || e <= 0.0 || e > 1.0 {
                    return Err(invalid(
                        "Mass Flow/Pressure Ratio/Efficiency",
                        format!(
                            "speed {s}, beta column {}: implausible point wc {w}, PR {p}, eff {e}",
                            k + 1
                        ),
                    ));
                }
            }
        }
        let mut slope_lo = Vec::with_capacity(n);
        let mut slope_hi = Vec::with_capacity(n);
        let mut pr_inv = pr.clone();
        let mut lifted = vec![0; n];
        for i in 0..n {
            let at = |v: &Vec<f64>, k: usize| v[i * m + k];
            let db_lo = betas[1] - betas[0];
            let db_hi = betas[m - 1] - betas[m - 2];
            let mean_pr_slope = (at(&pr, m - 1) - at(&pr, 0)) / (betas[m - 1] - betas[0]);
            // At least 10 % of the mean slope, decreasing (and never flat).
            let min_drop = (0.1 * mean_pr_slope.abs()).max(1e-3);
            let lo = [
                (at(&wc, 1) - at(&wc, 0)) / db_lo,
                ((at(&pr, 1) - at(&pr, 0)) / db_lo).min(-min_drop),
                (at(&eff, 1) - at(&eff, 0)) / db_lo,
            ];
            let hi = [
                (at(&wc, m - 1) - at(&wc, m - 2)) / db_hi,
                ((at(&pr, m - 1) - at(&pr, m - 2)) / db_hi).min(-min_drop),
                (at(&eff, m - 1) - at(&eff, m - 2)) / db_hi,
            ];
            slope_lo.push(lo);
            slope_hi.push(hi);
            // From the choke end toward surge, a key whose PR does not rise above the next
            // one's is lifted to fall at the extrapolation's least slope.
            for k in (0..m - 1).rev() {
                let next = pr_inv[i * m + k + 1];
                if pr_inv[i * m + k] <= next {
                    pr_inv[i * m + k] = next + min_drop * (betas[k + 1] - betas[k]);
                    lifted[i] = lifted[i].max(k + 1);
                }
            }
        }
        // Surge line: one row of PR against corrected flow.
        let surge_wc = surge_t.col_keys.clone();
        let surge_pr = surge_t
            .values
            .first()
            .cloned()
            .ok_or_else(|| invalid("Surge Line", "no PR row".into()))?;
        if surge_wc.len() < 2 || surge_wc[0] <= 0.0 || surge_pr.iter().any(|&p| p <= 1.0) {
            return Err(invalid(
                "Surge Line",
                "need at least 2 points with positive flow and PR > 1".into(),
            ));
        }
        Ok(CompressorMap {
            title: f.title.clone(),
            speeds: wc_t.row_keys.clone(),
            betas,
            wc,
            pr,
            eff,
            pr_inv,
            lifted,
            slope_lo,
            slope_hi,
            surge_wc,
            surge_pr,
            flipped,
            cubic: None,
        })
    }

    /// The same map interpolated with not-a-knot cubic splines inside its grid (module docs).
    /// Needs 4 to 64 speed lines and β values.
    pub fn with_cubic_interpolation(mut self) -> Result<Self, MapError> {
        self.cubic = Some(CubicGrid::for_map(&self.title, &self.speeds, &self.betas)?);
        Ok(self)
    }

    /// Whether the cubic interpolation is selected.
    pub fn is_cubic(&self) -> bool {
        self.cubic.is_some()
    }

    /// Cubic minus bilinear value of (wc, PR, eff) at the grid point nearest (`nc`, `beta`);
    /// zeros for the bilinear map.
    #[inline(never)]
    fn cubic_correction(&self, nc: f64, beta: f64) -> [f64; 3] {
        let Some(grid) = &self.cubic else {
            return [0.0; 3];
        };
        let (s, b) = (&self.speeds, &self.betas);
        let ncc = if nc.is_nan() {
            s[0]
        } else {
            nc.clamp(s[0], s[s.len() - 1])
        };
        let bc = if beta.is_nan() {
            b[0]
        } else {
            beta.clamp(b[0], b[b.len() - 1])
        };
        let bl = self.blend(ncc);
        let (k, f) = self.beta_pos(bc);
        let mut out = [0.0; 3];
        for (q, slot) in out.iter_mut().enumerate() {
            let lin = bl.c0 * self.line_value(q, bl.j, bc, k, f)
                + bl.c1 * self.line_value(q, bl.j + 1, bc, k, f);
            let values = match q {
                0 => &self.wc,
                1 => &self.pr,
                _ => &self.eff,
            };
            *slot = grid.eval(values, ncc, bc) - lin;
        }
        out
    }

    /// Title of the source file.
    pub fn title(&self) -> &str {
        &self.title
    }
    /// Speed-line keys (relative corrected speed).
    pub fn speeds(&self) -> &[f64] {
        &self.speeds
    }
    /// Beta keys (after any flip; increasing from surge to choke).
    pub fn betas(&self) -> &[f64] {
        &self.betas
    }
    /// Whether the file's beta direction was reversed on reading.
    pub fn flipped(&self) -> bool {
        self.flipped
    }
    /// gtwatch's internal β for a β stated in the map file's convention (identity unless the
    /// file was flipped; see the module docs).
    pub fn beta_from_file(&self, beta_file: f64) -> f64 {
        if self.flipped {
            let m = self.betas.len();
            self.betas[0] + self.betas[m - 1] - beta_file
        } else {
            beta_file
        }
    }
    /// The map file's β for an internal β (the inverse of [`CompressorMap::beta_from_file`]).
    pub fn beta_to_file(&self, beta: f64) -> f64 {
        // The flip is its own inverse.
        self.beta_from_file(beta)
    }
    /// Surge-line points (corrected flow, PR).
    pub fn surge_points(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.surge_wc
            .iter()
            .copied()
            .zip(self.surge_pr.iter().copied())
    }

    /// Highest corrected speed the map extrapolates to; faster is evaluated at this speed.
    pub fn nc_max(&self) -> f64 {
        let s = &self.speeds;
        let n = s.len();
        s[n - 1] + NC_EXTRAP_ABOVE.min(s[n - 1] - s[n - 2])
    }

    #[inline]
    fn blend(&self, nc: f64) -> Blend {
        let s = &self.speeds;
        let n = s.len();
        let nc = if nc.is_nan() { NC_MIN } else { nc };
        if nc < s[0] {
            let nc = nc.max(NC_MIN);
            let r = nc / s[0];
            let d = (s[0] - nc) / s[0];
            return Blend {
                j: 0,
                c0: 1.0,
                c1: 0.0,
                wc_f: r,
                pr_f: r * r,
                eff_f: 1.0 - 0.5 * d * d,
            };
        }
        if nc >= s[n - 1] {
            let nc = nc.min(self.nc_max());
            let u = (nc - s[n - 1]) / (s[n - 1] - s[n - 2]);
            return Blend {
                j: n - 2,
                c0: -u,
                c1: 1.0 + u,
                wc_f: 1.0,
                pr_f: 1.0,
                eff_f: 1.0,
            };
        }
        // s[0] <= nc < s[n-1]: j with s[j] <= nc < s[j+1].
        let j = s.partition_point(|&x| x <= nc) - 1;
        let t = (nc - s[j]) / (s[j + 1] - s[j]);
        Blend {
            j,
            c0: 1.0 - t,
            c1: t,
            wc_f: 1.0,
            pr_f: 1.0,
            eff_f: 1.0,
        }
    }

    /// Value of quantity `q` (0 wc, 1 pr, 2 eff) on stored line `i` at beta.
    #[inline]
    fn line_value(&self, q: usize, i: usize, beta: f64, k: usize, frac_or_db: f64) -> f64 {
        let m = self.betas.len();
        let v = match q {
            0 => &self.wc,
            1 => &self.pr,
            _ => &self.eff,
        };
        if beta < self.betas[0] {
            v[i * m] + frac_or_db * self.slope_lo[i][q]
        } else if beta > self.betas[m - 1] {
            v[i * m + m - 1] + frac_or_db * self.slope_hi[i][q]
        } else {
            let a = v[i * m + k];
            a + frac_or_db * (v[i * m + k + 1] - a)
        }
    }

    /// Segment index and position for beta: inside, `(k, fraction)`; outside, `(_, Δbeta)`.
    #[inline(always)]
    fn beta_pos(&self, beta: f64) -> (usize, f64) {
        let b = &self.betas;
        let m = b.len();
        if beta < b[0] {
            (0, beta - b[0])
        } else if beta > b[m - 1] {
            (m - 2, beta - b[m - 1])
        } else {
            let k = (b.partition_point(|&x| x <= beta)).clamp(1, m - 1) - 1;
            (k, (beta - b[k]) / (b[k + 1] - b[k]))
        }
    }

    /// Map point at relative corrected speed `nc` and `beta` (allocation-free).
    pub fn point(&self, nc: f64, beta: f64) -> CompressorPoint {
        self.point_in(&self.blend(nc), nc, beta)
    }

    /// [`CompressorMap::point`] on the speed blend `bl` of `nc` already found.
    #[inline(always)]
    fn point_in(&self, bl: &Blend, nc: f64, beta: f64) -> CompressorPoint {
        let (k, f) = self.beta_pos(beta);
        let mix = |q: usize| {
            bl.c0 * self.line_value(q, bl.j, beta, k, f)
                + bl.c1 * self.line_value(q, bl.j + 1, beta, k, f)
        };
        let (mut v0, mut v1, mut v2) = (mix(0), mix(1), mix(2));
        // The bilinear map (the common case) skips the correction entirely: the simulation's
        // hot path reads the map on every right-hand-side call.
        if self.cubic.is_some() {
            let corr = self.cubic_correction(nc, beta);
            v0 += corr[0];
            v1 += corr[1];
            v2 += corr[2];
        }
        let wc = (v0 * bl.wc_f).max(0.0);
        let pr = 1.0 + bl.pr_f * (v1 - 1.0);
        let eff = (v2 * bl.eff_f).clamp(EFF_MIN, EFF_MAX);
        CompressorPoint { wc, pr, eff }
    }

    /// Beta at which the (interpolated) speed line `nc` reaches pressure ratio `pr`. Exact
    /// inverse of `point(nc, beta).pr`: the line is piecewise linear in beta with the same
    /// breakpoints, so one scan over the beta keys and one linear solve. Defined for every `pr`
    /// (extrapolated beyond the keys) and continuous in it. Where a line rises from its surge
    /// end, it inverts the lifted PR instead (module docs, "Inverse"), so it is not the inverse
    /// of `point` there. With the cubic interpolation, the bilinear inverse is refined by
    /// Newton steps on [`CompressorMap::point`] outside the lifted stretches.
    pub fn beta_for_pr(&self, nc: f64, pr: f64) -> f64 {
        self.beta_for_pr_on(&self.blend(nc), nc, pr)
    }

    /// [`CompressorMap::beta_for_pr`] on the speed blend `bl` of `nc` already found (the
    /// Newton steps of a cubic map read the surface on it too).
    #[inline]
    fn beta_for_pr_on(&self, bl: &Blend, nc: f64, pr: f64) -> f64 {
        let mut b = self.beta_for_pr_in(bl, pr);
        if self.cubic.is_none() || self.in_lifted(bl, b) {
            return b;
        }
        for _ in 0..30 {
            let p = self.point_in(bl, nc, b).pr;
            let err = p - pr;
            if err.abs() <= 1e-13 * pr.abs().max(1.0) {
                break;
            }
            let db = 1e-7;
            let slope = (self.point_in(bl, nc, b + db).pr - p) / db;
            if slope >= 0.0 || !slope.is_finite() {
                break;
            }
            b -= err / slope;
        }
        b
    }

    /// Whether `beta` lies where either speed line of blend `bl` is lifted for the inverse
    /// (beyond the surge end included): there the cubic surface's PR is not monotone, and the
    /// bilinear inverse of the lifted PR stands.
    #[inline(always)]
    fn in_lifted(&self, bl: &Blend, beta: f64) -> bool {
        let upto = self.lifted[bl.j].max(self.lifted[bl.j + 1]);
        upto > 0 && beta < self.betas[upto]
    }

    /// The bilinear inverse (of the lifted PR) on the speed blend `bl` of `nc` already found.
    #[inline(always)]
    fn beta_for_pr_in(&self, bl: &Blend, pr: f64) -> f64 {
        let m = self.betas.len();
        let (j0, j1) = (bl.j * m, (bl.j + 1) * m);
        let pr_at = |k: usize| {
            1.0 + bl.pr_f * (bl.c0 * self.pr_inv[j0 + k] + bl.c1 * self.pr_inv[j1 + k] - 1.0)
        };
        let mut prev = pr_at(0);
        if pr >= prev {
            let slope =
                bl.pr_f * (bl.c0 * self.slope_lo[bl.j][1] + bl.c1 * self.slope_lo[bl.j + 1][1]);
            return self.betas[0] + (pr - prev) / slope;
        }
        for k in 1..m {
            let cur = pr_at(k);
            if pr >= cur {
                let d = cur - prev;
                return if d == 0.0 {
                    self.betas[k - 1]
                } else {
                    self.betas[k - 1] + (pr - prev) / d * (self.betas[k] - self.betas[k - 1])
                };
            }
            prev = cur;
        }
        let slope = bl.pr_f * (bl.c0 * self.slope_hi[bl.j][1] + bl.c1 * self.slope_hi[bl.j + 1][1]);
        self.betas[m - 1] + (pr - prev) / slope
    }

    /// Corrected flow at speed `nc` and pressure ratio `pr`: `point(nc, beta_for_pr(nc, pr)).wc`
    /// to the bit, with one speed blend for the inverse and the point (the dynamic model's
    /// first compressor read needs the flow alone, and no surge line).
    pub fn wc_at_pr(&self, nc: f64, pr: f64) -> f64 {
        let bl = self.blend(nc);
        self.point_in(&bl, nc, self.beta_for_pr_on(&bl, nc, pr)).wc
    }

    /// Pressure ratio on the surge line at corrected flow `wc` (map units).
    pub fn surge_pr(&self, wc: f64) -> f64 {
        let w = &self.surge_wc;
        let p = &self.surge_pr;
        let n = w.len();
        if wc <= w[0] {
            let r = wc.max(0.0) / w[0];
            return 1.0 + (p[0] - 1.0) * r * r;
        }
        let k = if wc >= w[n - 1] {
            n - 2
        } else {
            w.partition_point(|&x| x <= wc) - 1
        };
        p[k] + (wc - w[k]) * (p[k + 1] - p[k]) / (w[k + 1] - w[k])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::maps::gasturb::parse;
    use crate::maps::HPC_MAP;
    use proptest::prelude::*;

    fn hpc() -> CompressorMap {
        CompressorMap::from_gasturb(&parse(HPC_MAP, "hpc.map").expect("parse")).expect("build")
    }

    /// The flow-only read is the full read's flow to the bit, inside and outside the grid, for
    /// both interpolations (the dynamic model's result must not depend on which it calls).
    #[test]
    fn the_flow_only_read_is_the_full_reads_flow_to_the_bit() {
        for m in [hpc(), hpc().with_cubic_interpolation().expect("cubic")] {
            for i in 0..=40 {
                let nc = 0.2 + 1.0 * f64::from(i) / 40.0;
                for j in 0..=30 {
                    let pr = 0.8 + 30.0 * f64::from(j) / 30.0;
                    let full = m.point(nc, m.beta_for_pr(nc, pr)).wc;
                    assert_eq!(
                        m.wc_at_pr(nc, pr).to_bits(),
                        full.to_bits(),
                        "nc {nc} pr {pr}"
                    );
                }
            }
        }
    }

    #[test]
    fn reproduces_grid_points() {
        let m = hpc();
        let p = m.point(1.0, 0.5);
        assert!((p.pr - 22.9999).abs() < 1e-9 && (p.eff - 0.852).abs() < 1e-12);
        assert!((p.wc - 206.0).abs() < 1e-9);
        let p = m.point(0.5, 0.0);
        assert!((p.wc - 22.7411).abs() < 1e-12 && (p.pr - 2.4769).abs() < 1e-12);
        let p = m.point(1.05, 1.0);
        assert!((p.pr - 22.4038).abs() < 1e-9);
        assert!(!m.flipped());
    }

    #[test]
    fn continuous_at_boundaries() {
        let m = hpc();
        let e = 1e-9;
        let close = |a: CompressorPoint, b: CompressorPoint, tol: f64| {
            (a.wc - b.wc).abs() < tol * 250.0
                && (a.pr - b.pr).abs() < tol * 30.0
                && (a.eff - b.eff).abs() < tol
        };
        for i in 0..=40 {
            let beta = -0.3 + 1.6 * i as f64 / 40.0;
            for &nc in m.speeds().iter() {
                assert!(
                    close(m.point(nc - e, beta), m.point(nc + e, beta), 1e-6),
                    "nc {nc} beta {beta}"
                );
            }
            for nc in [0.02 + 1e-12, m.nc_max()] {
                assert!(
                    close(m.point(nc - e, beta), m.point(nc + e, beta), 1e-6),
                    "nc {nc}"
                );
            }
        }
        for i in 0..=60 {
            let nc = 0.05 + 1.1 * i as f64 / 60.0;
            for b in [0.0, 1.0, 0.5] {
                let (a, c) = (m.point(nc, b - e), m.point(nc, b + e));
                assert!(close(a, c, 1e-6), "beta {b} nc {nc}: {a:?} {c:?}");
            }
        }
        // Sub-idle law meets the lowest line.
        let a = m.point(0.5, 0.3);
        let b = m.point(0.5 - 1e-10, 0.3);
        assert!(close(a, b, 1e-8));
    }

    #[test]
    fn monotone_in_speed_and_beta() {
        let m = hpc();
        for i in 0..=30 {
            let beta = -0.2 + 1.4 * i as f64 / 30.0;
            let mut last = m.point(0.02, beta);
            let mut nc = 0.03;
            while nc <= 1.15 {
                let p = m.point(nc, beta);
                assert!(
                    p.wc >= last.wc,
                    "wc not increasing with nc at {nc}, beta {beta}"
                );
                last = p;
                nc += 0.01;
            }
        }
        let mut nc = 0.02;
        while nc <= 1.15 {
            let mut last = m.point(nc, -0.5).pr;
            let mut beta = -0.49;
            while beta <= 1.5 {
                let pr = m.point(nc, beta).pr;
                assert!(
                    pr < last,
                    "PR not decreasing in beta at nc {nc}, beta {beta}"
                );
                last = pr;
                beta += 0.01;
            }
            nc += 0.013;
        }
    }

    #[test]
    fn beta_for_pr_defined_for_every_pr_at_every_speed() {
        let m = hpc();
        for nc in [0.02, 0.1, 0.25, 0.5, 0.77, 1.0, 1.1, 1.15, 1.3] {
            for pr in [0.95, 1.0, 1.001, 1.05, 1.5, 3.0, 10.0, 24.0, 35.0] {
                let b = m.beta_for_pr(nc, pr);
                assert!(b.is_finite());
                let back = m.point(nc, b).pr;
                assert!(
                    (back - pr).abs() < 1e-9 * pr,
                    "nc {nc} pr {pr}: beta {b} -> {back}"
                );
            }
        }
    }

    #[test]
    fn surge_line_and_sub_idle() {
        let m = hpc();
        // Surge line is the beta-0 end of each speed line in this map.
        for &nc in m.speeds() {
            let p = m.point(nc, 0.0);
            assert!((m.surge_pr(p.wc) - p.pr).abs() < 1e-9);
        }
        // Below the lowest line the affinity law holds for both speed line and surge line.
        let p = m.point(0.25, 0.0);
        assert!((m.surge_pr(p.wc) - p.pr).abs() < 1e-9);
        let p0 = m.point(0.5, 0.4);
        let p = m.point(0.25, 0.4);
        assert!((p.wc - 0.5 * p0.wc).abs() < 1e-12);
        assert!((p.pr - 1.0 - 0.25 * (p0.pr - 1.0)).abs() < 1e-12);
        assert!((p.eff - p0.eff * (1.0 - 0.5 * 0.25)).abs() < 1e-12);
        // nc = 0 is treated as NC_MIN.
        assert_eq!(m.point(0.0, 0.5), m.point(NC_MIN, 0.5));
    }

    #[test]
    fn gspy_map_is_flipped_to_surge_at_beta_zero() {
        let text = include_str!("../../config/maps/gspy_compmap.map");
        let m = CompressorMap::from_gasturb(&parse(text, "gspy_compmap.map").expect("parse"))
            .expect("build");
        assert!(m.flipped());
        // File beta 1 (highest PR) is beta 0 here.
        let p = m.point(1.0, 0.0);
        assert!((p.pr - 7.9484).abs() < 1e-9 && (p.wc - 19.7).abs() < 1e-9);
        // Where its data are monotone the inverse works too.
        let b = m.beta_for_pr(0.9, 4.5);
        assert!((m.point(0.9, b).pr - 4.5).abs() < 1e-9);
    }

    /// The dynamic model reads flow at the PR its volumes hold: on a map whose low-speed lines
    /// rise from their surge end (GSPy's sample map, 0.45–0.6), that flow is continuous and
    /// falls as PR rises, at every speed from cranking up, bilinear and cubic. (Taking the
    /// crossing nearest surge made it jump by 27 % at 0.2 where PR passes the surge end.) Where
    /// the line falls, the inverse is still `point`'s.
    #[test]
    fn flow_at_pr_is_continuous_where_a_line_rises_from_surge() {
        let text = include_str!("../../config/maps/gspy_compmap.map");
        let lin = CompressorMap::from_gasturb(&parse(text, "gspy_compmap.map").expect("parse"))
            .expect("build");
        let cubic = lin.clone().with_cubic_interpolation().expect("cubic");
        for m in [&lin, &cubic] {
            for nc in [0.1, 0.2, 0.3, 0.45, 0.475, 0.5, 0.55, 0.6, 0.65, 0.8, 1.0] {
                // From a PR on the choke side past the humps (keys 0–0.125) and the surge end.
                let lo = m.point(nc, 0.9).pr;
                let hi = m.point(nc, -0.05).pr.max(m.point(nc, 0.25).pr);
                let steps = 20_000;
                let mut last = m.wc_at_pr(nc, lo);
                for i in 1..=steps {
                    let pr = lo + (hi - lo) * f64::from(i) / f64::from(steps);
                    let wc = m.wc_at_pr(nc, pr);
                    assert!(
                        wc <= last * (1.0 + 1e-6) && last - wc <= 0.01 * last,
                        "cubic {} nc {nc} pr {pr}: wc {last} -> {wc}",
                        m.is_cubic()
                    );
                    last = wc;
                }
            }
        }
        // The 0.9 line falls: there the inverse is the point's, cubic too.
        let b = cubic.beta_for_pr(0.9, 4.5);
        assert!((cubic.point(0.9, b).pr - 4.5).abs() < 1e-9);
    }

    /// The engine file's design β is the map file's β on both map families: GSPy's sample map
    /// (PR rises with the file's β, flipped) at GSPy's design β 0.79 lands between the file's
    /// columns 0.75 and 0.875 (bilinear: 32 % of the way), next to the point GSPy prints
    /// (turboshaft_2spool: PR map 6.7543, Eta map 0.8667, Wc map 19.857, from its cubic
    /// interpolation); the JT9D HPC map (not flipped) is unchanged.
    #[test]
    fn design_beta_in_the_map_files_convention() {
        let dir = "config/maps";
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(dir)
            .join("gspy_compmap.map");
        let m = CompressorMap::from_gasturb(&crate::maps::read_file(&path).expect("read"))
            .expect("build");
        assert!(m.flipped());
        let b = m.beta_from_file(0.79);
        assert!((b - 0.21).abs() < 1e-12, "{b}");
        assert!((m.beta_to_file(b) - 0.79).abs() < 1e-12);
        let p = m.point(1.0, b);
        let lin = |a: f64, c: f64| a + 0.32 * (c - a);
        assert!((p.pr - lin(6.62920, 7.06568)).abs() < 1e-9, "{dir}: {p:?}");
        assert!((p.eff - lin(0.87, 0.85)).abs() < 1e-9, "{dir}: {p:?}");
        assert!((p.wc - lin(19.87, 19.82)).abs() < 1e-9, "{dir}: {p:?}");
        // GSPy's printed point, within the bilinear-vs-cubic difference.
        assert!((p.pr / 6.7543 - 1.0).abs() < 0.005, "{dir}: {p:?}");
        assert!((p.eff / 0.8667 - 1.0).abs() < 0.005, "{dir}: {p:?}");
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(dir)
            .join("hpc.map");
        let h = CompressorMap::from_gasturb(&crate::maps::read_file(&path).expect("read"))
            .expect("build");
        assert!(!h.flipped());
        assert_eq!(h.beta_from_file(0.5), 0.5);
        assert!((h.point(1.0, h.beta_from_file(0.5)).pr - 22.9999).abs() < 1e-9);
    }

    /// Cubic interpolation: equals the grid at its nodes, stays continuous across the grid edge
    /// into the extrapolation, and `beta_for_pr` still inverts `point`.
    #[test]
    fn cubic_interpolation_is_continuous_and_invertible() {
        let m = hpc().with_cubic_interpolation().expect("cubic");
        assert!(m.is_cubic());
        let lin = hpc();
        for &nc in m.speeds() {
            for &b in m.betas() {
                let (a, c) = (m.point(nc, b), lin.point(nc, b));
                assert!((a.pr - c.pr).abs() < 1e-9 && (a.eff - c.eff).abs() < 1e-12);
            }
        }
        let (s0, s1) = (m.speeds()[0], m.speeds()[m.speeds().len() - 1]);
        let e = 1e-9;
        for i in 0..=20 {
            let beta = 0.05 * i as f64;
            for nc in [s0, s1] {
                let (a, c) = (m.point(nc - e, beta), m.point(nc + e, beta));
                assert!(
                    (a.pr - c.pr).abs() < 1e-6 && (a.wc - c.wc).abs() < 1e-5,
                    "nc {nc}"
                );
            }
        }
        for i in 0..=20 {
            let nc = 0.55 + 0.025 * i as f64;
            for b in [0.0, 1.0] {
                let (a, c) = (m.point(nc, b - e), m.point(nc, b + e));
                assert!((a.pr - c.pr).abs() < 1e-6 && (a.eff - c.eff).abs() < 1e-6);
            }
            for beta in [0.1, 0.45, 0.9] {
                let pr = m.point(nc, beta).pr;
                let back = m.beta_for_pr(nc, pr);
                assert!((back - beta).abs() < 1e-8, "nc {nc} beta {beta} -> {back}");
            }
        }
    }

    proptest! {
        #[test]
        fn beta_for_pr_inverts_point(nc in 0.0f64..1.2, beta in -0.5f64..1.5) {
            let m = hpc();
            let p = m.point(nc, beta);
            let b = m.beta_for_pr(nc, p.pr);
            prop_assert!((b - beta).abs() < 1e-9, "nc {} beta {} -> {}", nc, beta, b);
        }
    }
}
