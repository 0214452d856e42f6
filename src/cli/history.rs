//! `gtwatch history [--param D_GC,…] [--since …] [--until …] [--method A|B]
//! [--format table|csv|json]`: the stored health results, one row per start-up and method.
//!
//! JSON is one array of objects (`segment_id`, `start_ms`, `start_utc`, `method`, `health`,
//! `sigma`, `objective`, `residual_level`, `fit_quality`, `wash_id_before`, `gap_verdict`: the
//! verdict of the start-up's newest stored gap analysis, which names an instrument when one
//! explains the start-up; `gap_doubted`: the candidate an `ambiguous` verdict doubted, see
//! `gap::GapVerdict::doubted`; the table shows it beside the verdict, the CSV as its last
//! column). Reads the database read-only; the query is `Store::history`. Must not compute
//! trends.

use super::common::{db_path, parse_cli_time};
use crate::health::HEALTH_NAMES;
use crate::query::Format;
use crate::store::{HistoryFilter, HistoryRow, Store};
use anyhow::bail;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodFilter {
    A,
    B,
}

#[derive(Debug, clap::Args)]
pub struct HistoryArgs {
    /// Config file (for [storage].path).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Database file (instead of --config).
    #[arg(long)]
    pub db: Option<PathBuf>,
    /// Parameters to show, comma-separated (default: all six).
    #[arg(long, value_delimiter = ',')]
    pub param: Vec<String>,
    /// Only start-ups beginning at or after this time (2024-03-01, 2024-03-01T06:00:00Z, @EPOCH_S).
    #[arg(long)]
    pub since: Option<String>,
    /// Only start-ups beginning at or before this time.
    #[arg(long)]
    pub until: Option<String>,
    /// Only this method (A steady-state, B transient).
    #[arg(long, value_enum, ignore_case = true)]
    pub method: Option<MethodFilter>,
    #[arg(long, value_enum, default_value_t = Format::Table)]
    pub format: Format,
}

/// The parameter names asked for, canonical spelling, in catalogue order.
fn params(asked: &[String]) -> anyhow::Result<Vec<&'static str>> {
    if asked.is_empty() {
        return Ok(HEALTH_NAMES.to_vec());
    }
    let mut out = Vec::new();
    for a in asked {
        match HEALTH_NAMES
            .iter()
            .find(|n| n.eq_ignore_ascii_case(a.trim()))
        {
            Some(n) => out.push(*n),
            None => bail!(
                "--param '{a}' is not a health parameter (one of {})",
                HEALTH_NAMES.join(", ")
            ),
        }
    }
    Ok(out)
}

/// A result's CSV cells for `names`: value and σ each to 4 decimals, empty where absent.
pub(super) fn health_csv_cells(
    health: &BTreeMap<String, f64>,
    sigma: &BTreeMap<String, f64>,
    names: &[&str],
) -> Vec<String> {
    let cell = |v: Option<&f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
    names
        .iter()
        .flat_map(|n| [cell(health.get(*n)), cell(sigma.get(*n))])
        .collect()
}

/// A result's table cells for `names`: `value ± σ` (NaN where absent).
pub(super) fn write_health_cells(
    out: &mut dyn Write,
    health: &BTreeMap<String, f64>,
    sigma: &BTreeMap<String, f64>,
    names: &[&str],
) -> std::io::Result<()> {
    for n in names {
        let v = health.get(*n).copied().unwrap_or(f64::NAN);
        let s = sigma.get(*n).copied().unwrap_or(f64::NAN);
        write!(out, " {:>15}", format!("{v:.2} ± {s:.2}"))?;
    }
    Ok(())
}

/// The end of a result's table row: its fit quality and gap verdict.
pub(super) fn write_quality_and_gap(
    out: &mut dyn Write,
    fit_quality: Option<&str>,
    gap_verdict: Option<&str>,
    gap_doubted: Option<&str>,
) -> std::io::Result<()> {
    let doubted = gap_doubted.map_or(String::new(), |d| format!(" (doubted {d})"));
    writeln!(
        out,
        "  {:<8} {}{doubted}",
        fit_quality.unwrap_or("-"),
        gap_verdict.unwrap_or("")
    )
}

/// Writes the rows in `format`, showing `names` only.
pub(super) fn write_history(
    rows: &[HistoryRow],
    names: &[&str],
    format: Format,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    match format {
        Format::Json => {
            let docs: Vec<serde_json::Value> = rows
                .iter()
                .map(|r| {
                    let pick = |m: &std::collections::BTreeMap<String, f64>| {
                        names
                            .iter()
                            .filter_map(|n| {
                                m.get(*n).map(|v| ((*n).to_string(), serde_json::json!(v)))
                            })
                            .collect::<serde_json::Map<_, _>>()
                    };
                    serde_json::json!({
                        "diagnosis_id": r.diagnosis_id,
                        "segment_id": r.segment_id,
                        "start_ms": r.start_ms,
                        "start_utc": r.start_utc,
                        "method": r.method,
                        "health": pick(&r.health),
                        "sigma": pick(&r.sigma),
                        "objective": r.objective,
                        "residual_level": r.residual_level,
                        "fit_quality": r.fit_quality,
                        "wash_id_before": r.wash_id_before,
                        "gap_verdict": r.gap_verdict,
                        "gap_doubted": r.gap_doubted,
                    })
                })
                .collect();
            writeln!(out, "{}", serde_json::to_string_pretty(&docs)?)?;
        }
        Format::Csv => {
            let mut head = vec!["segment_id", "start_utc", "method"];
            let sig: Vec<String> = names.iter().map(|n| format!("sigma_{n}")).collect();
            for (n, s) in names.iter().zip(&sig) {
                head.push(n);
                head.push(s);
            }
            head.extend([
                "residual_level",
                "fit_quality",
                "wash_id_before",
                "gap_verdict",
                "gap_doubted",
            ]);
            writeln!(out, "{}", head.join(","))?;
            for r in rows {
                let mut cells = vec![
                    r.segment_id.to_string(),
                    r.start_utc.clone(),
                    r.method.clone(),
                ];
                cells.extend(health_csv_cells(&r.health, &r.sigma, names));
                cells.push(
                    r.residual_level
                        .map_or(String::new(), |v| format!("{v:.3}")),
                );
                cells.push(r.fit_quality.clone().unwrap_or_default());
                cells.push(r.wash_id_before.map_or(String::new(), |v| v.to_string()));
                cells.push(r.gap_verdict.clone().unwrap_or_default());
                cells.push(r.gap_doubted.clone().unwrap_or_default());
                writeln!(out, "{}", cells.join(","))?;
            }
        }
        Format::Table => {
            write!(out, "{:>7}  {:<24} {:<2}", "segment", "start (UTC)", "m")?;
            for n in names {
                write!(out, " {:>15}", format!("{n} ±1σ %"))?;
            }
            writeln!(out, "  quality  gap")?;
            for r in rows {
                write!(
                    out,
                    "{:>7}  {:<24} {:<2}",
                    r.segment_id, r.start_utc, r.method
                )?;
                write_health_cells(out, &r.health, &r.sigma, names)?;
                write_quality_and_gap(
                    out,
                    r.fit_quality.as_deref(),
                    r.gap_verdict.as_deref(),
                    r.gap_doubted.as_deref(),
                )?;
            }
            if rows.is_empty() {
                writeln!(out, "(no diagnoses stored)")?;
            }
        }
    }
    Ok(())
}

pub(super) fn run(args: HistoryArgs) -> anyhow::Result<ExitCode> {
    let path = db_path(args.db.as_ref(), args.config.as_ref())?;
    let names = params(&args.param)?;
    let filter = HistoryFilter {
        since_ms: args.since.as_deref().map(parse_cli_time).transpose()?,
        until_ms: args.until.as_deref().map(parse_cli_time).transpose()?,
        method: args.method.map(|m| match m {
            MethodFilter::A => "A".to_string(),
            MethodFilter::B => "B".to_string(),
        }),
    };
    let store = Store::open_readonly(&path)?;
    let rows = store.history(&filter)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    write_history(&rows, &names, args.format, &mut out)?;
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table's last columns: the fit quality, the gap verdict and, when the verdict doubted
    /// a candidate, which.
    #[test]
    fn the_table_shows_a_doubted_candidate_beside_the_verdict() {
        let mut out: Vec<u8> = Vec::new();
        write_quality_and_gap(
            &mut out,
            Some("suspect"),
            Some("ambiguous"),
            Some("fuel_meter_offset"),
        )
        .expect("write");
        assert_eq!(
            String::from_utf8(out).expect("utf-8"),
            "  suspect  ambiguous (doubted fuel_meter_offset)\n"
        );
        let mut out: Vec<u8> = Vec::new();
        write_quality_and_gap(&mut out, None, None, None).expect("write");
        assert_eq!(String::from_utf8(out).expect("utf-8"), "  -        \n");
    }
}
