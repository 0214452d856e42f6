//! Rank statistics shared by the accuracy tests that judge estimates by order (Spearman's ρ).
#![allow(dead_code)]

/// Spearman's rank correlation (average ranks for ties).
pub fn spearman(a: &[f64], b: &[f64]) -> f64 {
    fn ranks(x: &[f64]) -> Vec<f64> {
        let mut idx: Vec<usize> = (0..x.len()).collect();
        idx.sort_by(|&i, &j| x[i].total_cmp(&x[j]));
        let mut r = vec![0.0; x.len()];
        let mut k = 0;
        while k < idx.len() {
            let mut m = k;
            while m + 1 < idx.len() && x[idx[m + 1]] == x[idx[k]] {
                m += 1;
            }
            let avg = (k + m) as f64 / 2.0 + 1.0;
            for &i in &idx[k..=m] {
                r[i] = avg;
            }
            k = m + 1;
        }
        r
    }
    let (ra, rb) = (ranks(a), ranks(b));
    let n = a.len() as f64;
    let mean = (n + 1.0) / 2.0;
    let cov: f64 = ra
        .iter()
        .zip(&rb)
        .map(|(x, y)| (x - mean) * (y - mean))
        .sum();
    let va: f64 = ra.iter().map(|x| (x - mean).powi(2)).sum();
    let vb: f64 = rb.iter().map(|y| (y - mean).powi(2)).sum();
    if va == 0.0 || vb == 0.0 {
        // A constant series ranks nothing.
        return 0.0;
    }
    cov / (va * vb).sqrt()
}

/// The largest Spearman ρ any estimate can reach against `truth`: that of an estimate that
/// orders every pair the truth orders and breaks the truth's ties somehow (it cannot repeat
/// them). Below 1 when the truth has ties: on a grid where a parameter is healthy (0) on 10
/// levels of 20 and degraded on the others, a perfect estimate ranks at 0.936.
pub fn spearman_ceiling(truth: &[f64]) -> f64 {
    let mut idx: Vec<usize> = (0..truth.len()).collect();
    idx.sort_by(|&i, &j| truth[i].total_cmp(&truth[j]));
    let mut perfect = vec![0.0; truth.len()];
    for (rank, &i) in idx.iter().enumerate() {
        perfect[i] = rank as f64;
    }
    spearman(&perfect, truth)
}

/// Pairs of levels the truth orders (strictly) that the estimate orders the other way or
/// ties: 0 for an estimate that ranks the truth perfectly, whatever the truth's ties.
pub fn misordered_pairs(est: &[f64], truth: &[f64]) -> usize {
    let mut n = 0;
    for i in 0..truth.len() {
        for j in 0..truth.len() {
            if truth[i] < truth[j] && est[i] >= est[j] {
                n += 1;
            }
        }
    }
    n
}

/// How an estimate ranks the truth of a grid: Spearman's ρ, the ρ a perfect order reaches on
/// that truth ([`spearman_ceiling`]) and the pairs of levels misordered ([`misordered_pairs`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rank {
    pub rho: f64,
    pub ceiling: f64,
    pub misordered: usize,
}

impl Rank {
    /// The rank of `est` against `truth`, level by level.
    pub fn of(est: &[f64], truth: &[f64]) -> Rank {
        Rank {
            rho: spearman(est, truth),
            ceiling: spearman_ceiling(truth),
            misordered: misordered_pairs(est, truth),
        }
    }
}

impl std::fmt::Display for Rank {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Spearman {:.3} (a perfect order reaches {:.3}), {} of the pairs the truth orders \
             misordered",
            self.rho, self.ceiling, self.misordered
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spearman_of_known_orders() {
        assert!((spearman(&[1.0, 2.0, 3.0], &[10.0, 20.0, 30.0]) - 1.0).abs() < 1e-12);
        assert!((spearman(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        assert!(spearman(&[1.0, 2.0, 3.0, 4.0], &[1.0, 3.0, 2.0, 4.0]) < 0.9);
    }

    #[test]
    fn a_perfect_estimate_reaches_the_ceiling_and_misorders_nothing() {
        // Healthy on 10 levels of 20, degraded 0.4…4 on the others.
        let truth: Vec<f64> = (0..20)
            .map(|i| if i < 10 { 0.0 } else { 0.4 * (i - 9) as f64 })
            .collect();
        let ceiling = spearman_ceiling(&truth);
        assert!((ceiling - 0.9359).abs() < 1e-3, "{ceiling}");
        // Noise on the healthy levels, every degraded one above them in order.
        let est: Vec<f64> = truth
            .iter()
            .enumerate()
            .map(|(i, t)| t + 0.3 + 0.01 * ((i * 7) % 10) as f64)
            .collect();
        assert_eq!(misordered_pairs(&est, &truth), 0);
        assert!((spearman(&est, &truth) - ceiling).abs() < 1e-12);
        // One degraded level read below a healthy one.
        let mut worse = est.clone();
        worse[10] = 0.0;
        assert!(misordered_pairs(&worse, &truth) > 0);
        assert!(spearman(&worse, &truth) < ceiling);
        // Without ties the ceiling is 1.
        assert!((spearman_ceiling(&[3.0, 1.0, 2.0]) - 1.0).abs() < 1e-12);
    }
}
