//! `gtwatch steady`: one steady operating point and its full station table.
//! Must not open the database or write files: it prints.

use super::engine_args::EngineArgs;
use crate::engine::steady::{Demand, SteadyInputs};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("demand").args(["power_mw", "fuel_kg_s", "n1_rpm"])))]
pub struct SteadyArgs {
    #[command(flatten)]
    pub engine: EngineArgs,
    /// Power at the PT coupling, MW (default with no demand: the design power).
    #[arg(long)]
    pub power_mw: Option<f64>,
    /// Fuel flow, kg/s.
    #[arg(long)]
    pub fuel_kg_s: Option<f64>,
    /// GG speed, rpm.
    #[arg(long)]
    pub n1_rpm: Option<f64>,
    /// PT speed, rpm, held exactly in every load mode (a measured point reproduced at its
    /// measured speed). Without it: synchronous speed for a generator or a measured-speed
    /// load, and with a load curve (`[load] mode = "load_law"` or `"table"`) the speed at
    /// which the load absorbs what the engine delivers.
    #[arg(long)]
    pub n2_rpm: Option<f64>,
    /// Ambient temperature, K (default: the engine file's ambient).
    #[arg(long)]
    pub t_amb_k: Option<f64>,
    /// Ambient pressure, kPa.
    #[arg(long)]
    pub p_amb_kpa: Option<f64>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Highest GG speed a steady demand may ask for, as a fraction of design speed (overspeed trip
/// settings are typically 105–110 %).
const MAX_SPEED_FRACTION: f64 = 1.1;
/// Highest power demand, as a fraction of design power (cold-day output can exceed ISO rating).
const MAX_POWER_FRACTION: f64 = 1.5;

pub(super) fn run(a: SteadyArgs) -> anyhow::Result<ExitCode> {
    let (engine, health) = a.engine.load()?;
    let cfg = engine.cfg();
    // Issue 12 #8: a demand outside what the engine can run (e.g. 210 % GG speed) gave a
    // "solution" from the extrapolated maps; refuse it instead.
    let max_n1 = MAX_SPEED_FRACTION * cfg.design.gg_speed_rpm;
    let max_mw = MAX_POWER_FRACTION * cfg.design.power_mw;
    for (flag, v, lo, hi) in [
        ("--n1-rpm", a.n1_rpm, 0.0, max_n1),
        ("--power-mw", a.power_mw, 0.0, max_mw),
        ("--fuel-kg-s", a.fuel_kg_s, 0.0, f64::MAX),
    ] {
        if let Some(v) = v {
            if !v.is_finite() || v <= lo || v > hi {
                anyhow::bail!(
                    "{flag} {v} is outside what the engine can run ({lo} < value ≤ {hi:.1})"
                );
            }
        }
    }
    let demand = match (a.power_mw, a.fuel_kg_s, a.n1_rpm) {
        (Some(p), _, _) => Demand::PowerMw(p),
        (_, Some(f), _) => Demand::FuelKgS(f),
        (_, _, Some(n)) => Demand::N1Rpm(n),
        _ => Demand::PowerMw(cfg.design.power_mw),
    };
    let t_amb = a.t_amb_k.unwrap_or(cfg.ambient.temperature_k);
    let p_amb = a.p_amb_kpa.unwrap_or(cfg.ambient.pressure_kpa);
    let model = engine.model_at(&health, t_amb, p_amb);
    let inputs = SteadyInputs {
        t_amb_k: t_amb,
        p_amb_kpa: p_amb,
        n2_rpm: a.n2_rpm.unwrap_or(cfg.design.pt_speed_rpm),
        demand,
    };
    // A given --n2-rpm is held; otherwise the engine file's load mode decides the PT speed.
    let (p, load_mw) = match a.n2_rpm {
        Some(n2) => {
            if !(n2.is_finite() && n2 > 0.0) {
                anyhow::bail!("--n2-rpm {n2} must be a positive speed");
            }
            let (p, _, load) = crate::engine::load::solve_at_speed(&model, &inputs, None)?;
            (p, load)
        }
        None => {
            let (p, _) = crate::engine::load::solve(&model, cfg.load.as_ref(), &inputs, None)?;
            (p, crate::engine::load::load_power_mw(&model, p.n2_rpm))
        }
    };
    if a.json {
        let mut v = serde_json::to_value(p)?;
        if let Some(o) = v.as_object_mut() {
            o.insert("health".into(), serde_json::to_value(health)?);
            o.insert("load_power_mw".into(), serde_json::to_value(load_mw)?);
            o.insert(
                "demand".into(),
                serde_json::Value::String(format!("{demand:?}")),
            );
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("steady operating point: {demand:?}, health {health}");
        println!("{:>8} {:>10} {:>10}", "station", "T [K]", "P [kPa]");
        for (name, t, pr) in [
            ("1 inlet", p.t1_k, p.p1_kpa),
            ("2 comp", p.t2_k, p.p2_kpa),
            ("3 comb", p.t3_k, p.p3_kpa),
            ("34 HPT", p.t34_k, p.p34_kpa),
            ("4 PT", p.t4_k, p.p4_kpa),
        ] {
            println!("{name:>8} {t:>10.1} {pr:>10.2}");
        }
        println!("n1 {:.0} rpm, n2 {:.0} rpm", p.n1_rpm, p.n2_rpm);
        if let Some(l) = load_mw {
            println!(
                "the engine file's load absorbs {l:.3} MW at this PT speed (engine delivers \
                 {:.3} MW{})",
                p.power_mw,
                if a.n2_rpm.is_some() {
                    ": PT speed held at --n2-rpm"
                } else {
                    ""
                }
            );
        }
        println!(
            "air {:.2} kg/s, fuel {:.4} kg/s, exhaust {:.2} kg/s, power {:.2} MW, heat rate {:.0} kJ/kWh",
            p.air_flow_kg_s, p.fuel_kg_s, p.pt_flow_kg_s, p.power_mw, p.heat_rate_kj_kwh
        );
        println!(
            "PR {:.3}, efficiencies: compressor {:.4}, HPT {:.4}, PT {:.4}; surge margin {:.1} %",
            p.pressure_ratio,
            p.compressor_efficiency,
            p.hpt_efficiency,
            p.pt_efficiency,
            p.surge_margin_pct
        );
    }
    Ok(ExitCode::SUCCESS)
}
