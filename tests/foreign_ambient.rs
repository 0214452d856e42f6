//! A foreign unit on days unlike its baseline's: the adapted model must stay similar (one
//! corrected operating point, one non-dimensional state, at every ambient), or a healthy unit
//! reads as degraded whenever a day pairs its ambient and load otherwise than the baseline did.
//!
//! The unit (`tests/data/foreign/pyc28_pipeline_truth.toml`): pyCycle's compressor and HP
//! turbine maps, a VIGV schedule, a pipeline compressor's load law P ∝ n2^2.7, PR 19, 28 MW.
//! Its rows (`tests/data/foreign/pyc28_days.csv`, written with `gtwatch steady --engine` that
//! file at each load and ambient, plus noise of 100-s averages): a baseline of 9 loads from
//! 30 % to 100 % with the ambient from 253 K to 308 K shuffled over them, and four healthy days
//! of the same loads and ambients paired otherwise. The user's file
//! (`tests/data/foreign/pyc28_user_md22.toml`): `config/engine_md22.toml` with the design point
//! typed from one full-load reading on a 308 K day. The user's steps: `gtwatch calibrate
//! --adapt` on the baseline, then `gtwatch diagnose --method steady --group-by group`.
//!
//! Measured (`cargo test --release --test integration foreign_ambient -- --nocapture`): with the
//! HP turbine's knots in its own corrected speed the baseline fits within noise (0.71 σ) and
//! reads healthy, but the four other days read D_GC +1.8…+2.9 and D_GT to −1.9 points, every one
//! `poor` (residual 18–26): the adapted model is not similar (T34/T1 moves 4.72 % between
//! T1 − 25 K and T1 + 25 K at one corrected point, 0.33 % on the file before the adaptation).
//! The cause, found by taking the curves out one component at a time: the HP turbine's curves
//! are functions of its own corrected speed, whose temperature (T3) its flow and efficiency
//! set, so they feed back into their own argument and amplify the small non-similarity of real
//! gas. The calibration's similarity check (`AdaptReport::similarity`) sees it. A second cause
//! sat under it: fitted from zero, the compressor's speed re-labelling, flow and efficiency
//! curves (which trade one for another along a healthy line that measures no air flow) put the
//! operating line beyond the map's surge line (re-labelling 4 %, flow +41 %, efficiency +15 % at
//! the lowest knot; surge margin −10 % where the unit has 26 %), where flat, extrapolated speed
//! lines amplify the same effects. The operating-line check (`AdaptReport::operating_line`) sees
//! that, and the adaptation is fitted again from the re-labelling the data show (the unit runs
//! at 83 % corrected speed where the map's line of 91 % carries it) with the HPT's knots in
//! either speed; kept: its knots in the GG's corrected speed at the compressor inlet
//! (`engine::config::SpeedOf`), 0.63 σ, re-labelling 9 %, efficiency +1 %, no flow curve, surge
//! margin 16.5 % at least, T4/T1 0.69 % (0.49 % before). The same days then read within 0.39
//! points, every one `good`, and the model's own error in health units is 0.16–0.29 points
//! (0.19–0.58 with the fit kept before, from zero with the GG's speed).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::calibrate::adapt::{AdaptSettings, AdaptStrategy};
use gtwatch::calibrate::candidates::default_candidates;
use gtwatch::calibrate::{calibrate, CalibrationSettings};
use gtwatch::diagnosis::snapshot::{diagnose_snapshots, read_snapshots, Snapshot};
use gtwatch::engine::{Engine, EngineConfig};
use gtwatch::health::HEALTH_NAMES;
use std::collections::HashMap;
use std::path::PathBuf;

fn engine(file: &str) -> Engine {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(file);
    Engine::new(EngineConfig::load(&path).expect("engine file")).expect("engine")
}

/// The rows of `tests/data/foreign/pyc28_days.csv`, by day (the baseline first).
fn days() -> Vec<(String, Vec<Snapshot>)> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/foreign/pyc28_days.csv");
    let text = std::fs::read_to_string(path).expect("rows");
    let rows = read_snapshots(text.as_bytes(), &HashMap::new(), Some("group")).expect("rows");
    let mut out: Vec<(String, Vec<Snapshot>)> = Vec::new();
    for r in rows {
        match out.iter_mut().find(|(g, _)| *g == r.group) {
            Some((_, v)) => v.push(r),
            None => out.push((r.group.clone(), vec![r])),
        }
    }
    out
}

#[test]
fn an_adapted_foreign_unit_reads_healthy_on_days_unlike_its_baseline() {
    let model = engine("tests/data/foreign/pyc28_user_md22.toml");
    let days = days();
    assert_eq!(days.len(), 5);
    let (name, base) = &days[0];
    assert_eq!((name.as_str(), base.len()), ("baseline", 9));
    let settings = CalibrationSettings {
        threads: Some(2),
        adapt: Some(AdaptSettings::of(AdaptStrategy::Grown)),
        ..CalibrationSettings::default()
    };
    let cands = default_candidates(&model).expect("candidates");
    let (report, adapted) = calibrate(&model, base, &[], cands, &settings).expect("calibrate");
    let a = report.adaptation.as_ref().expect("adapted");
    eprintln!("baseline RMS after the adaptation {:.2} σ", a.rms_after);
    assert!(a.rms_after < 1.0, "baseline RMS {:.2} σ", a.rms_after);
    // What the baseline cannot show, the two checks do: fitted from zero, the compressor's
    // curves put 5 of the 9 healthy points beyond its map's surge line (surge margin −10 %, the
    // unit has 26 %) and T34/T1 moved 4.72 % between T1 − 25 K and T1 + 25 K at one corrected
    // point (0.33 % before the adaptation). Fitted again from the speed re-labelling the data
    // show, with the HP turbine's knots in either speed: in its own, 0.57 σ and 1.15 % (0.40 %
    // before); in the GG's at the compressor inlet, 0.63 σ and T4/T1 0.69 % (0.49 %), kept.
    for st in a.steps.iter().chain(&a.retried) {
        eprintln!("  step: {st}");
    }
    let sim = a.similarity.as_ref().expect("similarity checked");
    eprintln!("{}", sim.describe());
    assert!(!sim.departs, "{}", sim.describe());
    let line = a.operating_line.as_ref().expect("operating line checked");
    eprintln!("{}", line.describe());
    assert!(!line.beyond(), "{}", line.describe());
    assert!(
        a.retried
            .first()
            .is_some_and(|st| st.contains("beyond its map's surge line"))
            && a.retried.iter().filter(|st| st.ends_with(": kept")).count() == 1,
        "{:?}",
        a.retried
    );
    let hpt = adapted
        .cfg()
        .adaptation
        .as_ref()
        .and_then(|x| x.hpt.as_ref());
    assert_eq!(
        hpt.and_then(|c| c.speed_of),
        Some(gtwatch::engine::config::SpeedOf::GgInlet)
    );
    let cfg = crate::foreign_engine::diagnosis_cfg();
    for (i, (group, rows)) in days.iter().enumerate() {
        let report = diagnose_snapshots(&adapted, rows, &cfg).expect("diagnosis");
        assert!(report.failed.is_empty(), "{:?}", report.failed);
        let g = report.groups.first().expect("a group");
        let est = g.result.health.to_array();
        let verdict = format!("{:?}", g.result.fit_quality.verdict).to_lowercase();
        let off = est.iter().fold(0.0f64, |w, v| w.max(v.abs()));
        eprintln!(
            "{group}: {} — {verdict} (residual {:.2}), {} row(s) left out",
            HEALTH_NAMES
                .iter()
                .zip(est)
                .map(|(n, v)| format!("{n} {v:+.2}"))
                .collect::<Vec<_>>()
                .join(", "),
            g.result.fit_quality.normalised_residual,
            g.dropped.len()
        );
        if i == 0 {
            // The baseline itself: healthy, `good`.
            assert!(
                off <= 0.3 && verdict == "good",
                "baseline read {est:?} {verdict}"
            );
        }
        // Measured within 0.39 points (D_GC −0.38 on day 4), every day `good` (residual
        // 0.23–0.75); the fit from zero read D_GC +1.8…+2.9, `poor`; from the re-labelling
        // with the HPT's knots in its own speed, within 0.26 but day 2 `poor` (2.96).
        assert!(
            off <= 0.5 && verdict == "good",
            "{group}: {est:?} {verdict}"
        );
    }
}
