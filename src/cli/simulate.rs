//! `gtwatch simulate`: a start-up (or a day of operations) on the engine model, as CSV and SVG.
//! Must not open the database: it writes the CSV and SVG it is asked for and nothing else.

use super::engine_args::EngineArgs;
use crate::engine::sensors::MeasurementOptions;
use crate::engine::simulation::{run_scenario_observed, TruthSample};
use crate::engine::{Scenario, Trace};
use anyhow::Context;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// How often a long simulation says how far it has come (wall time).
const PROGRESS_EVERY: Duration = Duration::from_secs(10);

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ScenarioKind {
    /// REFERENCE §2 start-up from standstill to steady base load.
    Startup,
    /// Start, base load, normal stop, an aborted start (trip), then a hot restart to base load.
    Operations,
}

#[derive(Debug, clap::Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub engine: EngineArgs,
    #[arg(long, value_enum, default_value = "startup")]
    pub scenario: ScenarioKind,
    /// Add the default sensor noise (seeded).
    #[arg(long)]
    pub noise: bool,
    /// Add the configured sensor biases.
    #[arg(long)]
    pub bias: bool,
    /// Report instantaneous values (no sensor lags).
    #[arg(long)]
    pub no_lags: bool,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output CSV ("-" for standard output).
    #[arg(long, value_name = "FILE.csv", default_value = "-")]
    pub out: String,
    /// Also draw the traces as SVG.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
}

pub(super) fn run(a: SimulateArgs) -> anyhow::Result<ExitCode> {
    let (engine, health) = a.engine.load()?;
    let model = engine.model(&health);
    let scenario = match a.scenario {
        ScenarioKind::Startup => Scenario::startup(engine.cfg()),
        ScenarioKind::Operations => Scenario::operations(engine.cfg()),
    };
    // A stiff engine file can integrate for minutes (a start-up that hangs runs to the
    // scenario's time limit): say how far it has come rather than nothing.
    let started = Instant::now();
    let mut next_report = PROGRESS_EVERY;
    // The samples as they come, so that a run the integrator gives up on still leaves its trace
    // up to the failure (where it went wrong is what the user needs to see).
    let mut so_far: Vec<TruthSample> = Vec::new();
    let run = run_scenario_observed(&model, &scenario, |s| {
        so_far.push(*s);
        let wall = started.elapsed();
        if wall >= next_report {
            next_report = wall + PROGRESS_EVERY;
            tracing::info!(
                "simulating: t = {:.0} s, {} (GG {:.0} rpm, PT {:.0} rpm) after {:.0} s",
                s.t_s,
                s.phase,
                s.stations.n1_rpm,
                s.stations.n2_rpm,
                wall.as_secs_f64()
            );
        }
    });
    // `so_far` holds every sample the run produced, those it returns on success included.
    let (stats, failure) = match run {
        Ok((_, stats)) => (Some(stats), None),
        Err(e) => (None, Some(e)),
    };
    let samples = so_far;
    let meas = (!a.no_lags || a.noise || a.bias).then_some(MeasurementOptions {
        lags: !a.no_lags,
        noise: a.noise,
        bias: a.bias,
        seed: a.seed,
    });
    let trace = Trace::from_truth(&engine, &samples, meas.as_ref());
    if a.out == "-" {
        let stdout = std::io::stdout();
        trace.write_csv(stdout.lock())?;
    } else {
        let f = std::fs::File::create(&a.out).with_context(|| format!("creating {}", a.out))?;
        let mut w = std::io::BufWriter::new(f);
        trace.write_csv(&mut w)?;
        w.flush()?;
        match &stats {
            Some(stats) => tracing::info!(
                "wrote {} samples ({:.0} s simulated, {} steps) to {}",
                trace.len(),
                trace.t_s.last().copied().unwrap_or(0.0),
                stats.steps,
                a.out
            ),
            None => tracing::info!(
                "wrote the {} samples before the failure ({:.0} s simulated) to {}",
                trace.len(),
                trace.t_s.last().copied().unwrap_or(0.0),
                a.out
            ),
        }
    }
    // A start that hangs runs to the scenario's time limit without an error of the integrator:
    // say where it stuck (the trace is written above, to look at).
    let stuck = match a.scenario {
        ScenarioKind::Startup => crate::engine::start_outcome::stuck_start(engine.cfg(), &samples),
        ScenarioKind::Operations => None,
    };
    if let Some(path) = a.plot {
        let degraded: Vec<String> = crate::health::HEALTH_NAMES
            .iter()
            .zip(health.to_array())
            .filter(|(_, v)| *v != 0.0)
            .map(|(n, v)| format!("{n}={v}"))
            .collect();
        let health_text = if degraded.is_empty() {
            "healthy".to_string()
        } else {
            degraded.join(", ")
        };
        let title = format!("{} — {:?}, {health_text}", engine.cfg().name, a.scenario);
        let svg = crate::chart::startup::startup_svg(&trace, &title);
        std::fs::write(&path, svg).with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(e) = failure {
        return Err(anyhow::Error::new(e).context(
            "the simulation stopped (the trace up to the failure was written, to look at)",
        ));
    }
    if let Some(stuck) = stuck {
        anyhow::bail!("{stuck} (the trace was written, to look at)");
    }
    Ok(ExitCode::SUCCESS)
}
