//! Design-point cycle: from the reference engine's table and assumptions, the turbine inlet
//! temperature, fuel and air flow and every station at the design point (REFERENCE §1).
//!
//! The table fixes pressure ratio, compressor efficiency, exhaust flow and power; the cycle
//! assumptions fix losses and turbine efficiencies. T3 is the one unknown: it is found so that
//! the power at the PT coupling equals the table value. The map scalers are then derived from
//! this cycle in [`super::model::Engine::new`]. Pure arithmetic, no I/O; [`DesignCycles`]
//! keeps a few solved cycles so that an engine rebuilt with the same cycle numbers takes its
//! cycle over (the same numbers, less work).

use super::config::{AmbientConfig, DesignConfig, DynamicsConfig, EngineConfig, FuelConfig};
use super::cycle::ShaftLosses;
use super::error::EngineError;
use super::gas_path::{mixed_with_air, Stations, Stream};
use crate::thermo::{Fuel, Gas};
use std::sync::Mutex;

/// How many solved cycles [`DesignCycles`] keeps.
const KEPT_CYCLES: usize = 8;

/// Every number of an engine file the design cycle reads: the design table, the ambient, the
/// dynamics section (its shaft losses) and the fuel.
#[derive(Debug, Clone, PartialEq)]
struct CycleInputs {
    design: DesignConfig,
    ambient: AmbientConfig,
    dynamics: DynamicsConfig,
    fuel: Option<FuelConfig>,
}

impl CycleInputs {
    fn of(cfg: &EngineConfig) -> CycleInputs {
        CycleInputs {
            design: cfg.design.clone(),
            ambient: cfg.ambient.clone(),
            dynamics: cfg.dynamics.clone(),
            fuel: cfg.fuel.clone(),
        }
    }

    fn are_of(&self, cfg: &EngineConfig) -> bool {
        self.design == cfg.design
            && self.ambient == cfg.ambient
            && self.dynamics == cfg.dynamics
            && self.fuel == cfg.fuel
    }
}

/// The last few design cycles solved, each with the numbers it was solved from: an engine
/// rebuilt from a file whose cycle numbers are those of one of them takes that cycle over
/// instead of solving it again. Why: a calibration's Jacobian moves one number at a time,
/// mostly an adaptation curve's knot, which leaves the cycle as it was, and solving it again
/// was a tenth of a foreign unit's calibration time. The cycle is a pure function of those
/// numbers (compared exactly), so an engine is the same bit for bit with or without this; it
/// only saves the work. Shared between the threads of one problem (a lock held only to look
/// up or store).
#[derive(Debug, Default)]
pub(crate) struct DesignCycles {
    kept: Mutex<Vec<(CycleInputs, Stations)>>,
}

impl DesignCycles {
    /// Holding the cycle of `cfg`, already solved (`design`: an engine's own design point).
    pub(crate) fn with(cfg: &EngineConfig, design: &Stations) -> DesignCycles {
        DesignCycles {
            kept: Mutex::new(vec![(CycleInputs::of(cfg), *design)]),
        }
    }

    /// The design cycle of `cfg` ([`design_cycle`]), taken over when kept.
    pub(crate) fn cycle(&self, cfg: &EngineConfig, fuel: &Fuel) -> Result<Stations, EngineError> {
        if let Ok(kept) = self.kept.lock() {
            if let Some((_, s)) = kept.iter().find(|(k, _)| k.are_of(cfg)) {
                return Ok(*s);
            }
        }
        let solved = design_cycle(cfg, fuel)?;
        // A poisoned lock (a panic elsewhere) only costs the memo.
        if let Ok(mut kept) = self.kept.lock() {
            if kept.len() >= KEPT_CYCLES {
                kept.remove(0);
            }
            kept.push((CycleInputs::of(cfg), solved));
        }
        Ok(solved)
    }
}

/// Fuel flow for a given T3 at fixed total exhaust flow (fixed point, converges in a few steps):
/// W_air·h2 + W_f·(η_b·LHV + h_fuel) = (W_air + W_f)·h3, where of the exhaust flow less the
/// fuel the share `burnt_share` of the air went through the combustor (the rest was returned at
/// the HPT exit; 1 without returned air).
fn fuel_for_t3(
    cfg: &EngineConfig,
    fuel: &Fuel,
    w_total: f64,
    burnt_share: f64,
    h2: f64,
    t3: f64,
) -> (f64, f64, Gas) {
    let d = &cfg.design;
    let mut wf = 0.02 * w_total;
    let mut gas = fuel.products(0.02);
    let mut w_comb_air = w_total - wf;
    for _ in 0..50 {
        w_comb_air = (w_total - wf) * burnt_share;
        gas = fuel.products(wf / w_comb_air);
        let wf_new = w_comb_air * (gas.h(t3) - h2)
            / (d.combustion_efficiency * fuel.lhv() + fuel.sensible_enthalpy() - gas.h(t3));
        if (wf_new - wf).abs() < 1e-13 * w_total {
            wf = wf_new;
            break;
        }
        wf = wf_new;
    }
    (wf, w_comb_air, gas)
}

/// Computes the design cycle; fails if no T3 in 900–2400 K meets the power. The compressor's
/// map coordinates (β, surge margin) are left at 0: the map is scaled from this cycle, so the
/// caller fills them in afterwards.
pub(crate) fn design_cycle(cfg: &EngineConfig, fuel: &Fuel) -> Result<Stations, EngineError> {
    let d = &cfg.design;
    let air = Gas::air();
    let t1 = cfg.ambient.temperature_k;
    let p1 = cfg.ambient.pressure_kpa * (1.0 - d.inlet_loss_frac);
    let p2 = p1 * d.pressure_ratio;
    let h1 = air.h(t1);
    let h2s = air.h(air.isentropic_t(t1, d.pressure_ratio));
    let h2 = h1 + (h2s - h1) / d.compressor_efficiency;
    let t2 = air.t_from_h(h2);
    let p3 = p2 * (1.0 - d.combustor_loss_frac);
    let p4 = cfg.ambient.pressure_kpa * d.exhaust_back_pressure_ratio;
    let w_total = d.exhaust_flow_kg_s;
    // Shaft losses at design speed: the same law the steady and dynamic models use.
    let losses = ShaftLosses::from_config(cfg);
    let gg_friction = losses.gg_w(d.gg_speed_rpm);
    let pt_windage = losses.pt_w(d.pt_speed_rpm);

    // Everything that follows from a T3 guess.
    let eval = |t3: f64| -> Result<Stations, EngineError> {
        // Of the air leaving the compressor, the bleed goes overboard and the returned share
        // mixes in at the HPT exit: the exhaust carries the rest, the returned air and the fuel.
        // (`gas_path::combustor_air` is the forward rule: w_comb_air = w_comp (1 − bleed − return).)
        let kept = 1.0 - d.cooling_bleed_frac;
        let burnt_share = (kept - d.cooling_return_frac) / kept;
        let (wf, w_comb_air, gas) = fuel_for_t3(cfg, fuel, w_total, burnt_share, h2, t3);
        let w_comp = w_comb_air / (kept - d.cooling_return_frac);
        let w_return = w_comp * d.cooling_return_frac;
        let w_hpt = w_total - w_return; // the burnt air and the fuel (bit for bit w_total without return)
        let p_comp = w_comp * (h2 - h1);
        let p_hpt = (p_comp + gg_friction) / losses.gg_mechanical_efficiency;
        let h3 = gas.h(t3);
        let h34_hpt = h3 - p_hpt / w_hpt;
        let t34_hpt = gas.t_from_h(h34_hpt);
        let h34s = h3 - (h3 - h34_hpt) / d.hpt_efficiency;
        let t34s = gas.t_from_h(h34s);
        let hpt_pr = ((gas.phi(t3) - gas.phi(t34s)) / gas.r()).exp();
        let p34 = p3 / hpt_pr;
        let pt_pr = p34 / p4;
        if pt_pr <= 1.0 {
            return Err(EngineError::Calibration(format!(
                "T3 = {t3:.0} K leaves no expansion for the power turbine (P34/P4 = {pt_pr:.3})"
            )));
        }
        // The returned air mixes in at the HPT exit, as off design.
        let hpt_out = Stream {
            gas,
            w_kg_s: w_hpt,
            h: h34_hpt,
            t_k: t34_hpt,
        };
        let Stream {
            gas: pt_gas,
            h: h34,
            t_k: t34,
            ..
        } = mixed_with_air(fuel, hpt_out, w_return, h2);
        let t4s = pt_gas.isentropic_t(t34, 1.0 / pt_pr);
        let h4 = h34 - d.pt_efficiency * (h34 - pt_gas.h(t4s));
        let t4 = pt_gas.t_from_h(h4);
        let p_pt = w_total * (h34 - h4);
        let power = losses.pt_shaft(p_pt) - pt_windage;
        Ok(Stations {
            p_amb_kpa: cfg.ambient.pressure_kpa,
            n1_rpm: d.gg_speed_rpm,
            n2_rpm: d.pt_speed_rpm,
            t1_k: t1,
            p1_kpa: p1,
            t2_k: t2,
            p2_kpa: p2,
            t3_k: t3,
            p3_kpa: p3,
            t34_k: t34,
            p34_kpa: p34,
            t4_k: t4,
            p4_kpa: p4,
            air_flow_kg_s: w_comp,
            fuel_kg_s: wf,
            fuel_burnt_kg_s: wf,
            fuel_air_ratio: gas.far(),
            hpt_flow_kg_s: w_hpt,
            pt_flow_kg_s: w_total,
            power_mw: power / 1e6,
            pt_shaft_mw: power / 1e6,
            compressor_power_mw: p_comp / 1e6,
            hpt_power_mw: p_hpt / 1e6,
            pt_power_mw: p_pt / 1e6,
            pressure_ratio: d.pressure_ratio,
            hpt_pressure_ratio: hpt_pr,
            pt_pressure_ratio: pt_pr,
            compressor_efficiency: d.compressor_efficiency,
            hpt_efficiency: d.hpt_efficiency,
            pt_efficiency: d.pt_efficiency,
            compressor_beta: 0.0,
            surge_margin_pct: 0.0,
            starter_torque_n_m: 0.0,
        })
    };

    let target = d.power_mw;
    let residual = |t3: f64| -> f64 {
        match eval(t3) {
            Ok(dp) => dp.power_mw - target,
            Err(_) => -target,
        }
    };
    // Power rises monotonically with T3 here; bisection is robust and exact enough.
    let (mut lo, mut hi) = (900.0_f64, 2400.0_f64);
    if residual(lo) > 0.0 || residual(hi) < 0.0 {
        return Err(EngineError::Calibration(format!(
            "no turbine inlet temperature in {lo}–{hi} K gives {target} MW with these assumptions"
        )));
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if residual(mid) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
        if hi - lo < 1e-10 {
            break;
        }
    }
    eval(0.5 * (lo + hi))
}
