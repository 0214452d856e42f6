//! Steady-state matching: given ambient, health and one operating demand, find the operating
//! point where the compressor, HPT and PT agree on flow and the GG shaft balances.
//!
//! Unknowns (normalised by design values): GG speed n1, compressor β, PT inlet pressure P34 and
//! fuel flow; one of them is fixed or replaced by the demand. Residuals: HPT flow compatibility,
//! PT flow compatibility, GG work balance, and (for a power demand) the power. Newton's method
//! with a finite-difference Jacobian, Broyden's updates of it and backtracking; far off-design
//! demands are reached by continuation from the design point, and past a fold of the demand
//! (near idle the fuel flow is not monotone in GG speed) by walking the running line in GG
//! speed. A demand beyond every running point is refused with the extreme point reached. Pure:
//! no I/O.

use super::effects::CoreView;
use super::gas_path::{self, Adjust, CompressorSetting, HotSection, Inputs, Stations};
use super::model::{EngineError, Model};
use serde::Serialize;

mod newton;
use newton::{newton, newton_at};

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
    let c = &model.consts;
    // The speeds, the PT inlet pressure and the ambient are the point's inputs; P2 and T3 need
    // the core's gas path, computed only when an effect reads it or carries states
    // (`Effect::reads_gas_path`); otherwise what must not be read is NaN.
    let mut core = CoreView {
        t_s: 0.0,
        n1_rpm: inp.n1_rpm,
        n2_rpm: inp.n2_rpm,
        p2_kpa: f64::NAN,
        t3_k: f64::NAN,
        p34_kpa: inp.p34_kpa,
        t_amb_k: inp.t_amb_k,
        p_amb_kpa: inp.p_amb_kpa,
        n1_design_rpm: c.n1_design,
        fuel_design_kg_s: c.fuel_design,
    };
    let mut y = effects.layout().zeros();
    if effects.reads_gas_path() {
        let base = gas_path::evaluate(model, inp, None).stations();
        core.p2_kpa = base.p2_kpa;
        core.t3_k = base.t3_k;
        effects.steady_states(&core, &base, &mut y);
    }
    Adjust {
        extra_bleed: effects.bleed(&core, &y),
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
        (gp.pt.w_kg_s - w3 - gp.w_return_kg_s) / wd,
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
        pt_flow_error_kg_s: gp.pt.w_kg_s - w3 - gp.w_return_kg_s,
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

/// The demand's value, in its unit.
pub(crate) fn demand_value(d: Demand) -> f64 {
    match d {
        Demand::PowerMw(v) | Demand::FuelKgS(v) | Demand::N1Rpm(v) => v,
    }
}

/// The same kind of demand at value `v`.
pub(crate) fn with_value(d: Demand, v: f64) -> Demand {
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
    if let Ok((_, point)) = newton_at(model, inp, x0, stats) {
        return Ok(point);
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
                    // The demand has a turning point on the way (near idle the fuel flow is
                    // not monotone in GG speed): walk the running line in speed instead.
                    return along_speed(model, inp, x, stats).map_err(|w| {
                        EngineError::NoSteadySolution(match w {
                            Walk::OutOfRange(why) => format!(
                                "{why}, at {:.2} K, {:.3} kPa, PT {:.0} rpm",
                                inp.t_amb_k, inp.p_amb_kpa, inp.n2_rpm
                            ),
                            Walk::Failed(why) => format!(
                                "no operating point for {:?} at {:.2} K, {:.3} kPa: continuation \
                                 stopped at {:.1} % of the way ({e}), and along the running line \
                                 in GG speed: {why}",
                                inp.demand,
                                inp.t_amb_k,
                                inp.p_amb_kpa,
                                s * 100.0
                            ),
                        })
                    });
                }
            }
        }
    }
    Ok(evaluate(model, inp, &x).point)
}

/// The demand's quantity at a solved point (fuel flow or power), with its name and unit.
fn demand_quantity(d: Demand, p: &SteadyPoint) -> (f64, &'static str, &'static str) {
    match d {
        Demand::FuelKgS(_) => (p.fuel_kg_s, "fuel", "kg/s"),
        Demand::PowerMw(_) => (p.power_mw, "power", "MW"),
        Demand::N1Rpm(_) => (p.n1_rpm, "GG speed", "rpm"),
    }
}

/// Why the walk along the running line found no point.
enum Walk {
    /// The demand lies beyond every running point the model has (the reason names the end).
    OutOfRange(String),
    /// A solve on the way failed.
    Failed(String),
}

/// Lowest and highest GG speed the running-line walk tries, as fractions of design speed.
const WALK_N1_RANGE: (f64, f64) = (0.1, 1.25);

/// Speed-continuation: the fuel flow (or power) of the running line is not monotone in GG
/// speed everywhere — near idle, where the compressor leaves its lowest speed line for the
/// sub-idle extension, the fuel flow has a local minimum and maximum, a fold where continuation
/// in the fuel demand cannot pass. GG speed is monotone along the running line, so this walks
/// it in speed from `x` (a solved point) towards the target, until the demand's quantity
/// crosses the target, then solves the demand from the nearer side of that crossing (the
/// crossing nearest `x` is the one taken). When the walk reaches the end of what the model
/// runs at without crossing, the reason names the extreme point reached.
fn along_speed(
    model: &Model,
    inp: &SteadyInputs,
    x: Unknowns,
    stats: &mut SolveStats,
) -> Result<SteadyPoint, Walk> {
    let target = demand_value(inp.demand);
    let n1d = model.consts.n1_design;
    let value = |u: &Unknowns| demand_quantity(inp.demand, &evaluate(model, inp, u).point).0;
    let v0 = value(&x);
    // Fuel and power rise with speed on the running line's whole: walk down for a lower target.
    let down = target < v0;
    let (mut prev_x, mut prev_v) = (x, v0);
    // The point with the demand's quantity nearest the target (the end of the model's range).
    let mut extreme = (v0, x.0[0] * n1d);
    let mut step = 0.02_f64;
    loop {
        let n1 = prev_x.0[0] + if down { -step } else { step };
        if !(WALK_N1_RANGE.0..=WALK_N1_RANGE.1).contains(&n1) {
            break;
        }
        let sub = SteadyInputs {
            demand: Demand::N1Rpm(n1 * n1d),
            ..*inp
        };
        stats.continuation_steps += 1;
        let Ok(xn) = newton(model, &sub, prev_x, stats) else {
            step *= 0.5;
            if step < 1e-4 {
                break;
            }
            continue;
        };
        let vn = value(&xn);
        if (down && vn < extreme.0) || (!down && vn > extreme.0) {
            extreme = (vn, n1 * n1d);
        }
        if (vn - target) * (prev_v - target) <= 0.0 {
            return solve_in_bracket(model, inp, (prev_x, prev_v), (xn, vn), stats)
                .map_err(Walk::Failed);
        }
        (prev_x, prev_v) = (xn, vn);
        step = (step * 1.5).min(0.05);
    }
    let (_, name, unit) = demand_quantity(inp.demand, &evaluate(model, inp, &x).point);
    let side = if down { "below" } else { "above" };
    let end = if down { "lowest" } else { "highest" };
    Err(Walk::OutOfRange(format!(
        "{name} {target:.3} {unit} is {side} the model's {end} running point at {:.3} {unit} \
         (N1 {:.0} rpm)",
        extreme.0, extreme.1
    )))
}

/// Solves the demand between two solved running-line points whose quantities bracket the
/// target: bisection in GG speed narrows the bracket, then Newton on the demand itself.
fn solve_in_bracket(
    model: &Model,
    inp: &SteadyInputs,
    a: (Unknowns, f64),
    b: (Unknowns, f64),
    stats: &mut SolveStats,
) -> Result<SteadyPoint, String> {
    let target = demand_value(inp.demand);
    let n1d = model.consts.n1_design;
    let (mut a, mut b) = (a, b);
    let mut last = String::from("no bisection step");
    for _ in 0..40 {
        // Newton on the demand from the bracket end nearer the target.
        let near = if (a.1 - target).abs() <= (b.1 - target).abs() {
            a.0
        } else {
            b.0
        };
        match newton(model, inp, near, stats) {
            Ok(x) => {
                let n1 = x.0[0];
                let (lo, hi) = (a.0 .0[0].min(b.0 .0[0]), a.0 .0[0].max(b.0 .0[0]));
                // Accept only the crossing inside the bracket (not another branch's).
                if n1 >= lo - 1e-9 && n1 <= hi + 1e-9 {
                    return Ok(evaluate(model, inp, &x).point);
                }
            }
            Err(e) => last = e,
        }
        let mid = 0.5 * (a.0 .0[0] + b.0 .0[0]);
        let sub = SteadyInputs {
            demand: Demand::N1Rpm(mid * n1d),
            ..*inp
        };
        let xm = newton(model, &sub, a.0, stats)?;
        let vm = demand_quantity(inp.demand, &evaluate(model, inp, &xm).point).0;
        if (vm - target) * (a.1 - target) <= 0.0 {
            b = (xm, vm);
        } else {
            a = (xm, vm);
        }
    }
    Err(format!("the running-line crossing was not solved ({last})"))
}

#[cfg(test)]
mod tests;
