//! The pure assessment of one start-up segment: given its data (already read), the engine, the
//! settings and a cancel flag, decide whether it is diagnosable and, if so, run Method B on the
//! segment and Method A on its steady windows, keeping each result that fits well enough.
//!
//! [`assess`] is what the daemon's diagnosis worker and `gtwatch diagnose --segment` share:
//! the worker reads a segment, calls it and stores the [`Assessment`]; the command reads through
//! a read-only handle, calls it and prints. Must not read or write the database (or any file),
//! decide what is stored, or know where its input came from.

use super::steady::diagnose_steady;
use super::transient::diagnose_transient;
use super::{DiagnosisConfig, MethodResult};
use crate::engine::Engine;
use crate::optim::Cancel;
use crate::quality::SignalQuality;
use crate::recording::{Recording, RecordingError};
use crate::signals::Signal;
use serde::Serialize;

/// Signals a start-up must have for either method.
pub(crate) const REQUIRED: [Signal; 4] = [Signal::N1, Signal::FuelFlow, Signal::Power, Signal::T1];

/// Fewest samples a segment's recording must have.
const MIN_SAMPLES: usize = 20;

/// Why a segment, or one method on it, gave no result.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Undiagnosable {
    /// `None`: the segment as a whole; `Some("A")`/`Some("B")`: that method.
    pub method: Option<String>,
    /// `aborted`, `gaps`, `missing_signals`, `low_quality`, `bad_recording`, `too_short`,
    /// `residual_too_high` or `error`.
    pub reason: String,
    pub detail: String,
}

impl Undiagnosable {
    fn new(method: Option<&str>, reason: &str, detail: impl Into<String>) -> Undiagnosable {
        Undiagnosable {
            method: method.map(str::to_string),
            reason: reason.into(),
            detail: detail.into(),
        }
    }
}

/// One segment's data as the assessment needs it, borrowed from wherever it was read.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SegmentData<'a> {
    /// How the start-up ended: `completed`, `aborted` or `in_progress`.
    pub(crate) outcome: &'a str,
    /// Why an aborted start-up ended, if known.
    pub(crate) abort_cause: Option<&'a str>,
    /// Whether a data gap lies inside the start-up.
    pub(crate) has_gap: bool,
    /// The segment's good samples on its own time axis (or why they make no recording).
    pub(crate) recording: &'a Result<Recording, RecordingError>,
    /// Signals with no good sample at all in the segment.
    pub(crate) missing: &'a [Signal],
    /// Good and total sample counts per stored signal over the segment.
    pub(crate) quality: &'a [SignalQuality],
}

/// What [`assess`] needs besides the data and the engine.
#[derive(Debug, Clone)]
pub struct AssessSettings {
    /// The fit settings of both methods (its cancel flag is replaced by `assess`'s).
    pub fit: DiagnosisConfig,
    /// Each required signal needs at least this fraction of good samples.
    pub min_good_fraction: f64,
    /// A fit whose residual level is above this gives no result (`residual_too_high`).
    pub max_residual_level: f64,
}

/// One method's accepted result.
#[derive(Debug, Clone)]
pub(crate) struct MethodEstimate {
    /// "B" (transient, the whole segment) or "A" (steady windows).
    pub(crate) method: &'static str,
    /// The objective per signal (mean |residual| in noise σ), at most the settings' maximum.
    pub(crate) residual_level: f64,
    /// The fit itself: health, σ, objective, fit quality, model runs, wall time.
    pub(crate) result: MethodResult,
}

/// What the assessment of one segment found.
#[derive(Debug, Clone)]
pub(crate) enum Assessment {
    /// At least one method gave a result; `failures` holds the reasons of one that did not.
    Diagnosed {
        estimates: Vec<MethodEstimate>,
        failures: Vec<Undiagnosable>,
    },
    /// Nothing diagnosable, and why.
    Undiagnosable(Vec<Undiagnosable>),
    /// The cancel flag was set during the fit: no result, nothing to store.
    Cancelled,
}

/// Residual level of a result: the objective per signal (mean |residual| in noise σ).
pub(crate) fn residual_level(r: &MethodResult) -> f64 {
    r.objective / r.signals.len().max(1) as f64
}

/// Assesses one segment: the data checks first (outcome, gaps, missing signals, data quality,
/// recording), then both methods. Pure but for the methods' wall-time measurement; the same
/// input gives bit-identical estimates.
pub(crate) fn assess(
    data: &SegmentData<'_>,
    engine: &Engine,
    settings: &AssessSettings,
    cancel: &Cancel,
) -> Assessment {
    let recording = match data_check(data, settings.min_good_fraction) {
        Ok(r) => r,
        Err(why) => return Assessment::Undiagnosable(vec![why]),
    };
    let cfg = DiagnosisConfig {
        cancel: cancel.clone(),
        ..settings.fit.clone()
    };
    // Both methods run before either result is looked at (as the worker always did).
    let runs = [
        ("B", diagnose_transient(engine, recording, &cfg)),
        ("A", diagnose_steady(engine, recording, &cfg)),
    ];
    let mut estimates = Vec::new();
    let mut failures = Vec::new();
    for (method, run) in runs {
        if cancel.is_cancelled() {
            return Assessment::Cancelled;
        }
        match accept(method, run, settings.max_residual_level) {
            Ok(e) => estimates.push(e),
            Err(why) => failures.push(why),
        }
    }
    if estimates.is_empty() {
        Assessment::Undiagnosable(failures)
    } else {
        Assessment::Diagnosed {
            estimates,
            failures,
        }
    }
}

/// The segment's recording when its data may be diagnosed, else the one reason why not.
fn data_check<'a>(
    data: &SegmentData<'a>,
    min_good_fraction: f64,
) -> Result<&'a Recording, Undiagnosable> {
    if data.outcome != "completed" {
        return Err(Undiagnosable::new(
            None,
            "aborted",
            format!(
                "start-up {} ({})",
                data.outcome,
                data.abort_cause.unwrap_or("no cause")
            ),
        ));
    }
    if data.has_gap {
        return Err(Undiagnosable::new(
            None,
            "gaps",
            "data gap inside the start-up",
        ));
    }
    let missing: Vec<&str> = data
        .missing
        .iter()
        .filter(|s| REQUIRED.contains(s))
        .map(|s| s.column())
        .collect();
    if !missing.is_empty() {
        return Err(Undiagnosable::new(
            None,
            "missing_signals",
            format!("no good samples of {}", missing.join(", ")),
        ));
    }
    let counts: Vec<(Signal, u64, u64)> = data
        .quality
        .iter()
        .filter(|q| REQUIRED.contains(&q.signal))
        .map(|q| (q.signal, q.good, q.total))
        .collect();
    if let Some(why) = crate::quality::insufficient_quality(&counts, min_good_fraction) {
        return Err(Undiagnosable::new(None, "low_quality", why));
    }
    match data.recording {
        Err(e) => Err(Undiagnosable::new(None, "bad_recording", e.to_string())),
        Ok(r) if r.len() < MIN_SAMPLES => Err(Undiagnosable::new(
            None,
            "too_short",
            format!("{} samples", r.len()),
        )),
        Ok(r) => Ok(r),
    }
}

/// One method's run as an accepted estimate, or the reason it is not one.
fn accept(
    method: &'static str,
    run: Result<MethodResult, super::DiagnosisError>,
    max_residual_level: f64,
) -> Result<MethodEstimate, Undiagnosable> {
    let result = run.map_err(|e| Undiagnosable::new(Some(method), "error", e.to_string()))?;
    let level = residual_level(&result);
    if level.is_nan() || level > max_residual_level {
        return Err(Undiagnosable::new(
            Some(method),
            "residual_too_high",
            format!("residual level {level:.2} σ > {max_residual_level:.2} σ"),
        ));
    }
    Ok(MethodEstimate {
        method,
        residual_level: level,
        result,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> AssessSettings {
        AssessSettings {
            fit: DiagnosisConfig::default(),
            min_good_fraction: 0.9,
            max_residual_level: 5.0,
        }
    }

    fn good_counts() -> Vec<SignalQuality> {
        REQUIRED
            .iter()
            .map(|s| SignalQuality {
                signal: *s,
                good: 100,
                total: 100,
            })
            .collect()
    }

    /// The data checks decide without running a model, in order, and say why.
    #[test]
    fn data_checks_give_the_first_reason_without_a_fit() {
        let engine = Engine::reference().expect("engine");
        let too_few: Result<Recording, RecordingError> = Recording::new(
            vec![0.0],
            vec![crate::signals::Phase::Standstill],
            vec![[f64::NAN; crate::engine::trace::NSIG]],
        );
        assert!(too_few.is_err());
        let counts = good_counts();
        let base = SegmentData {
            outcome: "completed",
            abort_cause: None,
            has_gap: false,
            recording: &too_few,
            missing: &[],
            quality: &counts,
        };
        let mut low = good_counts();
        low[1].good = 50;
        let cases: Vec<(SegmentData<'_>, &str)> = vec![
            (
                SegmentData {
                    outcome: "aborted",
                    abort_cause: Some("trip"),
                    has_gap: true,
                    ..base
                },
                "aborted",
            ),
            (
                SegmentData {
                    has_gap: true,
                    ..base
                },
                "gaps",
            ),
            (
                SegmentData {
                    missing: &[Signal::Power],
                    ..base
                },
                "missing_signals",
            ),
            (
                SegmentData {
                    quality: &low,
                    ..base
                },
                "low_quality",
            ),
            (base, "bad_recording"),
        ];
        for (data, reason) in cases {
            match assess(&data, &engine, &settings(), &Cancel::new()) {
                Assessment::Undiagnosable(why) => {
                    assert_eq!(why.len(), 1, "{why:?}");
                    assert_eq!(why[0].reason, reason, "{why:?}");
                    assert_eq!(why[0].method, None);
                }
                other => panic!("{reason}: {other:?}"),
            }
        }
    }
}
