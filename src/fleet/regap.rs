//! The results of the fleet's gap-analysis jobs (`gtwatch fleet rediagnose --gap`), as
//! PostgreSQL SQL: a worker's report stored in `regap_analyses` in the transaction that marks
//! its job done, only while the worker still holds the lease ([`complete_gap`], the gap
//! counterpart of [`super::rediagnose::complete`]), and the stored reports read back.
//!
//! Must not run or judge an analysis (the worker room's `fleet` module runs `gap::analyse`),
//! and never touches an edge database.

use super::centre::{centre_err, Centre};
use super::rediagnose::{hold, in_tx, Job};
use super::FleetError;
use crate::store::NewGapAnalysis;
use serde::Serialize;

/// A gap job's result: the report with the columns the edge stores (`store::NewGapAnalysis`,
/// its `segment_id` the job's) and the job's wall time at the worker.
#[derive(Debug, Clone, PartialEq)]
pub struct GapJobResult {
    pub analysis: NewGapAnalysis,
    /// Reading the window and the analysis, s.
    pub wall_s: f64,
}

/// Stores `result` in `regap_analyses` and marks `job` done, in one transaction, if `worker`
/// still holds its lease; false (nothing written) if it lost it.
pub fn complete_gap(
    centre: &mut Centre,
    job: &Job,
    worker: &str,
    result: &GapJobResult,
) -> Result<bool, FleetError> {
    let name = centre.name.clone();
    let a = &result.analysis;
    let fin = |v: f64| v.is_finite().then_some(v);
    in_tx(centre, &name, "storing a gap analysis", |tx| {
        if !hold(tx, job.id, worker)? {
            return Ok(false);
        }
        tx.execute(
            "INSERT INTO regap_analyses (unit_id, segment_id, config_hash, job_id,
                 holdout_segment_id, effect, shrinkage, confidence, baseline_fit_quality,
                 normalised_residual, report_json, worker_id, wall_s, gtwatch_version)
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14)",
            &[
                &job.unit_id,
                &job.segment_id,
                &job.config_hash,
                &job.id,
                &a.holdout_segment_id,
                &a.effect,
                &fin(a.shrinkage),
                &fin(a.confidence),
                &a.baseline_fit_quality,
                &fin(a.normalised_residual),
                &a.report_json,
                &worker,
                &result.wall_s,
                &env!("CARGO_PKG_VERSION"),
            ],
        )?;
        tx.execute(
            "UPDATE rediagnosis_jobs SET state = 'done', done_at = now(), done_by = $2,
                 lease_until = NULL
             WHERE id = $1",
            &[&job.id, &worker],
        )?;
        Ok(true)
    })
}

/// One stored gap re-analysis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegapAnalysis {
    pub unit_id: String,
    pub segment_id: i64,
    pub config_hash: String,
    pub holdout_segment_id: Option<i64>,
    pub effect: String,
    pub baseline_fit_quality: String,
    /// The report, as `gtwatch gap --json` prints it.
    pub report_json: String,
    pub worker_id: String,
}

/// Every stored gap re-analysis (of one hash, or all), by unit and segment.
pub fn regap_analyses(
    centre: &mut Centre,
    config_hash: Option<&str>,
) -> Result<Vec<RegapAnalysis>, FleetError> {
    let name = centre.name.clone();
    let rows = centre
        .client
        .query(
            "SELECT unit_id, segment_id, config_hash, holdout_segment_id, effect,
                    baseline_fit_quality, report_json, worker_id
             FROM regap_analyses WHERE ($1::text IS NULL OR config_hash = $1)
             ORDER BY unit_id, segment_id, config_hash",
            &[&config_hash],
        )
        .map_err(centre_err(&name, "reading gap re-analyses"))?;
    Ok(rows
        .iter()
        .map(|r| RegapAnalysis {
            unit_id: r.get(0),
            segment_id: r.get(1),
            config_hash: r.get(2),
            holdout_segment_id: r.get(3),
            effect: r.get(4),
            baseline_fit_quality: r.get(5),
            report_json: r.get(6),
            worker_id: r.get(7),
        })
        .collect())
}
