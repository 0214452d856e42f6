//! Writing a calibrated engine file: the original text with the fitted numbers (and, where the
//! file moves, its map paths) replaced in place, comments and layout kept (`toml_edit`), and a
//! header comment saying what was calibrated when.
//!
//! What it is for: a text-to-text rewrite the CLI saves. What it must not do: I/O (the caller
//! reads and writes the files and checks the result loads).

use super::CalibrateError;
use toml_edit::{DocumentMut, Item, Value};

/// A value to put at a dotted key.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum NewValue {
    Number(f64),
    Text(String),
    /// A list of numbers (an `[adaptation]` curve or its knots).
    Numbers(Vec<f64>),
    /// A list of words (`adaptation.ensemble.files`).
    Words(Vec<String>),
}

/// A number rounded to 7 significant digits (the engine file's precision; the fit's σ is far
/// larger), so the written file reads `0.8612345`, not `0.86123449876543`.
fn rounded(v: f64) -> f64 {
    format!("{v:.6e}").parse::<f64>().unwrap_or(v)
}

/// The item at a dotted key (`design.hpt_efficiency`, `sensors.t4.bias`).
fn item_mut<'d>(doc: &'d mut DocumentMut, key: &str) -> Option<&'d mut Item> {
    let mut parts = key.split('.');
    let mut item = doc.get_mut(parts.next()?)?;
    for part in parts {
        item = item.get_mut(part)?;
    }
    Some(item)
}

/// Whether the file has a value at a dotted key (looked up without inserting anything, which
/// `item_mut` may).
fn has_value(doc: &DocumentMut, key: &str) -> bool {
    let mut parts = key.split('.');
    let Some(mut item) = parts.next().and_then(|p| doc.get(p)) else {
        return false;
    };
    for part in parts {
        match item.get(part) {
            Some(i) => item = i,
            None => return false,
        }
    }
    item.is_value()
}

/// `key` split into the list's key and the index of one of its elements, for a key that names
/// one knot of a list (`adaptation.compressor.speed[0]`, a value `calibrate --params` fits).
fn element_of(key: &str) -> Option<(&str, usize)> {
    let (list, rest) = key.strip_suffix(']')?.rsplit_once('[')?;
    Some((list, rest.parse().ok()?))
}

/// The table `[section.name]`, made (the section implicit, so only `[section.name]` headers
/// appear) where missing; `None` when either exists as something other than a table.
fn sub_table<'d>(
    doc: &'d mut DocumentMut,
    section: &str,
    name: &str,
) -> Option<&'d mut toml_edit::Table> {
    doc.entry(section)
        .or_insert_with(|| {
            let mut t = toml_edit::Table::new();
            t.set_implicit(true);
            Item::Table(t)
        })
        .as_table_mut()?
        .entry(name)
        .or_insert_with(|| Item::Table(toml_edit::Table::new()))
        .as_table_mut()
}

/// `original` with each `(key, value)` replaced, keeping each value's surrounding comments and
/// spacing, and `header` (comment lines without the `#`) put first. Every key must already be
/// in the file as a value of the same kind (an error names the key otherwise), except an
/// effect's number (`effects.<instance>.<param>`), whose table is added when missing, and a
/// word of a section the file has (`design.inlet_loss_law`), added when the file leaves it
/// at its default. One element of a list the file has (`adaptation.<component>.<curve>[i]`) is
/// replaced in place, the rest of the list and of its section kept.
pub(crate) fn rewrite(
    original: &str,
    path_name: &str,
    values: &[(String, NewValue)],
    header: &[String],
) -> Result<String, CalibrateError> {
    let mut doc: DocumentMut = original.parse().map_err(|e| CalibrateError::File {
        path: path_name.to_string(),
        reason: format!("not TOML: {e}"),
    })?;
    // A new adaptation replaces the file's whole `[adaptation]` section: curves the new fit
    // does not have must not survive from an older one. (Knot values refitted on the file's own
    // curves, `adaptation.<component>.<curve>[i]`, keep it.)
    if values
        .iter()
        .any(|(k, _)| k.starts_with("adaptation.") && element_of(k).is_none())
    {
        doc.remove("adaptation");
    }
    for (key, new) in values {
        let bad = |reason: &str| CalibrateError::File {
            path: path_name.to_string(),
            reason: format!("key `{key}`: {reason}"),
        };
        if let Some((list, i)) = element_of(key) {
            // Looked up without inserting (`has_value`) before `item_mut`, which would.
            let NewValue::Number(v) = new else {
                return Err(bad("one element of a list is a number"));
            };
            let element = has_value(&doc, list)
                .then(|| item_mut(&mut doc, list))
                .flatten()
                .and_then(Item::as_array_mut)
                .and_then(|a| a.get_mut(i))
                .filter(|e| matches!(e, Value::Float(_) | Value::Integer(_)))
                .ok_or_else(|| bad(&format!("`{list}` has no number at index {i} in the file")))?;
            let decor = element.decor().clone();
            *element = Value::from(rounded(*v));
            *element.decor_mut() = decor;
            continue;
        }
        // Before any look-up by `item_mut`: toml_edit's `get_mut` on a table inserts the
        // missing key (as an inline table once indexed further), which would shadow the
        // `[adaptation.<component>]` table made here.
        if let Some(rest) = key.strip_prefix("adaptation.") {
            // A curve or its knots (`adaptation.<component>.<curve>`, a list) or a value of a
            // sub-table (`adaptation.model_error_pct.<signal>`, a number).
            let value =
                match new {
                    NewValue::Numbers(list) => toml_edit::value(
                        list.iter()
                            .map(|v| rounded(*v))
                            .collect::<toml_edit::Array>(),
                    ),
                    NewValue::Number(v) => toml_edit::value(rounded(*v)),
                    NewValue::Words(list) => toml_edit::value(
                        list.iter()
                            .map(String::as_str)
                            .collect::<toml_edit::Array>(),
                    ),
                    // Which speed a component's knots are in (`adaptation.hpt.speed_of`), what
                    // shapes a turbine's efficiency (`adaptation.pt.efficiency_shape`).
                    NewValue::Text(word)
                        if key.ends_with(".speed_of") || key.ends_with(".efficiency_shape") =>
                    {
                        toml_edit::value(word.as_str())
                    }
                    NewValue::Text(_) => return Err(bad(
                        "an adaptation value is a number or a list (a word only for `speed_of` \
                         and `efficiency_shape`)",
                    )),
                };
            let (table_name, name) = rest
                .split_once('.')
                .ok_or_else(|| bad("use adaptation.<component>.<curve>"))?;
            let table = sub_table(&mut doc, "adaptation", table_name)
                .ok_or_else(|| bad("`adaptation` or the component is not a table in the file"))?;
            table.insert(name, value);
            continue;
        }
        if let (None, Some((effect, param)), NewValue::Number(v)) = (
            item_mut(&mut doc, key),
            key.strip_prefix("effects.").and_then(|r| r.split_once('.')),
            new,
        ) {
            // An effect the file does not have yet (a fitted instrument offset): its table is
            // added, `[effects."<instance>"]`.
            let table = sub_table(&mut doc, "effects", effect)
                .ok_or_else(|| bad("`effects` or the effect is not a table in the file"))?;
            table.insert(param, toml_edit::value(rounded(*v)));
            continue;
        }
        let default_value = match new {
            NewValue::Text(text) => Some(toml_edit::value(text.as_str())),
            // A number only for a key the engine file knows (it has an allowed range).
            NewValue::Number(v) if crate::engine::config::param_range(key).is_some() => {
                Some(toml_edit::value(rounded(*v)))
            }
            _ => None,
        };
        if let (false, Some((section, name)), Some(value)) =
            (has_value(&doc, key), key.split_once('.'), default_value)
        {
            // A word or number the file leaves at its default (`design.inlet_loss_law`,
            // `design.cooling_return_frac`): added to its section's table, which must exist.
            let table = doc
                .get_mut(section)
                .and_then(Item::as_table_mut)
                .filter(|_| !name.contains('.'))
                .ok_or_else(|| bad("its section is not a table in the file"))?;
            table.insert(name, value);
            continue;
        }
        let value = item_mut(&mut doc, key)
            .and_then(Item::as_value_mut)
            .ok_or_else(|| bad("not in the file as a value (cannot be replaced in place)"))?;
        let decor = value.decor().clone();
        *value = match (new, &*value) {
            (NewValue::Number(v), Value::Float(_) | Value::Integer(_)) => Value::from(rounded(*v)),
            (NewValue::Text(s), Value::String(_)) => Value::from(s.as_str()),
            _ => return Err(bad("has another type in the file")),
        };
        *value.decor_mut() = decor;
    }
    let mut out = String::new();
    for line in header {
        out.push_str("# ");
        out.push_str(line);
        out.push('\n');
    }
    out.push_str(&doc.to_string());
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::config::{EngineConfig, PressureLossLaw, REFERENCE_ENGINE_TOML};

    #[test]
    fn replaces_values_in_place_and_keeps_comments() {
        let text = rewrite(
            REFERENCE_ENGINE_TOML,
            "engine.toml",
            &[
                (
                    "design.hpt_efficiency".into(),
                    NewValue::Number(0.873456789123),
                ),
                ("maps.pt_file".into(), NewValue::Text("/abs/lpt.map".into())),
            ],
            &["calibrated".into()],
        )
        .expect("rewrite");
        assert!(text.starts_with("# calibrated\n"));
        assert!(text.contains("hpt_efficiency = 0.8734568\n"), "{text}");
        assert!(text.contains("pt_file = \"/abs/lpt.map\""));
        // Comments elsewhere and beside replaced values survive.
        assert!(text.contains("compressor_efficiency = 0.85  # isentropic"));
        assert!(text.contains("# ISO day"));
        let cfg = EngineConfig::from_toml_str(&text, "x").expect("loads");
        assert_eq!(cfg.design.hpt_efficiency, 0.8734568);
        for key in ["design.nope", "design", "maps.pt_file"] {
            let e = rewrite(
                REFERENCE_ENGINE_TOML,
                "engine.toml",
                &[(key.into(), NewValue::Number(1.0))],
                &[],
            )
            .expect_err(key);
            assert!(e.to_string().contains(key) && e.to_string().contains("engine.toml"));
        }
    }

    #[test]
    fn an_inlet_loss_law_is_replaced_in_place_or_added_to_design() {
        let set = |text: &str| {
            rewrite(
                text,
                "engine.toml",
                &[(
                    "design.inlet_loss_law".into(),
                    NewValue::Text("constant".into()),
                )],
                &[],
            )
            .expect("rewrite")
        };
        // The reference file states the law: replaced, its comment kept.
        let text = set(REFERENCE_ENGINE_TOML);
        assert!(
            text.contains("inlet_loss_law = \"constant\"     # off design"),
            "{text}"
        );
        let cfg = EngineConfig::from_toml_str(&text, "x").expect("loads");
        assert_eq!(cfg.design.inlet_loss_law, PressureLossLaw::Constant);
        // A file leaving it at its default gets the line in `[design]`.
        let without: String = REFERENCE_ENGINE_TOML
            .lines()
            .filter(|l| !l.starts_with("inlet_loss_law"))
            .map(|l| format!("{l}\n"))
            .collect();
        let cfg = EngineConfig::from_toml_str(&without, "x").expect("loads");
        assert_eq!(cfg.design.inlet_loss_law, PressureLossLaw::FlowSquared);
        let cfg = EngineConfig::from_toml_str(&set(&without), "x").expect("loads");
        assert_eq!(cfg.design.inlet_loss_law, PressureLossLaw::Constant);
        // A number the file leaves at its default is added the same way.
        let text = rewrite(
            &without,
            "engine.toml",
            &[("design.cooling_return_frac".into(), NewValue::Number(0.03))],
            &[],
        )
        .expect("rewrite");
        let cfg = EngineConfig::from_toml_str(&text, "x").expect("loads");
        assert_eq!(cfg.design.cooling_return_frac, 0.03);
        // A word for a section the file does not have is refused, naming the key.
        let e = rewrite(
            REFERENCE_ENGINE_TOML,
            "engine.toml",
            &[("nowhere.law".into(), NewValue::Text("constant".into()))],
            &[],
        )
        .expect_err("no section");
        assert!(e.to_string().contains("nowhere.law"), "{e}");
    }

    #[test]
    fn a_fitted_instrument_offset_adds_its_effect_table() {
        let key = "effects.sensor_bias:t34_k.offset";
        let text = rewrite(
            REFERENCE_ENGINE_TOML,
            "engine.toml",
            &[(key.into(), NewValue::Number(-1.23456789))],
            &[],
        )
        .expect("rewrite");
        assert!(
            text.contains("[effects.\"sensor_bias:t34_k\"]\noffset = -1.234568"),
            "{text}"
        );
        let cfg = EngineConfig::from_toml_str(&text, "x").expect("loads");
        assert_eq!(cfg.get_param(key).expect("key"), -1.234568);
    }

    #[test]
    fn an_adaptation_is_written_as_a_section_and_replaces_an_older_one() {
        let lists = [
            ("adaptation.compressor.speed_knots", vec![0.7, 0.85]),
            ("adaptation.compressor.speed", vec![0.12345678912, 0.05]),
            ("adaptation.pt.speed_knots", vec![0.8]),
            ("adaptation.pt.flow", vec![-0.02]),
        ];
        let mut values: Vec<(String, NewValue)> = lists
            .iter()
            .map(|(k, v)| (k.to_string(), NewValue::Numbers(v.clone())))
            .collect();
        values.push((
            "adaptation.model_error_pct.n1_rpm".into(),
            NewValue::Number(0.18),
        ));
        let text = rewrite(REFERENCE_ENGINE_TOML, "engine.toml", &values, &[]).expect("rewrite");
        let cfg = EngineConfig::from_toml_str(&text, "x").expect("loads");
        let a = cfg.adaptation.clone().expect("section");
        assert_eq!(a.model_error_pct.get("n1_rpm"), Some(&0.18));
        let c = a.compressor.expect("compressor");
        assert_eq!(c.speed_knots, vec![0.7, 0.85]);
        assert_eq!(c.speed, vec![0.1234568, 0.05]);
        assert!(c.flow.is_empty() && a.hpt.is_none());
        assert_eq!(a.pt.expect("pt").flow, vec![-0.02]);
        // Written again with other curves: the older section does not survive.
        let again = rewrite(
            &text,
            "engine.toml",
            &[
                (
                    "adaptation.hpt.speed_knots".into(),
                    NewValue::Numbers(vec![0.9]),
                ),
                (
                    "adaptation.hpt.efficiency".into(),
                    NewValue::Numbers(vec![0.01]),
                ),
            ],
            &[],
        )
        .expect("rewrite");
        let cfg = EngineConfig::from_toml_str(&again, "x").expect("loads");
        let a = cfg.adaptation.expect("section");
        assert!(a.compressor.is_none() && a.pt.is_none() && a.model_error_pct.is_empty());
        assert_eq!(a.hpt.expect("hpt").efficiency, vec![0.01]);
    }

    /// `calibrate --params adaptation.pt.flow[1],…` on an adapted file refits knot values of its
    /// own curves: each is replaced in its list, and the rest of the section (knots, other
    /// curves, the model error) stays. Before, the section was dropped and a key
    /// `"flow[1]" = …` written, which the engine file then refused.
    #[test]
    fn a_refitted_knot_value_replaces_its_element_and_keeps_the_section() {
        let adapted = rewrite(
            REFERENCE_ENGINE_TOML,
            "engine.toml",
            &[
                (
                    "adaptation.pt.speed_knots".into(),
                    NewValue::Numbers(vec![0.8, 0.9]),
                ),
                (
                    "adaptation.pt.flow".into(),
                    NewValue::Numbers(vec![-0.02, -0.01]),
                ),
                (
                    "adaptation.pt.efficiency".into(),
                    NewValue::Numbers(vec![0.01, 0.005]),
                ),
                (
                    "adaptation.model_error_pct.n1_rpm".into(),
                    NewValue::Number(0.2),
                ),
            ],
            &[],
        )
        .expect("adapted");
        let text = rewrite(
            &adapted,
            "engine.toml",
            &[
                ("adaptation.pt.flow[1]".into(), NewValue::Number(-0.0123)),
                ("design.hpt_efficiency".into(), NewValue::Number(0.88)),
            ],
            &[],
        )
        .expect("rewrite");
        let cfg = EngineConfig::from_toml_str(&text, "x").expect("loads");
        let a = cfg.adaptation.expect("section kept");
        let pt = a.pt.expect("pt");
        assert_eq!(pt.speed_knots, vec![0.8, 0.9]);
        assert_eq!(pt.flow, vec![-0.02, -0.0123]);
        assert_eq!(pt.efficiency, vec![0.01, 0.005]);
        assert_eq!(a.model_error_pct.get("n1_rpm"), Some(&0.2));
        assert_eq!(cfg.design.hpt_efficiency, 0.88);
        // An element the file does not have is an error naming the key, not a new entry.
        for key in ["adaptation.pt.flow[2]", "adaptation.hpt.flow[0]"] {
            let err = rewrite(
                &adapted,
                "engine.toml",
                &[(key.into(), NewValue::Number(0.1))],
                &[],
            )
            .expect_err(key);
            assert!(err.to_string().contains(key), "{err}");
        }
    }
}
