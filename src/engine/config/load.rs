//! The `[load]` section: what the power turbine drives (a generator, a load law P ∝ n^k, a
//! tabulated power–speed curve, or a measured PT speed).
//! Parses and validates only: the load's physics is `engine/load.rs`.

use serde::{Deserialize, Serialize};

/// What the power turbine drives.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LoadMode {
    /// A generator on the grid: PT speed held (today's behaviour).
    #[default]
    Generator,
    /// A mechanical drive or propeller absorbing `P = P_design · (n2/n2_design)^exponent`: the
    /// PT speed follows the load (steady and dynamic runs; `engine/load.rs`).
    LoadLaw,
    /// A mechanical drive whose absorbed power is a tabulated curve over PT speed
    /// (`speed_rpm`, `power_mw`: a propeller curve, a compressor on a fixed recycle): the PT
    /// speed follows the load as with `load_law`.
    Table,
    /// A load whose speed is set by something the model does not know (controllable-pitch
    /// propeller on a combinator schedule, compressor with a recycle valve, a speed governor
    /// acting on the load): the measured PT speed is an input of every diagnosis (steady,
    /// snapshot, calibration and Method B, where the model's PT follows the measured trace).
    /// In a simulation the load holds the PT at its design speed once loading begins, as a
    /// generator's breaker would.
    MeasuredSpeed,
}

/// The `[load]` section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadConfig {
    pub mode: LoadMode,
    /// Exponent k of the load law P ∝ n^k (3 for a propeller or centrifugal compressor).
    #[serde(default = "default_load_exponent")]
    pub exponent: f64,
    /// `mode = "table"`: PT speeds of the load curve, rpm, strictly increasing.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub speed_rpm: Vec<f64>,
    /// `mode = "table"`: power absorbed at each of `speed_rpm`, MW, strictly increasing.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub power_mw: Vec<f64>,
}

impl LoadConfig {
    /// `Err((key, reason))` when the table is malformed, or given to a mode that has none.
    pub fn check(&self) -> Result<(), (String, String)> {
        let table = self.mode == LoadMode::Table;
        let has_table = !self.speed_rpm.is_empty() || !self.power_mw.is_empty();
        if !table && has_table {
            return Err((
                "load.speed_rpm".into(),
                format!(
                    "a load curve is only read with mode = \"table\" (mode is {:?})",
                    self.mode
                ),
            ));
        }
        if !table {
            return Ok(());
        }
        if self.speed_rpm.len() < 2 {
            return Err((
                "load.speed_rpm".into(),
                "mode = \"table\" needs at least 2 points".into(),
            ));
        }
        if self.power_mw.len() != self.speed_rpm.len() {
            return Err((
                "load.power_mw".into(),
                format!(
                    "has {} values for {} speed_rpm",
                    self.power_mw.len(),
                    self.speed_rpm.len()
                ),
            ));
        }
        if self.speed_rpm.windows(2).any(|w| w[1] <= w[0]) || self.speed_rpm[0] <= 0.0 {
            return Err((
                "load.speed_rpm".into(),
                "must be positive and strictly increasing".into(),
            ));
        }
        if self.power_mw.windows(2).any(|w| w[1] <= w[0]) || self.power_mw[0] <= 0.0 {
            return Err((
                "load.power_mw".into(),
                "must be positive and strictly increasing with speed (a load that absorbs \
                 less at a higher speed has no unique operating speed)"
                    .into(),
            ));
        }
        Ok(())
    }
}

fn default_load_exponent() -> f64 {
    3.0
}
