use super::*;

fn q(cfg: &QualityConfig, s: Signal) -> ValueChecker {
    cfg.checker(&[s.column()], Some(s))
}

#[test]
fn nan_inf_and_range() {
    let cfg = QualityConfig::default();
    let mut n1 = q(&cfg, Signal::N1);
    assert_eq!(n1.check(0, f64::NAN, None), Quality::Bad);
    assert_eq!(n1.check(1, f64::INFINITY, None), Quality::Bad);
    assert_eq!(n1.check(2, -500.0, None), Quality::OutOfRange);
    assert_eq!(n1.check(3, 1e9, None), Quality::OutOfRange);
    assert_eq!(n1.check(4, 7600.0, None), Quality::Good);
    let mut t2 = q(&cfg, Signal::T2);
    assert_eq!(t2.check(0, 1e9, None), Quality::OutOfRange);
    let mut fuel = q(&cfg, Signal::FuelFlow);
    assert_eq!(fuel.check(0, -100.0, None), Quality::OutOfRange);
    assert_eq!(fuel.check(1, 2.0, None), Quality::Good);
}

#[test]
fn the_default_speed_ranges_cover_the_class_not_one_engine() {
    // A 6 100 rpm power turbine (an aero-derivative's high-speed PT) and a 15 000 rpm gas
    // generator are good readings; a unit's own envelope is an override.
    let mut cfg = QualityConfig::default();
    let mut n2 = q(&cfg, Signal::N2);
    assert_eq!(n2.check(0, 6100.0, None), Quality::Good);
    assert_eq!(n2.check(1, 30_000.0, None), Quality::OutOfRange);
    let mut n1 = q(&cfg, Signal::N1);
    assert_eq!(n1.check(0, 15_000.0, None), Quality::Good);
    cfg.limits.insert(
        "n2_rpm".into(),
        LimitOverride {
            hi: Some(4500.0),
            ..LimitOverride::default()
        },
    );
    assert_eq!(
        q(&cfg, Signal::N2).check(0, 6100.0, None),
        Quality::OutOfRange
    );
}

#[test]
fn overrides_apply_and_are_validated() {
    let mut cfg = QualityConfig::default();
    cfg.limits.insert(
        "power_mw".into(),
        LimitOverride {
            hi: Some(45.0),
            ..LimitOverride::default()
        },
    );
    let l = cfg
        .limits_for(&["power_mw"], Some(Signal::Power))
        .expect("limits");
    assert_eq!(l.hi, 45.0);
    assert_eq!(l.lo, default_limits(Signal::Power).lo);
    assert!(cfg.validate().is_empty());
    // A non-signal tag is range-checked only with a full override.
    assert!(cfg.limits_for(&["vib"], None).is_none());
    cfg.limits.insert(
        "vib".into(),
        LimitOverride {
            lo: Some(5.0),
            hi: Some(1.0),
            max_rate_per_s: Some(f64::NAN),
        },
    );
    cfg.stuck_after_s = -1.0;
    let keys: Vec<String> = cfg.validate().iter().map(|p| p.to_string()).collect();
    let all = keys.join("\n");
    assert!(all.contains("quality.limits.vib.hi"), "{all}");
    assert!(all.contains("quality.limits.vib.max_rate_per_s"), "{all}");
    assert!(all.contains("quality.stuck_after_s"), "{all}");
}

#[test]
fn frozen_value_while_engine_moves_is_stuck() {
    let cfg = QualityConfig::default();
    let mut p = q(&cfg, Signal::Power);
    // Power frozen at 12 MW for 300 s while n1 climbs 7000 -> 8500 rpm.
    let mut flags = Vec::new();
    for i in 0..300 {
        let n1 = 7000.0 + 5.0 * i as f64;
        flags.push(p.check(i * 1000, 12.0, Some(n1)));
    }
    assert_eq!(flags[0], Quality::Good);
    assert_eq!(flags[100], Quality::Good, "not before stuck_after_s");
    assert_eq!(flags[299], Quality::Stuck);
    // Frozen while n1 does not move (steady load): not stuck.
    let mut p = q(&cfg, Signal::Power);
    for i in 0..300 {
        assert_eq!(p.check(i * 1000, 31.4, Some(9000.0)), Quality::Good);
    }
    // Zero power during a start (breaker open) is legitimately constant.
    let mut p = q(&cfg, Signal::Power);
    for i in 0..300 {
        let n1 = 2000.0 + 20.0 * i as f64;
        assert_eq!(p.check(i * 1000, 0.0, Some(n1)), Quality::Good);
    }
}

fn pt(t_s: i64, v: f64) -> Point {
    Point {
        t_ms: t_s * 1000,
        value: v,
        quality: Quality::Good,
    }
}

fn run_spikes(values: &[f64], s: Signal) -> Vec<Quality> {
    let mut f = SpikeFilter::new(Some(default_limits(s)));
    let mut out = Vec::new();
    for (i, &v) in values.iter().enumerate() {
        out.extend(f.push(pt(i as i64, v)).map(|p| p.quality));
    }
    out.extend(f.finish().map(|p| p.quality));
    out
}

#[test]
fn isolated_spike_is_flagged_but_steps_are_not() {
    use Quality::{Good as G, Spike as S};
    // n1 7600 with one 11 000 rpm sample (inside the range, beyond 2000 rpm/s both ways).
    assert_eq!(
        run_spikes(&[7600.0, 7600.0, 11_000.0, 7600.0, 7600.0], Signal::N1),
        vec![G, G, S, G, G]
    );
    // A trip: fuel 2 kg/s -> 0 and stays there. A step, not a spike.
    assert_eq!(
        run_spikes(&[2.0, 2.0, 0.0, 0.0, 0.0], Signal::FuelFlow),
        vec![G, G, G, G, G]
    );
    // Load rejection 31 -> 0 MW.
    assert_eq!(
        run_spikes(&[31.0, 31.0, 0.0, 0.0], Signal::Power),
        vec![G, G, G, G]
    );
}

#[test]
fn quality_threshold_names_the_signal() {
    assert_eq!(
        insufficient_quality(&[(Signal::N1, 95, 100), (Signal::T2, 90, 100)], 0.9),
        None
    );
    let why = insufficient_quality(&[(Signal::N1, 95, 100), (Signal::T2, 50, 100)], 0.9)
        .expect("too low");
    assert!(
        why.contains("t2_k") || why.contains("T2") || why.contains("t2"),
        "{why}"
    );
    assert!(why.contains("50 good of 100"), "{why}");
    assert!(insufficient_quality(&[(Signal::P2, 0, 0)], 0.9).is_some());
}
