//! The simulation loop: the dynamic model integrated under a [`Controller`] (the start-up
//! sequencer, or a drive from measured data), landing exactly on timed events and output
//! samples and locating speed-threshold crossings by step refinement.
//!
//! The loop owns the state vector; a controller sees the engine through the station table and
//! acts on it only through an [`Actuator`] at its transitions. Pure and deterministic: no I/O,
//! no randomness.

use super::dynamic::{self, Drive, Scales, State, Stations};
use super::integrator::{step_factor, Ros2};
use super::model::{EngineError, Model};
use super::sequence::{End, Scenario, Sequencer};
use super::state::{Actuator, Shaft, IX_FAR, IX_P2, IX_P34, IX_T3};
use crate::signals::Phase;

/// Factor on the integrator's tolerance for the fuel-air-ratio state (see
/// [`Simulation::with_controller`]).
const FAR_TOLERANCE_FACTOR: f64 = 10.0;

/// Factor on the integrator's tolerance for the combustor-exit temperature (T3) and the
/// HPT-exit pressure (P34) volume states (see [`Simulation::with_controller`]).
const VOLUME_TOLERANCE_FACTOR: f64 = 3.0;

/// A speed threshold whose crossing is an event of the controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Watch {
    pub shaft: Shaft,
    pub rpm: f64,
    /// Crossing upward (else downward).
    pub rising: bool,
}

/// The discrete part of whatever drives the model: the start-up sequencer, or a drive from a
/// measured start-up. The simulation loop asks it for the drive of each step, integrates, and
/// lets it react at its events.
pub trait Controller {
    /// Drive for the next step.
    fn drive(&self, t_amb_k: f64, p_amb_kpa: f64) -> Drive;
    /// Earliest timed event strictly after `t`.
    fn next_time_event(&self, t: f64) -> Option<f64>;
    /// Speed thresholds whose crossing is an event in the current mode.
    fn watches(&self) -> Vec<Watch>;
    /// Applies the transitions due at `t` (station table `st`); acts on the engine through
    /// `act` (bumpless switches, grid lock). Returns what changed.
    fn update(&mut self, t: f64, act: &mut Actuator<'_>, st: &Stations) -> Change;
    /// Whether `update` must run after every step.
    fn polls(&self, t: f64) -> bool;
    /// Reported phase.
    fn phase(&self) -> Phase;
}

/// Error estimate above which a rejected step also refreshes the Jacobian (below it only the
/// step shrinks). Measured on the reference start-up: refreshing after every rejection took
/// 705 Jacobians and 447 rejections, this 532 and 327, at the same accuracy against a
/// tight-tolerance solution.
const STALE_JACOBIAN_ERR: f64 = 10.0;

/// Error level at which even fixed-step mode subdivides a step.
const FIXED_STEP_EMERGENCY_ERR: f64 = 50.0;

/// States within their physical range (normalised): positive pressures and temperature.
fn plausible(y: &State) -> bool {
    y[IX_P2] > 0.01 && y[IX_T3] > 0.1 && y[IX_P34] > 0.01 && y[IX_T3] < 2.0
}

/// One output sample: the true station table and the phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    pub t_s: f64,
    pub phase: Phase,
    pub stations: Stations,
}

/// How a run begins when the engine is not cold and still: shaft speeds and the temperature of
/// the hot section (gas and metal at rest).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartState {
    pub n1_rpm: f64,
    pub n2_rpm: f64,
    pub hot_section_k: f64,
}

/// What a controller's [`Controller::update`] changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Change {
    /// Nothing: the drive is the same function of time and state, the state untouched.
    None,
    /// Only the slope in time of a piecewise-linear input (a measured series entered its next
    /// segment): the drive is the same function of the state, so the integrator keeps its
    /// state Jacobian and re-estimates only ∂f/∂t.
    Slope,
    /// The drive (mode, switches, a command) or the state changed.
    Drive,
}

impl From<bool> for Change {
    /// `true`: something changed ([`Change::Drive`]); `false`: [`Change::None`].
    fn from(changed: bool) -> Change {
        if changed {
            Change::Drive
        } else {
            Change::None
        }
    }
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
    scales: Scales,
    ros: Ros2,
    fixed_step: Option<f64>,
    max_step: f64,
    h: f64,
    pub t: f64,
    pub y: State,
    t_amb_k: f64,
    p_amb_kpa: f64,
    pub stats: RunStats,
    /// The station table the controller's last update saw, when that update changed neither
    /// the drive nor the state and it was the last thing [`Simulation::advance_to`] did: the
    /// table at the current time and state, which [`Simulation::sample`] then need not
    /// evaluate again. Cleared at the start of every `advance_to`.
    settled: Option<Stations>,
    /// f at a point, evaluated with a station table there (the controller's update, or
    /// [`Simulation::sample`]) under a drive: the next step from that point under the same
    /// drive uses it instead of evaluating f again (one evaluation per output sample).
    seed: Option<Seed>,
}

/// f = `dy` at (`t`, `y`) under `drive`.
struct Seed {
    t: f64,
    y: State,
    dy: State,
    drive: Drive,
}

impl Simulation<Sequencer> {
    /// Starts at standstill at time 0 in the model's ambient, under the start-up sequencer.
    pub fn new(model: &Model, scenario: &Scenario) -> Simulation<Sequencer> {
        Simulation::with_controller(model, Sequencer::new(model, scenario))
    }
}

impl<C: Controller> Simulation<C> {
    /// Starts at standstill at time 0 in the model's ambient under `controller`.
    pub fn with_controller(model: &Model, controller: C) -> Simulation<C> {
        let cfg = model.cfg();
        let c = &model.consts;
        let y = dynamic::standstill_state(model, c.t_amb_k, c.p_amb_kpa);
        let fixed = (cfg.solver.fixed_step_s > 0.0).then_some(cfg.solver.fixed_step_s);
        let mut ros = Ros2::new(cfg.solver.rtol, cfg.solver.rtol * 0.1);
        // The combustor's fuel-air ratio relaxes in tens of milliseconds onto fuel/air flow and
        // enters the outputs only through the gas composition (R and cp move ~1e-5 for the
        // loosened error), yet at the common tolerance it set the step in two thirds of the
        // steps from light-off to loading. Held ten times more loosely, it no longer does.
        ros.loosen(IX_FAR, FAR_TOLERANCE_FACTOR);
        // T3 set the step in 1 000 of the start-up's 2 400 steps (light-off, acceleration, idle,
        // synchronisation), held at 6e-5 × 900 K = 0.05 K: a value no plant measures, reaching
        // the outputs through the HPT at a sixtieth of the T34 thermocouple's noise. P34, the
        // next, is measured at 0.25 % noise, 140 times its tolerance. Three times looser each:
        // 14 % fewer evaluations, every output still within 0.09 % of its range (the surge
        // margin 0.122 %) of an rtol-3e-8 solution. Not P2: the surge margin, a difference of
        // two nearly equal pressure ratios, moved by 0.7 % of its range at crank with P2 only
        // twice looser.
        ros.loosen(IX_T3, VOLUME_TOLERANCE_FACTOR);
        ros.loosen(IX_P34, VOLUME_TOLERANCE_FACTOR);
        Simulation {
            model: model.clone(),
            scales: Scales::of(model),
            seq: controller,
            ros,
            fixed_step: fixed,
            max_step: cfg.solver.max_step_s,
            h: fixed.unwrap_or(0.05),
            t: 0.0,
            y,
            t_amb_k: c.t_amb_k,
            p_amb_kpa: c.p_amb_kpa,
            stats: RunStats::default(),
            settled: None,
            seed: None,
        }
    }

    /// Starts from a turning, warm engine instead of a cold one at rest (a restart soon after a
    /// stop or a trip): the shafts at the given speeds, the hot section at `start.hot_section_k`.
    /// Call before the first [`Simulation::advance_to`].
    pub fn start_from(&mut self, start: &StartState) {
        self.y = dynamic::warm_standstill_state(
            &self.model,
            self.t_amb_k,
            self.p_amb_kpa,
            start.hot_section_k,
        );
        let mut act = Actuator::new(&mut self.y, &self.scales);
        act.set_speed_rpm(Shaft::Gg, start.n1_rpm);
        act.set_speed_rpm(Shaft::Pt, start.n2_rpm);
        self.ros.invalidate();
    }

    /// Station table at the current time.
    pub fn stations(&self) -> Stations {
        let drive = self.seq.drive(self.t_amb_k, self.p_amb_kpa);
        dynamic::evaluate(&self.model, self.t, &self.y, &drive).1
    }

    /// Advances to `t_target` ([`Simulation::advance_to`]) and returns the station table there
    /// (after the controller's transitions at that time, as [`Simulation::stations`] would).
    pub fn sample(&mut self, t_target: f64) -> Result<Stations, EngineError> {
        self.advance_to(t_target)?;
        if let Some(st) = self.settled.take() {
            return Ok(st);
        }
        let drive = self.seq.drive(self.t_amb_k, self.p_amb_kpa);
        let (dy, st) = dynamic::evaluate(&self.model, self.t, &self.y, &drive);
        self.seed = Some(Seed {
            t: self.t,
            y: self.y,
            dy,
            drive,
        });
        Ok(st)
    }

    fn sequencer_update(&mut self) {
        let drive = self.seq.drive(self.t_amb_k, self.p_amb_kpa);
        let (dy, st) = dynamic::evaluate(&self.model, self.t, &self.y, &drive);
        let mut act = Actuator::new(&mut self.y, &self.scales);
        let change = self.seq.update(self.t, &mut act, &st);
        match change {
            Change::Drive => self.ros.invalidate(),
            Change::Slope => {
                self.ros.forget_point();
                self.ros.refresh_time_derivative();
            }
            Change::None => self.ros.forget_point(),
        }
        self.settled = (change != Change::Drive).then_some(st);
        // Nothing the drive's function of (t, y) depends on changed: f here is known.
        self.seed = (change != Change::Drive).then_some(Seed {
            t: self.t,
            y: self.y,
            dy,
            drive,
        });
    }

    /// Fraction of the step (y0 → y1) at which the first watched threshold is crossed.
    fn first_crossing(&self, y0: &State, y1: &State) -> Option<f64> {
        self.seq
            .watches()
            .iter()
            .filter_map(|w| {
                let (i, level) = (w.shaft.index(), w.rpm / w.shaft.scale(&self.scales));
                let (a, b) = (y0[i] - level, y1[i] - level);
                let crossed = if w.rising {
                    a < 0.0 && b >= 0.0
                } else {
                    a > 0.0 && b <= 0.0
                };
                crossed.then(|| (a / (a - b)).clamp(0.0, 1.0))
            })
            .reduce(f64::min)
    }

    /// Integrates to exactly `t_target`, applying every sequencer event on the way.
    pub fn advance_to(&mut self, t_target: f64) -> Result<(), EngineError> {
        // The controller and the state are public: whatever the caller did between calls, no
        // value of f at a point is carried over from the last call.
        self.ros.forget_point();
        self.settled = None;
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
            if let Some(seed) = self.seed.take() {
                // The caller may have changed the controller or the state since: the seed is
                // used only where the point and the drive are exactly the same.
                if seed.t == self.t && seed.y == self.y && seed.drive.same_as(&drive) {
                    self.ros.seed_f0(self.t, &self.y, &seed.dy);
                }
            }
            let model = &self.model;
            // One memo per step: it holds the step's first evaluation (f at its start), whose
            // gas path the Jacobian's columns for the fuel integrator and for time share.
            let mut memo = dynamic::GasPathMemo::default();
            let mut f =
                |tt: f64, yy: &State| dynamic::derivatives(model, tt, yy, &drive, &mut memo);
            let Some(mut res) = self.ros.step(&mut f, self.t, &self.y, h) else {
                self.reject(h, true)?;
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
                // A step just over the tolerance asks for a shorter step, not a new Jacobian (a
                // W-method keeps its order with any); one far off, or out of range, may mean
                // the Jacobian no longer describes the fast states.
                let suspect = !plausible(&res.y) || res.err > STALE_JACOBIAN_ERR;
                self.reject(h * step_factor(res.err).min(0.25), suspect)?;
                continue;
            }
            // Locate a speed-threshold crossing inside the step and shorten the step to it.
            let mut crossed = false;
            if let Some(theta) = self.first_crossing(&self.y, &res.y) {
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
            self.settled = None;
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

    fn reject(&mut self, h_new: f64, suspect: bool) -> Result<(), EngineError> {
        self.stats.rejected += 1;
        // The retry starts from the same point with the same drive: the integrator refreshes
        // the Jacobian there unless it was just evaluated there, and reuses f there.
        if suspect {
            self.ros.rejected();
        }
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
    model: &Model,
    scenario: &Scenario,
) -> Result<(Vec<TruthSample>, RunStats), EngineError> {
    run_scenario_observed(model, scenario, |_| {})
}

/// [`run_scenario`], calling `observe` with each sample as it is produced: the caller can say
/// how far a long run has come (`gtwatch simulate` on a stiff engine integrates for minutes).
/// The samples and the result are those of [`run_scenario`].
pub fn run_scenario_observed(
    model: &Model,
    scenario: &Scenario,
    mut observe: impl FnMut(&TruthSample),
) -> Result<(Vec<TruthSample>, RunStats), EngineError> {
    let dt = model.cfg().sequence.sample_period_s;
    let mut sim = Simulation::new(model, scenario);
    let mut out = Vec::new();
    let mut k: u64 = 0;
    loop {
        let t = k as f64 * dt;
        let st = sim.sample(t)?;
        let sample = TruthSample {
            t_s: t,
            phase: sim.seq.phase(),
            stations: st,
        };
        observe(&sample);
        out.push(sample);
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
