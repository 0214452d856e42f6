//! The `[acquisition]` section: source, poll period, timeouts, backoff, clock re-anchoring and
//! the optional plant-clock field, with its validation (every problem, each naming its key).
//! Plain data: no I/O.

use crate::config_problem::{check_range, Bounds, ConfigProblem};
use serde::{Deserialize, Serialize};

/// The `[acquisition]` section: where samples come from and how the poll loop behaves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AcquisitionConfig {
    /// `modbus` (live polling of `[modbus]`) or `none` (no live acquisition: the daemon only
    /// runs the detector over replayed data).
    #[serde(default)]
    pub source: SourceKind,
    /// Poll period, ms (100 = 10 Hz).
    #[serde(default = "d_poll")]
    pub poll_period_ms: u64,
    /// Timeout for establishing the TCP connection, ms.
    #[serde(default = "d_connect")]
    pub connect_timeout_ms: u64,
    /// Timeout for one read request, ms. Must be shorter than the poll period's multiple you
    /// can tolerate losing; a timed-out connection is always dropped.
    #[serde(default = "d_request")]
    pub request_timeout_ms: u64,
    /// First reconnect delay after a failure, ms; doubles on each further failure…
    #[serde(default = "d_backoff0")]
    pub backoff_initial_ms: u64,
    /// …up to this cap, ms.
    #[serde(default = "d_backoff_max")]
    pub backoff_max_ms: u64,
    /// Wall-clock jump that re-anchors the sample clock, ms (see `acquire::clock`).
    #[serde(default = "d_rejump")]
    pub clock_jump_threshold_ms: u64,
    /// Name of a register-map field that carries the plant's own clock (Unix epoch ms, e.g.
    /// `plant_time_ms` served by `gtwatch plant-sim`). Set: every poll's samples are stamped
    /// with that value instead of the local clock, so a plant simulated faster than real time
    /// keeps its real durations; a poll whose clock value is invalid is a failed poll (a gap),
    /// and one whose clock did not advance is not stored. Absent (default): local clock.
    #[serde(default)]
    pub timestamp_field: Option<String>,
}

/// Where live samples come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceKind {
    #[default]
    Modbus,
    None,
}

fn d_poll() -> u64 {
    100
}
fn d_connect() -> u64 {
    3000
}
fn d_request() -> u64 {
    1000
}
fn d_backoff0() -> u64 {
    500
}
fn d_backoff_max() -> u64 {
    30_000
}
fn d_rejump() -> u64 {
    1000
}

impl Default for AcquisitionConfig {
    fn default() -> Self {
        AcquisitionConfig {
            source: SourceKind::Modbus,
            poll_period_ms: d_poll(),
            connect_timeout_ms: d_connect(),
            request_timeout_ms: d_request(),
            backoff_initial_ms: d_backoff0(),
            backoff_max_ms: d_backoff_max(),
            clock_jump_threshold_ms: d_rejump(),
            timestamp_field: None,
        }
    }
}

impl AcquisitionConfig {
    pub fn validate(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        let k = |s: &str| format!("acquisition.{s}");
        if !(1..=3_600_000).contains(&self.poll_period_ms) {
            p.push(ConfigProblem::new(
                k("poll_period_ms"),
                format!("{} ms is outside 1 ms … 1 h", self.poll_period_ms),
            ));
        }
        for (name, v) in [
            ("connect_timeout_ms", self.connect_timeout_ms),
            ("request_timeout_ms", self.request_timeout_ms),
            ("backoff_initial_ms", self.backoff_initial_ms),
            ("clock_jump_threshold_ms", self.clock_jump_threshold_ms),
        ] {
            if v == 0 {
                p.push(ConfigProblem::new(k(name), "must be greater than 0"));
            } else {
                check_range(
                    &mut p,
                    &k(name),
                    v,
                    Bounds {
                        lo: 1,
                        hi: 86_400_000,
                        unit: " ms",
                        why: "at most one day",
                    },
                );
            }
        }
        check_range(
            &mut p,
            &k("backoff_max_ms"),
            self.backoff_max_ms,
            Bounds {
                lo: 0,
                hi: 86_400_000,
                unit: " ms",
                why: "at most one day",
            },
        );
        if self.backoff_max_ms < self.backoff_initial_ms {
            p.push(ConfigProblem::new(
                k("backoff_max_ms"),
                format!(
                    "cap {} ms is below backoff_initial_ms {} ms",
                    self.backoff_max_ms, self.backoff_initial_ms
                ),
            ));
        }
        p
    }
}
