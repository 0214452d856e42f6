//! The supervisor's side of systemd: READY=1 after the first successful poll (at once when
//! nothing is polled), WATCHDOG=1 only while the poll loop makes progress, STOPPING=1 when
//! shutdown fires. Runs until shutdown. Must not start, stop or restart tasks itself (a hung
//! acquisition is systemd's to restart, through the withheld watchdog ping).

use crate::acquire::modbus::PollProgress;
use crate::shutdown::Shutdown;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

/// How often readiness is checked before the first successful poll.
const READY_CHECK: Duration = Duration::from_millis(50);

/// Readiness and watchdog notifications (mini-redis shape: a small struct with its own `run`).
pub struct Supervisor {
    /// Send sd_notify messages at all (off in tests).
    pub systemd_notify: bool,
    /// The poll loop's counters.
    pub progress: Arc<PollProgress>,
    /// Whether an acquisition task runs (without one the daemon is ready at once and the
    /// watchdog is fed unconditionally).
    pub acquiring: bool,
}

impl Supervisor {
    /// Notifies until `shutdown` fires, then sends STOPPING=1.
    pub async fn run(self, mut shutdown: Shutdown) {
        let watchdog = Watchdog::from_env(self.systemd_notify);
        let mut wd_tick = tokio::time::interval(watchdog.period);
        wd_tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut ready = !self.acquiring;
        if ready {
            notify(self.systemd_notify, &[sd_notify::NotifyState::Ready]);
        }
        let mut last_cycles = 0u64;
        let mut ready_check = tokio::time::interval(READY_CHECK);
        loop {
            tokio::select! {
                biased;
                _ = shutdown.wait() => break,
                _ = ready_check.tick(), if !ready => ready = self.check_ready(),
                _ = wd_tick.tick(), if watchdog.enabled => self.feed_watchdog(&mut last_cycles),
            }
        }
        notify(self.systemd_notify, &[sd_notify::NotifyState::Stopping]);
    }

    /// READY=1 once the first poll succeeded; whether it has.
    fn check_ready(&self) -> bool {
        if self.progress.polls_ok.load(Ordering::Relaxed) == 0 {
            return false;
        }
        tracing::info!("first poll succeeded; ready");
        notify(self.systemd_notify, &[sd_notify::NotifyState::Ready]);
        true
    }

    /// WATCHDOG=1 if the poll loop finished a cycle (a poll, or a failure it recorded) since
    /// the last ping. A PLC outage is a recorded gap, not a daemon fault; a hung loop or a
    /// writer that stopped accepting samples is, and then systemd restarts us.
    fn feed_watchdog(&self, last_cycles: &mut u64) {
        let cycles = self.progress.cycles.load(Ordering::Relaxed);
        if cycles != *last_cycles || !self.acquiring {
            *last_cycles = cycles;
            notify(true, &[sd_notify::NotifyState::Watchdog]);
        } else {
            tracing::warn!("acquisition made no progress; withholding watchdog ping");
        }
    }
}

/// Whether systemd asked for watchdog pings, and how often to send them (half its timeout).
struct Watchdog {
    enabled: bool,
    period: Duration,
}

impl Watchdog {
    fn from_env(systemd_notify: bool) -> Watchdog {
        let mut usec = 0u64;
        let enabled = systemd_notify && sd_notify::watchdog_enabled(false, &mut usec);
        Watchdog {
            enabled,
            period: Duration::from_micros((usec / 2).max(100_000)),
        }
    }
}

/// Sends `state` to systemd when `enabled`; a failure is only logged.
fn notify(enabled: bool, state: &[sd_notify::NotifyState]) {
    if enabled {
        if let Err(e) = sd_notify::notify(false, state) {
            tracing::debug!("sd_notify: {e}");
        }
    }
}
