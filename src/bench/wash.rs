//! `gtwatch bench wash`: the paper's Table 3 (before/after a compressor wash) on synthetic
//! truth, diagnosed by both methods, printed in the paper's layout next to the truth.
//! Must not diagnose anything itself: it prints what `diagnosis::bench::bench_wash` returns.

use crate::diagnosis::bench::{bench_wash, WashRow};
use crate::diagnosis::DiagnosisConfig;
use crate::engine::Engine;

fn line(
    time: &str,
    process: &str,
    m: &std::collections::BTreeMap<String, f64>,
    ratios: Option<(f64, f64)>,
) {
    let g = |k: &str| m.get(k).copied().unwrap_or(f64::NAN);
    let (r1, r2) = match ratios {
        Some((a, b)) => (format!("{a:8.2}"), format!("{b:8.2}")),
        None => ("       -".into(), "       -".into()),
    };
    println!(
        "{time:15} {process:18} {:7.2} {:7.2} {r1} {:7.2} {:7.2} {r2} {:7.2} {:7.2}",
        g("D_GC"),
        g("D_EC"),
        g("D_GT"),
        g("D_ET"),
        g("D_GP"),
        g("D_EP")
    );
}

/// Runs the bench with the optimiser seed `seed` and `cfg`; JSON or the table on stdout.
pub(crate) fn run(
    engine: &Engine,
    cfg: &DiagnosisConfig,
    seed: u64,
    json: bool,
) -> anyhow::Result<()> {
    let rep = bench_wash(engine, seed, cfg)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
        return Ok(());
    }
    println!(
        "{:15} {:18} {:>7} {:>7} {:>8} {:>7} {:>7} {:>8} {:>7} {:>7}",
        "Time", "Process", "D_GC", "D_EC", "GC/EC", "D_GT", "D_ET", "GT/ET", "D_GP", "D_EP"
    );
    let rows: [(&str, &WashRow); 3] = [
        ("Truth", &rep.truth),
        ("Steady-state (A)", &rep.steady),
        ("Transient (B)", &rep.transient),
    ];
    for (t, get) in [
        ("Before washing", 0),
        ("After washing", 1),
        ("Improvement", 2),
    ] {
        for (i, (name, r)) in rows.iter().enumerate() {
            let label = if i == 0 { t } else { "" };
            match get {
                0 => line(label, name, &r.before, None),
                1 => line(label, name, &r.after, None),
                _ => line(
                    label,
                    name,
                    &r.improvement,
                    Some((r.ratio_gc_ec, r.ratio_gt_et)),
                ),
            }
        }
    }
    println!("wall time (s): {:?}", rep.wall_s);
    Ok(())
}
