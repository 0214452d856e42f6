//! The diagnosis worker: every closed start-up segment in the database gets Method B on the
//! segment and Method A on its steady windows, or a recorded reason why not.
//!
//! The queue is the database (`Store::pending_segments`: closed segments without a result or
//! reason), so a restarted daemon picks up what was pending. `[diagnosis] threads` is how many
//! cores a drain uses: with a backlog (a replay of months of logs, a daemon that was down) up
//! to that many start-ups are fitted at once, each on its own scoped thread and one core; a
//! start-up alone in the queue gets all of them for its fit (one fit's threads wait for each
//! other at every generation, and its serial parts leave the other cores idle; independent fits
//! never wait for each other). The results do not depend on this: a fit is a
//! pure function of its data, settings and seed, whatever its thread count, and outcomes are
//! stored in queue order, so the rows are those of one-at-a-time diagnosis. The drain runs on
//! tokio's blocking pool in the daemon, never on the async runtime. The optimiser's cancel
//! flag is tied to the shutdown value: a cancelled fit stores nothing, and the segment (and any
//! after it) stays pending. Each segment's outcome is written as one request ([`NewOutcome`],
//! one transaction: all or nothing on kill -9) through a [`Db`], from the drain's own thread
//! only (the fit threads never touch the database): in the daemon that reads through the
//! worker's read-only connection and writes through the one writer.
//!
//! What is diagnosable and the fits themselves are [`crate::diagnosis::assess`] (pure); this
//! module reads a segment, calls it and stores the outcome ([`diagnose_segment`]).
//!
//! Hook for trends / wash advice: [`AfterResult`] is called after each stored outcome (see
//! [`drain_pending`]). The daemon's task that runs the drain is `daemon::diagnosis`.
//! Must not talk to Modbus, detect segments or hold fitting arithmetic of its own.

use crate::config_problem::ConfigProblem;
use crate::diagnosis::assess::{assess, AssessSettings, Assessment, SegmentData};
use crate::diagnosis::DiagnosisConfig;
use crate::engine::Engine;
use crate::health::{HealthBounds, HEALTH_BOUNDS, HEALTH_NAMES};
use crate::optim::Cancel;
use crate::store::{
    Db, NewDiagnosis, NewOutcome, SegmentRecording, Store, StoreError, Undiagnosable,
};

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Serialised settings leave the default health bounds out, so the configuration hash of
/// results stored before the key existed stays the same.
fn is_default_bounds(b: &[f64; 2]) -> bool {
    *b == [HEALTH_BOUNDS.0, HEALTH_BOUNDS.1]
}

/// `[diagnosis]` section: the worker's settings.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct DiagnosisSettings {
    /// Diagnose closed start-ups in `gtwatch run` and `gtwatch replay`. Default true.
    pub enabled: bool,
    /// Cores the diagnosis uses: start-ups of a backlog fitted at once (one core each), or the
    /// threads of a lone start-up's fit. Results do not depend on it. Default 1 (the daemon's
    /// 2 cores also poll and write); a replay of a long log gains from idle cores.
    pub threads: usize,
    /// Seed of the global optimiser. Default 1.
    pub seed: u64,
    /// Model runs per method (global + LM). Default 400.
    pub max_model_runs: usize,
    /// A fit whose residual level (objective per signal, mean |residual| in noise σ; ≈ 0.8 at
    /// pure noise) is above this is stored as undiagnosable. Default 5.
    pub max_residual_level: f64,
    /// Normalised residual (residual sum of squares per compared sample, in noise units; ≈ 0.7
    /// for a model that fits) up to which the stored `fit_quality` is "good"; above it
    /// "suspect", and above the larger of 2.5 and this "poor" (`diagnosis::fit_quality`).
    /// Default 0.9.
    pub good_residual_level: f64,
    /// Look for pending segments at least this often even without a wake-up, ms. Default 60 000.
    pub poll_interval_ms: u64,
    /// Data-quality threshold: each required signal (n1, fuel flow, power, T1) needs at least
    /// this fraction of good samples (quality 0) among all its samples in the segment, else
    /// the segment is stored undiagnosable (`low_quality`). Default 0.9.
    pub min_good_fraction: f64,
    /// Search interval of every health parameter, `[lower, upper]` percent. Default −3 … +10
    /// (REFERENCE §3); widen it for a unit far from new. An estimate that ends on a limit is
    /// stored with `fit_quality` at least "suspect" and named in the result.
    #[serde(skip_serializing_if = "is_default_bounds")]
    pub health_bounds: [f64; 2],
    /// 1σ of a prior on each fitted health parameter about new, points, in Method A
    /// (`diagnosis::prior`); 0: least squares on the data alone. Default 0.
    #[serde(skip_serializing_if = "crate::diagnosis::config::is_no_prior")]
    pub health_prior_pts: f64,
    /// The same for Method B. Default 1.
    #[serde(skip_serializing_if = "crate::diagnosis::config::is_no_prior")]
    pub transient_health_prior_pts: f64,
    /// `gtwatch run` analyses the model–plant gap (`gtwatch gap`) of every start-up whose
    /// Method B fit is not `good`, in the background once the diagnosis queue is empty, and
    /// stores it for the report; not one that carries on an analysed misfit
    /// (`worker::gap::covered_poor_fits`). Default true.
    pub gap_on_poor_fit: bool,
    /// Also analyse a start-up whose Method B health steps away from the unit's own trend
    /// since the last wash (`trend::steps_against_trend`): an input instrument that changed is
    /// more likely than the engine. Default true.
    pub gap_on_health_step: bool,
    /// Also analyse every n-th start-up that has a Method B result (a schedule; 0 = none).
    /// Default 0.
    pub gap_every_n: u32,
}

impl Default for DiagnosisSettings {
    fn default() -> Self {
        DiagnosisSettings {
            enabled: true,
            threads: 1,
            seed: 1,
            max_model_runs: 400,
            max_residual_level: 5.0,
            good_residual_level: 0.9,
            poll_interval_ms: 60_000,
            min_good_fraction: 0.9,
            health_bounds: [HEALTH_BOUNDS.0, HEALTH_BOUNDS.1],
            health_prior_pts: crate::diagnosis::prior::DEFAULT_HEALTH_PRIOR_PTS,
            transient_health_prior_pts: crate::diagnosis::prior::DEFAULT_TRANSIENT_HEALTH_PRIOR_PTS,
            gap_on_poor_fit: true,
            gap_on_health_step: true,
            gap_every_n: 0,
        }
    }
}

impl DiagnosisSettings {
    /// The health search limits, as every parameter's interval.
    pub fn bounds(&self) -> HealthBounds {
        HealthBounds::all(self.health_bounds[0], self.health_bounds[1])
    }

    /// Problems with this section; keys are prefixed `diagnosis.`.
    pub fn validate(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        if self.threads == 0 || self.threads > 256 {
            p.push(ConfigProblem::new(
                "diagnosis.threads",
                "must be between 1 and 256",
            ));
        }
        if self.max_model_runs < 20 {
            p.push(ConfigProblem::new(
                "diagnosis.max_model_runs",
                "must be at least 20",
            ));
        }
        if !(self.good_residual_level.is_finite() && self.good_residual_level > 0.0) {
            p.push(ConfigProblem::new(
                "diagnosis.good_residual_level",
                "must be a number > 0",
            ));
        }
        if !(self.max_residual_level.is_finite() && self.max_residual_level > 0.0) {
            p.push(ConfigProblem::new(
                "diagnosis.max_residual_level",
                "must be a number > 0",
            ));
        }
        if !(self.min_good_fraction.is_finite() && (0.0..=1.0).contains(&self.min_good_fraction)) {
            p.push(ConfigProblem::new(
                "diagnosis.min_good_fraction",
                "must be a number between 0 and 1",
            ));
        }
        let [lo, hi] = self.health_bounds;
        if let Err(e) = HealthBounds::all(lo, hi).check() {
            let why = e
                .split_once(": ")
                .map_or(e.as_str(), |(_, w)| w)
                .to_string();
            p.push(ConfigProblem::new("diagnosis.health_bounds", why));
        }
        for (key, v) in [
            ("diagnosis.health_prior_pts", self.health_prior_pts),
            (
                "diagnosis.transient_health_prior_pts",
                self.transient_health_prior_pts,
            ),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                p.push(ConfigProblem::new(
                    key,
                    "must be a number of points ≥ 0 (0: no prior)",
                ));
            }
        }
        if self.poll_interval_ms < 100 {
            p.push(ConfigProblem::new(
                "diagnosis.poll_interval_ms",
                "must be at least 100 ms",
            ));
        }
        p
    }

    /// The fit settings (defaults of `gtwatch diagnose` but for seed, runs and threads).
    pub fn fit_config(&self, cancel: &Cancel) -> DiagnosisConfig {
        DiagnosisConfig {
            seed: self.seed,
            max_model_runs: self.max_model_runs,
            threads: Some(self.threads.max(1)),
            cancel: cancel.clone(),
            quality: crate::diagnosis::fit_quality::Thresholds {
                good_level: self.good_residual_level,
                poor_level: self.good_residual_level.max(2.5),
                ..Default::default()
            },
            health_bounds: self.bounds(),
            health_prior_pts: self.health_prior_pts,
            transient_health_prior_pts: self.transient_health_prior_pts,
            ..DiagnosisConfig::default()
        }
    }

    /// The settings of [`assess`]: the fit (its cancel flag set by `assess`) and the two
    /// thresholds that decide what is diagnosable.
    pub fn assess_settings(&self) -> AssessSettings {
        AssessSettings {
            fit: self.fit_config(&Cancel::new()),
            min_good_fraction: self.min_good_fraction,
            max_residual_level: self.max_residual_level,
        }
    }
}

/// The engine and what identifies it, shared by every diagnosis of a run.
#[derive(Debug)]
pub struct WorkerContext {
    pub engine: Engine,
    pub settings: DiagnosisSettings,
    /// FNV-1a of the engine file's text and the fit settings: equal hash = same result.
    pub config_hash: String,
    /// The engine file's text with its map files written into it (what the hash covers; a
    /// fleet re-diagnosis job carries it, so a worker anywhere needs no other file).
    pub engine_text: String,
}

impl WorkerContext {
    /// `engine_file`: the `[plant] engine_model` file, `None` for the built-in engine.
    pub fn load(
        engine_file: Option<&std::path::Path>,
        settings: DiagnosisSettings,
    ) -> anyhow::Result<WorkerContext> {
        use anyhow::Context;
        let text = match engine_file {
            Some(p) => std::fs::read_to_string(p)
                .with_context(|| format!("reading engine file {}", p.display()))?,
            None => crate::engine::config::REFERENCE_ENGINE_TOML.to_string(),
        };
        let shown = engine_file.map_or("<built-in reference engine>".to_string(), |p| {
            p.display().to_string()
        });
        // Map files named relative to the engine file are read from beside it, as every other
        // command reads them (the daemon runs from /, a replay from anywhere).
        let dir = engine_file.and_then(|p| p.parent());
        WorkerContext::build(text, &shown, dir, settings)
    }

    /// From an engine file's text (`shown` names it in messages): what a fleet re-diagnosis
    /// job carries, so a worker anywhere computes the same engine, settings and hash.
    pub fn from_text(
        text: String,
        shown: &str,
        settings: DiagnosisSettings,
    ) -> anyhow::Result<WorkerContext> {
        WorkerContext::build(text, shown, None, settings)
    }

    /// The engine of `text` with its map files written into it (relative paths read from
    /// `dir` when given).
    fn build(
        text: String,
        shown: &str,
        dir: Option<&std::path::Path>,
        settings: DiagnosisSettings,
    ) -> anyhow::Result<WorkerContext> {
        // The map files are written into the text, so the text is the whole engine: the hash
        // changes with a map's contents, and a fleet job carrying the text needs no file.
        let text = crate::engine::config::inline_map_files(&text, dir)
            .map_err(|e| anyhow::anyhow!("engine {shown}: {e}"))?;
        let cfg = crate::engine::EngineConfig::from_toml_str(&text, shown)?;
        let engine = Engine::new(cfg).map_err(|e| anyhow::anyhow!("engine: {e}"))?;
        let fit = serde_json::to_string(&settings.fit_config(&Cancel::new()))?;
        let config_hash = format!("{:016x}", fnv1a(&[text.as_bytes(), fit.as_bytes()]));
        Ok(WorkerContext {
            engine,
            settings,
            config_hash,
            engine_text: text,
        })
    }
}

/// 64-bit FNV-1a over the parts (with a separator byte between them).
pub(crate) fn fnv1a(parts: &[&[u8]]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in parts {
        for b in p.iter().chain(std::iter::once(&0xffu8)) {
            h ^= u64::from(*b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

/// What happened to one segment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum SegmentOutcome {
    /// Results stored (ids of the `diagnoses` rows), plus reasons for a method that failed.
    Diagnosed {
        ids: Vec<i64>,
        failures: Vec<Undiagnosable>,
    },
    /// Nothing diagnosable; the reasons are stored.
    Undiagnosable(Vec<Undiagnosable>),
    /// Shutdown cancelled the fit: nothing stored, the segment stays pending.
    Cancelled,
}

/// Called after each stored outcome (segment id, outcome, that start-up's own wall time:
/// reading its data, both fits and storing, not the time it waited for an earlier start-up's
/// turn), in queue order, on the drain's thread with the worker's [`Db`]: the place to
/// recompute trends, detected washes and advice.
pub(crate) type AfterResult =
    Arc<dyn Fn(&mut dyn Db, i64, &SegmentOutcome, Duration) + Send + Sync>;

/// Reads one stored segment's data for [`assess`] (an error if there is no such segment).
/// Takes `&Store`, so a [`crate::store::ReadStore`] serves as well.
pub(crate) fn read_segment(store: &Store, segment_id: i64) -> Result<SegmentRecording, StoreError> {
    store
        .segment_recording(segment_id)?
        .ok_or_else(|| StoreError::Corrupt(format!("no segment {segment_id}")))
}

/// The assessment's view of a segment read from the store.
pub(crate) fn segment_data(rec: &SegmentRecording) -> SegmentData<'_> {
    SegmentData {
        outcome: &rec.segment.outcome,
        abort_cause: rec.segment.abort_cause.as_deref(),
        has_gap: rec.segment.has_gap,
        recording: &rec.recording,
        missing: &rec.missing,
        quality: &rec.quality,
    }
}

/// Assesses a segment already read, with the context's engine and settings. No I/O.
pub(crate) fn assess_segment(
    ctx: &WorkerContext,
    rec: &SegmentRecording,
    cancel: &Cancel,
) -> Assessment {
    assess_segment_on(ctx, rec, cancel, ctx.settings.threads)
}

/// [`assess_segment`] with each fit on `threads` threads. The result does not depend on them.
pub(crate) fn assess_segment_on(
    ctx: &WorkerContext,
    rec: &SegmentRecording,
    cancel: &Cancel,
    threads: usize,
) -> Assessment {
    let mut settings = ctx.settings.assess_settings();
    settings.fit.threads = Some(threads.max(1));
    assess(&segment_data(rec), &ctx.engine, &settings, cancel)
}

/// The `diagnoses` rows of an assessment (none unless it diagnosed the segment).
pub(crate) fn new_diagnoses(
    ctx: &WorkerContext,
    segment_id: i64,
    assessment: &Assessment,
) -> Vec<NewDiagnosis> {
    let Assessment::Diagnosed { estimates, .. } = assessment else {
        return Vec::new();
    };
    estimates
        .iter()
        .map(|e| NewDiagnosis {
            segment_id,
            method: e.method.into(),
            health: e.result.health.to_array(),
            sigma: HEALTH_NAMES.map(|n| e.result.sigma.get(n).copied().unwrap_or(f64::NAN)),
            objective: e.result.objective,
            residual_level: e.residual_level,
            fit_quality: e.result.fit_quality.verdict.as_str().into(),
            model_runs: e.result.model_runs,
            wall_s: e.result.wall_s,
            seed: ctx.settings.seed,
            config_hash: ctx.config_hash.clone(),
            gtwatch_version: env!("CARGO_PKG_VERSION").into(),
        })
        .collect()
}

/// The reasons an assessment found for what gave no result.
pub(crate) fn failures(assessment: &Assessment) -> &[Undiagnosable] {
    match assessment {
        Assessment::Diagnosed { failures, .. } => failures,
        Assessment::Undiagnosable(f) => f,
        Assessment::Cancelled => &[],
    }
}

/// Stores an assessment's outcome in one transaction (results and reasons, segment marked
/// diagnosed); a cancelled assessment stores nothing and the segment stays pending.
pub(crate) fn store_assessment(
    db: &mut dyn Db,
    ctx: &WorkerContext,
    segment_id: i64,
    assessment: &Assessment,
) -> Result<SegmentOutcome, StoreError> {
    let failures = failures(assessment).to_vec();
    let outcome = |results| NewOutcome {
        segment_id,
        results,
        failures: failures.clone(),
        config_hash: ctx.config_hash.clone(),
    };
    Ok(match assessment {
        Assessment::Cancelled => SegmentOutcome::Cancelled,
        Assessment::Undiagnosable(_) => {
            db.write_outcome(outcome(Vec::new()))?;
            SegmentOutcome::Undiagnosable(failures)
        }
        Assessment::Diagnosed { .. } => {
            let rows = new_diagnoses(ctx, segment_id, assessment);
            let ids = db.write_outcome(outcome(rows))?;
            SegmentOutcome::Diagnosed { ids, failures }
        }
    })
}

/// The worker's step for one stored segment: read it, assess it, store the outcome.
pub(crate) fn diagnose_segment(
    db: &mut dyn Db,
    ctx: &WorkerContext,
    segment_id: i64,
    cancel: &Cancel,
) -> Result<SegmentOutcome, StoreError> {
    let rec = read_segment(db.read(), segment_id)?;
    let assessment = assess_segment(ctx, &rec, cancel);
    store_assessment(db, ctx, segment_id, &assessment)
}

/// What a drain did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct DrainReport {
    pub diagnosed: u64,
    pub undiagnosable: u64,
    pub cancelled: bool,
}

/// One start-up a drain handed to a fit thread, on its way back.
struct Finished {
    /// Place in the drain's order (the order the segments were taken from the queue).
    seq: u64,
    segment_id: i64,
    /// The assessment, or the panic of the thread that made it.
    assessment: std::thread::Result<Assessment>,
    /// Reading its data and fitting it.
    wall: Duration,
}

/// Sets a cancel flag when dropped: however a drain ends (done, store error, panic), no fit it
/// started keeps a core busy for a result nobody will store.
struct CancelOnDrop<'a>(&'a Cancel);

impl Drop for CancelOnDrop<'_> {
    fn drop(&mut self) {
        self.0.cancel();
    }
}

/// How often a drain waiting for its fits looks at the caller's cancel flag.
const CANCEL_POLL: Duration = Duration::from_millis(50);

/// Diagnoses every pending segment, oldest first, until the queue is empty or `cancel` is set.
///
/// Up to `[diagnosis] threads` segments are fitted at once, each on a scoped thread of its own
/// (not a rayon pool: a fit builds its own pool, and a rayon worker waiting on another pool
/// runs that pool's queued jobs, which nests fits on one core). A segment taken while others
/// wait gets one core; the last one waiting gets every core still free, so a lone start-up
/// (the daemon's everyday case) is fitted on all `threads` as before. A fit's result does not
/// depend on its thread count (`optim`: random numbers drawn before each parallel evaluation,
/// results collected in order), so this changes no stored number.
///
/// Everything touching `db` stays on the calling thread: reading each segment's data, and
/// storing each outcome (one transaction) followed by `after`, strictly in queue order, so the
/// rows, their ids and what the hook sees are those of one-at-a-time diagnosis. A cancelled
/// fit stores nothing, and nothing after it in the order is stored either: those segments stay
/// pending, as a one-at-a-time drain would have left them.
pub(crate) fn drain_pending(
    db: &mut dyn Db,
    ctx: &WorkerContext,
    cancel: &Cancel,
    after: Option<&AfterResult>,
) -> Result<DrainReport, StoreError> {
    // The fits' own flag: set from `cancel` by the waiting loop, and when the drain ends.
    let stop = Cancel::new();
    std::thread::scope(|scope| {
        let _stop_fits = CancelOnDrop(&stop);
        let (tx, rx) = std::sync::mpsc::channel::<Finished>();
        let mut d = Drain {
            ctx,
            cancel,
            stop: &stop,
            cores: ctx.settings.threads.max(1),
            in_flight: BTreeMap::new(),
            done: BTreeMap::new(),
            next_seq: 0,
            next_store: 0,
            stopped: false,
            rep: DrainReport::default(),
        };
        // Look at the queue at the start and whenever a fit came back (cores freed), not at
        // every cancel check: a start-up closing meanwhile waits for the next free core.
        let mut look = true;
        loop {
            if !d.stopped && cancel.is_cancelled() {
                d.stop();
            }
            if !d.stopped && look {
                d.dispatch(db, scope, &tx)?;
            }
            if d.in_flight.is_empty() {
                // Nothing running: the queue is empty, or the drain stopped and every fit it
                // started has come back.
                return Ok(d.rep);
            }
            match rx.recv_timeout(CANCEL_POLL) {
                Ok(f) => {
                    d.in_flight.remove(&f.seq);
                    d.done.insert(f.seq, f);
                    d.store_ready(db, after)?;
                    look = true;
                }
                // `tx` lives here, so the channel cannot disconnect; a timeout just re-checks
                // the cancel flag.
                Err(_) => look = false,
            }
        }
    })
}

/// The state of one [`drain_pending`].
struct Drain<'a> {
    ctx: &'a WorkerContext,
    cancel: &'a Cancel,
    stop: &'a Cancel,
    /// `[diagnosis] threads`: cores the fits of this drain may use together.
    cores: usize,
    /// seq → (segment id, cores its fit uses).
    in_flight: BTreeMap<u64, (i64, usize)>,
    /// Fits back but not yet stored (an earlier one is still running), by seq.
    done: BTreeMap<u64, Finished>,
    next_seq: u64,
    /// The seq whose outcome is stored next.
    next_store: u64,
    /// Cancelled: nothing more is started or stored.
    stopped: bool,
    rep: DrainReport,
}

impl<'a> Drain<'a> {
    fn stop(&mut self) {
        self.stopped = true;
        self.rep.cancelled = true;
        self.stop.cancel();
    }

    /// Starts fits of pending segments not yet taken while cores are free.
    fn dispatch<'scope>(
        &mut self,
        db: &mut dyn Db,
        scope: &'scope std::thread::Scope<'scope, '_>,
        tx: &std::sync::mpsc::Sender<Finished>,
    ) -> Result<(), StoreError>
    where
        'a: 'scope,
    {
        let mut used: usize = self.in_flight.values().map(|(_, n)| n).sum();
        if used >= self.cores {
            return Ok(());
        }
        let taken: std::collections::HashSet<i64> = self
            .in_flight
            .values()
            .map(|(id, _)| *id)
            .chain(self.done.values().map(|f| f.segment_id))
            .collect();
        let waiting: Vec<i64> = db
            .read()
            .pending_segments()?
            .into_iter()
            .map(|s| s.id)
            .filter(|id| !taken.contains(id))
            .collect();
        for (k, &segment_id) in waiting.iter().enumerate() {
            let free = self.cores - used;
            if free == 0 {
                break;
            }
            // One core each while more wait; the last one waiting takes what is left.
            let threads = if k + 1 == waiting.len() { free } else { 1 };
            let began = Instant::now();
            let rec = read_segment(db.read(), segment_id)?;
            tracing::info!(segment = segment_id, threads, "diagnosing start-up");
            let seq = self.next_seq;
            self.next_seq += 1;
            self.in_flight.insert(seq, (segment_id, threads));
            used += threads;
            let (ctx, stop, tx) = (self.ctx, self.stop, tx.clone());
            scope.spawn(move || {
                let assessment = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    assess_segment_on(ctx, &rec, stop, threads)
                }));
                // The receiver is gone only when the drain already ended (an error or a
                // panic): nobody wants this result then.
                let _ = tx.send(Finished {
                    seq,
                    segment_id,
                    assessment,
                    wall: began.elapsed(),
                });
            });
        }
        Ok(())
    }

    /// Stores the outcomes that are next in order, each followed by the hook.
    fn store_ready(
        &mut self,
        db: &mut dyn Db,
        after: Option<&AfterResult>,
    ) -> Result<(), StoreError> {
        while let Some(f) = self.done.remove(&self.next_store) {
            self.next_store += 1;
            // A shutdown stores nothing more, even a fit that finished before its flag
            // reached it (as `assess` reports a fit that ends after the flag as cancelled).
            if !self.stopped && self.cancel.is_cancelled() {
                self.stop();
            }
            if self.stopped {
                continue;
            }
            let assessment = match f.assessment {
                Ok(a) => a,
                Err(panic) => {
                    // As when the fit ran on the drain's own thread: the drain panics (the
                    // daemon logs it and drains again later); the other fits are stopped.
                    self.stop.cancel();
                    std::panic::resume_unwind(panic);
                }
            };
            let stored = Instant::now();
            let outcome = store_assessment(db, self.ctx, f.segment_id, &assessment)?;
            let wall = f.wall + stored.elapsed();
            let seg = f.segment_id;
            match &outcome {
                SegmentOutcome::Diagnosed { ids, failures } => {
                    self.rep.diagnosed += 1;
                    tracing::info!(
                        segment = seg,
                        results = ids.len(),
                        failed_methods = failures.len(),
                        wall_s = wall.as_secs_f64(),
                        "start-up diagnosed"
                    );
                }
                SegmentOutcome::Undiagnosable(u) => {
                    self.rep.undiagnosable += 1;
                    let reasons: Vec<&str> = u.iter().map(|x| x.reason.as_str()).collect();
                    tracing::info!(segment = seg, reasons = ?reasons, "start-up not diagnosable");
                }
                SegmentOutcome::Cancelled => {
                    self.stop();
                    continue;
                }
            }
            // Hook point: trends, detected washes and advice are recomputed here.
            if let Some(h) = after {
                h(db, seg, &outcome, wall);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;

pub mod fleet;
pub(crate) mod gap;
