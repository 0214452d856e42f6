//! `gtwatch fleet history --postgres-url URL [--unit ID] [--method A|B]
//! [--format table|csv|json]`: every unit's health results at the centre, one row per start-up
//! and method, as `gtwatch history` shows one unit's.
//!
//! JSON is one array of objects (`unit_id`, `segment_id` (the edge's), `start_ms`,
//! `start_utc`, `method`, `health`, `sigma`, `residual_level`, `fit_quality`, `gap_verdict`,
//! `instrument_step`: the health the unit's wash advice corrected for an instrument's step, as
//! `gtwatch history` prints it; the table shows it as a `corrected:` line, the CSV as
//! `instrument_step` and `<param>_corrected` columns).
//! Reads the centre only; the query is `fleet::fleet_history`. Must not compute trends.
//!
//! Also `gtwatch fleet report --postgres-url URL --out DIR`: `DIR/fleet.html`, the page
//! `report::fleet` builds from the centre's results, washes and advice.

use super::common::FormatArgs;
use super::history::{
    health_csv_cells, instrument_step_json, shown, write_corrected_line, write_health_cells,
    write_quality_and_gap, MethodFilter, ShownCorrection,
};
use crate::fleet::{
    fleet_advice, fleet_history, fleet_washes, Centre, FleetHistoryFilter, FleetHistoryRow,
};
use crate::health::HEALTH_NAMES;
use crate::query::Format;
use crate::time::fmt_ms_rfc3339;
use anyhow::Context;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(Debug, clap::Args)]
pub struct FleetHistoryArgs {
    /// Central database, e.g. postgresql://gtwatch:secret@127.0.0.1:5432/fleet.
    #[arg(long)]
    pub postgres_url: String,
    /// Only this unit.
    #[arg(long)]
    pub unit: Option<String>,
    /// Only this method (A steady-state, B transient).
    #[arg(long, value_enum, ignore_case = true)]
    pub method: Option<MethodFilter>,
    /// The fleet re-diagnosis under this config hash (printed by `fleet rediagnose`) instead
    /// of the edges' own results.
    #[arg(long)]
    pub config_hash: Option<String>,
    #[command(flatten)]
    pub output: FormatArgs,
}

#[derive(Debug, clap::Args)]
pub struct FleetReportArgs {
    /// Central database, e.g. postgresql://gtwatch:secret@127.0.0.1:5432/fleet.
    #[arg(long)]
    pub postgres_url: String,
    /// Folder for `fleet.html` (created when missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Chart the fleet re-diagnosis under this config hash instead of the edges' results.
    #[arg(long)]
    pub config_hash: Option<String>,
}

pub(super) fn run_report(args: &FleetReportArgs) -> anyhow::Result<ExitCode> {
    let mut centre = Centre::connect_existing(&args.postgres_url, Duration::from_secs(30))?;
    let rows = fleet_history(
        &mut centre,
        &FleetHistoryFilter {
            config_hash: args.config_hash.clone(),
            ..FleetHistoryFilter::default()
        },
    )?;
    let washes = fleet_washes(&mut centre)?;
    let advice = fleet_advice(&mut centre)?;
    let page = crate::report::fleet::fleet_html(&centre.name, &rows, &washes, &advice);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let path = args.out.join("fleet.html");
    std::fs::write(&path, &page).with_context(|| format!("writing {}", path.display()))?;
    let units: std::collections::BTreeSet<&str> = rows.iter().map(|r| r.unit_id.as_str()).collect();
    println!(
        "wrote {} ({} KB): {} unit(s), {} result(s), {} wash(es)",
        path.display(),
        page.len().div_ceil(1024),
        units.len(),
        rows.len(),
        washes.len()
    );
    Ok(ExitCode::SUCCESS)
}

pub(super) fn run(args: &FleetHistoryArgs) -> anyhow::Result<ExitCode> {
    let mut centre = Centre::connect_existing(&args.postgres_url, Duration::from_secs(30))?;
    let filter = FleetHistoryFilter {
        unit_id: args.unit.clone(),
        method: args.method.map(|m| match m {
            MethodFilter::A => "A".to_string(),
            MethodFilter::B => "B".to_string(),
        }),
        config_hash: args.config_hash.clone(),
    };
    let rows = fleet_history(&mut centre, &filter)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match args.output.format() {
        Format::Json => write_json(&mut out, &rows)?,
        Format::Csv => write_csv(&mut out, &rows)?,
        Format::Table => write_table(&mut out, &rows)?,
    }
    Ok(ExitCode::SUCCESS)
}

/// What a central result shows as corrected, as `gtwatch history` decides it at the edge.
fn shown_correction(r: &FleetHistoryRow) -> Option<ShownCorrection> {
    ShownCorrection::of(
        r.instrument_step.as_ref(),
        &r.method,
        r.gap_verdict.as_deref(),
        r.gap_health_after,
    )
}

fn write_json(out: &mut dyn Write, rows: &[FleetHistoryRow]) -> anyhow::Result<()> {
    let docs: Vec<serde_json::Value> = rows
        .iter()
        .map(|r| {
            serde_json::json!({
                "unit_id": r.unit_id,
                "segment_id": r.segment_id,
                "start_ms": r.start_ms,
                "start_utc": fmt_ms_rfc3339(r.start_ms),
                "method": r.method,
                "health": r.health,
                "sigma": r.sigma,
                "residual_level": r.residual_level,
                "fit_quality": r.fit_quality,
                "gap_verdict": r.gap_verdict,
                "gap_health_after": r.gap_health_after.map(|h| shown(&h, &HEALTH_NAMES)),
                "instrument_step": r
                    .instrument_step
                    .as_ref()
                    .map(|c| instrument_step_json(c, &HEALTH_NAMES)),
            })
        })
        .collect();
    writeln!(out, "{}", serde_json::to_string_pretty(&docs)?)?;
    Ok(())
}

fn write_csv(out: &mut dyn Write, rows: &[FleetHistoryRow]) -> anyhow::Result<()> {
    let mut head: Vec<String> = vec!["unit_id".into(), "segment_id".into(), "start_utc".into()];
    head.push("method".into());
    for n in HEALTH_NAMES {
        head.push(n.to_string());
        head.push(format!("sigma_{n}"));
    }
    head.extend(
        [
            "residual_level",
            "fit_quality",
            "gap_verdict",
            "instrument_step",
        ]
        .map(String::from),
    );
    head.extend(HEALTH_NAMES.iter().map(|n| format!("{n}_corrected")));
    writeln!(out, "{}", head.join(","))?;
    for r in rows {
        let mut cells = vec![
            r.unit_id.clone(),
            r.segment_id.to_string(),
            fmt_ms_rfc3339(r.start_ms),
            r.method.clone(),
        ];
        cells.extend(health_csv_cells(&r.health, &r.sigma, &HEALTH_NAMES));
        cells.push(
            r.residual_level
                .map_or(String::new(), |v| format!("{v:.3}")),
        );
        cells.push(r.fit_quality.clone().unwrap_or_default());
        cells.push(r.gap_verdict.clone().unwrap_or_default());
        cells.extend(ShownCorrection::csv_cells(
            shown_correction(r).as_ref(),
            &HEALTH_NAMES,
        ));
        writeln!(out, "{}", cells.join(","))?;
    }
    Ok(())
}

fn write_table(out: &mut dyn Write, rows: &[FleetHistoryRow]) -> anyhow::Result<()> {
    write!(
        out,
        "{:<16} {:>7}  {:<24} {:<2}",
        "unit", "segment", "start (UTC)", "m"
    )?;
    for n in HEALTH_NAMES {
        write!(out, " {:>15}", format!("{n} ±1σ %"))?;
    }
    writeln!(out, "  quality  gap")?;
    for r in rows {
        write!(
            out,
            "{:<16} {:>7}  {:<24} {:<2}",
            r.unit_id,
            r.segment_id,
            fmt_ms_rfc3339(r.start_ms),
            r.method
        )?;
        write_health_cells(out, &r.health, &r.sigma, &HEALTH_NAMES)?;
        write_quality_and_gap(
            out,
            r.fit_quality.as_deref(),
            r.gap_verdict.as_deref(),
            None,
        )?;
        if let Some(c) = shown_correction(r) {
            // Under the unit's columns, as `gtwatch history` writes it under the segment's.
            write!(out, "{:<16} ", "")?;
            write_corrected_line(out, &c, &HEALTH_NAMES)?;
        }
    }
    if rows.is_empty() {
        writeln!(out, "(no results at the centre)")?;
    }
    Ok(())
}
