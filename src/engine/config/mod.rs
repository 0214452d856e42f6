//! Engine configuration: the reference engine's constants, read from TOML.
//!
//! Every constant the model uses lives here with its unit in the key name, so a plant engineer
//! can describe another engine of the same architecture without touching code. The defaults are
//! the reference engine of REFERENCE §1–2 and are identical to `config/engine.toml`.
//! This module only parses and validates numbers; it does no physics.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

mod adaptation;
mod fuel;
mod load;
mod maps;
mod offline_shape;
mod ranges;
pub use adaptation::{
    curves_of, AdaptationConfig, CalibratedRange, ComponentCurves, EfficiencyShape, EnsembleFiles,
    ModelErrorBySpeed, SpeedOf, CALIBRATED_MARGIN, COMPONENTS, EFFICIENCY_SHAPE_TRY_FRACTION,
    MAX_HEALTH_ERROR_PTS, MAX_MODEL_ERROR_PCT, UNRESOLVING_MODEL_ERROR_PCT,
};
pub use fuel::{FuelConfig, FuelKind, GasComposition};
pub use load::{LoadConfig, LoadMode};
pub use maps::{inline_map_files, MapInterpolation, MapsConfig, MAP_FILE_AND_TEXT_KEYS};
pub use offline_shape::{
    OfflineShape, DEFAULT_EFFICIENCY_SLOPE_SIGMA, DEFAULT_FLOW_SLOPE_SIGMA, MAX_SLOPE_SIGMA,
};
pub use ranges::{param_range, ParamRange};

/// The built-in reference engine, embedded so `gtwatch simulate` works with no files at all.
pub const REFERENCE_ENGINE_TOML: &str = include_str!("../../../config/engine.toml");

/// Error loading an engine file.
#[derive(Debug, thiserror::Error)]
pub enum EngineConfigError {
    #[error("cannot read engine file {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("engine file {path}: {message}")]
    Parse { path: String, message: String },
    #[error("engine file {path}: key `{key}`: {reason}")]
    Invalid {
        path: String,
        key: String,
        reason: String,
    },
}

/// Ambient (ISO day by default).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AmbientConfig {
    pub temperature_k: f64,
    pub pressure_kpa: f64,
}

/// How a duct's total-pressure loss varies away from the design point. At the design point
/// both laws give the engine file's value.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PressureLossLaw {
    /// The loss scales with the square of the duct's corrected flow (inlet: W√T1/P_amb;
    /// combustor: W2√T2/P2; exhaust: the back-pressure excess with W√T34/P_amb) — a fixed
    /// loss coefficient times dynamic head. gtwatch's default.
    #[default]
    FlowSquared,
    /// A constant pressure ratio at every operating point (GSP/GSPy's duct and combustor
    /// default): inlet P1 = (1 − frac)·P_amb, combustor P3 = (1 − frac)·P2, exhaust
    /// P4 = ratio·P_amb.
    Constant,
    /// Exhaust only: the stack discharges to ambient through a fixed effective area (a
    /// peer's nozzle element, e.g. pyCycle's): W·√T/(A·P4) is the compressible flow function
    /// of P4/P_amb, choked beyond the critical ratio; the area is the one that gives the
    /// design back-pressure at the design flow. Nearly the flow-squared law at small
    /// excesses; apart from it where the excess is large or the flow far from design.
    Nozzle,
}

impl PressureLossLaw {
    /// Its name in the engine file.
    pub fn name(self) -> &'static str {
        match self {
            PressureLossLaw::FlowSquared => "flow_squared",
            PressureLossLaw::Constant => "constant",
            PressureLossLaw::Nozzle => "nozzle",
        }
    }
}

/// Design-point table and the cycle assumptions of REFERENCE §1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DesignConfig {
    pub pressure_ratio: f64,
    pub exhaust_flow_kg_s: f64,
    pub power_mw: f64,
    pub compressor_efficiency: f64,
    pub hpt_efficiency: f64,
    pub pt_efficiency: f64,
    pub gg_speed_rpm: f64,
    pub pt_speed_rpm: f64,
    /// Inlet total-pressure loss at design flow, fraction of ambient pressure.
    pub inlet_loss_frac: f64,
    /// How the inlet loss varies off design (default: with corrected flow squared).
    #[serde(default)]
    pub inlet_loss_law: PressureLossLaw,
    /// Combustor total-pressure loss at design, fraction of P2.
    pub combustor_loss_frac: f64,
    /// How the combustor loss varies off design (default: with corrected flow squared).
    #[serde(default)]
    pub combustor_loss_law: PressureLossLaw,
    /// Combustion efficiency, (0, 1].
    pub combustion_efficiency: f64,
    /// Methane's LHV, J/kg, fuel at 288.15 K: the fuel description from before `[fuel]`
    /// existed (results bit for bit as then). Absent when the file has a `[fuel]` section;
    /// with neither, methane by composition (see `config/fuel.rs`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fuel_lhv_j_per_kg: Option<f64>,
    /// Mechanical efficiency of the gas-generator shaft, (0, 1]: the HPT delivers its gas power
    /// times this to the compressor (GasTurb/GSP convention). The engine file may give the
    /// legacy `mechanical_efficiency` instead, which sets both shafts.
    pub gg_mechanical_efficiency: f64,
    /// Mechanical efficiency of the power-turbine shaft, (0, 1]: the PT delivers its gas power
    /// times this at its coupling, before windage and bearing losses.
    pub pt_mechanical_efficiency: f64,
    /// Exhaust static back-pressure at design flow, multiple of ambient pressure.
    pub exhaust_back_pressure_ratio: f64,
    /// How the exhaust back-pressure excess varies off design (default: with flow squared).
    #[serde(default)]
    pub exhaust_loss_law: PressureLossLaw,
    /// Compressor air bled overboard (cooling/leakage), fraction of compressor flow.
    pub cooling_bleed_frac: f64,
    /// Compressor-exit air that bypasses the combustor and the HP turbine and mixes into the
    /// gas at the HP-turbine exit (rotor and disc cooling, seal leakage returned), fraction of
    /// compressor flow: it does no work in the HPT, is measured in T34 and P34 as mixed, and
    /// works in the PT. Air returned before the HPT rotor (nozzle cooling) is not this: mixed
    /// before the work it is combustor air in a one-dimensional model. Default 0: every
    /// result as before the key existed.
    #[serde(default)]
    pub cooling_return_frac: f64,
}

fn default_min_gg_speed_fraction() -> f64 {
    0.5
}

fn default_pt_approach_tau_s() -> f64 {
    10.0
}

fn default_sync_slip_pct() -> f64 {
    0.25
}

fn default_sync_timeout_s() -> f64 {
    120.0
}

/// Shafts, volumes and losses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsConfig {
    pub gg_inertia_kg_m2: f64,
    pub pt_inertia_kg_m2: f64,
    pub combustor_volume_m3: f64,
    pub duct_volume_m3: f64,
    /// GG bearing/windage loss at design speed (scales with speed squared), kW.
    pub gg_friction_kw_at_design: f64,
    /// PT + generator windage loss at synchronous speed (scales with speed cubed), kW.
    pub pt_windage_kw_at_sync: f64,
    /// Static torque the gas must overcome before the PT breaks away, N·m.
    pub pt_breakaway_torque_n_m: f64,
    /// GG bearing (Coulomb) friction torque, N·m: brings a coasting rotor to rest in finite time.
    pub gg_bearing_torque_n_m: f64,
    /// PT + generator bearing friction torque, N·m.
    pub pt_bearing_torque_n_m: f64,
}

/// Starter (torque falls linearly with speed to zero at `free_speed_rpm`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StarterConfig {
    pub max_torque_n_m: f64,
    pub free_speed_rpm: f64,
    pub cutout_rpm: f64,
    /// Proportional gain of the starter speed hold during purge, N·m per rpm.
    pub speed_hold_gain_n_m_per_rpm: f64,
}

/// Fuel control (REFERENCE §2): PID with back-calculation anti-windup, ratio-unit limits, rate limit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlConfig {
    /// GG speed loop: fuel [kg/s] per rpm of error.
    pub speed_kp_kg_s_per_rpm: f64,
    /// GG speed loop integral gain, kg/s per rpm·s.
    pub speed_ki_kg_s_per_rpm_s: f64,
    /// PT speed loop (before the breaker closes), kg/s per rpm.
    pub pt_speed_kp_kg_s_per_rpm: f64,
    pub pt_speed_ki_kg_s_per_rpm_s: f64,
    /// Power loop, kg/s per MW.
    pub power_kp_kg_s_per_mw: f64,
    pub power_ki_kg_s_per_mw_s: f64,
    /// Back-calculation anti-windup time constant, s.
    pub antiwindup_tau_s: f64,
    /// Minimum fuel flow while the flame is on, kg/s.
    pub min_fuel_kg_s: f64,
    /// Acceleration limit: fuel/P2 ratio unit, kg/s per kPa, as a table over GG speed in rpm.
    pub accel_limit_speed_rpm: Vec<f64>,
    pub accel_limit_ratio_kg_s_per_kpa: Vec<f64>,
    /// Deceleration limit (flame-out protection), kg/s per kPa.
    pub decel_limit_ratio_kg_s_per_kpa: f64,
    /// Gas-generator minimum-speed limit while the PT governor or the power loop has the fuel,
    /// as a fraction of `sequence.idle_speed_rpm` (0: none). Below it the fuel's lower limit
    /// rises by the GG speed loop's proportional gain per rpm (a droop floor), so a governor
    /// cutting the fuel against a PT overspeed cannot run the burning GG down to a standstill.
    #[serde(default = "default_min_gg_speed_fraction")]
    pub min_gg_speed_fraction: f64,
}

/// Start-up sequence timings and set-points (REFERENCE §2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SequenceConfig {
    pub standstill_s: f64,
    pub purge_speed_rpm: f64,
    pub purge_s: f64,
    pub light_off_speed_rpm: f64,
    pub light_off_fuel_kg_s: f64,
    pub light_off_hold_s: f64,
    /// GG speed set-point ramp during acceleration, rpm/s.
    pub accel_rate_rpm_s: f64,
    pub idle_speed_rpm: f64,
    /// Time at core idle before the PT governor starts accelerating the PT, s.
    pub idle_hold_s: f64,
    /// PT speed set-point ramp from break-away to synchronous speed, rpm/s.
    pub pt_accel_rate_rpm_s: f64,
    /// Time the synchroniser needs at synchronous speed before closing the breaker, s.
    pub sync_s: f64,
    /// Time constant of the PT speed set-point's final approach to synchronous speed, s: the
    /// ramp at `pt_accel_rate_rpm_s` blends into an exponential approach with the same slope,
    /// so the PT's acceleration power fades out smoothly and the governor does not overshoot.
    #[serde(default = "default_pt_approach_tau_s")]
    pub pt_approach_tau_s: f64,
    /// The synchroniser closes the breaker only while the PT slip is within this, % of
    /// synchronous speed (after `sync_s`); a start that cannot synchronise within
    /// `sync_timeout_s` more is tripped.
    #[serde(default = "default_sync_slip_pct")]
    pub sync_slip_pct: f64,
    #[serde(default = "default_sync_timeout_s")]
    pub sync_timeout_s: f64,
    pub min_load_mw: f64,
    pub warmup_s: f64,
    pub base_load_mw: f64,
    /// Load ramp rate to base load, MW/s.
    pub load_ramp_mw_s: f64,
    /// Time simulated at steady base load after the ramp ends, s.
    pub steady_s: f64,
    /// Normal stop: time at synchronous idle with the breaker open before the fuel is cut, s.
    pub cooldown_s: f64,
    /// GG speed below which a coasting engine counts as at rest, rpm.
    pub rest_speed_rpm: f64,
    /// Output sample period, s.
    pub sample_period_s: f64,
}

/// One measured channel: first-order lag, Gaussian noise (1σ) and bias.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorChannel {
    pub tau_s: f64,
    /// Relative noise, fraction of the reading (1σ).
    #[serde(default)]
    pub noise_rel: f64,
    /// Absolute noise in the signal's unit (1σ).
    #[serde(default)]
    pub noise_abs: f64,
    /// Constant bias in the signal's unit.
    #[serde(default)]
    pub bias: f64,
}

/// Measurement model for every output signal (REFERENCE §2 defaults).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorsConfig {
    pub n1: SensorChannel,
    pub n2: SensorChannel,
    pub t1: SensorChannel,
    pub p1: SensorChannel,
    pub t2: SensorChannel,
    pub p2: SensorChannel,
    pub t3: SensorChannel,
    pub p3: SensorChannel,
    pub t34: SensorChannel,
    pub p34: SensorChannel,
    pub t4: SensorChannel,
    pub p4: SensorChannel,
    pub fuel: SensorChannel,
    pub power: SensorChannel,
    /// PT coupling torque meter (absent from older engine files: 0.5 % noise, no lag).
    #[serde(default = "default_torque_channel")]
    pub torque: SensorChannel,
    /// Inlet depression transmitter, P_amb − P1 (absent from older files: 0.02 kPa noise,
    /// 0.05 s lag — a differential transmitter is far more precise than two absolute ones).
    #[serde(default = "default_dp_inlet_channel")]
    pub dp_inlet: SensorChannel,
}

fn default_torque_channel() -> SensorChannel {
    SensorChannel {
        tau_s: 0.0,
        noise_rel: 0.005,
        noise_abs: 0.0,
        bias: 0.0,
    }
}

fn default_dp_inlet_channel() -> SensorChannel {
    SensorChannel {
        tau_s: 0.05,
        noise_rel: 0.0,
        noise_abs: 0.02,
        bias: 0.0,
    }
}

/// Integration settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverConfig {
    /// Relative local error tolerance of the adaptive Rosenbrock integrator.
    pub rtol: f64,
    /// Largest internal step, s.
    pub max_step_s: f64,
    /// Fixed internal step, s; 0 selects the adaptive integrator.
    pub fixed_step_s: f64,
}

/// The whole engine description.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EngineConfig {
    pub name: String,
    pub ambient: AmbientConfig,
    pub design: DesignConfig,
    pub maps: MapsConfig,
    pub dynamics: DynamicsConfig,
    pub starter: StarterConfig,
    pub control: ControlConfig,
    pub sequence: SequenceConfig,
    pub sensors: SensorsConfig,
    pub solver: SolverConfig,
    /// The fuel (`config/fuel.rs`); absent = methane.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fuel: Option<FuelConfig>,
    /// What sets the PT speed in steady and dynamic runs (`engine/load.rs`); absent = generator.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load: Option<LoadConfig>,
    /// Optional model effects, each a table `[effects.<name>]` of its parameters (see
    /// `engine/effects`); absent = the core model alone. Parameters not given take the
    /// effect's defaults (filled in at load, so each is a named parameter).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub effects: BTreeMap<String, BTreeMap<String, f64>>,
    /// One unit's off-design corrections of the maps (`config/adaptation.rs`); absent = the
    /// maps as scaled at the design point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adaptation: Option<AdaptationConfig>,
}

impl EngineConfig {
    /// The built-in reference engine.
    #[allow(clippy::expect_used)] // embedded file, validated by a unit test
    pub fn reference() -> EngineConfig {
        // The embedded file is validated by a unit test, so this cannot fail at run time.
        Self::from_toml_str(REFERENCE_ENGINE_TOML, "<embedded config/engine.toml>")
            .expect("embedded reference engine is valid (checked by tests)")
    }

    pub fn from_toml_str(text: &str, path: &str) -> Result<EngineConfig, EngineConfigError> {
        let parse_error = |e: toml::de::Error| EngineConfigError::Parse {
            path: path.into(),
            message: e.to_string(),
        };
        let table: toml::Table = toml::from_str(text).map_err(parse_error)?;
        let mut cfg: EngineConfig = match legacy_mechanical_efficiency(table, path)? {
            // Deserialise from the text when nothing was rewritten: errors keep their line.
            None => toml::from_str(text).map_err(parse_error)?,
            Some(table) => table.try_into().map_err(parse_error)?,
        };
        cfg.validate(path)?;
        cfg.effects =
            super::effects::complete(&cfg.effects).map_err(|e| EngineConfigError::Invalid {
                path: path.into(),
                key: "effects".into(),
                reason: e.to_string(),
            })?;
        Ok(cfg)
    }

    /// Reads and validates an engine file. Relative map paths in `[maps]` are resolved against
    /// the engine file's directory (absolute paths are kept), so a file and its maps can be
    /// moved together and used from any working directory.
    pub fn load(path: &Path) -> Result<EngineConfig, EngineConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| EngineConfigError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let mut cfg = Self::from_toml_str(&text, &path.display().to_string())?;
        let dir = path.parent().unwrap_or_else(|| Path::new(""));
        cfg.maps.resolve_relative_to(dir);
        Ok(cfg)
    }

    /// Loads `path`, or the reference engine when `None`.
    pub fn load_or_reference(path: Option<&Path>) -> Result<EngineConfig, EngineConfigError> {
        match path {
            Some(p) => Self::load(p),
            None => Ok(Self::reference()),
        }
    }

    /// The fuel this engine burns: the `[fuel]` section, or methane (see `config/fuel.rs`).
    pub fn fuel(&self) -> Result<crate::thermo::Fuel, EngineConfigError> {
        self.fuel_checked().map_err(|p| EngineConfigError::Invalid {
            path: "<engine file>".into(),
            key: p.key,
            reason: p.reason,
        })
    }

    fn fuel_checked(&self) -> Result<crate::thermo::Fuel, fuel::FuelProblem> {
        fuel::engine_fuel(self.fuel.as_ref(), self.design.fuel_lhv_j_per_kg)
    }

    /// Checks every value: each number finite and inside its key's allowed range
    /// ([`param_range`]), then the relations between keys. The error names the key.
    pub fn validate(&self, path: &str) -> Result<(), EngineConfigError> {
        self.validate_sections(path)?;
        self.validate_numbers(path)?;
        self.validate_relations(path)
    }

    /// [`EngineConfig::validate`] without the pass over every number of the file, for a copy
    /// of a valid file whose changed numbers were each checked against their ranges already
    /// (`with_params` on an engine's own file): the same verdict for a fraction of the cost
    /// (that pass serialises the whole file, a sixth of a calibration's time).
    pub(crate) fn validate_changed(&self, path: &str) -> Result<(), EngineConfigError> {
        self.validate_sections(path)?;
        self.validate_relations(path)
    }

    /// The effects, the adaptation and the load, each checked as a whole.
    fn validate_sections(&self, path: &str) -> Result<(), EngineConfigError> {
        let bad = |key: &str, reason: &str| invalid(path, key, reason);
        super::effects::check(&self.effects).map_err(|e| bad("effects", &e.to_string()))?;
        if let Some(a) = &self.adaptation {
            a.check().map_err(|(key, reason)| bad(&key, &reason))?;
        }
        if let Some(l) = &self.load {
            l.check().map_err(|(key, reason)| bad(&key, &reason))?;
        }
        for (component, file, inline) in self.maps.sources() {
            if !file.is_empty() && !inline.is_empty() {
                return Err(bad(
                    &format!("maps.{component}_map"),
                    &format!(
                        "the map is given twice: as {component}_file and as its text here; \
                         keep one"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Every number of the file finite and inside its key's range.
    fn validate_numbers(&self, path: &str) -> Result<(), EngineConfigError> {
        let bad = |key: &str, reason: &str| invalid(path, key, reason);
        let tree = serde_json::to_value(self).map_err(|e| EngineConfigError::Parse {
            path: path.into(),
            message: e.to_string(),
        })?;
        let mut leaves: Vec<(String, Option<f64>)> = Vec::new();
        numeric_leaves(&tree, String::new(), &mut leaves);
        for (key, value) in &leaves {
            // serde_json writes a non-finite float as null.
            let Some(v) = *value else {
                return Err(bad(key, "must be a finite number"));
            };
            let Some(range) = param_range(key) else {
                return Err(bad(key, "has no allowed range (not a tunable number)"));
            };
            range.check(v).map_err(|reason| bad(key, &reason))?;
        }
        Ok(())
    }

    /// The relations between keys (and the fuel they describe).
    fn validate_relations(&self, path: &str) -> Result<(), EngineConfigError> {
        let bad = |key: &str, reason: &str| invalid(path, key, reason);
        self.fuel_checked().map_err(|p| bad(&p.key, &p.reason))?;
        for (key, law) in [
            ("design.inlet_loss_law", self.design.inlet_loss_law),
            ("design.combustor_loss_law", self.design.combustor_loss_law),
        ] {
            if law == PressureLossLaw::Nozzle {
                return Err(bad(
                    key,
                    "\"nozzle\" is an exhaust law only (design.exhaust_loss_law); use \
                     \"flow_squared\" or \"constant\"",
                ));
            }
        }
        let d = &self.design;
        if d.cooling_bleed_frac + d.cooling_return_frac >= 0.5 {
            return Err(bad(
                "design.cooling_return_frac",
                "with design.cooling_bleed_frac must take less than half the compressor's air",
            ));
        }
        let c = &self.control;
        if c.accel_limit_speed_rpm.len() != c.accel_limit_ratio_kg_s_per_kpa.len()
            || c.accel_limit_speed_rpm.len() < 2
        {
            return Err(bad(
                "control.accel_limit_ratio_kg_s_per_kpa",
                "needs the same number (>= 2) of entries as control.accel_limit_speed_rpm",
            ));
        }
        if c.accel_limit_speed_rpm.windows(2).any(|w| w[1] <= w[0]) {
            return Err(bad(
                "control.accel_limit_speed_rpm",
                "must be strictly increasing",
            ));
        }
        let s = &self.sequence;
        // Light-off at the purge speed itself is a sequence of its own: many aero-derivatives
        // ignite while the starter still holds the purge speed (the third blind unit's does).
        if !(s.light_off_speed_rpm <= s.purge_speed_rpm
            && s.purge_speed_rpm < self.starter.cutout_rpm
            && self.starter.cutout_rpm < s.idle_speed_rpm
            && s.idle_speed_rpm < self.design.gg_speed_rpm)
        {
            return Err(bad(
                "sequence",
                &format!(
                    "speeds must satisfy light_off <= purge < starter cut-out < idle < design \
                     GG speed (here {} / {} / {} / {} / {} rpm)",
                    s.light_off_speed_rpm,
                    s.purge_speed_rpm,
                    self.starter.cutout_rpm,
                    s.idle_speed_rpm,
                    self.design.gg_speed_rpm
                ),
            ));
        }
        if s.base_load_mw < s.min_load_mw {
            return Err(bad(
                "sequence.base_load_mw",
                "must be at least sequence.min_load_mw",
            ));
        }
        if self.solver.fixed_step_s != 0.0 && self.solver.fixed_step_s < 1e-4 {
            return Err(bad(
                "solver.fixed_step_s",
                "must be 0 (adaptive) or at least 1e-4 s",
            ));
        }
        Ok(())
    }
}

/// The legacy `design.mechanical_efficiency` (one value for both shafts): rewritten as
/// `gg_mechanical_efficiency` and `pt_mechanical_efficiency`. `None` when the file does not use
/// it; an error when it is combined with the per-shaft keys.
fn legacy_mechanical_efficiency(
    mut table: toml::Table,
    path: &str,
) -> Result<Option<toml::Table>, EngineConfigError> {
    let Some(design) = table.get_mut("design").and_then(|d| d.as_table_mut()) else {
        return Ok(None);
    };
    let Some(value) = design.remove("mechanical_efficiency") else {
        return Ok(None);
    };
    for key in ["gg_mechanical_efficiency", "pt_mechanical_efficiency"] {
        if design.contains_key(key) {
            return Err(EngineConfigError::Invalid {
                path: path.into(),
                key: "design.mechanical_efficiency".into(),
                reason: format!("give either it (both shafts) or design.{key}, not both"),
            });
        }
        design.insert(key.into(), value.clone());
    }
    Ok(Some(table))
}

/// Every number in `v` with its dotted key (`None` for null, i.e. a non-finite float).
fn numeric_leaves(v: &serde_json::Value, key: String, out: &mut Vec<(String, Option<f64>)>) {
    match v {
        serde_json::Value::Number(n) => out.push((key, n.as_f64())),
        serde_json::Value::Null => out.push((key, None)),
        serde_json::Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                numeric_leaves(item, format!("{key}[{i}]"), out);
            }
        }
        serde_json::Value::Object(map) => {
            for (k, item) in map {
                let sub = if key.is_empty() {
                    k.clone()
                } else {
                    format!("{key}.{k}")
                };
                numeric_leaves(item, sub, out);
            }
        }
        serde_json::Value::String(_) | serde_json::Value::Bool(_) => {}
    }
}

/// The error of a file value refused: the file, the key and why.
fn invalid(path: &str, key: &str, reason: &str) -> EngineConfigError {
    EngineConfigError::Invalid {
        path: path.into(),
        key: key.into(),
        reason: reason.into(),
    }
}

#[cfg(test)]
mod tests;
