//! The adapted model's own error (`[adaptation.model_error_pct]`, estimated by `calibrate
//! --adapt` on interior points left out) on a unit of the model's own map family: the example
//! baseline `examples/baseline_snapshots.csv` differs from `config/engine.toml` only in design
//! values, which the calibration fits, so the adapted model predicts its left-out points within
//! noise and must state (almost) no model error — a diagnosis of such a unit keeps weighting by
//! its instruments. The foreign units of `tests/foreign_engine.rs` check the other side (a GG
//! speed model error well above the tachometer's noise).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::calibrate::adapt::AdaptSettings;
use gtwatch::calibrate::candidates::default_candidates;
use gtwatch::calibrate::{calibrate, CalibrationSettings};
use gtwatch::diagnosis::snapshot::read_snapshots;
use gtwatch::engine::{Engine, EngineConfig};
use std::collections::HashMap;
use std::path::PathBuf;

#[test]
fn the_model_s_own_family_states_no_model_error() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let model =
        Engine::new(EngineConfig::load(&root.join("config/engine.toml")).expect("loads")).unwrap();
    let csv = std::fs::read_to_string(root.join("examples/baseline_snapshots.csv")).unwrap();
    let rows = read_snapshots(csv.as_bytes(), &HashMap::new(), None).expect("rows");
    let settings = CalibrationSettings {
        threads: Some(2),
        adapt: Some(AdaptSettings::default()),
        ..CalibrationSettings::default()
    };
    let cands = default_candidates(&model).expect("candidates");
    let (report, adapted) = calibrate(&model, &rows, &[], cands, &settings).expect("calibrate");
    let me = &report.adaptation.as_ref().expect("adaptation").model_error;
    eprintln!("{me:?}");
    assert!(me.folds >= 3, "{}", me.note);
    assert!(!me.signals.is_empty());
    for s in &me.signals {
        assert!(s.pct < 0.05, "{}: {:.3} %", s.signal, s.pct);
    }
    // The adapted engine carries what the report states.
    let stated = &adapted.cfg().adaptation.as_ref().unwrap().model_error_pct;
    assert_eq!(stated.len(), me.signals.len());
    // In health units too: healthy loads the refitted curves did not see read within the
    // noise of a third of the baseline, and the file carries the estimate.
    let he = &report.adaptation.as_ref().expect("adaptation").health_error;
    eprintln!("{he:?}");
    assert_eq!(he.parts.len(), 3, "{}", he.note);
    assert_eq!(he.points.len(), 6);
    assert!(he.points.values().all(|v| *v < 0.15), "{:?}", he.points);
    assert_eq!(
        &adapted.cfg().adaptation.as_ref().unwrap().health_error,
        &he.points
    );
}
