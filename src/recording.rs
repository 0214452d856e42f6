//! A recorded run of the engine as the plant's instruments saw it: sample times, phase labels
//! and one value per signal per sample, each either valid or missing, with the recording's own
//! sample period. It is the input of the diagnosis and of the model replay, whatever produced
//! it (a CSV file, the store's 10 Hz samples, a simulation).
//!
//! [`Recording::new`] is the only way in and checks what every consumer relies on: equal
//! lengths, finite and strictly increasing times, a sane sample period, no absurd time jump,
//! plausible ambient readings (P1 > 0, T1 > 0 where valid). [`Recording::check_startup`] adds
//! what a start-up diagnosis needs (the GG starts at rest and its speed rises). Validity: a cell
//! is valid iff it holds a finite number; [`Recording::value`] returns it as an `Option`, the raw
//! rows ([`Recording::rows`]) hold NaN where a cell is missing or invalid.
//!
//! Pure data: no I/O, no physics. Depends only on [`crate::signals`].

use crate::signals::{Phase, Signal, Values};
use std::borrow::Cow;

/// Shortest accepted sample period, s (the median spacing of the time column).
pub const MIN_SAMPLE_PERIOD_S: f64 = 1e-3;
/// Longest accepted sample period, s.
pub const MAX_SAMPLE_PERIOD_S: f64 = 60.0;
/// Largest accepted gap between two samples, in sample periods (a gap this large, or
/// [`MAX_GAP_S`] whichever is larger, means a broken time axis, not missing data).
pub const MAX_GAP_PERIODS: f64 = 100.0;
/// Largest accepted gap between two samples, s (see [`MAX_GAP_PERIODS`]).
pub const MAX_GAP_S: f64 = 300.0;
/// A spacing of more than this many sample periods (and more than [`HOLE_MIN_S`]) is a hole in
/// the record: data lost to an outage, not the recording's rhythm.
pub const HOLE_PERIODS: f64 = 5.0;
/// Shortest hole, s (see [`HOLE_PERIODS`]): a 10 Hz store's jitter is not one.
pub const HOLE_MIN_S: f64 = 3.0;
/// Longest accepted recording, s (one day: a start-up lasts well under an hour).
pub const MAX_DURATION_S: f64 = 86_400.0;
/// GG speed below which the engine counts as at rest, rpm.
pub const REST_N1_RPM: f64 = 100.0;
/// GG speed below which a P1 reading is the ambient pressure (no inlet loss), rpm.
pub const AMBIENT_REST_N1_RPM: f64 = 50.0;
/// Rise of the GG speed above its resting value a start-up must show, rpm.
pub const MIN_STARTUP_RISE_RPM: f64 = 1000.0;

/// Why a recording was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RecordingError {
    #[error("recording has {0} sample(s); at least 2 are needed")]
    TooShort(usize),
    #[error("recording columns differ in length: {times} times, {phases} phases, {rows} rows")]
    LengthMismatch {
        times: usize,
        phases: usize,
        rows: usize,
    },
    #[error("sample {index}: time {t_s} is not a finite number")]
    TimeNotFinite { index: usize, t_s: f64 },
    #[error("sample {index}: time {t_s} s does not increase (previous {prev_s} s)")]
    TimeNotIncreasing { index: usize, t_s: f64, prev_s: f64 },
    #[error("sample period {period_s} s (median time step) is outside {MIN_SAMPLE_PERIOD_S} … {MAX_SAMPLE_PERIOD_S} s")]
    BadPeriod { period_s: f64 },
    #[error("sample {index}: time jumps by {gap_s} s from {prev_s} s (sample period {period_s} s, at most {max_s} s accepted)")]
    TimeJump {
        index: usize,
        prev_s: f64,
        gap_s: f64,
        period_s: f64,
        max_s: f64,
    },
    #[error("recording spans {duration_s} s; at most {MAX_DURATION_S} s accepted")]
    TooLong { duration_s: f64 },
    #[error("sample {index} (t = {t_s} s): {signal} = {value} is not a valid ambient reading (must be > 0)")]
    Ambient {
        index: usize,
        t_s: f64,
        signal: Signal,
        value: f64,
    },
    #[error("not a start-up: {0}")]
    NotAStartup(String),
}

impl RecordingError {
    /// The sample the error is about, if it is about one.
    pub fn index(&self) -> Option<usize> {
        match self {
            RecordingError::TimeNotFinite { index, .. }
            | RecordingError::TimeNotIncreasing { index, .. }
            | RecordingError::TimeJump { index, .. }
            | RecordingError::Ambient { index, .. } => Some(*index),
            _ => None,
        }
    }
}

/// Fewest readings before light-off from which a fuel meter's zero is taken
/// ([`Recording::fuel_meter_zero`]).
pub const MIN_FUEL_ZERO_SAMPLES: usize = 3;

/// What a fuel-flow meter read before light-off, when no fuel flows: its zero offset.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FuelZero {
    /// The median reading, kg/s: what the meter adds to every reading.
    pub kg_s: f64,
    /// Readings it was taken from.
    pub samples: usize,
}

/// A hole in a recording: no sample between two neighbours further apart than
/// [`HOLE_PERIODS`] sample periods and [`HOLE_MIN_S`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Hole {
    /// Time of the last sample before the hole, s.
    pub from_s: f64,
    /// Time of the first sample after it, s.
    pub to_s: f64,
    /// Index of the first sample after it.
    pub index: usize,
    /// Phase label of that sample.
    pub phase: Phase,
}

/// A checked recording (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    t_s: Vec<f64>,
    phase: Vec<Phase>,
    rows: Vec<Values>,
    sample_period_s: f64,
}

fn check_cell(index: usize, t_s: f64, s: Signal, v: f64) -> Result<(), RecordingError> {
    if matches!(s, Signal::P1 | Signal::T1) && v.is_finite() && v <= 0.0 {
        return Err(RecordingError::Ambient {
            index,
            t_s,
            signal: s,
            value: v,
        });
    }
    Ok(())
}

impl Recording {
    /// A recording of `rows[k]` (indexed by [`Signal::index`], NaN or ±∞ = missing/invalid)
    /// taken at `t_s[k]` in phase `phase[k]`. Checks the rules in the module docs; ±∞ cells are
    /// stored as missing.
    pub fn new(
        t_s: Vec<f64>,
        phase: Vec<Phase>,
        mut rows: Vec<Values>,
    ) -> Result<Recording, RecordingError> {
        if t_s.len() != phase.len() || t_s.len() != rows.len() {
            return Err(RecordingError::LengthMismatch {
                times: t_s.len(),
                phases: phase.len(),
                rows: rows.len(),
            });
        }
        if t_s.len() < 2 {
            return Err(RecordingError::TooShort(t_s.len()));
        }
        for (index, &t) in t_s.iter().enumerate() {
            if !t.is_finite() {
                return Err(RecordingError::TimeNotFinite { index, t_s: t });
            }
            if index > 0 && t <= t_s[index - 1] {
                return Err(RecordingError::TimeNotIncreasing {
                    index,
                    t_s: t,
                    prev_s: t_s[index - 1],
                });
            }
        }
        let mut steps: Vec<f64> = t_s.windows(2).map(|w| w[1] - w[0]).collect();
        steps.sort_by(f64::total_cmp);
        let period_s = steps[(steps.len() - 1) / 2]; // lower median
        if !(MIN_SAMPLE_PERIOD_S..=MAX_SAMPLE_PERIOD_S).contains(&period_s) {
            return Err(RecordingError::BadPeriod { period_s });
        }
        let max_s = (MAX_GAP_PERIODS * period_s).max(MAX_GAP_S);
        for index in 1..t_s.len() {
            let gap_s = t_s[index] - t_s[index - 1];
            if gap_s > max_s {
                return Err(RecordingError::TimeJump {
                    index,
                    prev_s: t_s[index - 1],
                    gap_s,
                    period_s,
                    max_s,
                });
            }
        }
        let duration_s = t_s[t_s.len() - 1] - t_s[0];
        if duration_s > MAX_DURATION_S {
            return Err(RecordingError::TooLong { duration_s });
        }
        for (index, row) in rows.iter_mut().enumerate() {
            for s in Signal::ALL {
                let v = &mut row[s.index()];
                if !v.is_finite() {
                    *v = f64::NAN;
                }
                check_cell(index, t_s[index], s, *v)?;
            }
        }
        Ok(Recording {
            t_s,
            phase,
            rows,
            sample_period_s: period_s,
        })
    }

    /// Number of samples (at least 2).
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// Always false (a recording has at least two samples); for API symmetry.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// Sample times, s (strictly increasing).
    pub fn times(&self) -> &[f64] {
        &self.t_s
    }

    /// Phase label per sample.
    pub fn phases(&self) -> &[Phase] {
        &self.phase
    }

    /// Rows of values indexed by [`Signal::index`]; NaN where a cell is missing or invalid.
    pub fn rows(&self) -> &[Values] {
        &self.rows
    }

    /// The recording's own sample period: the median time step, s.
    pub fn sample_period_s(&self) -> f64 {
        self.sample_period_s
    }

    /// The holes in the record (see [`Hole`]), in time order.
    pub fn holes(&self) -> Vec<Hole> {
        let min_s = (HOLE_PERIODS * self.sample_period_s).max(HOLE_MIN_S);
        self.t_s
            .windows(2)
            .enumerate()
            .filter(|(_, w)| w[1] - w[0] > min_s)
            .map(|(i, w)| Hole {
                from_s: w[0],
                to_s: w[1],
                index: i + 1,
                phase: self.phase[i + 1],
            })
            .collect()
    }

    /// Duration from the first to the last sample, s.
    pub fn duration_s(&self) -> f64 {
        self.t_s[self.t_s.len() - 1] - self.t_s[0]
    }

    /// The valid value of signal `s` at sample `k` (`None` if missing, invalid or out of range).
    pub fn value(&self, k: usize, s: Signal) -> Option<f64> {
        self.rows
            .get(k)
            .map(|r| r[s.index()])
            .filter(|v| v.is_finite())
    }

    /// Whether sample `k` of signal `s` is valid.
    pub fn is_valid(&self, k: usize, s: Signal) -> bool {
        self.value(k, s).is_some()
    }

    /// Series of signal `s`, NaN where missing (for numeric code that masks by finiteness).
    pub fn series(&self, s: Signal) -> Vec<f64> {
        self.rows.iter().map(|v| v[s.index()]).collect()
    }

    /// Number of valid samples of signal `s`.
    pub fn valid_count(&self, s: Signal) -> usize {
        self.rows
            .iter()
            .filter(|v| v[s.index()].is_finite())
            .count()
    }

    /// Median of the valid values of a signal.
    pub fn median(&self, s: Signal) -> Option<f64> {
        let mut v: Vec<f64> = self
            .series(s)
            .into_iter()
            .filter(|x| x.is_finite())
            .collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        Some(v[v.len() / 2])
    }

    /// Whether the GG is at rest at sample `k` with a valid P1 (the samples whose P1 is the
    /// ambient pressure, no inlet loss then).
    pub fn at_rest_with_p1(&self, k: usize) -> bool {
        let r = &self.rows[k];
        r[Signal::N1.index()].abs() < AMBIENT_REST_N1_RPM && r[Signal::P1.index()].is_finite()
    }

    /// Ambient temperature and pressure: median T1, and mean P1 while the engine was at rest,
    /// else the maximum P1 seen; `default_t_k` / `default_p_kpa` where the data have none.
    pub fn ambient(&self, default_t_k: f64, default_p_kpa: f64) -> (f64, f64) {
        let t = self.median(Signal::T1).unwrap_or(default_t_k);
        let rest: Vec<f64> = (0..self.len())
            .filter(|&k| self.at_rest_with_p1(k))
            .map(|k| self.rows[k][Signal::P1.index()])
            .collect();
        let p = if rest.is_empty() {
            self.series(Signal::P1)
                .into_iter()
                .filter(|x| x.is_finite())
                .reduce(f64::max)
        } else {
            Some(rest.iter().sum::<f64>() / rest.len() as f64)
        };
        (t, p.unwrap_or(default_p_kpa))
    }

    /// The fuel meter's zero: the median of its valid readings from the first sample until the
    /// first phase in which fuel may burn ([`Phase::may_burn`]). Before light-off the fuel
    /// shut-off valve is closed, so whatever the meter shows there is its own offset, and it is
    /// in every later reading too (a flow meter's zero drift). `None` when fewer than
    /// [`MIN_FUEL_ZERO_SAMPLES`] such readings exist, or when they read exactly zero (a meter, or a
    /// control system, that shows nothing at no flow).
    pub fn fuel_meter_zero(&self) -> Option<FuelZero> {
        let k = Signal::FuelFlow.index();
        let mut v: Vec<f64> = self
            .phase
            .iter()
            .zip(&self.rows)
            .take_while(|(p, _)| !p.may_burn())
            .map(|(_, r)| r[k])
            .filter(|x| x.is_finite())
            .collect();
        if v.len() < MIN_FUEL_ZERO_SAMPLES {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let kg_s = v[v.len() / 2];
        (kg_s != 0.0).then_some(FuelZero {
            kg_s,
            samples: v.len(),
        })
    }

    /// This recording with its fuel meter's zero ([`Recording::fuel_meter_zero`]) taken off
    /// every valid fuel reading (borrowed as it is when there is none), and the zero. Applying
    /// it twice changes nothing: the zero of the result is read as exactly 0.
    pub fn fuel_zero_removed(&self) -> (Cow<'_, Recording>, Option<FuelZero>) {
        let Some(z) = self.fuel_meter_zero() else {
            return (Cow::Borrowed(self), None);
        };
        let k = Signal::FuelFlow.index();
        let mut out = self.clone();
        for r in &mut out.rows {
            if r[k].is_finite() {
                r[k] -= z.kg_s;
            }
        }
        (Cow::Owned(out), Some(z))
    }

    /// Sets one cell (NaN or ±∞ = missing), with the same checks as [`Recording::new`].
    pub fn set(&mut self, k: usize, s: Signal, value: f64) -> Result<(), RecordingError> {
        let v = if value.is_finite() { value } else { f64::NAN };
        let t = self
            .t_s
            .get(k)
            .copied()
            .ok_or(RecordingError::TooShort(k))?;
        check_cell(k, t, s, v)?;
        self.rows[k][s.index()] = v;
        Ok(())
    }

    /// The first `n` samples (at least 2), re-checked.
    pub fn truncated(&self, n: usize) -> Result<Recording, RecordingError> {
        let n = n.min(self.len());
        Recording::new(
            self.t_s[..n].to_vec(),
            self.phase[..n].to_vec(),
            self.rows[..n].to_vec(),
        )
    }

    /// The same recording with every time shifted by `-t0` (the replay's time axis).
    pub fn shifted_to_zero(&self) -> Recording {
        let t0 = self.t_s[0];
        Recording {
            t_s: self.t_s.iter().map(|t| t - t0).collect(),
            ..self.clone()
        }
    }

    /// Checks that this is a start-up the diagnosis can use: n1 is measured, starts at rest
    /// (below [`REST_N1_RPM`]) and rises by at least [`MIN_STARTUP_RISE_RPM`].
    pub fn check_startup(&self) -> Result<(), RecordingError> {
        let n1: Vec<f64> = self
            .series(Signal::N1)
            .into_iter()
            .filter(|v| v.is_finite())
            .collect();
        let Some(&first) = n1.first() else {
            return Err(RecordingError::NotAStartup(
                "the GG speed n1 is never measured".into(),
            ));
        };
        if first.abs() >= REST_N1_RPM {
            return Err(RecordingError::NotAStartup(format!(
                "the GG is not at rest at the first n1 sample (n1 = {first:.0} rpm; a start-up begins below {REST_N1_RPM} rpm)"
            )));
        }
        let max = n1.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if max - first < MIN_STARTUP_RISE_RPM {
            return Err(RecordingError::NotAStartup(format!(
                "the GG speed n1 never rises (from {first:.0} to at most {max:.0} rpm; a start-up rises by at least {MIN_STARTUP_RISE_RPM} rpm)"
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signals::NSIG;

    fn row(n1: f64, p1: f64, t1: f64) -> Values {
        let mut v = [f64::NAN; NSIG];
        v[Signal::N1.index()] = n1;
        v[Signal::P1.index()] = p1;
        v[Signal::T1.index()] = t1;
        v
    }

    fn build(t: &[f64], rows: Vec<Values>) -> Result<Recording, RecordingError> {
        Recording::new(t.to_vec(), vec![Phase::Crank; t.len()], rows)
    }

    /// Fuel readings `fuel` in phases `phases` (1 s apart).
    fn fuel_recording(phases: &[Phase], fuel: &[f64]) -> Recording {
        let t: Vec<f64> = (0..fuel.len()).map(|k| k as f64).collect();
        let rows = fuel
            .iter()
            .map(|&f| {
                let mut v = row(0.0, 101.3, 288.0);
                v[Signal::FuelFlow.index()] = f;
                v
            })
            .collect();
        Recording::new(t, phases.to_vec(), rows).expect("recording")
    }

    #[test]
    fn the_fuel_meter_zero_is_read_before_light_off_only() {
        use Phase::{Acceleration, Crank, LightOff, Purge, Standstill};
        let phases = [
            Standstill,
            Standstill,
            Crank,
            Purge,
            LightOff,
            Acceleration,
            Standstill,
        ];
        // The median of the valid unfired readings (a missing one skipped); the fired readings
        // and the later standstill are not read.
        let r = fuel_recording(&phases, &[0.021, f64::NAN, 0.019, 0.02, 0.3, 0.8, 0.5]);
        let z = r.fuel_meter_zero().expect("zero");
        assert_eq!((z.kg_s, z.samples), (0.02, 3));
        let (fixed, zero) = r.fuel_zero_removed();
        assert_eq!(zero, Some(z));
        let f = fixed.series(Signal::FuelFlow);
        assert!((f[4] - 0.28).abs() < 1e-12 && f[1].is_nan());
        // Taken off once: the corrected recording reads exactly zero at rest.
        assert!(fixed.fuel_meter_zero().is_none());
        assert!(matches!(fixed.fuel_zero_removed().0, Cow::Borrowed(_)));
        // A meter that reads nothing at rest, or too few readings: no zero.
        let quiet = fuel_recording(&phases, &[0.0, 0.0, 0.0, 0.0, 0.3, 0.8, 0.0]);
        assert!(quiet.fuel_meter_zero().is_none());
        let short = fuel_recording(&phases[2..], &[0.02, 0.02, 0.3, 0.8, 0.0]);
        assert!(short.fuel_meter_zero().is_none());
    }

    fn ramp(n: usize, dt: f64) -> (Vec<f64>, Vec<Values>) {
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let rows = (0..n)
            .map(|k| row(k as f64 * 500.0, 101.3, 288.0))
            .collect();
        (t, rows)
    }

    #[test]
    fn accepts_a_start_up_and_derives_its_period() {
        let (t, rows) = ramp(20, 0.1);
        let mut rows = rows;
        rows[3][Signal::P2.index()] = f64::INFINITY;
        let r = build(&t, rows).expect("valid");
        assert!((r.sample_period_s() - 0.1).abs() < 1e-12);
        assert_eq!(r.len(), 20);
        assert_eq!(r.value(3, Signal::P2), None);
        assert!(r.rows()[3][Signal::P2.index()].is_nan());
        assert_eq!(r.value(2, Signal::N1), Some(1000.0));
        assert_eq!(r.valid_count(Signal::P2), 0);
        r.check_startup().expect("a start-up");
        assert_eq!(r.ambient(290.0, 100.0), (288.0, 101.3));
    }

    #[test]
    fn refuses_broken_time_axes() {
        let (t, rows) = ramp(10, 1.0);
        let e = Recording::new(t.clone(), vec![Phase::Crank; 9], rows.clone()).expect_err("len");
        assert!(matches!(e, RecordingError::LengthMismatch { .. }), "{e}");
        assert!(matches!(
            build(&t[..1], rows[..1].to_vec()),
            Err(RecordingError::TooShort(1))
        ));
        let mut bad = t.clone();
        bad[4] = f64::NAN;
        assert!(matches!(
            build(&bad, rows.clone()),
            Err(RecordingError::TimeNotFinite { index: 4, .. })
        ));
        let mut bad = t.clone();
        bad[5] = bad[4];
        assert!(matches!(
            build(&bad, rows.clone()),
            Err(RecordingError::TimeNotIncreasing { index: 5, .. })
        ));
        // Issue 12 item 6: a last time of 1e12 s, a 1e7 s jump mid-file.
        let mut bad = t.clone();
        bad[9] = 1e12;
        let e = build(&bad, rows.clone()).expect_err("last time 1e12");
        assert!(
            matches!(e, RecordingError::TimeJump { index: 9, .. }),
            "{e}"
        );
        assert!(e.to_string().contains("time jumps"), "{e}");
        let mut bad = t.clone();
        bad.iter_mut().skip(5).for_each(|x| *x += 1e7);
        let e = build(&bad, rows.clone()).expect_err("1e7 jump");
        assert!(
            matches!(e, RecordingError::TimeJump { index: 5, .. }),
            "{e}"
        );
        // Period out of range.
        let tiny: Vec<f64> = (0..10).map(|k| k as f64 * 1e-6).collect();
        assert!(matches!(
            build(&tiny, rows.clone()),
            Err(RecordingError::BadPeriod { .. })
        ));
        // Too long overall (many steps, each within the gap limit).
        let long: Vec<f64> = (0..10).map(|k| k as f64 * 50_000.0).collect();
        assert!(build(&long, rows).is_err());
    }

    #[test]
    fn refuses_impossible_ambient_readings() {
        let (t, rows) = ramp(10, 1.0);
        let mut bad = rows.clone();
        bad[2][Signal::P1.index()] = 0.0;
        let e = build(&t, bad).expect_err("P1 = 0");
        assert!(
            matches!(
                e,
                RecordingError::Ambient {
                    index: 2,
                    signal: Signal::P1,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("p1_kpa = 0"), "{e}");
        let mut bad = rows.clone();
        bad[0][Signal::T1.index()] = -5.0;
        assert!(matches!(
            build(&t, bad),
            Err(RecordingError::Ambient {
                signal: Signal::T1,
                ..
            })
        ));
        // A missing ambient reading is fine; setting an invalid one is refused.
        let mut r = build(&t, rows).expect("valid");
        r.set(1, Signal::P1, f64::NAN).expect("missing is fine");
        assert_eq!(r.value(1, Signal::P1), None);
        assert!(r.set(1, Signal::T1, 0.0).is_err());
        assert_eq!(r.value(1, Signal::T1), Some(288.0));
    }

    #[test]
    fn not_a_start_up_is_named() {
        let t: Vec<f64> = (0..10).map(|k| k as f64).collect();
        // Constant n1.
        let rows = vec![row(0.0, 101.3, 288.0); 10];
        let e = build(&t, rows)
            .expect("valid")
            .check_startup()
            .expect_err("flat");
        assert!(e.to_string().contains("never rises"), "{e}");
        // Steady only: the GG turns from the first sample.
        let rows = vec![row(9000.0, 101.3, 288.0); 10];
        let e = build(&t, rows)
            .expect("valid")
            .check_startup()
            .expect_err("steady");
        assert!(e.to_string().contains("not at rest"), "{e}");
        // No n1 at all.
        let rows = vec![row(f64::NAN, 101.3, 288.0); 10];
        let e = build(&t, rows)
            .expect("valid")
            .check_startup()
            .expect_err("none");
        assert!(e.to_string().contains("never measured"), "{e}");
    }
}
