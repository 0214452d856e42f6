//! The `[replay]` section: how a historical CSV log is read (layout, time column and format,
//! time zone, delimiter, column or tag mapping, malformed-row policy), its defaults and its
//! validation with `replay.`-prefixed keys.
//!
//! Must not open files or touch the store: it only describes and checks the settings.

use crate::config_problem::{check_range, Bounds, ConfigProblem};
use crate::signals::Signal;
use crate::store::TagInfo;
use crate::time::TimeFormat;
use crate::units::{ColumnUnits, UnitError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What to do with a malformed row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum OnMalformed {
    /// Skip it, count it, report the first `max_reported` (default).
    #[default]
    Skip,
    /// Stop with an error naming the line; rows before it stay committed.
    Stop,
}

/// How a log file is laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Layout {
    /// Long if the header is exactly `tag`, the time column, `value` and optionally `status`
    /// (any order, names case-insensitive); wide otherwise (default).
    #[default]
    Auto,
    /// One row per time stamp, one column per tag.
    Wide,
    /// One row per tag and time stamp: `tag,time,value[,status]`.
    Long,
}

/// `[replay]` section.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReplayConfig {
    /// `auto` (default), `wide` or `long`.
    pub layout: Layout,
    /// Name of the time column. Default `time`.
    pub time_column: String,
    /// `iso8601` (default), `epoch_s` or `epoch_ms`.
    pub time_format: TimeFormat,
    /// IANA time zone of ISO 8601 stamps written without an offset (`Europe/Berlin`): they are
    /// local wall-clock times, converted to UTC (the spring gap is refused, the repeated autumn
    /// hour is resolved by row order; see `crate::time::LocalClock`). A stamp with `Z` or an
    /// offset always wins. Default `UTC` (no offset = UTC).
    pub time_zone: String,
    /// Field delimiter, one ASCII character. Default `,`.
    pub delimiter: String,
    /// CSV column name (wide layout) or name in the tag column (long layout) → tag. The tag is
    /// a signal name (`n1`, `n1_rpm`, `fuel_flow`, …; the tag is then named by the signal's
    /// column name, e.g. `n1_rpm`) or any other tag name. Empty (default): every column (or
    /// tag) whose name is a signal name is replayed, others are ignored.
    pub columns: BTreeMap<String, String>,
    /// Units of the signals the log does not give in the model's units (K, kPa absolute, rpm,
    /// kg/s, MW, kN·m), keyed by signal (`t2_k = "degC"`, `p2_kpa = "bar"`, `fuel_kg_s =
    /// "kg/h"`): converted as read, before the bad-value policy judges them (`crate::units`).
    /// Default: none (every signal in the model's unit).
    pub units: BTreeMap<String, String>,
    /// The engine's fuel, which a fuel column stated by volume (`fuel_kg_s = "Nm3/h"`) is
    /// converted with (its density at the meter's reference conditions): set by the caller from
    /// the engine file (`[plant] engine_model`), never read from `[replay]`.
    #[serde(skip)]
    pub fuel: Option<crate::thermo::Fuel>,
    /// `skip` (default) or `stop`.
    pub on_malformed: OnMalformed,
    /// How many malformed rows are listed in the report (all are counted). Default 20.
    pub max_reported: usize,
    /// Samples per transaction. Default 200 000.
    pub transaction_samples: usize,
    /// Write the replayed samples straight into the archive tier as compressed chunks (one
    /// transaction per chunk window of all tags, or per `transaction_samples`), never as hot
    /// rows: for historical logs, where no start-up is still open. Idempotent and crash-safe
    /// as the hot path; readers cannot tell the tiers apart. Default false (`gtwatch replay
    /// --archive` sets it).
    pub archive: bool,
    /// Consecutive rows further apart than this (seconds) record a gap. 0 = off. Default 10.
    pub gap_threshold_s: f64,
    /// A row stamped more than this many seconds after the wall clock is implausible: it is
    /// reported and not stored (one row dated +1000 years used to make every later row "go
    /// backwards"). Default 86 400 (one day, room for a clock set a little ahead).
    pub max_future_s: f64,
}

impl Default for ReplayConfig {
    fn default() -> Self {
        ReplayConfig {
            layout: Layout::Auto,
            time_column: "time".into(),
            time_format: TimeFormat::Iso8601,
            time_zone: "UTC".into(),
            delimiter: ",".into(),
            columns: BTreeMap::new(),
            units: BTreeMap::new(),
            fuel: None,
            on_malformed: OnMalformed::Skip,
            max_reported: 20,
            transaction_samples: 200_000,
            archive: false,
            gap_threshold_s: 10.0,
            max_future_s: 86_400.0,
        }
    }
}

impl ReplayConfig {
    /// The stated units of `[replay.units]`, parsed.
    pub fn column_units(&self) -> Result<ColumnUnits, UnitError> {
        ColumnUnits::from_pairs(self.units.iter().map(|(k, v)| (k.as_str(), v.as_str())))
    }

    /// Problems with this section; keys are prefixed `replay.`.
    pub fn validate(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        for (key, unit) in &self.units {
            if key
                .trim()
                .eq_ignore_ascii_case(crate::units::AMBIENT_PRESSURE_COLUMN)
            {
                p.push(ConfigProblem::new(
                    format!("replay.units.{key}"),
                    "not a signal: a replay converts signals only (a free tag is stored as it is)",
                ));
            } else if let Err(e) = ColumnUnits::from_pairs([(key.as_str(), unit.as_str())]) {
                p.push(ConfigProblem::new(format!("replay.units.{key}"), e.reason));
            }
        }
        if let Err(e) = self.column_units() {
            if !p.iter().any(|x| x.key.ends_with(&e.key)) {
                p.push(ConfigProblem::new(
                    format!("replay.units.{}", e.key),
                    e.reason,
                ));
            }
        }
        if self.time_column.trim().is_empty() {
            p.push(ConfigProblem::new(
                "replay.time_column",
                "must not be empty",
            ));
        }
        if let Some(why) = crate::time::zone_problem(&self.time_zone) {
            p.push(ConfigProblem::new("replay.time_zone", why));
        }
        if self.delimiter_byte().is_none() {
            p.push(ConfigProblem::new(
                "replay.delimiter",
                format!(
                    "must be exactly one ASCII character (got {:?})",
                    self.delimiter
                ),
            ));
        }
        check_range(
            &mut p,
            "replay.transaction_samples",
            self.transaction_samples as u64,
            Bounds {
                lo: 1,
                hi: 5_000_000,
                unit: "",
                why: "samples held in memory per transaction",
            },
        );
        check_range(
            &mut p,
            "replay.max_reported",
            self.max_reported as u64,
            Bounds {
                lo: 0,
                hi: 1_000_000,
                unit: "",
                why: "malformed rows kept in the report",
            },
        );
        if !self.gap_threshold_s.is_finite() || self.gap_threshold_s < 0.0 {
            p.push(ConfigProblem::new(
                "replay.gap_threshold_s",
                "must be a number >= 0 (0 turns gap detection off)",
            ));
        }
        if !self.max_future_s.is_finite() || !(0.0..=1e10).contains(&self.max_future_s) {
            p.push(ConfigProblem::new(
                "replay.max_future_s",
                "must be a number of seconds from 0 to 1e10",
            ));
        }
        for (col, tag) in &self.columns {
            if col.trim().is_empty() {
                p.push(ConfigProblem::new("replay.columns", "empty column name"));
            }
            if tag.trim().is_empty() {
                p.push(ConfigProblem::new(
                    format!("replay.columns.{col}"),
                    "tag name must not be empty",
                ));
            }
            if col == &self.time_column {
                p.push(ConfigProblem::new(
                    format!("replay.columns.{col}"),
                    "the time column cannot also be a data column",
                ));
            }
        }
        let mut seen: BTreeMap<String, &str> = BTreeMap::new();
        for (col, tag) in &self.columns {
            let info = tag_for_mapping(tag);
            if let Some(prev) = seen.insert(info.name.clone(), col) {
                p.push(ConfigProblem::new(
                    format!("replay.columns.{col}"),
                    format!("tag '{}' is already fed by column '{prev}'", info.name),
                ));
            }
        }
        p
    }

    /// The delimiter as a byte, if valid.
    pub fn delimiter_byte(&self) -> Option<u8> {
        let d = if self.delimiter == "\\t" {
            "\t"
        } else {
            &self.delimiter
        };
        match d.as_bytes() {
            [b] if b.is_ascii() => Some(*b),
            _ => None,
        }
    }
}

/// The tag a mapping value names: a signal's canonical tag, or a plain tag.
pub(super) fn tag_for_mapping(value: &str) -> TagInfo {
    match value.parse::<Signal>() {
        Ok(sig) => TagInfo::for_signal(sig),
        Err(_) => TagInfo {
            name: value.trim().to_string(),
            unit: String::new(),
            signal: None,
        },
    }
}
