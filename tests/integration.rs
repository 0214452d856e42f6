//! Every integration test of the project, as modules of one test binary.
//!
//! One binary rather than one per file (Cargo's default), for CI's 2 cores: each of the ~45
//! binaries linked the whole crate, and `cargo test` runs binaries one after another, so a
//! binary with one long test (a gap month, the demo, a Prometheus scrape that mostly waits)
//! left the other core idle. Here libtest's threads take the next test from the whole suite.
//! Run one file's tests with `cargo test --test integration <file>::`.
//!
//! It must not hold tests itself: each concern keeps its own module (file) below.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

mod common;
mod ranking;

mod architecture;
mod archive_tiers;
mod calibrate_ensemble;
mod calibrate_prewash;
mod calibrate_twin;
mod check_config;
mod cli_diagnose;
mod cli_nonsense;
mod daemon_admin_writes;
mod daemon_e2e;
mod daemon_faults;
mod daemon_process;
mod demo;
mod detect_cuts;
mod detector_consistency;
mod detector_on_model;
mod diagnose_segment_readonly;
mod effect_fuel_system;
mod faults_disk_full;
mod faults_modbus_frames;
mod faults_readonly;
mod faults_restart;
mod fleet_rediagnose;
mod fleet_sync;
mod foreign_ambient;
mod foreign_engine;
mod foreign_generator;
mod foreign_season;
mod foreign_simulator;
mod foreign_startups;
mod fuzz_regressions;
mod gap_cli;
mod gap_month;
mod gspy_adaptation;
mod gspy_turboshaft;
mod hot_restart;
mod md22_engine;
mod metrics_prometheus;
mod model_error;
mod permissions_cli;
mod plant_clock;
mod pt_load;
mod replay_cli;
mod replay_history;
mod replay_kill9;
mod replay_local_time;
mod snapshot_idle;
mod snapshot_input_noise;
mod snapshot_md22;
mod worker_kill;
mod writer_kill;
