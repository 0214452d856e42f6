//! `gtwatch plant-sim --listen ADDR [--speedup X]`: serve a simulated plant over Modbus TCP
//! with the register map of the configuration file, for tests and commissioning.
//!
//! The plant is the engine model (default: start-ups, base load, normal stops, an aborted start and
//! a hot restart, with sensor lags and noise), or the light scripted schedule (`--source scripted`).
//! Must never be pointed at a real control network as if it were the plant.

use crate::config::Config;
use crate::plantsim::{run_plant_sim, ModelPlant, PlantModel, ScriptedPlant, SimOptions};
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
    /// What produces the plant's values.
    #[arg(long, value_enum, default_value = "model")]
    pub source: Source,
    #[command(flatten)]
    pub engine: super::engine_args::EngineArgs,
    /// Seed of the sensor noise (model source).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Source {
    /// The dynamic engine model (REFERENCE §2 sequence) with sensor lags and noise.
    Model,
    /// Piecewise-linear scripted start-ups (fast, for detector tests).
    Scripted,
}

pub(super) fn run(args: PlantSimArgs) -> anyhow::Result<ExitCode> {
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
    let period_s = args.period_ms as f64 / 1000.0;
    let plant: Box<dyn PlantModel> = match args.source {
        Source::Scripted => Box::new(ScriptedPlant::demo(period_s)),
        Source::Model => {
            let (engine, health) = args.engine.load()?;
            // 400 cycles of the ≈ 1 h 20 min operations schedule: three weeks of plant.
            let model = crate::engine::plant::SimulatedPlant::new(
                &engine, &health, period_s, 400, args.seed,
            )?;
            Box::new(ModelPlant::new(model))
        }
    };
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
        run_plant_sim(args.listen, map, plant, opts, stop)
            .await
            .with_context(|| format!("plant-sim on {}", args.listen))
    })?;
    Ok(ExitCode::SUCCESS)
}
