//! The start-up detector as a pure state machine: time-ordered frames in, segments out.
//!
//! No I/O, no clock, no globals: the same frames give the same segments, live or on replay.
//! Phase rules follow the daemon contract (see `DetectorConfig` for thresholds).
//! Must not read or write the database; `detect::scan` does that.

mod history;

use super::DetectorConfig;
use crate::segment::{AbortCause, Outcome, PhaseSpan, SegmentRecord};
use crate::signals::Phase;
use history::{line_fit, median, noise};

/// One aligned sample of the detector's inputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Unix epoch ms.
    pub t_ms: i64,
    /// Gas-generator speed, rpm.
    pub n1: f64,
    /// Fuel flow, kg/s.
    pub fuel: f64,
    /// Generator power, MW.
    pub power: f64,
    /// Power-turbine speed, rpm, if measured.
    pub n2: Option<f64>,
}

/// What the machine believes the engine is doing outside a start.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Idle {
    /// Not enough context yet (fresh machine, resume point in the middle of operation).
    Unknown,
    /// n1 at rest, fuel off.
    Standstill,
    /// Fuel on after a completed start (or found running on resume).
    Running,
    /// Fuel off, n1 coasting down; tracks the lowest n1 seen (a restart rises from there).
    Coast { min_n1: f64, min_ms: i64 },
}

/// A start in progress.
#[derive(Debug, Clone)]
struct Active {
    rec: SegmentRecord,
    phase: Phase,
    /// Crank: highest n1 (operator stop = n1 falls back). After ignition: highest n1 (flame-out).
    peak_n1: f64,
    peak_ms: i64,
    /// Fuel flow when `peak_n1` was seen (flame-out needs the fuel to have stayed up).
    peak_fuel: f64,
    /// Purge: speed level the starter holds.
    ignition_ms: Option<i64>,
    ignition_n1: f64,
    /// Fuel flow the light-off held before acceleration (the unit's lowest burning level).
    light_off_fuel: Option<f64>,
    /// The GG speed the starter held for the purge, when the purge was found as a plateau
    /// below the configured purge speed ([`PLATEAU_MS`]).
    purge_level: Option<f64>,
    /// Steady load found and the start-up held open while it lasts
    /// ([`DetectorConfig::steady_extend_s`]).
    settling: Option<Settling>,
}

/// A completed start-up held open while its load stays in the steady band, so that its
/// diagnosis sees the unit settle.
#[derive(Debug, Clone, Copy)]
struct Settling {
    /// The steady power level and band the hold was found with, MW.
    level: f64,
    band: f64,
    /// The start-up closes here at the latest (ms).
    until_ms: i64,
    /// The last frame whose power was in the band (ms): where it closes when the load moves.
    last_in_ms: i64,
    /// Consecutive frames outside the band (one is noise; two are the load moving).
    outside: u32,
}

/// Steady load as [`Machine::steady_start`] finds it.
#[derive(Debug, Clone, Copy)]
struct SteadyFound {
    start_ms: i64,
    level: f64,
    band: f64,
}

/// A GG speed held this long (within 0.5 %) during the crank is the purge, and during the
/// acceleration is idle, though below the speeds the detector was configured with (the engine
/// file's `[sequence]`, or `[detector]`): a unit's purge and idle speeds need not be the file's
/// to the percent — an engine file copied from another unit, an idle scheduled on corrected
/// speed — and a purge 3 % below the file's (the second independent simulator's unit, purge at
/// 2 230 rpm against md22's 2 300) ended every start as an operator stop during the crank.
const PLATEAU_MS: i64 = 10_000;

/// The lowest a held speed may be, as a fraction of the configured purge speed, to count as
/// the purge (a crank's starter that holds less is no purge the file describes).
const PURGE_PLATEAU_MIN_FRAC: f64 = 0.7;

/// The same for idle: a speed held below this fraction of the configured idle is a hung
/// start's stagnation, not idle, and stays acceleration.
const IDLE_PLATEAU_MIN_FRAC: f64 = 0.9;

/// How far back the fuel's trend is read before a cut, to tell a trip from a ramped stop.
const TREND_BEFORE_CUT_MS: i64 = 10_000;

/// A ramped stop's fuel is compared this far back to find where the ramp began.
const RAMP_LOOK_BACK_MS: i64 = 5_000;

/// Frames kept before a start, for finding its onset (at 1 Hz: 15 min).
const CONTEXT_FRAMES: usize = 900;

/// Weight of each new at-rest reading in the fuel meter's zero (an exponential average over
/// about ten readings; the first one sets it).
const FUEL_ZERO_GAIN: f64 = 0.1;

/// The state machine. Feed frames in time order with [`Machine::push`].
#[derive(Debug, Clone)]
pub struct Machine {
    cfg: DetectorConfig,
    /// Time of the last fuel-off seen (for the hot-restart rule), carried across restarts.
    last_fuel_off_ms: Option<i64>,
    finished: Vec<SegmentRecord>,
    idle: Idle,
    active: Option<Active>,
    /// Recent frames: the open segment and some context before it.
    hist: Vec<Frame>,
    /// The fuel meter's reading with the GG at rest and no start open, where no fuel can flow:
    /// its zero offset, taken off every reading before it is compared with `fuel_on_kg_s`
    /// (`None` until the GG has been seen at rest). A meter reading 0.02 kg/s at rest made
    /// every frame "fuel on" and no start was ever found.
    fuel_zero: Option<f64>,
}

impl Machine {
    /// A machine that knows nothing of the past except the last fuel-off time.
    pub fn new(cfg: DetectorConfig, last_fuel_off_ms: Option<i64>) -> Machine {
        Machine {
            cfg,
            last_fuel_off_ms,
            finished: Vec::new(),
            idle: Idle::Unknown,
            active: None,
            hist: Vec::new(),
            fuel_zero: None,
        }
    }

    /// The fuel meter's zero learned at rest (see the field), kg/s.
    pub fn fuel_zero_kg_s(&self) -> Option<f64> {
        self.fuel_zero
    }

    /// Feeds one frame. Frames not later than the previous one are ignored.
    pub fn push(&mut self, frame: Frame) {
        if !(frame.n1.is_finite() && frame.fuel.is_finite() && frame.power.is_finite()) {
            return;
        }
        let mut after_gap = false;
        if let Some(prev) = self.hist.last() {
            if frame.t_ms <= prev.t_ms {
                return;
            }
            let gap_ms = (self.cfg.max_sample_gap_s * 1000.0) as i64;
            if frame.t_ms - prev.t_ms > gap_ms {
                let from = prev.t_ms;
                self.note_gap(from, frame.t_ms);
                after_gap = true;
            }
        }
        if after_gap && self.active.is_none() {
            // What the unit did during the gap is unknown: the frames before it are no context
            // for an onset after it (a unit at load before the gap is not starting), and a fuel
            // cut somewhere in the gap has no time (it is no fuel-off for the hot-restart rule).
            self.hist.clear();
            self.idle = Idle::Unknown;
        }
        if self.active.is_none() && self.rest(&frame) {
            // At rest no fuel flows: the reading is the meter's zero. Learnt before the last
            // frame is judged too, so a zero first seen here is not taken for a fuel cut.
            let z = self
                .fuel_zero
                .map_or(frame.fuel, |z| z + FUEL_ZERO_GAIN * (frame.fuel - z));
            self.fuel_zero = Some(z);
        }
        let fuel_was_on = if after_gap {
            None
        } else {
            self.hist.last().map(|f| self.fuel_on(f))
        };
        self.hist.push(frame);
        let fuel_on = self.fuel_on(&frame);
        if fuel_was_on == Some(true) && !fuel_on {
            self.last_fuel_off_ms = Some(frame.t_ms);
        }
        if self.active.is_some() {
            self.step_active(frame, fuel_was_on == Some(true) && !fuel_on);
            self.close_if_overdue(frame);
        } else {
            self.step_idle(frame);
        }
        if self.active.is_none() && self.hist.len() > 2 * CONTEXT_FRAMES {
            let cut = self.hist.len() - CONTEXT_FRAMES;
            self.hist.drain(..cut);
        }
    }

    /// Closes a start-up still open `max_startup_s` after it began (aborted, cause `unknown`):
    /// a signal that froze mid-start (power stuck below the steady band) must not hold it open
    /// — and its history in memory — for ever.
    fn close_if_overdue(&mut self, f: Frame) {
        let max_ms = (self.cfg.max_startup_s * 1000.0) as i64;
        let overdue = self
            .active
            .as_ref()
            .is_some_and(|a| f.t_ms - a.rec.start_ms > max_ms);
        if overdue {
            if let Some(a) = self.active.take() {
                match a.settling {
                    // Steady load was reached: the start-up completed; only its hold ends.
                    Some(st) => self.complete(a, st.last_in_ms, &f),
                    None => self.finish_abort(a, AbortCause::Unknown, f.t_ms, f),
                }
            }
        }
    }

    /// Marks a data gap; the open segment, if any, gets `has_gap` — unless it is a completed
    /// start-up held open for its steady load, which closes at its last steady sample instead.
    pub fn note_gap(&mut self, _from_ms: i64, _to_ms: i64) {
        if let Some(a) = self.active.take() {
            if let Some(st) = a.settling {
                close_completed(&mut self.finished, a, st.last_in_ms);
                self.idle = Idle::Unknown;
                self.trim_history();
                return;
            }
            let mut a = a;
            a.rec.has_gap = true;
            self.active = Some(a);
        }
    }

    /// The input has ended (a replayed log, a file): a completed start-up still held open for its
    /// steady load ([`DetectorConfig::steady_extend_s`]) closes at its last steady sample. Any
    /// other open start stays open: its end is not in the data. Not for live data, which go on.
    pub fn end_of_input(&mut self) {
        let held = self.active.as_ref().and_then(|a| a.settling);
        let last = self.hist.last().copied();
        if let (Some(st), Some(f)) = (held, last) {
            if let Some(a) = self.active.take() {
                self.complete(a, st.last_in_ms, &f);
            }
        }
    }

    /// Segments closed since the last call.
    pub fn take_finished(&mut self) -> Vec<SegmentRecord> {
        std::mem::take(&mut self.finished)
    }

    /// The segment in progress, if any.
    pub fn open_segment(&self) -> Option<SegmentRecord> {
        self.active.as_ref().map(|a| a.rec.clone())
    }

    pub fn last_fuel_off_ms(&self) -> Option<i64> {
        self.last_fuel_off_ms
    }

    fn rest(&self, f: &Frame) -> bool {
        f.n1 <= self.cfg.rest_speed_rpm
    }

    /// Whether fuel flows at `f`: its reading above the threshold once the meter's zero is
    /// taken off.
    fn fuel_on(&self, f: &Frame) -> bool {
        f.fuel - self.fuel_zero.unwrap_or(0.0) > self.cfg.fuel_on_kg_s
    }

    fn step_idle(&mut self, f: Frame) {
        let c = &self.cfg;
        match self.idle {
            Idle::Unknown => {
                self.idle = if self.fuel_on(&f) {
                    if f.power > c.breaker_closed_mw {
                        Idle::Running
                    } else {
                        Idle::Unknown
                    }
                } else if self.rest(&f) {
                    Idle::Standstill
                } else {
                    Idle::Coast {
                        min_n1: f.n1,
                        min_ms: f.t_ms,
                    }
                };
            }
            Idle::Running => {
                if !self.fuel_on(&f) {
                    self.idle = Idle::Coast {
                        min_n1: f.n1,
                        min_ms: f.t_ms,
                    };
                }
            }
            Idle::Standstill => {
                if f.n1 > c.rest_speed_rpm {
                    // Onset: the last sample still at the rest level before the rise.
                    let base = self.level_before(f.t_ms, |x| x.n1);
                    let band = (0.005 * base.abs()).max(5.0);
                    let onset = self.knee_back(|x| x.n1, base, band);
                    self.begin(onset, false);
                } else if self.fuel_on(&f) {
                    self.idle = Idle::Unknown;
                }
            }
            Idle::Coast { min_n1, min_ms } => {
                if self.rest(&f) && !self.fuel_on(&f) {
                    self.idle = Idle::Standstill;
                } else if !self.fuel_on(&f) {
                    let rise = (0.02 * min_n1).max(50.0);
                    if f.n1 < min_n1 {
                        self.idle = Idle::Coast {
                            min_n1: f.n1,
                            min_ms: f.t_ms,
                        };
                    } else if f.n1 > min_n1 + rise {
                        // The starter re-engaged while the rotor was still turning.
                        self.begin(min_ms, true);
                    }
                } else if f.power > c.breaker_closed_mw {
                    self.idle = Idle::Running;
                } else {
                    self.idle = Idle::Unknown;
                }
            }
        }
    }

    fn begin(&mut self, start_ms: i64, rotor_turning: bool) {
        let window_ms = (self.cfg.hot_restart_window_s * 1000.0) as i64;
        let recent_fuel_off = self
            .last_fuel_off_ms
            .is_some_and(|off| off <= start_ms && start_ms - off <= window_ms);
        let n1_at_start = self.value_at(start_ms, |x| x.n1);
        let hot = rotor_turning || recent_fuel_off || n1_at_start > self.cfg.rest_speed_rpm;
        let mut a = Active {
            rec: SegmentRecord {
                start_ms,
                end_ms: None,
                outcome: Outcome::InProgress,
                abort_cause: None,
                hot_restart: hot,
                has_gap: false,
                phases: vec![PhaseSpan {
                    phase: Phase::Crank,
                    start_ms,
                    end_ms: None,
                }],
            },
            phase: Phase::Crank,
            peak_n1: f64::MIN,
            peak_ms: start_ms,
            peak_fuel: 0.0,
            ignition_ms: None,
            ignition_n1: 0.0,
            light_off_fuel: None,
            purge_level: None,
            settling: None,
        };
        // Catch up on the frames between the onset and now (they are already in `hist`).
        let start_idx = self.index_at_or_after(start_ms);
        let frames: Vec<Frame> = self.hist[start_idx..].to_vec();
        for f in &frames {
            if f.n1 > a.peak_n1 {
                a.peak_n1 = f.n1;
                a.peak_ms = f.t_ms;
            }
        }
        self.active = Some(a);
        // Let the phase rules see the catch-up frames (e.g. crank already past purge entry).
        if let Some(last) = frames.last().copied() {
            self.step_active(last, false);
        }
    }

    fn step_active(&mut self, f: Frame, fuel_just_off: bool) {
        let Some(mut a) = self.active.take() else {
            return;
        };
        let c = self.cfg.clone();
        let fuel_on = self.fuel_on(&f);

        if let Some(st) = a.settling {
            self.step_settling(a, st, f, fuel_on);
            return;
        }

        // Fuel cut during a fuelled phase: trip (abrupt) or operator stop (ramped).
        if fuel_just_off && a.ignition_ms.is_some() {
            let (abrupt, knee) = self.classify_fuel_cut(f.t_ms, a.light_off_fuel);
            let cause = if abrupt {
                AbortCause::Trip
            } else {
                AbortCause::OperatorStop
            };
            self.finish_abort(a, cause, knee, f);
            return;
        }
        // Flame-out: fuel present but the gas generator decays. A decay the control commanded
        // (the governor cut the fuel back, e.g. while synchronising the PT) is not one: when the
        // fuel has fallen below 80 % of its value at the speed peak, the peak restarts here.
        if a.ignition_ms.is_some() && fuel_on {
            if f.n1 > a.peak_n1 || f.fuel < 0.8 * a.peak_fuel {
                a.peak_n1 = f.n1;
                a.peak_ms = f.t_ms;
                a.peak_fuel = f.fuel;
            } else if f.n1 < a.peak_n1 - c.flame_out_drop_rpm {
                let at = a.peak_ms;
                self.finish_abort(a, AbortCause::FlameOut, at, f);
                return;
            }
        }

        match a.phase {
            Phase::Crank => {
                if f.n1 > a.peak_n1 {
                    a.peak_n1 = f.n1;
                    a.peak_ms = f.t_ms;
                }
                if f.n1 >= c.purge_entry_frac * c.purge_speed_rpm {
                    enter(&mut a, Phase::Purge, f.t_ms);
                } else if let Some((level, since)) = self
                    .n1_plateau(f.t_ms, PLATEAU_MS)
                    .filter(|(level, _)| *level >= PURGE_PLATEAU_MIN_FRAC * c.purge_speed_rpm)
                {
                    a.purge_level = Some(level);
                    enter(&mut a, Phase::Purge, since);
                } else if f.n1 < a.peak_n1 - (0.03 * a.peak_n1).max(50.0) {
                    let at = a.peak_ms;
                    self.finish_abort(a, AbortCause::OperatorStop, at, f);
                    return;
                }
            }
            Phase::Purge => {
                let purge = a.purge_level.unwrap_or(c.purge_speed_rpm);
                if f.n1 < purge * (1.0 - c.purge_band_frac) {
                    // Starter released: light-off starts where n1 left the purge level.
                    let start = a.rec.phases.last().map_or(f.t_ms, |p| p.start_ms);
                    let level = self.median_between(start, f.t_ms, |x| x.n1);
                    let band =
                        (0.002 * level).max(4.0 * self.noise_between(start, f.t_ms, |x| x.n1));
                    let knee = self.knee_back(|x| x.n1, level, band);
                    enter(&mut a, Phase::LightOff, knee.max(start));
                } else if fuel_on {
                    enter(&mut a, Phase::LightOff, f.t_ms);
                }
            }
            Phase::LightOff => {
                if a.ignition_ms.is_none() {
                    if fuel_on {
                        a.ignition_ms = Some(f.t_ms);
                        a.ignition_n1 = f.n1;
                        a.peak_n1 = f.n1;
                        a.peak_ms = f.t_ms;
                        a.peak_fuel = f.fuel;
                    } else if f.n1 < 0.85 * c.light_off_speed_rpm {
                        // No fuel came: the start was stopped; it ended when the starter let go.
                        let at = a.rec.phases.last().map_or(f.t_ms, |p| p.start_ms);
                        a.rec.phases.pop();
                        self.finish_abort(a, AbortCause::OperatorStop, at, f);
                        return;
                    }
                } else if let Some(ign) = a.ignition_ms {
                    if f.n1 < a.ignition_n1 - c.light_off_flame_out_drop_rpm {
                        self.finish_abort(a, AbortCause::FlameOut, ign, f);
                        return;
                    }
                    // Acceleration: fuel rises above the light-off hold level.
                    if f.t_ms > ign {
                        let hold = self.median_between(ign, f.t_ms - 1, |x| x.fuel);
                        if f.fuel > 1.1 * hold + c.fuel_on_kg_s {
                            let band = (0.02 * hold)
                                .max(4.0 * self.noise_between(ign, f.t_ms - 1, |x| x.fuel));
                            let knee = self.knee_back(|x| x.fuel, hold, band).max(ign);
                            a.light_off_fuel = Some(hold);
                            enter(&mut a, Phase::Acceleration, knee);
                        }
                    }
                }
            }
            Phase::Acceleration => {
                if f.n1 >= c.idle_entry_frac * c.idle_speed_rpm {
                    enter(&mut a, Phase::Idle, f.t_ms);
                } else if let Some((_, since)) = self
                    .n1_plateau(f.t_ms, PLATEAU_MS)
                    .filter(|(level, _)| *level >= IDLE_PLATEAU_MIN_FRAC * c.idle_speed_rpm)
                {
                    enter(&mut a, Phase::Idle, since);
                }
                if f.power > c.breaker_closed_mw {
                    enter(&mut a, Phase::Loading, f.t_ms);
                }
            }
            Phase::Idle => {
                let n2_in_band = f.n2.is_some_and(|n2| {
                    (n2 - c.pt_sync_speed_rpm).abs() <= c.sync_band_frac * c.pt_sync_speed_rpm
                });
                if f.power > c.breaker_closed_mw {
                    enter(&mut a, Phase::Loading, f.t_ms);
                } else if n2_in_band {
                    enter(&mut a, Phase::Synchronisation, f.t_ms);
                }
            }
            Phase::Synchronisation if f.power > c.breaker_closed_mw => {
                enter(&mut a, Phase::Loading, f.t_ms);
            }
            Phase::Loading => {
                if let Some(found) = self.steady_start(&a, f.t_ms) {
                    enter(&mut a, Phase::Steady, found.start_ms);
                    let extend_ms = (c.steady_extend_s * 1000.0) as i64;
                    if extend_ms > 0 {
                        a.settling = Some(Settling {
                            level: found.level,
                            band: found.band,
                            until_ms: f.t_ms + extend_ms,
                            last_in_ms: f.t_ms,
                            outside: 0,
                        });
                    } else {
                        self.complete(a, f.t_ms, &f);
                        return;
                    }
                }
            }
            _ => {}
        }
        self.active = Some(a);
    }

    /// A completed start-up held open for its steady load: it ends when the load moves (two
    /// frames outside the band), the fuel goes or the hold is over.
    fn step_settling(&mut self, mut a: Active, mut st: Settling, f: Frame, fuel_on: bool) {
        let inside = (f.power - st.level).abs() <= st.band;
        if inside {
            st.last_in_ms = f.t_ms;
            st.outside = 0;
        } else {
            st.outside += 1;
        }
        if !fuel_on || st.outside >= 2 || f.t_ms >= st.until_ms {
            self.complete(a, st.last_in_ms, &f);
        } else {
            a.settling = Some(st);
            self.active = Some(a);
        }
    }

    /// Closes `a` as a completed start-up ending at `end_ms`; `f` (the frame just seen) says
    /// what the engine does next.
    fn complete(&mut self, a: Active, end_ms: i64, f: &Frame) {
        close_completed(&mut self.finished, a, end_ms);
        self.idle = if self.fuel_on(f) {
            Idle::Running
        } else if self.rest(f) {
            Idle::Standstill
        } else {
            Idle::Coast {
                min_n1: f.n1,
                min_ms: f.t_ms,
            }
        };
        self.trim_history();
    }

    /// Start of steady load, once power has held within the band for `steady_hold_s`, with the
    /// level and band it held in.
    fn steady_start(&self, a: &Active, now_ms: i64) -> Option<SteadyFound> {
        let c = &self.cfg;
        let hold_ms = (c.steady_hold_s * 1000.0) as i64;
        let loading_start = a.rec.phases.last().map_or(now_ms, |p| p.start_ms);
        if now_ms - loading_start < hold_ms {
            return None;
        }
        let from = now_ms - hold_ms;
        let lo = self.index_at_or_after(from);
        let win = &self.hist[lo..];
        if win.len() < 3 {
            return None;
        }
        let level = median(win.iter().map(|x| x.power).collect());
        if level < c.steady_min_load_frac * c.base_load_mw {
            return None;
        }
        let sigma = noise(&win.iter().map(|x| x.power).collect::<Vec<_>>());
        let band = (c.steady_band_frac * level).max(4.0 * sigma);
        // Noise alone puts a ~4σ sample in a 60-sample window now and then: tolerate up to 2 %
        // of the window outside the band, and step over isolated outliers when walking back.
        let outside = |x: &Frame| (x.power - level).abs() > band;
        let n_out = win.iter().filter(|x| outside(x)).count();
        if n_out > win.len() / 50 {
            return None;
        }
        // Coarse start: first sample after the last two consecutive ones outside the band.
        let li = self.index_at_or_after(loading_start);
        let mut s = lo;
        while s > li {
            let out1 = outside(&self.hist[s - 1]);
            let out2 = s >= li + 2 && outside(&self.hist[s - 2]);
            if out1 && (out2 || s - 1 == li) {
                break;
            }
            s -= 1;
        }
        // Refine on the ramp before it: where a line through the ramp reaches the level.
        let mut ramp_lo = s;
        while ramp_lo > li
            && s - ramp_lo < 10
            && self.hist[ramp_lo - 1].power < self.hist[ramp_lo].power + 2.0 * sigma
        {
            ramp_lo -= 1;
        }
        let ramp: Vec<(f64, f64)> = self.hist[ramp_lo..s]
            .iter()
            .map(|x| (x.t_ms as f64, x.power))
            .collect();
        let mut start = self.hist[s].t_ms;
        if let Some((slope, icpt)) = line_fit(&ramp) {
            if slope > 0.0 && ramp.len() >= 3 {
                let t_knee = (level - icpt) / slope;
                // Nearest sample to the knee, within a few samples of the coarse start. With
                // noisy power the band is wide (4σ) and the coarse start can come early by the
                // time the ramp takes to cross it: the search reaches that far past it.
                let dt_ms = (ramp[ramp.len() - 1].0 - ramp[0].0) / (ramp.len() - 1) as f64;
                let crossing = (band / (slope * dt_ms)).ceil();
                let reach = if crossing.is_finite() {
                    (crossing as usize + 1).clamp(4, 12)
                } else {
                    4
                };
                let hi = (s + reach).min(self.hist.len());
                let cand = self.hist[s.saturating_sub(2).max(li)..hi]
                    .iter()
                    .min_by(|p, q| {
                        (p.t_ms as f64 - t_knee)
                            .abs()
                            .total_cmp(&(q.t_ms as f64 - t_knee).abs())
                    })
                    .map(|x| x.t_ms);
                if let Some(t) = cand {
                    start = t;
                }
            }
        }
        Some(SteadyFound {
            start_ms: start,
            level,
            band,
        })
    }

    /// Was the fuel that just went off cut abruptly? Also returns when the cut began.
    ///
    /// A trip closes the valve from wherever the fuel is; an operator's stop ramps it down to
    /// the unit's lowest burning level first. So a cut is abrupt when the fuel
    /// `trip_fuel_cut_s` before it was still at least half its recent peak, or, the fuel
    /// already falling (the PT governor pulls the gas generator back while synchronising), when
    /// the fall before could not have brought it down within that time — its trend over the
    /// 10 s before would have left at least half of it — and it was at least twice the level
    /// the light-off held (`light_off_fuel`, known once acceleration began).
    fn classify_fuel_cut(&self, now_ms: i64, light_off_fuel: Option<f64>) -> (bool, i64) {
        let c = &self.cfg;
        let cut_ms = (c.trip_fuel_cut_s * 1000.0) as i64;
        let before = self.value_at(now_ms - cut_ms, |x| x.fuel);
        let recent_max = self
            .hist
            .iter()
            .rev()
            .take_while(|x| x.t_ms >= now_ms - 60_000)
            .map(|x| x.fuel)
            .fold(0.0, f64::max);
        let earlier = self.value_at(now_ms - cut_ms - TREND_BEFORE_CUT_MS, |x| x.fuel);
        let fall_rate = ((earlier - before) / (TREND_BEFORE_CUT_MS as f64 / 1000.0)).max(0.0);
        let projected = before - fall_rate * c.trip_fuel_cut_s;
        let cut_off_a_trend =
            light_off_fuel.is_some_and(|hold| projected >= 0.5 * before && before >= 2.0 * hold);
        let abrupt = (before >= 0.5 * recent_max || cut_off_a_trend) && before > c.fuel_on_kg_s;
        if abrupt {
            // A trip ends the start at the first sample without fuel.
            return (true, now_ms);
        }
        // A ramped stop began where the fuel started to fall: walk back while the fuel a few
        // seconds earlier was higher. Compared over a few seconds rather than sample to sample,
        // so a slow ramp's fall per sample, within the meter's noise, still counts as falling.
        let tol = 0.01 * recent_max;
        let mut i = self.hist.len() - 1;
        while i > 0 {
            let t_back = self.hist[i].t_ms - RAMP_LOOK_BACK_MS;
            let j = self.hist.partition_point(|x| x.t_ms < t_back).min(i - 1);
            if self.hist[j].fuel > self.hist[i].fuel + tol {
                i -= 1;
            } else {
                break;
            }
        }
        (false, self.hist[i].t_ms)
    }

    fn finish_abort(&mut self, mut a: Active, cause: AbortCause, at_ms: i64, f: Frame) {
        let at = at_ms.max(a.rec.start_ms);
        // Phases that began after the abort point did not really happen.
        a.rec.phases.retain(|p| p.start_ms <= at);
        close(&mut a, at, Outcome::Aborted, Some(cause));
        self.finished.push(a.rec);
        self.idle = if self.rest(&f) && !self.fuel_on(&f) {
            Idle::Standstill
        } else if self.fuel_on(&f) {
            Idle::Unknown
        } else {
            Idle::Coast {
                min_n1: f.n1,
                min_ms: f.t_ms,
            }
        };
        self.trim_history();
    }
}

fn enter(a: &mut Active, phase: Phase, at_ms: i64) {
    if let Some(last) = a.rec.phases.last_mut() {
        let at = at_ms.max(last.start_ms);
        last.end_ms = Some(at);
        a.rec.phases.push(PhaseSpan {
            phase,
            start_ms: at,
            end_ms: None,
        });
    }
    a.phase = phase;
}

/// Closes `a` as completed at `end_ms` into `finished`.
fn close_completed(finished: &mut Vec<SegmentRecord>, mut a: Active, end_ms: i64) {
    close(&mut a, end_ms, Outcome::Completed, None);
    finished.push(a.rec);
}

fn close(a: &mut Active, at_ms: i64, outcome: Outcome, cause: Option<AbortCause>) {
    if let Some(last) = a.rec.phases.last_mut() {
        last.end_ms = Some(at_ms.max(last.start_ms));
    }
    a.rec.end_ms = Some(at_ms);
    a.rec.outcome = outcome;
    a.rec.abort_cause = cause;
}

#[cfg(test)]
pub(crate) mod tests;
