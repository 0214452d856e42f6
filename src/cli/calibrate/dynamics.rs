//! `gtwatch calibrate --dynamics`: the thermocouples' lags and the rotors' inertias fitted to
//! the `--startup` recordings after the steady calibration (`calibrate::dynamics`), printed,
//! named in the written file's header and written where the start-ups determine them.
//! Must not fit anything the steady calibration owns.

use super::CalibrateArgs;
use crate::calibrate::dynamics::{dynamic_candidates, fit_dynamics, DynamicsFit};
use crate::diagnosis::DiagnosisConfig;
use crate::engine::Engine;
use crate::health::HEALTH_NAMES;
use crate::recording::Recording;
use anyhow::Context;

/// With `--dynamics`, the fit on the calibrated `engine` of the start-ups `recordings` (each
/// with its source's name); `None` without it.
pub(super) fn fit(
    a: &CalibrateArgs,
    engine: &Engine,
    recordings: &[(String, Recording)],
) -> anyhow::Result<Option<DynamicsFit>> {
    if !a.dynamics {
        return Ok(None);
    }
    let recs: Vec<Recording> = recordings.iter().map(|(_, r)| r.clone()).collect();
    let sources: Vec<String> = recordings.iter().map(|(s, _)| s.clone()).collect();
    let candidates = dynamic_candidates(engine, &recs).context("--dynamics")?;
    // The worker's own settings (seed, budget), on the calibration's threads.
    let base = DiagnosisConfig {
        threads: a.threads,
        ..DiagnosisConfig::default()
    };
    Ok(Some(
        fit_dynamics(engine, &recs, &sources, &candidates, &base).context("--dynamics")?,
    ))
}

/// The line the written file's header carries.
pub(super) fn header_line(fit: &DynamicsFit) -> String {
    let written: Vec<String> = fit
        .values
        .iter()
        .filter(|v| v.written)
        .map(|v| format!("{} {:.3} → {:.3}", v.key, v.before, v.value))
        .collect();
    format!(
        "  dynamics fitted to {} healthy start-up(s) (--dynamics, health held at zero): {}",
        fit.startups.len(),
        if written.is_empty() {
            "none determined, the file's kept".to_string()
        } else {
            written.join(", ")
        }
    )
}

/// The text report.
pub(super) fn print(fit: &DynamicsFit) {
    println!(
        "\ndynamics (--dynamics): Method B on {} healthy start-up(s), health held at zero, \
         {:.1} s",
        fit.startups.len(),
        fit.wall_s
    );
    println!(
        "  {:28} {:>9} {:>9} {:>8} {:>8}  written",
        "value", "file", "fitted", "1σ", "scatter"
    );
    for v in &fit.values {
        println!(
            "  {:28} {:9.3} {:9.3} {:8.3} {:>8}  {}",
            v.key,
            v.before,
            v.value,
            v.sigma,
            v.scatter.map_or("-".into(), |s| format!("{s:.2}")),
            if v.written { "yes" } else { v.why.as_str() }
        );
    }
    for (source, why) in &fit.left_out {
        println!("  left out: {source}: {why}");
    }
    println!(
        "  each start-up diagnosed (health free; truth zero) with the file's values → the \
         written ones:"
    );
    for s in &fit.startups {
        let show = |h: &[f64; 6]| {
            HEALTH_NAMES
                .iter()
                .zip(h)
                .map(|(n, v)| format!("{n} {v:+.2}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        println!("  {}", s.source);
        println!(
            "    before: {} ({}, {:.2})",
            show(&s.before.health),
            s.before.verdict.as_str(),
            s.before.normalised_residual
        );
        println!(
            "    after:  {} ({}, {:.2})",
            show(&s.after.health),
            s.after.verdict.as_str(),
            s.after.normalised_residual
        );
    }
}
