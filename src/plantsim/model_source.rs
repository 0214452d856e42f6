//! The engine model as the plant source (`gtwatch plant-sim --source model`).
//!
//! Pure stepping of [`crate::engine::plant::SimulatedPlant`]; no I/O besides a log line when the
//! model fails (the frame is then held).

use super::{PlantFrame, PlantModel};
use crate::signals::{Phase, NSIG};

/// The engine model as the plant source: [`crate::engine::plant::SimulatedPlant`] (the dynamic
/// model through a repeating schedule of starts, stops, an aborted start and a hot restart, with
/// live sensor lags and noise). If the model ever fails to advance, the last frame is held and the
/// failure logged: a test plant must not crash the server.
pub struct ModelPlant {
    plant: crate::engine::plant::SimulatedPlant,
    last: PlantFrame,
    failed: bool,
}

impl ModelPlant {
    pub fn new(plant: crate::engine::plant::SimulatedPlant) -> ModelPlant {
        ModelPlant {
            plant,
            last: PlantFrame {
                t_s: 0.0,
                values: [0.0; NSIG],
                phase: Phase::Standstill,
            },
            failed: false,
        }
    }
}

impl PlantModel for ModelPlant {
    fn step(&mut self) -> PlantFrame {
        if !self.failed {
            match self.plant.step() {
                Ok(s) => {
                    self.last = PlantFrame {
                        t_s: s.t_s,
                        values: s.values,
                        phase: s.phase,
                    }
                }
                Err(e) => {
                    tracing::error!("engine model stopped advancing, holding the last frame: {e}");
                    self.failed = true;
                }
            }
        }
        self.last.clone()
    }

    fn period_s(&self) -> f64 {
        self.plant.period_s()
    }
}
