//! Acceptance (issue 24, item 3): a historian export in local time replays whole. A 1 Hz
//! Europe/Berlin export spanning both 2026 clock changes, replayed with the real `gtwatch
//! replay`, stores every row once at the right UTC instant, and a second replay adds nothing.
//! Also: the long layout (`tag,time,value,status`, sorted by time or by tag) stores what the
//! wide layout stores; an explicit offset in the data wins over `time_zone`; a bad zone name
//! and a time in the spring gap are refused, naming the key or the line.
//!
//! The expected UTC instants are computed here from the known offsets (CET = +01:00 before
//! 2026-03-29 01:00Z and from 2026-10-25 01:00Z, CEST = +02:00 between), not by the code
//! under test.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const HOUR: i64 = 3_600_000;
const TAGS: [&str; 3] = ["n1_rpm", "fuel_kg_s", "power_mw"];

/// UTC epoch ms of an ISO 8601 UTC text.
fn utc(s: &str) -> i64 {
    gtwatch::time::parse_iso8601_ms(s).expect("utc")
}

/// Europe/Berlin's offset at UTC instant `t` in 2026, from the published rules.
fn berlin_offset_ms(t: i64) -> i64 {
    let summer = utc("2026-03-29T01:00:00Z")..utc("2026-10-25T01:00:00Z");
    if summer.contains(&t) {
        2 * HOUR
    } else {
        HOUR
    }
}

/// The local wall-clock text (`2026-10-25 02:30:00`) of UTC instant `t` in Berlin.
fn berlin_local(t: i64) -> String {
    let s = gtwatch::time::fmt_ms(t + berlin_offset_ms(t));
    format!("{} {}", &s[..10], &s[11..19])
}

/// Value of tag `k` at row `i`: smooth, in range, distinct per row.
fn value(k: usize, i: usize) -> f64 {
    match k {
        0 => 3000.0 + (i % 900) as f64 * 0.5,
        1 => 1.0 + (i % 900) as f64 * 0.001,
        _ => 10.0 + (i % 900) as f64 * 0.01,
    }
}

/// The UTC instants of the export: 1 Hz, local 01:30–03:30 on both change days.
fn instants() -> Vec<i64> {
    let spring = utc("2026-03-29T00:30:00Z")..=utc("2026-03-29T01:30:00Z"); // 01:30 CET–03:30 CEST
    let autumn = utc("2026-10-24T23:30:00Z")..=utc("2026-10-25T02:30:00Z"); // 01:30 CEST–03:30 CET
    spring
        .step_by(1000)
        .chain(autumn.step_by(1000))
        .collect::<Vec<_>>()
}

fn wide_csv(ts: &[i64]) -> String {
    let mut s = format!("time,{}\n", TAGS.join(","));
    for (i, &t) in ts.iter().enumerate() {
        s.push_str(&berlin_local(t));
        for k in 0..TAGS.len() {
            s.push_str(&format!(",{}", value(k, i)));
        }
        s.push('\n');
    }
    s
}

/// The same data as `tag,time,value,status`, sorted by time (then tag) or by tag (then time).
fn long_csv(ts: &[i64], by_tag: bool) -> String {
    let mut rows = Vec::new();
    for (i, &t) in ts.iter().enumerate() {
        for (k, tag) in TAGS.iter().enumerate() {
            rows.push((
                k,
                i,
                format!("{tag},{},{},Good\n", berlin_local(t), value(k, i)),
            ));
        }
    }
    if by_tag {
        rows.sort_by_key(|(k, i, _)| (*k, *i));
    }
    let mut s = String::from("tag,time,value,status\n");
    for (_, _, r) in rows {
        s.push_str(&r);
    }
    s
}

struct Case {
    _dir: tempfile::TempDir,
    csv: PathBuf,
    db: PathBuf,
    cfg: PathBuf,
}

fn setup(log: &str, time_zone: &str) -> Case {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("export.csv");
    let db = dir.path().join("plant.db");
    let cfg = dir.path().join("gtwatch.toml");
    std::fs::write(&csv, log).expect("write csv");
    std::fs::write(
        &cfg,
        format!(
            "[storage]\npath = {:?}\n\n[replay]\ntime_zone = {time_zone:?}\n",
            db.display().to_string()
        ),
    )
    .expect("write config");
    Case {
        _dir: dir,
        csv,
        db,
        cfg,
    }
}

fn replay(c: &Case) -> Output {
    replay_args(&c.cfg, &c.csv)
}

fn replay_args(cfg: &Path, csv: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["replay", "--no-detect", "--json", "--config"])
        .arg(cfg)
        .arg(csv)
        .output()
        .expect("gtwatch runs")
}

fn report(out: &Output) -> serde_json::Value {
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "JSON on stdout ({e}); stderr: {}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    v["files"][0].clone()
}

/// Every tag's (t_ms, value, quality), in tag order.
fn stored(db: &Path) -> Vec<Vec<(i64, f64, i64)>> {
    let conn = common::open_db(db);
    TAGS.iter().map(|t| common::tag_samples(&conn, t)).collect()
}

#[test]
fn berlin_export_across_both_clock_changes_stores_every_row_once_at_its_utc_instant() {
    let ts = instants();
    assert_eq!(ts.len(), 3601 + 10801);
    let log = wide_csv(&ts);
    // The export really holds the repeated hour twice, in order, and no spring-gap time.
    assert_eq!(log.matches("2026-10-25 02:30:00").count(), 2);
    assert_eq!(log.matches("2026-03-29 02:").count(), 0);
    let c = setup(&log, "Europe/Berlin");

    let out = replay(&c);
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let r = report(&out);
    assert_eq!(r["rows_read"], ts.len());
    assert_eq!(r["rows_malformed"], 0, "{r}");
    assert_eq!(r["samples_inserted"], ts.len() * TAGS.len());

    let got = stored(&c.db);
    for (k, tag) in TAGS.iter().enumerate() {
        let want: Vec<(i64, f64)> = ts
            .iter()
            .enumerate()
            .map(|(i, &t)| (t, value(k, i)))
            .collect();
        let have: Vec<(i64, f64)> = got[k].iter().map(|&(t, v, _)| (t, v)).collect();
        assert_eq!(have.len(), want.len(), "{tag}: one sample per row");
        assert_eq!(have, want, "{tag}: every row at its UTC instant");
    }
    // Spot checks written out: the first and second 02:30 of 25 October.
    let n1: Vec<i64> = got[0].iter().map(|s| s.0).collect();
    assert!(n1.contains(&utc("2026-10-25T00:30:00Z")), "02:30 CEST");
    assert!(n1.contains(&utc("2026-10-25T01:30:00Z")), "02:30 CET");
    assert!(n1.contains(&utc("2026-03-29T01:00:00Z")), "03:00 CEST");

    let again = replay(&c);
    assert!(again.status.success());
    let r = report(&again);
    assert_eq!(r["samples_inserted"], 0, "a second replay adds nothing");
    assert_eq!(r["samples_present"], ts.len() * TAGS.len());
    assert_eq!(stored(&c.db), got);
}

#[test]
fn long_layout_stores_what_the_wide_layout_stores() {
    let ts = instants();
    let wide = setup(&wide_csv(&ts), "Europe/Berlin");
    assert!(replay(&wide).status.success());
    let want = stored(&wide.db);
    assert_eq!(want[0].len(), ts.len());
    for by_tag in [false, true] {
        let long = setup(&long_csv(&ts, by_tag), "Europe/Berlin");
        let out = replay(&long);
        assert!(
            out.status.success(),
            "by_tag {by_tag}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let r = report(&out);
        assert_eq!(r["rows_read"], ts.len() * TAGS.len());
        assert_eq!(r["rows_malformed"], 0, "{r}");
        assert_eq!(stored(&long.db), want, "long (by tag: {by_tag}) = wide");
        let again = report(&replay(&long));
        assert_eq!(again["samples_inserted"], 0);
    }
}

#[test]
fn an_explicit_offset_in_the_data_wins_over_time_zone() {
    let log = "time,n1_rpm\n\
               2026-07-01T12:00:00Z,1\n\
               2026-07-01T14:00:01+02:00,2\n\
               2026-07-01 09:00:02-03:00,3\n\
               2026-07-01 14:00:03,4\n";
    let c = setup(log, "Europe/Berlin");
    let out = replay(&c);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let t0 = utc("2026-07-01T12:00:00Z");
    let have: Vec<(i64, f64)> = stored(&c.db)[0].iter().map(|&(t, v, _)| (t, v)).collect();
    assert_eq!(
        have,
        vec![
            (t0, 1.0),
            (t0 + 1000, 2.0),
            (t0 + 2000, 3.0),
            (t0 + 3000, 4.0)
        ]
    );
}

#[test]
fn a_bad_zone_name_is_refused_naming_the_key() {
    let c = setup("time,n1_rpm\n2026-07-01 12:00:00,1\n", "Europe/Berlni");
    let out = replay(&c);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("replay.time_zone"), "{err}");
    assert!(err.contains("Europe/Berlni"), "{err}");
    assert!(!c.db.exists(), "nothing created");
}

#[test]
fn a_time_in_the_spring_gap_is_reported_with_its_line() {
    let log = "time,n1_rpm\n\
               2026-03-29 01:59:59,1\n\
               2026-03-29 02:30:00,2\n\
               2026-03-29 03:00:00,3\n";
    let c = setup(log, "Europe/Berlin");
    let out = replay(&c);
    assert_eq!(out.status.code(), Some(3), "time rejected");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("line 3") && err.contains("does not exist"),
        "{err}"
    );
    let r = report(&out);
    assert_eq!(r["rows_nonexistent_time"], 1);
    let have: Vec<i64> = stored(&c.db)[0].iter().map(|s| s.0).collect();
    assert_eq!(
        have,
        vec![utc("2026-03-29T00:59:59Z"), utc("2026-03-29T01:00:00Z")]
    );
}
