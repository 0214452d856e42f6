//! Schema migrations: the SQL files in `migrations/`, embedded and applied in order.
//!
//! A new schema version is a new `migrations/NNNN_name.sql` appended to [`MIGRATIONS`]; never
//! edit a released file. Must not hold queries: only schema versioning.

use super::StoreError;
use rusqlite::Connection;
use rusqlite_migration::{Migrations, M};
use std::path::Path;

const MIGRATION_LIST: &[M<'static>] = &[
    M::up(include_str!("../../migrations/0001_initial.sql")),
    M::up(include_str!("../../migrations/0002_diagnosis_results.sql")),
];

/// All migrations in order.
pub const MIGRATIONS: Migrations<'static> = Migrations::from_slice(MIGRATION_LIST);

/// Schema version this build writes.
pub fn latest_version() -> usize {
    MIGRATION_LIST.len()
}

fn user_version(conn: &Connection) -> Result<usize, rusqlite::Error> {
    let v: i64 = conn.query_row("PRAGMA user_version", [], |r| r.get(0))?;
    Ok(usize::try_from(v).unwrap_or(0))
}

/// Brings a writable connection to the latest schema (in one transaction per migration).
pub(super) fn migrate(conn: &mut Connection, path: &Path) -> Result<(), StoreError> {
    let found = user_version(conn)?;
    if found > latest_version() {
        return Err(StoreError::SchemaTooNew {
            path: path.to_path_buf(),
            found,
            supported: latest_version(),
        });
    }
    MIGRATIONS
        .to_latest(conn)
        .map_err(|source| StoreError::Migration {
            path: path.to_path_buf(),
            source,
        })
}

/// A read-only connection cannot migrate: check the schema is there and not newer.
pub(super) fn check_readonly(conn: &Connection, path: &Path) -> Result<(), StoreError> {
    let found = user_version(conn)?;
    if found == 0 {
        return Err(StoreError::NotInitialised {
            path: path.to_path_buf(),
        });
    }
    if found > latest_version() {
        return Err(StoreError::SchemaTooNew {
            path: path.to_path_buf(),
            found,
            supported: latest_version(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn migrations_are_valid() {
        MIGRATIONS.validate().expect("migrations validate");
    }
}
