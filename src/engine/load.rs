//! Power-turbine load modes for steady operation (issue 10 item 5): what sets the PT speed.
//!
//! What it is for: a steady operating point of an engine whose PT drives a generator (speed
//! held by the grid, the caller's `n2_rpm`: [`super::steady::solve`] as before) or a mechanical
//! load whose absorbed power follows a law `P = P_design · (n2 / n2_design)^k` (propeller,
//! centrifugal compressor or pump: k ≈ 3), so the PT speed follows the load. What it must not
//! do: I/O, or change the gas-path matching itself (it only chooses `n2` around
//! [`super::steady::solve_with_stats`]).
//!
//! With a load law, a power demand fixes the speed in closed form,
//! `n2 = n2_design · (P / P_design)^(1/k)`; a fuel or GG-speed demand leaves the speed unknown,
//! found by a secant iteration on `P_engine(n2) − P_law(n2) = 0` (the engine's power depends
//! weakly on n2, the law strongly, so 3–6 steady solves suffice).
//!
//! Dynamic runs: [`PtLoadLaw`] is the same law frozen into a `Copy` value that the drive of each
//! integration step carries (`dynamic::Drive::pt_load`). The PT speed is then a state driven by
//! `J2 ω dω/dt = P_PT,net(n2) − P_law(n2)` whenever the breaker is not closed (a mechanical drive
//! has none), and the sequencer governs the PT speed (`sequence.rs`). In generator mode the drive
//! carries no law and the dynamic model is the grid-locked one, bit for bit.

use super::config::{LoadConfig, LoadMode};
use super::model::{EngineError, Model};
use super::steady::{solve_with_stats, Demand, SolveStats, SteadyInputs, SteadyPoint};

/// The load law of a mechanical drive as the dynamic model applies it: `P = P_design ·
/// (n2 / n2_design)^exponent`, frozen from the engine file and the calibrated design point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PtLoadLaw {
    /// Power absorbed at the design PT speed, W (the engine's design power).
    pub power_design_w: f64,
    /// Design PT speed, rpm.
    pub n2_design_rpm: f64,
    /// Exponent k of the law.
    pub exponent: f64,
}

impl PtLoadLaw {
    /// The model's load law, or `None` in generator mode (no `[load]`, or `mode = "generator"`).
    pub fn of(model: &Model) -> Option<PtLoadLaw> {
        let law = model.cfg().load.as_ref()?;
        (law.mode == LoadMode::LoadLaw).then_some(PtLoadLaw {
            power_design_w: model.consts.power_design_w,
            n2_design_rpm: model.consts.n2_design,
            exponent: law.exponent,
        })
    }

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

/// The load law's power at PT speed `n2_rpm`, MW.
pub fn law_power_mw(model: &Model, law: &LoadConfig, n2_rpm: f64) -> f64 {
    let c = &model.consts;
    c.power_design_w / 1e6 * (n2_rpm.max(0.0) / c.n2_design).powf(law.exponent)
}

/// Steady point under the engine file's load mode. In generator mode (or with no `[load]`
/// section) this is [`super::steady::solve`] at `inp.n2_rpm`; with a load law `inp.n2_rpm` is
/// only the first guess of the PT speed.
pub fn solve(
    model: &Model,
    load: Option<&LoadConfig>,
    inp: &SteadyInputs,
    guess: Option<&SteadyPoint>,
) -> Result<(SteadyPoint, SolveStats), EngineError> {
    let law = match load {
        Some(l) if l.mode == LoadMode::LoadLaw => l,
        _ => return solve_with_stats(model, inp, guess),
    };
    let c = &model.consts;
    if let Demand::PowerMw(p) = inp.demand {
        let n2 = c.n2_design * (p.max(0.0) * 1e6 / c.power_design_w).powf(1.0 / law.exponent);
        return solve_with_stats(model, &SteadyInputs { n2_rpm: n2, ..*inp }, guess);
    }
    let mut total = SolveStats::default();
    let mut at = |n2: f64, g: Option<&SteadyPoint>| -> Result<(SteadyPoint, f64), EngineError> {
        let (p, s) = solve_with_stats(model, &SteadyInputs { n2_rpm: n2, ..*inp }, g)?;
        total.newton_iterations += s.newton_iterations;
        total.evaluations += s.evaluations;
        total.continuation_steps += s.continuation_steps;
        let mismatch = p.power_mw - law_power_mw(model, law, n2);
        Ok((p, mismatch))
    };
    let mut n_a = if inp.n2_rpm > 0.0 {
        inp.n2_rpm
    } else {
        c.n2_design
    };
    let (mut p_a, mut f_a) = at(n_a, guess)?;
    // Second point: the law's speed for the power just found.
    let mut n_b =
        c.n2_design * (p_a.power_mw.max(1e-3) * 1e6 / c.power_design_w).powf(1.0 / law.exponent);
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
        "load law P ∝ n2^{}: no PT speed where the engine's power meets the load for {:?} \
         (last n2 {n_b:.1} rpm, mismatch {f_b:.4} MW)",
        law.exponent, inp.demand
    )))
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
            let law = law_power_mw(&m, &load, q.n2_rpm);
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
        let law = PtLoadLaw::of(&m).expect("load law");
        for n2 in [0.0, 900.0, 1800.0, 3600.0, 4000.0] {
            assert!((law.power_w(n2) / 1e6 - law_power_mw(&m, &load, n2)).abs() < 1e-12);
        }
        assert!((law.speed_for_power_rpm(31.4 / 8.0) / 1800.0 - 1.0).abs() < 1e-12);
        assert_eq!(law.power_w(-5.0), 0.0);
        let generator = Engine::reference().expect("reference");
        assert!(PtLoadLaw::of(&generator.model(&HealthParams::HEALTHY)).is_none());
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
}
