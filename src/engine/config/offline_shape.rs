//! `[adaptation.offline_shape]`: how little an adapted model knows of its compressor map's shape
//! *off* the healthy operating line, stated as the 1σ of two slopes along a speed line.
//!
//! Why: `calibrate --adapt` bends a borrowed map along the line the unit's healthy baseline
//! runs on, and nothing in that baseline shows how efficiency and flow change when the
//! compressor moves along a speed line, which is what degradation does: fouling moves it
//! towards choke, a worn or fouled turbine towards surge. At the same corrected speed the
//! model then takes the borrowed map's slope where the unit has its own, and the difference is
//! read as compressor health. On the third blind simulator's unit (`tests/data/foreign/indep3`,
//! noise-free rows and baseline) fouling of 5 points moved the compressor by −0.04 in log
//! pressure ratio and the efficiency was read 0.96 points too poor; HP-turbine wear moving it
//! by +0.03 read it 0.61 too good, at a stated σ of 0.2–0.3.
//!
//! The slopes: `efficiency_slope_sigma`, the 1σ of d(ln η)/d(ln PR) at constant corrected
//! speed near the operating line; `flow_slope_sigma`, that of d(ln W)/d(ln PR). Steady
//! diagnosis of an adapted file moves each point's efficiency (then flow) by that much per unit
//! of its log pressure ratio above the healthy line at the same GG speed and adds what the
//! re-fit makes of it to the parameters' σ (`diagnosis::steady::offline_shape`): nothing at
//! the healthy line, growing with how far degradation has moved the unit off it.
//!
//! The defaults are the spread of the map families gtwatch ships, measured where degradation
//! moves an engine built on each: at 92 % and 100 % of design GG speed, held, the secant of
//! ln η against ln PR from healthy to fouling of 4 points (towards choke) and to HP-turbine wear
//! of 2 / 3 (towards surge) (`gtwatch steady --engine E --n1-rpm N --health … --json`, efficiency
//! and PR read off): the md22 map (T-MATS JT9D HPC) +0.07 / +0.11 and +0.04 / +0.05, pyCycle's
//! AXI5 (`tests/data/foreign/pycgen_truth.toml`) +0.01 / +0.14 and −0.10 / +0.07, GSPy's sample
//! compressor (`config/gspy_turboshaft_2spool.toml`) −0.02 / −0.03 and −0.17 / −0.39: 1σ about
//! each side's mean 0.065 towards choke, 0.17 towards surge, 0.12 pooled. The flow's, air flow
//! over P1 with the fouling's own 4 % taken off: −0.07 / −0.03, −0.17 / −0.07, −0.20 / −0.03
//! and −0.08 / −0.05, −0.24 / −0.10, −0.21 / −0.04: 0.08 pooled. A unit's own map, or rows from
//! before a wash, narrow them; 0 turns the term off. A file without adaptation curves (the
//! model's own maps) has none.
//!
//! What it must not do: physics (the diagnosis applies it) or I/O.

use serde::{Deserialize, Serialize};

/// Default 1σ of d(ln η)/d(ln PR) at constant corrected speed (module docs).
pub const DEFAULT_EFFICIENCY_SLOPE_SIGMA: f64 = 0.12;
/// Default 1σ of d(ln W)/d(ln PR) at constant corrected speed (module docs).
pub const DEFAULT_FLOW_SLOPE_SIGMA: f64 = 0.08;
/// Largest slope σ the file may state: a slope of 2 would halve the efficiency over a
/// pressure-ratio change of a third, far beyond any speed line near its operating point.
pub const MAX_SLOPE_SIGMA: f64 = 2.0;

/// The section; a key left out takes its default.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OfflineShape {
    /// 1σ of the compressor's d(ln η)/d(ln PR) at constant corrected speed.
    #[serde(default = "default_efficiency")]
    pub efficiency_slope_sigma: f64,
    /// 1σ of the compressor's d(ln W)/d(ln PR) at constant corrected speed.
    #[serde(default = "default_flow")]
    pub flow_slope_sigma: f64,
}

fn default_efficiency() -> f64 {
    DEFAULT_EFFICIENCY_SLOPE_SIGMA
}

fn default_flow() -> f64 {
    DEFAULT_FLOW_SLOPE_SIGMA
}

impl Default for OfflineShape {
    fn default() -> Self {
        OfflineShape {
            efficiency_slope_sigma: DEFAULT_EFFICIENCY_SLOPE_SIGMA,
            flow_slope_sigma: DEFAULT_FLOW_SLOPE_SIGMA,
        }
    }
}

impl OfflineShape {
    /// Neither slope uncertain: the model's own maps.
    pub const NONE: OfflineShape = OfflineShape {
        efficiency_slope_sigma: 0.0,
        flow_slope_sigma: 0.0,
    };

    /// True when either slope is uncertain.
    pub fn any(&self) -> bool {
        self.efficiency_slope_sigma > 0.0 || self.flow_slope_sigma > 0.0
    }
}
