//! `gtwatch store stats`: rows, bytes and time span of each sample tier (hot `samples`,
//! `archive_chunks`, `rollups_1m`, `rollups_1h`), the file's pages, and what retention would do next.
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
    /// Table rows (hot: samples; archive: chunks; roll-ups: tag-minutes or tag-hours).
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
    /// Hourly roll-ups (`rollups_1h`, retention's second tier).
    pub rollups_1h: TierStats,
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
        let rollups_1h = self.tier(
            "SELECT COUNT(*), COALESCE(SUM(n_all), 0), MIN(t_ms), MAX(t_ms) FROM rollups_1h",
            "rollups_1h",
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
            rollups_1h,
            file,
            policy: *policy,
            next_retention: self.retention_outlook(now_ms, policy)?,
        })
    }
}

/// Bytes of each sample tier, for `bench soak`'s per-day file decomposition (cheaper than
/// [`Store::storage_stats`]: no counts, no retention outlook).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct TierBytes {
    /// Pages of each table with its indexes (`dbstat`; 0 where `dbstat` is missing).
    pub hot: u64,
    pub archive: u64,
    pub rollups_1m: u64,
    pub rollups_1h: u64,
    /// Blob bytes (times, values, quality codes) of the archive chunks wholly before the
    /// given time: past the retention cutoff these are the start-up windows kept raw.
    pub archive_blobs_before: u64,
    /// Free pages' bytes.
    pub free: u64,
}

impl Store {
    /// The tiers' bytes; `before_ms` splits off the archive chunks wholly older.
    pub fn tier_bytes(&self, before_ms: i64) -> Result<TierBytes, StoreError> {
        let b = |t: &str| -> Result<u64, StoreError> { Ok(self.table_bytes(t)?.unwrap_or(0)) };
        let blobs: i64 = self.conn.query_row(
            "SELECT COALESCE(SUM(length(t_blob) + length(v_blob) + length(q_blob)), 0)
             FROM archive_chunks WHERE t_end_ms < ?1",
            [before_ms],
            |r| r.get(0),
        )?;
        let free: i64 = self
            .conn
            .query_row("PRAGMA freelist_count", [], |r| r.get(0))?;
        let page: i64 = self.conn.query_row("PRAGMA page_size", [], |r| r.get(0))?;
        Ok(TierBytes {
            hot: b("samples")?,
            archive: b("archive_chunks")?,
            rollups_1m: b("rollups_1m")?,
            rollups_1h: b("rollups_1h")?,
            archive_blobs_before: count(blobs),
            free: count(free) * count(page),
        })
    }
}
