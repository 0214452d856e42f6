//! The poll loop: read the register map every period, decode, send samples to the
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
//! after it.
//!
//! The loop is a small state machine (`Link`: down → connect → up → poll; a failure backs
//! off to down) whose steps are named methods of one `Poller`.

use super::client::{resolve, ReadError, ReadOnlyClient};
use super::plan::{decode_request, plant_clock, PollPlan};
use super::progress::{Backoff, PollProgress, PollStats};
use super::AcquisitionConfig;
use crate::acquire::clock::SampleClock;
use crate::acquire::register_map::RegisterKind;
use crate::shutdown::Shutdown;
use crate::store::{Gap, Sample, TagId, WriteCmd, WriterHandle};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

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

/// Runs the poll loop until `shutdown`: one poll per period, samples sent as one
/// `WriteCmd::Samples` per poll, gaps as `WriteCmd::Gap`; a full channel makes it wait (the
/// poll is late, no sample is dropped). Returns the final tallies. Ends early only if the
/// writer has gone away (nothing could be stored).
pub async fn poll_loop(
    cfg: &AcquisitionConfig,
    plan: &PollPlan,
    tx: WriterHandle,
    progress: Arc<PollProgress>,
    shutdown: Shutdown,
) -> PollStats {
    let clock = SampleClock::new(Duration::from_millis(cfg.clock_jump_threshold_ms));
    poll_loop_with_clock(cfg, plan, tx, progress, shutdown, clock).await
}

/// [`poll_loop`] stamping samples with `clock` (a test steps its wall clock). A wall-clock
/// step that re-anchors the sample clock is logged, counted (`PollProgress::clock_reanchors`)
/// and, when samples are stamped by this clock, recorded as a gap of source
/// [`CLOCK_GAP_SOURCE`] from the last stamp before the step to the first after it.
pub async fn poll_loop_with_clock(
    cfg: &AcquisitionConfig,
    plan: &PollPlan,
    tx: WriterHandle,
    progress: Arc<PollProgress>,
    mut shutdown: Shutdown,
    clock: SampleClock,
) -> PollStats {
    let mut interval = tokio::time::interval(Duration::from_millis(cfg.poll_period_ms.max(1)));
    // After a stall, skip the missed ticks: polling faster to "catch up" would only produce
    // samples bunched in time.
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut poller = Poller::new(cfg, plan, tx, progress, clock);
    loop {
        tokio::select! {
            biased;
            _ = shutdown.wait() => break,
            _ = interval.tick() => {}
        }
        if poller.cycle(&mut shutdown).await == Flow::Stop {
            break;
        }
    }
    poller.finish().await
}

/// Whether the loop goes on after a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Flow {
    Continue,
    /// Shutdown, or the writer has gone away.
    Stop,
}

/// The link to the PLC: the state of the machine (connect → poll → back off → connect).
enum Link {
    /// No connection; the next attempt not before `retry_at` (at once if `None`).
    Down { retry_at: Option<Instant> },
    /// Connected: poll.
    Up(ReadOnlyClient),
}

/// What a connect attempt gave.
enum Connect {
    Connected(ReadOnlyClient),
    /// Backing off, or the attempt failed (recorded): try again at a later tick.
    NotYet,
    Shutdown,
}

/// What the plant clock says about one poll's readings.
enum PlantTime {
    /// A new frame at this plant time.
    At(i64),
    /// The same frame as the last poll's: nothing new to store.
    Stalled,
    /// No valid plant time (why).
    Invalid(String),
}

/// The poll loop's state between ticks.
struct Poller<'a> {
    plan: &'a PollPlan,
    tx: WriterHandle,
    progress: Arc<PollProgress>,
    clock: SampleClock,
    connect_timeout: Duration,
    request_timeout: Duration,
    backoff: Backoff,
    link: Link,
    outage: Option<Outage>,
    last_good_ms: Option<i64>,
    batch: Vec<Sample>,
    /// The tag whose value is the plant clock, when samples are stamped in plant time.
    time_tag: Option<TagId>,
    last_plant_ms: Option<i64>,
    gate: crate::acquire::gate::Gate,
}

impl<'a> Poller<'a> {
    fn new(
        cfg: &AcquisitionConfig,
        plan: &'a PollPlan,
        tx: WriterHandle,
        progress: Arc<PollProgress>,
        clock: SampleClock,
    ) -> Poller<'a> {
        let time_tag = cfg.timestamp_field.as_deref().and_then(|name| {
            plan.requests
                .iter()
                .flat_map(|r| r.fields.iter())
                .find(|(_, f)| f.name == name)
                .map(|(tag, _)| *tag)
        });
        Poller {
            plan,
            tx,
            progress,
            clock,
            connect_timeout: Duration::from_millis(cfg.connect_timeout_ms),
            request_timeout: Duration::from_millis(cfg.request_timeout_ms),
            backoff: Backoff::new(
                Duration::from_millis(cfg.backoff_initial_ms),
                Duration::from_millis(cfg.backoff_max_ms),
            ),
            link: Link::Down { retry_at: None },
            outage: None,
            last_good_ms: None,
            batch: Vec::with_capacity(plan.tag_count()),
            time_tag,
            last_plant_ms: None,
            gate: crate::acquire::gate::Gate::new(plan, &plan.quality),
        }
    }

    /// One tick: connect if down (unless backing off), then poll.
    async fn cycle(&mut self, shutdown: &mut Shutdown) -> Flow {
        self.progress.cycles.fetch_add(1, Ordering::Relaxed);
        let client = match std::mem::replace(&mut self.link, Link::Down { retry_at: None }) {
            Link::Up(client) => client,
            Link::Down { retry_at } => match self.connect(retry_at, shutdown).await {
                Connect::Connected(client) => client,
                Connect::NotYet => return Flow::Continue,
                Connect::Shutdown => return Flow::Stop,
            },
        };
        self.poll(client, shutdown).await
    }

    /// The connect step: a new connection, or the link left down (backing off).
    async fn connect(&mut self, retry_at: Option<Instant>, shutdown: &mut Shutdown) -> Connect {
        if retry_at.is_some_and(|t| Instant::now() < t) {
            self.link = Link::Down { retry_at };
            return Connect::NotYet;
        }
        let endpoint = &self.plan.endpoint;
        let connect_timeout = self.connect_timeout;
        // Name resolution counts against the connect timeout too.
        let attempt = async {
            match tokio::time::timeout(connect_timeout, resolve(endpoint)).await {
                Err(_) => Err(ReadError::Timeout(connect_timeout.as_millis() as u64)),
                Ok(Err(e)) => Err(e),
                Ok(Ok(addr)) => ReadOnlyClient::connect(addr, connect_timeout).await,
            }
        };
        let result = tokio::select! {
            biased;
            _ = shutdown.wait() => return Connect::Shutdown,
            r = attempt => r,
        };
        match result {
            Ok(client) => {
                self.progress.connects.fetch_add(1, Ordering::Relaxed);
                tracing::info!(endpoint = %self.plan.endpoint, "connected");
                Connect::Connected(client)
            }
            Err(e) => {
                let now = self.clock.now().t_ms;
                tracing::debug!(endpoint = %self.plan.endpoint, error = %e, "connect failed");
                let reason = format!(
                    "connect to {} failed: {}",
                    self.plan.endpoint,
                    e.stable_reason()
                );
                self.back_off(now, reason);
                Connect::NotYet
            }
        }
    }

    /// The poll step on a connected link: stamp, read every request, take the plant's time
    /// when configured, gate, then account for a good poll or back off after a failure.
    async fn poll(&mut self, mut client: ReadOnlyClient, shutdown: &mut Shutdown) -> Flow {
        let before = self.clock.last_issued_ms();
        let stamp = self.clock.now();
        if let Some(jump) = stamp.reanchored_by_ms {
            if self.clock_stepped(before, stamp.t_ms, jump).await == Flow::Stop {
                return Flow::Stop;
            }
        }
        let mut error = self.read_all(&mut client, stamp.t_ms, shutdown).await;
        if shutdown.is_triggered() && error.is_some() {
            return Flow::Stop;
        }
        let mut stamp_ms = stamp.t_ms;
        if let (Some(tag), None) = (self.time_tag, &error) {
            match self.plant_time(tag) {
                PlantTime::Stalled => {
                    // The plant has not produced a new frame since the last poll: storing it
                    // again would duplicate samples.
                    self.progress.clock_stalls.fetch_add(1, Ordering::Relaxed);
                    self.progress.polls_ok.fetch_add(1, Ordering::Relaxed);
                    self.link = Link::Up(client);
                    return Flow::Continue;
                }
                PlantTime::At(t) => stamp_ms = t,
                PlantTime::Invalid(why) => error = Some(why),
            }
        }
        if self.time_tag.is_some() && error.is_some() {
            // In plant time, a reading without a valid plant clock has no true time stamp:
            // never store it under the local clock's.
            self.batch.clear();
            stamp_ms = self.last_plant_ms.unwrap_or(stamp_ms);
        }
        // Whatever was decoded before a failure is a valid reading at this instant: keep it.
        let released = self.gate.apply(&self.batch);
        let flow = match error {
            Some(reason) => {
                // Drop the connection: a late reply must never be matched to the next request.
                drop(client);
                self.back_off(stamp_ms, reason);
                Flow::Continue
            }
            None => {
                self.link = Link::Up(client);
                self.resumed(stamp_ms).await
            }
        };
        if flow == Flow::Stop {
            return Flow::Stop;
        }
        self.send_samples(released).await
    }

    /// A wall-clock step re-anchored the sample clock: logged, counted and, when samples are
    /// stamped by this clock, recorded as a gap.
    async fn clock_stepped(&mut self, before: Option<i64>, t_ms: i64, jump: i64) -> Flow {
        tracing::warn!(
            jump_ms = jump,
            "wall clock jumped; sample clock re-anchored"
        );
        self.progress
            .clock_reanchors
            .fetch_add(1, Ordering::Relaxed);
        let (Some(from), None) = (before, self.time_tag) else {
            return Flow::Continue;
        };
        self.progress.gaps.fetch_add(1, Ordering::Relaxed);
        if self
            .tx
            .send(WriteCmd::Gap(clock_gap(from, t_ms, jump)))
            .await
            .is_err()
        {
            return Flow::Stop;
        }
        Flow::Continue
    }

    /// Reads every request of the plan into `batch`, stamped `t_ms`; the first failure's
    /// description, if any (what was decoded before it stays in `batch`).
    async fn read_all(
        &mut self,
        client: &mut ReadOnlyClient,
        t_ms: i64,
        shutdown: &mut Shutdown,
    ) -> Option<String> {
        self.batch.clear();
        let request_timeout = self.request_timeout;
        let plan = self.plan;
        for req in &plan.requests {
            let read = async {
                match req.kind {
                    RegisterKind::Holding => {
                        client
                            .read_holding_registers(
                                req.slave,
                                req.start,
                                req.count,
                                request_timeout,
                            )
                            .await
                    }
                    RegisterKind::Input => {
                        client
                            .read_input_registers(req.slave, req.start, req.count, request_timeout)
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
                Ok(words) => decode_request(req, &words, t_ms, &mut self.batch),
                Err(e) => {
                    tracing::debug!(error = %e, "read failed");
                    return Some(format!(
                        "read {} {}+{} from slave {}: {}",
                        req.kind,
                        req.start,
                        req.count,
                        req.slave,
                        e.stable_reason()
                    ));
                }
            }
        }
        None
    }

    /// The plant time of this poll's readings (re-stamping `batch` with it when new).
    fn plant_time(&mut self, tag: TagId) -> PlantTime {
        match plant_clock(&self.batch, tag) {
            Ok(t) if self.last_plant_ms == Some(t) => PlantTime::Stalled,
            // A plant clock that steps back (a restarted simulator, a PLC clock set back)
            // would interleave new readings with stored ones: an outage until it passes the
            // last stored time, recorded as a gap.
            Ok(t) if self.last_plant_ms.is_some_and(|last| t < last) => {
                PlantTime::Invalid(format!(
                    "plant clock went backwards from {} to {}",
                    crate::time::fmt_ms(self.last_plant_ms.unwrap_or(t)),
                    crate::time::fmt_ms(t)
                ))
            }
            Ok(t) => {
                for s in self.batch.iter_mut() {
                    s.t_ms = t;
                }
                self.last_plant_ms = Some(t);
                PlantTime::At(t)
            }
            Err(why) => PlantTime::Invalid(why),
        }
    }

    /// The back-off step: the failure is counted (opening an outage if none is open) and the
    /// link stays down until the backoff delay has passed.
    fn back_off(&mut self, now_ms: i64, reason: String) {
        self.progress.failures.fetch_add(1, Ordering::Relaxed);
        match &mut self.outage {
            Some(o) => o.failures += 1,
            None => {
                tracing::warn!(%reason, "acquisition interrupted");
                self.outage = Some(Outage {
                    start_ms: self.last_good_ms.unwrap_or(now_ms),
                    reason,
                    failures: 1,
                });
            }
        }
        self.link = Link::Down {
            retry_at: Some(Instant::now() + self.backoff.next_delay()),
        };
    }

    /// A good poll at `stamp_ms`: an open outage is closed and recorded as a gap, the backoff
    /// reset.
    async fn resumed(&mut self, stamp_ms: i64) -> Flow {
        if let Some(o) = self.outage.take() {
            let gap = Gap {
                // An outage before the first good poll started on the local clock; in plant
                // time its start is unknown, so the gap is marked where it ended.
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
            self.progress.gaps.fetch_add(1, Ordering::Relaxed);
            if self.tx.send(WriteCmd::Gap(gap)).await.is_err() {
                return Flow::Stop;
            }
        }
        self.backoff.reset();
        self.last_good_ms = Some(stamp_ms);
        self.progress.polls_ok.fetch_add(1, Ordering::Relaxed);
        Flow::Continue
    }

    /// Sends the gate's released samples to the writer (counted by quality).
    async fn send_samples(&mut self, released: Vec<Sample>) -> Flow {
        if released.is_empty() {
            return Flow::Continue;
        }
        self.count(&released);
        if self.tx.send(WriteCmd::Samples(released)).await.is_err() {
            tracing::error!("writer has stopped; ending acquisition");
            return Flow::Stop;
        }
        Flow::Continue
    }

    fn count(&self, released: &[Sample]) {
        let mut c = crate::quality::QualityCounts::default();
        for s in released {
            c.add(s.quality);
        }
        let p = &self.progress;
        p.samples
            .fetch_add(released.len() as u64, Ordering::Relaxed);
        p.flagged.fetch_add(c.flagged(), Ordering::Relaxed);
        p.stuck.fetch_add(c.stuck, Ordering::Relaxed);
        p.spike.fetch_add(c.spike, Ordering::Relaxed);
    }

    /// At shutdown (or when the writer went away): the readings the spike rule still holds
    /// are stored, an outage still open is recorded up to now, the connection closed.
    async fn finish(mut self) -> PollStats {
        let rest = self.gate.finish();
        if !rest.is_empty() {
            self.count(&rest);
            let _ = self.tx.send(WriteCmd::Samples(rest)).await;
        }
        if let Some(o) = self.outage.take() {
            // In plant time "now" is unknown once the plant stopped answering: the gap is
            // marked from the last good reading.
            let end_ms = if self.time_tag.is_some() {
                o.start_ms
            } else {
                self.clock.now().t_ms
            };
            let gap = Gap {
                start_ms: o.start_ms.min(end_ms),
                end_ms,
                source: GAP_SOURCE.to_string(),
                reason: format!("{} (still down at shutdown)", gap_reason(&o)),
            };
            self.progress.gaps.fetch_add(1, Ordering::Relaxed);
            let _ = self.tx.send(WriteCmd::Gap(gap)).await;
        }
        // Dropping the client closes the socket; no generic `Client::call` is reachable here.
        drop(self.link);
        self.progress.snapshot()
    }
}

/// Source name of the gaps that record a wall-clock step.
pub const CLOCK_GAP_SOURCE: &str = "clock";

/// The gap recording a re-anchor by `jump_ms` between the stamps `from_ms` and `to_ms`.
fn clock_gap(from_ms: i64, to_ms: i64, jump_ms: i64) -> Gap {
    let reason = if jump_ms < 0 {
        format!(
            "wall clock stepped back {:.3} s; sample times held just above the last stored time until it catches up",
            -jump_ms as f64 / 1000.0
        )
    } else {
        format!(
            "wall clock stepped forward {:.3} s",
            jump_ms as f64 / 1000.0
        )
    };
    Gap {
        start_ms: from_ms.min(to_ms),
        end_ms: to_ms,
        source: CLOCK_GAP_SOURCE.to_string(),
        reason,
    }
}

fn gap_reason(o: &Outage) -> String {
    if o.failures > 1 {
        format!("{} ({} failed attempts)", o.reason, o.failures)
    } else {
        o.reason.clone()
    }
}
