//! Whether a simulated start-up reached steady load and, for one that did not, where it stuck,
//! in words the author of an engine file can act on. A start that hangs (a starter that holds
//! the gas generator just below the speed the sequencer waits for, a light-off never reached)
//! otherwise runs silently to the scenario's time limit and writes an hour of cranking.
//! Reads a finished run's samples; must not run or change one.

use super::config::EngineConfig;
use super::sequence::PURGE_SPEED_FRACTION;
use super::simulation::TruthSample;
use crate::signals::Phase;
use std::fmt;

/// A start-up that never reached steady load: the phase it ended in, since when, and the
/// shaft speeds at the end.
#[derive(Debug, Clone, PartialEq)]
pub struct StuckStart {
    pub phase: Phase,
    /// Start of the final stretch in `phase`, s.
    pub since_s: f64,
    /// End of the run, s.
    pub end_s: f64,
    pub n1_rpm: f64,
    pub n2_rpm: f64,
    /// What to change in the engine file, where the phase says it.
    pub hint: Option<String>,
}

/// `None` when `samples` (a start-up scenario's run on an engine of `cfg`) reach steady load;
/// otherwise where the start stuck.
pub fn stuck_start(cfg: &EngineConfig, samples: &[TruthSample]) -> Option<StuckStart> {
    if samples.iter().any(|s| s.phase == Phase::Steady) {
        return None;
    }
    let last = samples.last()?;
    let since_s = samples
        .iter()
        .rev()
        .take_while(|s| s.phase == last.phase)
        .last()
        .map_or(last.t_s, |s| s.t_s);
    let (n1, n2) = (last.stations.n1_rpm, last.stations.n2_rpm);
    let q = &cfg.sequence;
    let hint = match last.phase {
        Phase::Crank => Some(format!(
            "the starter holds the GG at {n1:.0} rpm; the sequence purges only above {:.0} rpm \
             ({:.0} % of sequence.purge_speed_rpm = {:.0}): raise starter.max_torque_n_m or \
             starter.speed_hold_gain_n_m_per_rpm, or lower sequence.purge_speed_rpm",
            PURGE_SPEED_FRACTION * q.purge_speed_rpm,
            100.0 * PURGE_SPEED_FRACTION,
            q.purge_speed_rpm
        )),
        Phase::Standstill => Some("the start command never came".to_string()),
        Phase::Acceleration | Phase::Idle => Some(format!(
            "the GG ends at {n1:.0} rpm against sequence.idle_speed_rpm = {:.0}: check the fuel \
             limits in [control] and the starter's cut-out",
            q.idle_speed_rpm
        )),
        _ => None,
    };
    Some(StuckStart {
        phase: last.phase,
        since_s,
        end_s: last.t_s,
        n1_rpm: n1,
        n2_rpm: n2,
        hint,
    })
}

impl fmt::Display for StuckStart {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "the start-up never reached steady load: it stayed in {} from t = {:.0} s to the end \
             at {:.0} s (GG {:.0} rpm, PT {:.0} rpm)",
            self.phase.name(),
            self.since_s,
            self.end_s,
            self.n1_rpm,
            self.n2_rpm
        )?;
        if let Some(h) = &self.hint {
            write!(f, "; {h}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::{run_scenario, Engine, Scenario};
    use crate::health::HealthParams;

    fn run(cfg: EngineConfig) -> Option<StuckStart> {
        let engine = Engine::new(cfg).expect("engine");
        let model = engine.model(&HealthParams::default());
        let (samples, _) = run_scenario(&model, &Scenario::startup(engine.cfg())).expect("run");
        stuck_start(engine.cfg(), &samples)
    }

    #[test]
    fn the_reference_start_up_reaches_steady_load() {
        assert_eq!(run(EngineConfig::reference()), None);
    }

    #[test]
    fn a_starter_too_weak_for_the_purge_speed_is_named() {
        let mut cfg = EngineConfig::reference();
        // A fifth of the starter's torque cannot turn the compressor up to the purge speed.
        cfg.starter.max_torque_n_m *= 0.2;
        let stuck = run(cfg).expect("a hung start");
        assert_eq!(stuck.phase, Phase::Crank);
        assert!(stuck.n1_rpm > 0.0 && stuck.since_s < 60.0, "{stuck:?}");
        let text = stuck.to_string();
        assert!(
            text.contains("stayed in crank") && text.contains("sequence.purge_speed_rpm"),
            "{text}"
        );
    }
}
