//! Degradation trends: the fouling rate of one health parameter since the last wash, fitted
//! robustly to the diagnosis history, and detection of washes as recovery steps.
//!
//! Pure arithmetic on `(time, value, σ)` points: no I/O, no store, no clock. The rate is a
//! weighted Theil–Sen estimate (the weighted median of all pairwise slopes, each pair weighted by
//! the inverse variance of its slope), so one bad diagnosis cannot bend the trend the way it bends
//! a least-squares line. Its uncertainty combines the scatter of the points about the line (a
//! robust MAD) with the diagnoses' own 1σ, whichever is larger, propagated as for a least-squares
//! slope. What a wash is and when to wash are decided elsewhere (`wash`).

/// One diagnosis of one health parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrendPoint {
    /// Time in days (any origin).
    pub t_days: f64,
    /// Health parameter in percent (positive = degraded).
    pub value: f64,
    /// Its 1σ in percent; non-finite or non-positive means unknown.
    pub sigma: f64,
}

/// A fitted linear trend `value(t) = level + rate · (t − t_ref)`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RateFit {
    /// Points used.
    pub n: usize,
    /// Fouling rate, percent per day.
    pub rate_per_day: f64,
    /// 1σ of the rate, percent per day.
    pub rate_sigma_per_day: f64,
    /// Reference time of `level` (the weighted centre of the points), days.
    pub t_ref_days: f64,
    /// Fitted value at `t_ref_days`, percent.
    pub level: f64,
    /// Robust scatter of the points about the line (1.4826 · MAD), percent.
    pub scatter: f64,
}

impl RateFit {
    /// The trend's value at `t_days`.
    pub fn value_at(&self, t_days: f64) -> f64 {
        self.level + self.rate_per_day * (t_days - self.t_ref_days)
    }
}

/// Why no trend could be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrendError {
    #[error("a trend needs at least 3 diagnoses since the last wash, got {0}")]
    TooFew(usize),
    #[error("the diagnoses since the last wash span no time (all at {0} d)")]
    NoSpan(f64),
    #[error("diagnosis {index} has a non-finite time or value")]
    NotFinite { index: usize },
}

/// σ used where a point's own σ is unknown, percent (a typical Method B 1σ).
const DEFAULT_SIGMA: f64 = 0.1;

fn sigma_of(p: &TrendPoint) -> f64 {
    if p.sigma.is_finite() && p.sigma > 0.0 {
        p.sigma
    } else {
        DEFAULT_SIGMA
    }
}

/// Weighted median of `(value, weight)` pairs (lower weighted median; weights > 0).
pub fn weighted_median(items: &mut [(f64, f64)]) -> Option<f64> {
    if items.is_empty() {
        return None;
    }
    items.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = items.iter().map(|x| x.1).sum();
    let mut acc = 0.0;
    for &(v, w) in items.iter() {
        acc += w;
        if acc >= 0.5 * total {
            return Some(v);
        }
    }
    items.last().map(|x| x.0)
}

/// Fits the fouling rate to `points` (weighted Theil–Sen, see the module docs).
pub fn fit_rate(points: &[TrendPoint]) -> Result<RateFit, TrendError> {
    if let Some(index) = points
        .iter()
        .position(|p| !p.t_days.is_finite() || !p.value.is_finite())
    {
        return Err(TrendError::NotFinite { index });
    }
    let n = points.len();
    if n < 3 {
        return Err(TrendError::TooFew(n));
    }
    let mut slopes = Vec::with_capacity(n * (n - 1) / 2);
    for i in 0..n {
        for j in i + 1..n {
            let dt = points[j].t_days - points[i].t_days;
            if dt.abs() < 1e-9 {
                continue;
            }
            let slope = (points[j].value - points[i].value) / dt;
            let var = (sigma_of(&points[i]).powi(2) + sigma_of(&points[j]).powi(2)) / (dt * dt);
            slopes.push((slope, 1.0 / var));
        }
    }
    let Some(rate) = weighted_median(&mut slopes) else {
        return Err(TrendError::NoSpan(points[0].t_days));
    };
    // Weighted centre and level: the weighted median of the intercepts at the centre.
    let w: Vec<f64> = points.iter().map(|p| 1.0 / sigma_of(p).powi(2)).collect();
    let wsum: f64 = w.iter().sum();
    let t_ref = points
        .iter()
        .zip(&w)
        .map(|(p, w)| p.t_days * w)
        .sum::<f64>()
        / wsum;
    let mut levels: Vec<(f64, f64)> = points
        .iter()
        .zip(&w)
        .map(|(p, w)| (p.value - rate * (p.t_days - t_ref), *w))
        .collect();
    let level = weighted_median(&mut levels).unwrap_or(0.0);
    let mut abs_res: Vec<(f64, f64)> = points
        .iter()
        .map(|p| ((p.value - level - rate * (p.t_days - t_ref)).abs(), 1.0))
        .collect();
    let scatter = 1.4826 * weighted_median(&mut abs_res).unwrap_or(0.0);
    // Slope uncertainty as for least squares with per-point σ_k = max(own σ, scatter).
    let mut s_tt = 0.0;
    let mut s_w = 0.0;
    let mut s_t = 0.0;
    for p in points {
        let s = sigma_of(p).max(scatter);
        let wk = 1.0 / (s * s);
        s_w += wk;
        s_t += wk * p.t_days;
        s_tt += wk * p.t_days * p.t_days;
    }
    let det = s_w * s_tt - s_t * s_t;
    if det <= 0.0 {
        return Err(TrendError::NoSpan(points[0].t_days));
    }
    // Theil–Sen is ~1/0.91 less efficient than least squares on Gaussian data.
    let rate_sigma = (s_w / det).sqrt() / 0.91_f64.sqrt();
    Ok(RateFit {
        n,
        rate_per_day: rate,
        rate_sigma_per_day: rate_sigma,
        t_ref_days: t_ref,
        level,
        scatter,
    })
}

/// Settings of wash detection.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WashDetection {
    /// A recovery must exceed this many combined σ of the two diagnoses.
    pub min_sigmas: f64,
    /// ... and this many points of D_GC.
    pub min_step_gc: f64,
}

impl Default for WashDetection {
    fn default() -> Self {
        WashDetection {
            min_sigmas: 4.0,
            min_step_gc: 0.5,
        }
    }
}

/// One health vector of the history: D_GC and D_EC with their σ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompressorPoint {
    pub t_days: f64,
    pub d_gc: f64,
    pub sigma_gc: f64,
    pub d_ec: f64,
    pub sigma_ec: f64,
}

/// Indices `k` such that a wash happened between point `k − 1` and point `k`: D_GC recovers by
/// more than both thresholds and D_EC does not degrade at the same time (a wash cleans both).
/// Each comparison is against the median of up to three points before, so a single noisy
/// diagnosis does not fake a step.
pub fn detect_washes(history: &[CompressorPoint], cfg: &WashDetection) -> Vec<usize> {
    let mut found = Vec::new();
    let mut since = 0usize;
    for k in 1..history.len() {
        let lo = k.saturating_sub(3).max(since);
        let mut before: Vec<f64> = history[lo..k].iter().map(|p| p.d_gc).collect();
        before.sort_by(f64::total_cmp);
        let ref_gc = before[before.len() / 2];
        let mut before_ec: Vec<f64> = history[lo..k].iter().map(|p| p.d_ec).collect();
        before_ec.sort_by(f64::total_cmp);
        let ref_ec = before_ec[before_ec.len() / 2];
        let p = &history[k];
        let prev = &history[k - 1];
        let step = ref_gc - p.d_gc;
        let sig = (sigma_of_val(prev.sigma_gc).powi(2) + sigma_of_val(p.sigma_gc).powi(2)).sqrt();
        let ec_step = ref_ec - p.d_ec;
        let sig_ec =
            (sigma_of_val(prev.sigma_ec).powi(2) + sigma_of_val(p.sigma_ec).powi(2)).sqrt();
        if step > cfg.min_step_gc && step > cfg.min_sigmas * sig && ec_step > -2.0 * sig_ec {
            found.push(k);
            since = k;
        }
    }
    found
}

fn sigma_of_val(s: f64) -> f64 {
    if s.is_finite() && s > 0.0 {
        s
    } else {
        DEFAULT_SIGMA
    }
}

/// A start-up whose health parameter left the unit's own trend (issue 23 item 3): what the
/// trend of the previous diagnoses since the last wash predicts for it, and by how much more
/// than their scatter and its uncertainty it differs.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct HealthStep {
    /// Index of the parameter (`health::HEALTH_NAMES` order).
    pub param: usize,
    pub value: f64,
    pub expected: f64,
    /// The largest difference the trend allows, percent.
    pub tolerance: f64,
}

/// The parameters a wash recovers (`HEALTH_NAMES` order: D_GC and D_EC): their improvement is
/// a wash, not a step against the trend ([`steps_against_trend`]'s `recovers`).
pub const RECOVERED_BY_WASH: [bool; 6] = [true, true, false, false, false, false];

/// Smallest step that counts, percent: below it a start-up is within the scatter a trend of
/// real diagnoses shows.
pub const MIN_STEP: f64 = 0.5;
/// Steps are judged in units of the combined 1σ of the new value and the trend's prediction.
const STEP_SIGMAS: f64 = 4.0;
/// Diagnoses of the trend a step is judged against (the most recent ones since the wash).
const STEP_WINDOW: usize = 8;

/// How far one parameter of a start-up lies from what the trend before it predicts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Departure {
    pub value: f64,
    pub expected: f64,
    /// The largest difference the trend allows, percent (`STEP_SIGMAS` combined σ, at least
    /// [`MIN_STEP`]).
    pub tolerance: f64,
}

impl Departure {
    /// `value − expected`, percent.
    pub fn offset(&self) -> f64 {
        self.value - self.expected
    }
}

/// Each parameter of `current` against the trend of `previous` (the same parameter's
/// diagnoses since the last wash, oldest first; the last `STEP_WINDOW` of them): `None`
/// where fewer than 3 are there to fit a trend.
pub fn departures(
    previous: &[[TrendPoint; 6]],
    current: &[TrendPoint; 6],
) -> [Option<Departure>; 6] {
    let tail = &previous[previous.len().saturating_sub(STEP_WINDOW)..];
    std::array::from_fn(|k| {
        let points: Vec<TrendPoint> = tail.iter().map(|p| p[k]).collect();
        let fit = fit_rate(&points).ok()?;
        let cur = current[k];
        let expected = fit.value_at(cur.t_days);
        let mean_var =
            points.iter().map(|p| sigma_of(p).powi(2)).sum::<f64>() / points.len() as f64;
        let spread = fit.scatter.max(mean_var.sqrt());
        let sigma = (sigma_of(&cur).powi(2) + spread.powi(2)).sqrt();
        Some(Departure {
            value: cur.value,
            expected,
            tolerance: (STEP_SIGMAS * sigma).max(MIN_STEP),
        })
    })
}

/// The parameters of `current` that step away from the trend of `previous` (the same
/// parameter's diagnoses since the last wash, oldest first; at least 3 are needed, else none).
/// A compressor parameter (`recovers[i]`) that improves is left out: that is what a wash
/// (recorded or not yet detected) does, and the wash advice judges it.
pub fn steps_against_trend(
    previous: &[[TrendPoint; 6]],
    current: &[TrendPoint; 6],
    recovers: [bool; 6],
) -> Vec<HealthStep> {
    steps_of(&departures(previous, current), recovers)
}

/// The steps among `departures` (see [`steps_against_trend`]).
pub fn steps_of(departures: &[Option<Departure>; 6], recovers: [bool; 6]) -> Vec<HealthStep> {
    let mut out = Vec::new();
    for (k, d) in departures.iter().enumerate() {
        let Some(d) = d else {
            continue;
        };
        let off = d.offset();
        if off.abs() > d.tolerance && !(recovers[k] && off < 0.0) {
            out.push(HealthStep {
                param: k,
                value: d.value,
                expected: d.expected,
                tolerance: d.tolerance,
            });
        }
    }
    out
}

/// Whether a start-up that departs from the trend as `now` does carries on the step of an
/// earlier one that departed as `then` from the same trend (judged against it, since the
/// same wash): every parameter's offset from the trend within `now`'s tolerance of the
/// earlier one's. An input instrument that changed keeps the health it shifts shifted at
/// every start-up after; that is one step, not a new one each day.
pub fn same_step(now: &[Option<Departure>; 6], then: &[Option<Departure>; 6]) -> bool {
    now.iter().zip(then).all(|(a, b)| match (a, b) {
        (Some(a), Some(b)) => (a.offset() - b.offset()).abs() <= a.tolerance,
        (None, None) => true,
        _ => false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    fn line(n: usize, rate: f64, noise: f64, seed: u64) -> Vec<TrendPoint> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let nd = Normal::new(0.0, noise).unwrap();
        (0..n)
            .map(|k| TrendPoint {
                t_days: k as f64,
                value: 0.3 + rate * k as f64 + nd.sample(&mut rng),
                sigma: noise,
            })
            .collect()
    }

    #[test]
    fn exact_line_is_recovered() {
        let pts = line(10, 0.05, 1e-12, 1);
        let f = fit_rate(&pts).unwrap();
        assert!((f.rate_per_day - 0.05).abs() < 1e-9, "{f:?}");
        assert!((f.value_at(4.0) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn outlier_does_not_bend_the_rate() {
        let mut pts = line(20, 0.05, 0.03, 2);
        pts[7].value += 5.0; // one absurd diagnosis
        let f = fit_rate(&pts).unwrap();
        assert!((f.rate_per_day - 0.05).abs() < 0.01, "{f:?}");
    }

    #[test]
    fn rate_sigma_is_calibrated() {
        // Over 200 noisy histories, the true rate lies within 2σ of the estimate ≥ 90 % of the time
        // and the σ is not absurdly pessimistic (within 1σ at most 90 %... and ≥ 50 %).
        let (mut in1, mut in2) = (0, 0);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for _ in 0..200 {
            let pts = line(15, 0.04, 0.1, rng.random());
            let f = fit_rate(&pts).unwrap();
            let z = (f.rate_per_day - 0.04).abs() / f.rate_sigma_per_day;
            in1 += usize::from(z <= 1.0);
            in2 += usize::from(z <= 2.0);
        }
        assert!(in2 >= 180, "{in2}/200 within 2σ");
        assert!((100..=190).contains(&in1), "{in1}/200 within 1σ");
    }

    #[test]
    fn too_few_and_bad_points_are_errors() {
        assert_eq!(fit_rate(&line(2, 0.1, 0.01, 1)), Err(TrendError::TooFew(2)));
        let mut pts = line(5, 0.1, 0.01, 1);
        pts[2].value = f64::NAN;
        assert_eq!(fit_rate(&pts), Err(TrendError::NotFinite { index: 2 }));
        let same: Vec<TrendPoint> = (0..4)
            .map(|_| TrendPoint {
                t_days: 1.0,
                value: 1.0,
                sigma: 0.1,
            })
            .collect();
        assert!(matches!(fit_rate(&same), Err(TrendError::NoSpan(_))));
    }

    fn history(wash_at: Option<usize>, noise: f64, seed: u64) -> Vec<CompressorPoint> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let nd = Normal::new(0.0, noise).unwrap();
        let mut t0 = 0.0;
        (0..40)
            .map(|k| {
                if Some(k) == wash_at {
                    t0 = k as f64;
                }
                let age = k as f64 - t0;
                CompressorPoint {
                    t_days: k as f64,
                    d_gc: 0.1 * age + nd.sample(&mut rng),
                    sigma_gc: noise,
                    d_ec: 0.1 / 3.0 * age + nd.sample(&mut rng) / 2.0,
                    sigma_ec: noise / 2.0,
                }
            })
            .collect()
    }

    #[test]
    fn wash_is_found_on_its_day_and_nowhere_else() {
        for seed in 0..20 {
            assert_eq!(
                detect_washes(&history(Some(20), 0.05, seed), &WashDetection::default()),
                vec![20],
                "seed {seed}"
            );
            assert!(
                detect_washes(&history(None, 0.05, seed), &WashDetection::default()).is_empty(),
                "seed {seed}"
            );
        }
    }

    fn health_points(t: f64, values: [f64; 6]) -> [TrendPoint; 6] {
        values.map(|value| TrendPoint {
            t_days: t,
            value,
            sigma: 0.05,
        })
    }

    /// A fouling trend with scatter: the next start-up on the trend is no step; a 1.5-point
    /// step in the HP turbine is; a compressor that recovers (a wash) is not; with fewer than 3
    /// previous diagnoses nothing is judged.
    #[test]
    fn a_step_against_the_trend_is_found_and_a_wash_is_not_one() {
        let scatter = [0.03, -0.05, 0.04, -0.02, 0.05, -0.04, 0.01, 0.02];
        let previous: Vec<[TrendPoint; 6]> = scatter
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let t = i as f64;
                health_points(
                    t,
                    [
                        1.0 + 0.1 * t + e,
                        0.5 + 0.05 * t - e,
                        0.3 + e,
                        0.2,
                        0.1,
                        0.0,
                    ],
                )
            })
            .collect();
        let on_trend = health_points(8.0, [1.8, 0.9, 0.3, 0.2, 0.1, 0.0]);
        let recovers = RECOVERED_BY_WASH;
        assert!(steps_against_trend(&previous, &on_trend, recovers).is_empty());
        let stepped = health_points(8.0, [1.8, 0.9, 1.8, 0.2, 0.1, 0.0]);
        let steps = steps_against_trend(&previous, &stepped, recovers);
        assert_eq!(steps.len(), 1, "{steps:?}");
        assert_eq!(steps[0].param, 2);
        assert!((steps[0].expected - 0.3).abs() < 0.1, "{steps:?}");
        let washed = health_points(8.0, [0.2, 0.1, 0.3, 0.2, 0.1, 0.0]);
        assert!(steps_against_trend(&previous, &washed, recovers).is_empty());
        let fouled_faster = health_points(8.0, [3.5, 0.9, 0.3, 0.2, 0.1, 0.0]);
        assert_eq!(
            steps_against_trend(&previous, &fouled_faster, recovers).len(),
            1
        );
        assert!(steps_against_trend(&previous[..2], &stepped, recovers).is_empty());
    }
}
