//! A simulated start-up as a table of samples: true values, measured values and phase, with the
//! CSV layout that `gtwatch simulate` writes and the diagnosis reads.
//!
//! Column order follows [`Signal::ALL`]. Writing is to any `io::Write`; this module does not
//! open files. Must not run the model: it holds and writes what a simulation produced.

pub(crate) use super::gas_path::values_of;
use super::model::Engine;
use super::sensors::{self, MeasurementOptions};
use super::simulation::TruthSample;
use crate::recording::{Recording, RecordingError};
use crate::signals::{Phase, Signal};
use std::io::Write;

pub(crate) use crate::signals::{Values, NSIG};

/// A sampled run.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    pub t_s: Vec<f64>,
    pub phase: Vec<Phase>,
    pub truth: Vec<Values>,
    /// What the instruments report (equal to `truth` when no measurement model was applied).
    pub measured: Vec<Values>,
    /// Whether `measured` differs from `truth` (lags, noise or bias applied).
    pub has_measurement_model: bool,
}

impl Trace {
    /// Builds a trace from true samples, applying the measurement model if asked.
    /// With a measurement model, each signal passes through the enabled effects' instrument
    /// path (`effects`), then the engine file's sensor lags, noise and bias.
    pub fn from_truth(
        engine: &Engine,
        samples: &[TruthSample],
        meas: Option<&MeasurementOptions>,
    ) -> Trace {
        let cfg = engine.cfg();
        let t_s: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
        let phase = samples.iter().map(|s| s.phase).collect();
        let truth: Vec<Values> = samples.iter().map(|s| values_of(&s.stations)).collect();
        let mut measured = truth.clone();
        if let Some(o) = meas {
            // Lags use the samples' own intervals (the data's sample period).
            for s in Signal::ALL {
                let mut series: Vec<f64> = truth.iter().map(|v| v[s.index()]).collect();
                engine.effects().instrument(s, &t_s, &mut series);
                let m = sensors::measure_at(&cfg.sensors, s, &t_s, &series, o);
                for (row, val) in measured.iter_mut().zip(m) {
                    row[s.index()] = val;
                }
            }
        }
        Trace {
            t_s,
            phase,
            truth,
            measured,
            has_measurement_model: meas.is_some(),
        }
    }

    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// What the instruments recorded, as a checked [`Recording`] (diagnosis input).
    pub fn to_recording(&self) -> Result<Recording, RecordingError> {
        Recording::new(self.t_s.clone(), self.phase.clone(), self.measured.clone())
    }

    /// Measured series of one signal.
    pub fn measured_series(&self, s: Signal) -> Vec<f64> {
        self.measured.iter().map(|v| v[s.index()]).collect()
    }

    /// True series of one signal.
    pub fn true_series(&self, s: Signal) -> Vec<f64> {
        self.truth.iter().map(|v| v[s.index()]).collect()
    }

    /// Writes the CSV: `time_s, phase`, the measured columns, and `true_` columns when a
    /// measurement model was applied.
    pub fn write_csv<W: Write>(&self, mut w: W) -> std::io::Result<()> {
        let mut header: Vec<String> = vec!["time_s".into(), "phase".into()];
        header.extend(Signal::ALL.iter().map(|s| s.column().to_string()));
        if self.has_measurement_model {
            header.extend(Signal::ALL.iter().map(|s| format!("true_{}", s.column())));
        }
        writeln!(w, "{}", header.join(","))?;
        let mut line = String::with_capacity(512);
        for k in 0..self.len() {
            line.clear();
            line.push_str(&format!("{:.3},{}", self.t_s[k], self.phase[k]));
            for v in self.measured[k].iter() {
                line.push_str(&format!(",{}", fmt_value(*v)));
            }
            if self.has_measurement_model {
                for v in self.truth[k].iter() {
                    line.push_str(&format!(",{}", fmt_value(*v)));
                }
            }
            writeln!(w, "{line}")?;
        }
        Ok(())
    }
}

/// Six significant decimals: enough for every channel, stable across platforms.
fn fmt_value(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.6}")
    } else {
        String::new()
    }
}
