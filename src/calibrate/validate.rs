//! Leave-one-point-out validation of a calibration (`gtwatch calibrate --validate`): the
//! calibration run again once per operating point with that point left out, and the point
//! predicted by the result — per measured signal, (model − measured)/measured in %.
//!
//! Why: a calibration that fits its baseline within noise says nothing of how well it predicts
//! an operating point it was not fitted to, and that is what every later diagnosis asks of it.
//! The multiple-point adaptation literature reports its accuracy this way (prediction on
//! points not used); a plant engineer checks a model against the unit before trusting it. The
//! linearised estimate the adaptation writes (`[adaptation.model_error_pct]`,
//! [`adapt::model_error`](super::adapt)) keeps the shape the full fit chose; this re-runs the
//! whole calibration, knot growth included, so it is the exact test, at the cost of one
//! calibration per point.
//!
//! Each left-out point is placed against the others' relative corrected GG speeds: `interior`
//! (between the lowest and highest of the others: an interpolation), `below` or `above` (an
//! extrapolation of the curves, which diagnosis on an adapted file leaves out; reported, and
//! summarised apart).
//!
//! Each error is set beside what the left-out row's own noise alone would make it miss by
//! (`noise_pct`: the instrument's σ of the compared value and the σ of every input the solve is
//! given — fuel, T1, n2, P1 for the ambient — carried through the calibrated model at the row).
//! Why: a prediction is compared with a reading, not with the unit's true value; on the spot
//! readings of the independent simulator's unit (`tests/foreign_simulator/indep30.rs`, its file
//! stating a 0.5 % fuel meter) the readings' noise alone gives 0.30 % mean over the signals, as
//! much as the model's own miss, and the user must see which of the two a figure is. Pure: no
//! I/O, no printing.

use super::adapt::AdaptSettings;
use super::candidates::Candidate;
use super::problem::{prepare, residuals_on};
use super::startup::RestReading;
use super::{calibrate, CalibrateError, CalibrationSettings};
use crate::diagnosis::snapshot::{steady_data, Snapshot};
use crate::diagnosis::steady::{relative_gg_speed_at, with_input_noise};
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::signals::Signal;
use serde::Serialize;

/// Where a left-out point lies against the GG speeds of the points it was predicted from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Position {
    /// Between the lowest and highest of the others: the curves interpolate.
    Interior,
    /// Below every other point's speed: the curves extrapolate.
    Below,
    /// Above every other point's speed: the curves extrapolate.
    Above,
    /// The row has no GG speed to place it by.
    Unknown,
}

impl Position {
    pub fn as_str(self) -> &'static str {
        match self {
            Position::Interior => "interior",
            Position::Below => "below",
            Position::Above => "above",
            Position::Unknown => "unknown",
        }
    }
}

/// One measured signal's prediction error at a left-out point.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SignalError {
    /// The signal's CSV name.
    pub signal: String,
    /// (model − measured)/measured, %.
    pub pct: f64,
    /// 1σ of that error, in % of the value, that the row's own noise alone gives (its
    /// instrument's and the solve's inputs', [`noise_sigma_pct`]); `None` where the inputs'
    /// response could not be solved.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_pct: Option<f64>,
}

/// One operating point left out and predicted.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LeftOutPoint {
    /// The snapshot's file line (a start-up window's: its first sample's).
    pub line: u64,
    /// The snapshot's file or group.
    pub source: String,
    /// Relative corrected GG speed of the point (measured n1 and T1 on the engine file's
    /// design), when the row has n1.
    pub gg_speed: Option<f64>,
    pub position: Position,
    /// Per measured signal (empty when `failed`).
    pub errors: Vec<SignalError>,
    /// Mean |error| over the signals, %.
    pub mean_abs_pct: f64,
    /// Largest |error|, % , and its signal.
    pub worst_abs_pct: f64,
    pub worst_signal: String,
    /// The mean |error| the row's own noise alone would give, %: √(2/π) × the mean of the
    /// signals' `noise_pct` (the expected |x| of a normal x is √(2/π) σ).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_mean_abs_pct: Option<f64>,
    /// RMS over the signals of error / `noise_pct`: about 1 where the miss is the reading's
    /// noise, well above where it is the model's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_rms: Option<f64>,
    /// Why the point has no prediction (the calibration without it failed, or the calibrated
    /// model cannot solve it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failed: Option<String>,
    /// The adaptation shape the calibration without the point kept (`grown`, or
    /// `continuation`, also when tried in place of a `poor` grown shape); `None` without an
    /// adaptation.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shape: Option<&'static str>,
}

/// Mean and worst over a set of predicted points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Summary {
    /// Points predicted.
    pub points: usize,
    /// Mean over the points of each one's mean |error|, %.
    pub mean_pct: f64,
    /// Largest |error| of any signal at any of the points, %.
    pub worst_pct: f64,
    /// Mean over the points of the mean |error| their own noise alone would give, %
    /// ([`LeftOutPoint::noise_mean_abs_pct`]), when every point has it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_mean_pct: Option<f64>,
    /// RMS over the points' signals of error / noise σ ([`LeftOutPoint::noise_rms`]), when
    /// every point has it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_rms: Option<f64>,
}

impl Summary {
    fn of<'a>(points: impl Iterator<Item = &'a LeftOutPoint>) -> Option<Summary> {
        let ok: Vec<&LeftOutPoint> = points.filter(|p| p.failed.is_none()).collect();
        let n = ok.len() as f64;
        let noise: Option<Vec<(f64, f64)>> = ok
            .iter()
            .map(|p| p.noise_mean_abs_pct.zip(p.noise_rms))
            .collect();
        (!ok.is_empty()).then(|| Summary {
            points: ok.len(),
            mean_pct: ok.iter().map(|p| p.mean_abs_pct).sum::<f64>() / n,
            worst_pct: ok.iter().map(|p| p.worst_abs_pct).fold(0.0, f64::max),
            noise_mean_pct: noise
                .as_ref()
                .map(|v| v.iter().map(|(m, _)| m).sum::<f64>() / n),
            noise_rms: noise.map(|v| (v.iter().map(|(_, r)| r * r).sum::<f64>() / n).sqrt()),
        })
    }
}

/// The validation: every point left out in turn.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Validation {
    pub points: Vec<LeftOutPoint>,
    /// Over the interior points (interpolations), when any was predicted.
    pub interior: Option<Summary>,
    /// Over every point predicted, extrapolations included.
    pub all: Option<Summary>,
    /// Model evaluations of all the calibrations.
    pub model_runs: usize,
    /// The turbines' efficiency shape every fold was fitted with, as the calibration on every
    /// point chose it (`None` without an adaptation or where that calibration failed and each
    /// fold chose its own).
    pub efficiency_shape: Option<&'static str>,
}

/// Fewest operating points a validation needs: with fewer, a point left out leaves nothing to
/// calibrate an off-design shape on.
pub const MIN_POINTS: usize = 3;

/// Per measured signal of `row`, (model − measured)/measured in % of `engine` (`None` when the
/// row cannot be solved on it, or has nothing to compare).
pub fn prediction_errors_pct(engine: &Engine, row: &Snapshot) -> Option<Vec<(Signal, f64)>> {
    let prep = prepare(engine, std::slice::from_ref(row));
    let p = prep.points.first()?;
    let r = residuals_on(engine, &prep.points, &[]).ok()?;
    let out: Vec<(Signal, f64)> = p
        .data
        .outputs
        .iter()
        .zip(&r)
        .filter(|((_, v, _), r)| *v != 0.0 && r.is_finite())
        .map(|(&(s, v, sd), r)| (s, 100.0 * r * sd / v))
        .collect();
    (!out.is_empty()).then_some(out)
}

/// Per measured signal of `row`, the 1σ in % of its value of the prediction error the row's
/// own noise alone gives on `engine`: the compared value's instrument σ and, carried through
/// the model at the row, the σ of each input its solve is given (the fuel flow, T1, n2, and P1
/// where it gives the ambient pressure; `[sensors]`, one reading each) —
/// [`with_input_noise`]'s columns. `None` when the row cannot be solved on `engine`.
pub fn noise_sigma_pct(engine: &Engine, row: &Snapshot) -> Option<Vec<(Signal, f64)>> {
    let healthy = HealthParams::HEALTHY;
    let data = steady_data(engine, &healthy, row, 0, &mut Vec::new()).ok()?;
    let data = with_input_noise(engine, &healthy, data);
    let out: Vec<(Signal, f64)> = data
        .outputs
        .iter()
        .enumerate()
        .filter(|(_, (_, v, _))| *v != 0.0)
        .map(|(i, &(s, v, sd))| {
            let inputs: f64 = data
                .input_response
                .get(i)
                .map_or(0.0, |col| col.iter().map(|x| x * x).sum());
            (s, 100.0 * (sd * sd + inputs).sqrt() / v.abs())
        })
        .filter(|(_, x)| x.is_finite())
        .collect();
    (!out.is_empty()).then_some(out)
}

/// Leaves each of `rows` out in turn (each healthy row: not one of
/// [`CalibrationSettings::prewash_group`]): `engine` (the guesses) calibrated to the others
/// (and `rest`) over `candidates` with `settings`, as [`calibrate`] would, and the point
/// predicted.
pub fn leave_one_out(
    engine: &Engine,
    rows: &[Snapshot],
    rest: &[RestReading],
    candidates: &[Candidate],
    settings: &CalibrationSettings,
) -> Result<Validation, CalibrateError> {
    if rows.len() < MIN_POINTS {
        return Err(CalibrateError::Data(format!(
            "{} operating point(s): a leave-one-out validation needs at least {MIN_POINTS}",
            rows.len()
        )));
    }
    let mut points = Vec::with_capacity(rows.len());
    let mut model_runs = 0;
    // The turbines' efficiency shape is chosen once, on every point, and each fold fitted with
    // it: choosing it again in each fold (a second adaptation and 14 refits) doubled the
    // validation's time, and on the independent simulator's unit the truth-judged predictions
    // of its interior loads came out alike (0.204 % mean, 0.757 % worst chosen in each fold;
    // 0.200 / 0.849 % with the shape chosen on every point).
    let whole = match &settings.adapt {
        Some(a) if a.choose_efficiency_shape => {
            let whole = CalibrationSettings {
                adapt: Some(AdaptSettings {
                    health_error: false,
                    ..a.clone()
                }),
                ..settings.clone()
            };
            calibrate(engine, rows, rest, candidates.to_vec(), &whole).ok()
        }
        _ => None,
    };
    let settings = &match &whole {
        Some((report, _)) => {
            model_runs += report.model_runs;
            settings.with_efficiency_shape_of(report)
        }
        None => settings.clone(),
    };
    // Fixed here, or already by the caller's calibration on every point (`calibrate
    // --validate` validates after it).
    let efficiency_shape = settings
        .adapt
        .as_ref()
        .filter(|a| !a.choose_efficiency_shape)
        .map(|a| a.turbine_efficiency.name());
    // A pre-wash row stays in every fold: its fouling is the calibration's to find, and a row
    // left out is predicted healthy.
    let healthy =
        (0..rows.len()).filter(|&k| settings.prewash_group.as_ref() != Some(&rows[k].group));
    for k in healthy {
        if let Some((point, runs)) = left_out(engine, rows, k, rest, candidates, settings) {
            model_runs += runs;
            points.push(point);
        }
    }
    let interior = Summary::of(points.iter().filter(|p| p.position == Position::Interior));
    let all = Summary::of(points.iter());
    Ok(Validation {
        points,
        interior,
        all,
        model_runs,
        efficiency_shape,
    })
}

/// Row `k` of `rows` left out: `engine` calibrated to the others as [`leave_one_out`] does, and
/// the row predicted; the model runs it took (`None` when there is no row `k`).
pub fn left_out(
    engine: &Engine,
    rows: &[Snapshot],
    k: usize,
    rest: &[RestReading],
    candidates: &[Candidate],
    settings: &CalibrationSettings,
) -> Option<(LeftOutPoint, usize)> {
    let row = rows.get(k)?;
    let others: Vec<Snapshot> = rows
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != k)
        .map(|(_, r)| r.clone())
        .collect();
    let others_speeds: Vec<f64> = others.iter().filter_map(|r| gg_speed(engine, r)).collect();
    let speed = gg_speed(engine, row);
    let mut point = LeftOutPoint {
        line: row.line,
        source: row.group.clone(),
        gg_speed: speed,
        position: position(speed, &others_speeds),
        errors: Vec::new(),
        mean_abs_pct: f64::NAN,
        worst_abs_pct: f64::NAN,
        worst_signal: String::new(),
        noise_mean_abs_pct: None,
        noise_rms: None,
        failed: None,
        shape: None,
    };
    let mut runs = 0;
    // The prediction needs the fitted curves only, not the error in health units.
    let settings = &CalibrationSettings {
        adapt: settings.adapt.clone().map(|a| AdaptSettings {
            health_error: false,
            ..a
        }),
        ..settings.clone()
    };
    match calibrate(engine, &others, rest, candidates.to_vec(), settings) {
        Err(e) => point.failed = Some(format!("the calibration without it failed: {e}")),
        Ok((report, fitted)) => {
            runs = report.model_runs;
            point.shape = report.adaptation.as_ref().map(|a| a.strategy);
            match prediction_errors_pct(&fitted, row) {
                None => {
                    point.failed = Some("the model calibrated without it cannot solve it".into())
                }
                Some(err) => {
                    fill(&mut point, &err);
                    if let Some(noise) = noise_sigma_pct(&fitted, row) {
                        beside_noise(&mut point, &noise);
                    }
                }
            }
        }
    }
    Some((point, runs))
}

/// The row's relative corrected GG speed on `engine`'s design (`None` without a measured n1).
fn gg_speed(engine: &Engine, row: &Snapshot) -> Option<f64> {
    row.values
        .iter()
        .find(|(s, _)| *s == Signal::N1)
        .map(|(_, n1)| relative_gg_speed_at(engine, *n1, row.t_amb_k))
        .filter(|v| v.is_finite())
}

/// Where `speed` lies against the `others`' speeds (a margin of 0.001 counts as level).
fn position(speed: Option<f64>, others: &[f64]) -> Position {
    let Some(v) = speed else {
        return Position::Unknown;
    };
    let (Some(lo), Some(hi)) = (
        others.iter().copied().reduce(f64::min),
        others.iter().copied().reduce(f64::max),
    ) else {
        return Position::Unknown;
    };
    const LEVEL: f64 = 1e-3;
    if v < lo - LEVEL {
        Position::Below
    } else if v > hi + LEVEL {
        Position::Above
    } else {
        Position::Interior
    }
}

/// `point`'s errors, mean and worst from the per-signal errors `err`.
fn fill(point: &mut LeftOutPoint, err: &[(Signal, f64)]) {
    point.errors = err
        .iter()
        .map(|(s, pct)| SignalError {
            signal: s.column().to_string(),
            pct: *pct,
            noise_pct: None,
        })
        .collect();
    point.mean_abs_pct = err.iter().map(|(_, x)| x.abs()).sum::<f64>() / err.len() as f64;
    let (s, w) = err
        .iter()
        .map(|(s, x)| (*s, x.abs()))
        .fold((Signal::N1, -1.0), |a, b| if b.1 > a.1 { b } else { a });
    point.worst_abs_pct = w;
    point.worst_signal = s.column().to_string();
}

/// `point`'s errors set beside the row's own noise (`noise`: 1σ in % per signal,
/// [`noise_sigma_pct`]); the point's noise summaries only when every error has its σ.
fn beside_noise(point: &mut LeftOutPoint, noise: &[(Signal, f64)]) {
    for e in &mut point.errors {
        e.noise_pct = noise
            .iter()
            .find(|(s, _)| s.column() == e.signal)
            .map(|(_, x)| *x)
            .filter(|x| *x > 0.0);
    }
    let pairs: Option<Vec<(f64, f64)>> = point
        .errors
        .iter()
        .map(|e| e.noise_pct.map(|sd| (e.pct, sd)))
        .collect();
    let Some(pairs) = pairs.filter(|p| !p.is_empty()) else {
        return;
    };
    let n = pairs.len() as f64;
    let mean_sd = pairs.iter().map(|(_, sd)| sd).sum::<f64>() / n;
    point.noise_mean_abs_pct = Some((2.0 / std::f64::consts::PI).sqrt() * mean_sd);
    point.noise_rms = Some((pairs.iter().map(|(e, sd)| (e / sd).powi(2)).sum::<f64>() / n).sqrt());
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing
    use super::*;

    /// A point below, between or above the others' speeds is placed so; one without a speed,
    /// or with no other speed to compare, is unknown.
    #[test]
    fn a_left_out_point_is_placed_against_the_others_speeds() {
        let others = [0.80, 0.90, 0.85];
        assert_eq!(position(Some(0.75), &others), Position::Below);
        assert_eq!(position(Some(0.95), &others), Position::Above);
        assert_eq!(position(Some(0.87), &others), Position::Interior);
        // Level with the lowest within the margin: an interpolation.
        assert_eq!(position(Some(0.7995), &others), Position::Interior);
        assert_eq!(position(None, &others), Position::Unknown);
        assert_eq!(position(Some(0.8), &[]), Position::Unknown);
    }

    /// Mean and worst are over the points predicted; a failed point is left out of both.
    #[test]
    fn the_summary_skips_failed_points() {
        let mk = |mean: f64, worst: f64, failed: bool| LeftOutPoint {
            line: 2,
            source: String::new(),
            gg_speed: None,
            position: Position::Interior,
            errors: Vec::new(),
            mean_abs_pct: mean,
            worst_abs_pct: worst,
            worst_signal: String::new(),
            noise_mean_abs_pct: None,
            noise_rms: None,
            failed: failed.then(|| "x".to_string()),
            shape: None,
        };
        let pts = [mk(0.2, 0.5, false), mk(0.4, 0.9, false), mk(9.0, 9.0, true)];
        let s = Summary::of(pts.iter()).unwrap();
        assert_eq!(s.points, 2);
        assert!((s.mean_pct - 0.3).abs() < 1e-12);
        assert!((s.worst_pct - 0.9).abs() < 1e-12);
        assert!(Summary::of(pts[2..].iter()).is_none());
    }

    /// On the true model a prediction misses a noisy reading by the reading's own noise only;
    /// [`noise_sigma_pct`] states that noise's σ per signal: over 400 draws of one row's noise
    /// (instruments and inputs, `[sensors]`), every signal's errors are within 15 % of that σ
    /// (RMS of error / σ), and taking the compared value's instrument alone (the inputs taken
    /// as exact) understates the fuel-driven signals' by far (measured 0.94–1.04 of the stated
    /// σ; 1.55–2.17 of the instrument's alone on N1, P2, P34 and power).
    #[test]
    fn a_rows_own_noise_is_what_the_true_model_misses_it_by() {
        use crate::engine::gas_path::signal_value;
        use crate::engine::sensors::noise_sigma;
        use crate::engine::steady::{solve, Demand, SteadyInputs};
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let engine = Engine::reference().expect("engine");
        let sensors = &engine.cfg().sensors;
        let (t_amb, p_amb) = (291.0, 100.8);
        let inputs = SteadyInputs {
            t_amb_k: t_amb,
            p_amb_kpa: p_amb,
            n2_rpm: engine.cfg().design.pt_speed_rpm,
            demand: Demand::PowerMw(20.0),
        };
        let m = engine.model_at(&HealthParams::HEALTHY, t_amb, p_amb);
        let sp = solve(&m, &inputs, None).expect("steady");
        // A generator baseline's compared signals (every one a unit commonly logs).
        let compared = crate::calibrate::synthetic::GENERATOR_WRITTEN;
        let exact: Vec<(Signal, f64)> = compared
            .iter()
            .map(|&s| (s, signal_value(&sp.stations, s)))
            .collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let unit = Normal::new(0.0, 1.0).expect("normal");
        let mut e = |s: Signal, v: f64| v + noise_sigma(sensors, s, v) * unit.sample(&mut rng);
        const DRAWS: usize = 400;
        let mut z2 = vec![0.0; compared.len()];
        let mut z2_outputs_only = vec![0.0; compared.len()];
        for draw in 0..DRAWS {
            let row = Snapshot {
                line: draw as u64 + 2,
                group: "noise".into(),
                time_s: None,
                t_amb_k: e(Signal::T1, t_amb),
                p_amb_kpa: Some(p_amb),
                n2_rpm: e(Signal::N2, inputs.n2_rpm),
                fuel_kg_s: e(Signal::FuelFlow, sp.stations.fuel_kg_s),
                values: exact.iter().map(|&(s, v)| (s, e(s, v))).collect(),
            };
            let err = prediction_errors_pct(&engine, &row).expect("predicted");
            let sd = noise_sigma_pct(&engine, &row).expect("noise");
            assert_eq!(err.len(), compared.len());
            for (i, ((s, pct), (s2, sd))) in err.iter().zip(&sd).enumerate() {
                assert_eq!(s, s2);
                z2[i] += (pct / sd).powi(2) / DRAWS as f64;
                let v = row.values.iter().find(|(x, _)| x == s).expect("value").1;
                let alone = 100.0 * noise_sigma(sensors, *s, v) / v;
                z2_outputs_only[i] += (pct / alone).powi(2) / DRAWS as f64;
            }
        }
        for (i, s) in compared.iter().enumerate() {
            let (z, z_alone) = (z2[i].sqrt(), z2_outputs_only[i].sqrt());
            eprintln!("{s:?}: errors {z:.3} of the stated σ, {z_alone:.3} of the instrument's");
            assert!((0.85..=1.15).contains(&z), "{s:?}: {z:.3}");
        }
        for s in [Signal::N1, Signal::P2, Signal::P34, Signal::Power] {
            let i = compared.iter().position(|x| *x == s).expect("compared");
            assert!(z2_outputs_only[i].sqrt() > 1.3, "{s:?}");
        }
    }

    /// The worst signal is the one with the largest |error|, whatever its sign.
    #[test]
    fn fill_finds_the_worst_signal_by_magnitude() {
        let mut p = LeftOutPoint {
            line: 2,
            source: String::new(),
            gg_speed: None,
            position: Position::Interior,
            errors: Vec::new(),
            mean_abs_pct: f64::NAN,
            worst_abs_pct: f64::NAN,
            worst_signal: String::new(),
            noise_mean_abs_pct: None,
            noise_rms: None,
            failed: None,
            shape: None,
        };
        fill(
            &mut p,
            &[(Signal::N1, 0.1), (Signal::T4, -0.9), (Signal::P2, 0.5)],
        );
        assert_eq!(p.worst_signal, "t4_k");
        assert!((p.worst_abs_pct - 0.9).abs() < 1e-12);
        assert!((p.mean_abs_pct - 0.5).abs() < 1e-12);
        assert_eq!(p.errors.len(), 3);
    }
}
