//! The measured drive: the model run through a recorded start-up, as the diagnosis needs it.
//!
//! A [`Recording`] is a sampled start-up as the plant recorded it (phase labels, ambient, fuel
//! flow, GG speed, power, …). [`simulate_segment`] runs a health-scaled model through it and returns
//! what the plant's instruments would have shown, sample by sample, so the two can be compared.
//! The phases tell the model what the sequencer did (starter, ignition, breaker); the fuel either
//! comes from the measured fuel flow (open loop, the default) or from the model's own PID
//! controllers following the measured GG speed and power (closed loop, "demand" mode).
//! Pure: no I/O.

use super::config::{EngineConfig, LoadMode};
use super::control::{Feedback, FuelCommand, FuelLimits, Loop, Series, Setpoint, StarterCommand};
use super::dynamic::{Drive, Stations};
use super::load::PtLoad;
use super::model::{Engine, EngineError, Model};
use super::sensors::MeasurementOptions;
use super::simulation::{Change, Controller, Simulation, StartState, TruthSample, Watch};
use super::state::{Actuator, Shaft};
use super::trace::Trace;
use crate::health::HealthParams;
use crate::recording::{Recording, REST_N1_RPM};
use crate::signals::{Phase, Signal};
use std::sync::Arc;

/// How the model's fuel flow is set during a replay.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DriveMode {
    /// The measured fuel flow drives the model (open loop). Default: it is the plant's actual
    /// input, and every health effect then shows in the speeds, pressures and temperatures.
    MeasuredFuel,
    /// The model's controllers track the measured GG speed (before the breaker closes) and power
    /// (after): the fuel flow becomes an output compared with the measurement.
    Demand,
}

/// Replays the phases of a segment: starter, ignition and breaker from the labels, fuel from the
/// measurement or from PID loops following the measured speed and power.
#[derive(Debug, Clone)]
pub(crate) struct MeasuredDrive {
    cfg: EngineConfig,
    t_s: Arc<Vec<f64>>,
    phase: Arc<Vec<Phase>>,
    fuel: Arc<Series>,
    n1_sp: Arc<Series>,
    power_sp: Arc<Series>,
    mode: DriveMode,
    limits: Arc<FuelLimits>,
    k: usize,
    fuel_cmd: FuelCommand,
    pt_locked: bool,
    /// The engine file's PT load curve (`None`: generator or measured speed).
    pt_load: Option<PtLoad>,
    /// The measured PT speed the model follows (`[load] mode = "measured_speed"`), smoothed.
    pt_speed: Option<Arc<Series>>,
    flame: bool,
    starter: StarterCommand,
    /// Measured PT speed (for re-setting the model's after a hole).
    n2_meas: Arc<Series>,
    /// Indices of the samples that follow a hole in the record ([`Recording::holes`]).
    after_hole: Arc<Vec<usize>>,
}

fn clean(t: &[f64], v: Vec<f64>) -> Series {
    // Missing samples are dropped (interpolated over), never read as zero.
    let (ts, vs): (Vec<f64>, Vec<f64>) = t
        .iter()
        .zip(v)
        .filter(|(_, x)| x.is_finite())
        .map(|(a, b)| (*a, b))
        .unzip();
    Series { t_s: ts, value: vs }
}

/// Window of the moving average applied to a measured PT speed before the model follows it, s:
/// the model takes the load's power as `P_PT − J ω dω/dt`, and the derivative of raw speed
/// noise would swamp it.
const PT_SPEED_SMOOTHING_S: f64 = 1.0;
/// The smoothing window in samples at least (a 1 Hz log: 5 s).
const PT_SPEED_SMOOTHING_SAMPLES: f64 = 5.0;

/// The measured PT speed the model must follow: with `[load] mode = "measured_speed"` and a
/// recorded PT speed, its cleaned and smoothed series; otherwise `None`.
fn measured_pt_speed(model: &Model, seg: &Recording) -> Option<Arc<Series>> {
    let load = model.cfg().load.as_ref()?;
    if load.mode != LoadMode::MeasuredSpeed {
        return None;
    }
    let n2 = clean(seg.times(), seg.series(Signal::N2));
    if n2.t_s.len() < 2 {
        return None;
    }
    // At least five samples in the window, whatever the recording's rate.
    let span = n2.t_s[n2.t_s.len() - 1] - n2.t_s[0];
    let dt = span / (n2.t_s.len() - 1) as f64;
    Some(Arc::new(n2.smoothed(
        PT_SPEED_SMOOTHING_S.max(PT_SPEED_SMOOTHING_SAMPLES * dt),
    )))
}

impl MeasuredDrive {
    /// A controller replaying `seg` (its times must start at the simulation's time 0).
    pub(crate) fn new(model: &Model, seg: &Recording, mode: DriveMode) -> MeasuredDrive {
        let cfg = model.cfg();
        let t = seg.times();
        MeasuredDrive {
            cfg: cfg.clone(),
            t_s: Arc::new(t.to_vec()),
            phase: Arc::new(seg.phases().to_vec()),
            fuel: Arc::new(clean(t, seg.series(Signal::FuelFlow))),
            n1_sp: Arc::new(clean(t, seg.series(Signal::N1))),
            power_sp: Arc::new(clean(t, seg.series(Signal::Power))),
            mode,
            limits: Arc::new(FuelLimits::from_config(&cfg.control)),
            k: 0,
            fuel_cmd: FuelCommand::Off,
            pt_locked: false,
            pt_load: PtLoad::of(model),
            pt_speed: measured_pt_speed(model, seg),
            flame: false,
            starter: StarterCommand::Off,
            n2_meas: Arc::new(clean(t, seg.series(Signal::N2))),
            after_hole: Arc::new(seg.holes().iter().map(|h| h.index).collect()),
        }
    }

    /// After a hole in the record the model's shafts have run on fuel interpolated across it,
    /// which is not what the engine burnt, and a shaft (the PT above all, heavy and lightly
    /// loaded before the breaker closes) carries that error for minutes: at sample `k`, the
    /// first after a hole, the turning shafts are set to the measured speeds (a PT the grid or
    /// the measurement holds is left alone). Returns whether a speed was set.
    fn resync_after_hole(&self, k: usize, act: &mut Actuator<'_>) -> bool {
        if !self.after_hole.contains(&k) {
            return false;
        }
        let t = self.t_s[k];
        let n1 = self.n1_sp.value(t);
        if !(n1.is_finite() && n1 > REST_N1_RPM) {
            return false;
        }
        act.set_speed_rpm(Shaft::Gg, n1);
        let n2 = self.n2_meas.value(t);
        if !self.pt_locked && self.pt_speed.is_none() && n2.is_finite() && n2 >= 0.0 {
            act.set_speed_rpm(Shaft::Pt, n2);
        }
        true
    }

    fn measured_fuel_at(&self, k: usize) -> f64 {
        self.fuel.value(self.t_s[k]).max(0.0)
    }

    /// Sets starter, breaker, flame and fuel command for sample `self.k`; returns whether any
    /// of them changed.
    fn configure(&mut self, t: f64, act: &mut Actuator<'_>, st: &Stations) -> bool {
        let before = (self.starter, self.pt_locked, self.flame);
        let k = self.k;
        let ph = self.phase[k];
        let next_fuel = if k + 1 < self.t_s.len() {
            self.measured_fuel_at(k + 1)
        } else {
            0.0
        };
        let fuel_here = self.measured_fuel_at(k).max(next_fuel);
        let st_cfg = &self.cfg.starter;
        self.starter = match ph {
            Phase::Crank | Phase::Purge => {
                StarterCommand::hold(st_cfg, self.cfg.sequence.purge_speed_rpm)
            }
            Phase::LightOff if fuel_here <= 0.0 => StarterCommand::Off,
            Phase::LightOff | Phase::Acceleration => StarterCommand::FullUntil {
                max_torque: st_cfg.max_torque_n_m,
                free_speed: st_cfg.free_speed_rpm,
                cutout_rpm: st_cfg.cutout_rpm,
            },
            _ => StarterCommand::Off,
        };
        // A mechanical drive (load curve or measured speed) has no breaker: its PT speed follows
        // the load, or the measurement, throughout.
        let locked = self.pt_load.is_none()
            && self.pt_speed.is_none()
            && matches!(ph, Phase::Loading | Phase::Steady | Phase::Unloading);
        if locked && !self.pt_locked {
            // The breaker closed: the grid holds the PT at synchronous speed from here on.
            act.set_speed_rpm(Shaft::Pt, self.cfg.design.pt_speed_rpm);
        }
        self.pt_locked = locked;
        // Before light-off the fuel valve is shut: a reading there is the meter's zero, and
        // lighting the model's combustor on it, with no air through a standing engine, is what
        // failed every replay of a start-up whose meter read 0.02 kg/s at rest.
        // The interval into the first fired sample burns as before (the fuel ramps up in it).
        let may_burn = ph.may_burn() || self.phase.get(k + 1).is_some_and(|p| p.may_burn());
        self.flame = fuel_here > 0.0 && may_burn;
        let new_cmd = match self.mode {
            DriveMode::MeasuredFuel => FuelCommand::Trace(self.fuel.clone()),
            DriveMode::Demand => match ph {
                Phase::Acceleration | Phase::Idle | Phase::Synchronisation => FuelCommand::pid(
                    &self.cfg.control,
                    self.limits.clone(),
                    Loop::GgSpeed,
                    Setpoint::Series(self.n1_sp.clone()),
                ),
                Phase::Loading | Phase::Steady | Phase::Unloading => FuelCommand::pid(
                    &self.cfg.control,
                    self.limits.clone(),
                    Loop::Power,
                    Setpoint::Series(self.power_sp.clone()),
                ),
                _ => FuelCommand::Trace(self.fuel.clone()),
            },
        };
        let changed = match (&new_cmd, &self.fuel_cmd) {
            (FuelCommand::Pid { loop_kind: a, .. }, FuelCommand::Pid { loop_kind: b, .. }) => {
                a != b
            }
            (FuelCommand::Trace(_), FuelCommand::Trace(_)) => false,
            _ => true,
        };
        if changed {
            act.set_fuel_integrator_kg_s(new_cmd.bumpless_integrator(
                t,
                st.fuel_kg_s,
                &Feedback::of(st),
            ));
            self.fuel_cmd = new_cmd;
        }
        changed || before != (self.starter, self.pt_locked, self.flame)
    }
}

impl Controller for MeasuredDrive {
    fn drive(&self, t_amb_k: f64, p_amb_kpa: f64) -> Drive {
        Drive {
            t_amb_k,
            p_amb_kpa,
            fuel: self.fuel_cmd.clone(),
            starter: self.starter,
            pt_locked: self.pt_locked,
            pt_load: self.pt_load.clone(),
            pt_speed: self.pt_speed.clone(),
            flame: self.flame,
        }
    }

    fn next_time_event(&self, t: f64) -> Option<f64> {
        let i = self.t_s.partition_point(|&x| x <= t + 1e-9);
        self.t_s.get(i).copied()
    }

    fn watches(&self) -> Vec<Watch> {
        Vec::new()
    }

    fn update(&mut self, t: f64, act: &mut Actuator<'_>, st: &Stations) -> Change {
        let i = self.t_s.partition_point(|&x| x <= t + 1e-9);
        if i == 0 {
            return Change::None;
        }
        let k = i - 1;
        let first = self.k == 0 && matches!(self.fuel_cmd, FuelCommand::Off) && !self.flame;
        if k == self.k && !first {
            return Change::None;
        }
        self.k = k;
        let resynced = self.resync_after_hole(k, act);
        if self.configure(t, act, st) || first || resynced {
            Change::Drive
        } else {
            // The same phase and commands: only the measured series, linear between samples,
            // bend here.
            Change::Slope
        }
    }

    fn polls(&self, _t: f64) -> bool {
        false
    }

    fn phase(&self) -> Phase {
        self.phase.get(self.k).copied().unwrap_or(Phase::Standstill)
    }
}

/// The state a segment starts from, read from its samples before the GG rises out of rest:
/// each shaft's first measured speed (0 where none is measured), and the hot section's
/// temperature as its thermocouples show it at rest (T34, else T4; the mean over that window,
/// never below ambient). After a long stop this is a cold engine at rest; soon after a run or a
/// trip the power turbine is still coasting and the hot section is warm, and a model started
/// cold would read the difference as degradation.
pub(crate) fn start_state_of(seg: &Recording, t_amb_k: f64) -> StartState {
    let n1 = seg.series(Signal::N1);
    let window = n1
        .iter()
        .position(|v| v.is_finite() && *v > REST_N1_RPM)
        .unwrap_or(n1.len())
        .max(1);
    let rest_values = |s: Signal| -> Vec<f64> {
        seg.series(s)
            .into_iter()
            .take(window)
            .filter(|v| v.is_finite())
            .collect()
    };
    let first_speed = |s: Signal| rest_values(s).first().map_or(0.0, |v| v.max(0.0));
    let mean = |v: Vec<f64>| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    let hot = mean(rest_values(Signal::T34))
        .or_else(|| mean(rest_values(Signal::T4)))
        .unwrap_or(t_amb_k);
    StartState {
        n1_rpm: first_speed(Signal::N1),
        n2_rpm: first_speed(Signal::N2),
        hot_section_k: hot.max(t_amb_k),
    }
}

/// Simulates what the instruments would have recorded for `seg` on an engine with `health`.
/// The result has the segment's sample times; its `measured` values include the sensor lags
/// (no noise), its `truth` the model's true values.
pub(crate) fn simulate_segment(
    engine: &Engine,
    health: &HealthParams,
    seg: &Recording,
    mode: DriveMode,
) -> Result<Trace, EngineError> {
    let first_n1 = seg.rows()[0][Signal::N1.index()];
    if first_n1.is_finite() && first_n1 > 100.0 {
        return Err(EngineError::Simulation {
            t_s: seg.times()[0],
            reason: format!("segment must begin with the GG at rest (n1 = {first_n1:.0} rpm)"),
        });
    }
    let (t_amb, p_amb) = seg.ambient(
        engine.cfg().ambient.temperature_k,
        engine.cfg().ambient.pressure_kpa,
    );
    let model = engine.model_at(health, t_amb, p_amb);
    // Work in segment-relative time so the simulation starts at 0.
    let rseg = seg.shifted_to_zero();
    let ctl = MeasuredDrive::new(&model, &rseg, mode);
    let mut sim = Simulation::with_controller(&model, ctl);
    // A restart soon after a stop or a trip begins with the power turbine (large inertia, little
    // drag) still coasting and the hot section warm: start from what the data show.
    sim.start_from(&start_state_of(seg, t_amb));
    let mut samples = Vec::with_capacity(seg.len());
    for (k, &t) in rseg.times().iter().enumerate() {
        let st = sim.sample(t)?;
        samples.push(TruthSample {
            t_s: seg.times()[k],
            phase: seg.phases()[k],
            stations: st,
        });
    }
    let opts = MeasurementOptions {
        lags: true,
        noise: false,
        bias: false,
        seed: 0,
    };
    Ok(Trace::from_truth(engine, &samples, Some(&opts)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::simulation::run_scenario;
    use crate::engine::Scenario;

    fn startup(engine: &Engine, h: &HealthParams) -> Trace {
        let m = engine.model(h);
        let (s, _) = run_scenario(&m, &Scenario::startup(engine.cfg())).expect("runs");
        let opts = MeasurementOptions {
            lags: true,
            noise: false,
            bias: false,
            seed: 0,
        };
        Trace::from_truth(engine, &s, Some(&opts))
    }

    fn max_rel_dev(a: &Trace, b: &Trace, s: Signal, from: usize) -> f64 {
        a.measured
            .iter()
            .zip(&b.measured)
            .skip(from)
            .map(|(x, y)| (x[s.index()] - y[s.index()]).abs() / y[s.index()].abs().max(1.0))
            .fold(0.0, f64::max)
    }

    /// A cold start begins at rest and ambient; a restart whose first samples show a coasting
    /// PT and a warm hot section begins there, and only those samples (before the GG rises)
    /// count.
    #[test]
    fn start_state_is_read_from_the_samples_before_the_gg_rises() {
        let engine = Engine::reference().expect("engine");
        let plant = startup(&engine, &HealthParams::HEALTHY);
        let mut seg = plant.to_recording().expect("a valid recording");
        let t_amb = engine.cfg().ambient.temperature_k;
        let cold = start_state_of(&seg, t_amb);
        assert_eq!((cold.n1_rpm, cold.n2_rpm), (0.0, 0.0));
        assert!((cold.hot_section_k - t_amb).abs() < 1.0, "{cold:?}");
        let rises = seg
            .series(Signal::N1)
            .iter()
            .position(|v| *v > REST_N1_RPM)
            .expect("the GG rises");
        for k in 0..rises {
            seg.set(k, Signal::N2, 950.0 - k as f64).expect("set");
            seg.set(k, Signal::T34, if k == 0 { f64::NAN } else { 700.0 })
                .expect("set");
        }
        seg.set(rises, Signal::T34, 2000.0).expect("set");
        let warm = start_state_of(&seg, t_amb);
        assert_eq!(warm.n2_rpm, 950.0);
        assert!((warm.hot_section_k - 700.0).abs() < 1e-9, "{warm:?}");
    }

    #[test]
    fn open_loop_replay_reproduces_the_run_it_came_from() {
        let engine = Engine::reference().expect("engine");
        let h = HealthParams {
            D_GC: 3.0,
            D_EC: 1.0,
            D_ET: 1.0,
            ..HealthParams::HEALTHY
        };
        let plant = startup(&engine, &h);
        let seg = plant.to_recording().expect("a valid recording");
        let same = simulate_segment(&engine, &h, &seg, DriveMode::MeasuredFuel).expect("replays");
        let other = simulate_segment(
            &engine,
            &HealthParams::HEALTHY,
            &seg,
            DriveMode::MeasuredFuel,
        )
        .expect("replays");
        // From light-off on (the crank depends only on the starter), in the steady part:
        let from = seg
            .phases()
            .iter()
            .position(|p| *p == Phase::Steady)
            .expect("reaches steady");
        for s in [
            Signal::N1,
            Signal::P2,
            Signal::T2,
            Signal::T34,
            Signal::P34,
            Signal::Power,
        ] {
            let d_same = max_rel_dev(&same, &plant, s, from);
            let d_other = max_rel_dev(&other, &plant, s, from);
            assert!(
                d_same < 2e-3,
                "{s}: replay with the true health deviates {d_same}"
            );
            assert!(
                d_other > 3.0 * d_same,
                "{s}: health changes the replay ({d_other} vs {d_same})"
            );
        }
    }
}
