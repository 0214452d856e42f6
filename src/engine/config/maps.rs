//! The `[maps]` section: which GasTurb map each component reads (a file, or its text written
//! in the engine file), its design point on the map, and how the map is interpolated; and
//! [`inline_map_files`], which makes an engine file self-contained. Parses and validates only:
//! no map is read or built here.

use super::EngineConfigError;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Component maps: `""` selects the embedded map, otherwise a GasTurb file path; a relative
/// path is relative to the engine file's directory (see [`EngineConfig::load`]). A map's
/// GasTurb text may also be written in the file itself (`compressor_map`, `hpt_map`,
/// `pt_map`; [`inline_map_files`] turns paths into them), which makes an engine file
/// self-contained: what a fleet re-diagnosis job sends a worker elsewhere.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapsConfig {
    pub compressor_file: String,
    /// The compressor map's GasTurb text itself, instead of `compressor_file`.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub compressor_map: String,
    /// The HPT map's GasTurb text itself, instead of `hpt_file`.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub hpt_map: String,
    /// The PT map's GasTurb text itself, instead of `pt_file`.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub pt_map: String,
    /// Relative corrected speed of the design point on the compressor map.
    pub compressor_design_speed: f64,
    /// β of the design point **as the map file states it** (its column keys, as GasTurb and
    /// GSP/GSPy read the file), whichever way the file's PR runs with β; see `maps::compressor`.
    pub compressor_design_beta: f64,
    pub hpt_file: String,
    pub hpt_design_speed: f64,
    /// Map pressure ratio of the HPT design point (GasTurb/GSP turbine β converts as
    /// `PR = PRmin + β (PRmax − PRmin)` at the design speed).
    pub hpt_design_pr: f64,
    pub pt_file: String,
    pub pt_design_speed: f64,
    pub pt_design_pr: f64,
    /// How all three maps are interpolated inside their grids (default bilinear).
    #[serde(default)]
    pub interpolation: MapInterpolation,
}

/// Map interpolation inside the grid (`maps::compressor`, `maps::turbine`, `maps::spline`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MapInterpolation {
    /// Bilinear in (speed, β): gtwatch's default.
    #[default]
    Linear,
    /// Not-a-knot tensor-product cubic splines (SciPy's `RegularGridInterpolator` "cubic", as
    /// GSPy uses): smoother, for agreement with peers that interpolate so.
    Cubic,
}

/// The `[maps]` keys of a map's file and of its inline text, per component.
pub const MAP_FILE_AND_TEXT_KEYS: [(&str, &str); 3] = [
    ("compressor_file", "compressor_map"),
    ("hpt_file", "hpt_map"),
    ("pt_file", "pt_map"),
];

/// `text` (an engine file's) with every map it names by path written into it as that map's
/// inline GasTurb text (`compressor_file = "x.map"` becomes `compressor_file = ""` and
/// `compressor_map = "…"`), the rest of the file as it was: an engine that needs no other file.
/// Relative paths are read from `dir` (the engine file's directory) when given. Errors name the
/// key and the file.
pub fn inline_map_files(text: &str, dir: Option<&Path>) -> Result<String, EngineConfigError> {
    let invalid = |key: &str, reason: String| EngineConfigError::Invalid {
        path: "<engine file>".into(),
        key: key.into(),
        reason,
    };
    let mut doc: toml_edit::DocumentMut =
        text.parse()
            .map_err(|e: toml_edit::TomlError| EngineConfigError::Parse {
                path: "<engine file>".into(),
                message: e.to_string(),
            })?;
    let Some(maps) = doc.get_mut("maps").and_then(|m| m.as_table_like_mut()) else {
        return Ok(text.to_string());
    };
    let mut changed = false;
    for (file_key, map_key) in MAP_FILE_AND_TEXT_KEYS {
        let Some(file) = maps
            .get(file_key)
            .and_then(|v| v.as_str())
            .filter(|f| !f.is_empty())
            .map(str::to_string)
        else {
            continue;
        };
        let path = match dir {
            Some(d) if Path::new(&file).is_relative() => d.join(&file),
            _ => Path::new(&file).to_path_buf(),
        };
        let map_text = std::fs::read_to_string(&path).map_err(|e| {
            invalid(
                &format!("maps.{file_key}"),
                format!("reading {}: {e}", path.display()),
            )
        })?;
        maps.insert(file_key, toml_edit::value(""));
        maps.insert(map_key, toml_edit::value(map_text));
        changed = true;
    }
    Ok(if changed {
        doc.to_string()
    } else {
        text.to_string()
    })
}

impl MapsConfig {
    /// The map of each component: its file path and its inline text (at most one non-empty).
    pub fn sources(&self) -> [(&'static str, &str, &str); 3] {
        [
            ("compressor", &self.compressor_file, &self.compressor_map),
            ("hpt", &self.hpt_file, &self.hpt_map),
            ("pt", &self.pt_file, &self.pt_map),
        ]
    }

    /// Rewrites every non-empty, relative map path as `dir/path` (absolute paths and `""`, the
    /// embedded map, are unchanged). [`EngineConfig::load`] calls this with the engine file's
    /// directory.
    pub fn resolve_relative_to(&mut self, dir: &Path) {
        for file in [
            &mut self.compressor_file,
            &mut self.hpt_file,
            &mut self.pt_file,
        ] {
            if !file.is_empty() && Path::new(file.as_str()).is_relative() {
                *file = dir.join(file.as_str()).display().to_string();
            }
        }
    }
}
