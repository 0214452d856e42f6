//! The engine file's `[fuel]` section: a gas by its mole fractions or a liquid by its H/C
//! ratio, at its supply temperature.
//!
//! What it is for: reading and checking the fuel description and turning it into a
//! [`crate::thermo::Fuel`] (LHV, sensible enthalpy, products). What it must not do: physics of
//! its own (that is `thermo::fuel`) or I/O.
//!
//! ```toml
//! [fuel]
//! kind = "gas"             # or "liquid"
//! temperature_k = 300.0    # supply temperature
//! [fuel.composition]       # gas: mole fractions, summing to 1 (±0.001); absent species are 0
//! CH4 = 0.92
//! C2H6 = 0.05
//! N2 = 0.03
//! ```
//!
//! A liquid gives `h_to_c_ratio` (molar H/C) instead of `[fuel.composition]`, and optionally its
//! certificate's `lhv_j_per_kg` (else estimated from H/C, see `thermo::fuel`).
//!
//! Without a `[fuel]` section the engine burns methane: with `design.fuel_lhv_j_per_kg` given,
//! exactly as before fuels could be described (that LHV, fuel at 288.15 K); with neither, methane
//! by composition at 288.15 K. Giving both is an error.

use crate::thermo::{Fuel, FuelError};
use serde::{Deserialize, Serialize};

/// Gas or liquid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FuelKind {
    Gas,
    Liquid,
}

/// Mole fractions of a gas fuel; species not given are 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GasComposition {
    #[serde(rename = "CH4", default)]
    pub ch4: f64,
    #[serde(rename = "C2H6", default)]
    pub c2h6: f64,
    #[serde(rename = "C3H8", default)]
    pub c3h8: f64,
    #[serde(rename = "C4H10", default)]
    pub c4h10: f64,
    #[serde(rename = "N2", default)]
    pub n2: f64,
    #[serde(rename = "CO2", default)]
    pub co2: f64,
    #[serde(rename = "H2", default)]
    pub h2: f64,
}

impl GasComposition {
    /// In the order of [`crate::thermo::GAS_FUEL_SPECIES`].
    pub fn mole_fractions(&self) -> [f64; 7] {
        [
            self.ch4, self.c2h6, self.c3h8, self.c4h10, self.n2, self.co2, self.h2,
        ]
    }
}

/// The `[fuel]` section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FuelConfig {
    pub kind: FuelKind,
    /// Fuel supply temperature at the combustor, K.
    pub temperature_k: f64,
    /// Gas: mole fractions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub composition: Option<GasComposition>,
    /// Liquid: molar H/C ratio.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub h_to_c_ratio: Option<f64>,
    /// Liquid: LHV from the fuel certificate, J/kg (default: estimated from H/C).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lhv_j_per_kg: Option<f64>,
}

/// A fuel problem: the dotted key (under `fuel.` or `design.`) and the reason.
pub(super) struct FuelProblem {
    pub key: String,
    pub reason: String,
}

fn problem(key: &str, reason: impl Into<String>) -> FuelProblem {
    FuelProblem {
        key: key.into(),
        reason: reason.into(),
    }
}

impl FuelConfig {
    /// The fuel this section describes.
    pub fn fuel(&self) -> Result<Fuel, FuelError> {
        match self.kind {
            FuelKind::Gas => {
                let Some(c) = &self.composition else {
                    return Err(FuelError {
                        field: "composition".into(),
                        reason: "a gas fuel needs its mole fractions ([fuel.composition])".into(),
                    });
                };
                for (key, given) in [
                    ("h_to_c_ratio", self.h_to_c_ratio.is_some()),
                    ("lhv_j_per_kg", self.lhv_j_per_kg.is_some()),
                ] {
                    if given {
                        return Err(FuelError {
                            field: key.into(),
                            reason:
                                "is for a liquid fuel; a gas fuel's follows from its composition"
                                    .into(),
                        });
                    }
                }
                Fuel::gas(&c.mole_fractions(), self.temperature_k)
            }
            FuelKind::Liquid => {
                if self.composition.is_some() {
                    return Err(FuelError {
                        field: "composition".into(),
                        reason: "is for a gas fuel; a liquid is described by h_to_c_ratio".into(),
                    });
                }
                let Some(y) = self.h_to_c_ratio else {
                    return Err(FuelError {
                        field: "h_to_c_ratio".into(),
                        reason: "a liquid fuel needs its molar H/C ratio".into(),
                    });
                };
                Fuel::liquid(y, self.temperature_k, self.lhv_j_per_kg)
            }
        }
    }
}

/// The fuel an engine file burns (see the module docs for the default), or the key at fault.
pub(super) fn engine_fuel(
    section: Option<&FuelConfig>,
    design_lhv: Option<f64>,
) -> Result<Fuel, FuelProblem> {
    match (section, design_lhv) {
        (Some(_), Some(_)) => Err(problem(
            "design.fuel_lhv_j_per_kg",
            "give either it (methane at 288.15 K with this LHV) or a [fuel] section, not both",
        )),
        (Some(f), None) => f
            .fuel()
            .map_err(|e| problem(&format!("fuel.{}", e.field), e.reason)),
        (None, Some(lhv)) => Ok(Fuel::methane_with_lhv(lhv)),
        (None, None) => {
            let mut methane = [0.0; 7];
            methane[0] = 1.0;
            Fuel::gas(&methane, crate::thermo::T_REF_K)
                .map_err(|e| problem(&format!("fuel.{}", e.field), e.reason))
        }
    }
}
