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

use super::client::{resolve, ReadError, ReadOnlyClient};
use super::plan::{decode_request, plant_clock, PollPlan};
use super::progress::{Backoff, PollProgress, PollStats};
use super::AcquisitionConfig;
use crate::acquire::clock::SampleClock;
use crate::acquire::register_map::RegisterKind;
use crate::shutdown::Shutdown;
use crate::store::{Gap, Sample, TagId, WriteCmd};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

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
/// `WriteCmd::Samples` per poll, gaps as `WriteCmd::Gap`. Returns the final tallies. Ends early
/// only if the writer has gone away (nothing could be stored).
pub async fn poll_loop(
    cfg: &AcquisitionConfig,
    plan: &PollPlan,
    tx: mpsc::Sender<WriteCmd>,
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
    tx: mpsc::Sender<WriteCmd>,
    progress: Arc<PollProgress>,
    mut shutdown: Shutdown,
    mut clock: SampleClock,
) -> PollStats {
    let period = Duration::from_millis(cfg.poll_period_ms.max(1));
    let connect_timeout = Duration::from_millis(cfg.connect_timeout_ms);
    let request_timeout = Duration::from_millis(cfg.request_timeout_ms);
    let mut backoff = Backoff::new(
        Duration::from_millis(cfg.backoff_initial_ms),
        Duration::from_millis(cfg.backoff_max_ms),
    );
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
    let mut gate = crate::acquire::gate::Gate::new(plan, &plan.quality);
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
        let before = clock.last_issued_ms();
        let stamp = clock.now();
        if let Some(jump) = stamp.reanchored_by_ms {
            tracing::warn!(
                jump_ms = jump,
                "wall clock jumped; sample clock re-anchored"
            );
            progress.clock_reanchors.fetch_add(1, Ordering::Relaxed);
            if let (Some(from), None) = (before, time_tag) {
                let gap = clock_gap(from, stamp.t_ms, jump);
                progress.gaps.fetch_add(1, Ordering::Relaxed);
                if tx.send(WriteCmd::Gap(gap)).await.is_err() {
                    break;
                }
            }
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
                        crate::time::fmt_ms(last_plant_ms.unwrap_or(t)),
                        crate::time::fmt_ms(t)
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
