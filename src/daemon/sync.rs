//! The fleet sync task (`[fleet]`): every `interval_s`, sends what is new in the edge's store
//! to the central PostgreSQL (`crate::fleet::sync_once`).
//!
//! Reads through its own read-only connection and writes its high-water marks through the
//! one writer (`WriteCmd::FleetMark`), on the blocking pool. A centre that is down, slow
//! (connect and statement timeouts) or refusing (authentication, a newer schema) costs this
//! task only: the error is logged, counted and retried with a backoff doubling from 5 s to
//! 10 min (never shorter than the interval), and acquisition and diagnosis never wait for it.
//! Shutdown stops a running sync between batches. Must not hold SQL of either side.

use crate::fleet::sync::{sync_lag, LAG_STREAMS};
use crate::fleet::{sync_once, Centre, FleetConfig, FleetError, SyncReport};
use crate::shutdown::Shutdown;
use crate::store::{ReadStore, Store, StoreOptions, WriterHandle};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// First wait after a failed sync; doubles up to [`MAX_BACKOFF`].
const FIRST_BACKOFF: Duration = Duration::from_secs(5);
const MAX_BACKOFF: Duration = Duration::from_secs(600);

/// The sync task's counters (the daemon's report; tests read them).
#[derive(Debug, Default)]
pub struct SyncCounters {
    pub syncs_ok: AtomicU64,
    pub syncs_failed: AtomicU64,
    /// Rows sent over all syncs.
    pub rows_sent: AtomicU64,
    /// Unix epoch ms of the last successful sync (0: none yet).
    pub last_ok_ms: AtomicU64,
    /// Rows the edge holds above its marks after the last round, per stream of
    /// [`LAG_STREAMS`] (`fleet::sync::sync_lag`); meaningful once `lag_known`.
    pub lag_rows: [AtomicU64; LAG_STREAMS.len()],
    /// The lag was measured (a centre was reached once, so its marks are known).
    pub lag_known: AtomicBool,
}

impl SyncCounters {
    /// The lag per stream, once measured.
    pub fn lag(&self) -> Option<[u64; LAG_STREAMS.len()]> {
        self.lag_known
            .load(Ordering::Relaxed)
            .then(|| std::array::from_fn(|i| self.lag_rows[i].load(Ordering::Relaxed)))
    }
}

/// What the sync task did over the daemon's run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SyncTaskReport {
    pub syncs_ok: u64,
    pub syncs_failed: u64,
    pub rows_sent: u64,
}

/// What a sync keeps between rounds: its read connection and the centre's connection.
#[derive(Default)]
struct Conns {
    store: Option<ReadStore>,
    centre: Option<Centre>,
    /// The id of the centre last reached (its marks measure the lag while it is away).
    centre_id: Option<String>,
}

/// The fleet sync task (mini-redis shape: a small struct with its own `run`).
pub struct SyncTask {
    pub db_path: PathBuf,
    pub store_opts: StoreOptions,
    pub writer: WriterHandle,
    pub cfg: FleetConfig,
    pub counters: Arc<SyncCounters>,
}

impl SyncTask {
    /// Syncs every `interval_s` until shutdown.
    pub async fn run(self, mut shutdown: Shutdown) -> SyncTaskReport {
        let interval = Duration::from_secs(self.cfg.interval_s.max(1));
        let stop = Arc::new(AtomicBool::new(false));
        let mut conns = Some(Conns::default());
        let mut backoff = FIRST_BACKOFF.min(interval);
        loop {
            let state = conns.take().unwrap_or_default();
            let (db, opts, cfg) = (self.db_path.clone(), self.store_opts, self.cfg.clone());
            let (writer, stop2) = (self.writer.clone(), Arc::clone(&stop));
            let counters = Arc::clone(&self.counters);
            // The PostgreSQL client blocks (also when dropped): it lives on the blocking pool
            // only, and is dropped there when a sync fails.
            let job = tokio::task::spawn_blocking(move || {
                let mut state = state;
                let r = round(&mut state, &db, &opts, writer, &cfg, &stop2);
                measure_lag(&mut state, &cfg, &counters);
                if let Err(e) = &r {
                    // A lost or refusing centre is reconnected next time.
                    state.centre = None;
                    if matches!(e, FleetError::Edge(_)) {
                        state.store = None;
                    }
                }
                (state, r)
            });
            let outcome = tokio::select! {
                j = job => Some(j),
                _ = shutdown.wait() => None,
            };
            let wait = match outcome {
                None => {
                    stop.store(true, Ordering::Relaxed);
                    break;
                }
                Some(Err(e)) => {
                    self.failed(&format!("sync task failed: {e}"));
                    backoff
                }
                Some(Ok((state, Ok(report)))) => {
                    conns = Some(state);
                    self.succeeded(&report);
                    backoff = FIRST_BACKOFF.min(interval);
                    interval
                }
                Some(Ok((state, Err(e)))) => {
                    conns = Some(state);
                    self.failed(&crate::fleet::error_chain(&e));
                    let w = backoff.max(interval.min(MAX_BACKOFF));
                    backoff = (backoff * 2).min(MAX_BACKOFF);
                    w
                }
            };
            tokio::select! {
                _ = shutdown.wait() => break,
                _ = tokio::time::sleep(wait) => {}
            }
        }
        if let Some(c) = conns {
            let _ = tokio::task::spawn_blocking(move || drop(c)).await;
        }
        SyncTaskReport {
            syncs_ok: self.counters.syncs_ok.load(Ordering::Relaxed),
            syncs_failed: self.counters.syncs_failed.load(Ordering::Relaxed),
            rows_sent: self.counters.rows_sent.load(Ordering::Relaxed),
        }
    }

    fn succeeded(&self, r: &SyncReport) {
        let c = &self.counters;
        c.syncs_ok.fetch_add(1, Ordering::Relaxed);
        c.rows_sent.fetch_add(r.total_sent(), Ordering::Relaxed);
        c.last_ok_ms.store(
            u64::try_from(crate::store::now_ms()).unwrap_or(0),
            Ordering::Relaxed,
        );
        let sent: Vec<String> = r
            .streams
            .iter()
            .filter(|s| s.sent > 0 || s.removed > 0)
            .map(|s| format!("{} {}", s.table, s.sent))
            .collect();
        if sent.is_empty() {
            tracing::debug!(centre = %r.centre, "fleet sync: nothing new");
        } else {
            tracing::info!(centre = %r.centre, wall_s = r.wall_s, sent = %sent.join(", "), "fleet sync");
        }
    }

    fn failed(&self, why: &str) {
        let n = self.counters.syncs_failed.fetch_add(1, Ordering::Relaxed) + 1;
        tracing::warn!(failures = n, "fleet sync failed (retried): {why}");
    }
}

/// The edge's rows above its marks for the centre last reached, into `counters` (the
/// metrics' lag per table). Measured after every round, also a failed one: while the centre
/// is away the lag grows. Reads the edge only; a failure to read is logged and the last
/// figures stay.
fn measure_lag(state: &mut Conns, cfg: &FleetConfig, counters: &SyncCounters) {
    if let Some(c) = &state.centre {
        state.centre_id = Some(c.id.clone());
    }
    let (Some(store), Some(centre_id)) = (&state.store, &state.centre_id) else {
        return;
    };
    match sync_lag(store, centre_id, &cfg.unit_id, cfg.send_samples) {
        Ok(lag) => {
            for (i, (_, n)) in lag.iter().enumerate().take(LAG_STREAMS.len()) {
                counters.lag_rows[i].store(*n, Ordering::Relaxed);
            }
            counters.lag_known.store(true, Ordering::Relaxed);
        }
        Err(e) => tracing::debug!("fleet sync lag not measured: {e}"),
    }
}

/// One sync on the blocking pool, opening what is missing.
fn round(
    state: &mut Conns,
    db: &std::path::Path,
    opts: &StoreOptions,
    mut writer: WriterHandle,
    cfg: &FleetConfig,
    stop: &AtomicBool,
) -> Result<SyncReport, FleetError> {
    if state.store.is_none() {
        state.store = Some(Store::open_readonly_with(db, opts)?);
    }
    if state.centre.is_none() {
        state.centre = Some(Centre::connect(
            &cfg.postgres_url,
            Duration::from_secs(cfg.timeout_s),
        )?);
    }
    match (&state.store, &mut state.centre) {
        (Some(store), Some(centre)) => sync_once(store, &mut writer, centre, cfg, stop),
        _ => Err(FleetError::Stopped),
    }
}
