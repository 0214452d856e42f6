//! Reads a measured start-up from CSV into a [`Recording`]: the layout `gtwatch simulate` writes (`time_s,phase,`
//! then the signal columns by [`Signal::column`] name; any `true_…` columns are ignored), or any
//! CSV with a column mapping `time_s=Time,phase=State,n1_rpm=NGG,…` (canonical name = header in
//! the file). Signal columns are matched by canonical column name or short name
//! (case-insensitive). Empty cells and `nan`/`NA` are missing samples (NaN, excluded from the
//! objective, never zero); any other unparseable cell, an unknown phase or a time that does not
//! increase is an error naming the line and column. Cells the bad-value policy (`[quality]`,
//! the same rules as replay and acquisition) flags as stuck or a spike become missing too
//! (out-of-range values stay errors naming the line), and are counted ([`CsvQuality`]). Reads from any `io::Read`; opens no files.

use crate::quality::{Point, Quality, QualityConfig, QualityCounts, SpikeFilter};
use crate::recording::{Recording, RecordingError};
use crate::signals::{Phase, Signal, Values, NSIG};
use crate::units::ColumnUnits;
use std::collections::HashMap;
use std::io::Read;

/// A problem with the CSV input.
#[derive(Debug, thiserror::Error)]
pub enum CsvError {
    #[error("CSV: {0}")]
    Csv(#[from] csv::Error),
    #[error("column mapping entry '{0}' is not NAME=COLUMN")]
    BadMapping(String),
    #[error(
        "column mapping names '{0}', which is not time_s, phase, p_amb_kpa or a signal column"
    )]
    UnknownTarget(String),
    #[error("required column '{0}' is missing from the header")]
    MissingColumn(String),
    /// A start-up without its phase labels (a plant log, another simulator's output).
    #[error(
        "required column '{0}' is missing from the header: a start-up's rows need their phase \
         (standstill, crank, purge, light_off, acceleration, idle, synchronisation, loading, \
         steady; the `gtwatch simulate` layout). `gtwatch diagnose`, `gap` and `calibrate \
         --startup` find the start-ups of a log without them themselves; `gtwatch replay` \
         stores them; a file of steady points is read with `--method steady`"
    )]
    MissingPhase(String),
    #[error("line {line}, column '{column}': {reason}")]
    Cell {
        line: u64,
        column: String,
        reason: String,
    },
    #[error("no data rows")]
    Empty,
    /// A historian's long layout (`tag,time,value[,status]`): one row per tag and time.
    #[error(
        "the header ({0}) is a long layout, one row per tag and time stamp: this command reads \
         one column per signal. `gtwatch replay` reads long files ([replay] layout = \"long\") \
         and finds their start-ups; then `gtwatch diagnose --segment ID`"
    )]
    LongLayout(String),
    /// A log whose time steps are no sampling period a start-up is recorded at (a time column
    /// in milliseconds read as seconds).
    #[error(
        "the median time step is {median_s} s, outside {} … {} s: a time column must be \
         seconds or ISO 8601 date-times (one in milliseconds divides by 1000 first)",
        crate::recording::MIN_SAMPLE_PERIOD_S,
        crate::recording::MAX_SAMPLE_PERIOD_S
    )]
    Period { median_s: f64 },
    /// The rows do not form a usable recording (see [`Recording::new`]).
    #[error("{}{source}", line.map(|l| format!("line {l}: ")).unwrap_or_default())]
    Recording {
        line: Option<u64>,
        source: RecordingError,
    },
}

/// Canonical name of the ambient (barometric) pressure column, kPa: read by the snapshot
/// diagnosis (`diagnosis::snapshot`); a start-up's ambient pressure comes from P1 at rest.
pub use crate::units::AMBIENT_PRESSURE_COLUMN;

/// Parses a mapping `time_s=Time,phase=State,n1_rpm=NGG` (canonical = file header).
pub fn parse_mapping(s: &str) -> Result<HashMap<String, String>, CsvError> {
    let mut m = HashMap::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (k, v) = part
            .split_once('=')
            .ok_or_else(|| CsvError::BadMapping(part.into()))?;
        let k = k.trim();
        let canonical = if k.eq_ignore_ascii_case("time_s") || k.eq_ignore_ascii_case("time") {
            "time_s".to_string()
        } else if k.eq_ignore_ascii_case("phase") {
            "phase".to_string()
        } else if k.eq_ignore_ascii_case(AMBIENT_PRESSURE_COLUMN) {
            AMBIENT_PRESSURE_COLUMN.to_string()
        } else {
            k.parse::<Signal>()
                .map_err(|_| CsvError::UnknownTarget(k.into()))?
                .column()
                .to_string()
        };
        m.insert(canonical, v.trim().to_string());
    }
    Ok(m)
}

fn parse_phase(s: &str) -> Option<Phase> {
    s.parse::<Phase>()
        .ok()
        .or_else(|| s.trim().parse::<u16>().ok().and_then(Phase::from_code))
}

pub(crate) fn parse_value(s: &str) -> Result<f64, String> {
    let t = s.trim();
    if t.is_empty()
        || ["nan", "na", "n/a", "null"]
            .iter()
            .any(|m| t.eq_ignore_ascii_case(m))
    {
        return Ok(f64::NAN);
    }
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Ok(f64::NAN), // ±inf: an invalid reading, treated as missing
        Err(_) => Err(format!("'{t}' is not a number")),
    }
}

/// Reads a recording with the default bad-value policy; see [`read_recording_checked`].
pub fn read_recording<R: Read>(
    reader: R,
    mapping: &HashMap<String, String>,
) -> Result<Recording, CsvError> {
    read_recording_checked(
        reader,
        mapping,
        &ColumnUnits::default(),
        &QualityConfig::default(),
    )
    .map(|(r, _)| r)
}

/// Cells the bad-value policy flagged, per signal column (only columns with any flagged).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct CsvQuality {
    pub flagged: Vec<(Signal, QualityCounts)>,
}

impl CsvQuality {
    /// All flagged cells.
    pub fn total(&self) -> u64 {
        self.flagged.iter().map(|(_, c)| c.flagged()).sum()
    }
}

/// Applies `crate::quality`'s stateful rules (stuck, spike: the same as replay and acquisition)
/// to every signal column; a flagged cell becomes missing (NaN) and is counted.
fn apply_policy(
    quality: &QualityConfig,
    sig_cols: &[(Signal, usize)],
    t_s: &[f64],
    rows: &mut [Values],
) -> CsvQuality {
    let mut report = CsvQuality::default();
    let n1 = Signal::N1.index();
    let n1_ref: Vec<Option<f64>> = rows
        .iter()
        .map(|r| Some(r[n1]).filter(|v| v.is_finite()))
        .collect();
    for &(s, _) in sig_cols {
        let k = s.index();
        let mut checker = quality.checker(&[s.column(), s.short()], Some(s));
        let mut spikes = SpikeFilter::new(checker.limits());
        let mut counts = QualityCounts::default();
        let mut held: Option<usize> = None;
        let mut verdicts: Vec<(usize, Quality)> = Vec::new();
        for (i, row) in rows.iter().enumerate() {
            let v = row[k];
            if v.is_nan() {
                continue; // missing already
            }
            let t_ms = (t_s[i] * 1000.0).round() as i64;
            let q = checker.check(t_ms, v, n1_ref[i]);
            if let Some(p) = spikes.push(Point {
                t_ms,
                value: v,
                quality: q,
            }) {
                if let Some(j) = held {
                    verdicts.push((j, p.quality));
                }
            }
            held = Some(i);
        }
        if let (Some(p), Some(j)) = (spikes.finish(), held) {
            verdicts.push((j, p.quality));
        }
        for (j, q) in verdicts {
            // Out-of-range values are left to `Recording::new`, which refuses them naming the
            // line (an unusable file, not a flaky sensor).
            if matches!(q, Quality::Stuck | Quality::Spike) {
                counts.add(q);
                rows[j][k] = f64::NAN;
            }
        }
        if counts.flagged() > 0 {
            report.flagged.push((s, counts));
        }
    }
    report
}

/// A CSV file read into memory with its line ends normalised (see [`crlf_to_lf`]).
pub(crate) type CsvReader = csv::Reader<std::io::Cursor<Vec<u8>>>;

/// A CSV reader over `reader` (header row, cells trimmed) and its header.
pub(crate) fn open_csv<R: Read>(mut reader: R) -> Result<(CsvReader, csv::StringRecord), CsvError> {
    let mut raw = Vec::new();
    reader
        .read_to_end(&mut raw)
        .map_err(|e| CsvError::Csv(csv::Error::from(e)))?;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(std::io::Cursor::new(crlf_to_lf(raw)));
    let headers = rdr.headers()?.clone();
    Ok((rdr, headers))
}

/// `raw` with every CR LF line end as LF (a lone CR is kept). The csv reader counts lines at
/// LF and reports the records of a CR LF file — what spreadsheets and historians on Windows
/// write — one line early (rust-csv issue 395); the messages here name file lines.
fn crlf_to_lf(raw: Vec<u8>) -> Vec<u8> {
    if !raw.windows(2).any(|w| w == b"\r\n") {
        return raw;
    }
    let mut out = Vec::with_capacity(raw.len());
    for (i, &b) in raw.iter().enumerate() {
        if b == b'\r' && raw.get(i + 1) == Some(&b'\n') {
            continue;
        }
        out.push(b);
    }
    out
}

/// The header index of a canonical column: the file header `mapping` names for it, else the
/// canonical name itself or its short name, case-insensitive — never a header the mapping
/// gives to another column (a plant's `P3_KPA` mapped as the compressor discharge, `p2_kpa`,
/// is not also gtwatch's combustor-exit `p3_kpa`).
pub(crate) fn find_column(
    headers: &csv::StringRecord,
    mapping: &HashMap<String, String>,
    canonical: &str,
    short: Option<&str>,
) -> Option<usize> {
    if let Some(want) = mapping.get(canonical) {
        return headers.iter().position(|h| h.eq_ignore_ascii_case(want));
    }
    let taken = |h: &str| mapping.values().any(|v| h.eq_ignore_ascii_case(v));
    let named = |name: &str| {
        headers
            .iter()
            .position(|h| h.eq_ignore_ascii_case(name) && !taken(h))
    };
    named(canonical).or_else(|| short.and_then(named))
}

/// Reads a recording. `mapping` maps canonical names to the file's headers (empty = the
/// `gtwatch simulate` layout); `units` states the columns not in the model's units (converted
/// as read, before any check). The rows must also pass [`Recording::new`]'s checks; an error
/// there names the file line of the offending sample.
pub fn read_recording_checked<R: Read>(
    reader: R,
    mapping: &HashMap<String, String>,
    units: &ColumnUnits,
    quality: &QualityConfig,
) -> Result<(Recording, CsvQuality), CsvError> {
    let r = read_rows(reader, mapping, units, quality, Phases::Required)?;
    let rec = Recording::new(r.t_s, r.phases, r.rows).map_err(|source| CsvError::Recording {
        line: source.index().and_then(|i| r.lines.get(i).copied()),
        source,
    })?;
    Ok((rec, r.report))
}

/// A log as read: its rows in time order, not yet a [`Recording`] (a log may span days and
/// have holes; each start-up cut from it is checked as a recording then).
#[derive(Debug, Clone)]
pub struct Log {
    /// Times, s (from the first row when the file's are ISO 8601).
    pub t_s: Vec<f64>,
    /// Values per row, model units, indexed by [`Signal::index`] (NaN = missing).
    pub rows: Vec<Values>,
    /// The file line of each row.
    pub lines: Vec<u64>,
    /// The first row's time, Unix ms, when the file's times are ISO 8601.
    pub origin_ms: Option<i64>,
}

/// A recorded log without phase labels (a historian's export of a start-up or of days of
/// operation, another simulator's output): the same columns, units, checks and bad-value
/// policy as [`read_recording_checked`], no phase column, for `detect::in_memory` to find the
/// start-ups in.
pub fn read_log_checked<R: Read>(
    reader: R,
    mapping: &HashMap<String, String>,
    units: &ColumnUnits,
    quality: &QualityConfig,
) -> Result<(Log, CsvQuality), CsvError> {
    let r = read_rows(reader, mapping, units, quality, Phases::Absent)?;
    let mut steps: Vec<f64> = r.t_s.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    if let Some(&median_s) = steps.get(steps.len().saturating_sub(1) / 2) {
        let allowed = crate::recording::MIN_SAMPLE_PERIOD_S..=crate::recording::MAX_SAMPLE_PERIOD_S;
        if !allowed.contains(&median_s) {
            return Err(CsvError::Period { median_s });
        }
    }
    Ok((
        Log {
            t_s: r.t_s,
            rows: r.rows,
            lines: r.lines,
            origin_ms: r.origin_ms,
        },
        r.report,
    ))
}

/// What [`read_rows`] read.
struct Rows {
    t_s: Vec<f64>,
    phases: Vec<Phase>,
    rows: Vec<Values>,
    lines: Vec<u64>,
    report: CsvQuality,
    origin_ms: Option<i64>,
}

/// Whether the file carries its rows' phases.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phases {
    /// A `phase` column is required (a start-up as `gtwatch simulate` writes it).
    Required,
    /// None is read: every row is standstill until labelled.
    Absent,
}

/// Whether `headers` are a long layout's: `tag`, a time field, `value` and optionally
/// `status`, nothing else (names case-insensitive).
fn is_long_layout(headers: &csv::StringRecord) -> bool {
    let names: Vec<String> = headers.iter().map(str::to_ascii_lowercase).collect();
    let has = |n: &str| names.iter().any(|h| h == n);
    let known = |h: &String| {
        ["tag", "value", "status", "time", "timestamp", "time_s"].contains(&h.as_str())
    };
    has("tag") && has("value") && names.iter().all(known) && (3..=4).contains(&names.len())
}

/// One row's time: seconds, or an ISO 8601 date-time (then epoch ms, turned into seconds from
/// the first row's by the caller).
fn parse_time_cell(text: &str) -> Result<(f64, bool), String> {
    match parse_value(text) {
        Ok(t) => Ok((t, false)),
        Err(number_error) => crate::time::parse_iso8601_ms(text)
            .map(|ms| (ms as f64, true))
            .map_err(|_| format!("{number_error} nor an ISO 8601 date-time")),
    }
}

fn read_rows<R: Read>(
    reader: R,
    mapping: &HashMap<String, String>,
    units: &ColumnUnits,
    quality: &QualityConfig,
    phases_from: Phases,
) -> Result<Rows, CsvError> {
    let (mut rdr, headers) = open_csv(reader)?;
    if is_long_layout(&headers) {
        return Err(CsvError::LongLayout(
            headers.iter().collect::<Vec<_>>().join(","),
        ));
    }
    let find =
        |canonical: &str, short: Option<&str>| find_column(&headers, mapping, canonical, short);
    // A log's time column is often `time` or `timestamp`; a mapping names any other.
    let time_col = find("time_s", Some("time"))
        .or_else(|| find("time_s", Some("timestamp")))
        .ok_or_else(|| {
            CsvError::MissingColumn(mapping.get("time_s").cloned().unwrap_or("time_s".into()))
        })?;
    let phase_col = match phases_from {
        Phases::Required => Some(find("phase", None).ok_or_else(|| {
            CsvError::MissingPhase(mapping.get("phase").cloned().unwrap_or("phase".into()))
        })?),
        Phases::Absent => None,
    };
    let mut iso: Option<bool> = None;
    let sig_cols: Vec<(Signal, usize)> = Signal::ALL
        .iter()
        .filter_map(|&s| find(s.column(), Some(s.short())).map(|c| (s, c)))
        .collect();
    for (canonical, file_col) in mapping {
        if find(canonical, None).is_none() {
            return Err(CsvError::MissingColumn(file_col.clone()));
        }
    }
    let mut t_s: Vec<f64> = Vec::new();
    let mut phases: Vec<Phase> = Vec::new();
    let mut rows: Vec<Values> = Vec::new();
    let mut lines: Vec<u64> = Vec::new();
    for rec in rdr.records() {
        let rec = rec?;
        let line = rec.position().map_or(0, |p| p.line());
        let cell = |c: usize| rec.get(c).unwrap_or("");
        let col_name = |c: usize| headers.get(c).unwrap_or("?").to_string();
        let (t, is_iso) = parse_time_cell(cell(time_col)).map_err(|reason| CsvError::Cell {
            line,
            column: col_name(time_col),
            reason,
        })?;
        if !t.is_finite() {
            return Err(CsvError::Cell {
                line,
                column: col_name(time_col),
                reason: "time is missing".into(),
            });
        }
        if *iso.get_or_insert(is_iso) != is_iso {
            return Err(CsvError::Cell {
                line,
                column: col_name(time_col),
                reason: "mixes ISO 8601 date-times and numbers".into(),
            });
        }
        if let Some(&prev) = t_s.last() {
            if t <= prev {
                return Err(CsvError::Cell {
                    line,
                    column: col_name(time_col),
                    reason: format!("time {t} does not increase (previous {prev})"),
                });
            }
        }
        let ph = match phase_col {
            Some(c) => parse_phase(cell(c)).ok_or_else(|| CsvError::Cell {
                line,
                column: col_name(c),
                reason: format!("unknown phase '{}'", cell(c)),
            })?,
            None => Phase::Standstill,
        };
        let mut v: Values = [f64::NAN; NSIG];
        for &(s, c) in &sig_cols {
            let raw = parse_value(cell(c)).map_err(|reason| CsvError::Cell {
                line,
                column: col_name(c),
                reason,
            })?;
            v[s.index()] = units.to_model(s.column(), raw);
        }
        t_s.push(t);
        phases.push(ph);
        rows.push(v);
        lines.push(line);
    }
    if t_s.is_empty() {
        return Err(CsvError::Empty);
    }
    // ISO 8601 times: seconds from the first row, which is the origin returned.
    let origin_ms = match iso {
        Some(true) => {
            let t0 = t_s[0];
            t_s.iter_mut().for_each(|t| *t = (*t - t0) / 1000.0);
            Some(t0 as i64)
        }
        _ => None,
    };
    check_units(&sig_cols, &headers, &rows, &lines)?;
    let report = apply_policy(quality, &sig_cols, &t_s, &mut rows);
    Ok(Rows {
        t_s,
        phases,
        rows,
        lines,
        report,
        origin_ms,
    })
}

/// Refuses a column in another unit (°C for K, bar for kPa, …), judged at the recording's
/// most fired sample (largest fuel flow with the GG turning), where every relation between
/// the signals holds; a recording never fired is not judged.
fn check_units(
    sig_cols: &[(Signal, usize)],
    headers: &csv::StringRecord,
    rows: &[Values],
    lines: &[u64],
) -> Result<(), CsvError> {
    let fuel = |v: &Values| v[Signal::FuelFlow.index()];
    let fired = rows
        .iter()
        .enumerate()
        .filter(|(_, v)| fuel(v).is_finite() && fuel(v) > 0.0)
        .max_by(|a, b| fuel(a.1).total_cmp(&fuel(b.1)));
    let Some((k, v)) = fired else {
        return Ok(());
    };
    let row: Vec<(Signal, f64)> = sig_cols.iter().map(|(s, _)| (*s, v[s.index()])).collect();
    match super::unit_check::check_fired_point(&row) {
        Some(x) => {
            let c = sig_cols
                .iter()
                .find(|(s, _)| *s == x.signal)
                .map_or(0, |(_, c)| *c);
            Err(CsvError::Cell {
                line: lines.get(k).copied().unwrap_or(0),
                column: headers.get(c).unwrap_or("?").to_string(),
                reason: x.describe(),
            })
        }
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file with Windows line ends names the same lines as with Unix ones.
    #[test]
    fn crlf_files_name_their_file_lines() {
        let unix = "time_s,phase,n1_rpm\n0,standstill,0\n1,crank,abc\n";
        let windows = unix.replace('\n', "\r\n");
        for text in [unix.to_string(), windows] {
            let e = read_recording(text.as_bytes(), &HashMap::new()).expect_err("bad cell");
            assert_eq!(
                e.to_string(),
                "line 3, column 'n1_rpm': 'abc' is not a number"
            );
        }
        assert_eq!(crlf_to_lf(b"a\r\nb\rc\n".to_vec()), b"a\nb\rc\n".to_vec());
    }

    #[test]
    fn stated_units_are_converted_as_read() {
        let csv =
            "Time,State,NGG,CDT,CDP,FUEL\n0,standstill,0,15,1.01325,0\n1,crank,125,16,1.1,36\n";
        let map =
            parse_mapping("time_s=Time,phase=State,n1=NGG,t2_k=CDT,p2_kpa=CDP,fuel_kg_s=FUEL")
                .expect("mapping");
        let units =
            ColumnUnits::parse("n1_rpm=Hz,t2_k=degC,p2_kpa=bar,fuel_kg_s=kg/h").expect("units");
        let (seg, _) =
            read_recording_checked(csv.as_bytes(), &map, &units, &QualityConfig::default())
                .expect("reads");
        let near = |a: Option<f64>, b: f64| a.is_some_and(|a| (a - b).abs() < 1e-9);
        assert!(near(seg.value(1, Signal::N1), 7500.0));
        assert!(near(seg.value(0, Signal::T2), 288.15));
        assert!(near(seg.value(0, Signal::P2), 101.325));
        assert!(near(seg.value(1, Signal::FuelFlow), 0.01));
        // Unstated, the same file is judged as it stands: a GG at 125 "rpm" is refused.
        let e = read_recording(csv.as_bytes(), &map).expect_err("unstated");
        assert!(e.to_string().contains("column 'NGG'"), "{e}");
    }

    /// A plant's tag that happens to be one of gtwatch's own names, mapped to another signal,
    /// is that signal only: an aero-derivative's `P3` is its compressor discharge (gtwatch's
    /// `p2_kpa`), not also the combustor exit's `p3_kpa`, which would compare it twice.
    #[test]
    fn a_mapped_header_is_not_also_taken_by_its_own_name() {
        let csv = "Time,State,P3_KPA,T3\n0,standstill,101.3,288\n1,crank,102.0,289\n";
        let map = parse_mapping("time_s=Time,phase=State,p2_kpa=P3_KPA").expect("mapping");
        let seg = read_recording(csv.as_bytes(), &map).expect("reads");
        assert_eq!(seg.value(1, Signal::P2), Some(102.0));
        assert_eq!(seg.value(1, Signal::P3), None);
        // Unmapped, a gtwatch name is still read as that signal.
        assert_eq!(seg.value(1, Signal::T3), Some(289.0));
    }

    #[test]
    fn reads_simulate_layout_and_mapping_with_clear_errors() {
        let csv = "time_s,phase,n1_rpm,p2_kpa,true_n1_rpm\n0.0,standstill,0,101.3,0\n1.0,crank,,102.0,5\n2.0,crank,nan,103,6\n";
        let seg = read_recording(csv.as_bytes(), &HashMap::new()).expect("reads");
        assert_eq!(seg.len(), 3);
        assert_eq!(seg.phases()[1], Phase::Crank);
        assert_eq!(seg.value(1, Signal::N1), None);
        assert_eq!(seg.value(2, Signal::N1), None);
        assert_eq!(seg.value(2, Signal::P2), Some(103.0));
        // A column absent from the file is missing, not zero.
        assert_eq!(seg.value(0, Signal::T34), None);

        let other = "Time,State,NGG\n0,0,0\n1,1,100\n";
        let map = parse_mapping("time_s=Time,phase=State,n1=NGG").expect("mapping");
        let seg = read_recording(other.as_bytes(), &map).expect("reads");
        assert_eq!(seg.value(1, Signal::N1), Some(100.0));
        assert_eq!(seg.phases()[1], Phase::from_code(1).expect("code 1"));

        let bad = "time_s,phase,n1_rpm\n0,standstill,0\n1,crank,abc\n";
        let e = read_recording(bad.as_bytes(), &HashMap::new()).expect_err("bad cell");
        assert_eq!(
            e.to_string(),
            "line 3, column 'n1_rpm': 'abc' is not a number"
        );
        let bad = "time_s,phase\n0,standstill\n0,flying\n";
        let e = read_recording(bad.as_bytes(), &HashMap::new()).expect_err("bad");
        assert!(e.to_string().starts_with("line 3, column 'time_s'"), "{e}");
        assert!(matches!(
            read_recording("t,phase\n".as_bytes(), &HashMap::new()),
            Err(CsvError::MissingColumn(c)) if c == "time_s"
        ));
        // A log without phase labels is pointed at what labels them.
        let e = read_recording("time_s,n1_rpm\n0,0\n".as_bytes(), &HashMap::new())
            .expect_err("no phase");
        assert!(
            matches!(&e, CsvError::MissingPhase(c) if c == "phase")
                && e.to_string().contains("gtwatch replay"),
            "{e}"
        );
        assert!(matches!(
            parse_mapping("bogus=X"),
            Err(CsvError::UnknownTarget(_))
        ));
    }

    /// A log is read without phases; its ISO 8601 times become seconds from the first row
    /// (the origin returned), a `timestamp` column is found by name, and a file that mixes
    /// date-times with numbers is refused at the line that does.
    #[test]
    fn a_log_reads_iso_times_from_its_first_row() {
        let read = |text: &str| {
            read_log_checked(
                text.as_bytes(),
                &HashMap::new(),
                &ColumnUnits::default(),
                &QualityConfig::default(),
            )
        };
        let (log, _) = read(
            "timestamp,n1_rpm\n2025-07-01T06:00:00Z,0\n2025-07-01T06:00:01.5Z,10\n\
             2025-07-01 06:00:03,20\n",
        )
        .expect("a log");
        assert_eq!(log.t_s, vec![0.0, 1.5, 3.0]);
        assert_eq!(log.origin_ms, Some(1_751_349_600_000));
        assert_eq!(log.lines, vec![2, 3, 4]);
        assert_eq!(log.rows[2][Signal::N1.index()], 20.0);
        let (seconds, _) = read("time,n1_rpm\n10,0\n11,5\n").expect("seconds");
        assert_eq!((seconds.t_s, seconds.origin_ms), (vec![10.0, 11.0], None));
        let e = read("tag,time,value\nNGG,2025-07-01T06:00:00Z,0\n").expect_err("long");
        assert!(
            matches!(&e, CsvError::LongLayout(h) if h == "tag,time,value")
                && e.to_string().contains("gtwatch replay"),
            "{e}"
        );
        let e = read("time,n1_rpm\n1751349600000,0\n1751349601000,1\n1751349602000,2\n")
            .expect_err("milliseconds");
        assert!(
            matches!(e, CsvError::Period { median_s } if median_s == 1000.0),
            "{e}"
        );
        let e = read("time_s,n1_rpm\n2025-07-01T06:00:00Z,0\n5,1\n").expect_err("mixed");
        assert!(
            matches!(&e, CsvError::Cell { line: 3, reason, .. } if reason.contains("mixes")),
            "{e}"
        );
    }

    #[test]
    fn unusable_recordings_name_their_line() {
        // Issue 12 item 6: P1 = 0, T1 <= 0, a last time of 1e12 s, a 1e7 s jump.
        let head = "time_s,phase,n1_rpm,p1_kpa,t1_k\n";
        let cases = [
            ("0,standstill,0,101.3,288\n1,crank,10,0,288\n2,crank,20,101.3,288\n", "line 3: sample 1 (t = 1 s): p1_kpa = 0"),
            ("0,standstill,0,101.3,288\n1,crank,10,101.3,-3\n2,crank,20,101.3,288\n", "line 3: sample 1 (t = 1 s): t1_k = -3"),
            ("0,standstill,0,101.3,288\n1,crank,10,101.3,288\n1000000000000,crank,20,101.3,288\n", "line 4: sample 2: time jumps"),
            ("0,standstill,0,101.3,288\n1,crank,10,101.3,288\n10000001,crank,20,101.3,288\n10000002,crank,20,101.3,288\n", "line 4: sample 2: time jumps"),
            ("0,standstill,0,101.3,288\n", "recording has 1 sample(s)"),
        ];
        for (body, want) in cases {
            let e = read_recording(format!("{head}{body}").as_bytes(), &HashMap::new())
                .expect_err(want);
            assert!(e.to_string().starts_with(want), "{e} (want {want})");
        }
    }

    #[test]
    fn flagged_cells_become_missing_and_are_counted() {
        // n1 ramps 3000 → 5900 rpm; T34 has one spike (row 5) and is frozen from row 10 on.
        let mut csv = String::from("time_s,phase,n1_rpm,t34_k\n");
        for i in 0..30 {
            let t34 = match i {
                5 => 1400.0,
                i if i >= 10 => 800.0,
                i => 780.0 + 2.0 * i as f64,
            };
            csv.push_str(&format!("{i},acceleration,{},{t34}\n", 3000 + 100 * i));
        }
        let q = QualityConfig {
            stuck_after_s: 5.0,
            ..QualityConfig::default()
        };
        let (rec, report) =
            read_recording_checked(csv.as_bytes(), &HashMap::new(), &ColumnUnits::default(), &q)
                .expect("reads");
        let k = Signal::T34.index();
        let t34: Vec<f64> = rec.rows().iter().map(|r| r[k]).collect();
        assert!(t34[5].is_nan(), "spike kept: {t34:?}");
        assert!(t34[4].is_finite() && t34[6].is_finite());
        // Frozen since t = 10 s; stuck once older than 5 s and n1 moved > 500 rpm (t > 15).
        assert!(t34[..15]
            .iter()
            .enumerate()
            .all(|(i, v)| i == 5 || v.is_finite()));
        assert!(t34[16..].iter().all(|v| v.is_nan()), "{t34:?}");
        assert_eq!(report.flagged.len(), 1);
        let (sig, c) = report.flagged[0];
        assert_eq!(sig, Signal::T34);
        assert_eq!(c.spike, 1);
        assert_eq!(c.stuck, 14);
        assert_eq!(report.total(), 15);
    }
}
