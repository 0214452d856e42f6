//! Schema migrations: the SQL files in `migrations/`, embedded and applied in order.
//!
//! A new schema version is a new `migrations/NNNN_name.sql` appended to [`MIGRATIONS`]; never
//! edit a released file. Must not hold queries: only schema versioning.

use super::StoreError;
use rusqlite::{Connection, TransactionBehavior};
#[cfg(test)]
use rusqlite_migration::{Migrations, M};
use std::path::Path;

/// Name and SQL of each migration, in order (names appear in errors instead of the SQL).
const MIGRATION_SQL: &[(&str, &str)] = &[
    (
        "0001_initial.sql",
        include_str!("../../migrations/0001_initial.sql"),
    ),
    (
        "0002_diagnosis_results.sql",
        include_str!("../../migrations/0002_diagnosis_results.sql"),
    ),
    (
        "0003_quality_codes.sql",
        include_str!("../../migrations/0003_quality_codes.sql"),
    ),
    (
        "0004_gap_analyses.sql",
        include_str!("../../migrations/0004_gap_analyses.sql"),
    ),
    (
        "0005_fleet_sync.sql",
        include_str!("../../migrations/0005_fleet_sync.sql"),
    ),
    (
        "0006_archive.sql",
        include_str!("../../migrations/0006_archive.sql"),
    ),
    (
        "0007_rollups.sql",
        include_str!("../../migrations/0007_rollups.sql"),
    ),
    (
        "0008_rollups_1h.sql",
        include_str!("../../migrations/0008_rollups_1h.sql"),
    ),
    (
        "0009_instrument_corrections.sql",
        include_str!("../../migrations/0009_instrument_corrections.sql"),
    ),
    (
        "0010_corrections_also.sql",
        include_str!("../../migrations/0010_corrections_also.sql"),
    ),
];

#[cfg(test)]
const MIGRATION_LIST: &[M<'static>] = &[
    M::up(MIGRATION_SQL[0].1),
    M::up(MIGRATION_SQL[1].1),
    M::up(MIGRATION_SQL[2].1),
    M::up(MIGRATION_SQL[3].1),
    M::up(MIGRATION_SQL[4].1),
    M::up(MIGRATION_SQL[5].1),
    M::up(MIGRATION_SQL[6].1),
    M::up(MIGRATION_SQL[7].1),
    M::up(MIGRATION_SQL[8].1),
    M::up(MIGRATION_SQL[9].1),
];

/// All migrations in order (for `rusqlite_migration`'s validation in tests).
#[cfg(test)]
pub(super) const MIGRATIONS: Migrations<'static> = Migrations::from_slice(MIGRATION_LIST);

/// Schema version this build writes.
pub(super) fn latest_version() -> usize {
    MIGRATION_SQL.len()
}

fn user_version(conn: &Connection) -> Result<usize, rusqlite::Error> {
    let v: i64 = conn.query_row("PRAGMA user_version", [], |r| r.get(0))?;
    Ok(usize::try_from(v).unwrap_or(0))
}

fn check_not_newer(found: usize, path: &Path) -> Result<(), StoreError> {
    if found > latest_version() {
        return Err(StoreError::SchemaTooNew {
            path: path.to_path_buf(),
            found,
            supported: latest_version(),
        });
    }
    Ok(())
}

/// Brings a writable connection to the latest schema, safely when several processes open the
/// same fresh file at once: the write lock is taken first (`BEGIN IMMEDIATE`, which waits up to
/// the connection's busy timeout), the version is read again inside it, and only the missing
/// migrations run, all in that one transaction.
pub(super) fn migrate(conn: &mut Connection, path: &Path) -> Result<(), StoreError> {
    let found = user_version(conn)?;
    check_not_newer(found, path)?;
    if found == latest_version() {
        return Ok(());
    }
    let mig_err = |query: String, err: rusqlite::Error| StoreError::Migration {
        path: path.to_path_buf(),
        source: rusqlite_migration::Error::RusqliteError { query, err },
    };
    let tx = conn
        .transaction_with_behavior(TransactionBehavior::Immediate)
        .map_err(|e| mig_err("BEGIN IMMEDIATE".to_string(), e))?;
    // Another process may have migrated while this one waited for the lock.
    let found = user_version(&tx)?;
    check_not_newer(found, path)?;
    for (i, (name, sql)) in MIGRATION_SQL.iter().enumerate().skip(found) {
        tx.execute_batch(sql)
            .map_err(|e| mig_err(format!("migration {name}"), e))?;
        tx.pragma_update(None, "user_version", (i + 1) as i64)
            .map_err(|e| mig_err(format!("PRAGMA user_version after {name}"), e))?;
    }
    tx.commit()
        .map_err(|e| mig_err("COMMIT of the migrations".to_string(), e))
}

/// A read-only connection cannot migrate: check the schema is there and not newer.
pub(super) fn check_readonly(conn: &Connection, path: &Path) -> Result<(), StoreError> {
    let found = user_version(conn)?;
    if found == 0 {
        return Err(StoreError::NotInitialised {
            path: path.to_path_buf(),
        });
    }
    check_not_newer(found, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn migrations_are_valid() {
        MIGRATIONS.validate().expect("migrations validate");
    }

    /// Issue 12 #7: two processes migrating the same fresh file at once; one used to fail with
    /// "database is locked" or "table tags already exists". Several threads, each with its own
    /// connection, open a fresh file at the same moment: all must succeed.
    #[test]
    fn concurrent_open_of_a_fresh_file_migrates_once() {
        let dir = tempfile::tempdir().expect("tempdir");
        for round in 0..3 {
            let path = dir.path().join(format!("race{round}.db"));
            let barrier = std::sync::Arc::new(std::sync::Barrier::new(4));
            let handles: Vec<_> = (0..4)
                .map(|_| {
                    let path = path.clone();
                    let barrier = barrier.clone();
                    std::thread::spawn(move || {
                        barrier.wait();
                        crate::store::Store::open(&path).map(|_| ())
                    })
                })
                .collect();
            for h in handles {
                let r = h.join().expect("thread");
                assert!(r.is_ok(), "round {round}: {:?}", r.err());
            }
            let conn = Connection::open(&path).expect("open");
            assert_eq!(user_version(&conn).expect("version"), latest_version());
        }
    }

    #[test]
    fn newer_schema_is_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("new.db");
        let conn = Connection::open(&path).expect("open");
        conn.pragma_update(None, "user_version", 99_i64)
            .expect("pragma");
        drop(conn);
        let err = crate::store::Store::open(&path).expect_err("too new");
        assert!(
            matches!(err, StoreError::SchemaTooNew { found: 99, .. }),
            "{err}"
        );
    }
}
