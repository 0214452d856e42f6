//! Effect `fuel_system`: the fuel burnt lags the fuel metered. Between the metering valve (whose
//! flow the controller commands and the flowmeter records) and the burners lie the manifold and
//! lines: a transport delay while the fuel travels, then a first-order lag while the manifold
//! fills or drains (T-MATS models the fuel actuator and line the same way).
//!
//! The delay is approximated by three equal first-order stages (an Erlang chain: the mean delay
//! is exact, the front is smoothed; unlike a Padé approximant it never delivers negative fuel),
//! followed by the manifold lag: four states, in units of design fuel flow. In steady operation
//! everything metered burns, so the effect only changes transients.
//!
//! Signature: in the data, the recorded fuel flow leads the speeds, pressures and temperatures
//! by roughly `delay_s + lag_s` at every fuel change (light-off, acceleration, load steps); a
//! model without it shows an early T3/T34 and power rise, which a health fit absorbs as too
//! much turbine efficiency or too little compressor efficiency.
//! Pure: no I/O.

use super::{lag_rate, Context, CoreView, Effect, EffectSpec, ParamSpec};
use crate::engine::gas_path::Stations;
use std::sync::Arc;

/// Stages of the transport-delay chain.
const STAGES: usize = 3;

/// Registry entry.
pub(crate) static SPEC: EffectSpec = EffectSpec {
    name: "fuel_system",
    instrument: false,
    channels: super::Channels::Engine,
    summary: "fuel-system transport delay and manifold lag between metered and burnt fuel",
    signature: "recorded fuel flow leads the gas-path response (T3, T34, P2, speeds, power) \
                by about delay_s + lag_s at every fuel change; steady points unaffected",
    params: &[
        ParamSpec {
            name: "lag_s",
            unit: "s",
            default: 0.5,
            min: 0.0,
            max: 10.0,
            doc: "time constant of the manifold lag",
            refinement: false,
        },
        ParamSpec {
            name: "delay_s",
            unit: "s",
            default: 1.0,
            min: 0.0,
            max: 10.0,
            doc: "transport delay from the metering valve to the burners",
            refinement: false,
        },
    ],
    refinement_starts: None,
    build,
};

fn build(p: &[f64], _channel: Option<crate::signals::Signal>) -> Arc<dyn Effect> {
    Arc::new(FuelSystem {
        lag_s: p.first().copied().unwrap_or(0.5),
        delay_s: p.get(1).copied().unwrap_or(1.0),
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct FuelSystem {
    lag_s: f64,
    delay_s: f64,
}

impl Effect for FuelSystem {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn n_states(&self) -> usize {
        STAGES + 1
    }

    fn rest_states(&self, _core: &CoreView, x: &mut [f64]) {
        x.fill(0.0);
    }

    fn steady_states(&self, core: &CoreView, stations: &Stations, x: &mut [f64]) {
        x.fill(stations.fuel_kg_s / core.fuel_design_kg_s);
    }

    fn fuel_delivered(&self, _metered_kg_s: f64, core: &CoreView, x: &[f64]) -> f64 {
        x[STAGES].max(0.0) * core.fuel_design_kg_s
    }

    fn derivatives(&self, ctx: &Context<'_>, x: &[f64], dx: &mut [f64]) {
        let u = ctx.metered_fuel_kg_s / ctx.core.fuel_design_kg_s;
        let tau = self.delay_s / STAGES as f64;
        dx[0] = lag_rate(u, x[0], tau);
        for k in 1..STAGES {
            dx[k] = lag_rate(x[k - 1], x[k], tau);
        }
        dx[STAGES] = lag_rate(x[STAGES - 1], x[STAGES], self.lag_s);
    }
}

#[cfg(test)]
mod tests {
    use crate::engine::simulation::run_scenario;
    use crate::engine::{Engine, EngineConfig, Scenario};
    use crate::health::HealthParams;

    fn engine_with(lag_s: f64, delay_s: f64) -> Engine {
        let mut e = Engine::reference().expect("engine");
        e.set_param("effects.fuel_system.lag_s", lag_s)
            .expect("lag");
        e.set_param("effects.fuel_system.delay_s", delay_s)
            .expect("delay");
        e
    }

    #[test]
    fn enabled_from_the_engine_file_with_defaults() {
        let text = format!(
            "{}\n[effects.fuel_system]\nlag_s = 0.8\n",
            crate::engine::config::REFERENCE_ENGINE_TOML
        );
        let cfg = EngineConfig::from_toml_str(&text, "e.toml").expect("parses");
        assert_eq!(cfg.effects["fuel_system"]["lag_s"], 0.8);
        assert_eq!(cfg.effects["fuel_system"]["delay_s"], 1.0);
        let e = Engine::new(cfg).expect("builds");
        assert_eq!(e.effects().names(), ["fuel_system".to_string()]);
        assert_eq!(e.get_param("effects.fuel_system.lag_s").expect("key"), 0.8);
        let bad = format!(
            "{}\n[effects.fuel_system]\ndelay_s = -1\n",
            crate::engine::config::REFERENCE_ENGINE_TOML
        );
        let err = EngineConfig::from_toml_str(&bad, "e.toml").expect_err("range");
        assert!(err.to_string().contains("effects.fuel_system.delay_s"), "{err}");
    }

    /// The burnt fuel follows the metered fuel late, and by about the stated delay + lag; the
    /// metered (recorded) fuel trace is what the controller asked for; the start still works.
    #[test]
    fn burnt_fuel_lags_metered_fuel_by_delay_plus_lag() {
        let mut e = engine_with(0.5, 1.5);
        // A plant with 2 s in its fuel path has its power loop tuned for it: the reference
        // gains (crossover ≈ 1 rad/s) would turn 2 s of delay into a limit cycle.
        e.set_param("control.power_kp_kg_s_per_mw", 0.01)
            .expect("kp");
        e.set_param("control.power_ki_kg_s_per_mw_s", 0.015)
            .expect("ki");
        let m = e.model(&HealthParams::HEALTHY);
        let (s, _) = run_scenario(&m, &Scenario::startup(e.cfg())).expect("runs");
        assert!(
            s.iter()
                .any(|x| x.phase == crate::signals::Phase::Steady),
            "reaches steady load"
        );
        // The pure delay that best maps the metered onto the burnt fuel (least squares over
        // the whole start) is the chain's total time constant, delay + lag = 2 s, for inputs
        // smooth on that scale.
        let t: Vec<f64> = s.iter().map(|x| x.t_s).collect();
        let metered: Vec<f64> = s.iter().map(|x| x.stations.fuel_kg_s).collect();
        let at = |tt: f64| {
            let k = t.partition_point(|&x| x <= tt).clamp(1, t.len() - 1);
            let f = ((tt - t[k - 1]) / (t[k] - t[k - 1])).clamp(0.0, 1.0);
            metered[k - 1] + f * (metered[k] - metered[k - 1])
        };
        let misfit = |shift: f64| -> f64 {
            s.iter()
                .map(|x| (x.stations.fuel_burnt_kg_s - at(x.t_s - shift)).powi(2))
                .sum()
        };
        let best = (0..=100)
            .map(|i| i as f64 * 0.05)
            .min_by(|a, b| misfit(*a).total_cmp(&misfit(*b)))
            .expect("shifts");
        assert!((best - 2.0).abs() <= 0.3, "best shift {best} s");
        assert!(misfit(best) < 0.2 * misfit(0.0), "a delay explains the difference");
        let last = s.last().expect("samples").stations;
        assert!((last.fuel_burnt_kg_s / last.fuel_kg_s - 1.0).abs() < 0.01);
        // Without the effect, burnt = metered.
        let core = Engine::reference().expect("engine");
        let (c, _) = run_scenario(&core.model(&HealthParams::HEALTHY),
            &Scenario::startup(core.cfg()),
        )
        .expect("runs");
        assert!(c.iter().all(|x| x.stations.fuel_burnt_kg_s == x.stations.fuel_kg_s));
    }

    #[test]
    fn steady_points_do_not_see_the_effect() {
        use crate::engine::steady::{solve, Demand, SteadyInputs};
        let inp = SteadyInputs {
            t_amb_k: 288.15,
            p_amb_kpa: 101.325,
            n2_rpm: 3600.0,
            demand: Demand::PowerMw(25.0),
        };
        let h = HealthParams::HEALTHY;
        let a = solve(&engine_with(2.0, 3.0).model(&h), &inp, None).expect("solves");
        let b = solve(&Engine::reference().expect("e").model(&h), &inp, None).expect("solves");
        assert_eq!(a.stations, b.stations);
    }
}
