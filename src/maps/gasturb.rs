//! Reader for component maps in the GasTurb text format.
//!
//! What it is for: turn the text of a `.map` file into named numeric tables, with errors that
//! name the file, the table and the position (line and which value) of every problem.
//! What it must not do: interpret the tables (that is `compressor` / `turbine`), or touch the
//! file system anywhere but [`read_file`].
//!
//! Layout: a title line (usually a type code such as `99` then free text), optionally a
//! `Reynolds:` line, then named tables. A table is a line with its name (no numbers on it), then
//! a header number `rows + 1 + (columns + 1)/1000`, the `columns` column keys, and `rows` rows of
//! one key plus `columns` values. The body is read **by these counts, not by line breaks**:
//! other writers wrap long rows at arbitrary widths.

use std::path::Path;
use thiserror::Error;

/// A problem reading or interpreting a map file. Every variant names the source (file name).
#[derive(Debug, Error)]
pub enum MapError {
    #[error("cannot read map file {source_name}: {error}")]
    Io {
        source_name: String,
        error: std::io::Error,
    },
    #[error("{source_name}: table \"{table}\", line {line}: bad header {token:?}: {reason}")]
    BadHeader {
        source_name: String,
        table: String,
        line: usize,
        token: String,
        reason: String,
    },
    #[error(
        "{source_name}: table \"{table}\", line {line}, {position}: non-numeric token {token:?}"
    )]
    NonNumeric {
        source_name: String,
        table: String,
        line: usize,
        position: String,
        token: String,
    },
    #[error(
        "{source_name}: table \"{table}\" truncated at line {line}: expected {position}, found {found}"
    )]
    Truncated {
        source_name: String,
        table: String,
        line: usize,
        position: String,
        found: String,
    },
    #[error("{source_name}: table \"{table}\", line {line}, {position}: {reason}")]
    NonMonotone {
        source_name: String,
        table: String,
        line: usize,
        position: String,
        reason: String,
    },
    #[error("{source_name}: missing required table \"{table}\"")]
    MissingTable { source_name: String, table: String },
    #[error("{source_name}: table \"{table}\": {reason}")]
    Invalid {
        source_name: String,
        table: String,
        reason: String,
    },
    #[error("{source_name}: no title line (empty file)")]
    Empty { source_name: String },
}

/// One named table: `values[row][column]`, rows keyed by `row_keys` (usually speed) and
/// columns by `col_keys` (usually beta; for PR-limit and surge tables the speeds or flows).
#[derive(Debug, Clone, PartialEq)]
pub struct MapTable {
    pub name: String,
    pub col_keys: Vec<f64>,
    pub row_keys: Vec<f64>,
    pub values: Vec<Vec<f64>>,
}

/// A whole map file.
#[derive(Debug, Clone, PartialEq)]
pub struct GasTurbFile {
    /// Title text after the leading type code (e.g. "HPC map (...)" from "99    HPC map (...)").
    pub title: String,
    /// Tables in file order.
    pub tables: Vec<MapTable>,
    /// Name of the source the file was read from (for error messages downstream).
    pub source: String,
}

impl GasTurbFile {
    /// The table with this name (case-insensitive), if present.
    pub fn table(&self, name: &str) -> Option<&MapTable> {
        self.tables
            .iter()
            .find(|t| t.name.eq_ignore_ascii_case(name))
    }

    /// The table with this name, or a `MissingTable` error naming the source.
    pub fn require(&self, name: &str) -> Result<&MapTable, MapError> {
        self.table(name).ok_or_else(|| MapError::MissingTable {
            source_name: self.source.clone(),
            table: short(name),
        })
    }
}

/// Read and parse a map file; the file name is used as the source name in errors.
pub fn read_file(path: &Path) -> Result<GasTurbFile, MapError> {
    let source = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|error| MapError::Io {
        source_name: source.clone(),
        error,
    })?;
    parse(&text, &source)
}

struct Tok<'a> {
    text: &'a str,
    line: usize,
}

fn is_number(s: &str) -> bool {
    s.parse::<f64>().is_ok()
}

/// A line that opens a table: it has text and no numeric token at all.
fn is_name_line(line: &str) -> bool {
    let mut any = false;
    for t in line.split_whitespace() {
        if is_number(t) {
            return false;
        }
        any = true;
    }
    any
}

/// A token or name as quoted in an error: at most 40 characters, so that a multi-megabyte
/// garbage token does not turn into megabytes of error output.
fn short(text: &str) -> String {
    const MAX: usize = 40;
    match text.char_indices().nth(MAX) {
        None => text.to_string(),
        Some((cut, _)) => format!("{}... ({} bytes)", &text[..cut], text.len()),
    }
}

/// Parse GasTurb map text. `source` names the file in error messages.
pub fn parse(text: &str, source: &str) -> Result<GasTurbFile, MapError> {
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l))
        .filter(|(_, l)| !l.trim().is_empty())
        .collect();
    let Some(&(_, title_line)) = lines.first() else {
        return Err(MapError::Empty {
            source_name: source.to_string(),
        });
    };
    let title = {
        let t = title_line.trim();
        match t.split_once(char::is_whitespace) {
            Some((code, rest)) if is_number(code) => rest.trim().to_string(),
            None if is_number(t) => String::new(),
            _ => t.to_string(),
        }
    };

    let mut tables = Vec::new();
    let mut i = 1;
    while i < lines.len() {
        let (line_no, line) = lines[i];
        let trimmed = line.trim();
        if trimmed.to_ascii_lowercase().starts_with("reynolds") {
            i += 1;
            continue;
        }
        if !is_name_line(line) {
            let token = short(trimmed.split_whitespace().next().unwrap_or(""));
            return Err(MapError::Invalid {
                source_name: source.to_string(),
                table: tables
                    .last()
                    .map(|t: &MapTable| t.name.clone())
                    .unwrap_or_else(|| "(none)".into()),
                reason: format!(
                    "line {line_no}: unexpected value {token:?} after the end of the table \
                     (more values than the header declares, or a missing table name)"
                ),
            });
        }
        let name = trimmed.split_whitespace().collect::<Vec<_>>().join(" ");
        i += 1;
        // Tokens of the body: every following line until the next name line.
        let mut toks = Vec::new();
        while i < lines.len() && !is_name_line(lines[i].1) {
            let (ln, l) = lines[i];
            toks.extend(l.split_whitespace().map(|t| Tok { text: t, line: ln }));
            i += 1;
        }
        let end = if i < lines.len() {
            (
                lines[i].0,
                format!("table name {:?}", short(lines[i].1.trim())),
            )
        } else {
            (
                lines.last().map(|l| l.0).unwrap_or(line_no),
                "the end of the file".to_string(),
            )
        };
        let (table, used) = parse_table(source, &name, line_no, &toks, &end)?;
        if used < toks.len() {
            let extra = &toks[used];
            return Err(MapError::Invalid {
                source_name: source.to_string(),
                table: short(&name),
                reason: format!(
                    "line {}: value {:?} beyond the {} rows x {} columns the header declares",
                    extra.line,
                    short(extra.text),
                    table.row_keys.len(),
                    table.col_keys.len()
                ),
            });
        }
        tables.push(table);
    }
    Ok(GasTurbFile {
        title,
        tables,
        source: source.to_string(),
    })
}

fn parse_table(
    source: &str,
    name: &str,
    name_line: usize,
    toks: &[Tok<'_>],
    end: &(usize, String),
) -> Result<(MapTable, usize), MapError> {
    let end_line = end.0;
    let mut pos = 0usize;
    let take = |pos: &mut usize, what: &dyn Fn() -> String| -> Result<f64, MapError> {
        let Some(t) = toks.get(*pos) else {
            let found = end.1.clone();
            return Err(MapError::Truncated {
                source_name: source.to_string(),
                table: short(name),
                line: end_line,
                position: what(),
                found,
            });
        };
        *pos += 1;
        t.text
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| MapError::NonNumeric {
                source_name: source.to_string(),
                table: short(name),
                line: t.line,
                position: what(),
                token: short(t.text),
            })
    };

    let header_line = toks.first().map(|t| t.line).unwrap_or(name_line);
    let header = take(&mut pos, &|| "the header number".to_string())?;
    let bad_header = |reason: &str| MapError::BadHeader {
        source_name: source.to_string(),
        table: short(name),
        line: header_line,
        token: toks.first().map(|t| short(t.text)).unwrap_or_default(),
        reason: reason.to_string(),
    };
    if !(header.is_finite() && header > 0.0 && header <= 1.0e6) {
        return Err(bad_header(
            "must be rows + 1 + (columns + 1)/1000 with rows >= 1, columns >= 1",
        ));
    }
    let int_part = (header + 1e-9).floor();
    let thousandths = ((header - int_part) * 1000.0).round();
    if ((int_part + thousandths / 1000.0) - header).abs() > 1e-6 {
        return Err(bad_header(
            "fraction is not a whole number of thousandths (rows + 1 + (columns + 1)/1000)",
        ));
    }
    let rows = int_part as i64 - 1;
    let cols = thousandths as i64 - 1;
    if rows < 1 || cols < 1 {
        return Err(bad_header(&format!(
            "decodes to {rows} rows x {cols} columns; need at least 1 x 1"
        )));
    }
    let (rows, cols) = (rows as usize, cols as usize);

    let mut col_keys = Vec::with_capacity(cols);
    for c in 0..cols {
        let line = toks.get(pos).map(|t| t.line).unwrap_or(end_line);
        let v = take(&mut pos, &|| format!("column key {} of {cols}", c + 1))?;
        if let Some(&prev) = col_keys.last() {
            if v <= prev {
                return Err(MapError::NonMonotone {
                    source_name: source.to_string(),
                    table: short(name),
                    line,
                    position: format!("column key {} of {cols}", c + 1),
                    reason: format!("column keys must increase ({v} after {prev})"),
                });
            }
        }
        col_keys.push(v);
    }
    let mut row_keys = Vec::with_capacity(rows);
    let mut values = Vec::with_capacity(rows);
    for r in 0..rows {
        let line = toks.get(pos).map(|t| t.line).unwrap_or(end_line);
        let key = take(&mut pos, &|| format!("row {} of {rows} key (speed)", r + 1))?;
        if let Some(&prev) = row_keys.last() {
            if key <= prev {
                return Err(MapError::NonMonotone {
                    source_name: source.to_string(),
                    table: short(name),
                    line,
                    position: format!("row {} of {rows} key", r + 1),
                    reason: format!("speed keys must increase ({key} after {prev})"),
                });
            }
        }
        row_keys.push(key);
        let mut row = Vec::with_capacity(cols);
        for c in 0..cols {
            let v = take(&mut pos, &|| {
                format!(
                    "row {} of {rows} (key {key}), value {} of {cols}",
                    r + 1,
                    c + 1
                )
            })?;
            row.push(v);
        }
        values.push(row);
    }
    Ok((
        MapTable {
            name: name.to_string(),
            col_keys,
            row_keys,
            values,
        },
        pos,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "99  tiny map\nReynolds: RNI=0.1 f=1\nMass Flow\n   3.003 0.0 1.0\n 0.5 1 2\n 1.0 3 4\n\nEfficiency\n 2.003 0 1\n 0 0.7 0.8\n";

    #[test]
    fn parses_small_map() {
        let f = parse(SMALL, "tiny.map").expect("parses");
        assert_eq!(f.title, "tiny map");
        assert_eq!(f.tables.len(), 2);
        let m = f.require("mass flow").expect("table");
        assert_eq!(m.col_keys, vec![0.0, 1.0]);
        assert_eq!(m.row_keys, vec![0.5, 1.0]);
        assert_eq!(m.values, vec![vec![1.0, 2.0], vec![3.0, 4.0]]);
        assert_eq!(
            f.require("Efficiency").expect("t").values,
            vec![vec![0.7, 0.8]]
        );
    }

    fn err_text(text: &str) -> String {
        match parse(text, "bad.map") {
            Ok(_) => panic!("expected an error for {text:?}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn huge_bad_token_is_quoted_short() {
        // Regression (issue 12 #9): a 5 MB bad token gave 20 MB of stderr.
        let big = "x".repeat(5_000_000);
        let e = err_text(&format!("99 t\nMass Flow\n 3.003 0 1\n 0.5 1 {big}\n"));
        assert!(e.len() < 400, "{} bytes", e.len());
        assert!(e.contains("5000000 bytes"), "{e}");
        let e = err_text(&format!(
            "99 t\nMass Flow\n 3.003 0 1\n 0.5 1 2\n 1.0 3 4\n 9 {big}\n"
        ));
        assert!(e.len() < 400, "{} bytes", e.len());
    }

    #[test]
    fn truncated_table_names_file_table_and_position() {
        let text =
            "99 t\nMass Flow\n 3.003 0 1\n 0.5 1 2\n 1.0 3\nEfficiency\n 2.003 0 1\n 0 1 1\n";
        let e = err_text(text);
        assert!(e.contains("bad.map"), "{e}");
        assert!(e.contains("\"Mass Flow\""), "{e}");
        assert!(e.contains("truncated"), "{e}");
        assert!(e.contains("row 2 of 2 (key 1), value 2 of 2"), "{e}");
        assert!(e.contains("line 6"), "{e}");
        // Truncated at end of file.
        let e = err_text("99 t\nMass Flow\n 3.003 0 1\n 0.5 1 2\n");
        assert!(e.contains("row 2 of 2 key"), "{e}");
        assert!(e.contains("line 4"), "{e}");
    }

    #[test]
    fn non_numeric_token_names_line_and_value() {
        let e = err_text("99 t\nMass Flow\n 3.003 0 1\n 0.5 1 2\n 1.0 3 x4\n");
        assert!(e.contains("bad.map"), "{e}");
        assert!(e.contains("\"Mass Flow\""), "{e}");
        assert!(e.contains("line 5"), "{e}");
        assert!(e.contains("value 2 of 2"), "{e}");
        assert!(e.contains("\"x4\""), "{e}");
    }

    #[test]
    fn bad_header_is_reported() {
        let e = err_text("99 t\nMass Flow\n 3.0035 0 1\n 0.5 1 2\n");
        assert!(e.contains("bad header"), "{e}");
        assert!(e.contains("line 3"), "{e}");
        assert!(e.contains("\"Mass Flow\""), "{e}");
        let e = err_text("99 t\nSurge Line\n 1.003 0 1\n");
        assert!(e.contains("0 rows"), "{e}");
        let e = err_text("99 t\nSurge Line\n -2 0 1\n");
        assert!(e.contains("bad header"), "{e}");
    }

    #[test]
    fn non_monotone_speed_keys_are_reported() {
        let e = err_text("99 t\nMass Flow\n 3.003 0 1\n 0.9 1 2\n 0.8 3 4\n");
        assert!(e.contains("bad.map"), "{e}");
        assert!(e.contains("\"Mass Flow\""), "{e}");
        assert!(e.contains("line 5"), "{e}");
        assert!(e.contains("row 2 of 2 key"), "{e}");
        assert!(e.contains("must increase"), "{e}");
    }

    #[test]
    fn extra_values_are_reported() {
        let e = err_text("99 t\nMass Flow\n 2.003 0 1\n 0.9 1 2 7\n");
        assert!(e.contains("line 4"), "{e}");
        assert!(e.contains("\"7\""), "{e}");
    }

    #[test]
    fn missing_table_is_reported() {
        let f = parse(SMALL, "tiny.map").expect("parses");
        let e = f.require("Surge Line").expect_err("missing").to_string();
        assert!(
            e.contains("tiny.map") && e.contains("\"Surge Line\""),
            "{e}"
        );
    }

    #[test]
    fn empty_and_io_errors_name_the_source() {
        assert!(err_text("\n  \n").contains("bad.map"));
        let e = read_file(Path::new("/nonexistent/dir/x.map"))
            .expect_err("no file")
            .to_string();
        assert!(e.contains("/nonexistent/dir/x.map"), "{e}");
    }
}
