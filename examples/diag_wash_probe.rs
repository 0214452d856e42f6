//! Method B variants on the wash bench's data (seed 1): improvement of the PT parameters.
use gtwatch::diagnosis::bench::{synthetic_startup, wash_truth};
use gtwatch::diagnosis::transient::diagnose_transient;
use gtwatch::diagnosis::DiagnosisConfig;
use gtwatch::engine::Engine;
fn main() {
    let e = Engine::reference().expect("engine");
    let seed: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let (b, a) = wash_truth();
    let sb = synthetic_startup(&e, &b, seed * 2 + 11, true).expect("b");
    let sa = synthetic_startup(&e, &a, seed * 2 + 12, true).expect("a");
    for (rw, smooth) in [(1.0, true), (0.5, true), (0.25, true), (1.0, false)] {
        let cfg = DiagnosisConfig {
            rate_weight: rw,
            smooth_fuel: smooth,
            ..DiagnosisConfig::default()
        };
        let rb = diagnose_transient(&e, &sb, &cfg).expect("b");
        let ra = diagnose_transient(&e, &sa, &cfg).expect("a");
        let eb: Vec<String> = rb
            .health
            .to_array()
            .iter()
            .zip(b.to_array())
            .map(|(x, y)| format!("{:+.3}", x - y))
            .collect();
        let ea: Vec<String> = ra
            .health
            .to_array()
            .iter()
            .zip(a.to_array())
            .map(|(x, y)| format!("{:+.3}", x - y))
            .collect();
        println!(
            "rw {rw} smooth {smooth}: before err {}  after err {}  sigma_EP {:.3}",
            eb.join(" "),
            ea.join(" "),
            rb.sigma["D_EP"]
        );
    }
}
