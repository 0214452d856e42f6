//! Maps scaled to the engine's design point, with component health applied.
//!
//! What it is for: engine-unit look-ups for the dynamic model. Engine units are corrected speed
//! `Nc = N / sqrt(T_in / 288.15 K)` in rpm and corrected flow
//! `Wc = W · sqrt(T_in / 288.15 K) / (P_in / 101.325 kPa)` in kg/s. What it must not do: I/O,
//! allocation per call; the maps are shared (`Arc`), so scaled components are cheap to clone
//! and `Send + Sync`.
//!
//! Scaling (engine = scaler × map): `Nc = speed · nc`, `Wc = flow · wc`,
//! `PR = 1 + pr_minus_one · (PR_map − 1)`, `eff = eff · eff_map`. [`ScaledCompressor::calibrate`]
//! picks the scalers so that one map point becomes the engine design point exactly.
//!
//! Health (REFERENCE §3, `crate::health`): corrected flow × `flow_factor`, efficiency ×
//! `eff_factor`, e.g. `flow_factor = 1 − D_GC/100`. The flow factor shifts the whole map
//! including the surge line. `with_health` *replaces* the health factors (it is always relative
//! to the calibrated, healthy map), so an optimiser can call it for every candidate.
//!
//! Off-design adaptation ([`super::adapt`], the engine file's `[adaptation]`): curves of relative
//! corrected speed, zero at the design speed, that multiply flow, efficiency and (PR − 1) and
//! re-label the compressor speed line read; kept through `with_health`. A turbine's adaptation
//! may hold the map's efficiency at its design-point value, so its efficiency curve alone
//! shapes the efficiency (`ComponentAdaptation::hold_map_efficiency`).
//!
//! Surge margin, percent: `SM = (PR_surge(Wc) / PR − 1) · 100` with `PR_surge` the scaled surge
//! line's pressure ratio at the operating point's corrected flow. Positive inside the map, 0 on
//! the surge line, negative beyond it.

#[cfg(test)]
use super::adapt::SpeedCurve;
use super::adapt::{ComponentAdaptation, Factors};
use super::compressor::CompressorMap;
use super::turbine::TurbineMap;
use std::sync::Arc;

/// A component's off-design adaptation ([`super::adapt`]) and the corrected speed, engine
/// units (rpm), its relative speed is referred to: the design point's.
#[derive(Debug, Clone)]
struct Adaptation {
    design_nc_rpm: f64,
    curves: Arc<ComponentAdaptation>,
}

impl Adaptation {
    /// The factors at engine corrected speed `nc_rpm` (all 1 without an adaptation).
    #[inline]
    fn factors(this: &Option<Adaptation>, nc_rpm: f64) -> Factors {
        match this {
            None => Factors::ONE,
            Some(a) => a.curves.factors(nc_rpm / a.design_nc_rpm),
        }
    }

    fn of(design_nc_rpm: f64, curves: ComponentAdaptation) -> Option<Adaptation> {
        curves.is_active().then(|| Adaptation {
            design_nc_rpm,
            curves: Arc::new(curves),
        })
    }
}

/// Design-point scalers: engine = scaler × map (PR: `1 + pr_minus_one · (PR_map − 1)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapScalers {
    pub speed: f64,
    pub flow: f64,
    pub pr_minus_one: f64,
    pub eff: f64,
}

/// Compressor operating point in engine units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompressorOp {
    /// Corrected flow, kg/s.
    pub wc_kg_s: f64,
    /// Pressure ratio (engine).
    pub pr: f64,
    /// Isentropic efficiency (engine, health applied).
    pub eff: f64,
    /// Map auxiliary coordinate.
    pub beta: f64,
    /// `(PR_surge(Wc)/PR − 1) · 100`.
    pub surge_margin_pct: f64,
}

/// Turbine operating point in engine units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurbineOp {
    /// Corrected flow, kg/s.
    pub wc_kg_s: f64,
    /// Isentropic efficiency (engine, health applied).
    pub eff: f64,
    /// Map auxiliary coordinate.
    pub beta: f64,
}

/// A compressor map scaled to an engine, with health factors.
#[derive(Debug, Clone)]
pub struct ScaledCompressor {
    map: Arc<CompressorMap>,
    scalers: MapScalers,
    flow_factor: f64,
    eff_factor: f64,
    adaptation: Option<Adaptation>,
}

impl ScaledCompressor {
    /// Scalers so that the map point (`nc_map`, `beta_map`) becomes the engine design point
    /// (`design_nc_rpm`, `design_wc_kg_s`, `design_pr`, `design_eff`). Healthy (factors 1).
    pub fn calibrate(
        map: impl Into<Arc<CompressorMap>>,
        nc_map: f64,
        beta_map: f64,
        design_nc_rpm: f64,
        design_wc_kg_s: f64,
        design_pr: f64,
        design_eff: f64,
    ) -> Self {
        let map = map.into();
        let p = map.point(nc_map, beta_map);
        let scalers = MapScalers {
            speed: design_nc_rpm / nc_map,
            flow: design_wc_kg_s / p.wc,
            pr_minus_one: (design_pr - 1.0) / (p.pr - 1.0),
            eff: design_eff / p.eff,
        };
        Self::from_scalers(map, scalers)
    }

    /// A scaled compressor with given scalers, healthy.
    pub fn from_scalers(map: impl Into<Arc<CompressorMap>>, scalers: MapScalers) -> Self {
        ScaledCompressor {
            map: map.into(),
            scalers,
            flow_factor: 1.0,
            eff_factor: 1.0,
            adaptation: None,
        }
    }

    /// Same calibration with health factors (replacing any previous ones): corrected flow ×
    /// `flow_factor`, efficiency × `eff_factor`.
    pub fn with_health(&self, flow_factor: f64, eff_factor: f64) -> Self {
        ScaledCompressor {
            map: Arc::clone(&self.map),
            scalers: self.scalers,
            flow_factor,
            eff_factor,
            adaptation: self.adaptation.clone(),
        }
    }

    /// The same compressor with the off-design adaptation `curves` (replacing any previous
    /// one), relative speeds referred to `design_nc_rpm`. Inactive curves cost nothing.
    pub fn with_adaptation(&self, design_nc_rpm: f64, curves: ComponentAdaptation) -> Self {
        ScaledCompressor {
            adaptation: Adaptation::of(design_nc_rpm, curves),
            ..self.clone()
        }
    }

    pub fn scalers(&self) -> MapScalers {
        self.scalers
    }
    /// `(flow_factor, eff_factor)`.
    pub fn health(&self) -> (f64, f64) {
        (self.flow_factor, self.eff_factor)
    }
    pub fn map(&self) -> &CompressorMap {
        &self.map
    }

    /// The point at map coordinates (`nc_read`, `beta`) with the adaptation factors `a` of the
    /// engine speed it stands for (`nc_read` is already the re-labelled map speed).
    #[inline]
    fn op(&self, nc_read: f64, beta: f64, a: Factors) -> CompressorOp {
        let s = &self.scalers;
        let p = self.map.point(nc_read, beta);
        let pr_m1 = s.pr_minus_one * a.pr_minus_one;
        let pr = 1.0 + pr_m1 * (p.pr - 1.0);
        // Surge line in map units at the same map flow (health shifts the map as a whole).
        let pr_surge = 1.0 + pr_m1 * (self.map.surge_pr(p.wc) - 1.0);
        CompressorOp {
            wc_kg_s: s.flow * self.flow_factor * a.flow * p.wc,
            pr,
            eff: s.eff * self.eff_factor * a.eff * p.eff,
            beta,
            surge_margin_pct: (pr_surge / pr - 1.0) * 100.0,
        }
    }

    /// `at_pr(nc_rpm, pr).wc_kg_s` to the bit, reading the flow alone.
    pub fn flow_at_pr(&self, nc_rpm: f64, pr: f64) -> f64 {
        let s = &self.scalers;
        let a = Adaptation::factors(&self.adaptation, nc_rpm);
        let nc_read = nc_rpm / s.speed * a.speed;
        let pr_map = 1.0 + (pr - 1.0) / (s.pr_minus_one * a.pr_minus_one);
        s.flow * self.flow_factor * a.flow * self.map.wc_at_pr(nc_read, pr_map)
    }

    /// Operating point at corrected speed `nc_rpm` and engine pressure ratio `pr`.
    pub fn at_pr(&self, nc_rpm: f64, pr: f64) -> CompressorOp {
        let s = &self.scalers;
        let a = Adaptation::factors(&self.adaptation, nc_rpm);
        let nc_read = nc_rpm / s.speed * a.speed;
        let pr_map = 1.0 + (pr - 1.0) / (s.pr_minus_one * a.pr_minus_one);
        let beta = self.map.beta_for_pr(nc_read, pr_map);
        let mut op = self.op(nc_read, beta, a);
        op.pr = pr;
        op
    }

    /// Operating point at corrected speed `nc_rpm` and map coordinate `beta`.
    pub fn at_beta(&self, nc_rpm: f64, beta: f64) -> CompressorOp {
        let a = Adaptation::factors(&self.adaptation, nc_rpm);
        self.op(nc_rpm / self.scalers.speed * a.speed, beta, a)
    }
}

/// Which corrected speed a turbine's adaptation curves are read at.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum CurveSpeed {
    /// The turbine's own corrected speed, the one its map is read at.
    #[default]
    Own,
    /// A reference corrected speed the caller gives with each look-up
    /// ([`ScaledTurbine::at_pr_ref`]; the engine gives the gas generator's at the compressor
    /// inlet, see `engine::config::SpeedOf`), relative to the design speed the adaptation was
    /// given in that reference.
    Reference,
}

/// A turbine map scaled to an engine, with health factors.
#[derive(Debug, Clone)]
pub struct ScaledTurbine {
    map: Arc<TurbineMap>,
    scalers: MapScalers,
    flow_factor: f64,
    eff_factor: f64,
    adaptation: Option<Adaptation>,
    curves_at: CurveSpeed,
    /// The map's efficiency at the map point the design point was scaled to: what an
    /// adaptation that holds the map's efficiency reads everywhere.
    design_map_eff: f64,
}

impl ScaledTurbine {
    /// Scalers so that the map point (`nc_map`, `pr_map`) becomes the engine design point.
    pub fn calibrate(
        map: impl Into<Arc<TurbineMap>>,
        nc_map: f64,
        pr_map: f64,
        design_nc_rpm: f64,
        design_wc_kg_s: f64,
        design_pr: f64,
        design_eff: f64,
    ) -> Self {
        let map = map.into();
        let p = map.point(nc_map, pr_map);
        let scalers = MapScalers {
            speed: design_nc_rpm / nc_map,
            flow: design_wc_kg_s / p.wc,
            pr_minus_one: (design_pr - 1.0) / (pr_map - 1.0),
            eff: design_eff / p.eff,
        };
        ScaledTurbine {
            map,
            scalers,
            flow_factor: 1.0,
            eff_factor: 1.0,
            adaptation: None,
            curves_at: CurveSpeed::Own,
            design_map_eff: p.eff,
        }
    }

    /// Same calibration with health factors (replacing any previous ones).
    pub fn with_health(&self, flow_factor: f64, eff_factor: f64) -> Self {
        ScaledTurbine {
            map: Arc::clone(&self.map),
            scalers: self.scalers,
            flow_factor,
            eff_factor,
            adaptation: self.adaptation.clone(),
            curves_at: self.curves_at,
            design_map_eff: self.design_map_eff,
        }
    }

    /// The same turbine with the off-design adaptation `curves` (flow and efficiency curves;
    /// replacing any previous one), relative speeds referred to `design_nc_rpm`.
    pub fn with_adaptation(&self, design_nc_rpm: f64, curves: ComponentAdaptation) -> Self {
        self.with_adaptation_at(design_nc_rpm, curves, CurveSpeed::Own)
    }

    /// [`Self::with_adaptation`] with the curves read at `at`; `design_nc_rpm` is the design
    /// point's speed in that reference.
    pub fn with_adaptation_at(
        &self,
        design_nc_rpm: f64,
        curves: ComponentAdaptation,
        at: CurveSpeed,
    ) -> Self {
        ScaledTurbine {
            adaptation: Adaptation::of(design_nc_rpm, curves),
            curves_at: at,
            ..self.clone()
        }
    }

    pub fn scalers(&self) -> MapScalers {
        self.scalers
    }
    pub fn health(&self) -> (f64, f64) {
        (self.flow_factor, self.eff_factor)
    }
    pub fn map(&self) -> &TurbineMap {
        &self.map
    }

    /// Operating point at corrected speed `nc_rpm` and engine pressure ratio `pr` (inlet/outlet),
    /// adaptation curves read at `nc_rpm` (see [`Self::at_pr_ref`]).
    pub fn at_pr(&self, nc_rpm: f64, pr: f64) -> TurbineOp {
        self.at_pr_ref(nc_rpm, nc_rpm, pr)
    }

    /// [`Self::at_pr`] with `reference_nc_rpm`, the speed the adaptation curves are read at
    /// when they are read at a reference ([`CurveSpeed::Reference`]; else unused).
    pub fn at_pr_ref(&self, nc_rpm: f64, reference_nc_rpm: f64, pr: f64) -> TurbineOp {
        let s = &self.scalers;
        let curve_nc = match self.curves_at {
            CurveSpeed::Own => nc_rpm,
            CurveSpeed::Reference => reference_nc_rpm,
        };
        let a = Adaptation::factors(&self.adaptation, curve_nc);
        let p = self
            .map
            .point(nc_rpm / s.speed, 1.0 + (pr - 1.0) / s.pr_minus_one);
        let held = self
            .adaptation
            .as_ref()
            .is_some_and(|a| a.curves.hold_map_efficiency);
        let map_eff = if held { self.design_map_eff } else { p.eff };
        TurbineOp {
            wc_kg_s: s.flow * self.flow_factor * a.flow * p.wc,
            eff: s.eff * self.eff_factor * a.eff * map_eff,
            beta: p.beta,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::health::HealthParams;
    use crate::maps::{hpc, hpt, lpt};

    fn comp() -> ScaledCompressor {
        ScaledCompressor::calibrate(hpc().expect("hpc"), 1.0, 0.5, 9500.0, 80.0, 24.1, 0.85)
    }

    #[test]
    fn calibration_reproduces_design() {
        let c = comp();
        let op = c.at_beta(9500.0, 0.5);
        assert!((op.wc_kg_s - 80.0).abs() < 1e-12);
        assert!((op.pr - 24.1).abs() < 1e-12);
        assert!((op.eff - 0.85).abs() < 1e-14);
        let op = c.at_pr(9500.0, 24.1);
        assert!((op.beta - 0.5).abs() < 1e-12);
        assert!((op.wc_kg_s - 80.0).abs() < 1e-10);
        assert!((op.eff - 0.85).abs() < 1e-12);
        for (t, pr, eff) in [
            (hpt().expect("hpt"), 4.4, 0.88),
            (lpt().expect("lpt"), 5.3, 0.90),
        ] {
            let s = ScaledTurbine::calibrate(t, 1.0, 5.0, 9500.0, 12.5, pr, eff);
            let op = s.at_pr(9500.0, pr);
            assert!((op.wc_kg_s - 12.5).abs() < 1e-12);
            assert!((op.eff - eff).abs() < 1e-14);
            assert!((op.beta - 0.4).abs() < 1e-12);
        }
    }

    #[test]
    fn health_scales_flow_and_efficiency_exactly() {
        let c = comp();
        let h = HealthParams {
            D_GC: 3.0,
            D_EC: 1.0,
            ..HealthParams::HEALTHY
        };
        let d = c.with_health(h.compressor_flow_factor(), h.compressor_eff_factor());
        for (n, pr) in [(9500.0, 24.1), (7000.0, 8.0), (3000.0, 1.3)] {
            let (a, b) = (c.at_pr(n, pr), d.at_pr(n, pr));
            assert!((b.wc_kg_s / a.wc_kg_s - 0.97).abs() < 1e-12);
            assert!((b.eff / a.eff - 0.99).abs() < 1e-12);
            assert!((b.surge_margin_pct - a.surge_margin_pct).abs() < 1e-9);
        }
        // with_health replaces, it does not compound.
        let e = d.with_health(1.0, 1.0);
        assert_eq!(e.at_pr(9000.0, 20.0), c.at_pr(9000.0, 20.0));
        let t = ScaledTurbine::calibrate(hpt().expect("hpt"), 1.0, 5.0, 9500.0, 12.5, 4.4, 0.88);
        let u = t.with_health(0.98, 0.95);
        for pr in [1.01, 2.0, 4.4, 9.0] {
            let (a, b) = (t.at_pr(9000.0, pr), u.at_pr(9000.0, pr));
            assert!((b.wc_kg_s - 0.98 * a.wc_kg_s).abs() < 1e-12);
            assert!((b.eff - 0.95 * a.eff).abs() < 1e-14);
        }
    }

    #[test]
    fn a_held_map_efficiency_leaves_the_curve_alone_to_shape_it() {
        let t = ScaledTurbine::calibrate(lpt().expect("lpt"), 1.0, 5.0, 9500.0, 12.5, 5.3, 0.90);
        let curve = SpeedCurve::new(&[0.7], &[0.02]).expect("curve");
        let held = t.with_adaptation(
            9500.0,
            ComponentAdaptation {
                eff: Some(curve.clone()),
                hold_map_efficiency: true,
                ..Default::default()
            },
        );
        let shaped = t.with_adaptation(
            9500.0,
            ComponentAdaptation {
                eff: Some(curve.clone()),
                ..Default::default()
            },
        );
        let mut spread = 0.0_f64;
        for (n, pr) in [(9500.0, 5.3), (6650.0, 3.0), (6650.0, 6.0), (8000.0, 1.5)] {
            let (m, h, s) = (t.at_pr(n, pr), held.at_pr(n, pr), shaped.at_pr(n, pr));
            // Held: the design point's efficiency times the curve, whatever the map says here;
            // the flow still the map's.
            let want = 0.90 * (1.0 + curve.at(n / 9500.0));
            assert!(
                (h.eff - want).abs() < 1e-12,
                "{n} {pr}: {} vs {want}",
                h.eff
            );
            assert!((h.wc_kg_s - m.wc_kg_s).abs() < 1e-12);
            // Not held: the map's own efficiency times the curve.
            assert!((s.eff - m.eff * (1.0 + curve.at(n / 9500.0))).abs() < 1e-12);
            spread = spread.max((m.eff / 0.90 - 1.0).abs());
        }
        // The map's own shape is there to be dropped (else the test proves nothing).
        assert!(spread > 0.01, "map efficiency spread {spread}");
        // Health still scales it.
        let sick = held.with_health(1.0, 0.97);
        assert!((sick.at_pr(6650.0, 3.0).eff - 0.97 * held.at_pr(6650.0, 3.0).eff).abs() < 1e-14);
    }

    #[test]
    fn surge_margin() {
        let c = comp();
        // On the surge line (beta 0 on each speed line, and its sub-idle continuation): 0.
        for &nc in c.map().speeds() {
            let op = c.at_beta(nc * 9500.0, 0.0);
            assert!(op.surge_margin_pct.abs() < 1e-9, "{op:?}");
        }
        assert!(c.at_beta(3000.0, 0.0).surge_margin_pct.abs() < 1e-9);
        // Inside the map: positive; beyond surge: negative.
        for nc in [0.55, 0.7, 0.83, 0.96, 1.0, 1.04] {
            for beta in [0.05, 0.3, 0.5, 0.8, 1.0] {
                let op = c.at_beta(nc * 9500.0, beta);
                assert!(op.surge_margin_pct > 0.0, "nc {nc} beta {beta}: {op:?}");
            }
        }
        assert!(c.at_beta(9500.0, -0.1).surge_margin_pct < 0.0);
        // Design point margin is a plausible number.
        let sm = c.at_beta(9500.0, 0.5).surge_margin_pct;
        assert!((5.0..40.0).contains(&sm), "design SM {sm}");
    }

    #[test]
    fn send_sync_and_cheap_clone() {
        fn assert_send_sync<T: Send + Sync + Clone>() {}
        assert_send_sync::<ScaledCompressor>();
        assert_send_sync::<ScaledTurbine>();
        let c = comp();
        let d = c.clone();
        assert!(std::ptr::eq(c.map(), d.map()));
    }
}
