//! Fleet sync (issue 25 item 1): each edge (a unit's gtwatch) sends what it has found to a
//! central PostgreSQL database, so one place holds the start-ups, health results, gap
//! analyses, washes, advice and the full-resolution samples of every start-up of every unit.
//!
//! - [`centre`]: the central schema (its own migrations, `migrations/postgres/`, versioned by
//!   a `schema_version` table; an edge refuses a centre newer than it knows), the connection,
//!   and the fleet status (units, last sync, rows per table);
//! - [`sync`]: one sync of one edge: per table, bounded batches after a high-water mark kept
//!   at the edge (`fleet_sync`, written through the store), each batch committed at the centre
//!   before its mark moves, every row keyed by (unit_id, edge id) so a re-sent batch changes
//!   nothing (`ON CONFLICT DO NOTHING`, `DO UPDATE` where an edge row changes).
//!
//! - [`rediagnose`]: the distributed re-diagnosis queue at the centre (jobs per start-up and
//!   engine/config hash, claimed under a lease with `FOR UPDATE SKIP LOCKED`, completed with
//!   their result in one transaction) and a start-up window read back from the centre; the
//!   `worker` room's `fleet` module runs the diagnosis itself (`gtwatch fleet worker`);
//! - [`regap`]: the results of the queue's gap-analysis jobs (`fleet rediagnose --gap`).
//!
//! The daemon runs it as a task (`daemon::sync`), `gtwatch sync` once. Must not write the
//! edge's tables (only its marks, through a [`sync::MarkSink`]), hold edge SQL (that is
//! `store`'s) or ever block acquisition or diagnosis: a centre that is down, slow or refusing
//! is an error returned to the caller, which logs, counts and retries.

pub mod centre;
pub mod history;
pub mod rediagnose;
pub mod regap;
pub mod sync;

pub use centre::{fleet_status, Centre, UnitStatus};
pub use history::{
    fleet_advice, fleet_history, fleet_washes, FleetAdvice, FleetHistoryFilter, FleetHistoryRow,
    FleetWash,
};
pub use sync::{sync_once, MarkSink, StreamReport, SyncReport};

use crate::config_problem::{check_range, Bounds, ConfigProblem};
use serde::Deserialize;

/// `[fleet]`: where and what this unit sends. Absent: no sync.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FleetConfig {
    /// This unit's name in the fleet (letters, digits, `.`, `_`, `-`; at most 64).
    pub unit_id: String,
    /// libpq-style connection string or URL of the central database,
    /// e.g. `postgresql://gtwatch:secret@127.0.0.1:5432/fleet`.
    pub postgres_url: String,
    /// Seconds between syncs. Default 60.
    #[serde(default = "default_interval_s")]
    pub interval_s: u64,
    /// Send the full-resolution samples of each start-up window. Default true.
    #[serde(default = "default_true")]
    pub send_samples: bool,
    /// Rows per batch (one central transaction each). Default 5000.
    #[serde(default = "default_batch_rows")]
    pub batch_rows: usize,
    /// Connect and statement timeout at the centre, seconds. Default 30.
    #[serde(default = "default_timeout_s")]
    pub timeout_s: u64,
}

fn default_interval_s() -> u64 {
    60
}
fn default_true() -> bool {
    true
}
fn default_batch_rows() -> usize {
    5000
}
fn default_timeout_s() -> u64 {
    30
}

impl FleetConfig {
    /// A section with the defaults for what is not given (the command line's `gtwatch sync`).
    pub fn new(unit_id: &str, postgres_url: &str) -> FleetConfig {
        FleetConfig {
            unit_id: unit_id.to_string(),
            postgres_url: postgres_url.to_string(),
            interval_s: default_interval_s(),
            send_samples: true,
            batch_rows: default_batch_rows(),
            timeout_s: default_timeout_s(),
        }
    }

    /// Problems with this section; keys are prefixed `fleet.`.
    pub fn validate(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        if let Err(why) = check_unit_id(&self.unit_id) {
            p.push(ConfigProblem::new("fleet.unit_id", why));
        }
        if let Err(e) = self.postgres_url.parse::<postgres::Config>() {
            p.push(ConfigProblem::new(
                "fleet.postgres_url",
                format!(
                    "not a PostgreSQL connection string ({e}); e.g. \
                     \"postgresql://gtwatch:secret@127.0.0.1:5432/fleet\""
                ),
            ));
        }
        check_range(
            &mut p,
            "fleet.interval_s",
            self.interval_s,
            Bounds {
                lo: 1,
                hi: 86_400,
                unit: " s",
                why: "1 s … 1 day between syncs",
            },
        );
        check_range(
            &mut p,
            "fleet.batch_rows",
            self.batch_rows as u64,
            Bounds {
                lo: 1,
                hi: 100_000,
                unit: "",
                why: "rows in one central transaction; each is held in memory",
            },
        );
        check_range(
            &mut p,
            "fleet.timeout_s",
            self.timeout_s,
            Bounds {
                lo: 1,
                hi: 3_600,
                unit: " s",
                why: "1 s … 1 h for a connection or a statement at the centre",
            },
        );
        p
    }
}

/// Why `id` cannot name a unit, if it cannot.
pub fn check_unit_id(id: &str) -> Result<(), String> {
    if id.is_empty() {
        return Err("must not be empty".to_string());
    }
    if id.len() > 64 {
        return Err(format!("is {} characters long; at most 64", id.len()));
    }
    if let Some(c) = id
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-')))
    {
        return Err(format!(
            "'{id}' contains '{c}'; use letters, digits, '.', '_' and '-'"
        ));
    }
    Ok(())
}

/// What a sync or a status query can fail with.
#[derive(Debug, thiserror::Error)]
pub enum FleetError {
    #[error("fleet.postgres_url: {0}")]
    Url(String),
    #[error("cannot connect to the fleet centre {centre}")]
    Connect {
        centre: String,
        #[source]
        source: postgres::Error,
    },
    #[error("the fleet centre {centre} has schema version {found}, newer than this gtwatch knows ({supported}); upgrade gtwatch on this unit")]
    SchemaTooNew {
        centre: String,
        found: i32,
        supported: i32,
    },
    #[error("the fleet centre {centre} has no gtwatch schema (no schema_version table); run `gtwatch sync` from an edge first")]
    NoSchema { centre: String },
    #[error("fleet centre {centre}: {what}")]
    Centre {
        centre: String,
        what: String,
        #[source]
        source: postgres::Error,
    },
    #[error("fleet centre {centre}: {what}")]
    Data { centre: String, what: String },
    #[error("edge database: {0}")]
    Edge(#[from] crate::store::StoreError),
    #[error("sync stopped (shutdown)")]
    Stopped,
}

/// `host:port/dbname user=…` of a connection string, never its password (for messages).
pub fn describe_url(url: &str) -> String {
    match url.parse::<postgres::Config>() {
        Ok(c) => {
            let hosts: Vec<String> = c
                .get_hosts()
                .iter()
                .map(|h| match h {
                    postgres::config::Host::Tcp(s) => s.clone(),
                    postgres::config::Host::Unix(p) => p.display().to_string(),
                })
                .collect();
            let port = c.get_ports().first().copied().unwrap_or(5432);
            format!(
                "{}:{}/{} (user {})",
                hosts.join(","),
                port,
                c.get_dbname().unwrap_or(""),
                c.get_user().unwrap_or("")
            )
        }
        Err(_) => "(unparsable connection string)".to_string(),
    }
}

/// The error and its sources joined by `: ` (each text once), for logs.
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut out = e.to_string();
    let mut src = e.source();
    while let Some(s) = src {
        let t = s.to_string();
        if !out.contains(&t) {
            out.push_str(": ");
            out.push_str(&t);
        }
        src = s.source();
    }
    out
}
