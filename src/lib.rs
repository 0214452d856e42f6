//! gtwatch: transient-based gas-path diagnosis for a two-shaft industrial gas turbine.
//!
//! The physics (`thermo`, `maps`, `engine`, `optim`, `diagnosis`) is pure: no I/O, no async,
//! no globals, deterministic for a given seed. The daemon modules (`store`, `ingest`, `detect`,
//! `query`, `cli`) are a thin shell around it.
#![deny(clippy::unwrap_used)]

pub mod acquire;
pub mod advice;
pub mod calibrate;
pub mod chart;
pub mod cli;
pub mod config;
pub mod config_problem;
pub mod daemon;
pub mod demo;
pub mod detect;
pub mod diagnosis;
pub mod engine;
pub mod gap;
pub mod health;
pub mod ingest;
pub mod maps;
pub mod optim;
pub mod permissions;
pub mod plantsim;
pub mod plot;
pub mod quality;
pub mod query;
pub mod recording;
pub mod report;
pub mod segment;
pub mod shutdown;
pub mod signals;
pub mod store;
pub mod thermo;
pub mod time;
pub mod trend;
pub mod wash;
pub mod worker;
