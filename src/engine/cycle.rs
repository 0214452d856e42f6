//! Component station calculations shared by the steady-state solver and the dynamic model.
//!
//! Each function takes the inlet state and the component's operating coordinate and returns the
//! exit state, flow and power: compressor and turbines through their scaled maps, work from
//! enthalpy differences (never constant cp). Pure functions of their arguments: no state, no I/O.

use crate::maps::{ScaledCompressor, ScaledTurbine};
use crate::thermo::Gas;

/// Shaft losses: each shaft's mechanical efficiency (the fraction of its turbine's gas power
/// that reaches the shaft, GasTurb/GSP convention), and outside it GG bearings and windage ∝ n²,
/// PT and generator windage ∝ n³, and a smooth Coulomb bearing torque on each shaft. One law for
/// the design cycle, the steady solver and the dynamic model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShaftLosses {
    /// Gas-generator shaft mechanical efficiency, (0, 1].
    pub gg_mechanical_efficiency: f64,
    /// Power-turbine shaft mechanical efficiency, (0, 1].
    pub pt_mechanical_efficiency: f64,
    pub gg_friction_w: f64,
    pub pt_windage_w: f64,
    pub gg_bearing_nm: f64,
    pub pt_bearing_nm: f64,
    pub n1_design: f64,
    pub n2_design: f64,
}

impl ShaftLosses {
    /// The losses an engine file states.
    pub fn from_config(cfg: &super::config::EngineConfig) -> ShaftLosses {
        let dy = &cfg.dynamics;
        ShaftLosses {
            gg_mechanical_efficiency: cfg.design.gg_mechanical_efficiency,
            pt_mechanical_efficiency: cfg.design.pt_mechanical_efficiency,
            gg_friction_w: dy.gg_friction_kw_at_design * 1e3,
            pt_windage_w: dy.pt_windage_kw_at_sync * 1e3,
            gg_bearing_nm: dy.gg_bearing_torque_n_m,
            pt_bearing_nm: dy.pt_bearing_torque_n_m,
            n1_design: cfg.design.gg_speed_rpm,
            n2_design: cfg.design.pt_speed_rpm,
        }
    }
    /// HPT gas power reaching the GG shaft, W.
    #[inline]
    pub fn gg_shaft_w(&self, hpt_gas_power_w: f64) -> f64 {
        self.gg_mechanical_efficiency * hpt_gas_power_w
    }
    /// PT gas power (or torque) reaching the PT shaft.
    #[inline]
    pub fn pt_shaft(&self, pt_gas: f64) -> f64 {
        self.pt_mechanical_efficiency * pt_gas
    }
    /// Smooth Coulomb bearing torque (N·m): full value above ~50 rpm, zero at rest.
    #[inline]
    fn bearing_torque(torque: f64, n: f64) -> f64 {
        torque * (n / 20.0).tanh()
    }
    /// All GG shaft losses outside the mechanical efficiency, W.
    #[inline]
    pub fn gg_w(&self, n1: f64) -> f64 {
        let r = n1 / self.n1_design;
        self.gg_friction_w * r * r
            + Self::bearing_torque(self.gg_bearing_nm, n1) * n1 * std::f64::consts::PI / 30.0
    }
    /// All PT + generator losses outside the mechanical efficiency, W.
    #[inline]
    pub fn pt_w(&self, n2: f64) -> f64 {
        let r = n2.max(0.0) / self.n2_design;
        self.pt_windage_w * r * r * r
            + Self::bearing_torque(self.pt_bearing_nm, n2) * n2 * std::f64::consts::PI / 30.0
    }
}

/// Highest fuel-air ratio the combustor gas may have (the engine's rich limit; the gas tables
/// reach further, see `thermo::FAR_MAX`).
pub(crate) const MAX_FAR: f64 = 0.065;

/// ISO reference temperature and pressure for corrected quantities.
pub(crate) const T_STD_K: f64 = 288.15;
pub(crate) const P_STD_KPA: f64 = 101.325;

/// Corrected speed N/√θ.
#[inline]
pub(crate) fn corrected_speed(n_rpm: f64, t_k: f64) -> f64 {
    n_rpm / (t_k / T_STD_K).sqrt()
}

/// Physical flow from corrected flow: W = Wc·δ/√θ.
#[inline]
pub(crate) fn physical_flow(wc: f64, t_k: f64, p_kpa: f64) -> f64 {
    wc * (p_kpa / P_STD_KPA) / (t_k / T_STD_K).sqrt()
}

/// Compressor exit state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CompressorStation {
    pub(crate) w_kg_s: f64,
    pub(crate) wc_kg_s: f64,
    pub(crate) pr: f64,
    pub(crate) t_out_k: f64,
    pub(crate) h_in: f64,
    pub(crate) h_out: f64,
    pub(crate) eff: f64,
    pub(crate) beta: f64,
    pub(crate) surge_margin_pct: f64,
    pub(crate) power_w: f64,
}

/// Compressor exit state from an already evaluated map point, at pressure ratio `pr` (the
/// dynamic model: PR set by the plenum).
pub(crate) fn compressor_from_op(
    t_in: f64,
    p_in_kpa: f64,
    pr: f64,
    op: &crate::maps::CompressorOp,
) -> CompressorStation {
    compressor_finish(
        t_in,
        p_in_kpa,
        pr,
        op.wc_kg_s,
        op.eff,
        op.beta,
        op.surge_margin_pct,
    )
}

/// Compressor on its map at a given β (steady solver: β is an unknown).
pub(crate) fn compressor_at_beta(
    comp: &ScaledCompressor,
    t_in: f64,
    p_in_kpa: f64,
    n_rpm: f64,
    beta: f64,
) -> CompressorStation {
    let nc = corrected_speed(n_rpm, t_in);
    let op = comp.at_beta(nc, beta);
    compressor_finish(
        t_in,
        p_in_kpa,
        op.pr,
        op.wc_kg_s,
        op.eff,
        op.beta,
        op.surge_margin_pct,
    )
}

fn compressor_finish(
    t_in: f64,
    p_in_kpa: f64,
    pr: f64,
    wc: f64,
    eff: f64,
    beta: f64,
    surge_margin_pct: f64,
) -> CompressorStation {
    // A reference to one constant: `Gas::air()` by value copied its 340 bytes on every call.
    const AIR: Gas = Gas::AIR;
    let air = &AIR;
    let h_in = air.h(t_in);
    let t_is = air.isentropic_t(t_in, pr.max(1e-6));
    let h_is = air.h(t_is);
    let h_out = h_in + (h_is - h_in) / eff;
    let t_out = air.t_from_h_near(h_out, t_is, h_is);
    let w = physical_flow(wc, t_in, p_in_kpa);
    CompressorStation {
        w_kg_s: w,
        wc_kg_s: wc,
        pr,
        t_out_k: t_out,
        h_in,
        h_out,
        eff,
        beta,
        surge_margin_pct,
        power_w: w * (h_out - h_in),
    }
}

/// Turbine exit state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TurbineStation {
    pub(crate) w_kg_s: f64,
    pub(crate) wc_kg_s: f64,
    pub(crate) pr: f64,
    pub(crate) t_out_k: f64,
    pub(crate) h_in: f64,
    pub(crate) h_out: f64,
    pub(crate) eff: f64,
    pub(crate) power_w: f64,
}

/// Turbine on its map at expansion ratio `pr = p_in/p_out` (≥ 1 for expansion); `gg_nc_rpm`,
/// the gas generator's corrected speed at the compressor inlet, is where adaptation curves read
/// at that reference are read (`maps::CurveSpeed`).
pub(crate) fn turbine(
    turb: &ScaledTurbine,
    gas: &Gas,
    t_in: f64,
    p_in_kpa: f64,
    n_rpm: f64,
    pr: f64,
    gg_nc_rpm: f64,
) -> TurbineStation {
    let nc = corrected_speed(n_rpm, t_in);
    let op = turb.at_pr_ref(nc, gg_nc_rpm, pr);
    let h_in = gas.h(t_in);
    // Below PR 1 the map's linear law gives reverse flow; the gas then does no work.
    let t_is = gas.isentropic_t(t_in, 1.0 / pr.max(1.0));
    let h_is = gas.h(t_is);
    let h_out = h_in - op.eff * (h_in - h_is);
    let t_out = gas.t_from_h_near(h_out, t_is, h_is);
    let w = physical_flow(op.wc_kg_s, t_in, p_in_kpa);
    TurbineStation {
        w_kg_s: w,
        wc_kg_s: op.wc_kg_s,
        pr,
        t_out_k: t_out,
        h_in,
        h_out,
        eff: op.eff,
        power_w: w.max(0.0) * (h_in - h_out),
    }
}

/// Combustor exit temperature from an adiabatic energy balance (steady state):
/// W_air·h2 + W_f·(η_b·LHV + h_fuel) = (W_air + W_f)·h3 with sensible enthalpies referenced to
/// 288.15 K, the products those of the engine's fuel ([`super::model::Constants::fuel_heat_w`]).
pub(crate) fn combustor_exit_temperature(
    c: &super::model::Constants,
    w_air: f64,
    h2: f64,
    w_fuel: f64,
) -> (f64, Gas) {
    let far = if w_air > 0.0 {
        (w_fuel / w_air).clamp(0.0, MAX_FAR)
    } else {
        0.0
    };
    let gas = c.fuel.products(far);
    let h3 = (w_air * h2 + c.fuel_heat_w(w_fuel)) / (w_air + w_fuel);
    (gas.t_from_h(h3), gas)
}
