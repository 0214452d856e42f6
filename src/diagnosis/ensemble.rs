//! A diagnosis read with several calibrations of one unit (`[adaptation.ensemble]`, written by
//! `calibrate --ensemble`): the spread of their reads about the engine file's own, per health
//! parameter, and the σ with it.
//!
//! Why: calibrations that fit a unit's healthy baseline equally well differ off its healthy
//! operating line, where degradation is read, by what no healthy baseline shows and no
//! residual reveals (a model whose sensitivity to fouling is 19 % off fits the fouled points at
//! the wrong health; `calibrate::ensemble` has the measurement). Read with each, the unit's
//! degraded data show how far the calibration alone moves the estimate: that is stated beside
//! the read, and added in quadrature to its σ.
//!
//! What it must not do: I/O (the CLI loads the members' files); change the main read.

use super::{health_map, MethodResult};
use crate::health::HEALTH_NAMES;
use serde::Serialize;
use std::collections::BTreeMap;

/// One member's read of a group.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MemberRead {
    /// The member's engine file.
    pub file: String,
    /// Its health read, points (`None` when it could not diagnose the group: `failed` says why).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub health: Option<BTreeMap<String, f64>>,
    /// Its fit verdict.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failed: Option<String>,
}

/// The ensemble's read of one group.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EnsembleRead {
    pub members: Vec<MemberRead>,
    /// Per health parameter, the RMS of the members' reads about the main read, points (over
    /// the members that read the group).
    pub spread: BTreeMap<String, f64>,
    /// The main read's σ with the spread in quadrature, points.
    pub sigma_with_spread: BTreeMap<String, f64>,
    /// Members that read the group.
    pub read_by: usize,
}

impl EnsembleRead {
    /// One line for the text report: the spread and the σ with it, per parameter.
    pub fn describe(&self) -> String {
        let list = |m: &BTreeMap<String, f64>| {
            HEALTH_NAMES
                .iter()
                .map(|n| format!("{n} {:.2}", m.get(*n).copied().unwrap_or(f64::NAN)))
                .collect::<Vec<_>>()
                .join(", ")
        };
        format!(
            "calibration spread (the reads of {} other calibration(s) of this unit about this \
             one, [adaptation.ensemble]), points: {}; the σ with it: {}",
            self.read_by,
            list(&self.spread),
            list(&self.sigma_with_spread)
        )
    }
}

/// The spread of `members` (file, its read or why none) about `main`.
pub fn ensemble_read(
    main: &MethodResult,
    members: Vec<(String, Result<MethodResult, String>)>,
) -> EnsembleRead {
    let main_h = main.health.to_array();
    let reads: Vec<[f64; 6]> = members
        .iter()
        .filter_map(|(_, r)| r.as_ref().ok().map(|r| r.health.to_array()))
        .collect();
    let spread: BTreeMap<String, f64> = HEALTH_NAMES
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let s = if reads.is_empty() {
                f64::NAN
            } else {
                (reads
                    .iter()
                    .map(|h| (h[i] - main_h[i]).powi(2))
                    .sum::<f64>()
                    / reads.len() as f64)
                    .sqrt()
            };
            (name.to_string(), s)
        })
        .collect();
    let sigma_with_spread = HEALTH_NAMES
        .iter()
        .map(|name| {
            let s = main.sigma.get(*name).copied().unwrap_or(0.0);
            let e = spread.get(*name).copied().unwrap_or(0.0);
            let e = if e.is_finite() { e } else { 0.0 };
            (name.to_string(), s.hypot(e))
        })
        .collect();
    let members = members
        .into_iter()
        .map(|(file, r)| match r {
            Ok(r) => MemberRead {
                file,
                health: Some(health_map(&r.health)),
                fit: Some(r.fit_quality.verdict.as_str().to_string()),
                failed: None,
            },
            Err(e) => MemberRead {
                file,
                health: None,
                fit: None,
                failed: Some(e),
            },
        })
        .collect();
    EnsembleRead {
        members,
        spread,
        sigma_with_spread,
        read_by: reads.len(),
    }
}
