//! The engine model: design-point calibration, steady-state matching and the dynamic start-up
//! simulation of a two-shaft industrial gas turbine (REFERENCE §1–3, paper §2.1).
//!
//! Module map: `config` (engine TOML), `cycle` (component stations, loss laws), `gas_path` (the
//! one gas path and its station table, the station → signal mapping), `design` (design cycle),
//! `model` (calibrated engine, health-scaled instance), `params` (named engine parameters),
//! `steady` (Newton matching), `load` (PT load modes: what sets the PT speed), `state` (state vector and layout), `dynamic` (state equations),
//! `effects` (optional model effects and their hook points), `integrator` (stiff ROS2),
//! `control` (fuel PID, limits, starter), `sequence` (start-up/shutdown sequencer),
//! `simulation` (the integration loop under a controller), `start_outcome` (where a simulated
//! start-up that never reached steady load stuck), `measured_drive` (the model run
//! through a recorded start-up), `sensors` (measurement model), `trace` (sampled output and
//! CSV), `plant` (a running plant for the Modbus simulator), `error`.
//! Everything here is pure and deterministic; only `Engine::new` may read a map file.

pub mod config;
pub(crate) mod control;
pub(crate) mod cycle;
pub(crate) mod design;
pub(crate) mod dynamic;
pub(crate) mod effects;
pub(crate) mod error;
pub(crate) mod gas_path;
pub(crate) mod integrator;
pub mod load;
pub(crate) mod measured_drive;
pub(crate) mod model;
pub(crate) mod nozzle;
pub(crate) mod params;
pub(crate) mod plant;
pub mod sensors;
pub(crate) mod sequence;
pub mod simulation;
pub mod start_outcome;
pub(crate) mod state;
pub mod steady;
pub(crate) mod trace;

pub use config::EngineConfig;
pub use error::EngineError;
pub use gas_path::Stations;
pub use model::{DesignPoint, Engine, Model};
pub use sequence::{Command, End, Event, Scenario};
pub use simulation::{
    run_scenario, run_scenario_observed, Change, Controller, Simulation, TruthSample,
};
pub use steady::{Demand, SteadyInputs, SteadyPoint};
pub use trace::Trace;
#[cfg(test)]
mod tests;
