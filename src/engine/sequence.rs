//! The start-up and shutdown sequencer and the simulation loop that runs the model through it.
//!
//! The sequencer is the discrete part of the engine control (REFERENCE §2): standstill → crank →
//! purge → light-off (coast to light-off speed, ignition) → acceleration (starter cut-out) →
//! idle (PT break-away, PT speed governing) → synchronisation → loading (warm-up at minimum load,
//! ramp) → steady, and on command unloading → cool-down → shutdown, or a trip at any time.
//! It chooses the drive (fuel command, starter, breaker) for each integration step; the
//! simulation loop integrates the dynamic model between events, locating speed-threshold
//! crossings by step refinement and landing exactly on timed events and output samples.
//! Pure and deterministic: no I/O, no randomness (sensor noise is applied afterwards).

use super::config::EngineConfig;
use super::control::{
    FuelCommand, FuelLimits, Loop, Measured, Ramp, Series, Setpoint, StarterCommand,
};
use super::dynamic::{self, Drive, Scales, State, Stations, IX_FUEL_I, IX_N1, IX_N2, NX};
use super::integrator::{step_factor, Ros2};
use super::model::{EngineError, Model};
use crate::signals::Phase;
use std::sync::Arc;

/// An operator or protection command at a given time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    Start,
    /// Normal stop: unload, cool down, fuel off.
    Stop,
    /// Protective trip: fuel off and breaker open at once.
    Trip,
}

/// A command scheduled at `t_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    pub t_s: f64,
    pub command: Command,
}

/// When a scenario ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum End {
    /// At a fixed time.
    At(f64),
    /// This long after the engine first reaches steady load (with `max_s` as a guard).
    AfterSteady { hold_s: f64, max_s: f64 },
}

/// A sequence of commands and an end condition.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    pub events: Vec<Event>,
    pub end: End,
}

impl Scenario {
    /// REFERENCE §2 start-up from standstill to steady base load.
    pub fn startup(cfg: &EngineConfig) -> Scenario {
        Scenario {
            events: vec![Event {
                t_s: cfg.sequence.standstill_s,
                command: Command::Start,
            }],
            end: End::AfterSteady {
                hold_s: cfg.sequence.steady_s,
                max_s: 3600.0,
            },
        }
    }
}

impl Scenario {
    /// A stretch of operations for the plant simulator and the detector's tests: a start to base
    /// load, a normal stop, an aborted start (tripped during acceleration), and a hot restart
    /// soon after the trip that runs to base load.
    pub fn operations(cfg: &EngineConfig) -> Scenario {
        let s0 = cfg.sequence.standstill_s;
        // A start takes ~13 min; hold base load 5 min, then stop (cool-down + coast ≈ 6 min).
        let stop = s0 + 1100.0;
        let second = stop + 600.0;
        let trip = second + 120.0;
        let hot = trip + 240.0;
        Scenario {
            events: vec![
                Event {
                    t_s: s0,
                    command: Command::Start,
                },
                Event {
                    t_s: stop,
                    command: Command::Stop,
                },
                Event {
                    t_s: second,
                    command: Command::Start,
                },
                Event {
                    t_s: trip,
                    command: Command::Trip,
                },
                Event {
                    t_s: hot,
                    command: Command::Start,
                },
            ],
            end: End::At(hot + 1100.0),
        }
    }
}

/// Internal sequencer mode (finer than the reported [`Phase`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mode {
    Standstill,
    Crank,
    Purge { until: f64 },
    Coast,
    Ignition { until: f64 },
    Accel,
    Idle { until: f64 },
    PtGovern,
    Sync { until: f64 },
    Loading { ramp_done_at: f64 },
    Steady,
    Unloading { ramp_done_at: f64 },
    Cooldown { until: f64 },
    Coastdown { trip: bool },
}

/// A speed threshold the sequencer waits for.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Watch {
    index: usize,
    /// Threshold in normalised state units.
    level: f64,
    rising: bool,
}

/// The discrete part of whatever drives the model: the start-up sequencer, or a replay of a
/// measured segment. The simulation loop asks it for the drive of each step, integrates, and
/// lets it react at its events.
pub trait Controller {
    /// Drive for the next step.
    fn drive(&self, t_amb_k: f64, p_amb_kpa: f64) -> Drive;
    /// Earliest timed event strictly after `t`.
    fn next_time_event(&self, t: f64) -> Option<f64>;
    /// Fraction of the step y0 → y1 at which a watched threshold is crossed.
    fn first_crossing(&self, y0: &State, y1: &State) -> Option<f64>;
    /// Applies the transitions due at (t, y); may adjust `y` (bumpless switches, locking).
    fn update(&mut self, t: f64, y: &mut State, st: &Stations) -> bool;
    /// Whether `update` must run after every step.
    fn polls(&self, t: f64) -> bool;
    /// Reported phase.
    fn phase(&self) -> Phase;
}

/// The discrete controller.
#[derive(Debug, Clone)]
pub struct Sequencer {
    cfg: EngineConfig,
    scales: Scales,
    limits: Arc<FuelLimits>,
    mode: Mode,
    starter_engaged: bool,
    fuel: FuelCommand,
    pt_locked: bool,
    flame: bool,
    events: Vec<Event>,
    next_event: usize,
    /// Time the engine first reached steady load.
    pub steady_since: Option<f64>,
}

impl Sequencer {
    pub fn new(cfg: &EngineConfig, model: &Model, scenario: &Scenario) -> Sequencer {
        let mut events = scenario.events.clone();
        events.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        Sequencer {
            cfg: cfg.clone(),
            scales: Scales::of(model),
            limits: Arc::new(FuelLimits::from_config(&cfg.control)),
            mode: Mode::Standstill,
            starter_engaged: false,
            fuel: FuelCommand::Off,
            pt_locked: false,
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
            flame: self.flame,
        }
    }

    /// Earliest timed event strictly after `t` (mode timers and scheduled commands).
    fn next_time_event(&self, t: f64) -> Option<f64> {
        let timer = match self.mode {
            Mode::Purge { until }
            | Mode::Ignition { until }
            | Mode::Idle { until }
            | Mode::Sync { until }
            | Mode::Cooldown { until } => Some(until),
            Mode::Loading { ramp_done_at } | Mode::Unloading { ramp_done_at } => Some(ramp_done_at),
            _ => None,
        };
        let cmd = self.events.get(self.next_event).map(|e| e.t_s);
        [timer, cmd]
            .into_iter()
            .flatten()
            .filter(|&x| x > t + 1e-9)
            .reduce(f64::min)
    }

    fn watches(&self) -> Vec<Watch> {
        let q = &self.cfg.sequence;
        let sc = &self.scales;
        let n1 = |rpm: f64, rising: bool| Watch {
            index: IX_N1,
            level: rpm / sc.n1,
            rising,
        };
        let n2 = |rpm: f64, rising: bool| Watch {
            index: IX_N2,
            level: rpm / sc.n2,
            rising,
        };
        match self.mode {
            Mode::Crank => vec![n1(0.98 * q.purge_speed_rpm, true)],
            Mode::Coast => vec![n1(q.light_off_speed_rpm, false)],
            Mode::Accel => {
                let mut w = vec![n1(0.99 * q.idle_speed_rpm, true)];
                if self.starter_engaged {
                    w.push(n1(self.cfg.starter.cutout_rpm, true));
                }
                w
            }
            Mode::PtGovern => vec![n2(0.99 * self.cfg.design.pt_speed_rpm, true)],
            Mode::Coastdown { .. } => vec![n1(q.rest_speed_rpm, false)],
            _ => Vec::new(),
        }
    }

    /// Fraction of the step (y0 → y1) at which the first watched threshold is crossed.
    fn first_crossing(&self, y0: &State, y1: &State) -> Option<f64> {
        self.watches()
            .iter()
            .filter_map(|w| {
                let (a, b) = (y0[w.index] - w.level, y1[w.index] - w.level);
                let crossed = if w.rising {
                    a < 0.0 && b >= 0.0
                } else {
                    a > 0.0 && b <= 0.0
                };
                crossed.then(|| (a / (a - b)).clamp(0.0, 1.0))
            })
            .reduce(f64::min)
    }

    fn measured(st: &Stations) -> Measured {
        Measured {
            p2_kpa: st.p2_kpa,
            n1_rpm: st.n1_rpm,
            n2_rpm: st.n2_rpm,
            power_mw: st.pt_shaft_mw,
        }
    }

    /// Switches the fuel command bumplessly (the fuel flow is continuous across the switch).
    fn switch_fuel(&mut self, t: f64, y: &mut State, st: &Stations, cmd: FuelCommand) {
        let m = Self::measured(st);
        let i = cmd.bumpless_integrator(t, st.fuel_kg_s, &m);
        y[IX_FUEL_I] = i / self.scales.fuel;
        self.fuel = cmd;
    }

    fn pid(&self, loop_kind: Loop, setpoint: Setpoint) -> FuelCommand {
        FuelCommand::pid(&self.cfg.control, self.limits.clone(), loop_kind, setpoint)
    }

    /// Applies every transition due at time `t` with state `y`. Returns whether anything changed.
    /// `st` must be the station table at (t, y) under the drive before the call.
    pub fn update(&mut self, t: f64, y: &mut State, st: &Stations) -> bool {
        let mut changed = false;
        // Scheduled commands first.
        while let Some(ev) = self.events.get(self.next_event).copied() {
            if ev.t_s > t + 1e-9 {
                break;
            }
            self.next_event += 1;
            self.command(t, y, st, ev.command);
            changed = true;
        }
        for _ in 0..8 {
            if !self.transition(t, y, st) {
                break;
            }
            changed = true;
        }
        changed
    }

    fn command(&mut self, t: f64, y: &mut State, st: &Stations, c: Command) {
        let q = self.cfg.sequence.clone();
        match c {
            Command::Start => {
                if matches!(self.mode, Mode::Standstill | Mode::Coastdown { .. }) {
                    self.flame = false;
                    self.fuel = FuelCommand::Off;
                    self.pt_locked = false;
                    self.starter_engaged = true;
                    self.mode = if st.n1_rpm >= 0.98 * q.purge_speed_rpm {
                        Mode::Purge {
                            until: t + q.purge_s,
                        }
                    } else {
                        Mode::Crank
                    };
                }
            }
            Command::Stop => match self.mode {
                Mode::Steady | Mode::Loading { .. } => {
                    let p0 = st.pt_shaft_mw;
                    let ramp = Ramp {
                        t0: t,
                        v0: p0,
                        rate: q.load_ramp_mw_s,
                        target: q.min_load_mw.min(p0),
                    };
                    let cmd = self.pid(Loop::Power, Setpoint::Ramp(ramp));
                    self.switch_fuel(t, y, st, cmd);
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
    fn transition(&mut self, t: f64, y: &mut State, st: &Stations) -> bool {
        let q = self.cfg.sequence.clone();
        let sync = self.cfg.design.pt_speed_rpm;
        let tol = 1e-6;
        let n1 = y[IX_N1] * self.scales.n1;
        let n2 = y[IX_N2] * self.scales.n2;
        match self.mode {
            Mode::Crank if n1 >= 0.98 * q.purge_speed_rpm * (1.0 - tol) => {
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
                y[IX_FUEL_I] = q.light_off_fuel_kg_s / self.scales.fuel;
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
                self.switch_fuel(t, y, st, cmd);
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
            Mode::Idle { until } if t >= until - 1e-9 => {
                // The PT governor takes over: a PT speed ramp from wherever the PT has got to, at a
                // sixth of the rate over the last 5 %, so the PT's acceleration power (≈ 2 MW at
                // full rate) fades out instead of vanishing, and the GG is not starved.
                let r = q.pt_accel_rate_rpm_s;
                let knee = (0.95 * sync).max(n2);
                let t1 = t + (knee - n2) / r;
                let t2 = t1 + (sync - knee) / (r / 6.0);
                let series = Series {
                    t_s: vec![t, t1, t2],
                    value: vec![n2, knee, sync],
                };
                let cmd = self.pid(Loop::PtSpeed, Setpoint::Series(Arc::new(series)));
                self.switch_fuel(t, y, st, cmd);
                self.mode = Mode::PtGovern;
            }
            Mode::PtGovern if n2 >= 0.99 * sync * (1.0 - tol) => {
                self.mode = Mode::Sync {
                    until: t + q.sync_s,
                };
            }
            Mode::Sync { until } if t >= until - 1e-9 => {
                // Breaker closes: the grid holds the PT at synchronous speed from now on.
                self.pt_locked = true;
                y[IX_N2] = sync / self.scales.n2;
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
                self.switch_fuel(t, y, st, cmd);
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
                self.switch_fuel(t, y, st, cmd);
                self.mode = Mode::Cooldown {
                    until: t + q.cooldown_s,
                };
            }
            Mode::Cooldown { until } if t >= until - 1e-9 => self.cut_fuel(false),
            Mode::Coastdown { .. } if n1 <= q.rest_speed_rpm * (1.0 + tol) => {
                y[IX_N1] = 0.0;
                self.mode = Mode::Standstill;
            }
            _ => return false,
        }
        true
    }

    /// Whether `update` must be called after every step (conditions that are not thresholds).
    fn polls(&self, t: f64) -> bool {
        matches!(self.mode, Mode::Loading { ramp_done_at } if t >= ramp_done_at - 1e-9)
    }
}

impl Controller for Sequencer {
    fn drive(&self, t_amb_k: f64, p_amb_kpa: f64) -> Drive {
        Sequencer::drive(self, t_amb_k, p_amb_kpa)
    }
    fn next_time_event(&self, t: f64) -> Option<f64> {
        Sequencer::next_time_event(self, t)
    }
    fn first_crossing(&self, y0: &State, y1: &State) -> Option<f64> {
        Sequencer::first_crossing(self, y0, y1)
    }
    fn update(&mut self, t: f64, y: &mut State, st: &Stations) -> bool {
        Sequencer::update(self, t, y, st)
    }
    fn polls(&self, t: f64) -> bool {
        Sequencer::polls(self, t)
    }
    fn phase(&self) -> Phase {
        Sequencer::phase(self)
    }
}

/// Rate at which the set-point takes the minimum (block) load when the breaker closes, MW/s.
const BLOCK_LOAD_RATE_MW_S: f64 = 1.0;

/// How far ahead of the GG speed the acceleration reference starts, rpm.
const ACCEL_REFERENCE_LEAD_RPM: f64 = 150.0;

/// Error level at which even fixed-step mode subdivides a step.
const FIXED_STEP_EMERGENCY_ERR: f64 = 50.0;

/// States within their physical range (normalised): positive pressures and temperature.
fn plausible(y: &State) -> bool {
    y[dynamic::IX_P2] > 0.01
        && y[dynamic::IX_T3] > 0.1
        && y[dynamic::IX_P34] > 0.01
        && y[dynamic::IX_T3] < 2.0
}

/// One output sample: the true station table and the phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    pub t_s: f64,
    pub phase: Phase,
    pub stations: Stations,
}

/// Integration statistics (performance accounting).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct RunStats {
    pub steps: usize,
    pub rejected: usize,
    pub rhs_evals: usize,
    pub jacobians: usize,
}

/// The engine model running under a controller (the sequencer by default). It owns a clone of
/// its model (the maps are shared behind `Arc`s, so this is cheap).
pub struct Simulation<C: Controller = Sequencer> {
    model: Model,
    pub seq: C,
    ros: Ros2<NX>,
    fixed_step: Option<f64>,
    max_step: f64,
    h: f64,
    pub t: f64,
    pub y: State,
    t_amb_k: f64,
    p_amb_kpa: f64,
    pub stats: RunStats,
}

impl Simulation<Sequencer> {
    /// Starts at standstill at time 0 in the model's ambient, under the start-up sequencer.
    pub fn new(cfg: &EngineConfig, model: &Model, scenario: &Scenario) -> Simulation<Sequencer> {
        Simulation::with_controller(cfg, model, Sequencer::new(cfg, model, scenario))
    }
}

impl<C: Controller> Simulation<C> {
    /// Starts at standstill at time 0 in the model's ambient under `controller`.
    pub fn with_controller(cfg: &EngineConfig, model: &Model, controller: C) -> Simulation<C> {
        let c = &model.consts;
        let y = dynamic::standstill_state(model, c.t_amb_k, c.p_amb_kpa);
        let fixed = (cfg.solver.fixed_step_s > 0.0).then_some(cfg.solver.fixed_step_s);
        Simulation {
            model: model.clone(),
            seq: controller,
            ros: Ros2::new(cfg.solver.rtol, cfg.solver.rtol * 0.1),
            fixed_step: fixed,
            max_step: cfg.solver.max_step_s,
            h: fixed.unwrap_or(0.05),
            t: 0.0,
            y,
            t_amb_k: c.t_amb_k,
            p_amb_kpa: c.p_amb_kpa,
            stats: RunStats::default(),
        }
    }

    /// Station table at the current time.
    pub fn stations(&self) -> Stations {
        let drive = self.seq.drive(self.t_amb_k, self.p_amb_kpa);
        dynamic::evaluate(&self.model, self.t, &self.y, &drive).1
    }

    fn sequencer_update(&mut self) {
        let st = self.stations();
        if self.seq.update(self.t, &mut self.y, &st) {
            self.ros.invalidate();
        }
    }

    /// Integrates to exactly `t_target`, applying every sequencer event on the way.
    pub fn advance_to(&mut self, t_target: f64) -> Result<(), EngineError> {
        if self.t == 0.0 && self.stats.steps == 0 {
            self.sequencer_update();
        }
        while self.t < t_target - 1e-9 {
            let h_prop = match self.fixed_step {
                Some(fixed) => fixed.min(self.h),
                None => self.h,
            }
            .min(self.max_step);
            let mut h = h_prop.min(t_target - self.t);
            if let Some(te) = self.seq.next_time_event(self.t) {
                h = h.min(te - self.t);
            }
            // A step cut short by an output sample or an event says nothing about the step the
            // error allows: keep the proposal so the next step is not needlessly small.
            let limited = h < h_prop * 0.999;
            let drive = self.seq.drive(self.t_amb_k, self.p_amb_kpa);
            let model = &self.model;
            let mut f = |tt: f64, yy: &State| dynamic::evaluate(model, tt, yy, &drive).0;
            let Some(mut res) = self.ros.step(&mut f, self.t, &self.y, h) else {
                self.reject(h)?;
                continue;
            };
            // Adaptive mode rejects any step over the tolerance. Fixed-step mode keeps its step
            // unless the step is wildly wrong (ignition dumps ~2 MW into 0.2 kg of gas): then it
            // subdivides, so a fixed step can never run the states out of their physical range.
            let limit = if self.fixed_step.is_some() {
                FIXED_STEP_EMERGENCY_ERR
            } else {
                1.0
            };
            if res.err > limit || !plausible(&res.y) {
                self.reject(h * step_factor(res.err).min(0.25))?;
                continue;
            }
            // Locate a speed-threshold crossing inside the step and shorten the step to it.
            let mut crossed = false;
            if let Some(theta) = self.seq.first_crossing(&self.y, &res.y) {
                crossed = true;
                let h_ev = (h * theta * 1.000_001).max(1e-6);
                if h_ev < h * 0.999 {
                    if let Some(r2) = self.ros.step(&mut f, self.t, &self.y, h_ev) {
                        res = r2;
                        h = h_ev;
                    }
                }
            }
            self.t += h;
            self.y = res.y;
            self.stats.steps += 1;
            if self.fixed_step.is_none() {
                let grown = h * step_factor(res.err);
                let next = if limited && !crossed {
                    grown.max(h_prop)
                } else {
                    grown
                };
                self.h = next.clamp(1e-4, self.max_step);
            }
            let timed = self
                .seq
                .next_time_event(self.t - h)
                .is_some_and(|te| te <= self.t + 1e-9);
            if crossed || timed || self.seq.polls(self.t) {
                self.sequencer_update();
            }
        }
        self.t = t_target;
        self.stats.rhs_evals = self.ros.rhs_evals;
        self.stats.jacobians = self.ros.jac_evals;
        Ok(())
    }

    fn reject(&mut self, h_new: f64) -> Result<(), EngineError> {
        self.stats.rejected += 1;
        self.ros.invalidate();
        self.h = h_new;
        if h_new < 1e-7 {
            return Err(EngineError::Simulation {
                t_s: self.t,
                reason: format!("step size underflow in phase {}", self.seq.phase()),
            });
        }
        Ok(())
    }
}

/// Runs a scenario, sampling every `sample_period_s`; returns the true trajectory.
pub fn run_scenario(
    cfg: &EngineConfig,
    model: &Model,
    scenario: &Scenario,
) -> Result<(Vec<TruthSample>, RunStats), EngineError> {
    let dt = cfg.sequence.sample_period_s;
    let mut sim = Simulation::new(cfg, model, scenario);
    let mut out = Vec::new();
    let mut k: u64 = 0;
    loop {
        let t = k as f64 * dt;
        sim.advance_to(t)?;
        let st = sim.stations();
        out.push(TruthSample {
            t_s: t,
            phase: sim.seq.phase(),
            stations: st,
        });
        let done = match scenario.end {
            End::At(te) => t >= te - 1e-9,
            End::AfterSteady { hold_s, max_s } => {
                sim.seq
                    .steady_since
                    .is_some_and(|ts| t >= ts + hold_s - 1e-9)
                    || t >= max_s
            }
        };
        if done {
            break;
        }
        k += 1;
    }
    Ok((out, sim.stats))
}
