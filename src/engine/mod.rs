//! The engine model: design-point calibration, steady-state matching and the dynamic start-up
//! simulation of a two-shaft industrial gas turbine (REFERENCE §1–3, paper §2.1).
//!
//! Module map: `config` (engine TOML), `cycle` (component stations), `design` (design cycle),
//! `model` (calibrated engine, health-scaled instance), `steady` (Newton matching), `dynamic`
//! (state equations), `integrator` (stiff ROS2), `control` (fuel PID, limits, starter),
//! `sequence` (start-up/shutdown sequencer and simulation loop), `sensors` (measurement model),
//! `trace` (sampled output and CSV), `plant` (a running plant for the Modbus simulator).
//! Everything here is pure and deterministic; only `Engine::new` may read a map file.

pub mod config;
pub mod control;
pub mod cycle;
pub mod design;
pub mod dynamic;
pub mod integrator;
pub mod model;
pub mod params;
pub mod plant;
pub mod replay;
pub mod sensors;
pub mod sequence;
pub mod steady;
pub mod trace;

pub use config::EngineConfig;
pub use model::{DesignPoint, Engine, EngineError, Model};
pub use sequence::{Command, End, Event, Scenario};
pub use steady::{Demand, SteadyInputs, SteadyPoint};
pub use trace::Trace;
#[cfg(test)]
mod tests;
