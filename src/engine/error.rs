//! The engine's error type: what can go wrong building or running the model.
//! Plain data, no logic; every engine module returns it.
//! Must not log, print or decide what a caller does about an error.

use crate::maps;

/// Errors building or running the engine model.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    #[error(transparent)]
    Config(#[from] super::config::EngineConfigError),
    #[error("map: {0}")]
    Map(#[from] maps::MapError),
    /// A map named by an engine-file key could not be read or built. The map error is shown,
    /// not chained as a source, so the file is named once.
    #[error("engine file key `{key}`: {error}")]
    MapFile {
        key: String,
        error: Box<maps::MapError>,
    },
    #[error("design-point calibration failed: {0}")]
    Calibration(String),
    #[error("steady-state solver: {0}")]
    NoSteadySolution(String),
    #[error("simulation failed at t = {t_s:.2} s: {reason}")]
    Simulation { t_s: f64, reason: String },
    #[error("engine parameter `{key}`: {reason}")]
    Param { key: String, reason: String },
}
