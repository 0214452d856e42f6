//! The text report of `gtwatch calibrate`: the fitted values and why, the residuals per signal
//! and point, the adaptation's curves, its model error in signal and health units, and the
//! leave-one-out validation table. Must not fit, choose or write anything: it only prints what
//! `crate::calibrate` returned.

use crate::calibrate::validate::{Summary, Validation};
use crate::calibrate::Calibration;

/// The adapted model's own errors: per signal (with its profile along the GG speed and where
/// the baseline wants a load more) and in health units.
pub(super) fn print_model_errors(ad: &crate::calibrate::adapt::AdaptReport) {
    let me = &ad.model_error;
    if me.signals.is_empty() {
        println!("  model error: {}", me.note);
    } else {
        let list: Vec<String> = me
            .signals
            .iter()
            .map(|s| format!("{} {:.2} % ({:.1} σ)", s.signal, s.pct, s.rms_sigma))
            .collect();
        println!(
            "  model error on points left out (1σ, % of the value; added to the instrument \
             σ in steady diagnosis and in Method B): {}\n    ({})",
            list.join(", "),
            me.note
        );
        if let Some(t) = &me.by_speed {
            println!(
                "  along the operating line (each speed with its neighbours; a point is \
                 weighted by the error at its own GG speed):"
            );
            let knots: Vec<String> = t.speed_knots.iter().map(|k| format!("{k:>6.3}")).collect();
            println!("    {:<12} {}", "rel. N1 corr", knots.join(" "));
            for (signal, v) in &t.pct {
                let row: Vec<String> = v.iter().map(|p| format!("{p:>6.2}")).collect();
                println!("    {signal:<12} {}", row.join(" "));
            }
        }
        for c in &ad.coverage {
            println!("  baseline coverage: {}", c.describe());
        }
    }
    if let Some(sim) = &ad.similarity {
        println!("  {}", sim.describe());
    }
    if let Some(line) = &ad.operating_line {
        println!("  {}", line.describe());
    }
    for (i, line) in ad.retried.iter().enumerate() {
        println!("  {}{line}", if i == 0 { "" } else { "  " });
    }
    if let Some(line) = &ad.efficiency_tried {
        println!("  {line}");
    }
    let he = &ad.health_error;
    if he.points.is_empty() {
        println!("  model error in health units: {}", he.note);
    } else {
        let list: Vec<String> = he
            .points
            .iter()
            .map(|(k, v)| format!("{k} {v:.2}"))
            .collect();
        println!(
            "  model error in health units (1σ, points; added to each parameter's σ in \
             steady diagnosis): {}\n    ({})",
            list.join(", "),
            he.note
        );
        for p in &he.parts {
            let read: Vec<String> = p
                .health
                .iter()
                .map(|(k, v)| format!("{k} {v:+.2}"))
                .collect();
            let limit = if p.at_limit.is_empty() {
                String::new()
            } else {
                format!("; on its search limit: {}", p.at_limit.join(", "))
            };
            println!(
                "    healthy lines {:?} read {} (fit {}{limit})",
                p.diagnosed_lines,
                read.join(", "),
                p.fit
            );
        }
    }
}

pub(super) fn print_text(report: &Calibration, wall_s: f64) {
    println!(
        "{:<36} {:>12} {:>12} {:>10}  {:<17} why",
        "parameter", "guess", "fitted", "1σ", "status"
    );
    for p in &report.params {
        println!(
            "{:<36} {:>12.6} {:>12.6} {:>10}  {:<17} {}",
            p.key,
            p.guess,
            p.fitted,
            p.sigma.map_or("-".into(), |s| format!("{s:.2e}")),
            p.status,
            p.reason
        );
    }
    println!("\nresiduals per signal (model − measured, in noise σ): mean / RMS");
    for s in &report.signals {
        println!(
            "  {:<10} before {:+7.2} / {:6.2}   after {:+7.2} / {:6.2}",
            s.signal, s.mean_before, s.rms_before, s.mean_after, s.rms_after
        );
    }
    println!("residuals per operating point (RMS, σ)");
    for p in &report.points {
        println!(
            "  {:<40} line {:<5} before {:6.2}   after {:6.2}",
            p.source, p.line, p.rms_before, p.rms_after
        );
    }
    if let Some(pw) = &report.prewash {
        println!();
        for line in pw.describe() {
            println!("{line}");
        }
    }
    println!("\nafter calibration, per signal and point (model − measured, in noise σ):");
    for l in report.table.render().lines() {
        println!("  {l}");
    }
    if let Some(ad) = &report.adaptation {
        println!(
            "\noff-design adaptation ({} curves; fraction of the map's value, 0 at the design \
             speed): RMS {:.2} σ → {:.2} σ",
            ad.strategy, ad.rms_before, ad.rms_after
        );
        if let Some(f) = &ad.fallback {
            println!("  {f}");
        }
        for c in &ad.components {
            let knots: Vec<String> = c.knots.iter().map(|k| format!("{k:.3}")).collect();
            // The HP turbine's knots are in the GG's corrected speed (`SpeedOf`): say so.
            let of = if c.speed_of == crate::engine::config::SpeedOf::GgInlet {
                " (the GG's corrected speed at the compressor inlet)"
            } else {
                ""
            };
            println!(
                "  {:<10} speeds{of} {:.3}…{:.3}  knots [{}]  ({})",
                c.component,
                c.speed_range[0],
                c.speed_range[1],
                knots.join(", "),
                c.knots_reason
            );
            for k in &c.curves {
                let v: Vec<String> = k.values.iter().map(|x| format!("{x:+.4}")).collect();
                println!(
                    "    {:<15} [{}]{}",
                    k.curve,
                    v.join(", "),
                    if k.at_bound {
                        "  AT BOUND: the data want more than the interval allows".to_string()
                    } else if let Some(why) = &k.held {
                        format!("  ({why})")
                    } else {
                        String::new()
                    }
                );
            }
            for (curve, why) in &c.not_fitted {
                println!("    {curve:<15} not fitted: {why}");
            }
        }
        if let Some(c) = ad.calibrated {
            println!(
                "  calibrated on relative corrected GG speeds {:.3}…{:.3} \
                 ([adaptation.calibrated]): a diagnosis leaves out a snapshot beyond them by \
                 more than {}",
                c.gg_speed[0],
                c.gg_speed[1],
                crate::engine::config::CALIBRATED_MARGIN
            );
        }
        print_model_errors(ad);
    }
    for a in &report.assumptions {
        println!("note: {a}");
    }
    if let Some(law) = &report.inlet_loss_law {
        println!("{}", law.summary());
    }
    for d in &report.dropped {
        println!("line {} not used: {}", d.line, d.reason);
    }
    println!(
        "RMS residual {:.2} σ → {:.2} σ ({} LM iteration(s), {} model runs, {:.1} s)",
        report.rms_before, report.rms_after, report.lm_iterations, report.model_runs, wall_s
    );
    println!(
        "baseline fit: {} — {}",
        report.baseline_fit.verdict.as_str(),
        report.baseline_fit.summary
    );
}

/// In the noise's σ, how far a left-out signal must miss to be named as the model's miss rather
/// than the reading's (2: one signal in twenty of pure noise would be named; fewer than that in
/// a table of nine signals at nine points means the model).
const BEYOND_NOISE: f64 = 2.0;

/// Each predicted point's signals that miss by more than [`BEYOND_NOISE`] of their own noise's
/// σ, in words ("line 3 (interior): power_mw +2.35 % (2.6 σ)").
fn beyond_noise(v: &Validation) -> Vec<String> {
    v.points
        .iter()
        .filter(|p| p.failed.is_none())
        .filter_map(|p| {
            let cells: Vec<String> = p
                .errors
                .iter()
                .filter_map(|e| {
                    let z = e.pct / e.noise_pct?;
                    (z.abs() > BEYOND_NOISE)
                        .then(|| format!("{} {:+.2} % ({:.1} σ)", e.signal, e.pct, z.abs()))
                })
                .collect();
            (!cells.is_empty()).then(|| {
                format!(
                    "line {} ({}): {}",
                    p.line,
                    p.position.as_str(),
                    cells.join(", ")
                )
            })
        })
        .collect()
}

/// What a validation summary's points' own noise alone would give, in words ("" without it).
pub(super) fn beside_noise(s: &Summary) -> String {
    match (s.noise_mean_pct, s.noise_rms) {
        (Some(m), Some(r)) => format!(
            "; the rows' own noise alone would give {m:.3} % mean (the errors are {r:.2} of \
             its σ, RMS)"
        ),
        _ => String::new(),
    }
}

/// The `--validate` table: each point left out, its prediction errors, and the summaries (and
/// those of the design values alone, `design_only`, when the calibration adapted).
pub(super) fn print_validation(v: &Validation, design_only: Option<&Validation>, wall_s: f64) {
    println!(
        "\nvalidation: each operating point left out in turn, the calibration run again on the \
         others and the point predicted ((model − measured)/measured, %; {} model runs; {wall_s:.1} s \
         in all)",
        v.model_runs
    );
    if let Some(shape) = v.efficiency_shape {
        println!(
            "  each fold fitted with the turbines' efficiency shaped as the calibration on every \
             point chose (efficiency_shape = \"{shape}\")"
        );
    }
    let signals: Vec<String> = {
        let mut s: Vec<String> = Vec::new();
        for p in &v.points {
            for e in &p.errors {
                if !s.contains(&e.signal) {
                    s.push(e.signal.clone());
                }
            }
        }
        s
    };
    let head: Vec<String> = signals.iter().map(|s| format!("{s:>9}")).collect();
    // `noise %`: the mean |error| the row's own noise alone would give; `noise σ`: the RMS of
    // the errors in that noise's σ (about 1 where the miss is the reading's, not the model's).
    println!(
        "  {:>6} {:>8} {:<9} {:>7} {:>7} {:>7} {:>7}  {}",
        "line",
        "rel. N1",
        "position",
        "mean %",
        "worst %",
        "noise %",
        "noise σ",
        head.join("")
    );
    for p in &v.points {
        let speed = p.gg_speed.map_or("-".into(), |x| format!("{x:.3}"));
        if let Some(why) = &p.failed {
            println!(
                "  {:>6} {:>8} {:<9} not predicted: {why}",
                p.line,
                speed,
                p.position.as_str()
            );
            continue;
        }
        let cells: Vec<String> = signals
            .iter()
            .map(|s| {
                p.errors
                    .iter()
                    .find(|e| &e.signal == s)
                    .map_or(format!("{:>9}", "-"), |e| format!("{:>+9.3}", e.pct))
            })
            .collect();
        let opt = |x: Option<f64>, digits: usize| {
            x.map_or(format!("{:>7}", "-"), |x| format!("{x:>7.digits$}"))
        };
        println!(
            "  {:>6} {:>8} {:<9} {:>7.3} {:>7.3} {} {}  {}",
            p.line,
            speed,
            p.position.as_str(),
            p.mean_abs_pct,
            p.worst_abs_pct,
            opt(p.noise_mean_abs_pct, 3),
            opt(p.noise_rms, 2),
            cells.join("")
        );
    }
    let line = |label: &str, s: &Option<Summary>| match s {
        Some(s) => println!(
            "  {label}: mean |error| {:.3} %, worst {:.3} % ({} point(s)){}",
            s.mean_pct,
            s.worst_pct,
            s.points,
            beside_noise(s)
        ),
        None => println!("  {label}: no point predicted"),
    };
    // A fold's calibration may keep another shape than the whole one's (the continuation in
    // place of a `poor` grown shape): the table then compares two models, and says so.
    let mut shapes: Vec<&str> = v.points.iter().filter_map(|p| p.shape).collect();
    shapes.sort_unstable();
    shapes.dedup();
    if shapes.len() > 1 {
        let which: Vec<String> = shapes
            .iter()
            .map(|shape| {
                let lines: Vec<String> = v
                    .points
                    .iter()
                    .filter(|p| p.shape == Some(*shape))
                    .map(|p| p.line.to_string())
                    .collect();
                format!("{shape} (left out: line {})", lines.join(", "))
            })
            .collect();
        println!(
            "  the folds' calibrations kept different adaptation shapes: {}",
            which.join("; ")
        );
    }
    line("interior points (interpolated)", &v.interior);
    line("every point (extrapolations included)", &v.all);
    let beyond = beyond_noise(v);
    if !beyond.is_empty() {
        println!(
            "  beyond the rows' own noise (a signal more than {BEYOND_NOISE} of its σ off): {}",
            beyond.join("; ")
        );
    }
    if let Some(d) = design_only {
        let per_point: Vec<String> = d
            .points
            .iter()
            .map(|p| match &p.failed {
                None => format!(
                    "line {} {:.2} / {:.2}",
                    p.line, p.mean_abs_pct, p.worst_abs_pct
                ),
                Some(_) => format!("line {} not predicted", p.line),
            })
            .collect();
        println!(
            "  the same with the design values only (no adaptation), mean / worst %: {}",
            per_point.join(", ")
        );
        line("  design values only, interior points", &d.interior);
        line("  design values only, every point", &d.all);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::validate::{LeftOutPoint, Position, SignalError};

    /// A signal is named where it misses by more than [`BEYOND_NOISE`] of its own noise's σ,
    /// whatever the sign; one without a σ, or a failed point, is not.
    #[test]
    fn only_misses_beyond_the_rows_noise_are_named() {
        let e = |signal: &str, pct: f64, noise_pct: Option<f64>| SignalError {
            signal: signal.into(),
            pct,
            noise_pct,
        };
        let point = |line: u64, errors: Vec<SignalError>, failed: Option<String>| LeftOutPoint {
            line,
            source: String::new(),
            gg_speed: Some(0.82),
            position: Position::Interior,
            errors,
            mean_abs_pct: 0.0,
            worst_abs_pct: 0.0,
            worst_signal: String::new(),
            noise_mean_abs_pct: None,
            noise_rms: None,
            failed,
            shape: None,
        };
        let v = Validation {
            points: vec![
                point(
                    3,
                    vec![
                        e("power_mw", 2.35, Some(0.92)),
                        e("n1_rpm", -0.60, Some(0.14)),
                        e("t2_k", 0.5, Some(0.36)),
                        e("p2_kpa", 3.0, None),
                    ],
                    None,
                ),
                point(4, vec![e("t4_k", 0.1, Some(0.4))], None),
                point(5, vec![e("t4_k", 9.0, Some(0.4))], Some("x".into())),
            ],
            interior: None,
            all: None,
            model_runs: 0,
            efficiency_shape: None,
        };
        assert_eq!(
            beyond_noise(&v),
            ["line 3 (interior): power_mw +2.35 % (2.6 σ), n1_rpm -0.60 % (4.3 σ)"]
        );
    }
}
