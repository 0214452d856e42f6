//! Which columns (wide layout) or tags (long layout) a replay reads, decided before any row is
//! stored: the header names the layout and the fields; for a long file, [`plan_columns`] also
//! reads the tag field of every row, so a caller can check a log's tags before it creates a
//! database.
//!
//! Must not touch the store or parse values: it only maps names to tags.

use super::config::{tag_for_mapping, Layout, ReplayConfig};
use super::ReplayError;
use crate::signals::Signal;
use crate::store::TagInfo;
use std::path::Path;

/// Which CSV columns a replay reads, decided from the header alone (no database needed).
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnPlan {
    /// Number of header fields.
    pub n_fields: usize,
    /// Index of the time column.
    pub time_index: usize,
    /// Wide: (column index, column name, tag) for every replayed column. Long: (position in
    /// the file's tag list, name in the tag field, tag) for every replayed tag.
    pub mapped: Vec<(usize, String, TagInfo)>,
    /// Wide: header columns that are not replayed (neither the time column nor mapped). Long:
    /// names in the tag field that are not replayed.
    pub ignored: Vec<String>,
    /// Long layout: where the tag, value and status fields are. `None`: a wide file.
    pub long: Option<LongFields>,
}

/// The fields of a long (`tag,time,value[,status]`) file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LongFields {
    pub tag: usize,
    pub value: usize,
    pub status: Option<usize>,
}

impl ColumnPlan {
    /// Whether some replayed column feeds the tag named `tag`.
    pub fn feeds_tag(&self, tag: &str) -> bool {
        self.mapped.iter().any(|(_, _, info)| info.name == tag)
    }
}

/// A CSV reader as every replay pass uses it.
pub(super) fn csv_reader(
    cfg: &ReplayConfig,
    file: std::fs::File,
    buffer: usize,
) -> csv::Reader<std::io::BufReader<std::fs::File>> {
    csv::ReaderBuilder::new()
        .delimiter(cfg.delimiter_byte().unwrap_or(b','))
        .has_headers(true)
        .flexible(true)
        // `\n` alone ends a record; a `\r` before it is trimmed with the field. With csv's
        // default CRLF handling every line number of a CRLF file came out one too low.
        .terminator(csv::Terminator::Any(b'\n'))
        .buffer_capacity(buffer)
        .from_reader(std::io::BufReader::with_capacity(buffer, file))
}

fn open(path: &Path) -> Result<std::fs::File, ReplayError> {
    std::fs::File::open(path).map_err(|source| ReplayError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads the header of `path` and decides which columns a replay would use; for a long file it
/// reads every row's tag field too. Fails like [`super::replay_file`] would (missing file,
/// missing time or mapped column, nothing to replay), and for a long file also when a tag
/// mapped in `[replay.columns]` never occurs, so a caller can check every log before it
/// creates a database.
pub fn plan_columns(cfg: &ReplayConfig, path: &Path) -> Result<ColumnPlan, ReplayError> {
    let mut rdr = csv_reader(cfg, open(path)?, 64 << 10);
    let mut plan = plan_from_reader(&mut rdr, cfg, path)?;
    let Some(long) = plan.long else {
        return Ok(plan);
    };
    let mut names: Vec<String> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    let mut record = csv::ByteRecord::new();
    // Rows the replay would report as malformed are skipped here; it reports them.
    while rdr.read_byte_record(&mut record).unwrap_or(false) {
        if let Some(raw) = record.get(long.tag) {
            if !seen.contains(raw) {
                seen.insert(raw.to_vec());
                names.push(String::from_utf8_lossy(raw).trim().to_string());
            }
        }
    }
    for key in cfg.columns.keys() {
        if !names.iter().any(|n| n == key) {
            return Err(ReplayError::MissingTag {
                path: path.to_path_buf(),
                tag: key.clone(),
                available: names.join(", "),
            });
        }
    }
    for (i, name) in names.into_iter().enumerate() {
        match long_tag(cfg, &name) {
            Some(info) => plan.mapped.push((i, name, info)),
            None => plan.ignored.push(name),
        }
    }
    if plan.mapped.is_empty() {
        return Err(ReplayError::NoColumns {
            path: path.to_path_buf(),
            ignored: plan.ignored.join(", "),
        });
    }
    Ok(plan)
}

/// The tag a name in a long file's tag field feeds, if it is replayed.
pub(super) fn long_tag(cfg: &ReplayConfig, name: &str) -> Option<TagInfo> {
    if cfg.columns.is_empty() {
        name.parse::<Signal>().ok().map(TagInfo::for_signal)
    } else {
        cfg.columns.get(name).map(|t| tag_for_mapping(t))
    }
}

/// The long layout's fields if `names` (a header) is one: exactly `tag`, the time column,
/// `value` and optionally `status` (or `quality`), names other than the time column compared
/// case-insensitively. `layout = "long"` insists and names what is missing.
fn long_fields(
    cfg: &ReplayConfig,
    names: &[String],
    time_idx: usize,
    path: &Path,
) -> Result<Option<LongFields>, ReplayError> {
    if cfg.layout == Layout::Wide {
        return Ok(None);
    }
    let find = |want: &[&str]| {
        names
            .iter()
            .enumerate()
            .position(|(i, n)| i != time_idx && want.iter().any(|w| n.eq_ignore_ascii_case(w)))
    };
    let tag = find(&["tag", "tagname", "tag_name"]);
    let value = find(&["value"]);
    let status = find(&["status", "quality"]);
    let known = 1
        + usize::from(tag.is_some())
        + usize::from(value.is_some())
        + usize::from(status.is_some());
    match (tag, value) {
        (Some(tag), Some(value)) if known == names.len() => {
            Ok(Some(LongFields { tag, value, status }))
        }
        (None, _) | (_, None) if cfg.layout == Layout::Long => Err(ReplayError::MissingColumn {
            path: path.to_path_buf(),
            column: if tag.is_none() { "tag" } else { "value" }.into(),
            available: names.join(", "),
        }),
        _ if cfg.layout == Layout::Long => Err(ReplayError::Header {
            path: path.to_path_buf(),
            message: format!(
                "replay.layout = \"long\" takes only the fields tag, {}, value and status \
                 (found: {})",
                cfg.time_column,
                names.join(", ")
            ),
        }),
        _ => Ok(None),
    }
}

/// The plan from the header alone; a long file's `mapped` and `ignored` are left empty (its
/// tags are in the rows).
pub(super) fn plan_from_reader<R: std::io::Read>(
    rdr: &mut csv::Reader<R>,
    cfg: &ReplayConfig,
    path: &Path,
) -> Result<ColumnPlan, ReplayError> {
    let header = rdr
        .byte_headers()
        .map_err(|e| ReplayError::Header {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?
        .clone();
    let names: Vec<String> = header
        .iter()
        .map(|h| String::from_utf8_lossy(h).trim().to_string())
        .collect();
    let available = names.join(", ");
    let find = |col: &str| names.iter().position(|n| n == col);
    let time_idx = find(&cfg.time_column).ok_or_else(|| ReplayError::MissingColumn {
        path: path.to_path_buf(),
        column: cfg.time_column.clone(),
        available: available.clone(),
    })?;
    if let Some(long) = long_fields(cfg, &names, time_idx, path)? {
        return Ok(ColumnPlan {
            n_fields: names.len(),
            time_index: time_idx,
            mapped: Vec::new(),
            ignored: Vec::new(),
            long: Some(long),
        });
    }
    let mut ignored = Vec::new();
    let mut mapping: Vec<(usize, String, TagInfo)> = Vec::new();
    if cfg.columns.is_empty() {
        for (i, n) in names.iter().enumerate() {
            if i == time_idx {
                continue;
            }
            match n.parse::<Signal>() {
                Ok(sig) => mapping.push((i, n.clone(), TagInfo::for_signal(sig))),
                Err(_) => ignored.push(n.clone()),
            }
        }
    } else {
        for (col, tag) in &cfg.columns {
            let i = find(col).ok_or_else(|| ReplayError::MissingColumn {
                path: path.to_path_buf(),
                column: col.clone(),
                available: available.clone(),
            })?;
            mapping.push((i, col.clone(), tag_for_mapping(tag)));
        }
        for (i, n) in names.iter().enumerate() {
            if i != time_idx && !mapping.iter().any(|(j, _, _)| *j == i) {
                ignored.push(n.clone());
            }
        }
    }
    if mapping.is_empty() {
        return Err(ReplayError::NoColumns {
            path: path.to_path_buf(),
            ignored: ignored.join(", "),
        });
    }
    Ok(ColumnPlan {
        n_fields: names.len(),
        time_index: time_idx,
        mapped: mapping,
        ignored,
        long: None,
    })
}
