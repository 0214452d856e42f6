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

use super::control::{Feedback, FuelCommand, Series, StarterCommand};
use super::effects::{Context, CoreView};
pub(crate) use super::gas_path::Stations;
use super::gas_path::{self, Adjust, CompressorSetting, GasPath, HotSection, Inputs};
use super::load::PtLoad;
use super::model::Model;
pub(crate) use super::state::{
    Scales, State, FAR_SCALE, IX_FAR, IX_FUEL_I, IX_N1, IX_N2, IX_P2, IX_P34, IX_T3,
};
use std::f64::consts::PI;
use std::sync::Arc;

/// Speed below which torques are computed from power at this speed (rad/s), avoiding 1/ω.
const OMEGA_MIN: f64 = 2.0;

/// Time constant with which the model's PT speed is pulled onto an imposed (measured) speed
/// trace, s: short against the trace's own changes, long against the integrator's steps.
const PT_SPEED_TRACKING_TAU_S: f64 = 0.2;

/// Everything outside the engine that drives it during one integration step.
#[derive(Debug, Clone, PartialEq)]
pub struct Drive {
    pub t_amb_k: f64,
    pub p_amb_kpa: f64,
    pub fuel: FuelCommand,
    pub starter: StarterCommand,
    /// Breaker closed: the grid holds the PT at synchronous speed.
    pub pt_locked: bool,
    /// A mechanical load on the PT (`[load] mode = "load_law"` or `"table"`): while the PT is
    /// not locked it absorbs `P_load(n2)`, and the station table's `power_mw` is that power.
    /// `None`: generator or measured speed (an unloaded PT until the breaker closes; the core
    /// arithmetic is then unchanged).
    pub pt_load: Option<PtLoad>,
    /// The PT speed the load imposes (`[load] mode = "measured_speed"`: the measured trace of a
    /// recorded start-up, smoothed): while the breaker is open the model's PT follows it,
    /// `dn2/dt = dn2_meas/dt + (n2_meas − n2)/τ`, and the station table's `power_mw` is what
    /// the load takes, `P_PT,net − J2 ω dω/dt`. `None`: the PT speed is a free state.
    pub pt_speed: Option<Arc<Series>>,
    /// Flame on (fuel burns). Without flame, fuel flow is zero.
    pub flame: bool,
}

impl Drive {
    /// Whether `other` drives the model exactly as this one does, shared series compared by
    /// identity (cheap, and never wrongly the same): then f at a point is the same under both.
    pub(crate) fn same_as(&self, other: &Drive) -> bool {
        self.t_amb_k == other.t_amb_k
            && self.p_amb_kpa == other.p_amb_kpa
            && self.fuel.same_as(&other.fuel)
            && self.starter == other.starter
            && self.pt_locked == other.pt_locked
            && self.pt_load == other.pt_load
            && match (&self.pt_speed, &other.pt_speed) {
                (None, None) => true,
                (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                _ => false,
            }
            && self.flame == other.flame
    }
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

/// The core states in physical units, as the effects' hooks see them.
fn core_view(model: &Model, t: f64, y: &State, drive: &Drive) -> CoreView {
    let c = &model.consts;
    let s = Scales::of(model);
    CoreView {
        t_s: t,
        n1_rpm: y[IX_N1] * s.n1,
        n2_rpm: y[IX_N2] * s.n2,
        p2_kpa: y[IX_P2] * s.p2,
        t3_k: (y[IX_T3] * s.t3).max(150.0),
        p34_kpa: y[IX_P34] * s.p34,
        t_amb_k: drive.t_amb_k,
        p_amb_kpa: drive.p_amb_kpa,
        n1_design_rpm: c.n1_design,
        fuel_design_kg_s: c.fuel_design,
    }
}

/// The state of an engine at rest in ambient air (the model's layout: core and effect states).
pub(crate) fn standstill_state(model: &Model, t_amb_k: f64, p_amb_kpa: f64) -> State {
    warm_standstill_state(model, t_amb_k, p_amb_kpa, t_amb_k)
}

/// The state of an engine at rest whose hot section (the gas in it and, for effects with metal
/// states, the metal around it: at rest both are at one temperature) is at `hot_section_k`:
/// ambient after a long stop, warmer soon after a run or a trip.
pub(crate) fn warm_standstill_state(
    model: &Model,
    t_amb_k: f64,
    p_amb_kpa: f64,
    hot_section_k: f64,
) -> State {
    let s = Scales::of(model);
    let mut y = model.effects.layout().zeros();
    y[IX_P2] = p_amb_kpa / s.p2;
    y[IX_T3] = hot_section_k.max(t_amb_k) / s.t3;
    y[IX_P34] = p_amb_kpa / s.p34;
    if !model.effects.is_empty() {
        let rest = Drive {
            t_amb_k,
            p_amb_kpa,
            fuel: FuelCommand::Off,
            starter: StarterCommand::Off,
            pt_locked: false,
            pt_load: None,
            pt_speed: None,
            flame: false,
        };
        let core = core_view(model, 0.0, &y, &rest);
        model.effects.rest_states(&core, &mut y);
    }
    y
}

/// The gas path of one right-hand-side evaluation, kept for later evaluations whose gas-path
/// inputs are bit for bit the same: of the integrator's finite-difference Jacobian columns, the
/// fuel controller's integrator and time move only the control and balance arithmetic after
/// the gas path (the most expensive part of an evaluation). Owned by the caller (one per
/// integration step), holds the first evaluation it sees, and is used only by the core model
/// (with effects on, their hooks may read time and any state).
/// Its compressor stage is kept the same way for the columns that leave the compressor's
/// inputs as they were.
#[derive(Default)]
pub(crate) struct GasPathMemo {
    entry: Option<(GasPathKey, PlenumGas, GasPath)>,
    compressor: gas_path::CompressorMemo,
}

/// What the plenum's balances need of its gas: the gas constant and cv at T3.
#[derive(Clone, Copy)]
struct PlenumGas {
    r: f64,
    cv_t3: f64,
}

/// The gas path's inputs in [`core_rhs`], as bits (exact equality, NaN included).
#[derive(PartialEq, Eq, Clone, Copy)]
struct GasPathKey([u64; 8]);

impl GasPathKey {
    fn of(v: [f64; 8]) -> GasPathKey {
        GasPathKey(v.map(f64::to_bits))
    }
}

/// Evaluates the model: state derivatives (per second) and the station table.
pub(crate) fn evaluate(model: &Model, t: f64, y: &State, drive: &Drive) -> (State, Stations) {
    core_rhs(model, t, y, drive, None, |mut dy, rhs| {
        let st = rhs.stations(drive);
        rhs.effect_derivatives(model, y, &st, &mut dy);
        (dy, st)
    })
}

/// The state derivatives alone (per second): what the integrator calls. The same code as
/// [`evaluate`], compiled separately so the station table it does not need is never built
/// (unless an effect's derivatives read it).
/// The gas path is taken from `memo` when its inputs are unchanged (and this evaluation's is
/// stored when the memo is empty); the results are the same either way.
pub(crate) fn derivatives(
    model: &Model,
    t: f64,
    y: &State,
    drive: &Drive,
    memo: &mut GasPathMemo,
) -> State {
    core_rhs(model, t, y, drive, Some(memo), |mut dy, rhs| {
        if rhs.core.is_some() {
            let st = rhs.stations(drive);
            rhs.effect_derivatives(model, y, &st, &mut dy);
        }
        dy
    })
}

/// What the core right-hand side hands on besides the core derivatives: the station table's
/// ingredients and the effects' view. Borrowed, not moved: copying the gas path around cost
/// a few per cent of a simulation.
struct CoreRhs<'a> {
    gp: &'a GasPath,
    core: Option<CoreView>,
    wf_metered: f64,
    wf: f64,
    starter_tq: f64,
    /// Power the PT's load takes while the breaker is open, W.
    load_w: f64,
}

impl CoreRhs<'_> {
    #[inline(always)]
    fn stations(&self, drive: &Drive) -> Stations {
        let mut st = self.gp.stations();
        st.fuel_kg_s = self.wf_metered;
        st.fuel_burnt_kg_s = self.wf;
        if !drive.pt_locked {
            // Open breaker: no electrical power; a mechanical load absorbs its curve's power,
            // a speed-setting load what the PT delivers beyond accelerating itself.
            st.power_mw = self.load_w / 1e6;
        }
        st.starter_torque_n_m = self.starter_tq;
        st
    }

    #[inline(always)]
    fn effect_derivatives(&self, model: &Model, y: &State, st: &Stations, dy: &mut State) {
        if let Some(cv) = &self.core {
            let ctx = Context {
                core: cv,
                stations: st,
                metered_fuel_kg_s: self.wf_metered,
            };
            model.effects.derivatives(&ctx, y, dy);
        }
    }
}

/// The core model's right-hand side; `finish` gets the core derivatives and what the station
/// table and the effects' own derivatives need.
#[inline(always)]
fn core_rhs<R>(
    model: &Model,
    t: f64,
    y: &State,
    drive: &Drive,
    memo: Option<&mut GasPathMemo>,
    finish: impl FnOnce(State, &CoreRhs<'_>) -> R,
) -> R {
    let c = &model.consts;
    let s = Scales::of(model);
    let p2 = y[IX_P2] * s.p2;
    let t3 = (y[IX_T3] * s.t3).max(150.0);
    let p34 = y[IX_P34] * s.p34;
    let n1 = y[IX_N1] * s.n1;
    let n2 = y[IX_N2] * s.n2;
    let effects = &model.effects;
    // With no effect on, every hook is skipped: the arithmetic is the core model's alone.
    let core = (!effects.is_empty()).then(|| core_view(model, t, y, drive));
    let adjust = core.as_ref().map(|cv| Adjust {
        extra_bleed: effects.bleed(cv, y),
        deltas: effects.component_deltas(cv, y),
        losses: effects.duct_losses(cv, y),
    });

    // The gas path from the states: compressor into the plenum at P2, turbines on the
    // plenum's gas (temperature and composition are states).
    let far_gas = (y[IX_FAR] * FAR_SCALE).clamp(0.0, gas_path::MAX_FAR);
    let gas_path_of = |compressor: Option<&mut gas_path::CompressorMemo>| {
        let gas = c.fuel.products(far_gas);
        let gp = gas_path::evaluate_with(
            model,
            &Inputs {
                t_amb_k: drive.t_amb_k,
                p_amb_kpa: drive.p_amb_kpa,
                n1_rpm: n1,
                n2_rpm: n2,
                p34_kpa: p34,
                compressor: CompressorSetting::Plenum { p2_kpa: p2 },
                hot: HotSection::Plenum {
                    t3_k: t3,
                    gas: &gas,
                },
            },
            adjust.as_ref(),
            compressor,
        );
        // Of the gas itself the balances need two numbers: keeping them rather than the gas
        // (42 coefficients) spares a 336-byte copy per evaluation.
        (
            PlenumGas {
                r: gas.r(),
                cv_t3: gas.cv(t3),
            },
            gp,
        )
    };
    let fresh;
    let (pg, gp): (&PlenumGas, &GasPath) = match memo {
        Some(memo) if core.is_none() => {
            let key =
                GasPathKey::of([drive.t_amb_k, drive.p_amb_kpa, n1, n2, p34, p2, t3, far_gas]);
            match &mut memo.entry {
                Some((k, pg, gp)) if *k == key => (pg, gp),
                Some(_) => {
                    fresh = gas_path_of(Some(&mut memo.compressor));
                    (&fresh.0, &fresh.1)
                }
                slot @ None => {
                    let (pg, gp) = gas_path_of(Some(&mut memo.compressor));
                    let (_, pg, gp) = slot.insert((key, pg, gp));
                    (pg, gp)
                }
            }
        }
        _ => {
            fresh = gas_path_of(None);
            (&fresh.0, &fresh.1)
        }
    };
    let w_air = gp.w_combustor_air_kg_s;
    let w3 = gp.hpt.w_kg_s;
    let w4 = gp.pt.w_kg_s;
    let pt_gas_torque = gp.pt_gas_torque_n_m;

    // Fuel control, now that every quantity it may look at is known.
    let feedback = Feedback {
        p2_kpa: p2,
        n1_rpm: n1,
        n2_rpm: n2,
        power_mw: gp.pt_net_w / 1e6,
    };
    let cmd = drive.fuel.evaluate(t, y[IX_FUEL_I] * s.fuel, &feedback);
    let wf_metered = if drive.flame { cmd.fuel_kg_s } else { 0.0 };
    let wf = match (&core, drive.flame) {
        (Some(cv), true) => effects.fuel_delivered(wf_metered, cv, y).max(0.0),
        _ => wf_metered,
    };

    // Combustor volume: mass, energy and species balance (paper eq. 4–5 in full form).
    let r = pg.r;
    let m = p2 * 1e3 * c.v_comb / (r * t3);
    let dm = w_air + wf - w3;
    // h(T3) of this gas: the HPT's inlet enthalpy (the same call on the same numbers).
    let h3 = gp.hpt.h_in;
    let u3 = h3 - r * t3;
    let mut d_energy = w_air * gp.compressor.h_out + c.fuel_heat_w(wf) - w3 * h3 - u3 * dm;
    if let Some(cv) = &core {
        d_energy -= effects.heat_to_metal_w(cv, y);
    }
    let dt3 = d_energy / (m * pg.cv_t3);
    let dp2 = p2 * (dm / m + dt3 / t3);
    // Burnt-fuel mass fraction b = far/(1+far): m db/dt = wf − b (w_air + wf).
    let far = (y[IX_FAR] * FAR_SCALE).clamp(0.0, gas_path::MAX_FAR);
    let b = far / (1.0 + far);
    let db = (wf - b * (w_air + wf)) / m;
    let dfar = db * (1.0 + far) * (1.0 + far);
    // Duct: isothermal filling (paper eq. 4 form) at the PT inlet's temperature, the returned
    // cooling air (if any) flowing in beside the HPT's gas.
    let dp34 = r * gp.t34_k * (w3 + gp.w_return_kg_s - w4) / (c.v_duct * 1e3);

    // GG shaft: torque balance (eq. 6 is the same written with power and n).
    let w1 = n1 * PI / 30.0;
    let starter_tq = drive.starter.torque(n1);
    let tq1 = gp.gg_net_w / w1.max(OMEGA_MIN) + starter_tq;
    let mut dn1 = tq1 / c.gg_inertia * 30.0 / PI;
    if n1 <= 0.0 && dn1 < 0.0 {
        dn1 = 0.0;
    }

    // PT shaft: locked to the grid once the breaker closes; following the speed a load sets;
    // static friction until break-away; a mechanical load brakes it with P_load(n2)/ω.
    let w2r = n2.max(0.0) * PI / 30.0;
    let (dn2, load_w) = if drive.pt_locked {
        (0.0, 0.0)
    } else if let Some(trace) = &drive.pt_speed {
        let dn2 = trace.slope(t) + (trace.value(t) - n2) / PT_SPEED_TRACKING_TAU_S;
        let accel_w = c.pt_inertia * w2r * dn2 * PI / 30.0;
        (dn2, gp.pt_net_w - accel_w)
    } else {
        let mut tq2 = pt_gas_torque - c.pt_loss_w(n2.max(0.0)) / w2r.max(OMEGA_MIN);
        let load_w = drive.pt_load.as_ref().map_or(0.0, |l| l.power_w(n2));
        tq2 -= load_w / w2r.max(OMEGA_MIN);
        if n2 <= 0.5 && pt_gas_torque < c.pt_breakaway_nm {
            (0.0, load_w)
        } else {
            (tq2 / c.pt_inertia * 30.0 / PI, load_w)
        }
    };

    let dfi = cmd.integrator_rate;

    let mut dy = effects.layout().zeros();
    dy[IX_P2] = dp2 / s.p2;
    dy[IX_T3] = dt3 / s.t3;
    dy[IX_P34] = dp34 / s.p34;
    dy[IX_N1] = dn1 / s.n1;
    dy[IX_N2] = dn2 / s.n2;
    dy[IX_FUEL_I] = dfi / s.fuel;
    dy[IX_FAR] = dfar / FAR_SCALE;

    finish(
        dy,
        &CoreRhs {
            gp,
            core,
            wf_metered,
            wf,
            starter_tq,
            load_w,
        },
    )
}
