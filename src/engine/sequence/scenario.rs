//! The scenarios the sequencer runs: operator and protection commands at given times, and when
//! a run ends — a start-up to steady base load, or a stretch of operations (start, stop,
//! aborted start, hot restart) for the plant simulator and the detector's tests.
//!
//! Must not act on the engine: it states what is asked; the sequencer does it.

use crate::engine::config::EngineConfig;

/// An operator or protection command at a given time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    Start,
    /// Normal stop: unload, cool down, fuel off.
    Stop,
    /// Protective trip: fuel off and breaker open at once.
    Trip,
}

/// A command scheduled at `t_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    pub t_s: f64,
    pub command: Command,
}

/// When a scenario ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum End {
    /// At a fixed time.
    At(f64),
    /// This long after the engine first reaches steady load (with `max_s` as a guard).
    AfterSteady { hold_s: f64, max_s: f64 },
}

/// A sequence of commands and an end condition.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    pub events: Vec<Event>,
    pub end: End,
}

impl Scenario {
    /// REFERENCE §2 start-up from standstill to steady base load.
    pub fn startup(cfg: &EngineConfig) -> Scenario {
        Scenario {
            events: vec![Event {
                t_s: cfg.sequence.standstill_s,
                command: Command::Start,
            }],
            end: End::AfterSteady {
                hold_s: cfg.sequence.steady_s,
                max_s: 3600.0,
            },
        }
    }
}

impl Scenario {
    /// A stretch of operations for the plant simulator and the detector's tests: a start to base
    /// load, a normal stop, an aborted start (tripped during acceleration), and a hot restart
    /// soon after the trip that runs to base load.
    pub fn operations(cfg: &EngineConfig) -> Scenario {
        let s0 = cfg.sequence.standstill_s;
        // A start takes ~13 min; hold base load 5 min, then stop (cool-down + coast ≈ 6 min).
        let stop = s0 + 1100.0;
        let second = stop + 600.0;
        let trip = second + 120.0;
        let hot = trip + 240.0;
        Scenario {
            events: vec![
                Event {
                    t_s: s0,
                    command: Command::Start,
                },
                Event {
                    t_s: stop,
                    command: Command::Stop,
                },
                Event {
                    t_s: second,
                    command: Command::Start,
                },
                Event {
                    t_s: trip,
                    command: Command::Trip,
                },
                Event {
                    t_s: hot,
                    command: Command::Start,
                },
            ],
            end: End::At(hot + 1100.0),
        }
    }
}
