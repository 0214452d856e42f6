//! `gtwatch diagnose --input` of a log without phase labels: the start-up detector run over
//! the file in memory (`detect::in_memory`, the rules `gtwatch replay` applies), one start-up
//! chosen (`--start`, else the first that can be diagnosed) and handed to the diagnosis as if
//! the file had carried its phases. So a historian's export of a start-up, or another
//! simulator's, is diagnosed in one command without a database or a config file.
//! Must not store anything or guess a start the detector did not find.

use crate::detect::in_memory::{find_startups, FoundStartup};
use crate::detect::DetectorConfig;
use crate::diagnosis::csv_input::{read_log_checked, read_recording_checked, CsvQuality, Log};
use crate::engine::Engine;
use crate::recording::Recording;
use crate::units::ColumnUnits;
use anyhow::{bail, Context};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::path::Path;

/// The start-up chosen from a log, with what was found around it.
pub(super) struct LogStartup {
    /// Its samples, labelled with the detected phases.
    pub recording: Recording,
    /// The cells the bad-value policy flagged in the whole file.
    pub flagged: CsvQuality,
    /// What was found and chosen (JSON `startup`).
    pub summary: Value,
    /// The same in words, for the text output.
    pub lines: Vec<String>,
}

/// A start-up file as the commands that fit one read it: with its phase column as it is (then
/// `found` is `None`), else as a log whose start-up `start` (or the first diagnosable one) the
/// detector finds. `--start` on a file with phases is refused.
pub(super) fn read_startup_file(
    input: &Path,
    mapping: &HashMap<String, String>,
    units: &ColumnUnits,
    engine: &Engine,
    start: Option<usize>,
) -> anyhow::Result<(Recording, CsvQuality, Option<LogStartup>)> {
    if !has_phase_column(input, mapping)? {
        let (log, flagged) = read_log(input, mapping, units)?;
        let found = startup_from_log(input, &log, flagged, engine, start)?;
        return Ok((found.recording.clone(), found.flagged.clone(), Some(found)));
    }
    if start.is_some() {
        bail!(
            "--start picks a start-up of a log without phase labels; {} carries its phases \
             (one start-up)",
            input.display()
        );
    }
    let (rec, flagged) = labelled(input, mapping, units)?;
    Ok((rec, flagged, None))
}

/// Whether `input`'s header has the phase column (`phase`, or the one `mapping` names).
pub(super) fn has_phase_column(
    input: &Path,
    mapping: &HashMap<String, String>,
) -> anyhow::Result<bool> {
    use std::io::BufRead;
    let file =
        std::fs::File::open(input).with_context(|| format!("opening {}", input.display()))?;
    let mut header = String::new();
    std::io::BufReader::new(file)
        .read_line(&mut header)
        .with_context(|| format!("reading {}", input.display()))?;
    let phase = mapping.get("phase").map_or("phase", String::as_str);
    Ok(header
        .split(',')
        .any(|h| h.trim().trim_matches('"').eq_ignore_ascii_case(phase)))
}

/// `input` read as a start-up with its phase column.
fn labelled(
    input: &Path,
    mapping: &HashMap<String, String>,
    units: &ColumnUnits,
) -> anyhow::Result<(Recording, CsvQuality)> {
    let file =
        std::fs::File::open(input).with_context(|| format!("opening {}", input.display()))?;
    read_recording_checked(
        std::io::BufReader::new(file),
        mapping,
        units,
        &crate::quality::QualityConfig::default(),
    )
    .with_context(|| format!("reading {}", input.display()))
}

/// Every start-up of a file that can be diagnosed: the file itself when it carries its phases,
/// else each start-up the detector finds in it that reached load (`calibrate --startup`).
pub(super) fn startups_of_file(
    input: &Path,
    mapping: &HashMap<String, String>,
    units: &ColumnUnits,
    engine: &Engine,
) -> anyhow::Result<Vec<Recording>> {
    if has_phase_column(input, mapping)? {
        return Ok(vec![labelled(input, mapping, units)?.0]);
    }
    let (log, flagged) = read_log(input, mapping, units)?;
    let found = find_startups(&log.t_s, &log.rows, &detector_config(engine));
    let usable: Vec<Recording> = found
        .into_iter()
        .filter(FoundStartup::diagnosable)
        .filter_map(|f| f.recording.and_then(Result::ok))
        .collect();
    if usable.is_empty() {
        // The reason in the words `diagnose` gives it.
        startup_from_log(input, &log, flagged, engine, None)?;
        bail!("{}: no usable start-up", input.display());
    }
    Ok(usable)
}

/// Whether `input`, read as a log, holds a start-up the detector finds (any outcome); a file
/// that cannot be read as one (a snapshot file without a time column) holds none.
pub(super) fn holds_a_startup(
    input: &Path,
    mapping: &HashMap<String, String>,
    units: &ColumnUnits,
    engine: &Engine,
) -> bool {
    read_log(input, mapping, units).is_ok_and(|(log, _)| {
        !find_startups(&log.t_s, &log.rows, &detector_config(engine)).is_empty()
    })
}

fn read_log(
    input: &Path,
    mapping: &HashMap<String, String>,
    units: &ColumnUnits,
) -> anyhow::Result<(Log, CsvQuality)> {
    let file =
        std::fs::File::open(input).with_context(|| format!("opening {}", input.display()))?;
    read_log_checked(
        std::io::BufReader::new(file),
        mapping,
        units,
        &crate::quality::QualityConfig::default(),
    )
    .with_context(|| format!("reading {}", input.display()))
}

/// The detector's settings for a log of this engine: the defaults with the engine file's
/// sequence speeds, PT speed and base load (as a `[detector]` section that sets none).
fn detector_config(engine: &Engine) -> DetectorConfig {
    let mut cfg = DetectorConfig::default();
    cfg.fill_from_engine(None, engine.cfg());
    cfg
}

/// Finds the start-ups of `log` (read from `input`, its flagged cells `flagged`) with the
/// engine's sequence speeds and picks `start` (1-based over every start found) or the first
/// diagnosable one.
fn startup_from_log(
    input: &Path,
    log: &Log,
    flagged: CsvQuality,
    engine: &Engine,
    start: Option<usize>,
) -> anyhow::Result<LogStartup> {
    let cfg = detector_config(engine);
    let found = find_startups(&log.t_s, &log.rows, &cfg);
    let origin_ms = log.origin_ms;
    let at = |f: &FoundStartup| match origin_ms {
        Some(t0) => format!(" ({})", crate::time::fmt_ms_rfc3339(t0 + f.record.start_ms)),
        None => String::new(),
    };
    let mut lines: Vec<String> = found
        .iter()
        .enumerate()
        .map(|(k, f)| format!("start {}: {}{}", k + 1, f.describe(), at(f)))
        .collect();
    let chosen = match start {
        Some(k) if k == 0 || k > found.len() => bail!(
            "--start {k}: {} holds {} start-up(s){}",
            input.display(),
            found.len(),
            listing(&lines)
        ),
        Some(k) => k - 1,
        None => match found.iter().position(FoundStartup::diagnosable) {
            Some(k) => k,
            None if found.is_empty() => bail!(
                "{} has no phase column and the start-up detector found no start in it (GG \
                 speed rising from rest with fuel: n1_rpm and fuel_kg_s are needed, power_mw \
                 for the breaker; purge {:.0} rpm and idle {:.0} rpm from the engine file's \
                 [sequence]). A file of steady points is read with `--method steady`",
                input.display(),
                cfg.purge_speed_rpm,
                cfg.idle_speed_rpm
            ),
            None => bail!(
                "{}: no start-up in it reached load, so none can be diagnosed{}",
                input.display(),
                listing(&lines)
            ),
        },
    };
    let f = &found[chosen];
    let recording = match f.recording.clone().filter(|_| f.diagnosable()) {
        Some(Ok(r)) => r,
        Some(Err(e)) => {
            let line = e
                .index()
                .and_then(|i| log.lines.get(f.first_sample + i))
                .map(|l| format!("line {l}: "))
                .unwrap_or_default();
            bail!(
                "{}: start {} cannot be diagnosed: {line}{e}",
                input.display(),
                chosen + 1
            )
        }
        None => bail!(
            "--start {}: it did not reach load, so it cannot be diagnosed{}",
            chosen + 1,
            listing(&lines)
        ),
    };
    lines.push(format!(
        "diagnosing start {} of {}{}",
        chosen + 1,
        found.len(),
        if f.completed() {
            String::new()
        } else {
            "; the data end before the detector's steady-load hold closed it, so it is fitted \
             up to the last sample"
                .into()
        }
    ));
    let summary = json!({
        "chosen": chosen + 1,
        "found": found.iter().enumerate().map(|(k, f)| json!({
            "start": k + 1,
            "start_s": f.start_s(),
            "start_utc": origin_ms.map(|t0| crate::time::fmt_ms_rfc3339(t0 + f.record.start_ms)),
            "outcome": f.record.outcome,
            "abort_cause": f.record.abort_cause,
            "hot_restart": f.record.hot_restart,
            "phases": f.record.phases.iter().map(|p| p.phase.name()).collect::<Vec<_>>(),
            "diagnosable": f.diagnosable(),
        })).collect::<Vec<_>>(),
    });
    Ok(LogStartup {
        recording,
        flagged,
        summary,
        lines,
    })
}

fn listing(lines: &[String]) -> String {
    if lines.is_empty() {
        String::new()
    } else {
        format!(":\n  {}", lines.join("\n  "))
    }
}
