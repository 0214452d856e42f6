//! Unit tests of the steady solve (the parent module and its iteration, `newton`).

use super::*;
use crate::engine::Engine;
use crate::health::HealthParams;
use crate::thermo::Gas;

fn iso(demand: Demand) -> SteadyInputs {
    SteadyInputs {
        t_amb_k: 288.15,
        p_amb_kpa: 101.325,
        n2_rpm: 3600.0,
        demand,
    }
}

#[test]
fn design_point_meets_reference_table() {
    let e = Engine::reference().expect("engine");
    let m = e.model(&HealthParams::HEALTHY);
    let p = solve(&m, &iso(Demand::PowerMw(31.4)), None).expect("solves");
    // REFERENCE §1 tolerances.
    assert!(
        (p.pressure_ratio / 24.1 - 1.0).abs() < 0.005,
        "PR {}",
        p.pressure_ratio
    );
    assert!(
        (p.pt_flow_kg_s / 84.31 - 1.0).abs() < 0.005,
        "W {}",
        p.pt_flow_kg_s
    );
    assert!((p.power_mw / 31.4 - 1.0).abs() < 0.005, "P {}", p.power_mw);
    assert!(
        (p.compressor_efficiency - 0.85).abs() < 0.002,
        "eta {}",
        p.compressor_efficiency
    );
    assert!((p.n1_rpm / 9500.0 - 1.0).abs() < 1e-6, "n1 {}", p.n1_rpm);
    assert!(
        p.surge_margin_pct > 5.0,
        "surge margin {}",
        p.surge_margin_pct
    );
}

/// Energy closure over the whole engine at `p`, its exhaust of composition `exhaust`: fuel
/// heat = exhaust enthalpy rise + PT shaft work + the GG's net shaft work (its mechanical
/// losses leave the gas path).
fn assert_energy_closes(m: &Model, p: &SteadyPoint, exhaust: &Gas, demand: Demand) {
    let air = Gas::air();
    let heat_in = m.consts.fuel_heat_w(p.fuel_kg_s);
    let rise = p.pt_flow_kg_s * exhaust.h(p.t4_k) - p.air_flow_kg_s * air.h(p.t1_k);
    let shafts = (p.pt_power_mw + p.hpt_power_mw - p.compressor_power_mw) * 1e6;
    assert!(
        ((rise + shafts) - heat_in).abs() / heat_in < 1e-6,
        "{demand:?}: {rise} + {shafts} vs {heat_in}"
    );
}

#[test]
fn mass_and_energy_close_at_off_design() {
    let e = Engine::reference().expect("engine");
    let m = e.model(&HealthParams::HEALTHY);
    for demand in [
        Demand::PowerMw(20.0),
        Demand::PowerMw(8.0),
        Demand::N1Rpm(6800.0),
        Demand::FuelKgS(1.2),
    ] {
        let p = solve(&m, &iso(demand), None).expect("solves");
        assert!(
            p.hpt_flow_error_kg_s.abs() / p.pt_flow_kg_s < 1e-6,
            "{demand:?} {p:?}"
        );
        assert!(
            p.pt_flow_error_kg_s.abs() / p.pt_flow_kg_s < 1e-6,
            "{demand:?}"
        );
        assert!(
            p.gg_power_error_w.abs() / (p.compressor_power_mw * 1e6) < 1e-6,
            "{demand:?}"
        );
        assert_energy_closes(&m, &p, &m.consts.fuel.products(p.fuel_air_ratio), demand);
    }
}

/// Air returned at the HPT exit (`design.cooling_return_frac`): the design point is
/// reproduced, mass and energy close with it mixed into the PT's gas, and the same power
/// needs a hotter combustor exit than with that air burnt.
#[test]
fn cooling_air_returned_at_the_hpt_exit_closes_mass_and_energy() {
    let mut e = Engine::reference().expect("engine");
    let before = *e.design();
    e.set_param("design.cooling_return_frac", 0.04)
        .expect("a valid fraction");
    let d = *e.design();
    assert!(
        (d.pt_flow_kg_s - d.hpt_flow_kg_s - 0.04 * d.air_flow_kg_s).abs() < 1e-9,
        "{d:?}"
    );
    // The same power from less gas through the HPT: a hotter combustor exit.
    assert!(d.t3_k > before.t3_k + 5.0, "{} vs {}", d.t3_k, before.t3_k);
    let m = e.model(&HealthParams::HEALTHY);
    let design = solve(
        &m,
        &SteadyInputs {
            n2_rpm: d.n2_rpm,
            ..iso(Demand::PowerMw(d.power_mw))
        },
        None,
    )
    .expect("design point");
    for (what, got, want) in [
        ("n1", design.n1_rpm, d.n1_rpm),
        ("T34", design.t34_k, d.t34_k),
        ("T4", design.t4_k, d.t4_k),
        ("P34", design.p34_kpa, d.p34_kpa),
        ("fuel", design.fuel_kg_s, d.fuel_kg_s),
    ] {
        assert!((got / want - 1.0).abs() < 1e-4, "{what}: {got} vs {want}");
    }
    for demand in [Demand::PowerMw(20.0), Demand::PowerMw(8.0)] {
        let p = solve(&m, &iso(demand), None).expect("solves");
        assert!(
            p.pt_flow_error_kg_s.abs() / p.pt_flow_kg_s < 1e-6,
            "{demand:?}"
        );
        assert!(
            (p.pt_flow_kg_s - p.hpt_flow_kg_s - 0.04 * p.air_flow_kg_s).abs() / p.pt_flow_kg_s
                < 1e-6,
            "{demand:?}: the PT passes the HPT's gas and the returned air"
        );
        // The exhaust is the combustion products of the fuel in all the air (none overboard).
        let exhaust = m.consts.fuel.products(p.fuel_kg_s / p.air_flow_kg_s);
        assert_energy_closes(&m, &p, &exhaust, demand);
    }
}

#[test]
fn idle_solves_and_compressor_fouling_signs() {
    let e = Engine::reference().expect("engine");
    let clean = e.model(&HealthParams::HEALTHY);
    let idle = solve(&clean, &iso(Demand::N1Rpm(6800.0)), None).expect("idle");
    assert!(
        idle.power_mw > 0.0 && idle.power_mw < 8.0,
        "idle power {}",
        idle.power_mw
    );
    let fouled = e.model(&HealthParams {
        D_GC: 3.0,
        D_EC: 1.0,
        ..HealthParams::HEALTHY
    });
    let a = solve(&clean, &iso(Demand::PowerMw(31.4)), None).expect("clean");
    let b = solve(&fouled, &iso(Demand::PowerMw(31.4)), None).expect("fouled");
    assert!(b.t3_k > a.t3_k + 5.0, "T3 {} -> {}", a.t3_k, b.t3_k);
    assert!(
        b.fuel_kg_s > a.fuel_kg_s,
        "fuel {} -> {}",
        a.fuel_kg_s,
        b.fuel_kg_s
    );
    assert!(
        b.air_flow_kg_s < a.air_flow_kg_s,
        "air {} -> {}",
        a.air_flow_kg_s,
        b.air_flow_kg_s
    );
}

fn md22() -> Engine {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/engine_md22.toml");
    Engine::new(crate::engine::EngineConfig::load(&path).expect("md22 loads")).expect("md22")
}

/// Near idle the md22 running line's fuel flow is not monotone in GG speed (a local
/// minimum of 0.0942 kg/s near 4 650 rpm, a maximum of 0.0953 kg/s near 4 400 rpm, where
/// the compressor leaves its lowest speed line): continuation in the fuel demand stalls at
/// that fold, the walk in speed passes it. The point found is checked against the N1
/// solve at its own speed (truth: the same running line, solved without a fold).
#[test]
fn idle_fuel_below_a_fold_of_the_running_line_solves() {
    let e = md22();
    let m = e.model(&HealthParams::HEALTHY);
    let inp = SteadyInputs {
        n2_rpm: 6500.0,
        ..iso(Demand::FuelKgS(0.09))
    };
    let p = solve(&m, &inp, None).expect("idle fuel solves");
    assert!((p.fuel_kg_s - 0.09).abs() < 1e-9, "fuel {}", p.fuel_kg_s);
    assert!(p.n1_rpm > 3700.0 && p.n1_rpm < 4200.0, "n1 {}", p.n1_rpm);
    assert!(p.hpt_flow_error_kg_s.abs() < 1e-6 && p.gg_power_error_w.abs() < 1.0);
    let at_speed = SteadyInputs {
        demand: Demand::N1Rpm(p.n1_rpm),
        ..inp
    };
    let q = solve(&m, &at_speed, None).expect("same speed solves");
    assert!(
        (q.fuel_kg_s - 0.09).abs() < 1e-6,
        "fuel at n1 {}",
        q.fuel_kg_s
    );
    assert!(
        (q.t4_k - p.t4_k).abs() < 1e-3,
        "T4 {} vs {}",
        q.t4_k,
        p.t4_k
    );
}

/// A fuel flow below anything the model runs at is refused with the lowest running point.
#[test]
fn fuel_below_the_lowest_running_point_is_refused_with_it() {
    let e = md22();
    let m = e.model(&HealthParams::HEALTHY);
    let inp = SteadyInputs {
        n2_rpm: 6500.0,
        ..iso(Demand::FuelKgS(0.002))
    };
    let err = solve(&m, &inp, None)
        .expect_err("below the model's range")
        .to_string();
    assert!(
        err.contains("fuel 0.002 kg/s is below the model's lowest running point at"),
        "{err}"
    );
    assert!(err.contains("(N1 "), "{err}");
}

/// The solve cost reported for `bench steady`: a cold solve takes Newton iterations, each
/// with a Jacobian of 3 extra evaluations plus at least one line-search evaluation; a solve
/// started at its own solution takes none.
#[test]
fn solve_stats_count_the_work() {
    let e = Engine::reference().expect("engine");
    let m = e.model(&HealthParams::HEALTHY);
    let inp = iso(Demand::PowerMw(20.0));
    let (p, cold) = solve_with_stats(&m, &inp, None).expect("solves");
    assert!(cold.newton_iterations >= 2, "{cold:?}");
    // The first iteration's finite-difference Jacobian (4 free unknowns for a power
    // demand) and the start, then one or more evaluations per Broyden step.
    assert!(cold.evaluations > 4 + cold.newton_iterations, "{cold:?}");
    assert_eq!(solve(&m, &inp, None).expect("solves"), p);
    let (q, warm) = solve_with_stats(&m, &inp, Some(&p)).expect("solves");
    assert!(warm.newton_iterations <= 1, "{warm:?}");
    assert_eq!(warm.continuation_steps, 0);
    assert!((q.power_mw - p.power_mw).abs() < 1e-9);
}
