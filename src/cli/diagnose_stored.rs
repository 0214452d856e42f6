//! Diagnosis of stored start-ups from the command line: the worker run after `gtwatch replay`,
//! and `gtwatch diagnose --segment ID` (re-runs one stored segment, prints, stores nothing).
//!
//! Reads `[plant] engine_model` and `[diagnosis]` from the config file; the work itself is
//! `crate::worker`. Must not hold diagnosis logic.

use crate::optim::Cancel;
use crate::store::Store;
use crate::worker::gap::{self, AfterReplay};
use crate::worker::{
    assess_segment, drain_pending, failures, new_diagnoses, read_segment, DiagnosisSettings,
    WorkerContext,
};
use anyhow::{bail, Context};
use std::path::Path;

/// The worker's context from a config file (`None`: built-in engine, default settings).
pub(super) fn worker_context(config: Option<&Path>) -> anyhow::Result<WorkerContext> {
    let Some(path) = config else {
        return WorkerContext::load(None, DiagnosisSettings::default());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading config {}", path.display()))?;
    let table: toml::Table =
        toml::from_str(&text).with_context(|| format!("config {}", path.display()))?;
    let settings: DiagnosisSettings = match table.get("diagnosis") {
        Some(v) => v
            .clone()
            .try_into()
            .with_context(|| format!("config {}: [diagnosis]", path.display()))?,
        None => DiagnosisSettings::default(),
    };
    let problems = settings.validate();
    if !problems.is_empty() {
        let list: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
        bail!("config {}:\n  {}", path.display(), list.join("\n  "));
    }
    let engine = super::common::engine_model_path(&table, path);
    WorkerContext::load(engine.as_deref(), settings)
}

/// After a replay: diagnose every pending start-up (unless `[diagnosis] enabled = false`), then
/// ask the gap question of the start-ups the daemon's gap task would pick (`gap_on_poor_fit`,
/// `gap_on_health_step`, `gap_every_n`; `worker::gap` selects), then refresh the wash advice so a
/// step an instrument explains is attributed to it. The gap analyses start only once the
/// diagnosis queue is empty, as in the daemon, so they never delay a diagnosis. The summary goes
/// to stderr with `--json` (stdout holds the JSON report).
pub(super) fn diagnose_after_replay(
    store: &mut Store,
    config: &Path,
    json: bool,
) -> anyhow::Result<AfterReplay> {
    let ctx = worker_context(Some(config))?;
    let mut out = AfterReplay::default();
    if !ctx.settings.enabled {
        return Ok(out);
    }
    let say = |line: String| {
        if json {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
    };
    if !store.pending_segments()?.is_empty() {
        let t = std::time::Instant::now();
        let rep = drain_pending(store, &ctx, &Cancel::new(), None).context("diagnosis")?;
        out.diagnosed = rep.diagnosed;
        out.undiagnosable = rep.undiagnosable;
        out.diagnose_s = t.elapsed().as_secs_f64();
        say(format!(
            "diagnosis: {} start-ups diagnosed, {} not diagnosable, {:.1} s",
            rep.diagnosed, rep.undiagnosable, out.diagnose_s
        ));
    }
    if gap::selection(&ctx).is_some() {
        let t = std::time::Instant::now();
        let run = gap::analyse_until_idle(store, &ctx, &Cancel::new()).context("gap analysis")?;
        out.gap_s = t.elapsed().as_secs_f64();
        for (segment_id, reason) in &run.failed {
            eprintln!("gap analysis of segment {segment_id} failed: {reason}");
        }
        if !run.stored.is_empty() || !run.failed.is_empty() {
            let verdicts: Vec<String> = run
                .stored
                .iter()
                .map(|d| format!("segment {} {}", d.segment_id, d.effect))
                .collect();
            say(format!(
                "gap: {} analyses stored ({}), {} failed, {:.1} s",
                run.stored.len(),
                verdicts.join(", "),
                run.failed.len(),
                out.gap_s
            ));
        }
        out.gap = Some(run);
    }
    let analysed = out.gap.as_ref().is_some_and(|g| !g.stored.is_empty());
    if out.diagnosed > 0 || analysed {
        let econ = wash_economics(Some(config))?;
        let r = crate::advice::refresh(
            store,
            &ctx.engine,
            &econ,
            &crate::trend::WashDetection::default(),
            &ctx.settings.bounds(),
        )
        .context("wash advice")?;
        if let Some(a) = &r.advice {
            eprintln!("wash advice: {}", a.summary);
        }
    }
    Ok(out)
}

/// `gtwatch diagnose --segment ID`: re-runs one stored segment with the config's engine and
/// settings; prints JSON of both methods' results (or the reasons). Stores nothing: the
/// database is opened read-only ([`Store::open_readonly`]), so this works on a file nobody may
/// write and beside a running daemon.
pub(super) fn run_segment(db: &Path, config: Option<&Path>, segment: i64) -> anyhow::Result<()> {
    let ctx = worker_context(config)?;
    let store = Store::open_readonly(db).with_context(|| format!("opening {}", db.display()))?;
    if store.segment(segment)?.is_none() {
        bail!("database {} has no segment {segment}", db.display());
    }
    let rec = read_segment(&store, segment)?;
    drop(store);
    let assessment = assess_segment(&ctx, &rec, &Cancel::new());
    // Method B's run to load and steady end read apart, as `diagnose --input` reports them
    // (not stored: the daemon does not run it).
    let split = rec.recording.as_ref().ok().and_then(|r| {
        crate::diagnosis::phase_split::phase_split(
            &ctx.engine,
            r,
            &ctx.settings.fit_config(&Cancel::new()),
        )
    });
    let doc = serde_json::json!({
        "segment_id": segment,
        "config_hash": ctx.config_hash,
        "gtwatch_version": env!("CARGO_PKG_VERSION"),
        "results": new_diagnoses(&ctx, segment, &assessment),
        "undiagnosable": failures(&assessment),
        "phase_split": split,
    });
    println!("{}", serde_json::to_string_pretty(&doc)?);
    Ok(())
}

/// The `[wash]` section of a config file (defaults without a file or section).
pub(super) fn wash_economics(config: Option<&Path>) -> anyhow::Result<crate::wash::WashEconomics> {
    let Some(path) = config else {
        return Ok(crate::wash::WashEconomics::default());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading config {}", path.display()))?;
    let table: toml::Table =
        toml::from_str(&text).with_context(|| format!("config {}", path.display()))?;
    let econ: crate::wash::WashEconomics = match table.get("wash") {
        Some(v) => v
            .clone()
            .try_into()
            .with_context(|| format!("config {}: [wash]", path.display()))?,
        None => crate::wash::WashEconomics::default(),
    };
    econ.validate()
        .map_err(|e| anyhow::anyhow!("config {}: {e}", path.display()))?;
    Ok(econ)
}
