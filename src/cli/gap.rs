//! `gtwatch gap`: where the model and this start-up disagree, which effect of the library
//! explains it, and how far the gap shrinks with it (`src/gap`); `--list-effects` lists the
//! library. Reads the CSV like `gtwatch diagnose`; prints text or one JSON document.
//! With `--segment` it reads the stored start-up through a read-only handle and stores the
//! result afterwards in one short write, so it runs beside the daemon. Must not hold analysis
//! logic of its own (that is `crate::gap`) or a database handle across the analysis.

use super::diagnose::FitArgs;
use crate::diagnosis::csv_input::parse_mapping;
use crate::recording::Recording;
use anyhow::{bail, Context};
use clap::Args;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// `gtwatch gap`
#[derive(Debug, Clone, Args)]
pub struct GapArgs {
    /// List the effects library (names, instances, parameters, signatures) and exit.
    #[arg(long)]
    pub list_effects: bool,
    /// Start-up CSV (the layout `gtwatch simulate` writes, or any CSV with --map).
    #[arg(long, required_unless_present_any = ["list_effects", "segment"], conflicts_with = "segment")]
    pub input: Option<PathBuf>,
    /// Instead of a CSV: a stored start-up (engine from --config's [plant]); the result is
    /// stored in the database's `gap_analyses` table.
    #[arg(long)]
    pub segment: Option<i64>,
    /// With --segment: a second stored start-up of the unit to score candidates on.
    #[arg(long, requires = "segment")]
    pub holdout_segment: Option<i64>,
    /// Config file (with --segment): database path, engine file.
    #[arg(long, requires = "segment")]
    pub config: Option<PathBuf>,
    /// Database (with --segment; default: --config's [storage].path).
    #[arg(long, requires = "segment")]
    pub db: Option<PathBuf>,
    /// A second start-up of the same unit: candidates are scored on it (held out).
    #[arg(long)]
    pub holdout: Option<PathBuf>,
    /// Candidate effects: `all` or a comma-separated list of instance names.
    #[arg(long, default_value = "all")]
    pub effects: String,
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
    /// Engine TOML (default: the built-in reference engine).
    #[arg(long)]
    pub engine: Option<PathBuf>,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Write the engine file with the identified effect adopted (an `[effects]` table with its
    /// fitted parameters) to this path; later diagnoses with `--engine` that file use the
    /// augmented model. Refuses to overwrite an existing file.
    #[arg(long, value_name = "ENGINE.toml")]
    pub adopt: Option<PathBuf>,
    /// Write the residual map (signals × phases) as an SVG heat-map.
    #[arg(long, value_name = "FILE.svg")]
    pub svg: Option<PathBuf>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// Writes the adopted engine file (validated by loading it first).
fn adopt(a: &GapArgs, report: &crate::gap::GapReport, out: &Path) -> anyhow::Result<String> {
    if out.exists() {
        bail!("{} exists: --adopt writes a new engine file", out.display());
    }
    let to_dir = out.parent().unwrap_or_else(|| Path::new(""));
    let base = match &a.engine {
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            // Map paths relative to the engine file, restated for the new file's folder.
            let from_dir = p.parent().unwrap_or_else(|| Path::new(""));
            let moved = super::common::moved_map_paths(&text, p, from_dir, to_dir)?;
            if moved.is_empty() {
                text
            } else {
                crate::calibrate::edit::rewrite(&text, &p.display().to_string(), &moved, &[])?
            }
        }
        None => crate::engine::config::REFERENCE_ENGINE_TOML.to_string(),
    };
    let source = a
        .input
        .as_ref()
        .map_or_else(String::new, |p| p.display().to_string());
    let Some(text) = crate::gap::adopted_engine_text(&base, report, &source) else {
        return Ok(format!(
            "nothing to adopt: the verdict is `{}`",
            report.verdict.effect
        ));
    };
    // The new file must load where it is written, maps included.
    let mut check = crate::engine::EngineConfig::from_toml_str(&text, &out.display().to_string())
        .context("the adopted engine file does not load")?;
    check.maps.resolve_relative_to(to_dir);
    crate::engine::Engine::new(check).context("the adopted engine file does not build")?;
    std::fs::write(out, text).with_context(|| format!("writing {}", out.display()))?;
    Ok(format!(
        "adopted {} into {} (diagnose with --engine {})",
        report.verdict.effect,
        out.display(),
        out.display()
    ))
}

fn read(path: &Path, a: &GapArgs, engine: &crate::engine::Engine) -> anyhow::Result<Recording> {
    let mapping = match &a.map {
        Some(m) => parse_mapping(m)?,
        None => HashMap::new(),
    };
    let units = super::common::column_units(a.units.as_deref(), engine)?;
    // A log without phase labels: its first start-up that reached load, as `diagnose` picks;
    // what was found is said on stderr (stdout may be the one JSON document).
    let (rec, _, found) =
        super::diagnose_log::read_startup_file(path, &mapping, &units, engine, None)?;
    for line in found.iter().flat_map(|f| &f.lines) {
        eprintln!("{}: {line}", path.display());
    }
    Ok(rec)
}

pub(super) fn run(a: &GapArgs) -> anyhow::Result<ExitCode> {
    if a.list_effects {
        print_effects(a.json)?;
        return Ok(ExitCode::SUCCESS);
    }
    let candidates = crate::gap::select(&a.effects).map_err(anyhow::Error::msg)?;
    let cfg = a.fit.config()?;
    let Inputs {
        engine,
        rec,
        holdout,
        store,
    } = inputs(a)?;
    let report = crate::gap::analyse(&engine, &rec, holdout.as_ref(), &candidates, &cfg)?;
    if let (Some(db), Some(id)) = (&store, a.segment) {
        store_result(db, id, a.holdout_segment, &report)?;
    }
    if let Some(path) = &a.svg {
        let title = format!(
            "gtwatch gap: baseline fit {} (normalised residual {:.2}), verdict {}",
            report.baseline_fit_quality.as_str(),
            report.baseline_normalised_residual,
            report.verdict.effect
        );
        std::fs::write(path, crate::gap::svg::document(&report, &title))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let adopted = match &a.adopt {
        Some(out) => Some(adopt(a, &report, out)?),
        None => None,
    };
    if a.json {
        let mut v = serde_json::to_value(&report)?;
        if let Some(msg) = &adopted {
            v["adopted"] = serde_json::json!(msg);
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(ExitCode::SUCCESS);
    }
    print_report(&report);
    if let Some(msg) = adopted {
        println!("{msg}");
    }
    Ok(ExitCode::SUCCESS)
}

/// `--list-effects`: the library's effects, as text or JSON.
fn print_effects(json: bool) -> anyhow::Result<()> {
    if json {
        let list = crate::gap::list_effects();
        println!("{}", serde_json::to_string_pretty(&list)?);
        return Ok(());
    }
    // Columns as wide as the longest name (plus a space), so no name runs into its text.
    let registry = crate::engine::effects::REGISTRY;
    let name_w = registry.iter().map(|e| e.name.len()).max().unwrap_or(0) + 1;
    let param_w = registry
        .iter()
        .flat_map(|e| e.params.iter().map(|p| p.name.len()))
        .max()
        .unwrap_or(0)
        + 1;
    for e in registry {
        println!("{:name_w$} {}", e.name, e.summary);
        for p in e.params {
            println!(
                "  {:param_w$} {} [{}, {}] default {}: {}",
                p.name, p.unit, p.min, p.max, p.default, p.doc
            );
        }
        println!("  signature: {}", e.signature);
    }
    Ok(())
}

/// What the analysis runs on: the engine, the start-up, the held-out start-up, and (with
/// `--segment`) the database the result is stored in.
struct Inputs {
    engine: crate::engine::Engine,
    rec: Recording,
    holdout: Option<Recording>,
    store: Option<PathBuf>,
}

/// Reads the inputs from the CSV files (`--input`, `--holdout`) or the store (`--segment`).
fn inputs(a: &GapArgs) -> anyhow::Result<Inputs> {
    match (&a.input, a.segment) {
        (Some(input), _) => {
            let engine = super::load_engine(a.engine.as_deref())?;
            let holdout = match &a.holdout {
                Some(p) => Some(read(p, a, &engine)?),
                None => None,
            };
            Ok(Inputs {
                rec: read(input, a, &engine)?,
                engine,
                holdout,
                store: None,
            })
        }
        (None, Some(id)) => stored_inputs(a, id),
        (None, None) => bail!("--input or --segment is required (or --list-effects)"),
    }
}

/// The inputs of `--segment id`: the stored start-ups, read through a read-only handle that
/// is closed before the analysis.
fn stored_inputs(a: &GapArgs, id: i64) -> anyhow::Result<Inputs> {
    let db = super::common::db_path(a.db.as_ref(), a.config.as_ref())?;
    // Read-only while the (long) analysis runs; the result is stored afterwards in one
    // short write, also beside a running daemon.
    let s = crate::store::Store::open_readonly(&db)
        .with_context(|| format!("opening {}", db.display()))?;
    let stored = |seg: i64| -> anyhow::Result<Recording> {
        let r = s
            .segment_recording(seg)?
            .with_context(|| format!("no segment {seg} in {}", db.display()))?;
        r.recording
            .with_context(|| format!("segment {seg} cannot be analysed"))
    };
    let rec = stored(id)?;
    let holdout = match a.holdout_segment {
        Some(h) => Some(stored(h)?),
        None => None,
    };
    let engine = match &a.engine {
        Some(p) => super::load_engine(Some(p))?,
        None => super::diagnose_stored::worker_context(a.config.as_deref())?.engine,
    };
    drop(s);
    Ok(Inputs {
        engine,
        rec,
        holdout,
        store: Some(db),
    })
}

/// Stores the analysis of segment `id` in one short write.
fn store_result(
    db: &Path,
    id: i64,
    holdout_segment: Option<i64>,
    report: &crate::gap::GapReport,
) -> anyhow::Result<()> {
    crate::store::Store::open(db)
        .with_context(|| format!("opening {}", db.display()))?
        .insert_gap_analysis(&crate::store::NewGapAnalysis {
            segment_id: id,
            holdout_segment_id: holdout_segment,
            effect: report.verdict.effect.clone(),
            shrinkage: report.verdict.shrinkage,
            confidence: report.verdict.confidence,
            baseline_fit_quality: report.baseline_fit_quality.as_str().into(),
            normalised_residual: report.baseline_normalised_residual,
            report_json: serde_json::to_string(report)?,
        })
        .context("storing the gap analysis")?;
    Ok(())
}

/// The report as text: the baseline, the candidates, the verdict and the aliases.
fn print_report(report: &crate::gap::GapReport) {
    println!(
        "baseline fit: {} (normalised residual {:.2})",
        report.baseline_fit_quality.as_str(),
        report.baseline_normalised_residual
    );
    if !report.summary.is_empty() {
        println!("where: {}", report.summary);
    }
    if let Some(z) = report.fuel_meter_zero {
        println!(
            "fuel meter zero: it read {:+.4} kg/s before light-off (median of {} readings); \
             taken off every fuel reading before the fits",
            z.kg_s, z.samples
        );
    }
    if report.optimiser_spread > 0.0 {
        println!(
            "optimiser spread (baseline refitted with other seeds): {:.0} % of the residual",
            100.0 * report.optimiser_spread
        );
    }
    print_candidates(report);
    let v = &report.verdict;
    println!(
        "verdict: {} (shrinkage {:.0} %, confidence {:.2}) in {:.0} s ({} fits on {} threads)",
        v.effect,
        100.0 * v.shrinkage,
        v.confidence,
        report.wall_s,
        report.fits,
        report.threads
    );
    if let Some(d) = &v.doubted {
        println!(
            "  {d} explains the residual, yet needs a health further beyond new than the \
             baseline's; the instruments below would make the baseline's plausible"
        );
    }
    if !v.aliases.is_empty() {
        println!(
            "  the health may be hiding an error of: {} (one start-up cannot tell; see below)",
            v.aliases.join(", ")
        );
    }
    if crate::gap::names_effect(&v.effect)
        && v.fit_quality_after != crate::diagnosis::fit_quality::Verdict::Good
    {
        // The effect explains part of the gap only: the health after still absorbs the rest.
        println!(
            "  with {} the fit is still {}: the plant's effect differs from the library's form, \
             and the health after carries what it leaves (trust it no more than the fit)",
            v.effect,
            v.fit_quality_after.as_str()
        );
    }
    let (b, f) = (v.health_before.to_array(), v.health_after.to_array());
    for (i, n) in crate::health::HEALTH_NAMES.iter().enumerate() {
        println!("  {n:5} {:8.3} → {:8.3} %", b[i], f[i]);
    }
    print_aliases(&report.aliases);
}

/// The candidates with their scores, and those the linear screen left unfitted.
fn print_candidates(report: &crate::gap::GapReport) {
    if !report.candidates.is_empty() {
        let how = match report.scoring {
            crate::gap::Scoring::Holdout => "the held-out start-up".to_string(),
            crate::gap::Scoring::BlockedCv => format!(
                "blocked cross-validation (alternate {:.0}-s blocks)",
                crate::gap::CV_BLOCK_S
            ),
        };
        println!("candidates scored by {how}:");
    }
    for c in &report.candidates {
        println!(
            "  {:24} score {:+.2} (train {:+.2}{}) BIC gain {:.0} → {}{}",
            c.effect,
            c.score,
            c.train_shrinkage,
            c.heldout_shrinkage
                .map_or(String::new(), |h| format!(", held out {h:+.2}")),
            c.bic_gain,
            c.fit_quality.as_str(),
            if c.within_model_error() {
                format!(
                    " (within the adapted model's own error on its channel, {:.3e}: not told \
                     from the model's miss)",
                    c.model_error.unwrap_or(0.0)
                )
            } else {
                String::new()
            }
        );
    }
    if !report.unscreened.is_empty() {
        let list: Vec<String> = report
            .unscreened
            .iter()
            .map(|u| format!("{} {:.2}", u.effect, u.predicted_shrinkage))
            .collect();
        println!(
            "not fitted (linear screen's predicted shrinkage): {}",
            list.join(", ")
        );
    }
}

/// The input instruments the health may hide, with the health each implies.
fn print_aliases(a: &crate::gap::alias::Aliases) {
    if a.aliases.is_empty() {
        return;
    }
    println!(
        "input instruments the health parameters absorb (absorbed share; health shift for the \
         nominal error; '*' = can hide, one start-up cannot tell):"
    );
    for x in &a.aliases {
        let shift: Vec<String> = crate::health::HEALTH_NAMES
            .iter()
            .zip(x.health_shift.to_array())
            .filter(|(_, v)| v.abs() >= 0.1)
            .map(|(n, v)| format!("{n} {v:+.2}"))
            .collect();
        println!(
            "  {}{:24} {:3.0} %  {} {:+} {}: {}",
            if x.hidden { '*' } else { ' ' },
            x.effect,
            100.0 * x.absorbed,
            x.param,
            x.nominal,
            x.unit,
            if shift.is_empty() {
                "—".to_string()
            } else {
                shift.join(", ")
            }
        );
        if let (Some(m), Some(h)) = (x.plausible_magnitude, x.health_if_plausible) {
            let hv: Vec<String> = crate::health::HEALTH_NAMES
                .iter()
                .zip(h.to_array())
                .map(|(n, v)| format!("{n} {v:+.2}"))
                .collect();
            println!(
                "      the baseline's health is better than new; at {m:+.4} {} it would be: {}",
                x.unit,
                hv.join(", ")
            );
        }
    }
}
