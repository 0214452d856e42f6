//! The start-up detector over one recording held in memory: a historian's export of a start-up
//! (or of a day with several), another simulator's output — any log without phase labels —
//! read from a file by `gtwatch diagnose --input` and never stored.
//!
//! The same [`Machine`] as the stored scan, fed the same frames (GG speed's samples, the last
//! fuel flow, power and PT speed held as `scan` holds them), so a start-up found here has the
//! phases `gtwatch replay` would store for it. Each one found is cut out of the recording with
//! [`CONTEXT_BEFORE_MS`] of context before it and labelled as the store labels a segment's
//! samples. What it must not do: I/O, or judge what it finds beyond the machine's own rules.

use super::{DetectorConfig, Frame, Machine};
use crate::recording::{Recording, RecordingError};
use crate::segment::{Outcome, SegmentRecord};
use crate::signals::{Phase, Signal, Values};
use crate::store::CONTEXT_BEFORE_MS;

/// One start-up found in a recording.
#[derive(Debug, Clone)]
pub struct FoundStartup {
    /// What the detector found: outcome, phases (ms on the recording's time axis × 1000, from
    /// its origin), hot restart.
    pub record: SegmentRecord,
    /// Index of the first sample of [`FoundStartup::recording`] in the recording searched.
    pub first_sample: usize,
    /// Its samples from [`CONTEXT_BEFORE_MS`] before the start to the segment's end, labelled
    /// with the detected phases (the context as standstill), times from its first sample.
    /// `None` for a start still open at the end of the data before it reached load; an error
    /// when its samples are no usable recording (index of the offending sample counted from
    /// `first_sample`).
    pub recording: Option<Result<Recording, RecordingError>>,
}

impl FoundStartup {
    /// Time of the start in the recording searched, s.
    pub fn start_s(&self) -> f64 {
        self.record.start_ms as f64 / 1000.0
    }

    /// Whether the start reached steady load.
    pub fn completed(&self) -> bool {
        self.record.outcome == Outcome::Completed
    }

    /// Whether it can be diagnosed: completed, or still open at the end of the data once it
    /// is loading (an export that stops soon after the load is reached, before the detector's
    /// steady hold closed it). Its [`FoundStartup::recording`] is then cut at the last sample.
    pub fn diagnosable(&self) -> bool {
        self.completed() || (self.record.is_open() && reached_load(&self.record))
    }

    /// One line on what was found: when, how it ended, which phases.
    pub fn describe(&self) -> String {
        let r = &self.record;
        let how = match (r.outcome, r.abort_cause) {
            (Outcome::Aborted, Some(c)) => format!("aborted ({})", c.as_str()),
            (o, _) => o.as_str().replace('_', " "),
        };
        let phases: Vec<&str> = r.phases.iter().map(|p| p.phase.name()).collect();
        format!(
            "t = {:.0} s{}: {how}; {}",
            self.start_s(),
            if r.hot_restart { ", hot restart" } else { "" },
            phases.join(" → ")
        )
    }
}

/// The start-ups in a log of `rows` taken at `t_s` (s, increasing), found by the detector
/// with `cfg`. A frame needs the GG speed, fuel flow and power; a log without any power
/// reading is read as a unit whose breaker never closes (it runs to idle and no further).
pub fn find_startups(t_s: &[f64], rows: &[Values], cfg: &DetectorConfig) -> Vec<FoundStartup> {
    let ms: Vec<i64> = t_s.iter().map(|t| (t * 1000.0).round() as i64).collect();
    let has_power = rows.iter().any(|v| v[Signal::Power.index()].is_finite());
    let mut machine = Machine::new(cfg.clone(), None);
    // The last finite value of each secondary input, held as the stored scan holds them.
    let mut held: [Option<f64>; 3] = [None; 3];
    for (k, row) in rows.iter().enumerate() {
        for (slot, s) in [Signal::FuelFlow, Signal::Power, Signal::N2]
            .into_iter()
            .enumerate()
        {
            let v = row[s.index()];
            if v.is_finite() {
                held[slot] = Some(v);
            }
        }
        let n1 = row[Signal::N1.index()];
        let power = if has_power { held[1] } else { Some(0.0) };
        let (Some(fuel), Some(power)) = (held[0], power) else {
            continue;
        };
        if n1.is_finite() {
            machine.push(Frame {
                t_ms: ms[k],
                n1,
                fuel,
                power,
                n2: held[2],
            });
        }
    }
    // The file is all there is: a start-up held open for its steady load ends with it.
    machine.end_of_input();
    machine
        .take_finished()
        .into_iter()
        .chain(machine.open_segment())
        .map(|record| {
            let (first_sample, recording) = match labelled(t_s, rows, &ms, &record) {
                Some((first, r)) => (first, Some(r)),
                None => (0, None),
            };
            FoundStartup {
                record,
                first_sample,
                recording,
            }
        })
        .collect()
}

/// Whether an open start got as far as loading (or steady load).
fn reached_load(record: &SegmentRecord) -> bool {
    record
        .phases
        .iter()
        .any(|p| matches!(p.phase, Phase::Loading | Phase::Steady))
}

/// The samples of `record` with [`CONTEXT_BEFORE_MS`] before it, labelled with its phases (a
/// sample in no phase, the context, is standstill; where spans touch, the later phase), times
/// from the first. An open record ends at the last sample when it reached load. `None` for
/// any other open record, or when no samples lie in it.
fn labelled(
    t_s: &[f64],
    rows: &[Values],
    ms: &[i64],
    record: &SegmentRecord,
) -> Option<(usize, Result<Recording, RecordingError>)> {
    let end = match record.end_ms {
        Some(end) => end,
        None if reached_load(record) => *ms.last()?,
        None => return None,
    };
    let from = record.start_ms - CONTEXT_BEFORE_MS;
    let first = ms.iter().position(|&t| t >= from)?;
    let last = ms.iter().rposition(|&t| t <= end)?;
    if last < first {
        return None;
    }
    let phase_at = |t: i64| -> Phase {
        record
            .phases
            .iter()
            .rev()
            .find(|p| t >= p.start_ms && t <= p.end_ms.unwrap_or(end))
            .map_or(Phase::Standstill, |p| p.phase)
    };
    let t0 = t_s[first];
    let slice = Recording::new(
        t_s[first..=last].iter().map(|t| t - t0).collect(),
        ms[first..=last].iter().map(|&t| phase_at(t)).collect(),
        rows[first..=last].to_vec(),
    );
    Some((first, slice))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::sensors::MeasurementOptions;
    use crate::engine::simulation::run_scenario;
    use crate::engine::{Engine, Scenario, Trace};
    use crate::health::HealthParams;

    /// A simulated start-up with its phase labels thrown away is found again whole: one
    /// completed start, cut out from rest, whose detected phases are the simulator's own on
    /// nearly every sample.
    #[test]
    fn a_start_up_without_labels_is_found_and_labelled() {
        let engine = Engine::reference().expect("engine");
        let model = engine.model(&HealthParams::HEALTHY);
        let (samples, _) = run_scenario(&model, &Scenario::startup(engine.cfg())).expect("runs");
        let o = MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed: 3,
        };
        let trace = Trace::from_truth(&engine, &samples, Some(&o));
        let mut cfg = DetectorConfig::default();
        cfg.fill_from_engine(None, engine.cfg());
        let found = find_startups(&trace.t_s, &trace.measured, &cfg);
        assert_eq!(found.len(), 1, "{found:#?}");
        let f = &found[0];
        assert!(f.completed(), "{}", f.describe());
        let rec = f
            .recording
            .as_ref()
            .expect("closed start has its samples")
            .as_ref()
            .expect("a recording");
        rec.check_startup().expect("cut out from rest");
        let agree = rec
            .phases()
            .iter()
            .enumerate()
            .filter(|(k, p)| trace.phase[f.first_sample + k] == **p)
            .count();
        assert!(
            agree as f64 >= 0.97 * rec.len() as f64,
            "{agree} of {} samples in the simulator's phase: {}",
            rec.len(),
            f.describe()
        );
        assert!(rec.phases().contains(&Phase::Steady), "{}", f.describe());
    }
}
