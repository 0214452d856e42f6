//! The acquisition task: the Modbus poll loop (`acquire::modbus::poll_loop`) sending samples
//! and gaps to the writer over the bounded channel, until shutdown. A full channel makes the
//! loop wait (counted and logged by the `WriterHandle`): no sample is dropped for it. Only
//! built when `[acquisition] source = "modbus"` and a register map is configured. Must not
//! touch the database (the writer owns it) or hold polling logic of its own.

use super::DaemonError;
use crate::acquire::modbus::SourceKind;
use crate::acquire::modbus::{poll_loop, AcquisitionConfig, PollPlan, PollProgress, PollStats};
use crate::config::Config;
use crate::shutdown::Shutdown;
use crate::store::{TagId, WriterHandle};
use std::sync::Arc;

/// The acquisition task (mini-redis shape: a small struct with its own `run`).
pub struct AcquisitionTask {
    cfg: AcquisitionConfig,
    plan: PollPlan,
    tx: WriterHandle,
    progress: Arc<PollProgress>,
}

impl AcquisitionTask {
    /// The task for `cfg`, or `None` when nothing is polled. `tags` are the register map's
    /// tag ids in map order. The task owns `tx`: the writer ends once the task has ended (or
    /// at once when there is none).
    pub fn from_config(
        cfg: &Config,
        tags: &[TagId],
        tx: WriterHandle,
        progress: Arc<PollProgress>,
    ) -> Result<Option<AcquisitionTask>, DaemonError> {
        let (Some(map), SourceKind::Modbus) = (&cfg.modbus, cfg.acquisition.source) else {
            return Ok(None);
        };
        let mut plan = PollPlan::new(map, tags).map_err(DaemonError::Plan)?;
        plan.quality = cfg.quality.clone();
        Ok(Some(AcquisitionTask {
            cfg: cfg.acquisition.clone(),
            plan,
            tx,
            progress,
        }))
    }

    /// Polls until shutdown; returns the poll loop's tallies.
    pub async fn run(self, shutdown: Shutdown) -> PollStats {
        poll_loop(&self.cfg, &self.plan, self.tx, self.progress, shutdown).await
    }
}
