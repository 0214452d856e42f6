//! The one helper for blocking store work in the daemon's tasks: run a closure with the task's
//! own connection on tokio's blocking pool, opening the connection first when it is missing
//! (the first use, or lost because an earlier closure panicked).
//!
//! Every task that reads or writes the database outside the writer (the detector, the
//! diagnosis worker, the start-up) goes through [`BlockingStore::run`] instead of repeating
//! the take / spawn_blocking / reopen / put back dance. Must not decide what to do with an
//! error (the task logs, counts or retries) and must never run store work on the async runtime.

use crate::store::{Store, StoreError, StoreOptions};
use std::path::PathBuf;

/// Why a piece of blocking store work gave no result.
#[derive(Debug, thiserror::Error)]
pub enum BlockingError<E> {
    /// The connection could not be opened; the next run tries again.
    #[error("{0}")]
    Open(StoreError),
    /// The work itself failed; the connection is kept.
    #[error("{0}")]
    Work(E),
    /// The work panicked or was cancelled; the connection is lost and reopened next time.
    #[error("task failed: {0}")]
    Panicked(tokio::task::JoinError),
}

/// A task's own connection, used only on the blocking pool.
#[derive(Debug)]
pub struct BlockingStore {
    path: PathBuf,
    opts: StoreOptions,
    store: Option<Store>,
}

impl BlockingStore {
    /// A connection to `path`, opened with `opts` on first use.
    pub fn new(path: PathBuf, opts: StoreOptions) -> BlockingStore {
        BlockingStore {
            path,
            opts,
            store: None,
        }
    }

    /// Runs `work` with the connection on the blocking pool (opening it if needed).
    pub async fn run<T, E, F>(&mut self, work: F) -> Result<T, BlockingError<E>>
    where
        F: FnOnce(&mut Store) -> Result<T, E> + Send + 'static,
        T: Send + 'static,
        E: Send + 'static,
    {
        let store = self.store.take();
        let path = self.path.clone();
        let opts = self.opts;
        let joined = tokio::task::spawn_blocking(move || {
            let mut store = match store {
                Some(s) => s,
                None => match Store::open_with(&path, &opts) {
                    Ok(s) => s,
                    Err(e) => return (None, Err(BlockingError::Open(e))),
                },
            };
            let result = work(&mut store).map_err(BlockingError::Work);
            (Some(store), result)
        })
        .await;
        match joined {
            Ok((store, result)) => {
                self.store = store;
                result
            }
            Err(e) => Err(BlockingError::Panicked(e)),
        }
    }

    /// The connection, if open (the start-up hands it to the writer).
    pub fn into_store(self) -> Option<Store> {
        self.store
    }
}
