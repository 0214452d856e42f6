//! The start-up detector as a pure state machine: time-ordered frames in, segments out.
//!
//! No I/O, no clock, no globals: the same frames give the same segments, live or on replay.
//! Phase rules follow the daemon contract (see `DetectorConfig` for thresholds).
//! Must not read or write the database; `detect::scan` does that.

use super::DetectorConfig;
use crate::signals::Phase;
use serde::Serialize;

/// One aligned sample of the detector's inputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Unix epoch ms.
    pub t_ms: i64,
    /// Gas-generator speed, rpm.
    pub n1: f64,
    /// Fuel flow, kg/s.
    pub fuel: f64,
    /// Generator power, MW.
    pub power: f64,
    /// Power-turbine speed, rpm, if measured.
    pub n2: Option<f64>,
}

/// How a start-up ended (so far).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Still running (segment open).
    InProgress,
    /// Reached steady load.
    Completed,
    /// Ended before steady load.
    Aborted,
}

impl Outcome {
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::InProgress => "in_progress",
            Outcome::Completed => "completed",
            Outcome::Aborted => "aborted",
        }
    }
    pub fn parse(s: &str) -> Option<Outcome> {
        [Outcome::InProgress, Outcome::Completed, Outcome::Aborted]
            .into_iter()
            .find(|o| o.as_str() == s)
    }
}

/// Why an aborted start ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AbortCause {
    /// Fuel cut abruptly.
    Trip,
    /// Fuel present but n1 decays.
    FlameOut,
    /// Fuel ramped off, or the starter stopped before light-off.
    OperatorStop,
    /// The data ended or jumped in a way that fits none of the above.
    Unknown,
}

impl AbortCause {
    pub fn as_str(self) -> &'static str {
        match self {
            AbortCause::Trip => "trip",
            AbortCause::FlameOut => "flame_out",
            AbortCause::OperatorStop => "operator_stop",
            AbortCause::Unknown => "unknown",
        }
    }
    pub fn parse(s: &str) -> Option<AbortCause> {
        [
            AbortCause::Trip,
            AbortCause::FlameOut,
            AbortCause::OperatorStop,
            AbortCause::Unknown,
        ]
        .into_iter()
        .find(|o| o.as_str() == s)
    }
}

/// One phase of a segment. `end_ms` is `None` while the phase is running.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct PhaseSpan {
    pub phase: Phase,
    pub start_ms: i64,
    pub end_ms: Option<i64>,
}

/// A start-up as found so far.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SegmentRecord {
    pub start_ms: i64,
    /// `None` while open.
    pub end_ms: Option<i64>,
    pub outcome: Outcome,
    pub abort_cause: Option<AbortCause>,
    pub hot_restart: bool,
    pub has_gap: bool,
    /// Phases in time order; the last may be open.
    pub phases: Vec<PhaseSpan>,
}

impl SegmentRecord {
    pub fn is_open(&self) -> bool {
        self.end_ms.is_none()
    }
    /// The span of `phase`, if the start got there.
    pub fn phase(&self, phase: Phase) -> Option<&PhaseSpan> {
        self.phases.iter().find(|p| p.phase == phase)
    }
}

/// The state machine. Feed frames in time order with [`Machine::push`].
#[derive(Debug, Clone)]
pub struct Machine {
    cfg: DetectorConfig,
    /// Time of the last fuel-off seen (for the hot-restart rule), carried across restarts.
    last_fuel_off_ms: Option<i64>,
    finished: Vec<SegmentRecord>,
}

impl Machine {
    /// A machine that knows nothing of the past except the last fuel-off time.
    pub fn new(cfg: DetectorConfig, last_fuel_off_ms: Option<i64>) -> Machine {
        Machine {
            cfg,
            last_fuel_off_ms,
            finished: Vec::new(),
        }
    }

    /// Feeds one frame (time must increase).
    pub fn push(&mut self, _frame: Frame) {
        let _ = &self.cfg;
    }

    /// Marks a data gap between `from_ms` and `to_ms` (the open segment, if any, gets `has_gap`).
    pub fn note_gap(&mut self, _from_ms: i64, _to_ms: i64) {}

    /// Segments closed since the last call.
    pub fn take_finished(&mut self) -> Vec<SegmentRecord> {
        std::mem::take(&mut self.finished)
    }

    /// The segment in progress, if any.
    pub fn open_segment(&self) -> Option<SegmentRecord> {
        None
    }

    pub fn last_fuel_off_ms(&self) -> Option<i64> {
        self.last_fuel_off_ms
    }
}
