//! `gtwatch diagnose --method steady` on a snapshot file: each row one averaged steady
//! operating point (performance tests, historian averages), diagnosed per row or per
//! `--group-by` group (`diagnosis::snapshot`). Prints text or one JSON document.
//! Must not open the database or store results: it reads a file and prints.
//!
//! Line numbers, everywhere (text, JSON `lines`, `dropped_lines`, `dropped[].line`,
//! `failed[].lines`, the residual table's `line`, and the reader's error messages) are file
//! lines with the header as line 1: the first data row is line 2.

use super::diagnose::{print_text_of, result_json, DiagnoseArgs};
use crate::diagnosis::ensemble::{ensemble_read, EnsembleRead};
use crate::diagnosis::snapshot::{diagnose_snapshots, read_snapshots_in};
use crate::diagnosis::steady::model_error_note;
use crate::diagnosis::{DiagnosisConfig, Method};
use crate::engine::config::EngineConfig;
use crate::engine::Engine;
use crate::units::ColumnUnits;
use anyhow::{bail, Context};
use serde_json::json;
use std::collections::HashMap;
use std::io::BufReader;
use std::path::Path;
use std::process::ExitCode;

/// Whether `--method steady` should read `input` as snapshots: asked for (`--snapshots`,
/// `--group-by`), or the file has no phase column and is no log in which the start-up detector
/// finds a start (a historian's export of one: Method A on its steady windows, as for a
/// labelled start-up; read as snapshots, its rows at rest failed the unit check at line 2).
pub(super) fn wants_snapshots(
    a: &DiagnoseArgs,
    input: &Path,
    mapping: &HashMap<String, String>,
    units: &crate::units::ColumnUnits,
    engine: &crate::engine::Engine,
) -> anyhow::Result<bool> {
    if a.snapshots || a.group_by.is_some() {
        return Ok(true);
    }
    if a.method != super::diagnose::MethodArg::Steady {
        return Ok(false);
    }
    let labelled = super::diagnose_log::has_phase_column(input, mapping)?;
    Ok(!labelled && !super::diagnose_log::holds_a_startup(input, mapping, units, engine))
}

/// Each group read again with the calibrations the engine file lists in
/// `[adaptation.ensemble]` (`calibrate --ensemble`), by group name; empty without them. A
/// relative path is taken from the engine file's directory. A member file that cannot be read
/// is an error naming it; a group a member cannot diagnose is recorded as such.
fn ensemble_reads(
    a: &DiagnoseArgs,
    engine: &Engine,
    rows: &[crate::diagnosis::snapshot::Snapshot],
    cfg: &DiagnosisConfig,
    report: &crate::diagnosis::snapshot::SnapshotReport,
) -> anyhow::Result<HashMap<String, EnsembleRead>> {
    let Some(files) = engine
        .cfg()
        .adaptation
        .as_ref()
        .and_then(|ad| ad.ensemble.as_ref())
        .map(|e| e.files.clone())
    else {
        return Ok(HashMap::new());
    };
    let dir = a
        .engine
        .as_deref()
        .and_then(Path::parent)
        .unwrap_or_else(|| Path::new(""));
    let mut member_reports = Vec::new();
    for f in &files {
        let path = dir.join(f);
        let member = EngineConfig::load(&path)
            .map_err(anyhow::Error::from)
            .and_then(|c| Engine::new(c).map_err(anyhow::Error::from))
            .with_context(|| {
                format!(
                    "[adaptation.ensemble] names {} (calibrate --ensemble writes it beside the \
                     engine file)",
                    path.display()
                )
            })?;
        member_reports.push((f.clone(), diagnose_snapshots(&member, rows, cfg)));
    }
    Ok(report
        .groups
        .iter()
        .map(|g| {
            let members = member_reports
                .iter()
                .map(|(f, r)| {
                    let read = match r {
                        Err(e) => Err(e.to_string()),
                        Ok(r) => r
                            .groups
                            .iter()
                            .find(|x| x.group == g.group)
                            .map(|x| x.result.clone())
                            .ok_or_else(|| {
                                r.failed
                                    .iter()
                                    .find(|x| x.group == g.group)
                                    .map_or("not diagnosed".to_string(), |x| x.reason.clone())
                            }),
                    };
                    (f.clone(), read)
                })
                .collect();
            (g.group.clone(), ensemble_read(&g.result, members))
        })
        .collect())
}

/// Runs the snapshot diagnosis of `input`.
pub(super) fn run(
    a: &DiagnoseArgs,
    input: &Path,
    engine: &Engine,
    cfg: &DiagnosisConfig,
    mapping: &HashMap<String, String>,
    units: &ColumnUnits,
) -> anyhow::Result<ExitCode> {
    if a.method != super::diagnose::MethodArg::Steady {
        bail!("snapshot files are diagnosed with --method steady (no start-up to run Method B on)");
    }
    let file =
        std::fs::File::open(input).with_context(|| format!("opening {}", input.display()))?;
    let rows = read_snapshots_in(BufReader::new(file), mapping, units, a.group_by.as_deref())
        .with_context(|| format!("reading {}", input.display()))?;
    let report = diagnose_snapshots(engine, &rows, cfg)?;
    let ensembles = ensemble_reads(a, engine, &rows, cfg, &report)?;
    if a.json {
        let groups: Vec<_> = report
            .groups
            .iter()
            .map(|g| {
                let mut v = result_json(&g.result);
                if let Some(o) = v.as_object_mut() {
                    // A snapshot is a point, not a window of a start-up: its lines say where.
                    o.remove("steady_windows_s");
                    o.insert("group".into(), json!(g.group));
                    o.insert("lines".into(), json!(g.lines));
                    o.insert(
                        "dropped_lines".into(),
                        json!(crate::diagnosis::snapshot::lines_of(&g.dropped)),
                    );
                    o.insert("dropped".into(), json!(g.dropped));
                    o.insert("assumptions".into(), json!(g.assumptions));
                    o.insert("residual_table".into(), json!(g.residual_table));
                    if let Some(e) = ensembles.get(&g.group) {
                        o.insert("ensemble".into(), json!(e));
                    }
                }
                v
            })
            .collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({
                "method": "steady_snapshots",
                "group_by": a.group_by,
                "rows": rows.len(),
                "groups": groups,
                "failed": report.failed,
            }))?
        );
    } else {
        println!(
            "{} snapshot row(s), {} group(s) diagnosed, {} not",
            rows.len(),
            report.groups.len(),
            report.failed.len()
        );
        // With a stated model error the σ is the instrument's and the model's together.
        let scale = if model_error_note(engine.cfg()).is_some() {
            "in σ of noise and model error"
        } else {
            "in noise σ"
        };
        for g in &report.groups {
            println!("group {} (lines {:?})", g.group, g.lines);
            for s in &g.assumptions {
                println!("  note: {s}");
            }
            for d in &g.dropped {
                println!("  line {} not used: {}", d.line, d.reason);
            }
            print_text_of(
                "steady snapshots",
                "these snapshots",
                Method::Steady,
                &g.result,
            );
            if let Some(e) = ensembles.get(&g.group) {
                println!("  {}", e.describe());
                for m in &e.members {
                    match (&m.health, &m.failed) {
                        (Some(h), _) => {
                            let v: Vec<String> = crate::health::HEALTH_NAMES
                                .iter()
                                .filter_map(|k| h.get(*k).map(|x| format!("{k} {x:+.2}")))
                                .collect();
                            println!(
                                "    {}: {} ({})",
                                m.file,
                                v.join(", "),
                                m.fit.as_deref().unwrap_or("")
                            );
                        }
                        (None, why) => {
                            println!("    {}: not read: {}", m.file, why.as_deref().unwrap_or(""))
                        }
                    }
                }
            }
            if !g.residual_table.rows.is_empty() {
                println!("  residuals per row (model − measured, {scale}):");
                for l in g.residual_table.render().lines() {
                    println!("    {l}");
                }
            }
        }
        for f in &report.failed {
            println!(
                "group {} (lines {:?}): not diagnosed: {}",
                f.group, f.lines, f.reason
            );
        }
    }
    if report.groups.is_empty() {
        bail!(
            "no group could be diagnosed{}",
            report
                .failed
                .first()
                .map(|f| format!(" (first: {})", f.reason))
                .unwrap_or_default()
        );
    }
    Ok(if report.failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
