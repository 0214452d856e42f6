//! The whole product on a season of a unit nobody here made: forty start-ups of the second
//! blind simulator's unit (`tests/data/foreign/indep2/season.py`, each one `dyn.py`'s own, with
//! its engine, control, sequence, lags and noise; one every three days from March to June, 70 –
//! 100 % load on a warming ambient; compressor fouling growing 0.05 points a day with D_EC 0.45
//! of it, an offline wash between day 72 and day 75 taking 90 % of it; HP-turbine erosion growing
//! 0.008 points a day, never recovered; the PT untouched) replayed as one historian export
//! through the engine file a user calibrates from the unit's datasheet copy, its healthy
//! baseline and its first two healthy start-ups (`--dynamics --noisy-inputs --adapt`); then the
//! stored Method B history, the wash the trend finds and the advice, against the truth
//! (`season_truth.csv`).
//!
//! A measurement, not a CI test: the simulator takes about 100 s on two cores and the replay
//! about 40 s (the gap analyses off; then one per start-up not fitted `good`, about 30 s each). Run it with `cargo test --release --test integration
//! foreign_season -- --ignored --nocapture` (needs `python3`).

use crate::foreign_simulator::{calibrate_on_indep2, indep2_replay_config};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// One start of the season's truth file.
struct TrueStart {
    start_utc: String,
    health: [f64; 6],
}

fn read_truth(path: &Path) -> Vec<TrueStart> {
    let text = std::fs::read_to_string(path).expect("truth");
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).expect(name);
    let (t, h0) = (col("start_cmd_time"), col("true_D_GC"));
    lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            let mut health = [0.0; 6];
            for (i, h) in health.iter_mut().enumerate() {
                *h = v[h0 + i].parse().expect("number");
            }
            TrueStart {
                start_utc: v[t].to_string(),
                health,
            }
        })
        .collect()
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

#[test]
#[ignore = "measurement: cargo test --release --test integration foreign_season -- --ignored --nocapture"]
fn a_season_of_the_second_simulators_unit_is_trended_and_its_wash_found() {
    let dir = tempfile::tempdir().expect("tempdir");
    let season = dir.path().join("season");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/foreign/indep2/season.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg(&season)
        .arg("40")
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let truth = read_truth(&season.join("season_truth.csv"));
    assert_eq!(truth.len(), 40);

    let unit = dir.path().join("unit.toml");
    calibrate_on_indep2(dir.path(), &["--dynamics", "--noisy-inputs"], &unit);
    let cfg = indep2_replay_config(dir.path(), &unit, 2);
    let text = std::fs::read_to_string(&cfg)
        .expect("config")
        .replace("gap_on_poor_fit = true", "gap_on_poor_fit = false")
        .replace("gap_on_health_step = true", "gap_on_health_step = false");
    std::fs::write(&cfg, text).expect("config");
    let log = season.join("season_log.csv");
    crate::common::gtwatch_ok(&["replay", log.to_str().expect("utf-8")], &cfg);

    let history: Value = serde_json::from_slice(&crate::common::gtwatch_ok(
        &["history", "--method", "B", "--format", "json"],
        &cfg,
    ))
    .expect("json");
    let rows = history.as_array().expect("rows");
    assert_eq!(rows.len(), 40, "one Method B result per start-up");
    let by_start: BTreeMap<String, &Value> = rows
        .iter()
        .map(|r| {
            let t = r["start_utc"].as_str().expect("start");
            // Stored to the millisecond; the truth to the second.
            (
                t.trim_end_matches('Z').trim_end_matches(".000").to_string(),
                r,
            )
        })
        .collect();
    let mut errors: [Vec<f64>; 6] = Default::default();
    let mut good = 0;
    for t in &truth {
        let r = by_start
            .get(t.start_utc.trim_end_matches('Z'))
            .unwrap_or_else(|| panic!("no result for the start at {}", t.start_utc));
        good += usize::from(r["fit_quality"] == "good");
        for (p, e) in errors.iter_mut().enumerate() {
            let read = r["health"][gtwatch::health::HEALTH_NAMES[p]]
                .as_f64()
                .expect("estimate");
            e.push(read - t.health[p]);
        }
    }
    let rms_of: Vec<f64> = errors.iter().map(|e| rms(e)).collect();
    eprintln!("Method B |error| RMS over 40 start-ups D_GC…D_EP {rms_of:.2?}, {good} of 40 `good`");
    // The compressor and the HP turbine's flow, which the wash advice and the erosion trend
    // read: measured 0.26 / 0.11 / 0.13. The HP turbine's efficiency and the PT's, which these
    // signals barely separate, held by Method B's prior along those directions: 0.31, 0.78,
    // 0.67 (without it 0.56, 1.34, 1.04; what remains is three days of 30 °C and more, read
    // −2.3 / −1.8 on the PT).
    assert!(rms_of[0] <= 0.35, "D_GC RMS {:.2}", rms_of[0]);
    assert!(rms_of[1] <= 0.2, "D_EC RMS {:.2}", rms_of[1]);
    assert!(rms_of[2] <= 0.2, "D_GT RMS {:.2}", rms_of[2]);
    assert!(rms_of[3] <= 0.45, "D_ET RMS {:.2}", rms_of[3]);
    assert!(rms_of[4] <= 1.0, "D_GP RMS {:.2}", rms_of[4]);
    assert!(rms_of[5] <= 0.9, "D_EP RMS {:.2}", rms_of[5]);

    let advice: Value = serde_json::from_slice(&crate::common::gtwatch_ok(
        &["wash", "advise", "--json"],
        &cfg,
    ))
    .expect("json");
    // The wash is found between the last start before it (day 72) and the first after (75).
    let last_wash_ms = advice["last_wash_ms"].as_i64().expect("a wash found");
    let ms = |utc: &str| {
        let t = time::OffsetDateTime::parse(utc, &time::format_description::well_known::Rfc3339)
            .expect("time");
        (t.unix_timestamp_nanos() / 1_000_000) as i64
    };
    let (before, after) = (ms(&truth[24].start_utc), ms(&truth[25].start_utc));
    assert!(
        last_wash_ms > before && last_wash_ms <= after + 600_000,
        "wash at {last_wash_ms}, truth between {before} and {after}"
    );
    let rate = |p: &str| {
        advice["trends"]
            .as_array()
            .expect("trends")
            .iter()
            .find(|t| t["param"] == p)
            .and_then(|t| t["fit"]["rate_per_day"].as_f64())
            .unwrap_or_else(|| panic!("{p}'s rate in {advice:#}"))
    };
    let (gc, ec) = (rate("D_GC"), rate("D_EC"));
    eprintln!("fouling since the wash: D_GC {gc:+.4} (0.05), D_EC {ec:+.4} (0.0225) points a day");
    assert!((gc - 0.05).abs() <= 0.0075, "D_GC rate {gc:.4}");
    assert!((ec - 0.0225).abs() <= 0.006, "D_EC rate {ec:.4}");
    assert_eq!(advice["advice"]["decided_by"], "economic", "{advice:#}");

    // The gap analysis of every start-up whose fit is not `good`, as the daemon runs it: the
    // data have no instrument error, so none may be named (a named instrument sets the
    // start-up aside from the trend). Measured before the verdict asked a candidate to remove
    // the oscillation that alone made a fit `suspect`: `inlet_temperature` named on 3 of 13.
    let mut named = Vec::new();
    for (seq, t) in truth.iter().enumerate() {
        let r = by_start[t.start_utc.trim_end_matches('Z')];
        if r["fit_quality"] == "good" {
            continue;
        }
        let id = r["segment_id"].as_i64().expect("segment id").to_string();
        let gap: Value = serde_json::from_slice(&crate::common::gtwatch_ok(
            &["gap", "--segment", &id, "--threads", "2", "--json"],
            &cfg,
        ))
        .expect("json");
        let effect = gap["verdict"]["effect"]
            .as_str()
            .expect("effect")
            .to_string();
        eprintln!("start {}: gap verdict {effect}", seq + 1);
        if !["none", "unexplained", "ambiguous"].contains(&effect.as_str()) {
            named.push((seq + 1, effect));
        }
    }
    assert!(
        named.is_empty(),
        "effects named on a unit without any: {named:?}"
    );
}
