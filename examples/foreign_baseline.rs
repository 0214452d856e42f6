//! Writes the healthy steady baseline of a foreign unit run as a generator: 9 loads from 30 %
//! to 100 % at the file's design PT speed, days from 278 to 298 K and 99 to 102 kPa, each row
//! a 100-s average with instrument noise. The input of the README's "Start-ups on an adapted
//! file" (the same rows as `tests/foreign_startups.rs`):
//!
//! ```sh
//! cargo run --release --example foreign_baseline -- tests/data/foreign/aero25_truth.toml > base.csv
//! ```
//!
//! With `--before-wash D_GC,D_EC` the same loads on other days follow, the compressor fouled
//! by that much, in group `before_wash` (the baseline's rows are group `baseline`, column
//! `test`): the input of `calibrate --group-by test --prewash-group before_wash` (README, "Rows
//! from before a wash").
#![allow(clippy::expect_used)] // an example: a failure ends it with the message

use gtwatch::calibrate::synthetic::{generator_baseline_csv, generator_rows_csv};
use gtwatch::engine::{Engine, EngineConfig};
use gtwatch::health::HealthParams;
use std::path::PathBuf;

const USAGE: &str = "usage: foreign_baseline ENGINE.toml [--before-wash D_GC,D_EC]";

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = PathBuf::from(args.first().expect(USAGE));
    let fouling: Option<[f64; 2]> = match args.get(1).map(String::as_str) {
        None => None,
        Some("--before-wash") => {
            let v: Vec<f64> = args
                .get(2)
                .expect(USAGE)
                .split(',')
                .map(|x| x.trim().parse().expect("D_GC,D_EC: two numbers, points"))
                .collect();
            match v[..] {
                [d_gc, d_ec] => Some([d_gc, d_ec]),
                _ => {
                    eprintln!("--before-wash takes two numbers, D_GC,D_EC: {USAGE}");
                    std::process::exit(2);
                }
            }
        }
        Some(other) => {
            eprintln!("{other}: {USAGE}");
            std::process::exit(2);
        }
    };
    let truth =
        Engine::new(EngineConfig::load(&path).expect("engine file loads")).expect("engine builds");
    print!("{}", generator_baseline_csv(&truth, 7).expect("snapshots"));
    if let Some([d_gc, d_ec]) = fouling {
        let health = HealthParams::from_array([d_gc, d_ec, 0.0, 0.0, 0.0, 0.0]);
        let rows = generator_rows_csv(&truth, &health, "before_wash", 8, 7).expect("snapshots");
        // One header for the file.
        for line in rows.lines().skip(1) {
            println!("{line}");
        }
    }
}
