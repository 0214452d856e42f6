//! The diagnosis objective (paper eq. 10) and the residual vector behind it.
//!
//! Paper eq. 10 integrates the absolute deviation between measured and simulated outputs over
//! the segment. Here each signal is normalised by its instrument's 1σ noise at the reading
//! (`engine::sensors::noise_sigma`), so no channel dominates because of its unit:
//!
//! `f = Σ_signals (1/T) ∫_window |Z_meas − Z_model| / σ_noise dt`
//!
//! (T = window duration, so `f` is "mean absolute deviation in noise units, summed over
//! signals"). The integral is the sample sum weighted by each sample's share of the time axis.
//! The same normalised, time-weighted deviations form the residual vector that
//! Levenberg–Marquardt minimises in the least-squares sense. Samples whose measurement is
//! missing or invalid (NaN, ±∞) are *excluded* — never treated as zero — and the mask is fixed by
//! the measurement alone, so the residual vector has the same length at every parameter vector.
//! A non-finite model value makes the whole evaluation fail (cost `+∞`). Pure: no I/O.

use super::fuel_noise::Whitening;
use super::params::EvalError;
use crate::engine::config::SensorsConfig;
use crate::engine::sensors::noise_sigma;
use crate::engine::trace::Values;
use crate::signals::Signal;

/// One measured sample that takes part in the objective.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Term {
    /// Index into the sample axis.
    k: usize,
    /// Signal index (`Signal::index`).
    s: usize,
    /// Measured value.
    z: f64,
    /// 1 / σ of the normalisation.
    inv_sigma: f64,
    /// Time weight for the integral, s / window duration (sums to 1 per signal).
    w_abs: f64,
    /// √(time weight relative to the median sample spacing) for the residual vector.
    w_res: f64,
}

/// The objective prepared for one measured data set: which samples of which signals count and
/// how each is normalised.
#[derive(Debug, Clone, PartialEq)]
pub struct Objective {
    terms: Vec<Term>,
    signals: Vec<Signal>,
    /// The residuals' covariance when a point's values share errors
    /// ([`Objective::with_shared_errors`]); `None`: independent residuals.
    shared: Option<Whitening>,
}

/// Minimum normalisation: the noise σ at this fraction of the largest |reading| of the signal in
/// the window. Relative-noise channels have σ → 0 at zero reading (a GG at rest); without a
/// floor one zero-speed sample would dominate the objective.
pub(crate) const SIGMA_FLOOR_FRACTION: f64 = 0.1;

impl Objective {
    /// Builds the objective over the samples `in_window[k] == true` of `measured` (at times
    /// `t_s`), for `signals`, normalised with the instrument noise in `sensors` combined with
    /// `rate_weight` × the largest change to a neighbouring sample (model timing uncertainty,
    /// `σ² = σ_noise² + (rate_weight·ΔZ)²`; 0 = noise only). Signals without a noise model
    /// (σ = 0) are normalised by 0.1 % of their largest reading.
    pub fn new(
        t_s: &[f64],
        measured: &[Values],
        in_window: &[bool],
        signals: &[Signal],
        sensors: &SensorsConfig,
        rate_weight: f64,
    ) -> Objective {
        let n = t_s.len().min(measured.len()).min(in_window.len());
        // Time share of each sample: half the distance to its neighbours (trapezoid weights).
        let dt: Vec<f64> = (0..n)
            .map(|k| {
                let lo = if k > 0 { t_s[k - 1] } else { t_s[k] };
                let hi = if k + 1 < n { t_s[k + 1] } else { t_s[k] };
                ((hi - lo) / 2.0).max(0.0)
            })
            .collect();
        let mut sorted: Vec<f64> = dt.iter().copied().filter(|d| *d > 0.0).collect();
        sorted.sort_by(f64::total_cmp);
        let dt_med = sorted.get(sorted.len() / 2).copied().unwrap_or(1.0);
        let mut terms = Vec::new();
        for &sig in signals {
            let si = sig.index();
            let ok = |k: usize| in_window[k] && measured[k][si].is_finite();
            let max_abs = (0..n)
                .filter(|&k| ok(k))
                .map(|k| measured[k][si].abs())
                .fold(0.0, f64::max);
            let floor = {
                let f = noise_sigma(sensors, sig, SIGMA_FLOOR_FRACTION * max_abs);
                if f > 0.0 {
                    f
                } else {
                    1e-3 * max_abs
                }
            };
            if floor <= 0.0 {
                continue; // a signal that is zero throughout carries no information
            }
            let total: f64 = (0..n).filter(|&k| ok(k)).map(|k| dt[k]).sum();
            if total <= 0.0 {
                continue;
            }
            for k in (0..n).filter(|&k| ok(k)) {
                let z = measured[k][si];
                let noise = noise_sigma(sensors, sig, z).max(floor);
                // Largest change to a neighbouring sample: the replay knows its inputs only at
                // the samples, so events between samples (light-off, breaker) shift the model
                // by up to one sample; that mismatch scales with the local rate of change.
                // Measured with noise: take the change of a 3-sample moving average, so the
                // allowance follows the signal's rate of change and not its noise.
                let avg = |j: usize| -> Option<f64> {
                    let lo = j.saturating_sub(1);
                    let hi = (j + 1).min(n - 1);
                    let v: Vec<f64> = (lo..=hi)
                        .map(|i| measured[i][si])
                        .filter(|x| x.is_finite())
                        .collect();
                    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
                };
                let here = avg(k).unwrap_or(z);
                let step = [k.checked_sub(1), Some(k + 1)]
                    .into_iter()
                    .flatten()
                    .filter(|&j| j < n)
                    .filter_map(avg)
                    .map(|a| (a - here).abs())
                    .fold(0.0, f64::max);
                let sigma = noise.hypot(rate_weight * step);
                terms.push(Term {
                    k,
                    s: si,
                    z,
                    inv_sigma: 1.0 / sigma,
                    w_abs: dt[k] / total,
                    w_res: (dt[k] / dt_med).sqrt(),
                });
            }
        }
        let mut used: Vec<Signal> = signals
            .iter()
            .copied()
            .filter(|s| terms.iter().any(|t| t.s == s.index()))
            .collect();
        used.dedup();
        Objective {
            terms,
            signals: used,
            shared: None,
        }
    }

    /// Builds an objective from pre-averaged values with given 1σ (Method A: one "sample" per
    /// steady window and signal). `points[j]` holds `(signal, value, sigma)`.
    pub fn from_points(points: &[Vec<(Signal, f64, f64)>]) -> Objective {
        let mut terms = Vec::new();
        let mut signals = Vec::new();
        for (k, p) in points.iter().enumerate() {
            for &(s, z, sigma) in p {
                if !(z.is_finite() && sigma.is_finite() && sigma > 0.0) {
                    continue;
                }
                if !signals.contains(&s) {
                    signals.push(s);
                }
                terms.push(Term {
                    k,
                    s: s.index(),
                    z,
                    inv_sigma: 1.0 / sigma,
                    w_abs: 0.0,
                    w_res: 1.0,
                });
            }
        }
        // Eq. 10 over a set of points: each signal's deviations averaged over the points.
        for s in &signals {
            let cnt = terms.iter().filter(|t| t.s == s.index()).count() as f64;
            for t in terms.iter_mut().filter(|t| t.s == s.index()) {
                t.w_abs = 1.0 / cnt;
            }
        }
        Objective {
            terms,
            signals,
            shared: None,
        }
    }

    /// The objective with each term's σ widened by `extra(k, s, z)` in quadrature (sample `k`,
    /// signal `s`, measured value `z`; in the signal's unit, 0 = unchanged): an error the
    /// model itself makes, beside the instrument's noise (an adapted engine file's
    /// `[adaptation.model_error_pct]`).
    pub(crate) fn with_extra_sigma(
        mut self,
        extra: impl Fn(usize, Signal, f64) -> f64,
    ) -> Objective {
        for t in &mut self.terms {
            let Some(s) = Signal::ALL.get(t.s).copied() else {
                continue;
            };
            let e = extra(t.k, s, t.z);
            if e.is_finite() && e > 0.0 {
                t.inv_sigma = 1.0 / (1.0 / t.inv_sigma).hypot(e);
            }
        }
        self
    }

    /// The objective with shared errors within each point (`from_points`' sample axis):
    /// `response(k, s)` gives, for point `k` and signal `s`, the change of that signal's value per
    /// 1σ of each of the errors the point's values share (in the signal's unit; empty when
    /// none). Each point's errors are columns of `U` in noise units (zero outside the point's
    /// residuals), and the residuals are those of generalised least squares under `I + U Uᵀ`
    /// ([`Whitening`], as Method B's fuel-meter covariance): their sum of squares is the
    /// Mahalanobis distance and the fit weights each direction for what the shared errors can do
    /// there.
    pub(crate) fn with_shared_errors(
        mut self,
        response: impl Fn(usize, Signal) -> Vec<f64>,
    ) -> Objective {
        let columns = self.point_columns(response);
        self.shared = Whitening::new(&columns);
        self
    }

    /// The shared errors of [`Objective::with_shared_errors`] as residual-length columns in
    /// noise units (one per point and error; all-zero columns left out), without fitting under
    /// them.
    pub(crate) fn point_columns(
        &self,
        response: impl Fn(usize, Signal) -> Vec<f64>,
    ) -> Vec<Vec<f64>> {
        let n = self.terms.len();
        let mut columns: Vec<Vec<f64>> = Vec::new();
        let mut i = 0;
        while i < n {
            let k = self.terms[i].k;
            let len = self.terms[i..].iter().take_while(|t| t.k == k).count();
            let first = columns.len();
            for (a, t) in self.terms[i..i + len].iter().enumerate() {
                let Some(s) = Signal::ALL.get(t.s).copied() else {
                    continue;
                };
                for (u, v) in response(k, s).iter().enumerate() {
                    if first + u == columns.len() {
                        columns.push(vec![0.0; n]);
                    }
                    columns[first + u][i + a] = v * t.inv_sigma;
                }
            }
            i += len;
        }
        columns.retain(|c| c.iter().any(|v| *v != 0.0));
        columns
    }

    /// Number of residuals.
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// Whether no sample takes part.
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// The signals that take part (those with at least one valid sample).
    pub fn signals(&self) -> &[Signal] {
        &self.signals
    }

    /// Checks that `model` has a finite value wherever a measurement is compared.
    pub fn check(&self, model: &[Values]) -> Result<(), EvalError> {
        for t in &self.terms {
            match model.get(t.k).map(|v| v[t.s]) {
                None => {
                    return Err(EvalError::Short {
                        got: model.len(),
                        want: t.k + 1,
                    })
                }
                Some(m) if !m.is_finite() => {
                    return Err(EvalError::NonFinite {
                        signal: Signal::ALL[t.s],
                        sample: t.k,
                    })
                }
                Some(_) => {}
            }
        }
        Ok(())
    }

    /// Paper eq. 10 (normalised): `Σ_s mean_t |Δ| / σ`; `+∞` if a model value is not finite
    /// or `model` is too short.
    pub fn eq10(&self, model: &[Values]) -> f64 {
        let mut f = 0.0;
        for t in &self.terms {
            let Some(m) = model.get(t.k).map(|v| v[t.s]) else {
                return f64::INFINITY;
            };
            if !m.is_finite() {
                return f64::INFINITY;
            }
            f += t.w_abs * (t.z - m).abs() * t.inv_sigma;
        }
        f
    }

    /// The residual vector `(Z_meas − Z_model)/σ · √w` into `out` (cleared first). Non-finite
    /// model values give non-finite residuals (a failed evaluation).
    pub fn residuals(&self, model: &[Values], out: &mut Vec<f64>) {
        out.clear();
        out.extend(self.terms.iter().map(|t| match model.get(t.k) {
            Some(v) => (t.z - v[t.s]) * t.inv_sigma * t.w_res,
            None => f64::NAN,
        }));
        if let Some(w) = &self.shared {
            w.apply(out);
        }
    }

    /// Variance inflation for serially correlated residuals: per signal, the Bartlett-weighted
    /// sum `1 + 2 Σ_{l=1..L} (1 − l/(L+1)) ρ_l` of the residuals' autocorrelations (lags,
    /// input noise propagated by the dynamics make neighbouring residuals correlated, so the
    /// data hold fewer independent samples than residuals), averaged over signals weighted by
    /// their share of the sum of squares; at least 1. Signals with fewer than 4·L residuals
    /// count as uncorrelated.
    pub fn correlation_inflation(&self, residuals: &[f64], max_lag: usize) -> f64 {
        let mut total_w = 0.0;
        let mut acc = 0.0;
        for sig in &self.signals {
            let r: Vec<f64> = self
                .terms
                .iter()
                .zip(residuals)
                .filter(|(t, v)| t.s == sig.index() && v.is_finite())
                .map(|(_, v)| *v)
                .collect();
            let ss: f64 = r.iter().map(|v| v * v).sum();
            if ss <= 0.0 {
                continue;
            }
            let mut f = 1.0;
            if r.len() >= 4 * max_lag {
                let mean = r.iter().sum::<f64>() / r.len() as f64;
                let c0: f64 = r.iter().map(|v| (v - mean).powi(2)).sum();
                for l in 1..=max_lag {
                    let cl: f64 = r
                        .windows(l + 1)
                        .map(|w| (w[0] - mean) * (w[l] - mean))
                        .sum();
                    let w = 1.0 - l as f64 / (max_lag as f64 + 1.0);
                    f += 2.0 * w * cl / c0.max(1e-300);
                }
            }
            acc += ss * f.max(1.0);
            total_w += ss;
        }
        if total_w > 0.0 {
            (acc / total_w).max(1.0)
        } else {
            1.0
        }
    }

    /// Sum of squared residuals (`+∞` on a failed evaluation).
    pub fn ssr(&self, model: &[Values]) -> f64 {
        let mut r = Vec::with_capacity(self.len());
        self.residuals(model, &mut r);
        let s: f64 = r.iter().map(|v| v * v).sum();
        if s.is_finite() {
            s
        } else {
            f64::INFINITY
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::config::EngineConfig;
    use crate::engine::trace::NSIG;

    fn row(n1: f64, t2: f64) -> Values {
        let mut v = [f64::NAN; NSIG];
        v[Signal::N1.index()] = n1;
        v[Signal::T2.index()] = t2;
        v
    }

    /// A model error widens σ in quadrature where it is stated and nowhere else: T2's 2 K
    /// instrument σ beside a 1.5 K model error is 2.5 K; N1 stays at its own.
    #[test]
    fn an_extra_sigma_adds_in_quadrature_where_stated() {
        let cfg = EngineConfig::reference().sensors;
        let t = [0.0, 1.0];
        let meas = [row(9000.0, 700.0), row(9000.0, 700.0)];
        let win = [true; 2];
        let obj = Objective::new(&t, &meas, &win, &[Signal::N1, Signal::T2], &cfg, 0.0)
            .with_extra_sigma(|_, s, _| if s == Signal::T2 { 1.5 } else { 0.0 });
        let mut off = meas;
        off.iter_mut().for_each(|v| v[Signal::T2.index()] += 2.5);
        assert!((obj.eq10(&off) - 1.0).abs() < 1e-12, "{}", obj.eq10(&off));
        let mut n1_off = meas;
        let sd = noise_sigma(&cfg, Signal::N1, 9000.0);
        n1_off.iter_mut().for_each(|v| v[Signal::N1.index()] += sd);
        assert!(
            (obj.eq10(&n1_off) - 1.0).abs() < 1e-12,
            "{}",
            obj.eq10(&n1_off)
        );
    }

    #[test]
    fn missing_samples_are_excluded_not_zero() {
        let cfg = EngineConfig::reference().sensors;
        let t = [0.0, 1.0, 2.0, 3.0];
        let meas = [
            row(9000.0, 700.0),
            row(f64::NAN, 700.0),
            row(9000.0, f64::INFINITY),
            row(9000.0, 700.0),
        ];
        let win = [true; 4];
        let obj = Objective::new(&t, &meas, &win, &[Signal::N1, Signal::T2], &cfg, 0.0);
        // N1: 3 valid samples, T2: 3 valid samples.
        assert_eq!(obj.len(), 6);
        // A model equal to the measurement where valid gives zero, whatever sits in the gaps.
        let mut model = meas;
        model[1][Signal::N1.index()] = 0.0;
        model[2][Signal::T2.index()] = 0.0;
        assert_eq!(obj.eq10(&model), 0.0);
        assert_eq!(obj.ssr(&model), 0.0);
        // T2 off by 2 K (its 1σ) everywhere: eq. 10 contributes exactly 1 from T2.
        let mut off = model;
        off.iter_mut().for_each(|v| v[Signal::T2.index()] += 2.0);
        assert!((obj.eq10(&off) - 1.0).abs() < 1e-12, "{}", obj.eq10(&off));
        // A NaN model value where a measurement exists fails the evaluation.
        let mut bad = model;
        bad[0][Signal::N1.index()] = f64::NAN;
        assert_eq!(obj.eq10(&bad), f64::INFINITY);
        assert_eq!(obj.ssr(&bad), f64::INFINITY);
        // … and says where.
        assert_eq!(
            obj.check(&bad),
            Err(EvalError::NonFinite {
                signal: Signal::N1,
                sample: 0
            })
        );
        assert_eq!(obj.check(&model), Ok(()));
        assert!(matches!(
            obj.check(&model[..2]),
            Err(EvalError::Short { .. })
        ));
        // Outside the window nothing counts.
        let obj2 = Objective::new(
            &t,
            &meas,
            &[true, true, false, false],
            &[Signal::T2],
            &cfg,
            0.0,
        );
        assert_eq!(obj2.len(), 2);
    }
}
