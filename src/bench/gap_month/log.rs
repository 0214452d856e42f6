//! The logs and configurations of `gtwatch bench gap-month`: the faulty and the clean month's
//! CSV logs written from one plant run (the meter error applied to the recorded fuel column
//! only, the poor day's effect in the plant), and the replay configuration with or without the
//! gap settings. Must not replay or judge anything (the parent module does).

use super::{BenchGapMonthArgs, EPOCH_MS};
use crate::bench::month::{create_log, log_columns};
use crate::engine::effects::{EffectParams, EffectSet};
use crate::engine::Engine;
use crate::plantsim::fouling::DAY_S;
use crate::plantsim::{FoulingPlant, FoulingSchedule, PlantModel};
use crate::signals::Signal;
use crate::time::fmt_ms;
use anyhow::{ensure, Context};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

/// The poor start-up's effect as an `[effects]` section.
fn poor_effects(name: &str, params: &[String]) -> anyhow::Result<EffectSet> {
    let mut given = EffectParams::new();
    for p in params.iter().filter(|p| !p.is_empty()) {
        let (k, v) = p
            .split_once('=')
            .with_context(|| format!("--poor-params: {p:?} is not key=value"))?;
        let v: f64 = v
            .trim()
            .parse()
            .with_context(|| format!("--poor-params: {p:?}"))?;
        given.insert(k.trim().to_string(), v);
    }
    let section = BTreeMap::from([(name.to_string(), given)]);
    EffectSet::from_section(&section).map_err(|e| anyhow::anyhow!("--poor-effect {name}: {e}"))
}

/// Writes the faulty and the clean log from one run of the plant; returns the rows per log.
pub(super) fn write_logs(
    a: &BenchGapMonthArgs,
    engine: &Engine,
    schedule: &FoulingSchedule,
    meter_from: usize,
    poor_day: usize,
    faulty: &Path,
    clean: &Path,
) -> anyhow::Result<u64> {
    let mut plant = FoulingPlant::new(engine, schedule.clone(), a.seed, EPOCH_MS)?
        .with_idle_step(a.idle_step)
        .with_effects_on_day(poor_day, poor_effects(&a.poor_effect, &a.poor_params)?);
    let cols = log_columns();
    let (mut wf, mut wc) = (create_log(faulty, &cols)?, create_log(clean, &cols)?);
    let end_s = a.days as f64 * DAY_S;
    let mut rows = 0u64;
    loop {
        let f = plant.step();
        if f.t_s >= end_s {
            break;
        }
        let t = fmt_ms(EPOCH_MS + (f.t_s * 1000.0).round() as i64);
        let wrong = (f.t_s / DAY_S).floor() as usize >= meter_from;
        write!(wf, "{t}")?;
        write!(wc, "{t}")?;
        for s in &cols {
            let v = f.get(*s);
            // The meter's error is in the record, not in the engine: only the column changes.
            let recorded = if wrong && *s == Signal::FuelFlow {
                v * a.meter_scale
            } else {
                v
            };
            write!(wf, ",{recorded:.4}")?;
            write!(wc, ",{v:.4}")?;
        }
        writeln!(wf)?;
        writeln!(wc)?;
        rows += 1;
    }
    wf.flush()?;
    wc.flush()?;
    Ok(rows)
}

/// The shipped configuration pointed at `db`, with the bench's budget and, unless `gap`, the
/// gap settings off.
pub(super) fn config_text(a: &BenchGapMonthArgs, db: &Path, gap: bool) -> anyhow::Result<String> {
    let mut text = include_str!("../../../config/gtwatch.toml").to_string();
    let mut set = |from: &str, to: &str| -> anyhow::Result<()> {
        ensure!(
            text.contains(from),
            "the shipped configuration has no line {from:?}"
        );
        text = text.replacen(from, to, 1);
        Ok(())
    };
    set(
        "path = \"/var/lib/gtwatch/gtwatch.db\"",
        &format!("path = \"{}\"", db.display()),
    )?;
    if let Some(n) = a.threads {
        set("threads = 1", &format!("threads = {n}"))?;
    }
    if let Some(n) = a.max_model_runs {
        set("max_model_runs = 400", &format!("max_model_runs = {n}"))?;
    }
    if !gap {
        set("gap_on_poor_fit = true", "gap_on_poor_fit = false")?;
        set("gap_on_health_step = true", "gap_on_health_step = false")?;
    }
    Ok(text)
}
