//! The six component health parameters (REFERENCE §3, paper Table 2).
//!
//! Percent, positive = degraded. Scaled maps: corrected flow × (1 − D_G/100),
//! efficiency × (1 − D_E/100). Pure data: no physics here beyond the scaler arithmetic.
//! Ground floor: must not depend on any other module of the crate, do I/O or run a model.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Names of the six parameters in their canonical order.
pub const HEALTH_NAMES: [&str; 6] = ["D_GC", "D_EC", "D_GT", "D_ET", "D_GP", "D_EP"];

/// Default search bounds in percent (REFERENCE §3).
pub const HEALTH_BOUNDS: (f64, f64) = (-3.0, 10.0);

/// The interval each health parameter is searched in, percent (by index into [`HEALTH_NAMES`]).
/// The default is [`HEALTH_BOUNDS`] for all six; a unit far from new (or an engine whose model is
/// not yet adapted) may need wider limits: `[diagnosis] health_bounds` in the config,
/// `--fit-param D_GC=LOW:HIGH` on the command line. An estimate that ends on its limit is
/// flagged, never reported as a plain value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HealthBounds {
    pub lower: [f64; 6],
    pub upper: [f64; 6],
}

impl Default for HealthBounds {
    fn default() -> Self {
        HealthBounds::all(HEALTH_BOUNDS.0, HEALTH_BOUNDS.1)
    }
}

impl HealthBounds {
    /// The same interval for all six parameters.
    pub fn all(lower: f64, upper: f64) -> HealthBounds {
        HealthBounds {
            lower: [lower; 6],
            upper: [upper; 6],
        }
    }

    /// True for the default [`HEALTH_BOUNDS`] on all six (serialised settings leave them out,
    /// so the stored results' configuration hashes stay what they were).
    pub fn is_default(&self) -> bool {
        *self == HealthBounds::default()
    }

    /// Parameter `index`'s interval.
    pub fn of(&self, index: usize) -> (f64, f64) {
        (self.lower[index], self.upper[index])
    }

    /// Sets parameter `index`'s interval (checked with [`HealthBounds::check`]).
    pub fn set(&mut self, index: usize, lower: f64, upper: f64) -> Result<(), String> {
        check_interval(lower, upper)?;
        self.lower[index] = lower;
        self.upper[index] = upper;
        Ok(())
    }

    /// Why these bounds cannot be searched, naming the parameter. Each interval
    /// must hold 0 (a healthy engine) and stay within [`PLAUSIBLE_RANGE`].
    pub fn check(&self) -> Result<(), String> {
        for (i, name) in HEALTH_NAMES.iter().enumerate() {
            check_interval(self.lower[i], self.upper[i]).map_err(|e| format!("{name}: {e}"))?;
        }
        Ok(())
    }
}

fn check_interval(lower: f64, upper: f64) -> Result<(), String> {
    let (lo, hi) = PLAUSIBLE_RANGE;
    if !(lower.is_finite() && upper.is_finite() && lower < 0.0 && upper > 0.0) {
        return Err(format!(
            "interval {lower} … {upper} % must be finite and hold 0 strictly inside (a healthy engine)"
        ));
    }
    if lower < lo || upper > hi {
        return Err(format!(
            "interval {lower} … {upper} % reaches beyond the plausible {lo} … {hi} %"
        ));
    }
    Ok(())
}

/// Component health vector, each in percent degradation.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[allow(non_snake_case)]
pub struct HealthParams {
    /// Compressor flow-capacity degradation.
    pub D_GC: f64,
    /// Compressor efficiency degradation.
    pub D_EC: f64,
    /// HP turbine flow-capacity degradation.
    pub D_GT: f64,
    /// HP turbine efficiency degradation.
    pub D_ET: f64,
    /// Power turbine flow-capacity degradation.
    pub D_GP: f64,
    /// Power turbine efficiency degradation.
    pub D_EP: f64,
}

impl HealthParams {
    pub const HEALTHY: HealthParams = HealthParams {
        D_GC: 0.0,
        D_EC: 0.0,
        D_GT: 0.0,
        D_ET: 0.0,
        D_GP: 0.0,
        D_EP: 0.0,
    };

    pub fn to_array(self) -> [f64; 6] {
        [
            self.D_GC, self.D_EC, self.D_GT, self.D_ET, self.D_GP, self.D_EP,
        ]
    }

    pub fn from_array(a: [f64; 6]) -> Self {
        HealthParams {
            D_GC: a[0],
            D_EC: a[1],
            D_GT: a[2],
            D_ET: a[3],
            D_GP: a[4],
            D_EP: a[5],
        }
    }

    pub fn from_slice(a: &[f64]) -> Option<Self> {
        let arr: [f64; 6] = a.try_into().ok()?;
        Some(Self::from_array(arr))
    }

    /// Multiplier on the compressor corrected flow.
    pub fn compressor_flow_factor(&self) -> f64 {
        1.0 - self.D_GC / 100.0
    }
    pub fn compressor_eff_factor(&self) -> f64 {
        1.0 - self.D_EC / 100.0
    }
    pub fn hpt_flow_factor(&self) -> f64 {
        1.0 - self.D_GT / 100.0
    }
    pub fn hpt_eff_factor(&self) -> f64 {
        1.0 - self.D_ET / 100.0
    }
    pub fn pt_flow_factor(&self) -> f64 {
        1.0 - self.D_GP / 100.0
    }
    pub fn pt_eff_factor(&self) -> f64 {
        1.0 - self.D_EP / 100.0
    }
}

impl fmt::Display for HealthParams {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.to_array();
        let parts: Vec<String> = HEALTH_NAMES
            .iter()
            .zip(a)
            .map(|(n, v)| format!("{n}={v:.3}"))
            .collect();
        f.write_str(&parts.join(","))
    }
}

/// Error parsing a `D_GC=3,D_EC=1` health string.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HealthParseError {
    #[error("'{0}' is not NAME=VALUE (expected e.g. D_GC=3,D_EC=1)")]
    NotAssignment(String),
    #[error("unknown health parameter '{0}' (expected one of D_GC, D_EC, D_GT, D_ET, D_GP, D_EP)")]
    UnknownName(String),
    #[error("value of {name} is not a number: '{value}'")]
    NotANumber { name: String, value: String },
    #[error("{name} = {value} % is not a plausible degradation (allowed {lo} … {hi} %)")]
    OutOfRange {
        name: String,
        value: f64,
        lo: f64,
        hi: f64,
    },
}

/// A health estimate below −(this + 3σ) points is better than new beyond its uncertainty and
/// beyond what a calibration leaves: most likely an input instrument (fuel meter, T1, power) or
/// a design value the fit absorbed. (A turbine's flow capacity, D_GT or D_GP, also rises with
/// nozzle erosion, together with an efficiency loss: [`below_plausible_each`] lets that
/// pattern through.)
pub const IMPLAUSIBLE_MARGIN: f64 = 0.3;

/// How far an estimate with 1σ `sigma` lies below plausibility, points (0 where plausible, and
/// where σ is not finite: an unidentifiable estimate says nothing).
pub fn below_plausible(value: f64, sigma: f64) -> f64 {
    if !(value.is_finite() && sigma.is_finite()) {
        return 0.0;
    }
    (-(value + IMPLAUSIBLE_MARGIN + 3.0 * sigma)).max(0.0)
}

/// Least efficiency loss, as a share of the flow capacity gained, with which a turbine's flow
/// capacity above new reads as nozzle erosion (see [`below_plausible_each`]): erosion opens the
/// nozzle throat and roughens the blading, so a real erosion costs efficiency of the same order
/// as the capacity it adds; half of it is the threshold.
pub const EROSION_EFFICIENCY_SHARE: f64 = 0.5;

/// Per parameter of a health vector (order of [`HEALTH_NAMES`]) with 1σ `sigma`, how far it lies
/// below plausibility (points; 0 where plausible): [`below_plausible`] of each value, except a
/// turbine's flow capacity above new (D_GT, D_GP) that comes with the pattern of nozzle erosion:
/// the same turbine's efficiency down beyond its own 3σ and by at least
/// [`EROSION_EFFICIENCY_SHARE`] of the capacity gained. An input instrument does not make that
/// pattern on its own: a fuel meter reading high raises the compressor's and the HP turbine's
/// flow capacity with no HP-turbine efficiency loss, so those stay flagged (its power-turbine
/// part looks like erosion and is let through).
pub fn below_plausible_each(h: &[f64; 6], sigma: &[f64; 6]) -> [f64; 6] {
    let mut out = [0.0; 6];
    for (o, (v, s)) in out.iter_mut().zip(h.iter().zip(sigma)) {
        *o = below_plausible(*v, *s);
    }
    // (flow capacity, efficiency) of the HP turbine and of the power turbine.
    for (flow, eff) in [(2, 3), (4, 5)] {
        let eroded = sigma[eff].is_finite()
            && h[eff] > 3.0 * sigma[eff]
            && h[eff] >= EROSION_EFFICIENCY_SHARE * -h[flow];
        if out[flow] > 0.0 && eroded {
            out[flow] = 0.0;
        }
    }
    out
}

/// Σ of the squared points below plausibility over a health vector (0: plausible), each value
/// on its own ([`below_plausible`]; the gap analysis asks whether an instrument would make the
/// vector plausible, and keeps counting an erosion-like turbine among the reasons to ask).
pub fn implausibility(h: &[f64; 6], sigma: &[f64; 6]) -> f64 {
    h.iter()
        .zip(sigma)
        .map(|(v, s)| below_plausible(*v, *s).powi(2))
        .sum()
}

/// Plausible range of a health parameter given on the command line or in a file, percent: far
/// wider than the diagnosis's default search bounds (−3 … +10), yet excluding values no engine can have
/// (a map scaled by 1 − D/100 with D = −50 or +60 runs a start-up into nonsense).
pub const PLAUSIBLE_RANGE: (f64, f64) = (-10.0, 30.0);

impl FromStr for HealthParams {
    type Err = HealthParseError;
    /// Parses `D_GC=3,D_EC=1` (unnamed parameters stay 0; names are case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let mut a = [0.0; 6];
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (name, value) = part
                .split_once('=')
                .ok_or_else(|| HealthParseError::NotAssignment(part.into()))?;
            let name = name.trim();
            let idx = HEALTH_NAMES
                .iter()
                .position(|n| n.eq_ignore_ascii_case(name))
                .ok_or_else(|| HealthParseError::UnknownName(name.into()))?;
            a[idx] = value
                .trim()
                .parse()
                .map_err(|_| HealthParseError::NotANumber {
                    name: name.into(),
                    value: value.trim().into(),
                })?;
            let (lo, hi) = PLAUSIBLE_RANGE;
            if !(lo..=hi).contains(&a[idx]) {
                return Err(HealthParseError::OutOfRange {
                    name: HEALTH_NAMES[idx].into(),
                    value: a[idx],
                    lo,
                    hi,
                });
            }
        }
        Ok(Self::from_array(a))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Erosion's pattern (a turbine's capacity up with its efficiency down) is plausible; a
    /// fuel meter reading 3 % high (Method B on the reference engine: D_GC −2.9, D_GT −3.0,
    /// D_ET −0.1, D_GP −2.9, D_EP +2.2) keeps the compressor and the HP turbine flagged.
    #[test]
    fn a_turbines_capacity_above_new_is_plausible_only_with_erosions_efficiency_loss() {
        let sigma = [0.1; 6];
        let eroded = [0.0, 0.0, -2.0, 3.0, 0.0, 0.0];
        assert_eq!(below_plausible_each(&eroded, &sigma), [0.0; 6]);
        let fuel_meter = [-2.9, -0.1, -3.0, -0.1, -2.9, 2.2];
        let b = below_plausible_each(&fuel_meter, &sigma);
        assert!(b[0] > 0.0 && b[2] > 0.0, "{b:?}");
        assert_eq!(b[4], 0.0, "the PT's part looks like erosion: {b:?}");
        // Too little efficiency loss for the capacity, or a loss within its own uncertainty.
        let small_loss = [0.0, 0.0, -2.0, 0.8, 0.0, 0.0];
        assert!(below_plausible_each(&small_loss, &sigma)[2] > 0.0);
        let uncertain = [0.0, 0.0, -2.0, 1.2, 0.0, 0.0];
        let wide = [0.1, 0.1, 0.1, 0.5, 0.1, 0.1];
        assert!(below_plausible_each(&uncertain, &wide)[2] > 0.0);
        // An efficiency better than new is never excused.
        let better = [0.0, -1.0, 0.0, 0.0, 0.0, 0.0];
        assert!(below_plausible_each(&better, &sigma)[1] > 0.0);
    }

    #[test]
    fn health_bounds_hold_zero_and_stay_plausible() {
        let mut b = HealthBounds::default();
        assert!(b.is_default() && b.check().is_ok());
        assert_eq!(b.of(0), HEALTH_BOUNDS);
        b.set(0, -5.0, 20.0).expect("wider");
        assert_eq!(b.of(0), (-5.0, 20.0));
        assert_eq!(b.of(1), HEALTH_BOUNDS);
        assert!(!b.is_default());
        assert!(b.set(1, 1.0, 5.0).expect_err("no 0").contains("hold 0"));
        assert!(b
            .set(1, -3.0, 31.0)
            .expect_err("too wide")
            .contains("plausible"));
        assert!(b.set(1, f64::NAN, 5.0).is_err());
        let bad = HealthBounds {
            lower: [-3.0, -3.0, -3.0, 0.5, -3.0, -3.0],
            ..HealthBounds::default()
        };
        assert!(bad.check().expect_err("D_ET").starts_with("D_ET:"));
    }

    #[test]
    fn implausible_health_is_refused_with_its_name() {
        // Issue 12 #8: `simulate --health D_GC=-50` ran an hour in crank and exited 0.
        for s in ["D_GC=-50", "d_ec=60", "D_GT=nan", "D_EP=inf"] {
            let e = s.parse::<HealthParams>().unwrap_err();
            assert!(matches!(e, HealthParseError::OutOfRange { .. }), "{s}: {e}");
        }
        let e = "D_GC=-50".parse::<HealthParams>().unwrap_err().to_string();
        assert!(e.contains("D_GC = -50"), "{e}");
        assert!("D_GC=-10,D_EC=30".parse::<HealthParams>().is_ok());
    }

    #[test]
    fn parse_and_display() {
        let h: HealthParams = "D_GC=3, d_ec=1".parse().expect("parses");
        assert_eq!(h.D_GC, 3.0);
        assert_eq!(h.D_EC, 1.0);
        assert_eq!(h.D_GT, 0.0);
        assert!((h.compressor_flow_factor() - 0.97).abs() < 1e-12);
        assert!("D_XX=1".parse::<HealthParams>().is_err());
        assert!("D_GC=abc".parse::<HealthParams>().is_err());
        assert!("D_GC".parse::<HealthParams>().is_err());
        let back: HealthParams = h.to_string().parse().expect("round trip");
        assert_eq!(back, h);
    }
}
