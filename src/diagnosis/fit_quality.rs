//! How well the fitted model reproduces the plant, and where it does not: the `fit_quality`
//! verdict every diagnosis result carries, and the residual map (signals × start-up phases)
//! behind it (issue 9 item 1).
//!
//! A health estimate is only as good as the model's fit: an unmodelled effect (a slow
//! thermocouple, a biased transmitter, a fuel-system delay) is absorbed by the health parameters
//! while the optimiser still reports tight σ. The residual is where it shows. For each signal
//! and phase this module measures, in the signal's own instrument-noise units:
//! - `norm_error`: RMS of (measured − model)/σ — about 1 where the model fits within noise;
//! - `bias`: the signed mean of (measured − model), in the signal's unit (and in σ);
//! - `shift_s`: the time shift that best aligns the model's rate of change with the measured
//!   one (cross-correlation of derivatives; positive = the measurement lags the model);
//! - `lag_like_s`: the part of the residual proportional to the signal's rate of change, as a
//!   first-order lag τ would leave it (residual = −τ·dZ/dt of the measurement), with the share
//!   of the residual variance it explains.
//!
//! Each sample is normalised like the objective does: σ² = σ_noise² + (ΔZ)², ΔZ the larger
//! change to a neighbouring sample (timing uncertainty), so a fast edge is not a "gap" — here
//! the smaller of the measured and the model's change, so a ripple the model lacks still is.
//!
//! The verdict (`good` / `suspect` / `poor`) rests on the result's normalised residual (the
//! residual sum of squares per compared sample, in noise units: ≈ 0.7 for the exact model on
//! noisy data; 1.1–1.7 with a thermocouple lag, a fuel-system delay or a 1 % temperature bias;
//! 13–23 with a 1 % P2 bias — `examples/fit_quality_calibration.rs`) and on the worst cell.
//! Pure arithmetic on given series: no I/O, no model runs.

use super::periodic::Periodicity;
use crate::engine::config::SensorsConfig;
use crate::engine::sensors::noise_sigma;
use crate::engine::trace::Values;
use crate::signals::{Phase, Signal};
use serde::Serialize;

/// The verdict on a fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The model reproduces the data within noise: the health estimate stands.
    Good,
    /// A systematic residual beyond noise: the health estimate may carry a model error.
    Suspect,
    /// The model does not fit the plant: do not use the health estimate as is.
    Poor,
}

impl Verdict {
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Good => "good",
            Verdict::Suspect => "suspect",
            Verdict::Poor => "poor",
        }
    }
}

/// Normalised residual of the exact model on noisy data (see the module doc): what a fit
/// with nothing unmodelled leaves, so `good_level` minus it is the room the `good` band has
/// for anything else.
pub const EXACT_MODEL_LEVEL: f64 = 0.7;

/// Thresholds of the verdict, on the normalised residual (SSR per compared sample).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Thresholds {
    /// Normalised residual up to which a fit is `good` (the exact model gives ≈ 0.7).
    pub good_level: f64,
    /// Normalised residual above which a fit is `poor`.
    pub poor_level: f64,
    /// A cell whose `norm_error` exceeds this makes a `good` fit `suspect`.
    pub suspect_cell: f64,
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds {
            good_level: 0.9,
            poor_level: 2.5,
            suspect_cell: 5.0,
        }
    }
}

/// The standard normal quantile of the probability with which a fit of the exact model to spot
/// readings must be judged `good` (99 %; [`spot_reading_good_level`]).
const SPOT_READING_GOOD_Z: f64 = 2.326_348;

/// The normalised residual up to which a fit of `params` parameters to `residuals` values of
/// spot readings (each value one reading, its inputs' noise in its covariance: `--noisy-inputs`)
/// is `good`: never below `base`, and at least the level the exact model stays under with
/// probability 0.99. Why: on such rows the residual sum of the exact model is χ² with
/// `residuals − params` degrees of freedom, its level (that sum per value) about 0.92 for nine
/// rows of eight values and six parameters, with a spread of 0.16 —
/// against `good` up to 0.9, set where the exact model reads 0.7 (a start-up, whose σ allows
/// for timing, or averaged rows); the model's own twin on such rows was `suspect` on 3 of 6
/// draws of its noise (1.17, 1.04, 0.99). Wilson–Hilferty's quantile (within 1 % from 10
/// degrees of freedom up).
pub fn spot_reading_good_level(base: f64, residuals: usize, params: usize) -> f64 {
    let k = residuals.saturating_sub(params).max(1) as f64;
    let a = 2.0 / (9.0 * k);
    let quantile = k * (1.0 - a + SPOT_READING_GOOD_Z * a.sqrt()).powi(3);
    base.max(quantile / residuals.max(1) as f64)
}

/// One cell of the residual map.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualCell {
    /// The signal, by its CSV column name (`t34_k`).
    #[serde(serialize_with = "column_name")]
    pub signal: Signal,
    pub phase: Phase,
    /// Samples compared.
    pub samples: usize,
    /// RMS of (measured − model)/σ.
    pub norm_error: f64,
    /// Mean of (measured − model), in the signal's unit.
    pub bias: f64,
    /// Mean of (measured − model)/σ.
    pub bias_sigma: f64,
    /// Shift that best aligns the derivatives, s (positive: the measurement lags the model);
    /// `None` where the signal hardly moves.
    pub shift_s: Option<f64>,
    /// Lag-like part: τ of residual ≈ −τ·dZ/dt (measured rate), s (`None` where the signal
    /// hardly moves).
    pub lag_like_s: Option<f64>,
    /// Share of the residual's variance the lag-like term explains (0…1).
    pub lag_share: f64,
}

/// The verdict with the numbers behind it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitQuality {
    pub verdict: Verdict,
    /// Residual sum of squares per compared sample, in noise units (≈ 0.7 for a model that
    /// fits): the number the verdict rests on.
    pub normalised_residual: f64,
    /// The worst cell's `norm_error` (0 without a residual map).
    pub worst_cell_error: f64,
    pub thresholds: Thresholds,
    /// Oscillations in the residual the model does not have (see [`super::periodic`]); any
    /// makes a `good` fit `suspect`.
    pub periodic: Vec<Periodicity>,
    /// Health estimates that ended on their search limits: the true value may lie beyond, so the
    /// estimate is not a measurement; any makes a `good` fit `suspect`.
    pub at_limit: Vec<LimitHit>,
    /// Health estimates better than new beyond their uncertainty
    /// ([`crate::health::below_plausible`]): an input instrument or a design value absorbed by
    /// the health; any makes a `good` fit `suspect`.
    pub implausible: Vec<Implausible>,
    /// Compared signals the adapted model itself predicts no better than
    /// [`crate::engine::config::UNRESOLVING_MODEL_ERROR_PCT`] between its calibration points
    /// (its `[adaptation.model_error_pct]`): their σ carries that error, so a small residual
    /// says little; any makes a `good` fit `suspect` ([`FitQuality::with_model_error`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub model_error_beyond: Vec<ModelErrorBeyond>,
    /// The verdict on the residual alone (before the health checks above): `good` here with a
    /// `suspect` verdict means the model reproduces the data but the health it needs is not
    /// believable.
    pub residual_verdict: Verdict,
    /// Where the gap lies, in plain words (empty for a good fit).
    pub summary: String,
}

/// A fitted parameter that ended on a limit of its search interval.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LimitHit {
    pub name: String,
    pub value: f64,
    /// The limit it sits on.
    pub limit: f64,
    /// `lower` or `upper`.
    pub side: &'static str,
}

/// A health estimate better than new beyond its uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Implausible {
    pub name: String,
    pub value: f64,
    pub sigma: f64,
}

impl Implausible {
    /// Plain words with what to suspect.
    pub fn describe(&self) -> String {
        // A turbine's flow capacity above new with its efficiency loss is erosion and not
        // flagged (`health::below_plausible_each`); flagged, it came without that loss.
        let why = if matches!(self.name.as_str(), "D_GT" | "D_GP") {
            "more flow capacity than new beyond its uncertainty without the efficiency loss \
             nozzle erosion brings: an input instrument (fuel meter, T1, power) or a design \
             value is more likely than the engine"
        } else {
            "better than new beyond its uncertainty: an input instrument (fuel meter, T1, power) \
             or a design value is more likely than the engine"
        };
        format!(
            "{} = {:+.2} ± {:.2} % is {why} (run gtwatch gap for the aliases)",
            self.name, self.value, self.sigma
        )
    }
}

/// A compared signal whose stated model error leaves it no information on health.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelErrorBeyond {
    /// The signal's CSV name.
    pub signal: String,
    /// Its model error, % of the value.
    pub pct: f64,
}

impl FitQuality {
    /// The verdict of a steady diagnosis on `engine_cfg` comparing `signals`: a `good` one
    /// becomes `suspect` when the file's adaptation states a model error of at least
    /// [`crate::engine::config::UNRESOLVING_MODEL_ERROR_PCT`] on any of them, and the summary
    /// says so. Why: that error is in each σ ([`super::steady::with_model_error`]), so the
    /// residual is small whatever the health; on a foreign unit whose adaptation followed its
    /// calibration points but predicted points left out 2.5–5.6 % off on six signals, levels of
    /// a degradation grid read up to 2.3 points off at a normalised residual of 0.2.
    pub fn with_model_error(
        mut self,
        engine_cfg: &crate::engine::EngineConfig,
        signals: &[Signal],
        speeds: &[Option<f64>],
    ) -> Self {
        let Some(a) = &engine_cfg.adaptation else {
            return self;
        };
        self.model_error_beyond = a
            .unresolving_signals(speeds)
            .into_iter()
            .filter(|(k, _)| signals.iter().any(|s| s.column() == k))
            .map(|(signal, pct)| ModelErrorBeyond { signal, pct })
            .collect();
        if self.model_error_beyond.is_empty() {
            return self;
        }
        let list: Vec<String> = self
            .model_error_beyond
            .iter()
            .map(|m| format!("{} {:.1} %", m.signal, m.pct))
            .collect();
        let words = format!(
            "the adapted model's own error between its calibration points \
             ([adaptation.model_error_pct], by GG speed [adaptation.model_error_by_speed]) is \
             at least {} at every point here: the fit is within it whatever the health, so \
             the estimate is not resolved; diagnose these points with others where the model \
             predicts better, or re-calibrate on a baseline with more loads, or with \
             --adapt-strategy continuation",
            list.join(", ")
        );
        if self.verdict == Verdict::Good {
            self.verdict = Verdict::Suspect;
            self.summary = words;
        } else {
            self.summary = format!("{}; {words}", self.summary);
        }
        self
    }
}

/// What the health estimates of a result say about it, beside its residual.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HealthFlags {
    pub at_limit: Vec<LimitHit>,
    pub implausible: Vec<Implausible>,
}

/// An estimate within this fraction of its interval's width from a limit is "at" it.
pub const AT_LIMIT_FRACTION: f64 = 0.002;

impl LimitHit {
    /// The hit of `value` on `[lower, upper]`, if it is within [`AT_LIMIT_FRACTION`] of the
    /// width from a limit.
    pub fn of(name: &str, value: f64, lower: f64, upper: f64) -> Option<LimitHit> {
        let tol = AT_LIMIT_FRACTION * (upper - lower);
        let hit = |limit: f64, side: &'static str| LimitHit {
            name: name.to_string(),
            value,
            limit,
            side,
        };
        if value <= lower + tol {
            Some(hit(lower, "lower"))
        } else if value >= upper - tol {
            Some(hit(upper, "upper"))
        } else {
            None
        }
    }

    /// Plain words with what to do.
    pub fn describe(&self) -> String {
        format!(
            "{} ended on its {} search limit {:+} % (estimate {:+.2}): the true value may lie \
             beyond, or the model does not fit this unit; widen it with [diagnosis] \
             health_bounds or --fit-param {}=LOW:HIGH",
            self.name, self.side, self.limit, self.value, self.name
        )
    }
}

fn column_name<S: serde::Serializer>(s: &Signal, ser: S) -> Result<S::Ok, S::Error> {
    ser.serialize_str(s.column())
}

/// Cells with fewer samples are not reported (no statistics on a handful of points).
const MIN_CELL_SAMPLES: usize = 5;
/// Largest shift searched, s.
const MAX_SHIFT_S: f64 = 15.0;
/// A signal "moves" in a phase when its model changes by more than this many noise σ.
const MOVES_SIGMA: f64 = 10.0;

/// The residual map of `measured` against `model` (rows indexed like `t_s`) for `signals`.
/// Cells are ordered by signal, then phase order of first appearance. Each sample's σ is the
/// instrument's, widened by `extra(k, s, z)` in quadrature (sample `k`, signal `s`, measured
/// value `z`, in the signal's unit; 0 = none): the model's own error of an adapted engine file,
/// as Method B's objective weighs it, so a cell is judged against what the model can do and an
/// offset within its stated error is not called a disagreement.
pub fn localise(
    t_s: &[f64],
    phases: &[Phase],
    measured: &[Values],
    model: &[Values],
    signals: &[Signal],
    sensors: &SensorsConfig,
    extra: &dyn Fn(usize, Signal, f64) -> f64,
) -> Vec<ResidualCell> {
    let n = t_s
        .len()
        .min(phases.len())
        .min(measured.len())
        .min(model.len());
    let mut order: Vec<Phase> = Vec::new();
    for &p in &phases[..n] {
        if !order.contains(&p) {
            order.push(p);
        }
    }
    let mut cells = Vec::new();
    for &s in signals {
        let i = s.index();
        // σ floor as the objective uses it: noise at 10 % of the largest reading.
        let peak = measured[..n]
            .iter()
            .map(|v| v[i].abs())
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        let floor = noise_sigma(sensors, s, 0.1 * peak)
            .max(1e-3 * peak)
            .max(1e-12);
        for &p in &order {
            let idx: Vec<usize> = (0..n)
                .filter(|&k| {
                    phases[k] == p && measured[k][i].is_finite() && model[k][i].is_finite()
                })
                .collect();
            if idx.len() < MIN_CELL_SAMPLES {
                continue;
            }
            cells.push(cell(
                t_s, measured, model, &idx, s, p, sensors, floor, extra,
            ));
        }
    }
    cells
}

#[allow(clippy::too_many_arguments)]
fn cell(
    t_s: &[f64],
    measured: &[Values],
    model: &[Values],
    idx: &[usize],
    s: Signal,
    p: Phase,
    sensors: &SensorsConfig,
    floor: f64,
    extra: &dyn Fn(usize, Signal, f64) -> f64,
) -> ResidualCell {
    let i = s.index();
    let m = idx.len() as f64;
    // σ² = σ_noise² + ΔZ² (timing uncertainty: the larger change to a neighbour), as the
    // objective normalises.
    //
    // The change counts only as far as the model moves too (the smaller of the measured and
    // the model's change): an oscillation or spikes the model does not have are a gap, not
    // timing — with the measured change alone a 0.2 Hz ripple normalised itself away.
    let step_in = |src: &[Values], k: usize| -> f64 {
        let z = src[k][i];
        let d = |j: Option<usize>| {
            j.and_then(|j| src.get(j))
                .map(|v| (v[i] - z).abs())
                .filter(|d| d.is_finite())
                .unwrap_or(0.0)
        };
        d(k.checked_sub(1)).max(d(Some(k + 1)))
    };
    let step = |k: usize| step_in(measured, k).min(step_in(model, k));
    let sig = |k: usize| {
        let z = measured[k][i];
        let n = noise_sigma(sensors, s, z).max(floor);
        let x = Some(extra(k, s, z))
            .filter(|x| x.is_finite())
            .unwrap_or(0.0);
        (n * n + x * x + step(k).powi(2)).sqrt()
    };
    let e: Vec<f64> = idx.iter().map(|&k| measured[k][i] - model[k][i]).collect();
    let r: Vec<f64> = idx.iter().zip(&e).map(|(&k, d)| d / sig(k)).collect();
    let norm_error = (r.iter().map(|v| v * v).sum::<f64>() / m).sqrt();
    let bias = e.iter().sum::<f64>() / m;
    let bias_sigma = r.iter().sum::<f64>() / m;
    // Model and measured rates (central differences on the cell's samples).
    let rate = |src: &[Values]| -> Vec<f64> {
        (0..idx.len())
            .map(|j| {
                let a = idx[j.saturating_sub(1)];
                let b = idx[(j + 1).min(idx.len() - 1)];
                let dt = t_s[b] - t_s[a];
                if dt > 0.0 {
                    (src[b][i] - src[a][i]) / dt
                } else {
                    0.0
                }
            })
            .collect()
    };
    let dm = rate(model);
    let dz = rate(measured);
    let span = idx
        .iter()
        .map(|&k| model[k][i])
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    let typical_sigma = idx.iter().map(|&k| sig(k)).sum::<f64>() / m;
    let moves = span.1 - span.0 > MOVES_SIGMA * typical_sigma;
    // A first-order lag τ leaves exactly e = −τ·dZ_meas/dt: regress on the measured rate.
    let (lag_like_s, lag_share) = if moves {
        lag_like(&e, &dz)
    } else {
        (None, 0.0)
    };
    let shift_s = if moves {
        best_shift(t_s, idx, &dz, &dm)
    } else {
        None
    };
    ResidualCell {
        signal: s,
        phase: p,
        samples: idx.len(),
        norm_error,
        bias,
        bias_sigma,
        shift_s,
        lag_like_s,
        lag_share,
    }
}

/// Least squares e ≈ a + b·dz: τ = −b and the share of var(e) the rate term explains.
fn lag_like(e: &[f64], dm: &[f64]) -> (Option<f64>, f64) {
    let m = e.len() as f64;
    let (me, md) = (e.iter().sum::<f64>() / m, dm.iter().sum::<f64>() / m);
    let sdd: f64 = dm.iter().map(|d| (d - md).powi(2)).sum();
    let see: f64 = e.iter().map(|v| (v - me).powi(2)).sum();
    if sdd <= 0.0 || see <= 0.0 {
        return (None, 0.0);
    }
    let sed: f64 = e.iter().zip(dm).map(|(v, d)| (v - me) * (d - md)).sum();
    let b = sed / sdd;
    (Some(-b), (sed * sed / (sdd * see)).clamp(0.0, 1.0))
}

/// The shift τ (s) maximising the correlation of the measured rate with the model rate
/// delayed by τ, on the cell's sample grid (median spacing), refined by a parabola.
fn best_shift(t_s: &[f64], idx: &[usize], dz: &[f64], dm: &[f64]) -> Option<f64> {
    let n = idx.len();
    if n < 2 * MIN_CELL_SAMPLES {
        return None;
    }
    let mut gaps: Vec<f64> = idx.windows(2).map(|w| t_s[w[1]] - t_s[w[0]]).collect();
    gaps.sort_by(f64::total_cmp);
    let dt = gaps[gaps.len() / 2];
    if dt <= 0.0 {
        return None;
    }
    let max_lag = ((MAX_SHIFT_S / dt).round() as usize).min(n / 2);
    let corr = |lag: isize| -> f64 {
        let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
        for j in 0..n as isize {
            let jm = j - lag;
            if jm < 0 || jm >= n as isize {
                continue;
            }
            let (x, y) = (dz[j as usize], dm[jm as usize]);
            sxy += x * y;
            sxx += x * x;
            syy += y * y;
        }
        if sxx > 0.0 && syy > 0.0 {
            sxy / (sxx * syy).sqrt()
        } else {
            f64::NEG_INFINITY
        }
    };
    let lags: Vec<isize> = (-(max_lag as isize)..=max_lag as isize).collect();
    let cs: Vec<f64> = lags.iter().map(|&l| corr(l)).collect();
    let (best, &c0) = cs.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    if !c0.is_finite() || c0 <= 0.0 {
        return None;
    }
    let mut shift = lags[best] as f64;
    if best > 0 && best + 1 < cs.len() {
        let (a, b, c) = (cs[best - 1], c0, cs[best + 1]);
        let den = a - 2.0 * b + c;
        if den < 0.0 && a.is_finite() && c.is_finite() {
            shift += (0.5 * (a - c) / den).clamp(-0.5, 0.5);
        }
    }
    Some(shift * dt)
}

/// The verdict for a result with normalised residual `level`, residual map `cells`, the
/// oscillations found in its residual and the estimates that ended on a search limit.
pub fn assess(
    level: f64,
    cells: &[ResidualCell],
    periodic: &[Periodicity],
    flags: &HealthFlags,
    th: &Thresholds,
) -> FitQuality {
    let worst = cells
        .iter()
        .filter(|c| c.norm_error.is_finite())
        .max_by(|a, b| a.norm_error.total_cmp(&b.norm_error));
    let worst_cell_error = worst.map_or(0.0, |c| c.norm_error);
    let residual_verdict = if !level.is_finite() || level > th.poor_level {
        Verdict::Poor
    } else if level > th.good_level || worst_cell_error > th.suspect_cell || !periodic.is_empty() {
        Verdict::Suspect
    } else {
        Verdict::Good
    };
    let verdict = if residual_verdict == Verdict::Good
        && !(flags.at_limit.is_empty() && flags.implausible.is_empty())
    {
        Verdict::Suspect
    } else {
        residual_verdict
    };
    let summary = if verdict == Verdict::Good {
        String::new()
    } else {
        let mut text = describe(level, cells);
        for p in periodic {
            text.push_str(&format!(
                "; {} oscillates at {:.3} Hz ({:.1} s period), amplitude {:.3} ({:.1} σ), not in the model",
                p.signal.column(),
                p.frequency_hz,
                p.period_s,
                p.amplitude,
                p.amplitude_sigma
            ));
        }
        for h in &flags.at_limit {
            text.push_str("; ");
            text.push_str(&h.describe());
        }
        for h in &flags.implausible {
            text.push_str("; ");
            text.push_str(&h.describe());
        }
        text
    };
    FitQuality {
        verdict,
        normalised_residual: level,
        worst_cell_error,
        thresholds: *th,
        periodic: periodic.to_vec(),
        at_limit: flags.at_limit.clone(),
        implausible: flags.implausible.clone(),
        model_error_beyond: Vec::new(),
        residual_verdict,
        summary,
    }
}

/// Plain words for the largest residual cells: "T34 during acceleration: lag-like, about
/// 4.1 s (5.2 σ)".
pub fn describe(level: f64, cells: &[ResidualCell]) -> String {
    let mut sorted: Vec<&ResidualCell> = cells.iter().collect();
    sorted.sort_by(|a, b| b.norm_error.total_cmp(&a.norm_error));
    let parts: Vec<String> = sorted
        .iter()
        .take(3)
        .filter(|c| c.norm_error > 1.5)
        .map(|c| format!("{} during {}: {}", c.signal.column(), c.phase, character(c)))
        .collect();
    if parts.is_empty() {
        format!("normalised residual {level:.2}, spread over signals and phases")
    } else {
        format!(
            "normalised residual {level:.2}; largest: {}",
            parts.join("; ")
        )
    }
}

/// What a cell's residual looks like.
fn character(c: &ResidualCell) -> String {
    let kind = match (c.lag_like_s, c.shift_s) {
        (Some(tau), _) if c.lag_share > 0.5 && tau.abs() > 0.3 => {
            format!("lag-like, about {tau:.1} s")
        }
        (_, Some(sh)) if sh.abs() >= 1.0 && c.bias_sigma.abs() < 0.5 * c.norm_error => {
            format!("time-shifted, about {sh:.1} s")
        }
        _ if c.bias_sigma.abs() > 0.7 * c.norm_error => {
            format!("offset, mean {:+.3} ({:+.1} σ)", c.bias, c.bias_sigma)
        }
        _ => "shape mismatch".to_string(),
    };
    format!("{kind} ({:.1} σ RMS)", c.norm_error)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// χ²'s 99 % quantile per value (tables: 66 degrees of freedom 95.63, 10 23.21, 200 249.4)
    /// and never below the base level.
    #[test]
    fn spot_readings_are_good_up_to_the_exact_models_99_percent_level() {
        for (n, p, table) in [(72, 6, 95.63), (16, 6, 23.21), (206, 6, 249.4)] {
            let level = spot_reading_good_level(0.0, n, p);
            let want = table / n as f64;
            assert!(
                (level / want - 1.0).abs() < 0.01,
                "{n}, {p}: {level} vs {want}"
            );
        }
        assert_eq!(spot_reading_good_level(5.0, 72, 6), 5.0);
    }

    /// A stated model error of at least 2 % on a compared signal makes a `good` fit `suspect`
    /// and says why; on a signal not compared, or below the threshold, nothing changes; a fit
    /// already `poor` stays so with the words appended.
    #[test]
    fn a_model_error_that_leaves_health_unresolved_is_not_good() {
        use crate::engine::config::AdaptationConfig;
        use crate::engine::EngineConfig;
        let th = Thresholds::default();
        let good = || assess(0.7, &[], &[], &HealthFlags::default(), &th);
        let mut cfg = EngineConfig::reference();
        let compared = [Signal::N1, Signal::T34];
        assert_eq!(good().with_model_error(&cfg, &compared, &[]), good());
        let mut a = AdaptationConfig::default();
        a.model_error_pct.insert("n1_rpm".into(), 1.9);
        a.model_error_pct.insert("torque_knm".into(), 20.0);
        cfg.adaptation = Some(a.clone());
        // 1.9 % on a compared signal, 20 % on one not compared: still good.
        assert_eq!(
            good().with_model_error(&cfg, &compared, &[]).verdict,
            Verdict::Good
        );
        a.model_error_pct.insert("t34_k".into(), 2.0);
        cfg.adaptation = Some(a);
        let q = good().with_model_error(&cfg, &compared, &[]);
        assert_eq!(q.verdict, Verdict::Suspect);
        assert_eq!(q.residual_verdict, Verdict::Good);
        assert_eq!(
            q.model_error_beyond,
            vec![ModelErrorBeyond {
                signal: "t34_k".into(),
                pct: 2.0
            }]
        );
        assert!(q.summary.contains("t34_k 2.0 %"), "{}", q.summary);
        let poor = assess(9.0, &[], &[], &HealthFlags::default(), &th).with_model_error(
            &cfg,
            &compared,
            &[],
        );
        assert_eq!(poor.verdict, Verdict::Poor);
        assert!(
            poor.summary.starts_with("normalised residual 9.00") && poor.summary.contains("t34_k")
        );

        // Along the operating line: T34 predicted within 0.5 % at speed 0.95, 4 % at 0.8. A
        // diagnosis with a point at 0.95 is resolved by it; one with points at 0.8 only is not
        // (its smallest error is said).
        let mut a = AdaptationConfig::default();
        a.model_error_pct.insert("t34_k".into(), 2.5);
        a.model_error_by_speed = Some(crate::engine::config::ModelErrorBySpeed {
            speed_knots: vec![0.8, 0.95],
            pct: [("t34_k".to_string(), vec![4.0, 0.5])]
                .into_iter()
                .collect(),
        });
        cfg.adaptation = Some(a);
        let both = good().with_model_error(&cfg, &compared, &[Some(0.8), Some(0.95)]);
        assert_eq!(both.verdict, Verdict::Good, "{}", both.summary);
        let low = good().with_model_error(&cfg, &compared, &[Some(0.78), Some(0.8), None]);
        assert_eq!(low.verdict, Verdict::Suspect);
        assert_eq!(low.model_error_beyond[0].signal, "t34_k");
        assert!(
            (low.model_error_beyond[0].pct - 2.5).abs() < 1e-12,
            "{low:?}"
        );
        let low = good().with_model_error(&cfg, &compared, &[Some(0.78), Some(0.8)]);
        assert!(
            (low.model_error_beyond[0].pct - 4.0).abs() < 1e-12,
            "{low:?}"
        );
    }

    /// A turbine's flow capacity above new, flagged, says it lacks erosion's efficiency loss and
    /// names the instruments; an efficiency better than new names the instruments only.
    #[test]
    fn implausible_words_tell_turbine_flow_from_efficiency() {
        let of = |name: &str| {
            Implausible {
                name: name.into(),
                value: -1.2,
                sigma: 0.2,
            }
            .describe()
        };
        for name in ["D_GT", "D_GP"] {
            let text = of(name);
            assert!(
                text.contains("without the efficiency loss nozzle erosion brings")
                    && text.contains("fuel meter"),
                "{text}"
            );
        }
        for name in ["D_GC", "D_EC", "D_ET", "D_EP"] {
            let text = of(name);
            assert!(
                text.contains("better than new") && !text.contains("erosion"),
                "{text}"
            );
        }
    }

    /// An estimate on a limit makes a good fit suspect and says what to do; one inside does not.
    #[test]
    fn estimate_on_a_search_limit_is_flagged() {
        assert!(LimitHit::of("D_GC", 5.0, -3.0, 10.0).is_none());
        let hit = LimitHit::of("D_GC", 9.99, -3.0, 10.0).expect("at the upper limit");
        assert_eq!((hit.side, hit.limit), ("upper", 10.0));
        let low = LimitHit::of("D_EP", -3.0, -3.0, 10.0).expect("at the lower limit");
        assert_eq!(low.side, "lower");
        let th = Thresholds::default();
        assert_eq!(
            assess(0.7, &[], &[], &HealthFlags::default(), &th).verdict,
            Verdict::Good
        );
        let flags = HealthFlags {
            at_limit: vec![hit],
            ..HealthFlags::default()
        };
        let q = assess(0.7, &[], &[], &flags, &th);
        assert_eq!(q.verdict, Verdict::Suspect);
        assert!(
            q.summary.contains("D_GC ended on its upper search limit"),
            "{}",
            q.summary
        );
        assert_eq!(q.at_limit.len(), 1);
    }
    use crate::engine::EngineConfig;
    use crate::signals::NSIG;

    /// A smooth T34-like rise measured three ways: exactly, with a 4 s first-order lag, with
    /// a constant offset. The map says which is which.
    #[test]
    fn the_map_tells_lag_from_offset_from_a_fit() {
        let cfg = EngineConfig::reference();
        let n = 300;
        let t: Vec<f64> = (0..n).map(|k| k as f64).collect();
        let phases = vec![Phase::Acceleration; n];
        // A smooth rise (tanh step): its rate is a bump, so a delay shows as a shift.
        let truth = |tt: f64| 300.0 + 250.0 * (1.0 + ((tt - 120.0) / 25.0).tanh());
        let row = |v: f64| {
            let mut r = [f64::NAN; NSIG];
            r[Signal::T34.index()] = v;
            r
        };
        let model: Vec<Values> = t.iter().map(|&x| row(truth(x))).collect();
        // 4 s lag, integrated exactly on the 1 s grid.
        let mut lagged = Vec::with_capacity(n);
        let mut y = truth(0.0);
        for &x in &t {
            let a = (-1.0f64 / 4.0).exp();
            y = a * y + (1.0 - a) * truth(x);
            lagged.push(row(y));
        }
        let offset: Vec<Values> = t.iter().map(|&x| row(truth(x) + 8.0)).collect();
        let map = |meas: &[Values]| {
            localise(
                &t,
                &phases,
                meas,
                &model,
                &[Signal::T34],
                &cfg.sensors,
                &|_, _, _| 0.0,
            )
            .pop()
            .expect("one cell")
        };
        let exact = map(&model);
        assert_eq!(exact.norm_error, 0.0);
        let lag = map(&lagged);
        let tau = lag.lag_like_s.expect("moves");
        assert!((tau - 4.0).abs() < 0.8 && lag.lag_share > 0.9, "{lag:?}");
        let shift = lag.shift_s.expect("shift");
        assert!((2.5..6.0).contains(&shift), "{lag:?}");
        assert!(
            character(&lag).starts_with("lag-like"),
            "{}",
            character(&lag)
        );
        let off = map(&offset);
        assert!(
            (off.bias - 8.0).abs() < 1e-9 && off.lag_share < 0.1,
            "{off:?}"
        );
        assert!(character(&off).starts_with("offset"), "{}", character(&off));
        // The same offset judged beside a model error of 8 K (an adapted file's own): σ
        // widened in quadrature, the cell's normalised error falls by that much.
        let with_model = localise(
            &t,
            &phases,
            &offset,
            &model,
            &[Signal::T34],
            &cfg.sensors,
            &|_, _, _| 8.0,
        )
        .pop()
        .expect("one cell");
        assert!(
            with_model.norm_error < 0.8 * off.norm_error && with_model.norm_error < 1.0,
            "{} against {}",
            with_model.norm_error,
            off.norm_error
        );

        let th = Thresholds::default();
        assert_eq!(
            assess(0.7, &[exact], &[], &HealthFlags::default(), &th).verdict,
            Verdict::Good
        );
        // A clean overall residual with one cell far beyond noise is suspect.
        let bad_cell = ResidualCell {
            norm_error: 6.0,
            ..lag.clone()
        };
        let q = assess(
            0.8,
            std::slice::from_ref(&bad_cell),
            &[],
            &HealthFlags::default(),
            &th,
        );
        assert_eq!(q.verdict, Verdict::Suspect, "one bad cell");
        assert!(
            q.summary.contains("t34_k during acceleration: lag-like"),
            "{}",
            q.summary
        );
        // A ripple the model lacks makes a fit suspect, however small its residual.
        let ripple = Periodicity {
            signal: Signal::P34,
            frequency_hz: 0.2,
            period_s: 5.0,
            amplitude: 2.0,
            amplitude_sigma: 1.0,
            p_value: 1e-12,
        };
        let q = assess(
            0.7,
            &[],
            std::slice::from_ref(&ripple),
            &HealthFlags::default(),
            &th,
        );
        assert_eq!(q.verdict, Verdict::Suspect);
        assert!(
            q.summary.contains("p34_kpa oscillates at 0.200 Hz"),
            "{}",
            q.summary
        );
        assert_eq!(
            assess(1.3, &[], &[], &HealthFlags::default(), &th).verdict,
            Verdict::Suspect
        );
        assert_eq!(
            assess(3.0, &[], &[], &HealthFlags::default(), &th).verdict,
            Verdict::Poor
        );
        assert_eq!(
            assess(f64::NAN, &[], &[], &HealthFlags::default(), &th).verdict,
            Verdict::Poor
        );
    }
}
