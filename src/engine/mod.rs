//! The engine model: design-point calibration, steady-state matching and the dynamic start-up
//! simulation of a two-shaft industrial gas turbine (REFERENCE §1–3, paper §2.1).
//!
//! Module map: `config` (engine TOML), `cycle` (component stations, loss laws), `gas_path` (the
//! one gas path and its station table, the station → signal mapping), `design` (design cycle),
//! `model` (calibrated engine, health-scaled instance), `params` (named engine parameters),
//! `steady` (Newton matching), `load` (PT load modes: what sets the PT speed), `state` (state vector and layout), `dynamic` (state equations),
//! `effects` (optional model effects and their hook points), `integrator` (stiff ROS2),
//! `control` (fuel PID, limits, starter), `sequence` (start-up/shutdown sequencer),
//! `simulation` (the integration loop under a controller), `measured_drive` (the model run
//! through a recorded start-up), `sensors` (measurement model), `trace` (sampled output and
//! CSV), `plant` (a running plant for the Modbus simulator), `error`.
//! Everything here is pure and deterministic; only `Engine::new` may read a map file.

pub mod config;
pub mod control;
pub mod cycle;
pub mod design;
pub mod dynamic;
pub mod effects;
pub mod error;
pub mod gas_path;
pub mod integrator;
pub mod load;
pub mod measured_drive;
pub mod model;
pub mod params;
pub mod plant;
pub mod sensors;
pub mod sequence;
pub mod simulation;
pub mod state;
pub mod steady;
pub mod trace;

pub use config::EngineConfig;
pub use error::EngineError;
pub use gas_path::Stations;
pub use model::{DesignPoint, Engine, Model};
pub use sequence::{Command, End, Event, Scenario};
pub use simulation::{run_scenario, Controller, Simulation, TruthSample};
pub use steady::{Demand, SteadyInputs, SteadyPoint};
pub use trace::Trace;
#[cfg(test)]
mod tests;
