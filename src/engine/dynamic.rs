//! The dynamic engine model: state equations of REFERENCE §2 / paper §2.1.
//!
//! States (normalised by design values so one tolerance fits all): combustor plenum pressure P2
//! and gas temperature T3 (paper eq. 4–5, written with the full mass and energy balance of the
//! volume) and its fuel-air ratio (the burnt-gas composition the turbines see), HPT→PT duct
//! pressure P34, GG and PT speeds (eq. 6, written as torque balances so standstill is not
//! singular) and the fuel controller's integrator. With the composition a state, the fuel
//! controller (which may close a loop on PT power) is evaluated after the turbines without an
//! algebraic loop. The volume states make the
//! system stiff (filling times ~10 ms); see `integrator.rs` for how that is handled.
//! The compressor delivers into the combustor plenum at P2; the combustor pressure loss sits
//! between the plenum and the HPT. The exhaust back-pressure and inlet loss follow the flow.
//! Pure functions of (time, state, drive): no I/O, no hidden state.

use super::control::{FuelCommand, Measured, StarterCommand};
use super::cycle;
use super::model::Model;
use crate::thermo::Gas;
use std::f64::consts::PI;

/// Number of states.
pub const NX: usize = 7;
/// State indices.
pub const IX_P2: usize = 0;
pub const IX_T3: usize = 1;
pub const IX_P34: usize = 2;
pub const IX_N1: usize = 3;
pub const IX_N2: usize = 4;
pub const IX_FUEL_I: usize = 5;
pub const IX_FAR: usize = 6;
/// Scale of the fuel-air-ratio state.
pub const FAR_SCALE: f64 = 0.02;

/// State vector (normalised).
pub type State = [f64; NX];

/// Below this fraction of design GG speed the compressor's flow and work fade linearly to zero:
/// the maps' speed lines degenerate at standstill, and a machine at rest moves no air.
const STANDSTILL_FADE: f64 = 0.02;
/// PT speed fraction below which its gas torque is held at the value there (stall torque).
const PT_STALL_FRACTION: f64 = 0.1;
/// Speed below which torques are computed from power at this speed (rad/s), avoiding 1/ω.
const OMEGA_MIN: f64 = 2.0;

/// Everything outside the engine that drives it during one integration step.
#[derive(Debug, Clone, PartialEq)]
pub struct Drive {
    pub t_amb_k: f64,
    pub p_amb_kpa: f64,
    pub fuel: FuelCommand,
    pub starter: StarterCommand,
    /// Breaker closed: the grid holds the PT at synchronous speed.
    pub pt_locked: bool,
    /// Flame on (fuel burns). Without flame, fuel flow is zero.
    pub flame: bool,
}

/// All algebraic quantities at one instant: the station table of the running engine.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stations {
    pub n1_rpm: f64,
    pub n2_rpm: f64,
    pub t1_k: f64,
    pub p1_kpa: f64,
    pub t2_k: f64,
    pub p2_kpa: f64,
    pub t3_k: f64,
    pub p3_kpa: f64,
    pub t34_k: f64,
    pub p34_kpa: f64,
    pub t4_k: f64,
    pub p4_kpa: f64,
    pub air_kg_s: f64,
    pub fuel_kg_s: f64,
    pub hpt_flow_kg_s: f64,
    pub pt_flow_kg_s: f64,
    /// Electrical power delivered to the grid (0 while the breaker is open), MW.
    pub power_mw: f64,
    /// Power the PT delivers at its coupling, MW (net of windage).
    pub pt_shaft_mw: f64,
    pub surge_margin_pct: f64,
    pub compressor_eff: f64,
    pub hpt_eff: f64,
    pub pt_eff: f64,
    pub starter_torque_n_m: f64,
}

/// Normalisation of the states.
#[derive(Debug, Clone, Copy)]
pub struct Scales {
    pub p2: f64,
    pub t3: f64,
    pub p34: f64,
    pub n1: f64,
    pub n2: f64,
    pub fuel: f64,
}

impl Scales {
    pub fn of(model: &Model) -> Scales {
        let c = &model.consts;
        Scales {
            p2: c.p2_design_kpa,
            t3: c.t3_design_k,
            p34: c.p34_design_kpa,
            n1: c.n1_design,
            n2: c.n2_design,
            fuel: c.fuel_design,
        }
    }
}

/// The state of an engine at rest in ambient air.
pub fn standstill_state(model: &Model, t_amb_k: f64, p_amb_kpa: f64) -> State {
    let s = Scales::of(model);
    let mut y = [0.0; NX];
    y[IX_P2] = p_amb_kpa / s.p2;
    y[IX_T3] = t_amb_k / s.t3;
    y[IX_P34] = p_amb_kpa / s.p34;
    y
}

/// Evaluates the model: state derivatives (per second) and the station table.
pub fn evaluate(model: &Model, t: f64, y: &State, drive: &Drive) -> (State, Stations) {
    let c = &model.consts;
    let s = Scales::of(model);
    let p2 = y[IX_P2] * s.p2;
    let t3 = (y[IX_T3] * s.t3).max(150.0);
    let p34 = y[IX_P34] * s.p34;
    let n1 = y[IX_N1] * s.n1;
    let n2 = y[IX_N2] * s.n2;
    let t1 = drive.t_amb_k;
    let p_amb = drive.p_amb_kpa;

    // Compressor: PR is set by the plenum; the inlet loss depends on the flow it gives. The
    // coupling is weak (1 % loss at design), so the map is read once at the PR of a speed-based
    // inlet-loss guess and the loss then follows from that flow: the PR used differs from
    // P2/P1 by ~1e-4 relative at design and the resulting flow error is ~1e-5.
    let n1_map = n1.max(STANDSTILL_FADE * c.n1_design);
    let fade = (n1.max(0.0) / (STANDSTILL_FADE * c.n1_design)).min(1.0);
    let nc1 = cycle::corrected_speed(n1_map, t1);
    let p1_guess = p_amb * (1.0 - c.inlet_loss_frac * (n1 / c.n1_design).powi(2));
    let op = model.comp.at_pr(nc1, p2 / p1_guess);
    let p1 = c.p1(p_amb, op.wc_kg_s * fade);
    let comp = cycle::compressor_from_op(t1, p1, p2 / p1, &op);
    let w2 = comp.w_kg_s * fade;
    let p_comp = comp.power_w * fade;
    let w_air = w2 * (1.0 - c.bleed);

    // Combustor gas (composition is a state) and turbines, from states only.
    let far = (y[IX_FAR] * FAR_SCALE).clamp(0.0, 0.065);
    let gas = Gas::products(far);
    let p3 = c.p3(p2, w2.max(0.0), comp.t_out_k);
    let hpt = cycle::turbine(&model.hpt, &gas, t3, p3, n1.max(0.0), p3 / p34);
    let w3 = hpt.w_kg_s;
    let p4 = c.p4(p_amb, w3, hpt.t_out_k);
    // The PT's gas torque is largest at stall; the map's efficiency (and so P/ω) is meaningless
    // there, so the torque is evaluated at no less than PT_STALL_FRACTION of design speed and
    // held constant below it (a turbine's torque-speed line is nearly flat near stall).
    let n2_eval = n2.max(PT_STALL_FRACTION * c.n2_design);
    let pt = cycle::turbine(&model.pt, &gas, hpt.t_out_k, p34, n2_eval, p34 / p4);
    let w4 = pt.w_kg_s;
    let pt_gas_torque = c.eta_m * pt.power_w / (n2_eval * PI / 30.0);
    let pt_net = pt_gas_torque * n2.max(0.0) * PI / 30.0 - c.pt_loss_w(n2.max(0.0));

    // Fuel control, now that every measured quantity it may look at is known.
    let meas = Measured {
        p2_kpa: p2,
        n1_rpm: n1,
        n2_rpm: n2,
        power_mw: pt_net / 1e6,
    };
    let cmd = drive.fuel.evaluate(t, y[IX_FUEL_I] * s.fuel, &meas);
    let wf = if drive.flame { cmd.fuel_kg_s } else { 0.0 };

    // Combustor volume: mass, energy and species balance (paper eq. 4–5 in full form).
    let r = gas.r();
    let m = p2 * 1e3 * c.v_comb / (r * t3);
    let dm = w_air + wf - w3;
    let h3 = gas.h(t3);
    let u3 = h3 - r * t3;
    let d_energy = w_air * comp.h_out + wf * c.eta_b * c.lhv - w3 * h3 - u3 * dm;
    let dt3 = d_energy / (m * gas.cv(t3));
    let dp2 = p2 * (dm / m + dt3 / t3);
    // Burnt-fuel mass fraction b = far/(1+far): m db/dt = wf − b (w_air + wf).
    let b = far / (1.0 + far);
    let db = (wf - b * (w_air + wf)) / m;
    let dfar = db * (1.0 + far) * (1.0 + far);
    // Duct: isothermal filling (paper eq. 4 form) at the HPT exit temperature.
    let dp34 = r * hpt.t_out_k * (w3 - w4) / (c.v_duct * 1e3);

    // GG shaft: torque balance (eq. 6 is the same written with power and n).
    let w1 = n1 * PI / 30.0;
    let starter_tq = drive.starter.torque(n1);
    let aero = c.eta_m * hpt.power_w - p_comp - c.gg_loss_w(n1);
    let tq1 = aero / w1.max(OMEGA_MIN) + starter_tq;
    let mut dn1 = tq1 / c.gg_inertia * 30.0 / PI;
    if n1 <= 0.0 && dn1 < 0.0 {
        dn1 = 0.0;
    }

    // PT shaft: locked to the grid once the breaker closes; static friction until break-away.
    let w2r = n2.max(0.0) * PI / 30.0;
    let dn2 = if drive.pt_locked {
        0.0
    } else {
        let tq2 = pt_gas_torque - c.pt_loss_w(n2.max(0.0)) / w2r.max(OMEGA_MIN);
        if n2 <= 0.5 && pt_gas_torque < c.pt_breakaway_nm {
            0.0
        } else {
            tq2 / c.pt_inertia * 30.0 / PI
        }
    };

    let dfi = cmd.integrator_rate;

    let mut dy = [0.0; NX];
    dy[IX_P2] = dp2 / s.p2;
    dy[IX_T3] = dt3 / s.t3;
    dy[IX_P34] = dp34 / s.p34;
    dy[IX_N1] = dn1 / s.n1;
    dy[IX_N2] = dn2 / s.n2;
    dy[IX_FUEL_I] = dfi / s.fuel;
    dy[IX_FAR] = dfar / FAR_SCALE;

    let st = Stations {
        n1_rpm: n1,
        n2_rpm: n2,
        t1_k: t1,
        p1_kpa: p1,
        t2_k: comp.t_out_k,
        p2_kpa: p2,
        t3_k: t3,
        p3_kpa: p3,
        t34_k: hpt.t_out_k,
        p34_kpa: p34,
        t4_k: pt.t_out_k,
        p4_kpa: p4,
        air_kg_s: w2,
        fuel_kg_s: wf,
        hpt_flow_kg_s: w3,
        pt_flow_kg_s: w4,
        power_mw: if drive.pt_locked { pt_net / 1e6 } else { 0.0 },
        pt_shaft_mw: pt_net / 1e6,
        surge_margin_pct: comp.surge_margin_pct,
        compressor_eff: comp.eff,
        hpt_eff: hpt.eff,
        pt_eff: pt.eff,
        starter_torque_n_m: starter_tq,
    };
    (dy, st)
}
