//! The daemon's counters in the Prometheus text exposition format (OpenMetrics text 1.0, which
//! Prometheus scrapes natively), written by the `prometheus-client` crate (the Prometheus
//! organisation's own Rust client): [`Exposition::encode`] turns a [`Snapshot`] of counters the
//! daemon already keeps, read at scrape time, plus the [`DurationHistogram`] of diagnosis
//! times, into the page `GET /metrics` serves.
//!
//! What it is for: naming and describing the series (the README's "Metrics" list is this
//! file's). What it must not do: count anything itself, decide anything, do I/O or hold a lock
//! that a producer could wait on (the snapshot closure reads atomics; the histogram's lock is
//! taken for one observation or one encode). The HTTP side is `daemon::metrics`.

use prometheus_client::encoding::{DescriptorEncoder, EncodeMetric};
use prometheus_client::metrics::counter::ConstCounter;
use prometheus_client::metrics::gauge::ConstGauge;
use prometheus_client::metrics::histogram::Histogram;
use prometheus_client::metrics::MetricType;
use prometheus_client::registry::{Registry, Unit};
use std::sync::Arc;
use std::time::Duration;

/// The content type of [`Exposition::encode`]'s page.
pub(crate) const CONTENT_TYPE: &str = "application/openmetrics-text; version=1.0.0; charset=utf-8";

/// Prefix of every series.
const PREFIX: &str = "gtwatch";

/// The daemon's counters at one moment (totals since the daemon started, except the gauges).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Snapshot {
    /// Polls in which every request succeeded.
    pub polls_ok: u64,
    /// Polls or connection attempts that failed.
    pub polls_failed: u64,
    /// Modbus connections made.
    pub connects: u64,
    /// Outages the acquisition recorded as gaps.
    pub poll_gaps: u64,
    /// Samples polled, and of them stored flagged (not good).
    pub samples_polled: u64,
    pub samples_flagged: u64,
    /// Samples new to the database and committed by the writer.
    pub samples_written: u64,
    /// Gaps committed by the writer (outages, restarts, dropped buffers).
    pub gaps_written: u64,
    /// Failed commit attempts (each retried) and samples dropped by a full buffer.
    pub write_errors: u64,
    pub samples_dropped: u64,
    /// Start-up segments the detector closed.
    pub segments_closed: u64,
    /// Start-ups diagnosed / found not diagnosable.
    pub diagnosed: u64,
    pub undiagnosable: u64,
    /// Closed start-ups waiting for their diagnosis (gauge; `None`: no diagnosis in this run).
    pub diagnosis_queue: Option<u64>,
    /// Gap analyses stored, yielded (redone later), failed.
    pub gap_stored: u64,
    pub gap_cancelled: u64,
    pub gap_failed: u64,
    /// The fleet sync's counters (`None`: no `[fleet]` in this run).
    pub fleet: Option<FleetSnapshot>,
    /// The storage maintenance's counters (`None`: compaction and retention off).
    pub compaction: Option<CompactionSnapshot>,
}

/// The storage maintenance task's totals at one moment (compaction, retention, vacuum).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CompactionSnapshot {
    /// Periods whose compaction, retention and vacuum all ran to the end.
    pub runs: u64,
    /// Archive chunks written and the samples they took from the hot tier.
    pub chunks: u64,
    pub samples_archived: u64,
    /// Raw samples replaced by 1-minute roll-ups.
    pub samples_rolled_up: u64,
    /// 1-minute roll-up rows merged into hourly roll-ups.
    pub rollup_minutes_merged: u64,
    /// Pages returned to the file system by incremental vacuum.
    pub pages_vacuumed: u64,
    /// Maintenance steps that failed (retried next period).
    pub failures: u64,
    /// Unix ms when the last run finished (0: none yet).
    pub last_run_ms: u64,
}

/// The fleet sync's counters at one moment.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FleetSnapshot {
    /// Syncs that committed at the centre, and failed ones (each retried with backoff).
    pub syncs_ok: u64,
    pub syncs_failed: u64,
    /// Rows sent over all syncs.
    pub rows_sent: u64,
    /// Unix ms of the last successful sync (0: none yet).
    pub last_ok_ms: u64,
    /// Rows the edge holds above its high-water marks after the last sync round, per table of
    /// [`SYNC_LAG_TABLES`] (`None`: not measured yet, no centre reached).
    pub lag_rows: Option<[u64; SYNC_LAG_TABLES.len()]>,
}

/// The tables of the sync lag gauge, in [`FleetSnapshot::lag_rows`] order (the fleet sync's
/// streams: `fleet::sync::LAG_STREAMS`).
pub const SYNC_LAG_TABLES: [&str; 6] = [
    "segments",
    "diagnoses",
    "gap_analyses",
    "recommendations",
    "washes",
    "samples",
];

/// Wall time of each start-up's diagnosis (Method B and A, storing and the after-result hook
/// included), seconds. Cheap to clone; clones share the buckets.
#[derive(Debug, Clone)]
pub struct DurationHistogram(Histogram);

impl Default for DurationHistogram {
    fn default() -> Self {
        // 0.5 s … 512 s: a start-up takes ≈ 5 s on two cores, a slow machine or a long start-up
        // a minute or more.
        let buckets = prometheus_client::metrics::histogram::exponential_buckets(0.5, 2.0, 11);
        DurationHistogram(Histogram::new(buckets))
    }
}

impl DurationHistogram {
    pub fn observe(&self, d: Duration) {
        self.0.observe(d.as_secs_f64());
    }
}

/// Where the snapshot comes from: read at every scrape.
type Source = Arc<dyn Fn() -> Snapshot + Send + Sync>;

/// The page's writer: a registry holding the counters' collector and the histogram.
pub(crate) struct Exposition {
    registry: Registry,
}

impl Exposition {
    /// An exposition reading `source` at every scrape, with `durations` as the diagnosis
    /// histogram.
    pub(crate) fn new(
        source: impl Fn() -> Snapshot + Send + Sync + 'static,
        durations: &DurationHistogram,
    ) -> Exposition {
        let mut registry = Registry::with_prefix(PREFIX);
        registry.register_with_unit(
            "diagnosis_duration",
            "Wall time of one start-up's diagnosis (both methods, stored)",
            Unit::Seconds,
            durations.0.clone(),
        );
        registry.register_collector(Box::new(Counters {
            source: Arc::new(source),
        }));
        Exposition { registry }
    }

    /// The page, in the OpenMetrics text format ([`CONTENT_TYPE`]).
    pub(crate) fn encode(&self) -> Result<String, std::fmt::Error> {
        let mut out = String::new();
        prometheus_client::encoding::text::encode(&mut out, &self.registry)?;
        Ok(out)
    }
}

/// The collector of the snapshot's counters and gauges.
struct Counters {
    source: Source,
}

impl std::fmt::Debug for Counters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Counters")
    }
}

/// (name without prefix and `_total`, help, value) of every counter in `s`.
fn counters(s: &Snapshot) -> [(&'static str, &'static str, u64); 16] {
    [
        ("polls", "Modbus polls in which every request succeeded", s.polls_ok),
        ("polls_failed", "Modbus polls or connection attempts that failed", s.polls_failed),
        ("connects", "Modbus TCP connections made", s.connects),
        ("poll_gaps", "Acquisition outages recorded as gaps", s.poll_gaps),
        ("samples_polled", "Samples read from the plant", s.samples_polled),
        ("samples_flagged", "Samples read and stored flagged (not good)", s.samples_flagged),
        ("samples_written", "Samples new to the database, committed by the writer", s.samples_written),
        ("gaps_written", "Gaps committed by the writer (outages, restarts, dropped buffers)", s.gaps_written),
        ("write_errors", "Failed commit attempts of the writer (each retried)", s.write_errors),
        ("samples_dropped", "Samples dropped because the writer's buffer was full while the database refused writes", s.samples_dropped),
        ("segments", "Start-up segments the detector closed", s.segments_closed),
        ("diagnosed", "Start-ups diagnosed", s.diagnosed),
        ("undiagnosable", "Start-ups found not diagnosable (reasons stored)", s.undiagnosable),
        ("gap_analyses", "Gap analyses stored", s.gap_stored),
        ("gap_analyses_yielded", "Gap analyses cancelled to let a diagnosis run (redone later)", s.gap_cancelled),
        ("gap_analyses_failed", "Gap analyses that failed", s.gap_failed),
    ]
}

impl prometheus_client::collector::Collector for Counters {
    fn encode(&self, mut encoder: DescriptorEncoder) -> Result<(), std::fmt::Error> {
        let s = (self.source)();
        for (name, help, value) in counters(&s) {
            let m = encoder.encode_descriptor(name, help, None, MetricType::Counter)?;
            ConstCounter::new(value).encode(m)?;
        }
        if let Some(f) = s.fleet {
            for (name, help, value) in [
                (
                    "fleet_syncs",
                    "Fleet syncs committed at the centre",
                    f.syncs_ok,
                ),
                (
                    "fleet_syncs_failed",
                    "Fleet syncs that failed (retried with backoff)",
                    f.syncs_failed,
                ),
                (
                    "fleet_rows_sent",
                    "Rows sent to the fleet centre",
                    f.rows_sent,
                ),
            ] {
                let m = encoder.encode_descriptor(name, help, None, MetricType::Counter)?;
                ConstCounter::new(value).encode(m)?;
            }
            // A timestamp gauge, so an alert can say "no sync for an hour": time() - this.
            let m = encoder.encode_descriptor(
                "fleet_last_sync_timestamp_seconds",
                "Unix time of the last fleet sync committed at the centre (0: none yet)",
                None,
                MetricType::Gauge,
            )?;
            ConstGauge::new(i64::try_from(f.last_ok_ms / 1000).unwrap_or(i64::MAX)).encode(m)?;
            if let Some(lag) = f.lag_rows {
                let mut m = encoder.encode_descriptor(
                    "fleet_sync_lag_rows",
                    "Rows the edge holds above its fleet sync high-water mark after the last sync round, per table (what the next sync sends)",
                    None,
                    MetricType::Gauge,
                )?;
                for (table, n) in SYNC_LAG_TABLES.iter().zip(lag) {
                    let labels = [("table", *table)];
                    let fam = m.encode_family(&labels)?;
                    ConstGauge::new(i64::try_from(n).unwrap_or(i64::MAX)).encode(fam)?;
                }
            }
        }
        if let Some(c) = s.compaction {
            for (name, help, value) in [
                (
                    "storage_maintenance_runs",
                    "Storage maintenance periods that ran to the end (compaction, retention, vacuum)",
                    c.runs,
                ),
                (
                    "archive_chunks",
                    "Archive chunks written by compaction",
                    c.chunks,
                ),
                (
                    "samples_archived",
                    "Samples moved from the hot tier into archive chunks",
                    c.samples_archived,
                ),
                (
                    "samples_rolled_up",
                    "Raw steady samples replaced by 1-minute roll-ups (retention)",
                    c.samples_rolled_up,
                ),
                (
                    "rollup_minutes_merged",
                    "1-minute roll-up rows merged into hourly roll-ups (retention's second tier)",
                    c.rollup_minutes_merged,
                ),
                (
                    "pages_vacuumed",
                    "Database pages returned to the file system by incremental vacuum",
                    c.pages_vacuumed,
                ),
                (
                    "storage_maintenance_failures",
                    "Storage maintenance steps that failed (retried next period)",
                    c.failures,
                ),
            ] {
                let m = encoder.encode_descriptor(name, help, None, MetricType::Counter)?;
                ConstCounter::new(value).encode(m)?;
            }
            let m = encoder.encode_descriptor(
                "storage_maintenance_last_run_timestamp_seconds",
                "Unix time the last storage maintenance run finished (0: none yet)",
                None,
                MetricType::Gauge,
            )?;
            ConstGauge::new(i64::try_from(c.last_run_ms / 1000).unwrap_or(i64::MAX)).encode(m)?;
        }
        if let Some(depth) = s.diagnosis_queue {
            let m = encoder.encode_descriptor(
                "diagnosis_queue",
                "Closed start-ups waiting for their diagnosis",
                None,
                MetricType::Gauge,
            )?;
            ConstGauge::new(i64::try_from(depth).unwrap_or(i64::MAX)).encode(m)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_names_every_series_with_its_value() {
        let h = DurationHistogram::default();
        h.observe(Duration::from_millis(5600));
        let e = Exposition::new(
            || Snapshot {
                polls_ok: 12,
                samples_written: 340,
                diagnosis_queue: Some(2),
                fleet: Some(FleetSnapshot {
                    syncs_ok: 3,
                    syncs_failed: 1,
                    rows_sent: 35_047,
                    last_ok_ms: 1_764_000_000_123,
                    lag_rows: Some([0, 1, 0, 2, 0, 12_345]),
                }),
                compaction: Some(CompactionSnapshot {
                    runs: 2,
                    chunks: 48,
                    samples_archived: 1_234_567,
                    samples_rolled_up: 86_400,
                    rollup_minutes_merged: 1_440,
                    pages_vacuumed: 4096,
                    failures: 1,
                    last_run_ms: 1_764_003_600_999,
                }),
                ..Snapshot::default()
            },
            &h,
        );
        let page = e.encode().expect("encode");
        for line in [
            "# TYPE gtwatch_polls counter",
            "gtwatch_polls_total 12",
            "gtwatch_samples_written_total 340",
            "gtwatch_polls_failed_total 0",
            "gtwatch_diagnosis_queue 2",
            "# TYPE gtwatch_fleet_syncs counter",
            "gtwatch_fleet_syncs_total 3",
            "gtwatch_fleet_syncs_failed_total 1",
            "gtwatch_fleet_rows_sent_total 35047",
            "gtwatch_fleet_last_sync_timestamp_seconds 1764000000",
            "# TYPE gtwatch_fleet_sync_lag_rows gauge",
            "gtwatch_fleet_sync_lag_rows{table=\"segments\"} 0",
            "gtwatch_fleet_sync_lag_rows{table=\"diagnoses\"} 1",
            "gtwatch_fleet_sync_lag_rows{table=\"recommendations\"} 2",
            "gtwatch_fleet_sync_lag_rows{table=\"samples\"} 12345",
            "# TYPE gtwatch_storage_maintenance_runs counter",
            "gtwatch_storage_maintenance_runs_total 2",
            "gtwatch_archive_chunks_total 48",
            "gtwatch_samples_archived_total 1234567",
            "gtwatch_samples_rolled_up_total 86400",
            "gtwatch_rollup_minutes_merged_total 1440",
            "gtwatch_pages_vacuumed_total 4096",
            "gtwatch_storage_maintenance_failures_total 1",
            "gtwatch_storage_maintenance_last_run_timestamp_seconds 1764003600",
            "gtwatch_diagnosis_duration_seconds_count 1",
            "gtwatch_diagnosis_duration_seconds_bucket{le=\"8.0\"} 1",
            "# EOF",
        ] {
            assert!(page.lines().any(|l| l == line), "{line:?} missing:\n{page}");
        }
    }

    #[test]
    fn no_lag_gauge_before_a_centre_was_reached() {
        let e = Exposition::new(
            || Snapshot {
                fleet: Some(FleetSnapshot::default()),
                ..Snapshot::default()
            },
            &DurationHistogram::default(),
        );
        let page = e.encode().expect("encode");
        assert!(page.contains("gtwatch_fleet_syncs_total 0"), "{page}");
        assert!(!page.contains("fleet_sync_lag_rows"), "{page}");
    }

    #[test]
    fn no_queue_gauge_without_diagnosis() {
        let e = Exposition::new(Snapshot::default, &DurationHistogram::default());
        let page = e.encode().expect("encode");
        assert!(!page.contains("diagnosis_queue"), "{page}");
    }
}
