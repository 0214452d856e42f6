//! The SQLite store: tags, samples, gaps, segments and the diagnosis tables.
//!
//! One [`Store`] wraps one `rusqlite::Connection`. The daemon owns exactly one writable store
//! (the single writer, [`spawn_writer`]): its other tasks read through read-only connections
//! ([`Store::open_readonly_with`]) and hand their writes to the writer as typed requests
//! ([`WriteCmd`], through a [`WriterHandle`]; [`Db`] is the one interface the detector, the
//! worker and the wash advice write through, whether to a store of their own or to the
//! daemon's writer). Query commands open the file read-only so they never block or disturb
//! the writer; the few commands that write beside a running daemon (`wash`, a stored gap
//! analysis) do so in short transactions. Every connection counts the times it waited for a
//! lock ([`lock_waits`]). Schema lives in `migrations/` and is applied on open.
//! This module must not know about Modbus, CSV or the detector's rules: it stores and fetches.
//!
//! Durability choice: `journal_mode=WAL` with `synchronous=NORMAL`. In WAL mode a committed
//! transaction is in the WAL file before `COMMIT` returns, so killing the process (kill -9,
//! panic, OOM) never loses or corrupts committed data; only a power loss or OS crash can roll
//! back the last few transactions (never corrupt). Set `storage.synchronous = "full"` if the
//! host may lose power without a UPS.

/// SQL reading the candidate an `ambiguous` verdict doubted (`verdict.doubted`) from the stored
/// gap report of the `gap_analyses` row aliased `$t`: the one spelling of that JSON path for
/// every query (a literal, so it composes with `concat!`).
macro_rules! doubted_sql {
    ($t:literal) => {
        concat!("json_extract(", $t, ".report_json, '$.verdict.doubted')")
    };
}

/// The columns of `instrument_corrections` after `segment_id`, in `InstrumentCorrection`'s
/// order (`corrections::from_row` reads them so), each prefixed by `$p` (`"c."` for a table
/// alias, `""` for none): the one list for every query (a literal, so it composes with
/// `concat!`).
macro_rules! correction_columns {
    ($p:literal) => {
        concat!(
            $p,
            "onset_segment_id, ",
            $p,
            "effect, ",
            $p,
            "unit, ",
            $p,
            "magnitude, ",
            $p,
            "magnitude_sigma, ",
            $p,
            "d_gc, ",
            $p,
            "d_ec, ",
            $p,
            "d_gt, ",
            $p,
            "d_et, ",
            $p,
            "d_gp, ",
            $p,
            "d_ep, ",
            $p,
            "sigma_gc, ",
            $p,
            "sigma_ec, ",
            $p,
            "sigma_gt, ",
            $p,
            "sigma_et, ",
            $p,
            "sigma_gp, ",
            $p,
            "sigma_ep, ",
            $p,
            "also"
        )
    };
}

pub mod archive;
mod channel;
mod corrections;
pub use corrections::{CorrectionsWrite, InstrumentCorrection};
mod db;
mod detection;
mod diagnoses;
mod fleet;
pub use fleet::{
    ColKind, FleetColumn, FleetCursor, FleetMark, FleetRows, FleetSamples, FleetTable, FleetWindow,
    FLEET_CORRECTIONS, FLEET_DIAGNOSES, FLEET_GAP_ANALYSES, FLEET_PHASE_COLUMNS,
    FLEET_RECOMMENDATIONS, FLEET_SEGMENTS, FLEET_TAG_COLUMNS, FLEET_WASHES,
};
mod gap;
mod locks;
pub use gap::{GapAnalysisRow, GapSelection, NewGapAnalysis};
mod segments;
mod washes;
pub use segments::{PhaseRow, SampleRow, StartupRow};
pub use washes::{
    AdviceWrite, NewRecommendation, NewWash, RecommendationRow, WashRow, DETECTED_PREFIX,
};
mod retention;
mod schema;
mod stats;
mod storage_config;
mod writer;

pub use retention::{
    combine as combine_rollups, floor_to, rollups as minute_rollups, RetainStats, RetentionOutlook,
    RetentionPolicy, Rollup, RollupTier, HOUR_MS, MINUTE_MS, VACUUM_STEP_PAGES,
};
pub use stats::{FileStats, StoreStats, TierBytes, TierStats};
pub use storage_config::{StorageConfig, StoreOptions, Synchronous};

pub use archive::{ArchiveStats, CompactStats, CHUNK_SPAN_MS, DEFAULT_MAX_CHUNK_SAMPLES};
pub use db::{Db, ViaWriter};
pub use detection::{ResumeState, ScanWrite};
pub use diagnoses::{
    build_segment_recording, DiagnosisTiming, HistoryFilter, HistoryRow, NewDiagnosis, NewOutcome,
    SegmentInfo, SegmentRecording, SignalQuality, Undiagnosable, CONTEXT_BEFORE_MS,
};
pub use locks::{lock_waits, LockWaits};

pub use writer::{
    run_writer, run_writer_with_progress, spawn_writer, writer_channel, WriteCmd, WriterConfig,
    WriterHandle, WriterProgress, WriterStats,
};

use crate::quality::Quality;
use crate::signals::Signal;
use rusqlite::{params, Connection, OpenFlags, OptionalExtension};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Row id of a tag in the `tags` table.
pub type TagId = i64;

/// One measured value of one tag at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub tag: TagId,
    /// Unix epoch milliseconds, UTC.
    pub t_ms: i64,
    pub value: f64,
    pub quality: Quality,
}

/// A period without data (Modbus outage, hole in a replayed log).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Gap {
    pub start_ms: i64,
    pub end_ms: i64,
    /// Who noticed it, e.g. `modbus` or `replay:plant.csv`.
    pub source: String,
    pub reason: String,
}

/// A tag as declared by the register map or the replay column mapping.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TagInfo {
    pub name: String,
    pub unit: String,
    /// The engine quantity this tag measures, if it is one of [`Signal`].
    pub signal: Option<Signal>,
}

impl TagInfo {
    /// The canonical tag for a signal: name = column name (`n1_rpm`), unit from the name.
    pub fn for_signal(signal: Signal) -> TagInfo {
        TagInfo {
            name: signal.column().to_string(),
            unit: signal_unit(signal).to_string(),
            signal: Some(signal),
        }
    }
}

/// Engineering unit of a signal (the suffix of its column name).
pub fn signal_unit(signal: Signal) -> &'static str {
    match signal {
        Signal::N1 | Signal::N2 => "rpm",
        Signal::T1 | Signal::T2 | Signal::T3 | Signal::T34 | Signal::T4 => "K",
        Signal::P1 | Signal::P2 | Signal::P3 | Signal::P34 | Signal::P4 => "kPa",
        Signal::FuelFlow => "kg/s",
        Signal::Power => "MW",
        Signal::SurgeMargin => "%",
        Signal::Torque => "kN·m",
        Signal::InletDepression => "kPa",
    }
}

/// A tag row as read back from the database.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TagRow {
    pub id: TagId,
    pub name: String,
    pub unit: String,
    pub signal: Option<Signal>,
}

/// Errors from the store.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("cannot open database {path}")]
    Open {
        path: PathBuf,
        #[source]
        source: rusqlite::Error,
    },
    #[error("database {path}: schema migration failed")]
    Migration {
        path: PathBuf,
        #[source]
        source: rusqlite_migration::Error,
    },
    #[error("database {path} has schema version {found}, newer than this gtwatch ({supported}); upgrade gtwatch")]
    SchemaTooNew {
        path: PathBuf,
        found: usize,
        supported: usize,
    },
    #[error(
        "database {path} is not initialised (no schema); run the daemon or `gtwatch replay` first"
    )]
    NotInitialised { path: PathBuf },
    #[error(
        "database {path} has an unfinished write (the {path}-journal file beside it) from a process that stopped while creating it; a read-only open cannot roll it back: open it once with write access (`gtwatch store vacuum --db {path}`, the daemon or `gtwatch replay` do) and try again"
    )]
    UnfinishedWrite { path: PathBuf },
    #[error("unknown tag '{0}'")]
    UnknownTag(String),
    #[error("invalid value in database: {0}")]
    Corrupt(String),
    #[error("writer task failed: {0}")]
    Writer(String),
    #[error(transparent)]
    Sql(#[from] rusqlite::Error),
}

/// What [`Store::open_readonly`] uses: SQLite's default page cache (`cache_mib` 0) and a
/// busy timeout of 5 s.
const READONLY_OPTIONS: StoreOptions = StoreOptions {
    cache_mib: 0,
    synchronous: Synchronous::Normal,
    busy_timeout_ms: 5000,
    max_db_mib: 0,
};

/// The database. Not `Sync`: one owner at a time (the writer task, or a command).
#[derive(Debug)]
pub struct Store {
    conn: Connection,
    path: PathBuf,
    read_only: bool,
}

/// The file SQLite keeps beside a database, its name with `suffix` (`-wal`, `-journal`).
fn beside(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.as_os_str().to_os_string();
    name.push(suffix);
    PathBuf::from(name)
}

/// The `-wal` file of a database.
fn wal_file(path: &Path) -> PathBuf {
    beside(path, "-wal")
}

/// Whether `path` has a non-empty rollback journal beside it (`<path>-journal`): the
/// transaction that wrote it did not finish, and the next writer rolls it back.
fn hot_journal(path: &Path) -> bool {
    std::fs::metadata(beside(path, "-journal")).is_ok_and(|m| m.len() > 0)
}

/// A `file:` URI opening `path` read-only and immutable (`%`, `?` and `#` escaped).
fn immutable_uri(path: &Path) -> String {
    let mut uri = String::from("file:");
    for ch in path.to_string_lossy().chars() {
        match ch {
            '%' => uri.push_str("%25"),
            '?' => uri.push_str("%3f"),
            '#' => uri.push_str("%23"),
            c => uri.push(c),
        }
    }
    uri.push_str("?mode=ro&immutable=1");
    uri
}

/// Current wall-clock time in Unix epoch ms.
pub fn now_ms() -> i64 {
    let now = time::OffsetDateTime::now_utc();
    (now.unix_timestamp_nanos() / 1_000_000) as i64
}

/// Read-only access to a store: opened `SQLITE_OPEN_READ_ONLY` by [`Store::open_readonly`],
/// it never migrates or writes, and as a type it offers only the store's `&self` methods (the
/// queries): every write takes `&mut Store`, which a `ReadStore` cannot lend. Readers (`history`,
/// `segments`, `export`, `report`, the demo's monitor) use it beside a running daemon.
#[derive(Debug)]
pub struct ReadStore(Store);

impl std::ops::Deref for ReadStore {
    type Target = Store;
    fn deref(&self) -> &Store {
        &self.0
    }
}

impl Store {
    /// Opens (creating if needed) a writable store with default options.
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        Store::open_with(path, &StoreOptions::default())
    }

    /// Opens (creating if needed) a writable store: WAL, pragmas, migrations.
    pub fn open_with(path: &Path, opts: &StoreOptions) -> Result<Store, StoreError> {
        let open_err = |source| StoreError::Open {
            path: path.to_path_buf(),
            source,
        };
        if let Some(dir) = path.parent() {
            if !dir.as_os_str().is_empty() && !dir.exists() {
                std::fs::create_dir_all(dir).map_err(|e| StoreError::Open {
                    path: path.to_path_buf(),
                    source: rusqlite::Error::ToSqlConversionFailure(Box::new(e)),
                })?;
            }
        }
        let mut conn = Connection::open(path).map_err(open_err)?;
        locks::install(&conn, opts.busy_timeout_ms).map_err(open_err)?;
        // A new file frees the pages that compaction and retention empty (`PRAGMA
        // incremental_vacuum`). Only possible before the first table exists; an existing file
        // keeps its mode until `gtwatch store vacuum` (README "Storage tiers").
        let tables: i64 = conn
            .query_row("SELECT COUNT(*) FROM sqlite_master", [], |r| r.get(0))
            .map_err(open_err)?;
        if tables == 0 {
            conn.execute_batch("PRAGMA auto_vacuum = INCREMENTAL;")
                .map_err(open_err)?;
        }
        // Switching a fresh file to WAL takes an exclusive lock and does not wait on the busy
        // handler: retry while another opener holds it (issue 12 #7, "database is locked").
        let wal_deadline =
            std::time::Instant::now() + Duration::from_millis(opts.busy_timeout_ms.max(1000));
        let mode: String = loop {
            match conn.query_row("PRAGMA journal_mode=WAL", [], |r| r.get(0)) {
                Err(rusqlite::Error::SqliteFailure(e, _))
                    if e.code == rusqlite::ErrorCode::DatabaseBusy
                        && std::time::Instant::now() < wal_deadline =>
                {
                    std::thread::sleep(Duration::from_millis(10));
                    locks::count_wait(Duration::from_millis(10));
                }
                r => break r.map_err(open_err)?,
            }
        };
        if !mode.eq_ignore_ascii_case("wal") {
            tracing::warn!(path = %path.display(), mode, "could not switch the database to WAL mode");
        }
        let sync = match opts.synchronous {
            Synchronous::Normal => "NORMAL",
            Synchronous::Full => "FULL",
        };
        conn.execute_batch(&format!(
            "PRAGMA synchronous={sync};
             PRAGMA foreign_keys=ON;
             PRAGMA temp_store=MEMORY;
             PRAGMA cache_size=-{};",
            u64::from(opts.cache_mib.max(1)) * 1024
        ))
        .map_err(open_err)?;
        schema::migrate(&mut conn, path)?;
        if opts.max_db_mib > 0 {
            let page_size: i64 = conn
                .query_row("PRAGMA page_size", [], |r| r.get(0))
                .map_err(open_err)?;
            let pages = i64::from(opts.max_db_mib) * 1024 * 1024 / page_size.max(512);
            // SQLite answers with the cap it applied (never below the current size).
            let _applied: i64 = conn
                .query_row(&format!("PRAGMA max_page_count = {pages}"), [], |r| {
                    r.get(0)
                })
                .map_err(open_err)?;
        }
        Ok(Store {
            conn,
            path: path.to_path_buf(),
            read_only: false,
        })
    }

    /// Opens an existing store read-only (for `segments`, `export`, … while the daemon runs).
    /// Fails if the file does not exist or has no schema; never writes.
    ///
    /// A WAL database needs its `-shm` file even to be read. When nobody has it open (no
    /// `-wal` file beside it) and the directory is not writable, SQLite cannot create that
    /// file and refuses; then the file is opened `immutable` instead: no connection is
    /// writing it, and none could start a WAL write in a directory we cannot write either
    /// without the `-wal` file appearing first. A file with a hot rollback journal beside it
    /// (a process killed while creating it) is refused ([`StoreError::UnfinishedWrite`]):
    /// `immutable` would read its half-written pages, and only a writer can roll it back.
    pub fn open_readonly(path: &Path) -> Result<ReadStore, StoreError> {
        Store::open_readonly_with(path, &READONLY_OPTIONS)
    }

    /// [`Store::open_readonly`] with the page cache and busy timeout of `opts` (the daemon's
    /// tasks read with the `[storage]` settings; the other options do not apply to a reader).
    pub fn open_readonly_with(path: &Path, opts: &StoreOptions) -> Result<ReadStore, StoreError> {
        let conn = match Store::readonly_connection(path, false, opts) {
            Ok(conn) => conn,
            // A hot rollback journal: a process stopped mid-write while the file was still in
            // rollback mode (only while it was being created; a store is WAL from then on).
            // `immutable` would read the half-written pages; only a writer can roll it back.
            Err(_) if hot_journal(path) => {
                return Err(StoreError::UnfinishedWrite {
                    path: path.to_path_buf(),
                })
            }
            Err(e) if path.is_file() && !wal_file(path).exists() => {
                tracing::debug!(path = %path.display(), "read-only open failed ({e}); retrying immutable");
                Store::readonly_connection(path, true, opts).map_err(|_| e)?
            }
            Err(e) => return Err(e),
        };
        Ok(ReadStore(Store {
            conn,
            path: path.to_path_buf(),
            read_only: true,
        }))
    }

    /// A read-only connection whose schema was checked; `immutable`: without locks or `-shm`.
    fn readonly_connection(
        path: &Path,
        immutable: bool,
        opts: &StoreOptions,
    ) -> Result<Connection, StoreError> {
        let open_err = |source| StoreError::Open {
            path: path.to_path_buf(),
            source,
        };
        let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
        let conn = if immutable {
            Connection::open_with_flags(immutable_uri(path), flags | OpenFlags::SQLITE_OPEN_URI)
        } else {
            Connection::open_with_flags(path, flags)
        }
        .map_err(open_err)?;
        locks::install(&conn, opts.busy_timeout_ms).map_err(open_err)?;
        if opts.cache_mib > 0 {
            conn.execute_batch(&format!(
                "PRAGMA cache_size=-{};",
                u64::from(opts.cache_mib) * 1024
            ))
            .map_err(open_err)?;
        }
        schema::check_readonly(&conn, path)?;
        Ok(conn)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn is_read_only(&self) -> bool {
        self.read_only
    }

    /// The underlying connection, for the crate's unit tests only: all SQL lives in `store/`.
    #[cfg(test)]
    pub(crate) fn conn(&self) -> &Connection {
        &self.conn
    }

    /// Mutable connection access (transactions), inside the crate only.
    pub(crate) fn conn_mut(&mut self) -> &mut Connection {
        &mut self.conn
    }

    /// Returns the id of the tag named `tag.name`, creating it if absent. An existing tag's
    /// unit and signal are updated to the declared ones.
    pub fn ensure_tag(&mut self, tag: &TagInfo) -> Result<TagId, StoreError> {
        let signal = tag.signal.map(|s| s.column());
        let existing: Option<TagId> = self
            .conn
            .query_row(
                "SELECT id FROM tags WHERE name = ?1",
                params![tag.name],
                |r| r.get(0),
            )
            .optional()?;
        if let Some(id) = existing {
            self.conn.execute(
                "UPDATE tags SET unit = ?2, signal = ?3 WHERE id = ?1 AND (unit IS NOT ?2 OR signal IS NOT ?3)",
                params![id, tag.unit, signal],
            )?;
            return Ok(id);
        }
        self.conn.execute(
            "INSERT INTO tags (name, unit, signal, created_at_ms) VALUES (?1, ?2, ?3, ?4)",
            params![tag.name, tag.unit, signal, now_ms()],
        )?;
        Ok(self.conn.last_insert_rowid())
    }

    /// All tags, by id.
    pub fn tags(&self) -> Result<Vec<TagRow>, StoreError> {
        let mut stmt = self
            .conn
            .prepare_cached("SELECT id, name, unit, signal FROM tags ORDER BY id")?;
        let rows = stmt.query_map([], |r| {
            Ok((
                r.get::<_, i64>(0)?,
                r.get::<_, String>(1)?,
                r.get::<_, String>(2)?,
                r.get::<_, Option<String>>(3)?,
            ))
        })?;
        let mut out = Vec::new();
        for row in rows {
            let (id, name, unit, signal) = row?;
            let signal = match signal {
                Some(s) => Some(
                    s.parse::<Signal>()
                        .map_err(|e| StoreError::Corrupt(format!("tag {name}: {e}")))?,
                ),
                None => None,
            };
            out.push(TagRow {
                id,
                name,
                unit,
                signal,
            });
        }
        Ok(out)
    }

    /// The tag with this name.
    pub fn tag_by_name(&self, name: &str) -> Result<TagRow, StoreError> {
        self.tags()?
            .into_iter()
            .find(|t| t.name == name)
            .ok_or_else(|| StoreError::UnknownTag(name.to_string()))
    }

    /// The first (lowest id) tag that measures `signal`.
    pub fn tag_for_signal(&self, signal: Signal) -> Result<Option<TagRow>, StoreError> {
        Ok(self.tags()?.into_iter().find(|t| t.signal == Some(signal)))
    }

    /// Inserts a batch in one transaction. Idempotent on (tag, t_ms): a sample already stored
    /// is left as it is. Returns how many were new.
    pub fn insert_samples(&mut self, batch: &[Sample]) -> Result<usize, StoreError> {
        if batch.is_empty() {
            return Ok(0);
        }
        // Immediate: the insert first reads the archive's coverage, and a deferred transaction
        // that read before it wrote cannot wait for another writer (SQLITE_BUSY at once).
        let tx = self
            .conn
            .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        let inserted = insert_samples_in(&tx, batch)?;
        tx.commit()?;
        Ok(inserted)
    }

    /// Inserts samples and records gaps in one transaction; returns how many samples were new.
    pub fn insert_samples_and_gaps(
        &mut self,
        batch: &[Sample],
        gaps: &[Gap],
    ) -> Result<usize, StoreError> {
        // Immediate: the insert first reads the archive's coverage, and a deferred transaction
        // that read before it wrote cannot wait for another writer (SQLITE_BUSY at once).
        let tx = self
            .conn
            .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        let inserted = insert_samples_in(&tx, batch)?;
        for g in gaps {
            record_gap_in(&tx, g)?;
        }
        tx.commit()?;
        Ok(inserted)
    }

    /// Records a gap (idempotent on source, start, end).
    pub fn record_gap(&mut self, gap: &Gap) -> Result<(), StoreError> {
        record_gap_in(&self.conn, gap)
    }

    /// All gaps overlapping `[from_ms, to_ms]`.
    pub fn gaps_between(&self, from_ms: i64, to_ms: i64) -> Result<Vec<Gap>, StoreError> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT start_ms, end_ms, source, reason FROM gaps
             WHERE end_ms >= ?1 AND start_ms <= ?2 ORDER BY start_ms",
        )?;
        let rows = stmt.query_map(params![from_ms, to_ms], |r| {
            Ok(Gap {
                start_ms: r.get(0)?,
                end_ms: r.get(1)?,
                source: r.get(2)?,
                reason: r.get(3)?,
            })
        })?;
        Ok(rows.collect::<Result<Vec<_>, _>>()?)
    }

    /// Number of stored samples (all tags, both tiers).
    pub fn sample_count(&self) -> Result<i64, StoreError> {
        archive::count_all(&self.conn)
    }

    /// `PRAGMA integrity_check`; `Ok("ok")` when the file is sound.
    pub fn integrity_check(&self) -> Result<String, StoreError> {
        Ok(self
            .conn
            .query_row("PRAGMA integrity_check", [], |r| r.get(0))?)
    }
}

/// Inserts within an open transaction; returns how many rows were new. A sample whose (tag,
/// time) is already stored, hot or archived, is left as it is (README "Storage tiers").
pub(crate) fn insert_samples_in(conn: &Connection, batch: &[Sample]) -> Result<usize, StoreError> {
    // Sorted by (tag, time) the inserts append to each tag's run of the primary-key B-tree
    // instead of hopping between tags row by row: several times faster for large batches.
    let mut order: Vec<u32> = (0..batch.len() as u32).collect();
    if batch.len() > 64 {
        order.sort_unstable_by_key(|&i| {
            let s = &batch[i as usize];
            (s.tag, s.t_ms)
        });
    }
    let mut inserted = 0usize;
    let mut min_t = i64::MAX;
    let mut archived = archive::ArchivedTimes::default();
    let mut rolled = retention::RolledUpMinutes::default();
    {
        let mut stmt = conn.prepare_cached(
            "INSERT OR IGNORE INTO samples (tag_id, t_ms, value, quality) VALUES (?1, ?2, ?3, ?4)",
        )?;
        for &i in &order {
            let s = &batch[i as usize];
            if archived.contains(conn, s.tag, s.t_ms)? || rolled.contains(conn, s.tag, s.t_ms)? {
                continue;
            }
            stmt.raw_bind_parameter(1, s.tag)?;
            stmt.raw_bind_parameter(2, s.t_ms)?;
            stmt.raw_bind_parameter(3, s.value)?;
            stmt.raw_bind_parameter(4, s.quality.code())?;
            inserted += stmt.raw_execute()?;
            min_t = min_t.min(s.t_ms);
        }
    }
    // Samples older than what the detector has scanned (a late replay) make it rescan.
    if inserted > 0 {
        conn.prepare_cached(
            "UPDATE detector_state SET rescan_from_ms = MIN(COALESCE(rescan_from_ms, ?1), ?1)
             WHERE id = 1 AND scanned_to_ms IS NOT NULL AND ?1 <= scanned_to_ms",
        )?
        .execute(params![min_t])?;
    }
    Ok(inserted)
}

pub(crate) fn record_gap_in(conn: &Connection, gap: &Gap) -> Result<(), StoreError> {
    let (start, end) = if gap.end_ms >= gap.start_ms {
        (gap.start_ms, gap.end_ms)
    } else {
        (gap.end_ms, gap.start_ms)
    };
    conn.prepare_cached(
        "INSERT OR IGNORE INTO gaps (start_ms, end_ms, source, reason) VALUES (?1, ?2, ?3, ?4)",
    )?
    .execute(params![start, end, gap.source, gap.reason])?;
    Ok(())
}

#[cfg(test)]
mod tests;
