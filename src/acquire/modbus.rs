//! The Modbus TCP poll loop: read the register map every period, decode, send samples to the
//! writer, and turn outages into recorded gaps.
//!
//! Read-only by construction: the only client type here is [`ReadOnlyClient`], whose private
//! tokio-modbus context is reachable only through `read_holding_registers` (function 3) and
//! `read_input_registers` (function 4). Nothing in this module may write to the control system.
//!
//! Every connect and request is wrapped in a timeout. After any error or timeout the connection
//! is dropped and re-made (with capped exponential backoff): a reply that arrives after its
//! timeout then lands on a closed socket and can never be taken for the answer to the next
//! request. An outage is recorded as a [`Gap`] from the last good poll to the first good poll
//! after it, with the reason of the first failure. The loop never panics on plant input.

use crate::acquire::clock::SampleClock;
use crate::acquire::register_map::{
    decode_field, FieldSpec, ModbusConfig, ReadingStatus, RegisterKind,
};
use crate::config_problem::{check_range, Bounds, ConfigProblem};
use crate::shutdown::Shutdown;
use crate::store::{Gap, Quality, Sample, TagId, WriteCmd};
use serde::{Deserialize, Serialize};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;
use tokio_modbus::client::{tcp, Context, Reader};
use tokio_modbus::prelude::SlaveContext;
use tokio_modbus::Slave;

/// The `[acquisition]` section: where samples come from and how the poll loop behaves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AcquisitionConfig {
    /// `modbus` (live polling of `[modbus]`) or `none` (no live acquisition: the daemon only
    /// runs the detector over replayed data).
    #[serde(default)]
    pub source: SourceKind,
    /// Poll period, ms (100 = 10 Hz).
    #[serde(default = "d_poll")]
    pub poll_period_ms: u64,
    /// Timeout for establishing the TCP connection, ms.
    #[serde(default = "d_connect")]
    pub connect_timeout_ms: u64,
    /// Timeout for one read request, ms. Must be shorter than the poll period's multiple you
    /// can tolerate losing; a timed-out connection is always dropped.
    #[serde(default = "d_request")]
    pub request_timeout_ms: u64,
    /// First reconnect delay after a failure, ms; doubles on each further failure…
    #[serde(default = "d_backoff0")]
    pub backoff_initial_ms: u64,
    /// …up to this cap, ms.
    #[serde(default = "d_backoff_max")]
    pub backoff_max_ms: u64,
    /// Wall-clock jump that re-anchors the sample clock, ms (see `acquire::clock`).
    #[serde(default = "d_rejump")]
    pub clock_jump_threshold_ms: u64,
    /// Name of a register-map field that carries the plant's own clock (Unix epoch ms, e.g.
    /// `plant_time_ms` served by `gtwatch plant-sim`). Set: every poll's samples are stamped
    /// with that value instead of the local clock, so a plant simulated faster than real time
    /// keeps its real durations; a poll whose clock value is invalid is a failed poll (a gap),
    /// and one whose clock did not advance is not stored. Absent (default): local clock.
    #[serde(default)]
    pub timestamp_field: Option<String>,
}

/// Where live samples come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceKind {
    #[default]
    Modbus,
    None,
}

fn d_poll() -> u64 {
    100
}
fn d_connect() -> u64 {
    3000
}
fn d_request() -> u64 {
    1000
}
fn d_backoff0() -> u64 {
    500
}
fn d_backoff_max() -> u64 {
    30_000
}
fn d_rejump() -> u64 {
    1000
}

impl Default for AcquisitionConfig {
    fn default() -> Self {
        AcquisitionConfig {
            source: SourceKind::Modbus,
            poll_period_ms: d_poll(),
            connect_timeout_ms: d_connect(),
            request_timeout_ms: d_request(),
            backoff_initial_ms: d_backoff0(),
            backoff_max_ms: d_backoff_max(),
            clock_jump_threshold_ms: d_rejump(),
            timestamp_field: None,
        }
    }
}

impl AcquisitionConfig {
    pub fn validate(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        let k = |s: &str| format!("acquisition.{s}");
        if !(1..=3_600_000).contains(&self.poll_period_ms) {
            p.push(ConfigProblem::new(
                k("poll_period_ms"),
                format!("{} ms is outside 1 ms … 1 h", self.poll_period_ms),
            ));
        }
        for (name, v) in [
            ("connect_timeout_ms", self.connect_timeout_ms),
            ("request_timeout_ms", self.request_timeout_ms),
            ("backoff_initial_ms", self.backoff_initial_ms),
            ("clock_jump_threshold_ms", self.clock_jump_threshold_ms),
        ] {
            if v == 0 {
                p.push(ConfigProblem::new(k(name), "must be greater than 0"));
            } else {
                check_range(
                    &mut p,
                    &k(name),
                    v,
                    Bounds {
                        lo: 1,
                        hi: 86_400_000,
                        unit: " ms",
                        why: "at most one day",
                    },
                );
            }
        }
        check_range(
            &mut p,
            &k("backoff_max_ms"),
            self.backoff_max_ms,
            Bounds {
                lo: 0,
                hi: 86_400_000,
                unit: " ms",
                why: "at most one day",
            },
        );
        if self.backoff_max_ms < self.backoff_initial_ms {
            p.push(ConfigProblem::new(
                k("backoff_max_ms"),
                format!(
                    "cap {} ms is below backoff_initial_ms {} ms",
                    self.backoff_max_ms, self.backoff_initial_ms
                ),
            ));
        }
        p
    }
}

/// Why a read failed. Any of these drops the connection.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("timed out after {0} ms")]
    Timeout(u64),
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    #[error("protocol error: {0}")]
    Protocol(String),
    #[error("device answered with Modbus exception {0:?}")]
    Exception(tokio_modbus::ExceptionCode),
    #[error("device returned {got} registers, {want} requested")]
    ShortResponse { got: usize, want: usize },
}

impl ReadError {
    /// The text stored as a gap's reason: the same for the same fault on every run. An I/O
    /// error's OS text is not (tokio-modbus 0.17 maps EOF through `last_os_error`, giving
    /// `Success (os error 0)`, `Operation now in progress (os error 115)`, … for one server
    /// death), so only its kind is kept; the full text goes to the log.
    pub fn stable_reason(&self) -> String {
        match self {
            ReadError::Io(e) => {
                let what = match e.kind() {
                    std::io::ErrorKind::ConnectionRefused => "connection refused",
                    std::io::ErrorKind::TimedOut => "connection timed out",
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::InvalidInput => {
                        "address not resolved"
                    }
                    _ => "connection lost",
                };
                format!("I/O error: {what}")
            }
            ReadError::Protocol(_) => "protocol error".to_string(),
            other => other.to_string(),
        }
    }
}

/// A Modbus TCP client that can only read (function codes 3 and 4). The tokio-modbus context
/// is private, so no code path can reach its `Writer` methods.
pub struct ReadOnlyClient {
    ctx: Context,
}

impl std::fmt::Debug for ReadOnlyClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ReadOnlyClient")
    }
}

impl ReadOnlyClient {
    /// Connects with a timeout.
    pub async fn connect(addr: SocketAddr, timeout: Duration) -> Result<Self, ReadError> {
        match tokio::time::timeout(timeout, tcp::connect(addr)).await {
            Err(_) => Err(ReadError::Timeout(timeout.as_millis() as u64)),
            Ok(Err(e)) => Err(ReadError::Io(e)),
            Ok(Ok(ctx)) => Ok(ReadOnlyClient { ctx }),
        }
    }

    /// Reads `count` holding registers (function 3) from `slave`.
    pub async fn read_holding_registers(
        &mut self,
        slave: u8,
        addr: u16,
        count: u16,
        timeout: Duration,
    ) -> Result<Vec<u16>, ReadError> {
        self.read(RegisterKind::Holding, slave, addr, count, timeout)
            .await
    }

    /// Reads `count` input registers (function 4) from `slave`.
    pub async fn read_input_registers(
        &mut self,
        slave: u8,
        addr: u16,
        count: u16,
        timeout: Duration,
    ) -> Result<Vec<u16>, ReadError> {
        self.read(RegisterKind::Input, slave, addr, count, timeout)
            .await
    }

    async fn read(
        &mut self,
        kind: RegisterKind,
        slave: u8,
        addr: u16,
        count: u16,
        timeout: Duration,
    ) -> Result<Vec<u16>, ReadError> {
        self.ctx.set_slave(Slave(slave));
        let call = async {
            match kind {
                RegisterKind::Holding => self.ctx.read_holding_registers(addr, count).await,
                RegisterKind::Input => self.ctx.read_input_registers(addr, count).await,
            }
        };
        let words = match tokio::time::timeout(timeout, call).await {
            Err(_) => return Err(ReadError::Timeout(timeout.as_millis() as u64)),
            Ok(Err(tokio_modbus::Error::Transport(e))) => return Err(ReadError::Io(e)),
            Ok(Err(tokio_modbus::Error::Protocol(e))) => {
                return Err(ReadError::Protocol(e.to_string()))
            }
            Ok(Ok(Err(code))) => return Err(ReadError::Exception(code)),
            Ok(Ok(Ok(words))) => words,
        };
        if words.len() < count as usize {
            return Err(ReadError::ShortResponse {
                got: words.len(),
                want: count as usize,
            });
        }
        Ok(words)
    }
}

/// One request of the poll plan, with the tag id of each field.
#[derive(Debug, Clone)]
pub struct PlannedRequest {
    pub slave: u8,
    pub kind: RegisterKind,
    pub start: u16,
    pub count: u16,
    pub fields: Vec<(TagId, FieldSpec)>,
}

/// What the poll loop reads, in order. Built from a checked register map.
#[derive(Debug, Clone)]
pub struct PollPlan {
    pub endpoint: String,
    pub requests: Vec<PlannedRequest>,
    /// The bad-value policy applied to every polled value (`[quality]`).
    pub quality: crate::quality::QualityConfig,
}

impl PollPlan {
    /// `tags` holds the tag id of every field in map order ([`ModbusConfig::fields`]).
    /// The map must have passed `check()`; addresses are then within u16.
    pub fn new(map: &ModbusConfig, tags: &[TagId]) -> Result<PollPlan, String> {
        let mut ids = tags.iter().copied();
        let mut requests = Vec::new();
        for (i, r) in map.requests.iter().enumerate() {
            let start = u16::try_from(r.start_address)
                .map_err(|_| format!("modbus.request[{i}].start_address out of range"))?;
            let count = u16::try_from(r.register_count())
                .map_err(|_| format!("modbus.request[{i}] register count out of range"))?;
            let mut fields = Vec::new();
            for f in &r.fields {
                let id = ids
                    .next()
                    .ok_or_else(|| "fewer tag ids than fields".to_string())?;
                fields.push((id, f.clone()));
            }
            requests.push(PlannedRequest {
                slave: r.slave_id,
                kind: r.register,
                start,
                count,
                fields,
            });
        }
        Ok(PollPlan {
            endpoint: map.endpoint.clone(),
            requests,
            quality: crate::quality::QualityConfig::default(),
        })
    }

    pub fn tag_count(&self) -> usize {
        self.requests.iter().map(|r| r.fields.len()).sum()
    }
}

/// Counters the daemon reads while the loop runs (watchdog, logs, benchmarks).
#[derive(Debug, Default)]
pub struct PollProgress {
    /// Polls in which every request succeeded.
    pub polls_ok: AtomicU64,
    /// Polls or connection attempts that failed.
    pub failures: AtomicU64,
    pub samples: AtomicU64,
    /// Samples stored flagged (any code but good).
    pub flagged: AtomicU64,
    /// ... of which flagged stuck (code 3) and spike (code 4).
    pub stuck: AtomicU64,
    pub spike: AtomicU64,
    pub gaps: AtomicU64,
    pub connects: AtomicU64,
    /// Loop iterations completed (a poll, a recorded failure or a backoff wait): liveness.
    pub cycles: AtomicU64,
    /// Polls not stored because the plant clock (`timestamp_field`) had not advanced.
    pub clock_stalls: AtomicU64,
}

/// Final tallies when the loop ends.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct PollStats {
    pub polls_ok: u64,
    pub failures: u64,
    pub samples: u64,
    pub flagged: u64,
    pub stuck: u64,
    pub spike: u64,
    pub gaps: u64,
    pub connects: u64,
}

impl PollProgress {
    pub fn snapshot(&self) -> PollStats {
        PollStats {
            polls_ok: self.polls_ok.load(Ordering::Relaxed),
            failures: self.failures.load(Ordering::Relaxed),
            samples: self.samples.load(Ordering::Relaxed),
            flagged: self.flagged.load(Ordering::Relaxed),
            stuck: self.stuck.load(Ordering::Relaxed),
            spike: self.spike.load(Ordering::Relaxed),
            gaps: self.gaps.load(Ordering::Relaxed),
            connects: self.connects.load(Ordering::Relaxed),
        }
    }
}

/// Source name recorded with gaps.
pub const GAP_SOURCE: &str = "modbus";

/// An outage in progress.
#[derive(Debug)]
struct Outage {
    /// Time of the last good poll before it (or of the first failure if there was none).
    start_ms: i64,
    reason: String,
    failures: u64,
}

/// Capped exponential backoff.
#[derive(Debug, Clone)]
pub struct Backoff {
    initial: Duration,
    max: Duration,
    next: Duration,
}

impl Backoff {
    pub fn new(initial: Duration, max: Duration) -> Self {
        Backoff {
            initial,
            max,
            next: initial,
        }
    }
    /// The delay before the next attempt; doubles the one after, up to the cap.
    pub fn next_delay(&mut self) -> Duration {
        let d = self.next;
        self.next = (self.next * 2).min(self.max);
        d
    }
    pub fn reset(&mut self) {
        self.next = self.initial;
    }
}

fn quality(status: ReadingStatus) -> Quality {
    match status {
        ReadingStatus::Good => Quality::Good,
        ReadingStatus::OutOfRange => Quality::OutOfRange,
        ReadingStatus::NotFinite => Quality::Bad,
    }
}

/// The plant clock of one poll: the value of `tag` among the decoded samples, as epoch ms.
fn plant_clock(batch: &[Sample], tag: TagId) -> Result<i64, String> {
    let Some(s) = batch.iter().find(|s| s.tag == tag) else {
        return Err("plant clock field missing from the poll".into());
    };
    // Between 1970 and 2262 (i64 nanoseconds elsewhere); anything else is not a clock.
    if s.quality != Quality::Good || !(s.value.is_finite() && (0.0..9.2e15).contains(&s.value)) {
        return Err(format!(
            "plant clock field holds an invalid time ({} ms)",
            s.value
        ));
    }
    Ok(s.value.round() as i64)
}

/// The bad-value policy's range check (`crate::quality`) for a field: the register map's own
/// `min`/`max` when it sets either (the per-tag override), else the signal's default range.
fn policy_quality(f: &crate::acquire::register_map::FieldSpec, value: f64, q: Quality) -> Quality {
    if q != Quality::Good || f.min.is_some() || f.max.is_some() {
        return q;
    }
    let limits = f.signal.map(crate::quality::default_limits);
    crate::quality::classify_value(value, limits.as_ref())
}

/// Decodes one request's registers into samples (pure; flagged values keep their quality).
pub fn decode_request(req: &PlannedRequest, words: &[u16], t_ms: i64, out: &mut Vec<Sample>) {
    for (tag, f) in &req.fields {
        let sample = match decode_field(f, u32::from(req.start), words) {
            Ok(r) => Sample {
                tag: *tag,
                t_ms,
                // SQLite cannot store NaN (it becomes NULL); a Bad sample keeps 0 as value and
                // its quality says the number is meaningless.
                value: if r.value.is_finite() { r.value } else { 0.0 },
                quality: policy_quality(f, r.value, quality(r.status)),
            },
            Err(_) => Sample {
                tag: *tag,
                t_ms,
                value: 0.0,
                quality: Quality::Bad,
            },
        };
        out.push(sample);
    }
}

/// Resolves `host:port` (DNS names allowed) to the first address.
async fn resolve(endpoint: &str) -> Result<SocketAddr, ReadError> {
    tokio::net::lookup_host(endpoint)
        .await?
        .next()
        .ok_or_else(|| ReadError::Protocol(format!("{endpoint} resolves to no address")))
}

/// Runs the poll loop until `shutdown`: one poll per period, samples sent as one
/// `WriteCmd::Samples` per poll, gaps as `WriteCmd::Gap`. Returns the final tallies. Ends early
/// only if the writer has gone away (nothing could be stored).
pub async fn poll_loop(
    cfg: &AcquisitionConfig,
    plan: &PollPlan,
    tx: mpsc::Sender<WriteCmd>,
    progress: Arc<PollProgress>,
    mut shutdown: Shutdown,
) -> PollStats {
    let period = Duration::from_millis(cfg.poll_period_ms.max(1));
    let connect_timeout = Duration::from_millis(cfg.connect_timeout_ms);
    let request_timeout = Duration::from_millis(cfg.request_timeout_ms);
    let mut backoff = Backoff::new(
        Duration::from_millis(cfg.backoff_initial_ms),
        Duration::from_millis(cfg.backoff_max_ms),
    );
    let mut clock = SampleClock::new(Duration::from_millis(cfg.clock_jump_threshold_ms));
    let mut interval = tokio::time::interval(period);
    // After a stall, skip the missed ticks: polling faster to "catch up" would only produce
    // samples bunched in time.
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut client: Option<ReadOnlyClient> = None;
    let mut retry_at: Option<Instant> = None;
    let mut outage: Option<Outage> = None;
    let mut last_good_ms: Option<i64> = None;
    let mut batch: Vec<Sample> = Vec::with_capacity(plan.tag_count());
    // The tag whose value is the plant clock, when samples are stamped in plant time.
    let time_tag: Option<TagId> = cfg.timestamp_field.as_deref().and_then(|name| {
        plan.requests
            .iter()
            .flat_map(|r| r.fields.iter())
            .find(|(_, f)| f.name == name)
            .map(|(tag, _)| *tag)
    });
    let mut last_plant_ms: Option<i64> = None;
    let mut gate = super::gate::Gate::new(plan, &plan.quality);
    let count = |released: &[Sample], progress: &PollProgress| {
        let mut c = crate::quality::QualityCounts::default();
        for s in released {
            c.add(s.quality);
        }
        progress
            .samples
            .fetch_add(released.len() as u64, Ordering::Relaxed);
        progress.flagged.fetch_add(c.flagged(), Ordering::Relaxed);
        progress.stuck.fetch_add(c.stuck, Ordering::Relaxed);
        progress.spike.fetch_add(c.spike, Ordering::Relaxed);
    };

    let fail = |outage: &mut Option<Outage>,
                last_good: Option<i64>,
                now_ms: i64,
                reason: String,
                progress: &PollProgress| {
        progress.failures.fetch_add(1, Ordering::Relaxed);
        match outage {
            Some(o) => o.failures += 1,
            None => {
                tracing::warn!(%reason, "acquisition interrupted");
                *outage = Some(Outage {
                    start_ms: last_good.unwrap_or(now_ms),
                    reason,
                    failures: 1,
                });
            }
        }
    };

    loop {
        tokio::select! {
            biased;
            _ = shutdown.wait() => break,
            _ = interval.tick() => {}
        }
        progress.cycles.fetch_add(1, Ordering::Relaxed);
        if client.is_none() {
            if retry_at.is_some_and(|t| Instant::now() < t) {
                continue;
            }
            // Name resolution counts against the connect timeout too.
            let attempt = async {
                match tokio::time::timeout(connect_timeout, resolve(&plan.endpoint)).await {
                    Err(_) => Err(ReadError::Timeout(connect_timeout.as_millis() as u64)),
                    Ok(Err(e)) => Err(e),
                    Ok(Ok(addr)) => ReadOnlyClient::connect(addr, connect_timeout).await,
                }
            };
            let result = tokio::select! {
                biased;
                _ = shutdown.wait() => break,
                r = attempt => r,
            };
            match result {
                Ok(c) => {
                    progress.connects.fetch_add(1, Ordering::Relaxed);
                    tracing::info!(endpoint = %plan.endpoint, "connected");
                    client = Some(c);
                }
                Err(e) => {
                    let now = clock.now().t_ms;
                    tracing::debug!(endpoint = %plan.endpoint, error = %e, "connect failed");
                    let reason =
                        format!("connect to {} failed: {}", plan.endpoint, e.stable_reason());
                    fail(&mut outage, last_good_ms, now, reason, &progress);
                    retry_at = Some(Instant::now() + backoff.next_delay());
                    continue;
                }
            }
        }
        let Some(conn) = client.as_mut() else {
            continue;
        };
        let stamp = clock.now();
        if let Some(jump) = stamp.reanchored_by_ms {
            tracing::warn!(
                jump_ms = jump,
                "wall clock jumped; sample clock re-anchored"
            );
        }
        batch.clear();
        let mut error: Option<String> = None;
        for req in &plan.requests {
            let read = async {
                match req.kind {
                    RegisterKind::Holding => {
                        conn.read_holding_registers(
                            req.slave,
                            req.start,
                            req.count,
                            request_timeout,
                        )
                        .await
                    }
                    RegisterKind::Input => {
                        conn.read_input_registers(req.slave, req.start, req.count, request_timeout)
                            .await
                    }
                }
            };
            let result = tokio::select! {
                biased;
                _ = shutdown.wait() => Err(ReadError::Protocol("shutdown".into())),
                r = read => r,
            };
            match result {
                Ok(words) => decode_request(req, &words, stamp.t_ms, &mut batch),
                Err(e) => {
                    tracing::debug!(error = %e, "read failed");
                    error = Some(format!(
                        "read {} {}+{} from slave {}: {}",
                        req.kind,
                        req.start,
                        req.count,
                        req.slave,
                        e.stable_reason()
                    ));
                    break;
                }
            }
        }
        if shutdown.is_triggered() && error.is_some() {
            break;
        }
        let mut stamp_ms = stamp.t_ms;
        if let (Some(tag), None) = (time_tag, &error) {
            match plant_clock(&batch, tag) {
                Ok(t) if last_plant_ms == Some(t) => {
                    // The plant has not produced a new frame since the last poll: storing it
                    // again would duplicate samples.
                    progress.clock_stalls.fetch_add(1, Ordering::Relaxed);
                    progress.polls_ok.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                Ok(t) if last_plant_ms.is_some_and(|last| t < last) => {
                    // A plant clock that steps back (a restarted simulator, a PLC clock set
                    // back) would interleave new readings with stored ones: an outage until
                    // it passes the last stored time, recorded as a gap.
                    error = Some(format!(
                        "plant clock went backwards from {} to {}",
                        crate::ingest::fmt_ms(last_plant_ms.unwrap_or(t)),
                        crate::ingest::fmt_ms(t)
                    ));
                }
                Ok(t) => {
                    for s in batch.iter_mut() {
                        s.t_ms = t;
                    }
                    stamp_ms = t;
                    last_plant_ms = Some(t);
                }
                Err(why) => error = Some(why),
            }
        }
        if time_tag.is_some() && error.is_some() {
            // In plant time, a reading without a valid plant clock has no true time stamp:
            // never store it under the local clock's.
            batch.clear();
            stamp_ms = last_plant_ms.unwrap_or(stamp_ms);
        }
        // Whatever was decoded before a failure is a valid reading at this instant: keep it.
        let released = gate.apply(&batch);
        if let Some(reason) = error {
            // Drop the connection: a late reply must never be matched to the next request.
            client = None;
            fail(&mut outage, last_good_ms, stamp_ms, reason, &progress);
            retry_at = Some(Instant::now() + backoff.next_delay());
        } else {
            if let Some(o) = outage.take() {
                let gap = Gap {
                    // An outage before the first good poll started on the local clock; in
                    // plant time its start is unknown, so the gap is marked where it ended.
                    start_ms: o.start_ms.min(stamp_ms),
                    end_ms: stamp_ms,
                    source: GAP_SOURCE.to_string(),
                    reason: gap_reason(&o),
                };
                tracing::info!(
                    seconds = (gap.end_ms - gap.start_ms) as f64 / 1000.0,
                    reason = %gap.reason,
                    "acquisition resumed"
                );
                progress.gaps.fetch_add(1, Ordering::Relaxed);
                if tx.send(WriteCmd::Gap(gap)).await.is_err() {
                    break;
                }
            }
            backoff.reset();
            retry_at = None;
            last_good_ms = Some(stamp_ms);
            progress.polls_ok.fetch_add(1, Ordering::Relaxed);
        }
        if !released.is_empty() {
            count(&released, &progress);
            if tx.send(WriteCmd::Samples(released)).await.is_err() {
                tracing::error!("writer has stopped; ending acquisition");
                break;
            }
        }
    }
    // The readings the spike rule still holds are valid: store them.
    let rest = gate.finish();
    if !rest.is_empty() {
        count(&rest, &progress);
        let _ = tx.send(WriteCmd::Samples(rest)).await;
    }
    // An outage still open at shutdown is recorded up to now, so the data shows it.
    if let Some(o) = outage.take() {
        // In plant time "now" is unknown once the plant stopped answering: the gap is marked
        // from the last good reading.
        let end_ms = if time_tag.is_some() {
            o.start_ms
        } else {
            clock.now().t_ms
        };
        let gap = Gap {
            start_ms: o.start_ms.min(end_ms),
            end_ms,
            source: GAP_SOURCE.to_string(),
            reason: format!("{} (still down at shutdown)", gap_reason(&o)),
        };
        progress.gaps.fetch_add(1, Ordering::Relaxed);
        let _ = tx.send(WriteCmd::Gap(gap)).await;
    }
    // Dropping the client closes the socket; no generic `Client::call` is reachable here.
    drop(client);
    progress.snapshot()
}

fn gap_reason(o: &Outage) -> String {
    if o.failures > 1 {
        format!("{} ({} failed attempts)", o.reason, o.failures)
    } else {
        o.reason.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;
    use tokio::net::TcpListener;
    use tokio_modbus::prelude::{ExceptionCode, Request, Response};
    use tokio_modbus::server::tcp::{accept_tcp_connection, Server};

    #[test]
    fn gap_reason_for_a_server_death_is_stable() {
        // Regression (issue 12 #9): one server death was stored as `I/O error: Success (os
        // error 0)`, `Operation now in progress (os error 115)` or `Connection reset by peer`.
        let texts: Vec<String> = [
            std::io::Error::from_raw_os_error(0),
            std::io::Error::from_raw_os_error(115),
            std::io::Error::from(std::io::ErrorKind::ConnectionReset),
            std::io::Error::from(std::io::ErrorKind::UnexpectedEof),
        ]
        .into_iter()
        .map(|e| ReadError::Io(e).stable_reason())
        .collect();
        assert!(
            texts.iter().all(|t| t == "I/O error: connection lost"),
            "{texts:?}"
        );
        let refused = ReadError::Io(std::io::ErrorKind::ConnectionRefused.into());
        assert_eq!(refused.stable_reason(), "I/O error: connection refused");
    }

    /// Issue 12 #3: the bad-value policy's default ranges apply to Modbus fields of a signal
    /// when the register map sets no range of its own.
    #[test]
    fn default_signal_ranges_flag_modbus_values() {
        use crate::acquire::register_map::{encode_field, ByteOrder, DataType, FieldSpec};
        let f = FieldSpec {
            name: "n1_rpm".into(),
            address: 0,
            data_type: DataType::F32,
            byte_order: ByteOrder::ABCD,
            scale: 1.0,
            offset: 0.0,
            unit: "rpm".into(),
            signal: Some(crate::signals::Signal::N1),
            min: None,
            max: None,
        };
        let req = PlannedRequest {
            slave: 1,
            kind: crate::acquire::register_map::RegisterKind::Holding,
            start: 0,
            count: 2,
            fields: vec![(7, f.clone())],
        };
        let q = |v: f64| {
            let mut out = Vec::new();
            decode_request(&req, &encode_field(&f, v), 0, &mut out);
            out[0].quality
        };
        assert_eq!(q(7600.0), Quality::Good);
        assert_eq!(q(-500.0), Quality::OutOfRange);
        assert_eq!(q(1e9), Quality::OutOfRange);
        assert_eq!(q(f64::INFINITY), Quality::Bad);
    }

    #[test]
    fn backoff_doubles_up_to_the_cap_and_resets() {
        let mut b = Backoff::new(Duration::from_millis(100), Duration::from_millis(500));
        let d: Vec<u128> = (0..5).map(|_| b.next_delay().as_millis()).collect();
        assert_eq!(d, vec![100, 200, 400, 500, 500]);
        b.reset();
        assert_eq!(b.next_delay().as_millis(), 100);
    }

    /// A server that records the function code of every request it receives, and answers
    /// reads with zeros (and writes with success, so a write would go unnoticed otherwise).
    #[derive(Clone)]
    struct Recorder {
        codes: Arc<Mutex<Vec<u8>>>,
    }

    impl tokio_modbus::server::Service for Recorder {
        type Request = Request<'static>;
        type Response = Response;
        type Exception = ExceptionCode;
        type Future = std::future::Ready<Result<Response, ExceptionCode>>;
        fn call(&self, req: Request<'static>) -> Self::Future {
            if let Ok(mut c) = self.codes.lock() {
                c.push(req.function_code().value());
            }
            std::future::ready(Ok(match req {
                Request::ReadHoldingRegisters(_, n) => {
                    Response::ReadHoldingRegisters(vec![0; n as usize])
                }
                Request::ReadInputRegisters(_, n) => {
                    Response::ReadInputRegisters(vec![0; n as usize])
                }
                Request::WriteSingleRegister(a, w) => Response::WriteSingleRegister(a, w),
                Request::WriteMultipleRegisters(a, w) => {
                    Response::WriteMultipleRegisters(a, w.len() as u16)
                }
                Request::WriteSingleCoil(a, c) => Response::WriteSingleCoil(a, c),
                _ => return std::future::ready(Err(ExceptionCode::IllegalFunction)),
            }))
        }
    }

    #[tokio::test]
    async fn the_poll_loop_sends_only_read_function_codes() {
        use crate::acquire::register_map::{ByteOrder, DataType, RequestSpec};
        let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
        let addr = listener.local_addr().expect("addr");
        let codes = Arc::new(Mutex::new(Vec::new()));
        let rec = Recorder {
            codes: Arc::clone(&codes),
        };
        let server = tokio::spawn(async move {
            let s = Server::new(listener);
            let new_service = move |_a| Ok(Some(rec.clone()));
            let on_connected = |stream, a| {
                let ns = new_service.clone();
                async move { accept_tcp_connection(stream, a, ns) }
            };
            let _ = s.serve(&on_connected, |_e| {}).await;
        });
        let field = |name: &str, address| FieldSpec {
            name: name.into(),
            address,
            data_type: DataType::U16,
            byte_order: ByteOrder::ABCD,
            scale: 1.0,
            offset: 0.0,
            unit: String::new(),
            signal: None,
            min: None,
            max: None,
        };
        let map = ModbusConfig {
            endpoint: addr.to_string(),
            requests: vec![
                RequestSpec {
                    slave_id: 1,
                    register: RegisterKind::Holding,
                    start_address: 0,
                    count: None,
                    fields: vec![field("a", 0), field("b", 1)],
                },
                RequestSpec {
                    slave_id: 2,
                    register: RegisterKind::Input,
                    start_address: 10,
                    count: None,
                    fields: vec![field("c", 10)],
                },
            ],
        };
        let plan = PollPlan::new(&map, &[1, 2, 3]).expect("plan");
        let cfg = AcquisitionConfig {
            poll_period_ms: 10,
            ..AcquisitionConfig::default()
        };
        let (tx, mut rx) = mpsc::channel(64);
        let (trigger, shutdown) = crate::shutdown::shutdown_channel();
        let progress = Arc::new(PollProgress::default());
        let p2 = Arc::clone(&progress);
        let task = tokio::spawn(async move { poll_loop(&cfg, &plan, tx, p2, shutdown).await });
        let mut samples = 0;
        while samples < 60 {
            match rx.recv().await {
                Some(WriteCmd::Samples(s)) => samples += s.len(),
                Some(_) => {}
                None => break,
            }
        }
        trigger.trigger();
        let stats = task.await.expect("join");
        server.abort();
        assert!(stats.polls_ok >= 20, "{stats:?}");
        let codes = codes.lock().expect("lock").clone();
        assert!(codes.len() >= 40);
        assert!(codes.iter().all(|&c| c == 3 || c == 4), "{codes:?}");
        assert!(codes.contains(&3) && codes.contains(&4));
    }

    #[tokio::test]
    async fn an_outage_open_at_shutdown_is_recorded_as_a_gap() {
        // A port nobody listens on.
        let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        let addr = l.local_addr().expect("addr");
        drop(l);
        let plan = PollPlan {
            quality: crate::quality::QualityConfig::default(),
            endpoint: addr.to_string(),
            requests: vec![],
        };
        let cfg = AcquisitionConfig {
            poll_period_ms: 10,
            backoff_initial_ms: 10,
            backoff_max_ms: 40,
            ..AcquisitionConfig::default()
        };
        let (tx, mut rx) = mpsc::channel(64);
        let (trigger, shutdown) = crate::shutdown::shutdown_channel();
        let progress = Arc::new(PollProgress::default());
        let p2 = Arc::clone(&progress);
        let task = tokio::spawn(async move { poll_loop(&cfg, &plan, tx, p2, shutdown).await });
        tokio::time::sleep(Duration::from_millis(200)).await;
        trigger.trigger();
        let stats = task.await.expect("join");
        assert_eq!(stats.polls_ok, 0);
        assert!(stats.failures >= 3, "{stats:?}");
        assert!(progress.cycles.load(Ordering::Relaxed) >= 10);
        let mut gaps = Vec::new();
        while let Some(cmd) = rx.recv().await {
            if let WriteCmd::Gap(g) = cmd {
                gaps.push(g);
            }
        }
        assert_eq!(gaps.len(), 1, "{gaps:?}");
        let g = &gaps[0];
        assert!(g.end_ms - g.start_ms >= 150, "{g:?}");
        assert!(
            g.reason
                .starts_with(&format!("connect to {addr} failed: I/O error:")),
            "{}",
            g.reason
        );
        assert!(
            g.reason
                .ends_with("failed attempts) (still down at shutdown)"),
            "{}",
            g.reason
        );
    }
}
