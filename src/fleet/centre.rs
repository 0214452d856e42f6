//! The central PostgreSQL database: its schema and migrations (`migrations/postgres/`), the
//! connection an edge syncs through, and the fleet status. All central SQL lives here and in
//! `sync`; nothing here touches the edge.

use super::{describe_url, FleetError};
use postgres::{Client, NoTls};
use serde::Serialize;
use std::time::Duration;

/// Central migrations in order; version n is the n-th. Never edit a released one.
const MIGRATIONS: &[(&str, &str)] = &[
    (
        "0001_fleet.sql",
        include_str!("../../migrations/postgres/0001_fleet.sql"),
    ),
    (
        "0002_rediagnosis.sql",
        include_str!("../../migrations/postgres/0002_rediagnosis.sql"),
    ),
    (
        "0003_regap.sql",
        include_str!("../../migrations/postgres/0003_regap.sql"),
    ),
    (
        "0004_instrument_corrections.sql",
        include_str!("../../migrations/postgres/0004_instrument_corrections.sql"),
    ),
];

/// The schema version that added the gap-analysis jobs (`0003_regap.sql`).
const GAP_JOBS_SCHEMA_VERSION: i32 = 3;

/// The schema version that added the instrument corrections (`0004_instrument_corrections.sql`).
const CORRECTIONS_SCHEMA_VERSION: i32 = 4;

/// Advisory lock key serialising two edges migrating a fresh centre at once.
const MIGRATION_LOCK: i64 = 0x0067_7477_6174_6368; // "gtwatch" in ASCII

/// The central schema version this build knows.
pub fn supported_version() -> i32 {
    MIGRATIONS.len() as i32
}

/// The rows of each central table, per unit (what `fleet status` lists).
pub const CENTRAL_TABLES: &[&str] = &[
    "segments",
    "segment_phases",
    "diagnoses",
    "gap_analyses",
    "washes",
    "recommendations",
    "samples",
    "instrument_corrections",
];

/// An open connection to the centre whose schema was checked.
pub struct Centre {
    pub(super) client: Client,
    /// The centre's identity (its `centre` row): edges key their marks by it.
    pub id: String,
    /// `host:port/db (user …)` for messages.
    pub name: String,
}

impl std::fmt::Debug for Centre {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Centre")
            .field("id", &self.id)
            .field("name", &self.name)
            .finish_non_exhaustive()
    }
}

pub(super) fn centre_err(centre: &str, what: &str) -> impl FnOnce(postgres::Error) -> FleetError {
    let centre = centre.to_string();
    let what = what.to_string();
    move |source| FleetError::Centre {
        centre,
        what,
        source,
    }
}

/// Connects with a connect and statement timeout of `timeout`.
fn open(url: &str, timeout: Duration) -> Result<(Client, String), FleetError> {
    let name = describe_url(url);
    let mut cfg: postgres::Config = url
        .parse()
        .map_err(|e: postgres::Error| FleetError::Url(e.to_string()))?;
    cfg.connect_timeout(timeout);
    cfg.options(&format!(
        "-c statement_timeout={} -c lock_timeout={}",
        timeout.as_millis(),
        timeout.as_millis()
    ));
    if cfg.get_application_name().is_none() {
        cfg.application_name("gtwatch");
    }
    let client = cfg.connect(NoTls).map_err(|source| FleetError::Connect {
        centre: name.clone(),
        source,
    })?;
    Ok((client, name))
}

/// The centre's schema version (0: no gtwatch schema).
fn version(client: &mut impl postgres::GenericClient, name: &str) -> Result<i32, FleetError> {
    let exists: bool = client
        .query_one("SELECT to_regclass('schema_version') IS NOT NULL", &[])
        .map_err(centre_err(name, "reading the schema version"))?
        .get(0);
    if !exists {
        return Ok(0);
    }
    let v: Option<i32> = client
        .query_one("SELECT MAX(version) FROM schema_version", &[])
        .map_err(centre_err(name, "reading the schema version"))?
        .get(0);
    Ok(v.unwrap_or(0))
}

fn refuse_newer(found: i32, name: &str) -> Result<(), FleetError> {
    if found > supported_version() {
        return Err(FleetError::SchemaTooNew {
            centre: name.to_string(),
            found,
            supported: supported_version(),
        });
    }
    Ok(())
}

impl Centre {
    /// Connects as an edge: creates or upgrades the central schema (under an advisory lock, in
    /// one transaction) and refuses a centre newer than this build.
    pub fn connect(url: &str, timeout: Duration) -> Result<Centre, FleetError> {
        let (mut client, name) = open(url, timeout)?;
        let mut tx = client
            .transaction()
            .map_err(centre_err(&name, "BEGIN of the migration"))?;
        tx.execute("SELECT pg_advisory_xact_lock($1)", &[&MIGRATION_LOCK])
            .map_err(centre_err(&name, "taking the migration lock"))?;
        let found = version(&mut tx, &name)?;
        refuse_newer(found, &name)?;
        for (i, (file, sql)) in MIGRATIONS.iter().enumerate().skip(found as usize) {
            tx.batch_execute(sql)
                .map_err(centre_err(&name, &format!("migration {file}")))?;
            tx.execute(
                "INSERT INTO schema_version (version) VALUES ($1)",
                &[&(i as i32 + 1)],
            )
            .map_err(centre_err(&name, &format!("recording migration {file}")))?;
        }
        tx.commit()
            .map_err(centre_err(&name, "COMMIT of the migration"))?;
        Centre::identify(client, name)
    }

    /// Connects to read (the fleet status): the schema must exist and not be newer.
    pub fn connect_existing(url: &str, timeout: Duration) -> Result<Centre, FleetError> {
        let (mut client, name) = open(url, timeout)?;
        match version(&mut client, &name)? {
            0 => Err(FleetError::NoSchema { centre: name }),
            v => {
                refuse_newer(v, &name)?;
                Centre::identify(client, name)
            }
        }
    }

    fn identify(mut client: Client, name: String) -> Result<Centre, FleetError> {
        let id: String = client
            .query_one("SELECT id FROM centre LIMIT 1", &[])
            .map_err(centre_err(&name, "reading the centre's id"))?
            .get(0);
        Ok(Centre { client, id, name })
    }

    /// The centre's schema version (the number of central migrations applied).
    pub fn schema_version(&mut self) -> Result<i32, FleetError> {
        version(&mut self.client, &self.name)
    }

    /// Whether the centre's schema has the gap-analysis jobs (`0003_regap.sql`, version 3):
    /// a read-only connection does not upgrade an older one.
    pub fn has_gap_jobs(&mut self) -> Result<bool, FleetError> {
        Ok(self.schema_version()? >= GAP_JOBS_SCHEMA_VERSION)
    }

    /// Whether the centre's schema has the instrument corrections
    /// (`0004_instrument_corrections.sql`, version 4): a read-only connection does not upgrade
    /// an older one.
    pub fn has_corrections(&mut self) -> Result<bool, FleetError> {
        Ok(self.schema_version()? >= CORRECTIONS_SCHEMA_VERSION)
    }

    /// Checks again that the schema is not newer (the centre may be upgraded while an edge
    /// keeps its connection).
    pub fn check_version(&mut self) -> Result<(), FleetError> {
        let found = version(&mut self.client, &self.name)?;
        refuse_newer(found, &self.name)
    }

    /// Rows of `table` held for `unit_id` (tests, and `gtwatch sync` totals).
    pub fn count(&mut self, table: &str, unit_id: &str) -> Result<i64, FleetError> {
        if !CENTRAL_TABLES.contains(&table)
            || (table == "instrument_corrections" && !self.has_corrections()?)
        {
            return Ok(0);
        }
        Ok(self
            .client
            .query_one(
                &format!("SELECT COUNT(*) FROM {table} WHERE unit_id = $1"),
                &[&unit_id],
            )
            .map_err(centre_err(&self.name, &format!("counting {table}")))?
            .get(0))
    }

    /// Runs a query and returns its rows as text (tests compare checksums with it).
    pub fn query_text(&mut self, sql: &str) -> Result<Vec<Vec<Option<String>>>, FleetError> {
        let rows = self
            .client
            .simple_query(sql)
            .map_err(centre_err(&self.name, "query"))?;
        Ok(rows
            .into_iter()
            .filter_map(|m| match m {
                postgres::SimpleQueryMessage::Row(r) => {
                    Some((0..r.len()).map(|i| r.get(i).map(str::to_string)).collect())
                }
                _ => None,
            })
            .collect())
    }
}

/// One unit at the centre: its last sync and its rows per table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct UnitStatus {
    pub unit_id: String,
    /// Unix epoch ms, UTC.
    pub last_sync_ms: i64,
    pub gtwatch_version: String,
    /// (table, rows), in [`CENTRAL_TABLES`] order.
    pub counts: Vec<(String, i64)>,
}

/// Every unit at the centre, by name.
pub fn fleet_status(centre: &mut Centre) -> Result<Vec<UnitStatus>, FleetError> {
    let name = centre.name.clone();
    let rows = centre
        .client
        .query(
            "SELECT unit_id, (extract(epoch FROM last_sync_at) * 1000)::bigint, gtwatch_version
             FROM units ORDER BY unit_id",
            &[],
        )
        .map_err(centre_err(&name, "listing units"))?;
    let mut out: Vec<UnitStatus> = rows
        .iter()
        .map(|r| UnitStatus {
            unit_id: r.get(0),
            last_sync_ms: r.get(1),
            gtwatch_version: r.get(2),
            counts: Vec::new(),
        })
        .collect();
    // An older centre read by this build has no corrections table: none counted.
    let corrections = centre.has_corrections()?;
    for table in CENTRAL_TABLES {
        if *table == "instrument_corrections" && !corrections {
            for u in &mut out {
                u.counts.push(((*table).to_string(), 0));
            }
            continue;
        }
        let counts = centre
            .client
            .query(
                &format!("SELECT unit_id, COUNT(*) FROM {table} GROUP BY unit_id"),
                &[],
            )
            .map_err(centre_err(&name, &format!("counting {table}")))?;
        for u in &mut out {
            let n = counts
                .iter()
                .find(|r| r.get::<_, String>(0) == u.unit_id)
                .map_or(0, |r| r.get::<_, i64>(1));
            u.counts.push(((*table).to_string(), n));
        }
    }
    Ok(out)
}
