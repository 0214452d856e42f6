//! Issue 23's acceptance on a short month, end to end through the binary: `gtwatch bench
//! gap-month` writes seven days of a fouling unit (one start-up a day) whose fuel meter reads 3 %
//! high from the sixth start-up on and whose third start-up runs with heat soak the model does
//! not describe, replays the log through `gtwatch replay`'s own path, and reports
//! what was stored. Nobody runs `gtwatch gap` here: the analyses must have been asked for by
//! the replay's gap step (the daemon's selection), the meter's misfit once, not every day. Then `gtwatch report` must show the
//! verdicts, and the advice must not move by more than a day against the same month with a
//! correct meter.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use std::process::Command;

const DAYS: &str = "7";
const METER_FROM: usize = 5;
const POOR_DAY: usize = 2;

#[test]
fn a_replayed_month_gets_its_gap_analyses_unasked_and_the_meter_step_leaves_the_advice() {
    let dir = tempfile::tempdir().expect("tempdir");
    let t = std::time::Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args([
            "bench",
            "gap-month",
            "--days",
            DAYS,
            "--meter-from",
            &METER_FROM.to_string(),
            "--poor-day",
            &POOR_DAY.to_string(),
            "--gc-per-day",
            "0.25",
            "--idle-step",
            "10",
            "--max-model-runs",
            "150",
            "--threads",
            "2",
            "--no-baseline",
            "--clean-without-gap",
            "--json",
            "--keep",
        ])
        .arg(dir.path())
        .output()
        .expect("bench runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    eprintln!(
        "bench gap-month --days {DAYS}: {:.0} s\n{}",
        t.elapsed().as_secs_f64(),
        serde_json::to_string_pretty(&r).unwrap()
    );
    let start_ups = r["start_ups"].as_array().expect("start_ups");
    assert_eq!(start_ups.len(), 7, "one start-up a day");

    // Both analyses stored without being asked: the poorly fitting start-up, and the first one
    // the meter moved.
    let verdicts = |day: usize| -> Vec<String> {
        start_ups
            .iter()
            .find(|s| s["day"] == day)
            .map(|s| {
                s["gap_verdicts"]
                    .as_array()
                    .expect("verdicts")
                    .iter()
                    .map(|v| v.as_str().expect("verdict").to_string())
                    .collect()
            })
            .unwrap_or_default()
    };
    let poor = verdicts(POOR_DAY);
    assert!(!poor.is_empty(), "the poor start-up was not analysed");
    let onset = verdicts(METER_FROM);
    assert!(
        !onset.is_empty(),
        "the meter's first start-up was not analysed"
    );
    // The meter stays wrong after its first start-up: the next fits are as poor, in the same
    // way, and that first analysis stands for them (not one analysis a day).
    for day in METER_FROM + 1..DAYS.parse::<usize>().expect("days") {
        assert!(
            verdicts(day).is_empty(),
            "day {day} analysed again: {:?}",
            verdicts(day)
        );
    }
    assert!(
        r["poor_explained"].as_bool().expect("poor_explained"),
        "the poor start-up's analysis named {poor:?}, not fuel_system"
    );
    // No start-up before the meter's step other than the poor one was analysed: the selection
    // asked only where the fit or the trend called for it.
    for day in (0..METER_FROM).filter(|d| *d != POOR_DAY) {
        assert!(verdicts(day).is_empty(), "day {day}: {:?}", verdicts(day));
    }

    // The step is the fuel meter's: named by the analysis of its first start-up or by the
    // joint fit of the sequence; no start-up before it is taken for an instrument's.
    assert!(
        r["instrument_named"].as_bool().expect("instrument_named"),
        "the meter was not named: onset {onset:?}, advice {}",
        r["advice"]
    );
    assert_eq!(
        r["set_aside_before_step"],
        serde_json::json!([]),
        "start-ups before the step set aside"
    );

    // The advice is not moved by the meter against the clean month.
    let shift = r["advice_shift_days"].as_f64().expect("both months advise");
    assert!(shift <= 1.0, "advice moved by {shift:.2} days");

    // The report shows the verdicts.
    let report_dir = dir.path().join("report");
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["report", "--config"])
        .arg(dir.path().join("faulty.toml"))
        .arg("--out")
        .arg(&report_dir)
        .output()
        .expect("report runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let html = std::fs::read_to_string(report_dir.join("report.html")).expect("report.html");
    let gap = &html[html.find("Model–plant gap").expect("gap section")..];
    for v in poor.iter().chain(onset.iter()) {
        assert!(gap.contains(v.as_str()), "report lacks verdict {v}");
    }
}
