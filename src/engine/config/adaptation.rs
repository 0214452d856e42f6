//! The engine file's `[adaptation]` section: one unit's off-design corrections of the component
//! maps, as knots of modification curves over each component's relative corrected speed
//! (`maps::adapt` evaluates them; `gtwatch calibrate --adapt` fits them).
//!
//! ```toml
//! [adaptation.compressor]
//! speed_knots = [0.70, 0.80, 0.90]      # relative corrected speed, design = 1 (implicit anchor)
//! speed = [0.04, 0.02, 0.01]            # speed line read: n·(1 + f)
//! flow = [0.0, 0.0, 0.0]                # corrected flow × (1 + f)
//! efficiency = [-0.01, 0.0, 0.0]        # isentropic efficiency × (1 + f)
//! pressure_ratio = [0.0, 0.0, 0.0]      # (PR − 1) × (1 + f)
//! [adaptation.hpt]                      # flow, efficiency
//! [adaptation.pt]                       # flow, efficiency
//! ```
//!
//! `[adaptation.model_error_pct]` (written by `calibrate --adapt`, or set by hand) states, per
//! compared signal (CSV name, e.g. `n1_rpm = 0.4`), the 1σ of the adapted model's own error in
//! % of the value: how well it predicted operating points left out of its calibration. Steady
//! diagnosis adds it to the instrument's noise σ, so a signal the model predicts no better than
//! that is weighted for what the model can do, not for what the instrument can.
//!
//! Every curve passes through 0 at relative speed 1 (the design point the `[design]` table
//! fixes stays exact), so a knot may not sit at 1. A curve left out is no correction.
//! What it must not do: physics (only the shape of the numbers is checked here).

use crate::signals::Signal;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The corrections of one component.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ComponentCurves {
    /// Relative corrected speeds of the knots, strictly increasing, none within 0.01 of 1.
    pub speed_knots: Vec<f64>,
    /// Fractional correction of the corrected flow at each knot.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub flow: Vec<f64>,
    /// Fractional correction of the isentropic efficiency at each knot.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub efficiency: Vec<f64>,
    /// Fractional correction of (PR − 1) at each knot (compressor only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pressure_ratio: Vec<f64>,
    /// Fractional re-labelling of the speed line read at each knot (compressor only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub speed: Vec<f64>,
}

/// The `[adaptation]` section.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdaptationConfig {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compressor: Option<ComponentCurves>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hpt: Option<ComponentCurves>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pt: Option<ComponentCurves>,
    /// 1σ of the adapted model's own error per signal (CSV name), % of the value.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub model_error_pct: BTreeMap<String, f64>,
}

/// Largest model error a file may state, % of the value: beyond it the model predicts nothing.
pub const MAX_MODEL_ERROR_PCT: f64 = 20.0;

/// Model error at which a signal no longer tells health, % of the value: a point of any
/// component's degradation moves a gas-path signal by a few tenths of a percent (the power or
/// torque at a given fuel flow by a percent or two), so a model that predicts the signal no
/// better than 2 % between its own calibration points leaves it a point or more of health of
/// slack; a diagnosis resting on such signals cannot be `good` (its residual is small because
/// the σ is large, not because the model fits). Measured: a foreign unit the adaptation
/// predicts within 0.7 % on every signal reads a degradation grid within 0.62 points; one it
/// predicts 2.5–5.6 % off on six signals read it up to 2.3 points off at residuals of 0.2.
pub const UNRESOLVING_MODEL_ERROR_PCT: f64 = 2.0;

impl AdaptationConfig {
    /// The signals (CSV name) whose stated model error is at least
    /// [`UNRESOLVING_MODEL_ERROR_PCT`], with it (%).
    pub fn unresolving_signals(&self) -> Vec<(String, f64)> {
        self.model_error_pct
            .iter()
            .filter(|(_, v)| **v >= UNRESOLVING_MODEL_ERROR_PCT)
            .map(|(k, v)| (k.clone(), *v))
            .collect()
    }

    /// The model's own 1σ error of signal `s` as a fraction of its value (0 when not stated).
    pub fn model_error_fraction(&self, s: Signal) -> f64 {
        self.model_error_pct
            .get(s.column())
            .map_or(0.0, |pct| pct / 100.0)
    }
}

/// The components, by their key in the section.
pub const COMPONENTS: [&str; 3] = ["compressor", "hpt", "pt"];

/// The curves of each component, by their key: the compressor has all four, the turbines flow
/// and efficiency.
pub fn curves_of(component: &str) -> &'static [&'static str] {
    match component {
        "compressor" => &["speed", "flow", "efficiency", "pressure_ratio"],
        _ => &["flow", "efficiency"],
    }
}

impl ComponentCurves {
    /// The values of curve `name` (empty when absent or unknown).
    pub fn curve(&self, name: &str) -> &[f64] {
        match name {
            "flow" => &self.flow,
            "efficiency" => &self.efficiency,
            "pressure_ratio" => &self.pressure_ratio,
            "speed" => &self.speed,
            _ => &[],
        }
    }

    /// Mutable access to curve `name`.
    pub fn curve_mut(&mut self, name: &str) -> Option<&mut Vec<f64>> {
        match name {
            "flow" => Some(&mut self.flow),
            "efficiency" => Some(&mut self.efficiency),
            "pressure_ratio" => Some(&mut self.pressure_ratio),
            "speed" => Some(&mut self.speed),
            _ => None,
        }
    }
}

impl AdaptationConfig {
    /// Component `name`'s curves.
    pub fn component(&self, name: &str) -> Option<&ComponentCurves> {
        match name {
            "compressor" => self.compressor.as_ref(),
            "hpt" => self.hpt.as_ref(),
            "pt" => self.pt.as_ref(),
            _ => None,
        }
    }

    /// Mutable slot of component `name`.
    pub fn component_mut(&mut self, name: &str) -> Option<&mut Option<ComponentCurves>> {
        match name {
            "compressor" => Some(&mut self.compressor),
            "hpt" => Some(&mut self.hpt),
            "pt" => Some(&mut self.pt),
            _ => None,
        }
    }

    /// `Err((key, reason))` for the first malformed component: knots not strictly increasing,
    /// a knot at the design speed, a curve whose length differs from the knots', a curve the
    /// component does not have.
    pub fn check(&self) -> Result<(), (String, String)> {
        // The values' range (0–MAX_MODEL_ERROR_PCT) is `param_range`'s, checked with every
        // number of the file.
        for name in self.model_error_pct.keys() {
            if !Signal::ALL.iter().any(|s| s.column() == name) {
                return Err((
                    format!("adaptation.model_error_pct.{name}"),
                    "is no signal's CSV name (e.g. n1_rpm, t34_k)".into(),
                ));
            }
        }
        for name in COMPONENTS {
            let Some(c) = self.component(name) else {
                continue;
            };
            let key = |k: &str| format!("adaptation.{name}.{k}");
            if c.speed_knots.is_empty() {
                return Err((key("speed_knots"), "needs at least one knot".into()));
            }
            if c.speed_knots.windows(2).any(|w| w[1] <= w[0]) {
                return Err((key("speed_knots"), "must be strictly increasing".into()));
            }
            if let Some(k) = c.speed_knots.iter().find(|k| (**k - 1.0).abs() < 0.01) {
                return Err((
                    key("speed_knots"),
                    format!(
                        "knot {k} is at the design speed, where every curve is 0 by \
                         construction; leave it out"
                    ),
                ));
            }
            for curve in ["speed", "flow", "efficiency", "pressure_ratio"] {
                let v = c.curve(curve);
                if v.is_empty() {
                    continue;
                }
                if !curves_of(name).contains(&curve) {
                    return Err((key(curve), format!("a {name} has no `{curve}` curve")));
                }
                if v.len() != c.speed_knots.len() {
                    return Err((
                        key(curve),
                        format!(
                            "has {} values for {} speed_knots",
                            v.len(),
                            c.speed_knots.len()
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::engine::config::{EngineConfig, REFERENCE_ENGINE_TOML};
    use crate::engine::steady::{solve, Demand, SteadyInputs};
    use crate::engine::Engine;
    use crate::health::HealthParams;

    fn with(section: &str) -> Result<EngineConfig, String> {
        let text = format!("{REFERENCE_ENGINE_TOML}\n{section}\n");
        EngineConfig::from_toml_str(&text, "x.toml").map_err(|e| e.to_string())
    }

    #[test]
    fn malformed_sections_name_the_key() {
        for (section, key) in [
            (
                "[adaptation.compressor]\nspeed_knots = [0.8, 0.7]\nflow = [0.1, 0.1]",
                "adaptation.compressor.speed_knots",
            ),
            (
                "[adaptation.compressor]\nspeed_knots = [0.8, 1.0]\nflow = [0.1, 0.1]",
                "adaptation.compressor.speed_knots",
            ),
            (
                "[adaptation.hpt]\nspeed_knots = [0.8]\nflow = [0.1, 0.1]",
                "adaptation.hpt.flow",
            ),
            (
                "[adaptation.pt]\nspeed_knots = [0.8]\npressure_ratio = [0.1]",
                "adaptation.pt.pressure_ratio",
            ),
            (
                "[adaptation.pt]\nspeed_knots = [0.8]\nflow = [0.9]",
                "adaptation.pt.flow",
            ),
            (
                "[adaptation.model_error_pct]\nn1 = 0.3",
                "adaptation.model_error_pct.n1",
            ),
            (
                "[adaptation.model_error_pct]\nt34_k = -0.3",
                "adaptation.model_error_pct.t34_k",
            ),
            (
                "[adaptation.model_error_pct]\nt34_k = 30.0",
                "adaptation.model_error_pct.t34_k",
            ),
        ] {
            let err = with(section).expect_err(section);
            assert!(err.contains(key), "{section}: {err}");
        }
    }

    #[test]
    fn the_design_point_stays_and_part_load_moves() {
        let plain = Engine::new(EngineConfig::reference()).expect("reference");
        let cfg = with(
            "[adaptation.compressor]\nspeed_knots = [0.7, 0.85]\nspeed = [0.05, 0.02]\n\
             efficiency = [-0.02, -0.01]",
        )
        .expect("loads");
        let adapted = Engine::new(cfg).expect("adapted");
        assert_eq!(plain.design(), adapted.design());
        let inp = |mw: f64| SteadyInputs {
            t_amb_k: 288.15,
            p_amb_kpa: 101.325,
            n2_rpm: 3600.0,
            demand: Demand::PowerMw(mw),
        };
        let h = HealthParams::HEALTHY;
        let a = solve(&plain.model(&h), &inp(31.4), None).expect("design");
        let b = solve(&adapted.model(&h), &inp(31.4), None).expect("design");
        assert!((a.stations.n1_rpm / b.stations.n1_rpm - 1.0).abs() < 1e-6);
        let a = solve(&plain.model(&h), &inp(10.0), None).expect("part load");
        let b = solve(&adapted.model(&h), &inp(10.0), None).expect("part load");
        // The speed line read is re-labelled upwards: the same flow at a lower speed.
        assert!(b.stations.n1_rpm < a.stations.n1_rpm - 50.0, "{a:?} {b:?}");
    }
}
