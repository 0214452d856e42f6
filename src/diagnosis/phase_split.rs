//! Method B read twice more on one start-up: on its run to load alone (every start-up phase
//! before `steady`) and on its steady end alone, and the health parameters the two parts read
//! apart beyond their uncertainties.
//!
//! Why: a model whose transient differs from the unit's (a compressor off its operating line
//! in a way the healthy baseline never showed, a governor, a lag) can fit the whole start-up
//! within noise and still put that difference into the health. The residual cannot show it;
//! the two parts can, because each part's health then absorbs a different share of it. On the
//! second blind simulator's start-ups (`tests/data/foreign/indep2/startups`) the run to load
//! alone reads D_GC up to 1.5 points above the steady end on a healthy unit, D_ET up to 1.9
//! above and D_EP up to 2.6 below; on the model's own twin (`gtwatch simulate --noise`, seeds
//! 1–4) the parts agree within 0.21 points.
//!
//! The whole start-up's result is not changed: this reports. It must not do I/O.

use super::transient::diagnose_transient;
use super::{DiagnosisConfig, MethodResult};
use crate::engine::Engine;
use crate::health::HEALTH_NAMES;
use crate::recording::Recording;
use crate::signals::Phase;
use serde::Serialize;
use std::collections::BTreeMap;

/// A difference smaller than this, points, is not reported however small the σ.
pub const MIN_DIFFERENCE_PTS: f64 = 0.3;
/// A difference is reported when it exceeds this many σ of the difference.
pub const MIN_DIFFERENCE_SIGMA: f64 = 3.0;

/// The health one part of the start-up reads.
#[derive(Debug, Clone, Serialize)]
pub struct PartRead {
    /// The phases compared (the model runs through the whole start-up).
    pub phases: Vec<Phase>,
    pub health: BTreeMap<String, f64>,
    pub sigma: BTreeMap<String, f64>,
    /// The part's own fit verdict, by the whole start-up's thresholds: a part alone can exceed
    /// them by noise alone (the steady end of a twin start-up: normalised residual 1.03 against
    /// `good` up to 0.9; the thresholds are set for whole start-ups), so it is shown, not
    /// judged.
    pub fit_quality: &'static str,
}

/// A health parameter the two parts read apart.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Difference {
    pub param: &'static str,
    /// The run to load's read less the steady end's, points.
    pub difference: f64,
    /// 1σ of the difference.
    pub sigma: f64,
}

/// The start-up read in two parts.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseSplit {
    /// Every start-up phase before `steady`.
    pub to_load: PartRead,
    pub steady: PartRead,
    /// The parameters read apart by more than [`MIN_DIFFERENCE_PTS`] and
    /// [`MIN_DIFFERENCE_SIGMA`] σ.
    pub differ: Vec<Difference>,
}

impl PhaseSplit {
    /// One line of plain words (empty when the parts agree).
    pub fn statement(&self) -> String {
        if self.differ.is_empty() {
            return String::new();
        }
        let each: Vec<String> = self
            .differ
            .iter()
            .map(|d| {
                format!(
                    "{} {:+.2} vs {:+.2} ({:+.2} ± {:.2})",
                    d.param,
                    self.to_load
                        .health
                        .get(d.param)
                        .copied()
                        .unwrap_or(f64::NAN),
                    self.steady.health.get(d.param).copied().unwrap_or(f64::NAN),
                    d.difference,
                    d.sigma
                )
            })
            .collect();
        format!(
            "the run to load and the steady end read {} apart (to load vs steady): the model's \
             transient differs from the unit's, and the whole start-up's read of these holds \
             some of that difference, so it is in doubt by about half of it (`--phases steady` \
             reads the steady end alone)",
            each.join(", ")
        )
    }
}

fn part(r: &MethodResult, phases: &[Phase]) -> PartRead {
    PartRead {
        phases: phases.to_vec(),
        health: r.health_map(),
        sigma: r.sigma.clone(),
        fit_quality: r.fit_quality.verdict.as_str(),
    }
}

/// The parameters `a` and `b` read apart (see [`PhaseSplit::differ`]).
pub fn differences(a: &PartRead, b: &PartRead) -> Vec<Difference> {
    HEALTH_NAMES
        .iter()
        .filter_map(|&p| {
            let (ha, hb) = (*a.health.get(p)?, *b.health.get(p)?);
            let (sa, sb) = (*a.sigma.get(p)?, *b.sigma.get(p)?);
            let d = ha - hb;
            let s = sa.hypot(sb);
            (d.is_finite()
                && s.is_finite()
                && d.abs() > MIN_DIFFERENCE_PTS
                && d.abs() > MIN_DIFFERENCE_SIGMA * s)
                .then_some(Difference {
                    param: p,
                    difference: d,
                    sigma: s,
                })
        })
        .collect()
}

/// `segment` read by Method B on its run to load and on its steady end apart, with `cfg`
/// otherwise. `None` when either part cannot be read on its own (a start-up that never
/// reached steady, a part with no compared samples).
pub fn phase_split(
    engine: &Engine,
    segment: &Recording,
    cfg: &DiagnosisConfig,
) -> Option<PhaseSplit> {
    let to_load: Vec<Phase> = Phase::STARTUP
        .iter()
        .copied()
        .filter(|p| *p != Phase::Steady)
        .collect();
    let steady = vec![Phase::Steady];
    let read = |phases: &[Phase]| {
        let mut c = cfg.clone();
        c.window.phases = phases.to_vec();
        // A part the data cannot read alone is no evidence either way.
        diagnose_transient(engine, segment, &c)
            .ok()
            .map(|r| part(&r, phases))
    };
    let (Some(to_load), Some(steady)) = (read(&to_load), read(&steady)) else {
        return None;
    };
    let differ = differences(&to_load, &steady);
    Some(PhaseSplit {
        to_load,
        steady,
        differ,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(values: [f64; 6], sigma: f64) -> PartRead {
        PartRead {
            phases: vec![Phase::Steady],
            health: HEALTH_NAMES
                .iter()
                .zip(values)
                .map(|(n, v)| (n.to_string(), v))
                .collect(),
            sigma: HEALTH_NAMES
                .iter()
                .map(|n| (n.to_string(), sigma))
                .collect(),
            fit_quality: "good",
        }
    }

    /// Only a difference both material (over 0.3 points) and beyond 3σ is reported.
    #[test]
    fn a_difference_must_be_material_and_beyond_its_sigma() {
        let a = read([1.0, 0.5, 0.0, 0.0, 0.0, 0.0], 0.05);
        let b = read([2.0, 0.6, 0.0, -0.5, 0.25, 0.0], 0.05);
        let d = differences(&a, &b);
        let names: Vec<&str> = d.iter().map(|d| d.param).collect();
        assert_eq!(names, ["D_GC", "D_ET"]);
        assert!((d[0].difference + 1.0).abs() < 1e-12);
        assert!((d[0].sigma - 0.05f64.hypot(0.05)).abs() < 1e-12);
        // The same 1-point miss with σ 0.4 on each part: 1.77σ, not reported.
        assert!(differences(&read([1.0; 6], 0.4), &read([2.0; 6], 0.4)).is_empty());
        let split = PhaseSplit {
            to_load: a,
            steady: b,
            differ: d,
        };
        assert!(split
            .statement()
            .contains("D_GC +1.00 vs +2.00 (-1.00 ± 0.07)"));
    }
}
