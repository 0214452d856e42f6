//! Engine configuration: the reference engine's constants, read from TOML.
//!
//! Every constant the model uses lives here with its unit in the key name, so a plant engineer
//! can describe another engine of the same architecture without touching code. The defaults are
//! the reference engine of REFERENCE §1–2 and are identical to `config/engine.toml`.
//! This module only parses and validates numbers; it does no physics.

use serde::{Deserialize, Serialize};
use std::path::Path;

/// The built-in reference engine, embedded so `gtwatch simulate` works with no files at all.
pub const REFERENCE_ENGINE_TOML: &str = include_str!("../../config/engine.toml");

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
    /// Combustor total-pressure loss at design, fraction of P2.
    pub combustor_loss_frac: f64,
    pub combustion_efficiency: f64,
    pub fuel_lhv_j_per_kg: f64,
    /// Mechanical efficiency of each shaft.
    pub mechanical_efficiency: f64,
    /// Exhaust static back-pressure at design flow, multiple of ambient pressure.
    pub exhaust_back_pressure_ratio: f64,
    /// Compressor air bled overboard (cooling/leakage), fraction of compressor flow.
    pub cooling_bleed_frac: f64,
}

/// Component maps: `""` selects the embedded map, otherwise a GasTurb file path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapsConfig {
    pub compressor_file: String,
    pub compressor_design_speed: f64,
    pub compressor_design_beta: f64,
    pub hpt_file: String,
    pub hpt_design_speed: f64,
    pub hpt_design_pr: f64,
    pub pt_file: String,
    pub pt_design_speed: f64,
    pub pt_design_pr: f64,
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
        let cfg: EngineConfig = toml::from_str(text).map_err(|e| EngineConfigError::Parse {
            path: path.into(),
            message: e.to_string(),
        })?;
        cfg.validate(path)?;
        Ok(cfg)
    }

    pub fn load(path: &Path) -> Result<EngineConfig, EngineConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| EngineConfigError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_toml_str(&text, &path.display().to_string())
    }

    /// Loads `path`, or the reference engine when `None`.
    pub fn load_or_reference(path: Option<&Path>) -> Result<EngineConfig, EngineConfigError> {
        match path {
            Some(p) => Self::load(p),
            None => Ok(Self::reference()),
        }
    }

    fn validate(&self, path: &str) -> Result<(), EngineConfigError> {
        let bad = |key: &str, reason: &str| EngineConfigError::Invalid {
            path: path.into(),
            key: key.into(),
            reason: reason.into(),
        };
        let positive: [(&str, f64); 22] = [
            ("ambient.temperature_k", self.ambient.temperature_k),
            ("ambient.pressure_kpa", self.ambient.pressure_kpa),
            ("design.pressure_ratio", self.design.pressure_ratio - 1.0),
            ("design.exhaust_flow_kg_s", self.design.exhaust_flow_kg_s),
            ("design.power_mw", self.design.power_mw),
            ("design.gg_speed_rpm", self.design.gg_speed_rpm),
            ("design.pt_speed_rpm", self.design.pt_speed_rpm),
            ("design.fuel_lhv_j_per_kg", self.design.fuel_lhv_j_per_kg),
            ("dynamics.gg_inertia_kg_m2", self.dynamics.gg_inertia_kg_m2),
            ("dynamics.pt_inertia_kg_m2", self.dynamics.pt_inertia_kg_m2),
            (
                "dynamics.combustor_volume_m3",
                self.dynamics.combustor_volume_m3,
            ),
            ("dynamics.duct_volume_m3", self.dynamics.duct_volume_m3),
            ("starter.max_torque_n_m", self.starter.max_torque_n_m),
            ("starter.free_speed_rpm", self.starter.free_speed_rpm),
            ("sequence.purge_speed_rpm", self.sequence.purge_speed_rpm),
            ("sequence.idle_speed_rpm", self.sequence.idle_speed_rpm),
            (
                "sequence.light_off_fuel_kg_s",
                self.sequence.light_off_fuel_kg_s,
            ),
            ("sequence.accel_rate_rpm_s", self.sequence.accel_rate_rpm_s),
            (
                "sequence.pt_accel_rate_rpm_s",
                self.sequence.pt_accel_rate_rpm_s,
            ),
            ("sequence.load_ramp_mw_s", self.sequence.load_ramp_mw_s),
            ("sequence.sample_period_s", self.sequence.sample_period_s),
            ("solver.max_step_s", self.solver.max_step_s),
        ];
        for (key, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(key, "must be a positive number"));
            }
        }
        let fractions: [(&str, f64); 9] = [
            (
                "design.compressor_efficiency",
                self.design.compressor_efficiency,
            ),
            ("design.hpt_efficiency", self.design.hpt_efficiency),
            ("design.pt_efficiency", self.design.pt_efficiency),
            (
                "design.combustion_efficiency",
                self.design.combustion_efficiency,
            ),
            (
                "design.mechanical_efficiency",
                self.design.mechanical_efficiency,
            ),
            ("design.inlet_loss_frac", self.design.inlet_loss_frac),
            (
                "design.combustor_loss_frac",
                self.design.combustor_loss_frac,
            ),
            ("design.cooling_bleed_frac", self.design.cooling_bleed_frac),
            ("solver.rtol", self.solver.rtol),
        ];
        for (key, v) in fractions {
            if !(v.is_finite() && (0.0..1.0).contains(&v)) {
                return Err(bad(key, "must be a fraction in [0, 1)"));
            }
        }
        if self.design.exhaust_back_pressure_ratio < 1.0 {
            return Err(bad("design.exhaust_back_pressure_ratio", "must be >= 1"));
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
        if !(s.light_off_speed_rpm < s.purge_speed_rpm
            && s.purge_speed_rpm < self.starter.cutout_rpm
            && self.starter.cutout_rpm < s.idle_speed_rpm
            && s.idle_speed_rpm < self.design.gg_speed_rpm)
        {
            return Err(bad(
                "sequence",
                "speeds must satisfy light_off < purge < starter cut-out < idle < design GG speed",
            ));
        }
        if s.base_load_mw < s.min_load_mw {
            return Err(bad(
                "sequence.base_load_mw",
                "must be at least sequence.min_load_mw",
            ));
        }
        if self.solver.fixed_step_s < 0.0 {
            return Err(bad("solver.fixed_step_s", "must be >= 0 (0 = adaptive)"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_engine_parses() {
        let cfg = EngineConfig::reference();
        assert_eq!(cfg.design.pressure_ratio, 24.1);
        assert_eq!(cfg.dynamics.gg_inertia_kg_m2, 40.0);
    }

    #[test]
    fn unknown_key_is_named() {
        let text = REFERENCE_ENGINE_TOML.replace("[ambient]", "[ambient]\nhumidity_pct = 3");
        let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err("unknown key");
        assert!(err.to_string().contains("humidity_pct"), "{err}");
    }

    #[test]
    fn invalid_value_is_named() {
        let text = REFERENCE_ENGINE_TOML.replace(
            "compressor_efficiency = 0.85",
            "compressor_efficiency = 1.5",
        );
        let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err("bad value");
        assert!(
            err.to_string().contains("design.compressor_efficiency"),
            "{err}"
        );
    }
}
