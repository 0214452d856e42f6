//! A plant that fouls day by day: one start-up a day on the engine model, with the health of
//! each day's start taken from a [`FoulingSchedule`] (compressor fouling growing, a little
//! turbine wear, an offline wash that recovers most of the compressor fouling). This is the
//! plant `gtwatch demo` runs the daemon against, and the truth its results are compared with.
//!
//! Time is the plant's own (see `PlantModel::epoch_ms`): the start-up and the base-load hold
//! are sampled every second; the idle rest of each day, with the unit at standstill, every
//! `idle_step_s`, so a day costs a few thousand frames instead of 86 400 while every stored
//! sample is still a true reading at its plant time. Pure: no I/O, no clock.

use super::{PlantFrame, PlantModel};
use crate::engine::effects::EffectSet;
use crate::engine::plant::live_channels;
use crate::engine::sensors::OnlineChannel;
use crate::engine::trace::{values_of, Values, NSIG};
use crate::engine::{
    sequence::{Command, End, Event, Scenario},
    simulation::Simulation,
};
use crate::engine::{Engine, EngineError};
use crate::health::HealthParams;
use crate::signals::Phase;
use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::Arc;

/// Seconds in a plant day.
pub(crate) const DAY_S: f64 = 86_400.0;

/// The plant day (0-based) a time falls on, for a plant whose day 0 starts at `epoch_ms`;
/// `None` before it.
pub(crate) fn day_of(t_ms: i64, epoch_ms: i64) -> Option<usize> {
    let d = (t_ms - epoch_ms) as f64 / (DAY_S * 1000.0);
    (d >= 0.0).then(|| d.floor() as usize)
}

/// How the engine's health develops over the days of the demo.
#[derive(Debug, Clone, PartialEq)]
pub struct FoulingSchedule {
    /// Number of days (one start-up each).
    pub days: usize,
    /// Compressor fouling on day 0, D_GC points.
    pub initial_gc: f64,
    /// Growth of D_GC per day, points.
    pub gc_per_day: f64,
    /// D_EC as a fraction of D_GC (fouling costs flow capacity ≈ 3× efficiency).
    pub ec_ratio: f64,
    /// HP-turbine wear per day, points of D_GT and D_ET.
    pub gt_per_day: f64,
    pub et_per_day: f64,
    /// Day whose start-up is the first after an offline wash (`None`: no wash).
    pub wash_day: Option<usize>,
    /// Fraction of the compressor fouling an offline wash removes.
    pub wash_recovery: f64,
    /// Further offline washes every this many days after `wash_day` (`None`: only that one).
    pub wash_every: Option<usize>,
}

impl FoulingSchedule {
    /// The demo's schedule over `days` days: D_GC from 0.2 rising 0.25 points a day (faster in
    /// a short demo, so about 1.25 points have built up before the wash), D_EC a third of it,
    /// slight HP-turbine wear, and an offline wash before the middle day.
    pub fn demo(days: usize) -> FoulingSchedule {
        let wash_day = (days >= 3).then_some(days / 2);
        FoulingSchedule {
            days,
            initial_gc: 0.2,
            gc_per_day: wash_day.map_or(0.25, |w| (1.25 / w as f64).max(0.25)),
            ec_ratio: 1.0 / 3.0,
            gt_per_day: 0.03,
            et_per_day: 0.02,
            wash_day,
            wash_recovery: 0.9,
            wash_every: None,
        }
    }

    /// A schedule for runs of months or years (`bench month --days 365`): what a plant that
    /// washes its compressor every 30 days sees. D_GC from 0.2 rising 0.1 points a day (3
    /// points a month), D_EC a third of it, every wash removing 90 % of the fouling, and the
    /// HP turbine wearing 1.5 points of D_GT and 1 of D_ET a year. The demo's schedule, with
    /// one wash, would foul a year's compressor by 45 points: no engine runs like that.
    pub fn periodic(days: usize) -> FoulingSchedule {
        FoulingSchedule {
            days,
            initial_gc: 0.2,
            gc_per_day: 0.1,
            ec_ratio: 1.0 / 3.0,
            gt_per_day: 1.5 / 365.0,
            et_per_day: 1.0 / 365.0,
            wash_day: (days > 30).then_some(30),
            wash_recovery: 0.9,
            wash_every: Some(30),
        }
    }

    /// The wash days up to and including `day`, in order.
    fn washes_until(&self, day: usize) -> Vec<usize> {
        let Some(first) = self.wash_day.filter(|&w| w > 0 && w <= day) else {
            return Vec::new();
        };
        match self.wash_every.filter(|&p| p > 0) {
            None => vec![first],
            Some(p) => (first..=day).step_by(p).collect(),
        }
    }

    /// The true health on `day` (0-based).
    pub fn health_on(&self, day: usize) -> HealthParams {
        let d = day as f64;
        // Fouling just before each wash (after the previous day's start plus one day's
        // growth), of which `wash_recovery` is removed; growth then restarts from the residue.
        let (mut gc0, mut since) = (self.initial_gc, 0usize);
        for w in self.washes_until(day) {
            let before = gc0 + self.gc_per_day * (w - since) as f64;
            gc0 = before * (1.0 - self.wash_recovery);
            since = w;
        }
        let gc = gc0 + self.gc_per_day * (day - since) as f64;
        HealthParams {
            D_GC: gc,
            D_EC: gc * self.ec_ratio,
            D_GT: self.gt_per_day * d,
            D_ET: self.et_per_day * d,
            D_GP: 0.0,
            D_EP: 0.0,
        }
    }
}

/// Plant-time layout of one day, s from the day's start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DayTimes {
    /// Start command.
    pub start_s: f64,
    /// Normal stop command (after ~13 min of start-up and ~5 min at base load).
    pub stop_s: f64,
    /// End of the 1 s sampling (unit at standstill again).
    pub active_end_s: f64,
}

impl Default for DayTimes {
    fn default() -> Self {
        DayTimes {
            start_s: 120.0,
            stop_s: 120.0 + 1100.0,
            active_end_s: 120.0 + 1100.0 + 720.0,
        }
    }
}

/// The running day: the engine model through one start and stop.
struct Day {
    sim: Simulation,
    channels: Vec<OnlineChannel>,
    k: u64,
}

/// The fouling plant (see the module docs).
pub struct FoulingPlant {
    engine: Engine,
    schedule: FoulingSchedule,
    times: DayTimes,
    seed: u64,
    epoch_ms: i64,
    /// Sample period during the active part of a day, s.
    period_s: f64,
    /// Sample spacing while idle, s.
    idle_step_s: f64,
    day: usize,
    running: Option<Day>,
    /// Plant time of the last frame, s from the epoch.
    t_s: f64,
    /// Last true values (held, with fresh noise, while idle).
    idle_truth: Values,
    idle_channels: Vec<OnlineChannel>,
    failed: bool,
    /// Plant time of the last frame, Unix ms, for whoever watches progress.
    clock: Arc<AtomicI64>,
    /// An effect the plant carries on one day only (the day, the effects): a start-up the
    /// diagnosis' model does not describe (`gtwatch bench gap-month`).
    effects_on: Option<(usize, Arc<EffectSet>)>,
}

impl FoulingPlant {
    /// A plant of `engine` following `schedule`, its day 0 starting at `epoch_ms` (Unix ms).
    pub fn new(
        engine: &Engine,
        schedule: FoulingSchedule,
        seed: u64,
        epoch_ms: i64,
    ) -> Result<FoulingPlant, EngineError> {
        let period_s = 1.0;
        let idle_channels = live_channels(engine, period_s, seed ^ 0x1d1e);
        let mut plant = FoulingPlant {
            engine: engine.clone(),
            schedule,
            times: DayTimes::default(),
            seed,
            epoch_ms,
            period_s,
            idle_step_s: 120.0,
            day: 0,
            running: None,
            t_s: 0.0,
            idle_truth: [0.0; NSIG],
            idle_channels,
            failed: false,
            clock: Arc::new(AtomicI64::new(epoch_ms)),
            effects_on: None,
        };
        plant.running = Some(plant.start_day(0)?);
        if let Some(d) = &plant.running {
            plant.idle_truth = values_of(&d.sim.stations());
        }
        Ok(plant)
    }

    pub fn schedule(&self) -> &FoulingSchedule {
        &self.schedule
    }

    /// Samples the idle hours every `step_s` (default 120 s; 1 s gives a plain 1 Hz log).
    pub fn with_idle_step(mut self, step_s: f64) -> FoulingPlant {
        if step_s.is_finite() && step_s >= self.period_s {
            self.idle_step_s = step_s;
        }
        self
    }

    /// Runs day `day`'s start-up with `effects` on the plant's model (the other days without):
    /// one start-up with behaviour the diagnosis does not model. Day 0 is started by
    /// [`FoulingPlant::new`], before this can say anything: `day` must be 1 or later.
    pub fn with_effects_on_day(mut self, day: usize, effects: EffectSet) -> FoulingPlant {
        self.effects_on = Some((day, Arc::new(effects)));
        self
    }

    /// The plant clock (Unix ms of the last frame produced), shared for progress displays.
    pub fn clock(&self) -> Arc<AtomicI64> {
        Arc::clone(&self.clock)
    }

    pub fn times(&self) -> DayTimes {
        self.times
    }

    /// Plant time (Unix ms) of the start command of `day`.
    pub fn start_ms(&self, day: usize) -> i64 {
        self.epoch_ms + ((day as f64 * DAY_S + self.times.start_s) * 1000.0) as i64
    }

    fn start_day(&self, day: usize) -> Result<Day, EngineError> {
        let health = self.schedule.health_on(day);
        let mut model = self.engine.model(&health);
        if let Some((_, effects)) = self.effects_on.as_ref().filter(|(d, _)| *d == day) {
            model.effects = Arc::clone(effects);
        }
        let scenario = Scenario {
            events: vec![
                Event {
                    t_s: self.times.start_s,
                    command: Command::Start,
                },
                Event {
                    t_s: self.times.stop_s,
                    command: Command::Stop,
                },
            ],
            end: End::At(self.times.active_end_s),
        };
        let sim = Simulation::new(&model, &scenario);
        Ok(Day {
            sim,
            channels: live_channels(
                &self.engine,
                self.period_s,
                self.seed.wrapping_add(day as u64),
            ),
            k: 0,
        })
    }

    fn idle_frame(&mut self, t_s: f64) -> PlantFrame {
        let mut values = [0.0; NSIG];
        for (i, ch) in self.idle_channels.iter_mut().enumerate() {
            values[i] = ch.sample(self.idle_truth[i]);
        }
        PlantFrame {
            t_s,
            values,
            phase: Phase::Standstill,
        }
    }
}

impl PlantModel for FoulingPlant {
    fn step(&mut self) -> PlantFrame {
        let f = self.next_frame();
        self.clock.store(
            self.epoch_ms + (f.t_s * 1000.0).round() as i64,
            Ordering::Relaxed,
        );
        f
    }

    fn period_s(&self) -> f64 {
        self.period_s
    }

    fn epoch_ms(&self) -> Option<i64> {
        Some(self.epoch_ms)
    }
}

impl FoulingPlant {
    fn next_frame(&mut self) -> PlantFrame {
        let day_start = self.day as f64 * DAY_S;
        if let Some(day) = self.running.as_mut().filter(|_| !self.failed) {
            day.k += 1;
            let local = day.k as f64 * self.period_s;
            if local <= self.times.active_end_s {
                match day.sim.advance_to(local) {
                    Ok(()) => {
                        let truth = values_of(&day.sim.stations());
                        let mut values = [0.0; NSIG];
                        for (i, ch) in day.channels.iter_mut().enumerate() {
                            values[i] = ch.sample(truth[i]);
                        }
                        self.idle_truth = truth;
                        self.t_s = day_start + local;
                        return PlantFrame {
                            t_s: self.t_s,
                            values,
                            phase: day.sim.seq.phase(),
                        };
                    }
                    Err(e) => {
                        tracing::error!(day = self.day, "fouling plant stopped advancing: {e}");
                        self.failed = true;
                    }
                }
            }
            self.running = None;
        }
        // Idle: standstill samples until the next day's active part begins.
        let next = self.t_s + self.idle_step_s;
        let next_day_start = (self.day + 1) as f64 * DAY_S;
        if !self.failed && self.day + 1 < self.schedule.days && next >= next_day_start {
            self.day += 1;
            match self.start_day(self.day) {
                Ok(d) => {
                    self.running = Some(d);
                    return self.next_frame();
                }
                Err(e) => {
                    tracing::error!(day = self.day, "fouling plant cannot start the day: {e}");
                    self.failed = true;
                }
            }
        }
        self.t_s = next
            .min(next_day_start - self.period_s)
            .max(self.t_s + self.period_s);
        let t = self.t_s;
        self.idle_frame(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedule_fouls_and_the_wash_recovers_most_of_it() {
        let s = FoulingSchedule::demo(10);
        assert_eq!(s.wash_day, Some(5));
        let h4 = s.health_on(4);
        let h5 = s.health_on(5);
        assert!((h4.D_GC - (0.2 + 1.0)).abs() < 1e-12);
        assert!((h4.D_EC - h4.D_GC / 3.0).abs() < 1e-12);
        // Before the wash on day 5: 0.2 + 5 × 0.25 = 1.45; 90 % removed.
        assert!((h5.D_GC - 0.145).abs() < 1e-12, "{}", h5.D_GC);
        assert!((s.health_on(7).D_GC - (0.145 + 0.5)).abs() < 1e-12);
        // Turbine wear keeps growing through the wash.
        assert!(s.health_on(7).D_GT > h5.D_GT);
    }

    #[test]
    fn a_periodic_schedule_washes_every_thirty_days_and_stays_bounded() {
        let s = FoulingSchedule::periodic(365);
        // Day 29: 0.2 + 29 × 0.1; day 30, the first after a wash: (0.2 + 3.0) × 0.1.
        assert!((s.health_on(29).D_GC - 3.1).abs() < 1e-12);
        assert!((s.health_on(30).D_GC - 0.32).abs() < 1e-12);
        // Day 60, after the second wash: (0.32 + 3.0) × 0.1; day 61 one day's growth more.
        assert!((s.health_on(60).D_GC - 0.332).abs() < 1e-12);
        assert!((s.health_on(61).D_GC - 0.432).abs() < 1e-12);
        let worst = (0..365).map(|d| s.health_on(d).D_GC).fold(0.0, f64::max);
        assert!(worst < 3.5, "{worst}");
        assert!((s.health_on(364).D_GT - 1.5 * 364.0 / 365.0).abs() < 1e-12);
        // Only one wash without a period: the demo's.
        let one = FoulingSchedule::demo(10);
        assert_eq!(one.washes_until(9), vec![5]);
        assert_eq!(s.washes_until(95), vec![30, 60, 90]);
    }

    #[test]
    fn a_day_is_one_start_at_one_hertz_then_idle_frames_until_the_next() {
        let engine = Engine::reference().expect("engine");
        let mut p = FoulingPlant::new(&engine, FoulingSchedule::demo(2), 1, 0).expect("plant");
        let mut frames = Vec::new();
        loop {
            let f = p.step();
            let done = f.t_s > DAY_S + p.times().active_end_s;
            frames.push(f);
            if done {
                break;
            }
        }
        // Strictly increasing plant time; 1 s during the active part.
        assert!(frames.windows(2).all(|w| w[1].t_s > w[0].t_s));
        let active: Vec<&PlantFrame> = frames.iter().filter(|f| f.t_s <= 1940.0).collect();
        assert!(active
            .windows(2)
            .all(|w| (w[1].t_s - w[0].t_s - 1.0).abs() < 1e-9));
        // Both days reach steady load and come back to standstill.
        for day in 0..2 {
            let lo = day as f64 * DAY_S;
            let phases: Vec<Phase> = frames
                .iter()
                .filter(|f| f.t_s > lo && f.t_s < lo + DAY_S)
                .map(|f| f.phase)
                .collect();
            assert!(
                phases.contains(&Phase::Steady),
                "day {day}: no steady phase"
            );
            assert_eq!(phases.last(), Some(&Phase::Standstill), "day {day}");
        }
        // A day costs a few thousand frames, not 86 400.
        assert!(frames.len() < 5000, "{} frames", frames.len());
    }
}
