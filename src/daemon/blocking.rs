//! The one helper for blocking store work in the daemon's tasks: run a closure with the task's
//! own connection on tokio's blocking pool, opening the connection first when it is missing
//! (the first use, or lost because an earlier closure panicked).
//!
//! The start-up opens the writable connection with it ([`BlockingStore::writable`]) and hands
//! it to the writer; the detector and the diagnosis worker read through read-only ones
//! ([`BlockingStore::read_only`]) and write through the writer. All go through
//! [`BlockingStore::run`] instead of repeating the take / spawn_blocking / reopen / put back
//! dance. Must not decide what to do with an error (the task logs, counts or retries) and must
//! never run store work on the async runtime.

use crate::store::{ReadStore, Store, StoreError, StoreOptions};
use std::path::{Path, PathBuf};

/// Why a piece of blocking store work gave no result.
#[derive(Debug, thiserror::Error)]
pub(super) enum BlockingError<E> {
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

/// How a connection of kind `S` is opened.
type Opener<S> = fn(&Path, &StoreOptions) -> Result<S, StoreError>;

/// A task's own connection (a writable [`Store`] or a [`ReadStore`]), used only on the
/// blocking pool.
#[derive(Debug)]
pub(super) struct BlockingStore<S = Store> {
    path: PathBuf,
    opts: StoreOptions,
    open: Opener<S>,
    store: Option<S>,
}

impl BlockingStore<Store> {
    /// A writable connection to `path`, opened with `opts` on first use (the writer's).
    pub(super) fn writable(path: PathBuf, opts: StoreOptions) -> BlockingStore<Store> {
        BlockingStore {
            path,
            opts,
            open: Store::open_with,
            store: None,
        }
    }
}

impl BlockingStore<ReadStore> {
    /// A read-only connection to `path`, opened with `opts` on first use.
    pub(super) fn read_only(path: PathBuf, opts: StoreOptions) -> BlockingStore<ReadStore> {
        BlockingStore {
            path,
            opts,
            open: Store::open_readonly_with,
            store: None,
        }
    }
}

impl<S: Send + 'static> BlockingStore<S> {
    /// Runs `work` with the connection on the blocking pool (opening it if needed).
    pub(super) async fn run<T, E, F>(&mut self, work: F) -> Result<T, BlockingError<E>>
    where
        F: FnOnce(&mut S) -> Result<T, E> + Send + 'static,
        T: Send + 'static,
        E: Send + 'static,
    {
        let store = self.store.take();
        let path = self.path.clone();
        let opts = self.opts;
        let open = self.open;
        let joined = tokio::task::spawn_blocking(move || {
            let mut store = match store {
                Some(s) => s,
                None => match open(&path, &opts) {
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
    pub(super) fn into_store(self) -> Option<S> {
        self.store
    }
}
