//! The steps in the health since the last firm wash, and what explains each: the joint fits
//! of the start-ups (`gap::sequence`) run on the stored results, the lines `wash advise` and
//! the stored advice say them in, the detected washes an instrument's step explains, and the
//! corrected health of the start-ups an instrument's error moved (stored so `history` shows
//! it). Must not fit engine models or write to the store (the refresh writes what it returns).

use super::seq_point;
use crate::engine::effects::is_instrument;
use crate::gap::sequence::{self, SeqPoint, SequenceAttribution, SequenceVerdict};
use crate::health::HealthBounds;
use crate::store::{
    CorrectionsWrite, HistoryRow, InstrumentCorrection, Store, StoreError, WashRow,
};
use serde::Serialize;

/// A step in the health since the last wash, attributed by a joint fit of the start-ups
/// ([`sequence`]): when it names an instrument, the trends see the health of the onset and
/// later start-ups (to the one before it read right again, when it was repaired) corrected by
/// that instrument's error.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct StepAttribution {
    /// The first start-up of this step.
    pub(crate) onset_segment_id: i64,
    pub(crate) onset_ms: i64,
    /// Start-ups fitted jointly (since the last wash, a detected one before the onset
    /// included) and how many from the onset on.
    pub(crate) start_ups: usize,
    pub(crate) from_onset: usize,
    /// The start-up whose stored gap analysis gave the instruments' signatures (none: only
    /// the engine's explanations were weighed).
    pub(crate) signatures_from_segment: Option<i64>,
    /// Whether the trends use the corrected health.
    pub(crate) corrected: bool,
    /// When the named instrument's error ended (a repair, a recalibration): the first
    /// start-up that read right again.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) until_segment_id: Option<i64>,
    /// When the named instrument drifts: the last start-up it read right at.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) drift_from_segment_id: Option<i64>,
    pub(crate) attribution: SequenceAttribution,
}

/// One line saying what the joint fit of the start-ups since the last wash made of the first
/// step in their health.
pub(crate) fn step_line(step: &StepAttribution) -> String {
    use crate::gap::sequence::SequenceVerdict as V;
    let head = format!(
        "step from start-up {} at {} ({} of {} start-ups since the wash from it on): ",
        step.onset_segment_id,
        crate::time::fmt_ms_rfc3339(step.onset_ms),
        step.from_onset,
        step.start_ups
    );
    // A step the joint fit left open between an instrument and the engine, decided by what the
    // stepped start-ups' own gap analyses named.
    let decided = if step.attribution.undecided_between.is_empty() {
        String::new()
    } else {
        format!(
            " (the joint fit alone could not tell it from {}; the stepped start-ups' own gap \
             analyses named it)",
            step.attribution.undecided_between.join(", ")
        )
    };
    let tail = match &step.attribution.verdict {
        V::NoStep => "not persistent (the start-ups after it are back on the trend)".to_string(),
        V::Instrument {
            effect,
            unit,
            magnitude,
            magnitude_sigma,
            drift,
            ..
        } => {
            let (m, s, u) = if unit == "fraction" {
                (magnitude * 100.0, magnitude_sigma * 100.0, "%")
            } else {
                (*magnitude, *magnitude_sigma, unit.as_str())
            };
            if let (Some(d), Some(from)) = (drift, step.drift_from_segment_id) {
                let per = if unit == "fraction" { 100.0 } else { 1.0 };
                return head
                    + &format!(
                        "the instrument {effect} drifts since start-up {from}, the last it read \
                         right at: {:+.3} ± {:.3} {u} a day, {m:+.2} ± {s:.2} {u} at the newest; \
                         the trends use the health corrected for it",
                        d.rate_per_day * per,
                        d.rate_sigma * per
                    )
                    + &decided;
            }
            match step.until_segment_id {
                Some(back) => format!(
                    "the instrument {effect} was off by {m:+.2} ± {s:.2} {u} until start-up {back}, \
                     which reads right again (repaired or recalibrated); the trends use the health \
                     corrected for it"
                ),
                None => format!(
                    "the instrument {effect} is off by {m:+.2} ± {s:.2} {u}; the trends use the health corrected for it"
                ),
            }
        }
        V::Ambiguous { candidates } => format!(
            "ambiguous between {} (health used as measured)",
            candidates.join(", ")
        ),
        V::HealthStep { explanation } => format!(
            "the engine's ({explanation}){}",
            if step.signatures_from_segment.is_none() {
                "; no stored gap analysis gave the instruments' signatures"
            } else {
                ""
            }
        ),
    };
    head + &tail + &decided
}

/// The detected (unconfirmed) washes that lie just before the onset of a step the sequence
/// attributes to an instrument, or just before the start-up it read right again from: the
/// recovery they saw was the instrument's.
pub(super) fn explained_washes(
    washes: &[WashRow],
    rows: &[HistoryRow],
    basis_from: usize,
    steps: &[StepAttribution],
) -> Vec<i64> {
    let just_before = |k: usize| {
        let before = k.checked_sub(1).map_or(i64::MIN, |i| rows[i].start_ms);
        (before, rows[k].start_ms)
    };
    let mut edges = Vec::new();
    for step in steps.iter().filter(|s| s.corrected) {
        edges.push(just_before(basis_from + step.attribution.onset));
        let range = step.attribution.corrected_range(rows.len() - basis_from);
        if range.end < rows.len() - basis_from {
            edges.push(just_before(basis_from + range.end));
        }
    }
    washes
        .iter()
        .filter(|w| {
            w.is_detected()
                && edges
                    .iter()
                    .any(|(before, at)| w.t_ms > *before && w.t_ms <= *at)
        })
        .map(|w| w.id)
        .collect()
}

/// The instruments' signatures for a step from the first of `from_onset` on: those of the newest
/// stored gap analysis of one of them that has any, and its start-up.
fn newest_signatures(
    store: &Store,
    from_onset: &[HistoryRow],
) -> Result<(Vec<sequence::Signature>, Option<i64>), StoreError> {
    for r in from_onset.iter().rev() {
        if let Some(json) = store.newest_gap_report_json(r.segment_id)? {
            let signatures = sequence::signatures_from_report(&json);
            if !signatures.is_empty() {
                return Ok((signatures, Some(r.segment_id)));
            }
        }
    }
    Ok((Vec::new(), None))
}

/// Attributes the steps in the results since the last firm wash ([`sequence::attribute_steps`];
/// from a detected wash before the first onset on, when one lies there: see the body), each
/// with the instruments' signatures from the newest stored gap analysis of a start-up from its
/// onset on (the daemon analyses every start-up that steps against its trend), else of any
/// since the wash; when no start-up steps, the drift of an instrument
/// ([`sequence::drift_onset`]) is looked for. Returns the
/// steps, oldest first, and each result's health and σ as the trends should see them: corrected
/// for every instrument a step names, else as stored.
pub(super) fn attribute_since(
    store: &Store,
    since: &[HistoryRow],
    washes: &[WashRow],
    bounds: &HealthBounds,
) -> Result<(Vec<StepAttribution>, Vec<SeqPoint>), StoreError> {
    let points: Vec<SeqPoint> = since.iter().map(|r| seq_point(r, bounds)).collect();
    // A wash recovers the compressor: its improvement is not a step.
    let recovers = crate::trend::RECOVERED_BY_WASH;
    // No start-up steps away from the trend: an instrument may still drift (each start-up a
    // little further off than the last bends the trend it is compared with), looked for with
    // the signatures of the newest stored gap analysis since the wash.
    let k = match sequence::onset(&points, recovers) {
        Some(k) => k,
        None => {
            let (signatures, _) = newest_signatures(store, since)?;
            match sequence::drift_onset(&points, &signatures) {
                Some(k) => k,
                None => return Ok((Vec::new(), points)),
            }
        }
    };
    // The trend lines are straight between washes: a wash the trend detected (not yet
    // confirmed) before the onset restarts them, when enough start-ups lie between for a trend;
    // closer, every hypothesis gets the wash's step in both compressor parameters beside its
    // own. Not one just before the onset: that recovery may be the step itself (a fuel meter
    // reading high looks like a cleaner compressor), which is what is being attributed.
    let wash = washes
        .iter()
        .filter(|w| w.is_detected())
        .filter_map(|w| since.iter().position(|r| r.start_ms > w.t_ms))
        .filter(|&j| j > 0 && j < k)
        .max();
    // (Restarted with fewer than that between, the onset found after the wash was a later
    // start-up than the step's own.)
    let (from, k, wash_at) = match wash {
        Some(j) if k - j >= sequence::MIN_BEFORE => match sequence::onset(&points[j..], recovers) {
            Some(kk) => (j, j + kk, None),
            None => (0, k, Some(j)),
        },
        Some(j) => (0, k, Some(j)),
        None => (0, k, None),
    };
    let mut failed: Option<StoreError> = None;
    let mut sources: Vec<Option<i64>> = Vec::new();
    // What each start-up's own gap analysis named: it decides a step the joint fit cannot.
    let named: Vec<Option<String>> = since[from..]
        .iter()
        .map(|r| r.gap_verdict.clone().filter(|v| is_instrument(v)))
        .collect();
    let attributions = sequence::attribute_steps(
        &points[from..],
        k - from,
        recovers,
        wash_at,
        |kk| {
            // Those of a start-up from the onset on, else of any since the wash (a
            // linearisation at a start-up before the step serves as well: the signature is how
            // the health answers an instrument's error, not the error itself).
            let found = newest_signatures(store, &since[from + kk..]).and_then(|got| match got {
                (sigs, Some(src)) => Ok((sigs, Some(src))),
                _ => newest_signatures(store, &since[from..]),
            });
            match found {
                Ok((signatures, source)) => {
                    sources.push(source);
                    signatures
                }
                Err(e) => {
                    sources.push(None);
                    failed.get_or_insert(e);
                    Vec::new()
                }
            }
        },
        &named,
    );
    if let Some(e) = failed {
        return Err(e);
    }
    let attributions: Vec<SequenceAttribution> =
        attributions.into_iter().map(|a| a.shifted(from)).collect();
    let seen = sequence::corrected_by_all(&attributions, &points);
    let steps = attributions
        .into_iter()
        .zip(sources)
        .map(|(attribution, signatures_from_segment)| {
            let onset = attribution.onset;
            StepAttribution {
                onset_segment_id: since[onset].segment_id,
                onset_ms: since[onset].start_ms,
                start_ups: since.len() - from,
                from_onset: since.len() - onset,
                signatures_from_segment,
                corrected: matches!(attribution.verdict, SequenceVerdict::Instrument { .. }),
                until_segment_id: attribution
                    .verdict
                    .until()
                    .and_then(|m| since.get(m).map(|r| r.segment_id)),
                drift_from_segment_id: attribution
                    .verdict
                    .drift()
                    .and_then(|d| since.get(d.from).map(|r| r.segment_id)),
                attribution,
            }
        })
        .collect();
    Ok((steps, seen))
}

/// What the store should hold of the corrected health of `since` (the start-ups the joint fit
/// saw, `seen` their health as the trends see it) after this refresh: `None` when `stored`
/// already says it, so a refresh that changes nothing writes nothing. A start-up two named
/// instruments moved is corrected for both; its row names the newer step's instrument and, in
/// `also`, the older.
pub(super) fn corrections_write(
    since: &[HistoryRow],
    seen: &[SeqPoint],
    steps: &[StepAttribution],
    stored: &[InstrumentCorrection],
) -> Option<CorrectionsWrite> {
    let refreshed_ms = since.last()?.start_ms;
    let fitted: Vec<i64> = since.iter().map(|r| r.segment_id).collect();
    let mut rows: Vec<InstrumentCorrection> = Vec::new();
    for (j, (r, p)) in since.iter().zip(seen).enumerate() {
        // The named instruments whose error moved this start-up, oldest step first.
        let moved: Vec<InstrumentCorrection> = steps
            .iter()
            .filter_map(|s| match &s.attribution.verdict {
                SequenceVerdict::Instrument {
                    effect,
                    unit,
                    magnitude,
                    magnitude_sigma,
                    drift,
                    ..
                } if s.corrected && s.attribution.corrected_range(since.len()).contains(&j) => {
                    // A drifting instrument was off at this start-up by what it had drifted
                    // since the last start-up it read right at.
                    let (magnitude, magnitude_sigma) = match drift {
                        Some(d) => {
                            let days = (p.t_days - seen[d.from].t_days).max(0.0);
                            (d.rate_per_day * days, d.rate_sigma * days)
                        }
                        None => (*magnitude, *magnitude_sigma),
                    };
                    Some(InstrumentCorrection {
                        segment_id: r.segment_id,
                        onset_segment_id: s.onset_segment_id,
                        effect: effect.clone(),
                        unit: unit.clone(),
                        magnitude,
                        magnitude_sigma,
                        health: p.health,
                        sigma: p.sigma,
                        also: String::new(),
                    })
                }
                _ => None,
            })
            .collect();
        if let Some((newest, older)) = moved.split_last() {
            let also: Vec<String> = older
                .iter()
                .map(|c| format!("{} from start-up {}", c.describe(), c.onset_segment_id))
                .collect();
            rows.push(InstrumentCorrection {
                also: also.join("; "),
                ..newest.clone()
            });
        }
    }
    let now: Vec<&InstrumentCorrection> = stored
        .iter()
        .filter(|c| fitted.contains(&c.segment_id))
        .collect();
    (now.len() != rows.len() || now.iter().zip(&rows).any(|(a, b)| *a != b)).then_some(
        CorrectionsWrite {
            fitted_segments: fitted,
            rows,
            refreshed_ms,
        },
    )
}
