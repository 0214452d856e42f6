//! The gas path, once: inlet loss → compressor → bleed → combustor → HPT → duct → PT → exhaust,
//! computed into one station table ([`Stations`]) that the design point, a steady operating
//! point and an instant of a transient all share, and the one mapping from that table to the
//! measured signals ([`signal_value`]).
//!
//! The steady solver and the dynamic model differ only in what fixes the compressor's operating
//! point (its map β, or the plenum pressure P2 a volume state holds) and the hot section (an
//! adiabatic burn of a given fuel flow, or the plenum's temperature and composition states);
//! everything downstream — loss laws, bleed, turbine maps, the PT stall-torque rule, shaft
//! losses — is this file. The design calibration uses the same laws and constants
//! ([`MAX_FAR`], [`combustor_air`]) and reports its cycle in the same table.
//! Pure: no I/O, no state.

use super::cycle::{self, CompressorStation, TurbineStation};
use super::effects::{ComponentDeltas, DuctLosses, ExtraBleed};
use super::model::Model;
use crate::signals::{Signal, Values, NSIG};
use crate::thermo::{Fuel, Gas};
use std::f64::consts::PI;

pub(crate) use super::cycle::MAX_FAR;
/// Below this fraction of design GG speed the compressor's flow and work fade linearly to zero:
/// the maps' speed lines degenerate at standstill, and a machine at rest moves no air.
pub(crate) const STANDSTILL_FADE: f64 = 0.02;
/// PT speed fraction below which its gas torque is held at the value there (stall torque).
pub(crate) const PT_STALL_FRACTION: f64 = 0.1;

/// The station table: every station and component quantity of the engine at one operating
/// point, whether the design point, a steady point or an instant of a transient.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Stations {
    /// Ambient (static) pressure the inlet draws from, kPa.
    pub p_amb_kpa: f64,
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
    /// Compressor inlet air flow, kg/s.
    pub air_flow_kg_s: f64,
    /// Fuel flow as metered (what the controller commands and the flowmeter reads), kg/s.
    pub fuel_kg_s: f64,
    /// Fuel flow burning in the combustor, kg/s (the metered flow unless an effect delays it).
    pub fuel_burnt_kg_s: f64,
    pub fuel_air_ratio: f64,
    /// Gas flow through the HPT, kg/s.
    pub hpt_flow_kg_s: f64,
    /// Gas flow through the PT (the exhaust flow), kg/s.
    pub pt_flow_kg_s: f64,
    /// Electrical power delivered to the grid (0 while the breaker is open), MW.
    pub power_mw: f64,
    /// Power the PT delivers at its coupling, net of windage and bearings, MW.
    pub pt_shaft_mw: f64,
    pub compressor_power_mw: f64,
    pub hpt_power_mw: f64,
    /// Gas power of the PT (before mechanical losses), MW.
    pub pt_power_mw: f64,
    pub pressure_ratio: f64,
    pub hpt_pressure_ratio: f64,
    pub pt_pressure_ratio: f64,
    pub compressor_efficiency: f64,
    pub hpt_efficiency: f64,
    pub pt_efficiency: f64,
    pub compressor_beta: f64,
    pub surge_margin_pct: f64,
    pub starter_torque_n_m: f64,
}

/// The one station → signal mapping: the value a signal's instrument reads from a station table.
pub(crate) fn signal_value(st: &Stations, s: Signal) -> f64 {
    match s {
        Signal::N1 => st.n1_rpm,
        Signal::N2 => st.n2_rpm,
        Signal::T1 => st.t1_k,
        Signal::P1 => st.p1_kpa,
        Signal::T2 => st.t2_k,
        Signal::P2 => st.p2_kpa,
        Signal::T3 => st.t3_k,
        Signal::P3 => st.p3_kpa,
        Signal::T34 => st.t34_k,
        Signal::P34 => st.p34_kpa,
        Signal::T4 => st.t4_k,
        Signal::P4 => st.p4_kpa,
        Signal::FuelFlow => st.fuel_kg_s,
        Signal::Power => st.power_mw,
        Signal::SurgeMargin => st.surge_margin_pct,
        Signal::Torque => torque_knm(st.power_mw, st.n2_rpm),
        Signal::InletDepression => st.p_amb_kpa - st.p1_kpa,
    }
}

/// Shaft torque at the PT coupling, kN·m, for `power_mw` delivered there at `n2_rpm`: what a
/// torque meter on the coupling reads (power = torque × ω). Below 1 rpm the speed is held at
/// 1 rpm: a shaft at rest transmits no power, and the reading must stay finite.
pub(crate) fn torque_knm(power_mw: f64, n2_rpm: f64) -> f64 {
    power_mw * 1e3 / (n2_rpm.max(1.0) * PI / 30.0)
}

/// Every signal's value in a station table.
pub(crate) fn values_of(st: &Stations) -> Values {
    let mut v = [0.0; NSIG];
    for s in Signal::ALL {
        v[s.index()] = signal_value(st, s);
    }
    v
}

/// The air reaching the combustor when `w_compressor_kg_s` leaves the compressor and the
/// fraction `bleed` is bled overboard.
#[inline]
pub(crate) fn combustor_air(w_compressor_kg_s: f64, bleed: f64) -> f64 {
    w_compressor_kg_s * (1.0 - bleed)
}

/// What fixes the compressor's operating point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum CompressorSetting {
    /// The map's β line (steady matching: β is an unknown of the solver).
    Beta(f64),
    /// The delivery pressure a plenum holds, kPa (dynamic model: P2 is a state).
    Plenum { p2_kpa: f64 },
}

/// What fixes the hot section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum HotSection<'g> {
    /// An adiabatic burn of this fuel flow in the compressor's air (steady state).
    Burn { fuel_kg_s: f64 },
    /// The combustor plenum's gas temperature and gas (dynamic model states; the caller owns
    /// the gas, which it needs for the plenum balance too, so it is not copied around).
    Plenum { t3_k: f64, gas: &'g Gas },
}

/// The operating inputs of one gas-path evaluation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Inputs<'g> {
    pub(crate) t_amb_k: f64,
    pub(crate) p_amb_kpa: f64,
    pub(crate) n1_rpm: f64,
    pub(crate) n2_rpm: f64,
    pub(crate) p34_kpa: f64,
    pub(crate) compressor: CompressorSetting,
    pub(crate) hot: HotSection<'g>,
}

/// What enabled effects change in the gas path (see `effects`): extra bleed and component
/// flow/efficiency multipliers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Adjust {
    pub(crate) extra_bleed: ExtraBleed,
    pub(crate) deltas: ComponentDeltas,
    pub(crate) losses: DuctLosses,
}

impl Adjust {
    /// No change (the core model).
    pub(crate) const NONE: Adjust = Adjust {
        extra_bleed: ExtraBleed::NONE,
        deltas: ComponentDeltas::NONE,
        losses: DuctLosses::NONE,
    };
}

/// One evaluation of the gas path: the station table and the intermediate quantities the
/// dynamic model's balances and the steady solver's residuals need.
#[derive(Debug, Clone, Copy)]
pub(crate) struct GasPath {
    /// The inputs' speeds, inlet temperature and duct pressure, for the station table.
    pub(crate) n1_rpm: f64,
    pub(crate) n2_rpm: f64,
    pub(crate) t1_k: f64,
    pub(crate) p34_kpa: f64,
    /// Ambient pressure, kPa (the inlet depression P_amb − P1 is a flow measure).
    pub(crate) p_amb_kpa: f64,
    /// Station pressures (compressor inlet after the inlet loss, exit, combustor exit, PT
    /// exit before the exhaust loss) and the combustor exit temperature.
    pub(crate) p1_kpa: f64,
    pub(crate) p2_kpa: f64,
    pub(crate) p3_kpa: f64,
    pub(crate) p4_kpa: f64,
    pub(crate) t3_k: f64,
    /// Fuel-air ratio of the combustor gas.
    pub(crate) fuel_air_ratio: f64,
    /// PT inlet: the HPT's exit gas with the returned cooling air mixed in
    /// (`design.cooling_return_frac`; without it the HPT's exit temperature), K.
    pub(crate) t34_k: f64,
    /// Cooling air mixed in at the HPT exit, kg/s (0 without `design.cooling_return_frac`).
    pub(crate) w_return_kg_s: f64,
    /// Compressor exit state.
    pub(crate) compressor: CompressorStation,
    pub(crate) hpt: TurbineStation,
    pub(crate) pt: TurbineStation,
    /// Air the compressor delivers (after the standstill fade), kg/s.
    pub(crate) w_compressor_kg_s: f64,
    /// Air reaching the combustor (after bleed), kg/s.
    pub(crate) w_combustor_air_kg_s: f64,
    /// Gas leaving the combustor toward the HPT, kg/s: the burn's air plus fuel (steady), or
    /// the HPT map's flow (dynamic).
    pub(crate) w_combustor_out_kg_s: f64,
    /// Compressor shaft power (after the standstill fade), W.
    pub(crate) compressor_power_w: f64,
    /// PT gas torque at the evaluated PT speed, N·m.
    pub(crate) pt_gas_torque_n_m: f64,
    /// PT power at the coupling, net of windage and bearings, W.
    pub(crate) pt_net_w: f64,
    /// GG shaft power balance without the starter: HPT less compressor and losses, W.
    pub(crate) gg_net_w: f64,
}

impl GasPath {
    /// The station table (fuel and starter fields are the caller's to fill). Rendered on
    /// demand rather than stored: the integrator's right-hand side never needs it, and
    /// building it on every call cost a few per cent of a simulation.
    pub(crate) fn stations(&self) -> Stations {
        let (comp, hpt, pt) = (&self.compressor, &self.hpt, &self.pt);
        Stations {
            p_amb_kpa: self.p_amb_kpa,
            n1_rpm: self.n1_rpm,
            n2_rpm: self.n2_rpm,
            t1_k: self.t1_k,
            p1_kpa: self.p1_kpa,
            t2_k: comp.t_out_k,
            p2_kpa: self.p2_kpa,
            t3_k: self.t3_k,
            p3_kpa: self.p3_kpa,
            t34_k: self.t34_k,
            p34_kpa: self.p34_kpa,
            t4_k: pt.t_out_k,
            p4_kpa: self.p4_kpa,
            air_flow_kg_s: self.w_compressor_kg_s,
            fuel_kg_s: 0.0,
            fuel_burnt_kg_s: 0.0,
            fuel_air_ratio: self.fuel_air_ratio,
            hpt_flow_kg_s: hpt.w_kg_s,
            pt_flow_kg_s: pt.w_kg_s,
            power_mw: self.pt_net_w / 1e6,
            pt_shaft_mw: self.pt_net_w / 1e6,
            compressor_power_mw: self.compressor_power_w / 1e6,
            hpt_power_mw: hpt.power_w / 1e6,
            pt_power_mw: pt.power_w / 1e6,
            pressure_ratio: comp.pr,
            hpt_pressure_ratio: self.p3_kpa / self.p34_kpa,
            pt_pressure_ratio: self.p34_kpa / self.p4_kpa,
            compressor_efficiency: comp.eff,
            hpt_efficiency: hpt.eff,
            pt_efficiency: pt.eff,
            compressor_beta: comp.beta,
            surge_margin_pct: comp.surge_margin_pct,
            starter_torque_n_m: 0.0,
        }
    }
}

/// Evaluates the gas path on `model` (health applied) with `adjust` from the enabled effects
/// (`None` when no effect is on: the core model alone, without even comparing deltas).
#[inline(always)]
pub(crate) fn evaluate(model: &Model, inp: &Inputs, adjust: Option<&Adjust>) -> GasPath {
    evaluate_with(model, inp, adjust, None)
}

/// The compressor's share of a gas-path evaluation: its inlet pressure and exit state. It
/// depends on the ambient, the GG speed and the plenum pressure alone.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CompressorStage {
    p1: f64,
    comp: CompressorStation,
}

/// The compressor stage of one evaluation of the dynamic model's gas path, kept for later
/// evaluations whose compressor inputs (ambient, GG speed, plenum pressure) are bit for bit
/// the same: of the integrator's finite-difference Jacobian columns, those of the combustor
/// temperature and composition, the duct pressure and the PT speed leave the compressor where
/// it was, and the compressor is about a third of an evaluation. Holds the first evaluation it
/// sees; used for the core model only (no effect adjusts the maps or losses).
#[derive(Default)]
pub(crate) struct CompressorMemo {
    entry: Option<([u64; 4], CompressorStage)>,
}

/// [`evaluate`], taking the compressor stage from `memo` when its inputs are unchanged (and
/// storing this one when the memo is empty); the results are the same either way.
#[inline(always)]
pub(crate) fn evaluate_with(
    model: &Model,
    inp: &Inputs,
    adjust: Option<&Adjust>,
    memo: Option<&mut CompressorMemo>,
) -> GasPath {
    let adjusted;
    let (comp_map, hpt_map, pt_map) = match adjust {
        Some(a) if a.deltas != ComponentDeltas::NONE => {
            adjusted = adjusted_maps(model, &a.deltas);
            (&adjusted.0, &adjusted.1, &adjusted.2)
        }
        _ => (&model.comp, &model.hpt, &model.pt),
    };
    let stage = match (memo, inp.compressor) {
        (Some(memo), CompressorSetting::Plenum { p2_kpa }) if adjust.is_none() => {
            let key = [inp.t_amb_k, inp.p_amb_kpa, inp.n1_rpm, p2_kpa].map(f64::to_bits);
            match &memo.entry {
                Some((k, stage)) if *k == key => *stage,
                _ => {
                    let stage = compressor_stage(model, inp, adjust, comp_map);
                    if memo.entry.is_none() {
                        memo.entry = Some((key, stage));
                    }
                    stage
                }
            }
        }
        _ => compressor_stage(model, inp, adjust, comp_map),
    };
    after_compressor(model, inp, adjust, &stage, hpt_map, pt_map)
}

/// The duct-loss multipliers of the effects (`None`: the engine file's loss laws alone).
#[inline(always)]
fn effect_losses(adjust: Option<&Adjust>) -> Option<&DuctLosses> {
    adjust
        .map(|a| &a.losses)
        .filter(|l| **l != DuctLosses::NONE)
}

/// The compressor stage: inlet loss and compressor on `comp_map`.
#[inline(always)]
fn compressor_stage(
    model: &Model,
    inp: &Inputs,
    adjust: Option<&Adjust>,
    comp_map: &crate::maps::ScaledCompressor,
) -> CompressorStage {
    let c = &model.consts;
    let (n1, t1, p_amb) = (inp.n1_rpm, inp.t_amb_k, inp.p_amb_kpa);
    // Duct-loss multipliers of the effects (the loss laws themselves are the engine file's).
    let losses = effect_losses(adjust);
    let inlet = |p1: f64| match losses {
        Some(l) if l.inlet != 1.0 => p_amb - (p_amb - p1) * l.inlet,
        _ => p1,
    };

    // Compressor: below STANDSTILL_FADE of design speed its flow and work fade to zero.
    let n1_map = n1.max(STANDSTILL_FADE * c.n1_design);
    let fade = (n1.max(0.0) / (STANDSTILL_FADE * c.n1_design)).min(1.0);
    let (p1, comp) = match inp.compressor {
        CompressorSetting::Beta(beta) => {
            // The inlet loss depends on the corrected flow, which β fixes directly.
            let probe = cycle::compressor_at_beta(comp_map, t1, p_amb, n1_map, beta);
            let p1 = inlet(c.p1(p_amb, probe.wc_kg_s * fade));
            (
                p1,
                cycle::compressor_at_beta(comp_map, t1, p1, n1_map, beta),
            )
        }
        CompressorSetting::Plenum { p2_kpa: p2 } => {
            // PR is set by the plenum; the inlet loss depends on the flow it gives. The map is
            // read at the PR of a speed-based inlet-loss guess, the loss follows from that
            // flow, and the map is read again at the PR it gives. The guess alone (one read)
            // is exact at design only: it takes the loss as ∝ n1², where the flow falls faster
            // than the speed, so at 10 % load the PR read was ~0.3 % off P2/P1, the point
            // off the map's speed line, and the dynamic model settled 2.4 rpm (0.03 %) above
            // the steady solution with 0.075 % more air — a misfit Method A's window means
            // see on the model's own twin. After the second read the coupling (weak: a 1 %
            // loss at design) leaves ~1e-6.
            let nc1 = cycle::corrected_speed(n1_map, t1);
            let p1_guess = inlet(c.p1_guess(p_amb, n1));
            let wc_first = comp_map.flow_at_pr(nc1, p2 / p1_guess);
            let p1_first = inlet(c.p1(p_amb, wc_first * fade));
            let op = comp_map.at_pr(nc1, p2 / p1_first);
            let p1 = inlet(c.p1(p_amb, op.wc_kg_s * fade));
            (p1, cycle::compressor_from_op(t1, p1, p2 / p1, &op))
        }
    };
    CompressorStage { p1, comp }
}

/// Everything downstream of the compressor stage: bleed, combustor, HPT, duct, PT, exhaust and
/// the shaft balances.
#[inline(always)]
fn after_compressor(
    model: &Model,
    inp: &Inputs,
    adjust: Option<&Adjust>,
    stage: &CompressorStage,
    hpt_map: &crate::maps::ScaledTurbine,
    pt_map: &crate::maps::ScaledTurbine,
) -> GasPath {
    let c = &model.consts;
    let (n1, n2, t1, p_amb) = (inp.n1_rpm, inp.n2_rpm, inp.t_amb_k, inp.p_amb_kpa);
    let losses = effect_losses(adjust);
    let fade = (n1.max(0.0) / (STANDSTILL_FADE * c.n1_design)).min(1.0);
    let (p1, comp) = (stage.p1, stage.comp);
    let p2 = match inp.compressor {
        CompressorSetting::Beta(_) => p1 * comp.pr,
        CompressorSetting::Plenum { p2_kpa } => p2_kpa,
    };
    let w2 = comp.w_kg_s * fade;
    let (bleed, p_comp) = match adjust {
        Some(a) if a.extra_bleed.fraction != 0.0 => {
            // An effect's bleed from part way along the compressor did not take the rest of
            // its work (`ExtraBleed::work_saved`).
            let saved = a.extra_bleed.work_saved(comp.t_out_k / t1);
            (
                (c.bleed + a.extra_bleed.fraction).clamp(0.0, 0.5),
                comp.power_w * fade * (1.0 - saved),
            )
        }
        _ => (c.bleed, comp.power_w * fade),
    };
    // Air returned at the HPT exit leaves the compressor's exit with the bleed.
    let w_return = w2 * c.cooling_return;
    let w_air = combustor_air(w2, bleed + c.cooling_return);

    // Combustor and HPT.
    let p3 = c.p3(p2, w2.max(0.0), comp.t_out_k);
    let burnt;
    let (t3, gas, w_burn) = match inp.hot {
        HotSection::Burn { fuel_kg_s } => {
            let (t3, gas) = cycle::combustor_exit_temperature(c, w_air, comp.h_out, fuel_kg_s);
            burnt = gas;
            (t3, &burnt, Some(w_air + fuel_kg_s))
        }
        HotSection::Plenum { t3_k, gas } => (t3_k, gas, None),
    };
    // The GG's corrected speed at the compressor inlet: where the HP turbine's adaptation curves
    // are read when its file says so (`engine::config::SpeedOf`).
    let gg_nc = cycle::corrected_speed(n1.max(0.0), t1);
    let hpt = cycle::turbine(hpt_map, gas, t3, p3, n1.max(0.0), p3 / inp.p34_kpa, gg_nc);
    let w3 = w_burn.unwrap_or(hpt.w_kg_s);
    let hpt_out = Stream {
        gas: *gas,
        w_kg_s: w3,
        h: hpt.h_out,
        t_k: hpt.t_out_k,
    };
    let pt_in = mixed_with_air(&c.fuel, hpt_out, w_return, comp.h_out);
    let p4 = match losses {
        Some(l) if l.exhaust != 1.0 => {
            p_amb + (c.p4(p_amb, pt_in.w_kg_s, pt_in.t_k) - p_amb) * l.exhaust
        }
        _ => c.p4(p_amb, pt_in.w_kg_s, pt_in.t_k),
    };

    // PT. Its gas torque is largest at stall; the map's efficiency (and so P/ω) is meaningless
    // there, so the torque is evaluated at no less than PT_STALL_FRACTION of design speed and
    // held constant below it (a turbine's torque-speed line is nearly flat near stall).
    let n2_eval = n2.max(PT_STALL_FRACTION * c.n2_design);
    let p34 = inp.p34_kpa;
    let pt = cycle::turbine(pt_map, &pt_in.gas, pt_in.t_k, p34, n2_eval, p34 / p4, gg_nc);
    let pt_gas_torque = c.shaft.pt_shaft(pt.power_w) / (n2_eval * PI / 30.0);
    let pt_net = pt_gas_torque * n2.max(0.0) * PI / 30.0 - c.pt_loss_w(n2.max(0.0));
    let gg_net = c.shaft.gg_shaft_w(hpt.power_w) - p_comp - c.gg_loss_w(n1);

    GasPath {
        n1_rpm: n1,
        n2_rpm: n2,
        t1_k: t1,
        p34_kpa: p34,
        p_amb_kpa: p_amb,
        p1_kpa: p1,
        p2_kpa: p2,
        p3_kpa: p3,
        p4_kpa: p4,
        t3_k: t3,
        fuel_air_ratio: gas.far(),
        t34_k: pt_in.t_k,
        w_return_kg_s: w_return,
        compressor: comp,
        hpt,
        pt,
        w_compressor_kg_s: w2,
        w_combustor_air_kg_s: w_air,
        w_combustor_out_kg_s: w3,
        compressor_power_w: p_comp,
        pt_gas_torque_n_m: pt_gas_torque,
        pt_net_w: pt_net,
        gg_net_w: gg_net,
    }
}

/// A flow of one gas: its composition, mass flow, specific enthalpy and temperature.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Stream {
    pub(crate) gas: Gas,
    pub(crate) w_kg_s: f64,
    pub(crate) h: f64,
    pub(crate) t_k: f64,
}

/// `stream` with `w_air` kg/s of air at enthalpy `h_air` mixed in at constant pressure (its
/// fuel-air ratio diluted); without air, `stream` as it is. The PT's inlet where cooling air
/// returns at the HPT exit (`design.cooling_return_frac`), in the design cycle and off design.
#[inline]
pub(crate) fn mixed_with_air(fuel: &Fuel, stream: Stream, w_air: f64, h_air: f64) -> Stream {
    if w_air <= 0.0 || stream.w_kg_s <= 0.0 {
        return stream;
    }
    let far = stream.gas.far();
    // The fuel-air ratio counts fuel per kg of air: the stream carries w/(1+far) of air.
    let air_in_gas = stream.w_kg_s / (1.0 + far);
    let gas = fuel.products(far * air_in_gas / (air_in_gas + w_air));
    let w_kg_s = stream.w_kg_s + w_air;
    let h = (stream.w_kg_s * stream.h + w_air * h_air) / w_kg_s;
    Stream {
        gas,
        w_kg_s,
        h,
        t_k: gas.t_from_h(h),
    }
}

/// The model's maps with effect deltas multiplied onto their health factors.
fn adjusted_maps(
    model: &Model,
    d: &ComponentDeltas,
) -> (
    crate::maps::ScaledCompressor,
    crate::maps::ScaledTurbine,
    crate::maps::ScaledTurbine,
) {
    let (cf, ce) = model.comp.health();
    let (hf, he) = model.hpt.health();
    let (pf, pe) = model.pt.health();
    (
        model
            .comp
            .with_health(cf * d.compressor_flow, ce * d.compressor_eff),
        model.hpt.with_health(hf * d.hpt_flow, he * d.hpt_eff),
        model.pt.with_health(pf * d.pt_flow, pe * d.pt_eff),
    )
}
