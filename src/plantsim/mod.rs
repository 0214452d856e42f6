//! A simulated plant served over Modbus TCP, for tests and commissioning.
//!
//! [`PlantModel`] is the interface a plant simulation implements; [`ScriptedPlant`] is a deterministic
//! stand-in that follows the start-up phase definitions of the daemon contract with
//! piecewise-linear trajectories (normal start, aborted start, hot restart, shutdown, trip), so
//! the daemon and its end-to-end tests work without the engine model. [`spawn_plant_sim`] runs
//! a Modbus TCP server that encodes every frame into registers per the register map (the
//! inverse of the daemon's decoder) and publishes the true phase code in the extra field
//! `phase_truth` when the map has one.
//!
//! The server only answers reads (function codes 3 and 4); any other request gets the
//! exception "illegal function". This module must not be used to talk to a real plant.
//!
//! Rooms: [`model_source`] (the engine model as the plant), [`scripted`] (a deterministic
//! piecewise-linear stand-in), [`fouling`] (a plant that fouls day by day, one start a day, for
//! `gtwatch demo`), [`server`] (the Modbus TCP server and its register image).

pub(crate) mod fouling;
pub(crate) mod model_source;
pub(crate) mod scripted;
pub(crate) mod server;

pub use fouling::{FoulingPlant, FoulingSchedule};
pub use model_source::ModelPlant;
pub use scripted::{demo_schedule, ScriptLevels, ScriptStep, ScriptTiming, ScriptedPlant};
pub use server::{run_plant_sim, spawn_plant_sim, PlantSimHandle, SimOptions};

use crate::signals::{Phase, Signal};
/// The plant's measured values at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantFrame {
    /// Simulation time, s.
    pub t_s: f64,
    /// Indexed by [`Signal::index`].
    pub values: [f64; crate::signals::NSIG],
    /// True operating phase of this frame.
    pub phase: Phase,
}

impl PlantFrame {
    pub fn get(&self, s: Signal) -> f64 {
        self.values[s.index()]
    }
}

/// A plant simulation stepped at a fixed sample period.
pub trait PlantModel: Send {
    /// Advance by one sample period and return the plant's measured values at the new time.
    fn step(&mut self) -> PlantFrame;
    fn period_s(&self) -> f64;
    /// Plant clock (Unix epoch ms) at model time 0, published in the `plant_time_ms` field when
    /// the map has one. `None` (default): the wall clock when the simulator starts.
    fn epoch_ms(&self) -> Option<i64> {
        None
    }
}
