//! Fuels: a gas by its mole fractions, or a liquid by its H/C ratio, at its supply temperature.
//!
//! What it is for: from a fuel's description, the three things the combustor energy balance
//! needs — the lower heating value at [`T_REF_K`], the fuel's sensible enthalpy at its supply
//! temperature (relative to [`T_REF_K`]), and the change of product composition per kilogram of
//! fuel burnt, hence the products' `cp`, `h`, `φ` through [`Fuel::products`]. What it must not
//! do: I/O, allocation, globals other than `const`s.
//!
//! # Combustion
//!
//! Complete lean combustion from the C, H, O, N balance: each mole of fuel gives
//! `C` mol CO2 (plus the fuel's own CO2), `H/2` mol H2O and the fuel's N2, and takes
//! `C + H/4` mol O2 from the air (C, H: atoms of C and H per mole of fuel). As for methane in
//! [`Gas::products`], the lean formula is continued past stoichiometric.
//!
//! # Heating value
//!
//! Gas: `LHV(T_REF) = [Σ x_i H°_i + (C + H/4) H°_O2 − C H°_CO2 − H/2 H°_H2O(g)] / M_fuel`, every
//! `H°` the standard molar enthalpy *including the heat of formation* at 288.15 K from the same
//! NASA polynomials ([`super::species`]: GRI-Mech 3.0, n-butane from Burcat's database via
//! JetSurF 2.0). This gives CH4 50.03 MJ/kg, C2H6 47.52, C3H8 46.36, n-C4H10 45.73, H2 119.90
//! (ISO 6976:2016 net calorific values at 15 °C: 802.69, 1428.84, 2043.37, 2657.60, 241.72
//! kJ/mol, i.e. 50.04, 47.52, 46.34, 45.72, 119.91 MJ/kg; tested in `fuel_tests.rs`).
//!
//! # Density at a meter's reference conditions
//!
//! A gas meter states volumes at reference conditions ([`VolumeBasis`]: normal m³ at 0 °C,
//! standard m³ at 15 °C, both 101.325 kPa; standard ft³ at 60 °F and 14.696 psia). The density
//! there is `ρ = p M / (Z R T)` with the compression factor of ISO 6976 (1995, §5):
//! `Z = 1 − (Σ x_i √b_i)²`, `√b_i` the components' summation factors at 0 °C and 15 °C
//! (CH4 0.0490 / 0.0447, C2H6 0.1000 / 0.0922, C3H8 0.1453 / 0.1338, n-C4H10 0.2069 / 0.1871,
//! N2 0.0224 / 0.0173, CO2 0.0819 / 0.0748, H2 −0.0040 / −0.0048); the 15 °C factors serve
//! 60 °F (0.56 K apart, Z then changes by under 1e-5). Methane: 0.7175 kg/m³ at 0 °C (Z
//! 0.9976; an ideal gas would be 0.24 % lighter, the size of a fuel meter's whole error
//! budget). A liquid has no such density here.
//!
//! Liquid `CH_y`: the higher heating value from the correlation of Channiwala & Parikh (2002),
//! *A unified correlation for estimating HHV of solid, liquid and gaseous fuels*, Fuel 81,
//! 1051–1063: `HHV [MJ/kg] = 0.3491 C + 1.1783 H` (C, H in mass percent; no S, O, N, ash), less
//! the latent heat of the water formed (2465.4 kJ/kg at 15 °C, IAPWS-IF97 steam tables). It
//! gives 43.4 MJ/kg for H/C 1.92 (Jet A, typically 43.2) and 44.3 for n-dodecane (44.1 from its
//! heat of formation); the correlation's stated mean error is 1.5 %, so a fuel certificate's
//! LHV, when known, should be given instead (`lhv_j_per_kg`). The liquid's sensible enthalpy
//! uses a constant `cp` of 2.0 kJ/(kg K) (kerosene and diesel near 300 K, CRC Handbook of
//! Aviation Fuel Properties, 2004).

use super::species::{
    Species, C2H6, C3H8, C4H10, CH4, CO2, H2, H2O, N2, O2, W_C, W_CO2, W_H, W_H2O, W_N2, W_O2,
};
use super::{derive, Coeffs, Gas, DELTA, T_REF_K, Y_AIR, Y_DELTA};

/// The gas-fuel species, in the order of the mole-fraction array of [`Fuel::gas`].
pub const GAS_FUEL_SPECIES: [&str; 7] = ["CH4", "C2H6", "C3H8", "C4H10", "N2", "CO2", "H2"];

/// How far the mole fractions of a gas fuel may sum away from 1 (they are then normalised).
pub const COMPOSITION_SUM_TOLERANCE: f64 = 1e-3;

/// Specific heat of a liquid fuel, J/(kg K) (kerosene/diesel near 300 K).
pub const LIQUID_CP_J_PER_KG_K: f64 = 2000.0;

/// Supply temperatures accepted, K (the fuel species' polynomials are used below 1000 K).
pub const FUEL_T_MIN_K: f64 = 200.0;
pub const FUEL_T_MAX_K: f64 = 800.0;

/// Latent heat of water at 15 °C, J/kg (IAPWS-IF97).
const WATER_HFG_J_PER_KG: f64 = 2.4654e6;

/// Per gas-fuel species: NASA data, C atoms burnt to CO2 and H atoms burnt to H2O per molecule
/// (N2 and CO2 pass through: handled on their own).
const GAS_SPECIES: [(&Species, f64, f64); 7] = [
    (&CH4, 1.0, 4.0),
    (&C2H6, 2.0, 6.0),
    (&C3H8, 3.0, 8.0),
    (&C4H10, 4.0, 10.0),
    (&N2, 0.0, 0.0),
    (&CO2, 0.0, 0.0),
    (&H2, 0.0, 2.0),
];
const IX_N2: usize = 4;
const IX_CO2: usize = 5;

/// Universal gas constant, J/(mol K) (CODATA 2018, exact).
const R_UNIVERSAL: f64 = 8.314_462_618;

/// ISO 6976 summation factors √b of the gas-fuel species at 0 °C and at 15 °C, in the order of
/// [`GAS_FUEL_SPECIES`] (C4H10 as n-butane; module docs).
const SUMMATION_FACTORS: [[f64; 2]; 7] = [
    [0.0490, 0.0447],
    [0.1000, 0.0922],
    [0.1453, 0.1338],
    [0.2069, 0.1871],
    [0.0224, 0.0173],
    [0.0819, 0.0748],
    [-0.0040, -0.0048],
];

/// The reference conditions a gas meter states volumes at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VolumeBasis {
    /// Normal cubic metre: 0 °C, 101.325 kPa (DIN 1343; European gas metering).
    Normal,
    /// Standard cubic metre: 15 °C, 101.325 kPa (ISO 13443).
    Standard,
    /// Standard cubic foot: 60 °F, 14.696 psia (GPA 2145; a meter on the AGA base of 14.73
    /// psia counts 0.23 % fewer of them per kilogram).
    StandardCubicFoot,
}

impl VolumeBasis {
    /// Reference temperature (K) and pressure (kPa).
    pub fn conditions(self) -> (f64, f64) {
        match self {
            VolumeBasis::Normal => (273.15, 101.325),
            VolumeBasis::Standard => (288.15, 101.325),
            VolumeBasis::StandardCubicFoot => (288.15 + 5.0 / 9.0 * (60.0 - 59.0), 101.325),
        }
    }

    /// Cubic metres in one of this basis's volume units (1 for m³, 0.3048³ for ft³).
    pub fn unit_volume_m3(self) -> f64 {
        match self {
            VolumeBasis::Normal | VolumeBasis::Standard => 1.0,
            VolumeBasis::StandardCubicFoot => 0.3048 * 0.3048 * 0.3048,
        }
    }
}

/// What a gas fuel's density at a meter's reference conditions rests on.
#[derive(Clone, Copy, Debug, PartialEq)]
struct GasVolume {
    /// Molar mass, kg/kmol.
    molar_mass: f64,
    /// Σ x_i √b_i at 0 °C and at 15 °C (ISO 6976).
    summation: [f64; 2],
}

/// A fuel description that cannot be used; `field` names the offending part
/// (`composition.CH4`, `composition`, `h_to_c_ratio`, `temperature_k`, `lhv_j_per_kg`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct FuelError {
    pub field: String,
    pub reason: String,
}

fn fuel_error(field: impl Into<String>, reason: impl Into<String>) -> FuelError {
    FuelError {
        field: field.into(),
        reason: reason.into(),
    }
}

/// A fuel as the combustor sees it. Cheap to copy (~50 f64); built once per engine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fuel {
    /// Property coefficients' change per kg of fuel burnt (see `thermo::derive`).
    delta: Coeffs,
    /// Mass fractions (N2, O2, Ar, CO2, H2O) gained per kg of fuel burnt.
    y_delta: [f64; 5],
    lhv: f64,
    h_sensible: f64,
    temperature_k: f64,
    /// A gas's molar mass and compression-factor sums (none for a liquid).
    gas_volume: Option<GasVolume>,
}

fn check_temperature(t_k: f64) -> Result<(), FuelError> {
    if !(FUEL_T_MIN_K..=FUEL_T_MAX_K).contains(&t_k) {
        return Err(fuel_error(
            "temperature_k",
            format!("{t_k} K is outside {FUEL_T_MIN_K}–{FUEL_T_MAX_K} K"),
        ));
    }
    Ok(())
}

impl Fuel {
    /// Methane with a given LHV, delivered at 288.15 K: the model before fuels could be
    /// described (and still the default of an engine file with `design.fuel_lhv_j_per_kg`).
    /// Its products are exactly [`Gas::products`].
    pub fn methane_with_lhv(lhv_j_per_kg: f64) -> Fuel {
        Fuel {
            delta: DELTA,
            y_delta: Y_DELTA,
            lhv: lhv_j_per_kg,
            h_sensible: 0.0,
            temperature_k: T_REF_K,
            gas_volume: Some(GasVolume {
                molar_mass: CH4.w,
                summation: SUMMATION_FACTORS[0],
            }),
        }
    }

    /// A gas fuel from its mole fractions in the order of [`GAS_FUEL_SPECIES`] (CH4, C2H6,
    /// C3H8, C4H10, N2, CO2, H2), supplied at `temperature_k`. The fractions must each be in
    /// [0, 1] and sum to 1 within [`COMPOSITION_SUM_TOLERANCE`]; they are then normalised.
    pub fn gas(mole_fractions: &[f64; 7], temperature_k: f64) -> Result<Fuel, FuelError> {
        check_temperature(temperature_k)?;
        for (x, name) in mole_fractions.iter().zip(GAS_FUEL_SPECIES) {
            if !(x.is_finite() && (0.0..=1.0).contains(x)) {
                return Err(fuel_error(
                    format!("composition.{name}"),
                    format!("mole fraction {x} is outside [0, 1]"),
                ));
            }
        }
        let sum: f64 = mole_fractions.iter().sum();
        if (sum - 1.0).abs() > COMPOSITION_SUM_TOLERANCE {
            return Err(fuel_error(
                "composition",
                format!(
                    "mole fractions ({}) sum to {sum:.6}, not 1 (tolerance {COMPOSITION_SUM_TOLERANCE})",
                    GAS_FUEL_SPECIES.join(", ")
                ),
            ));
        }
        let x = mole_fractions.map(|v| v / sum);
        let (mut c, mut h, mut w, mut h_ref, mut h_fuel) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let mut summation = [0.0; 2];
        for ((xi, (sp, ci, hi)), b) in x.iter().zip(GAS_SPECIES).zip(SUMMATION_FACTORS) {
            summation[0] += xi * b[0];
            summation[1] += xi * b[1];
            c += xi * ci;
            h += xi * hi;
            w += xi * sp.w;
            h_ref += xi * sp.h_molar_low(T_REF_K);
            h_fuel += xi * sp.h_molar_low(temperature_k);
        }
        if c + h <= 0.0 {
            return Err(fuel_error(
                "composition",
                "has no combustible species (only N2 and CO2)",
            ));
        }
        // Inert N2 and CO2 appear on both sides of the reaction: leave them out of the heat.
        let inert = x[IX_N2] * N2.h_molar_low(T_REF_K) + x[IX_CO2] * CO2.h_molar_low(T_REF_K);
        let o2 = c + h / 4.0;
        let released = (h_ref - inert) + o2 * O2.h_molar_low(T_REF_K)
            - c * CO2.h_molar_low(T_REF_K)
            - h / 2.0 * H2O.h_molar_low(T_REF_K);
        let y_delta = [
            x[IX_N2] * W_N2 / w,
            -o2 * W_O2 / w,
            0.0,
            (c + x[IX_CO2]) * W_CO2 / w,
            h / 2.0 * W_H2O / w,
        ];
        Ok(Fuel {
            delta: derive(y_delta),
            y_delta,
            lhv: released / w,
            h_sensible: (h_fuel - h_ref) / w,
            temperature_k,
            gas_volume: Some(GasVolume {
                molar_mass: w,
                summation,
            }),
        })
    }

    /// A liquid hydrocarbon `CH_y` by its molar H/C ratio `y`, supplied at `temperature_k`.
    /// The LHV is `lhv_j_per_kg` when given (a fuel certificate's value), else the
    /// Channiwala–Parikh estimate (module docs).
    pub fn liquid(
        h_to_c_ratio: f64,
        temperature_k: f64,
        lhv_j_per_kg: Option<f64>,
    ) -> Result<Fuel, FuelError> {
        check_temperature(temperature_k)?;
        let y = h_to_c_ratio;
        if !(y.is_finite() && (0.5..=4.0).contains(&y)) {
            return Err(fuel_error(
                "h_to_c_ratio",
                format!("{y} is outside [0.5, 4] (molar H/C of a liquid hydrocarbon)"),
            ));
        }
        let w = W_C + y * W_H;
        let water = y / 2.0 * W_H2O / w;
        let lhv = match lhv_j_per_kg {
            Some(v) if v.is_finite() && v > 0.0 => v,
            Some(v) => {
                return Err(fuel_error(
                    "lhv_j_per_kg",
                    format!("{v} must be a positive number"),
                ))
            }
            None => {
                let (mc, mh) = (100.0 * W_C / w, 100.0 * y * W_H / w);
                (0.3491 * mc + 1.1783 * mh) * 1e6 - water * WATER_HFG_J_PER_KG
            }
        };
        let y_delta = [0.0, -(1.0 + y / 4.0) * W_O2 / w, 0.0, W_CO2 / w, water];
        Ok(Fuel {
            delta: derive(y_delta),
            y_delta,
            lhv,
            h_sensible: LIQUID_CP_J_PER_KG_K * (temperature_k - T_REF_K),
            temperature_k,
            gas_volume: None,
        })
    }

    /// Products of complete lean combustion of this fuel in dry air at fuel-air ratio `far`
    /// (kg fuel / kg air), clamped to `0 ..= FAR_MAX` as [`Gas::products`].
    #[inline]
    pub fn products(&self, far: f64) -> Gas {
        Gas::mixed(&self.delta, far)
    }

    /// Lower heating value at 288.15 K, J/kg (water as vapour).
    pub fn lhv(&self) -> f64 {
        self.lhv
    }

    /// Sensible enthalpy of the fuel at its supply temperature relative to 288.15 K, J/kg
    /// (0 for fuel supplied at 288.15 K).
    pub fn sensible_enthalpy(&self) -> f64 {
        self.h_sensible
    }

    /// Supply temperature, K.
    pub fn temperature_k(&self) -> f64 {
        self.temperature_k
    }

    /// Density at the reference conditions of `basis`, kg/m³ (real gas, ISO 6976's compression
    /// factor; module docs); `None` for a liquid.
    pub fn density_kg_m3(&self, basis: VolumeBasis) -> Option<f64> {
        let g = self.gas_volume?;
        let (t_k, p_kpa) = basis.conditions();
        let sum = match basis {
            VolumeBasis::Normal => g.summation[0],
            VolumeBasis::Standard | VolumeBasis::StandardCubicFoot => g.summation[1],
        };
        let z = 1.0 - sum * sum;
        Some(p_kpa * g.molar_mass / (z * R_UNIVERSAL * t_k))
    }

    /// Fuel-air ratio at which the products' O2 vanishes.
    pub fn stoichiometric_far(&self) -> f64 {
        -Y_AIR[1] / self.y_delta[1]
    }

    /// Mass fractions of N2, O2, Ar, CO2, H2O in the products at fuel-air ratio `far`
    /// (unclamped; for checks and reports).
    pub fn product_mass_fractions(&self, far: f64) -> [f64; 5] {
        let mut y = [0.0; 5];
        for (i, v) in y.iter_mut().enumerate() {
            *v = (Y_AIR[i] + far * self.y_delta[i]) / (1.0 + far);
        }
        y
    }
}

#[cfg(test)]
#[path = "fuel_tests.rs"]
mod tests;
