//! A running plant: the engine model advanced one sample period at a time through a repeating
//! schedule of start-ups, base-load running, normal stops, an aborted start and a hot restart,
//! with the instruments' lags and noise applied live. This is what `gtwatch plant-sim` serves over
//! Modbus for tests and commissioning. Pure: time is simulated, nothing here sleeps or does I/O.

use super::sensors::{MeasurementOptions, OnlineChannel};
use super::trace::{values_of, Values, NSIG};
use super::{
    sequence::{Command, End, Event, Scenario},
    simulation::Simulation,
};
use super::{Engine, EngineError};
use crate::health::HealthParams;
use crate::signals::{Phase, Signal};

/// One sample of the running plant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantSample {
    pub t_s: f64,
    /// Measured values indexed by [`Signal::index`].
    pub values: Values,
    pub phase: Phase,
}

/// The schedule repeated by the plant: one cycle of operations (see [`Scenario::operations`]).
pub(crate) fn repeating_schedule(engine: &Engine, cycles: usize) -> (Vec<Event>, f64) {
    let one = Scenario::operations(engine.cfg());
    let period = match one.end {
        End::At(t) => t + engine.cfg().sequence.cooldown_s + 600.0,
        End::AfterSteady { max_s, .. } => max_s,
    };
    let mut events = Vec::new();
    for c in 0..cycles {
        let offset = c as f64 * period;
        events.extend(one.events.iter().map(|e| Event {
            t_s: e.t_s + offset,
            command: e.command,
        }));
        // Each cycle ends with a normal stop so the next begins from rest.
        if let End::At(t) = one.end {
            events.push(Event {
                t_s: offset + t,
                command: Command::Stop,
            });
        }
    }
    (events, period)
}

/// One live instrument channel per signal (lags and default noise seeded by `seed`, no bias),
/// sampled every `period_s`: what a simulated plant's readings pass through.
pub(crate) fn live_channels(engine: &Engine, period_s: f64, seed: u64) -> Vec<OnlineChannel> {
    let opts = MeasurementOptions {
        lags: true,
        noise: true,
        bias: false,
        seed,
    };
    Signal::ALL
        .iter()
        .map(|s| OnlineChannel::new(&engine.cfg().sensors, *s, period_s, &opts))
        .collect()
}

/// The engine model running as a plant.
pub struct SimulatedPlant {
    sim: Simulation,
    channels: Vec<OnlineChannel>,
    period_s: f64,
    k: u64,
}

impl SimulatedPlant {
    /// A plant of `engine` with `health`, sampled every `period_s`, running `cycles` cycles of the
    /// operations schedule (≈ 1 h 15 min each) with the default noise seeded by `seed`.
    pub fn new(
        engine: &Engine,
        health: &HealthParams,
        period_s: f64,
        cycles: usize,
        seed: u64,
    ) -> Result<SimulatedPlant, EngineError> {
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(EngineError::Simulation {
                t_s: 0.0,
                reason: format!("sample period must be positive, got {period_s}"),
            });
        }
        let model = engine.model(health);
        let (events, period) = repeating_schedule(engine, cycles.max(1));
        let scenario = Scenario {
            events,
            end: End::At(period * cycles.max(1) as f64),
        };
        let sim = Simulation::new(&model, &scenario);
        Ok(SimulatedPlant {
            sim,
            channels: live_channels(engine, period_s, seed),
            period_s,
            k: 0,
        })
    }

    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Advances one sample period and returns the instruments' readings.
    pub fn step(&mut self) -> Result<PlantSample, EngineError> {
        self.k += 1;
        let t = self.k as f64 * self.period_s;
        self.sim.advance_to(t)?;
        let truth = values_of(&self.sim.stations());
        let mut values = [0.0; NSIG];
        for (i, ch) in self.channels.iter_mut().enumerate() {
            values[i] = ch.sample(truth[i]);
        }
        Ok(PlantSample {
            t_s: t,
            values,
            phase: self.sim.seq.phase(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plant_runs_a_start_with_noise_at_ten_hertz() {
        let engine = Engine::reference().expect("engine");
        let mut plant =
            SimulatedPlant::new(&engine, &HealthParams::HEALTHY, 0.1, 1, 1).expect("plant");
        let mut phases = Vec::new();
        let mut last = None;
        // 20 simulated minutes at 10 Hz.
        for _ in 0..12_000 {
            let s = plant.step().expect("steps");
            if last != Some(s.phase) {
                phases.push(s.phase);
                last = Some(s.phase);
            }
            assert!(s.values.iter().all(|v| v.is_finite()));
        }
        assert_eq!(
            &phases[..4],
            &[
                Phase::Standstill,
                Phase::Crank,
                Phase::Purge,
                Phase::LightOff
            ]
        );
        assert!(phases.contains(&Phase::Steady), "{phases:?}");
    }
}
