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
//! speed_of = "gg_inlet"                 # knots in the GG's corrected speed (see below)
//! [adaptation.pt]                       # flow, efficiency
//! efficiency_shape = "curve"            # the map's efficiency held (see below)
//! ```
//!
//! `speed_of` says which corrected speed a component's knots are in. `own_inlet` (the default):
//! the component's own, its shaft speed over √ of its inlet temperature, relative to the
//! design point's. `gg_inlet` (the HP turbine only): the gas generator's corrected speed at the
//! compressor inlet, n1/√(T1/T1_design) over the design's. `calibrate --adapt` writes it where
//! the HP turbine's own speed made the adapted model depart from similarity
//! (`calibrate::adapt::Similarity`), or moved it further from similarity than the GG's did when
//! the fit was run again to keep the compressor on its map (`calibrate::adapt::OperatingLine`;
//! on the unit below 1.15 % against 0.69 %, and a healthy day read `poor` against `good`): its
//! flow and efficiency set the combustor exit temperature
//! T3 through the GG's power balance, and T3 is in its own corrected speed, so curves over that
//! speed feed back into their own argument. On a foreign unit with pyCycle's compressor map
//! under md22's file the adapted model then gave, at one corrected GG and PT speed, T34/T1
//! 3.230 at 253 K and 3.107 at 308 K where the unit gives 3.101 and 3.091; on the unit of
//! `tests/foreign_ambient.rs`, healthy days whose ambient and load paired otherwise than on the
//! baseline's read D_GC +1.8…+2.9, `poor`. Over the GG's inlet-corrected speed (an input of
//! every point) the curves have no such loop: the same days read within 0.52 points, `good`
//! (within 0.39 with the compressor kept on its map).
//! Along the healthy operating line the two speeds map one to one, so the curves are as
//! expressive there; the HPT's own speed stays the first choice because on the other foreign
//! units it gives their figures (the GG's moved them, not always for the better). Files
//! written before `speed_of` existed keep their meaning (own inlet).
//!
//! `efficiency_shape` (turbines only) says what shapes a turbine's efficiency away from the
//! design point. `map` (the default): the map's own efficiency at each point, times the
//! efficiency curve. `curve`: the map's efficiency held at its value at the design point, so the
//! efficiency curve alone shapes it over corrected speed (and the map's change of efficiency
//! with pressure ratio is dropped). A map borrowed from another make brings its own fall-off
//! of efficiency with speed: the independent simulator's unit (`tests/data/foreign/indep30`)
//! runs its power turbine at 0.903–0.905 from 30 % to 100 % load where md22's PT map, scaled
//! to the same design point, gives 0.843 at the lowest load, and the curve undoing that
//! fall-off is bent beyond what its smoothness and the data allow. `calibrate --adapt` writes `curve` where a
//! turbine's fitted efficiency curve moves the map by more than
//! [`EFFICIENCY_SHAPE_TRY_FRACTION`] and the fit with the map's efficiency held predicts its
//! own left-out points better (`calibrate::adapt` docs).
//!
//! `[adaptation.model_error_pct]` (written by `calibrate --adapt`, or set by hand) states, per
//! compared signal (CSV name, e.g. `n1_rpm = 0.4`), the 1σ of the adapted model's own error in
//! % of the value: how well it predicted operating points left out of its calibration. Steady
//! diagnosis adds it to the instrument's noise σ, and Method B to each compared sample's, so a
//! signal the model predicts no better than that is weighted for what the model can do, not
//! for what the instrument can.
//!
//! `[adaptation.model_error_by_speed]` (written with it) states the same where it varies along
//! the operating line: `speed_knots` (relative corrected GG speed, n1/√(T1/T1_design) over the
//! design's) and per signal one % per knot, interpolated linearly between knots; beyond them
//! the end segment's line where it rises outward, else the end value (the knots are the
//! interior calibration points; the lowest and highest load lie beyond them). A map borrowed
//! from another make is bent furthest at low speed, and predicts worst there; weighting every
//! point by the one average error gives the low loads a say the model cannot back. Where a
//! signal has no row here, `model_error_pct` holds at every speed.
//!
//! `[adaptation.health_error]` (written with them, or set by hand) states, per health parameter
//! (`D_GC = 0.12`), the 1σ of the adapted model's own error in health points: what a healthy
//! unit reads at loads the curves were not fitted to (estimated by refitting the final curves
//! without each of interleaved parts of the interior loads and diagnosing that part). Steady diagnosis adds it to each
//! parameter's σ, so a parameter the adapted model cannot tell apart from its own error is not
//! called separable however small the residual is.
//!
//! `[adaptation.ensemble]` (written by `calibrate --ensemble`) lists `files`: engine files of
//! the same unit calibrated on the baseline with a part of its loads left out each. They fit
//! the baseline as well as this file and differ off the healthy line, where the baseline does
//! not reach; steady snapshot diagnosis reads every group with each of them too and states
//! the spread of the reads (`diagnosis::ensemble`).
//!
//! `[adaptation.calibrated]` (written with them) states the reach of the calibration:
//! `gg_speed = [lo, hi]`, the relative corrected GG speeds of its lowest and highest operating
//! point. Steady diagnosis leaves out a snapshot beyond them by more than
//! [`CALIBRATED_MARGIN`], with the reason: there the curves are extrapolated (above the design
//! anchor they go on with its slope) and the model's own error was never measured. A unit
//! calibrated on a summer baseline meets this on a cold day at full load, and a fouled GG
//! turns faster than its healthy one did.
//!
//! Every curve passes through 0 at relative speed 1 (the design point the `[design]` table
//! fixes stays exact), so a knot may not sit at 1. A curve left out is no correction.
//! What it must not do: physics (only the shape of the numbers is checked here).

use super::offline_shape::OfflineShape;
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
    /// Which corrected speed the knots are in (absent: the component's own).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_of: Option<SpeedOf>,
    /// What shapes a turbine's efficiency away from the design point (absent: the map).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub efficiency_shape: Option<EfficiencyShape>,
}

/// What shapes a turbine's efficiency away from the design point (module docs).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EfficiencyShape {
    /// The map's efficiency at each point, times the efficiency curve.
    #[default]
    Map,
    /// The map's efficiency held at its design-point value; the efficiency curve alone.
    Curve,
}

impl EfficiencyShape {
    /// The word the engine file uses.
    pub fn name(self) -> &'static str {
        match self {
            EfficiencyShape::Map => "map",
            EfficiencyShape::Curve => "curve",
        }
    }
}

/// A turbine's fitted efficiency curve that moves the map's efficiency by more than this
/// fraction at some knot is working against the map's own efficiency shape, and
/// `calibrate --adapt` fits the unit again with the map's efficiency held
/// ([`EfficiencyShape::Curve`]). Below it the map's shape serves (on our own twins the curves
/// stay within a few tenths of a percent).
pub const EFFICIENCY_SHAPE_TRY_FRACTION: f64 = 0.01;

/// The corrected speed a component's adaptation knots are in (module docs).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SpeedOf {
    /// The component's own: shaft speed over √ of its inlet temperature.
    #[default]
    OwnInlet,
    /// The gas generator's at the compressor inlet (HP turbine only).
    GgInlet,
}

impl SpeedOf {
    /// The word the engine file uses.
    pub fn name(self) -> &'static str {
        match self {
            SpeedOf::OwnInlet => "own_inlet",
            SpeedOf::GgInlet => "gg_inlet",
        }
    }
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
    /// The same along the operating line, where it varies with GG speed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_error_by_speed: Option<ModelErrorBySpeed>,
    /// How far the calibration reached (written by `calibrate --adapt`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibrated: Option<CalibratedRange>,
    /// 1σ of the adapted model's own error in health units per health parameter (`D_GC` …),
    /// points: what a healthy unit at loads the curves were not fitted to reads.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub health_error: BTreeMap<String, f64>,
    /// Other calibrations of the same unit that fit parts of its baseline
    /// (`calibrate --ensemble`): steady diagnosis reads each snapshot group with them too and
    /// states the spread.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ensemble: Option<EnsembleFiles>,
    /// How uncertain the compressor map's slopes off the healthy line are
    /// ([`super::offline_shape`]); absent: the defaults, when the file has curves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offline_shape: Option<OfflineShape>,
}

/// `[adaptation.ensemble]`: the engine files of the calibrations on parts of the baseline.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnsembleFiles {
    /// Paths of engine files (a relative path is taken from this engine file's directory;
    /// `calibrate --ensemble` writes absolute ones).
    pub files: Vec<String>,
}

/// The operating range the adaptation was fitted on: beyond it the curves are extrapolated
/// and the model's own error is not known, so steady diagnosis leaves such a point out.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibratedRange {
    /// Relative corrected GG speed (n1/√(T1/T1_design) over the design's) of the calibration's
    /// lowest and highest operating point.
    pub gg_speed: [f64; 2],
}

/// How far beyond [`CalibratedRange::gg_speed`] (relative corrected GG speed) a point may run
/// and still count as calibrated. Measured on a generator unit of GSPy's maps adapted to
/// healthy loads up to 0.998 (`tests/gspy_adaptation.rs`): the healthy model missed the GG
/// speed by up to 0.24 % inside the range, 0.21 % at 0.005 beyond it, then 0.45 % at 0.008,
/// 0.85 % at 0.013 and 1.1 % at 0.017.
pub const CALIBRATED_MARGIN: f64 = 0.005;

impl CalibratedRange {
    /// Why a point at relative corrected GG speed `rel` is not diagnosed on these curves
    /// (`None` within the range and its margin).
    pub fn beyond(&self, rel: f64) -> Option<String> {
        let [lo, hi] = self.gg_speed;
        let (side, covers) = if rel < lo - CALIBRATED_MARGIN {
            (
                "below the lowest",
                "lower loads, or warmer days at the lowest",
            )
        } else if rel > hi + CALIBRATED_MARGIN {
            ("above the highest", "colder days at full load")
        } else {
            return None;
        };
        Some(format!(
            "relative corrected GG speed {rel:.3} is {side} the adapted model was calibrated at \
             ({lo:.3}…{hi:.3}, [adaptation.calibrated]): its curves are extrapolated there and \
             its own error is not known, so the point is left out; calibrate on a baseline \
             that covers it ({covers})"
        ))
    }
}

/// The adapted model's own error per signal at knots of relative corrected GG speed.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ModelErrorBySpeed {
    /// Relative corrected GG speeds (design = 1), strictly increasing.
    pub speed_knots: Vec<f64>,
    /// Per signal (CSV name): 1σ, % of the value, at each knot.
    #[serde(flatten)]
    pub pct: BTreeMap<String, Vec<f64>>,
}

impl ModelErrorBySpeed {
    /// Signal `s`'s error (%) at relative corrected GG speed `rel`: linear between knots;
    /// beyond them the end segment's line where it rises outward, else the end value (at most
    /// [`MAX_MODEL_ERROR_PCT`]); `None` when the table has no row for it.
    pub fn pct_at(&self, s: Signal, rel: f64) -> Option<f64> {
        let v = self.pct.get(s.column())?;
        let k = &self.speed_knots;
        if v.is_empty() || v.len() != k.len() {
            return None;
        }
        let last = k.len() - 1;
        if last == 0 {
            return Some(v[0]);
        }
        // Beyond the knots: the end segment's trend where it grows outward (the error rises
        // towards the end the map is bent most), else the end value.
        let i = k.partition_point(|x| *x <= rel).clamp(1, last);
        let w = (rel - k[i - 1]) / (k[i] - k[i - 1]);
        let line = v[i - 1] + w * (v[i] - v[i - 1]);
        let out = if rel < k[0] {
            line.max(v[0])
        } else if rel > k[last] {
            line.max(v[last])
        } else {
            line
        };
        Some(out.min(MAX_MODEL_ERROR_PCT))
    }
}

/// Largest model error a file may state, % of the value: beyond it the model predicts nothing.
pub const MAX_MODEL_ERROR_PCT: f64 = 20.0;

/// Largest model error in health units a file may state, points (the health parameters' own
/// default limits span 13).
pub const MAX_HEALTH_ERROR_PTS: f64 = 10.0;

impl AdaptationConfig {
    /// The model's own 1σ error of health parameter `index` (order of
    /// [`crate::health::HEALTH_NAMES`]), points (0 when not stated).
    /// The off-line slopes' σ steady diagnosis applies: the file's `[adaptation.offline_shape]`,
    /// else the defaults where a component has curves (a borrowed map bent to this unit), else
    /// none.
    pub fn offline_shape(&self) -> OfflineShape {
        match self.offline_shape {
            Some(s) => s,
            None if self.compressor.is_some() || self.hpt.is_some() || self.pt.is_some() => {
                OfflineShape::default()
            }
            None => OfflineShape::NONE,
        }
    }

    pub fn health_error_pts(&self, index: usize) -> f64 {
        crate::health::HEALTH_NAMES
            .get(index)
            .and_then(|n| self.health_error.get(*n))
            .copied()
            .unwrap_or(0.0)
    }
}

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
    /// [`UNRESOLVING_MODEL_ERROR_PCT`] at every one of `speeds` (the relative corrected GG
    /// speeds of the points a diagnosis rests on; `None` or none given: the average), with the
    /// smallest there (%): one point where the model predicts the signal well lets it tell
    /// health, however poorly the model does elsewhere.
    pub fn unresolving_signals(&self, speeds: &[Option<f64>]) -> Vec<(String, f64)> {
        let at: &[Option<f64>] = if speeds.is_empty() { &[None] } else { speeds };
        Signal::ALL
            .iter()
            .filter_map(|&s| {
                let best = at
                    .iter()
                    .map(|r| 100.0 * self.model_error_fraction(s, *r))
                    .fold(f64::INFINITY, f64::min);
                (best >= UNRESOLVING_MODEL_ERROR_PCT).then(|| (s.column().to_string(), best))
            })
            .collect()
    }

    /// The model's own 1σ error of signal `s` as a fraction of its value (0 when not stated)
    /// at relative corrected GG speed `rel` (`None`: not known, the average holds).
    pub fn model_error_fraction(&self, s: Signal, rel: Option<f64>) -> f64 {
        rel.zip(self.model_error_by_speed.as_ref())
            .and_then(|(rel, t)| t.pct_at(s, rel))
            .or_else(|| self.model_error_pct.get(s.column()).copied())
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
        for name in self.health_error.keys() {
            if !crate::health::HEALTH_NAMES.contains(&name.as_str()) {
                return Err((
                    format!("adaptation.health_error.{name}"),
                    format!(
                        "is no health parameter (one of {})",
                        crate::health::HEALTH_NAMES.join(", ")
                    ),
                ));
            }
        }
        if let Some(t) = &self.model_error_by_speed {
            let key = |k: &str| format!("adaptation.model_error_by_speed.{k}");
            check_knots(&t.speed_knots).map_err(|r| (key("speed_knots"), r))?;
            for (name, v) in &t.pct {
                if !Signal::ALL.iter().any(|s| s.column() == name) {
                    return Err((
                        key(name),
                        "is no signal's CSV name (e.g. n1_rpm, t34_k)".into(),
                    ));
                }
                check_length(v, &t.speed_knots).map_err(|r| (key(name), r))?;
            }
        }
        if let Some(e) = &self.ensemble {
            if e.files.is_empty() || e.files.iter().any(|f| f.trim().is_empty()) {
                return Err((
                    "adaptation.ensemble.files".into(),
                    "must name at least one engine file, none empty".into(),
                ));
            }
        }
        if let Some(c) = &self.calibrated {
            let [lo, hi] = c.gg_speed;
            if lo > hi {
                return Err((
                    "adaptation.calibrated.gg_speed".into(),
                    format!("the lowest speed {lo} is above the highest {hi}"),
                ));
            }
        }
        for name in COMPONENTS {
            let Some(c) = self.component(name) else {
                continue;
            };
            let key = |k: &str| format!("adaptation.{name}.{k}");
            if c.speed_of == Some(SpeedOf::GgInlet) && name != "hpt" {
                return Err((
                    key("speed_of"),
                    format!(
                        "`gg_inlet` is for the HP turbine's curves only (a {name}'s knots are in \
                         its own corrected speed: leave `speed_of` out)"
                    ),
                ));
            }
            if c.efficiency_shape == Some(EfficiencyShape::Curve) && name == "compressor" {
                return Err((
                    key("efficiency_shape"),
                    "`curve` is for a turbine's efficiency only (the compressor's follows its \
                     map: leave `efficiency_shape` out)"
                        .into(),
                ));
            }
            check_knots(&c.speed_knots).map_err(|r| (key("speed_knots"), r))?;
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
                check_length(v, &c.speed_knots).map_err(|r| (key(curve), r))?;
            }
        }
        Ok(())
    }
}

/// Why `knots` are no knots: none, or not strictly increasing.
fn check_knots(knots: &[f64]) -> Result<(), String> {
    if knots.is_empty() {
        return Err("needs at least one knot".into());
    }
    if knots.windows(2).any(|w| w[1] <= w[0]) {
        return Err("must be strictly increasing".into());
    }
    Ok(())
}

/// Why `values` do not go with `knots`: another count.
fn check_length(values: &[f64], knots: &[f64]) -> Result<(), String> {
    if values.len() == knots.len() {
        return Ok(());
    }
    Err(format!(
        "has {} values for {} speed_knots",
        values.len(),
        knots.len()
    ))
}

#[cfg(test)]
mod tests;
