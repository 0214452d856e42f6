//! The diagnosis worker: every closed start-up segment in the database gets Method B on the
//! segment and Method A on its steady windows, or a recorded reason why not.
//!
//! The queue is the database (`Store::pending_segments`: closed segments without a result or
//! reason), so a restarted daemon picks up what was pending. One segment at a time (bounded
//! concurrency 1); the fit itself runs on its own rayon pool of `[diagnosis] threads`, called
//! from tokio's blocking pool, never on the async runtime. The optimiser's cancel flag is tied
//! to the shutdown value: a cancelled fit stores nothing, and the segment stays pending. Each
//! segment's outcome is written in one transaction (all or nothing on kill -9).
//!
//! Hook for trends / wash advice: [`AfterResult`] is called after each stored outcome (see
//! [`DiagnosisTask::with_after_result`] and [`drain_pending`]).
//! Must not talk to Modbus, detect segments or hold fitting arithmetic of its own.

use crate::config_problem::ConfigProblem;
use crate::diagnosis::steady::diagnose_steady;
use crate::diagnosis::transient::diagnose_transient;
use crate::diagnosis::{DiagnosisConfig, MethodResult};
use crate::engine::Engine;
use crate::health::{HealthBounds, HEALTH_BOUNDS, HEALTH_NAMES};
use crate::optim::Cancel;
use crate::shutdown::Shutdown;
use crate::signals::Signal;
use crate::store::{NewDiagnosis, Store, StoreError, StoreOptions, Undiagnosable};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;

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
    /// Threads of one fit. Default 1 (the daemon's 2 cores also poll and write).
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
        }
    }
}

impl DiagnosisSettings {
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
            health_bounds: HealthBounds::all(self.health_bounds[0], self.health_bounds[1]),
            ..DiagnosisConfig::default()
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
        let cfg = crate::engine::EngineConfig::from_toml_str(&text, &shown)?;
        let engine = Engine::new(cfg).map_err(|e| anyhow::anyhow!("engine: {e}"))?;
        let fit = serde_json::to_string(&settings.fit_config(&Cancel::new()))?;
        let config_hash = format!("{:016x}", fnv1a(&[text.as_bytes(), fit.as_bytes()]));
        Ok(WorkerContext {
            engine,
            settings,
            config_hash,
        })
    }
}

/// 64-bit FNV-1a over the parts (with a separator byte between them).
pub fn fnv1a(parts: &[&[u8]]) -> u64 {
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

/// Signals a start-up must have for either method.
const REQUIRED: [Signal; 4] = [Signal::N1, Signal::FuelFlow, Signal::Power, Signal::T1];

/// Called after each stored outcome (segment id, outcome), on the worker's blocking thread,
/// with the worker's writable store: the place to recompute trends, detected washes and advice.
pub type AfterResult = Arc<dyn Fn(&mut Store, i64, &SegmentOutcome) + Send + Sync>;

fn failure(method: Option<&str>, reason: &str, detail: impl Into<String>) -> Undiagnosable {
    Undiagnosable {
        method: method.map(str::to_string),
        reason: reason.into(),
        detail: detail.into(),
    }
}

/// Residual level of a result: the objective per signal (mean |residual| in noise σ).
pub fn residual_level(r: &MethodResult) -> f64 {
    r.objective / r.signals.len().max(1) as f64
}

/// Diagnoses one stored segment (both methods) and stores the outcome. With `store_result`
/// false (`gtwatch diagnose --segment`) nothing is written and the results are returned.
pub fn diagnose_segment(
    store: &mut Store,
    ctx: &WorkerContext,
    segment_id: i64,
    cancel: &Cancel,
    store_result: bool,
) -> Result<(SegmentOutcome, Vec<NewDiagnosis>), StoreError> {
    let Some(rec) = store.segment_recording(segment_id)? else {
        return Err(StoreError::Corrupt(format!("no segment {segment_id}")));
    };
    let mut failures = Vec::new();
    if rec.segment.outcome != "completed" {
        failures.push(failure(
            None,
            "aborted",
            format!(
                "start-up {} ({})",
                rec.segment.outcome,
                rec.segment.abort_cause.as_deref().unwrap_or("no cause")
            ),
        ));
    } else if rec.segment.has_gap {
        failures.push(failure(None, "gaps", "data gap inside the start-up"));
    } else {
        let missing: Vec<&str> = rec
            .missing
            .iter()
            .filter(|s| REQUIRED.contains(s))
            .map(|s| s.column())
            .collect();
        let quality: Vec<(Signal, u64, u64)> = rec
            .quality
            .iter()
            .filter(|q| REQUIRED.contains(&q.signal))
            .map(|q| (q.signal, q.good, q.total))
            .collect();
        if !missing.is_empty() {
            failures.push(failure(
                None,
                "missing_signals",
                format!("no good samples of {}", missing.join(", ")),
            ));
        } else if let Some(why) =
            crate::quality::insufficient_quality(&quality, ctx.settings.min_good_fraction)
        {
            failures.push(failure(None, "low_quality", why));
        } else {
            match &rec.recording {
                Err(e) => failures.push(failure(None, "bad_recording", e.to_string())),
                Ok(r) if r.len() < 20 => {
                    failures.push(failure(None, "too_short", format!("{} samples", r.len())))
                }
                Ok(_) => {}
            }
        }
    }
    let recording = match (&rec.recording, failures.is_empty()) {
        (Ok(r), true) => r,
        _ => {
            if store_result {
                store.insert_outcome(segment_id, &[], &failures, &ctx.config_hash)?;
            }
            return Ok((SegmentOutcome::Undiagnosable(failures), Vec::new()));
        }
    };
    let cfg = ctx.settings.fit_config(cancel);
    let mut results = Vec::new();
    for (name, r) in [
        ("B", diagnose_transient(&ctx.engine, recording, &cfg)),
        ("A", diagnose_steady(&ctx.engine, recording, &cfg)),
    ] {
        if cancel.is_cancelled() {
            return Ok((SegmentOutcome::Cancelled, Vec::new()));
        }
        match r {
            Ok(r) => {
                let level = residual_level(&r);
                if level.is_nan() || level > ctx.settings.max_residual_level {
                    failures.push(failure(
                        Some(name),
                        "residual_too_high",
                        format!(
                            "residual level {level:.2} σ > {:.2} σ",
                            ctx.settings.max_residual_level
                        ),
                    ));
                    continue;
                }
                let sigma = HEALTH_NAMES.map(|n| r.sigma.get(n).copied().unwrap_or(f64::NAN));
                results.push(NewDiagnosis {
                    segment_id,
                    method: name.into(),
                    health: r.health.to_array(),
                    sigma,
                    objective: r.objective,
                    residual_level: level,
                    fit_quality: r.fit_quality.verdict.as_str().into(),
                    model_runs: r.model_runs,
                    wall_s: r.wall_s,
                    seed: ctx.settings.seed,
                    config_hash: ctx.config_hash.clone(),
                    gtwatch_version: env!("CARGO_PKG_VERSION").into(),
                });
            }
            Err(e) => failures.push(failure(Some(name), "error", e.to_string())),
        }
    }
    let outcome = if results.is_empty() {
        if store_result {
            store.insert_outcome(segment_id, &[], &failures, &ctx.config_hash)?;
        }
        SegmentOutcome::Undiagnosable(failures)
    } else {
        let ids = if store_result {
            store.insert_outcome(segment_id, &results, &failures, &ctx.config_hash)?
        } else {
            Vec::new()
        };
        SegmentOutcome::Diagnosed { ids, failures }
    };
    Ok((outcome, results))
}

/// What a drain did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct DrainReport {
    pub diagnosed: u64,
    pub undiagnosable: u64,
    pub cancelled: bool,
}

/// Diagnoses every pending segment, oldest first, until the queue is empty or `cancel` is set.
pub fn drain_pending(
    store: &mut Store,
    ctx: &WorkerContext,
    cancel: &Cancel,
    after: Option<&AfterResult>,
) -> Result<DrainReport, StoreError> {
    let mut rep = DrainReport::default();
    loop {
        if cancel.is_cancelled() {
            rep.cancelled = true;
            return Ok(rep);
        }
        let Some(seg) = store.pending_segments()?.into_iter().next() else {
            return Ok(rep);
        };
        tracing::info!(segment = seg.id, "diagnosing start-up");
        let (outcome, _) = diagnose_segment(store, ctx, seg.id, cancel, true)?;
        match &outcome {
            SegmentOutcome::Diagnosed { ids, failures } => {
                rep.diagnosed += 1;
                tracing::info!(
                    segment = seg.id,
                    results = ids.len(),
                    failed_methods = failures.len(),
                    "start-up diagnosed"
                );
            }
            SegmentOutcome::Undiagnosable(f) => {
                rep.undiagnosable += 1;
                let reasons: Vec<&str> = f.iter().map(|x| x.reason.as_str()).collect();
                tracing::info!(segment = seg.id, reasons = ?reasons, "start-up not diagnosable");
            }
            SegmentOutcome::Cancelled => {
                rep.cancelled = true;
                return Ok(rep);
            }
        }
        // Hook point: trends, detected washes and advice are recomputed here.
        if let Some(f) = after {
            f(store, seg.id, &outcome);
        }
    }
}

/// The diagnosis task of the daemon (mini-redis shape: a small struct with its own `run`).
pub struct DiagnosisTask {
    pub db_path: PathBuf,
    pub store_opts: StoreOptions,
    pub ctx: Arc<WorkerContext>,
    /// The detector wakes the worker through this when a segment closes.
    pub wake: Arc<Notify>,
    pub after_result: Option<AfterResult>,
}

impl DiagnosisTask {
    pub fn with_after_result(mut self, f: AfterResult) -> Self {
        self.after_result = Some(f);
        self
    }

    /// Drains the queue now, then whenever woken (or every `poll_interval_ms`), until shutdown.
    /// Shutdown cancels a running fit; the segment stays pending for the next start.
    pub async fn run(self, shutdown: Shutdown) -> DrainReport {
        let cancel = Cancel::new();
        {
            let mut sd = shutdown.clone();
            let c = cancel.clone();
            tokio::spawn(async move {
                sd.wait().await;
                c.cancel();
            });
        }
        let mut total = DrainReport::default();
        let mut store: Option<Store> = None;
        let mut sd = shutdown;
        let period = Duration::from_millis(self.ctx.settings.poll_interval_ms.max(100));
        loop {
            if sd.is_triggered() {
                break;
            }
            let path = self.db_path.clone();
            let opts = self.store_opts;
            let ctx = Arc::clone(&self.ctx);
            let c = cancel.clone();
            let after = self.after_result.clone();
            let s = store.take();
            let r = tokio::task::spawn_blocking(move || {
                let mut st = match s {
                    Some(s) => s,
                    None => match Store::open_with(&path, &opts) {
                        Ok(s) => s,
                        Err(e) => return (None, Err(e)),
                    },
                };
                let r = drain_pending(&mut st, &ctx, &c, after.as_ref());
                (Some(st), r)
            })
            .await;
            match r {
                Ok((s, Ok(rep))) => {
                    store = s;
                    total.diagnosed += rep.diagnosed;
                    total.undiagnosable += rep.undiagnosable;
                    total.cancelled |= rep.cancelled;
                }
                Ok((s, Err(e))) => {
                    store = s;
                    tracing::warn!("diagnosis worker: {e}");
                }
                Err(e) => tracing::error!("diagnosis worker task failed: {e}"),
            }
            tokio::select! {
                _ = sd.wait() => break,
                _ = self.wake.notified() => {}
                _ = tokio::time::sleep(period) => {}
            }
        }
        total
    }
}

#[cfg(test)]
mod tests;
