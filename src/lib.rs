//! gtwatch: transient-based gas-path diagnosis for a two-shaft industrial gas turbine.
//!
//! The physics (`thermo`, `maps`, `engine`, `optim`, `diagnosis`) is pure: no I/O, no async,
//! no globals, deterministic for a given seed. The daemon modules are a thin async shell.
#![deny(clippy::unwrap_used)]

pub mod cli;
pub mod diagnosis;
pub mod engine;
pub mod health;
pub mod maps;
pub mod optim;
pub mod signals;
pub mod thermo;
