//! Optional model effects: the seam where plant behaviour the core model leaves out (fuel-system
//! lag, heat soak, bleed schedules, instrument errors, …) plugs in without editing the core.
//!
//! An effect is one file in this folder implementing [`Effect`] plus one line in [`REGISTRY`].
//! It is switched on and parameterised by the engine file's `[effects.<name>]` table (e.g.
//! `[effects.fuel_system]` with `lag_s = 0.5`); each parameter is an ordinary named engine
//! parameter (`effects.fuel_system.lag_s`), so the diagnosis can fit it like any other.
//!
//! The core model calls the effects at named hook points, in the order they are listed:
//! - **states**: an effect may own a block of extra states ([`Effect::n_states`],
//!   [`Effect::rest_states`], [`Effect::derivatives`]), placed after the core states by
//!   [`super::state::StateLayout`];
//! - **fuel delivery** ([`Effect::fuel_delivered`]): metered fuel → fuel burnt;
//! - **bleed / flow schedule** ([`Effect::bleed_fraction`]): extra compressor bleed;
//! - **component deltas** ([`Effect::component_deltas`]): flow and efficiency multipliers;
//! - **duct losses** ([`Effect::duct_losses`]): multipliers on the inlet and exhaust pressure
//!   losses;
//! - **heat exchange** ([`Effect::heat_to_metal_w`]): heat the combustor gas gives to metal;
//! - **instrument path** ([`Effect::instrument`]): what a channel's instrument makes of the
//!   signal it measures;
//! - **ambient** ([`Effect::true_ambient`]): the ambient the engine runs in, given the one its
//!   instruments read (an input instrument's error).
//!
//! With no effect on, the core skips every hook, so its results are bit for bit those of the
//! model without this seam. Effects are pure: no I/O, no globals, deterministic.

/// Declares the effect modules and the registry from one list: adding an effect is one file in
/// this folder and its name here.
macro_rules! registry {
    ($($effect:ident),* $(,)?) => {
        $(pub(crate) mod $effect;)*
        /// Every effect gtwatch knows, in registry order.
        pub(crate) static REGISTRY: &[EffectSpec] = &[$($effect::SPEC),*];
    };
}

registry!(
    fuel_system,
    sensor_lag,
    sensor_bias,
    heat_soak,
    bleed_schedule,
    vigv_schedule,
    tip_clearance,
    duct_loss,
    fuel_meter,
    fuel_meter_offset,
    inlet_temperature,
    sensor_scale,
);

use super::gas_path::Stations;
use crate::signals::Signal;
use std::collections::BTreeMap;
use std::fmt::Debug;
use std::sync::Arc;

/// A bounded parameter of an effect.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub(crate) struct ParamSpec {
    pub(crate) name: &'static str,
    pub(crate) unit: &'static str,
    pub(crate) default: f64,
    pub(crate) min: f64,
    pub(crate) max: f64,
    pub(crate) doc: &'static str,
    /// Fitted only when the gap analysis refines the effect it named (a second time constant,
    /// say): at its default the effect is its simpler form, and the screen and the scoring of
    /// every candidate keep that form's few parameters.
    pub(crate) refinement: bool,
}

/// Which instances of an effect exist: one for the engine, or one per measured channel
/// (named `name:column`, e.g. `sensor_lag:t34_k`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum Channels {
    /// One instance, named by the effect's name.
    Engine,
    /// One per temperature channel the plant measures (T1, T2, T34, T4).
    Temperatures,
    /// One per measured channel (everything but T3 and P3, which plants do not measure).
    Measured,
}

impl Channels {
    /// The signals an instance may address.
    pub(crate) fn signals(self) -> Vec<Signal> {
        match self {
            Channels::Engine => Vec::new(),
            Channels::Temperatures => vec![Signal::T1, Signal::T2, Signal::T34, Signal::T4],
            Channels::Measured => Signal::ALL
                .iter()
                .copied()
                .filter(|s| !matches!(s, Signal::T3 | Signal::P3))
                .collect(),
        }
    }
}

/// Where a refinement's fits start, from the simple form's fitted parameters (see
/// [`EffectSpec::refinement_starts`]).
pub(crate) type RefinementStarts = fn(&[f64]) -> Vec<Vec<f64>>;

/// A registry entry: what the effect is called, what it does, its parameters and how to build it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct EffectSpec {
    pub(crate) name: &'static str,
    /// Whether the effect is an instrument's error (what a channel or an input meter reads)
    /// rather than the engine's own behaviour. A start-up whose gap analysis names an instrument
    /// reports a health the instrument distorted: the wash advice sets it aside.
    pub(crate) instrument: bool,
    /// One instance, or one per channel.
    pub(crate) channels: Channels,
    /// One line: what the effect models.
    pub(crate) summary: &'static str,
    /// Where the effect shows in the data (its signature), for the gap analysis and the user.
    pub(crate) signature: &'static str,
    pub(crate) params: &'static [ParamSpec],
    /// Where the gap analysis starts fitting the refinement (the parameters marked
    /// `refinement`) from the simple form's fitted parameters (in `params` order, complete):
    /// one vector of the refinement's values, in `params` order, per start. `None`: from their
    /// defaults, once.
    pub(crate) refinement_starts: Option<RefinementStarts>,
    /// Builds the effect from a complete, validated parameter set (in `params` order) and, for
    /// per-channel effects, its channel.
    pub(crate) build: fn(&[f64], Option<Signal>) -> Arc<dyn Effect>,
}

/// Whether `instance` (an effect's instance name, e.g. `fuel_meter` or `sensor_bias:p2_kpa`)
/// is an instrument's error. `false` for names that are not effects (`none`, `ambiguous`,
/// `unexplained`).
pub(crate) fn is_instrument(instance: &str) -> bool {
    resolve(instance).is_ok_and(|(spec, _)| spec.instrument)
}

/// An effect instance name split into the registry entry and its channel.
fn resolve(instance: &str) -> Result<(&'static EffectSpec, Option<Signal>), EffectError> {
    let (base, column) = match instance.split_once(':') {
        Some((b, c)) => (b, Some(c)),
        None => (instance, None),
    };
    let unknown = || EffectError::Unknown {
        name: instance.into(),
        known: instance_names().join(", "),
    };
    let spec = REGISTRY
        .iter()
        .find(|s| s.name == base)
        .ok_or_else(unknown)?;
    match (spec.channels, column) {
        (Channels::Engine, None) => Ok((spec, None)),
        (Channels::Engine, Some(_)) | (_, None) => Err(unknown()),
        (ch, Some(c)) => {
            let sig: Signal = c.parse().map_err(|_| unknown())?;
            if ch.signals().contains(&sig) && sig.column() == c {
                Ok((spec, Some(sig)))
            } else {
                Err(unknown())
            }
        }
    }
}

/// Every instance name the registry offers (`fuel_system`, `sensor_lag:t34_k`, …).
pub(crate) fn instance_names() -> Vec<String> {
    let mut out = Vec::new();
    for s in REGISTRY {
        match s.channels {
            Channels::Engine => out.push(s.name.to_string()),
            ch => out.extend(
                ch.signals()
                    .into_iter()
                    .map(|sig| format!("{}:{}", s.name, sig.column())),
            ),
        }
    }
    out
}

/// The registry entry of an instance name (`fuel_system`, `sensor_lag:t34_k`).
pub(crate) fn spec(instance: &str) -> Option<&'static EffectSpec> {
    resolve(instance).ok().map(|(s, _)| s)
}

/// Flow and efficiency multipliers on the three components (1 = no change).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComponentDeltas {
    pub compressor_flow: f64,
    pub compressor_eff: f64,
    pub hpt_flow: f64,
    pub hpt_eff: f64,
    pub pt_flow: f64,
    pub pt_eff: f64,
}

impl ComponentDeltas {
    pub const NONE: ComponentDeltas = ComponentDeltas {
        compressor_flow: 1.0,
        compressor_eff: 1.0,
        hpt_flow: 1.0,
        hpt_eff: 1.0,
        pt_flow: 1.0,
        pt_eff: 1.0,
    };
}

/// Multipliers on the inlet pressure loss (ambient → compressor inlet) and the exhaust
/// back-pressure excess (PT exit → ambient); 1 = the engine file's loss.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DuctLosses {
    pub inlet: f64,
    pub exhaust: f64,
}

impl DuctLosses {
    pub const NONE: DuctLosses = DuctLosses {
        inlet: 1.0,
        exhaust: 1.0,
    };
}

/// The bleed the effects add to the core's (see [`Effect::bleed_fraction`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtraBleed {
    /// Fraction of compressor flow bled overboard (all effects together).
    pub fraction: f64,
    /// Where it leaves: the fraction of the compressor's log pressure ratio ahead of the port
    /// (bleed-weighted over the effects; 1 = the compressor's exit).
    pub port: f64,
}

impl ExtraBleed {
    /// No extra bleed.
    pub const NONE: ExtraBleed = ExtraBleed {
        fraction: 0.0,
        port: 1.0,
    };

    /// The fraction of the compressor's power the bled air did not take, for a compressor of
    /// temperature ratio `tau` (exit over inlet): the air bled at the port has had the work of
    /// the polytropic path up to the port's pressure, `(tau^port − 1) / (tau − 1)` of the whole.
    pub fn work_saved(&self, tau: f64) -> f64 {
        if self.fraction == 0.0 || self.port >= 1.0 || tau.is_nan() || tau <= 1.0 + 1e-9 {
            return 0.0;
        }
        let port = self.port.max(0.0);
        let at_port = (tau.powf(port) - 1.0) / (tau - 1.0);
        self.fraction * (1.0 - at_port)
    }
}

/// What the hooks evaluated before the gas path may look at: the core states in physical units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoreView {
    pub t_s: f64,
    pub n1_rpm: f64,
    pub n2_rpm: f64,
    pub p2_kpa: f64,
    pub t3_k: f64,
    pub p34_kpa: f64,
    pub t_amb_k: f64,
    pub p_amb_kpa: f64,
    /// Design GG speed, rpm (for schedules in fractions of design speed).
    pub n1_design_rpm: f64,
    /// Design fuel flow, kg/s (the natural scale of fuel states).
    pub fuel_design_kg_s: f64,
}

#[cfg(test)]
impl CoreView {
    /// A core view for an effect's tests: a standard day, the GG at `n1_rpm` of a 10 000 rpm
    /// design, the combustor gas at `t3_k`, the rest at round values.
    pub(crate) fn for_tests(n1_rpm: f64, t3_k: f64) -> CoreView {
        CoreView {
            t_s: 0.0,
            n1_rpm,
            n2_rpm: 0.0,
            p2_kpa: 101.0,
            t3_k,
            p34_kpa: 101.0,
            t_amb_k: crate::engine::cycle::T_STD_K,
            p_amb_kpa: 101.325,
            n1_design_rpm: 10_000.0,
            fuel_design_kg_s: 2.0,
        }
    }
}

/// What [`Effect::derivatives`] may look at: the core view, the finished station table and the
/// fuel flow the controller metered.
#[derive(Debug, Clone, Copy)]
pub struct Context<'a> {
    pub core: &'a CoreView,
    pub stations: &'a Stations,
    pub metered_fuel_kg_s: f64,
}

/// A switchable extension of the engine model. Every hook has a neutral default, so an effect
/// implements only the hooks it uses.
pub trait Effect: Debug + Send + Sync {
    /// Registry name (`snake_case`).
    fn name(&self) -> &'static str;
    /// Number of states the effect owns.
    fn n_states(&self) -> usize {
        0
    }
    /// Whether the effect's hooks read the gas path's state (P2, T3, P34 of [`CoreView`]) or
    /// its states need it; `false` for a schedule on the speeds and the ambient alone, which a
    /// steady point then evaluates without first computing the core's gas path for it (half
    /// the cost of a point).
    fn reads_gas_path(&self) -> bool {
        true
    }
    /// The fuel that burns at a steady point for a metered flow, kg/s: the steady limit of
    /// [`Effect::fuel_delivered`] (a delay or lag passes the metered flow unchanged; a meter
    /// error does not).
    fn steady_fuel_burnt(&self, metered_kg_s: f64) -> f64 {
        metered_kg_s
    }
    /// The ambient the engine really runs in, given the ambient its instruments read (T1 and
    /// the ambient pressure are inputs of the model: an error on them enters here).
    fn true_ambient(&self, t_amb_k: f64, p_amb_kpa: f64) -> (f64, f64) {
        (t_amb_k, p_amb_kpa)
    }
    /// The effect's states with the engine at rest.
    fn rest_states(&self, _core: &CoreView, _x: &mut [f64]) {}
    /// The effect's states in equilibrium at a steady point (`stations` as the core model
    /// computes it). The default is the rest state: override it when a gas-path hook depends
    /// on the states.
    fn steady_states(&self, core: &CoreView, _stations: &Stations, x: &mut [f64]) {
        self.rest_states(core, x)
    }
    /// Time derivatives of the effect's states (per second).
    fn derivatives(&self, _ctx: &Context<'_>, _x: &[f64], _dx: &mut [f64]) {}
    /// Fuel delivery: the fuel that burns, given the fuel `upstream` of this effect (the metered
    /// flow, or what earlier effects delivered), kg/s.
    fn fuel_delivered(&self, upstream_kg_s: f64, _core: &CoreView, _x: &[f64]) -> f64 {
        upstream_kg_s
    }
    /// Bleed / flow schedule: extra fraction of compressor flow bled overboard.
    fn bleed_fraction(&self, _core: &CoreView, _x: &[f64]) -> f64 {
        0.0
    }
    /// Where that bleed leaves the compressor, as the fraction of its log pressure ratio ahead
    /// of the port (1: its exit, the air having had all its work).
    fn bleed_port(&self) -> f64 {
        1.0
    }
    /// Component deltas: multiply `d` by this effect's flow/efficiency changes.
    fn component_deltas(&self, _core: &CoreView, _x: &[f64], _d: &mut ComponentDeltas) {}
    /// Duct losses: multiply `d` by this effect's inlet/exhaust loss changes.
    fn duct_losses(&self, _core: &CoreView, _x: &[f64], _d: &mut DuctLosses) {}
    /// Heat exchange: heat flow from the combustor gas into metal, W (negative: metal heats gas).
    fn heat_to_metal_w(&self, _core: &CoreView, _x: &[f64]) -> f64 {
        0.0
    }
    /// Instrument path: what the instrument of `signal` records, given the series it would record
    /// without this effect (sample times `t_s`). Whole series, so lags and delays are possible.
    fn instrument(&self, _signal: Signal, _t_s: &[f64], _series: &mut [f64]) {}
}

/// Parameter values of one effect as the engine file states them.
pub(crate) type EffectParams = BTreeMap<String, f64>;

/// Errors building an effect from the engine file.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub(crate) enum EffectError {
    #[error("unknown effect `{name}` (known: {known})")]
    Unknown { name: String, known: String },
    #[error("effect `{effect}` has no parameter `{param}` (it has: {known})")]
    UnknownParam {
        effect: String,
        param: String,
        known: String,
    },
}

/// The range of `effects.<effect>.<param>`, if both exist.
pub(crate) fn param_spec(effect: &str, param: &str) -> Option<&'static ParamSpec> {
    spec(effect)?.params.iter().find(|p| p.name == param)
}

/// The complete parameter vector of `spec` from the file's values (defaults for the rest).
fn values_for(spec: &EffectSpec, given: &EffectParams) -> Result<Vec<f64>, EffectError> {
    if let Some(bad) = given
        .keys()
        .find(|k| !spec.params.iter().any(|p| p.name == k.as_str()))
    {
        return Err(EffectError::UnknownParam {
            effect: spec.name.into(),
            param: bad.clone(),
            known: spec
                .params
                .iter()
                .map(|p| p.name)
                .collect::<Vec<_>>()
                .join(", "),
        });
    }
    Ok(spec
        .params
        .iter()
        .map(|p| given.get(p.name).copied().unwrap_or(p.default))
        .collect())
}

/// Checks the names in an `[effects]` section (values are range-checked with every other
/// engine-file number).
pub(crate) fn check(section: &BTreeMap<String, EffectParams>) -> Result<(), EffectError> {
    for (name, given) in section {
        let (s, _) = resolve(name)?;
        values_for(s, given)?;
    }
    Ok(())
}

/// The `[effects]` section with every enabled effect's parameters complete (defaults filled
/// in), so each is addressable as a named parameter.
pub(crate) fn complete(
    section: &BTreeMap<String, EffectParams>,
) -> Result<BTreeMap<String, EffectParams>, EffectError> {
    check(section)?;
    let mut out = BTreeMap::new();
    for (name, given) in section {
        if let Ok((s, _)) = resolve(name) {
            let vals = values_for(s, given)?;
            out.insert(
                name.clone(),
                s.params
                    .iter()
                    .zip(vals)
                    .map(|(p, v)| (p.name.to_string(), v))
                    .collect(),
            );
        }
    }
    Ok(out)
}

/// The enabled effects of a model, in order, with the state block each owns.
#[derive(Debug, Clone, Default)]
pub struct EffectSet {
    effects: Vec<Arc<dyn Effect>>,
    /// Instance names, in effect order.
    names: Vec<String>,
    layout: super::state::StateLayout,
}

impl EffectSet {
    /// No effects: the core model alone.
    pub fn none() -> EffectSet {
        EffectSet {
            effects: Vec::new(),
            names: Vec::new(),
            layout: super::state::StateLayout::core(),
        }
    }

    /// The effects of an `[effects]` section (in name order).
    pub fn from_section(section: &BTreeMap<String, EffectParams>) -> Result<EffectSet, String> {
        check(section).map_err(|e| e.to_string())?;
        let mut effects = Vec::new();
        let mut names = Vec::new();
        for (name, given) in section {
            let (s, channel) = resolve(name).map_err(|e| e.to_string())?;
            let vals = values_for(s, given).map_err(|e| e.to_string())?;
            effects.push((s.build)(&vals, channel));
            names.push(name.clone());
        }
        let sizes: Vec<usize> = effects.iter().map(|e| e.n_states()).collect();
        let layout = super::state::StateLayout::with_blocks(&sizes).map_err(|e| e.to_string())?;
        Ok(EffectSet {
            effects,
            names,
            layout,
        })
    }

    /// Effects given as built instances, in order, not resolved through [`REGISTRY`]: for
    /// models that must stay out of the candidate library (the gap bench's hidden truths).
    /// Put the set on a [`super::Model`] (`model.effects`) to simulate with it.
    pub fn from_instances(instances: Vec<(String, Arc<dyn Effect>)>) -> Result<EffectSet, String> {
        let sizes: Vec<usize> = instances.iter().map(|(_, e)| e.n_states()).collect();
        let layout = super::state::StateLayout::with_blocks(&sizes).map_err(|e| e.to_string())?;
        let (names, effects) = instances.into_iter().unzip();
        Ok(EffectSet {
            effects,
            names,
            layout,
        })
    }

    /// Whether no effect is on.
    pub fn is_empty(&self) -> bool {
        self.effects.is_empty()
    }

    /// Whether any enabled effect reads the gas path's state or carries states
    /// ([`Effect::reads_gas_path`]).
    pub fn reads_gas_path(&self) -> bool {
        self.effects
            .iter()
            .any(|e| e.reads_gas_path() || e.n_states() > 0)
    }

    /// The state layout (core plus each effect's block).
    pub fn layout(&self) -> &super::state::StateLayout {
        &self.layout
    }

    /// Instance names of the enabled effects, in order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    fn each<'s>(&'s self, y: &'s [f64]) -> impl Iterator<Item = (&'s dyn Effect, &'s [f64])> {
        self.effects
            .iter()
            .enumerate()
            .map(move |(i, e)| (e.as_ref(), &y[self.layout.block(i)]))
    }

    /// The fuel that burns at a steady point for a metered flow (the effects in order).
    pub fn steady_fuel_burnt(&self, metered_kg_s: f64) -> f64 {
        self.effects
            .iter()
            .fold(metered_kg_s, |wf, e| e.steady_fuel_burnt(wf))
    }

    /// The ambient the engine really runs in, given the measured one (the effects in order).
    pub fn true_ambient(&self, t_amb_k: f64, p_amb_kpa: f64) -> (f64, f64) {
        self.effects
            .iter()
            .fold((t_amb_k, p_amb_kpa), |(t, p), e| e.true_ambient(t, p))
    }

    /// Fills every effect's rest states into `y`.
    pub fn rest_states(&self, core: &CoreView, y: &mut [f64]) {
        for (i, e) in self.effects.iter().enumerate() {
            e.rest_states(core, &mut y[self.layout.block(i)]);
        }
    }

    /// Fills every effect's steady-state (equilibrium) states into `y`.
    pub fn steady_states(&self, core: &CoreView, stations: &Stations, y: &mut [f64]) {
        for (i, e) in self.effects.iter().enumerate() {
            e.steady_states(core, stations, &mut y[self.layout.block(i)]);
        }
    }

    /// Fuel burnt for a metered flow (the effects in order).
    pub fn fuel_delivered(&self, metered_kg_s: f64, core: &CoreView, y: &[f64]) -> f64 {
        self.each(y)
            .fold(metered_kg_s, |wf, (e, x)| e.fuel_delivered(wf, core, x))
    }

    /// Total extra bleed, with where it leaves the compressor (its bleed-weighted port).
    pub fn bleed(&self, core: &CoreView, y: &[f64]) -> ExtraBleed {
        let mut total = 0.0;
        let mut ported = 0.0;
        for (e, x) in self.each(y) {
            let b = e.bleed_fraction(core, x);
            total += b;
            ported += b * e.bleed_port();
        }
        ExtraBleed {
            fraction: total,
            port: if total != 0.0 { ported / total } else { 1.0 },
        }
    }

    /// Combined component deltas.
    pub fn component_deltas(&self, core: &CoreView, y: &[f64]) -> ComponentDeltas {
        let mut d = ComponentDeltas::NONE;
        for (e, x) in self.each(y) {
            e.component_deltas(core, x, &mut d);
        }
        d
    }

    /// Combined duct-loss multipliers.
    pub fn duct_losses(&self, core: &CoreView, y: &[f64]) -> DuctLosses {
        let mut d = DuctLosses::NONE;
        for (e, x) in self.each(y) {
            e.duct_losses(core, x, &mut d);
        }
        d
    }

    /// Total heat from the combustor gas to metal, W.
    pub fn heat_to_metal_w(&self, core: &CoreView, y: &[f64]) -> f64 {
        self.each(y).map(|(e, x)| e.heat_to_metal_w(core, x)).sum()
    }

    /// Every effect's state derivatives into `dy`.
    pub fn derivatives(&self, ctx: &Context<'_>, y: &[f64], dy: &mut [f64]) {
        for (i, e) in self.effects.iter().enumerate() {
            let r = self.layout.block(i);
            e.derivatives(ctx, &y[r.clone()], &mut dy[r]);
        }
    }

    /// The instrument path of every effect applied to one recorded series.
    pub fn instrument(&self, signal: Signal, t_s: &[f64], series: &mut [f64]) {
        for e in &self.effects {
            e.instrument(signal, t_s, series);
        }
    }
}

/// First-order lag derivative dx/dt = (u − x)/τ, with τ below `TAU_MIN_S` treated as
/// `TAU_MIN_S` (a pass-through as fast as the integrator's tolerance allows). Shared by effects.
pub(crate) fn lag_rate(u: f64, x: f64, tau_s: f64) -> f64 {
    (u - x) / tau_s.max(TAU_MIN_S)
}

/// A lumped metal temperature node (normalised by 1000 K) following the combustor gas (T3) with a
/// time constant: at ambient with the engine at rest, at T3 in steady operation. Shared by the
/// effects whose metal lags the gas (`heat_soak`, `tip_clearance`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct MetalNode {
    pub(crate) tau_s: f64,
}

impl MetalNode {
    /// Normalisation of the node's state, K.
    pub(crate) const T_SCALE_K: f64 = 1000.0;
    /// The node's temperature, K, from its state.
    pub(crate) fn temperature_k(x: f64) -> f64 {
        x * Self::T_SCALE_K
    }
    /// State at rest: the metal at the temperature of the still gas around it (ambient after a
    /// long stop, warmer in a restart soon after a run).
    pub(crate) fn rest(core: &CoreView) -> f64 {
        core.t3_k.max(core.t_amb_k) / Self::T_SCALE_K
    }
    /// State in steady operation (at the gas temperature).
    pub(crate) fn steady(stations: &Stations) -> f64 {
        stations.t3_k / Self::T_SCALE_K
    }
    /// d(state)/dt.
    pub(crate) fn rate(&self, core: &CoreView, x: f64) -> f64 {
        lag_rate(core.t3_k / Self::T_SCALE_K, x, self.tau_s)
    }
}

/// Shortest time constant an effect state is given, s.
pub(crate) const TAU_MIN_S: f64 = 1e-3;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registry_names_are_unique_snake_case_and_defaults_in_range() {
        for (i, s) in REGISTRY.iter().enumerate() {
            assert!(
                s.name
                    .chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_'),
                "{}",
                s.name
            );
            assert!(REGISTRY[..i].iter().all(|o| o.name != s.name));
            for p in s.params {
                assert!(
                    p.min <= p.default && p.default <= p.max,
                    "{}.{}",
                    s.name,
                    p.name
                );
            }
        }
    }

    /// A refinement's starts give one value per refinement parameter, within its range; an
    /// effect with starts has a refinement to start.
    #[test]
    fn refinement_starts_fit_the_refinement_parameters() {
        for s in REGISTRY {
            let refinement: Vec<&ParamSpec> = s.params.iter().filter(|p| p.refinement).collect();
            let Some(starts) = s.refinement_starts else {
                continue;
            };
            assert!(
                !refinement.is_empty(),
                "{}: starts without a refinement",
                s.name
            );
            let defaults: Vec<f64> = s.params.iter().map(|p| p.default).collect();
            let all = starts(&defaults);
            assert!(!all.is_empty(), "{}", s.name);
            for start in all {
                assert_eq!(start.len(), refinement.len(), "{}", s.name);
                for (p, v) in refinement.iter().zip(start) {
                    assert!(p.min <= v && v <= p.max, "{}.{} start {v}", s.name, p.name);
                }
            }
        }
    }

    #[test]
    fn unknown_effect_and_parameter_are_named() {
        let mut sec = BTreeMap::new();
        sec.insert("warp_drive".to_string(), EffectParams::new());
        let e = check(&sec).expect_err("unknown").to_string();
        assert!(e.contains("warp_drive"), "{e}");
        for name in instance_names() {
            assert!(e.contains(&name), "{e} lists {name}");
            let mut sec = BTreeMap::new();
            let mut p = EffectParams::new();
            p.insert("no_such_param".into(), 1.0);
            sec.insert(name.clone(), p);
            let e = check(&sec).expect_err("unknown param").to_string();
            assert!(e.contains("no_such_param"), "{e}");
        }
    }

    #[test]
    fn every_effect_completes_with_defaults_and_lays_out_its_states() {
        assert!(EffectSet::none().layout().is_core_only());
        for name in instance_names() {
            let (s, ch) = resolve(&name).expect("resolves");
            let mut sec = BTreeMap::new();
            sec.insert(name.clone(), EffectParams::new());
            let full = complete(&sec).expect("complete");
            assert_eq!(full[&name].len(), s.params.len());
            let set = EffectSet::from_section(&full).expect("builds");
            assert_eq!(set.names(), std::slice::from_ref(&name));
            let defaults: Vec<f64> = s.params.iter().map(|p| p.default).collect();
            let n = (s.build)(&defaults, ch).n_states();
            assert_eq!(set.layout().len(), super::super::state::NX_CORE + n);
        }
        // A per-channel effect needs a channel it covers; an engine effect takes none.
        for s in REGISTRY {
            let bad = match s.channels {
                Channels::Engine => format!("{}:t34_k", s.name),
                _ => s.name.to_string(),
            };
            assert!(resolve(&bad).is_err(), "{bad}");
        }
    }

    /// Every effect at its defaults: the start-up still reaches steady load, at the core
    /// model's steady power (each effect changes transients or instruments, not the rating).
    #[test]
    fn every_effect_at_defaults_runs_a_start_to_the_same_load() {
        use crate::engine::simulation::run_scenario;
        use crate::engine::{Engine, Scenario};
        use crate::health::HealthParams;
        let h = HealthParams::HEALTHY;
        let core = Engine::reference().expect("engine");
        let end = |e: &Engine| {
            let (s, _) = run_scenario(&e.model(&h), &Scenario::startup(e.cfg())).expect("runs");
            let last = s.last().expect("samples");
            assert_eq!(last.phase, crate::signals::Phase::Steady);
            last.stations.power_mw
        };
        let p0 = end(&core);
        for spec in REGISTRY {
            let name = match spec.channels {
                Channels::Engine => spec.name.to_string(),
                ch => format!("{}:{}", spec.name, ch.signals()[0].column()),
            };
            let mut e = core.clone();
            let first = spec.params[0];
            e.set_param(&format!("effects.{name}.{}", first.name), first.default)
                .expect("enables");
            assert_eq!(e.effects().names(), std::slice::from_ref(&name));
            let p = end(&e);
            assert!((p / p0 - 1.0).abs() < 0.01, "{name}: {p} MW vs {p0} MW");
        }
    }
}
