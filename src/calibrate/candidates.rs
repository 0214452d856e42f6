//! The design parameters `gtwatch calibrate` may fit, each with the realistic interval a unit's
//! true value lies in around the engine file's guess.
//!
//! What it is for: one table of keys and ranges (efficiencies ±3 points, design air flow ±5 %,
//! flow-setting design values ±6 %, losses ±50 %, map design points shifted) so the fit and the
//! identifiability analysis speak of the same intervals. What it must not do: I/O or physics.
//!
//! The engine file states its design as a cycle table (pressure ratio, exhaust flow, power,
//! component efficiencies, losses) and the maps are scaled so that table holds; the components'
//! flow capacities follow from it: the compressor's from the exhaust (air) flow, the HPT's from
//! flow, T3 (set by the power) and P3 (set by the pressure ratio and combustor loss), the PT's
//! from the HPT's expansion. So "flow capacities" are fitted through those table values.

use super::CalibrateError;
use crate::engine::config::{param_range, LoadMode};
use crate::engine::Engine;
use crate::signals::Signal;

/// How wide the realistic interval around the guess is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Spread {
    /// ± this much, in the key's unit (efficiency points as fractions: 0.03 = 3 points).
    Absolute(f64),
    /// ± this fraction of the guess.
    Relative(f64),
    /// ± this fraction of (guess − 1): a ratio whose excess over one is the loss.
    Excess(f64),
}

/// The default candidates, in the order they are reported, with their spread and meaning.
pub const DEFAULT_CANDIDATES: &[(&str, Spread, &str)] = &[
    (
        "design.compressor_efficiency",
        Spread::Absolute(0.03),
        "compressor design efficiency",
    ),
    (
        "design.hpt_efficiency",
        Spread::Absolute(0.03),
        "HP-turbine design efficiency",
    ),
    (
        "design.pt_efficiency",
        Spread::Absolute(0.03),
        "power-turbine design efficiency",
    ),
    (
        "design.exhaust_flow_kg_s",
        Spread::Relative(0.05),
        "design air flow (compressor flow capacity)",
    ),
    (
        "design.pressure_ratio",
        Spread::Relative(0.06),
        "design pressure ratio (with the flow, the HPT flow capacity)",
    ),
    (
        "design.power_mw",
        Spread::Relative(0.06),
        "design power (sets design T3, hence the turbines' flow capacities)",
    ),
    (
        "design.inlet_loss_frac",
        Spread::Relative(0.5),
        "inlet pressure loss",
    ),
    (
        "design.combustor_loss_frac",
        Spread::Relative(0.5),
        "combustor pressure loss",
    ),
    (
        "design.exhaust_back_pressure_ratio",
        Spread::Excess(0.5),
        "exhaust back-pressure excess",
    ),
    (
        "design.combustion_efficiency",
        Spread::Absolute(0.005),
        "combustion efficiency",
    ),
    (
        "maps.compressor_design_beta",
        Spread::Absolute(0.1),
        "compressor map design point (β)",
    ),
    (
        "maps.hpt_design_pr",
        Spread::Relative(0.1),
        "HPT map design point (PR)",
    ),
    (
        "maps.pt_design_pr",
        Spread::Relative(0.1),
        "PT map design point (PR)",
    ),
];

/// Keys outside the default table that still have a sensible spread when asked for.
const EXTRA_SPREADS: &[(&str, Spread)] = &[
    (LOAD_EXPONENT, Spread::Absolute(0.5)),
    ("design.gg_mechanical_efficiency", Spread::Absolute(0.01)),
    ("design.pt_mechanical_efficiency", Spread::Absolute(0.01)),
    ("design.cooling_bleed_frac", Spread::Absolute(0.02)),
    ("design.cooling_return_frac", Spread::Absolute(0.04)),
    ("maps.compressor_design_speed", Spread::Absolute(0.05)),
    ("maps.hpt_design_speed", Spread::Absolute(0.05)),
    ("maps.pt_design_speed", Spread::Absolute(0.05)),
    ("dynamics.gg_friction_kw_at_design", Spread::Relative(0.5)),
    ("dynamics.pt_windage_kw_at_sync", Spread::Relative(0.5)),
];

/// Spread of any other engine-file number asked for by name: ±10 % of its guess.
pub const OTHER_SPREAD: Spread = Spread::Relative(0.1);

/// One design parameter to calibrate: its key, the engine file's value (the guess) and the
/// realistic interval `[lower, upper]` (inside the key's allowed range).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Candidate {
    pub key: String,
    pub guess: f64,
    pub lower: f64,
    pub upper: f64,
}

/// Spread of an adaptation curve's knot value (`adaptation.<component>.<curve>[i]`), by curve:
/// a speed line re-labelled by up to ±30 %, flow ±30 %, efficiency ±15 %, (PR − 1) ±50 % per
/// step of the fit (a unit of another make is that far from a borrowed map at part speed: at
/// 70 % speed one maker's compressor runs at the pressure ratio another's reaches at 90 %).
pub fn adaptation_spread(curve: &str) -> f64 {
    match curve {
        "speed" => 0.30,
        "flow" => 0.30,
        "efficiency" => 0.15,
        "pressure_ratio" => 0.50,
        _ => 0.10,
    }
}

/// The spread used for `key`.
pub fn spread_of(key: &str) -> Spread {
    if let Some(rest) = key.strip_prefix("adaptation.") {
        let curve = rest
            .split('.')
            .nth(1)
            .and_then(|c| c.split('[').next())
            .unwrap_or("");
        return Spread::Absolute(adaptation_spread(curve));
    }
    DEFAULT_CANDIDATES
        .iter()
        .find(|(k, _, _)| *k == key)
        .map(|(_, s, _)| *s)
        .or_else(|| {
            EXTRA_SPREADS
                .iter()
                .find(|(k, _)| *k == key)
                .map(|(_, s)| *s)
        })
        .unwrap_or(OTHER_SPREAD)
}

/// The candidate for `key` on `engine`: an error names a key that is not a tunable number of
/// the engine file, or whose interval collapses (a value of zero with a relative spread).
pub fn candidate(engine: &Engine, key: &str) -> Result<Candidate, CalibrateError> {
    let bad = |reason: String| CalibrateError::Param {
        key: key.to_string(),
        reason,
    };
    if key.starts_with("sensors.") {
        return Err(bad(
            "not a design parameter (sensor settings are not calibrated; instrument offsets: \
             --offsets)"
                .into(),
        ));
    }
    let guess = engine.get_param(key).map_err(|e| bad(e.to_string()))?;
    let range = param_range(key)
        .ok_or_else(|| bad("has no allowed range (not a tunable number)".into()))?;
    if key.starts_with("effects.") {
        // An effect's parameter (a VIGV schedule, a bleed, a clearance…; the effect is enabled
        // with its defaults when the file has none): no datasheet value to spread around, so
        // its realistic interval is the library's whole range (`--params KEY=LOW:HIGH` narrows).
        if !(range.min < guess && guess < range.max) {
            return Err(bad(format!(
                "the value {guess} is on the edge of the library's range {}…{}: set it inside \
                 first, or give an interval",
                range.min, range.max
            )));
        }
        return Ok(Candidate {
            key: key.to_string(),
            guess,
            lower: range.min,
            upper: range.max,
        });
    }
    let half = match spread_of(key) {
        Spread::Absolute(d) => d,
        Spread::Relative(f) => f * guess.abs(),
        Spread::Excess(f) => f * (guess - 1.0).abs(),
    };
    let mut lower = (guess - half).max(range.min);
    if range.min_exclusive && lower <= range.min {
        lower = range.min + 1e-6 * half.max(1e-12);
    }
    let upper = (guess + half).min(range.max);
    if upper.partial_cmp(&lower) != Some(std::cmp::Ordering::Greater) {
        return Err(bad(format!(
            "its realistic interval around {guess} is empty (within the allowed range {}…{})",
            range.min, range.max
        )));
    }
    Ok(Candidate {
        key: key.to_string(),
        guess,
        lower,
        upper,
    })
}

/// The candidate for `key` with the interval `[lower, upper]` the user states
/// (`--params key=LOW:HIGH`): inside the key's allowed range, containing the file's value.
pub fn candidate_in(
    engine: &Engine,
    key: &str,
    lower: f64,
    upper: f64,
) -> Result<Candidate, CalibrateError> {
    let bad = |reason: String| CalibrateError::Param {
        key: key.to_string(),
        reason,
    };
    let base = candidate(engine, key)?;
    if upper.partial_cmp(&lower) != Some(std::cmp::Ordering::Greater) {
        return Err(bad(format!(
            "interval {lower}:{upper} is empty (LOW must be < HIGH)"
        )));
    }
    let range = param_range(key)
        .ok_or_else(|| bad("has no allowed range (not a tunable number)".into()))?;
    for v in [lower, upper] {
        range
            .check(v)
            .map_err(|r| bad(format!("interval bound {r}")))?;
    }
    if !(lower <= base.guess && base.guess <= upper) {
        return Err(bad(format!(
            "interval {lower}:{upper} does not contain the engine file's value {} (the fit \
             starts there): set the file's value inside it first",
            base.guess
        )));
    }
    Ok(Candidate {
        lower,
        upper,
        ..base
    })
}

/// The default candidates on `engine`: [`DEFAULT_CANDIDATES`], and on a mechanical drive
/// (`[load] mode = "load_law"`) the load law's exponent.
pub fn default_candidates(engine: &Engine) -> Result<Vec<Candidate>, CalibrateError> {
    let law = engine
        .cfg()
        .load
        .as_ref()
        .is_some_and(|l| l.mode == LoadMode::LoadLaw);
    DEFAULT_CANDIDATES
        .iter()
        .map(|(k, _, _)| *k)
        .chain(law.then_some(LOAD_EXPONENT))
        .map(|k| candidate(engine, k))
        .collect()
}

/// Realistic interval of an instrument offset: ± this fraction of the channel's largest reading
/// in the calibration data (of the order of a transmitter's full scale; REFERENCE §5 states
/// biases of 0.8–1.5 % of full scale).
pub const OFFSET_FRACTION: f64 = 0.02;

/// The engine-file key of the offset of the instrument of `s`: the `sensor_bias` effect of
/// the library on that channel, which the diagnosis applies to the model's readings.
pub fn offset_key(s: Signal) -> String {
    format!("effects.sensor_bias:{}.offset", s.column())
}

/// The candidate offset of the instrument of `s`, `largest` its largest reading (absolute) in
/// the calibration data; the guess is the file's offset (0 without one).
pub fn offset_candidate(
    engine: &Engine,
    s: Signal,
    largest: f64,
) -> Result<Candidate, CalibrateError> {
    let key = offset_key(s);
    let guess = engine.get_param(&key).map_err(|e| CalibrateError::Param {
        key: key.clone(),
        reason: e.to_string(),
    })?;
    let half = OFFSET_FRACTION * largest.abs();
    if !(half > 0.0 && half.is_finite()) {
        return Err(CalibrateError::Param {
            key,
            reason: format!("no reading to size its interval from (largest {largest})"),
        });
    }
    Ok(Candidate {
        key,
        guess,
        lower: guess - half,
        upper: guess + half,
    })
}

/// The load law's exponent (P ∝ n2^k), a candidate on a mechanical drive.
pub const LOAD_EXPONENT: &str = "load.exponent";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_are_realistic_and_inside_the_allowed_ranges() {
        let e = Engine::reference().expect("engine");
        let c = default_candidates(&e).expect("candidates");
        assert_eq!(c.len(), DEFAULT_CANDIDATES.len());
        let by = |k: &str| c.iter().find(|x| x.key == k).expect(k).clone();
        let eff = by("design.compressor_efficiency");
        assert!((eff.lower - 0.82).abs() < 1e-12 && (eff.upper - 0.88).abs() < 1e-12);
        let flow = by("design.exhaust_flow_kg_s");
        assert!((flow.upper / flow.guess - 1.05).abs() < 1e-12);
        let exh = by("design.exhaust_back_pressure_ratio");
        assert!((exh.lower - 1.015).abs() < 1e-12 && (exh.upper - 1.045).abs() < 1e-12);
        // Combustion efficiency 0.995 + 0.005 = 1.0 is the ceiling.
        assert!(by("design.combustion_efficiency").upper <= 1.0);
        for x in &c {
            assert!(x.lower < x.guess && x.guess < x.upper, "{x:?}");
        }
        for key in [
            "sensors.t4.bias",
            "effects.no_such_effect.x",
            "effects.vigv_schedule.nope",
            "design.nope",
            "name",
        ] {
            let err = candidate(&e, key).expect_err(key);
            assert!(err.to_string().contains(key), "{err}");
        }
        // An effect's parameter: its default (the file has no VIGV) within the library's range.
        let v = candidate(&e, "effects.vigv_schedule.flow_delta_pct").expect("vigv");
        assert_eq!((v.lower, v.guess, v.upper), (-15.0, -3.0, 15.0));
    }
}
