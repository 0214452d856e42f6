//! Whether the first adaptation stands, and what is fitted in its place where it does not: the
//! two checks of what a baseline cannot show (`similarity`, `surge`) on every candidate, the
//! alternatives fitted where the first departs from similarity, and the rule that keeps one.
//!
//! Why a file of its own: the fit (`adapt_shape`) knows nothing of the checks; this decides
//! between fits, each checked against the same file before the adaptation (`before`, solved
//! once for all of them).
//!
//! What it must not do: I/O; change a fit (it runs, checks and chooses).

use super::before::Before;
use super::fitting::within_noise;
use super::{adapt_shape, efficiency_shape, gg_speeds, similarity, surge};
use super::{AdaptReport, AdaptSettings, Ctx};
use super::{CalibrateError, Similarity};
use crate::engine::config::SpeedOf;
use crate::engine::Engine;

/// Adapts `engine` (design values already calibrated) to `points`; `design_keys` are the
/// design values identified before, which stay free beside the curves while they remain
/// identifiable. Returns the report and the adapted engine.
///
/// The steps: the speed ranges the data cover; one knot per component at its furthest speed,
/// keeping the curves the data identify, and its fit; the knots grown while every knot stays
/// identified; the σ of the final knots and the report. Then two checks of what the baseline
/// cannot show, the similarity (`similarity`) and the compressor's operating line
/// (`surge`); where the model departs from similarity the adaptation is run again otherwise
/// (below) and an alternative kept when it fits within noise, stays similar and on the map.
pub fn adapt(
    engine: &Engine,
    design_keys: &[String],
    ctx: Ctx,
) -> Result<(AdaptReport, Engine), CalibrateError> {
    let before = Before::new(engine, ctx.points);
    let (kept, settings) = similar_and_on_map(engine, design_keys, ctx, &before)?;
    let c = Ctx {
        settings: &settings,
        ..ctx
    };
    efficiency_shape::tried(engine, design_keys, c, &before, kept)
}

/// The first adaptation, or the alternative kept where it departs from similarity (module
/// docs), with the settings it was fitted with.
fn similar_and_on_map(
    engine: &Engine,
    design_keys: &[String],
    ctx: Ctx,
    before: &Before,
) -> Result<((AdaptReport, Engine), AdaptSettings), CalibrateError> {
    let first = checked(engine, design_keys, ctx, before)?;
    let departs = first.0.similarity.as_ref().is_some_and(|s| s.departs);
    let off_map = first.0.operating_line.as_ref().is_some_and(|o| o.beyond());
    let hpt_fitted = first
        .0
        .components
        .iter()
        .any(|c| c.component == "hpt" && !c.curves.is_empty());
    let own = ctx.settings.hpt_speed_of == SpeedOf::OwnInlet;
    let mut tries: Vec<AdaptSettings> = Vec::new();
    let relabel =
        off_map && departs && within_noise(first.0.rms_after) && !ctx.settings.relabel_start;
    if relabel {
        // The compressor's curves trade one for another along the healthy line, and from zero
        // the fit can end with the line beyond the map's surge line (the unit of
        // `tests/foreign_ambient.rs`: speed line re-labelled 4 %, flow +41 %, efficiency +15 %,
        // surge margin −10 % where the unit has 26 %), where the flat, extrapolated speed lines
        // make the model depart from similarity (T34/T1 4.72 %, 0.33 % before; its healthy
        // days read up to 2.9 points off). Fitted again from the re-labelling the data show,
        // with the HP turbine's knots in either speed (that unit: 0.57 σ, 0.75 points from
        // similarity beyond the model before, one day `poor`; 0.63 σ, 0.20, days within 0.39
        // points, `good`, kept). Only where the model also departs from similarity: the
        // combinator unit of `tests/foreign_engine.rs` (9 % inside the surge line at its lowest
        // load) runs that load 4–8 % beyond it in its continuation fit, in most fits on 8 of
        // its loads, and with its design point typed to a few digits, similar all the same;
        // there, fitted again on the map, its error in health units grew (0.16 → 0.43–0.44
        // points) and an 8-load fold's prediction of its full load fell from 0.39 to 0.67 %
        // mean, so the check's line is the user's to weigh.
        tries.push(AdaptSettings {
            relabel_start: true,
            ..ctx.settings.clone()
        });
        if own {
            tries.push(AdaptSettings {
                relabel_start: true,
                hpt_speed_of: SpeedOf::GgInlet,
                ..ctx.settings.clone()
            });
        }
    } else if departs && hpt_fitted && own {
        // The HP turbine's curves over its own corrected speed feed back through T3, its
        // inlet temperature, which they set, and can make the adapted model depart from
        // similarity (the unit above fitted from zero: T34/T1 moved 4.72 % between days 50 K
        // apart at one corrected point, 0.33 % before). The baseline cannot tell the two
        // apart, so the HPT's knots go in the GG's corrected speed at the compressor inlet.
        // Only then: on the other units the HPT's own speed gives other figures, not worse
        // fits.
        tries.push(AdaptSettings {
            hpt_speed_of: SpeedOf::GgInlet,
            ..ctx.settings.clone()
        });
    }
    if tries.is_empty() {
        return Ok((first, ctx.settings.clone()));
    }
    let why = if relabel {
        "the first fit put the compressor's healthy operating line beyond its map's surge line \
         and departs from similarity"
    } else {
        "the first fit departs from similarity with the HP turbine's knots in its own \
         corrected speed"
    };
    let mut runs = first.0.model_runs;
    let mut lines: Vec<String> = vec![format!(
        "{why} ({}); fitted again, an alternative is kept when it fits within noise, stays \
         similar and on the map (of those, the one that moves least from similarity)",
        summary(&first.0)
    )];
    let mut best = first;
    let mut kept: Option<usize> = None;
    for (i, settings) in tries.iter().enumerate() {
        let c = Ctx { settings, ..ctx };
        let other = checked(engine, design_keys, c, before)?;
        runs += other.0.model_runs;
        lines.push(format!("{}: {}", describe_try(settings), summary(&other.0)));
        if passes(&other.0) && (kept.is_none() || excess(&other.0) < excess(&best.0)) {
            best = other;
            kept = Some(i);
        }
    }
    for (i, line) in lines.iter_mut().enumerate().skip(1) {
        line.push_str(if kept == Some(i - 1) {
            ": kept"
        } else {
            ": not kept"
        });
    }
    if kept.is_none() {
        lines[0].push_str("; none is, the first fit stands");
    }
    let (mut report, adapted) = best;
    report.model_runs = runs;
    report.retried = lines;
    let settings = kept.map_or_else(|| ctx.settings.clone(), |i| tries[i].clone());
    Ok(((report, adapted), settings))
}

/// An adaptation and its two checks against `before` (`engine` at the same points).
pub(super) fn checked(
    engine: &Engine,
    design_keys: &[String],
    ctx: Ctx,
    before: &Before,
) -> Result<(AdaptReport, Engine), CalibrateError> {
    let (mut report, adapted) = adapt_shape(engine, design_keys, ctx)?;
    if report.components.iter().any(|c| !c.curves.is_empty()) {
        if let Ok(gg) = gg_speeds(&adapted, ctx.points) {
            report.similarity = Some(similarity::check(before, &adapted, ctx.points, &gg));
            report.operating_line = Some(surge::check(before, &adapted, ctx.points, &gg));
        }
    }
    Ok((report, adapted))
}

/// An adaptation's fit and checks in one phrase, for the report.
pub(super) fn summary(r: &AdaptReport) -> String {
    format!(
        "data RMS {:.2} σ; {}; {}",
        r.rms_after,
        r.similarity
            .as_ref()
            .map_or_else(|| "similarity not checked".into(), Similarity::describe),
        r.operating_line
            .as_ref()
            .map_or_else(|| "operating line not checked".into(), |o| o.describe()),
    )
}

/// Whether an alternative adaptation may replace the first: it fits within noise and passes
/// both checks. One that only moves the failure elsewhere does not: on the combinator unit of
/// `tests/foreign_engine.rs` with its 38.75 % load left out, the first fit ran its lowest load
/// 4.9 % beyond the surge line and both alternatives did too; the one a little more similar
/// predicted the load left out at 3.3 % mean where the first predicts 0.3 %.
fn passes(r: &AdaptReport) -> bool {
    within_noise(r.rms_after)
        && r.similarity.as_ref().is_some_and(|s| !s.departs)
        && r.operating_line.as_ref().is_some_and(|o| !o.beyond())
}

/// How far an adaptation moves from similarity beyond the model before it (percentage
/// points): among alternatives that pass, the least is kept.
fn excess(r: &AdaptReport) -> f64 {
    r.similarity
        .as_ref()
        .map_or(f64::INFINITY, Similarity::excess)
}

/// How an alternative was fitted, for the report's steps.
fn describe_try(s: &AdaptSettings) -> String {
    format!(
        "the compressor's speed re-labelling started {}, the HP turbine's knots in {}",
        if s.relabel_start {
            "where the data put the points on the map's speed lines"
        } else {
            "from zero"
        },
        match s.hpt_speed_of {
            SpeedOf::OwnInlet => "its own corrected speed",
            SpeedOf::GgInlet => "the GG's corrected speed at the compressor inlet",
        }
    )
}
