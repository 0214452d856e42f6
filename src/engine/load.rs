//! Power-turbine load modes (issue 10 item 5, issue 22 item 2): what sets the PT speed.
//!
//! What it is for: a steady operating point of an engine whose PT drives
//! - a generator (speed held by the grid, the caller's `n2_rpm`: [`super::steady::solve`]);
//! - a mechanical load whose absorbed power follows a law `P = P_design · (n2 / n2_design)^k`
//!   (propeller, centrifugal compressor or pump: k ≈ 3) or a tabulated power–speed curve
//!   (`[load] mode = "table"`), so the PT speed follows the load;
//! - a load whose speed something else sets (`mode = "measured_speed"`: pitch, recycle valve,
//!   combinator schedule): the caller's `n2_rpm` (the measured speed) is used exactly, as for a
//!   generator.
//!
//! What it must not do: I/O, or change the gas-path matching itself (it only chooses `n2`
//! around [`super::steady::solve_with_stats`]).
//!
//! With a load curve, a power demand fixes the speed directly (the curve's inverse); a fuel or
//! GG-speed demand leaves the speed unknown, found by a secant iteration on
//! `P_engine(n2) − P_load(n2) = 0` (the engine's power depends weakly on n2, the load
//! strongly, so 3–6 steady solves suffice).
//!
//! Dynamic runs: [`PtLoad`] is the same curve frozen into a value that the drive of each
//! integration step carries (`dynamic::Drive::pt_load`). The PT speed is then a state driven by
//! `J2 ω dω/dt = P_PT,net(n2) − P_load(n2)` whenever the breaker is not closed (a mechanical
//! drive has none), and the sequencer governs the PT speed (`sequence.rs`). In generator mode
//! the drive carries no load and the dynamic model is the grid-locked one, bit for bit.

use super::config::{LoadConfig, LoadMode};
use super::model::{EngineError, Model};
use super::steady::{solve_with_stats, Demand, SolveStats, SteadyInputs, SteadyPoint};
use std::sync::Arc;

/// The load of a mechanical drive as the dynamic model applies it, frozen from the engine file
/// and the calibrated design point: the power it absorbs at each PT speed.
#[derive(Debug, Clone, PartialEq)]
pub enum PtLoad {
    /// `P = P_design · (n2 / n2_design)^exponent`.
    Law(PtLoadLaw),
    /// A tabulated curve (`[load] mode = "table"`).
    Table(Arc<LoadCurve>),
}

/// The power law of a mechanical drive: `P = P_design · (n2 / n2_design)^exponent`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PtLoadLaw {
    /// Power absorbed at the design PT speed, W (the engine's design power).
    pub power_design_w: f64,
    /// Design PT speed, rpm.
    pub n2_design_rpm: f64,
    /// Exponent k of the law.
    pub exponent: f64,
}

/// A tabulated power–speed curve: piecewise linear between its points, a cube law through the
/// first point below it (a propeller or fan near standstill) and the last segment's power law
/// (its local exponent) above the last point. Speeds and powers strictly increase, so the
/// curve has an inverse.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadCurve {
    speed_rpm: Vec<f64>,
    power_w: Vec<f64>,
}

/// Exponent of the curve below its first point (power ∝ speed³ near standstill).
const LOW_SPEED_EXPONENT: f64 = 3.0;

impl LoadCurve {
    /// The curve of a checked `[load]` table (`LoadConfig::check`); `None` when it has fewer
    /// than 2 points or is not increasing.
    pub fn new(speed_rpm: &[f64], power_mw: &[f64]) -> Option<LoadCurve> {
        let ok = speed_rpm.len() >= 2
            && speed_rpm.len() == power_mw.len()
            && speed_rpm[0] > 0.0
            && power_mw[0] > 0.0
            && speed_rpm.windows(2).all(|w| w[1] > w[0])
            && power_mw.windows(2).all(|w| w[1] > w[0]);
        ok.then(|| LoadCurve {
            speed_rpm: speed_rpm.to_vec(),
            power_w: power_mw.iter().map(|p| p * 1e6).collect(),
        })
    }

    /// Local exponent of the last segment, d ln P / d ln n.
    fn top_exponent(&self) -> f64 {
        let k = self.speed_rpm.len() - 1;
        (self.power_w[k] / self.power_w[k - 1]).ln()
            / (self.speed_rpm[k] / self.speed_rpm[k - 1]).ln()
    }

    /// Power absorbed at `n2_rpm`, W (0 at and below standstill).
    pub fn power_w(&self, n2_rpm: f64) -> f64 {
        let (s, p) = (&self.speed_rpm, &self.power_w);
        let n = n2_rpm.max(0.0);
        let last = s.len() - 1;
        if n <= s[0] {
            return p[0] * (n / s[0]).powf(LOW_SPEED_EXPONENT);
        }
        if n >= s[last] {
            return p[last] * (n / s[last]).powf(self.top_exponent());
        }
        let i = s.partition_point(|&v| v <= n) - 1;
        p[i] + (n - s[i]) / (s[i + 1] - s[i]) * (p[i + 1] - p[i])
    }

    /// The speed at which the curve absorbs `power_w`, rpm (the inverse of [`Self::power_w`]).
    pub fn speed_rpm(&self, power_w: f64) -> f64 {
        let (s, p) = (&self.speed_rpm, &self.power_w);
        let w = power_w.max(0.0);
        let last = s.len() - 1;
        if w <= p[0] {
            return s[0] * (w / p[0]).powf(1.0 / LOW_SPEED_EXPONENT);
        }
        if w >= p[last] {
            return s[last] * (w / p[last]).powf(1.0 / self.top_exponent());
        }
        let i = p.partition_point(|&v| v <= w) - 1;
        s[i] + (w - p[i]) / (p[i + 1] - p[i]) * (s[i + 1] - s[i])
    }

    /// Local exponent d ln P / d ln n at `n2_rpm`.
    pub fn local_exponent(&self, n2_rpm: f64) -> f64 {
        let (s, p) = (&self.speed_rpm, &self.power_w);
        let last = s.len() - 1;
        if n2_rpm <= s[0] {
            return LOW_SPEED_EXPONENT;
        }
        if n2_rpm >= s[last] {
            return self.top_exponent();
        }
        let i = s.partition_point(|&v| v <= n2_rpm) - 1;
        let slope = (p[i + 1] - p[i]) / (s[i + 1] - s[i]);
        slope * n2_rpm / self.power_w(n2_rpm).max(1e-9)
    }
}

impl PtLoad {
    /// The model's load, or `None` when the PT speed is not set by a load curve (generator,
    /// measured speed).
    pub fn of(model: &Model) -> Option<PtLoad> {
        let load = model.cfg().load.as_ref()?;
        match load.mode {
            LoadMode::Generator | LoadMode::MeasuredSpeed => None,
            LoadMode::LoadLaw => Some(PtLoad::Law(PtLoadLaw {
                power_design_w: model.consts.power_design_w,
                n2_design_rpm: model.consts.n2_design,
                exponent: load.exponent,
            })),
            LoadMode::Table => {
                LoadCurve::new(&load.speed_rpm, &load.power_mw).map(|c| PtLoad::Table(Arc::new(c)))
            }
        }
    }

    /// Power the load absorbs at PT speed `n2_rpm`, W (0 at and below standstill).
    #[inline]
    pub fn power_w(&self, n2_rpm: f64) -> f64 {
        match self {
            PtLoad::Law(l) => l.power_w(n2_rpm),
            PtLoad::Table(c) => c.power_w(n2_rpm),
        }
    }

    /// The PT speed at which the load absorbs `power_mw`, rpm.
    pub fn speed_for_power_rpm(&self, power_mw: f64) -> f64 {
        match self {
            PtLoad::Law(l) => l.speed_for_power_rpm(power_mw),
            PtLoad::Table(c) => c.speed_rpm(power_mw * 1e6),
        }
    }

    /// Local exponent d ln P / d ln n at `n2_rpm` (k for a law): how a relative power error
    /// maps onto a relative speed error, `dn/n = dP/(k P)`.
    pub fn local_exponent(&self, n2_rpm: f64) -> f64 {
        match self {
            PtLoad::Law(l) => l.exponent,
            PtLoad::Table(c) => c.local_exponent(n2_rpm),
        }
    }

    /// A short description for messages.
    pub fn describe(&self) -> String {
        match self {
            PtLoad::Law(l) => format!("load law P ∝ n2^{}", l.exponent),
            PtLoad::Table(c) => format!("load curve of {} points", c.speed_rpm.len()),
        }
    }
}

impl PtLoadLaw {
    /// Power the load absorbs at PT speed `n2_rpm`, W (0 at and below standstill).
    #[inline]
    pub fn power_w(&self, n2_rpm: f64) -> f64 {
        self.power_design_w * (n2_rpm.max(0.0) / self.n2_design_rpm).powf(self.exponent)
    }

    /// The PT speed at which the load absorbs `power_mw`, rpm.
    pub fn speed_for_power_rpm(&self, power_mw: f64) -> f64 {
        self.n2_design_rpm
            * (power_mw.max(0.0) * 1e6 / self.power_design_w).powf(1.0 / self.exponent)
    }
}

/// The load's power at PT speed `n2_rpm`, MW (`None`: the PT speed is not set by a load curve).
pub fn load_power_mw(model: &Model, n2_rpm: f64) -> Option<f64> {
    PtLoad::of(model).map(|l| l.power_w(n2_rpm) / 1e6)
}

/// Steady point under the engine file's load mode. In generator and measured-speed mode (or
/// with no `[load]` section) this is [`super::steady::solve`] at `inp.n2_rpm`; with a load curve
/// `inp.n2_rpm` is only the first guess of the PT speed (use [`solve_at_speed`] to hold it).
pub fn solve(
    model: &Model,
    load: Option<&LoadConfig>,
    inp: &SteadyInputs,
    guess: Option<&SteadyPoint>,
) -> Result<(SteadyPoint, SolveStats), EngineError> {
    let curve = match load.map(|l| l.mode) {
        Some(LoadMode::LoadLaw | LoadMode::Table) => PtLoad::of(model),
        _ => None,
    };
    let Some(curve) = curve else {
        return solve_with_stats(model, inp, guess);
    };
    let c = &model.consts;
    if let Demand::PowerMw(p) = inp.demand {
        let n2 = curve.speed_for_power_rpm(p);
        return solve_with_stats(model, &SteadyInputs { n2_rpm: n2, ..*inp }, guess);
    }
    let mut total = SolveStats::default();
    let mut at = |n2: f64, g: Option<&SteadyPoint>| -> Result<(SteadyPoint, f64), EngineError> {
        let (p, s) = solve_with_stats(model, &SteadyInputs { n2_rpm: n2, ..*inp }, g)?;
        total.newton_iterations += s.newton_iterations;
        total.evaluations += s.evaluations;
        total.continuation_steps += s.continuation_steps;
        let mismatch = p.power_mw - curve.power_w(n2) / 1e6;
        Ok((p, mismatch))
    };
    let mut n_a = if inp.n2_rpm > 0.0 {
        inp.n2_rpm
    } else {
        c.n2_design
    };
    let (mut p_a, mut f_a) = at(n_a, guess)?;
    // Second point: the load's speed for the power just found.
    let mut n_b = curve.speed_for_power_rpm(p_a.power_mw.max(1e-3));
    if (n_b - n_a).abs() < 1e-9 * c.n2_design {
        return Ok((p_a, total));
    }
    let (mut p_b, mut f_b) = at(n_b, Some(&p_a))?;
    for _ in 0..40 {
        if f_b.abs() < 1e-9 * c.power_design_w / 1e6 {
            return Ok((p_b, total));
        }
        let slope = (f_b - f_a) / (n_b - n_a);
        if !slope.is_finite() || slope == 0.0 {
            break;
        }
        let n_next = (n_b - f_b / slope).clamp(0.05 * c.n2_design, 1.5 * c.n2_design);
        (n_a, p_a, f_a) = (n_b, p_b, f_b);
        n_b = n_next;
        (p_b, f_b) = at(n_b, Some(&p_a))?;
    }
    Err(EngineError::NoSteadySolution(format!(
        "{}: no PT speed where the engine's power meets the load for {:?} \
         (last n2 {n_b:.1} rpm, mismatch {f_b:.4} MW)",
        curve.describe(),
        inp.demand
    )))
}

/// Steady point at exactly `inp.n2_rpm`, whatever the load mode (a measured point reproduced at
/// its measured PT speed: `steady --n2-rpm`), with the power the engine file's load would
/// absorb at that speed (`None` when no load curve sets the PT speed).
pub fn solve_at_speed(
    model: &Model,
    inp: &SteadyInputs,
    guess: Option<&SteadyPoint>,
) -> Result<(SteadyPoint, SolveStats, Option<f64>), EngineError> {
    let (p, stats) = solve_with_stats(model, inp, guess)?;
    Ok((p, stats, load_power_mw(model, inp.n2_rpm)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::{Engine, EngineConfig};
    use crate::health::HealthParams;

    fn propeller_engine() -> (Engine, LoadConfig) {
        let text = format!(
            "{}\n[load]\nmode = \"load_law\"\nexponent = 3.0\n",
            crate::engine::config::REFERENCE_ENGINE_TOML
        );
        let cfg = EngineConfig::from_toml_str(&text, "x.toml").expect("load law file");
        let load = cfg.load.clone().expect("[load]");
        (Engine::new(cfg).expect("engine"), load)
    }

    /// On a cube law the PT speed follows the load: at a fuel demand the solved point sits on
    /// the law; a power demand gives the closed-form speed; the design point is unchanged;
    /// generator mode keeps the caller's speed.
    #[test]
    fn pt_speed_follows_a_cube_law() {
        let (e, load) = propeller_engine();
        let m = e.model(&HealthParams::HEALTHY);
        let base = SteadyInputs {
            t_amb_k: 288.15,
            p_amb_kpa: 101.325,
            n2_rpm: 3600.0,
            demand: Demand::PowerMw(31.4),
        };
        let (dp, _) = solve(&m, Some(&load), &base, None).expect("design");
        assert!((dp.n2_rpm / 3600.0 - 1.0).abs() < 1e-9, "{}", dp.n2_rpm);
        let half = SteadyInputs {
            demand: Demand::PowerMw(31.4 / 8.0),
            ..base
        };
        let (p, _) = solve(&m, Some(&load), &half, None).expect("eighth power");
        assert!((p.n2_rpm / 1800.0 - 1.0).abs() < 1e-9, "{}", p.n2_rpm);
        assert!((p.power_mw / (31.4 / 8.0) - 1.0).abs() < 1e-6);
        let mut speeds: Vec<f64> = Vec::new();
        for wf in [0.9, 1.4, 1.9] {
            let inp = SteadyInputs {
                demand: Demand::FuelKgS(wf),
                ..base
            };
            let (q, stats) = solve(&m, Some(&load), &inp, None).expect("fuel demand");
            let law = load_power_mw(&m, q.n2_rpm).expect("a load law");
            assert!((q.power_mw / law - 1.0).abs() < 1e-6, "wf {wf}: {q:?}");
            assert!(
                q.n2_rpm < 4500.0 && q.n2_rpm > 1000.0,
                "wf {wf}: {}",
                q.n2_rpm
            );
            speeds.push(q.n2_rpm);
            assert!(stats.newton_iterations > 0);
            // Against the generator at the same fuel: different speed, different power.
            let (g, _) = solve(&m, None, &inp, None).expect("generator");
            assert_eq!(g.n2_rpm, 3600.0);
            assert!((g.n2_rpm - q.n2_rpm).abs() > 50.0);
        }
        // More fuel, more power, a faster PT.
        assert!(speeds.windows(2).all(|w| w[1] > w[0]), "{speeds:?}");
    }

    /// The dynamic form of the law: the same power as [`law_power_mw`], its inverse, and none in
    /// generator mode.
    #[test]
    fn dynamic_law_matches_the_steady_one() {
        let (e, load) = propeller_engine();
        let m = e.model(&HealthParams::HEALTHY);
        let law = PtLoad::of(&m).expect("load law");
        for n2 in [0.0, 900.0, 1800.0, 3600.0, 4000.0] {
            let p = 31.4 * (n2 / 3600.0_f64).powf(load.exponent);
            assert!((law.power_w(n2) / 1e6 - p).abs() < 1e-9 * 31.4);
        }
        assert!((law.speed_for_power_rpm(31.4 / 8.0) / 1800.0 - 1.0).abs() < 1e-12);
        assert_eq!(law.power_w(-5.0), 0.0);
        let generator = Engine::reference().expect("reference");
        assert!(PtLoad::of(&generator.model(&HealthParams::HEALTHY)).is_none());
    }

    #[test]
    fn load_section_is_checked() {
        let text = format!(
            "{}\n[load]\nmode = \"load_law\"\nexponent = 0.0\n",
            crate::engine::config::REFERENCE_ENGINE_TOML
        );
        let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err("bad exponent");
        assert!(err.to_string().contains("load.exponent"), "{err}");
        let text = format!(
            "{}\n[load]\nmode = \"propeller\"\n",
            crate::engine::config::REFERENCE_ENGINE_TOML
        );
        let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err("bad mode");
        assert!(err.to_string().contains("propeller"), "{err}");
    }

    /// A tabulated curve: exact at its points, linear between, a cube law below the first point
    /// and the last segment's power law above the last; the inverse returns the speed; the
    /// local exponent is d ln P / d ln n.
    #[test]
    fn load_curve_interpolates_and_inverts() {
        let c = LoadCurve::new(&[2000.0, 4000.0, 6000.0], &[2.0, 10.0, 24.0]).expect("curve");
        assert_eq!(c.power_w(4000.0), 10.0e6);
        assert!((c.power_w(3000.0) - 6.0e6).abs() < 1e-6);
        assert!((c.power_w(1000.0) - 2.0e6 / 8.0).abs() < 1e-6);
        let k_top = (24.0_f64 / 10.0).ln() / (1.5_f64).ln();
        assert!((c.power_w(6600.0) / 24.0e6 - 1.1_f64.powf(k_top)).abs() < 1e-12);
        assert_eq!(c.power_w(-1.0), 0.0);
        for n in [500.0, 2000.0, 2500.0, 3999.0, 5000.0, 6000.0, 7000.0] {
            assert!((c.speed_rpm(c.power_w(n)) - n).abs() < 1e-6, "{n}");
        }
        assert!((c.local_exponent(3000.0) - 8.0e6 / 2000.0 * 3000.0 / 6.0e6).abs() < 1e-12);
        assert_eq!(c.local_exponent(1000.0), 3.0);
        assert!(LoadCurve::new(&[2000.0, 4000.0], &[5.0, 4.0]).is_none());
        assert!(LoadCurve::new(&[2000.0], &[5.0]).is_none());
    }

    /// A table load: at a fuel demand the point sits on the curve; a power demand gives the
    /// curve's speed; [`solve_at_speed`] holds the given speed whatever the mode.
    #[test]
    fn pt_speed_follows_a_table_and_is_held_when_given() {
        let text = format!(
            "{}\n[load]\nmode = \"table\"\nspeed_rpm = [1800.0, 3000.0, 3600.0, 4200.0]\n\
             power_mw = [4.0, 18.0, 31.4, 45.0]\n",
            crate::engine::config::REFERENCE_ENGINE_TOML
        );
        let cfg = EngineConfig::from_toml_str(&text, "x.toml").expect("table file");
        let load = cfg.load.clone().expect("[load]");
        let e = Engine::new(cfg).expect("engine");
        let m = e.model(&HealthParams::HEALTHY);
        let base = SteadyInputs {
            t_amb_k: 288.15,
            p_amb_kpa: 101.325,
            n2_rpm: 3600.0,
            demand: Demand::FuelKgS(1.4),
        };
        let (q, _) = solve(&m, Some(&load), &base, None).expect("fuel demand");
        let on_curve = load_power_mw(&m, q.n2_rpm).expect("a curve");
        assert!((q.power_mw / on_curve - 1.0).abs() < 1e-6, "{q:?}");
        assert!(q.n2_rpm > 1800.0 && q.n2_rpm < 3600.0, "{}", q.n2_rpm);
        let p = SteadyInputs {
            demand: Demand::PowerMw(18.0),
            ..base
        };
        let (q, _) = solve(&m, Some(&load), &p, None).expect("power demand");
        assert!((q.n2_rpm - 3000.0).abs() < 1e-9, "{}", q.n2_rpm);
        let held = SteadyInputs {
            n2_rpm: 3333.0,
            ..base
        };
        let (q, _, l) = solve_at_speed(&m, &held, None).expect("held");
        assert_eq!(q.n2_rpm, 3333.0);
        assert!((l.expect("load power") - (18.0 + 333.0 / 600.0 * 13.4)).abs() < 1e-9);
    }

    #[test]
    fn load_table_is_checked() {
        for (table, key) in [
            (
                "speed_rpm = [3000.0, 2000.0]\npower_mw = [1.0, 2.0]",
                "load.speed_rpm",
            ),
            (
                "speed_rpm = [2000.0, 3000.0]\npower_mw = [2.0, 1.0]",
                "load.power_mw",
            ),
            (
                "speed_rpm = [2000.0, 3000.0]\npower_mw = [2.0]",
                "load.power_mw",
            ),
            ("speed_rpm = [2000.0]\npower_mw = [2.0]", "load.speed_rpm"),
        ] {
            let text = format!(
                "{}\n[load]\nmode = \"table\"\n{table}\n",
                crate::engine::config::REFERENCE_ENGINE_TOML
            );
            let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err(table);
            assert!(err.to_string().contains(key), "{table}: {err}");
        }
        let text = format!(
            "{}\n[load]\nmode = \"measured_speed\"\nspeed_rpm = [1.0, 2.0]\npower_mw = [1.0, 2.0]\n",
            crate::engine::config::REFERENCE_ENGINE_TOML
        );
        let err = EngineConfig::from_toml_str(&text, "x.toml").expect_err("table unused");
        assert!(err.to_string().contains("only read with mode"), "{err}");
    }
}
