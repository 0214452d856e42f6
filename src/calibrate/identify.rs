//! Which design parameters healthy data can identify: the diagnosis's identifiability idea
//! (`diagnosis::separability`) applied to the calibration's candidates.
//!
//! What it is for: from the Jacobian of the noise-scaled residuals with respect to the
//! candidates (each in units of its realistic interval), choose the largest set whose
//! linearised covariance `(JᵀJ)⁻¹` gives every member a 1σ of at most [`MAX_SIGMA_FRACTION`]
//! of its interval and no pair a correlation of [`MAX_CORRELATION`] or more. The set is grown
//! greedily, best-determined first (the candidate whose 1σ in the enlarged set is smallest
//! joins next), so of a confounded pair the better-informed member is fitted and absorbs the
//! combination the data determine, and the other stays at its guess with the reason. What it
//! must not do: evaluate the model (it gets the Jacobian) or I/O.

use nalgebra::DMatrix;
use serde::Serialize;

/// Largest 1σ, as a fraction of the candidate's realistic interval, still called identified:
/// the data then pin the value to an eighth of what was known before.
pub(crate) const MAX_SIGMA_FRACTION: f64 = 0.125;
/// Correlation beyond which two estimates are one combination, not two parameters (the
/// diagnosis's threshold).
pub(crate) const MAX_CORRELATION: f64 = 0.95;

/// The verdict for one candidate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct Verdict {
    pub(crate) identifiable: bool,
    /// 1σ as a fraction of the interval: in the identified set for a member, alone otherwise
    /// (`None` when the data carry no information on it at all).
    pub(crate) sigma_fraction: Option<f64>,
    /// Plain words: why it is fitted or kept at its guess.
    pub(crate) reason: String,
}

/// Covariance of the columns `set` of `f = JᵀJ` (unit coordinates), or `None` when singular.
fn covariance(f: &DMatrix<f64>, set: &[usize]) -> Option<DMatrix<f64>> {
    let k = set.len();
    let mut a = DMatrix::zeros(k, k);
    for (p, &i) in set.iter().enumerate() {
        for (q, &j) in set.iter().enumerate() {
            a[(p, q)] = f[(i, j)];
        }
    }
    let c = a.cholesky()?.inverse();
    c.iter().all(|v| v.is_finite()).then_some(c)
}

/// Largest |ρ| of member `p` of a covariance with any other member, and that member's index.
fn worst_correlation(c: &DMatrix<f64>, p: usize) -> (f64, Option<usize>) {
    let mut worst = (0.0, None);
    for q in 0..c.nrows() {
        if q != p {
            let rho = (c[(p, q)] / (c[(p, p)] * c[(q, q)]).sqrt()).abs();
            if rho > worst.0 {
                worst = (rho, Some(q));
            }
        }
    }
    worst
}

/// Whether every member of `set` passes, given its covariance.
fn admissible(c: &DMatrix<f64>) -> bool {
    (0..c.nrows()).all(|p| {
        c[(p, p)].sqrt() <= MAX_SIGMA_FRACTION && worst_correlation(c, p).0 < MAX_CORRELATION
    })
}

/// Verdicts for the candidates `names` from the Jacobian `jac` (residuals × candidates, the
/// residuals in noise σ, each column per unit of the candidate's interval width).
pub(crate) fn identify(jac: &DMatrix<f64>, names: &[String]) -> Vec<Verdict> {
    let n = jac.ncols();
    let f = jac.transpose() * jac;
    let mut chosen: Vec<usize> = Vec::new();
    loop {
        let mut best: Option<(usize, f64)> = None;
        for j in (0..n).filter(|j| !chosen.contains(j)) {
            let mut set = chosen.clone();
            set.push(j);
            let Some(c) = covariance(&f, &set) else {
                continue;
            };
            if !admissible(&c) {
                continue;
            }
            let s = c[(set.len() - 1, set.len() - 1)].sqrt();
            if best.is_none_or(|(_, b)| s < b) {
                best = Some((j, s));
            }
        }
        match best {
            Some((j, _)) => chosen.push(j),
            None => break,
        }
    }
    let pct = |v: f64| format!("{:.0} %", 100.0 * v);
    let final_cov = covariance(&f, &chosen);
    (0..n)
        .map(|j| {
            if let (Some(p), Some(c)) = (chosen.iter().position(|&k| k == j), &final_cov) {
                let s = c[(p, p)].sqrt();
                let (rho, with) = worst_correlation(c, p);
                let partner = with
                    .map(|q| format!(", largest |ρ| {rho:.2} with {}", names[chosen[q]]))
                    .unwrap_or_default();
                return Verdict {
                    identifiable: true,
                    sigma_fraction: Some(s),
                    reason: format!("identified: 1σ {} of its interval{partner}", pct(s)),
                };
            }
            let alone = (f[(j, j)] > 0.0).then(|| 1.0 / f[(j, j)].sqrt());
            let reason = match alone {
                None => "the data carry no information on it".to_string(),
                Some(s) if s > MAX_SIGMA_FRACTION => format!(
                    "the data barely inform it (1σ {} of its interval even alone)",
                    pct(s)
                ),
                Some(_) => {
                    let mut set = chosen.clone();
                    set.push(j);
                    match covariance(&f, &set) {
                        None => "confounded with the identified parameters (no independent \
                                 information)"
                            .to_string(),
                        Some(c) => {
                            let p = set.len() - 1;
                            let (rho, with) = worst_correlation(&c, p);
                            let s = c[(p, p)].sqrt();
                            match with {
                                Some(q) if rho >= MAX_CORRELATION => format!(
                                    "confounded with {} (ρ = {rho:.3}), which is fitted and \
                                     absorbs their combination",
                                    names[set[q]]
                                ),
                                _ if s > MAX_SIGMA_FRACTION => format!(
                                    "fitted beside the identified parameters its 1σ would be {} \
                                     of its interval",
                                    pct(s)
                                ),
                                _ => {
                                    // Admitting it would spoil another member.
                                    let spoiled = (0..p)
                                        .max_by(|&a, &b| c[(a, a)].total_cmp(&c[(b, b)]))
                                        .map(|q| names[set[q]].clone())
                                        .unwrap_or_default();
                                    format!("fitting it too would leave {spoiled} undetermined")
                                }
                            }
                        }
                    }
                }
            };
            Verdict {
                identifiable: false,
                sigma_fraction: alone,
                reason,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(n: usize) -> Vec<String> {
        (0..n).map(|i| format!("p{i}")).collect()
    }

    #[test]
    fn independent_columns_are_identified() {
        // 20 residuals; three orthogonal, well-informed columns.
        let mut j = DMatrix::zeros(20, 3);
        for i in 0..20 {
            j[(i, i % 3)] = 10.0;
        }
        let v = identify(&j, &names(3));
        assert!(v.iter().all(|x| x.identifiable), "{v:?}");
        assert!(v.iter().all(|x| x.sigma_fraction.expect("finite") < 0.1));
    }

    #[test]
    fn confounded_and_uninformed_columns_are_kept_with_the_reason() {
        let mut j = DMatrix::zeros(30, 4);
        for i in 0..30 {
            let t = i as f64 / 29.0;
            j[(i, 0)] = 20.0 * t;
            // Column 1 almost equals column 0 (ρ → 1), slightly weaker.
            j[(i, 1)] = 19.0 * t + 0.01 * (i % 2) as f64;
            j[(i, 2)] = 15.0 * (1.0 - t);
            // Column 3: hardly any effect.
            j[(i, 3)] = 0.01;
        }
        let v = identify(&j, &names(4));
        assert!(v[0].identifiable && v[2].identifiable, "{v:?}");
        assert!(
            !v[1].identifiable && v[1].reason.contains("confounded with p0"),
            "{v:?}"
        );
        assert!(
            !v[3].identifiable && v[3].reason.contains("barely"),
            "{v:?}"
        );
        let none = identify(&DMatrix::zeros(5, 1), &names(1));
        assert!(!none[0].identifiable && none[0].sigma_fraction.is_none());
    }
}
