//! `gtwatch bench <kind>`: benchmarks that print JSON. Each kind lives in its own file.
//! Must not hold benchmark logic itself: it dispatches to the kind's file.

use std::process::ExitCode;

#[derive(Debug, clap::Subcommand)]
pub enum BenchCmd {
    /// Replay ingest throughput into SQLite (synthetic CSV in a temporary directory).
    Replay(super::bench_replay::BenchReplayArgs),
    /// Wall time of one complete start-up simulation (median of repeated runs).
    Sim(super::bench_sim::BenchSimArgs),
    /// Diagnosis accuracy on synthetic start-ups with known truth (Method B and Method A).
    Diagnosis(super::bench_diagnosis::BenchDiagnosisArgs),
    /// The paper's Table 3 (before/after a compressor wash) on synthetic truth.
    Wash(super::bench_wash::BenchWashArgs),
    /// A month of 1 Hz plant data replayed: ingest, detection and diagnosis times, accuracy.
    Month(super::bench_month::BenchMonthArgs),
    /// Blind proof of the gap analysis: hidden effects unlike the library's forms.
    Gap(super::bench_gap::BenchGapArgs),
    /// Daemon CPU (live polling of a simulated plant) or memory after a simulated day (--day).
    Daemon(super::bench_daemon::BenchDaemonArgs),
    /// Reliability soak: N days × M tags of 1 Hz data through writer and detector at full
    /// speed; throughput and resident memory per simulated day.
    Soak(super::bench_soak::BenchSoakArgs),
    /// In-process time per off-design steady operating point (median, p90) and Newton
    /// iterations, over a grid across the load range and ambient temperatures.
    Steady(super::bench_steady::BenchSteadyArgs),
}

pub fn run(cmd: BenchCmd) -> anyhow::Result<ExitCode> {
    match cmd {
        BenchCmd::Replay(a) => super::bench_replay::run(a),
        BenchCmd::Sim(a) => super::bench_sim::run(a),
        BenchCmd::Diagnosis(a) => super::bench_diagnosis::run(&a),
        BenchCmd::Wash(a) => super::bench_wash::run(&a),
        BenchCmd::Daemon(a) => super::bench_daemon::run(a),
        BenchCmd::Month(a) => super::bench_month::run(a),
        BenchCmd::Gap(a) => super::bench_gap::run(a),
        BenchCmd::Soak(a) => super::bench_soak::run(a),
        BenchCmd::Steady(a) => super::bench_steady::run(a),
    }
}
