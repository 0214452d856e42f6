//! The calibrated engine and its health-scaled instance.
//!
//! [`Engine`] is built once from an [`EngineConfig`]: it loads the three maps and calibrates their
//! scalers so the reference design point (REFERENCE §1) holds. [`Model`] is that engine with one
//! health vector applied; the steady solver and the dynamic model both run on a `Model`.
//! Pure: map files are read only by [`Engine::new`] when the config names a file path.

use super::config::{EfficiencyShape, EngineConfig, MapInterpolation, PressureLossLaw, SpeedOf};
use super::cycle::{ShaftLosses, P_STD_KPA, T_STD_K};
use super::design::DesignCycles;
use super::effects::EffectSet;
use crate::health::HealthParams;
use crate::maps::{self, CompressorMap, ScaledCompressor, ScaledTurbine, TurbineMap};
use crate::thermo::Fuel;
use std::path::Path;
use std::sync::Arc;

pub(crate) use super::error::EngineError;
/// The design point as calibrated: the station table of the reference cycle.
pub type DesignPoint = super::gas_path::Stations;

/// Constants of the model, derived from the config and the design point (SI units, kPa).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Constants {
    pub t_amb_k: f64,
    pub p_amb_kpa: f64,
    pub inlet_loss_frac: f64,
    pub inlet_loss_law: PressureLossLaw,
    pub wc1_design: f64,
    pub combustor_loss_frac: f64,
    pub combustor_loss_law: PressureLossLaw,
    /// W2·√T2/P2 at design, for the combustor loss law.
    pub q2_design: f64,
    pub exhaust_excess_ratio: f64,
    pub exhaust_loss_law: PressureLossLaw,
    /// W·√T34/P_amb at design, for the exhaust back-pressure law.
    pub q4_design: f64,
    pub eta_b: f64,
    /// The fuel: LHV, sensible enthalpy at its supply temperature, products' properties.
    pub fuel: Fuel,
    pub bleed: f64,
    /// Compressor air mixed back in at the HP-turbine exit, fraction of compressor flow
    /// (`design.cooling_return_frac`).
    pub cooling_return: f64,
    pub gg_inertia: f64,
    pub pt_inertia: f64,
    pub v_comb: f64,
    pub v_duct: f64,
    pub shaft: ShaftLosses,
    pub pt_breakaway_nm: f64,
    pub n1_design: f64,
    pub n2_design: f64,
    pub power_design_w: f64,
    pub fuel_design: f64,
    pub flow_design: f64,
    pub p2_design_kpa: f64,
    pub t3_design_k: f64,
    pub p34_design_kpa: f64,
    /// Compressor design β in gtwatch's internal convention (surge end low).
    pub beta_design: f64,
}

impl Constants {
    /// Compressor inlet pressure: ambient less an inlet loss ∝ (corrected flow)², or a
    /// constant fraction ([`PressureLossLaw`]).
    #[inline]
    pub fn p1(&self, p_amb: f64, wc1: f64) -> f64 {
        match self.inlet_loss_law {
            // `Nozzle` is refused on the inlet by the engine file's validation.
            PressureLossLaw::FlowSquared | PressureLossLaw::Nozzle => {
                let r = wc1 / self.wc1_design;
                p_amb * (1.0 - self.inlet_loss_frac * r * r)
            }
            PressureLossLaw::Constant => p_amb * (1.0 - self.inlet_loss_frac),
        }
    }
    /// A first guess of P1 from the GG speed alone (flow ∝ speed), exact for a constant loss.
    #[inline]
    pub fn p1_guess(&self, p_amb: f64, n1: f64) -> f64 {
        match self.inlet_loss_law {
            PressureLossLaw::FlowSquared | PressureLossLaw::Nozzle => {
                p_amb * (1.0 - self.inlet_loss_frac * (n1 / self.n1_design).powi(2))
            }
            PressureLossLaw::Constant => p_amb * (1.0 - self.inlet_loss_frac),
        }
    }
    /// Combustor exit pressure: P2 less a loss ∝ (W√T2/P2)², or a constant fraction.
    #[inline]
    pub fn p3(&self, p2: f64, w2: f64, t2: f64) -> f64 {
        match self.combustor_loss_law {
            // `Nozzle` is refused on the combustor by the engine file's validation.
            PressureLossLaw::FlowSquared | PressureLossLaw::Nozzle => {
                let r = w2 * t2.sqrt() / p2 / self.q2_design;
                p2 * (1.0 - (self.combustor_loss_frac * r * r).min(0.5))
            }
            PressureLossLaw::Constant => p2 * (1.0 - self.combustor_loss_frac),
        }
    }
    /// Exhaust back-pressure: ambient plus an excess ∝ (W√T34/P_amb)², a constant ratio, or
    /// the pressure a fixed-area nozzle needs to pass the flow ([`super::nozzle`]).
    #[inline]
    pub fn p4(&self, p_amb: f64, w: f64, t34: f64) -> f64 {
        match self.exhaust_loss_law {
            PressureLossLaw::FlowSquared => {
                let r = w.max(0.0) * t34.sqrt() / p_amb / self.q4_design;
                p_amb * (1.0 + self.exhaust_excess_ratio * r * r)
            }
            PressureLossLaw::Constant => p_amb * (1.0 + self.exhaust_excess_ratio),
            PressureLossLaw::Nozzle => {
                let r = w.max(0.0) * t34.sqrt() / p_amb / self.q4_design;
                p_amb * super::nozzle::pressure_ratio(1.0 + self.exhaust_excess_ratio, r)
            }
        }
    }
    /// Heat the combustor gas receives from `wf` kg/s of fuel, W: `wf·(η_b·LHV + h_fuel)` with
    /// the fuel's sensible enthalpy relative to 288.15 K (0 for the legacy methane, so the sum
    /// is bit for bit `wf·η_b·LHV`).
    #[inline]
    pub fn fuel_heat_w(&self, wf: f64) -> f64 {
        wf * self.eta_b * self.fuel.lhv() + wf * self.fuel.sensible_enthalpy()
    }
    /// All GG shaft losses outside the mechanical efficiency, W.
    #[inline]
    pub fn gg_loss_w(&self, n1: f64) -> f64 {
        self.shaft.gg_w(n1)
    }
    /// All PT + generator losses outside the mechanical efficiency, W.
    #[inline]
    pub fn pt_loss_w(&self, n2: f64) -> f64 {
        self.shaft.pt_w(n2)
    }
}

/// The calibrated engine (healthy maps). It owns its parameters: the engine file is read-only
/// through [`Engine::cfg`] and changed only through [`Engine::set_param`] (`engine/params.rs`),
/// which rebuilds the design calibration and the frozen constants.
#[derive(Debug, Clone)]
pub struct Engine {
    cfg: Arc<EngineConfig>,
    design: DesignPoint,
    consts: Constants,
    maps: RawMaps,
    comp: ScaledCompressor,
    hpt: ScaledTurbine,
    pt: ScaledTurbine,
    effects: Arc<EffectSet>,
}

/// The unscaled component maps as read from the engine file's map paths (shared, cheap to
/// clone): kept so a parameter change recalibrates without reading files again.
#[derive(Debug, Clone)]
pub(crate) struct RawMaps {
    comp: Arc<CompressorMap>,
    hpt: Arc<TurbineMap>,
    pt: Arc<TurbineMap>,
}

/// The engine with one health vector applied: what the solvers run on.
#[derive(Debug, Clone)]
pub struct Model {
    pub comp: ScaledCompressor,
    pub hpt: ScaledTurbine,
    pub pt: ScaledTurbine,
    pub consts: Constants,
    pub health: HealthParams,
    /// The enabled effects and the state layout they need.
    pub effects: Arc<EffectSet>,
    /// The engine file the model was built from (control, sequence, sensors, solver settings).
    cfg: Arc<EngineConfig>,
}

impl Model {
    /// The engine file this model was built from.
    pub fn cfg(&self) -> &EngineConfig {
        &self.cfg
    }
}

fn map_error(key: &str) -> impl Fn(maps::MapError) -> EngineError + '_ {
    move |error| EngineError::MapFile {
        key: key.into(),
        error: Box::new(error),
    }
}

/// A map's GasTurb text as the engine file gives it: inline (`inline`, the `*_map` key), from
/// a file (`file`), else the embedded one. Returns the key errors are reported under.
fn parse_map(
    component: &str,
    file: &str,
    inline: &str,
    embedded: &str,
    name: &str,
) -> (String, Result<maps::gasturb::GasTurbFile, maps::MapError>) {
    if !inline.is_empty() {
        let key = format!("maps.{component}_map");
        let parsed = maps::gasturb::parse(inline, &key);
        (key, parsed)
    } else if !file.is_empty() {
        let parsed = maps::gasturb::read_file(Path::new(file));
        (format!("maps.{component}_file"), parsed)
    } else {
        let parsed = maps::gasturb::parse(embedded, name);
        (format!("maps.{component}_file"), parsed)
    }
}

fn load_compressor(
    file: &str,
    inline: &str,
    interp: MapInterpolation,
) -> Result<CompressorMap, EngineError> {
    let (key, parsed) = parse_map(
        "compressor",
        file,
        inline,
        maps::HPC_MAP,
        "embedded hpc.map",
    );
    let key = key.as_str();
    let parsed = parsed.map_err(map_error(key))?;
    let map = CompressorMap::from_gasturb(&parsed).map_err(map_error(key))?;
    match interp {
        MapInterpolation::Linear => Ok(map),
        MapInterpolation::Cubic => map.with_cubic_interpolation().map_err(map_error(key)),
    }
}

fn load_turbine(
    component: &str,
    file: &str,
    inline: &str,
    embedded: &str,
    name: &str,
    interp: MapInterpolation,
) -> Result<TurbineMap, EngineError> {
    let (key, parsed) = parse_map(component, file, inline, embedded, name);
    let key = key.as_str();
    let parsed = parsed.map_err(map_error(key))?;
    let map = TurbineMap::from_gasturb(&parsed).map_err(map_error(key))?;
    match interp {
        MapInterpolation::Linear => Ok(map),
        MapInterpolation::Cubic => map.with_cubic_interpolation().map_err(map_error(key)),
    }
}

/// Which corrected speed the engine file's HP-turbine knots are in.
fn hpt_speed_of(cfg: &EngineConfig) -> SpeedOf {
    cfg.adaptation
        .as_ref()
        .and_then(|a| a.hpt.as_ref())
        .and_then(|c| c.speed_of)
        .unwrap_or_default()
}

/// The engine file's adaptation curves of `component` (none when the file has none).
fn adaptation_of(cfg: &EngineConfig, component: &str) -> maps::ComponentAdaptation {
    let Some(c) = cfg.adaptation.as_ref().and_then(|a| a.component(component)) else {
        return maps::ComponentAdaptation::default();
    };
    let curve = |v: &[f64]| maps::SpeedCurve::new(&c.speed_knots, v);
    maps::ComponentAdaptation {
        flow: curve(&c.flow),
        eff: curve(&c.efficiency),
        pr: curve(&c.pressure_ratio),
        speed: curve(&c.speed),
        hold_map_efficiency: c.efficiency_shape == Some(EfficiencyShape::Curve),
    }
}

impl Engine {
    /// Loads the maps and calibrates them to the design point.
    pub fn new(cfg: EngineConfig) -> Result<Engine, EngineError> {
        cfg.validate("<engine>")?;
        let maps = RawMaps {
            comp: Arc::new(load_compressor(
                &cfg.maps.compressor_file,
                &cfg.maps.compressor_map,
                cfg.maps.interpolation,
            )?),
            hpt: Arc::new(load_turbine(
                "hpt",
                &cfg.maps.hpt_file,
                &cfg.maps.hpt_map,
                maps::HPT_MAP,
                "embedded hpt.map",
                cfg.maps.interpolation,
            )?),
            pt: Arc::new(load_turbine(
                "pt",
                &cfg.maps.pt_file,
                &cfg.maps.pt_map,
                maps::LPT_MAP,
                "embedded lpt.map",
                cfg.maps.interpolation,
            )?),
        };
        Engine::calibrate(cfg, maps)
    }

    /// Design calibration and frozen constants from `cfg` on already loaded maps.
    pub(crate) fn calibrate(cfg: EngineConfig, maps: RawMaps) -> Result<Engine, EngineError> {
        Engine::calibrate_with(cfg, maps, &DesignCycles::default())
    }

    /// [`Engine::calibrate`] taking the design cycle from `cycles` where it holds the one of
    /// `cfg` (the same engine, bit for bit; see [`DesignCycles`]).
    pub(crate) fn calibrate_with(
        cfg: EngineConfig,
        maps: RawMaps,
        cycles: &DesignCycles,
    ) -> Result<Engine, EngineError> {
        let comp_map = Arc::clone(&maps.comp);
        let hpt_map = Arc::clone(&maps.hpt);
        let pt_map = Arc::clone(&maps.pt);
        let effects = Arc::new(Engine::build_effects(&cfg)?);
        let fuel = cfg.fuel()?;
        let mut design = cycles.cycle(&cfg, &fuel)?;
        let d = &cfg.design;
        let m = &cfg.maps;
        let theta1 = design.t1_k / T_STD_K;
        let delta1 = design.p1_kpa / P_STD_KPA;
        let wc1 = design.air_flow_kg_s * theta1.sqrt() / delta1;
        // The engine file states the design β as the map file does; the map works internally
        // with the surge end at low β (`maps::compressor` docs).
        let beta_design = comp_map.beta_from_file(m.compressor_design_beta);
        let comp = ScaledCompressor::calibrate(
            comp_map,
            m.compressor_design_speed,
            beta_design,
            d.gg_speed_rpm / theta1.sqrt(),
            wc1,
            d.pressure_ratio,
            d.compressor_efficiency,
        );
        let comp = comp.with_adaptation(
            d.gg_speed_rpm / theta1.sqrt(),
            adaptation_of(&cfg, "compressor"),
        );
        let theta3 = design.t3_k / T_STD_K;
        let wc3 = design.hpt_flow_kg_s * theta3.sqrt() / (design.p3_kpa / P_STD_KPA);
        let hpt = ScaledTurbine::calibrate(
            hpt_map,
            m.hpt_design_speed,
            m.hpt_design_pr,
            d.gg_speed_rpm / theta3.sqrt(),
            wc3,
            design.hpt_pressure_ratio,
            d.hpt_efficiency,
        );
        // The HP turbine's curves are read at its own corrected speed, or at the GG's at the
        // compressor inlet where the file says so (`SpeedOf`: why, in its docs).
        let hpt = match hpt_speed_of(&cfg) {
            SpeedOf::OwnInlet => {
                hpt.with_adaptation(d.gg_speed_rpm / theta3.sqrt(), adaptation_of(&cfg, "hpt"))
            }
            SpeedOf::GgInlet => hpt.with_adaptation_at(
                d.gg_speed_rpm / theta1.sqrt(),
                adaptation_of(&cfg, "hpt"),
                maps::CurveSpeed::Reference,
            ),
        };
        let theta34 = design.t34_k / T_STD_K;
        let wc34 = design.pt_flow_kg_s * theta34.sqrt() / (design.p34_kpa / P_STD_KPA);
        let pt = ScaledTurbine::calibrate(
            pt_map,
            m.pt_design_speed,
            m.pt_design_pr,
            d.pt_speed_rpm / theta34.sqrt(),
            wc34,
            design.pt_pressure_ratio,
            d.pt_efficiency,
        );
        let pt = pt.with_adaptation(d.pt_speed_rpm / theta34.sqrt(), adaptation_of(&cfg, "pt"));
        let dy = &cfg.dynamics;
        let consts = Constants {
            t_amb_k: cfg.ambient.temperature_k,
            p_amb_kpa: cfg.ambient.pressure_kpa,
            inlet_loss_frac: d.inlet_loss_frac,
            inlet_loss_law: d.inlet_loss_law,
            wc1_design: wc1,
            combustor_loss_frac: d.combustor_loss_frac,
            combustor_loss_law: d.combustor_loss_law,
            q2_design: design.air_flow_kg_s * design.t2_k.sqrt() / design.p2_kpa,
            exhaust_excess_ratio: d.exhaust_back_pressure_ratio - 1.0,
            exhaust_loss_law: d.exhaust_loss_law,
            q4_design: design.pt_flow_kg_s * design.t34_k.sqrt() / cfg.ambient.pressure_kpa,
            eta_b: d.combustion_efficiency,
            fuel,
            bleed: d.cooling_bleed_frac,
            cooling_return: d.cooling_return_frac,
            gg_inertia: dy.gg_inertia_kg_m2,
            pt_inertia: dy.pt_inertia_kg_m2,
            v_comb: dy.combustor_volume_m3,
            v_duct: dy.duct_volume_m3,
            shaft: ShaftLosses::from_config(&cfg),
            pt_breakaway_nm: dy.pt_breakaway_torque_n_m,
            n1_design: d.gg_speed_rpm,
            n2_design: d.pt_speed_rpm,
            power_design_w: d.power_mw * 1e6,
            fuel_design: design.fuel_kg_s,
            flow_design: design.pt_flow_kg_s,
            p2_design_kpa: design.p2_kpa,
            t3_design_k: design.t3_k,
            p34_design_kpa: design.p34_kpa,
            beta_design,
        };
        // The design point's β and surge margin come from the scaled map.
        let at_design = super::cycle::compressor_at_beta(
            &comp,
            design.t1_k,
            design.p1_kpa,
            design.n1_rpm,
            beta_design,
        );
        design.compressor_beta = at_design.beta;
        design.surge_margin_pct = at_design.surge_margin_pct;
        Ok(Engine {
            cfg: Arc::new(cfg),
            design,
            consts,
            maps,
            comp,
            hpt,
            pt,
            effects,
        })
    }

    fn build_effects(cfg: &EngineConfig) -> Result<EffectSet, EngineError> {
        EffectSet::from_section(&cfg.effects).map_err(|reason| EngineError::Param {
            key: "effects".into(),
            reason,
        })
    }

    /// Replaces the engine file's `[effects]` section (already validated) and rebuilds only the
    /// effects: they never change the design calibration.
    pub(crate) fn replace_effects(&mut self, cfg: EngineConfig) -> Result<(), EngineError> {
        self.effects = Arc::new(Engine::build_effects(&cfg)?);
        self.cfg = Arc::new(cfg);
        Ok(())
    }

    /// The enabled effects.
    pub fn effects(&self) -> &EffectSet {
        &self.effects
    }

    /// The engine file this engine was built from (read-only: change values with
    /// [`Engine::set_param`]).
    pub fn cfg(&self) -> &EngineConfig {
        &self.cfg
    }

    /// The calibrated design point.
    pub fn design(&self) -> &DesignPoint {
        &self.design
    }

    /// The constants frozen from the engine file and the design point.
    pub fn consts(&self) -> &Constants {
        &self.consts
    }

    /// The maps this engine was calibrated on (for a rebuild after a parameter change).
    /// A [`DesignCycles`] holding this engine's own design cycle.
    pub(crate) fn design_cycles(&self) -> DesignCycles {
        let mut cycle = self.design;
        // As the cycle leaves them: the engine fills them in from its scaled map.
        cycle.compressor_beta = 0.0;
        cycle.surge_margin_pct = 0.0;
        DesignCycles::with(self.cfg(), &cycle)
    }

    pub(crate) fn raw_maps(&self) -> &RawMaps {
        &self.maps
    }

    /// The built-in reference engine.
    pub fn reference() -> Result<Engine, EngineError> {
        Engine::new(EngineConfig::reference())
    }

    /// The engine with `health` applied to its maps (REFERENCE §3 scalers).
    pub fn model(&self, health: &HealthParams) -> Model {
        Model {
            comp: self.comp.with_health(
                health.compressor_flow_factor(),
                health.compressor_eff_factor(),
            ),
            hpt: self
                .hpt
                .with_health(health.hpt_flow_factor(), health.hpt_eff_factor()),
            pt: self
                .pt
                .with_health(health.pt_flow_factor(), health.pt_eff_factor()),
            consts: self.consts,
            health: *health,
            effects: Arc::clone(&self.effects),
            cfg: Arc::clone(&self.cfg),
        }
    }

    /// The model at given ambient conditions (the design calibration stays ISO).
    pub fn model_at(&self, health: &HealthParams, t_amb_k: f64, p_amb_kpa: f64) -> Model {
        let mut m = self.model(health);
        // The ambient given is what the instruments read; an input-instrument effect
        // (`inlet_temperature`) says what the engine really breathes.
        let (t, p) = m.effects.true_ambient(t_amb_k, p_amb_kpa);
        m.consts.t_amb_k = t;
        m.consts.p_amb_kpa = p;
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::steady::{solve, Demand, SteadyInputs};

    /// Constant-ratio loss laws hold their design ratios at part load; the default flow law does
    /// not, and both give the same design point.
    #[test]
    fn pressure_loss_laws() {
        let reference = Engine::reference().expect("reference");
        let mut cfg = EngineConfig::reference();
        cfg.design.inlet_loss_law = PressureLossLaw::Constant;
        cfg.design.combustor_loss_law = PressureLossLaw::Constant;
        cfg.design.exhaust_loss_law = PressureLossLaw::Constant;
        let constant = Engine::new(cfg).expect("constant laws");
        assert_eq!(constant.design(), reference.design());
        let inp = SteadyInputs {
            t_amb_k: 288.15,
            p_amb_kpa: 101.325,
            n2_rpm: 3600.0,
            demand: Demand::PowerMw(15.0),
        };
        let healthy = HealthParams::HEALTHY;
        let c = solve(&constant.model(&healthy), &inp, None).expect("constant");
        let f = solve(&reference.model(&healthy), &inp, None).expect("flow");
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        assert!(rel(c.p1_kpa, 101.325 * 0.99) < 1e-14, "{}", c.p1_kpa);
        assert!(rel(c.p3_kpa, c.p2_kpa * 0.96) < 1e-14);
        assert!(rel(c.p4_kpa, 101.325 * 1.03) < 1e-14);
        // Flow squared: the losses follow the corrected flows (the inlet's falls at part load,
        // the combustor's W2·√T2/P2 rises).
        assert!(f.p1_kpa > 101.325 * 0.99 + 0.1, "{}", f.p1_kpa);
        assert!(f.p3_kpa / f.p2_kpa < 0.959, "{}", f.p3_kpa / f.p2_kpa);
        assert!(f.p4_kpa < 101.325 * 1.03 - 0.5, "{}", f.p4_kpa);
        // A fixed-area exhaust nozzle: the same design point, and at part load a back-pressure
        // beside the flow-squared law's (both nearly Bernoulli at a 3 % excess), not the
        // constant one.
        let mut cfg = EngineConfig::reference();
        cfg.design.exhaust_loss_law = PressureLossLaw::Nozzle;
        let nozzle = Engine::new(cfg).expect("nozzle law");
        assert_eq!(nozzle.design(), reference.design());
        let n = solve(&nozzle.model(&healthy), &inp, None).expect("nozzle");
        assert!(
            rel(n.p4_kpa, f.p4_kpa) < 1e-3,
            "{} vs {}",
            n.p4_kpa,
            f.p4_kpa
        );
        assert!(n.p4_kpa != f.p4_kpa);
        assert!(n.p4_kpa < 101.325 * 1.03 - 0.5, "{}", n.p4_kpa);
    }
}
