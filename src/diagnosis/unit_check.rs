//! Wrong-unit detection: a column given in another unit than the model reads (°C for K, bar or
//! psi or Pa for kPa, kW for MW, kg/h for kg/s, percent for rpm) is refused with the unit it
//! most likely is, instead of being diagnosed as a strange engine.
//!
//! Single values can rarely tell (400 is a plausible T2 in K and in °C), so the checks use
//! what one fired operating point must satisfy: the inlet is at an ambient a site can have
//! (T1 200–330 K, P1 40–115 kPa), the compressor raises pressure and temperature, the hot end
//! is hotter than the inlet, the GG turns at thousands of rpm, the fuel flow is below a few
//! kg/s per 10 MW. The first check that fails *and* holds again after one unit conversion names
//! that unit, and the message says how to state it (`--units`, `crate::units`), so the file
//! is read as it is. Pure: no I/O; it reads values, never changes them.

use crate::signals::Signal;
use crate::units::{model_unit, quantity_of, unit_for, Quantity, Unit};

/// A column that looks like it is in another unit.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct UnitSuspect {
    pub(crate) signal: Signal,
    pub(crate) value: f64,
    /// The unit it looks like, as people write it, e.g. "°C".
    pub(crate) likely_unit: &'static str,
    /// That unit's name for `--units` (`degC`), when it is one the files may state.
    pub(crate) stated_as: Option<&'static str>,
    /// The value converted from that unit into the expected one.
    pub(crate) converted: f64,
}

impl UnitSuspect {
    /// Plain words: "15.2 looks like °C (288.15 K), not K: state the column's unit (`--units
    /// t1_k=degC`) or convert it to K".
    pub(crate) fn describe(&self) -> String {
        let unit = model_unit(self.signal);
        let converted = if self.converted.is_finite() {
            format!(" ({:.4} {unit})", self.converted)
        } else {
            String::new()
        };
        let what = match self.stated_as {
            Some(name) => format!(
                "state the column's unit (`--units {}={name}`) or convert it to {unit}",
                self.signal.column()
            ),
            None => format!("convert the column to {unit}"),
        };
        // A gas meter's volume flow is of the same order as kg/h (0.7–0.8 kg per normal m³):
        // name those units too, or the user converts at the wrong density.
        let volume = if self.signal == Signal::FuelFlow {
            " (a gas metered by volume is stated as such: Nm3/h, Sm3/h, scf/h, kscf/h or \
             MMscfd, converted with the engine file's [fuel])"
        } else {
            ""
        };
        format!(
            "{} looks like {}{converted}, not {unit}: {what}{volume}",
            self.value, self.likely_unit
        )
    }
}

/// The units a column of `quantity` is most often mistakenly given in, in the order they are
/// tried (names of [`crate::units::UNITS`]).
fn likely(quantity: Quantity) -> &'static [&'static str] {
    match quantity {
        Quantity::Temperature => &["degC", "degF"],
        Quantity::Pressure => &["bar", "MPa", "psi", "Pa", "mbar"],
        Quantity::Power => &["kW", "W"],
        Quantity::MassFlow => &["kg/h", "t/h"],
        _ => &[],
    }
}

/// The first of the units a column of `quantity` is most often mistakenly given in that takes
/// `value` into the range `ok` accepts, with the value converted: what an implausible value
/// most likely is. `None` when no such unit does.
pub(crate) fn likely_unit(
    quantity: Quantity,
    value: f64,
    ok: &dyn Fn(f64) -> bool,
) -> Option<(&'static Unit, f64)> {
    likely(quantity).iter().find_map(|name| {
        let u = unit_for(quantity, name).ok()?;
        let c = u.to_model(value);
        ok(c).then_some((u, c))
    })
}

/// Limits: a hot-end temperature (T34, T4) in °C beside a T1 in K reads as a plausible K value
/// and passes; so does a P2 in MPa that would be a low but possible pressure ratio in bar.
/// The first unit problem of one fired steady operating point (`values`: the row's signals;
/// absent or non-finite ones are skipped). `None` when every present signal is consistent.
pub(crate) fn check_fired_point(values: &[(Signal, f64)]) -> Option<UnitSuspect> {
    let get = |s: Signal| {
        values
            .iter()
            .find(|(x, v)| *x == s && v.is_finite())
            .map(|(_, v)| *v)
    };
    let suspect = |s: Signal, v: f64, ok: &dyn Fn(f64) -> bool| {
        if ok(v) {
            return None;
        }
        likely_unit(quantity_of(s), v, ok).map(|(u, c)| UnitSuspect {
            signal: s,
            value: v,
            likely_unit: u.label,
            stated_as: Some(u.name),
            converted: c,
        })
    };
    // The inlet first: it anchors the ratios below.
    let t1 = get(Signal::T1);
    if let Some(v) = t1 {
        if let Some(x) = suspect(Signal::T1, v, &|k| (200.0..=330.0).contains(&k)) {
            return Some(x);
        }
    }
    let p1 = get(Signal::P1);
    if let Some(v) = p1 {
        if let Some(x) = suspect(Signal::P1, v, &|k| (40.0..=115.0).contains(&k)) {
            return Some(x);
        }
    }
    // Pressures downstream: the compressor raises pressure; the exhaust is near ambient.
    let p_ref = p1.filter(|p| (40.0..=115.0).contains(p));
    if let Some(p1) = p_ref {
        for (s, lo, hi) in [
            (Signal::P2, 1.8, 45.0),
            (Signal::P34, 1.05, 20.0),
            (Signal::P4, 0.9, 1.6),
        ] {
            if let Some(v) = get(s) {
                let ok = |k: f64| (lo * p1..=hi * p1).contains(&k);
                if let Some(x) = suspect(s, v, &ok) {
                    return Some(x);
                }
            }
        }
    }
    // Temperatures downstream: hotter than the inlet, within what a gas turbine reaches; with
    // both pressures, T2 between the isentropic rise (efficiency 1) and that of an efficiency
    // of 0.6 — the check that tells a T2 in °C from one in K when T1 is in K.
    if let Some(t1) = t1.filter(|t| (200.0..=330.0).contains(t)) {
        let pr = match (p_ref, get(Signal::P2)) {
            (Some(p1), Some(p2)) if (1.8 * p1..=45.0 * p1).contains(&p2) => Some(p2 / p1),
            _ => None,
        };
        let (t2_lo, t2_hi) = match pr {
            Some(pr) => {
                let ideal = pr.powf(0.2857) - 1.0;
                (t1 * (1.0 + 0.97 * ideal), t1 * (1.0 + ideal / 0.6))
            }
            None => (1.1 * t1, 3.2 * t1),
        };
        for (s, lo, hi) in [
            (Signal::T2, t2_lo, t2_hi),
            (Signal::T34, 1.4 * t1, 6.0 * t1),
            (Signal::T4, 1.3 * t1, 4.5 * t1),
        ] {
            if let Some(v) = get(s) {
                let ok = |k: f64| (lo..=hi).contains(&k);
                if let Some(x) = suspect(s, v, &ok) {
                    return Some(x);
                }
            }
        }
    }
    // Power: an industrial gas turbine's shaft, 0.1–600 MW at a fired point.
    if let Some(v) = get(Signal::Power) {
        if let Some(x) = suspect(Signal::Power, v, &|k| (-1.0..=600.0).contains(&k)) {
            return Some(x);
        }
    }
    // Fuel: at most ≈ 0.1 kg/s per MW, and never above 40 kg/s.
    if let Some(v) = get(Signal::FuelFlow) {
        if let Some(x) = suspect(Signal::FuelFlow, v, &|k| k > 0.0 && k <= 40.0) {
            return Some(x);
        }
    }
    // The GG of a fired engine turns at thousands of rpm (a gas generator at 105 "rpm" is a
    // percent reading).
    if let Some(v) = get(Signal::N1).filter(|v| *v > 0.0 && *v <= 130.0) {
        return Some(UnitSuspect {
            signal: Signal::N1,
            value: v,
            likely_unit: "percent of a design speed",
            stated_as: None,
            converted: f64::NAN,
        });
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point() -> Vec<(Signal, f64)> {
        vec![
            (Signal::T1, 288.15),
            (Signal::P1, 100.5),
            (Signal::N1, 9500.0),
            (Signal::T2, 700.0),
            (Signal::P2, 2100.0),
            (Signal::T34, 1050.0),
            (Signal::P34, 450.0),
            (Signal::T4, 800.0),
            (Signal::P4, 104.0),
            (Signal::FuelFlow, 1.6),
            (Signal::Power, 28.0),
        ]
    }

    fn with(s: Signal, v: f64) -> Vec<(Signal, f64)> {
        point()
            .into_iter()
            .map(|(x, old)| (x, if x == s { v } else { old }))
            .collect()
    }

    #[test]
    fn a_consistent_point_passes_and_each_wrong_unit_is_named() {
        assert_eq!(check_fired_point(&point()), None);
        let cases = [
            (Signal::T1, 15.0, "°C"),
            (Signal::T1, 59.0, "°F"),
            (Signal::P1, 1.005, "bar"),
            (Signal::P1, 14.6, "psi"),
            (Signal::P1, 100_500.0, "Pa"),
            (Signal::T2, 426.85, "°C"),
            (Signal::P2, 21.0, "bar"),
            (Signal::P34, 4.5, "bar"),
            (Signal::Power, 28_000.0, "kW"),
            (Signal::FuelFlow, 5760.0, "kg/h"),
            (Signal::N1, 98.0, "percent of a design speed"),
        ];
        for (s, v, unit) in cases {
            let x = check_fired_point(&with(s, v)).unwrap_or_else(|| panic!("{s} = {v} passed"));
            assert_eq!((x.signal, x.likely_unit), (s, unit), "{s} = {v}: {x:?}");
            assert!(x.describe().contains(unit));
            // A fuel flow also names the gas meter's volume units.
            assert_eq!(x.describe().contains("Nm3/h"), s == Signal::FuelFlow, "{s}");
        }
    }
}
