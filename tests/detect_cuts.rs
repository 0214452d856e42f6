//! The daemon's detector scans whenever its timer fires, so a scan may stop at any sample. On
//! the end-to-end test's script (a cold start, a trip, a start shut down and restarted hot
//! before the gas generator stopped), scanning the data in two parts cut at any sample finds
//! exactly what one pass finds.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use gtwatch::detect::{scan, DetectorConfig};
use gtwatch::plantsim::{PlantModel, ScriptLevels, ScriptedPlant};
use gtwatch::quality::Quality;
use gtwatch::signals::Signal;
use gtwatch::store::{Sample, Store, TagInfo};

/// Per frame: the samples of n1, fuel, power and n2 at the frame's time.
fn frames() -> Vec<Vec<(Signal, i64, f64)>> {
    let mut plant = ScriptedPlant::new(
        &common::e2e_schedule(),
        &common::e2e_timing(),
        ScriptLevels::default(),
        1.0,
        false,
    );
    let n = plant.duration_s().ceil() as usize + 1;
    (0..n)
        .map(|_| {
            let f = plant.step();
            let t = common::EPOCH_MS + (f.t_s * 1000.0).round() as i64;
            [Signal::N1, Signal::FuelFlow, Signal::Power, Signal::N2]
                .into_iter()
                .map(|s| (s, t, f.get(s)))
                .collect()
        })
        .collect()
}

fn insert(store: &mut Store, frames: &[Vec<(Signal, i64, f64)>]) {
    let mut batch = Vec::new();
    for fr in frames {
        for &(s, t, v) in fr {
            let tag = store.ensure_tag(&TagInfo::for_signal(s)).expect("tag");
            batch.push(Sample {
                tag,
                t_ms: t,
                value: v,
                quality: Quality::Good,
            });
        }
    }
    store.insert_samples(&batch).expect("insert");
}

fn segments(path: &std::path::Path) -> Vec<(i64, Option<i64>, String, bool)> {
    let conn = rusqlite::Connection::open(path).expect("open");
    let mut st = conn
        .prepare("SELECT start_ms, end_ms, outcome, hot_restart FROM segments ORDER BY start_ms")
        .expect("prepare");
    st.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))
        .expect("query")
        .collect::<Result<_, _>>()
        .expect("rows")
}

#[test]
fn a_scan_cut_at_any_sample_finds_what_one_pass_finds() {
    let all = frames();
    let cfg = DetectorConfig {
        steady_hold_s: 6.0,
        trip_fuel_cut_s: 3.0,
        hot_restart_window_s: 40.0,
        max_sample_gap_s: 5.0,
        resume_margin_s: 60.0,
        ..DetectorConfig::default()
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let one_path = dir.path().join("one.db");
    let mut one = Store::open(&one_path).expect("open");
    insert(&mut one, &all);
    scan(&mut one, &cfg).expect("scan");
    let reference = segments(&one_path);
    assert_eq!(reference.len(), 4, "{reference:?}");
    // Every cut from half a minute before each start's onset to a minute after it (the
    // stretches where the machine's state matters), one sample apart.
    let first_ms = all[0][0].1;
    let mut cuts: Vec<usize> = reference
        .iter()
        .flat_map(|r| {
            let at = ((r.0 - first_ms) / 1000) as usize;
            at.saturating_sub(30)..(at + 60).min(all.len())
        })
        .collect();
    cuts.dedup();
    let mut bad = Vec::new();
    for cut in cuts {
        let path = dir.path().join(format!("cut{cut}.db"));
        let mut inc = Store::open(&path).expect("open");
        insert(&mut inc, &all[..cut]);
        scan(&mut inc, &cfg).expect("scan");
        insert(&mut inc, &all[cut..]);
        scan(&mut inc, &cfg).expect("scan");
        drop(inc);
        let got = segments(&path);
        if got != reference {
            bad.push((cut, got));
        }
        std::fs::remove_file(&path).ok();
    }
    assert!(
        bad.is_empty(),
        "{} cuts change the result; reference {reference:?}; first: {:?}",
        bad.len(),
        bad.iter().take(3).collect::<Vec<_>>()
    );
}
