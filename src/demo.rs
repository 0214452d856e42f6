//! `gtwatch demo`: the whole product on an embedded default, with nothing installed or
//! configured.
//!
//! A [`FoulingPlant`] (the engine model fouling day by day, one start-up a day, an offline wash
//! midway, noise and sensor lags on) is served over Modbus TCP on 127.0.0.1 by the plant
//! simulator in lock-step with the poller; the real daemon (`daemon::run`: acquisition, writer,
//! detector, diagnosis worker, trend and wash advice) polls it into a fresh SQLite file, taking
//! sample times from the plant's clock so a day passes in seconds of wall time while every
//! stored duration is the plant's own. When every day's start-up is diagnosed, the daemon is
//! stopped and a [`DemoReport`] compares each result with the implanted truth.
//!
//! This is an orchestration shell like the daemon: no physics here, and nothing outside the
//! output folder is written. The configuration it runs is written to `DIR/gtwatch.toml`, so the
//! usual commands (`history`, `wash advise`, `segments`) work on the result afterwards.

use crate::acquire::modbus::PollStats;
use crate::acquire::register_map::PLANT_TIME_FIELD;
use crate::config::Config;
use crate::daemon::{self, RunOptions};
use crate::engine::Engine;
use crate::health::{HealthParams, HEALTH_NAMES};
use crate::plantsim::fouling::{day_of, DAY_S};
use crate::plantsim::{spawn_plant_sim, FoulingPlant, FoulingSchedule, SimOptions};
use crate::query::list_segments;
use crate::shutdown::shutdown_channel;
use crate::store::{HistoryFilter, HistoryRow, RecommendationRow, Store, WashRow};
use crate::time::fmt_ms;
use crate::worker::WorkerContext;
use anyhow::{bail, Context};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The first line of the configuration the demo writes: marks a folder the demo may reuse.
const MARKER: &str = "# gtwatch demo configuration (written by `gtwatch demo`; safe to delete)";

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoOptions {
    /// Plant days, one start-up each (≥ 3 for the wash to fall inside).
    pub days: usize,
    /// Seed of the sensor noise (and the diagnosis).
    pub seed: u64,
    /// Output folder (database, configuration, report).
    pub out_dir: PathBuf,
    /// Plant seconds per wall second while the engine runs (each poll advances one 1 s frame).
    pub speedup: f64,
    /// Plant clock at the start of day 0, Unix ms.
    pub epoch_ms: i64,
    /// Give up (and report what there is) after this much wall time.
    pub timeout: Duration,
}

impl Default for DemoOptions {
    fn default() -> Self {
        DemoOptions {
            days: 10,
            seed: 1,
            out_dir: PathBuf::from("gtwatch-demo"),
            speedup: 500.0,
            // 2026-01-05T00:00:00Z: a fixed calendar, so runs with the same seed agree.
            epoch_ms: 1_767_571_200_000,
            timeout: Duration::from_secs(600),
        }
    }
}

impl DemoOptions {
    fn validate(&self) -> anyhow::Result<()> {
        if !(2..=365).contains(&self.days) {
            bail!("--days {} is outside 2 … 365", self.days);
        }
        if !(self.speedup.is_finite() && (1.0..=1000.0).contains(&self.speedup)) {
            bail!(
                "--speedup {} is outside 1 … 1000 (plant seconds per wall second)",
                self.speedup
            );
        }
        Ok(())
    }

    /// The poll period that gives `speedup` with one 1 s plant frame per poll.
    pub fn poll_period_ms(&self) -> u64 {
        (1000.0 / self.speedup).round().max(1.0) as u64
    }
}

/// One day of the demo: the truth and what gtwatch made of it.
#[derive(Debug, Clone, Serialize)]
pub struct DemoDay {
    pub day: usize,
    pub start_utc: String,
    /// Implanted health, percent.
    pub truth: HealthParams,
    /// Whether an offline wash preceded this day's start.
    pub washed_before: bool,
    pub segment_id: Option<i64>,
    pub outcome: Option<String>,
    /// Method B (transient) result.
    pub method_b: Option<HistoryRow>,
    /// Method A (steady-state) result.
    pub method_a: Option<HistoryRow>,
    /// Why the segment was not diagnosed, if it was not.
    pub undiagnosable: Vec<String>,
}

impl DemoDay {
    /// Largest |estimate − truth| over the six parameters of Method B, points.
    pub fn max_error_b(&self) -> Option<f64> {
        let b = self.method_b.as_ref()?;
        let truth = self.truth.to_array();
        HEALTH_NAMES
            .iter()
            .enumerate()
            .map(|(i, n)| b.health.get(*n).map(|v| (v - truth[i]).abs()))
            .try_fold(0.0f64, |m, e| e.map(|e| m.max(e)))
    }
}

/// What the demo did and found.
#[derive(Debug, Clone, Serialize)]
pub struct DemoReport {
    pub out_dir: PathBuf,
    pub db_path: PathBuf,
    pub config_path: PathBuf,
    pub days: Vec<DemoDay>,
    /// Day whose start-up was the first after the offline wash.
    pub wash_day: Option<usize>,
    /// Washes in the database (detected ones have a `detected:` note).
    pub washes: Vec<DemoWash>,
    pub advice: Option<DemoAdvice>,
    pub poll: PollStats,
    pub wall_s: f64,
    /// False if the timeout ended the run before every day was diagnosed.
    pub complete: bool,
    /// The HTML report written at the end.
    pub report_path: PathBuf,
}

/// A wash as stored, with the day it falls before.
#[derive(Debug, Clone, Serialize)]
pub struct DemoWash {
    pub t_utc: String,
    pub kind: String,
    pub detected: bool,
    /// The first day whose start-up comes after this wash.
    pub before_day: Option<usize>,
}

/// The stored wash advice.
#[derive(Debug, Clone, Serialize)]
pub struct DemoAdvice {
    pub kind: String,
    pub message: String,
}

/// Progress events, for the command line to show.
#[derive(Debug, Clone, PartialEq)]
pub enum DemoEvent {
    /// The plant reached this day (0-based).
    PlantDay(usize),
    /// A start-up was found on this day.
    Startup {
        day: usize,
        segment_id: i64,
        outcome: String,
    },
    /// Method B finished for this day.
    Diagnosed {
        day: usize,
        d_gc: f64,
        truth_gc: f64,
        fit_quality: String,
    },
}

/// The configuration text the demo runs: the shipped reference configuration with the plant
/// endpoint, the database, the poll period, the plant clock and a faster detector cadence.
pub fn demo_config_text(endpoint: &str, poll_period_ms: u64) -> anyhow::Result<String> {
    let shipped = include_str!("../config/gtwatch.toml");
    let mut text = format!("{MARKER}\n{shipped}");
    let subs: [(&str, String); 6] = [
        (
            "path = \"/var/lib/gtwatch/gtwatch.db\"",
            "path = \"gtwatch.db\"".into(),
        ),
        (
            "poll_period_ms = 100",
            format!("poll_period_ms = {poll_period_ms}\ntimestamp_field = \"{PLANT_TIME_FIELD}\""),
        ),
        (
            "endpoint = \"127.0.0.1:5020\"",
            format!("endpoint = \"{endpoint}\""),
        ),
        // The detector and worker react within a second of wall time (a plant day is seconds).
        (
            "detect_interval_ms = 10000",
            "detect_interval_ms = 1000".into(),
        ),
        ("poll_interval_ms = 60000", "poll_interval_ms = 1000".into()),
        // The plant clock: a field after `phase_truth` (address 18, one register) in request 0,
        // so the written file is complete and `check-config` accepts it.
        (
            "name = \"phase_truth\"\naddress = 18\ntype = \"u16\"\n",
            format!(
                "name = \"phase_truth\"\naddress = 18\ntype = \"u16\"\n\n\
                 # The simulator's clock, Unix epoch ms (gtwatch demo stamps samples with it).\n\
                 [[modbus.request.field]]\nname = \"{PLANT_TIME_FIELD}\"\naddress = 19\n\
                 type = \"f64\"\nunit = \"ms\"\n"
            ),
        ),
    ];
    for (from, to) in subs {
        if !text.contains(from) {
            bail!("the embedded reference configuration has no line '{from}' to adapt");
        }
        text = text.replacen(from, &to, 1);
    }
    Ok(text)
}

/// Prepares the output folder: refuses one with a database the demo did not make.
fn prepare_out_dir(dir: &Path) -> anyhow::Result<(PathBuf, PathBuf)> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let db = dir.join("gtwatch.db");
    let cfg = dir.join("gtwatch.toml");
    if db.exists() {
        let ours = std::fs::read_to_string(&cfg)
            .map(|t| t.starts_with(MARKER))
            .unwrap_or(false);
        if !ours {
            bail!(
                "{} already holds a database the demo did not write; choose another --out",
                dir.display()
            );
        }
        for suffix in ["", "-wal", "-shm"] {
            let p = dir.join(format!("gtwatch.db{suffix}"));
            if p.exists() {
                std::fs::remove_file(&p).with_context(|| format!("removing {}", p.display()))?;
            }
        }
    }
    Ok((db, cfg))
}

/// Runs the demo. `on_event` is called from the monitoring loop as things happen.
pub async fn run_demo(
    opts: &DemoOptions,
    mut on_event: impl FnMut(DemoEvent),
) -> anyhow::Result<DemoReport> {
    opts.validate()?;
    let started = Instant::now();
    let (db_path, config_path) = prepare_out_dir(&opts.out_dir)?;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .context("binding the plant simulator on 127.0.0.1")?;
    let cfg = demo_config(opts, &listener, &config_path, &db_path)?;
    let engine = Engine::reference()?;
    let plant_name = cfg.plant.name.clone();
    let schedule = FoulingSchedule::demo(opts.days);
    let plant = FoulingPlant::new(&engine, schedule.clone(), opts.seed, opts.epoch_ms)?;
    let clock = plant.clock();
    let map = cfg
        .modbus
        .clone()
        .context("demo configuration has no [modbus]")?;
    let sim = spawn_plant_sim(
        listener,
        map,
        Box::new(plant),
        SimOptions {
            speedup: 1.0,
            tick: None,
            lockstep: true,
        },
        None,
    )?;
    let worker = Arc::new(WorkerContext::load(None, cfg.diagnosis.clone())?);
    let (trigger, shutdown) = shutdown_channel();
    let daemon_task = tokio::spawn(daemon::run(
        cfg,
        shutdown,
        RunOptions {
            systemd_notify: false,
            progress: None,
            worker: Some(worker),
            after_result: None,
            compaction_timing: None,
        },
    ));
    let watch = Watch {
        opts,
        db_path: &db_path,
        schedule: &schedule,
        clock: &clock,
        started,
    };
    let complete = watch.until_done(&daemon_task, &mut on_event).await;
    trigger.trigger();
    let run_report = daemon_task
        .await
        .context("daemon task panicked")?
        .context("daemon")?;
    sim.stop().await.context("stopping the plant simulator")?;
    summarise(
        opts,
        &engine,
        &plant_name,
        &schedule,
        Finished {
            db_path,
            config_path,
            poll: run_report.poll,
            started,
            complete,
        },
    )
}

/// Writes the demo's configuration (polling the simulator at `listener`) to `config_path`
/// and loads it with the database at `db_path` and the demo's seed; refuses an invalid one.
fn demo_config(
    opts: &DemoOptions,
    listener: &tokio::net::TcpListener,
    config_path: &Path,
    db_path: &Path,
) -> anyhow::Result<Config> {
    let endpoint = listener.local_addr()?.to_string();
    let text = demo_config_text(&endpoint, opts.poll_period_ms())?;
    std::fs::write(config_path, &text)
        .with_context(|| format!("writing {}", config_path.display()))?;
    let mut cfg = Config::load(config_path)?;
    cfg.storage.path = db_path.to_path_buf();
    cfg.diagnosis.seed = opts.seed;
    let problems = cfg.check();
    if !problems.is_empty() {
        bail!(
            "demo configuration invalid: {}",
            problems
                .iter()
                .map(|p| p.to_string())
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    Ok(cfg)
}

/// The monitoring loop's view: what it watches and since when.
struct Watch<'a> {
    opts: &'a DemoOptions,
    db_path: &'a Path,
    schedule: &'a FoulingSchedule,
    /// The plant's clock, Unix ms.
    clock: &'a std::sync::atomic::AtomicI64,
    started: Instant,
}

/// What the monitoring loop has already reported.
#[derive(Default)]
struct Seen {
    day: Option<usize>,
    segments: std::collections::BTreeSet<i64>,
    results: std::collections::BTreeSet<i64>,
}

impl Watch<'_> {
    /// Watches the database until every day's start-up has a result (or a recorded reason)
    /// and the last day is over: `true`; `false` when the daemon ended or the demo timed out.
    async fn until_done(
        &self,
        daemon_task: &tokio::task::JoinHandle<Result<daemon::RunReport, daemon::DaemonError>>,
        on_event: &mut impl FnMut(DemoEvent),
    ) -> bool {
        let opts = self.opts;
        let last_day_end_ms = opts.epoch_ms
            + (((opts.days - 1) as f64 * DAY_S
                + crate::plantsim::fouling::DayTimes::default().active_end_s)
                * 1000.0) as i64;
        let mut seen = Seen::default();
        let mut tick = tokio::time::interval(Duration::from_millis(250));
        loop {
            tick.tick().await;
            let now_ms = self.clock.load(Ordering::Relaxed);
            if let Some(d) = day_of(now_ms, opts.epoch_ms).map(|d| d.min(opts.days - 1)) {
                if seen.day.is_none_or(|s| d > s) {
                    seen.day = Some(d);
                    on_event(DemoEvent::PlantDay(d));
                }
            }
            if daemon_task.is_finished() {
                return false;
            }
            if let Ok(store) = Store::open_readonly(self.db_path) {
                let all_done = self.report_new(&store, &mut seen, on_event);
                if all_done && now_ms > last_day_end_ms {
                    return true;
                }
            }
            if self.started.elapsed() > opts.timeout {
                tracing::warn!("demo timed out; reporting what was diagnosed so far");
                return false;
            }
        }
    }

    /// Reports start-ups and results not reported yet; whether every day has its outcome.
    fn report_new(
        &self,
        store: &Store,
        seen: &mut Seen,
        on_event: &mut impl FnMut(DemoEvent),
    ) -> bool {
        let state = collect_days(store, self.opts, self.schedule).unwrap_or_default();
        for d in &state {
            if let (Some(id), Some(o)) = (d.segment_id, &d.outcome) {
                if seen.segments.insert(id) {
                    on_event(DemoEvent::Startup {
                        day: d.day,
                        segment_id: id,
                        outcome: o.clone(),
                    });
                }
            }
            if let Some(b) = &d.method_b {
                if seen.results.insert(b.diagnosis_id) {
                    on_event(DemoEvent::Diagnosed {
                        day: d.day,
                        d_gc: b.value("D_GC"),
                        truth_gc: d.truth.D_GC,
                        fit_quality: b.fit_quality.clone().unwrap_or_default(),
                    });
                }
            }
        }
        state.len() == self.opts.days
            && state
                .iter()
                .all(|d| d.method_b.is_some() || !d.undiagnosable.is_empty())
    }
}

/// How the run ended, for the summary.
struct Finished {
    db_path: PathBuf,
    config_path: PathBuf,
    poll: PollStats,
    started: Instant,
    complete: bool,
}

/// The demo's report from the database the daemon left: each day against the truth, the
/// washes, the advice, and the HTML report written beside it.
fn summarise(
    opts: &DemoOptions,
    engine: &Engine,
    plant_name: &str,
    schedule: &FoulingSchedule,
    run: Finished,
) -> anyhow::Result<DemoReport> {
    let store = Store::open_readonly(&run.db_path)?;
    let days = collect_days(&store, opts, schedule)?;
    let washes = store
        .washes()?
        .into_iter()
        .map(|w: WashRow| DemoWash {
            t_utc: fmt_ms(w.t_ms),
            kind: w.kind.clone(),
            detected: w.is_detected(),
            before_day: days
                .iter()
                .find(|d| d.method_b.as_ref().is_some_and(|b| b.start_ms > w.t_ms))
                .map(|d| d.day),
        })
        .collect();
    let report = crate::report::write_report(
        &store,
        engine,
        crate::report::header_now(plant_name, &run.db_path),
        &opts.out_dir,
        None,
        None,
    )?;
    let advice = store
        .latest_recommendation()?
        .map(|r: RecommendationRow| DemoAdvice {
            kind: r.kind,
            message: r.message,
        });
    Ok(DemoReport {
        out_dir: opts.out_dir.clone(),
        db_path: run.db_path,
        config_path: run.config_path,
        days,
        wash_day: schedule.wash_day,
        washes,
        advice,
        poll: run.poll,
        wall_s: run.started.elapsed().as_secs_f64(),
        complete: run.complete,
        report_path: report.path,
    })
}

/// Each day's start-up, results and reasons as stored so far (days with no start-up yet are
/// left out).
fn collect_days(
    store: &Store,
    opts: &DemoOptions,
    schedule: &FoulingSchedule,
) -> anyhow::Result<Vec<DemoDay>> {
    let segments = list_segments(store, Some(opts.epoch_ms))?;
    let history = store.history(&HistoryFilter::default())?;
    let mut out = Vec::new();
    for seg in segments {
        let Some(day) = day_of(seg.start_ms, opts.epoch_ms) else {
            continue;
        };
        if day >= opts.days || out.iter().any(|d: &DemoDay| d.day == day) {
            continue;
        }
        let pick = |m: &str| {
            history
                .iter()
                .find(|h| h.segment_id == seg.id && h.method == m)
                .cloned()
        };
        let undiagnosable = store
            .undiagnosable_reasons(seg.id)?
            .into_iter()
            .map(|(method, reason, detail)| {
                format!(
                    "{}{reason}: {detail}",
                    method.map(|m| format!("{m}: ")).unwrap_or_default()
                )
            })
            .collect();
        out.push(DemoDay {
            day,
            start_utc: fmt_ms(seg.start_ms),
            truth: schedule.health_on(day),
            washed_before: schedule.wash_day == Some(day),
            segment_id: Some(seg.id),
            outcome: Some(seg.outcome.as_str().to_string()),
            method_b: pick("B"),
            method_a: pick("A"),
            undiagnosable,
        });
    }
    Ok(out)
}
