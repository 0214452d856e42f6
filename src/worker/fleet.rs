//! The fleet re-diagnosis worker (`gtwatch fleet worker`, issue 25 item 3): claims jobs from
//! the centre's queue under a lease, reads each start-up's window from the centre, runs the
//! edge's own diagnosis on it ([`assess_segment_on`] with the job's engine text and settings,
//! whose hash it checks) or, for a gap job, the edge's own gap analysis
//! ([`super::gap::analyse_startup`], as the daemon's gap task runs it), and stores the result
//! with its hash and this worker's id in the transaction that marks the job done, only while
//! it still holds the lease.
//!
//! A renewal thread, with its own connection, extends the lease every third of its length while
//! a fit runs; when the lease is lost (renewal refused, or the centre unreachable until the
//! lease ran out) it cancels the fit, and the worker writes nothing for that job. A worker
//! killed at any moment leaves a pending job whose lease expires, which another then claims.
//! Any number of workers on any number of machines share one queue. A centre that goes away
//! (restart, network) is ridden out: the worker reconnects with a backoff and ends with the
//! error only after a few minutes of failures.
//!
//! Lives in the worker room because it runs the diagnosis; the queue's SQL is
//! `crate::fleet::rediagnose`'s and `crate::fleet::regap`'s. Must not hold SQL, fitting
//! arithmetic of its own, or touch an edge database.

use super::{assess_segment_on, failures, new_diagnoses, DiagnosisSettings, WorkerContext};
use crate::diagnosis::assess::Assessment;
use crate::fleet::rediagnose::{self, Job, JobKind, JobResult};
use crate::fleet::regap::{self, GapJobResult};
use crate::fleet::{Centre, FleetError};
use crate::optim::Cancel;
use crate::store::SegmentRecording;
use serde::Serialize;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How a worker runs.
#[derive(Debug, Clone)]
pub struct FleetWorkerOptions {
    pub postgres_url: String,
    /// This worker's id in the queue (`host:pid` by default).
    pub worker_id: String,
    /// Lease length; renewed every third of it.
    pub lease: Duration,
    /// Stop after this many jobs finished (done, failed or lost); `None`: no limit.
    pub max_jobs: Option<u64>,
    /// Exit when no job is pending (none waiting, none leased by anyone); otherwise wait.
    pub idle_exit: bool,
    /// Wait between looks at an empty (or fully leased) queue.
    pub poll: Duration,
    /// Threads of each fit (the result does not depend on it).
    pub threads: usize,
    /// Connect and statement timeout at the centre.
    pub timeout: Duration,
}

/// What a worker did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct FleetWorkerReport {
    pub worker_id: String,
    /// Jobs whose result this worker stored (diagnoses and gap analyses).
    pub done: u64,
    /// Of those, start-ups found undiagnosable.
    pub undiagnosable: u64,
    /// Of those, gap analyses.
    pub gap_done: u64,
    /// Jobs this worker could not run (marked failed, with the reason).
    pub failed: u64,
    /// Jobs whose lease this worker lost before storing (nothing written).
    pub lost: u64,
    /// Time spent fitting, s.
    pub fit_s: f64,
    pub wall_s: f64,
    /// CPU time of this process (all threads, user + system), s; `None` where `/proc` is not.
    pub cpu_s: Option<f64>,
}

/// CPU time of this process so far (user + system, all threads), s: fields 14 and 15 of
/// `/proc/self/stat`, in clock ticks of 1/100 s (Linux's USER_HZ on every architecture it
/// exposes to user space).
fn process_cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) may hold spaces: fields are counted after its ')'.
    let rest = &stat[stat.rfind(')')? + 1..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// `host:pid`, the default worker id.
pub fn default_worker_id() -> String {
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|h| h.trim().to_string())
        .filter(|h| !h.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_else(|| "worker".to_string());
    format!("{host}:{}", std::process::id())
}

/// The job being held, shared with the renewal thread.
#[derive(Default)]
struct Held {
    /// (job id, the fit's cancel flag, when the lease was last confirmed).
    job: Option<(i64, Cancel, Instant)>,
    /// The worker is ending: the renewal thread ends too.
    quit: bool,
}

/// The lease renewal thread and what it watches.
struct Renewer {
    held: Arc<Mutex<Held>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Renewer {
    fn start(opts: &FleetWorkerOptions) -> Renewer {
        let held = Arc::new(Mutex::new(Held::default()));
        let (h, url, worker, lease, timeout) = (
            Arc::clone(&held),
            opts.postgres_url.clone(),
            opts.worker_id.clone(),
            opts.lease,
            opts.timeout,
        );
        let thread = std::thread::spawn(move || renew_loop(&h, &url, &worker, lease, timeout));
        Renewer {
            held,
            thread: Some(thread),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Held> {
        // A panic while holding this lock leaves plain data behind: keep using it.
        self.held
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn watch(&self, job: i64, cancel: &Cancel) {
        self.lock().job = Some((job, cancel.clone(), Instant::now()));
    }

    fn unwatch(&self) {
        self.lock().job = None;
    }
}

impl Drop for Renewer {
    fn drop(&mut self) {
        self.lock().quit = true;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Renews the held job's lease every third of its length; cancels the fit when it is lost.
fn renew_loop(held: &Mutex<Held>, url: &str, worker: &str, lease: Duration, timeout: Duration) {
    let every = lease / 3;
    let mut centre: Option<Centre> = None;
    let mut last_try = Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(50).min(every));
        let job = {
            let g = held
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            if g.quit {
                return;
            }
            g.job.clone()
        };
        let Some((id, cancel, confirmed)) = job else {
            continue;
        };
        if last_try.elapsed() < every || cancel.is_cancelled() {
            continue;
        }
        last_try = Instant::now();
        if centre.is_none() {
            centre = Centre::connect_existing(url, timeout.min(lease)).ok();
        }
        let renewed = match centre.as_mut() {
            Some(c) => rediagnose::renew(c, id, worker, lease),
            None => Err(FleetError::Stopped),
        };
        match renewed {
            Ok(true) => {
                let mut g = held
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                if let Some(j) = g.job.as_mut().filter(|j| j.0 == id) {
                    j.2 = Instant::now();
                }
            }
            Ok(false) => {
                tracing::warn!(
                    job = id,
                    "lease lost (taken over or expired): the fit stops"
                );
                cancel.cancel();
            }
            Err(e) => {
                centre = None;
                if confirmed.elapsed() >= lease {
                    tracing::warn!(job = id, "lease ran out unrenewed ({e}): the fit stops");
                    cancel.cancel();
                }
            }
        }
    }
}

/// Diagnosis contexts of the hashes seen, built once each.
type Contexts = HashMap<String, Arc<WorkerContext>>;

/// The context a job runs with, its hash checked against the job's.
fn context_for(contexts: &mut Contexts, job: &Job) -> Result<Arc<WorkerContext>, String> {
    if let Some(c) = contexts.get(&job.config_hash) {
        return Ok(Arc::clone(c));
    }
    let settings: DiagnosisSettings = serde_json::from_str(&job.settings_json)
        .map_err(|e| format!("the job's [diagnosis] settings: {e}"))?;
    let ctx = WorkerContext::from_text(job.engine_toml.clone(), &job.engine_name, settings)
        .map_err(|e| format!("the job's engine {}: {e:#}", job.engine_name))?;
    if ctx.config_hash != job.config_hash {
        return Err(format!(
            "this gtwatch ({}) computes config hash {} for the job's engine and settings, \
             not the job's {}: run a worker of the version that queued it",
            env!("CARGO_PKG_VERSION"),
            ctx.config_hash,
            job.config_hash
        ));
    }
    let ctx = Arc::new(ctx);
    contexts.insert(job.config_hash.clone(), Arc::clone(&ctx));
    Ok(ctx)
}

/// What became of one claimed job.
enum JobEnd {
    Done {
        undiagnosable: bool,
        gap: bool,
        fit_s: f64,
    },
    Failed,
    Lost,
}

/// Runs jobs until the queue is empty (`idle_exit`), `max_jobs` are finished, or `stop` is set.
pub fn run_fleet_worker(
    opts: &FleetWorkerOptions,
    stop: &Cancel,
) -> Result<FleetWorkerReport, FleetError> {
    let t0 = Instant::now();
    let mut centre = Centre::connect(&opts.postgres_url, opts.timeout)?;
    let renewer = Renewer::start(opts);
    let mut contexts = Contexts::new();
    let mut rep = FleetWorkerReport {
        worker_id: opts.worker_id.clone(),
        ..FleetWorkerReport::default()
    };
    let mut finished = 0u64;
    let mut failures = 0u32;
    tracing::info!(worker = %opts.worker_id, centre = %centre.name, "fleet worker started");
    while !stop.is_cancelled() && opts.max_jobs.is_none_or(|m| finished < m) {
        match step(&mut centre, opts, &renewer, &mut contexts, stop) {
            Ok(Step::Idle) => {
                failures = 0;
                // An error here counts as work pending: the next claim meets it again.
                let empty = opts.idle_exit
                    && rediagnose::queue_counts(&mut centre, None, None)
                        .is_ok_and(|q| q.pending() == 0);
                if empty {
                    break;
                }
                sleep_unless(stop, opts.poll);
            }
            Ok(Step::Ran(end)) => {
                failures = 0;
                finished += 1;
                match end {
                    JobEnd::Done {
                        undiagnosable,
                        gap,
                        fit_s,
                    } => {
                        rep.done += 1;
                        rep.undiagnosable += u64::from(undiagnosable);
                        rep.gap_done += u64::from(gap);
                        rep.fit_s += fit_s;
                    }
                    JobEnd::Failed => rep.failed += 1,
                    JobEnd::Lost => rep.lost += 1,
                }
            }
            // The centre went away (a restart, the network): a job in hand is left to its
            // lease; reconnect with a backoff, and give up after a few minutes of failures.
            Err(e) => {
                failures += 1;
                if failures > MAX_FAILURES {
                    return Err(e);
                }
                let wait = RETRY_FIRST * 2u32.pow(failures.min(6) - 1);
                tracing::warn!(
                    failures,
                    "fleet centre: {} (retried in {} s)",
                    crate::fleet::error_chain(&e),
                    wait.as_secs()
                );
                sleep_unless(stop, wait);
                if let Ok(c) = Centre::connect(&opts.postgres_url, opts.timeout) {
                    centre = c;
                }
            }
        }
    }
    drop(renewer);
    rep.wall_s = t0.elapsed().as_secs_f64();
    rep.cpu_s = process_cpu_s();
    tracing::info!(?rep, "fleet worker ends");
    Ok(rep)
}

/// Consecutive failures at the centre a worker rides out (≈ 5 min with [`RETRY_FIRST`]
/// doubling to 32 s) before it ends with the error.
const MAX_FAILURES: u32 = 12;
const RETRY_FIRST: Duration = Duration::from_millis(500);

/// What one look at the queue did.
enum Step {
    /// No job claimable.
    Idle,
    Ran(JobEnd),
}

/// Claims one job and runs it.
fn step(
    centre: &mut Centre,
    opts: &FleetWorkerOptions,
    renewer: &Renewer,
    contexts: &mut Contexts,
    stop: &Cancel,
) -> Result<Step, FleetError> {
    let Some(job) = rediagnose::claim(centre, &opts.worker_id, opts.lease)? else {
        return Ok(Step::Idle);
    };
    tracing::info!(
        job = job.id,
        kind = job.kind.as_str(),
        unit = %job.unit_id,
        segment = job.segment_id,
        attempt = job.attempts,
        "job claimed"
    );
    let cancel = Cancel::new();
    renewer.watch(job.id, &cancel);
    let end = run_job(centre, opts, contexts, &job, &cancel, stop);
    renewer.unwatch();
    end.map(Step::Ran)
}

fn sleep_unless(stop: &Cancel, d: Duration) {
    let until = Instant::now() + d;
    while !stop.is_cancelled() && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(50).min(d));
    }
}

/// Sets a fit's cancel flag when the worker's stop is set, from a thread of its own, until
/// dropped.
struct StopWatcher {
    done: Cancel,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl StopWatcher {
    fn start(stop: &Cancel, fit_cancel: &Cancel) -> StopWatcher {
        let (stop, fit_cancel) = (stop.clone(), fit_cancel.clone());
        let done = Cancel::new();
        let d = done.clone();
        let thread = std::thread::spawn(move || {
            while !d.is_cancelled() && !fit_cancel.is_cancelled() {
                if stop.is_cancelled() {
                    fit_cancel.cancel();
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        });
        StopWatcher {
            done,
            thread: Some(thread),
        }
    }
}

impl Drop for StopWatcher {
    fn drop(&mut self) {
        self.done.cancel();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A claimed job, read and about to run: what [`diagnose_job`] and [`gap_job`] share.
struct Claimed<'a> {
    job: &'a Job,
    ctx: &'a WorkerContext,
    window: &'a SegmentRecording,
    /// Set on a lost lease or on the worker's own stop.
    cancel: &'a Cancel,
    threads: usize,
    worker: &'a str,
    /// When the job was claimed (its wall time is stored with the result).
    began: Instant,
}

/// Marks the job failed with `why`; `Lost` if its lease was gone.
fn fail_job(centre: &mut Centre, job: &Job, worker: &str, why: &str) -> Result<JobEnd, FleetError> {
    tracing::warn!(job = job.id, "job failed: {why}");
    Ok(if rediagnose::fail(centre, job.id, worker, why)? {
        JobEnd::Failed
    } else {
        JobEnd::Lost
    })
}

/// After a fit stopped by `cancel`: the job is given back at once when the worker stops.
fn stopped(centre: &mut Centre, c: &Claimed<'_>, stop: &Cancel) -> JobEnd {
    if stop.is_cancelled() {
        // Stopping: give the job back now rather than when the lease runs out.
        let _ = rediagnose::release(centre, c.job.id, c.worker);
    }
    tracing::warn!(
        job = c.job.id,
        "fit stopped (lease lost or shutdown): nothing stored"
    );
    JobEnd::Lost
}

/// One claimed job: context, window, then its diagnosis or gap analysis.
fn run_job(
    centre: &mut Centre,
    opts: &FleetWorkerOptions,
    contexts: &mut Contexts,
    job: &Job,
    cancel: &Cancel,
    stop: &Cancel,
) -> Result<JobEnd, FleetError> {
    let began = Instant::now();
    let ctx = match context_for(contexts, job) {
        Ok(c) => c,
        Err(why) => return fail_job(centre, job, &opts.worker_id, &why),
    };
    let window = match rediagnose::read_window(centre, &job.unit_id, job.segment_id) {
        Ok(r) => r,
        Err(e @ FleetError::Data { .. }) => {
            return fail_job(centre, job, &opts.worker_id, &e.to_string())
        }
        Err(e) => return Err(e),
    };
    let claimed = Claimed {
        job,
        ctx: &ctx,
        window: &window,
        cancel,
        threads: opts.threads,
        worker: &opts.worker_id,
        began,
    };
    match job.kind {
        JobKind::Diagnose => diagnose_job(centre, &claimed, stop),
        JobKind::Gap => gap_job(centre, &claimed, stop),
    }
}

/// The edge's diagnosis of the window, stored if the lease is still held.
fn diagnose_job(centre: &mut Centre, c: &Claimed<'_>, stop: &Cancel) -> Result<JobEnd, FleetError> {
    let job = c.job;
    let t_fit = Instant::now();
    let assessment = {
        let _watch = StopWatcher::start(stop, c.cancel);
        assess_segment_on(c.ctx, c.window, c.cancel, c.threads)
    };
    let fit_s = t_fit.elapsed().as_secs_f64();
    if matches!(assessment, Assessment::Cancelled) || c.cancel.is_cancelled() {
        return Ok(stopped(centre, c, stop));
    }
    let estimates = new_diagnoses(c.ctx, job.segment_id, &assessment);
    let undiagnosable = estimates.is_empty();
    let result = JobResult {
        outcome: if undiagnosable {
            "undiagnosable"
        } else {
            "diagnosed"
        }
        .to_string(),
        estimates,
        failures_json: rediagnose::failures_json(failures(&assessment)),
        wall_s: c.began.elapsed().as_secs_f64(),
    };
    if rediagnose::complete(centre, job, c.worker, &result)? {
        tracing::info!(
            job = job.id,
            unit = %job.unit_id,
            segment = job.segment_id,
            outcome = %result.outcome,
            fit_s,
            "job done"
        );
        Ok(JobEnd::Done {
            undiagnosable,
            gap: false,
            fit_s,
        })
    } else {
        tracing::warn!(
            job = job.id,
            "lease lost before the result was stored: nothing stored"
        );
        Ok(JobEnd::Lost)
    }
}

/// The edge's gap analysis of the window (the daemon's: no held-out start-up, every
/// candidate), stored if the lease is still held. A window the recording's checks refuse, or
/// an analysis that fails, marks the job failed, as the daemon skips such a start-up.
fn gap_job(centre: &mut Centre, c: &Claimed<'_>, stop: &Cancel) -> Result<JobEnd, FleetError> {
    let job = c.job;
    let rec = match &c.window.recording {
        Ok(r) => r,
        Err(e) => {
            let why = format!("the segment cannot be analysed: {e}");
            return fail_job(centre, job, c.worker, &why);
        }
    };
    let t_fit = Instant::now();
    let analysed = {
        let _watch = StopWatcher::start(stop, c.cancel);
        super::gap::analyse_startup(c.ctx, job.segment_id, rec, c.cancel, c.threads)
    };
    let fit_s = t_fit.elapsed().as_secs_f64();
    let gap = match analysed {
        Ok(Some(g)) if !c.cancel.is_cancelled() => g,
        Ok(_) => return Ok(stopped(centre, c, stop)),
        Err(why) if c.cancel.is_cancelled() => {
            tracing::debug!(job = job.id, "analysis failed while cancelled: {why}");
            return Ok(stopped(centre, c, stop));
        }
        Err(why) => return fail_job(centre, job, c.worker, &why),
    };
    let result = GapJobResult {
        analysis: gap.row,
        wall_s: c.began.elapsed().as_secs_f64(),
    };
    if regap::complete_gap(centre, job, c.worker, &result)? {
        tracing::info!(
            job = job.id,
            unit = %job.unit_id,
            segment = job.segment_id,
            effect = %result.analysis.effect,
            fit_s,
            "gap job done"
        );
        Ok(JobEnd::Done {
            undiagnosable: false,
            gap: true,
            fit_s,
        })
    } else {
        tracing::warn!(
            job = job.id,
            "lease lost before the analysis was stored: nothing stored"
        );
        Ok(JobEnd::Lost)
    }
}
