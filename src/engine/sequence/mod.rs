//! The start-up and shutdown sequencer: the discrete part of the engine control.
//!
//! The sequencer is the discrete part of the engine control (REFERENCE §2): standstill → crank →
//! purge → light-off (coast to light-off speed, ignition) → acceleration (starter cut-out) →
//! idle (PT break-away, PT speed governing) → synchronisation → loading (warm-up at minimum load,
//! ramp) → steady, and on command unloading (to 1 % of base load, then the breaker opens) →
//! cool-down (PT governed at synchronous speed) → shutdown, or a trip at any time.
//! It chooses the drive (fuel command, starter, breaker) for each integration step and acts on
//! the engine only through [`Actuator`] at its transitions; `simulation.rs` runs the model
//! under it.
//!
//! Mechanical drive (`[load] mode = "load_law"`, e.g. a pipeline compressor): there is no
//! breaker and no synchronisation; the driven machine is coupled from standstill and absorbs
//! `P_law(n2)` (`load.rs`). As a pipeline compressor's unit control does, the fuel governs PT
//! speed (the station control asks for a compressor speed), within the same acceleration,
//! deceleration and minimum-fuel limits. After core idle the PT governor ramps the PT to its
//! minimum governed speed (where the law absorbs `min_load_mw`), holds it for the warm-up
//! (`warmup_s`, reported as loading), then ramps the speed set-point to the speed where the law
//! absorbs `base_load_mw`, in the time the power ramp `load_ramp_mw_s` would take; steady when
//! the shaft power is within 1 % of base load after the ramp. A stop ramps the speed back to the
//! minimum governed speed, holds it for the cool-down, then cuts the fuel.
//! Pure and deterministic: no I/O, no randomness (sensor noise is applied afterwards).

mod mechanical;
mod scenario;

pub use scenario::{Command, End, Event, Scenario};

use super::config::EngineConfig;
use super::control::{
    Approach, Feedback, FuelCommand, FuelLimits, GgFloor, Loop, Ramp, Series, Setpoint,
    StarterCommand,
};
use super::dynamic::{Drive, Stations};
use super::load::PtLoad;
use super::model::Model;
use super::simulation::{Change, Controller, Watch};
use super::state::{Actuator, Shaft};
use crate::signals::Phase;
use std::sync::Arc;

/// Fraction of `sequence.purge_speed_rpm` the cranking GG must reach before the purge starts
/// (the starter's speed hold droops a little below its set point).
pub(crate) const PURGE_SPEED_FRACTION: f64 = 0.98;

/// Internal sequencer mode (finer than the reported [`Phase`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mode {
    Standstill,
    Crank,
    Purge {
        until: f64,
    },
    Coast,
    Ignition {
        until: f64,
    },
    Accel,
    Idle {
        until: f64,
    },
    PtGovern,
    /// Generator: the PT governor approaches synchronous speed and the synchroniser closes the
    /// breaker at `until` once the slip allows; the phase reads Idle until `announced` (the PT
    /// within 1 % of synchronous speed, where a unit's synchroniser starts matching), then
    /// Synchronisation.
    Sync {
        until: f64,
        announced: bool,
    },
    Loading {
        ramp_done_at: f64,
    },
    Steady,
    Unloading {
        ramp_done_at: f64,
    },
    Cooldown {
        until: f64,
    },
    Coastdown {
        trip: bool,
    },
}

/// The discrete controller.
#[derive(Debug, Clone)]
pub struct Sequencer {
    cfg: EngineConfig,
    limits: Arc<FuelLimits>,
    /// The limits of the loops that do not govern the GG (PT speed, power): with the GG
    /// minimum-speed floor (`control.min_gg_speed_fraction`).
    governed_limits: Arc<FuelLimits>,
    mode: Mode,
    starter_engaged: bool,
    fuel: FuelCommand,
    pt_locked: bool,
    /// The PT's mechanical load law (`None`: generator on a breaker).
    pt_load: Option<PtLoad>,
    flame: bool,
    events: Vec<Event>,
    next_event: usize,
    /// Time the engine first reached steady load.
    pub steady_since: Option<f64>,
}

impl Sequencer {
    pub fn new(model: &Model, scenario: &Scenario) -> Sequencer {
        let cfg = model.cfg();
        let mut events = scenario.events.clone();
        events.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        let limits = FuelLimits::from_config(&cfg.control);
        let floor = GgFloor {
            speed_rpm: cfg.control.min_gg_speed_fraction * cfg.sequence.idle_speed_rpm,
            gain_kg_s_per_rpm: cfg.control.speed_kp_kg_s_per_rpm,
        };
        Sequencer {
            cfg: cfg.clone(),
            governed_limits: Arc::new(limits.clone().with_gg_floor(floor)),
            limits: Arc::new(limits),
            mode: Mode::Standstill,
            starter_engaged: false,
            fuel: FuelCommand::Off,
            pt_locked: false,
            pt_load: PtLoad::of(model),
            flame: false,
            events,
            next_event: 0,
            steady_since: None,
        }
    }

    /// The reported phase of operation.
    pub fn phase(&self) -> Phase {
        match self.mode {
            Mode::Standstill => Phase::Standstill,
            Mode::Crank => Phase::Crank,
            Mode::Purge { .. } => Phase::Purge,
            Mode::Coast | Mode::Ignition { .. } => Phase::LightOff,
            Mode::Accel => Phase::Acceleration,
            Mode::Idle { .. } | Mode::PtGovern => Phase::Idle,
            Mode::Sync {
                announced: false, ..
            } => Phase::Idle,
            Mode::Sync { .. } => Phase::Synchronisation,
            Mode::Loading { .. } => Phase::Loading,
            Mode::Steady => Phase::Steady,
            Mode::Unloading { .. } | Mode::Cooldown { .. } => Phase::Unloading,
            Mode::Coastdown { trip: false } => Phase::Shutdown,
            Mode::Coastdown { trip: true } => Phase::Trip,
        }
    }

    pub fn drive(&self, t_amb_k: f64, p_amb_kpa: f64) -> Drive {
        let st = &self.cfg.starter;
        let starter = if !self.starter_engaged {
            StarterCommand::Off
        } else {
            match self.mode {
                Mode::Crank | Mode::Purge { .. } => {
                    StarterCommand::hold(st, self.cfg.sequence.purge_speed_rpm)
                }
                _ => StarterCommand::full(st),
            }
        };
        Drive {
            t_amb_k,
            p_amb_kpa,
            fuel: self.fuel.clone(),
            starter,
            pt_locked: self.pt_locked,
            pt_load: self.pt_load.clone(),
            pt_speed: None,
            flame: self.flame,
        }
    }

    /// Earliest timed event strictly after `t` (mode timers and scheduled commands).
    pub fn next_time_event(&self, t: f64) -> Option<f64> {
        let timer = match self.mode {
            Mode::Purge { until }
            | Mode::Ignition { until }
            | Mode::Idle { until }
            | Mode::Sync { until, .. }
            | Mode::Cooldown { until } => Some(until),
            Mode::Loading { ramp_done_at } | Mode::Unloading { ramp_done_at } => Some(ramp_done_at),
            _ => None,
        };
        let cmd = self.events.get(self.next_event).map(|e| e.t_s);
        // The set-point's kinks are where the load ramp starts and ends within a mode.
        let kink = self.fuel.next_setpoint_kink(t);
        [timer, cmd, kink]
            .into_iter()
            .flatten()
            .filter(|&x| x > t + 1e-9)
            .reduce(f64::min)
    }

    /// Speed thresholds whose crossing triggers a transition in the current mode.
    pub fn watches(&self) -> Vec<Watch> {
        let q = &self.cfg.sequence;
        let n1 = |rpm: f64, rising: bool| Watch {
            shaft: Shaft::Gg,
            rpm,
            rising,
        };
        let n2 = |rpm: f64, rising: bool| Watch {
            shaft: Shaft::Pt,
            rpm,
            rising,
        };
        match self.mode {
            Mode::Crank => vec![n1(PURGE_SPEED_FRACTION * q.purge_speed_rpm, true)],
            Mode::Coast => vec![n1(q.light_off_speed_rpm, false)],
            Mode::Accel => {
                let mut w = vec![n1(0.99 * q.idle_speed_rpm, true)];
                if self.starter_engaged {
                    w.push(n1(self.cfg.starter.cutout_rpm, true));
                }
                w
            }
            // A PT already turning (a hot restart) can reach its governed range while the GG
            // holds core idle: the governor takes over there instead of letting it overspeed.
            Mode::Idle { .. } => vec![n2(self.pt_handover_rpm(), true)],
            Mode::PtGovern => vec![n2(0.99 * self.pt_governor_target_rpm(), true)],
            Mode::Sync {
                announced: false, ..
            } => vec![n2(0.99 * self.pt_governor_target_rpm(), true)],
            Mode::Coastdown { .. } => vec![n1(q.rest_speed_rpm, false)],
            _ => Vec::new(),
        }
    }

    /// Switches the fuel command bumplessly (the fuel flow is continuous across the switch).
    fn switch_fuel(&mut self, t: f64, act: &mut Actuator<'_>, st: &Stations, cmd: FuelCommand) {
        let i = cmd.bumpless_integrator(t, st.fuel_kg_s, &Feedback::of(st));
        act.set_fuel_integrator_kg_s(i);
        self.fuel = cmd;
    }

    fn pid(&self, loop_kind: Loop, setpoint: Setpoint) -> FuelCommand {
        let limits = match loop_kind {
            Loop::GgSpeed => self.limits.clone(),
            // A PT governor cutting the fuel against an overspeed (a load rejection, a hot
            // restart's PT arriving fast) would otherwise run the burning GG down to rest.
            Loop::PtSpeed | Loop::Power => self.governed_limits.clone(),
        };
        FuelCommand::pid(&self.cfg.control, limits, loop_kind, setpoint)
    }

    /// Applies every transition due at time `t` with state `y`. Returns whether anything changed.
    /// `st` must be the station table at (t, y) under the drive before the call.
    pub fn update(&mut self, t: f64, act: &mut Actuator<'_>, st: &Stations) -> bool {
        let mut changed = false;
        // Scheduled commands first.
        while let Some(ev) = self.events.get(self.next_event).copied() {
            if ev.t_s > t + 1e-9 {
                break;
            }
            self.next_event += 1;
            self.command(t, act, st, ev.command);
            changed = true;
        }
        for _ in 0..8 {
            if !self.transition(t, act, st) {
                break;
            }
            changed = true;
        }
        changed
    }

    fn command(&mut self, t: f64, act: &mut Actuator<'_>, st: &Stations, c: Command) {
        let q = self.cfg.sequence.clone();
        match c {
            Command::Start => {
                if matches!(self.mode, Mode::Standstill | Mode::Coastdown { .. }) {
                    self.flame = false;
                    self.fuel = FuelCommand::Off;
                    self.pt_locked = false;
                    self.starter_engaged = true;
                    self.mode = if st.n1_rpm >= PURGE_SPEED_FRACTION * q.purge_speed_rpm {
                        Mode::Purge {
                            until: t + q.purge_s,
                        }
                    } else {
                        Mode::Crank
                    };
                }
            }
            Command::Stop => match self.mode {
                Mode::Steady | Mode::Loading { .. } if self.pt_load.is_some() => {
                    self.mechanical_stop(t, act, st);
                }
                Mode::Steady | Mode::Loading { .. } => {
                    // A unit is unloaded to a small forward power before its breaker opens: a
                    // breaker opened at minimum load is a load rejection (the PT overspeeds, the
                    // governor cuts the fuel to its minimum and a small gas generator dives
                    // towards flame-out).
                    let p0 = st.pt_shaft_mw;
                    let ramp = Ramp {
                        t0: t,
                        v0: p0,
                        rate: q.load_ramp_mw_s,
                        target: (BREAKER_OPEN_FRACTION * q.base_load_mw).min(p0),
                    };
                    let cmd = self.pid(Loop::Power, Setpoint::Ramp(ramp));
                    self.switch_fuel(t, act, st, cmd);
                    self.mode = Mode::Unloading {
                        ramp_done_at: ramp.end_time().max(t + 1.0),
                    };
                }
                Mode::Standstill
                | Mode::Coastdown { .. }
                | Mode::Unloading { .. }
                | Mode::Cooldown { .. } => {}
                _ => self.cut_fuel(false),
            },
            Command::Trip => {
                if !matches!(self.mode, Mode::Standstill) {
                    self.cut_fuel(true);
                }
            }
        }
    }

    fn cut_fuel(&mut self, trip: bool) {
        self.flame = false;
        self.fuel = FuelCommand::Off;
        self.starter_engaged = false;
        self.pt_locked = false;
        self.mode = Mode::Coastdown { trip };
    }

    /// One transition if its condition holds at (t, y).
    fn transition(&mut self, t: f64, act: &mut Actuator<'_>, st: &Stations) -> bool {
        let q = self.cfg.sequence.clone();
        let sync = self.cfg.design.pt_speed_rpm;
        let tol = 1e-6;
        let n1 = act.speed_rpm(Shaft::Gg);
        let n2 = act.speed_rpm(Shaft::Pt);
        if let Some(law) = self.pt_load.clone() {
            if let Some(done) = self.mechanical_transition(t, act, st, &law, n2) {
                return done;
            }
        }
        match self.mode {
            Mode::Crank if n1 >= PURGE_SPEED_FRACTION * q.purge_speed_rpm * (1.0 - tol) => {
                self.mode = Mode::Purge {
                    until: t + q.purge_s,
                };
            }
            Mode::Purge { until } if t >= until - 1e-9 => {
                self.starter_engaged = false;
                self.mode = Mode::Coast;
            }
            Mode::Coast if n1 <= q.light_off_speed_rpm * (1.0 + tol) => {
                self.starter_engaged = true;
                self.flame = true;
                self.fuel = FuelCommand::Fixed(q.light_off_fuel_kg_s);
                act.set_fuel_integrator_kg_s(q.light_off_fuel_kg_s);
                self.mode = Mode::Ignition {
                    until: t + q.light_off_hold_s,
                };
            }
            Mode::Ignition { until } if t >= until - 1e-9 => {
                // The speed reference starts a little ahead of the GG so the fuel rises from the
                // light-off level at once (an acceleration schedule), never dipping below it.
                let ramp = Ramp {
                    t0: t,
                    v0: (n1 + ACCEL_REFERENCE_LEAD_RPM).min(q.idle_speed_rpm),
                    rate: q.accel_rate_rpm_s,
                    target: q.idle_speed_rpm,
                };
                let cmd = self.pid(Loop::GgSpeed, Setpoint::Ramp(ramp));
                self.switch_fuel(t, act, st, cmd);
                self.mode = Mode::Accel;
            }
            Mode::Accel
                if self.starter_engaged && n1 >= self.cfg.starter.cutout_rpm * (1.0 - tol) =>
            {
                self.starter_engaged = false;
            }
            Mode::Accel if n1 >= 0.99 * q.idle_speed_rpm * (1.0 - tol) => {
                self.starter_engaged = false;
                self.mode = Mode::Idle {
                    until: t + q.idle_hold_s,
                };
            }
            Mode::Idle { until } if t >= until - 1e-9 || self.pt_in_governed_range(n2) => {
                // The PT governor takes over: a PT speed ramp from wherever the PT has got to,
                // blending into an exponential approach to synchronous speed, so the PT's
                // acceleration power (≈ 2 MW at full rate) fades out smoothly, the GG is not
                // starved and the governor does not ring around synchronous speed.
                let approach =
                    Approach::new(t, n2, sync, q.pt_accel_rate_rpm_s, q.pt_approach_tau_s);
                // The synchroniser's timer runs from the set-point passing 99 %, taken at the
                // sequence logic's next scan: a time the approach fixes at hand-over, not where
                // the integrator places a crossing on the slow end of the approach (every
                // millisecond there moves the whole loading that follows).
                let armed = (approach.time_at(0.99 * sync) / SCAN_S).ceil() * SCAN_S;
                let cmd = self.pid(Loop::PtSpeed, Setpoint::Approach(approach));
                self.switch_fuel(t, act, st, cmd);
                self.mode = Mode::Sync {
                    until: armed + q.sync_s,
                    announced: false,
                };
            }
            Mode::Sync {
                until,
                announced: false,
            } if n2 >= 0.99 * sync * (1.0 - tol) => {
                self.mode = Mode::Sync {
                    until,
                    announced: true,
                };
            }
            Mode::Sync { until, .. }
                if t >= until + q.sync_timeout_s
                    && (n2 / sync - 1.0).abs() * 100.0 > q.sync_slip_pct =>
            {
                // The synchroniser never saw the slip within its window: the start is aborted.
                self.cut_fuel(true);
            }
            Mode::Sync { until, .. }
                if t >= until - 1e-9 && (n2 / sync - 1.0).abs() * 100.0 <= q.sync_slip_pct =>
            {
                // Breaker closes: the grid holds the PT at synchronous speed from now on.
                self.pt_locked = true;
                act.set_speed_rpm(Shaft::Pt, sync);
                let p0 = st.pt_shaft_mw.max(0.0);
                let r = q.load_ramp_mw_s;
                // Block load on closing (no reverse power), then warm-up, then the ramp.
                let t1 = t + (q.min_load_mw - p0).max(0.0) / BLOCK_LOAD_RATE_MW_S;
                let t2 = t1 + q.warmup_s;
                let t3 = t2 + (q.base_load_mw - q.min_load_mw) / r;
                let series = Series {
                    t_s: vec![t, t1, t2, t3],
                    value: vec![p0, q.min_load_mw, q.min_load_mw, q.base_load_mw],
                };
                let cmd = self.pid(Loop::Power, Setpoint::Series(Arc::new(series)));
                self.switch_fuel(t, act, st, cmd);
                self.mode = Mode::Loading { ramp_done_at: t3 };
            }
            Mode::Loading { ramp_done_at }
                if t >= ramp_done_at - 1e-9
                    && (st.pt_shaft_mw - q.base_load_mw).abs() <= 0.01 * q.base_load_mw =>
            {
                self.mode = Mode::Steady;
                self.steady_since.get_or_insert(t);
            }
            Mode::Unloading { ramp_done_at } if t >= ramp_done_at - 1e-9 => {
                // Breaker opens; the PT governor holds synchronous speed while the engine cools.
                self.pt_locked = false;
                let cmd = self.pid(Loop::PtSpeed, Setpoint::Ramp(Ramp::hold(sync)));
                self.switch_fuel(t, act, st, cmd);
                self.mode = Mode::Cooldown {
                    until: t + q.cooldown_s,
                };
            }
            Mode::Cooldown { until } if t >= until - 1e-9 => self.cut_fuel(false),
            Mode::Coastdown { .. } if n1 <= q.rest_speed_rpm * (1.0 + tol) => {
                act.set_speed_rpm(Shaft::Gg, 0.0);
                self.mode = Mode::Standstill;
            }
            _ => return false,
        }
        true
    }

    /// Whether the PT has reached its governed range during the idle hold: a hot restart's PT,
    /// still turning, gets there on the GG's idle power alone and, left to it, overspeeds.
    fn pt_in_governed_range(&self, n2: f64) -> bool {
        n2 >= self.pt_handover_rpm() * (1.0 - 1e-6)
    }

    /// The PT speed at which the governor takes over from the idle hold: where its set-point
    /// would leave the ramp for the final approach (generator: `pt_accel_rate_rpm_s ·
    /// pt_approach_tau_s` below synchronous speed, within 90–99 % of it; mechanical drive: the
    /// knee at 95 % of the minimum governed speed), so the approach has its whole length to
    /// take up the PT's momentum.
    fn pt_handover_rpm(&self) -> f64 {
        let target = self.pt_governor_target_rpm();
        match &self.pt_load {
            None => {
                let q = &self.cfg.sequence;
                (target - q.pt_accel_rate_rpm_s * q.pt_approach_tau_s)
                    .clamp(0.9 * target, 0.99 * target)
            }
            Some(_) => 0.95 * target,
        }
    }

    /// The PT speed the governor ramps to after core idle: synchronous speed for a generator, the
    /// minimum governed speed of a mechanical drive.
    fn pt_governor_target_rpm(&self) -> f64 {
        match &self.pt_load {
            None => self.cfg.design.pt_speed_rpm,
            Some(law) => law.speed_for_power_rpm(self.cfg.sequence.min_load_mw),
        }
    }

    /// Whether `update` must be called after every step (conditions that are not thresholds).
    pub fn polls(&self, t: f64) -> bool {
        match self.mode {
            Mode::Loading { ramp_done_at } => t >= ramp_done_at - 1e-9,
            // The synchroniser waits for the slip once its time has passed.
            Mode::Sync { until, .. } => t >= until - 1e-9,
            _ => false,
        }
    }
}

impl Controller for Sequencer {
    fn drive(&self, t_amb_k: f64, p_amb_kpa: f64) -> Drive {
        Sequencer::drive(self, t_amb_k, p_amb_kpa)
    }
    fn next_time_event(&self, t: f64) -> Option<f64> {
        Sequencer::next_time_event(self, t)
    }
    fn watches(&self) -> Vec<Watch> {
        Sequencer::watches(self)
    }
    fn update(&mut self, t: f64, act: &mut Actuator<'_>, st: &Stations) -> Change {
        if Sequencer::update(self, t, act, st) {
            Change::Drive
        } else if self.fuel.setpoint_kinks_at(t) {
            // The same loop on the same set-point, whose slope in time just changed.
            Change::Slope
        } else {
            Change::None
        }
    }
    fn polls(&self, t: f64) -> bool {
        Sequencer::polls(self, t)
    }
    fn phase(&self) -> Phase {
        Sequencer::phase(self)
    }
}

/// The forward power, as a fraction of base load, a normal stop unloads to before the breaker
/// opens (the reverse-power relay's margin).
const BREAKER_OPEN_FRACTION: f64 = 0.01;
/// Rate at which the set-point takes the minimum (block) load when the breaker closes, MW/s.
const BLOCK_LOAD_RATE_MW_S: f64 = 1.0;
/// The sequence logic's scan period, s: a timer it starts from a computed time begins on this
/// grid.
const SCAN_S: f64 = 0.1;

/// How far ahead of the GG speed the acceleration reference starts, rpm.
const ACCEL_REFERENCE_LEAD_RPM: f64 = 150.0;
