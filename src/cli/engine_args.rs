//! Arguments shared by the engine-model commands (engine file, health vector).
//! Must not run the model: it only parses and loads.

use crate::engine::{Engine, EngineConfig};
use crate::health::HealthParams;
use anyhow::Context;
use std::path::PathBuf;

#[derive(Debug, Clone, clap::Args)]
pub struct EngineArgs {
    /// Engine description (TOML); default: the built-in reference engine (config/engine.toml).
    #[arg(long, value_name = "FILE")]
    pub engine: Option<PathBuf>,
    /// Health vector in percent, e.g. D_GC=3,D_EC=1 (unnamed parameters are 0).
    #[arg(long, value_name = "D_GC=…,D_EC=…", default_value = "")]
    pub health: String,
}

impl EngineArgs {
    pub fn engine(&self) -> anyhow::Result<Engine> {
        let cfg = EngineConfig::load_or_reference(self.engine.as_deref())?;
        Engine::new(cfg).context("building the engine model")
    }

    pub fn health(&self) -> anyhow::Result<HealthParams> {
        self.health.parse::<HealthParams>().context("--health")
    }

    /// The engine and the health vector the flags name (the engine first: its error is the
    /// one reported when both are wrong). The preamble of every model command.
    pub fn load(&self) -> anyhow::Result<(Engine, HealthParams)> {
        let engine = self.engine()?;
        Ok((engine, self.health()?))
    }
}
