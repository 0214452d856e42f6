//! Sample timestamps from a monotonic-corrected wall clock.
//!
//! Samples need Unix-epoch times (the store and the plant engineers think in UTC), but the
//! wall clock can step (NTP corrections, an operator setting the time) and a step in the
//! middle of a start-up would tear a transient apart. So the clock is anchored to the wall
//! clock once and then advanced by `Instant` (monotonic): spacing between samples is exact.
//! Slow NTP slewing makes the two drift apart by at most a few ms per hour; when they differ by
//! more than `rejump_threshold` (default 1 s) the clock re-anchors to the wall clock, because
//! then the wall clock was deliberately changed and the stored times should follow it. The
//! re-anchoring is reported so the caller can log it. Timestamps never go backwards: after a
//! backward re-anchor, times are held at the last issued value + 1 ms until the wall clock
//! catches up (the store is keyed on (tag, t_ms), so duplicates would be dropped).
//! No I/O other than reading the clocks. The wall clock read is a [`WallClock`], so a test
//! (or a fault-injection run) can step it while the poll loop runs.

use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Where wall-clock readings come from.
#[derive(Debug, Clone, Default)]
pub enum WallClock {
    /// The system clock.
    #[default]
    System,
    /// The system clock plus an offset (ms) that may be changed at any time: a clock an
    /// operator or NTP steps, for fault injection.
    Shifted(Arc<AtomicI64>),
}

impl WallClock {
    /// Current reading in Unix epoch milliseconds.
    pub fn now_ms(&self) -> i64 {
        match self {
            WallClock::System => wall_now_ms(),
            WallClock::Shifted(offset) => wall_now_ms() + offset.load(Ordering::Relaxed),
        }
    }
}

/// A clock reading in Unix epoch milliseconds plus whether it re-anchored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stamp {
    pub t_ms: i64,
    /// Wall-clock jump (wall − monotonic prediction, ms) that caused a re-anchor, if any.
    pub reanchored_by_ms: Option<i64>,
}

/// Monotonic-corrected wall clock (see the module docs).
#[derive(Debug, Clone)]
pub struct SampleClock {
    anchor_wall_ms: i64,
    anchor_mono: Instant,
    rejump_threshold_ms: i64,
    last_ms: Option<i64>,
    wall: WallClock,
}

/// Current wall-clock time in Unix epoch milliseconds.
pub(crate) fn wall_now_ms() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_millis() as i64)
        .unwrap_or(0)
}

impl SampleClock {
    pub fn new(rejump_threshold: Duration) -> Self {
        Self::with_wall(WallClock::System, rejump_threshold)
    }

    /// A clock reading `wall` (see [`WallClock::Shifted`]).
    pub fn with_wall(wall: WallClock, rejump_threshold: Duration) -> Self {
        let mut c = Self::anchored(wall.now_ms(), Instant::now(), rejump_threshold);
        c.wall = wall;
        c
    }

    /// A clock anchored at the given readings (for tests and replays of clock behaviour).
    pub fn anchored(wall_ms: i64, mono: Instant, rejump_threshold: Duration) -> Self {
        SampleClock {
            anchor_wall_ms: wall_ms,
            anchor_mono: mono,
            rejump_threshold_ms: rejump_threshold.as_millis() as i64,
            last_ms: None,
            wall: WallClock::System,
        }
    }

    /// The last timestamp issued, if any.
    pub fn last_issued_ms(&self) -> Option<i64> {
        self.last_ms
    }

    /// Timestamp for now.
    pub fn now(&mut self) -> Stamp {
        let wall = self.wall.now_ms();
        self.stamp(wall, Instant::now())
    }

    /// Timestamp given explicit wall and monotonic readings (pure; `now` calls this).
    pub fn stamp(&mut self, wall_ms: i64, mono: Instant) -> Stamp {
        let predicted = self.anchor_wall_ms
            + mono.saturating_duration_since(self.anchor_mono).as_millis() as i64;
        let jump = wall_ms - predicted;
        let mut reanchored_by_ms = None;
        let mut t = predicted;
        if jump.abs() > self.rejump_threshold_ms {
            self.anchor_wall_ms = wall_ms;
            self.anchor_mono = mono;
            reanchored_by_ms = Some(jump);
            t = wall_ms;
        }
        if let Some(last) = self.last_ms {
            t = t.max(last + 1);
        }
        self.last_ms = Some(t);
        Stamp {
            t_ms: t,
            reanchored_by_ms,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_monotonic_time_and_ignores_small_wall_noise() {
        let t0 = Instant::now();
        let mut c = SampleClock::anchored(1_000_000, t0, Duration::from_secs(1));
        let s = c.stamp(1_000_000, t0);
        assert_eq!(s.t_ms, 1_000_000);
        // Wall clock slewed by 300 ms: below the threshold, monotonic wins.
        let s = c.stamp(1_000_400, t0 + Duration::from_millis(100));
        assert_eq!((s.t_ms, s.reanchored_by_ms), (1_000_100, None));
    }

    #[test]
    fn reanchors_on_a_forward_jump() {
        let t0 = Instant::now();
        let mut c = SampleClock::anchored(1_000_000, t0, Duration::from_secs(1));
        let s = c.stamp(1_000_000 + 3_600_000 + 200, t0 + Duration::from_millis(200));
        assert_eq!(s.reanchored_by_ms, Some(3_600_000));
        assert_eq!(s.t_ms, 4_600_200);
        let s = c.stamp(0, t0 + Duration::from_millis(300)); // wall unreadable/garbage later
        assert_eq!(s.reanchored_by_ms, Some(-4_600_300));
    }

    #[test]
    fn never_goes_backwards_after_a_backward_jump() {
        let t0 = Instant::now();
        let mut c = SampleClock::anchored(10_000, t0, Duration::from_secs(1));
        assert_eq!(c.stamp(10_000, t0).t_ms, 10_000);
        let s = c.stamp(5_000, t0 + Duration::from_millis(100));
        assert_eq!(s.reanchored_by_ms, Some(-5_100));
        assert_eq!(s.t_ms, 10_001);
        // Subsequent samples follow the new anchor but stay strictly increasing.
        let s = c.stamp(5_100, t0 + Duration::from_millis(200));
        assert_eq!(s.t_ms, 10_002);
        let s = c.stamp(20_000, t0 + Duration::from_millis(15_100));
        assert_eq!((s.t_ms, s.reanchored_by_ms), (20_000, None));
    }
}
