//! A step in a unit's health history, attributed across consecutive start-ups (issue 23 item
//! 3): is it the engine, or an instrument that drives the model?
//!
//! One start-up cannot tell a fuel meter reading 3 % high from a turbine that lost two points:
//! the six health parameters absorb the meter's error ([`super::alias`]). A *sequence* can. An
//! instrument that goes wrong at start-up k moves every later estimate by the same vector —
//! its alias signature `s` times the error's size `θ` — while the engine's health goes on
//! following its trend. So the start-ups since the last wash are fitted jointly, per health
//! parameter a line `a + b·t` (the trend, shared by all start-ups) plus, from the onset k on,
//! one of:
//! - nothing (no step: a noisy start-up);
//! - the onset start-up alone off, in any direction (an outlier: one bad fit, 6 parameters);
//! - a step in one health parameter (a component fault: FOD, a burnt blade), six hypotheses;
//! - a wash (a step in both compressor parameters, 2 parameters);
//! - a step in all six (anything the engine may do, 6 parameters);
//! - `θ·s` for each instrument signature (1 parameter each);
//! - `θ·s` from the onset until a later start-up, each instrument again (the instrument was
//!   repaired or recalibrated in between: 2 parameters, its size and the start-up it ended
//!   before; at least [`MIN_WINDOW`] start-ups long, since one start-up alone is an outlier);
//! - `r·(t − t_m)·s`, each instrument drifting from the last start-up `m` it read right at
//!   (at most the one before the onset: a slow drift leaves the trend later than it began; 2
//!   parameters, its rate and `m`), and, as what the engine may do the same way, a change of
//!   rate from `m` in one health parameter, in both compressor parameters (fouling that speeds
//!   up) or in all six.
//!
//! A drift that never steps far enough from the trend of the start-ups before it for any
//! [`onset`] is looked for by [`drift_onset`]: an instrument's drift that beats the trend alone
//! decisively gives the onset, and the attribution then weighs it against everything above.
//!
//! Steps are attributed one after another ([`attribute_steps`]): when a free step from a later
//! start-up, beside the best explanation, fits decisively better, the first step is fitted on
//! the start-ups before it, its explanation taken out, and the next attributed in the rest (a
//! noisy start-up, a component fault or one instrument must not hide or bend the next).
//!
//! Hypotheses are compared by BIC (χ² + parameters · ln N): an instrument wins only when its one
//! parameter explains the step as well as the engine's six, and better than any one-component
//! fault. Each estimate's variance is its own σ² plus the scatter the trend before the onset
//! shows beyond it, so an optimistic Method B σ does not make noise look like evidence. An
//! estimate on its search limit is censored (left out of the fit); its corrected value is
//! given with a σ as large as the correction, since the unlimited estimate lies beyond. The
//! instrument's size comes with its 1σ, and the corrected health (estimate − θ·s) is what the
//! trend and the wash advice should see.
//!
//! Pure: no I/O, no model runs, no store; deterministic. The signatures come from a stored gap
//! analysis's aliases (linearised at that start-up's fit), the points from stored Method B
//! results. Must not decide what a plant does with the verdict (that is `advice`).

use crate::health::{HealthBounds, HEALTH_NAMES};
use crate::trend::{steps_against_trend, TrendPoint};
use serde::Serialize;

/// Fewest start-ups before the onset: a trend needs three.
pub(crate) const MIN_BEFORE: usize = 3;
/// Fewest start-ups an instrument's error that ended (a repair) is taken to have lasted: one
/// start-up off alone is the outlier hypothesis's, whatever its direction.
pub(crate) const MIN_WINDOW: usize = 2;
/// BIC margin (2·Δ ln L) by which the best instrument must beat every engine explanation to be
/// named; closer than this, the verdict is ambiguous. 6 is "strong evidence" on the usual scale
/// (Kass & Raftery 1995).
pub(crate) const DECISIVE_BIC: f64 = 6.0;
/// Floor of a health estimate's 1σ, percent: no diagnosis is better than this from one start-up.
const SIGMA_FLOOR: f64 = 0.03;

/// One start-up's Method B result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SeqPoint {
    /// Days (any origin).
    pub(crate) t_days: f64,
    /// Health estimate, percent (`HEALTH_NAMES` order).
    pub(crate) health: [f64; 6],
    /// Its 1σ, percent (non-finite or ≤ 0: unknown, the floor is used).
    pub(crate) sigma: [f64; 6],
    /// Estimates that ended on their search limit: censored (the unlimited estimate lies
    /// beyond), so they take no part in the joint fit.
    pub(crate) at_limit: [bool; 6],
}

/// How close to a search limit an estimate counts as on it (censored), percent.
pub(crate) const LIMIT_TOL: f64 = 0.01;

impl SeqPoint {
    /// A result at `t_days`, each estimate censored when it sits on its interval of `bounds`.
    pub(crate) fn new(
        t_days: f64,
        health: [f64; 6],
        sigma: [f64; 6],
        bounds: &HealthBounds,
    ) -> SeqPoint {
        SeqPoint {
            t_days,
            health,
            sigma,
            at_limit: std::array::from_fn(|i| {
                let (lo, hi) = bounds.of(i);
                health[i] <= lo + LIMIT_TOL || health[i] >= hi - LIMIT_TOL
            }),
        }
    }
}

/// How an instrument's error moves the health estimate: `shift` per `nominal` error.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct Signature {
    /// Effect instance (`fuel_meter`, `inlet_temperature`, `sensor_scale:power_mw`).
    pub(crate) effect: String,
    pub(crate) unit: String,
    /// Error size the shift is given for, in `unit`.
    pub(crate) nominal: f64,
    /// Estimate − truth of each health parameter for an error of `nominal`, points.
    pub(crate) shift: [f64; 6],
    /// Largest error that is physically credible, ± in `unit` (beyond it the hypothesis is
    /// dropped: a 40 % fuel-meter error is not an explanation).
    pub(crate) max_magnitude: f64,
}

/// One explanation of the step, fitted.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct Hypothesis {
    /// `none`, `outlier`, `wash`, `step:D_GT`, `step:all`, or an instrument's effect
    /// instance.
    pub(crate) name: String,
    /// Whether it is an instrument.
    pub(crate) instrument: bool,
    pub(crate) chi2: f64,
    /// Parameters beyond the six trend lines (0, 1 or 6).
    pub(crate) extra_params: usize,
    pub(crate) bic: f64,
    /// The fitted change of each health estimate from the onset on, points.
    pub(crate) step: [f64; 6],
    /// An instrument's error (in its unit) and its 1σ.
    pub(crate) magnitude: Option<f64>,
    pub(crate) magnitude_sigma: Option<f64>,
    /// An instrument's error that ended: the index of the first start-up back right (the
    /// error lasted from the onset to the one before). `None`: from the onset on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) until: Option<usize>,
    /// An instrument drifting rather than stepped: the last start-up it read right at (its
    /// error grows from that start-up's time on, `step` and `magnitude` are per day).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) drift_from: Option<usize>,
    /// The time of `drift_from`, days: the hypothesis answers how far its drift had gone at
    /// any time ([`Hypothesis::shift_at`]) without the points it was fitted to.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) drift_from_days: Option<f64>,
    /// 1σ of `step`, points.
    pub(crate) step_sigma: [f64; 6],
    /// Each parameter's trend under this hypothesis: value at `t_ref_days`, rate per day.
    pub(crate) trend: [[f64; 2]; 6],
    /// Each trend line's covariance (value at `t_ref_days`, rate, theirs): how well the line
    /// is known where it stands for an estimate on its limit.
    #[serde(skip)]
    pub(crate) trend_cov: [[f64; 3]; 6],
    pub(crate) t_ref_days: f64,
}

impl Hypothesis {
    /// The trend line of parameter `i` at `t_days` under this hypothesis, and its 1σ.
    pub(crate) fn line_at(&self, i: usize, t_days: f64) -> (f64, f64) {
        let dt = t_days - self.t_ref_days;
        let [va, vb, cab] = self.trend_cov[i];
        (
            self.trend[i][0] + self.trend[i][1] * dt,
            (va + dt * dt * vb + 2.0 * dt * cab).max(0.0).sqrt(),
        )
    }

    /// How much this explanation moves the health of a start-up at `t_days` that it is on:
    /// the step, or what the drift had reached by then.
    pub(crate) fn shift_at(&self, t_days: f64) -> [f64; 6] {
        let g = share(self.drift_from_days, t_days);
        std::array::from_fn(|i| g * self.step[i])
    }
}

/// What the sequence says.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub(crate) enum SequenceVerdict {
    /// No persistent step: the start-up that left the trend is not followed by the others (the
    /// best explanation is `none` or `outlier`).
    NoStep,
    /// An instrument's error, decisively.
    Instrument {
        effect: String,
        unit: String,
        magnitude: f64,
        magnitude_sigma: f64,
        /// Index of the first start-up the instrument read right again (repaired); `None`:
        /// it still reads wrong at the newest.
        #[serde(skip_serializing_if = "Option::is_none")]
        until: Option<usize>,
        /// The instrument drifts: its error grows from the last start-up it read right at
        /// (`magnitude` is then the error it reached at the newest start-up it moved).
        #[serde(skip_serializing_if = "Option::is_none")]
        drift: Option<Drift>,
    },
    /// An instrument explains the step best, but not decisively: these are within
    /// [`DECISIVE_BIC`] of it (instruments and engine explanations).
    Ambiguous { candidates: Vec<String> },
    /// The engine's health stepped (the best explanation is not an instrument).
    HealthStep { explanation: String },
}

impl SequenceVerdict {
    /// One-word form for the benchmarks' tables: `no_step`, `instrument:<effect>`,
    /// `ambiguous:<a>|<b>`, `health_step:<explanation>`.
    pub(crate) fn label(&self) -> String {
        match self {
            SequenceVerdict::NoStep => "no_step".to_string(),
            SequenceVerdict::Instrument { effect, .. } => format!("instrument:{effect}"),
            SequenceVerdict::Ambiguous { candidates } => {
                format!("ambiguous:{}", candidates.join("|"))
            }
            SequenceVerdict::HealthStep { explanation } => format!("health_step:{explanation}"),
        }
    }

    /// The start-up the named instrument read right again from, when it was repaired.
    pub(crate) fn until(&self) -> Option<usize> {
        match self {
            SequenceVerdict::Instrument { until, .. } => *until,
            _ => None,
        }
    }

    /// The named instrument's drift, when it drifts.
    pub(crate) fn drift(&self) -> Option<Drift> {
        match self {
            SequenceVerdict::Instrument { drift, .. } => *drift,
            _ => None,
        }
    }

    /// The instrument's fitted magnitude and its 1σ, when the verdict names one.
    pub(crate) fn instrument_magnitude(&self) -> Option<(f64, f64)> {
        match self {
            SequenceVerdict::Instrument {
                magnitude,
                magnitude_sigma,
                ..
            } => Some((*magnitude, *magnitude_sigma)),
            _ => None,
        }
    }
}

/// An instrument's error that grows with time rather than stepped (a meter's calibration
/// drifting, a thermocouple decaying).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub(crate) struct Drift {
    /// Index of the last start-up it read right at: the error grows from its time on.
    pub(crate) from: usize,
    /// Growth of the error per day, in the instrument's unit, and its 1σ.
    pub(crate) rate_per_day: f64,
    pub(crate) rate_sigma: f64,
}

/// The attribution of the first step in a sequence.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct SequenceAttribution {
    /// Index of the first start-up that left the trend.
    pub(crate) onset: usize,
    pub(crate) verdict: SequenceVerdict,
    /// The joint fit could not tell the named instrument from these (engine explanations
    /// among them): the stepped start-ups' own gap analyses decided ([`Self::decided_by`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub(crate) undecided_between: Vec<String>,
    /// Every hypothesis, best (lowest BIC) first.
    pub(crate) hypotheses: Vec<Hypothesis>,
}

impl SequenceAttribution {
    /// An `ambiguous` verdict decided by what the stepped start-ups' own gap analyses named
    /// (`named[j]`: the instrument start-up `j`'s analysis named, if any): when the start-ups
    /// this step moved whose analysis named an instrument all named the same one, and it is
    /// among the candidates, it is the verdict, sized by its hypothesis. Each analysis fitted
    /// the instrument to the whole transient of one start-up, where an instrument's error and
    /// a change of health differ in shape (a power transducer reading low and a power turbine
    /// gaining efficiency, alike in the health estimates the joint fit sees, are not alike in
    /// time); the joint fit sees only the health estimates. Anything else stays as it is.
    pub(crate) fn decided_by(
        mut self,
        named: &[Option<String>],
        signatures: &[Signature],
        points: &[SeqPoint],
    ) -> SequenceAttribution {
        let SequenceVerdict::Ambiguous { candidates } = &self.verdict else {
            return self;
        };
        let mut said: Vec<&str> = named
            .iter()
            .skip(self.onset)
            .flatten()
            .map(String::as_str)
            .collect();
        said.sort_unstable();
        said.dedup();
        let [one] = said.as_slice() else {
            return self;
        };
        if !candidates.iter().any(|c| c == one) {
            return self;
        }
        let Some(h) = self
            .hypotheses
            .iter()
            .find(|h| h.instrument && h.name == *one)
        else {
            return self;
        };
        let verdict = instrument_verdict(h, signatures, points);
        let others: Vec<String> = candidates.iter().filter(|c| *c != one).cloned().collect();
        self.verdict = verdict;
        self.undecided_between = others;
        self
    }

    /// The same attribution of a sequence whose first `by` start-ups were left out, stated
    /// on the whole sequence (indices moved by `by`).
    pub(crate) fn shifted(mut self, by: usize) -> SequenceAttribution {
        self.onset += by;
        if let SequenceVerdict::Instrument { until, drift, .. } = &mut self.verdict {
            if let Some(m) = until {
                *m += by;
            }
            if let Some(d) = drift {
                d.from += by;
            }
        }
        for h in &mut self.hypotheses {
            if let Some(m) = &mut h.until {
                *m += by;
            }
            if let Some(m) = &mut h.drift_from {
                *m += by;
            }
        }
        self
    }

    /// The start-ups the instrument's error moved: from the onset to the end of the sequence,
    /// or to the start-up before it read right again. Empty unless the verdict names one.
    pub(crate) fn corrected_range(&self, n: usize) -> std::ops::Range<usize> {
        match &self.verdict {
            SequenceVerdict::Instrument { until, drift, .. } => {
                drift.map_or(self.onset, |d| d.from + 1)..until.unwrap_or(n).min(n)
            }
            _ => 0..0,
        }
    }

    /// `points` without this step's best explanation (its first hypothesis): nothing for
    /// `none`, the onset's offset for an outlier, else the fitted step from the onset on (to
    /// the start-up before an instrument read right again). What the next step is looked for
    /// and attributed in; not a correction (a step the engine took is its health).
    pub(crate) fn explained(&self, points: &[SeqPoint]) -> Vec<SeqPoint> {
        let Some(best) = self.hypotheses.first() else {
            return points.to_vec();
        };
        let n = points.len();
        let range = match best.name.as_str() {
            "none" => 0..0,
            "outlier" => self.onset..(self.onset + 1).min(n),
            _ => best.drift_from.map_or(self.onset, |m| m + 1)..best.until.unwrap_or(n).min(n),
        };
        map_within(points, range, |p| {
            let shift = best.shift_at(p.t_days);
            SeqPoint {
                health: std::array::from_fn(|i| p.health[i] - shift[i]),
                ..*p
            }
        })
    }

    /// The health and 1σ each start-up would have without the instrument's error (unchanged
    /// unless the verdict names an instrument; the start-ups of [`Self::corrected_range`] are
    /// corrected).
    pub(crate) fn corrected(&self, points: &[SeqPoint]) -> Vec<SeqPoint> {
        let SequenceVerdict::Instrument {
            effect,
            until,
            drift,
            ..
        } = &self.verdict
        else {
            return points.to_vec();
        };
        let Some(h) = self.hypotheses.iter().find(|h| {
            &h.name == effect && h.until == *until && h.drift_from == drift.map(|d| d.from)
        }) else {
            return points.to_vec();
        };
        let range = self.corrected_range(points.len());
        map_within(points, range, |p| {
            // A censored estimate says only that the health lies beyond the limit; under
            // the instrument's hypothesis the health follows its trend, so that is the
            // corrected value, with the line's 1σ where it stands: the estimate's own σ, at a
            // bound, says nothing, and a line carried days beyond the last estimate it was
            // fitted to is known less well than where they lie.
            let g = share(h.drift_from_days, p.t_days);
            let shift = h.shift_at(p.t_days);
            let on_line: [(f64, f64); 6] = std::array::from_fn(|i| h.line_at(i, p.t_days));
            SeqPoint {
                t_days: p.t_days,
                health: std::array::from_fn(|i| {
                    if p.at_limit[i] {
                        on_line[i].0
                    } else {
                        p.health[i] - shift[i]
                    }
                }),
                sigma: std::array::from_fn(|i| {
                    if p.at_limit[i] {
                        on_line[i].1
                    } else {
                        (sigma_of(p.sigma[i]).powi(2) + (g * h.step_sigma[i]).powi(2)).sqrt()
                    }
                }),
                at_limit: [false; 6],
            }
        })
    }
}

/// `points` with `f` applied to those in `range`, the others as they are.
fn map_within(
    points: &[SeqPoint],
    range: std::ops::Range<usize>,
    f: impl Fn(&SeqPoint) -> SeqPoint,
) -> Vec<SeqPoint> {
    points
        .iter()
        .enumerate()
        .map(|(j, p)| if range.contains(&j) { f(p) } else { *p })
        .collect()
}

/// The instrument signatures of a stored gap report (its `aliases`, as [`super::alias`] wrote
/// them). A report without them (an older version, a baseline that could not be linearised)
/// gives none; an alias without `max_magnitude` (stored before it existed) gets three times its
/// nominal.
pub(crate) fn signatures_from_report(report_json: &str) -> Vec<Signature> {
    #[derive(serde::Deserialize)]
    struct StoredAlias {
        effect: String,
        unit: String,
        nominal: f64,
        max_magnitude: Option<f64>,
        health_shift: crate::health::HealthParams,
    }
    let Ok(v) = serde_json::from_str::<serde_json::Value>(report_json) else {
        return Vec::new();
    };
    let Some(list) = v.pointer("/aliases/aliases").and_then(|a| a.as_array()) else {
        return Vec::new();
    };
    list.iter()
        .filter_map(|a| serde_json::from_value::<StoredAlias>(a.clone()).ok())
        .filter(|a| a.nominal.is_finite() && a.nominal != 0.0)
        .map(|a| Signature {
            max_magnitude: a.max_magnitude.unwrap_or(3.0 * a.nominal.abs()),
            effect: a.effect,
            unit: a.unit,
            nominal: a.nominal,
            shift: a.health_shift.to_array(),
        })
        .collect()
}

fn sigma_of(s: f64) -> f64 {
    if s.is_finite() && s > 0.0 {
        s.max(SIGMA_FLOOR)
    } else {
        SIGMA_FLOOR.max(0.1)
    }
}

/// The first start-up (at least [`MIN_BEFORE`] in) whose health steps away from the trend of
/// those before it; `recovers` as for [`steps_against_trend`] (a compressor recovering is a
/// wash, judged elsewhere).
pub(crate) fn onset(points: &[SeqPoint], recovers: [bool; 6]) -> Option<usize> {
    onset_from(points, 0, recovers)
}

/// [`onset`], looking from start-up `min_k` on.
pub(crate) fn onset_from(points: &[SeqPoint], min_k: usize, recovers: [bool; 6]) -> Option<usize> {
    let as_trend = |p: &SeqPoint| -> [TrendPoint; 6] {
        std::array::from_fn(|i| TrendPoint {
            t_days: p.t_days,
            value: p.health[i],
            sigma: p.sigma[i],
        })
    };
    let trend: Vec<[TrendPoint; 6]> = points.iter().map(as_trend).collect();
    (MIN_BEFORE.max(min_k)..points.len())
        .find(|&k| !steps_against_trend(&trend[..k], &trend[k], recovers).is_empty())
}

/// The first start-up of an instrument's drift in a sequence none of whose start-ups steps
/// away from the trend of those before it ([`onset`] finds none: a slow drift bends the trend
/// it is compared with): the start-up after the last one read right at, for the drift of an
/// instrument in `signatures` that fits better than the trend alone by [`DECISIVE_BIC`] (its
/// rate and its start counted as parameters). `None` when no drift does, or the sequence is
/// too short. Whether it is the instrument's is then for [`attribute_steps`] to weigh, beside
/// the engine's own rate changes.
pub(crate) fn drift_onset(points: &[SeqPoint], signatures: &[Signature]) -> Option<usize> {
    let n = points.len();
    let n_obs = observations(points);
    (MIN_BEFORE - 1..n.saturating_sub(MIN_WINDOW))
        .filter_map(|m| {
            let var = variances(points, m + 1);
            let none = solve(
                points,
                m + 1,
                &var,
                &Spec {
                    cols: &[],
                    until: n,
                    mismatch_sigma: None,
                    breaks: Breaks::default(),
                    ramp_from_days: None,
                },
            )?;
            let none_bic = none.chi2 + none.params as f64 * n_obs.ln();
            signatures
                .iter()
                .filter_map(|s| {
                    instrument_fit(points, m + 1, &var, s, n_obs, n, Breaks::default(), Some(m))
                })
                .map(|h| h.bic + n_obs.ln())
                .filter(|bic| bic + DECISIVE_BIC < none_bic)
                .min_by(f64::total_cmp)
                .map(|bic| (m, bic))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(m, _)| m + 1)
}

/// Most steps attributed in one sequence (since the last firm wash).
pub(crate) const MAX_STEPS: usize = 3;

/// Attributes the steps in `points` one after another, the first from start-up `first` on
/// ([`attribute_at`]), at most [`MAX_STEPS`]. Each next step is looked for, from the start-up
/// after the earlier onset on, in what the earlier steps' best explanations leave
/// ([`SequenceAttribution::explained`]: an outlier, a step the engine took and an
/// instrument's error are each taken out), so that a noisy start-up or a component fault does
/// not hide an instrument's step after it, nor one instrument another. A step followed by
/// another is fitted on the start-ups before the next onset only, so the later step does not
/// bend its fit. `wash_at`: a detected wash from that start-up on, before the first onset, that
/// every hypothesis has beside its own step. `signatures(k)`: the instruments' signatures for a
/// step from start-up `k`. `named[j]`: the instrument start-up `j`'s own gap analysis named, if
/// any (may be shorter than `points`), which decides a step the joint fit leaves `ambiguous`
/// ([`SequenceAttribution::decided_by`]).
pub(crate) fn attribute_steps(
    points: &[SeqPoint],
    first: usize,
    recovers: [bool; 6],
    wash_at: Option<usize>,
    mut signatures: impl FnMut(usize) -> Vec<Signature>,
    named: &[Option<String>],
) -> Vec<SequenceAttribution> {
    let mut out: Vec<SequenceAttribution> = Vec::new();
    let mut work = points.to_vec();
    let mut next = Some(first);
    while let Some(k) = next.filter(|k| out.len() < MAX_STEPS && *k < points.len()) {
        let sigs = signatures(k);
        let mut att = attribute_at(&work, k, &sigs, wash_at);
        let single_bic = att.hypotheses.first().map_or(f64::INFINITY, |h| h.bic);
        next = later_step(&work, k, &sigs, wash_at, single_bic);
        let end = next.unwrap_or(work.len());
        if next.is_some() {
            att = attribute_at(&work[..end], k, &sigs, wash_at);
        }
        att = att.decided_by(&named[..named.len().min(end)], &sigs, &work[..end]);
        work = att.explained(&work);
        // A step the joint fits do not see as such (below the decisive margin) may still leave
        // the trend in what this one leaves.
        next = next.or_else(|| onset_from(&work, k + 1, recovers));
        out.push(att);
    }
    out
}

/// The health each start-up would have without the errors of the instruments `steps` name
/// ([`SequenceAttribution::corrected`] of each, in turn).
pub(crate) fn corrected_by_all(
    steps: &[SequenceAttribution],
    points: &[SeqPoint],
) -> Vec<SeqPoint> {
    steps
        .iter()
        .fold(points.to_vec(), |seen, step| step.corrected(&seen))
}

/// Attributes the first step in `points` (the start-ups since the last wash, oldest first) to
/// the engine or to one of the instruments in `signatures`. `None` when no start-up leaves
/// the trend (or there are too few before it). (`advice` finds the onset first, to pick the
/// stored signatures.)
#[cfg(test)]
pub(crate) fn attribute(
    points: &[SeqPoint],
    signatures: &[Signature],
    recovers: [bool; 6],
) -> Option<SequenceAttribution> {
    let k = onset(points, recovers)?;
    Some(attribute_at(points, k, signatures, None))
}

/// [`attribute`] with the onset given, every hypothesis beside a detected wash from start-up
/// `wash_at` on, when given (before the onset).
fn attribute_at(
    points: &[SeqPoint],
    k: usize,
    signatures: &[Signature],
    wash_at: Option<usize>,
) -> SequenceAttribution {
    let breaks = Breaks {
        later: None,
        wash_at,
    };
    let mut hyps = hypotheses(points, k, signatures, breaks);
    hyps.sort_by(|a, b| a.bic.total_cmp(&b.bic));
    let verdict = verdict_of(&hyps, signatures, points);
    SequenceAttribution {
        onset: k,
        verdict,
        undecided_between: Vec::new(),
        hypotheses: hyps,
    }
}

/// Every explanation of a step from start-up `k` on, fitted (unsorted), each beside the
/// `breaks` (a wash only when it lies before the onset); with a later step, no instrument that
/// ended (its end would be that step) and no drift or change of rate: whether a later step
/// exists is weighed against the steps, and searching each drift's start at each candidate
/// later step made a refresh of 120 start-ups take 5 s instead of a tenth.
fn hypotheses(
    points: &[SeqPoint],
    k: usize,
    signatures: &[Signature],
    breaks: Breaks,
) -> Vec<Hypothesis> {
    let breaks = Breaks {
        wash_at: breaks.wash_at.filter(|&w| w > 0 && w < k),
        ..breaks
    };
    let var = variances(points, k);
    let n_obs = observations(points);
    let unit: Vec<[f64; 6]> = (0..6)
        .map(|i| std::array::from_fn(|j| f64::from(u8::from(i == j))))
        .collect();
    let n = points.len();
    let engine_fit =
        |name: String, cols: &[[f64; 6]], only_onset: bool, drift_from: Option<usize>| {
            let ramp_from_days = drift_from.map(|m| points[m].t_days);
            let spec = Spec {
                cols,
                until: if only_onset { k + 1 } else { n },
                mismatch_sigma: None,
                breaks,
                ramp_from_days,
            };
            let on = drift_from.map_or(k, |m| m + 1);
            solve(points, on, &var, &spec).map(|s| {
                let mut h = hypothesis(name, false, s, cols, n_obs);
                h.drift_from = drift_from;
                h.drift_from_days = ramp_from_days;
                h
            })
        };
    // The engine's health changing its rate from the last start-up before the onset or an
    // earlier one (the best start by χ², one parameter more): a fault that develops, fouling
    // that speeds up. Beside an instrument's drift, what the engine may do the same way.
    // Where a drift or a change of rate may start: the last start-up before it at most the
    // one before the onset, with a trend's worth before it.
    let drift_starts = if breaks.later.is_some() {
        0..0
    } else {
        MIN_BEFORE - 1..k
    };
    let rate_change = |name: String, cols: &[[f64; 6]]| {
        best_searched(
            drift_starts
                .clone()
                .filter_map(|m| engine_fit(name.clone(), cols, false, Some(m))),
            n_obs,
        )
    };
    let mut hyps: Vec<Hypothesis> = Vec::new();
    hyps.extend(engine_fit("none".into(), &[], false, None));
    for (i, name) in HEALTH_NAMES.iter().enumerate() {
        hyps.extend(engine_fit(
            format!("step:{name}"),
            &unit[i..=i],
            false,
            None,
        ));
        hyps.extend(rate_change(format!("rate:{name}"), &unit[i..=i]));
    }
    hyps.extend(engine_fit("step:all".into(), &unit, false, None));
    hyps.extend(rate_change("rate:all".into(), &unit));
    hyps.extend(engine_fit("outlier".into(), &unit, true, None));
    hyps.extend(engine_fit("wash".into(), &unit[..2], false, None));
    // Compressor fouling speeding up or slowing down (a dusty season, a filter change): both
    // compressor parameters, as a wash steps them.
    hyps.extend(rate_change("rate:fouling".into(), &unit[..2]));
    for s in signatures {
        hyps.extend(instrument_fit(points, k, &var, s, n_obs, n, breaks, None));
        // The same instrument drifting from the last start-up it read right at, at most the
        // one before the onset (a slow drift leaves the trend later than it began): the best
        // start (by χ²), counted as one parameter more.
        hyps.extend(best_searched(
            drift_starts
                .clone()
                .filter_map(|m| instrument_fit(points, k, &var, s, n_obs, n, breaks, Some(m))),
            n_obs,
        ));
        if breaks.later.is_some() {
            continue;
        }
        // The same instrument repaired before the newest start-up: the best end (by χ²),
        // counted as one parameter more.
        hyps.extend(best_searched(
            (k + MIN_WINDOW..n)
                .filter_map(|m| instrument_fit(points, k, &var, s, n_obs, m, breaks, None)),
            n_obs,
        ));
    }
    hyps
}

/// The best of one hypothesis fitted at each candidate start-up (a drift's start, an
/// instrument's end): the least χ², with the start-up searched counted as one parameter more.
fn best_searched(fits: impl Iterator<Item = Hypothesis>, n_obs: f64) -> Option<Hypothesis> {
    fits.min_by(|a, b| a.chi2.total_cmp(&b.chi2)).map(|mut h| {
        h.extra_params += 1;
        h.bic += n_obs.ln();
        h
    })
}

/// The names, each once and best first, of the hypotheses after the best that `admit` takes
/// and that come within [`DECISIVE_BIC`] of it: what the data cannot tell from the best.
fn close_to_best(hyps: &[Hypothesis], admit: impl Fn(&Hypothesis) -> bool) -> Vec<String> {
    let Some(best) = hyps.first() else {
        return Vec::new();
    };
    let mut names = vec![best.name.clone()];
    for h in hyps[1..]
        .iter()
        .filter(|h| admit(h) && h.bic - best.bic < DECISIVE_BIC)
    {
        if !names.contains(&h.name) {
            names.push(h.name.clone());
        }
    }
    names
}

/// A second step in what follows a step from start-up `k`: the start-up `m` from which a free
/// step in all six parameters, beside the best explanation of the first, fits the sequence
/// better by [`DECISIVE_BIC`] than any single explanation does (`single_bic`, the best
/// hypothesis's BIC; the second step's start-up counts as one parameter more). Each step
/// keeps at least [`MIN_WINDOW`] start-ups. Without it an instrument that "ended" at `m`, or
/// a step averaged over both, would explain two steps as one: a component fault at start-up 4
/// and a fuel meter reading high from start-up 9 were named a fuel meter reading *low* from 4
/// until 9.
fn later_step(
    points: &[SeqPoint],
    k: usize,
    signatures: &[Signature],
    wash_at: Option<usize>,
    single_bic: f64,
) -> Option<usize> {
    let n = points.len();
    let n_obs = observations(points);
    (k + MIN_WINDOW..=n.saturating_sub(MIN_WINDOW))
        .filter_map(|m| {
            let breaks = Breaks {
                later: Some(m),
                wash_at,
            };
            let best = hypotheses(points, k, signatures, breaks)
                .into_iter()
                .map(|h| h.bic)
                .min_by(f64::total_cmp)?;
            Some((m, best + n_obs.ln()))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .filter(|(_, bic)| *bic + DECISIVE_BIC < single_bic)
        .map(|(m, _)| m)
}

/// Estimates that take part in the joint fit (those not on a search limit): the N of BIC.
fn observations(points: &[SeqPoint]) -> f64 {
    points
        .iter()
        .map(|p| p.at_limit.iter().filter(|c| !**c).count())
        .sum::<usize>() as f64
}

/// An instrument's hypothesis: its signature times the error, from the onset to start-up
/// `until` (exclusive; the sequence's length: to the end), plus a mismatch shared by those
/// start-ups with a prior of
/// [`SIGNATURE_REL_ERROR`] of the step (the signature is a linearisation at one start-up's
/// fit; a 3 % fuel-meter error is not small). Two passes: the error's size first, then the
/// mismatch's prior from it. `None` when the signature is empty, the fit fails or the error
/// is beyond the credible.
#[allow(clippy::too_many_arguments)] // one fit's whole specification, each a different kind
fn instrument_fit(
    points: &[SeqPoint],
    k: usize,
    var: &[[f64; 6]],
    s: &Signature,
    n_obs: f64,
    until: usize,
    breaks: Breaks,
    drift_from: Option<usize>,
) -> Option<Hypothesis> {
    if s.nominal == 0.0 || s.shift.iter().all(|v| *v == 0.0) {
        return None;
    }
    // The column is the shift per unit error, so the coefficient is the error itself.
    let col: [f64; 6] = std::array::from_fn(|i| s.shift[i] / s.nominal);
    let cols = [col];
    let ramp_from_days = drift_from.map(|m| points[m].t_days);
    // A drift moves every start-up after the last it read right at, before the onset too.
    let k = drift_from.map_or(k, |m| m + 1);
    // The newest start-up the error moved, and its share of the column (1 for a step; for a
    // drift the days it has run, by which its rate's prior floor is divided).
    let last_on = until
        .min(breaks.later.unwrap_or(until))
        .min(points.len())
        .max(k + 1)
        - 1;
    let reached = share(ramp_from_days, points[last_on].t_days);
    if reached <= 0.0 {
        return None;
    }
    let first = solve(
        points,
        k,
        var,
        &Spec {
            cols: &cols,
            until,
            mismatch_sigma: None,
            breaks,
            ramp_from_days,
        },
    )?;
    let step_norm = col
        .iter()
        .map(|c| (c * first.coef[0]).powi(2))
        .sum::<f64>()
        .sqrt();
    let prior = (SIGNATURE_REL_ERROR * step_norm * reached / 6f64.sqrt()).max(SIGMA_FLOOR);
    let second = solve(
        points,
        k,
        var,
        &Spec {
            cols: &cols,
            until,
            mismatch_sigma: Some(prior),
            breaks,
            ramp_from_days,
        },
    )?;
    let mut h = hypothesis(s.effect.clone(), true, second, &cols, n_obs);
    h.until = (until < points.len()).then_some(until);
    h.drift_from = drift_from;
    h.drift_from_days = ramp_from_days;
    // A drift's coefficient is its rate: the error it reached at the newest start-up it moved
    // is what must be credible.
    h.magnitude
        .is_some_and(|m| (m * reached).abs() <= s.max_magnitude)
        .then_some(h)
}

/// Relative error of an instrument's linear signature (a 1σ share of the step it predicts):
/// the alias test on the reference engine corrects a 3 % fuel-meter error to within half a
/// point on steps of 3–4 points.
pub(crate) const SIGNATURE_REL_ERROR: f64 = 0.2;

fn hypothesis(
    name: String,
    instrument: bool,
    s: Solved,
    cols: &[[f64; 6]],
    n_obs: f64,
) -> Hypothesis {
    let step: [f64; 6] = std::array::from_fn(|i| {
        cols.iter().zip(&s.coef).map(|(c, x)| c[i] * x).sum::<f64>() + s.mismatch[i]
    });
    Hypothesis {
        name,
        instrument,
        chi2: s.chi2,
        extra_params: cols.len(),
        bic: s.chi2 + s.params as f64 * n_obs.ln(),
        step,
        magnitude: instrument.then(|| s.coef[0]),
        until: None,
        drift_from: None,
        drift_from_days: None,
        magnitude_sigma: instrument.then(|| s.coef_sigma[0]),
        step_sigma: s.step_sigma,
        trend: s.lines,
        trend_cov: s.line_cov,
        t_ref_days: s.t_ref_days,
    }
}

fn verdict_of(
    hyps: &[Hypothesis],
    signatures: &[Signature],
    points: &[SeqPoint],
) -> SequenceVerdict {
    let Some(best) = hyps.first() else {
        return SequenceVerdict::NoStep;
    };
    if best.name == "none" || best.name == "outlier" {
        return SequenceVerdict::NoStep;
    }
    if !best.instrument {
        // An instrument as close as an instrument must beat the engine by: the data cannot
        // tell them apart (a power transducer drifting and the power turbine wearing on look
        // alike), so neither is taken.
        let candidates = close_to_best(hyps, |h| h.instrument);
        if candidates.len() > 1 {
            return SequenceVerdict::Ambiguous { candidates };
        }
        return SequenceVerdict::HealthStep {
            explanation: best.name.clone(),
        };
    }
    // The same instrument ended or not is one candidate (the best of the two is taken).
    let candidates = close_to_best(hyps, |_| true);
    if candidates.len() > 1 {
        return SequenceVerdict::Ambiguous { candidates };
    }
    instrument_verdict(best, signatures, points)
}

/// The verdict naming the instrument of hypothesis `best`, sized as it fitted.
fn instrument_verdict(
    best: &Hypothesis,
    signatures: &[Signature],
    points: &[SeqPoint],
) -> SequenceVerdict {
    let unit = signatures
        .iter()
        .find(|s| s.effect == best.name)
        .map(|s| s.unit.clone())
        .unwrap_or_default();
    let magnitude = best.magnitude.unwrap_or(0.0);
    let magnitude_sigma = best.magnitude_sigma.unwrap_or(0.0);
    let drift = best.drift_from.map(|from| Drift {
        from,
        rate_per_day: magnitude,
        rate_sigma: magnitude_sigma,
    });
    // A drift is stated by the error it reached at the newest start-up it moved.
    let reached = points
        .get(best.until.unwrap_or(points.len()).saturating_sub(1))
        .map_or(1.0, |p| share(best.drift_from_days, p.t_days));
    SequenceVerdict::Instrument {
        effect: best.name.clone(),
        unit,
        magnitude: magnitude * reached,
        magnitude_sigma: magnitude_sigma * reached,
        until: best.until,
        drift,
    }
}

mod fit;
pub(crate) use fit::Breaks;
use fit::{share, solve, variances, Solved, Spec};

#[cfg(test)]
mod tests;
