//! The senders' side of the writer's bounded channel: [`WriterHandle`], cloned by every task
//! that writes (acquisition, the detector, the diagnosis worker).
//!
//! Back-pressure is explicit: a send that finds the channel full waits for room (it never
//! drops or replaces the command, so acquisition never loses a sample to a busy writer), and
//! the wait is counted ([`WriterHandle::channel_full_waits`]) and logged at warn level ("writer
//! channel full") the first time and then at every power of two. Requests that need an answer
//! (a scan, an outcome, the advice) carry a oneshot and wait for it, asynchronously or, on the
//! blocking pool, blocking. Must not touch the database (the writer does) or decide what to
//! write.

use super::writer::{Reply, WriteCmd};
use super::StoreError;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;
use tokio::sync::{mpsc, oneshot};

/// A new bounded channel to the writer (`capacity` ≥ 1): the senders' handle and the writer's
/// receiver.
pub fn writer_channel(capacity: usize) -> (WriterHandle, mpsc::Receiver<WriteCmd>) {
    let (tx, rx) = mpsc::channel(capacity.max(1));
    (
        WriterHandle {
            tx,
            pressure: Arc::default(),
        },
        rx,
    )
}

/// Counters shared by all clones of one handle.
#[derive(Debug, Default)]
struct Pressure {
    full_waits: AtomicU64,
    waited_us: AtomicU64,
}

/// A sender to the writer (see the module comment). Cheap to clone; the writer ends once every
/// clone is dropped.
#[derive(Debug, Clone)]
pub struct WriterHandle {
    tx: mpsc::Sender<WriteCmd>,
    pressure: Arc<Pressure>,
}

/// The error of a send to a writer that has ended.
fn gone() -> StoreError {
    StoreError::Writer("the writer has stopped".to_string())
}

impl WriterHandle {
    /// A handle on an existing sender (tests and benches that build the channel themselves).
    pub fn from_sender(tx: mpsc::Sender<WriteCmd>) -> WriterHandle {
        WriterHandle {
            tx,
            pressure: Arc::default(),
        }
    }

    /// Sends `cmd`, waiting for room when the channel is full (counted and logged).
    pub async fn send(&self, cmd: WriteCmd) -> Result<(), StoreError> {
        match self.tx.try_send(cmd) {
            Ok(()) => Ok(()),
            Err(mpsc::error::TrySendError::Closed(_)) => Err(gone()),
            Err(mpsc::error::TrySendError::Full(cmd)) => {
                let t = self.full_wait_begins();
                let r = self.tx.send(cmd).await.map_err(|_| gone());
                self.full_wait_ends(t);
                r
            }
        }
    }

    /// [`WriterHandle::send`] from a blocking thread (never on the async runtime).
    pub fn blocking_send(&self, cmd: WriteCmd) -> Result<(), StoreError> {
        match self.tx.try_send(cmd) {
            Ok(()) => Ok(()),
            Err(mpsc::error::TrySendError::Closed(_)) => Err(gone()),
            Err(mpsc::error::TrySendError::Full(cmd)) => {
                let t = self.full_wait_begins();
                let r = self.tx.blocking_send(cmd).map_err(|_| gone());
                self.full_wait_ends(t);
                r
            }
        }
    }

    /// Sends the request `make` builds around a reply and waits for the writer's answer.
    pub async fn request<T>(
        &self,
        make: impl FnOnce(Reply<T>) -> WriteCmd,
    ) -> Result<T, StoreError> {
        let (reply, answer) = oneshot::channel();
        self.send(make(reply)).await?;
        answer.await.map_err(|_| gone())?
    }

    /// [`WriterHandle::request`] from a blocking thread (never on the async runtime).
    pub fn blocking_request<T>(
        &self,
        make: impl FnOnce(Reply<T>) -> WriteCmd,
    ) -> Result<T, StoreError> {
        let (reply, answer) = oneshot::channel();
        self.blocking_send(make(reply))?;
        answer.blocking_recv().map_err(|_| gone())?
    }

    /// Commits everything sent so far; returns once it is on disk.
    pub async fn flush(&self) -> Result<(), StoreError> {
        let (ack, done) = oneshot::channel();
        self.send(WriteCmd::Flush(ack)).await?;
        done.await.map_err(|_| gone())
    }

    /// Times a sender of this channel found it full and waited.
    pub fn channel_full_waits(&self) -> u64 {
        self.pressure.full_waits.load(Ordering::Relaxed)
    }

    /// Counts and (at the first and every power of two) logs a wait for room as it begins.
    fn full_wait_begins(&self) -> Instant {
        let n = self.pressure.full_waits.fetch_add(1, Ordering::Relaxed) + 1;
        if n.is_power_of_two() {
            tracing::warn!(
                waits = n,
                total_waited_ms = self.pressure.waited_us.load(Ordering::Relaxed) / 1000,
                capacity = self.tx.max_capacity(),
                "writer channel full: the sender waits for the writer (back-pressure)"
            );
        }
        Instant::now()
    }

    /// Adds the time a wait for room took.
    fn full_wait_ends(&self, since: Instant) {
        let waited_us = since.elapsed().as_micros() as u64;
        self.pressure
            .waited_us
            .fetch_add(waited_us, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A full channel makes the sender wait (counted), and nothing is lost.
    #[tokio::test]
    async fn a_full_channel_slows_the_sender_and_is_counted() {
        let (h, mut rx) = writer_channel(1);
        h.send(WriteCmd::Samples(Vec::new())).await.expect("room");
        assert_eq!(h.channel_full_waits(), 0);
        let h2 = h.clone();
        let sender = tokio::spawn(async move { h2.send(WriteCmd::Samples(Vec::new())).await });
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
        assert!(!sender.is_finished(), "the sender waits for room");
        let mut got = 0;
        while got < 2 {
            rx.recv().await.expect("command");
            got += 1;
        }
        sender.await.expect("join").expect("sent");
        assert_eq!(h.channel_full_waits(), 1);
        drop(h);
        assert!(rx.recv().await.is_none());
    }
}
