//! Physical units of the columns a plant's files bring, and their conversion into the units the
//! model reads (K, kPa absolute, rpm, kg/s, MW, kN·m). A historian export in °C, bar and kg/h,
//! or another maker's simulator in °F and psia, is read as it is once each column's unit is
//! stated (`--units t2_k=degC,p2_kpa=bar` on the file commands, `[replay.units]` for a replay).
//!
//! Conversions are affine and exact (`model = scale · value + offset`); a unit of the wrong
//! kind for the column (°C for a pressure) is refused naming both, and so is a gauge pressure
//! (`barg`, `psig`: the model reads absolute pressures, and the site's barometer is not a
//! constant). A speed in % of design is refused too: the design speed is the engine file's,
//! not the file's.
//!
//! A gas fuel metered by volume (`Nm3/h`, `Sm3/h`, `scf/h`, `kscf/h`, `MMscfd`) is a mass flow
//! once the fuel's density at the meter's reference conditions is known: the engine file's
//! `[fuel]` gives it ([`crate::thermo::Fuel::density_kg_m3`]), and [`ColumnUnits::bind_fuel`]
//! binds it to the stated units once the engine is read; a volume unit with no fuel bound
//! converts to NaN (a missing value), never to a guess.
//! What it must not do: I/O, or guess a unit from values (that is `diagnosis::unit_check`).

use crate::signals::Signal;
use crate::thermo::{Fuel, VolumeBasis};
use std::collections::BTreeMap;

/// Canonical name of the ambient (barometric) pressure column, kPa.
pub const AMBIENT_PRESSURE_COLUMN: &str = "p_amb_kpa";

/// What a column measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    Temperature,
    /// An absolute pressure.
    Pressure,
    /// A pressure difference (the inlet depression): gauge and water-column units are fine.
    PressureDifference,
    RotationalSpeed,
    MassFlow,
    Power,
    Torque,
    /// A dimensionless ratio (the model's surge margin).
    Fraction,
}

impl Quantity {
    fn describe(self) -> &'static str {
        match self {
            Quantity::Temperature => "a temperature",
            Quantity::Pressure => "an absolute pressure",
            Quantity::PressureDifference => "a pressure difference",
            Quantity::RotationalSpeed => "a shaft speed",
            Quantity::MassFlow => "a mass flow",
            Quantity::Power => "a power",
            Quantity::Torque => "a torque",
            Quantity::Fraction => "a fraction",
        }
    }
}

/// What `signal` measures.
pub fn quantity_of(signal: Signal) -> Quantity {
    match signal {
        Signal::T1 | Signal::T2 | Signal::T3 | Signal::T34 | Signal::T4 => Quantity::Temperature,
        Signal::P1 | Signal::P2 | Signal::P3 | Signal::P34 | Signal::P4 => Quantity::Pressure,
        Signal::InletDepression => Quantity::PressureDifference,
        Signal::N1 | Signal::N2 => Quantity::RotationalSpeed,
        Signal::FuelFlow => Quantity::MassFlow,
        Signal::Power => Quantity::Power,
        Signal::Torque => Quantity::Torque,
        Signal::SurgeMargin => Quantity::Fraction,
    }
}

/// The unit the model reads `signal` in.
pub fn model_unit(signal: Signal) -> &'static str {
    match quantity_of(signal) {
        Quantity::Temperature => "K",
        Quantity::Pressure | Quantity::PressureDifference => "kPa",
        Quantity::RotationalSpeed => "rpm",
        Quantity::MassFlow => "kg/s",
        Quantity::Power => "MW",
        Quantity::Torque => "kN·m",
        Quantity::Fraction => "fraction",
    }
}

/// One unit a column may be in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    /// The name to state it by (ASCII, e.g. `degC`).
    pub name: &'static str,
    /// As people write it (`°C`).
    pub label: &'static str,
    /// Other spellings accepted (case-insensitive, like `name`).
    aliases: &'static [&'static str],
    pub quantity: Quantity,
    /// model value = `scale` · value + `offset` (times the fuel's density at `volume`'s
    /// reference conditions for a fuel metered by volume).
    scale: f64,
    offset: f64,
    /// A gas fuel's volume flow at these reference conditions: `scale` turns it into m³/s.
    volume: Option<VolumeBasis>,
}

impl Unit {
    /// `value` in the model's unit; NaN for a volume flow, which needs the fuel's density
    /// ([`ColumnUnits::to_model`] once [`ColumnUnits::bind_fuel`] has it).
    #[inline]
    pub fn to_model(&self, value: f64) -> f64 {
        match self.volume {
            None => self.scale * value + self.offset,
            Some(_) => f64::NAN,
        }
    }

    /// Whether converting changes nothing (the model's own unit).
    pub fn is_identity(&self) -> bool {
        self.scale == 1.0 && self.offset == 0.0 && self.volume.is_none()
    }
}

const fn unit(
    name: &'static str,
    label: &'static str,
    aliases: &'static [&'static str],
    quantity: Quantity,
    scale: f64,
    offset: f64,
) -> Unit {
    Unit {
        name,
        label,
        aliases,
        quantity,
        scale,
        offset,
        volume: None,
    }
}

/// A gas fuel's volume flow at `basis`'s reference conditions, `m3_per_s` cubic metres a
/// second per unit.
const fn volume_unit(
    name: &'static str,
    label: &'static str,
    aliases: &'static [&'static str],
    basis: VolumeBasis,
    m3_per_s: f64,
) -> Unit {
    Unit {
        volume: Some(basis),
        ..unit(name, label, aliases, MassFlow, m3_per_s, 0.0)
    }
}

/// A cubic foot in m³ (exact by definition).
const FT3_M3: f64 = 0.3048 * 0.3048 * 0.3048;

use Quantity::{
    Fraction, MassFlow, Power, Pressure, PressureDifference, RotationalSpeed, Temperature, Torque,
};

/// Pounds-mass in kilograms (exact by definition).
const LB_KG: f64 = 0.453_592_37;
/// Pound-force per square inch in kPa.
const PSI_KPA: f64 = 6.894_757_293_168;
/// Standard gravity, m/s² (water-column units).
const G0: f64 = 9.806_65;

/// Every unit known, the model's own first for each quantity.
pub const UNITS: &[Unit] = &[
    unit("K", "K", &["kelvin"], Temperature, 1.0, 0.0),
    unit(
        "degC",
        "°C",
        &["°C", "C", "celsius", "deg_c"],
        Temperature,
        1.0,
        273.15,
    ),
    unit(
        "degF",
        "°F",
        &["°F", "F", "fahrenheit", "deg_f"],
        Temperature,
        5.0 / 9.0,
        273.15 - 32.0 * 5.0 / 9.0,
    ),
    unit(
        "degR",
        "°R",
        &["°R", "R", "rankine", "deg_r"],
        Temperature,
        5.0 / 9.0,
        0.0,
    ),
    unit(
        "kPa",
        "kPa",
        &["kPaa", "kPa(a)", "kPa abs"],
        Pressure,
        1.0,
        0.0,
    ),
    unit("Pa", "Pa", &["Paa", "Pa(a)"], Pressure, 1e-3, 0.0),
    unit("hPa", "hPa", &[], Pressure, 0.1, 0.0),
    unit("mbar", "mbar", &["mbara", "mbar(a)"], Pressure, 0.1, 0.0),
    unit(
        "bar",
        "bar",
        &["bara", "bar(a)", "bar abs"],
        Pressure,
        100.0,
        0.0,
    ),
    unit("MPa", "MPa", &["MPaa", "MPa(a)"], Pressure, 1000.0, 0.0),
    unit(
        "psi",
        "psi",
        &["psia", "psi(a)", "lbf/in2"],
        Pressure,
        PSI_KPA,
        0.0,
    ),
    unit("atm", "atm", &[], Pressure, 101.325, 0.0),
    unit("inHg", "inHg", &["in_hg"], Pressure, 3.386_389, 0.0),
    unit(
        "mmHg",
        "mmHg",
        &["torr", "mm_hg"],
        Pressure,
        0.133_322_387_415,
        0.0,
    ),
    // A pressure difference: the same scales, plus the water columns filter-house gauges read.
    unit(
        "kPa",
        "kPa",
        &["kPad", "kPag"],
        PressureDifference,
        1.0,
        0.0,
    ),
    unit("Pa", "Pa", &["Pad", "Pag"], PressureDifference, 1e-3, 0.0),
    unit("hPa", "hPa", &[], PressureDifference, 0.1, 0.0),
    unit(
        "mbar",
        "mbar",
        &["mbard", "mbarg"],
        PressureDifference,
        0.1,
        0.0,
    ),
    unit(
        "bar",
        "bar",
        &["bard", "barg"],
        PressureDifference,
        100.0,
        0.0,
    ),
    unit(
        "psi",
        "psi",
        &["psid", "psig"],
        PressureDifference,
        PSI_KPA,
        0.0,
    ),
    unit(
        "mmH2O",
        "mmH₂O",
        &["mmH₂O", "mmwc", "mm_h2o"],
        PressureDifference,
        G0 * 1e-3,
        0.0,
    ),
    unit(
        "inH2O",
        "inH₂O",
        &["inH₂O", "inwc", "in_h2o"],
        PressureDifference,
        G0 * 0.0254,
        0.0,
    ),
    unit(
        "rpm",
        "rpm",
        &["1/min", "min-1", "r/min"],
        RotationalSpeed,
        1.0,
        0.0,
    ),
    unit(
        "rad/s",
        "rad/s",
        &[],
        RotationalSpeed,
        30.0 / std::f64::consts::PI,
        0.0,
    ),
    unit(
        "Hz",
        "Hz",
        &["rps", "r/s", "1/s"],
        RotationalSpeed,
        60.0,
        0.0,
    ),
    unit("kg/s", "kg/s", &[], MassFlow, 1.0, 0.0),
    unit("g/s", "g/s", &[], MassFlow, 1e-3, 0.0),
    unit("kg/min", "kg/min", &[], MassFlow, 1.0 / 60.0, 0.0),
    unit("kg/h", "kg/h", &["kg/hr"], MassFlow, 1.0 / 3600.0, 0.0),
    unit("t/h", "t/h", &["t/hr", "tonne/h"], MassFlow, 1.0 / 3.6, 0.0),
    unit("lb/s", "lb/s", &["lbm/s", "pps"], MassFlow, LB_KG, 0.0),
    unit(
        "lb/h",
        "lb/h",
        &["lbm/h", "lb/hr", "pph"],
        MassFlow,
        LB_KG / 3600.0,
        0.0,
    ),
    // A gas fuel by volume at a meter's reference conditions (module docs).
    volume_unit(
        "Nm3/h",
        "Nm³/h",
        &["Nm³/h", "Nm3/hr", "Nm^3/h"],
        VolumeBasis::Normal,
        1.0 / 3600.0,
    ),
    volume_unit(
        "Nm3/s",
        "Nm³/s",
        &["Nm³/s", "Nm^3/s"],
        VolumeBasis::Normal,
        1.0,
    ),
    volume_unit(
        "Sm3/h",
        "Sm³/h",
        &["Sm³/h", "Sm3/hr", "Sm^3/h"],
        VolumeBasis::Standard,
        1.0 / 3600.0,
    ),
    volume_unit(
        "Sm3/s",
        "Sm³/s",
        &["Sm³/s", "Sm^3/s"],
        VolumeBasis::Standard,
        1.0,
    ),
    volume_unit(
        "scf/h",
        "scf/h",
        &["scfh", "scf/hr"],
        VolumeBasis::StandardCubicFoot,
        FT3_M3 / 3600.0,
    ),
    volume_unit(
        "kscf/h",
        "kscf/h",
        &["kscfh", "Mscf/h", "Mscfh", "mscf/hr"],
        VolumeBasis::StandardCubicFoot,
        1e3 * FT3_M3 / 3600.0,
    ),
    volume_unit(
        "MMscfd",
        "MMscf/d",
        &["MMscf/d", "MMscf/day", "mmscfd"],
        VolumeBasis::StandardCubicFoot,
        1e6 * FT3_M3 / 86_400.0,
    ),
    unit("MW", "MW", &[], Power, 1.0, 0.0),
    unit("kW", "kW", &[], Power, 1e-3, 0.0),
    unit("W", "W", &[], Power, 1e-6, 0.0),
    unit(
        "hp",
        "hp",
        &["bhp", "shp"],
        Power,
        7.456_998_715_822_7e-4,
        0.0,
    ),
    unit(
        "kNm",
        "kN·m",
        &["kN·m", "kN.m", "kN*m", "kN-m"],
        Torque,
        1.0,
        0.0,
    ),
    unit(
        "Nm",
        "N·m",
        &["N·m", "N.m", "N*m", "N-m"],
        Torque,
        1e-3,
        0.0,
    ),
    unit(
        "lbf.ft",
        "lbf·ft",
        &[
            "lbf·ft", "lbfft", "lbf-ft", "ft.lbf", "ft·lbf", "ftlbf", "lb.ft", "lb-ft",
        ],
        Torque,
        1.355_817_948_331_4e-3,
        0.0,
    ),
    unit("fraction", "fraction", &[], Fraction, 1.0, 0.0),
    unit("percent", "%", &["%", "pct"], Fraction, 0.01, 0.0),
];

/// Gauge pressures people write, refused for an absolute pressure.
const GAUGE: &[&str] = &[
    "barg", "bar(g)", "psig", "psi(g)", "kpag", "kpa(g)", "mbarg", "mbar(g)", "pag", "mpag",
];

fn matches(u: &Unit, text: &str) -> bool {
    u.name.eq_ignore_ascii_case(text) || u.aliases.iter().any(|a| a.eq_ignore_ascii_case(text))
}

/// The unit `text` names for a column measuring `quantity`, or why it cannot be.
pub fn unit_for(quantity: Quantity, text: &str) -> Result<&'static Unit, String> {
    let t = text.trim();
    if let Some(u) = UNITS
        .iter()
        .find(|u| u.quantity == quantity && matches(u, t))
    {
        return Ok(u);
    }
    if quantity == Quantity::Pressure && GAUGE.iter().any(|g| g.eq_ignore_ascii_case(t)) {
        return Err(format!(
            "'{t}' is a gauge pressure: the model reads absolute pressure; add the site's \
             barometric pressure to the column first and state the absolute unit ({})",
            names_of(quantity)
        ));
    }
    if quantity == Quantity::RotationalSpeed && ["%", "percent", "pct"].contains(&t) {
        return Err(format!(
            "'{t}': a speed in % of design needs the engine's design speed; convert the column \
             to rpm (one of {})",
            names_of(quantity)
        ));
    }
    if let Some(other) = UNITS.iter().find(|u| matches(u, t)) {
        return Err(format!(
            "'{t}' is a unit of {}, and this column is {}; one of {}",
            other.quantity.describe(),
            quantity.describe(),
            names_of(quantity)
        ));
    }
    Err(format!(
        "unknown unit '{t}' for {}; one of {}",
        quantity.describe(),
        names_of(quantity)
    ))
}

/// The names of the mass-flow units that need no fuel, ', '-joined.
fn mass_names() -> String {
    UNITS
        .iter()
        .filter(|u| u.quantity == MassFlow && u.volume.is_none())
        .map(|u| u.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The names the units of `quantity` are stated by, ', '-joined.
pub fn names_of(quantity: Quantity) -> String {
    UNITS
        .iter()
        .filter(|u| u.quantity == quantity)
        .map(|u| u.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// A column of a file, by its canonical name: a signal's column (`t2_k`) or the ambient
/// pressure's ([`AMBIENT_PRESSURE_COLUMN`]).
fn column_of(key: &str) -> Result<(String, Quantity), String> {
    let k = key.trim();
    if k.eq_ignore_ascii_case(AMBIENT_PRESSURE_COLUMN) {
        return Ok((AMBIENT_PRESSURE_COLUMN.to_string(), Quantity::Pressure));
    }
    let s: Signal = k.parse().map_err(|e| format!("{e}"))?;
    Ok((s.column().to_string(), quantity_of(s)))
}

/// The stated unit of each column that is not in the model's unit, by canonical column name.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ColumnUnits {
    units: BTreeMap<String, &'static Unit>,
    /// The fuel a volume flow is converted with ([`ColumnUnits::bind_fuel`]).
    fuel: Option<Fuel>,
}

/// A unit statement that cannot be used: which entry, and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unit of '{key}': {reason}")]
pub struct UnitError {
    pub key: String,
    pub reason: String,
}

impl ColumnUnits {
    /// From `(column, unit)` pairs: the column a signal name (`t2_k`, `T2`, `fuel_flow`) or
    /// `p_amb_kpa`, the unit one of [`UNITS`] of its quantity.
    pub fn from_pairs<'a>(
        pairs: impl IntoIterator<Item = (&'a str, &'a str)>,
    ) -> Result<ColumnUnits, UnitError> {
        let mut units = BTreeMap::new();
        for (key, text) in pairs {
            let err = |reason: String| UnitError {
                key: key.trim().to_string(),
                reason,
            };
            let (column, quantity) = column_of(key).map_err(err)?;
            let u = unit_for(quantity, text).map_err(err)?;
            if units.insert(column.clone(), u).is_some() {
                return Err(err(format!("{column} is stated twice")));
            }
        }
        Ok(ColumnUnits { units, fuel: None })
    }

    /// Parses `t2_k=degC,p2_kpa=bar,fuel_kg_s=kg/h` (the `--units` option).
    pub fn parse(text: &str) -> Result<ColumnUnits, UnitError> {
        let mut pairs = Vec::new();
        for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (k, v) = part.split_once('=').ok_or_else(|| UnitError {
                key: part.to_string(),
                reason: "not COLUMN=UNIT (e.g. t2_k=degC)".into(),
            })?;
            pairs.push((k, v));
        }
        ColumnUnits::from_pairs(pairs)
    }

    /// No column stated (every one in the model's unit).
    pub fn is_empty(&self) -> bool {
        self.units.is_empty()
    }

    /// The stated unit of canonical column `column`, if any.
    pub fn of(&self, column: &str) -> Option<&'static Unit> {
        self.units.get(column).copied()
    }

    /// `value` of canonical column `column` in the model's unit (unchanged when none was
    /// stated; NaN stays NaN; a fuel's volume flow is NaN until a fuel is bound).
    #[inline]
    pub fn to_model(&self, column: &str, value: f64) -> f64 {
        match self.units.get(column) {
            Some(u) => self.convert(u, value),
            None => value,
        }
    }

    /// `value` in unit `u` (one of these columns' units) in the model's unit: a fuel's volume
    /// flow with the bound fuel's density (NaN with none), any other as [`Unit::to_model`].
    #[inline]
    pub fn convert(&self, u: &Unit, value: f64) -> f64 {
        match u.volume {
            None => u.to_model(value),
            Some(basis) => self
                .fuel
                .and_then(|f| f.density_kg_m3(basis))
                .map_or(f64::NAN, |rho| u.scale * value * rho),
        }
    }

    /// Whether a column is stated as a gas fuel's volume flow (which needs the engine's fuel).
    pub fn needs_fuel(&self) -> bool {
        self.units.values().any(|u| u.volume.is_some())
    }

    /// The engine's fuel, for a fuel column stated by volume: its density at the meter's
    /// reference conditions turns the volume flow into a mass flow. Refused (naming the column)
    /// when the fuel is a liquid, which has no such density.
    pub fn bind_fuel(&mut self, fuel: &Fuel) -> Result<(), UnitError> {
        for (column, u) in &self.units {
            if let Some(basis) = u.volume {
                if fuel.density_kg_m3(basis).is_none() {
                    return Err(UnitError {
                        key: column.clone(),
                        reason: format!(
                            "'{}' is a gas volume flow, and the engine file's fuel is a liquid: \
                             state the column's mass flow unit ({})",
                            u.name,
                            mass_names()
                        ),
                    });
                }
            }
        }
        self.fuel = Some(*fuel);
        Ok(())
    }

    /// The stated units as `column=unit`, ','-joined (what `--units` takes).
    pub fn describe(&self) -> String {
        self.units
            .iter()
            .map(|(c, u)| format!("{c}={}", u.name))
            .collect::<Vec<_>>()
            .join(",")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn conv(q: Quantity, name: &str, v: f64) -> f64 {
        unit_for(q, name).expect(name).to_model(v)
    }

    #[test]
    fn conversions_land_on_known_values() {
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1.0);
        assert!(close(conv(Temperature, "degC", 15.0), 288.15));
        assert!(close(conv(Temperature, "°C", -273.15), 0.0));
        assert!(close(conv(Temperature, "degF", 59.0), 288.15));
        assert!(close(conv(Temperature, "F", -40.0), 233.15));
        assert!(close(conv(Temperature, "degR", 518.67), 288.15));
        assert!(close(conv(Pressure, "bar", 1.01325), 101.325));
        assert!((conv(Pressure, "psia", 14.695_948_775) - 101.325).abs() < 1e-8);
        assert!(close(conv(Pressure, "Pa", 101_325.0), 101.325));
        assert!(close(conv(Pressure, "mbar", 1013.25), 101.325));
        assert!(close(conv(Pressure, "atm", 1.0), 101.325));
        assert!(close(conv(Pressure, "inHg", 10.0), 33.863_89));
        assert!((conv(Pressure, "mmHg", 760.0) - 101.325).abs() < 1e-4);
        assert!(close(conv(Pressure, "Torr", 760.0), 101.325_014_435_4));
        assert!(close(conv(PressureDifference, "mmH2O", 100.0), 0.980_665));
        assert!(close(conv(PressureDifference, "inwc", 4.0), 0.996_355_64));
        assert!(close(
            conv(RotationalSpeed, "rad/s", std::f64::consts::PI),
            30.0
        ));
        assert!(close(conv(RotationalSpeed, "Hz", 50.0), 3000.0));
        assert!(close(conv(MassFlow, "kg/h", 5760.0), 1.6));
        assert!(close(conv(MassFlow, "t/h", 5.76), 1.6));
        assert!(close(conv(MassFlow, "lb/s", 1.0), 0.453_592_37));
        assert!(close(conv(MassFlow, "pph", 3600.0), 0.453_592_37));
        assert!(close(conv(Power, "kW", 28_000.0), 28.0));
        assert!(close(conv(Power, "hp", 1000.0), 0.745_699_871_582_27));
        assert!(close(conv(Torque, "N.m", 45_000.0), 45.0));
        assert!(close(conv(Torque, "lbf.ft", 1000.0), 1.355_817_948_331_4));
        assert!(close(conv(Fraction, "%", 12.0), 0.12));
        // The model's own units change nothing.
        for q in [
            Temperature,
            Pressure,
            RotationalSpeed,
            MassFlow,
            Power,
            Torque,
        ] {
            let own = UNITS.iter().find(|u| u.quantity == q).expect("own");
            assert!(own.is_identity(), "{q:?}");
        }
    }

    #[test]
    fn a_unit_of_the_wrong_kind_or_a_gauge_pressure_is_refused_with_the_reason() {
        let e = unit_for(Pressure, "degC").expect_err("°C for a pressure");
        assert!(
            e.contains("a temperature") && e.contains("an absolute pressure"),
            "{e}"
        );
        assert!(
            e.contains("bar") && e.contains("psi"),
            "the choices are listed: {e}"
        );
        let e = unit_for(Pressure, "barg").expect_err("gauge");
        assert!(e.contains("gauge") && e.contains("absolute"), "{e}");
        // A difference may be read from a gauge.
        assert!(conv(PressureDifference, "mbarg", 10.0) == 1.0);
        let e = unit_for(RotationalSpeed, "%").expect_err("percent speed");
        assert!(e.contains("design speed"), "{e}");
        let e = unit_for(Temperature, "kelvins please").expect_err("unknown");
        assert!(e.starts_with("unknown unit") && e.contains("degC"), "{e}");
    }

    #[test]
    fn column_units_parse_and_convert_by_canonical_column() {
        let u = ColumnUnits::parse("T2=degC, p2_kpa=bar,fuel_flow=kg/h,p_amb_kpa=hPa").expect("ok");
        assert_eq!(
            u.describe(),
            "fuel_kg_s=kg/h,p2_kpa=bar,p_amb_kpa=hPa,t2_k=degC"
        );
        assert_eq!(u.to_model("t2_k", 400.0), 673.15);
        assert_eq!(u.to_model("p2_kpa", 20.0), 2000.0);
        assert_eq!(u.to_model("p_amb_kpa", 1000.0), 100.0);
        assert_eq!(u.to_model("t4_k", 800.0), 800.0, "unstated: unchanged");
        assert!(u.to_model("t2_k", f64::NAN).is_nan());
        assert!(ColumnUnits::parse("").expect("empty").is_empty());
        let e = ColumnUnits::parse("t2_k=bar").expect_err("wrong kind");
        assert_eq!(e.key, "t2_k");
        assert!(e.to_string().starts_with("unit of 't2_k': "), "{e}");
        let e = ColumnUnits::parse("t9_k=degC").expect_err("no such signal");
        assert!(e.reason.contains("signal"), "{e}");
        let e = ColumnUnits::parse("t2_k degC").expect_err("no =");
        assert!(e.reason.contains("COLUMN=UNIT"), "{e}");
        let e = ColumnUnits::parse("T2=degC,t2_k=K").expect_err("twice");
        assert!(e.reason.contains("twice"), "{e}");
    }

    /// A gas fuel by volume is a mass flow through the bound fuel's density at the meter's
    /// reference conditions; unbound it is NaN (missing), never a guess; a liquid refuses it.
    #[test]
    fn a_gas_fuel_by_volume_converts_with_the_bound_fuel() {
        let mut u = ColumnUnits::parse("fuel_kg_s=Nm3/h,t2_k=degC").expect("ok");
        assert!(u.needs_fuel());
        assert!(!ColumnUnits::parse("fuel_kg_s=kg/h")
            .expect("ok")
            .needs_fuel());
        assert!(u.to_model("fuel_kg_s", 3600.0).is_nan(), "no fuel bound");
        assert_eq!(u.to_model("t2_k", 400.0), 673.15);
        let methane = Fuel::methane_with_lhv(50.0e6);
        u.bind_fuel(&methane).expect("a gas");
        let rho_n = methane.density_kg_m3(VolumeBasis::Normal).expect("gas");
        assert!((u.to_model("fuel_kg_s", 3600.0) - rho_n).abs() < 1e-12);
        assert!((rho_n - 0.7175).abs() < 5e-4, "{rho_n}");
        for (text, basis, m3_per_s) in [
            ("Sm3/h", VolumeBasis::Standard, 1.0 / 3600.0),
            ("scfh", VolumeBasis::StandardCubicFoot, FT3_M3 / 3600.0),
            (
                "Mscf/h",
                VolumeBasis::StandardCubicFoot,
                1e3 * FT3_M3 / 3600.0,
            ),
            (
                "MMscfd",
                VolumeBasis::StandardCubicFoot,
                1e6 * FT3_M3 / 86_400.0,
            ),
        ] {
            let mut u = ColumnUnits::parse(&format!("fuel_flow={text}")).expect(text);
            u.bind_fuel(&methane).expect("a gas");
            let rho = methane.density_kg_m3(basis).expect("gas");
            let got = u.to_model("fuel_kg_s", 2.0);
            assert!(
                (got / (2.0 * m3_per_s * rho) - 1.0).abs() < 1e-12,
                "{text}: {got}"
            );
        }
        // 1 MMscfd of methane is about 0.222 kg/s (19.2 t/day).
        let mut d = ColumnUnits::parse("fuel_kg_s=MMscfd").expect("ok");
        d.bind_fuel(&methane).expect("gas");
        let kg_s = d.to_model("fuel_kg_s", 1.0);
        assert!((kg_s - 0.2224).abs() < 1e-3, "{kg_s}");
        let diesel = Fuel::liquid(1.8, 300.0, None).expect("diesel");
        let e = u
            .clone()
            .bind_fuel(&diesel)
            .expect_err("a liquid by volume");
        assert_eq!(e.key, "fuel_kg_s");
        assert!(
            e.reason.contains("liquid") && e.reason.contains("kg/h"),
            "{e}"
        );
        let e = unit_for(Temperature, "Nm3/h").expect_err("a volume flow for T");
        assert!(e.contains("a mass flow"), "{e}");
    }
}
