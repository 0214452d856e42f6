//! Which health parameters the compared signals can separate, said in plain words with every
//! result: a unit without a PT-inlet measurement cannot tell D_GP from D_EP, and a health vector
//! that silently splits their combination between them would mislead the wash advice.
//!
//! From the fit's linearised covariance (σ and correlations of the health parameters at the
//! optimum):
//! - parameters whose estimates correlate with |ρ| ≥ [`MAX_CORRELATION`] (directly or through
//!   a chain) are **confounded**: the data determine only some combinations of them, the
//!   eigenvectors of their covariance with 1σ ≤ [`MAX_SIGMA`] points (half a point at 2σ),
//!   reported as `a·X + b·Y … = v ± σ`;
//! - a parameter outside such a group is **not identifiable** when the data carry no
//!   information on it (σ = ∞) or its 1σ exceeds [`MAX_SIGMA`];
//! - the rest are **separable**.
//!
//! Pure arithmetic on the fit's numbers: no I/O.

use crate::health::HEALTH_NAMES;
use serde::Serialize;

/// Largest 1σ (points) of a parameter (or a combination) still called determined: the wash
/// advice acts on changes of about half a point, which needs 2σ ≤ 0.5.
pub(crate) const MAX_SIGMA: f64 = 0.25;
/// Correlation beyond which two estimates are one combination, not two parameters.
pub(crate) const MAX_CORRELATION: f64 = 0.95;

/// A determined combination `Σ wᵢ·Xᵢ` of confounded parameters.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Combination {
    /// Unit-norm weights per parameter name.
    pub weights: Vec<(String, f64)>,
    /// The combination's value and 1σ, points.
    pub value: f64,
    pub sigma: f64,
}

/// Parameters whose estimates are tied together: the data determine only some combinations.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConfoundedGroup {
    pub members: Vec<String>,
    /// Largest |correlation| between two members.
    pub max_correlation: f64,
    /// The combinations the data determine (1σ ≤ [`MAX_SIGMA`]), best first.
    pub determined: Vec<Combination>,
}

/// The verdict for one result.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct Separability {
    pub separable: Vec<String>,
    pub confounded: Vec<ConfoundedGroup>,
    pub not_identifiable: Vec<String>,
    /// Plain words, e.g. "D_GP and D_EP are not separable with these signals: only
    /// 0.71·D_GP + 0.71·D_EP = 1.20 ± 0.10 is determined".
    pub statement: String,
}

/// One fitted health parameter: its index in [`HEALTH_NAMES`], value, 1σ and its row of the
/// correlation matrix over `params` (the same order).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct HealthEstimate {
    pub(crate) index: usize,
    pub(crate) value: f64,
    pub(crate) sigma: f64,
    pub(crate) correlation: Vec<f64>,
}

/// Assesses the fitted health parameters (fixed ones are simply not listed in `params`).
pub(crate) fn assess(params: &[HealthEstimate], signals: &[String]) -> Separability {
    let n = params.len();
    let name = |k: usize| HEALTH_NAMES[params[k].index].to_string();
    // Finite σ: the data say something about the parameter, alone or in a combination.
    let informed: Vec<bool> = params.iter().map(|p| p.sigma.is_finite()).collect();
    let ident: Vec<bool> = params
        .iter()
        .map(|p| p.sigma.is_finite() && p.sigma <= MAX_SIGMA)
        .collect();
    let rho = |i: usize, j: usize| params[i].correlation.get(j).copied().unwrap_or(0.0);
    // Groups: connected components of the "correlated beyond MAX_CORRELATION" relation among
    // the identifiable parameters (a chain D_ET–D_GP–D_EP is one group).
    let mut group: Vec<usize> = (0..n).collect();
    fn root(g: &mut [usize], mut k: usize) -> usize {
        while g[k] != k {
            g[k] = g[g[k]];
            k = g[k];
        }
        k
    }
    for i in 0..n {
        for j in i + 1..n {
            let r = rho(i, j);
            if informed[i] && informed[j] && r.is_finite() && r.abs() >= MAX_CORRELATION {
                let (a, b) = (root(&mut group, i), root(&mut group, j));
                group[a] = b;
            }
        }
    }
    let mut out = Separability::default();
    let mut done = vec![false; n];
    for k in 0..n {
        if done[k] {
            continue;
        }
        if !informed[k] {
            out.not_identifiable.push(name(k));
            continue;
        }
        let r = root(&mut group, k);
        let members: Vec<usize> = (0..n)
            .filter(|&m| informed[m] && root(&mut group, m) == r)
            .collect();
        for &m in &members {
            done[m] = true;
        }
        if members.len() == 1 {
            if ident[k] {
                out.separable.push(name(k));
            } else {
                out.not_identifiable.push(name(k));
            }
            continue;
        }
        let mut max_corr: f64 = 0.0;
        for (a, &i) in members.iter().enumerate() {
            for &j in &members[a + 1..] {
                max_corr = max_corr.max(rho(i, j).abs());
            }
        }
        out.confounded.push(ConfoundedGroup {
            members: members.iter().map(|&m| name(m)).collect(),
            max_correlation: max_corr,
            determined: determined(params, &members, &name),
        });
    }
    let with = if signals.is_empty() {
        String::new()
    } else {
        format!(" from {}", signals.join(", "))
    };
    let mut parts = Vec::new();
    if out.confounded.is_empty() && out.not_identifiable.is_empty() {
        parts.push(format!(
            "all {n} fitted health parameters are separable{with}"
        ));
    } else {
        for g in &out.confounded {
            let combos: Vec<String> = g
                .determined
                .iter()
                .map(|c| {
                    let terms: Vec<String> = c
                        .weights
                        .iter()
                        .filter(|(_, w)| w.abs() >= 0.05)
                        .map(|(p, w)| format!("{w:+.2}·{p}"))
                        .collect();
                    format!("{} = {:.2} ± {:.2}", terms.join(" "), c.value, c.sigma)
                })
                .collect();
            parts.push(format!(
                "{} are not separable with these signals (correlation up to {:.2}){}",
                join_and(&g.members),
                g.max_correlation,
                if combos.is_empty() {
                    String::new()
                } else {
                    format!(": only {} determined", combos.join(" and "))
                }
            ));
        }
        if !out.not_identifiable.is_empty() {
            parts.push(format!(
                "{} not identifiable{with} (1σ over {MAX_SIGMA} points)",
                join_and(&out.not_identifiable)
            ));
        }
        if !out.separable.is_empty() {
            parts.push(format!("separable: {}", out.separable.join(", ")));
        }
    }
    out.statement = parts.join("; ");
    out
}

fn join_and(names: &[String]) -> String {
    match names {
        [] => String::new(),
        [one] => one.clone(),
        [rest @ .., last] => format!("{} and {last}", rest.join(", ")),
    }
}

/// The combinations of a confounded group the data determine: eigenvectors of the group's
/// covariance whose σ (√eigenvalue) is at most [`MAX_SIGMA`], smallest σ first.
fn determined(
    params: &[HealthEstimate],
    members: &[usize],
    name: &dyn Fn(usize) -> String,
) -> Vec<Combination> {
    let m = members.len();
    let cov = nalgebra::DMatrix::from_fn(m, m, |a, b| {
        let (i, j) = (members[a], members[b]);
        let r = if a == b {
            1.0
        } else {
            params[i].correlation.get(j).copied().unwrap_or(0.0)
        };
        r * params[i].sigma * params[j].sigma
    });
    let eig = nalgebra::SymmetricEigen::new(cov);
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    order
        .into_iter()
        .filter_map(|e| {
            let sigma = eig.eigenvalues[e].max(0.0).sqrt();
            if sigma > MAX_SIGMA {
                return None;
            }
            let mut w: Vec<f64> = (0..m).map(|a| eig.eigenvectors[(a, e)]).collect();
            // Sign: the largest weight positive (a stable, readable form).
            let big = w
                .iter()
                .copied()
                .fold(0.0_f64, |acc, x| if x.abs() > acc.abs() { x } else { acc });
            if big < 0.0 {
                w.iter_mut().for_each(|x| *x = -*x);
            }
            let value = members
                .iter()
                .zip(&w)
                .map(|(&i, wi)| wi * params[i].value)
                .sum();
            Some(Combination {
                weights: members
                    .iter()
                    .zip(&w)
                    .map(|(&i, &wi)| (name(i), wi))
                    .collect(),
                value,
                sigma,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(index: usize, value: f64, sigma: f64, correlation: Vec<f64>) -> HealthEstimate {
        HealthEstimate {
            index,
            value,
            sigma,
            correlation,
        }
    }

    #[test]
    fn anti_correlated_pair_reports_its_sum() {
        // D_GP and D_EP anti-correlated at −0.99, each σ 0.8 (too wide alone): their sum is known.
        let p = vec![
            est(0, 1.0, 0.1, vec![1.0, 0.0, 0.0]),
            est(4, 0.7, 0.8, vec![0.0, 1.0, -0.99]),
            est(5, 0.5, 0.8, vec![0.0, -0.99, 1.0]),
        ];
        let s = assess(&p, &["t2_k".into()]);
        assert_eq!(s.separable, vec!["D_GC".to_string()]);
        assert_eq!(s.confounded.len(), 1);
        let g = &s.confounded[0];
        assert_eq!(g.members, vec!["D_GP".to_string(), "D_EP".to_string()]);
        // Only the sum direction is determined: the difference has σ 0.8·√1.99 > 0.25 points.
        assert_eq!(g.determined.len(), 1);
        let c = &g.determined[0];
        assert!((c.weights[0].1 - c.weights[1].1).abs() < 1e-9, "{c:?}");
        assert!((c.value - (0.7 + 0.5) / 2f64.sqrt()).abs() < 1e-9);
        // σ of (x+y)/√2 = √((σ²+σ²+2ρσ²)/2) = σ√(1+ρ).
        assert!(
            (c.sigma - 0.8 * (0.01f64).sqrt()).abs() < 1e-9,
            "{}",
            c.sigma
        );
        assert!(
            s.statement.contains("D_GP and D_EP are not separable"),
            "{}",
            s.statement
        );
    }

    #[test]
    fn infinite_or_wide_sigma_is_not_identifiable_and_clean_fit_says_so() {
        let p = vec![
            est(2, 0.3, f64::INFINITY, vec![1.0, 0.0]),
            est(3, 0.1, 1.5, vec![0.0, 1.0]),
        ];
        let s = assess(&p, &[]);
        assert_eq!(
            s.not_identifiable,
            vec!["D_GT".to_string(), "D_ET".to_string()]
        );
        assert!(s.separable.is_empty() && s.confounded.is_empty());
        let p = vec![
            est(0, 0.3, 0.1, vec![1.0, 0.2]),
            est(1, 0.1, 0.1, vec![0.2, 1.0]),
        ];
        let s = assess(&p, &["p2_kpa".into()]);
        assert_eq!(s.separable.len(), 2);
        assert!(s.statement.starts_with("all 2 fitted"), "{}", s.statement);
    }

    #[test]
    fn a_chain_of_correlations_is_one_group() {
        // D_ET–D_GP and D_GP–D_EP strongly correlated, D_ET–D_EP less so: one group of three.
        let p = vec![
            est(3, 0.1, 0.1, vec![1.0, -0.97, 0.9]),
            est(4, 0.2, 0.2, vec![-0.97, 1.0, -0.96]),
            est(5, 0.3, 0.15, vec![0.9, -0.96, 1.0]),
        ];
        let s = assess(&p, &[]);
        assert_eq!(s.confounded.len(), 1);
        assert_eq!(s.confounded[0].members.len(), 3);
        assert!(s.separable.is_empty());
        assert!(
            s.statement.contains("D_ET, D_GP and D_EP"),
            "{}",
            s.statement
        );
    }
}
