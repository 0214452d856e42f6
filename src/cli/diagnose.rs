//! `gtwatch diagnose`: read a start-up CSV, run Method B and/or Method A, print the health
//! parameters with 1σ, the objective, model runs and wall time (text or JSON).
//! Must not open the database or store results: it reads a CSV and prints.

use crate::diagnosis::csv_input::parse_mapping;
use crate::diagnosis::params::FitParam;
use crate::diagnosis::phase_split::{phase_split, PhaseSplit, MIN_DIFFERENCE_PTS};
use crate::diagnosis::steady::diagnose_steady;
use crate::diagnosis::transient::diagnose_transient;
use crate::diagnosis::{DiagnosisConfig, Method, MethodResult, Optimiser};
use crate::engine::measured_drive::DriveMode;
use crate::health::HEALTH_NAMES;
use crate::signals::Phase;
use anyhow::bail;
use clap::{Args, ValueEnum};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::path::PathBuf;
use std::process::ExitCode;

/// Which diagnosis method(s).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    Transient,
    Steady,
    Both,
}

/// Method B's drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DriveArg {
    /// Open loop on the measured fuel flow (default).
    MeasuredFuel,
    /// Controllers follow the measured GG speed and power; fuel flow is compared.
    Demand,
}

/// Optimiser choice.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OptimiserArg {
    Cuckoo,
    CuckooLm,
    Cmaes,
    De,
}

impl From<OptimiserArg> for Optimiser {
    fn from(o: OptimiserArg) -> Optimiser {
        match o {
            OptimiserArg::Cuckoo => Optimiser::Cuckoo,
            OptimiserArg::CuckooLm => Optimiser::CuckooLm,
            OptimiserArg::Cmaes => Optimiser::CmaEs,
            OptimiserArg::De => Optimiser::De,
        }
    }
}

/// Options shared by `diagnose` and the benches.
#[derive(Debug, Clone, Args)]
pub struct FitArgs {
    /// Seed of the global optimiser.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Optimiser.
    #[arg(long, value_enum, default_value = "cuckoo-lm")]
    pub optimiser: OptimiserArg,
    /// Model runs per method for the optimisation (global + LM).
    #[arg(long)]
    pub max_runs: Option<usize>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Method B drive mode.
    #[arg(long, value_enum, default_value = "measured-fuel")]
    pub drive: DriveArg,
    /// Also fit an engine-file or effect value within bounds, `KEY=LOW:HIGH` (repeatable), e.g.
    /// `effects.fuel_system.delay_s=0:4` (fitting an effect's parameter enables the effect); a
    /// health parameter's name sets its search interval instead of the default −3:10, e.g.
    /// `D_GC=-5:20`.
    #[arg(long = "fit-param", value_name = "KEY=LOW:HIGH")]
    pub fit_params: Vec<String>,
    /// 1σ of a prior on each fitted health parameter about new, points, in a steady diagnosis
    /// (Method A, snapshots; default 0: least squares on the data alone): along what the signals
    /// barely determine the read is held toward new instead of absorbing the model's small
    /// errors; the result names the parameters it held.
    #[arg(long = "health-prior", value_name = "PTS")]
    pub health_prior: Option<f64>,
    /// The same for Method B (default 1: a start-up determines every direction of a
    /// well-instrumented unit, where it takes no prior).
    #[arg(long = "transient-health-prior", value_name = "PTS")]
    pub transient_health_prior: Option<f64>,
    /// Method B compares only the samples of these start-up phases, comma-separated (crank,
    /// purge, light_off, acceleration, idle, synchronisation, loading, steady; default all):
    /// the model still runs through the whole start-up. Reading the same start-up on its
    /// `steady` and on its `loading` part says whether the transient carries a model error the
    /// health absorbs.
    #[arg(long, value_name = "PHASE,…", value_delimiter = ',')]
    pub phases: Vec<String>,
}

/// The start-up phases `names` name, or why not.
fn parse_phases(names: &[String]) -> anyhow::Result<Vec<Phase>> {
    names
        .iter()
        .map(|n| {
            let n = n.trim();
            n.parse::<Phase>()
                .ok()
                .filter(|p| Phase::STARTUP.contains(p))
                .ok_or_else(|| {
                    let known: Vec<&str> = Phase::STARTUP.iter().map(|p| p.name()).collect();
                    anyhow::anyhow!(
                        "--phases: `{n}` is not a start-up phase (one of {})",
                        known.join(", ")
                    )
                })
        })
        .collect()
}

/// Parses `KEY=LOW:HIGH` into a named fit parameter.
pub(super) fn parse_fit_param(text: &str) -> anyhow::Result<FitParam> {
    let bad = |why: &str| anyhow::anyhow!("--fit-param `{text}`: {why} (expected KEY=LOW:HIGH)");
    let (key, range) = text.split_once('=').ok_or_else(|| bad("no `=`"))?;
    let (lo, hi) = range
        .split_once(':')
        .ok_or_else(|| bad("no `:` in the range"))?;
    let lo: f64 = lo.trim().parse().map_err(|_| bad("LOW is not a number"))?;
    let hi: f64 = hi.trim().parse().map_err(|_| bad("HIGH is not a number"))?;
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(bad("needs finite LOW < HIGH"));
    }
    let key = key.trim();
    Ok(
        match key.strip_prefix("effects.").and_then(|r| r.split_once('.')) {
            Some((effect, param)) => FitParam::effect(effect, param, lo, hi),
            None => FitParam::engine_value(key, lo, hi),
        },
    )
}

/// Index of a health parameter named `name` (case-insensitive), if it is one.
fn health_index(name: &str) -> Option<usize> {
    HEALTH_NAMES
        .iter()
        .position(|n| n.eq_ignore_ascii_case(name))
}

impl FitArgs {
    /// The diagnosis configuration these options select; refuses settings that cannot give a
    /// result (`--max-runs 0`, `--threads 0`).
    pub fn config(&self) -> anyhow::Result<DiagnosisConfig> {
        let mut cfg = DiagnosisConfig {
            seed: self.seed,
            optimiser: self.optimiser.into(),
            threads: self.threads,
            drive_mode: match self.drive {
                DriveArg::MeasuredFuel => DriveMode::MeasuredFuel,
                DriveArg::Demand => DriveMode::Demand,
            },
            ..DiagnosisConfig::default()
        };
        if let Some(n) = self.max_runs {
            cfg.max_model_runs = n;
        }
        if let Some(p) = self.health_prior {
            cfg.health_prior_pts = p;
        }
        if let Some(p) = self.transient_health_prior {
            cfg.transient_health_prior_pts = p;
        }
        if !self.phases.is_empty() {
            cfg.window.phases = parse_phases(&self.phases)?;
        }
        for p in &self.fit_params {
            let param = parse_fit_param(p)?;
            match health_index(&param.name) {
                Some(i) => cfg
                    .health_bounds
                    .set(i, param.lower, param.upper)
                    .map_err(|e| anyhow::anyhow!("--fit-param `{p}`: {e}"))?,
                None => cfg.extra_params.push(param),
            }
        }
        cfg.validate()?;
        Ok(cfg)
    }
}

/// `gtwatch diagnose`
#[derive(Debug, Clone, Args)]
pub struct DiagnoseArgs {
    /// Start-up CSV (the layout `gtwatch simulate` writes, or any CSV with --map). Without a
    /// phase column the start-up detector finds the start-ups in it (as `gtwatch replay`
    /// would, with the engine file's sequence speeds) and labels their phases; the time column
    /// may be seconds or ISO 8601 date-times.
    #[arg(long, required_unless_present = "segment")]
    pub input: Option<PathBuf>,
    /// Instead of a CSV: re-run one stored start-up segment of the database (prints JSON,
    /// stores nothing); engine and settings from --config's [plant] and [diagnosis].
    #[arg(long, conflicts_with = "input")]
    pub segment: Option<i64>,
    /// A log without phase labels holding several start-ups: diagnose this one (1-based, in
    /// the order the start-up detector finds them; default: the first that reached load).
    #[arg(long, value_name = "N", conflicts_with = "segment")]
    pub start: Option<usize>,
    /// Config file (with --segment): database path, engine file, [diagnosis] settings.
    #[arg(long, requires = "segment")]
    pub config: Option<PathBuf>,
    /// Database (with --segment; default: --config's [storage].path).
    #[arg(long, requires = "segment")]
    pub db: Option<PathBuf>,
    /// Column mapping for other CSVs: `time_s=Time,phase=State,n1_rpm=NGG,…`.
    #[arg(long)]
    pub map: Option<String>,
    /// Units of columns not in the model's (K, kPa absolute, rpm, kg/s, MW, kN·m), converted as
    /// read: `t2_k=degC,p2_kpa=bar,fuel_kg_s=kg/h` (canonical or short signal names, and
    /// `p_amb_kpa`; units such as degC, degF, bar, mbar, psi, Pa, MPa, kg/h, t/h, lb/s, kW, hp,
    /// Nm, rad/s; a gas fuel by volume, Nm3/h, Sm3/h, scf/h, kscf/h or MMscfd, with the engine
    /// file's [fuel]; gauge pressures are refused).
    #[arg(long)]
    pub units: Option<String>,
    /// Method(s). `steady` on a file without a phase column (or with --snapshots/--group-by)
    /// diagnoses snapshots: each row one averaged steady point with its own ambient, PT speed
    /// and fuel flow.
    #[arg(long, value_enum, default_value = "both")]
    pub method: MethodArg,
    /// Read --input as steady snapshots (one averaged operating point per row).
    #[arg(long)]
    pub snapshots: bool,
    /// Snapshots: pool the rows sharing this column's value into one health vector per group
    /// (default: one per row).
    #[arg(long, value_name = "COLUMN")]
    pub group_by: Option<String>,
    /// Snapshots: each row is a spot reading, its inputs (fuel flow, T1, n2, P1) as noisy as
    /// its compared values (`[sensors]`): the fit runs under the covariance that noise gives each
    /// row. Without it a row's inputs are taken as exact (averages).
    #[arg(long)]
    pub noisy_inputs: bool,
    /// Engine TOML (default: the built-in reference engine).
    #[arg(long)]
    pub engine: Option<PathBuf>,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// JSON of one method's result.
pub(super) fn result_json(r: &MethodResult) -> Value {
    json!({
        "health": r.health_map(),
        "sigma": r.sigma,
        "objective": r.objective,
        "ssr": r.ssr,
        "residuals": r.residuals,
        "global_objective": r.global_objective,
        "model_runs": r.model_runs,
        "wall_s": r.wall_s,
        "optimiser": r.optimiser.name(),
        "signals": r.signals.iter().map(|s| s.column()).collect::<Vec<_>>(),
        "steady_windows_s": r.windows,
        "ambient_kpa": r.ambient_kpa.map(|(p, s)| json!({ "value": p, "sigma": s })),
        "fuel_meter_zero": r.fuel_meter_zero,
        "record_holes": r.record_holes,
        "params": r.params,
        "failed_runs": r.failures,
        "fit_quality": r.fit_quality,
        "separability": r.separability,
        "health_prior": r.health_prior,
        "localisation": r.localisation,
        "left_out": r.left_out,
    })
}

/// The phase split's lines under Method B's result.
fn print_phase_split(split: &PhaseSplit) {
    let line = |p: &crate::diagnosis::phase_split::PartRead| {
        HEALTH_NAMES
            .iter()
            .map(|n| {
                format!(
                    "{n} {:+.2}±{:.2}",
                    p.health.get(*n).copied().unwrap_or(f64::NAN),
                    p.sigma.get(*n).copied().unwrap_or(f64::NAN)
                )
            })
            .collect::<Vec<_>>()
            .join("  ")
    };
    // Without the parts' verdicts: judged by the whole start-up's thresholds, a steady end
    // alone exceeds them by noise alone (the twin's: normalised residual 1.03).
    println!("  run to load alone: {}", line(&split.to_load));
    println!("  steady end alone:  {}", line(&split.steady));
    if split.differ.is_empty() {
        println!("  the two parts agree within {MIN_DIFFERENCE_PTS} points or 3σ");
    } else {
        println!("  {}", split.statement());
    }
}

pub(crate) fn print_text(m: Method, r: &MethodResult) {
    print_text_of(m.name(), "this start-up", m, r);
}

/// [`print_text`] with the title of the method line and what was fitted ("this start-up",
/// "these snapshots") named in words.
pub(crate) fn print_text_of(title: &str, subject: &str, m: Method, r: &MethodResult) {
    println!(
        "{} (Method {}): objective {:.4}, {} model runs, {:.2} s",
        title,
        if m == Method::Transient { "B" } else { "A" },
        r.objective,
        r.model_runs,
        r.wall_s
    );
    let q = &r.fit_quality;
    println!(
        "  fit quality: {} (normalised residual {:.2}; good up to {:.2}){}",
        q.verdict.as_str(),
        q.normalised_residual,
        q.thresholds.good_level,
        if q.summary.is_empty() {
            String::new()
        } else {
            format!("\n  where the model and the data disagree: {}", q.summary)
        }
    );
    if q.verdict != crate::diagnosis::fit_quality::Verdict::Good {
        println!("  the model does not fit {subject}: the health below absorbs the mismatch");
    }
    if let Some(z) = r.fuel_meter_zero {
        println!(
            "  fuel meter zero: it read {:+.4} kg/s before light-off (median of {} readings, no \
             fuel flowing); taken off every fuel reading before the fit",
            z.kg_s, z.samples
        );
    }
    if let Some(longest) = r
        .record_holes
        .iter()
        .max_by(|a, b| (a.to_s - a.from_s).total_cmp(&(b.to_s - b.from_s)))
    {
        println!(
            "  record: {} hole(s) without samples (longest {:.0} s, {:.0}–{:.0} s, before {}): the \
             measured inputs are interpolated across each, and the model's shaft speeds are set \
             to the measured ones after it",
            r.record_holes.len(),
            longest.to_s - longest.from_s,
            longest.from_s,
            longest.to_s,
            longest.phase.name()
        );
    }
    for note in &r.left_out {
        println!("  left out: {note}");
    }
    if !r.separability.statement.is_empty() {
        println!("  separability: {}", r.separability.statement);
    }
    if let Some(p) = &r.health_prior {
        println!("  {}", p.line());
    } else if m == Method::Steady
        && (!r.separability.not_identifiable.is_empty() || !r.separability.confounded.is_empty())
    {
        // Where least squares alone may wander along what the data do not determine.
        println!(
            "  no prior: the parameters these signals do not determine are read by least squares \
             alone, which can move far along them to absorb a small model error; \
             --health-prior 1 holds them toward new (README \"A prior on the health\")"
        );
    }
    let h = r.health.to_array();
    for (i, n) in HEALTH_NAMES.iter().enumerate() {
        let s = r.sigma.get(*n).copied().unwrap_or(f64::NAN);
        let flag = q
            .at_limit
            .iter()
            .find(|hit| hit.name == *n)
            .map(|hit| {
                format!(
                    "  AT ITS {} SEARCH LIMIT {:+} %",
                    hit.side.to_uppercase(),
                    hit.limit
                )
            })
            .unwrap_or_default();
        println!("  {n:5} {:8.3} ± {:.3} %{flag}", h[i], s);
    }
    for p in r.params.iter().filter(|p| p.target.engine_key().is_some()) {
        println!("  {} {:.6} ± {:.6}", p.name, p.value, p.sigma);
    }
    if r.failures.count > 0 {
        println!("  {} model runs failed:", r.failures.count);
        for (reason, n) in &r.failures.reasons {
            println!("    {n} × {reason}");
        }
    }
}

/// Runs `gtwatch diagnose`.
pub(super) fn run(a: &DiagnoseArgs) -> anyhow::Result<ExitCode> {
    if let Some(seg) = a.segment {
        let db = super::common::db_path(a.db.as_ref(), a.config.as_ref())?;
        super::diagnose_stored::run_segment(&db, a.config.as_deref(), seg)?;
        return Ok(ExitCode::SUCCESS);
    }
    let Some(input) = &a.input else {
        bail!("--input or --segment is required");
    };
    let mut cfg = a.fit.config()?;
    cfg.snapshot_input_noise = a.noisy_inputs;
    let engine = super::load_engine(a.engine.as_deref())?;
    let mapping = match &a.map {
        Some(m) => parse_mapping(m)?,
        None => HashMap::new(),
    };
    let units = super::common::column_units(a.units.as_deref(), &engine)?;
    if super::diagnose_snapshots::wants_snapshots(a, input, &mapping, &units, &engine)? {
        return super::diagnose_snapshots::run(a, input, &engine, &cfg, &mapping, &units);
    }
    let (seg, flagged, found) =
        super::diagnose_log::read_startup_file(input, &mapping, &units, &engine, a.start)?;
    if let (Some(found), false) = (&found, a.json) {
        for l in &found.lines {
            println!("{l}");
        }
    }
    let startup_json = found.map(|f| f.summary);
    for (signal, c) in &flagged.flagged {
        tracing::warn!(
            file = %input.display(),
            signal = signal.column(),
            out_of_range = c.out_of_range,
            stuck = c.stuck,
            spike = c.spike,
            "cells flagged by the bad-value policy are treated as missing"
        );
    }
    let methods: Vec<Method> = match a.method {
        MethodArg::Transient => vec![Method::Transient],
        MethodArg::Steady => vec![Method::Steady],
        MethodArg::Both => vec![Method::Transient, Method::Steady],
    };
    let mut out = serde_json::Map::new();
    let mut failed = 0;
    for m in &methods {
        let r = match m {
            Method::Transient => diagnose_transient(&engine, &seg, &cfg),
            Method::Steady => diagnose_steady(&engine, &seg, &cfg),
        };
        match r {
            Ok(r) => {
                if !a.json {
                    print_text(*m, &r);
                }
                let mut j = result_json(&r);
                // The run to load and the steady end read apart, unless the user chose phases.
                if *m == Method::Transient && a.fit.phases.is_empty() {
                    let split = phase_split(&engine, &seg, &cfg);
                    if let Some(split) = &split {
                        if !a.json {
                            print_phase_split(split);
                        }
                    }
                    j["phase_split"] = json!(split);
                }
                out.insert(m.name().into(), j);
            }
            Err(e) => {
                failed += 1;
                if !a.json {
                    eprintln!("{}: {e}", m.name());
                }
                out.insert(m.name().into(), json!({ "error": e.to_string() }));
            }
        }
    }
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&match startup_json {
                Some(s) => json!({ "startup": s, "methods": out }),
                None => json!({ "methods": out }),
            })?
        );
    }
    if failed == methods.len() {
        bail!("no method succeeded");
    }
    Ok(if failed > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}
