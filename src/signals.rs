//! The engine's signal and phase vocabulary, shared by the physics, the store and the daemon.
//!
//! Every module names a measured quantity with [`Signal`] and a start-up phase with [`Phase`],
//! so a CSV column, a database tag and a model output agree on spelling and unit. This module
//! holds names only: no physics, no I/O.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// A gas-path quantity the plant measures or the model computes. Units are in the column name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Signal {
    /// Gas-generator (compressor/HPT) shaft speed, rpm.
    N1,
    /// Power-turbine shaft speed, rpm.
    N2,
    /// Compressor inlet total temperature, K.
    T1,
    /// Compressor inlet total pressure, kPa.
    P1,
    /// Compressor exit temperature, K.
    T2,
    /// Compressor exit pressure, kPa.
    P2,
    /// Combustor exit / HPT inlet temperature, K (not measured on real plants).
    T3,
    /// Combustor exit pressure, kPa.
    P3,
    /// HPT exit / PT inlet temperature, K.
    T34,
    /// HPT exit / PT inlet pressure, kPa.
    P34,
    /// PT exit (exhaust) temperature, K.
    T4,
    /// PT exit pressure, kPa.
    P4,
    /// Fuel mass flow, kg/s.
    FuelFlow,
    /// Power at the PT coupling (generator output), MW.
    Power,
    /// Compressor surge margin, percent (model only).
    SurgeMargin,
    /// Shaft torque at the PT coupling, kN·m (a torque meter: power = torque × ω; mechanical
    /// drives often measure this rather than electrical power).
    Torque,
    /// Compressor inlet depression, ambient minus compressor-inlet total pressure, kPa: the
    /// bellmouth/filter-house pressure drop, a flow measure (it grows with flow squared).
    InletDepression,
}

impl Signal {
    /// All signals in the canonical column order of `gtwatch simulate`.
    pub const ALL: [Signal; 17] = [
        Signal::N1,
        Signal::N2,
        Signal::T1,
        Signal::P1,
        Signal::T2,
        Signal::P2,
        Signal::T3,
        Signal::P3,
        Signal::T34,
        Signal::P34,
        Signal::T4,
        Signal::P4,
        Signal::FuelFlow,
        Signal::Power,
        Signal::SurgeMargin,
        Signal::Torque,
        Signal::InletDepression,
    ];

    /// Column / tag name with its unit, e.g. `n1_rpm`, `p2_kpa`.
    pub const fn column(self) -> &'static str {
        match self {
            Signal::N1 => "n1_rpm",
            Signal::N2 => "n2_rpm",
            Signal::T1 => "t1_k",
            Signal::P1 => "p1_kpa",
            Signal::T2 => "t2_k",
            Signal::P2 => "p2_kpa",
            Signal::T3 => "t3_k",
            Signal::P3 => "p3_kpa",
            Signal::T34 => "t34_k",
            Signal::P34 => "p34_kpa",
            Signal::T4 => "t4_k",
            Signal::P4 => "p4_kpa",
            Signal::FuelFlow => "fuel_kg_s",
            Signal::Power => "power_mw",
            Signal::SurgeMargin => "surge_margin",
            Signal::Torque => "torque_knm",
            Signal::InletDepression => "dp_inlet_kpa",
        }
    }

    /// Short engineering name as used in configs and register maps: `n1`, `T2`, `fuel_flow`, …
    pub const fn short(self) -> &'static str {
        match self {
            Signal::N1 => "n1",
            Signal::N2 => "n2",
            Signal::T1 => "T1",
            Signal::P1 => "P1",
            Signal::T2 => "T2",
            Signal::P2 => "P2",
            Signal::T3 => "T3",
            Signal::P3 => "P3",
            Signal::T34 => "T34",
            Signal::P34 => "P34",
            Signal::T4 => "T4",
            Signal::P4 => "P4",
            Signal::FuelFlow => "fuel_flow",
            Signal::Power => "power",
            Signal::SurgeMargin => "surge_margin",
            Signal::Torque => "torque",
            Signal::InletDepression => "dp_inlet",
        }
    }

    /// Index into [`Signal::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for Signal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.column())
    }
}

/// Number of signals ([`Signal::ALL`]).
pub const NSIG: usize = Signal::ALL.len();

/// One value per signal, indexed by [`Signal::index`] (NaN where missing).
pub type Values = [f64; NSIG];

/// Error for an unknown signal or phase name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {kind} '{name}' (expected one of: {expected})")]
pub struct UnknownName {
    pub kind: &'static str,
    pub name: String,
    pub expected: String,
}

impl FromStr for Signal {
    type Err = UnknownName;
    /// Accepts the column name (`p2_kpa`), the short name (`P2`, case-insensitive) or the
    /// snake-case variant name (`fuel_flow`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim();
        Signal::ALL
            .iter()
            .copied()
            .find(|sig| sig.column().eq_ignore_ascii_case(t) || sig.short().eq_ignore_ascii_case(t))
            .ok_or_else(|| UnknownName {
                kind: "signal",
                name: t.to_string(),
                expected: Signal::ALL
                    .iter()
                    .map(|s| s.short())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }
}

/// Phase of engine operation that a sample belongs to (REFERENCE §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    Standstill,
    Crank,
    Purge,
    LightOff,
    Acceleration,
    Idle,
    Synchronisation,
    Loading,
    Steady,
    Unloading,
    Shutdown,
    Trip,
}

impl Phase {
    pub const ALL: [Phase; 12] = [
        Phase::Standstill,
        Phase::Crank,
        Phase::Purge,
        Phase::LightOff,
        Phase::Acceleration,
        Phase::Idle,
        Phase::Synchronisation,
        Phase::Loading,
        Phase::Steady,
        Phase::Unloading,
        Phase::Shutdown,
        Phase::Trip,
    ];

    /// The phases of a start-up with the engine turning, in order: crank to steady (standstill
    /// carries no information; unloading, shutdown and trip are not part of a start-up).
    pub const STARTUP: [Phase; 8] = [
        Phase::Crank,
        Phase::Purge,
        Phase::LightOff,
        Phase::Acceleration,
        Phase::Idle,
        Phase::Synchronisation,
        Phase::Loading,
        Phase::Steady,
    ];

    /// Whether fuel may burn in this phase: from light-off on. Before it (standstill, crank,
    /// purge) the sequence keeps the fuel shut-off valve closed, so a fuel meter reading
    /// anything there reads its own zero offset, not a flow.
    pub const fn may_burn(self) -> bool {
        !matches!(self, Phase::Standstill | Phase::Crank | Phase::Purge)
    }

    pub const fn name(self) -> &'static str {
        match self {
            Phase::Standstill => "standstill",
            Phase::Crank => "crank",
            Phase::Purge => "purge",
            Phase::LightOff => "light_off",
            Phase::Acceleration => "acceleration",
            Phase::Idle => "idle",
            Phase::Synchronisation => "synchronisation",
            Phase::Loading => "loading",
            Phase::Steady => "steady",
            Phase::Unloading => "unloading",
            Phase::Shutdown => "shutdown",
            Phase::Trip => "trip",
        }
    }

    /// Small integer code, stable across releases (used in Modbus registers and the database).
    pub fn code(self) -> u16 {
        self as u16
    }

    pub fn from_code(code: u16) -> Option<Phase> {
        Phase::ALL.get(code as usize).copied()
    }
}

impl fmt::Display for Phase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Phase {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim();
        Phase::ALL
            .iter()
            .copied()
            .find(|p| {
                p.name().eq_ignore_ascii_case(t)
                    || (t.eq_ignore_ascii_case("lightoff") && *p == Phase::LightOff)
            })
            .ok_or_else(|| UnknownName {
                kind: "phase",
                name: t.to_string(),
                expected: Phase::ALL
                    .iter()
                    .map(|p| p.name())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for s in Signal::ALL {
            assert_eq!(s.column().parse::<Signal>(), Ok(s));
            assert_eq!(s.short().parse::<Signal>(), Ok(s));
            assert_eq!(Signal::ALL[s.index()], s);
        }
        for p in Phase::ALL {
            assert_eq!(p.name().parse::<Phase>(), Ok(p));
            assert_eq!(Phase::from_code(p.code()), Some(p));
        }
        assert!("t9".parse::<Signal>().is_err());
    }
}
