//! gtwatch: transient-based gas-path diagnosis for a two-shaft industrial gas turbine.
//!
//! The modules form a house of floors (README.md, "Architecture"; checked by
//! `tests/architecture.rs`): the foundations (`thermo`, `maps`, `health`, `signals`, `optim`,
//! and shared plain types such as `quality`, `segment`, `time`), the engine model, what is
//! computed with it (`diagnosis`, `calibrate`, `gap`, `trend`, `wash`), the data floor (`store`,
//! `ingest`, `acquire`, `detect`, …), the services (`worker`, `daemon`, `report`, …), the
//! benchmarks (`bench`) and `cli`.
//! Code refers only to its own floor or below, never to a floor above, and no two modules refer
//! to each other. The physics is pure: no I/O, no async, no globals, deterministic for a given
//! seed. This file only declares the modules; it must not hold code of its own.
#![deny(clippy::unwrap_used)]

pub mod acquire;
pub(crate) mod advice;
pub(crate) mod bench;
pub mod calibrate;
pub(crate) mod chart;
pub mod cli;
pub mod config;
pub(crate) mod config_problem;
pub mod daemon;
pub mod demo;
pub mod detect;
pub mod diagnosis;
pub mod engine;
pub mod fleet;
pub(crate) mod gap;
pub mod health;
pub mod ingest;
pub mod maps;
pub(crate) mod metrics;
pub mod optim;
pub(crate) mod permissions;
pub mod plantsim;
pub mod quality;
pub(crate) mod query;
pub mod recording;
pub(crate) mod report;
pub mod segment;
pub mod shutdown;
pub mod signals;
pub mod store;
pub mod thermo;
pub mod time;
pub mod trend;
pub mod units;
pub mod wash;
pub(crate) mod worker;
