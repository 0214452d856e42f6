//! Steady-state matching: given ambient, health and one operating demand, find the operating
//! point where the compressor, HPT and PT agree on flow and the GG shaft balances.
//!
//! Unknowns (normalised by design values): GG speed n1, compressor β, PT inlet pressure P34 and
//! fuel flow; one of them is fixed or replaced by the demand. Residuals: HPT flow compatibility,
//! PT flow compatibility, GG work balance, and (for a power demand) the power. Newton's method
//! with a finite-difference Jacobian and backtracking; far off-design demands are reached by
//! continuation from the design point. Pure: no I/O.

use super::effects::CoreView;
use super::gas_path::{self, Adjust, CompressorSetting, HotSection, Inputs, Stations};
use super::model::{EngineError, Model};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// What the operator asks of the engine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Demand {
    /// Power at the PT coupling, MW.
    PowerMw(f64),
    /// Fuel mass flow, kg/s.
    FuelKgS(f64),
    /// GG speed, rpm.
    N1Rpm(f64),
}

/// Operating conditions for a steady solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SteadyInputs {
    pub t_amb_k: f64,
    pub p_amb_kpa: f64,
    pub n2_rpm: f64,
    pub demand: Demand,
}

/// A steady operating point: the station table ([`Stations`], also reachable through `Deref`)
/// with the cycle figures and the solver's closure errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SteadyPoint {
    #[serde(flatten)]
    pub stations: Stations,
    pub heat_rate_kj_kwh: f64,
    pub thermal_efficiency: f64,
    /// HPT map flow minus combustor exit flow, kg/s (mass closure; ~0 when solved).
    pub hpt_flow_error_kg_s: f64,
    /// PT map flow minus HPT flow, kg/s.
    pub pt_flow_error_kg_s: f64,
    /// HPT shaft power minus compressor power and losses, W (energy closure).
    pub gg_power_error_w: f64,
}

impl std::ops::Deref for SteadyPoint {
    type Target = Stations;
    fn deref(&self) -> &Stations {
        &self.stations
    }
}

/// What one [`solve_with_stats`] cost: Newton iterations (Jacobian updates), gas-path
/// evaluations (each a full station calculation) and continuation steps (0 when the first
/// Newton run from the guess converged).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct SolveStats {
    pub newton_iterations: u32,
    pub evaluations: u32,
    pub continuation_steps: u32,
}

/// Unknown vector layout: [n1, beta, p34, wf], each normalised.
#[derive(Debug, Clone, Copy)]
struct Unknowns([f64; 4]);

struct Evaluated {
    point: SteadyPoint,
    residuals: [f64; 4],
}

/// The gas-path adjustments of the enabled effects at a steady point: their hooks see the
/// point as the core model computes it, with each effect's states at equilibrium.
fn effect_adjust(model: &Model, inp: &Inputs) -> Adjust {
    let effects = &model.effects;
    if effects.is_empty() {
        return Adjust::NONE;
    }
    let base = gas_path::evaluate(model, inp, None).stations();
    let c = &model.consts;
    let core = CoreView {
        t_s: 0.0,
        n1_rpm: base.n1_rpm,
        n2_rpm: base.n2_rpm,
        p2_kpa: base.p2_kpa,
        t3_k: base.t3_k,
        p34_kpa: base.p34_kpa,
        t_amb_k: inp.t_amb_k,
        p_amb_kpa: inp.p_amb_kpa,
        n1_design_rpm: c.n1_design,
        fuel_design_kg_s: c.fuel_design,
    };
    let mut y = effects.layout().zeros();
    effects.steady_states(&core, &base, &mut y);
    Adjust {
        extra_bleed: effects.bleed_fraction(&core, &y),
        deltas: effects.component_deltas(&core, &y),
        losses: effects.duct_losses(&core, &y),
    }
}

fn evaluate(model: &Model, inp: &SteadyInputs, x: &Unknowns) -> Evaluated {
    let c = &model.consts;
    let n1 = x.0[0] * c.n1_design;
    let wf = x.0[3] * c.fuel_design;
    // The unknown is the metered fuel (what a fuel demand fixes); an input-instrument effect
    // (`fuel_meter`) says how much of it burns.
    let burnt = model.effects.steady_fuel_burnt(wf);
    let gp_inputs = Inputs {
        t_amb_k: inp.t_amb_k,
        p_amb_kpa: inp.p_amb_kpa,
        n1_rpm: n1,
        n2_rpm: inp.n2_rpm,
        p34_kpa: x.0[2] * c.p34_design_kpa,
        compressor: CompressorSetting::Beta(x.0[1]),
        hot: HotSection::Burn { fuel_kg_s: burnt },
    };
    let adjust = effect_adjust(model, &gp_inputs);
    let gp = gas_path::evaluate(model, &gp_inputs, Some(&adjust));
    let w3 = gp.w_combustor_out_kg_s;
    let power_w = gp.pt_net_w;
    let gg_err = gp.gg_net_w;
    let wd = c.flow_design;
    let pd = c.power_design_w;
    let target_power = match inp.demand {
        Demand::PowerMw(p) => p * 1e6,
        _ => power_w,
    };
    let residuals = [
        (gp.hpt.w_kg_s - w3) / wd,
        (gp.pt.w_kg_s - w3) / wd,
        gg_err / pd,
        (power_w - target_power) / pd,
    ];
    let heat = burnt * c.fuel.lhv();
    let mut stations = gp.stations();
    stations.fuel_kg_s = wf;
    stations.fuel_burnt_kg_s = burnt;
    let point = SteadyPoint {
        stations,
        heat_rate_kj_kwh: if power_w > 0.0 {
            heat / power_w * 3600.0
        } else {
            f64::INFINITY
        },
        thermal_efficiency: if heat > 0.0 { power_w / heat } else { 0.0 },
        hpt_flow_error_kg_s: gp.hpt.w_kg_s - w3,
        pt_flow_error_kg_s: gp.pt.w_kg_s - w3,
        gg_power_error_w: gg_err,
    };
    Evaluated { point, residuals }
}

/// Which unknowns are free and which residuals are used for a demand.
fn layout(demand: Demand) -> (&'static [usize], &'static [usize]) {
    match demand {
        Demand::PowerMw(_) => (&[0, 1, 2, 3], &[0, 1, 2, 3]),
        Demand::FuelKgS(_) => (&[0, 1, 2], &[0, 1, 2]),
        Demand::N1Rpm(_) => (&[1, 2, 3], &[0, 1, 2]),
    }
}

fn fix_demand(model: &Model, demand: Demand, x: &mut Unknowns) {
    match demand {
        Demand::FuelKgS(wf) => x.0[3] = wf / model.consts.fuel_design,
        Demand::N1Rpm(n) => x.0[0] = n / model.consts.n1_design,
        Demand::PowerMw(_) => {}
    }
}

fn norm(r: &[f64], rows: &[usize]) -> f64 {
    rows.iter().map(|&i| r[i] * r[i]).sum::<f64>().sqrt()
}

fn valid(x: &Unknowns, model: &Model, inp: &SteadyInputs) -> bool {
    x.0[0] > 0.05
        && (-1.0..=2.0).contains(&x.0[1])
        && x.0[2] * model.consts.p34_design_kpa > inp.p_amb_kpa * 1.0005
        && x.0[3] > 0.0
        && x.0.iter().all(|v| v.is_finite())
}

/// Newton iteration from `x0`; returns the converged unknowns.
fn newton(
    model: &Model,
    inp: &SteadyInputs,
    x0: Unknowns,
    stats: &mut SolveStats,
) -> Result<Unknowns, String> {
    let (free, rows) = layout(inp.demand);
    let mut x = x0;
    fix_demand(model, inp.demand, &mut x);
    let mut ev = evaluate(model, inp, &x);
    stats.evaluations += 1;
    let mut f = norm(&ev.residuals, rows);
    for _iter in 0..60 {
        if f < 1e-11 {
            return Ok(x);
        }
        stats.newton_iterations += 1;
        let n = free.len();
        let mut jac = DMatrix::<f64>::zeros(n, n);
        for (j, &k) in free.iter().enumerate() {
            let h = 1e-7 * x.0[k].abs().max(1e-2);
            let mut xp = x;
            xp.0[k] += h;
            let evp = evaluate(model, inp, &xp);
            stats.evaluations += 1;
            for (i, &r) in rows.iter().enumerate() {
                jac[(i, j)] = (evp.residuals[r] - ev.residuals[r]) / h;
            }
        }
        let rhs = DVector::from_iterator(n, rows.iter().map(|&r| -ev.residuals[r]));
        let dx = jac
            .lu()
            .solve(&rhs)
            .ok_or("singular Jacobian (no unique operating point)")?;
        // Backtracking: accept the largest step that keeps the point valid and lowers |r|.
        let mut lambda = 1.0;
        let mut accepted = false;
        for _ in 0..30 {
            let mut xn = x;
            for (j, &k) in free.iter().enumerate() {
                xn.0[k] += lambda * dx[j];
            }
            if valid(&xn, model, inp) {
                let evn = evaluate(model, inp, &xn);
                stats.evaluations += 1;
                let fnew = norm(&evn.residuals, rows);
                if fnew.is_finite() && fnew < f {
                    x = xn;
                    ev = evn;
                    f = fnew;
                    accepted = true;
                    break;
                }
            }
            lambda *= 0.5;
        }
        if !accepted {
            return Err(format!("Newton stalled with residual norm {f:.3e}"));
        }
    }
    if f < 1e-9 {
        Ok(x)
    } else {
        Err(format!(
            "no convergence after 60 iterations (residual norm {f:.3e})"
        ))
    }
}

fn design_guess(model: &Model) -> Unknowns {
    Unknowns([1.0, model.consts.beta_design, 1.0, 1.0])
}

fn guess_from(model: &Model, p: &SteadyPoint) -> Unknowns {
    let c = &model.consts;
    Unknowns([
        p.n1_rpm / c.n1_design,
        p.compressor_beta,
        p.p34_kpa / c.p34_design_kpa,
        p.fuel_kg_s / c.fuel_design,
    ])
}

fn demand_value(d: Demand) -> f64 {
    match d {
        Demand::PowerMw(v) | Demand::FuelKgS(v) | Demand::N1Rpm(v) => v,
    }
}

fn with_value(d: Demand, v: f64) -> Demand {
    match d {
        Demand::PowerMw(_) => Demand::PowerMw(v),
        Demand::FuelKgS(_) => Demand::FuelKgS(v),
        Demand::N1Rpm(_) => Demand::N1Rpm(v),
    }
}

/// Solves for the steady operating point. `guess` (a nearby solution) speeds it up; without it
/// the solve starts at the design point and walks the demand there by continuation if needed.
pub fn solve(
    model: &Model,
    inp: &SteadyInputs,
    guess: Option<&SteadyPoint>,
) -> Result<SteadyPoint, EngineError> {
    solve_with_stats(model, inp, guess).map(|(p, _)| p)
}

/// [`solve`], also reporting what the solve cost (for `gtwatch bench steady`).
pub fn solve_with_stats(
    model: &Model,
    inp: &SteadyInputs,
    guess: Option<&SteadyPoint>,
) -> Result<(SteadyPoint, SolveStats), EngineError> {
    let mut stats = SolveStats::default();
    let point = solve_counted(model, inp, guess, &mut stats)?;
    Ok((point, stats))
}

fn solve_counted(
    model: &Model,
    inp: &SteadyInputs,
    guess: Option<&SteadyPoint>,
    stats: &mut SolveStats,
) -> Result<SteadyPoint, EngineError> {
    let x0 = guess
        .map(|g| guess_from(model, g))
        .unwrap_or_else(|| design_guess(model));
    if let Ok(x) = newton(model, inp, x0, stats) {
        return Ok(evaluate(model, inp, &x).point);
    }
    // Continuation: start from the design point's own demand value and step towards the target.
    let design = newton(
        model,
        &SteadyInputs {
            demand: Demand::N1Rpm(model.consts.n1_design),
            ..*inp
        },
        design_guess(model),
        stats,
    )
    .map_err(|e| EngineError::NoSteadySolution(format!("even the design speed fails: {e}")))?;
    let dp = evaluate(model, inp, &design).point;
    let start = match inp.demand {
        Demand::PowerMw(_) => dp.power_mw,
        Demand::FuelKgS(_) => dp.fuel_kg_s,
        Demand::N1Rpm(_) => dp.n1_rpm,
    };
    let target = demand_value(inp.demand);
    let mut x = design;
    let mut s = 0.0_f64;
    let mut ds = 0.1_f64;
    while s < 1.0 {
        let s_try = (s + ds).min(1.0);
        let sub = SteadyInputs {
            demand: with_value(inp.demand, start + s_try * (target - start)),
            ..*inp
        };
        stats.continuation_steps += 1;
        match newton(model, &sub, x, stats) {
            Ok(xn) => {
                x = xn;
                s = s_try;
                ds = (ds * 1.5).min(0.25);
            }
            Err(e) => {
                ds *= 0.5;
                if ds < 1e-3 {
                    return Err(EngineError::NoSteadySolution(format!(
                        "no operating point for {:?} at {:.2} K, {:.3} kPa: continuation stopped at {:.1} % of the way ({e})",
                        inp.demand,
                        inp.t_amb_k,
                        inp.p_amb_kpa,
                        s * 100.0
                    )));
                }
            }
        }
    }
    Ok(evaluate(model, inp, &x).point)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::Engine;
    use crate::health::HealthParams;

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
            // Energy closure over the whole engine: fuel heat = exhaust enthalpy rise + PT shaft
            // work + the GG's net shaft work (its mechanical losses leave the gas path).
            let gas = m.consts.fuel.products(p.fuel_air_ratio);
            let air = crate::thermo::Gas::air();
            let c = &m.consts;
            let heat_in = c.fuel_heat_w(p.fuel_kg_s);
            let exhaust = p.pt_flow_kg_s * gas.h(p.t4_k) - p.air_flow_kg_s * air.h(p.t1_k);
            let shafts = (p.pt_power_mw + p.hpt_power_mw - p.compressor_power_mw) * 1e6;
            assert!(
                ((exhaust + shafts) - heat_in).abs() / heat_in < 1e-6,
                "{demand:?}: {exhaust} + {shafts} vs {heat_in}"
            );
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
        assert!(cold.evaluations > 4 * cold.newton_iterations, "{cold:?}");
        assert_eq!(solve(&m, &inp, None).expect("solves"), p);
        let (q, warm) = solve_with_stats(&m, &inp, Some(&p)).expect("solves");
        assert!(warm.newton_iterations <= 1, "{warm:?}");
        assert_eq!(warm.continuation_steps, 0);
        assert!((q.power_mw - p.power_mw).abs() < 1e-9);
    }
}
