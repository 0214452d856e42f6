//! `gtwatch plant-sim --listen ADDR [--speedup X]`: serve a simulated plant over Modbus TCP
//! with the register map of the configuration file, for tests and commissioning.
//!
//! The plant is the scripted demo schedule (start-ups, steady running, an aborted start, a hot
//! restart, a trip). Must never be pointed at a real control network as if it were the plant.

use crate::config::Config;
use crate::plantsim::{run_plant_sim, ScriptedPlant, SimOptions};
use anyhow::{bail, Context};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct PlantSimArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1:5020")]
    pub listen: SocketAddr,
    /// Configuration whose [modbus] register map is served.
    #[arg(long, default_value = "config/gtwatch.toml")]
    pub config: PathBuf,
    /// Plant frames per frame period of wall time (1 = real time).
    #[arg(long, default_value_t = 1.0)]
    pub speedup: f64,
    /// Plant sample period, ms.
    #[arg(long, default_value_t = 100)]
    pub period_ms: u64,
}

pub fn run(args: PlantSimArgs) -> anyhow::Result<ExitCode> {
    let cfg = Config::load(&args.config)?;
    let Some(map) = cfg.modbus else {
        bail!("{}: no [modbus] section to serve", args.config.display());
    };
    let problems = map.check();
    if !problems.is_empty() {
        let list: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
        bail!("{}: {}", args.config.display(), list.join("; "));
    }
    if !(args.speedup > 0.0 && args.speedup.is_finite()) || args.period_ms == 0 {
        bail!("--speedup must be > 0 and --period-ms ≥ 1");
    }
    let plant = ScriptedPlant::demo(args.period_ms as f64 / 1000.0);
    let opts = SimOptions {
        speedup: args.speedup,
        tick: None,
        lockstep: false,
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    rt.block_on(async move {
        let stop = async {
            let _ = tokio::signal::ctrl_c().await;
        };
        run_plant_sim(args.listen, map, Box::new(plant), opts, stop)
            .await
            .with_context(|| format!("plant-sim on {}", args.listen))
    })?;
    Ok(ExitCode::SUCCESS)
}
