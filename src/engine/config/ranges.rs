//! Allowed ranges of the engine file's numbers, by dotted key.
//!
//! What it is for: the one table `EngineConfig::validate` and `set_param` check numbers against.
//! What it must not do: physics or I/O.

/// Allowed interval of one engine-file number: `[min, max]`, or `(min, max]` when
/// `min_exclusive`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamRange {
    pub min: f64,
    pub max: f64,
    /// The lower bound itself is not allowed.
    pub min_exclusive: bool,
}

impl ParamRange {
    pub(super) const fn new(min: f64, max: f64) -> ParamRange {
        ParamRange {
            min,
            max,
            min_exclusive: false,
        }
    }
    /// An efficiency: (0, 1]. 1.0 (ideal combustion, lossless shaft, as peers' examples use)
    /// is allowed.
    const fn efficiency() -> ParamRange {
        ParamRange {
            min: 0.0,
            max: 1.0,
            min_exclusive: true,
        }
    }
    /// `Err(reason)` unless `v` is finite and inside the range.
    pub fn check(&self, v: f64) -> Result<(), String> {
        if !v.is_finite() {
            return Err("must be a finite number".into());
        }
        let below = if self.min_exclusive {
            v <= self.min
        } else {
            v < self.min
        };
        if below || v > self.max {
            let open = if self.min_exclusive { '(' } else { '[' };
            return Err(format!(
                "{v} is outside the allowed range {open}{}, {}]",
                self.min, self.max
            ));
        }
        Ok(())
    }
}

/// Allowed ranges of every number in the engine file, by dotted key. Array elements use the
/// array's key; `sensors.*` covers every channel. Deliberately wide: they reject values that
/// would make the model hang or panic (NaN, zero steps, negative inertia), not unusual engines.
const RANGES: &[(&str, ParamRange)] = &[
    ("ambient.temperature_k", ParamRange::new(180.0, 350.0)),
    ("ambient.pressure_kpa", ParamRange::new(20.0, 120.0)),
    ("design.pressure_ratio", ParamRange::new(1.01, 80.0)),
    ("design.exhaust_flow_kg_s", ParamRange::new(0.01, 5000.0)),
    ("design.power_mw", ParamRange::new(0.001, 2000.0)),
    ("design.compressor_efficiency", ParamRange::efficiency()),
    ("design.hpt_efficiency", ParamRange::efficiency()),
    ("design.pt_efficiency", ParamRange::efficiency()),
    ("design.gg_speed_rpm", ParamRange::new(100.0, 200_000.0)),
    ("design.pt_speed_rpm", ParamRange::new(100.0, 200_000.0)),
    ("design.inlet_loss_frac", ParamRange::new(0.0, 0.5)),
    ("design.combustor_loss_frac", ParamRange::new(0.0, 0.5)),
    ("design.combustion_efficiency", ParamRange::efficiency()),
    ("design.fuel_lhv_j_per_kg", ParamRange::new(1.0e6, 2.0e8)),
    ("fuel.temperature_k", ParamRange::new(200.0, 800.0)),
    ("load.exponent", ParamRange::new(0.5, 5.0)),
    ("load.speed_rpm", ParamRange::new(1.0, 100_000.0)),
    ("load.power_mw", ParamRange::new(1.0e-4, 2000.0)),
    // Off-design adaptation (`config/adaptation.rs`): knots in relative corrected speed,
    // corrections as fractions, bounded as `maps::adapt` clamps them.
    ("adaptation.*.speed_knots", ParamRange::new(0.05, 2.0)),
    ("adaptation.calibrated.gg_speed", ParamRange::new(0.05, 2.0)),
    ("adaptation.*.flow", ParamRange::new(-0.5, 0.5)),
    ("adaptation.*.efficiency", ParamRange::new(-0.5, 0.5)),
    ("adaptation.*.pressure_ratio", ParamRange::new(-0.5, 0.5)),
    ("adaptation.*.speed", ParamRange::new(-0.5, 0.5)),
    (
        "adaptation.offline_shape.efficiency_slope_sigma",
        ParamRange::new(0.0, super::offline_shape::MAX_SLOPE_SIGMA),
    ),
    (
        "adaptation.offline_shape.flow_slope_sigma",
        ParamRange::new(0.0, super::offline_shape::MAX_SLOPE_SIGMA),
    ),
    ("fuel.composition.CH4", ParamRange::new(0.0, 1.0)),
    ("fuel.composition.C2H6", ParamRange::new(0.0, 1.0)),
    ("fuel.composition.C3H8", ParamRange::new(0.0, 1.0)),
    ("fuel.composition.C4H10", ParamRange::new(0.0, 1.0)),
    ("fuel.composition.N2", ParamRange::new(0.0, 1.0)),
    ("fuel.composition.CO2", ParamRange::new(0.0, 1.0)),
    ("fuel.composition.H2", ParamRange::new(0.0, 1.0)),
    ("fuel.h_to_c_ratio", ParamRange::new(0.5, 4.0)),
    ("fuel.lhv_j_per_kg", ParamRange::new(1.0e6, 2.0e8)),
    ("design.gg_mechanical_efficiency", ParamRange::efficiency()),
    ("design.pt_mechanical_efficiency", ParamRange::efficiency()),
    (
        "design.exhaust_back_pressure_ratio",
        ParamRange::new(1.0, 2.0),
    ),
    ("design.cooling_bleed_frac", ParamRange::new(0.0, 0.5)),
    ("design.cooling_return_frac", ParamRange::new(0.0, 0.3)),
    ("maps.compressor_design_speed", ParamRange::new(0.05, 5.0)),
    ("maps.compressor_design_beta", ParamRange::new(-1.0, 2.0)),
    ("maps.hpt_design_speed", ParamRange::new(0.05, 5.0)),
    ("maps.hpt_design_pr", ParamRange::new(1.01, 100.0)),
    ("maps.pt_design_speed", ParamRange::new(0.05, 5.0)),
    ("maps.pt_design_pr", ParamRange::new(1.01, 100.0)),
    ("dynamics.gg_inertia_kg_m2", ParamRange::new(1.0e-3, 1.0e6)),
    ("dynamics.pt_inertia_kg_m2", ParamRange::new(1.0e-3, 1.0e7)),
    (
        "dynamics.combustor_volume_m3",
        ParamRange::new(1.0e-4, 100.0),
    ),
    ("dynamics.duct_volume_m3", ParamRange::new(1.0e-4, 100.0)),
    (
        "dynamics.gg_friction_kw_at_design",
        ParamRange::new(0.0, 1.0e5),
    ),
    (
        "dynamics.pt_windage_kw_at_sync",
        ParamRange::new(0.0, 1.0e5),
    ),
    (
        "dynamics.pt_breakaway_torque_n_m",
        ParamRange::new(0.0, 1.0e7),
    ),
    (
        "dynamics.gg_bearing_torque_n_m",
        ParamRange::new(0.0, 1.0e6),
    ),
    (
        "dynamics.pt_bearing_torque_n_m",
        ParamRange::new(0.0, 1.0e7),
    ),
    ("starter.max_torque_n_m", ParamRange::new(1.0, 1.0e7)),
    ("starter.free_speed_rpm", ParamRange::new(1.0, 200_000.0)),
    ("starter.cutout_rpm", ParamRange::new(1.0, 200_000.0)),
    (
        "starter.speed_hold_gain_n_m_per_rpm",
        ParamRange::new(0.0, 1.0e5),
    ),
    ("control.speed_kp_kg_s_per_rpm", ParamRange::new(0.0, 1.0)),
    ("control.speed_ki_kg_s_per_rpm_s", ParamRange::new(0.0, 1.0)),
    (
        "control.pt_speed_kp_kg_s_per_rpm",
        ParamRange::new(0.0, 1.0),
    ),
    (
        "control.pt_speed_ki_kg_s_per_rpm_s",
        ParamRange::new(0.0, 1.0),
    ),
    ("control.power_kp_kg_s_per_mw", ParamRange::new(0.0, 100.0)),
    (
        "control.power_ki_kg_s_per_mw_s",
        ParamRange::new(0.0, 100.0),
    ),
    ("control.antiwindup_tau_s", ParamRange::new(1.0e-3, 1.0e4)),
    ("control.min_fuel_kg_s", ParamRange::new(0.0, 100.0)),
    (
        "control.accel_limit_speed_rpm",
        ParamRange::new(0.0, 200_000.0),
    ),
    (
        "control.accel_limit_ratio_kg_s_per_kpa",
        ParamRange::new(0.0, 1.0),
    ),
    (
        "control.decel_limit_ratio_kg_s_per_kpa",
        ParamRange::new(0.0, 1.0),
    ),
    ("control.min_gg_speed_fraction", ParamRange::new(0.0, 1.0)),
    ("sequence.standstill_s", ParamRange::new(0.0, 86_400.0)),
    ("sequence.purge_speed_rpm", ParamRange::new(1.0, 200_000.0)),
    ("sequence.purge_s", ParamRange::new(0.0, 86_400.0)),
    (
        "sequence.light_off_speed_rpm",
        ParamRange::new(0.0, 200_000.0),
    ),
    (
        "sequence.light_off_fuel_kg_s",
        ParamRange::new(1.0e-6, 100.0),
    ),
    ("sequence.light_off_hold_s", ParamRange::new(0.0, 86_400.0)),
    ("sequence.accel_rate_rpm_s", ParamRange::new(1.0e-2, 1.0e5)),
    ("sequence.idle_speed_rpm", ParamRange::new(1.0, 200_000.0)),
    ("sequence.idle_hold_s", ParamRange::new(0.0, 86_400.0)),
    (
        "sequence.pt_accel_rate_rpm_s",
        ParamRange::new(1.0e-2, 1.0e5),
    ),
    ("sequence.sync_s", ParamRange::new(0.0, 86_400.0)),
    ("sequence.pt_approach_tau_s", ParamRange::new(0.0, 600.0)),
    ("sequence.sync_slip_pct", ParamRange::new(0.01, 10.0)),
    ("sequence.sync_timeout_s", ParamRange::new(1.0, 86_400.0)),
    ("sequence.min_load_mw", ParamRange::new(0.0, 2000.0)),
    ("sequence.warmup_s", ParamRange::new(0.0, 86_400.0)),
    ("sequence.base_load_mw", ParamRange::new(0.0, 2000.0)),
    ("sequence.load_ramp_mw_s", ParamRange::new(1.0e-4, 1.0e3)),
    ("sequence.steady_s", ParamRange::new(0.0, 86_400.0)),
    ("sequence.cooldown_s", ParamRange::new(0.0, 86_400.0)),
    ("sequence.rest_speed_rpm", ParamRange::new(0.0, 10_000.0)),
    ("sequence.sample_period_s", ParamRange::new(1.0e-3, 3600.0)),
    ("sensors.*.tau_s", ParamRange::new(0.0, 600.0)),
    ("sensors.*.noise_rel", ParamRange::new(0.0, 1.0)),
    ("sensors.*.noise_abs", ParamRange::new(0.0, 1.0e4)),
    ("sensors.*.bias", ParamRange::new(-1.0e6, 1.0e6)),
    ("solver.rtol", ParamRange::new(1.0e-10, 0.1)),
    ("solver.max_step_s", ParamRange::new(1.0e-3, 60.0)),
    ("solver.fixed_step_s", ParamRange::new(0.0, 60.0)),
];

/// The allowed range of the number at dotted `key` (array index `[i]` ignored), if it has one.
pub fn param_range(key: &str) -> Option<ParamRange> {
    let base = key.split('[').next().unwrap_or(key);
    if let Some(rest) = base.strip_prefix("effects.") {
        let (effect, param) = rest.split_once('.')?;
        let p = crate::engine::effects::param_spec(effect, param)?;
        return Some(ParamRange::new(p.min, p.max));
    }
    if let Some((_, r)) = RANGES.iter().find(|(k, _)| *k == base) {
        return Some(*r);
    }
    let parts: Vec<&str> = base.split('.').collect();
    if parts.len() == 3
        && parts[0] == "adaptation"
        && (parts[1] == "model_error_pct"
            || (parts[1] == "model_error_by_speed" && parts[2] != "speed_knots"))
    {
        return Some(ParamRange::new(0.0, super::adaptation::MAX_MODEL_ERROR_PCT));
    }
    if parts.len() == 3 && parts[0] == "adaptation" && parts[1] == "health_error" {
        return Some(ParamRange::new(
            0.0,
            super::adaptation::MAX_HEALTH_ERROR_PTS,
        ));
    }
    if parts.len() == 3 && (parts[0] == "sensors" || parts[0] == "adaptation") {
        let wild = format!("{}.*.{}", parts[0], parts[2]);
        return RANGES.iter().find(|(k, _)| *k == wild).map(|(_, r)| *r);
    }
    None
}
