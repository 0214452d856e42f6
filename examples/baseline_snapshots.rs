//! Writes `examples/baseline_snapshots.csv`: 20 healthy steady snapshots (35–95 % load,
//! ambient 278–298 K, 99.5–101.5 kPa, instrument noise of an average of 25 samples) of an
//! example unit whose design differs from `config/engine.toml` the way a real unit differs from
//! its datasheet (`gtwatch::calibrate::synthetic::example_unit`). The input of the README's
//! "Calibrating to your unit":
//!
//! ```sh
//! cargo run --example baseline_snapshots > examples/baseline_snapshots.csv
//! ```
#![allow(clippy::expect_used)] // an example: a failure ends it with the message

use gtwatch::calibrate::synthetic::{example_unit, load_sweep, snapshot_csv};
use gtwatch::engine::Engine;
use gtwatch::health::HealthParams;

fn main() {
    let file = Engine::reference().expect("reference engine");
    let unit = file
        .with_params(&example_unit(&file).expect("example unit"))
        .expect("example unit");
    let csv = snapshot_csv(
        &unit,
        &HealthParams::HEALTHY,
        &load_sweep(&file, 20),
        "baseline",
        25.0,
        2026,
    )
    .expect("snapshots");
    print!("{csv}");
}
