//! A start-up segment as the detector finds it and the store keeps it: its span, how it ended
//! (completed, aborted and why), whether it was a hot restart or crossed a data gap, and its
//! phases in time order.
//!
//! Plain data shared by the detector's state machine (`detect`), the store that writes and reads
//! segments (`store`) and the read-side queries (`query`), so none of them has to import another
//! for the type. Foundation floor: depends only on [`crate::signals`]. Must not detect, store or
//! format anything beyond the stable names of its enums.

use crate::signals::Phase;
use serde::Serialize;

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
