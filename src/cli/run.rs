//! `gtwatch run --config FILE`: the monitoring daemon (see `crate::daemon`).
//!
//! Maps SIGTERM/SIGINT onto the daemon's shutdown value and reports what was done at exit.
//! Must not hold daemon logic.

use crate::config::Config;
use crate::daemon::{self, RunOptions};
use crate::shutdown::shutdown_channel;
use crate::worker::WorkerContext;
use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Configuration file.
    #[arg(long, default_value = "/etc/gtwatch/gtwatch.toml")]
    pub config: PathBuf,
}

/// Completes on the first SIGTERM or SIGINT.
async fn termination_signal() -> std::io::Result<()> {
    use tokio::signal::unix::{signal, SignalKind};
    let mut term = signal(SignalKind::terminate())?;
    let mut int = signal(SignalKind::interrupt())?;
    tokio::select! {
        _ = term.recv() => tracing::info!("SIGTERM received"),
        _ = int.recv() => tracing::info!("SIGINT received"),
    }
    Ok(())
}

/// Refuses paths other users could write (see `crate::permissions`); warns on group-writable.
fn refuse_unsafe_permissions(config: &std::path::Path, cfg: &Config) -> anyhow::Result<()> {
    use crate::permissions::{check_daemon_paths, current_uid, Severity};
    let findings = check_daemon_paths(
        config,
        cfg.plant.engine_model.as_deref(),
        &cfg.storage.path,
        current_uid(),
    );
    let mut refused = Vec::new();
    for f in findings {
        match f.severity {
            Severity::Warning => tracing::warn!("{f}"),
            Severity::Refuse => refused.push(f.to_string()),
        }
    }
    if refused.is_empty() {
        Ok(())
    } else {
        anyhow::bail!(
            "refusing to start: {} (the daemon trusts these paths; another user able to write them could redirect acquisition or rewrite the history)",
            refused.join("; ")
        )
    }
}

pub(super) fn run(args: RunArgs) -> anyhow::Result<ExitCode> {
    let cfg = Config::load_checked(&args.config)?;
    refuse_unsafe_permissions(&args.config, &cfg)?;
    let worker = if cfg.diagnosis.enabled {
        Some(std::sync::Arc::new(WorkerContext::load(
            cfg.plant.engine_model.as_deref(),
            cfg.diagnosis.clone(),
        )?))
    } else {
        None
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    rt.block_on(async move {
        let (trigger, shutdown) = shutdown_channel();
        tokio::spawn(async move {
            if let Err(e) = termination_signal().await {
                tracing::error!("cannot listen for signals: {e}");
                return;
            }
            trigger.trigger();
        });
        let report = daemon::run(
            cfg,
            shutdown,
            RunOptions {
                systemd_notify: true,
                progress: None,
                worker,
                after_result: None,
                compaction_timing: None,
            },
        )
        .await?;
        tracing::info!(
            polls = report.poll.polls_ok,
            failures = report.poll.failures,
            gaps = report.poll.gaps,
            samples_inserted = report.writer.samples_inserted,
            "stopped"
        );
        Ok(ExitCode::SUCCESS)
    })
}
