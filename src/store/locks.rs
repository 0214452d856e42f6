//! Lock waits, counted: the busy handler every connection of the store installs instead of
//! SQLite's `busy_timeout`.
//!
//! When a connection finds the database locked by another one, SQLite calls the busy handler;
//! this one counts the wait ([`lock_waits`]: once per lock a statement waited for, however
//! many retries it took, plus the time slept), then sleeps with SQLite's own `busy_timeout`
//! schedule (1, 2, 5, 10, 15, 20, 25, 25, 25, 50, 50, 100 ms, then 100 ms) and gives up
//! (`SQLITE_BUSY`, "database is locked") once the wait reaches the limit. In the daemon the one
//! writer owns the writable connection and every other task reads in WAL mode, so nothing in
//! it should ever wait: `gtwatch bench daemon` prints the count as `store_lock_waits`.
//!
//! rusqlite takes the handler as a plain function, which cannot tell connections apart: the
//! counters are process-wide and the wait limit is the longest busy timeout of any connection
//! opened in the process (in the daemon and the commands that is `storage.busy_timeout_ms`,
//! or 5 s for read-only handles). Must not hold queries.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Locks waited for (first calls of the busy handler), process-wide.
static WAITS: AtomicU64 = AtomicU64::new(0);
/// Milliseconds slept waiting for locks, process-wide.
static WAITED_MS: AtomicU64 = AtomicU64::new(0);
/// The wait limit, ms: the longest busy timeout of the connections opened so far.
static LIMIT_MS: AtomicU64 = AtomicU64::new(0);

/// SQLite's `busy_timeout` delays, ms (sqlite3.c, `sqliteDefaultBusyCallback`).
const DELAYS_MS: [u64; 12] = [1, 2, 5, 10, 15, 20, 25, 25, 25, 50, 50, 100];

/// How often connections of this process waited for a lock, and for how long in total.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct LockWaits {
    /// Locks waited for (a statement that waited counts once, however many retries it took).
    pub waits: u64,
    /// Time slept waiting, ms.
    pub waited_ms: u64,
}

/// The lock waits of every connection this process opened so far.
pub fn lock_waits() -> LockWaits {
    LockWaits {
        waits: WAITS.load(Ordering::Relaxed),
        waited_ms: WAITED_MS.load(Ordering::Relaxed),
    }
}

/// Installs the counting busy handler on `conn`, with `timeout_ms` as (at least) the limit.
pub(super) fn install(conn: &rusqlite::Connection, timeout_ms: u64) -> rusqlite::Result<()> {
    LIMIT_MS.fetch_max(timeout_ms, Ordering::Relaxed);
    conn.busy_handler(Some(on_busy))
}

/// Counts one wait that is not the busy handler's (a retry loop of the store's own).
pub(super) fn count_wait(slept: Duration) {
    WAITS.fetch_add(1, Ordering::Relaxed);
    WAITED_MS.fetch_add(slept.as_millis() as u64, Ordering::Relaxed);
}

/// Milliseconds already waited before retry number `count` (0-based).
fn waited_before(count: usize) -> u64 {
    let n = count.min(DELAYS_MS.len());
    let head: u64 = DELAYS_MS[..n].iter().sum();
    head + (count.saturating_sub(DELAYS_MS.len()) as u64) * 100
}

/// The busy handler: count, sleep, retry until the limit (see the module comment).
fn on_busy(count: i32) -> bool {
    let count = usize::try_from(count).unwrap_or(0);
    if count == 0 {
        WAITS.fetch_add(1, Ordering::Relaxed);
    }
    let limit = LIMIT_MS.load(Ordering::Relaxed);
    let waited = waited_before(count);
    if waited >= limit {
        return false;
    }
    let delay = DELAYS_MS
        .get(count)
        .copied()
        .unwrap_or(100)
        .min(limit - waited);
    std::thread::sleep(Duration::from_millis(delay));
    WAITED_MS.fetch_add(delay, Ordering::Relaxed);
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedule_is_sqlites() {
        assert_eq!(waited_before(0), 0);
        assert_eq!(waited_before(3), 8);
        assert_eq!(waited_before(12), 328);
        assert_eq!(waited_before(14), 528);
    }

    /// A connection that finds the file locked by another one waits (counted) and, once the
    /// lock is gone, goes on.
    #[test]
    fn a_wait_for_a_lock_is_counted() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("l.db");
        let mut a = crate::store::Store::open(&path).expect("a");
        let b = crate::store::Store::open(&path).expect("b");
        let before = lock_waits().waits;
        let tx = a
            .conn_mut()
            .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)
            .expect("lock");
        let t = std::thread::spawn(move || {
            b.conn
                .execute(
                    "INSERT INTO washes (t_ms, kind, note) VALUES (1, 'online', '')",
                    [],
                )
                .expect("insert after waiting")
        });
        std::thread::sleep(Duration::from_millis(100));
        tx.commit().expect("release");
        assert_eq!(t.join().expect("join"), 1);
        assert!(lock_waits().waits > before);
    }
}
