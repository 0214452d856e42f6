//! One bad-value policy for every input path (Modbus acquisition, CSV replay, diagnose input).
//!
//! A value is classified, never dropped: the caller stores it with the [`Quality`] returned
//! here, and only `Good` samples feed detection and diagnosis. The rules, in order:
//!
//! 1. **Bad** (code 2): NaN or ±inf (stored as 0.0: SQLite cannot hold NaN).
//! 2. **OutOfRange** (code 1): outside the signal's physical range ([`default_limits`], or a
//!    `[quality.limits.<tag>]` override).
//! 3. **Stuck** (code 3): the value has been bit-identical for longer than
//!    `quality.stuck_after_s` while the engine moved (the row's gas-generator speed n1 differs
//!    by more than `quality.stuck_reference_rpm` from its value when the freeze began). Values
//!    at the bottom of the range (within 1 % of the span: speed, fuel, power at zero) are
//!    exempt, as are signals that legitimately hold still while the engine moves (n1 itself,
//!    which is the reference, n2 held synchronous, T1, P1, P4, surge margin).
//! 4. **Spike** (code 4): an isolated jump — a sample further from both neighbours than the
//!    signal's rate limit allows while the neighbours agree with each other. It needs the next
//!    sample, so a [`SpikeFilter`] delays its output by one sample.
//!
//! Time stamps out of order are not a per-value code: the replay counts those rows and does not
//! store them (a sample keyed at a wrong time would overwrite or shadow a real one).
//! The codes themselves ([`Quality`], stored as `samples.quality`) are defined here, beside the
//! rules that assign them, so the diagnosis's CSV input, replay, acquisition and the store all
//! take them from this ground-floor room (see README.md, "Architecture").
//! Pure: no I/O, no clock, no globals; must not know about the store, the CSV reader or Modbus.

use crate::config_problem::ConfigProblem;
use crate::signals::Signal;
use serde::Deserialize;
use std::collections::BTreeMap;

/// Sample quality, stored as INTEGER (`samples.quality`). Only `Good` (0) samples feed
/// detection and diagnosis; every other code is stored flagged and counted. Codes 0–2 are
/// those of schema 1 (unchanged); 3 and 4 came with schema 3. Defined here, beside the policy that assigns it, so every floor that reads or
/// writes samples (diagnosis CSV input, replay, acquisition, the store) can name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[repr(u8)]
pub enum Quality {
    #[default]
    Good = 0,
    /// Outside the signal's physical range (or the register map's range).
    OutOfRange = 1,
    /// Not a number: NaN, ±inf, or registers that do not decode (value stored as 0).
    Bad = 2,
    /// Stuck sensor: bit-identical value for longer than `quality.stuck_after_s` while the
    /// engine moved.
    Stuck = 3,
    /// Isolated spike: a jump beyond the signal's rate limit from the last good value.
    Spike = 4,
}

impl Quality {
    pub fn from_code(code: i64) -> Option<Quality> {
        match code {
            0 => Some(Quality::Good),
            1 => Some(Quality::OutOfRange),
            2 => Some(Quality::Bad),
            3 => Some(Quality::Stuck),
            4 => Some(Quality::Spike),
            _ => None,
        }
    }
    /// Stable lower-case name (`good`, `out_of_range`, `bad`, `stuck`, `spike`).
    pub fn name(self) -> &'static str {
        match self {
            Quality::Good => "good",
            Quality::OutOfRange => "out_of_range",
            Quality::Bad => "bad",
            Quality::Stuck => "stuck",
            Quality::Spike => "spike",
        }
    }
    pub fn code(self) -> u8 {
        self as u8
    }
}

/// Physical limits of one signal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignalLimits {
    /// Lowest plausible value (engineering units of the signal).
    pub lo: f64,
    /// Highest plausible value.
    pub hi: f64,
    /// Largest plausible rate of change, units per second (spike rule).
    pub max_rate_per_s: f64,
}

/// Default limits of every engine signal: what the class of machine (industrial two-shaft
/// units up to ~100 MW) can physically show, not one engine's envelope. The shaft speeds span
/// the class (gas generators to 25 000 rpm, power turbines to 20 000 rpm): a 4 500 rpm PT limit,
/// right for a 3 600 rpm generator, flagged every PT reading of a 6 100 rpm unit as out of range
/// and so took it from the detector and the diagnosis. A unit's own tighter range is a
/// `[quality.limits.<tag>]` override.
pub fn default_limits(signal: Signal) -> SignalLimits {
    let l = |lo: f64, hi: f64, max_rate_per_s: f64| SignalLimits {
        lo,
        hi,
        max_rate_per_s,
    };
    match signal {
        Signal::N1 => l(-100.0, 25_000.0, 2_000.0),
        Signal::N2 => l(-100.0, 20_000.0, 1_500.0),
        Signal::T1 => l(200.0, 340.0, 10.0),
        Signal::P1 => l(50.0, 120.0, 20.0),
        Signal::T2 => l(200.0, 1_000.0, 300.0),
        Signal::P2 => l(50.0, 4_000.0, 1_500.0),
        Signal::T3 => l(200.0, 2_200.0, 600.0),
        Signal::P3 => l(50.0, 4_000.0, 1_500.0),
        Signal::T34 => l(200.0, 1_600.0, 500.0),
        Signal::P34 => l(50.0, 1_500.0, 600.0),
        Signal::T4 => l(200.0, 1_200.0, 400.0),
        Signal::P4 => l(50.0, 200.0, 50.0),
        Signal::FuelFlow => l(-0.05, 6.0, 3.0),
        Signal::Power => l(-5.0, 100.0, 60.0),
        Signal::SurgeMargin => l(-50.0, 100.0, 100.0),
        Signal::Torque => l(-20.0, 500.0, 300.0),
        Signal::InletDepression => l(-1.0, 10.0, 5.0),
    }
}

/// Signals exempt from the stuck rule (they legitimately hold still while the engine moves).
fn stuck_exempt(signal: Signal) -> bool {
    matches!(
        signal,
        Signal::N1 | Signal::N2 | Signal::T1 | Signal::P1 | Signal::P4 | Signal::SurgeMargin
    )
}

/// A per-tag override of the limits; absent keys keep the default.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct LimitOverride {
    pub lo: Option<f64>,
    pub hi: Option<f64>,
    pub max_rate_per_s: Option<f64>,
}

/// `[quality]` section.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct QualityConfig {
    /// A value bit-identical for longer than this (s) while the engine moves is stuck.
    /// 0 = rule off. Default 120.
    pub stuck_after_s: f64,
    /// "The engine moves": n1 changed by more than this (rpm) since the freeze began.
    /// Default 500.
    pub stuck_reference_rpm: f64,
    /// Tag (or replay column / signal) name → limit overrides, e.g.
    /// `[quality.limits.power_mw] hi = 45.0`.
    pub limits: BTreeMap<String, LimitOverride>,
}

impl Default for QualityConfig {
    fn default() -> Self {
        QualityConfig {
            stuck_after_s: 120.0,
            stuck_reference_rpm: 500.0,
            limits: BTreeMap::new(),
        }
    }
}

impl QualityConfig {
    /// Problems with this section; keys are prefixed `quality.`.
    pub fn validate(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        if !self.stuck_after_s.is_finite() || !(0.0..=86_400.0).contains(&self.stuck_after_s) {
            p.push(ConfigProblem::new(
                "quality.stuck_after_s",
                "must be between 0 (off) and 86400 s",
            ));
        }
        if !self.stuck_reference_rpm.is_finite() || self.stuck_reference_rpm <= 0.0 {
            p.push(ConfigProblem::new(
                "quality.stuck_reference_rpm",
                "must be a positive number of rpm",
            ));
        }
        for (name, o) in &self.limits {
            let key = |k: &str| format!("quality.limits.{name}.{k}");
            for (k, v) in [
                ("lo", o.lo),
                ("hi", o.hi),
                ("max_rate_per_s", o.max_rate_per_s),
            ] {
                if let Some(v) = v {
                    if !v.is_finite() {
                        p.push(ConfigProblem::new(key(k), "must be a finite number"));
                    }
                }
            }
            if let Some(r) = o.max_rate_per_s {
                if r <= 0.0 {
                    p.push(ConfigProblem::new(
                        key("max_rate_per_s"),
                        "must be positive",
                    ));
                }
            }
            if let (Some(lo), Some(hi)) = (o.lo, o.hi) {
                if lo >= hi {
                    p.push(ConfigProblem::new(
                        key("hi"),
                        format!("must be above lo ({lo})"),
                    ));
                }
            }
            if o.lo.is_none() && o.hi.is_none() && o.max_rate_per_s.is_none() {
                p.push(ConfigProblem::new(
                    format!("quality.limits.{name}"),
                    "sets nothing (expected lo, hi or max_rate_per_s)",
                ));
            }
        }
        p
    }

    /// The limits for a tag: the signal's defaults with the override of the first of `names`
    /// that has one. `None` when the tag is not an engine signal and has no full override
    /// (`lo` and `hi`): such tags are only checked for NaN/inf.
    pub fn limits_for(&self, names: &[&str], signal: Option<Signal>) -> Option<SignalLimits> {
        let o = names.iter().find_map(|n| self.limits.get(*n)).copied();
        let base = signal.map(default_limits);
        match (base, o) {
            (Some(b), None) => Some(b),
            (Some(b), Some(o)) => Some(SignalLimits {
                lo: o.lo.unwrap_or(b.lo),
                hi: o.hi.unwrap_or(b.hi),
                max_rate_per_s: o.max_rate_per_s.unwrap_or(b.max_rate_per_s),
            }),
            (
                None,
                Some(LimitOverride {
                    lo: Some(lo),
                    hi: Some(hi),
                    max_rate_per_s,
                }),
            ) => Some(SignalLimits {
                lo,
                hi,
                max_rate_per_s: max_rate_per_s.unwrap_or(f64::INFINITY),
            }),
            (None, _) => None,
        }
    }

    /// A checker for one tag.
    pub fn checker(&self, names: &[&str], signal: Option<Signal>) -> ValueChecker {
        ValueChecker {
            limits: self.limits_for(names, signal),
            stuck_after_ms: if signal.is_some_and(|s| !stuck_exempt(s)) {
                (self.stuck_after_s * 1000.0).round() as i64
            } else {
                0
            },
            stuck_reference_rpm: self.stuck_reference_rpm,
            freeze: None,
        }
    }
}

/// The classification of a single value (rules 1–2), before the stateful rules.
pub fn classify_value(v: f64, limits: Option<&SignalLimits>) -> Quality {
    if !v.is_finite() {
        return Quality::Bad;
    }
    match limits {
        Some(l) if v < l.lo || v > l.hi => Quality::OutOfRange,
        _ => Quality::Good,
    }
}

/// Where a run of identical values began.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Freeze {
    since_ms: i64,
    value: f64,
    reference: Option<f64>,
}

/// Rules 1–3 for one tag, fed in time order.
#[derive(Debug, Clone, PartialEq)]
pub struct ValueChecker {
    limits: Option<SignalLimits>,
    stuck_after_ms: i64,
    stuck_reference_rpm: f64,
    freeze: Option<Freeze>,
}

impl ValueChecker {
    /// The limits in force (for the spike rule).
    pub fn limits(&self) -> Option<SignalLimits> {
        self.limits
    }

    /// Classifies `v` at `t_ms`; `n1_rpm` is the engine's gas-generator speed at the same time
    /// if known and good (the stuck rule's reference).
    pub fn check(&mut self, t_ms: i64, v: f64, n1_rpm: Option<f64>) -> Quality {
        let q = classify_value(v, self.limits.as_ref());
        if q != Quality::Good {
            self.freeze = None;
            return q;
        }
        if self.stuck_after_ms <= 0 {
            return Quality::Good;
        }
        let at_bottom = self
            .limits
            .is_some_and(|l| v <= l.lo.max(0.0) + 0.01 * (l.hi - l.lo));
        match self.freeze {
            Some(f) if f.value.to_bits() == v.to_bits() && !at_bottom => {
                let f = Freeze {
                    reference: f.reference.or(n1_rpm),
                    ..f
                };
                self.freeze = Some(f);
                let moved = match (f.reference, n1_rpm) {
                    (Some(a), Some(b)) => (a - b).abs() > self.stuck_reference_rpm,
                    _ => false,
                };
                if t_ms - f.since_ms > self.stuck_after_ms && moved {
                    Quality::Stuck
                } else {
                    Quality::Good
                }
            }
            _ => {
                self.freeze = Some(Freeze {
                    since_ms: t_ms,
                    value: v,
                    reference: n1_rpm,
                });
                Quality::Good
            }
        }
    }
}

/// A sample as the spike filter sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    pub t_ms: i64,
    pub value: f64,
    pub quality: Quality,
}

/// Rule 4 for one tag: holds one sample back; [`SpikeFilter::push`] returns the previous
/// sample with its final quality. Call [`SpikeFilter::finish`] at the end of the stream.
#[derive(Debug, Clone, PartialEq)]
pub struct SpikeFilter {
    max_rate_per_s: f64,
    /// Last good sample before `held`.
    before: Option<Point>,
    held: Option<Point>,
}

impl SpikeFilter {
    pub fn new(limits: Option<SignalLimits>) -> SpikeFilter {
        SpikeFilter {
            max_rate_per_s: limits.map_or(f64::INFINITY, |l| l.max_rate_per_s),
            before: None,
            held: None,
        }
    }

    fn too_fast(&self, a: &Point, b: &Point) -> bool {
        let dt_s = ((b.t_ms - a.t_ms).abs() as f64 / 1000.0).max(1e-3);
        (b.value - a.value).abs() > self.max_rate_per_s * dt_s
    }

    /// Feeds the next sample; returns the one held back (if any) with its final quality.
    pub fn push(&mut self, next: Point) -> Option<Point> {
        let out = match (self.before, self.held) {
            (Some(a), Some(mut b))
                if b.quality == Quality::Good && next.quality == Quality::Good =>
            {
                if self.too_fast(&a, &b) && self.too_fast(&b, &next) && !self.too_fast(&a, &next) {
                    b.quality = Quality::Spike;
                }
                Some(b)
            }
            (_, h) => h,
        };
        if let Some(o) = out {
            if o.quality == Quality::Good {
                self.before = Some(o);
            }
        }
        self.held = Some(next);
        out
    }

    /// The last held sample (its successor is unknown, so it is never a spike).
    pub fn finish(&mut self) -> Option<Point> {
        self.held.take()
    }
}

/// Counts of values per quality (replay summary, daemon statistics).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct QualityCounts {
    pub good: u64,
    pub out_of_range: u64,
    pub bad: u64,
    pub stuck: u64,
    pub spike: u64,
}

impl QualityCounts {
    pub fn add(&mut self, q: Quality) {
        match q {
            Quality::Good => self.good += 1,
            Quality::OutOfRange => self.out_of_range += 1,
            Quality::Bad => self.bad += 1,
            Quality::Stuck => self.stuck += 1,
            Quality::Spike => self.spike += 1,
        }
    }
    /// All flagged (not good) values.
    pub fn flagged(&self) -> u64 {
        self.out_of_range + self.bad + self.stuck + self.spike
    }
}

/// How many of a signal's samples in a segment are good (quality 0) of all it has there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SignalQuality {
    pub signal: Signal,
    pub good: u64,
    pub total: u64,
}

/// Whether a segment's data is good enough to diagnose: for each required signal, the
/// fraction of good samples among all its samples in the segment must reach `min_fraction`.
/// Returns the first failing signal's description, or `None` when the data is good enough.
pub fn insufficient_quality(counts: &[(Signal, u64, u64)], min_fraction: f64) -> Option<String> {
    for &(signal, good, total) in counts {
        let frac = if total == 0 {
            0.0
        } else {
            good as f64 / total as f64
        };
        if frac < min_fraction {
            return Some(format!(
                "data quality too low: {} has {good} good of {total} samples ({:.0} % < {:.0} %)",
                signal.column(),
                100.0 * frac,
                100.0 * min_fraction
            ));
        }
    }
    None
}

#[cfg(test)]
mod tests;
