//! `gtwatch store stats`: rows, bytes and time span of each sample tier (hot `samples`,
//! `archive_chunks`, `rollups_1m`), the file's pages, and what retention would do next.
//!
//! Bytes per tier come from SQLite's `dbstat` virtual table (compiled into the bundled
//! SQLite), summed over each table and its indexes; where `dbstat` is missing they are
//! `None`. Reads only: safe beside a running daemon. Must not write or change any setting.

use super::retention::{RetentionOutlook, RetentionPolicy};
use super::{Store, StoreError};
use rusqlite::OptionalExtension;

/// One tier's size and span.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct TierStats {
    /// Table rows (hot: samples; archive: chunks; roll-ups: tag-minutes).
    pub rows: u64,
    /// Raw samples the tier holds (roll-ups: the raw samples they summarise, `n_all`).
    pub samples: u64,
    /// Bytes of the table's and its indexes' pages (`dbstat`), if available.
    pub bytes: Option<u64>,
    /// `bytes / samples`.
    pub bytes_per_sample: Option<f64>,
    pub oldest_ms: Option<i64>,
    pub newest_ms: Option<i64>,
}

/// The file's pages.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct FileStats {
    pub page_size: u64,
    pub page_count: u64,
    pub free_pages: u64,
    /// `page_size × page_count` (the main file; the `-wal` file is not counted).
    pub file_bytes: u64,
    /// `none`, `full` or `incremental` (only `incremental` shrinks after retention).
    pub auto_vacuum: &'static str,
}

/// Everything `gtwatch store stats` prints.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StoreStats {
    pub hot: TierStats,
    pub archive: TierStats,
    pub rollups: TierStats,
    pub file: FileStats,
    pub policy: RetentionPolicy,
    /// What the next retention run would do (all zero when `raw_days` is 0).
    pub next_retention: RetentionOutlook,
}

fn count(v: i64) -> u64 {
    u64::try_from(v).unwrap_or(0)
}

impl Store {
    /// Bytes of each named table with its indexes, from `dbstat` (None if not compiled in).
    fn table_bytes(&self, table: &str) -> Result<Option<u64>, StoreError> {
        let r = self
            .conn
            .query_row(
                "SELECT COALESCE(SUM(d.pgsize), 0) FROM dbstat AS d
                 JOIN sqlite_schema AS m ON m.name = d.name
                 WHERE d.aggregate = 1 AND m.tbl_name = ?1",
                [table],
                |r| r.get::<_, i64>(0),
            )
            .optional();
        match r {
            Ok(v) => Ok(v.map(count)),
            Err(rusqlite::Error::SqliteFailure(_, Some(msg))) if msg.contains("dbstat") => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    fn tier(&self, sql: &str, table: &str) -> Result<TierStats, StoreError> {
        let (rows, samples, oldest_ms, newest_ms) = self.conn.query_row(sql, [], |r| {
            Ok((
                count(r.get(0)?),
                count(r.get(1)?),
                r.get::<_, Option<i64>>(2)?,
                r.get::<_, Option<i64>>(3)?,
            ))
        })?;
        let bytes = self.table_bytes(table)?;
        Ok(TierStats {
            rows,
            samples,
            bytes,
            bytes_per_sample: bytes
                .filter(|_| samples > 0)
                .map(|b| b as f64 / samples as f64),
            oldest_ms,
            newest_ms,
        })
    }

    /// Sizes of the tiers and the file, and what retention under `policy` would do at
    /// `now_ms`.
    pub fn storage_stats(
        &self,
        now_ms: i64,
        policy: &RetentionPolicy,
    ) -> Result<StoreStats, StoreError> {
        let hot = self.tier(
            "SELECT COUNT(*), COUNT(*), MIN(t_ms), MAX(t_ms) FROM samples",
            "samples",
        )?;
        let archive = self.tier(
            "SELECT COUNT(*), COALESCE(SUM(n), 0), MIN(t_start_ms), MAX(t_end_ms)
             FROM archive_chunks",
            "archive_chunks",
        )?;
        let rollups = self.tier(
            "SELECT COUNT(*), COALESCE(SUM(n_all), 0), MIN(t_ms), MAX(t_ms) FROM rollups_1m",
            "rollups_1m",
        )?;
        let pragma = |name: &str| -> Result<i64, StoreError> {
            Ok(self
                .conn
                .query_row(&format!("PRAGMA {name}"), [], |r| r.get(0))?)
        };
        let page_size = count(pragma("page_size")?);
        let page_count = count(pragma("page_count")?);
        let file = FileStats {
            page_size,
            page_count,
            free_pages: count(pragma("freelist_count")?),
            file_bytes: page_size * page_count,
            auto_vacuum: match pragma("auto_vacuum")? {
                1 => "full",
                2 => "incremental",
                _ => "none",
            },
        };
        Ok(StoreStats {
            hot,
            archive,
            rollups,
            file,
            policy: *policy,
            next_retention: self.retention_outlook(now_ms, policy)?,
        })
    }
}
