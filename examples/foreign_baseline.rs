//! Writes the healthy steady baseline of a foreign unit run as a generator: 9 loads from 30 %
//! to 100 % at the file's design PT speed, days from 278 to 298 K and 99 to 102 kPa, each row
//! a 100-s average with instrument noise. The input of the README's "Start-ups on an adapted
//! file" (the same rows as `tests/foreign_startups.rs`):
//!
//! ```sh
//! cargo run --release --example foreign_baseline -- tests/data/foreign/aero25_truth.toml > base.csv
//! ```
#![allow(clippy::expect_used)] // an example: a failure ends it with the message

use gtwatch::calibrate::synthetic::generator_baseline_csv;
use gtwatch::engine::{Engine, EngineConfig};
use std::path::PathBuf;

fn main() {
    let path = PathBuf::from(
        std::env::args()
            .nth(1)
            .expect("usage: foreign_baseline ENGINE.toml"),
    );
    let truth =
        Engine::new(EngineConfig::load(&path).expect("engine file loads")).expect("engine builds");
    print!("{}", generator_baseline_csv(&truth, 7).expect("snapshots"));
}
