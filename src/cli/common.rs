//! Helpers shared by the data commands: loading the `[storage]`, `[replay]` and `[detector]`
//! sections from the config file, parsing times given on the command line, and the listing
//! commands' output-format options (`FormatArgs`).
//!
//! Reads only the three sections the data side owns and ignores the others (they belong to the
//! full `Config`, which validates them); must not validate other sections.

use crate::calibrate::edit::NewValue;
use crate::detect::DetectorConfig;
use crate::engine::EngineConfig;
use crate::ingest::ReplayConfig;
use crate::store::StorageConfig;
use anyhow::{bail, Context};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The sections of `gtwatch.toml` the data commands need.
#[derive(Debug, Clone, Default, Deserialize)]
pub(super) struct DataSections {
    #[serde(default)]
    pub storage: StorageConfig,
    #[serde(default)]
    pub replay: ReplayConfig,
    #[serde(default)]
    pub detector: DetectorConfig,
    #[serde(default)]
    pub quality: crate::quality::QualityConfig,
}

impl DataSections {
    /// Reads and checks the three sections; every problem names its key.
    pub(super) fn load(path: &Path) -> anyhow::Result<DataSections> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading config {}", path.display()))?;
        let value: toml::Table =
            toml::from_str(&text).with_context(|| format!("config {}", path.display()))?;
        let mut pick = toml::Table::new();
        for key in ["storage", "replay", "detector", "quality"] {
            if let Some(v) = value.get(key) {
                pick.insert(key.to_string(), v.clone());
            }
        }
        let mut sections: DataSections = pick
            .try_into()
            .with_context(|| format!("config {}", path.display()))?;
        // The detector's engine speeds come from the engine file unless the section sets them.
        let engine_file = engine_model_path(&value, path);
        match crate::engine::config::EngineConfig::load_or_reference(engine_file.as_deref()) {
            Ok(engine) => {
                sections
                    .detector
                    .fill_from_engine(value.get("detector"), &engine);
                // A fuel column stated by volume is converted with the engine's fuel.
                sections.replay.fuel = engine.fuel().ok();
            }
            // Commands that only read the database must not fail on the engine file; the
            // commands that use the engine report it themselves.
            Err(e) => tracing::warn!(
                "[detector]: the engine file could not be read ({e}); its speeds are the \
                 built-in engine's"
            ),
        }
        let mut problems = sections.storage.validate();
        problems.extend(sections.replay.validate());
        problems.extend(sections.detector.validate());
        problems.extend(sections.quality.validate());
        if !problems.is_empty() {
            let list: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
            bail!("config {}:\n  {}", path.display(), list.join("\n  "));
        }
        // A relative database path is relative to the config file's directory.
        if sections.storage.path.is_relative() {
            if let Some(dir) = path.parent() {
                sections.storage.path = dir.join(&sections.storage.path);
            }
        }
        Ok(sections)
    }
}

/// `[plant] engine_model` of the config file `config` read as `table`, a relative path taken
/// from the file's folder; `None` when not set (the built-in engine).
pub(super) fn engine_model_path(table: &toml::Table, config: &Path) -> Option<PathBuf> {
    let m = PathBuf::from(table.get("plant")?.get("engine_model")?.as_str()?);
    Some(match config.parent() {
        Some(dir) if m.is_relative() => dir.join(m),
        _ => m,
    })
}

/// The database path from `--db`, else from `--config`'s `[storage].path`.
pub(super) fn db_path(db: Option<&PathBuf>, config: Option<&PathBuf>) -> anyhow::Result<PathBuf> {
    match (db, config) {
        (Some(db), _) => Ok(db.clone()),
        (None, Some(cfg)) => Ok(DataSections::load(cfg)?.storage.path),
        (None, None) => bail!("give the database with --db FILE or --config FILE"),
    }
}

/// Parses a command-line time: ISO 8601 date-time (no offset = UTC), a date (midnight UTC),
/// or `@SECONDS` since the Unix epoch.
pub(super) fn parse_cli_time(s: &str) -> anyhow::Result<i64> {
    if let Some(rest) = s.strip_prefix('@') {
        return crate::time::parse_time(rest.as_bytes(), crate::time::TimeFormat::EpochS)
            .map_err(|e| anyhow::anyhow!("'{s}': {e}"));
    }
    crate::time::parse_iso8601_ms(s).map_err(|e| {
        anyhow::anyhow!(
            "'{s}' is not a time (use 2024-03-01, 2024-03-01T12:00:00Z or @EPOCH_S): {e}"
        )
    })
}

/// The `--units` option's statement of the columns not in the model's units (none: every column
/// is in the model's units), a fuel flow by volume (`fuel_kg_s=Nm3/h`) converted with the fuel
/// of `engine`.
pub(super) fn column_units(
    text: Option<&str>,
    engine: &crate::engine::Engine,
) -> anyhow::Result<crate::units::ColumnUnits> {
    let Some(t) = text else {
        return Ok(crate::units::ColumnUnits::default());
    };
    let mut units =
        crate::units::ColumnUnits::parse(t).map_err(|e| anyhow::anyhow!("--units: {e}"))?;
    if units.needs_fuel() {
        let fuel = engine
            .cfg()
            .fuel()
            .context("--units: the engine file's [fuel]")?;
        units
            .bind_fuel(&fuel)
            .map_err(|e| anyhow::anyhow!("--units: {e}"))?;
    }
    Ok(units)
}

/// The map paths of `original` (as written, relative to `from_dir`) restated for a file in
/// `to_dir`: unchanged when both folders are the same, else absolute (`calibrate` and `gap
/// --adopt` write a new engine file wherever the user says).
pub(super) fn moved_map_paths(
    original: &str,
    engine_path: &Path,
    from_dir: &Path,
    to_dir: &Path,
) -> anyhow::Result<Vec<(String, NewValue)>> {
    let raw = EngineConfig::from_toml_str(original, &engine_path.display().to_string())?;
    let canon = |d: &Path| {
        let d = if d.as_os_str().is_empty() {
            Path::new(".")
        } else {
            d
        };
        d.canonicalize()
            .with_context(|| format!("resolving folder {}", d.display()))
    };
    let (from, to) = (canon(from_dir)?, canon(to_dir)?);
    if from == to {
        return Ok(Vec::new());
    }
    let mut out = Vec::new();
    for (component, file, _) in raw.maps.sources() {
        if !file.is_empty() && Path::new(file).is_relative() {
            let abs = from.join(file);
            out.push((
                format!("maps.{component}_file"),
                NewValue::Text(abs.display().to_string()),
            ));
        }
    }
    Ok(out)
}

/// The output format options of the listing commands (`history`, `segments`, `fleet history`,
/// `wash advise`): `--format table|csv|json`, or `--json`, the spelling every other command
/// takes.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct FormatArgs {
    #[arg(long, value_enum, default_value_t = crate::query::Format::Table)]
    format: crate::query::Format,
    /// The same as `--format json`: one JSON document.
    #[arg(long, conflicts_with = "format")]
    json: bool,
}

impl FormatArgs {
    /// The format asked for.
    pub fn format(&self) -> crate::query::Format {
        if self.json {
            crate::query::Format::Json
        } else {
            self.format
        }
    }
}
