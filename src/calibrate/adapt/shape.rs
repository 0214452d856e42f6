//! The adaptation's shape during the fit: per component its knots and the values of its
//! active curves, as the engine file's `[adaptation]` section, the fit's parameter keys and
//! the smoothness rows of the penalty. Must not fit (that is the parent module's `fit`).

use super::super::problem::SmoothnessRow;
use crate::engine::config::{
    AdaptationConfig, ComponentCurves, EfficiencyShape, SpeedOf, COMPONENTS,
};
use crate::engine::Engine;
use crate::maps::SpeedCurve;

/// The key of knot `i` of `curve` of `component`.
pub(super) fn key(component: &str, curve: &str, i: usize) -> String {
    format!("adaptation.{component}.{curve}[{i}]")
}

/// State of the fit: per component its knots and the values of its active curves.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Shape {
    /// Per component (order of [`COMPONENTS`]): knots (empty = not adapted).
    pub(super) knots: [Vec<f64>; 3],
    /// Per component: active curves and their values at the knots.
    pub(super) curves: [Vec<(String, Vec<f64>)>; 3],
    /// Per component: curves held at the shape they were fitted to at fewer knots (values at
    /// the component's knots, re-sampled as they move), in the file but not fitted: a curve
    /// the data no longer resolve beside the others at more knots keeps what it took, rather
    /// than its correction being thrown away.
    pub(super) held: [Vec<Held>; 3],
    /// Which corrected speed the HP turbine's knots are in.
    pub(super) hpt_speed_of: SpeedOf,
    /// What shapes the turbines' efficiency away from the design point.
    pub(super) turbine_efficiency: EfficiencyShape,
}

/// A curve held at the shape it was fitted to at fewer knots, and why (the report says it).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Held {
    pub(super) curve: String,
    /// Values at the component's knots.
    pub(super) values: Vec<f64>,
    pub(super) reason: String,
}

impl Shape {
    pub(super) fn config(&self) -> Option<AdaptationConfig> {
        let mut a = AdaptationConfig::default();
        let mut any = false;
        for (ci, name) in COMPONENTS.iter().enumerate() {
            if self.knots[ci].is_empty() || (self.curves[ci].is_empty() && self.held[ci].is_empty())
            {
                continue;
            }
            let speed_of = self.speed_of(name);
            let efficiency_shape = self.efficiency_shape(name);
            let mut c = ComponentCurves {
                speed_knots: self.knots[ci].clone(),
                speed_of: (speed_of != SpeedOf::OwnInlet).then_some(speed_of),
                efficiency_shape: (efficiency_shape != EfficiencyShape::Map)
                    .then_some(efficiency_shape),
                ..Default::default()
            };
            let held = self.held[ci].iter().map(|h| (&h.curve, &h.values));
            for (curve, values) in self.curves[ci].iter().map(|(c, v)| (c, v)).chain(held) {
                if let Some(slot) = c.curve_mut(curve) {
                    *slot = values.clone();
                }
            }
            if let Some(slot) = a.component_mut(name) {
                *slot = Some(c);
                any = true;
            }
        }
        any.then_some(a)
    }

    /// Which corrected speed component `name`'s knots are in.
    pub(super) fn speed_of(&self, name: &str) -> SpeedOf {
        if name == "hpt" {
            self.hpt_speed_of
        } else {
            SpeedOf::OwnInlet
        }
    }

    /// What shapes component `name`'s efficiency away from the design point.
    pub(super) fn efficiency_shape(&self, name: &str) -> EfficiencyShape {
        if name == "compressor" {
            EfficiencyShape::Map
        } else {
            self.turbine_efficiency
        }
    }

    /// Knots per component.
    pub(super) fn levels(&self) -> Vec<usize> {
        self.knots.iter().map(Vec::len).collect()
    }

    /// Every knot value's key, in a fixed order.
    pub(super) fn keys(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (ci, name) in COMPONENTS.iter().enumerate() {
            for (curve, values) in &self.curves[ci] {
                out.extend((0..values.len()).map(|i| key(name, curve, i)));
            }
        }
        out
    }

    /// Component `ci` moved to `new_knots`, each active and held curve re-sampled there.
    pub(super) fn resampled(&self, ci: usize, new_knots: Vec<f64>) -> Shape {
        let mut s = self.clone();
        let held = s.held[ci].iter_mut().map(|h| &mut h.values);
        for values in s.curves[ci].iter_mut().map(|(_, v)| v).chain(held) {
            let old = SpeedCurve::new(&self.knots[ci], values);
            *values = new_knots
                .iter()
                .map(|&k| old.as_ref().map_or(0.0, |c| c.at(k)))
                .collect();
        }
        s.knots[ci] = new_knots;
        s
    }

    /// Component `ci`'s curves `names` moved from the fitted to the held ones, for `reason`.
    pub(super) fn with_held(&self, ci: usize, names: &[String], reason: &str) -> Shape {
        let mut s = self.clone();
        let (held, kept): (Vec<_>, Vec<_>) = std::mem::take(&mut s.curves[ci])
            .into_iter()
            .partition(|(curve, _)| names.contains(curve));
        s.curves[ci] = kept;
        s.held[ci].extend(held.into_iter().map(|(curve, values)| Held {
            curve,
            values,
            reason: reason.to_string(),
        }));
        s
    }

    /// Reads the fitted values back from `engine`'s file.
    pub(super) fn read_back(&mut self, engine: &Engine) {
        for (ci, name) in COMPONENTS.iter().enumerate() {
            for (curve, values) in &mut self.curves[ci] {
                for (i, v) in values.iter_mut().enumerate() {
                    if let Ok(x) = engine.get_param(&key(name, curve, i)) {
                        *v = x;
                    }
                }
            }
        }
    }

    /// Prior rows for the candidate vector `keys`: each knot value over `scale` (a value of
    /// `scale` costs one noise σ), so a curve the data leave free (two correlated curves can
    /// trade a straight ramp, which the curvature penalty does not see) stays at the map.
    pub(super) fn prior(&self, keys: &[String], scale: f64) -> Vec<SmoothnessRow> {
        self.keys()
            .iter()
            .filter_map(|k| keys.iter().position(|x| x == k))
            .map(|j| SmoothnessRow {
                terms: vec![(j, 1.0)],
                scale,
            })
            .collect()
    }

    /// Smoothness rows for the candidate vector `keys` (adaptation knots found by key).
    pub(super) fn smoothness(&self, keys: &[String], scale: f64) -> Vec<SmoothnessRow> {
        let mut rows = Vec::new();
        for (ci, name) in COMPONENTS.iter().enumerate() {
            // Knots and the anchor (1, 0), which is no variable, in the order of speed (knots
            // may lie on both sides of it).
            let below = self.knots[ci].partition_point(|x| *x < 1.0);
            let mut xs = self.knots[ci].clone();
            xs.insert(below, 1.0);
            for (curve, values) in &self.curves[ci] {
                let mut idx: Vec<Option<usize>> = (0..values.len())
                    .map(|i| {
                        let k = key(name, curve, i);
                        keys.iter().position(|x| *x == k)
                    })
                    .collect();
                idx.insert(below.min(idx.len()), None);
                for i in 1..xs.len().saturating_sub(1) {
                    let (h0, h1) = (xs[i] - xs[i - 1], xs[i + 1] - xs[i]);
                    let w = 2.0 / (h0 + h1);
                    let coef = [w / h0, -w / h0 - w / h1, w / h1];
                    let terms: Vec<(usize, f64)> = [idx[i - 1], idx[i], idx[i + 1]]
                        .iter()
                        .zip(coef)
                        .filter_map(|(j, c)| j.map(|j| (j, c)))
                        .collect();
                    if !terms.is_empty() {
                        rows.push(SmoothnessRow { terms, scale });
                    }
                }
            }
        }
        rows
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_held_curve_stays_in_the_file_but_not_in_the_fit() {
        let shape = Shape {
            hpt_speed_of: SpeedOf::OwnInlet,
            turbine_efficiency: EfficiencyShape::Map,
            knots: [vec![0.75, 0.875], vec![], vec![]],
            curves: [
                vec![
                    ("speed".to_string(), vec![0.15, 0.07]),
                    ("flow".to_string(), vec![0.10, 0.03]),
                ],
                vec![],
                vec![],
            ],
            held: Default::default(),
        };
        let held = shape.with_held(0, &["flow".to_string()], "not identified");
        assert_eq!(
            held.keys(),
            vec![
                "adaptation.compressor.speed[0]",
                "adaptation.compressor.speed[1]"
            ]
        );
        assert!(held.smoothness(&held.keys(), 1.0).len() == 1);
        let a = held.config().expect("adapted");
        let c = a.compressor.as_ref().expect("compressor");
        assert_eq!(c.flow, vec![0.10, 0.03]);
        assert_eq!(c.speed, vec![0.15, 0.07]);
        // Grown to three knots, the held curve is re-sampled with the others: its file values
        // follow the knots, and it still has no key.
        let grown = held.resampled(0, vec![0.75, 0.8333, 0.9167]);
        assert_eq!(grown.keys().len(), 3);
        let c = grown
            .config()
            .expect("adapted")
            .compressor
            .expect("compressor");
        assert_eq!(c.flow.len(), 3);
        assert!((c.flow[0] - 0.10).abs() < 1e-12, "{:?}", c.flow);
        assert!(c.flow[1] < 0.10 && c.flow[2] > 0.0, "{:?}", c.flow);
        // A component with only held curves is still written.
        let only = held.with_held(0, &["speed".to_string()], "neither");
        assert!(only.keys().is_empty());
        let reasons: Vec<(&str, &str)> = only.held[0]
            .iter()
            .map(|h| (h.curve.as_str(), h.reason.as_str()))
            .collect();
        assert_eq!(reasons, [("flow", "not identified"), ("speed", "neither")]);
        assert!(only.config().is_some_and(|a| a.compressor.is_some()));
    }

    #[test]
    fn smoothness_takes_the_anchor_in_its_place_among_knots_on_both_sides() {
        // Knots 0.8, 0.9 below the design speed and 1.1 above: the second differences run over
        // 0.8, 0.9, (1.0, 0), 1.1.
        let shape = Shape {
            hpt_speed_of: SpeedOf::OwnInlet,
            turbine_efficiency: EfficiencyShape::Map,
            knots: [vec![], vec![], vec![0.8, 0.9, 1.1]],
            curves: [
                vec![],
                vec![],
                vec![("flow".to_string(), vec![0.01, 0.02, 0.03])],
            ],
            held: Default::default(),
        };
        let keys = shape.keys();
        assert_eq!(keys.len(), 3);
        let rows = shape.smoothness(&keys, 1.0);
        assert_eq!(rows.len(), 2, "{rows:?}");
        // At 0.9: its neighbours 0.8 (a knot) and the anchor (no variable).
        let at_09: Vec<usize> = rows[0].terms.iter().map(|t| t.0).collect();
        assert_eq!(at_09, vec![0, 1]);
        // At the anchor: 0.9 and 1.1, both with the outer coefficient (positive), h = 0.1.
        let at_anchor = &rows[1].terms;
        assert_eq!(
            at_anchor.iter().map(|t| t.0).collect::<Vec<_>>(),
            vec![1, 2]
        );
        for (_, c) in at_anchor {
            assert!((c - 100.0).abs() < 1e-9, "{at_anchor:?}");
        }
        // Below the design only, as before: the anchor last.
        let below = Shape {
            hpt_speed_of: SpeedOf::OwnInlet,
            turbine_efficiency: EfficiencyShape::Map,
            knots: [vec![0.8, 0.9], vec![], vec![]],
            curves: [
                vec![("speed".to_string(), vec![0.02, 0.01])],
                vec![],
                vec![],
            ],
            held: Default::default(),
        };
        let rows = below.smoothness(&below.keys(), 1.0);
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].terms.len(), 2);
    }
}
