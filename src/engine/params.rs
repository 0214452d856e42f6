//! Named engine parameters: the one place to read or change a number of the engine file by its
//! dotted key (`dynamics.gg_inertia_kg_m2`, `sensors.t4.tau_s`,
//! `control.accel_limit_speed_rpm[2]`, `effects.fuel_system.lag_s`).
//!
//! Setting a parameter of an effect the file does not enable enables that effect, with its
//! defaults for the other parameters; effect parameters never touch the design calibration, so
//! changing one only rebuilds the effects.
//!
//! [`Engine::set_param`] validates the new value (finite, inside the key's range, and the
//! relations between keys) and rebuilds everything that depends on it — design calibration and
//! the frozen [`super::model::Constants`] — so a change can never silently do nothing. On error
//! the engine is left unchanged. Pure: no I/O (the maps are kept in memory, never re-read).

use super::config::{param_range, EngineConfig};
use super::design::DesignCycles;
use super::model::{Engine, EngineError};
use serde_json::Value;

fn param_error(key: &str, reason: impl Into<String>) -> EngineError {
    EngineError::Param {
        key: key.into(),
        reason: reason.into(),
    }
}

/// One step of a dotted key: an object field, optionally followed by an array index.
struct Step<'a> {
    field: &'a str,
    index: Option<usize>,
}

fn parse_key(key: &str) -> Result<Vec<Step<'_>>, EngineError> {
    if key.is_empty() {
        return Err(param_error(key, "empty key"));
    }
    key.split('.')
        .map(|part| match part.split_once('[') {
            None if !part.is_empty() => Ok(Step {
                field: part,
                index: None,
            }),
            Some((field, rest)) if !field.is_empty() => {
                let idx = rest
                    .strip_suffix(']')
                    .and_then(|i| i.parse::<usize>().ok())
                    .ok_or_else(|| param_error(key, "malformed array index (use `name[i]`)"))?;
                Ok(Step {
                    field,
                    index: Some(idx),
                })
            }
            _ => Err(param_error(key, "malformed key (use `section.name`)")),
        })
        .collect()
}

/// The JSON node a key points to, for reading or writing.
fn node_mut<'v>(tree: &'v mut Value, key: &str) -> Result<&'v mut Value, EngineError> {
    let mut node = tree;
    for step in parse_key(key)? {
        node = node
            .get_mut(step.field)
            .ok_or_else(|| param_error(key, format!("no such key `{}`", step.field)))?;
        if let Some(i) = step.index {
            node = node
                .get_mut(i)
                .ok_or_else(|| param_error(key, format!("index {i} out of range")))?;
        }
    }
    Ok(node)
}

/// The number a dotted key names, reached directly, for the keys a calibration sets on every
/// model evaluation (the design table, the shaft losses, the maps' design coordinates, the
/// load exponent, the adaptation curves, the effects' parameters); `None` for any other key
/// (and for one that names nothing), which goes through the file's tree
/// ([`EngineConfig::with_params`]) and gets its error there. Why: a calibration sets 10–40
/// numbers per evaluation, and the round trip of the whole file through a JSON tree was a
/// tenth of a foreign unit's calibration time. Setting a field directly gives the same file
/// as the round trip (each of these is a plain `f64`, and the tree holds an `f64` exactly);
/// `direct_setting_equals_the_round_trip` checks it key by key.
fn number_mut<'c>(cfg: &'c mut EngineConfig, key: &str) -> Option<&'c mut f64> {
    let (section, rest) = key.split_once('.')?;
    match section {
        "design" => {
            let d = &mut cfg.design;
            Some(match rest {
                "pressure_ratio" => &mut d.pressure_ratio,
                "exhaust_flow_kg_s" => &mut d.exhaust_flow_kg_s,
                "power_mw" => &mut d.power_mw,
                "compressor_efficiency" => &mut d.compressor_efficiency,
                "hpt_efficiency" => &mut d.hpt_efficiency,
                "pt_efficiency" => &mut d.pt_efficiency,
                "gg_speed_rpm" => &mut d.gg_speed_rpm,
                "pt_speed_rpm" => &mut d.pt_speed_rpm,
                "inlet_loss_frac" => &mut d.inlet_loss_frac,
                "combustor_loss_frac" => &mut d.combustor_loss_frac,
                "combustion_efficiency" => &mut d.combustion_efficiency,
                "gg_mechanical_efficiency" => &mut d.gg_mechanical_efficiency,
                "pt_mechanical_efficiency" => &mut d.pt_mechanical_efficiency,
                "exhaust_back_pressure_ratio" => &mut d.exhaust_back_pressure_ratio,
                "cooling_bleed_frac" => &mut d.cooling_bleed_frac,
                "cooling_return_frac" => &mut d.cooling_return_frac,
                _ => return None,
            })
        }
        "dynamics" => {
            let d = &mut cfg.dynamics;
            Some(match rest {
                "gg_friction_kw_at_design" => &mut d.gg_friction_kw_at_design,
                "pt_windage_kw_at_sync" => &mut d.pt_windage_kw_at_sync,
                _ => return None,
            })
        }
        "maps" => {
            let m = &mut cfg.maps;
            Some(match rest {
                "compressor_design_speed" => &mut m.compressor_design_speed,
                "compressor_design_beta" => &mut m.compressor_design_beta,
                "hpt_design_speed" => &mut m.hpt_design_speed,
                "hpt_design_pr" => &mut m.hpt_design_pr,
                "pt_design_speed" => &mut m.pt_design_speed,
                "pt_design_pr" => &mut m.pt_design_pr,
                _ => return None,
            })
        }
        "load" if rest == "exponent" => cfg.load.as_mut().map(|l| &mut l.exponent),
        "effects" => {
            let (effect, param) = rest.split_once('.')?;
            cfg.effects.get_mut(effect)?.get_mut(param)
        }
        "adaptation" => {
            let (component, item) = rest.split_once('.')?;
            let (curve, index) = item.strip_suffix(']')?.split_once('[')?;
            let index: usize = index.parse().ok()?;
            let a = cfg.adaptation.as_mut()?;
            let c = match component {
                "compressor" => a.compressor.as_mut()?,
                "hpt" => a.hpt.as_mut()?,
                "pt" => a.pt.as_mut()?,
                _ => return None,
            };
            let values = match curve {
                "speed_knots" => &mut c.speed_knots,
                "flow" => &mut c.flow,
                "efficiency" => &mut c.efficiency,
                "pressure_ratio" => &mut c.pressure_ratio,
                "speed" => &mut c.speed,
                _ => return None,
            };
            values.get_mut(index)
        }
        _ => None,
    }
}

fn tree_of(cfg: &EngineConfig, key: &str) -> Result<Value, EngineError> {
    serde_json::to_value(cfg).map_err(|e| param_error(key, e.to_string()))
}

impl EngineConfig {
    /// The number at dotted `key`. A parameter of an effect the file does not enable reads as
    /// that effect's default (the value it takes once enabled).
    pub fn get_param(&self, key: &str) -> Result<f64, EngineError> {
        if let Some((effect, param)) = key.strip_prefix("effects.").and_then(|r| r.split_once('.'))
        {
            if !self.effects.contains_key(effect) {
                return super::effects::param_spec(effect, param)
                    .map(|p| p.default)
                    .ok_or_else(|| param_error(key, "no such effect parameter"));
            }
        }
        let mut tree = tree_of(self, key)?;
        let node = node_mut(&mut tree, key)?;
        node.as_f64()
            .ok_or_else(|| param_error(key, "is not a number (a section, list or text)"))
    }

    /// A copy with the number at dotted `key` set to `value`, validated as a whole.
    pub fn with_param(&self, key: &str, value: f64) -> Result<EngineConfig, EngineError> {
        self.with_params([(key, value)])
    }

    /// A copy with several numbers set, validated once as a whole (the relations between keys
    /// are checked on the final values, not on each intermediate state). Errors name the first
    /// key refused.
    ///
    /// Why once: a calibration sets 10–40 numbers per model evaluation, and a round trip
    /// through the file's tree plus the whole file's validation per key was four fifths of a
    /// foreign unit's adaptation time (the engine's physics one fifth).
    pub fn with_params<'k>(
        &self,
        values: impl IntoIterator<Item = (&'k str, f64)>,
    ) -> Result<EngineConfig, EngineError> {
        self.with_params_on(values, Base::Unchecked)
    }

    /// [`EngineConfig::with_params`], told whether `self` is known valid (an engine's own
    /// file: every [`Engine`] is built from a validated one), in which case the result is
    /// validated without the pass over every number ([`EngineConfig::validate_changed`]): each
    /// changed number has been checked against its range here, the others were valid.
    fn with_params_on<'k>(
        &self,
        values: impl IntoIterator<Item = (&'k str, f64)>,
        known: Base,
    ) -> Result<EngineConfig, EngineError> {
        let values: Vec<(&str, f64)> = values.into_iter().collect();
        let mut base = self.clone();
        for &(key, value) in &values {
            let range = param_range(key).ok_or_else(|| param_error(key, "not a tunable number"))?;
            range.check(value).map_err(|r| param_error(key, r))?;
            if let Some((effect, _)) = key.strip_prefix("effects.").and_then(|r| r.split_once('.'))
            {
                if !base.effects.contains_key(effect) {
                    base.effects.insert(effect.to_string(), Default::default());
                    base.effects = super::effects::complete(&base.effects)
                        .map_err(|e| param_error(key, e.to_string()))?;
                }
            }
        }
        if values.is_empty() {
            return Ok(base);
        }
        // A key the direct setter does not reach sends all of them through the tree, which
        // sets every one again on top of those already set.
        let cfg = if set_directly(&mut base, &values) {
            base
        } else {
            self.set_through_tree(base, &values)?
        };
        match known {
            Base::Valid => cfg.validate_changed("<set_param>")?,
            Base::Unchecked => cfg.validate("<set_param>")?,
        }
        Ok(cfg)
    }

    /// `values` set on `base` (a copy of `self` with its effects completed) through the file's
    /// tree: any key, each refused with its reason.
    fn set_through_tree(
        &self,
        base: EngineConfig,
        values: &[(&str, f64)],
    ) -> Result<EngineConfig, EngineError> {
        let Some(&(first, _)) = values.first() else {
            return Ok(base);
        };
        let mut tree = tree_of(&base, first)?;
        for &(key, value) in values {
            let node = node_mut(&mut tree, key)?;
            if !node.is_number() {
                return Err(param_error(
                    key,
                    "is not a number (a section, list or text)",
                ));
            }
            let num = serde_json::Number::from_f64(value)
                .ok_or_else(|| param_error(key, "must be a finite number"))?;
            *node = Value::Number(num);
        }
        match serde_json::from_value(tree) {
            Ok(cfg) => Ok(cfg),
            // Name the key the file's types refuse (e.g. a fraction for a count): set one
            // at a time, the first that fails is it (the cold path only).
            Err(e) if values.len() > 1 => {
                for &(key, value) in values {
                    self.with_params([(key, value)])?;
                }
                Err(param_error(first, e.to_string()))
            }
            Err(e) => Err(param_error(first, e.to_string())),
        }
    }
}

/// `values` set on `base` field by field ([`number_mut`]); `false` at the first key it does not
/// reach (those before it are set).
fn set_directly(base: &mut EngineConfig, values: &[(&str, f64)]) -> bool {
    for &(key, value) in values {
        match number_mut(base, key) {
            Some(slot) => *slot = value,
            None => return false,
        }
    }
    true
}

/// Whether the file numbers are set on is known to be valid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Base {
    /// An engine's own file (validated when the engine was built).
    Valid,
    /// Any file.
    Unchecked,
}

impl Engine {
    /// The engine-file number at dotted `key` (e.g. `dynamics.gg_inertia_kg_m2`).
    pub fn get_param(&self, key: &str) -> Result<f64, EngineError> {
        self.cfg().get_param(key)
    }

    /// Sets the engine-file number at dotted `key` and rebuilds the design calibration and
    /// constants. Errors (unknown key, non-finite or out-of-range value, a broken relation
    /// between keys, a failed calibration) leave the engine unchanged.
    pub fn set_param(&mut self, key: &str, value: f64) -> Result<(), EngineError> {
        let cfg = self.cfg().with_param(key, value)?;
        if key.starts_with("effects.") {
            // Effects never change the design calibration: rebuild them alone.
            return self.replace_effects(cfg);
        }
        *self = Engine::calibrate_with(cfg, self.raw_maps().clone(), &self.design_cycles())?;
        Ok(())
    }

    /// A copy built from `cfg` (validated) on this engine's maps, without reading map files
    /// again: for a structural change of the file, such as a new `[adaptation]` section, that
    /// numbers alone cannot make. A `cfg` naming other map files or another interpolation is
    /// refused (the maps it holds were loaded for this engine's; `Engine::new` reads them):
    /// built on these maps it would silently be another engine than its file says.
    pub fn with_config(&self, cfg: EngineConfig) -> Result<Engine, EngineError> {
        cfg.validate("<with_config>")?;
        let (old, new) = (&self.cfg().maps, &cfg.maps);
        let changed = [
            (
                "maps.compressor_file",
                old.compressor_file != new.compressor_file,
            ),
            ("maps.hpt_file", old.hpt_file != new.hpt_file),
            ("maps.pt_file", old.pt_file != new.pt_file),
            (
                "maps.compressor_map",
                old.compressor_map != new.compressor_map,
            ),
            ("maps.hpt_map", old.hpt_map != new.hpt_map),
            ("maps.pt_map", old.pt_map != new.pt_map),
            ("maps.interpolation", old.interpolation != new.interpolation),
        ];
        if let Some((key, _)) = changed.iter().find(|(_, c)| *c) {
            return Err(EngineError::Param {
                key: (*key).to_string(),
                reason: "differs from the engine's loaded maps; build the engine from the file \
                         (Engine::new) to load other maps"
                    .into(),
            });
        }
        Engine::calibrate(cfg, self.raw_maps().clone())
    }

    /// A copy with several engine-file numbers set at once and the design calibrated once
    /// (what `set_param` in a loop would give, at the cost of one calibration). Errors name the
    /// first key refused; `self` is never changed.
    pub fn with_params(&self, values: &[(String, f64)]) -> Result<Engine, EngineError> {
        self.with_params_cycles(values, &self.design_cycles())
    }

    /// [`Engine::with_params`] taking the design cycle from `cycles` where it holds the one of
    /// the new file (a problem that builds an engine per evaluation keeps one for all of
    /// them; the engine is the same bit for bit).
    pub(crate) fn with_params_cycles(
        &self,
        values: &[(String, f64)],
        cycles: &DesignCycles,
    ) -> Result<Engine, EngineError> {
        let cfg = self
            .cfg()
            .with_params_on(values.iter().map(|(k, v)| (k.as_str(), *v)), Base::Valid)?;
        Engine::calibrate_with(cfg, self.raw_maps().clone(), cycles)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::config::REFERENCE_ENGINE_TOML;

    fn engine() -> Engine {
        Engine::reference().expect("reference engine")
    }

    #[test]
    fn with_config_refuses_other_maps_than_it_holds() {
        let e = engine();
        let mut cfg = e.cfg().clone();
        cfg.maps.interpolation = crate::engine::config::MapInterpolation::Cubic;
        let err = e.with_config(cfg).expect_err("other interpolation refused");
        assert!(err.to_string().contains("maps.interpolation"), "{err}");
        let mut cfg = e.cfg().clone();
        cfg.maps.pt_file = "elsewhere.map".into();
        let err = e.with_config(cfg).expect_err("other map file refused");
        assert!(err.to_string().contains("maps.pt_file"), "{err}");
        // Numbers and sections other than the maps' files still go through.
        let mut cfg = e.cfg().clone();
        cfg.design.power_mw *= 1.01;
        assert!(e.with_config(cfg).is_ok());
    }

    /// An engine's `with_params` skips the pass over every number of its (valid) file: it must
    /// refuse and accept exactly what the file's full validation does.
    #[test]
    fn an_engines_with_params_judges_as_the_full_validation() {
        let e = engine();
        let idle = e.cfg().sequence.idle_speed_rpm;
        let cases: [(&str, f64); 5] = [
            ("design.hpt_efficiency", 0.87),
            ("design.hpt_efficiency", 2.0),
            ("design.hpt_efficiency", f64::NAN),
            // A relation between keys: idle above the design GG speed.
            ("design.gg_speed_rpm", idle - 1.0),
            ("control.accel_limit_speed_rpm[2]", 1.0e9),
        ];
        for (key, value) in cases {
            let full = e.cfg().with_params([(key, value)]);
            let fast = e.with_params(&[(key.to_string(), value)]);
            match (&full, &fast) {
                (Ok(cfg), Ok(engine)) => assert_eq!(engine.cfg(), cfg, "{key} = {value}"),
                (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "{key} = {value}"),
                _ => panic!("{key} = {value}: full {full:?}, engine {:?}", fast.is_ok()),
            }
        }
        assert!(e
            .with_params(&[("design.hpt_efficiency".into(), 0.87)])
            .is_ok());
        assert!(e
            .with_params(&[("design.gg_speed_rpm".into(), idle - 1.0)])
            .is_err());
    }

    #[test]
    fn get_reads_nested_and_indexed_keys() {
        let e = engine();
        assert_eq!(e.get_param("dynamics.gg_inertia_kg_m2").expect("key"), 40.0);
        assert_eq!(e.get_param("sensors.t4.tau_s").expect("key"), 3.0);
        assert_eq!(
            e.get_param("control.accel_limit_speed_rpm[2]")
                .expect("key"),
            5000.0
        );
    }

    #[test]
    fn unknown_or_non_numeric_keys_are_named() {
        let e = engine();
        for key in [
            "dynamics.nope",
            "name",
            "dynamics",
            "",
            "control.accel_limit_speed_rpm[99]",
        ] {
            let err = e.get_param(key).expect_err(key);
            assert!(err.to_string().contains(&format!("`{key}`")), "{err}");
        }
    }

    #[test]
    fn set_rebuilds_constants_and_design() {
        let mut e = engine();
        let t3_before = e.design().t3_k;
        e.set_param("dynamics.gg_inertia_kg_m2", 55.0)
            .expect("valid value");
        assert_eq!(e.consts().gg_inertia, 55.0);
        assert_eq!(e.cfg().dynamics.gg_inertia_kg_m2, 55.0);
        assert_eq!(e.model(&Default::default()).consts.gg_inertia, 55.0);
        // A design value moves the calibrated cycle.
        e.set_param("design.compressor_efficiency", 0.83)
            .expect("valid value");
        assert!(e.design().t3_k > t3_before + 1.0, "{}", e.design().t3_k);
    }

    #[test]
    fn set_rejects_bad_values_and_leaves_engine_unchanged() {
        let mut e = engine();
        let cases: [(&str, f64); 6] = [
            ("dynamics.gg_inertia_kg_m2", f64::NAN),
            ("dynamics.gg_inertia_kg_m2", -1.0),
            ("solver.max_step_s", 1e-300),
            ("sequence.min_load_mw", f64::INFINITY),
            // Breaks a relation between keys: base load below minimum load.
            ("sequence.base_load_mw", 1.0),
            ("name", 1.0),
        ];
        for (key, v) in cases {
            let err = e.set_param(key, v).expect_err(key);
            assert!(
                err.to_string()
                    .contains(key.split('.').next().unwrap_or(key)),
                "{err}"
            );
            assert_eq!(e.cfg(), &EngineConfig::reference(), "{key}");
        }
    }

    /// A batch is the values set one after another, checked once on the final state; a bad
    /// key among them is named.
    #[test]
    fn several_values_are_set_at_once_and_checked_as_a_whole() {
        let cfg = EngineConfig::reference();
        let one_by_one = cfg
            .with_param("dynamics.gg_inertia_kg_m2", 55.0)
            .and_then(|c| c.with_param("design.compressor_efficiency", 0.83))
            .expect("valid values");
        let batch = cfg
            .with_params([
                ("dynamics.gg_inertia_kg_m2", 55.0),
                ("design.compressor_efficiency", 0.83),
            ])
            .expect("valid values");
        assert_eq!(batch, one_by_one);
        // Base load below the minimum load alone breaks a relation; with the minimum lowered
        // in the same batch, the final state holds it.
        let low = 0.25 * cfg.sequence.min_load_mw;
        assert!(cfg.with_param("sequence.base_load_mw", low).is_err());
        let both = cfg
            .with_params([
                ("sequence.base_load_mw", low),
                ("sequence.min_load_mw", 0.5 * low),
            ])
            .expect("valid as a whole");
        assert_eq!(both.sequence.base_load_mw, low);
        for bad in ["dynamics.nope", "name"] {
            let err = cfg
                .with_params([("dynamics.gg_inertia_kg_m2", 55.0), (bad, 1.0)])
                .expect_err(bad);
            assert!(err.to_string().contains(&format!("`{bad}`")), "{err}");
        }
        assert_eq!(cfg.with_params([]).expect("nothing to set"), cfg);
    }

    /// Issue 12 item 5: values that used to panic or hang are load errors naming the key.
    #[test]
    fn load_rejects_non_finite_and_absurd_values() {
        let cases: [(&str, &str, &str); 8] = [
            (
                "min_load_mw = 3.0",
                "min_load_mw = nan",
                "sequence.min_load_mw",
            ),
            (
                "max_step_s = 1.0",
                "max_step_s = 1e-300",
                "solver.max_step_s",
            ),
            (
                "speed_kp_kg_s_per_rpm = 2.0e-4",
                "speed_kp_kg_s_per_rpm = nan",
                "control.speed_kp_kg_s_per_rpm",
            ),
            (
                "base_load_mw = 31.4",
                "base_load_mw = nan",
                "sequence.base_load_mw",
            ),
            (
                "compressor_design_beta = 0.5",
                "compressor_design_beta = nan",
                "maps.compressor_design_beta",
            ),
            (
                "exhaust_back_pressure_ratio = 1.03",
                "exhaust_back_pressure_ratio = nan",
                "design.exhaust_back_pressure_ratio",
            ),
            (
                "t4 = { tau_s = 3.0, noise_abs = 3.0 }",
                "t4 = { tau_s = inf, noise_abs = 3.0 }",
                "sensors.t4.tau_s",
            ),
            (
                "fixed_step_s = 0.0",
                "fixed_step_s = 1e-300",
                "solver.fixed_step_s",
            ),
        ];
        for (from, to, key) in cases {
            assert!(REFERENCE_ENGINE_TOML.contains(from), "{from}");
            let text = REFERENCE_ENGINE_TOML.replace(from, to);
            let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err(key);
            let msg = err.to_string();
            assert!(msg.contains(key) && msg.contains("x.toml"), "{key}: {msg}");
        }
    }

    #[test]
    fn every_number_of_the_reference_engine_has_a_range() {
        // validate() fails on a number without a range, so the reference engine passing proves
        // the table is complete; check it also contains the reference value of a few keys.
        let cfg = EngineConfig::reference();
        for key in [
            "design.power_mw",
            "sensors.p4.noise_rel",
            "control.min_fuel_kg_s",
        ] {
            let r = param_range(key).expect(key);
            let v = cfg.get_param(key).expect(key);
            assert!(r.check(v).is_ok(), "{key}");
        }
    }

    /// Every key the direct setter reaches gives the same file as the round trip through the
    /// tree, one key at a time and all at once; keys it does not reach go through the tree.
    #[test]
    fn direct_setting_equals_the_round_trip() {
        use crate::engine::config::{AdaptationConfig, ComponentCurves, LoadConfig, LoadMode};
        let curves = |scale: f64| ComponentCurves {
            speed_knots: vec![0.7, 0.85, 1.0],
            flow: vec![0.01 * scale, -0.02 * scale, 0.0],
            efficiency: vec![-0.01 * scale, 0.005, 0.0],
            pressure_ratio: vec![0.02, 0.01 * scale, 0.0],
            speed: vec![0.003, -0.001, 0.0],
            speed_of: None,
            efficiency_shape: None,
        };
        let mut cfg = EngineConfig::reference()
            .with_param("effects.vigv_schedule.flow_delta_pct", -3.0)
            .expect("effect enabled");
        cfg.adaptation = Some(AdaptationConfig {
            compressor: Some(curves(1.0)),
            hpt: Some(curves(0.5)),
            pt: Some(curves(2.0)),
            ..AdaptationConfig::default()
        });
        cfg.load = Some(LoadConfig {
            mode: LoadMode::LoadLaw,
            exponent: 3.0,
            speed_rpm: Vec::new(),
            power_mw: Vec::new(),
        });
        let mut keys: Vec<String> = [
            "pressure_ratio",
            "exhaust_flow_kg_s",
            "power_mw",
            "compressor_efficiency",
            "hpt_efficiency",
            "pt_efficiency",
            "gg_speed_rpm",
            "pt_speed_rpm",
            "inlet_loss_frac",
            "combustor_loss_frac",
            "combustion_efficiency",
            "gg_mechanical_efficiency",
            "pt_mechanical_efficiency",
            "exhaust_back_pressure_ratio",
            "cooling_bleed_frac",
            "cooling_return_frac",
        ]
        .iter()
        .map(|k| format!("design.{k}"))
        .collect();
        keys.extend(
            [
                "dynamics.gg_friction_kw_at_design",
                "dynamics.pt_windage_kw_at_sync",
                "maps.compressor_design_speed",
                "maps.compressor_design_beta",
                "maps.hpt_design_speed",
                "maps.hpt_design_pr",
                "maps.pt_design_speed",
                "maps.pt_design_pr",
                "load.exponent",
            ]
            .map(String::from),
        );
        for p in cfg.effects["vigv_schedule"].keys() {
            keys.push(format!("effects.vigv_schedule.{p}"));
        }
        for c in ["compressor", "hpt", "pt"] {
            for curve in [
                "speed_knots",
                "flow",
                "efficiency",
                "pressure_ratio",
                "speed",
            ] {
                for i in 0..3 {
                    keys.push(format!("adaptation.{c}.{curve}[{i}]"));
                }
            }
        }
        let values: Vec<(&str, f64)> = keys
            .iter()
            .map(|k| {
                let v = cfg.get_param(k).expect(k);
                (k.as_str(), v * (1.0 + 1e-3) + 1e-4)
            })
            .collect();
        let mut probe = cfg.clone();
        for &(key, value) in &values {
            assert!(number_mut(&mut probe, key).is_some(), "{key}");
            let one = [(key, value)];
            let tree = cfg.set_through_tree(cfg.clone(), &one).expect(key);
            let mut direct = cfg.clone();
            assert!(set_directly(&mut direct, &one), "{key}");
            assert_eq!(direct, tree, "{key}");
            assert_eq!(tree.get_param(key).expect(key), value, "{key}");
        }
        let tree = cfg.set_through_tree(cfg.clone(), &values).expect("all");
        let mut direct = cfg.clone();
        assert!(set_directly(&mut direct, &values));
        assert_eq!(direct, tree);
        // Keys it does not reach: other sections, optional numbers, lists without an index,
        // indices beyond a curve, nothing at all.
        for key in [
            "sensors.t4.tau_s",
            "design.fuel_lhv_j_per_kg",
            "adaptation.compressor.flow",
            "adaptation.compressor.flow[3]",
            "adaptation.model_error_pct.n1_rpm",
            "effects.no_such_effect.x",
            "design.nope",
        ] {
            assert!(number_mut(&mut probe, key).is_none(), "{key}");
        }
    }

    /// An engine rebuilt after numbers the design cycle does not read (an adaptation curve's
    /// value) takes its cycle over; after one it reads, solves it again: either way the engine
    /// is the one its file builds from scratch, bit for bit (the whole engine's `Debug`).
    #[test]
    fn a_rebuilt_engine_is_the_one_its_file_builds() {
        use crate::engine::config::{AdaptationConfig, ComponentCurves};
        let e = engine();
        let mut cfg = e.cfg().clone();
        cfg.adaptation = Some(AdaptationConfig {
            compressor: Some(ComponentCurves {
                speed_knots: vec![0.7, 0.85],
                flow: vec![-0.02, -0.01],
                efficiency: vec![-0.01, -0.005],
                ..ComponentCurves::default()
            }),
            ..AdaptationConfig::default()
        });
        let adapted = e.with_config(cfg).expect("adapted");
        for values in [
            vec![("adaptation.compressor.flow[1]".to_string(), 0.01)],
            vec![
                ("adaptation.compressor.efficiency[0]".to_string(), -0.03),
                ("design.pressure_ratio".to_string(), 15.5),
            ],
        ] {
            let rebuilt = adapted.with_params(&values).expect("rebuilt");
            let fresh = Engine::calibrate(rebuilt.cfg().clone(), adapted.raw_maps().clone())
                .expect("fresh");
            assert_eq!(format!("{rebuilt:?}"), format!("{fresh:?}"), "{values:?}");
        }
    }
}
