//! Counters of the running poll loop (read by the daemon's watchdog, logs and benchmarks), its
//! final tallies, and the capped exponential reconnect backoff. No I/O.

use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Counters the daemon reads while the loop runs (watchdog, logs, benchmarks).
#[derive(Debug, Default)]
pub struct PollProgress {
    /// Polls in which every request succeeded.
    pub polls_ok: AtomicU64,
    /// Polls or connection attempts that failed.
    pub failures: AtomicU64,
    pub samples: AtomicU64,
    /// Samples stored flagged (any code but good).
    pub flagged: AtomicU64,
    /// ... of which flagged stuck (code 3) and spike (code 4).
    pub stuck: AtomicU64,
    pub spike: AtomicU64,
    pub gaps: AtomicU64,
    pub connects: AtomicU64,
    /// Loop iterations completed (a poll, a recorded failure or a backoff wait): liveness.
    pub cycles: AtomicU64,
    /// Polls not stored because the plant clock (`timestamp_field`) had not advanced.
    pub clock_stalls: AtomicU64,
    /// Wall-clock steps that re-anchored the sample clock (`acquire::clock`).
    pub clock_reanchors: AtomicU64,
}

/// Final tallies when the loop ends.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct PollStats {
    pub polls_ok: u64,
    pub failures: u64,
    pub samples: u64,
    pub flagged: u64,
    pub stuck: u64,
    pub spike: u64,
    pub gaps: u64,
    pub connects: u64,
}

impl PollProgress {
    pub fn snapshot(&self) -> PollStats {
        PollStats {
            polls_ok: self.polls_ok.load(Ordering::Relaxed),
            failures: self.failures.load(Ordering::Relaxed),
            samples: self.samples.load(Ordering::Relaxed),
            flagged: self.flagged.load(Ordering::Relaxed),
            stuck: self.stuck.load(Ordering::Relaxed),
            spike: self.spike.load(Ordering::Relaxed),
            gaps: self.gaps.load(Ordering::Relaxed),
            connects: self.connects.load(Ordering::Relaxed),
        }
    }
}

/// Capped exponential backoff.
#[derive(Debug, Clone)]
pub struct Backoff {
    initial: Duration,
    max: Duration,
    next: Duration,
}

impl Backoff {
    pub fn new(initial: Duration, max: Duration) -> Self {
        Backoff {
            initial,
            max,
            next: initial,
        }
    }
    /// The delay before the next attempt; doubles the one after, up to the cap.
    pub fn next_delay(&mut self) -> Duration {
        let d = self.next;
        self.next = (self.next * 2).min(self.max);
        d
    }
    pub fn reset(&mut self) {
        self.next = self.initial;
    }
}
