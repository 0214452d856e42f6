//! Component maps: the GasTurb text-format reader, compressor and turbine maps with the
//! extrapolation a start-up from cranking needs, and design-point scaling with health factors.
//!
//! What it is for: fast, allocation-free map look-ups for the engine model. What it must not do:
//! I/O other than [`gasturb::read_file`]; globals other than the embedded map texts.
//!
//! The engine's three maps (public NASA T-MATS JT9D data, Apache-2.0, see
//! `config/maps/SOURCES.md`) are embedded in the binary ([`HPC_MAP`], [`HPT_MAP`], [`LPT_MAP`])
//! so a deployed daemon needs no data files; [`hpc`], [`hpt`], [`lpt`] parse them.
//!
//! Layers:
//! * [`gasturb`]: text -> named tables ([`GasTurbFile`]), errors naming file, table, position.
//! * [`compressor`], [`turbine`]: map units (relative corrected speed, beta, map flow), with the
//!   documented extrapolation rules.
//! * [`scaled`]: engine units and health ([`ScaledCompressor`], [`ScaledTurbine`]).
//!
//! β conventions: an engine file states the compressor design β as the map file does (GasTurb /
//! GSP read the column keys as they stand); internally a compressor map runs from the surge end
//! at low β, flipping files whose PR rises with β ([`CompressorMap::beta_from_file`]). Turbine
//! design points are given as map PR, `PRmin + β (PRmax − PRmin)` for a GasTurb/GSP turbine β.
//!
//! Interpolation is bilinear in (speed, β) inside every map by default, or the not-a-knot
//! tensor-product cubic spline of [`spline`] (as GSPy/SciPy) when an engine file selects
//! `maps.interpolation = "cubic"` (see [`compressor`], [`turbine`]).

pub(crate) mod adapt;
pub mod compressor;
pub mod gasturb;
pub(crate) mod scaled;
pub(crate) mod spline;
pub mod turbine;

pub use adapt::{ComponentAdaptation, SpeedCurve};
pub use compressor::{CompressorMap, CompressorPoint};
pub use gasturb::{parse, read_file, GasTurbFile, MapError, MapTable};
pub use scaled::{
    CompressorOp, CurveSpeed, MapScalers, ScaledCompressor, ScaledTurbine, TurbineOp,
};
pub use turbine::{TurbineMap, TurbinePoint};

/// The engine's compressor map (JT9D HPC; design speed 1.0, beta 0.5: PR 23.0, eff 0.852).
pub const HPC_MAP: &str = include_str!("../../config/maps/hpc.map");
/// The engine's HP turbine map (JT9D HPT; design speed 1.0, PR 5.0: eff 0.9328).
pub const HPT_MAP: &str = include_str!("../../config/maps/hpt.map");
/// The engine's power turbine map (JT9D LPT; design speed 1.0, PR 5.0: eff 0.9383).
pub const LPT_MAP: &str = include_str!("../../config/maps/lpt.map");

/// Map coordinates of the compressor design point: speed 1.0, beta 0.5.
pub const HPC_DESIGN: (f64, f64) = (1.0, 0.5);
/// Map coordinates of the HPT and power-turbine design points: speed 1.0, PR 5.0.
pub const TURBINE_DESIGN: (f64, f64) = (1.0, 5.0);

/// Parse the embedded compressor map.
pub fn hpc() -> Result<CompressorMap, MapError> {
    CompressorMap::from_gasturb(&parse(HPC_MAP, "hpc.map (embedded)")?)
}
/// Parse the embedded HP turbine map.
pub fn hpt() -> Result<TurbineMap, MapError> {
    TurbineMap::from_gasturb(&parse(HPT_MAP, "hpt.map (embedded)")?)
}
/// Parse the embedded power turbine map.
pub fn lpt() -> Result<TurbineMap, MapError> {
    TurbineMap::from_gasturb(&parse(LPT_MAP, "lpt.map (embedded)")?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::{Path, PathBuf};

    /// The project's own copies of the GasTurb-format maps (sources in `config/maps/SOURCES.md`);
    /// a clone has them, so the tests never read outside the repository.
    fn map_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("config/maps")
    }

    /// The maps taken unchanged from their sources (the md22_* maps are derived from these).
    const SOURCE_MAPS: [&str; 5] = [
        "hpc.map",
        "hpt.map",
        "lpt.map",
        "gspy_compmap.map",
        "gspy_turbimap.map",
    ];

    #[test]
    fn embedded_maps_equal_map_files() {
        for (name, text) in [
            ("hpc.map", HPC_MAP),
            ("hpt.map", HPT_MAP),
            ("lpt.map", LPT_MAP),
        ] {
            let file = std::fs::read_to_string(map_dir().join(name)).expect("map file");
            assert_eq!(file, text, "{name} differs from config/maps");
        }
    }

    #[test]
    fn every_source_map_parses_and_builds() {
        for name in SOURCE_MAPS {
            let path = map_dir().join(name);
            let f = read_file(&path).expect("parses");
            assert!(!f.tables.is_empty());
            if f.table("Surge Line").is_some() {
                let m = CompressorMap::from_gasturb(&f).expect("compressor map");
                let p = m.point(1.0, 0.5);
                assert!(p.wc > 0.0 && p.pr > 1.0 && p.eff > 0.5, "{path:?}: {p:?}");
            } else {
                let m = TurbineMap::from_gasturb(&f).expect("turbine map");
                let (lo, hi) = m.pr_limits(1.0);
                let p = m.point(1.0, 0.5 * (lo + hi));
                assert!(p.wc > 0.0 && p.eff > 0.5, "{path:?}: {p:?}");
            }
        }
        // Building the wrong type names the missing table.
        let f = read_file(&map_dir().join("hpt.map")).expect("parses");
        let e = CompressorMap::from_gasturb(&f)
            .expect_err("not a compressor")
            .to_string();
        assert!(
            e.contains("hpt.map") && e.contains("\"Pressure Ratio\""),
            "{e}"
        );
    }

    #[test]
    fn design_points_of_embedded_maps() {
        let p = hpc().expect("hpc").point(HPC_DESIGN.0, HPC_DESIGN.1);
        assert!((p.pr - 23.0).abs() < 1e-3 && (p.eff - 0.852).abs() < 1e-12);
        let t = hpt()
            .expect("hpt")
            .point(TURBINE_DESIGN.0, TURBINE_DESIGN.1);
        assert!((t.eff - 0.9328).abs() < 1e-12);
        let t = lpt()
            .expect("lpt")
            .point(TURBINE_DESIGN.0, TURBINE_DESIGN.1);
        assert!((t.eff - 0.9383).abs() < 1e-12);
    }

    /// Re-wrap all numbers of each table at arbitrary widths (as other writers do) and check the
    /// parse is unchanged.
    #[test]
    fn rewrapped_files_parse_identically() {
        for name in [
            "hpc.map",
            "hpt.map",
            "gspy_compmap.map",
            "gspy_turbimap.map",
        ] {
            let text = std::fs::read_to_string(map_dir().join(name)).expect("map");
            let reference = parse(&text, name).expect("parses");
            for width in [1usize, 2, 3, 5, 7, 13, 40] {
                let mut out = String::new();
                let mut count = 0;
                for (i, line) in text.lines().enumerate() {
                    let numeric = line
                        .split_whitespace()
                        .next()
                        .is_some_and(|t| t.parse::<f64>().is_ok());
                    if i == 0 || !numeric {
                        if count > 0 {
                            out.push('\n');
                            count = 0;
                        }
                        out.push_str(line);
                        out.push('\n');
                        continue;
                    }
                    for tok in line.split_whitespace() {
                        out.push_str("  ");
                        out.push_str(tok);
                        count += 1;
                        if count % width == 0 {
                            out.push('\n');
                            count = 0;
                        }
                    }
                }
                let wrapped = parse(&out, name).expect("wrapped parses");
                assert_eq!(wrapped, reference, "{name} wrapped at {width}");
            }
        }
    }
}
