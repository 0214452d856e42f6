//! `gtwatch calibrate`: adapt an engine file's design values to one unit's healthy baseline
//! (steady snapshots, the CSV `gtwatch diagnose --method steady` reads, and/or the steady
//! windows of recorded start-ups) and write the new
//! engine file (`calibrate`, `calibrate::edit`). Prints a report, or one JSON document.
//! Must not fit anything itself (that is `crate::calibrate`) or write any file but the output
//! engine file.

mod dynamics;
mod print;

use super::common::moved_map_paths;
use crate::calibrate::adapt::{AdaptSettings, AdaptStrategy};
use crate::calibrate::candidates::{candidate, candidate_in, default_candidates, offset_candidate};
use crate::calibrate::edit::{rewrite, NewValue};
use crate::calibrate::ensemble::Member;
use crate::calibrate::startup::{rest_readings, startup_snapshots};
use crate::calibrate::validate::{leave_one_out, Summary, Validation};
use crate::calibrate::{calibrate, Calibration, CalibrationSettings};
use crate::diagnosis::csv_input::parse_mapping;
use crate::diagnosis::snapshot::read_snapshots_in;
use crate::engine::{Engine, EngineConfig};
use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use print::{print_text, print_validation};
use serde_json::json;
use std::collections::HashMap;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// `gtwatch calibrate`
#[derive(Debug, Clone, Args)]
pub struct CalibrateArgs {
    /// Engine file with the design guesses (TOML).
    #[arg(long, value_name = "FILE")]
    pub engine: PathBuf,
    /// Healthy steady snapshots across the load range: one averaged operating point per row
    /// (T1, n2, fuel flow and the measured signals; an ambient-pressure column if any).
    #[arg(
        long,
        value_name = "SNAPSHOTS.csv",
        required_unless_present = "startup"
    )]
    pub input: Option<PathBuf>,
    /// Healthy start-up recordings (the layout `gtwatch simulate` writes, or any CSV with
    /// --map; repeat for several; a log without a phase column gives every start-up the
    /// detector finds in it that reached load): each steady window (idle, holds, the settled
    /// load) becomes one operating point, found and averaged with Method A's stability criteria.
    #[arg(long, value_name = "STARTUP.csv")]
    pub startup: Vec<PathBuf>,
    /// Write the calibrated engine file here (without it nothing is written).
    #[arg(long, value_name = "NEW.toml")]
    pub out: Option<PathBuf>,
    /// Candidate parameters (dotted engine-file keys), comma-separated, each optionally with
    /// its interval `KEY=LOW:HIGH` (default: a realistic interval around the file's value);
    /// default set: design efficiencies, air flow, pressure ratio, power, losses, combustion
    /// efficiency and map design points.
    #[arg(long, value_name = "KEY,KEY…")]
    pub params: Option<String>,
    /// Also fit a constant offset of each gas-path pressure instrument (P2, P34, P4: the
    /// `sensor_bias` effect of the channel, ± 2 % of its largest reading), over-determined by
    /// the --startup recordings' samples at rest, where every pressure is the ambient;
    /// identified offsets are written as `[effects."sensor_bias:<column>"]` tables.
    #[arg(long)]
    pub offsets: bool,
    /// Also adapt the maps off design: smooth modification curves of each component's
    /// relative corrected speed (compressor speed line, flow, efficiency, pressure ratio; HPT
    /// and PT flow and efficiency), as many curves and knots as the identifiability analysis
    /// finds the data support, written as the `[adaptation]` section. For a unit whose maps
    /// are not the engine file's (another make, variable stators, a different off-design shape).
    #[arg(long)]
    pub adapt: bool,
    /// How --adapt chooses and fits its curves. `grown` (default): the curves the
    /// identifiability analysis identifies, knots grown while each stays identified; the shape
    /// for diagnosis. `continuation`: every curve the data inform, correlated ones too, at every
    /// knot the data's speeds carry (at most 6), fitted from nearly straight curves to the
    /// final smoothness; predicts the healthy unit between its loads best, but what the
    /// correlated curves do off the operating line is not in healthy data, so degradation can
    /// read with more cross-talk (README, "Calibrating to your unit").
    #[arg(long, value_enum, default_value_t = AdaptStrategyArg::Grown, requires = "adapt")]
    pub adapt_strategy: AdaptStrategyArg,
    /// Most knots a component's curves get with --adapt (default 6; fewer when the data's
    /// speeds carry fewer). Fewer knots give stiffer curves; compare the model error the
    /// calibration reports (on one unit with a flat part-load running line they fitted worse
    /// and predicted no better).
    #[arg(long, requires = "adapt", value_parser = clap::value_parser!(u8).range(1..=12))]
    pub adapt_max_knots: Option<u8>,
    /// Also validate the calibration on points it was not fitted to: calibrate again once per
    /// operating point with that point left out (the same settings, --adapt included) and
    /// predict it; per point the error of each measured signal in % of its value, placed
    /// against the others' GG speeds (`interior`, or `below`/`above`: an extrapolation).
    /// Costs one more calibration per point.
    #[arg(long)]
    pub validate: bool,
    /// Also calibrate the baseline three more times, an interleaved third of its interior
    /// loads left out each (the same settings), and write them beside --out
    /// (`<out>.part1.toml` …), listed in its `[adaptation.ensemble]`: calibrations that fit the
    /// baseline alike differ off the healthy line, where degradation is read, and snapshot
    /// diagnosis on the written file then states how far they part on your unit's data
    /// (README, "Calibrations that fit alike: --ensemble"). Costs three more calibrations.
    #[arg(long, requires_all = ["adapt", "out"])]
    pub ensemble: bool,
    /// Also fit the unit's dynamics to the --startup recordings (healthy start-ups): each
    /// measured thermocouple's lag (T2, T34, T4) and both rotors' inertias, by Method B with
    /// the health held at zero on the calibrated file, pooled over the start-ups; a value is
    /// written where the pool determines it (1σ within 20 %), and each start-up's health is
    /// shown read with the file's values and with the fitted ones. For an engine file copied
    /// from another unit, whose lags and inertias are that unit's. Costs three Method B fits
    /// per start-up
    #[arg(long, requires = "startup")]
    pub dynamics: bool,
    /// The --input rows are spot readings, their inputs (fuel flow, T1, n2, P1) as noisy as
    /// their compared values (`[sensors]`): each point is fitted under the covariance that
    /// noise gives it, `rᵀ (I + C Cᵀ)⁻¹ r`, rather than with its inputs taken as exact (as
    /// `diagnose --noisy-inputs` reads such rows). Without it a row's inputs are exact
    /// (averages)
    #[arg(long)]
    pub noisy_inputs: bool,
    /// The group (a value of the --group-by column) whose rows were taken just before a
    /// compressor wash, the others after it (healthy): the calibration finds their compressor
    /// fouling (D_GC, D_EC; a wash removes nothing else) in rounds with the fit, and with
    /// --adapt they show the curves how the unit runs off its healthy operating line, which a
    /// healthy baseline cannot (README, "Rows from before a wash"). Costs 2–5 calibrations.
    #[arg(long, value_name = "GROUP", requires = "group_by")]
    pub prewash_group: Option<String>,
    /// The column of --input that names each row's group (as `diagnose --group-by`); needed by
    /// --prewash-group. Without it every row of --input is one group, named by the file.
    #[arg(long, value_name = "COLUMN")]
    pub group_by: Option<String>,
    /// Column mapping for the snapshot file: `t1_k=T_inlet,n1_rpm=NGG,…`.
    #[arg(long)]
    pub map: Option<String>,
    /// Units of columns not in the model's (K, kPa absolute, rpm, kg/s, MW, kN·m), converted as
    /// read: `t2_k=degC,p2_kpa=bar,fuel_kg_s=kg/h` (canonical or short signal names, and
    /// `p_amb_kpa`; units such as degC, degF, bar, mbar, psi, Pa, MPa, kg/h, t/h, lb/s, kW, hp,
    /// Nm, rad/s; a gas fuel by volume, Nm3/h, Sm3/h, scf/h, kscf/h or MMscfd, with the engine
    /// file's [fuel]; gauge pressures are refused).
    #[arg(long)]
    pub units: Option<String>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print one JSON document.
    #[arg(long)]
    pub json: bool,
}

/// `--adapt-strategy` (the calibration's own [`AdaptStrategy`], without clap in it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AdaptStrategyArg {
    Grown,
    Continuation,
}

impl From<AdaptStrategyArg> for AdaptStrategy {
    fn from(a: AdaptStrategyArg) -> Self {
        match a {
            AdaptStrategyArg::Grown => AdaptStrategy::Grown,
            AdaptStrategyArg::Continuation => AdaptStrategy::Continuation,
        }
    }
}

/// The data files of a run, as the header and the JSON name them.
fn sources(a: &CalibrateArgs) -> Vec<String> {
    a.input
        .iter()
        .chain(&a.startup)
        .map(|p| p.display().to_string())
        .collect()
}

fn header(a: &CalibrateArgs, report: &Calibration, n_rows: usize) -> Vec<String> {
    let now = crate::time::fmt_rfc3339(time::OffsetDateTime::now_utc());
    // Rows before a wash are operating points, not healthy ones; left out when no round ran.
    let (n_points, healthy) = match &report.prewash {
        Some(pw) if pw.fouling.is_some() => (n_rows, ""),
        Some(pw) => (n_rows.saturating_sub(pw.rows), "healthy "),
        None => (n_rows, "healthy "),
    };
    let mut h = vec![format!(
        "Calibrated by gtwatch calibrate {} at {now}: {} fitted to {n_points} {healthy}operating \
         point(s) of {}",
        env!("CARGO_PKG_VERSION"),
        a.engine.display(),
        sources(a).join(", ")
    )];
    if a.noisy_inputs {
        h.push(
            "  the rows fitted as spot readings, under their inputs' noise (--noisy-inputs)"
                .to_string(),
        );
    }
    if let Some(pw) = &report.prewash {
        // The rows before the wash are not healthy: say at what they were run.
        h.push(match &pw.fouling {
            Some(f) => format!(
                "  of them {} of group {} taken before a wash, run at a compressor fouling \
                 found with the calibration: D_GC {:+.2}, D_EC {:+.2} points",
                pw.rows, pw.group, f.d_gc, f.d_ec
            ),
            None => format!(
                "  the {} rows of group {} (before a wash) left out: {}",
                pw.rows,
                pw.group,
                pw.stopped.as_deref().unwrap_or("no round ran")
            ),
        });
    }
    for p in &report.params {
        if p.identifiable {
            h.push(format!(
                "  {} = {:.7} (was {}; 1σ {:.2e})",
                p.key,
                p.fitted,
                p.guess,
                p.sigma.unwrap_or(f64::NAN)
            ));
        } else if p.status == "at_bound" {
            h.push(format!(
                "  {} = {:.7} (was {}; AT THE BOUND of [{}, {}]: the data want more)",
                p.key, p.fitted, p.guess, p.lower, p.upper
            ));
        }
    }
    let kept: Vec<&str> = report
        .params
        .iter()
        .filter(|p| p.status == "not_identifiable")
        .map(|p| p.key.as_str())
        .collect();
    if !kept.is_empty() {
        h.push(format!(
            "  kept at the file's values (not identifiable from these data): {}",
            kept.join(", ")
        ));
    }
    h.push(format!(
        "  RMS residual {:.2} σ before, {:.2} σ after",
        report.rms_before, report.rms_after
    ));
    if let Some(ad) = &report.adaptation {
        // Which shape the file holds: the grown one, or the continuation kept in its place.
        h.push(format!(
            "  adaptation: {} curves{}",
            ad.strategy,
            ad.fallback
                .as_ref()
                .map_or(String::new(), |f| format!(" ({f})"))
        ));
    }
    h.push(format!(
        "  baseline fit: {} ({})",
        report.baseline_fit.verdict.as_str(),
        report.baseline_fit.summary
    ));
    h
}

/// One `--params` entry: `key` (its realistic interval) or `key=LOW:HIGH` (the user's).
fn param_candidate(
    engine: &Engine,
    entry: &str,
) -> anyhow::Result<crate::calibrate::candidates::Candidate> {
    let Some((key, interval)) = entry.split_once('=') else {
        return Ok(candidate(engine, entry)?);
    };
    let parse = |v: &str| {
        v.trim()
            .parse::<f64>()
            .with_context(|| format!("`{entry}`: `{v}` is not a number (use KEY=LOW:HIGH)"))
    };
    let (lo, hi) = interval
        .split_once(':')
        .with_context(|| format!("`{entry}`: use KEY=LOW:HIGH"))?;
    Ok(candidate_in(engine, key.trim(), parse(lo)?, parse(hi)?)?)
}

/// Every number the calibration writes into the new file: the fitted values, the adaptation's
/// curves and the adapted model's own error.
fn fitted_values(report: &Calibration) -> Vec<(String, NewValue)> {
    let mut values: Vec<(String, NewValue)> = report
        .changes()
        .into_iter()
        .map(|(k, v)| (k, NewValue::Number(v)))
        .collect();
    values.extend(
        report
            .adaptation_lists()
            .into_iter()
            .map(|(k, v)| (k, NewValue::Numbers(v))),
    );
    values.extend(
        report
            .adaptation_words()
            .into_iter()
            .map(|(k, v)| (k, NewValue::Text(v))),
    );
    values.extend(
        report
            .model_error_values()
            .into_iter()
            .map(|(k, v)| (k, NewValue::Number(v))),
    );
    // The inlet loss law the measured P1 chose, where it is not the file's.
    if let Some(law) = report.inlet_loss_law.as_ref().filter(|l| l.changed()) {
        values.push((
            "design.inlet_loss_law".into(),
            NewValue::Text(law.chosen.name().into()),
        ));
    }
    values
}

/// The adaptation `a` asks for (`None` without `--adapt`).
fn adapt_settings(a: &CalibrateArgs) -> Option<AdaptSettings> {
    a.adapt.then(|| {
        let mut s = AdaptSettings::of(a.adapt_strategy.into());
        if let Some(n) = a.adapt_max_knots {
            s.max_knots = usize::from(n);
        }
        s
    })
}

pub(super) fn run(a: CalibrateArgs) -> anyhow::Result<ExitCode> {
    let start = Instant::now();
    let original = std::fs::read_to_string(&a.engine)
        .with_context(|| format!("reading engine file {}", a.engine.display()))?;
    let cfg = EngineConfig::load(&a.engine)?;
    let engine = Engine::new(cfg).context("building the engine model")?;
    let mapping = match &a.map {
        Some(m) => parse_mapping(m)?,
        None => HashMap::new(),
    };
    let units = super::common::column_units(a.units.as_deref(), &engine)?;
    let mut rows = Vec::new();
    let mut rest = Vec::new();
    if let Some(input) = &a.input {
        let file =
            std::fs::File::open(input).with_context(|| format!("opening {}", input.display()))?;
        let mut snaps = read_snapshots_in(
            BufReader::new(file),
            &mapping,
            &units,
            a.group_by.as_deref(),
        )
        .with_context(|| format!("reading {}", input.display()))?;
        if a.group_by.is_none() {
            for r in &mut snaps {
                r.group = input.display().to_string();
            }
        }
        rows.extend(snaps);
    }
    let startup_recs = startups(&a, &engine, &mapping, &units, &mut rows, &mut rest)?;
    let mut candidates = match &a.params {
        None => default_candidates(&engine)?,
        Some(list) => {
            let keys: Vec<&str> = list
                .split(',')
                .map(str::trim)
                .filter(|k| !k.is_empty())
                .collect();
            if keys.is_empty() {
                bail!("--params: no key given");
            }
            keys.iter()
                .map(|k| param_candidate(&engine, k))
                .collect::<anyhow::Result<Vec<_>>>()
                .context("--params")?
        }
    };
    if a.offsets {
        let mut seen: Vec<crate::signals::Signal> = Vec::new();
        for r in &rest {
            if !seen.contains(&r.signal) {
                seen.push(r.signal);
            }
        }
        if seen.is_empty() {
            bail!(
                "--offsets needs --startup recordings with samples at rest before the start \
                 (the one state where every pressure's truth, the ambient, is known)"
            );
        }
        for sig in seen {
            let largest = rows
                .iter()
                .flat_map(|r| r.values.iter())
                .filter(|(x, _)| *x == sig)
                .fold(engine.cfg().ambient.pressure_kpa, |m, (_, v)| {
                    m.max(v.abs())
                });
            candidates.push(offset_candidate(&engine, sig, largest).context("--offsets")?);
        }
    }
    let settings = CalibrationSettings {
        threads: a.threads,
        adapt: adapt_settings(&a),
        prewash_group: a.prewash_group.clone(),
        noisy_inputs: a.noisy_inputs,
        ..CalibrationSettings::default()
    };
    let (members, ensemble_s) = ensemble(&a, &engine, &rows, &rest, &candidates, &settings)?;
    let (report, fitted) = calibrated(&a, &engine, &rows, &rest, candidates.clone(), &settings)?;
    // Folds fitted with the efficiency shape this calibration chose (`leave_one_out` would
    // calibrate again to choose it); its wall time is reported without the validation's.
    let chosen = settings.with_efficiency_shape_of(&report);
    let (validation, validation_design_only, validation_s) =
        validations(a.validate, &engine, &rows, &rest, &candidates, &chosen)?;
    let dynamics = dynamics::fit(&a, &fitted, &startup_recs)?;
    let mut head = with_validation(
        header(&a, &report, rows.len()),
        validation.as_ref(),
        validation_design_only.as_ref(),
    );
    head.extend(dynamics.as_ref().map(dynamics::header_line));
    let ensemble_files = write_members(&a, &original, &members, rows.len())?;
    let dynamic_values: Vec<(String, NewValue)> = dynamics
        .as_ref()
        .map(|d| d.changes())
        .unwrap_or_default()
        .into_iter()
        .map(|(k, v)| (k, NewValue::Number(v)))
        .collect();
    write_out(
        &a,
        &original,
        &report,
        &head,
        &ensemble_files,
        dynamic_values,
    )?;
    let dynamics_s = dynamics.as_ref().map_or(0.0, |d| d.wall_s);
    let wall_s = start.elapsed().as_secs_f64() - validation_s - ensemble_s - dynamics_s;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({
                "engine": a.engine.display().to_string(),
                "input": a.input.as_ref().map(|p| p.display().to_string()),
                "startups": a.startup.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
                "out": a.out.as_ref().map(|p| p.display().to_string()),
                "rows": rows.len(),
                "rest_readings": rest,
                "calibration": report,
                "validation": validation,
                "validation_design_only": validation_design_only,
                "validation_s": validation.as_ref().map(|_| validation_s),
                "ensemble": ensemble_json(&members, &ensemble_files),
                "ensemble_s": a.ensemble.then_some(ensemble_s),
                "dynamics": dynamics,
                "wall_s": wall_s,
            }))?
        );
    } else {
        print_text(&report, wall_s);
        if let Some(v) = &validation {
            print_validation(v, validation_design_only.as_ref(), validation_s);
        }
        print_ensemble(&members, &ensemble_files, ensemble_s);
        if let Some(d) = &dynamics {
            dynamics::print(d);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The `--startup` files' start-ups (each with its source's name), their steady windows added
/// to `rows` and their pressure readings at rest to `rest`. A file without a steady window is
/// an error naming it.
fn startups(
    a: &CalibrateArgs,
    engine: &Engine,
    mapping: &HashMap<String, String>,
    units: &crate::units::ColumnUnits,
    rows: &mut Vec<crate::diagnosis::snapshot::Snapshot>,
    rest: &mut Vec<crate::calibrate::startup::RestReading>,
) -> anyhow::Result<Vec<(String, crate::recording::Recording)>> {
    let criteria = crate::diagnosis::config::SteadyCriteria::default();
    let mut startup_recs = Vec::new();
    for path in &a.startup {
        // A log without phase labels gives every start-up in it that reached load.
        let recs = super::diagnose_log::startups_of_file(path, mapping, units, engine)?;
        let mut windows = Vec::new();
        for (k, rec) in recs.iter().enumerate() {
            let source = match recs.len() {
                1 => path.display().to_string(),
                _ => format!("{} start {}", path.display(), k + 1),
            };
            windows.extend(startup_snapshots(rec, engine.cfg(), &criteria, &source));
            rest.extend(rest_readings(rec, engine.cfg(), &source));
            startup_recs.push((source, rec.clone()));
        }
        if windows.is_empty() {
            bail!(
                "{}: no steady window (Method A's criteria: n1, P2, T2, T34 and power stable \
                 for at least {} s above {:.0} % GG speed)",
                path.display(),
                criteria.min_duration_s,
                100.0 * criteria.min_n1_fraction
            );
        }
        rows.extend(windows);
    }
    Ok(startup_recs)
}

/// The calibration of `engine` on `rows` (and `rest`) and the calibrated engine, its error
/// naming the engine file and the data it was calibrated on.
fn calibrated(
    a: &CalibrateArgs,
    engine: &Engine,
    rows: &[crate::diagnosis::snapshot::Snapshot],
    rest: &[crate::calibrate::startup::RestReading],
    candidates: Vec<crate::calibrate::candidates::Candidate>,
    settings: &CalibrationSettings,
) -> anyhow::Result<(Calibration, Engine)> {
    calibrate(engine, rows, rest, candidates, settings).with_context(|| {
        format!(
            "calibrating {} on {}",
            a.engine.display(),
            sources(a).join(", ")
        )
    })
}

/// With `--ensemble`, the calibrations on parts of the baseline ([`crate::calibrate::ensemble`])
/// and their wall time, s; none without it.
fn ensemble(
    a: &CalibrateArgs,
    engine: &Engine,
    rows: &[crate::diagnosis::snapshot::Snapshot],
    rest: &[crate::calibrate::startup::RestReading],
    candidates: &[crate::calibrate::candidates::Candidate],
    settings: &CalibrationSettings,
) -> anyhow::Result<(Vec<Member>, f64)> {
    if !a.ensemble {
        return Ok((Vec::new(), 0.0));
    }
    let start = Instant::now();
    let members = crate::calibrate::ensemble::members(engine, rows, rest, candidates, settings)
        .map_err(|e| anyhow::anyhow!("--ensemble: {e}"))?;
    Ok((members, start.elapsed().as_secs_f64()))
}

/// The ensemble's members for `--json`: file, rows left out, fit.
fn ensemble_json(members: &[Member], files: &[String]) -> Vec<serde_json::Value> {
    members
        .iter()
        .zip(files)
        .map(|(m, f)| {
            json!({
                "file": f,
                "left_out_lines": m.left_out,
                "rms_after": m.report.rms_after,
                "baseline_fit": m.report.baseline_fit.verdict.as_str(),
            })
        })
        .collect()
}

/// The ensemble's members in the text report.
fn print_ensemble(members: &[Member], files: &[String], secs: f64) {
    if members.is_empty() {
        return;
    }
    println!(
        "\nensemble (--ensemble): {} calibrations, each without an interleaved part of the \
         interior loads ({secs:.1} s); a snapshot diagnosis on the written file reads each group \
         with them too and states their spread",
        members.len()
    );
    for (m, f) in members.iter().zip(files) {
        println!(
            "  without lines {:?}: RMS {:.2} σ, baseline fit {} → {f}",
            m.left_out,
            m.report.rms_after,
            m.report.baseline_fit.verdict.as_str()
        );
    }
}

/// With `validate`, every point left out in turn ([`leave_one_out`]) with `settings`, and with
/// an adaptation also with the design values only (what the adaptation is to improve on); the
/// wall time of both, s.
fn validations(
    validate: bool,
    engine: &Engine,
    rows: &[crate::diagnosis::snapshot::Snapshot],
    rest: &[crate::calibrate::startup::RestReading],
    candidates: &[crate::calibrate::candidates::Candidate],
    settings: &CalibrationSettings,
) -> anyhow::Result<(Option<Validation>, Option<Validation>, f64)> {
    if !validate {
        return Ok((None, None, 0.0));
    }
    let start = Instant::now();
    let v = leave_one_out(engine, rows, rest, candidates, settings).context("--validate")?;
    let design_only = match settings.adapt {
        None => None,
        Some(_) => {
            let plain = CalibrationSettings {
                adapt: None,
                ..settings.clone()
            };
            Some(
                leave_one_out(engine, rows, rest, candidates, &plain)
                    .context("--validate (design values only)")?,
            )
        }
    };
    Ok((Some(v), design_only, start.elapsed().as_secs_f64()))
}

/// Writes the calibrated engine file to `--out` (the file's text `original` with the fitted
/// values and the `extra` ones (`--dynamics`), the header lines `head` and, with `--ensemble`,
/// its members' files in `[adaptation.ensemble]`) and checks it loads, maps included; says so when there is no
/// `--out`.
fn write_out(
    a: &CalibrateArgs,
    original: &str,
    report: &Calibration,
    head: &[String],
    ensemble_files: &[String],
    mut extra: Vec<(String, NewValue)>,
) -> anyhow::Result<()> {
    let Some(out) = &a.out else {
        eprintln!("no --out given: nothing written");
        return Ok(());
    };
    // The ensemble's members, written first, are listed in the file they belong to.
    if !ensemble_files.is_empty() {
        extra.push((
            "adaptation.ensemble.files".to_string(),
            NewValue::Words(ensemble_files.to_vec()),
        ));
    }
    write_file(a, original, out, report, head, extra)
}

/// The path of ensemble member `j` (from 1) beside `out`: `unit.toml` → `unit.part1.toml`.
fn member_path(out: &Path, j: usize) -> PathBuf {
    let stem = out
        .file_stem()
        .map_or_else(|| "calibrated".into(), |s| s.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}.part{j}.toml"))
}

/// Writes each ensemble member beside `--out` with its own header and a line saying which
/// rows it left out (of the `n_rows` calibrated); their absolute paths, in order.
fn write_members(
    a: &CalibrateArgs,
    original: &str,
    members: &[Member],
    n_rows: usize,
) -> anyhow::Result<Vec<String>> {
    let Some(out) = &a.out else {
        return Ok(Vec::new());
    };
    let mut paths = Vec::new();
    for (j, m) in members.iter().enumerate() {
        let path = member_path(out, j + 1);
        let mut h = vec![format!(
            "One of {} calibrations of an ensemble (gtwatch calibrate --ensemble): the baseline \
             without lines {:?}; RMS {:.2} σ, baseline fit {}",
            members.len(),
            m.left_out,
            m.report.rms_after,
            m.report.baseline_fit.verdict.as_str()
        )];
        h.extend(header(
            a,
            &m.report,
            n_rows.saturating_sub(m.left_out.len()),
        ));
        write_file(a, original, &path, &m.report, &h, Vec::new())?;
        let abs = std::path::absolute(&path).with_context(|| path.display().to_string())?;
        paths.push(abs.display().to_string());
    }
    Ok(paths)
}

/// Writes `report`'s calibrated engine file to `out` (see [`write_out`]).
fn write_file(
    a: &CalibrateArgs,
    original: &str,
    out: &Path,
    report: &Calibration,
    head: &[String],
    extra: Vec<(String, NewValue)>,
) -> anyhow::Result<()> {
    let from_dir = a.engine.parent().unwrap_or_else(|| Path::new(""));
    let to_dir = out.parent().unwrap_or_else(|| Path::new(""));
    let mut values = fitted_values(report);
    values.extend(extra);
    values.extend(moved_map_paths(original, &a.engine, from_dir, to_dir)?);
    let text = rewrite(original, &a.engine.display().to_string(), &values, head)?;
    std::fs::write(out, &text).with_context(|| format!("writing {}", out.display()))?;
    // The written file must load, maps included.
    let check = EngineConfig::load(out)?;
    Engine::new(check).with_context(|| format!("checking the written {}", out.display()))?;
    eprintln!("wrote {}", out.display());
    Ok(())
}

/// `header` with the `--validate` summaries, when run: the file then says how well it predicted
/// the points left out of its own calibration.
fn with_validation(
    mut header: Vec<String>,
    v: Option<&Validation>,
    design_only: Option<&Validation>,
) -> Vec<String> {
    let Some(v) = v else {
        return header;
    };
    let said = |s: &Option<Summary>| {
        s.map_or("none predicted".to_string(), |s| {
            format!(
                "mean |error| {:.3} %, worst {:.3} % ({} point(s)){}",
                s.mean_pct,
                s.worst_pct,
                s.points,
                print::beside_noise(&s)
            )
        })
    };
    header.push(format!(
        "  validated (--validate: each point left out in turn and predicted): interior points {}; \
         every point {}",
        said(&v.interior),
        said(&v.all)
    ));
    if let Some(d) = design_only {
        header.push(format!(
            "  the design values alone, likewise: interior points {}",
            said(&d.interior)
        ));
    }
    header
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        args: CalibrateArgs,
    }

    fn parsed(extra: &[&str]) -> Result<CalibrateArgs, clap::Error> {
        let mut argv = vec!["calibrate", "--engine", "e.toml", "--input", "s.csv"];
        argv.extend_from_slice(extra);
        Cli::try_parse_from(argv).map(|c| c.args)
    }

    /// `--adapt-max-knots` sets the adaptation's most knots (1–12), only beside `--adapt`.
    #[test]
    fn adapt_max_knots_sets_the_most_knots_only_with_adapt() {
        let a = parsed(&["--adapt", "--adapt-max-knots", "3"]).expect("parses");
        assert_eq!(adapt_settings(&a).map(|s| s.max_knots), Some(3));
        let a = parsed(&["--adapt"]).expect("parses");
        assert_eq!(
            adapt_settings(&a).map(|s| s.max_knots),
            Some(AdaptSettings::default().max_knots)
        );
        assert!(adapt_settings(&parsed(&[]).expect("parses")).is_none());
        for bad in [
            &["--adapt", "--adapt-max-knots", "0"][..],
            &["--adapt", "--adapt-max-knots", "13"],
            &["--adapt-max-knots", "3"],
        ] {
            let e = parsed(bad).expect_err("refused").to_string();
            assert!(e.contains("--adapt"), "{bad:?}: {e}");
        }
    }
}
