//! The fleet's health history, read from the centre: every unit's stored results, one row per
//! start-up and method, with the newest gap verdict of its start-up (`gtwatch fleet history`,
//! the central counterpart of `gtwatch history`). With a configuration hash, the results the
//! fleet's re-diagnosis workers stored for it (`rediagnosis_estimates`) instead of the edges',
//! with the gap verdict of the start-up's re-analysis under that hash (`regap_analyses`) where
//! one was made, else the edge's. An edge's Method B result carries the health its wash advice
//! corrected for an instrument's step, where it made one (`instrument_corrections`).
//!
//! Reads only; must not compute trends or write to the centre.

use super::centre::{centre_err, Centre};
use super::FleetError;
use crate::health::HEALTH_NAMES;
use crate::store::InstrumentCorrection;
use serde::Serialize;
use std::collections::BTreeMap;

/// One central result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FleetHistoryRow {
    pub unit_id: String,
    /// The start-up's segment id at its edge.
    pub segment_id: i64,
    /// Start of the start-up, Unix ms.
    pub start_ms: i64,
    pub method: String,
    /// Health parameter → estimate, percent.
    pub health: BTreeMap<String, f64>,
    /// Health parameter → 1σ, where the edge stored one.
    pub sigma: BTreeMap<String, f64>,
    pub residual_level: Option<f64>,
    pub fit_quality: Option<String>,
    /// The effect named by the start-up's newest gap analysis, if one was synced (with a
    /// configuration hash: by its gap re-analysis under that hash, if one was made).
    pub gap_verdict: Option<String>,
    /// The health of a Method B result corrected for an instrument's step, as the unit's wash
    /// advice last said (`instrument_corrections`; the edges' own results only: a
    /// re-diagnosis under another configuration is not what that joint fit corrected).
    pub instrument_step: Option<InstrumentCorrection>,
    /// The health after of the start-up's newest synced gap analysis, when it named something
    /// (`verdict.health_after`; the edges' own results only), as `gtwatch history` shows it.
    pub gap_health_after: Option<[f64; 6]>,
}

impl FleetHistoryRow {
    /// The value of `param` a trend uses and its 1σ: the health corrected for an instrument's
    /// step where the unit's wash advice made one (a fuel meter reading high must not read as
    /// a washed compressor), else the fitted one.
    pub fn trend_value(&self, param: &str) -> Option<(f64, Option<f64>)> {
        match &self.instrument_step {
            Some(c) => HEALTH_NAMES
                .iter()
                .position(|n| *n == param)
                .map(|i| (c.health[i], Some(c.sigma[i]))),
            None => Some((*self.health.get(param)?, self.sigma.get(param).copied())),
        }
    }
}

/// Which results to read.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FleetHistoryFilter {
    /// One unit only.
    pub unit_id: Option<String>,
    /// One method only (`A` or `B`).
    pub method: Option<String>,
    /// The re-diagnosis under this engine/config hash (`gtwatch fleet rediagnose` prints it)
    /// instead of the edges' own results.
    pub config_hash: Option<String>,
}

/// The newest synced gap analysis of `d`'s start-up, `g` (looked up once per result; both the
/// verdict and the health after are read from it).
const EDGE_GAP_JOIN: &str = "LEFT JOIN LATERAL (
             SELECT n.effect, n.report_json FROM gap_analyses n
             WHERE n.unit_id = d.unit_id AND n.segment_id = d.segment_id
             ORDER BY n.created_at_ms DESC, n.edge_id DESC LIMIT 1) g ON TRUE";

/// The health after of `g`, as JSON text (the edges' own results only: `$3`, the
/// configuration hash, NULL).
const EDGE_GAP_HEALTH_AFTER: &str =
    "CASE WHEN $3::text IS NULL THEN g.report_json::jsonb -> 'verdict' ->> 'health_after' END";

/// The newest synced gap verdict of `d`'s start-up.
const EDGE_GAP: &str = "g.effect";

/// The corrected start-up's columns of `c` (`instrument_corrections`) the history reads, from
/// column 19 on.
const CORRECTION_COLUMNS: &str = "c.onset_segment_id, c.effect, c.unit, c.magnitude,
    c.magnitude_sigma, c.d_gc, c.d_ec, c.d_gt, c.d_et, c.d_gp, c.d_ep,
    c.sigma_gc, c.sigma_ec, c.sigma_gt, c.sigma_et, c.sigma_gp, c.sigma_ep, c.also";

/// `c` joined to a Method B result of the edges' own (`$3`, the configuration hash, NULL).
const CORRECTION_JOIN: &str = "LEFT JOIN instrument_corrections c
           ON c.unit_id = d.unit_id AND c.edge_id = d.segment_id AND d.method = 'B'
              AND $3::text IS NULL";

/// The same columns, all NULL, on a centre older than the corrections (schema version 4).
const NO_CORRECTION_COLUMNS: &str = "NULL::bigint, NULL::text, NULL::text, NULL::float8,
    NULL::float8, NULL::float8, NULL::float8, NULL::float8, NULL::float8, NULL::float8,
    NULL::float8, NULL::float8, NULL::float8, NULL::float8, NULL::float8, NULL::float8,
    NULL::float8, NULL::text";

/// The columns every history query returns, from `d` (a results table) joined with its
/// start-up `s`, its newest gap analysis `g` and its correction `c` when `corrections`; `{table}`, `{gap}` (the verdict) and
/// `{filter}` are filled in by the caller.
fn history_query(table: &str, gap: &str, filter: &str, order: &str, corrections: bool) -> String {
    let (columns, join) = if corrections {
        (CORRECTION_COLUMNS, CORRECTION_JOIN)
    } else {
        (NO_CORRECTION_COLUMNS, "")
    };
    format!(
        "SELECT d.unit_id, d.segment_id, s.start_ms, d.method,
                d.d_gc, d.d_ec, d.d_gt, d.d_et, d.d_gp, d.d_ep,
                d.sigma_gc, d.sigma_ec, d.sigma_gt, d.sigma_et, d.sigma_gp, d.sigma_ep,
                d.residual_level, d.fit_quality, {gap}, {columns}, {EDGE_GAP_HEALTH_AFTER}
         FROM {table} d
         JOIN segments s ON s.unit_id = d.unit_id AND s.edge_id = d.segment_id
         {EDGE_GAP_JOIN}
         {join}
         WHERE ($1::text IS NULL OR d.unit_id = $1)
           AND ($2::text IS NULL OR d.method = $2)
           AND {filter}
         ORDER BY d.unit_id, s.start_ms, d.method{order}"
    )
}

/// The central results, by unit, start time and method.
pub fn fleet_history(
    centre: &mut Centre,
    f: &FleetHistoryFilter,
) -> Result<Vec<FleetHistoryRow>, FleetError> {
    let name = centre.name.clone();
    let corrections = centre.has_corrections()?;
    let query = if f.config_hash.is_some() {
        // The results re-diagnosed under config hash `$3`, the gap verdict re-analysed under
        // it where the centre has gap jobs (schema version 3) and one was made.
        let gap = if centre.has_gap_jobs()? {
            format!(
                "COALESCE((SELECT r.effect FROM regap_analyses r
                   WHERE r.unit_id = d.unit_id AND r.segment_id = d.segment_id
                     AND r.config_hash = $3), {EDGE_GAP})"
            )
        } else {
            EDGE_GAP.to_string()
        };
        history_query(
            "rediagnosis_estimates",
            &gap,
            "d.config_hash = $3",
            "",
            corrections,
        )
    } else {
        // The edges' own results (`$3` is NULL, named so its type is known).
        history_query(
            "diagnoses",
            EDGE_GAP,
            "$3::text IS NULL",
            ", d.edge_id",
            corrections,
        )
    };
    let rows = centre
        .client
        .query(&query, &[&f.unit_id, &f.method, &f.config_hash])
        .map_err(centre_err(&name, "reading the fleet's results"))?;
    let mut out = Vec::with_capacity(rows.len());
    for r in &rows {
        let mut health = BTreeMap::new();
        let mut sigma = BTreeMap::new();
        for (i, n) in HEALTH_NAMES.iter().enumerate() {
            if let Some(v) = r.get::<_, Option<f64>>(4 + i) {
                health.insert((*n).to_string(), v);
            }
            if let Some(s) = r.get::<_, Option<f64>>(10 + i) {
                sigma.insert((*n).to_string(), s);
            }
        }
        let segment_id = r.get::<_, Option<i64>>(1).unwrap_or(-1);
        out.push(FleetHistoryRow {
            unit_id: r.get(0),
            segment_id,
            start_ms: r.get::<_, Option<i64>>(2).unwrap_or(0),
            method: r.get::<_, Option<String>>(3).unwrap_or_default(),
            health,
            sigma,
            residual_level: r.get(16),
            fit_quality: r.get(17),
            gap_verdict: r.get(18),
            instrument_step: correction(r, segment_id),
            gap_health_after: r
                .get::<_, Option<String>>(37)
                .and_then(|j| serde_json::from_str::<crate::health::HealthParams>(&j).ok())
                .map(|h| h.to_array()),
        });
    }
    Ok(out)
}

/// The correction in columns 19… of a history row, `None` when it has none (the LEFT JOIN's
/// NULLs; a row the centre holds with a NULL value is not shown as a correction either).
fn correction(r: &postgres::Row, segment_id: i64) -> Option<InstrumentCorrection> {
    let onset_segment_id = r.get::<_, Option<i64>>(19)?;
    let mut health = [0.0; 6];
    let mut sigma = [0.0; 6];
    for i in 0..HEALTH_NAMES.len() {
        health[i] = r.get::<_, Option<f64>>(24 + i)?;
        sigma[i] = r.get::<_, Option<f64>>(30 + i)?;
    }
    Some(InstrumentCorrection {
        segment_id,
        onset_segment_id,
        effect: r.get::<_, Option<String>>(20)?,
        unit: r.get::<_, Option<String>>(21)?,
        magnitude: r.get::<_, Option<f64>>(22)?,
        magnitude_sigma: r.get::<_, Option<f64>>(23)?,
        health,
        sigma,
        also: r.get::<_, Option<String>>(36).unwrap_or_default(),
    })
}

/// A wash stored at the centre.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FleetWash {
    pub unit_id: String,
    /// Unix ms.
    pub t_ms: i64,
    pub kind: String,
}

/// A unit's newest wash recommendation at the centre.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FleetAdvice {
    pub unit_id: String,
    /// Unix ms the advice was made for (the unit's newest result).
    pub t_ms: i64,
    pub message: String,
    /// The advice's basis as the edge stored it (JSON: trend, advice, economics).
    pub basis: String,
}

/// Every wash at the centre, by unit and time.
pub fn fleet_washes(centre: &mut Centre) -> Result<Vec<FleetWash>, FleetError> {
    let name = centre.name.clone();
    let rows = centre
        .client
        .query(
            "SELECT unit_id, t_ms, kind FROM washes WHERE t_ms IS NOT NULL
             ORDER BY unit_id, t_ms, edge_id",
            &[],
        )
        .map_err(centre_err(&name, "reading the fleet's washes"))?;
    Ok(rows
        .iter()
        .map(|r| FleetWash {
            unit_id: r.get(0),
            t_ms: r.get(1),
            kind: r.get::<_, Option<String>>(2).unwrap_or_default(),
        })
        .collect())
}

/// Each unit's newest offline-wash recommendation.
pub fn fleet_advice(centre: &mut Centre) -> Result<Vec<FleetAdvice>, FleetError> {
    let name = centre.name.clone();
    let rows = centre
        .client
        .query(
            "SELECT DISTINCT ON (unit_id) unit_id, t_ms, message, basis FROM recommendations
             WHERE kind = 'wash_offline' AND t_ms IS NOT NULL
             ORDER BY unit_id, t_ms DESC, edge_id DESC",
            &[],
        )
        .map_err(centre_err(&name, "reading the fleet's wash advice"))?;
    Ok(rows
        .iter()
        .map(|r| FleetAdvice {
            unit_id: r.get(0),
            t_ms: r.get(1),
            message: r.get::<_, Option<String>>(2).unwrap_or_default(),
            basis: r.get::<_, Option<String>>(3).unwrap_or_default(),
        })
        .collect())
}
