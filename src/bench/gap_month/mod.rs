//! `gtwatch bench gap-month`: issue 23's acceptance run. A month of a fouling unit with one
//! instrument step and one start-up the model does not describe, replayed the way a plant
//! engineer replays a historian export (replay → detection → diagnosis → the gap analyses the
//! configuration asks for → wash advice), and what the product made of it.
//!
//! The plant ([`FoulingPlant`], no wash): one start-up a day on a compressor fouling trend; from
//! start-up `meter_from` on, the fuel meter reads `meter_scale` × the fuel flow (applied to the
//! recorded `fuel_kg_s` column only — the engine burns what it burns); on day `poor_day` the
//! plant's model carries an engine effect the diagnosis does not model (default: heat soak,
//! `heat_soak` 3 kW/K with a 300 s time constant: the hot section's metal takes heat from the
//! gas through the start). The same frames are also written without the
//! meter error (the clean month).
//!
//! Three databases, each filled by the product's own replay path (the command line's
//! functions, handed in as [`Commands`]): the faulty month with the shipped `[diagnosis]` gap
//! settings, the same month with them off (the baseline: no gap analysis at all), and the clean
//! month with the gap settings. Reports per start-up its fit, its analyses, and the latency of
//! its diagnosis (from the moment detection made it pending to its Method B result stored, and
//! the Method B wall time) in both runs of the faulty month; the sequence verdict; and the wash
//! advice of the three. Asserts nothing (benchmarks never do); the test `tests/gap_month.rs`
//! does, on a short month. Must not select start-ups for analysis itself (`worker::gap` does).

mod log;

use super::month::{Commands, Sections};
use crate::advice::AdviceReport;
use crate::detect::scan;
use crate::engine::Engine;
use crate::health::HEALTH_NAMES;
use crate::ingest::{replay_file, Progress};
use crate::plantsim::fouling::{day_of, DAY_S};
use crate::plantsim::FoulingSchedule;
use crate::store::{now_ms, HistoryFilter, Store};
use crate::time::fmt_ms;
use crate::worker::gap::AfterReplay;
use anyhow::{bail, ensure, Context};
use log::{config_text, write_logs};
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Debug, clap::Args)]
pub struct BenchGapMonthArgs {
    /// Plant days (one start-up each).
    #[arg(long, default_value_t = 30)]
    pub days: usize,
    /// Seed of the sensor noise (the diagnosis' seed is the configuration's).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// First day (0-based) whose recorded fuel flow carries the meter error (default: two
    /// thirds in).
    #[arg(long)]
    pub meter_from: Option<usize>,
    /// The meter's reading over the true fuel flow from `meter_from` on.
    #[arg(long, default_value_t = 1.03)]
    pub meter_scale: f64,
    /// Day (0-based, at least 1) whose start-up the plant runs with `poor_effect` (default: a
    /// third in).
    #[arg(long)]
    pub poor_day: Option<usize>,
    /// The engine effect of that start-up, as an engine file's `[effects.NAME]` table:
    /// `NAME` and `key=value` parameters.
    #[arg(long, default_value = "heat_soak")]
    pub poor_effect: String,
    #[arg(long, value_delimiter = ',', default_value = "ua_kw_per_k=3,tau_s=300")]
    pub poor_params: Vec<String>,
    /// Compressor fouling, D_GC points per day (D_EC a third of it).
    #[arg(long, default_value_t = 0.1)]
    pub gc_per_day: f64,
    /// Sample spacing of the idle hours, s (1: a plain 1 Hz log; the start-ups are always 1 Hz).
    #[arg(long, default_value_t = 1.0)]
    pub idle_step: f64,
    /// `[diagnosis] max_model_runs` (default: the shipped configuration's).
    #[arg(long)]
    pub max_model_runs: Option<usize>,
    /// `[diagnosis] threads` (default: the shipped configuration's, 1).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Skip the baseline (the faulty month without gap settings): no latency comparison.
    #[arg(long)]
    pub no_baseline: bool,
    /// Replay the clean month without the gap settings: its only analysis would be the poor
    /// start-up's, which has no Method B result and so cannot move the advice (saves that
    /// analysis' time in a short test).
    #[arg(long)]
    pub clean_without_gap: bool,
    /// Keep the logs, configurations and databases in DIR (default: a temporary directory).
    #[arg(long)]
    pub keep: Option<PathBuf>,
    /// Print JSON only (compact).
    #[arg(long)]
    pub json: bool,
}

/// One start-up of the faulty month.
#[derive(Debug, Serialize)]
struct StartUp {
    segment_id: i64,
    day: usize,
    start_utc: String,
    meter_error: bool,
    poor_effect: bool,
    /// Method B fit quality as stored (`None`: no Method B result; see `undiagnosable`).
    fit_quality: Option<String>,
    undiagnosable: Vec<String>,
    /// Largest |Method B − truth| over the six parameters, points.
    max_abs_error: Option<f64>,
    /// The verdicts of the gap analyses stored for it (oldest first).
    gap_verdicts: Vec<String>,
    /// From pending (detection done) to the Method B result stored, s; with gap settings.
    latency_s: Option<f64>,
    method_b_wall_s: Option<f64>,
    /// The same without gap settings (the baseline run).
    latency_baseline_s: Option<f64>,
    method_b_wall_baseline_s: Option<f64>,
}

/// The wash advice of one database, as `gtwatch wash advise` shows it.
#[derive(Debug, Serialize)]
struct Advice {
    /// Advised wash, days after the month's first midnight.
    advised_day: Option<f64>,
    summary: Option<String>,
    /// The first step's verdict: `instrument:<effect>`, `ambiguous:<candidates>`,
    /// `health_step:<explanation>`, `no_step`, or `None` (no step found).
    step_verdict: Option<String>,
    step_onset_day: Option<usize>,
    /// The named instrument's fitted error and 1σ.
    instrument_magnitude: Option<(f64, f64)>,
    set_aside: Vec<i64>,
    washes_detected: Vec<i64>,
}

#[derive(Debug, Serialize)]
struct Latency {
    /// Start-ups without an analysis compared (those with a Method B result in both runs).
    compared: usize,
    mean_s: f64,
    baseline_mean_s: f64,
    /// Largest |latency − baseline latency| over them, s.
    max_abs_diff_s: f64,
    method_b_wall_mean_s: f64,
    method_b_wall_baseline_mean_s: f64,
    /// The last Method B result was stored before the first gap analysis started (what the
    /// daemon's priority rule promises).
    diagnoses_before_gap: bool,
}

#[derive(Debug, Serialize)]
struct GapMonthResult {
    bench: &'static str,
    days: usize,
    meter_from: usize,
    meter_scale: f64,
    poor_day: usize,
    poor_effect: String,
    gc_per_day: f64,
    max_model_runs: Option<usize>,
    threads: Option<usize>,
    rows: u64,
    generate_s: f64,
    ingest_s: f64,
    detect_s: f64,
    /// The faulty month with gap settings: diagnosis and gap analyses.
    after: AfterReplay,
    after_baseline: Option<AfterReplay>,
    after_clean: AfterReplay,
    start_ups: Vec<StartUp>,
    /// Start-ups with a stored gap analysis, and the verdicts.
    analysed: BTreeMap<usize, Vec<String>>,
    /// The fuel meter was named for the step: the first start-up with the meter error has its
    /// own analysis naming `fuel_meter`, or the joint fit of the sequence names it.
    instrument_named: bool,
    /// Start-ups before the meter's step whose result the advice set aside as an
    /// instrument's (a false attribution).
    set_aside_before_step: Vec<usize>,
    /// The poor start-up's analysis named the plant's effect.
    poor_explained: bool,
    /// Advice: the faulty month with the gap analyses, the same without (baseline), the clean
    /// month.
    advice: Advice,
    advice_baseline: Option<Advice>,
    advice_clean: Advice,
    /// |advised day − clean month's|, days.
    advice_shift_days: Option<f64>,
    advice_shift_baseline_days: Option<f64>,
    latency: Option<Latency>,
    wall_s: f64,
}

/// The month's first midnight: 2026-01-05T00:00:00Z.
const EPOCH_MS: i64 = 1_767_571_200_000;

fn day_ms(t_ms: i64) -> f64 {
    (t_ms - EPOCH_MS) as f64 / (DAY_S * 1000.0)
}

/// One replayed database: its configuration, the time detection finished, and what ran after.
struct Run {
    db: PathBuf,
    cfg: PathBuf,
    pending_ms: i64,
    after: AfterReplay,
}

/// Ingests `log` into `db` and runs the detector (as `gtwatch replay` does); returns the
/// ingest report's wall time and the detection's.
fn ingest(
    commands: &Commands,
    log: &Path,
    db: &Path,
    cfg: &Path,
) -> anyhow::Result<(f64, f64, Sections)> {
    let sections = (commands.load_sections)(cfg)?;
    let mut store = Store::open_with(db, &sections.storage.options())?;
    let rep = replay_file(&mut store, &sections.replay, log, Progress::Silent)?;
    let t = Instant::now();
    scan(&mut store, &sections.detector).context("start-up detection")?;
    Ok((rep.elapsed_s, t.elapsed().as_secs_f64(), sections))
}

/// Diagnosis, gap analyses and advice on an ingested database (what `gtwatch replay` runs
/// after its detector).
fn after(commands: &Commands, db: &Path, cfg: &Path, s: &Sections) -> anyhow::Result<Run> {
    let mut store = Store::open_with(db, &s.storage.options())?;
    // Every closed start-up is pending from here on, as a detector that closed them all at
    // once leaves them.
    let pending_ms = now_ms();
    let after = (commands.diagnose_after_replay)(&mut store, cfg)?;
    Ok(Run {
        db: db.to_path_buf(),
        cfg: cfg.to_path_buf(),
        pending_ms,
        after,
    })
}

fn advice_of(commands: &Commands, run: &Run, s: &Sections) -> anyhow::Result<Advice> {
    let mut store = Store::open_with(&run.db, &s.storage.options())?;
    let r: AdviceReport = (commands.advise)(&mut store, &run.cfg)?;
    let day_of_seg = |id: i64| -> anyhow::Result<Option<usize>> {
        Ok(store
            .segment(id)?
            .and_then(|g| day_of(g.start_ms, EPOCH_MS)))
    };
    // The step an instrument explains, else the first.
    let step = r
        .steps
        .iter()
        .find(|s| s.corrected)
        .or_else(|| r.steps.first());
    let (step_verdict, step_onset_day, instrument_magnitude) = match step {
        None => (None, None, None),
        Some(st) => {
            let v = st.attribution.verdict.label();
            let m = st.attribution.verdict.instrument_magnitude();
            (Some(v), day_of_seg(st.onset_segment_id)?, m)
        }
    };
    Ok(Advice {
        advised_day: r.advised_ms.map(day_ms),
        summary: r.advice.as_ref().map(|a| a.summary.clone()),
        step_verdict,
        step_onset_day,
        instrument_magnitude,
        set_aside: r.set_aside.iter().map(|s| s.segment_id).collect(),
        washes_detected: r.detected_now.clone(),
    })
}

/// Per segment: (latency s, Method B wall s).
fn latencies(run: &Run, s: &Sections) -> anyhow::Result<BTreeMap<i64, (f64, f64)>> {
    let store = Store::open_with(&run.db, &s.storage.options())?;
    Ok(store
        .diagnosis_timings()?
        .into_iter()
        .filter(|t| t.method == "B")
        .map(|t| {
            (
                t.segment_id,
                ((t.created_at_ms - run.pending_ms) as f64 / 1000.0, t.wall_s),
            )
        })
        .collect())
}

/// The days of the start-ups `segments`.
fn result_days(start_ups: &[StartUp], segments: &[i64]) -> Vec<usize> {
    start_ups
        .iter()
        .filter(|s| segments.contains(&s.segment_id))
        .map(|s| s.day)
        .collect()
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (n, s) = v.fold((0usize, 0.0), |(n, s), x| (n + 1, s + x));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

fn copy_db(from: &Path, to: &Path) -> anyhow::Result<()> {
    for suffix in ["", "-wal", "-shm"] {
        let f = PathBuf::from(format!("{}{suffix}", from.display()));
        let t = PathBuf::from(format!("{}{suffix}", to.display()));
        if f.exists() {
            std::fs::copy(&f, &t)
                .with_context(|| format!("copying {} to {}", f.display(), t.display()))?;
        }
    }
    Ok(())
}

/// Each start-up of the faulty month as stored: its fit, its analyses, its latencies.
fn start_ups_of(
    store: &Store,
    schedule: &FoulingSchedule,
    meter_from: usize,
    poor_day: usize,
    lat: &BTreeMap<i64, (f64, f64)>,
    lat_base: &BTreeMap<i64, (f64, f64)>,
) -> anyhow::Result<Vec<StartUp>> {
    let segments = crate::query::list_segments(store, None)?;
    let history = store.history(&HistoryFilter {
        method: Some("B".into()),
        ..HistoryFilter::default()
    })?;
    let mut start_ups = Vec::new();
    for g in &segments {
        let Some(day) = day_of(g.start_ms, EPOCH_MS) else {
            continue;
        };
        let b = history.iter().find(|h| h.segment_id == g.id);
        let truth = schedule.health_on(day).to_array();
        let max_abs_error = b.map(|h| {
            HEALTH_NAMES
                .iter()
                .enumerate()
                .map(|(i, n)| (h.value(n) - truth[i]).abs())
                .fold(0.0f64, f64::max)
        });
        // Oldest first.
        let mut verdicts: Vec<String> = store
            .gap_analyses(g.id)?
            .into_iter()
            .map(|r| r.effect)
            .collect();
        verdicts.reverse();
        start_ups.push(StartUp {
            segment_id: g.id,
            day,
            start_utc: fmt_ms(g.start_ms),
            meter_error: day >= meter_from,
            poor_effect: day == poor_day,
            fit_quality: b.and_then(|h| h.fit_quality.clone()),
            undiagnosable: store
                .undiagnosable_reasons(g.id)?
                .into_iter()
                .map(|(_, reason, _)| reason)
                .collect(),
            max_abs_error,
            gap_verdicts: verdicts,
            latency_s: lat.get(&g.id).map(|v| v.0),
            method_b_wall_s: lat.get(&g.id).map(|v| v.1),
            latency_baseline_s: lat_base.get(&g.id).map(|v| v.0),
            method_b_wall_baseline_s: lat_base.get(&g.id).map(|v| v.1),
        });
    }
    Ok(start_ups)
}

/// Whether every Method B result was stored before the first gap analysis started (what the
/// daemon's priority rule promises; the start is its storing time less its wall time).
fn diagnoses_before_gap(store: &Store, after: &AfterReplay) -> anyhow::Result<bool> {
    let first = after.gap.as_ref().and_then(|g| g.stored.first());
    let Some(first) = first else {
        return Ok(true);
    };
    let started_ms = store
        .gap_analyses(first.segment_id)?
        .iter()
        .find(|r| r.id == first.analysis_id)
        .map(|r| r.created_at_ms - (first.wall_s * 1000.0) as i64);
    let last_b_ms = store
        .diagnosis_timings()?
        .iter()
        .map(|t| t.created_at_ms)
        .max();
    Ok(match (started_ms, last_b_ms) {
        (Some(g), Some(b)) => b <= g,
        _ => true,
    })
}

/// The latencies of the start-ups without an analysis, with and without the gap settings.
fn latency_summary(start_ups: &[StartUp], diagnoses_before_gap: bool) -> Latency {
    let both: Vec<&StartUp> = start_ups
        .iter()
        .filter(|s| s.gap_verdicts.is_empty())
        .filter(|s| s.latency_s.is_some() && s.latency_baseline_s.is_some())
        .collect();
    Latency {
        compared: both.len(),
        mean_s: mean(both.iter().filter_map(|s| s.latency_s)),
        baseline_mean_s: mean(both.iter().filter_map(|s| s.latency_baseline_s)),
        max_abs_diff_s: both
            .iter()
            .filter_map(|s| Some((s.latency_s? - s.latency_baseline_s?).abs()))
            .fold(0.0, f64::max),
        method_b_wall_mean_s: mean(both.iter().filter_map(|s| s.method_b_wall_s)),
        method_b_wall_baseline_mean_s: mean(both.iter().filter_map(|s| s.method_b_wall_baseline_s)),
        diagnoses_before_gap,
    }
}

/// The meter's first day and the poor start-up's day, checked.
fn days_of(a: &BenchGapMonthArgs) -> anyhow::Result<(usize, usize)> {
    ensure!(a.days >= 3, "--days must be at least 3");
    let meter_from = a.meter_from.unwrap_or(a.days * 2 / 3);
    let poor_day = a.poor_day.unwrap_or((a.days / 3).max(1));
    ensure!(
        meter_from < a.days && poor_day >= 1 && poor_day < a.days,
        "--meter-from and --poor-day must be days of the month (--poor-day at least 1)"
    );
    ensure!(
        a.meter_scale.is_finite() && a.meter_scale > 0.0,
        "--meter-scale must be positive"
    );
    Ok((meter_from, poor_day))
}

pub(crate) fn run(a: BenchGapMonthArgs, commands: &Commands) -> anyhow::Result<ExitCode> {
    let wall = Instant::now();
    let (meter_from, poor_day) = days_of(&a)?;
    let dir = a.keep.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("gtwatch-bench-gap-month-{}", std::process::id()))
    });
    std::fs::create_dir_all(&dir)?;
    for name in ["faulty.db", "baseline.db", "clean.db"] {
        for suffix in ["", "-wal", "-shm"] {
            let _ = std::fs::remove_file(dir.join(format!("{name}{suffix}")));
        }
    }
    let engine = Engine::reference()?;
    let schedule = FoulingSchedule {
        gc_per_day: a.gc_per_day,
        wash_day: None,
        ..FoulingSchedule::demo(a.days)
    };

    // 1. The logs.
    let t = Instant::now();
    let (faulty_log, clean_log) = (dir.join("faulty.csv"), dir.join("clean.csv"));
    let rows = write_logs(
        &a,
        &engine,
        &schedule,
        meter_from,
        poor_day,
        &faulty_log,
        &clean_log,
    )?;
    let generate_s = t.elapsed().as_secs_f64();

    // 2. The configurations.
    let (faulty_db, baseline_db, clean_db) = (
        dir.join("faulty.db"),
        dir.join("baseline.db"),
        dir.join("clean.db"),
    );
    let write_cfg = |name: &str, db: &Path, gap: bool| -> anyhow::Result<PathBuf> {
        let p = dir.join(name);
        std::fs::write(&p, config_text(&a, db, gap)?)?;
        Ok(p)
    };
    let faulty_cfg = write_cfg("faulty.toml", &faulty_db, true)?;
    let baseline_cfg = write_cfg("baseline.toml", &baseline_db, false)?;
    let clean_cfg = write_cfg("clean.toml", &clean_db, !a.clean_without_gap)?;

    // 3. Ingest and detect once per log; the baseline starts from a copy of the faulty month's
    // database as detection left it.
    let (ingest_s, detect_s, sections) = ingest(commands, &faulty_log, &faulty_db, &faulty_cfg)?;
    if !a.no_baseline {
        copy_db(&faulty_db, &baseline_db)?;
    }
    let faulty = after(commands, &faulty_db, &faulty_cfg, &sections)?;
    let baseline = if a.no_baseline {
        None
    } else {
        let s = (commands.load_sections)(&baseline_cfg)?;
        Some((after(commands, &baseline_db, &baseline_cfg, &s)?, s))
    };
    let (_, _, clean_sections) = ingest(commands, &clean_log, &clean_db, &clean_cfg)?;
    let clean = after(commands, &clean_db, &clean_cfg, &clean_sections)?;

    // 4. What the product stored.
    let store = Store::open_with(&faulty_db, &sections.storage.options())?;
    let lat = latencies(&faulty, &sections)?;
    let lat_base = match &baseline {
        Some((run, s)) => latencies(run, s)?,
        None => BTreeMap::new(),
    };
    let start_ups = start_ups_of(&store, &schedule, meter_from, poor_day, &lat, &lat_base)?;
    let mut analysed: BTreeMap<usize, Vec<String>> = BTreeMap::new();
    for s in start_ups.iter().filter(|s| !s.gap_verdicts.is_empty()) {
        analysed.insert(s.day, s.gap_verdicts.clone());
    }
    let before_gap = diagnoses_before_gap(&store, &faulty.after)?;
    drop(store);

    let advice = advice_of(commands, &faulty, &sections)?;
    let advice_clean = advice_of(commands, &clean, &clean_sections)?;
    let advice_baseline = match &baseline {
        Some((run, s)) => Some(advice_of(commands, run, s)?),
        None => None,
    };
    let shift = |x: &Advice| match (x.advised_day, advice_clean.advised_day) {
        (Some(p), Some(q)) => Some((p - q).abs()),
        _ => None,
    };
    let latency = baseline
        .as_ref()
        .map(|_| latency_summary(&start_ups, before_gap));
    let poor_name = a.poor_effect.clone();
    let poor_explained = analysed
        .get(&poor_day)
        .is_some_and(|v| v.last().is_some_and(|e| *e == poor_name));
    let instrument_named = advice.step_verdict.as_deref() == Some("instrument:fuel_meter")
        || analysed
            .get(&meter_from)
            .is_some_and(|v| v.last().is_some_and(|e| e == "fuel_meter"));
    let set_aside_before_step: Vec<usize> = result_days(&start_ups, &advice.set_aside)
        .into_iter()
        .filter(|d| *d < meter_from)
        .collect();
    let result = GapMonthResult {
        bench: "gap-month",
        days: a.days,
        meter_from,
        meter_scale: a.meter_scale,
        poor_day,
        poor_effect: poor_name,
        gc_per_day: a.gc_per_day,
        max_model_runs: a.max_model_runs,
        threads: a.threads,
        rows,
        generate_s,
        ingest_s,
        detect_s,
        after: faulty.after,
        after_baseline: baseline.map(|(r, _)| r.after),
        after_clean: clean.after,
        start_ups,
        analysed,
        instrument_named,
        set_aside_before_step,
        poor_explained,
        advice_shift_days: shift(&advice),
        advice_shift_baseline_days: advice_baseline.as_ref().and_then(shift),
        advice,
        advice_baseline,
        advice_clean,
        latency,
        wall_s: wall.elapsed().as_secs_f64(),
    };
    if a.keep.is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    }
    let mut out = std::io::stdout().lock();
    if a.json {
        serde_json::to_writer(&mut out, &result)?;
    } else {
        serde_json::to_writer_pretty(&mut out, &result)?;
    }
    writeln!(out)?;
    if result.start_ups.is_empty() {
        bail!("the detector found no start-up in the replayed month");
    }
    Ok(ExitCode::SUCCESS)
}
