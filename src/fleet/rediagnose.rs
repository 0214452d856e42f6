//! The distributed re-diagnosis queue at the centre (issue 25 item 3), as PostgreSQL SQL: jobs
//! queued per (unit, start-up, engine/config hash, kind), claimed under a lease, renewed, and
//! completed together with their result in one transaction; and a start-up window read back
//! from the centre as the diagnosis reads it at the edge. A job's [`JobKind`] is a diagnosis
//! or a gap analysis (whose result is stored by [`super::regap`]).
//!
//! - [`enqueue`]: one job of a kind per start-up of the chosen units whose window is complete
//!   at the centre (`sample_windows`), carrying by hash the engine file's text and the
//!   `[diagnosis]` settings (`rediagnosis_configs`); the same (unit, segment, hash, kind)
//!   queued again is nothing.
//! - [`claim`]: `SELECT … FOR UPDATE SKIP LOCKED` of a pending job whose lease is free or
//!   expired; it gets this worker's id and a lease of the given length (server clock).
//! - [`renew`]: extends the lease while it is still this worker's and not expired.
//! - [`release`]: gives a job back at once (a worker stopping on SIGTERM).
//! - [`complete`] / [`fail`]: write the outcome and mark the job done (or failed) in one
//!   transaction, only while this worker still holds an unexpired lease (the job row is
//!   locked for it); a worker that lost its lease writes nothing. `rediagnoses` is unique per
//!   (unit, segment, hash), so a result exists at most once whatever the workers do.
//! - [`retry_failed`]: failed jobs back to pending (attempts kept, error cleared).
//! - [`read_window`]: the segment, its phases and its samples through the unit's tags, turned
//!   into a recording by the store's own adapter ([`build_segment_recording`]).
//!
//! Must not fit anything or decide what a result is (the worker room runs the diagnosis), and
//! never touches an edge database.

use super::centre::{centre_err, Centre};
use super::FleetError;
use crate::signals::Signal;
use crate::store::{
    build_segment_recording, NewDiagnosis, SampleRow, SegmentInfo, SegmentRecording,
    CONTEXT_BEFORE_MS,
};
use serde::Serialize;
use std::collections::HashMap;
use std::time::Duration;

/// What a job runs on its start-up.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum JobKind {
    /// The edge's diagnosis (Method B and A): `rediagnoses`, `rediagnosis_estimates`.
    #[default]
    Diagnose,
    /// The edge's gap analysis: `regap_analyses`.
    Gap,
}

impl JobKind {
    /// The `kind` column's value.
    pub fn as_str(self) -> &'static str {
        match self {
            JobKind::Diagnose => "diagnose",
            JobKind::Gap => "gap",
        }
    }

    fn parse(s: &str) -> Option<JobKind> {
        match s {
            "diagnose" => Some(JobKind::Diagnose),
            "gap" => Some(JobKind::Gap),
            _ => None,
        }
    }
}

/// What to queue: which start-ups, and what to diagnose them with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EnqueueRequest {
    /// Only these units (empty: every unit).
    pub units: Vec<String>,
    /// Only start-ups beginning at or after this Unix ms.
    pub since_ms: Option<i64>,
    /// The engine/config hash (`worker::WorkerContext::config_hash`) of what follows.
    pub config_hash: String,
    /// The engine file's name, for messages.
    pub engine_name: String,
    /// The engine file's text.
    pub engine_toml: String,
    /// The `[diagnosis]` settings, as JSON.
    pub settings_json: String,
    /// The jobs' kind.
    pub kind: JobKind,
}

/// What [`enqueue`] did.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct EnqueueReport {
    pub config_hash: String,
    pub kind: JobKind,
    /// Start-ups matching the request whose window is complete at the centre.
    pub startups: u64,
    /// Jobs queued now.
    pub enqueued: u64,
    /// Of `startups`, those already queued (any state) with this hash and kind.
    pub already_queued: u64,
    /// Matching start-ups whose window is not (yet) complete at the centre: not queued.
    pub without_window: u64,
}

/// Queues the request's jobs (idempotent) in one transaction.
pub fn enqueue(centre: &mut Centre, req: &EnqueueRequest) -> Result<EnqueueReport, FleetError> {
    let name = centre.name.clone();
    let units: Option<Vec<String>> = (!req.units.is_empty()).then(|| req.units.clone());
    let mut tx = centre
        .client
        .transaction()
        .map_err(centre_err(&name, "BEGIN of the enqueue"))?;
    let existing: Option<(String, String)> = tx
        .query_opt(
            "SELECT engine_toml, settings_json FROM rediagnosis_configs WHERE config_hash = $1",
            &[&req.config_hash],
        )
        .map_err(centre_err(&name, "reading the job configs"))?
        .map(|r| (r.get(0), r.get(1)));
    match existing {
        Some((e, s)) if e != req.engine_toml || s != req.settings_json => {
            return Err(FleetError::Data {
                centre: name,
                what: format!(
                    "config hash {} is stored with another engine text or settings (a hash \
                     collision, or settings serialised differently by another gtwatch version)",
                    req.config_hash
                ),
            })
        }
        Some(_) => {}
        None => {
            tx.execute(
                "INSERT INTO rediagnosis_configs (config_hash, engine_name, engine_toml, settings_json)
                 VALUES ($1, $2, $3, $4)",
                &[
                    &req.config_hash,
                    &req.engine_name,
                    &req.engine_toml,
                    &req.settings_json,
                ],
            )
            .map_err(centre_err(&name, "storing the job config"))?;
        }
    }
    let filter = "s.kind = 'startup' AND s.end_ms IS NOT NULL
                  AND ($1::text[] IS NULL OR s.unit_id = ANY($1))
                  AND ($2::bigint IS NULL OR s.start_ms >= $2)";
    let complete = "EXISTS (SELECT 1 FROM sample_windows w WHERE w.unit_id = s.unit_id
                      AND w.segment_id = s.edge_id AND w.end_ms = s.end_ms
                      AND w.from_ms = s.start_ms - $3)";
    let counts = tx
        .query_one(
            &format!(
                "SELECT count(*) FILTER (WHERE {complete}),
                        count(*) FILTER (WHERE NOT {complete}),
                        count(*) FILTER (WHERE {complete} AND EXISTS (
                            SELECT 1 FROM rediagnosis_jobs j WHERE j.unit_id = s.unit_id
                              AND j.segment_id = s.edge_id AND j.config_hash = $4
                              AND j.kind = $5))
                 FROM segments s WHERE {filter}"
            ),
            &[
                &units,
                &req.since_ms,
                &CONTEXT_BEFORE_MS,
                &req.config_hash,
                &req.kind.as_str(),
            ],
        )
        .map_err(centre_err(&name, "counting start-ups"))?;
    let enqueued = tx
        .execute(
            &format!(
                "INSERT INTO rediagnosis_jobs (unit_id, segment_id, config_hash, kind)
                 SELECT s.unit_id, s.edge_id, $4, $5 FROM segments s
                 WHERE {filter} AND {complete}
                 ORDER BY s.unit_id, s.start_ms
                 ON CONFLICT (unit_id, segment_id, config_hash, kind) DO NOTHING"
            ),
            &[
                &units,
                &req.since_ms,
                &CONTEXT_BEFORE_MS,
                &req.config_hash,
                &req.kind.as_str(),
            ],
        )
        .map_err(centre_err(&name, "queuing jobs"))?;
    tx.commit()
        .map_err(centre_err(&name, "COMMIT of the enqueue"))?;
    let n = |i: usize| u64::try_from(counts.get::<_, i64>(i)).unwrap_or(0);
    Ok(EnqueueReport {
        config_hash: req.config_hash.clone(),
        kind: req.kind,
        startups: n(0),
        enqueued,
        already_queued: n(2),
        without_window: n(1),
    })
}

/// A claimed job and what it runs with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Job {
    pub id: i64,
    pub unit_id: String,
    pub segment_id: i64,
    pub config_hash: String,
    pub kind: JobKind,
    /// Claims of this job so far, this one included.
    pub attempts: i32,
    pub engine_name: String,
    pub engine_toml: String,
    pub settings_json: String,
}

fn lease_secs(lease: Duration) -> f64 {
    lease.as_secs_f64().max(0.001)
}

/// Claims the oldest pending job whose lease is free or expired, for `worker` and `lease`.
pub fn claim(
    centre: &mut Centre,
    worker: &str,
    lease: Duration,
) -> Result<Option<Job>, FleetError> {
    let name = centre.name.clone();
    let row = centre
        .client
        .query_opt(
            "WITH c AS (
                 SELECT id FROM rediagnosis_jobs
                 WHERE state = 'pending' AND (lease_until IS NULL OR lease_until < now())
                 ORDER BY id LIMIT 1
                 FOR UPDATE SKIP LOCKED)
             UPDATE rediagnosis_jobs j
                SET lease_owner = $1, lease_until = now() + make_interval(secs => $2),
                    attempts = j.attempts + 1
               FROM c, rediagnosis_configs k
              WHERE j.id = c.id AND k.config_hash = j.config_hash
             RETURNING j.id, j.unit_id, j.segment_id, j.config_hash, j.attempts,
                       k.engine_name, k.engine_toml, k.settings_json, j.kind",
            &[&worker, &lease_secs(lease)],
        )
        .map_err(centre_err(&name, "claiming a job"))?;
    let Some(r) = row else {
        return Ok(None);
    };
    let kind: String = r.get(8);
    let kind = JobKind::parse(&kind).ok_or_else(|| FleetError::Data {
        centre: name.clone(),
        what: format!("job {} has kind {kind}", r.get::<_, i64>(0)),
    })?;
    Ok(Some(Job {
        id: r.get(0),
        unit_id: r.get(1),
        segment_id: r.get(2),
        config_hash: r.get(3),
        kind,
        attempts: r.get(4),
        engine_name: r.get(5),
        engine_toml: r.get(6),
        settings_json: r.get(7),
    }))
}

/// Extends `job`'s lease by `lease` from now; false when it is no longer this worker's (taken
/// over after it expired, or finished).
pub fn renew(
    centre: &mut Centre,
    job: i64,
    worker: &str,
    lease: Duration,
) -> Result<bool, FleetError> {
    let name = centre.name.clone();
    let n = centre
        .client
        .execute(
            "UPDATE rediagnosis_jobs SET lease_until = now() + make_interval(secs => $3)
             WHERE id = $1 AND lease_owner = $2 AND state = 'pending' AND lease_until > now()",
            &[&job, &worker, &lease_secs(lease)],
        )
        .map_err(centre_err(&name, "renewing a lease"))?;
    Ok(n == 1)
}

/// Gives `job` back at once (a worker stopping: another may claim it without waiting for the
/// lease to run out); false when it was no longer this worker's.
pub fn release(centre: &mut Centre, job: i64, worker: &str) -> Result<bool, FleetError> {
    let name = centre.name.clone();
    let n = centre
        .client
        .execute(
            "UPDATE rediagnosis_jobs SET lease_owner = NULL, lease_until = NULL
             WHERE id = $1 AND lease_owner = $2 AND state = 'pending'",
            &[&job, &worker],
        )
        .map_err(centre_err(&name, "releasing a lease"))?;
    Ok(n == 1)
}

/// A job's result: the estimates (one per method that gave one) and the reasons for what gave
/// none.
#[derive(Debug, Clone, PartialEq)]
pub struct JobResult {
    /// `diagnosed` or `undiagnosable`.
    pub outcome: String,
    pub estimates: Vec<NewDiagnosis>,
    /// JSON array of the reasons (method, reason, detail).
    pub failures_json: String,
    /// The job's wall time at the worker: reading the window and the fits.
    pub wall_s: f64,
}

/// Locks `job` if `worker` still holds an unexpired lease on it; false otherwise.
pub(super) fn hold(
    tx: &mut postgres::Transaction<'_>,
    job: i64,
    worker: &str,
) -> Result<bool, postgres::Error> {
    Ok(tx
        .query_opt(
            "SELECT 1 FROM rediagnosis_jobs
             WHERE id = $1 AND lease_owner = $2 AND state = 'pending' AND lease_until > now()
             FOR UPDATE",
            &[&job, &worker],
        )?
        .is_some())
}

/// Stores `result` and marks `job` done, in one transaction, if `worker` still holds its
/// lease; false (nothing written) if it lost it.
pub fn complete(
    centre: &mut Centre,
    job: &Job,
    worker: &str,
    result: &JobResult,
) -> Result<bool, FleetError> {
    let name = centre.name.clone();
    let work = |tx: &mut postgres::Transaction<'_>| -> Result<bool, postgres::Error> {
        if !hold(tx, job.id, worker)? {
            return Ok(false);
        }
        tx.execute(
            "INSERT INTO rediagnoses (unit_id, segment_id, config_hash, job_id, outcome,
                 failures_json, worker_id, wall_s, gtwatch_version)
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9)",
            &[
                &job.unit_id,
                &job.segment_id,
                &job.config_hash,
                &job.id,
                &result.outcome,
                &result.failures_json,
                &worker,
                &result.wall_s,
                &env!("CARGO_PKG_VERSION"),
            ],
        )?;
        for e in &result.estimates {
            let fin = |v: f64| v.is_finite().then_some(v);
            let h: Vec<Option<f64>> = e.health.iter().map(|v| fin(*v)).collect();
            let s: Vec<Option<f64>> = e.sigma.iter().map(|v| fin(*v)).collect();
            let runs = i64::try_from(e.model_runs).unwrap_or(i64::MAX);
            let seed = i64::try_from(e.seed).unwrap_or(i64::MAX);
            tx.execute(
                "INSERT INTO rediagnosis_estimates (unit_id, segment_id, config_hash, method,
                     d_gc, d_ec, d_gt, d_et, d_gp, d_ep,
                     sigma_gc, sigma_ec, sigma_gt, sigma_et, sigma_gp, sigma_ep,
                     objective, residual_level, fit_quality, model_runs, wall_s, seed)
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16,
                         $17, $18, $19, $20, $21, $22)",
                &[
                    &job.unit_id,
                    &job.segment_id,
                    &job.config_hash,
                    &e.method,
                    &h[0],
                    &h[1],
                    &h[2],
                    &h[3],
                    &h[4],
                    &h[5],
                    &s[0],
                    &s[1],
                    &s[2],
                    &s[3],
                    &s[4],
                    &s[5],
                    &fin(e.objective),
                    &fin(e.residual_level),
                    &e.fit_quality,
                    &runs,
                    &e.wall_s,
                    &seed,
                ],
            )?;
        }
        tx.execute(
            "UPDATE rediagnosis_jobs SET state = 'done', done_at = now(), done_by = $2,
                 lease_until = NULL
             WHERE id = $1",
            &[&job.id, &worker],
        )?;
        Ok(true)
    };
    in_tx(centre, &name, "storing a result", work)
}

/// Marks `job` failed with `error` (a job that cannot be run: no window, an engine file this
/// build refuses, a hash it does not reproduce), if `worker` still holds its lease.
pub fn fail(centre: &mut Centre, job: i64, worker: &str, error: &str) -> Result<bool, FleetError> {
    let name = centre.name.clone();
    in_tx(centre, &name, "marking a job failed", |tx| {
        if !hold(tx, job, worker)? {
            return Ok(false);
        }
        tx.execute(
            "UPDATE rediagnosis_jobs SET state = 'failed', done_at = now(), done_by = $2,
                 error = $3, lease_until = NULL
             WHERE id = $1",
            &[&job, &worker, &error],
        )?;
        Ok(true)
    })
}

pub(super) fn in_tx<T>(
    centre: &mut Centre,
    name: &str,
    what: &str,
    work: impl FnOnce(&mut postgres::Transaction<'_>) -> Result<T, postgres::Error>,
) -> Result<T, FleetError> {
    let result = (|| {
        let mut tx = centre.client.transaction()?;
        let out = work(&mut tx)?;
        tx.commit()?;
        Ok(out)
    })();
    result.map_err(centre_err(name, what))
}

/// Which failed jobs [`retry_failed`] puts back.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RetryFilter {
    /// Only these units (empty: every unit).
    pub units: Vec<String>,
    /// Only this engine/config hash (`None`: every hash).
    pub config_hash: Option<String>,
}

/// Puts the failed jobs `filter` selects back to pending (no lease, the error and the finish
/// cleared, the attempts kept); how many.
pub fn retry_failed(centre: &mut Centre, filter: &RetryFilter) -> Result<u64, FleetError> {
    let name = centre.name.clone();
    let units: Option<Vec<String>> = (!filter.units.is_empty()).then(|| filter.units.clone());
    centre
        .client
        .execute(
            "UPDATE rediagnosis_jobs
                SET state = 'pending', error = NULL, done_at = NULL, done_by = NULL,
                    lease_owner = NULL, lease_until = NULL
              WHERE state = 'failed'
                AND ($1::text[] IS NULL OR unit_id = ANY($1))
                AND ($2::text IS NULL OR config_hash = $2)",
            &[&units, &filter.config_hash],
        )
        .map_err(centre_err(&name, "putting failed jobs back"))
}

/// Jobs per state (`pending` split into `leased` and `waiting`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct QueueCounts {
    pub waiting: i64,
    pub leased: i64,
    pub done: i64,
    pub failed: i64,
}

impl QueueCounts {
    /// Jobs not finished (waiting or leased).
    pub fn pending(&self) -> i64 {
        self.waiting + self.leased
    }
}

/// The queue's jobs per state, diagnoses and gap analyses apart.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct QueueByKind {
    pub diagnose: QueueCounts,
    pub gap: QueueCounts,
}

/// The queue's jobs per kind and state (of one hash, or all).
pub fn queue_by_kind(
    centre: &mut Centre,
    config_hash: Option<&str>,
) -> Result<QueueByKind, FleetError> {
    Ok(QueueByKind {
        diagnose: queue_counts(centre, config_hash, Some(JobKind::Diagnose))?,
        gap: queue_counts(centre, config_hash, Some(JobKind::Gap))?,
    })
}

/// The queue's jobs per state (of one hash, or all; of one kind, or all).
pub fn queue_counts(
    centre: &mut Centre,
    config_hash: Option<&str>,
    kind: Option<JobKind>,
) -> Result<QueueCounts, FleetError> {
    let kind = kind.map(JobKind::as_str);
    let name = centre.name.clone();
    let r = centre
        .client
        .query_one(
            "SELECT count(*) FILTER (WHERE state = 'pending'
                                       AND (lease_until IS NULL OR lease_until < now())),
                    count(*) FILTER (WHERE state = 'pending' AND lease_until >= now()),
                    count(*) FILTER (WHERE state = 'done'),
                    count(*) FILTER (WHERE state = 'failed')
             FROM rediagnosis_jobs WHERE ($1::text IS NULL OR config_hash = $1)
                                     AND ($2::text IS NULL OR kind = $2)",
            &[&config_hash, &kind],
        )
        .map_err(centre_err(&name, "counting jobs"))?;
    Ok(QueueCounts {
        waiting: r.get(0),
        leased: r.get(1),
        done: r.get(2),
        failed: r.get(3),
    })
}

/// One stored re-diagnosis estimate (tests and reports compare them with the edge's).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RediagnosisEstimate {
    pub unit_id: String,
    pub segment_id: i64,
    pub config_hash: String,
    pub method: String,
    /// D_GC … D_EP, percent (NaN: NULL).
    pub health: [f64; 6],
    pub objective: f64,
    pub residual_level: f64,
    pub fit_quality: String,
    pub worker_id: String,
}

/// Every stored estimate (of one hash, or all), by unit, segment and method.
pub fn rediagnosis_estimates(
    centre: &mut Centre,
    config_hash: Option<&str>,
) -> Result<Vec<RediagnosisEstimate>, FleetError> {
    let name = centre.name.clone();
    let rows = centre
        .client
        .query(
            "SELECT e.unit_id, e.segment_id, e.config_hash, e.method,
                    e.d_gc, e.d_ec, e.d_gt, e.d_et, e.d_gp, e.d_ep,
                    e.objective, e.residual_level, e.fit_quality, r.worker_id
             FROM rediagnosis_estimates e
             JOIN rediagnoses r USING (unit_id, segment_id, config_hash)
             WHERE ($1::text IS NULL OR e.config_hash = $1)
             ORDER BY e.unit_id, e.segment_id, e.method",
            &[&config_hash],
        )
        .map_err(centre_err(&name, "reading re-diagnoses"))?;
    let f = |r: &postgres::Row, i: usize| r.get::<_, Option<f64>>(i).unwrap_or(f64::NAN);
    Ok(rows
        .iter()
        .map(|r| RediagnosisEstimate {
            unit_id: r.get(0),
            segment_id: r.get(1),
            config_hash: r.get(2),
            method: r.get(3),
            health: [f(r, 4), f(r, 5), f(r, 6), f(r, 7), f(r, 8), f(r, 9)],
            objective: f(r, 10),
            residual_level: f(r, 11),
            fit_quality: r.get::<_, Option<String>>(12).unwrap_or_default(),
            worker_id: r.get(13),
        })
        .collect())
}

/// The start-up `segment_id` of `unit_id` as the centre holds it, read as the edge's
/// diagnosis reads its own copy (`Store::segment_recording`): the same rows give the same
/// recording.
pub fn read_window(
    centre: &mut Centre,
    unit_id: &str,
    segment_id: i64,
) -> Result<SegmentRecording, FleetError> {
    let name = centre.name.clone();
    let missing = |what: String| FleetError::Data {
        centre: name.clone(),
        what: format!("unit {unit_id} segment {segment_id}: {what}"),
    };
    let seg = centre
        .client
        .query_opt(
            "SELECT edge_id, start_ms, end_ms, outcome, abort_cause, status, has_gap
             FROM segments WHERE unit_id = $1 AND edge_id = $2",
            &[&unit_id, &segment_id],
        )
        .map_err(centre_err(&name, "reading a segment"))?
        .map(|r| SegmentInfo {
            id: r.get(0),
            start_ms: r.get::<_, Option<i64>>(1).unwrap_or(0),
            end_ms: r.get(2),
            outcome: r.get::<_, Option<String>>(3).unwrap_or_default(),
            abort_cause: r.get(4),
            status: r.get::<_, Option<String>>(5).unwrap_or_default(),
            has_gap: r.get::<_, Option<i64>>(6).unwrap_or(0) != 0,
        })
        .ok_or_else(|| missing("no such segment at the centre".to_string()))?;
    let Some(end_ms) = seg.end_ms else {
        return Err(missing("the segment is still open".to_string()));
    };
    let from = seg.start_ms - CONTEXT_BEFORE_MS;
    let window = centre
        .client
        .query_opt(
            "SELECT 1 FROM sample_windows WHERE unit_id = $1 AND segment_id = $2
               AND from_ms = $3 AND end_ms = $4",
            &[&unit_id, &segment_id, &from, &end_ms],
        )
        .map_err(centre_err(&name, "reading a window"))?;
    if window.is_none() {
        return Err(missing(
            "its samples are not all at the centre (no complete window)".to_string(),
        ));
    }
    let phases: Vec<(i64, i64, Option<i64>)> = centre
        .client
        .query(
            "SELECT phase_code, start_ms, end_ms FROM segment_phases
             WHERE unit_id = $1 AND edge_id = $2 ORDER BY start_ms, phase_code",
            &[&unit_id, &segment_id],
        )
        .map_err(centre_err(&name, "reading phases"))?
        .iter()
        .map(|r| {
            (
                r.get::<_, Option<i64>>(0).unwrap_or(-1),
                r.get::<_, Option<i64>>(1).unwrap_or(0),
                r.get(2),
            )
        })
        .collect();
    // The first tag (in edge id order) of each signal, as the edge picks it.
    let mut tag_of: HashMap<Signal, String> = HashMap::new();
    let tags = centre
        .client
        .query(
            "SELECT name, signal FROM tags WHERE unit_id = $1 AND signal IS NOT NULL
             ORDER BY edge_id",
            &[&unit_id],
        )
        .map_err(centre_err(&name, "reading tags"))?;
    for r in &tags {
        let (tag, signal): (Option<String>, String) = (r.get(0), r.get(1));
        let sig: Signal = signal
            .parse()
            .map_err(|e| missing(format!("tag signal {signal}: {e}")))?;
        if let Some(tag) = tag {
            tag_of.entry(sig).or_insert(tag);
        }
    }
    let names: Vec<String> = tag_of.values().cloned().collect();
    let mut by_tag: HashMap<String, Vec<SampleRow>> = HashMap::new();
    let rows = centre
        .client
        .query(
            "SELECT tag, t_ms, value, quality FROM samples
             WHERE unit_id = $1 AND tag = ANY($2) AND t_ms BETWEEN $3 AND $4
             ORDER BY tag, t_ms",
            &[&unit_id, &names, &from, &end_ms],
        )
        .map_err(centre_err(&name, "reading samples"))?;
    for r in &rows {
        by_tag.entry(r.get(0)).or_default().push(SampleRow {
            t_ms: r.get(1),
            value: r.get(2),
            quality: r.get(3),
        });
    }
    build_segment_recording(seg, &phases, |sig| {
        Ok(tag_of
            .get(&sig)
            .map(|t| by_tag.get(t).cloned().unwrap_or_default()))
    })
    .map_err(|e| missing(e.to_string()))
}

/// The reasons of an assessment as the JSON stored with a result.
pub fn failures_json(failures: &[crate::store::Undiagnosable]) -> String {
    serde_json::to_string(failures).unwrap_or_else(|_| "[]".to_string())
}
