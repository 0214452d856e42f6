//! The shutdown signal passed into long-running tasks as a value (as in mini-redis).
//!
//! `main` maps SIGTERM/SIGINT onto a [`ShutdownTrigger`]; tests trigger it directly. Every task
//! holds a cloned [`Shutdown`] and selects on [`Shutdown::wait`]. Dropping the trigger also
//! counts as shutdown, so a task can never outlive its owner by waiting forever.
//! Must not decide when to shut down or hold any task state: it only carries the signal.

use tokio::sync::watch;

/// Triggers shutdown of every task holding a [`Shutdown`] made from it.
#[derive(Debug)]
pub struct ShutdownTrigger {
    tx: watch::Sender<bool>,
}

/// Observes the shutdown signal.
#[derive(Debug, Clone)]
pub struct Shutdown {
    rx: watch::Receiver<bool>,
}

/// A new trigger and its first observer.
pub fn shutdown_channel() -> (ShutdownTrigger, Shutdown) {
    let (tx, rx) = watch::channel(false);
    (ShutdownTrigger { tx }, Shutdown { rx })
}

impl ShutdownTrigger {
    pub fn trigger(&self) {
        let _ = self.tx.send(true);
    }

    /// Another observer.
    pub fn subscribe(&self) -> Shutdown {
        Shutdown {
            rx: self.tx.subscribe(),
        }
    }
}

impl Shutdown {
    pub fn is_triggered(&self) -> bool {
        *self.rx.borrow()
    }

    /// Completes once shutdown was triggered (or the trigger dropped).
    pub async fn wait(&mut self) {
        let _ = self.rx.wait_for(|&v| v).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn trigger_and_drop_both_end_the_wait() {
        let (t, mut s) = shutdown_channel();
        let mut s2 = t.subscribe();
        assert!(!s.is_triggered());
        t.trigger();
        s.wait().await;
        s2.wait().await;
        assert!(s.is_triggered());
        let (t, mut s) = shutdown_channel();
        drop(t);
        s.wait().await;
    }
}
