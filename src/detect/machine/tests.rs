//! Synthetic start-ups that follow the contract's phase definitions, at 1 Hz, with sensor
//! noise (speeds 0.05 %, fuel 0.5 %, power 0.5 %, 1 sigma). Truth boundaries are computed
//! from the noise-free trajectories by the contract's rules.

use super::*;
use crate::signals::Phase;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Piecewise-linear function through (t_s, value) points; constant outside.
#[derive(Clone)]
pub(crate) struct Pl(pub Vec<(f64, f64)>);

impl Pl {
    pub(crate) fn at(&self, t: f64) -> f64 {
        let p = &self.0;
        if t <= p[0].0 {
            return p[0].1;
        }
        for w in p.windows(2) {
            let ((t0, v0), (t1, v1)) = (w[0], w[1]);
            if t <= t1 {
                return if t1 > t0 {
                    v0 + (v1 - v0) * (t - t0) / (t1 - t0)
                } else {
                    v1
                };
            }
        }
        p[p.len() - 1].1
    }
}

/// A scripted trace: n1, fuel, power, n2 as functions of time (s).
#[derive(Clone)]
pub(crate) struct Script {
    pub(crate) n1: Pl,
    pub(crate) fuel: Pl,
    pub(crate) power: Pl,
    pub(crate) n2: Pl,
}

/// Times (s) of a normal start beginning at `t0` with the rotor at `n1_0`.
pub(crate) struct StartTimes {
    pub(crate) crank: f64,
    pub(crate) purge_hold_end: f64,
    pub(crate) accel: f64,
    pub(crate) at_idle: f64,
    pub(crate) breaker: f64,
    pub(crate) ramp_start: f64,
    pub(crate) at_load: f64,
}

/// Appends a normal start to the point lists. Returns its key times.
pub(crate) fn push_start(s: &mut Script, t0: f64, n1_0: f64) -> StartTimes {
    let crank_s = 40.0 * (2300.0 - n1_0) / 2300.0;
    let purge_at = t0 + crank_s;
    let release = purge_at + 60.0;
    let fuel_on = release + 20.0;
    let accel = fuel_on + 5.0;
    let idle = accel + 45.0;
    let n2_sync = idle + 60.0;
    let breaker = n2_sync + 40.0;
    let warm = breaker + 10.0;
    let ramp = warm + 240.0;
    let load = ramp + 120.0;
    s.n1.0.extend([
        (t0, n1_0),
        (purge_at, 2300.0),
        (release, 2300.0),
        (fuel_on, 1700.0),
        (accel, 1700.0),
        (idle, 6800.0),
        (ramp, 6800.0),
        (load, 7600.0),
    ]);
    s.fuel.0.extend([
        (fuel_on - 0.001, 0.0),
        (fuel_on, 0.08),
        (accel, 0.08),
        (accel + 40.0, 0.6),
        (warm, 0.7),
        (ramp, 0.8),
        (load, 2.1),
    ]);
    s.n2.0.extend([(idle, 0.0), (n2_sync, 3600.0)]);
    s.power
        .0
        .extend([(breaker - 0.5, 0.0), (warm, 3.0), (ramp, 3.0), (load, 31.4)]);
    StartTimes {
        crank: t0,
        purge_hold_end: release,
        accel,
        at_idle: idle,
        breaker,
        ramp_start: ramp,
        at_load: load,
    }
}

pub(crate) fn empty_script() -> Script {
    Script {
        n1: Pl(vec![(0.0, 0.0)]),
        fuel: Pl(vec![(0.0, 0.0)]),
        power: Pl(vec![(0.0, 0.0)]),
        n2: Pl(vec![(0.0, 0.0)]),
    }
}

pub(crate) const T0_MS: i64 = 1_700_000_000_000;

/// Samples the script at 1 Hz over [0, end_s], with relative Gaussian noise.
pub(crate) fn frames(s: &Script, end_s: i64, seed: u64, with_n2: bool) -> Vec<Frame> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let unit = Normal::new(0.0, 1.0).expect("normal");
    let mut noisy = |v: f64, rel: f64| v * (1.0 + rel * unit.sample(&mut rng));
    (0..=end_s)
        .map(|k| {
            let t = k as f64;
            Frame {
                t_ms: T0_MS + k * 1000,
                n1: noisy(s.n1.at(t), 0.0005),
                fuel: noisy(s.fuel.at(t), 0.005),
                power: noisy(s.power.at(t), 0.005),
                n2: if with_n2 {
                    Some(noisy(s.n2.at(t), 0.0005))
                } else {
                    None
                },
            }
        })
        .collect()
}

fn run(frames: &[Frame]) -> (Vec<SegmentRecord>, Option<SegmentRecord>) {
    let mut m = Machine::new(DetectorConfig::default(), None);
    for f in frames {
        m.push(*f);
    }
    (m.take_finished(), m.open_segment())
}

/// First whole second in [from, to] where `pred` holds on the noise-free script.
fn first_where(from: f64, to: f64, pred: impl Fn(f64) -> bool) -> f64 {
    let mut t = from.ceil();
    while t <= to {
        if pred(t) {
            return t;
        }
        t += 1.0;
    }
    panic!("condition never holds in [{from}, {to}]");
}

/// Contract truth for each phase start of a normal start.
fn truth(s: &Script, k: &StartTimes, with_n2: bool) -> Vec<(Phase, f64)> {
    let purge = first_where(k.crank, k.purge_hold_end, |t| s.n1.at(t) >= 0.98 * 2300.0);
    let idle = first_where(k.accel, k.ramp_start, |t| s.n1.at(t) >= 0.99 * 6800.0);
    let loading = first_where(k.at_idle, k.ramp_start, |t| s.power.at(t) > 0.5);
    // Steady: power within 1 % of the final setpoint from here on.
    let steady = first_where(k.ramp_start, k.at_load + 10.0, |t| {
        (s.power.at(t) - 31.4).abs() <= 0.01 * 31.4
    });
    let mut v = vec![
        (Phase::Crank, k.crank),
        (Phase::Purge, purge),
        (Phase::LightOff, k.purge_hold_end),
        (Phase::Acceleration, k.accel),
    ];
    if with_n2 {
        let sync = first_where(k.at_idle, k.breaker, |t| {
            (s.n2.at(t) - 3600.0).abs() <= 0.01 * 3600.0
        });
        v.push((Phase::Idle, idle));
        v.push((Phase::Synchronisation, sync));
    } else {
        v.push((Phase::Idle, idle));
    }
    v.push((Phase::Loading, loading));
    v.push((Phase::Steady, steady));
    v
}

fn assert_phases(seg: &SegmentRecord, truth: &[(Phase, f64)]) {
    let found: Vec<Phase> = seg.phases.iter().map(|p| p.phase).collect();
    let want: Vec<Phase> = truth.iter().map(|p| p.0).collect();
    assert_eq!(found, want, "phase sequence");
    for (phase, t) in truth {
        let span = seg.phase(*phase).expect("phase present");
        let got = (span.start_ms - T0_MS) as f64 / 1000.0;
        assert!(
            (got - t).abs() <= 2.0,
            "{phase}: found start {got} s, truth {t} s"
        );
    }
    // Phases tile the segment.
    for w in seg.phases.windows(2) {
        assert_eq!(w[0].end_ms, Some(w[1].start_ms));
    }
}

#[test]
fn normal_start_boundaries_within_two_samples() {
    for seed in 0..5 {
        for with_n2 in [true, false] {
            let mut s = empty_script();
            let k = push_start(&mut s, 30.0, 0.0);
            let end = k.at_load as i64 + 300;
            let (done, open) = run(&frames(&s, end, seed, with_n2));
            assert!(open.is_none(), "seed {seed}: segment left open");
            assert_eq!(done.len(), 1, "seed {seed}: {done:?}");
            let seg = &done[0];
            assert_eq!(seg.outcome, Outcome::Completed);
            assert!(!seg.hot_restart && !seg.has_gap && seg.abort_cause.is_none());
            assert_phases(seg, &truth(&s, &k, with_n2));
        }
    }
}

/// A normal start cut at `cut_s`: `trip` cuts the fuel, otherwise the flame goes out
/// (fuel stays, n1 decays at 150 rpm/s to rest).
fn cut_start(cut_s: f64, trip: bool) -> (Script, StartTimes) {
    let mut s = empty_script();
    let k = push_start(&mut s, 30.0, 0.0);
    let n1_cut = s.n1.at(cut_s);
    let fuel_cut = s.fuel.at(cut_s);
    let fuel_before = s.fuel.at(cut_s - 1.0);
    s.n1.0.retain(|p| p.0 < cut_s);
    s.fuel.0.retain(|p| p.0 < cut_s);
    s.power.0.retain(|p| p.0 < cut_s);
    s.n1.0
        .extend([(cut_s, n1_cut), (cut_s + n1_cut / 150.0, 0.0)]);
    if trip {
        s.fuel.0.extend([(cut_s - 1.0, fuel_before), (cut_s, 0.0)]);
    } else {
        s.fuel.0.extend([
            (cut_s, fuel_cut),
            (cut_s + 20.0, fuel_cut),
            (cut_s + 21.0, 0.0),
        ]);
    }
    s.power.0.push((cut_s, 0.0));
    s.n2.0.retain(|p| p.0 < cut_s);
    (s, k)
}

#[test]
fn aborted_start_by_trip() {
    let (s, k) = cut_start(185.0, true);
    assert!(185.0 > k.accel && 185.0 < k.at_idle);
    let (done, open) = run(&frames(&s, 600, 7, true));
    assert!(open.is_none());
    assert_eq!(done.len(), 1, "{done:?}");
    let seg = &done[0];
    assert_eq!(seg.outcome, Outcome::Aborted);
    assert_eq!(seg.abort_cause, Some(AbortCause::Trip));
    let end = (seg.end_ms.expect("closed") - T0_MS) as f64 / 1000.0;
    assert!((end - 185.0).abs() <= 2.0, "trip at {end}");
    assert_eq!(
        seg.phases.last().map(|p| p.phase),
        Some(Phase::Acceleration)
    );
    let accel = seg.phase(Phase::Acceleration).expect("accel");
    assert!(((accel.start_ms - T0_MS) as f64 / 1000.0 - k.accel).abs() <= 2.0);
}

#[test]
fn aborted_start_by_flame_out() {
    let (s, _k) = cut_start(205.0, false);
    let (done, _open) = run(&frames(&s, 600, 8, true));
    assert_eq!(done.len(), 1, "{done:?}");
    let seg = &done[0];
    assert_eq!(seg.outcome, Outcome::Aborted);
    assert_eq!(seg.abort_cause, Some(AbortCause::FlameOut));
    let end = (seg.end_ms.expect("closed") - T0_MS) as f64 / 1000.0;
    assert!((end - 205.0).abs() <= 2.0, "flame-out at {end}");
}

/// A normal start whose fuel, from `from_s` on idle, follows `fuel` (the GG speed falling with
/// it from 6 800 to 5 000 rpm) and is then cut at `cut_s`; the rotor coasts from there.
fn fuel_path_then_cut(from_s: f64, fuel: &[(f64, f64)], cut_s: f64) -> Vec<SegmentRecord> {
    let mut s = empty_script();
    let k = push_start(&mut s, 30.0, 0.0);
    assert!(
        from_s > k.at_idle && cut_s < k.breaker,
        "cut before the breaker closes"
    );
    let fuel_at_from = s.fuel.at(from_s);
    for pl in [&mut s.n1, &mut s.fuel, &mut s.power, &mut s.n2] {
        pl.0.retain(|p| p.0 < from_s);
    }
    s.fuel.0.push((from_s, fuel_at_from));
    s.fuel.0.extend_from_slice(fuel);
    s.fuel
        .0
        .extend([(cut_s - 0.5, s.fuel.at(cut_s - 0.5)), (cut_s, 0.0)]);
    s.n1.0.extend([
        (from_s, 6800.0),
        (cut_s, 5000.0),
        (cut_s + 5000.0 / 150.0, 0.0),
    ]);
    s.n2.0
        .extend([(from_s, 3000.0), (cut_s, 3000.0), (cut_s + 60.0, 0.0)]);
    let (done, open) = run(&frames(&s, 600, 11, true));
    assert!(open.is_none());
    assert_eq!(done.len(), 1, "{done:?}");
    done
}

/// A trip while the governor is already pulling the fuel back (the PT governor decelerating the
/// gas generator while synchronising, as the foreign unit's operations day does): the fuel three
/// seconds before the cut is below half its recent peak, but its trend would have taken far
/// longer to bring it down, and it is well above the light-off level — a trip, not a ramped stop.
#[test]
fn a_trip_while_the_governor_pulls_the_fuel_back_is_a_trip() {
    let done = fuel_path_then_cut(230.0, &[(250.0, 0.2)], 250.5);
    assert_eq!(done[0].abort_cause, Some(AbortCause::Trip), "{done:?}");
    let end = (done[0].end_ms.expect("closed") - T0_MS) as f64 / 1000.0;
    assert!((end - 251.0).abs() <= 1.0, "tripped at {end}");
}

/// An operator's stop ramps the fuel down to the light-off level before the valve closes:
/// a fast ramp (20 s) and a slow one (60 s) are both stops, not trips; the stop began where the
/// ramp began.
#[test]
fn a_ramped_stop_is_an_operator_stop_fast_or_slow() {
    for ramp_s in [20.0, 60.0] {
        let end_ramp = 230.0 + ramp_s;
        let done = fuel_path_then_cut(230.0, &[(end_ramp, 0.08)], end_ramp + 1.0);
        let seg = &done[0];
        assert_eq!(
            seg.abort_cause,
            Some(AbortCause::OperatorStop),
            "{ramp_s} s: {done:?}"
        );
        let end = (seg.end_ms.expect("closed") - T0_MS) as f64 / 1000.0;
        assert!(
            (end - 230.0).abs() <= 3.0,
            "{ramp_s} s ramp: stop began at {end}"
        );
    }
}

#[test]
fn operator_stop_during_purge() {
    let mut s = empty_script();
    // Crank 0 -> 2300 over 40 s, purge 30 s, starter released, rotor coasts to rest, no fuel.
    s.n1.0
        .extend([(10.0, 0.0), (50.0, 2300.0), (80.0, 2300.0), (200.0, 0.0)]);
    let (done, open) = run(&frames(&s, 300, 9, true));
    assert!(open.is_none());
    assert_eq!(done.len(), 1, "{done:?}");
    let seg = &done[0];
    assert_eq!(seg.abort_cause, Some(AbortCause::OperatorStop));
    let end = (seg.end_ms.expect("closed") - T0_MS) as f64 / 1000.0;
    assert!((end - 80.0).abs() <= 2.0, "stopped at {end}");
    assert_eq!(seg.phases.last().map(|p| p.phase), Some(Phase::Purge));
}

/// A completed start, a trip from load, and a restart while the rotor still turns.
pub(crate) fn hot_restart_script() -> (Script, StartTimes, f64, StartTimes) {
    let mut s = empty_script();
    let k1 = push_start(&mut s, 30.0, 0.0);
    let trip = k1.at_load + 200.0;
    // Trip from load: fuel and power cut, n1 coasts 7600 -> 1000 rpm in 66 s.
    s.n1.0.push((trip, 7600.0));
    s.fuel.0.extend([(trip - 1.0, 2.1), (trip, 0.0)]);
    s.power.0.extend([(trip - 1.0, 31.4), (trip, 0.0)]);
    s.n2.0.extend([(trip, 3600.0), (trip + 120.0, 0.0)]);
    let restart = trip + 66.0;
    s.n1.0.push((restart, 1000.0));
    let k2 = push_start(&mut s, restart, 1000.0);
    (s, k1, trip, k2)
}

#[test]
fn hot_restart_after_trip_from_load() {
    let (s, k1, _trip, k2) = hot_restart_script();
    let end = k2.at_load as i64 + 300;
    let (done, open) = run(&frames(&s, end, 11, true));
    assert!(open.is_none());
    assert_eq!(done.len(), 2, "{done:?}");
    assert!(!done[0].hot_restart);
    assert_phases(&done[0], &truth(&s, &k1, true));
    let seg = &done[1];
    assert!(seg.hot_restart, "second start must be a hot restart");
    assert_eq!(seg.outcome, Outcome::Completed);
    assert_phases(seg, &truth(&s, &k2, true));
}

/// A fuel meter that reads `offset` kg/s (±1 g/s of its own noise) where no fuel flows: the
/// detector reads its zero at rest and finds the same starts, cold and hot, as with a meter
/// that reads nothing. Before, every frame was "fuel on" and no start was ever found.
#[test]
fn a_fuel_meter_reading_at_rest_is_its_zero() {
    let (s, k1, _trip, k2) = hot_restart_script();
    let end = k2.at_load as i64 + 300;
    for (offset, seed) in [(0.02, 21), (-0.01, 22)] {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let unit = Normal::new(0.0, 0.001).expect("normal");
        let fr: Vec<Frame> = frames(&s, end, 11, true)
            .into_iter()
            .map(|f| Frame {
                fuel: f.fuel + offset + unit.sample(&mut rng),
                ..f
            })
            .collect();
        let mut m = Machine::new(DetectorConfig::default(), None);
        for f in &fr {
            m.push(*f);
        }
        let z = m.fuel_zero_kg_s().expect("the GG was at rest");
        assert!((z - offset).abs() < 0.001, "zero {z} for {offset}");
        let done = m.take_finished();
        assert!(m.open_segment().is_none());
        assert_eq!(done.len(), 2, "offset {offset}: {done:?}");
        assert!(!done[0].hot_restart && done[1].hot_restart);
        assert_phases(&done[0], &truth(&s, &k1, true));
        assert_phases(&done[1], &truth(&s, &k2, true));
        assert!(done.iter().all(|d| d.outcome == Outcome::Completed));
    }
}

#[test]
fn start_within_window_of_fuel_off_is_hot_even_from_rest() {
    let mut s = empty_script();
    let k1 = push_start(&mut s, 30.0, 0.0);
    let stop = k1.at_load + 100.0;
    s.n1.0.extend([(stop, 7600.0), (stop + 100.0, 0.0)]);
    s.fuel.0.extend([(stop - 1.0, 2.1), (stop, 0.0)]);
    s.power.0.extend([(stop - 1.0, 31.4), (stop, 0.0)]);
    s.n2.0.extend([(stop, 3600.0), (stop + 100.0, 0.0)]);
    // 10 minutes at rest, then a new start: within the 30-minute window.
    let k2 = push_start(&mut s, stop + 700.0, 0.0);
    let (done, _) = run(&frames(&s, k2.at_load as i64 + 120, 12, true));
    assert_eq!(done.len(), 2, "{done:?}");
    assert!(done[1].hot_restart);
    assert_eq!(done[1].outcome, Outcome::Completed);
}

#[test]
fn start_with_data_gap_is_marked_and_still_found() {
    let mut s = empty_script();
    let k = push_start(&mut s, 30.0, 0.0);
    let all = frames(&s, k.at_load as i64 + 300, 13, true);
    // 30 s without samples during the warm-up at minimum load.
    let gap_from = T0_MS + ((k.breaker + 60.0) as i64) * 1000;
    let kept: Vec<Frame> = all
        .into_iter()
        .filter(|f| f.t_ms < gap_from || f.t_ms >= gap_from + 30_000)
        .collect();
    let (done, open) = run(&kept);
    assert!(open.is_none());
    assert_eq!(done.len(), 1);
    assert!(done[0].has_gap);
    assert_eq!(done[0].outcome, Outcome::Completed);
    assert_phases(&done[0], &truth(&s, &k, true));
}

#[test]
fn open_segment_while_start_is_running() {
    let mut s = empty_script();
    let k = push_start(&mut s, 30.0, 0.0);
    let (done, open) = run(&frames(&s, k.at_idle as i64 + 10, 14, true));
    assert!(done.is_empty());
    let open = open.expect("open segment");
    assert!(open.is_open());
    assert_eq!(open.outcome, Outcome::InProgress);
    assert_eq!(open.phases.last().map(|p| p.phase), Some(Phase::Idle));
    assert_eq!(open.phases.last().and_then(|p| p.end_ms), None);
}

/// A power transmitter that freezes at 4 MW during loading (the engine goes on to base load):
/// the start is closed as aborted (`unknown`) after `max_startup_s` instead of staying in
/// progress for ever, and the next start, with the transmitter repaired, is found and completed.
#[test]
fn frozen_power_signal_closes_the_start_after_the_limit() {
    let mut s = empty_script();
    let k1 = push_start(&mut s, 30.0, 0.0);
    let freeze = k1.ramp_start + 30.0;
    let stop = k1.at_load + 4000.0;
    s.n1.0.extend([(stop, 7600.0), (stop + 100.0, 0.0)]);
    s.fuel.0.extend([(stop - 1.0, 2.1), (stop, 0.0)]);
    s.n2.0.extend([(stop, 3600.0), (stop + 100.0, 0.0)]);
    let restart = stop + 3000.0;
    let k2 = push_start(&mut s, restart, 0.0);
    let mut fr = frames(&s, k2.at_load as i64 + 120, 21, true);
    for f in fr.iter_mut() {
        let t = (f.t_ms - T0_MS) as f64 / 1000.0;
        if t >= freeze && t < restart - 100.0 {
            f.power = 4.0;
        }
        if t >= stop && t < restart - 100.0 {
            f.power = 4.0; // still frozen while the unit stops
        }
    }
    let (done, open) = run(&fr);
    assert!(open.is_none(), "{open:?}");
    assert_eq!(done.len(), 2, "{done:?}");
    assert_eq!(done[0].outcome, Outcome::Aborted);
    assert_eq!(done[0].abort_cause, Some(AbortCause::Unknown));
    let limit = DetectorConfig::default().max_startup_s;
    let length_s = (done[0].end_ms.expect("closed") - done[0].start_ms) as f64 / 1000.0;
    assert!((limit..limit + 5.0).contains(&length_s), "{length_s} s");
    assert_eq!(done[1].outcome, Outcome::Completed);
    assert!(done[1].start_ms as f64 >= T0_MS as f64 + 1000.0 * (restart - 1.0));
}

/// A unit whose purge and idle are held a few percent below the configured speeds (an engine
/// file copied from another unit, an idle on corrected speed): the held speeds are its purge
/// and idle, the start completes with every phase where the script put it; a speed held far
/// below idle (a hung start's stagnation) is not idle.
#[test]
fn held_speeds_below_the_configured_ones_are_purge_and_idle() {
    let mut s = empty_script();
    let k = push_start(&mut s, 10.0, 0.0);
    let f = frames(&s, (k.at_load + 200.0) as i64, 11, true);
    let detect = |cfg: DetectorConfig| {
        let mut m = Machine::new(cfg, None);
        for x in &f {
            m.push(*x);
        }
        m.take_finished()
    };
    // Purge held at 2 300 rpm against 2 392 configured (0.96), idle at 6 800 against 7 140
    // (0.95).
    let cfg = DetectorConfig {
        purge_speed_rpm: 2392.0,
        idle_speed_rpm: 7140.0,
        ..DetectorConfig::default()
    };
    let segs = detect(cfg.clone());
    assert_eq!(segs.len(), 1, "{segs:#?}");
    let seg = &segs[0];
    assert_eq!(seg.outcome, Outcome::Completed, "{seg:#?}");
    let at = |p: Phase| {
        seg.phase(p)
            .map(|x| (x.start_ms - T0_MS) as f64 / 1000.0)
            .unwrap_or_else(|| panic!("{p} missing: {seg:#?}"))
    };
    let purge_at = first_where(k.crank, k.purge_hold_end, |t| s.n1.at(t) >= 2300.0 - 2.0);
    assert!(
        (at(Phase::Purge) - purge_at).abs() <= 2.0,
        "purge {}",
        at(Phase::Purge)
    );
    assert!((at(Phase::LightOff) - k.purge_hold_end).abs() <= 2.0);
    assert!(
        (at(Phase::Idle) - k.at_idle).abs() <= 2.0,
        "idle {}",
        at(Phase::Idle)
    );
    assert!(seg.phase(Phase::Synchronisation).is_some() && seg.phase(Phase::Steady).is_some());
    // Held at 0.8 of the configured idle: acceleration until the breaker closes, no idle.
    let hung = DetectorConfig {
        idle_speed_rpm: 8500.0,
        ..cfg
    };
    let segs = detect(hung);
    assert_eq!(segs.len(), 1, "{segs:#?}");
    assert!(segs[0].phase(Phase::Idle).is_none(), "{:#?}", segs[0]);
    assert_eq!(segs[0].outcome, Outcome::Completed);
}

fn run_with(cfg: DetectorConfig, frames: &[Frame]) -> (Vec<SegmentRecord>, Option<SegmentRecord>) {
    let mut m = Machine::new(cfg, None);
    for f in frames {
        m.push(*f);
    }
    (m.take_finished(), m.open_segment())
}

fn extended(extend_s: f64) -> DetectorConfig {
    DetectorConfig {
        steady_extend_s: extend_s,
        ..DetectorConfig::default()
    }
}

/// Held open for its steady load (`steady_extend_s`): the same phases as without, the start-up
/// still completed, its steady phase as long as the hold asks while the load stays; without it,
/// closed where steady load is found (the hold, 60 s, after it began).
#[test]
fn a_start_up_held_for_its_steady_load_ends_when_the_hold_is_over() {
    for seed in 0..3 {
        let mut s = empty_script();
        let k = push_start(&mut s, 30.0, 0.0);
        let fr = frames(&s, k.at_load as i64 + 900, seed, true);
        let steady_len = |seg: &SegmentRecord| {
            let span = seg.phase(Phase::Steady).expect("steady");
            (span.end_ms.expect("closed") - span.start_ms) as f64 / 1000.0
        };
        let (plain, _) = run_with(DetectorConfig::default(), &fr);
        let (held, open) = run_with(extended(300.0), &fr);
        assert!(open.is_none(), "seed {seed}: left open");
        assert_eq!((plain.len(), held.len()), (1, 1), "seed {seed}");
        let (p, h) = (&plain[0], &held[0]);
        assert_eq!(h.outcome, Outcome::Completed);
        assert!(!h.has_gap && h.abort_cause.is_none());
        assert_phases(h, &truth(&s, &k, true));
        let (lp, lh) = (steady_len(p), steady_len(h));
        assert!(
            (55.0..=65.0).contains(&lp),
            "seed {seed}: steady {lp} s without the hold"
        );
        assert!(
            (lh - lp - 300.0).abs() <= 1.0,
            "seed {seed}: steady {lh} s held, {lp} s without"
        );
    }
}

/// The load moving, the fuel cut or the data stopping during the hold close the start-up as
/// completed at its last steady sample; one noisy sample outside the band does not.
#[test]
fn a_held_start_up_closes_completed_where_its_load_moves_or_its_data_stop() {
    let mut s = empty_script();
    let k = push_start(&mut s, 30.0, 0.0);
    let load = k.at_load;
    // The load steps down 150 s after it was reached (the hold would have run 300 s more).
    s.power
        .0
        .extend([(load + 150.0, 31.4), (load + 151.0, 20.0)]);
    s.fuel.0.extend([(load + 150.0, 2.1), (load + 151.0, 1.6)]);
    let mut fr = frames(&s, load as i64 + 600, 4, true);
    // One sample far off the band, 100 s into the load: a spike, not a move.
    let spike = fr
        .iter()
        .position(|f| f.t_ms >= T0_MS + (load as i64 + 100) * 1000)
        .expect("frame");
    fr[spike].power *= 1.1;
    let (done, open) = run_with(extended(300.0), &fr);
    assert!(open.is_none());
    assert_eq!(done.len(), 1, "{done:?}");
    let seg = &done[0];
    assert_eq!(seg.outcome, Outcome::Completed);
    let end_s = (seg.end_ms.expect("closed") - T0_MS) as f64 / 1000.0;
    assert!(
        (end_s - (load + 150.0)).abs() <= 2.0,
        "closed at {end_s} s, the load moved at {} s",
        load + 150.0
    );

    // Data stopping for longer than the gap limit 120 s into the load: closed before the gap,
    // not marked as having one.
    let mut s = empty_script();
    let k = push_start(&mut s, 30.0, 0.0);
    let gap_from = k.at_load as i64 + 120;
    let fr: Vec<Frame> = frames(&s, k.at_load as i64 + 900, 5, true)
        .into_iter()
        .filter(|f| {
            let t = (f.t_ms - T0_MS) / 1000;
            t <= gap_from || t > gap_from + 60
        })
        .collect();
    let (done, _) = run_with(extended(300.0), &fr);
    assert_eq!(done.len(), 1, "{done:?}");
    let seg = &done[0];
    assert_eq!(seg.outcome, Outcome::Completed);
    assert!(!seg.has_gap);
    assert_eq!(seg.end_ms, Some(T0_MS + gap_from * 1000));

    // The fuel cut 200 s into the load (a trip): completed at its last steady sample, and the
    // trip starts no new segment.
    let mut s = empty_script();
    let k = push_start(&mut s, 30.0, 0.0);
    let cut = k.at_load + 200.0;
    s.fuel.0.extend([(cut, 2.1), (cut + 0.5, 0.0)]);
    s.power.0.extend([(cut, 31.4), (cut + 0.5, 0.0)]);
    s.n1.0.extend([(cut, 7600.0), (cut + 120.0, 0.0)]);
    let (done, open) = run_with(extended(300.0), &frames(&s, cut as i64 + 200, 6, true));
    assert!(open.is_none());
    assert_eq!(done.len(), 1, "{done:?}");
    assert_eq!(done[0].outcome, Outcome::Completed);
    let end_s = (done[0].end_ms.expect("closed") - T0_MS) as f64 / 1000.0;
    assert!(
        (end_s - cut).abs() <= 1.5,
        "closed at {end_s} s, cut at {cut} s"
    );
}

/// An input that ends inside the hold (a replayed log, a file): the held start-up stays open
/// while more data may come, and closes completed at its last steady sample once the input is
/// said to have ended; a start still short of steady load stays open.
#[test]
fn a_held_start_up_closes_at_the_end_of_the_input() {
    let mut s = empty_script();
    let k = push_start(&mut s, 30.0, 0.0);
    let end = k.at_load as i64 + 150;
    let mut m = Machine::new(extended(300.0), None);
    for f in frames(&s, end, 7, true) {
        m.push(f);
    }
    assert!(m.take_finished().is_empty());
    assert!(m.open_segment().is_some(), "held open while data may come");
    m.end_of_input();
    let done = m.take_finished();
    assert_eq!(done.len(), 1, "{done:?}");
    assert_eq!(done[0].outcome, Outcome::Completed);
    assert_eq!(done[0].end_ms, Some(T0_MS + end * 1000));
    assert!(m.open_segment().is_none());

    // Ended during the loading ramp: nothing to close.
    let mut m = Machine::new(extended(300.0), None);
    for f in frames(&s, k.ramp_start as i64 + 30, 7, true) {
        m.push(f);
    }
    m.end_of_input();
    assert!(m.take_finished().is_empty());
    assert!(m.open_segment().is_some());
}
