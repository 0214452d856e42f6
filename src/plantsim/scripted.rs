//! A deterministic scripted plant: piecewise-linear trajectories through the start-up phases of
//! the daemon contract (normal start, aborted start, hot restart, shutdown, trip), so the daemon
//! and its tests work without the engine model. Pure: no I/O, no clock.

use super::{PlantFrame, PlantModel};
use crate::signals::{Phase, Signal, NSIG};

/// Operating points of the scripted start (contract defaults; speeds rpm, fuel kg/s, power MW).
#[derive(Debug, Clone, PartialEq)]
pub struct ScriptLevels {
    pub purge_rpm: f64,
    pub light_off_rpm: f64,
    pub idle_rpm: f64,
    pub full_load_rpm: f64,
    pub pt_sync_rpm: f64,
    pub base_load_mw: f64,
    pub warmup_mw: f64,
    pub light_off_fuel: f64,
    pub idle_fuel: f64,
    pub full_load_fuel: f64,
}

impl Default for ScriptLevels {
    fn default() -> Self {
        ScriptLevels {
            purge_rpm: 2300.0,
            light_off_rpm: 1700.0,
            idle_rpm: 6800.0,
            full_load_rpm: 9500.0,
            pt_sync_rpm: 3600.0,
            base_load_mw: 31.4,
            warmup_mw: 3.0,
            light_off_fuel: 0.12,
            idle_fuel: 0.35,
            full_load_fuel: 1.75,
        }
    }
}

/// Durations of the scripted phases, s.
#[derive(Debug, Clone, PartialEq)]
pub struct ScriptTiming {
    /// Crank from rest to 98 % of purge speed.
    pub crank_s: f64,
    pub purge_s: f64,
    /// Starter released: coast from purge to light-off speed.
    pub coast_to_light_off_s: f64,
    /// Fuel on at the light-off flow before the acceleration schedule.
    pub light_off_hold_s: f64,
    pub acceleration_s: f64,
    /// GG settles at idle before the PT breaks away.
    pub idle_settle_s: f64,
    /// PT break-away up to 99 % of synchronous speed.
    pub pt_run_up_s: f64,
    pub synchronisation_s: f64,
    /// Breaker closed: ramp to the warm-up load.
    pub warmup_ramp_s: f64,
    pub warmup_s: f64,
    pub load_ramp_s: f64,
    pub unloading_s: f64,
    /// Fuel off: GG coast from idle to rest.
    pub coast_down_s: f64,
}

impl Default for ScriptTiming {
    fn default() -> Self {
        ScriptTiming {
            crank_s: 30.0,
            purge_s: 60.0,
            coast_to_light_off_s: 10.0,
            light_off_hold_s: 5.0,
            acceleration_s: 40.0,
            idle_settle_s: 5.0,
            pt_run_up_s: 30.0,
            synchronisation_s: 15.0,
            warmup_ramp_s: 10.0,
            warmup_s: 240.0,
            load_ramp_s: 150.0,
            unloading_s: 120.0,
            coast_down_s: 90.0,
        }
    }
}

impl ScriptTiming {
    /// Every duration divided by `factor` (for quick tests).
    pub fn compressed(factor: f64) -> Self {
        let d = ScriptTiming::default();
        ScriptTiming {
            crank_s: d.crank_s / factor,
            purge_s: d.purge_s / factor,
            coast_to_light_off_s: d.coast_to_light_off_s / factor,
            light_off_hold_s: d.light_off_hold_s / factor,
            acceleration_s: d.acceleration_s / factor,
            idle_settle_s: d.idle_settle_s / factor,
            pt_run_up_s: d.pt_run_up_s / factor,
            synchronisation_s: d.synchronisation_s / factor,
            warmup_ramp_s: d.warmup_ramp_s / factor,
            warmup_s: d.warmup_s / factor,
            load_ramp_s: d.load_ramp_s / factor,
            unloading_s: d.unloading_s / factor,
            coast_down_s: d.coast_down_s / factor,
        }
    }
}

/// One step of a plant schedule.
#[derive(Debug, Clone, PartialEq)]
pub enum ScriptStep {
    /// At rest (n1 coasts to 0 first if still turning).
    Standstill { duration_s: f64 },
    /// A full start from the current state to steady base load. Begun while n1 is still
    /// turning (after `Shutdown { coast_to_rpm > 0 }`), it is a hot restart.
    Start,
    /// A start that trips (fuel cut abruptly) `after_s` into the given phase, then coasts to rest.
    AbortedStart { trip_in: Phase, after_s: f64 },
    /// Constant load.
    Steady { duration_s: f64 },
    /// Unload, open the breaker, cut fuel and coast down to `coast_to_rpm` (0 = to rest).
    Shutdown { coast_to_rpm: f64 },
    /// Fuel cut abruptly from load, coast to rest.
    Trip,
}

/// State the piecewise-linear trajectories interpolate between.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Operating {
    n1: f64,
    n2: f64,
    fuel: f64,
    power: f64,
}

/// One linear piece: the state moves from the previous leg's end to `end` over `duration_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Leg {
    phase: Phase,
    duration_s: f64,
    end: Operating,
}

/// A deterministic scripted plant (see the module docs). Time `t` belongs to the leg whose
/// half-open interval `[start, end)` contains it, so the first frame of a phase already
/// satisfies that phase's entry condition from the contract (e.g. the first purge frame has
/// n1 ≥ 98 % of purge speed).
#[derive(Debug, Clone)]
pub struct ScriptedPlant {
    legs: Vec<Leg>,
    /// Leg start times, s.
    starts: Vec<f64>,
    total_s: f64,
    period_s: f64,
    looping: bool,
    k: u64,
    ambient_t_k: f64,
    ambient_p_kpa: f64,
    levels: ScriptLevels,
}

impl ScriptedPlant {
    /// Builds the plant from a schedule; `period_s` is the sample period. With `looping`, the
    /// schedule repeats forever (it should then end at rest); otherwise the last state holds.
    pub fn new(
        schedule: &[ScriptStep],
        timing: &ScriptTiming,
        levels: ScriptLevels,
        period_s: f64,
        looping: bool,
    ) -> Self {
        let legs = build_legs(schedule, timing, &levels);
        let mut starts = Vec::with_capacity(legs.len());
        let mut t = 0.0;
        for l in &legs {
            starts.push(t);
            t += l.duration_s;
        }
        ScriptedPlant {
            legs,
            starts,
            total_s: t,
            period_s,
            looping,
            k: 0,
            ambient_t_k: 288.15,
            ambient_p_kpa: 101.325,
            levels,
        }
    }

    /// The commissioning demo: cold start, steady, shutdown; an aborted start (trip during
    /// acceleration); a start followed by a shutdown that is restarted hot before the GG has
    /// stopped; a trip from load. Repeats forever.
    pub fn demo(period_s: f64) -> Self {
        Self::new(
            &demo_schedule(),
            &ScriptTiming::default(),
            ScriptLevels::default(),
            period_s,
            true,
        )
    }

    /// Total schedule length, s.
    pub fn duration_s(&self) -> f64 {
        self.total_s
    }

    /// The plant's frame at time `t_s` (pure: does not advance the plant).
    pub fn frame_at(&self, t_s: f64) -> PlantFrame {
        let tt = if self.looping && self.total_s > 0.0 {
            t_s.rem_euclid(self.total_s)
        } else {
            t_s
        };
        let idx = match self.starts.partition_point(|&s| s <= tt) {
            0 => 0,
            i => i - 1,
        };
        let (phase, op) = match self.legs.get(idx) {
            None => (Phase::Standstill, REST),
            Some(leg) => {
                let from = if idx == 0 {
                    REST
                } else {
                    self.legs[idx - 1].end
                };
                let x = if leg.duration_s > 0.0 {
                    ((tt - self.starts[idx]) / leg.duration_s).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                (leg.phase, lerp(from, leg.end, x))
            }
        };
        PlantFrame {
            t_s,
            values: self.measurements(op),
            phase,
        }
    }

    /// Plausible gas-path values from the scripted operating state. Not physics: simple
    /// monotone relations so that every channel moves with the start-up the way a plant's does.
    fn measurements(&self, op: Operating) -> [f64; NSIG] {
        let (t1, p1) = (self.ambient_t_k, self.ambient_p_kpa);
        let r = (op.n1 / self.levels.full_load_rpm).max(0.0);
        let pr = 1.0 + 23.1 * r.powf(2.2);
        let p2 = 0.99 * p1 * pr;
        let t2 = t1 * (1.0 + (pr.powf(0.2857) - 1.0) / 0.85);
        let air = 83.0 * r.powf(1.5) + 0.5;
        let far = op.fuel / air;
        let t3 = t2 + far * 50.0e6 * 0.995 / 1250.0;
        let p3 = 0.96 * p2;
        let t34 = t3 - (t3 - t2) * 0.35 * r;
        let p34 = p1 * (1.0 + 3.2 * r * r);
        let t4 = t34 - (t34 - t1) * 0.3 * (op.n2 / self.levels.pt_sync_rpm).clamp(0.0, 1.0);
        let p4 = 1.03 * p1;
        let mut v = [0.0; NSIG];
        v[Signal::N1.index()] = op.n1;
        v[Signal::N2.index()] = op.n2;
        v[Signal::T1.index()] = t1;
        v[Signal::P1.index()] = p1;
        v[Signal::T2.index()] = t2;
        v[Signal::P2.index()] = p2;
        v[Signal::T3.index()] = t3;
        v[Signal::P3.index()] = p3;
        v[Signal::T34.index()] = t34;
        v[Signal::P34.index()] = p34;
        v[Signal::T4.index()] = t4;
        v[Signal::P4.index()] = p4;
        v[Signal::FuelFlow.index()] = op.fuel;
        v[Signal::Power.index()] = op.power;
        v[Signal::SurgeMargin.index()] = 20.0;
        v
    }
}

impl PlantModel for ScriptedPlant {
    fn step(&mut self) -> PlantFrame {
        self.k += 1;
        self.frame_at(self.k as f64 * self.period_s)
    }
    fn period_s(&self) -> f64 {
        self.period_s
    }
}

const REST: Operating = Operating {
    n1: 0.0,
    n2: 0.0,
    fuel: 0.0,
    power: 0.0,
};

fn lerp(a: Operating, b: Operating, x: f64) -> Operating {
    let f = |p: f64, q: f64| p + (q - p) * x;
    Operating {
        n1: f(a.n1, b.n1),
        n2: f(a.n2, b.n2),
        fuel: f(a.fuel, b.fuel),
        power: f(a.power, b.power),
    }
}

/// The commissioning demo schedule (see [`ScriptedPlant::demo`]).
pub fn demo_schedule() -> Vec<ScriptStep> {
    vec![
        ScriptStep::Standstill { duration_s: 120.0 },
        ScriptStep::Start,
        ScriptStep::Steady { duration_s: 600.0 },
        ScriptStep::Shutdown { coast_to_rpm: 0.0 },
        ScriptStep::Standstill { duration_s: 2400.0 },
        ScriptStep::AbortedStart {
            trip_in: Phase::Acceleration,
            after_s: 20.0,
        },
        ScriptStep::Standstill { duration_s: 2400.0 },
        ScriptStep::Start,
        ScriptStep::Steady { duration_s: 300.0 },
        ScriptStep::Shutdown {
            coast_to_rpm: 900.0,
        },
        ScriptStep::Start,
        ScriptStep::Steady { duration_s: 900.0 },
        ScriptStep::Trip,
        ScriptStep::Standstill { duration_s: 2400.0 },
    ]
}

/// Expands a schedule into linear legs.
fn build_legs(schedule: &[ScriptStep], tm: &ScriptTiming, lv: &ScriptLevels) -> Vec<Leg> {
    let mut legs: Vec<Leg> = Vec::new();
    let mut cur = REST;
    let push = |legs: &mut Vec<Leg>, cur: &mut Operating, phase, duration_s: f64, end| {
        legs.push(Leg {
            phase,
            duration_s: duration_s.max(0.0),
            end,
        });
        *cur = end;
    };
    // Fuel and n1 on the loading line as a function of power.
    let loaded = |power: f64| {
        let x = (power / lv.base_load_mw).clamp(0.0, 1.0);
        Operating {
            n1: lv.idle_rpm + (lv.full_load_rpm - lv.idle_rpm) * x.powf(0.7),
            n2: lv.pt_sync_rpm,
            fuel: lv.idle_fuel + (lv.full_load_fuel - lv.idle_fuel) * x,
            power,
        }
    };
    // Fuel cut (a step: zero-length leg, so the first frame of `phase` has no fuel and the
    // breaker open) then coast of the GG (and PT) to `to_rpm`, taking a time proportional to
    // the speed lost relative to a full coast from idle.
    let cut_and_coast = |legs: &mut Vec<Leg>, cur: &mut Operating, phase: Phase, to_rpm: f64| {
        let from = *cur;
        let cut = Operating {
            fuel: 0.0,
            power: 0.0,
            ..from
        };
        push(legs, cur, phase, 0.0, cut);
        let frac = ((from.n1 - to_rpm) / lv.idle_rpm).clamp(0.0, 1.5);
        let end = Operating {
            n1: to_rpm,
            n2: if to_rpm > 0.0 { from.n2 * 0.3 } else { 0.0 },
            fuel: 0.0,
            power: 0.0,
        };
        push(legs, cur, phase, tm.coast_down_s * frac, end);
    };
    for step in schedule {
        match step {
            ScriptStep::Standstill { duration_s } => {
                if cur.n1 > 0.0 || cur.n2 > 0.0 {
                    let ph = legs.last().map_or(Phase::Shutdown, |l| l.phase);
                    cut_and_coast(&mut legs, &mut cur, ph, 0.0);
                }
                push(&mut legs, &mut cur, Phase::Standstill, *duration_s, REST);
            }
            ScriptStep::Start | ScriptStep::AbortedStart { .. } => {
                let trip = match step {
                    ScriptStep::AbortedStart { trip_in, after_s } => Some((*trip_in, *after_s)),
                    _ => None,
                };
                let start_legs = start_legs(cur, tm, lv, &loaded);
                for leg in start_legs {
                    if let Some((trip_in, after_s)) = trip {
                        if leg.phase == trip_in && after_s < leg.duration_s {
                            let x = after_s / leg.duration_s;
                            let at = lerp(cur, leg.end, x);
                            push(&mut legs, &mut cur, leg.phase, after_s, at);
                            cut_and_coast(&mut legs, &mut cur, Phase::Trip, 0.0);
                            break;
                        }
                    }
                    push(&mut legs, &mut cur, leg.phase, leg.duration_s, leg.end);
                }
            }
            ScriptStep::Steady { duration_s } => {
                let hold = cur;
                push(&mut legs, &mut cur, Phase::Steady, *duration_s, hold);
            }
            ScriptStep::Shutdown { coast_to_rpm } => {
                let idle = Operating {
                    n1: lv.idle_rpm,
                    n2: lv.pt_sync_rpm,
                    fuel: lv.idle_fuel,
                    power: 0.0,
                };
                push(&mut legs, &mut cur, Phase::Unloading, tm.unloading_s, idle);
                cut_and_coast(&mut legs, &mut cur, Phase::Shutdown, *coast_to_rpm);
            }
            ScriptStep::Trip => {
                cut_and_coast(&mut legs, &mut cur, Phase::Trip, 0.0);
            }
        }
    }
    legs
}

/// The legs of a normal start from `from` (rest or a slow roll) to the first steady frame.
fn start_legs(
    from: Operating,
    tm: &ScriptTiming,
    lv: &ScriptLevels,
    loaded: &dyn Fn(f64) -> Operating,
) -> Vec<Leg> {
    let op = |n1: f64, n2: f64, fuel: f64, power: f64| Operating {
        n1,
        n2,
        fuel,
        power,
    };
    let crank_end = 0.98 * lv.purge_rpm;
    // Crank duration scales with the speed still to gain (a slow roll cranks faster).
    let crank_frac = ((crank_end - from.n1) / crank_end).clamp(0.05, 1.0);
    let lo_fuel = lv.light_off_fuel;
    let accel_end = 0.99 * lv.idle_rpm;
    let sync_n2 = 0.99 * lv.pt_sync_rpm;
    // The breaker closes between two frames: the first loading frame already carries 0.6 MW.
    let first_load = 0.6;
    vec![
        Leg {
            phase: Phase::Crank,
            duration_s: tm.crank_s * crank_frac,
            end: op(crank_end, 0.0, 0.0, 0.0),
        },
        // The starter governor settles at purge speed and holds it (the last few rpm of the
        // crank are taken between two frames).
        Leg {
            phase: Phase::Purge,
            duration_s: 0.0,
            end: op(lv.purge_rpm, 0.0, 0.0, 0.0),
        },
        Leg {
            phase: Phase::Purge,
            duration_s: tm.purge_s,
            end: op(lv.purge_rpm, 0.0, 0.0, 0.0),
        },
        // Starter released: coast down to light-off speed with no fuel…
        Leg {
            phase: Phase::LightOff,
            duration_s: tm.coast_to_light_off_s,
            end: op(lv.light_off_rpm, 0.0, 0.0, 0.0),
        },
        // …then fuel and ignition on (a step) and held.
        Leg {
            phase: Phase::LightOff,
            duration_s: 0.0,
            end: op(lv.light_off_rpm, 0.0, lo_fuel, 0.0),
        },
        Leg {
            phase: Phase::LightOff,
            duration_s: tm.light_off_hold_s,
            end: op(lv.light_off_rpm, 0.0, lo_fuel, 0.0),
        },
        Leg {
            phase: Phase::Acceleration,
            duration_s: tm.acceleration_s,
            end: op(accel_end, 0.0, lv.idle_fuel * 1.3, 0.0),
        },
        Leg {
            phase: Phase::Idle,
            duration_s: tm.idle_settle_s,
            end: op(lv.idle_rpm, 0.0, lv.idle_fuel, 0.0),
        },
        Leg {
            phase: Phase::Idle,
            duration_s: tm.pt_run_up_s,
            end: op(lv.idle_rpm, sync_n2, lv.idle_fuel, 0.0),
        },
        Leg {
            phase: Phase::Synchronisation,
            duration_s: tm.synchronisation_s,
            end: op(lv.idle_rpm, lv.pt_sync_rpm, lv.idle_fuel, 0.0),
        },
        Leg {
            phase: Phase::Loading,
            duration_s: 0.0,
            end: loaded(first_load),
        },
        Leg {
            phase: Phase::Loading,
            duration_s: tm.warmup_ramp_s,
            end: loaded(lv.warmup_mw),
        },
        Leg {
            phase: Phase::Loading,
            duration_s: tm.warmup_s,
            end: loaded(lv.warmup_mw),
        },
        Leg {
            phase: Phase::Loading,
            duration_s: tm.load_ramp_s,
            end: loaded(lv.base_load_mw),
        },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quick_plant(schedule: &[ScriptStep]) -> ScriptedPlant {
        ScriptedPlant::new(
            schedule,
            &ScriptTiming::compressed(5.0),
            ScriptLevels::default(),
            0.5,
            false,
        )
    }

    fn run(p: &mut ScriptedPlant) -> Vec<PlantFrame> {
        let n = (p.duration_s() / p.period_s()).ceil() as usize;
        (0..n).map(|_| p.step()).collect()
    }

    /// Phase sequence without repeats.
    fn phases(frames: &[PlantFrame]) -> Vec<Phase> {
        let mut v: Vec<Phase> = Vec::new();
        for f in frames {
            if v.last() != Some(&f.phase) {
                v.push(f.phase);
            }
        }
        v
    }

    #[test]
    fn normal_start_follows_the_contract_phases_and_entry_conditions() {
        use Phase::*;
        let mut p = quick_plant(&[
            ScriptStep::Standstill { duration_s: 10.0 },
            ScriptStep::Start,
            ScriptStep::Steady { duration_s: 20.0 },
            ScriptStep::Shutdown { coast_to_rpm: 0.0 },
            ScriptStep::Standstill { duration_s: 10.0 },
        ]);
        let fr = run(&mut p);
        assert_eq!(
            phases(&fr),
            vec![
                Standstill,
                Crank,
                Purge,
                LightOff,
                Acceleration,
                Idle,
                Synchronisation,
                Loading,
                Steady,
                Unloading,
                Shutdown,
                Standstill
            ]
        );
        let lv = ScriptLevels::default();
        for w in fr.windows(2) {
            let (a, b) = (&w[0], &w[1]);
            let n1 = b.get(Signal::N1);
            match b.phase {
                Standstill => assert!(n1 == 0.0 && b.get(Signal::FuelFlow) == 0.0),
                Purge => {
                    assert!((n1 - lv.purge_rpm).abs() <= 0.02 * lv.purge_rpm);
                    assert_eq!(b.get(Signal::FuelFlow), 0.0);
                }
                Crank => assert!(n1 < 0.98 * lv.purge_rpm),
                Acceleration => assert!(n1 < 0.99 * lv.idle_rpm && b.get(Signal::FuelFlow) > 0.0),
                Idle => assert!(n1 >= 0.99 * lv.idle_rpm && b.get(Signal::N2) < 0.99 * 3600.0),
                Synchronisation => {
                    assert!(b.get(Signal::N2) >= 0.99 * 3600.0);
                    assert!(b.get(Signal::Power) <= 0.5);
                }
                Loading => assert!(b.get(Signal::Power) > 0.5),
                Steady => assert_eq!(b.get(Signal::Power), lv.base_load_mw),
                Shutdown => assert_eq!(b.get(Signal::FuelFlow), 0.0),
                _ => {}
            }
            // Entry into acceleration: fuel has started rising from the light-off flow.
            if a.phase == LightOff && b.phase == Acceleration {
                assert!(a.get(Signal::FuelFlow) > 0.0);
                assert!(b.get(Signal::FuelFlow) >= a.get(Signal::FuelFlow));
            }
        }
        // Gas-path values are finite and move with speed.
        let steady = fr.iter().find(|f| f.phase == Steady).expect("steady");
        assert!((steady.get(Signal::P2) / steady.get(Signal::P1) - 23.86).abs() < 0.1);
        assert!(fr.iter().all(|f| f.values.iter().all(|v| v.is_finite())));
    }

    #[test]
    fn aborted_start_trips_with_an_abrupt_fuel_cut() {
        let mut p = quick_plant(&[
            ScriptStep::Standstill { duration_s: 5.0 },
            ScriptStep::AbortedStart {
                trip_in: Phase::Acceleration,
                after_s: 4.0,
            },
            ScriptStep::Standstill { duration_s: 5.0 },
        ]);
        let fr = run(&mut p);
        use Phase::*;
        assert_eq!(
            phases(&fr),
            vec![
                Standstill,
                Crank,
                Purge,
                LightOff,
                Acceleration,
                Trip,
                Standstill
            ]
        );
        let i = fr.iter().position(|f| f.phase == Trip).expect("trip");
        assert!(fr[i - 1].get(Signal::FuelFlow) > 0.1);
        assert_eq!(fr[i].get(Signal::FuelFlow), 0.0);
        assert!(fr[i].get(Signal::N1) > 2000.0);
    }

    #[test]
    fn hot_restart_cranks_from_a_slow_roll() {
        let mut p = quick_plant(&[
            ScriptStep::Start,
            ScriptStep::Steady { duration_s: 5.0 },
            ScriptStep::Shutdown {
                coast_to_rpm: 900.0,
            },
            ScriptStep::Start,
            ScriptStep::Steady { duration_s: 5.0 },
        ]);
        let fr = run(&mut p);
        let second_crank = fr
            .windows(2)
            .filter(|w| w[0].phase == Phase::Shutdown && w[1].phase == Phase::Crank)
            .map(|w| w[1].get(Signal::N1))
            .collect::<Vec<_>>();
        assert_eq!(second_crank.len(), 1);
        assert!(second_crank[0] > 850.0, "{second_crank:?}");
    }

    #[test]
    fn demo_loops_and_is_deterministic() {
        let a = ScriptedPlant::demo(1.0);
        let b = ScriptedPlant::demo(1.0);
        let t = a.duration_s();
        assert_eq!(a.frame_at(1234.0), b.frame_at(1234.0));
        assert_eq!(a.frame_at(500.0).values, a.frame_at(500.0 + t).values);
    }
}
