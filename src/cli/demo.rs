//! `gtwatch demo [--days N] [--speedup X] [--seed S] [--out DIR] [--json]`: the whole product on
//! an embedded default (see `crate::demo`), with progress on stderr and, at the end, the trend
//! table against the implanted truth, the washes found and the wash advice.
//!
//! Must not hold demo logic: it parses flags, prints events and the final report.

use crate::demo::{run_demo, DemoEvent, DemoOptions, DemoReport};
use crate::health::HEALTH_NAMES;
use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// Plant days to run, one start-up each (an offline wash falls before the middle day).
    #[arg(long, default_value_t = 10)]
    pub days: usize,
    /// Plant seconds per wall second while the engine runs (idle hours pass faster still).
    #[arg(long, default_value_t = 500.0)]
    pub speedup: f64,
    /// Seed of the sensor noise and the diagnosis.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output folder: database, the configuration used, the report.
    #[arg(long, default_value = "gtwatch-demo")]
    pub out: PathBuf,
    /// Give up after this many wall seconds and report what was diagnosed.
    #[arg(long, default_value_t = 600)]
    pub timeout_s: u64,
    /// Print the final report as one JSON document (progress still goes to stderr).
    #[arg(long)]
    pub json: bool,
}

pub(super) fn run(a: DemoArgs) -> anyhow::Result<ExitCode> {
    let opts = DemoOptions {
        days: a.days,
        seed: a.seed,
        out_dir: a.out.clone(),
        speedup: a.speedup,
        timeout: Duration::from_secs(a.timeout_s),
        ..DemoOptions::default()
    };
    eprintln!(
        "gtwatch demo: {} plant days, one start-up a day, compressor fouling with an offline wash \
         midway; plant-sim on 127.0.0.1 → daemon → {}",
        opts.days,
        opts.out_dir.join("gtwatch.db").display()
    );
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    let report = rt.block_on(run_demo(&opts, |e| match e {
        DemoEvent::PlantDay(d) => eprintln!("  plant: day {}/{}", d + 1, opts.days),
        DemoEvent::Startup {
            day,
            segment_id,
            outcome,
        } => eprintln!(
            "  day {}: start-up found (segment {segment_id}, {outcome})",
            day + 1
        ),
        DemoEvent::Diagnosed {
            day,
            d_gc,
            truth_gc,
            fit_quality,
        } => eprintln!(
            "  day {}: diagnosed D_GC {d_gc:.2} % (truth {truth_gc:.2}), fit {fit_quality}",
            day + 1
        ),
    }))?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render(&report));
    }
    Ok(if report.complete {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// The human-readable summary.
fn render(r: &DemoReport) -> String {
    let mut s = String::new();
    s.push_str("\nDegradation trend, Method B (transient) against the implanted truth, percent:\n");
    s.push_str(&format!("{:>4} {:<11}", "day", "start (UTC)"));
    for n in HEALTH_NAMES {
        s.push_str(&format!(" {:>14}", format!("{n} est/true")));
    }
    s.push_str("  fit\n");
    for d in &r.days {
        let date = d.start_utc.get(..10).unwrap_or(&d.start_utc);
        s.push_str(&format!("{:>4} {:<11}", d.day + 1, date));
        let truth = d.truth.to_array();
        for (i, n) in HEALTH_NAMES.iter().enumerate() {
            let est = d
                .method_b
                .as_ref()
                .and_then(|b| b.health.get(*n))
                .map_or("-".to_string(), |v| format!("{v:.2}"));
            s.push_str(&format!(" {:>14}", format!("{est}/{:.2}", truth[i])));
        }
        let fit = d
            .method_b
            .as_ref()
            .and_then(|b| b.fit_quality.clone())
            .unwrap_or_else(|| d.undiagnosable.join("; "));
        let wash = if d.washed_before {
            "  ← after offline wash"
        } else {
            ""
        };
        s.push_str(&format!("  {fit}{wash}\n"));
    }
    let worst = r
        .days
        .iter()
        .filter_map(|d| d.max_error_b())
        .fold(0.0f64, f64::max);
    s.push_str(&format!(
        "largest error over all days and parameters: {worst:.2} points\n"
    ));
    s.push_str("\nWashes in the database:\n");
    if r.washes.is_empty() {
        s.push_str("  none\n");
    }
    for w in &r.washes {
        s.push_str(&format!(
            "  {} {} wash{}{}\n",
            w.t_utc,
            w.kind,
            if w.detected {
                ", detected in the D_GC/D_EC trend"
            } else {
                ", recorded"
            },
            w.before_day
                .map(|d| format!(", before day {}'s start-up", d + 1))
                .unwrap_or_default()
        ));
    }
    if let Some(d) = r.wash_day {
        s.push_str(&format!(
            "  (truth: an offline wash before day {}'s start-up)\n",
            d + 1
        ));
    }
    s.push_str("\nWash advice:\n");
    match &r.advice {
        Some(a) => s.push_str(&format!("  {}\n", a.message)),
        None => s.push_str("  none stored\n"),
    }
    s.push_str(&format!(
        "\n{} in {:.0} s ({} polls, {} failed). Database: {}\nReport: {}\nTry: gtwatch history --config {}\n     gtwatch wash advise --config {}\n",
        if r.complete { "Done" } else { "Stopped before every day was diagnosed" },
        r.wall_s,
        r.poll.polls_ok,
        r.poll.failures,
        r.db_path.display(),
        r.report_path.display(),
        r.config_path.display(),
        r.config_path.display(),
    ));
    s
}
