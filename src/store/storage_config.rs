//! The `[storage]` section of the daemon's configuration and the connection tuning it becomes
//! ([`StoreOptions`]): database and archive paths, retention, cache, sync level, size caps,
//! each validated with the key named. Must not open a database.

use super::{RetentionPolicy, WriterConfig};
use crate::config_problem::{check_range, Bounds, ConfigProblem};
use serde::Deserialize;
use std::path::PathBuf;
use std::time::Duration;

/// How strictly SQLite syncs to disk (see the module comment).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Synchronous {
    /// Safe against process crashes; may lose the last transactions on power loss.
    #[default]
    Normal,
    /// Also safe against power loss; slower commits.
    Full,
}

/// `[storage]` section.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StorageConfig {
    /// Database file. Default `/var/lib/gtwatch/gtwatch.db`.
    pub path: PathBuf,
    /// The writer commits when it holds this many samples. Default 5000.
    pub batch_size: usize,
    /// ... or when the oldest buffered sample is this old, in ms. Default 1000.
    pub flush_interval_ms: u64,
    /// SQLite page cache in MiB. Default 16 (keeps the daemon under 50 MB resident; bulk replays may want more).
    pub cache_mib: u32,
    /// `normal` (default) or `full`.
    pub synchronous: Synchronous,
    /// Read-only connections wait this long for a lock, in ms. Default 5000.
    pub busy_timeout_ms: u64,
    /// Cap on the database size in MiB (`PRAGMA max_page_count`); 0 (default) = no cap. When
    /// the database reaches it, writes fail like on a full disk (`SQLITE_FULL`): the writer
    /// keeps acquisition running, holds a bounded buffer and records the samples it had to
    /// drop as `writer_buffer_full` gaps until space is freed inside the file (or the cap is
    /// raised and the daemon restarted). A file already larger than the cap is capped at its
    /// current size.
    pub max_db_mib: u32,
    /// The daemon archives samples older than this many hours (README "Storage tiers"):
    /// compressed per-tag chunks in the same file, read back transparently. Default 24;
    /// 0 = off (everything stays in the hot tier).
    pub compact_after_hours: u32,
    /// Steady operation is kept at full resolution this many days, then replaced by 1-minute
    /// roll-ups (table `rollups_1m`, view `samples_1m`; README "Storage tiers"). Default 0 =
    /// keep every raw sample forever.
    pub raw_days: u32,
    /// Samples within this many seconds of a start-up segment stay raw forever, whatever
    /// `raw_days` says. Default 600.
    pub segment_margin_s: u32,
    /// 1-minute roll-ups older than this many days are merged into hourly roll-ups (table
    /// `rollups_1h`, view `samples_1h`; README "Retention and roll-ups"). Default 0 = keep the
    /// minute roll-ups forever; else more than `raw_days`.
    pub rollup_1m_days: u32,
}

impl Default for StorageConfig {
    fn default() -> Self {
        StorageConfig {
            path: PathBuf::from("/var/lib/gtwatch/gtwatch.db"),
            batch_size: 5000,
            flush_interval_ms: 1000,
            cache_mib: 16,
            synchronous: Synchronous::Normal,
            busy_timeout_ms: 5000,
            max_db_mib: 0,
            compact_after_hours: 24,
            raw_days: 0,
            segment_margin_s: 600,
            rollup_1m_days: 0,
        }
    }
}

impl StorageConfig {
    /// Problems with this section; keys are prefixed `storage.`.
    pub fn validate(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        if self.path.as_os_str().is_empty() {
            p.push(ConfigProblem::new("storage.path", "must not be empty"));
        }
        // Bounds: values past these crashed the daemon at start-up (a 1e10 batch is a 320 GB
        // allocation; a busy timeout past i32::MAX ms panics in SQLite's binding).
        check_range(
            &mut p,
            "storage.batch_size",
            self.batch_size as u64,
            Bounds {
                lo: 1,
                hi: 1_000_000,
                unit: "",
                why: "samples buffered before a commit; each takes memory",
            },
        );
        check_range(
            &mut p,
            "storage.flush_interval_ms",
            self.flush_interval_ms,
            Bounds {
                lo: 1,
                hi: 3_600_000,
                unit: " ms",
                why: "1 ms … 1 h",
            },
        );
        check_range(
            &mut p,
            "storage.busy_timeout_ms",
            self.busy_timeout_ms,
            Bounds {
                lo: 0,
                hi: 600_000,
                unit: " ms",
                why: "at most 10 minutes of waiting for a lock",
            },
        );
        check_range(
            &mut p,
            "storage.max_db_mib",
            u64::from(self.max_db_mib),
            Bounds {
                lo: 0,
                hi: 8 * 1024 * 1024,
                unit: " MiB",
                why: "0 (no cap) … 8 TiB",
            },
        );
        check_range(
            &mut p,
            "storage.compact_after_hours",
            u64::from(self.compact_after_hours),
            Bounds {
                lo: 0,
                hi: 24 * 3650,
                unit: " h",
                why: "0 (off) … 10 years",
            },
        );
        check_range(
            &mut p,
            "storage.raw_days",
            u64::from(self.raw_days),
            Bounds {
                lo: 0,
                hi: 36_500,
                unit: " days",
                why: "0 (keep raw forever) … 100 years",
            },
        );
        check_range(
            &mut p,
            "storage.segment_margin_s",
            u64::from(self.segment_margin_s),
            Bounds {
                lo: 0,
                hi: 7 * 86_400,
                unit: " s",
                why: "0 … 7 days around each start-up",
            },
        );
        if self.raw_days > 0
            && self.compact_after_hours > 0
            && u64::from(self.raw_days) * 24 < u64::from(self.compact_after_hours)
        {
            p.push(ConfigProblem::new(
                "storage.raw_days",
                format!(
                    "{} days is shorter than storage.compact_after_hours ({} h): samples would be rolled up before they are archived; raise raw_days or lower compact_after_hours",
                    self.raw_days, self.compact_after_hours
                ),
            ));
        }
        self.validate_rollup_1m_days(&mut p);
        if self.cache_mib == 0 || self.cache_mib > 16 * 1024 {
            p.push(ConfigProblem::new(
                "storage.cache_mib",
                "must be between 1 and 16384",
            ));
        }
        p
    }

    /// The writer settings of this section.
    pub fn writer(&self) -> WriterConfig {
        WriterConfig {
            batch_size: self.batch_size.max(1),
            flush_interval: Duration::from_millis(self.flush_interval_ms.max(1)),
            max_buffered: 0,
            retry_initial: Duration::from_millis(250),
            close_retry: Duration::from_secs(5),
        }
    }

    /// The retention policy of this section (`raw_days` 0: off).
    pub fn retention(&self) -> RetentionPolicy {
        RetentionPolicy {
            raw_days: self.raw_days,
            segment_margin_s: self.segment_margin_s,
            rollup_1m_days: self.rollup_1m_days,
        }
    }

    /// Store options of this section.
    pub fn options(&self) -> StoreOptions {
        StoreOptions {
            cache_mib: self.cache_mib,
            synchronous: self.synchronous,
            busy_timeout_ms: self.busy_timeout_ms,
            max_db_mib: self.max_db_mib,
        }
    }
}

/// Connection tuning applied by [`Store::open_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StoreOptions {
    pub cache_mib: u32,
    pub synchronous: Synchronous,
    pub busy_timeout_ms: u64,
    /// Database size cap in MiB (`PRAGMA max_page_count`), 0 = none.
    pub max_db_mib: u32,
}

impl Default for StoreOptions {
    fn default() -> Self {
        StorageConfig::default().options()
    }
}
