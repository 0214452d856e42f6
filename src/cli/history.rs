//! `gtwatch history [--param D_GC,…] [--since …] [--until …] [--method A|B]
//! [--format table|csv|json]`: the stored health results, one row per start-up and method.
//!
//! JSON is one array of objects (`segment_id`, `start_ms`, `start_utc`, `method`, `health`,
//! `sigma`, `objective`, `residual_level`, `fit_quality`, `wash_id_before`, `gap_verdict`: the
//! verdict of the start-up's newest stored gap analysis, which names an instrument when one
//! explains the start-up; `gap_doubted`: the candidate an `ambiguous` verdict doubted, see
//! `gap::GapVerdict::doubted`; the table shows it beside the verdict, the CSV as its column;
//! `instrument_step`: when the wash advice's joint fit of the start-ups since the last firm
//! wash named an instrument's step from this start-up or an earlier one on, the instrument,
//! its error and the health corrected for it, `health` staying as fitted; the table shows it
//! as a line under the result, the CSV as `instrument_step` and `<param>_corrected` columns;
//! `gap_health_after`: the health the start-up's newest gap analysis gives with its named
//! effect, shown the same way under a Method B result whose analysis names an instrument and
//! that no joint fit corrected). Reads the database read-only; the query is `Store::history`.
//! Must not compute
//! trends.

use super::common::{db_path, parse_cli_time, FormatArgs};
use crate::engine::effects::is_instrument;
use crate::health::HEALTH_NAMES;
use crate::query::Format;
use crate::store::{HistoryFilter, HistoryRow, InstrumentCorrection, Store};
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
    #[command(flatten)]
    pub output: FormatArgs,
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

/// The values of `names` among six in `HEALTH_NAMES` order, by name.
pub(super) fn shown(values: &[f64; 6], names: &[&str]) -> BTreeMap<String, f64> {
    HEALTH_NAMES
        .iter()
        .zip(values)
        .filter(|(n, _)| names.contains(n))
        .map(|(n, v)| (n.to_string(), *v))
        .collect()
}

/// Index of health parameter `name` in `HEALTH_NAMES` (names come from [`params`]).
fn health_index(name: &str) -> usize {
    HEALTH_NAMES.iter().position(|n| *n == name).unwrap_or(0)
}

/// The corrected health a result shows under its fitted one, and where it comes from.
pub(super) struct ShownCorrection {
    health: [f64; 6],
    /// Its 1σ, where the correction states one (the wash advice's joint fit).
    sigma: Option<[f64; 6]>,
    /// The CSV's `instrument_step` cell.
    label: String,
    /// The end of the table's line.
    source: String,
}

impl ShownCorrection {
    /// The wash advice's joint fit's correction of a start-up.
    pub(super) fn of_step(c: &InstrumentCorrection) -> ShownCorrection {
        let also = if c.also.is_empty() {
            String::new()
        } else {
            format!("; also {}", c.also)
        };
        ShownCorrection {
            health: c.health,
            sigma: Some(c.sigma),
            label: c.describe_all(),
            source: format!(
                "instrument {} from start-up {} on{also} (wash advice's joint fit)",
                c.describe(),
                c.onset_segment_id
            ),
        }
    }

    /// The CSV cells `instrument_step` and `<param>_corrected` of `names`; empty without one.
    pub(super) fn csv_cells(c: Option<&ShownCorrection>, names: &[&str]) -> Vec<String> {
        let mut cells = vec![c.map_or(String::new(), |c| c.label.clone())];
        for n in names {
            cells.push(c.map_or(String::new(), |c| {
                format!("{:.4}", c.health[health_index(n)])
            }));
        }
        cells
    }
}

/// The JSON of the wash advice's correction of a start-up (`instrument_step`), `names` shown.
pub(super) fn instrument_step_json(c: &InstrumentCorrection, names: &[&str]) -> serde_json::Value {
    serde_json::json!({
        "effect": c.effect,
        "unit": c.unit,
        "magnitude": c.magnitude,
        "magnitude_sigma": c.magnitude_sigma,
        "onset_segment_id": c.onset_segment_id,
        "also": c.also,
        "health_corrected": shown(&c.health, names),
        "sigma_corrected": shown(&c.sigma, names),
    })
}

/// What a result shows as corrected: the wash advice's joint fit when it corrected this
/// start-up, else, for a Method B result whose own newest gap analysis names an instrument
/// (the start-up the advice sets aside), that analysis's health after (it refits the
/// transient: not Method A's).
fn correction_of(r: &HistoryRow) -> Option<ShownCorrection> {
    ShownCorrection::of(
        r.instrument_step.as_ref(),
        &r.method,
        r.gap_verdict.as_deref(),
        r.gap_health_after,
    )
}

impl ShownCorrection {
    /// What a result (its method, correction, gap verdict and that analysis's health after)
    /// shows as corrected: see [`correction_of`]. `fleet history` shows the same.
    pub(super) fn of(
        step: Option<&InstrumentCorrection>,
        method: &str,
        gap_verdict: Option<&str>,
        gap_health_after: Option<[f64; 6]>,
    ) -> Option<ShownCorrection> {
        if let Some(c) = step {
            return Some(ShownCorrection::of_step(c));
        }
        let effect = gap_verdict?;
        if method != "B" || !is_instrument(effect) {
            return None;
        }
        gap_health_after.map(|health| ShownCorrection {
            health,
            sigma: None,
            label: format!("{effect} (gap analysis)"),
            source: format!("instrument {effect} (this start-up's gap analysis)"),
        })
    }
}

/// The table's line under a result an instrument moved: its corrected health under the
/// fitted values, and where the correction comes from.
pub(super) fn write_corrected_line(
    out: &mut dyn Write,
    c: &ShownCorrection,
    names: &[&str],
) -> std::io::Result<()> {
    write!(out, "{:>7}  {:<24} {:<2}", "", "  corrected:", "")?;
    for n in names {
        let i = health_index(n);
        let cell = match c.sigma {
            Some(s) => format!("{:.2} ± {:.2}", c.health[i], s[i]),
            None => format!("{:.2}", c.health[i]),
        };
        write!(out, " {cell:>15}")?;
    }
    writeln!(out, "  {}", c.source)
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
                        "gap_health_after": r.gap_health_after.map(|h| shown(&h, names)),
                        "instrument_step": r
                            .instrument_step
                            .as_ref()
                            .map(|c| instrument_step_json(c, names)),
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
                "instrument_step",
            ]);
            let corrected: Vec<String> = names.iter().map(|n| format!("{n}_corrected")).collect();
            head.extend(corrected.iter().map(String::as_str));
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
                cells.extend(ShownCorrection::csv_cells(correction_of(r).as_ref(), names));
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
                if let Some(c) = correction_of(r) {
                    write_corrected_line(out, &c, names)?;
                }
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
    write_history(&rows, &names, args.output.format(), &mut out)?;
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::InstrumentCorrection;

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

    /// A result an instrument's step moved: the table shows its corrected health on a line
    /// under the fitted one, the CSV and JSON as their own fields; the fitted values stay.
    #[test]
    fn a_corrected_result_shows_the_instrument_and_the_corrected_health() {
        let names = ["D_GC", "D_EP"];
        let row = HistoryRow {
            diagnosis_id: 7,
            segment_id: 5,
            start_ms: 0,
            start_utc: "1970-01-01T00:00:00.000Z".into(),
            method: "B".into(),
            health: HEALTH_NAMES.iter().map(|n| (n.to_string(), -1.5)).collect(),
            sigma: HEALTH_NAMES.iter().map(|n| (n.to_string(), 0.1)).collect(),
            objective: 1.0,
            residual_level: Some(0.8),
            fit_quality: Some("good".into()),
            wash_id_before: None,
            gap_verdict: None,
            gap_doubted: None,
            gap_health_after: None,
            instrument_step: Some(InstrumentCorrection {
                segment_id: 5,
                onset_segment_id: 4,
                effect: "fuel_meter".into(),
                unit: "fraction".into(),
                magnitude: 0.0257,
                magnitude_sigma: 0.0021,
                health: [1.25, 0.5, 0.0, 0.0, 0.0, 0.75],
                sigma: [0.125; 6],
                also: String::new(),
            }),
        };
        let text = |format: Format| {
            let mut out: Vec<u8> = Vec::new();
            write_history(std::slice::from_ref(&row), &names, format, &mut out).expect("write");
            String::from_utf8(out).expect("utf-8")
        };
        let table = text(Format::Table);
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 3, "{table}");
        assert!(lines[1].contains("-1.50 ± 0.10"), "{table}");
        assert!(lines[2].contains("corrected:"), "{table}");
        assert!(lines[2].contains("1.25 ± 0.12"), "{table}");
        assert!(lines[2].contains("0.75 ± 0.12"), "{table}");
        assert!(
            lines[2].contains("instrument fuel_meter +2.57 ± 0.21 % from start-up 4 on"),
            "{table}"
        );
        let csv = text(Format::Csv);
        let mut csv_lines = csv.lines();
        let head: Vec<&str> = csv_lines.next().expect("head").split(',').collect();
        let cells: Vec<&str> = csv_lines.next().expect("row").split(',').collect();
        let at = |c: &str| cells[head.iter().position(|h| *h == c).expect(c)];
        assert_eq!(at("D_GC"), "-1.5000");
        assert_eq!(at("D_GC_corrected"), "1.2500");
        assert_eq!(at("D_EP_corrected"), "0.7500");
        assert_eq!(at("instrument_step"), "fuel_meter +2.57 ± 0.21 %");
        let json: serde_json::Value = serde_json::from_str(&text(Format::Json)).expect("json");
        let step = &json[0]["instrument_step"];
        assert_eq!(step["effect"], "fuel_meter");
        assert_eq!(step["onset_segment_id"], 4);
        assert_eq!(step["health_corrected"]["D_EP"], 0.75);
        assert!(step["health_corrected"].get("D_EC").is_none());
        assert_eq!(json[0]["health"]["D_GC"], -1.5);
    }

    /// A Method B result whose own gap analysis names an instrument shows that analysis's
    /// health after as corrected; the Method A result of the same start-up does not.
    #[test]
    fn a_start_up_its_own_gap_analysis_explains_shows_the_health_after() {
        let names = ["D_GC"];
        let row = |method: &str| HistoryRow {
            diagnosis_id: 1,
            segment_id: 29,
            start_ms: 0,
            start_utc: "1970-01-01T00:00:00.000Z".into(),
            method: method.into(),
            health: HEALTH_NAMES.iter().map(|n| (n.to_string(), 0.08)).collect(),
            sigma: HEALTH_NAMES.iter().map(|n| (n.to_string(), 0.1)).collect(),
            objective: 1.0,
            residual_level: Some(0.7),
            fit_quality: Some("suspect".into()),
            wash_id_before: None,
            gap_verdict: Some("fuel_meter".into()),
            gap_doubted: None,
            gap_health_after: Some([3.18, 1.01, 1.03, 0.58, 0.17, -0.18]),
            instrument_step: None,
        };
        let table = |r: HistoryRow| {
            let mut out: Vec<u8> = Vec::new();
            write_history(&[r], &names, Format::Table, &mut out).expect("write");
            String::from_utf8(out).expect("utf-8")
        };
        let b = table(row("B"));
        assert!(
            b.lines().nth(2).is_some_and(|l| l.contains("3.18")
                && l.contains("instrument fuel_meter (this start-up's gap analysis)")),
            "{b}"
        );
        assert_eq!(table(row("A")).lines().count(), 2);
        let mut inlet = row("B");
        inlet.gap_verdict = Some("heat_soak".into());
        assert_eq!(table(inlet).lines().count(), 2, "not an instrument");
    }
}
