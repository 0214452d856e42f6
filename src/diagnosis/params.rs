//! The fitted parameters of a diagnosis: a list of named, bounded parameters ([`FitParam`]),
//! each addressing a health parameter, the ambient pressure (a nuisance parameter), an
//! engine-file value or an effect parameter ([`ParamTarget`]); the map from the optimiser's
//! vector to what the model needs ([`ParamMap`]); and why a model evaluation failed
//! ([`EvalError`], tallied by [`FailureLog`]).
//!
//! Engine-file and effect values are applied with `Engine::set_param` on a copy of the engine,
//! so calibration and the gap tool fit them with the same [`super::fit`] as health. Pure: no
//! I/O, no globals. Must not run the optimiser: it only maps its vector to model inputs.

use crate::engine::Engine;
use crate::health::{HealthBounds, HealthParams, HEALTH_NAMES};
use crate::optim::Bounds;
use crate::signals::Signal;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use super::DiagnosisError;

/// Half-width of the ambient-pressure search interval around its first estimate, kPa.
pub const AMBIENT_HALF_RANGE_KPA: f64 = 1.0;

/// What a fitted parameter sets.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamTarget {
    /// A health parameter, by index into [`HEALTH_NAMES`], %.
    Health(usize),
    /// The ambient pressure, kPa (nuisance parameter; the replay reads it from P1 at rest).
    AmbientPressure,
    /// An engine-file value by its dotted key, e.g. `dynamics.gg_inertia_kg_m2`.
    EngineValue(String),
    /// A parameter of an optional effect: engine-file key `effects.<effect>.<param>`.
    Effect { effect: String, param: String },
}

impl ParamTarget {
    /// The dotted engine-file key of an engine or effect value (`None` for health/ambient).
    pub fn engine_key(&self) -> Option<String> {
        match self {
            ParamTarget::EngineValue(k) => Some(k.clone()),
            ParamTarget::Effect { effect, param } => Some(format!("effects.{effect}.{param}")),
            _ => None,
        }
    }
}

/// One fitted parameter: its name in reports, its bounds and what it sets.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitParam {
    pub name: String,
    pub lower: f64,
    pub upper: f64,
    pub target: ParamTarget,
}

impl FitParam {
    /// Health parameter `index` (into [`HEALTH_NAMES`]) within the default [`HealthBounds`].
    pub fn health(index: usize) -> Result<FitParam, DiagnosisError> {
        FitParam::health_within(index, &HealthBounds::default())
    }

    /// Health parameter `index` (into [`HEALTH_NAMES`]) within its interval of `bounds`.
    pub fn health_within(index: usize, bounds: &HealthBounds) -> Result<FitParam, DiagnosisError> {
        let name = HEALTH_NAMES.get(index).ok_or_else(|| {
            DiagnosisError::Config(format!("health parameter index {index} is not 0…5"))
        })?;
        let (lower, upper) = bounds.of(index);
        Ok(FitParam {
            name: (*name).to_string(),
            lower,
            upper,
            target: ParamTarget::Health(index),
        })
    }

    /// The ambient pressure within `p0` ± [`AMBIENT_HALF_RANGE_KPA`].
    pub fn ambient_pressure(p0: f64) -> FitParam {
        FitParam {
            name: "ambient_pressure_kpa".into(),
            lower: p0 - AMBIENT_HALF_RANGE_KPA,
            upper: p0 + AMBIENT_HALF_RANGE_KPA,
            target: ParamTarget::AmbientPressure,
        }
    }

    /// An engine-file value (dotted key) within `[lower, upper]`.
    pub fn engine_value(key: &str, lower: f64, upper: f64) -> FitParam {
        FitParam {
            name: key.to_string(),
            lower,
            upper,
            target: ParamTarget::EngineValue(key.to_string()),
        }
    }

    /// An effect parameter (`effects.<effect>.<param>`) within `[lower, upper]`.
    pub fn effect(effect: &str, param: &str, lower: f64, upper: f64) -> FitParam {
        FitParam {
            name: format!("effects.{effect}.{param}"),
            lower,
            upper,
            target: ParamTarget::Effect {
                effect: effect.to_string(),
                param: param.to_string(),
            },
        }
    }
}

/// Why one model evaluation failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EvalError {
    /// The engine model failed (simulation or steady solve).
    #[error("engine model: {0}")]
    Model(String),
    /// A parameter could not be applied (e.g. `Engine::set_param` refused the value).
    #[error("parameter {name}: {reason}")]
    Param { name: String, reason: String },
    /// The model produced a non-finite value where a measurement is compared.
    #[error("model value of {signal} is not finite at sample {sample}")]
    NonFinite { signal: Signal, sample: usize },
    /// The model produced fewer samples than the data have.
    #[error("model produced {got} of {want} samples")]
    Short { got: usize, want: usize },
}

/// Tally of failed evaluations by reason (the summary names the [`FailureLog::MAX_REASONS`]
/// most frequent texts and counts the rest under "other"). Every distinct text is counted
/// (at most one per evaluation, so bounded by the fit's budget) and the cut is made only in the
/// summary: which texts are named must not depend on the order parallel evaluations failed in,
/// or a stored reason would depend on the fit's thread count.
#[derive(Debug, Default)]
pub struct FailureLog {
    total: AtomicUsize,
    reasons: Mutex<BTreeMap<String, usize>>,
}

/// Failed evaluations of a fit, as reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Failures {
    /// Evaluations that failed (counted in `model_runs` too).
    pub count: usize,
    /// Reason → how often.
    pub reasons: BTreeMap<String, usize>,
}

impl FailureLog {
    /// Distinct reason texts kept.
    pub const MAX_REASONS: usize = 8;

    /// Records one failure.
    pub fn record(&self, e: &EvalError) {
        self.total.fetch_add(1, Ordering::Relaxed);
        if let Ok(mut m) = self.reasons.lock() {
            *m.entry(e.to_string()).or_insert(0) += 1;
        }
    }

    /// The tally so far: the most frequent texts (ties in text order), the rest as "other".
    pub fn summary(&self) -> Failures {
        let all = self.reasons.lock().map(|m| m.clone()).unwrap_or_default();
        let mut by_count: Vec<(String, usize)> = all.into_iter().collect();
        // Stable sort of a text-ordered list: equal counts stay in text order.
        by_count.sort_by_key(|e| std::cmp::Reverse(e.1));
        let mut reasons = BTreeMap::new();
        for (k, (text, n)) in by_count.into_iter().enumerate() {
            let key = if k < Self::MAX_REASONS {
                text
            } else {
                "other".into()
            };
            *reasons.entry(key).or_insert(0) += n;
        }
        Failures {
            count: self.total.load(Ordering::Relaxed),
            reasons,
        }
    }
}

/// What one optimiser vector means for the model.
#[derive(Debug, Clone, PartialEq)]
pub struct Applied {
    pub health: HealthParams,
    /// Fitted ambient pressure, kPa (`None` = not fitted).
    pub ambient_kpa: Option<f64>,
    /// Engine-file / effect values to set: (dotted key, value).
    pub engine_values: Vec<(String, f64)>,
}

/// Maps the optimiser's vector (one entry per [`FitParam`], in order) to health, ambient
/// pressure and engine values; parameters not fitted stay at `base` / the engine's values.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamMap {
    params: Vec<FitParam>,
    /// Start value per parameter for the non-health ones (health starts at the given vector).
    start: Vec<f64>,
    base: [f64; 6],
    bounds: Bounds,
}

impl ParamMap {
    /// A map of `params`, each non-health parameter starting at `start[i]` (clamped into its
    /// bounds; health parameters start from the vector given to [`ParamMap::project`]).
    /// Names must be unique, bounds finite with lower < upper, and at least one parameter.
    pub fn new(
        params: Vec<FitParam>,
        base: HealthParams,
        start: Vec<f64>,
    ) -> Result<ParamMap, DiagnosisError> {
        if params.is_empty() {
            return Err(DiagnosisError::Data("no free parameter to fit".into()));
        }
        if start.len() != params.len() {
            return Err(DiagnosisError::Config(format!(
                "{} start values for {} parameters",
                start.len(),
                params.len()
            )));
        }
        for (i, p) in params.iter().enumerate() {
            if params[..i]
                .iter()
                .any(|q| q.name == p.name || q.target == p.target)
            {
                return Err(DiagnosisError::Config(format!(
                    "parameter '{}' is fitted twice",
                    p.name
                )));
            }
        }
        let bounds = Bounds::new(
            params.iter().map(|p| p.lower).collect(),
            params.iter().map(|p| p.upper).collect(),
        )
        .map_err(|e| {
            DiagnosisError::Config(format!(
                "bounds of [{}]: {e}",
                params
                    .iter()
                    .map(|p| p.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })?;
        let start = params
            .iter()
            .zip(start)
            .map(|(p, s)| {
                if s.is_finite() {
                    s.clamp(p.lower, p.upper)
                } else {
                    p.lower
                }
            })
            .collect();
        Ok(ParamMap {
            params,
            start,
            base: base.to_array(),
            bounds,
        })
    }

    /// The classic diagnosis map: free health parameters `free` (indices into
    /// [`HEALTH_NAMES`]) within `bounds`, the others at `base`, then the ambient pressure when
    /// `ambient0` is given, then `extra` parameters starting at the engine's current values.
    pub fn for_diagnosis(
        free: &[usize],
        base: HealthParams,
        bounds: &HealthBounds,
        ambient0: Option<f64>,
        extra: &[FitParam],
        engine: &Engine,
    ) -> Result<ParamMap, DiagnosisError> {
        let mut params = Vec::new();
        let mut start = Vec::new();
        for &i in free {
            params.push(FitParam::health_within(i, bounds)?);
            // A start outside a narrowed interval would be refused by the optimiser.
            let (lo, hi) = bounds.of(i);
            start.push(base.to_array()[i].clamp(lo, hi));
        }
        if let Some(p) = ambient0 {
            params.push(FitParam::ambient_pressure(p));
            start.push(p);
        }
        for p in extra {
            let key = p.target.engine_key().ok_or_else(|| {
                DiagnosisError::Config(format!(
                    "extra parameter '{}' must address an engine-file or effect value",
                    p.name
                ))
            })?;
            let v = super::engine_param(engine, &key).map_err(|reason| {
                DiagnosisError::Config(format!("parameter '{}': {reason}", p.name))
            })?;
            params.push(p.clone());
            start.push(v);
        }
        ParamMap::new(params, base, start)
    }

    /// The parameters, in the optimiser's order.
    pub fn params(&self) -> &[FitParam] {
        &self.params
    }

    /// What `x` sets.
    pub fn apply(&self, x: &[f64]) -> Applied {
        let mut h = self.base;
        let mut ambient_kpa = None;
        let mut engine_values = Vec::new();
        for (p, &v) in self.params.iter().zip(x) {
            match &p.target {
                ParamTarget::Health(i) => h[*i] = v,
                ParamTarget::AmbientPressure => ambient_kpa = Some(v),
                t => {
                    if let Some(k) = t.engine_key() {
                        engine_values.push((k, v));
                    }
                }
            }
        }
        Applied {
            health: HealthParams::from_array(h),
            ambient_kpa,
            engine_values,
        }
    }

    /// The full health vector for `x`.
    pub fn health(&self, x: &[f64]) -> HealthParams {
        self.apply(x).health
    }

    /// The fitted ambient pressure in `x`, kPa (`None` if not fitted).
    pub fn ambient(&self, x: &[f64]) -> Option<f64> {
        self.apply(x).ambient_kpa
    }

    /// The optimiser's start vector: health parameters from `h`, the others at their start.
    pub fn project(&self, h: &HealthParams) -> Vec<f64> {
        let a = h.to_array();
        self.params
            .iter()
            .zip(&self.start)
            .map(|(p, &s)| match p.target {
                ParamTarget::Health(i) => a[i],
                _ => s,
            })
            .collect()
    }

    /// Box bounds of the optimiser's vector.
    pub fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    /// Indices (into [`HEALTH_NAMES`]) of the free health parameters, in order.
    pub fn free(&self) -> Vec<usize> {
        self.params
            .iter()
            .filter_map(|p| match p.target {
                ParamTarget::Health(i) => Some(i),
                _ => None,
            })
            .collect()
    }

    /// Whether any parameter needs a modified engine (engine-file or effect values).
    pub fn touches_engine(&self) -> bool {
        self.params.iter().any(|p| p.target.engine_key().is_some())
    }

    /// A copy of `engine` with the engine-file / effect values of `applied` set.
    pub fn engine_for(&self, engine: &Engine, applied: &Applied) -> Result<Engine, EvalError> {
        let mut e = engine.clone();
        for (key, v) in &applied.engine_values {
            super::set_engine_param(&mut e, key, *v).map_err(|reason| EvalError::Param {
                name: key.clone(),
                reason,
            })?;
        }
        Ok(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_parameters_map_in_order_and_refuse_nonsense() {
        let base = HealthParams {
            D_GT: 2.0,
            ..HealthParams::HEALTHY
        };
        let m = ParamMap::for_diagnosis(
            &[0, 1],
            base,
            &HealthBounds::default(),
            Some(101.0),
            &[],
            &Engine::reference().expect("engine"),
        )
        .expect("map");
        let names: Vec<&str> = m.params().iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["D_GC", "D_EC", "ambient_pressure_kpa"]);
        assert_eq!(m.bounds().dim(), 3);
        let a = m.apply(&[3.0, 1.0, 100.5]);
        assert_eq!(a.health.D_GC, 3.0);
        assert_eq!(a.health.D_GT, 2.0); // not fitted: base
        assert_eq!(a.ambient_kpa, Some(100.5));
        assert!(a.engine_values.is_empty());
        assert_eq!(m.project(&base), vec![0.0, 0.0, 101.0]);
        assert_eq!(m.free(), vec![0, 1]);
        assert!(!m.touches_engine());
        // Engine and effect targets carry their dotted keys.
        let fx = FitParam::effect("fuel_system", "tau_s", 0.0, 2.0);
        assert_eq!(
            fx.target.engine_key().as_deref(),
            Some("effects.fuel_system.tau_s")
        );
        let m = ParamMap::new(
            vec![
                FitParam::health(2).expect("D_GT"),
                FitParam::engine_value("dynamics.gg_inertia_kg_m2", 10.0, 20.0),
            ],
            HealthParams::HEALTHY,
            vec![0.0, 99.0],
        )
        .expect("map");
        // Start clamped into the bounds.
        assert_eq!(m.project(&HealthParams::HEALTHY), vec![0.0, 20.0]);
        assert_eq!(
            m.apply(&[1.0, 12.0]).engine_values,
            vec![("dynamics.gg_inertia_kg_m2".to_string(), 12.0)]
        );
        assert!(m.touches_engine());
        // Nonsense: twice the same parameter, empty, inverted bounds, bad index.
        let twice = vec![
            FitParam::health(0).expect("ok"),
            FitParam::health(0).expect("ok"),
        ];
        let e = ParamMap::new(twice, HealthParams::HEALTHY, vec![0.0; 2]).expect_err("twice");
        assert!(e.to_string().contains("fitted twice"), "{e}");
        assert!(ParamMap::new(vec![], HealthParams::HEALTHY, vec![]).is_err());
        let inverted = vec![FitParam::engine_value("x.y", 2.0, 1.0)];
        let e = ParamMap::new(inverted, HealthParams::HEALTHY, vec![1.5]).expect_err("bounds");
        assert!(e.to_string().contains("x.y"), "{e}");
        assert!(FitParam::health(6).is_err());
    }

    #[test]
    fn failure_log_counts_reasons() {
        let log = FailureLog::default();
        for _ in 0..3 {
            log.record(&EvalError::Model("step size underflow".into()));
        }
        log.record(&EvalError::Short { got: 1, want: 2 });
        let s = log.summary();
        assert_eq!(s.count, 4);
        assert_eq!(s.reasons["engine model: step size underflow"], 3);
        assert_eq!(s.reasons.len(), 2);
        for i in 0..20 {
            log.record(&EvalError::Model(format!("t = {i}")));
        }
        let s = log.summary();
        assert_eq!(s.count, 24);
        assert_eq!(s.reasons.len(), FailureLog::MAX_REASONS + 1);
        assert!(s.reasons["other"] > 0);
    }

    /// Parallel evaluations fail in any order: the summary must not show which came first.
    #[test]
    fn failure_log_summary_does_not_depend_on_the_order() {
        let errors: Vec<EvalError> = (0..30)
            .map(|i| EvalError::Model(format!("t = {}", i % 12)))
            .collect();
        let (forward, backward) = (FailureLog::default(), FailureLog::default());
        errors.iter().for_each(|e| forward.record(e));
        errors.iter().rev().for_each(|e| backward.record(e));
        let s = forward.summary();
        assert_eq!(s, backward.summary());
        assert_eq!(s.count, 30);
        assert_eq!(s.reasons.len(), FailureLog::MAX_REASONS + 1);
        // t = 0 … 5 failed three times, t = 6 … 11 twice: the six most frequent are named.
        assert_eq!(s.reasons["engine model: t = 0"], 3);
        assert_eq!(s.reasons.values().sum::<usize>(), 30);
    }
}
