//! The writer task: the one owner of the daemon's writable connection (`store::run_writer_with_progress`).
//! Acquisition sends it samples and gaps, the detector and the diagnosis worker their typed
//! write requests (a scan, an outcome, the wash advice), all over the one bounded channel.
//!
//! Unlike the other tasks it does not stop when shutdown fires: acquisition sends its last
//! samples and the gap of an outage still open after shutdown, the detector its final scan, so
//! the writer runs until every sender is gone, commits what it holds and returns. Must not
//! decide what to store (that is its senders') or hold SQL (that is the store's).

use crate::shutdown::Shutdown;
use crate::store::{
    run_writer_with_progress, Store, StoreError, WriteCmd, WriterConfig, WriterProgress,
    WriterStats,
};
use std::sync::Arc;
use tokio::sync::mpsc;

/// The writer task (mini-redis shape: a small struct with its own `run`).
pub struct WriterTask {
    pub store: Store,
    pub rx: mpsc::Receiver<WriteCmd>,
    pub cfg: WriterConfig,
    /// Running totals, published as the writer goes (the metrics endpoint reads them).
    pub progress: Arc<WriterProgress>,
}

impl WriterTask {
    /// Writes until the channel closes (after shutdown, once acquisition has ended).
    /// `_shutdown` is taken for the tasks' common shape and deliberately not waited on.
    pub async fn run(self, _shutdown: Shutdown) -> Result<WriterStats, StoreError> {
        run_writer_with_progress(self.store, self.rx, self.cfg, self.progress).await
    }
}
