//! Diagnosis results in the store: the worker's queue (closed start-ups without a result),
//! the store → recording adapter (a segment's good samples on its own time axis, with the
//! detector's phases), writing results and undiagnosable reasons, and the history query.
//!
//! Each write is one transaction that also marks the segment `diagnosed`, so a killed process
//! leaves either the whole result or nothing. Must not fit models or decide what is diagnosable.

use super::corrections::{self, InstrumentCorrection};
use super::{Store, StoreError};
/// The types the assessment shares with the store live on the floor below it.
pub use crate::diagnosis::assess::Undiagnosable;
use crate::engine::trace::{Values, NSIG};
use crate::health::HEALTH_NAMES;
pub use crate::quality::SignalQuality;
use crate::recording::{Recording, RecordingError};
use crate::signals::{Phase, Signal};
use rusqlite::{params, OptionalExtension};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};

/// A closed start-up segment.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SegmentInfo {
    pub id: i64,
    pub start_ms: i64,
    pub end_ms: Option<i64>,
    /// `completed`, `aborted` or `in_progress`.
    pub outcome: String,
    pub abort_cause: Option<String>,
    pub status: String,
    pub has_gap: bool,
}

/// A stored segment's samples as the diagnosis reads them.
#[derive(Debug, Clone)]
pub struct SegmentRecording {
    pub segment: SegmentInfo,
    /// Time axis in s from the first sample (the data's own sample period), phases from the
    /// detector, values NaN where a signal had no good sample at that time; the recording's
    /// own checks (time axis, ambient readings) may refuse it, which makes it undiagnosable.
    pub recording: Result<Recording, RecordingError>,
    /// Unix ms of `recording.t_s[0]`.
    pub t0_ms: i64,
    /// Signals with no good sample at all in the segment.
    pub missing: Vec<Signal>,
    /// Good and total sample counts per stored signal over the segment (data-quality gate).
    pub quality: Vec<SignalQuality>,
}

/// One result to store.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NewDiagnosis {
    pub segment_id: i64,
    /// "A" or "B".
    pub method: String,
    /// D_GC … D_EP, percent.
    pub health: [f64; 6],
    /// 1σ, percent (non-finite stored as NULL).
    pub sigma: [f64; 6],
    pub objective: f64,
    pub residual_level: f64,
    pub fit_quality: String,
    pub model_runs: usize,
    pub wall_s: f64,
    pub seed: u64,
    pub config_hash: String,
    pub gtwatch_version: String,
}

/// What the worker found for one segment, as one write ([`Store::store_outcome`]).
#[derive(Debug, Clone, PartialEq)]
pub struct NewOutcome {
    pub segment_id: i64,
    /// One per method that gave a result.
    pub results: Vec<NewDiagnosis>,
    /// Reasons for what could not be diagnosed.
    pub failures: Vec<Undiagnosable>,
    pub config_hash: String,
}

/// One row of `gtwatch history`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HistoryRow {
    pub diagnosis_id: i64,
    pub segment_id: i64,
    pub start_ms: i64,
    pub start_utc: String,
    pub method: String,
    /// Parameter name → percent.
    pub health: BTreeMap<String, f64>,
    /// Parameter name → 1σ percent (absent when not estimated).
    pub sigma: BTreeMap<String, f64>,
    pub objective: f64,
    pub residual_level: Option<f64>,
    pub fit_quality: Option<String>,
    /// The last wash (operator-recorded or detected) before this start-up, if any.
    pub wash_id_before: Option<i64>,
    /// The verdict of the start-up's newest gap analysis, if one is stored (`fuel_meter`,
    /// `inlet_temperature`: a step an instrument explains; `ambiguous`, `none`, …).
    pub gap_verdict: Option<String>,
    /// With an `ambiguous` gap verdict: the candidate that explained the residual but was
    /// doubted for the health it needed (`verdict.doubted` of the stored report, e.g.
    /// `fuel_meter_offset`); `None` otherwise and for reports stored before it existed.
    pub gap_doubted: Option<String>,
    /// A Method B result's health corrected for an instrument's step, when the newest joint
    /// fit of the start-ups since the last firm wash named one from this start-up or an
    /// earlier one on (`instrument_corrections`); `health` stays as fitted.
    pub instrument_step: Option<InstrumentCorrection>,
    /// The health the start-up's newest gap analysis gives with the effect it named adopted
    /// (`verdict.health_after` of the stored report; `None` when nothing was named or the
    /// report predates it), percent in `HEALTH_NAMES` order.
    pub gap_health_after: Option<[f64; 6]>,
}

/// When a stored result was written and how long its fit took: what the latency of a
/// diagnosis is measured from (`gtwatch bench gap-month`).
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnosisTiming {
    pub segment_id: i64,
    /// "A" or "B".
    pub method: String,
    /// Wall time of the fit, s.
    pub wall_s: f64,
    /// Unix ms at which the result was stored.
    pub created_at_ms: i64,
}

/// Filter of [`Store::history`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HistoryFilter {
    pub since_ms: Option<i64>,
    pub until_ms: Option<i64>,
    /// "A" or "B".
    pub method: Option<String>,
}

impl HistoryRow {
    /// The result's value of health parameter `name`, percent (NaN when absent).
    pub fn value(&self, name: &str) -> f64 {
        self.health.get(name).copied().unwrap_or(f64::NAN)
    }

    /// Its 1σ, percent (NaN when not estimated).
    pub fn sigma_of(&self, name: &str) -> f64 {
        self.sigma.get(name).copied().unwrap_or(f64::NAN)
    }
}

/// Samples taken before the segment's start as standstill context for the model.
pub const CONTEXT_BEFORE_MS: i64 = 10_000;

/// A closed segment's recording from its rows, wherever they are stored (this database, or the
/// fleet centre's copy for a re-diagnosis): `phases` as (phase code, start ms, end ms), in
/// (start, code) order; `samples(signal)` the samples of any quality of the signal's tag over
/// `[start_ms - CONTEXT_BEFORE_MS, end_ms]`, time-ordered (`None`: no tag has that signal).
/// The time axis is n1's good samples; each signal's good samples at those times are its
/// values; the data-quality counts are over `[start_ms, end_ms]`. No I/O of its own: the same
/// rows give the same recording, bit for bit.
pub fn build_segment_recording(
    seg: SegmentInfo,
    phases: &[(i64, i64, Option<i64>)],
    mut samples: impl FnMut(Signal) -> Result<Option<Vec<super::SampleRow>>, StoreError>,
) -> Result<SegmentRecording, StoreError> {
    let id = seg.id;
    let Some(end_ms) = seg.end_ms else {
        return Err(StoreError::Corrupt(format!("segment {id} is still open")));
    };
    let mut phase_spans: Vec<(i64, i64, Phase)> = Vec::with_capacity(phases.len());
    for &(code, s, e) in phases {
        let phase = u16::try_from(code)
            .ok()
            .and_then(Phase::from_code)
            .ok_or_else(|| StoreError::Corrupt(format!("segment {id}: phase code {code}")))?;
        phase_spans.push((s, e.unwrap_or(end_ms), phase));
    }
    let good = |rows: &[super::SampleRow]| -> Vec<(i64, f64)> {
        rows.iter()
            .filter(|s| s.quality == 0)
            .map(|s| (s.t_ms, s.value))
            .collect()
    };
    let Some(n1) = samples(Signal::N1)? else {
        return Err(StoreError::UnknownTag("n1 (no tag has signal n1)".into()));
    };
    let axis: Vec<i64> = good(&n1).into_iter().map(|(t, _)| t).collect();
    let index: HashMap<i64, usize> = axis.iter().enumerate().map(|(i, t)| (*t, i)).collect();
    let mut values: Vec<Values> = vec![[f64::NAN; NSIG]; axis.len()];
    let mut missing = Vec::new();
    let mut quality = Vec::new();
    for sig in Signal::ALL {
        let rows = if sig == Signal::N1 {
            Some(n1.clone())
        } else {
            samples(sig)?
        };
        let Some(rows) = rows else {
            missing.push(sig);
            continue;
        };
        let in_segment = rows.iter().filter(|s| s.t_ms >= seg.start_ms);
        let (mut n_good, mut total) = (0u64, 0u64);
        for s in in_segment {
            total += 1;
            if s.quality == 0 {
                n_good += 1;
            }
        }
        quality.push(SignalQuality {
            signal: sig,
            good: n_good,
            total,
        });
        let mut any = false;
        for (t, v) in good(&rows) {
            if let Some(&k) = index.get(&t) {
                values[k][sig.index()] = v;
                any = true;
            }
        }
        if !any {
            missing.push(sig);
        }
    }
    let t0 = axis.first().copied().unwrap_or(seg.start_ms);
    let phase_at = |t: i64| -> Phase {
        phase_spans
            .iter()
            .rev()
            .find(|(s, e, _)| t >= *s && t <= *e)
            .map_or(Phase::Standstill, |p| p.2)
    };
    let recording = Recording::new(
        axis.iter().map(|t| (t - t0) as f64 / 1000.0).collect(),
        axis.iter().map(|t| phase_at(*t)).collect(),
        values,
    );
    Ok(SegmentRecording {
        segment: seg,
        recording,
        t0_ms: t0,
        missing,
        quality,
    })
}

pub(super) fn segment_row(r: &rusqlite::Row<'_>) -> rusqlite::Result<SegmentInfo> {
    Ok(SegmentInfo {
        id: r.get(0)?,
        start_ms: r.get(1)?,
        end_ms: r.get(2)?,
        outcome: r.get(3)?,
        abort_cause: r.get(4)?,
        status: r.get(5)?,
        has_gap: r.get(6)?,
    })
}

pub(super) const SEGMENT_COLS: &str = "id, start_ms, end_ms, outcome, abort_cause, status, has_gap";

impl Store {
    /// The worker's queue: closed start-ups with neither a result nor a recorded reason,
    /// oldest first.
    pub fn pending_segments(&self) -> Result<Vec<SegmentInfo>, StoreError> {
        let mut st = self.conn.prepare_cached(&format!(
            "SELECT {SEGMENT_COLS} FROM segments g WHERE kind = 'startup' AND status = 'closed'
               AND NOT EXISTS (SELECT 1 FROM diagnoses d WHERE d.segment_id = g.id)
               AND NOT EXISTS (SELECT 1 FROM undiagnosable u WHERE u.segment_id = g.id)
             ORDER BY start_ms"
        ))?;
        let rows = st.query_map([], segment_row)?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// One segment by id.
    pub fn segment(&self, id: i64) -> Result<Option<SegmentInfo>, StoreError> {
        Ok(self
            .conn
            .query_row(
                &format!("SELECT {SEGMENT_COLS} FROM segments WHERE id = ?1"),
                params![id],
                segment_row,
            )
            .optional()?)
    }

    /// The store → recording adapter: the segment's good samples (plus 10 s of context before
    /// it, labelled standstill) on the n1 tag's time stamps, with the detector's phases
    /// ([`build_segment_recording`] on what this database holds).
    pub fn segment_recording(&self, id: i64) -> Result<Option<SegmentRecording>, StoreError> {
        let Some(seg) = self.segment(id)? else {
            return Ok(None);
        };
        let Some(end_ms) = seg.end_ms else {
            return Err(StoreError::Corrupt(format!("segment {id} is still open")));
        };
        let from = seg.start_ms - CONTEXT_BEFORE_MS;
        let phases: Vec<(i64, i64, Option<i64>)> = {
            let mut st = self.conn.prepare_cached(
                "SELECT phase_code, start_ms, end_ms FROM segment_phases WHERE segment_id = ?1
                 ORDER BY start_ms, phase_code",
            )?;
            let rows = st.query_map(params![id], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))?;
            rows.collect::<Result<_, _>>()?
        };
        let tags = self.tags()?;
        let samples = |sig: Signal| -> Result<Option<Vec<super::SampleRow>>, StoreError> {
            match tags.iter().find(|t| t.signal == Some(sig)) {
                Some(t) => Ok(Some(super::archive::read_samples(
                    &self.conn, t.id, from, end_ms, false,
                )?)),
                None => Ok(None),
            }
        };
        build_segment_recording(seg, &phases, samples).map(Some)
    }

    /// Stores what the worker found for one segment — results (one per method) and reasons
    /// for what could not be diagnosed — and marks the segment diagnosed, in one transaction:
    /// a killed process leaves all of it or none.
    pub fn insert_outcome(
        &mut self,
        segment_id: i64,
        results: &[NewDiagnosis],
        failures: &[Undiagnosable],
        config_hash: &str,
    ) -> Result<Vec<i64>, StoreError> {
        // IMMEDIATE: the write lock up front, waiting up to the busy timeout. A deferred
        // transaction that reads first fails at once (SQLITE_BUSY) when another connection
        // wrote meanwhile (a command writing beside the daemon's writer).
        let tx = self
            .conn
            .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        let mut ids = Vec::new();
        for d in results {
            let s = d.sigma.map(|v| v.is_finite().then_some(v));
            tx.execute(
                "INSERT INTO diagnoses (segment_id, method, d_gc, d_ec, d_gt, d_et, d_gp, d_ep,
                    sigma_gc, sigma_ec, sigma_gt, sigma_et, sigma_gp, sigma_ep, objective,
                    model_runs, wall_s, model_version, seed, created_at_ms, residual_level,
                    fit_quality, config_hash, gtwatch_version)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16,
                    ?17, ?18, ?19, ?20, ?21, ?22, ?23, ?24)",
                params![
                    segment_id,
                    d.method,
                    d.health[0],
                    d.health[1],
                    d.health[2],
                    d.health[3],
                    d.health[4],
                    d.health[5],
                    s[0],
                    s[1],
                    s[2],
                    s[3],
                    s[4],
                    s[5],
                    d.objective,
                    d.model_runs as i64,
                    d.wall_s,
                    d.config_hash,
                    d.seed as i64,
                    super::now_ms(),
                    d.residual_level,
                    d.fit_quality,
                    d.config_hash,
                    d.gtwatch_version,
                ],
            )?;
            ids.push(tx.last_insert_rowid());
        }
        for f in failures {
            tx.execute(
                "INSERT INTO undiagnosable (segment_id, method, reason, detail, config_hash,
                                            gtwatch_version, created_at_ms)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                params![
                    segment_id,
                    f.method,
                    f.reason,
                    f.detail,
                    config_hash,
                    env!("CARGO_PKG_VERSION"),
                    super::now_ms()
                ],
            )?;
        }
        tx.execute(
            "UPDATE segments SET status = 'diagnosed', updated_at_ms = ?2 WHERE id = ?1",
            params![segment_id, super::now_ms()],
        )?;
        tx.commit()?;
        Ok(ids)
    }

    /// [`Store::insert_outcome`] of one [`NewOutcome`]: the ids of the stored results.
    pub fn store_outcome(&mut self, o: &NewOutcome) -> Result<Vec<i64>, StoreError> {
        self.insert_outcome(o.segment_id, &o.results, &o.failures, &o.config_hash)
    }

    /// Reasons recorded for a segment: (method, reason, detail).
    pub fn undiagnosable_reasons(
        &self,
        segment_id: i64,
    ) -> Result<Vec<(Option<String>, String, String)>, StoreError> {
        let mut st = self.conn.prepare_cached(
            "SELECT method, reason, detail FROM undiagnosable WHERE segment_id = ?1 ORDER BY id",
        )?;
        let rows = st.query_map(params![segment_id], |r| {
            Ok((r.get(0)?, r.get(1)?, r.get(2)?))
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Every stored result's fit wall time and storing time, by segment and method.
    pub fn diagnosis_timings(&self) -> Result<Vec<DiagnosisTiming>, StoreError> {
        let mut st = self.conn.prepare_cached(
            "SELECT segment_id, method, wall_s, created_at_ms FROM diagnoses
             ORDER BY segment_id, method, id",
        )?;
        let rows = st.query_map([], |r| {
            Ok(DiagnosisTiming {
                segment_id: r.get(0)?,
                method: r.get(1)?,
                wall_s: r.get(2)?,
                created_at_ms: r.get(3)?,
            })
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Stored results in start-up order (then method, then age).
    pub fn history(&self, f: &HistoryFilter) -> Result<Vec<HistoryRow>, StoreError> {
        let mut st = self.conn.prepare_cached(concat!(
            "SELECT d.id, d.segment_id, g.start_ms,
                    strftime('%Y-%m-%dT%H:%M:%fZ', g.start_ms / 1000.0, 'unixepoch'), d.method,
                    d.d_gc, d.d_ec, d.d_gt, d.d_et, d.d_gp, d.d_ep,
                    d.sigma_gc, d.sigma_ec, d.sigma_gt, d.sigma_et, d.sigma_gp, d.sigma_ep,
                    d.objective, d.residual_level, d.fit_quality,
                    (SELECT w.id FROM washes w WHERE w.t_ms <= g.start_ms
                      ORDER BY w.t_ms DESC, w.id DESC LIMIT 1),
                    a.effect, ",
            doubted_sql!("a"),
            ", json_extract(a.report_json, '$.verdict.health_after'), ",
            correction_columns!("c."),
            "
             FROM diagnoses d JOIN segments g ON g.id = d.segment_id
             -- the start-up's newest gap analysis, if any
             LEFT JOIN gap_analyses a ON a.id = (
                 SELECT n.id FROM gap_analyses n WHERE n.segment_id = g.id
                 ORDER BY n.created_at_ms DESC, n.id DESC LIMIT 1)
             -- its health corrected for an instrument's step (Method B results only)
             LEFT JOIN instrument_corrections c ON c.segment_id = g.id AND d.method = 'B'
             WHERE (?1 IS NULL OR g.start_ms >= ?1) AND (?2 IS NULL OR g.start_ms <= ?2)
               AND (?3 IS NULL OR d.method = ?3)
             ORDER BY g.start_ms, d.method, d.created_at_ms, d.id"
        ))?;
        let rows = st.query_map(params![f.since_ms, f.until_ms, f.method], |r| {
            let mut health = BTreeMap::new();
            let mut sigma = BTreeMap::new();
            for (i, n) in HEALTH_NAMES.iter().enumerate() {
                health.insert(n.to_string(), r.get::<_, f64>(5 + i)?);
                if let Some(s) = r.get::<_, Option<f64>>(11 + i)? {
                    sigma.insert(n.to_string(), s);
                }
            }
            Ok(HistoryRow {
                diagnosis_id: r.get(0)?,
                segment_id: r.get(1)?,
                start_ms: r.get(2)?,
                start_utc: r.get(3)?,
                method: r.get(4)?,
                health,
                sigma,
                objective: r.get(17)?,
                residual_level: r.get(18)?,
                fit_quality: r.get(19)?,
                wash_id_before: r.get(20)?,
                gap_verdict: r.get(21)?,
                // A report that is not the JSON this version writes reads as doubting nothing.
                gap_doubted: r.get::<_, Option<String>>(22).ok().flatten(),
                gap_health_after: r
                    .get::<_, Option<String>>(23)
                    .ok()
                    .flatten()
                    .and_then(|j| serde_json::from_str::<crate::health::HealthParams>(&j).ok())
                    .map(|h| h.to_array()),
                instrument_step: corrections::from_row(r, r.get(1)?, 24)?,
            })
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }
}
