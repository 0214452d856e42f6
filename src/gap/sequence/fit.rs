//! The joint fit behind every hypothesis of [`super`]: weighted least squares of the start-ups'
//! health estimates on six trend lines plus what a hypothesis adds (columns switched on from the
//! onset, a shared mismatch held by a prior, a free later step), and each estimate's variance.
//!
//! Pure linear algebra on the points given; must not decide between hypotheses (that is
//! [`super`]'s).

use super::{sigma_of, SeqPoint};
use nalgebra::{DMatrix, DVector};

/// Each estimate's variance: its own σ² plus, per parameter, the scatter the start-ups before
/// the onset show about their own line beyond their σ (method of moments).
pub(super) fn variances(points: &[SeqPoint], k: usize) -> Vec<[f64; 6]> {
    let before = &points[..k];
    let t_mean = before.iter().map(|p| p.t_days).sum::<f64>() / k as f64;
    let mut extra = [0.0; 6];
    for (i, e) in extra.iter_mut().enumerate() {
        // Weighted line through the points before the onset.
        let (mut sw, mut st, mut stt, mut sy, mut sty) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for p in before.iter().filter(|p| !p.at_limit[i]) {
            let w = 1.0 / sigma_of(p.sigma[i]).powi(2);
            let t = p.t_days - t_mean;
            sw += w;
            st += w * t;
            stt += w * t * t;
            sy += w * p.health[i];
            sty += w * t * p.health[i];
        }
        let det = sw * stt - st * st;
        let (a, b) = if det.abs() > 1e-12 {
            ((stt * sy - st * sty) / det, (sw * sty - st * sy) / det)
        } else {
            (sy / sw, 0.0)
        };
        let used: Vec<&SeqPoint> = before.iter().filter(|p| !p.at_limit[i]).collect();
        if used.is_empty() || sw <= 0.0 {
            continue;
        }
        let dof = (used.len() as f64 - 2.0).max(1.0);
        let ss: f64 = used
            .iter()
            .map(|p| (p.health[i] - a - b * (p.t_days - t_mean)).powi(2))
            .sum();
        let own: f64 = used
            .iter()
            .map(|p| sigma_of(p.sigma[i]).powi(2))
            .sum::<f64>()
            / used.len() as f64;
        *e = (ss / dof - own).max(0.0);
    }
    points
        .iter()
        .map(|p| std::array::from_fn(|i| sigma_of(p.sigma[i]).powi(2) + extra[i]))
        .collect()
}

pub(super) struct Solved {
    /// χ², the mismatch's prior included.
    pub(super) chi2: f64,
    /// Parameters fitted (trend lines and extra columns an estimate informs; the mismatch,
    /// held by its prior, is not counted).
    pub(super) params: usize,
    /// The extra columns' coefficients and their 1σ.
    pub(super) coef: Vec<f64>,
    pub(super) coef_sigma: Vec<f64>,
    /// The shared mismatch (0 without one; per day of a drift).
    pub(super) mismatch: [f64; 6],
    /// 1σ of the whole step (extra columns and mismatch) in each parameter (per day of a
    /// drift).
    pub(super) step_sigma: [f64; 6],
    /// Each parameter's trend line: value at `t_ref_days` and rate per day.
    pub(super) lines: [[f64; 2]; 6],
    /// Each line's covariance: the value's variance, the rate's, and theirs.
    pub(super) line_cov: [[f64; 3]; 6],
    pub(super) t_ref_days: f64,
}

/// What one hypothesis adds to the six trend lines.
pub(super) struct Spec<'a> {
    /// Health-space directions switched on from the onset (each one coefficient).
    pub(super) cols: &'a [[f64; 6]],
    /// Switched on from the onset to this start-up (exclusive): the onset alone for an
    /// outlier, the sequence's length for a step that lasts (ended earlier by a later step).
    pub(super) until: usize,
    /// A mismatch in every direction shared from the onset on (growing with a drift's share),
    /// held to 0 with this 1σ, in points at the newest start-up it is on.
    pub(super) mismatch_sigma: Option<f64>,
    /// Steps every hypothesis of the sequence has besides its own.
    pub(super) breaks: Breaks,
    /// `None`: the columns are a step (the same at every start-up they are on). `Some(t0)`: a
    /// drift, each start-up's share growing with its time since `t0` (days), so a column's
    /// coefficient is a rate per day.
    pub(super) ramp_from_days: Option<f64>,
}

/// How much of a hypothesis's columns a start-up at `t_days` carries: all of a step, the days
/// since its start of a drift.
pub(super) fn share(ramp_from_days: Option<f64>, t_days: f64) -> f64 {
    ramp_from_days.map_or(1.0, |t0| (t_days - t0).max(0.0))
}

/// Steps in a sequence besides the one a hypothesis explains, each free.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Breaks {
    /// A second step in all six parameters from this start-up to the end (the first step's
    /// columns then end there).
    pub(crate) later: Option<usize>,
    /// A wash (a step in both compressor parameters) before the onset, from this start-up on:
    /// one the trend detected, too close before the onset to restart the fit after it.
    pub(crate) wash_at: Option<usize>,
}

/// Weighted least squares of all estimates on six lines plus what `spec` adds.
pub(super) fn solve(
    points: &[SeqPoint],
    k: usize,
    var: &[[f64; 6]],
    spec: &Spec<'_>,
) -> Option<Solved> {
    let n = points.len();
    // A later step ends this one's columns where it begins.
    let until = spec.breaks.later.map_or(spec.until, |m| spec.until.min(m));
    let t_ref = points.iter().map(|p| p.t_days).sum::<f64>() / n as f64;
    let nc = spec.cols.len();
    let md = if spec.mismatch_sigma.is_some() { 6 } else { 0 };
    // The share at the newest start-up the columns are on: the mismatch's scale.
    let reach = (k..until.max(k + 1).min(n))
        .map(|j| share(spec.ramp_from_days, points[j].t_days))
        .fold(0.0, f64::max);
    let reach = if reach > 0.0 { reach } else { 1.0 };
    // The later step's six columns come after the hypothesis's, then the wash's two.
    let lc = 12 + nc + md;
    let wc = lc + if spec.breaks.later.is_some() { 6 } else { 0 };
    let p = wc + if spec.breaks.wash_at.is_some() { 2 } else { 0 };
    let rows = n * 6 + md;
    let mut a = DMatrix::<f64>::zeros(rows, p);
    let mut y = DVector::<f64>::zeros(rows);
    for (j, pt) in points.iter().enumerate() {
        let on = j >= k && j < until.max(k + 1);
        let g = share(spec.ramp_from_days, pt.t_days);
        for i in 0..6 {
            let r = j * 6 + i;
            // A censored estimate weighs nothing.
            let w = if pt.at_limit[i] {
                0.0
            } else {
                1.0 / var[j][i].sqrt()
            };
            a[(r, 2 * i)] = w;
            a[(r, 2 * i + 1)] = w * (pt.t_days - t_ref);
            if on {
                for (c, col) in spec.cols.iter().enumerate() {
                    a[(r, 12 + c)] = w * g * col[i];
                }
                if md > 0 {
                    a[(r, 12 + nc + i)] = w * g / reach;
                }
            }
            if spec.breaks.later.is_some_and(|m| j >= m) {
                a[(r, lc + i)] = w;
            }
            if i < 2 && spec.breaks.wash_at.is_some_and(|m| j >= m) {
                a[(r, wc + i)] = w;
            }
            y[r] = w * pt.health[i];
        }
    }
    if let Some(sm) = spec.mismatch_sigma {
        for i in 0..md {
            a[(n * 6 + i, 12 + nc + i)] = 1.0 / sm;
        }
    }
    // Columns no uncensored estimate informs (a parameter on its limit at every start-up
    // from the onset) are left out, and count as no parameter.
    let kept: Vec<usize> = (0..p)
        .filter(|&c| a.rows(0, n * 6).column(c).norm() > 1e-12)
        .collect();
    let a = a.select_columns(kept.iter());
    let inv = (a.transpose() * &a).try_inverse()?;
    let x = &inv * (a.transpose() * &y);
    let chi2 = (&a * &x - &y).norm_squared();
    let mut full = vec![0.0; p];
    let mut full_sigma = vec![0.0; p];
    for (pos, &c) in kept.iter().enumerate() {
        full[c] = x[pos];
        full_sigma[c] = inv[(pos, pos)].max(0.0).sqrt();
    }
    if !chi2.is_finite() || full.iter().any(|v| !v.is_finite()) {
        return None;
    }
    // 1σ of the step in each parameter: g'·C·g over the columns that make it.
    let step_sigma: [f64; 6] = std::array::from_fn(|i| {
        let g = |c: usize| -> f64 {
            if (12..12 + nc).contains(&c) {
                spec.cols[c - 12][i]
            } else if c == 12 + nc + i && md > 0 {
                1.0 / reach
            } else {
                0.0
            }
        };
        let mut v = 0.0;
        for (pa, &ca) in kept.iter().enumerate() {
            for (pb, &cb) in kept.iter().enumerate() {
                v += g(ca) * inv[(pa, pb)] * g(cb);
            }
        }
        v.max(0.0).sqrt()
    });
    let cov = |ca: usize, cb: usize| -> f64 {
        match (
            kept.iter().position(|&c| c == ca),
            kept.iter().position(|&c| c == cb),
        ) {
            (Some(pa), Some(pb)) => inv[(pa, pb)],
            _ => 0.0,
        }
    };
    Some(Solved {
        line_cov: std::array::from_fn(|i| {
            [
                cov(2 * i, 2 * i).max(0.0),
                cov(2 * i + 1, 2 * i + 1).max(0.0),
                cov(2 * i, 2 * i + 1),
            ]
        }),
        step_sigma,
        chi2,
        params: kept.iter().filter(|&&c| c < 12 + nc || c >= lc).count(),
        coef: full[12..12 + nc].to_vec(),
        coef_sigma: full_sigma[12..12 + nc].to_vec(),
        mismatch: std::array::from_fn(|i| {
            if md > 0 {
                full[12 + nc + i] / reach
            } else {
                0.0
            }
        }),
        lines: std::array::from_fn(|i| [full[2 * i], full[2 * i + 1]]),
        t_ref_days: t_ref,
    })
}
