//! `gtwatch diagnose --segment ID` stores nothing and so never opens the database writable
//! (issue 27 item 2): it reproduces the daemon's stored result bit for bit (same config hash,
//! same health, σ, objective) while the daemon holds the database, and again on a database
//! file whose directory and file nobody may write, leaving both as they were.
//!
//! Root ignores permission bits, so when the tests run as root the read-only run is started as
//! user `nobody` (65534), for whom the files are read-only like for any other user.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use gtwatch::health::HealthParams;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{chmod, running_as_root, NOBODY};

/// The start-up this test stores (see `common::store_startup`).
fn store_startup(db: &Path) {
    common::store_startup(
        db,
        &HealthParams {
            D_GC: 1.5,
            D_EC: 0.6,
            D_GT: 0.5,
            D_ET: 0.3,
            D_GP: 0.2,
            D_EP: 0.4,
        },
        5,
    );
}

/// A stored (or printed) result: method, health, σ (NaN where not estimated), objective.
#[derive(Debug, Clone, PartialEq)]
struct Result6 {
    method: String,
    health: [f64; 6],
    sigma: [Option<f64>; 6],
    objective: f64,
    residual_level: f64,
}

/// The stored results (by method) and their config hash.
fn stored(db: &Path) -> (Vec<Result6>, String) {
    let c = common::open_db(db);
    let mut st = c
        .prepare(
            "SELECT method, d_gc, d_ec, d_gt, d_et, d_gp, d_ep, sigma_gc, sigma_ec, sigma_gt,
                    sigma_et, sigma_gp, sigma_ep, objective, residual_level, config_hash
             FROM diagnoses ORDER BY method",
        )
        .expect("prepare");
    let mut hash = String::new();
    let rows: Vec<Result6> = st
        .query_map([], |r| {
            let h: String = r.get(15)?;
            Ok((
                Result6 {
                    method: r.get(0)?,
                    health: std::array::from_fn(|i| r.get(1 + i).expect("health")),
                    sigma: std::array::from_fn(|i| r.get(7 + i).expect("sigma")),
                    objective: r.get(13)?,
                    residual_level: r.get(14)?,
                },
                h,
            ))
        })
        .expect("query")
        .map(|r| {
            let (row, h) = r.expect("row");
            hash = h;
            row
        })
        .collect();
    (rows, hash)
}

/// The raw text of every value of `key` in a JSON document, in order (an array whole).
/// serde_json's parser is not correctly rounded (it may be one ulp off), so the printed
/// numbers are read from their text with Rust's `str::parse`, which is: the comparison with
/// the stored values is bit for bit.
fn raw_values(text: &str, key: &str) -> Vec<String> {
    let pat = format!("\"{key}\":");
    text.match_indices(&pat)
        .map(|(i, _)| {
            let rest = text[i + pat.len()..].trim_start();
            let end = if rest.starts_with('[') {
                rest.find(']').expect("array end") + 1
            } else {
                rest.find([',', '\n', '}']).unwrap_or(rest.len())
            };
            rest[..end].to_string()
        })
        .collect()
}

fn number(token: &str) -> Option<f64> {
    let t = token.trim().trim_matches(|c| c == '[' || c == ']').trim();
    (t != "null").then(|| t.parse().expect("a JSON number"))
}

fn numbers(array: &str) -> Vec<Option<f64>> {
    array
        .trim()
        .trim_matches(|c| c == '[' || c == ']')
        .split(',')
        .map(number)
        .collect()
}

/// The printed results (by method) and config hash of `gtwatch diagnose --segment`.
fn printed(stdout: &str) -> (Vec<Result6>, String) {
    let doc: serde_json::Value = serde_json::from_str(stdout).expect("JSON output");
    let methods: Vec<String> = doc["results"]
        .as_array()
        .expect("results")
        .iter()
        .map(|r| r["method"].as_str().expect("method").to_string())
        .collect();
    // The results' own numbers (the phase split before them has health and σ too).
    let results = &stdout[stdout.find("\"results\"").expect("results")..];
    let (health, sigma) = (raw_values(results, "health"), raw_values(results, "sigma"));
    let (objective, level) = (
        raw_values(results, "objective"),
        raw_values(results, "residual_level"),
    );
    // Method B's run to load and steady end read apart, as `diagnose --input` reports them.
    assert!(
        doc["phase_split"]["differ"].is_array(),
        "{:#}",
        doc["phase_split"]
    );
    assert_eq!(health.len(), methods.len(), "{stdout}");
    let mut rows: Vec<Result6> = methods
        .into_iter()
        .enumerate()
        .map(|(k, method)| {
            let h = numbers(&health[k]);
            let s = numbers(&sigma[k]);
            Result6 {
                method,
                health: std::array::from_fn(|i| h[i].expect("health")),
                sigma: std::array::from_fn(|i| s[i]),
                objective: number(&objective[k]).expect("objective"),
                residual_level: number(&level[k]).expect("level"),
            }
        })
        .collect();
    rows.sort_by(|a, b| a.method.cmp(&b.method));
    let hash = doc["config_hash"].as_str().expect("hash").to_string();
    (rows, hash)
}

/// Runs `gtwatch diagnose --segment ID` (as `nobody` if `as_nobody` and root); returns stdout.
fn diagnose_segment(db: &Path, cfg: &Path, segment: i64, as_nobody: bool) -> String {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_gtwatch"));
    cmd.args(["diagnose", "--segment", &segment.to_string(), "--db"])
        .arg(db)
        .arg("--config")
        .arg(cfg)
        .stdin(Stdio::null());
    if as_nobody && running_as_root() {
        cmd.uid(NOBODY).gid(NOBODY);
    }
    let out = cmd.output().expect("gtwatch diagnose runs");
    assert!(
        out.status.success(),
        "diagnose --segment failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8")
}

#[test]
fn diagnose_segment_reproduces_the_stored_result_beside_a_daemon_and_on_a_read_only_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    chmod(dir.path(), 0o755);
    let dbdir = dir.path().join("data");
    std::fs::create_dir(&dbdir).expect("mkdir");
    let db = dbdir.join("plant.db");
    store_startup(&db);
    let text = include_str!("../config/gtwatch.toml")
        .replace(
            "path = \"/var/lib/gtwatch/gtwatch.db\"",
            &format!("path = {:?}", db.display().to_string()),
        )
        .replace("source = \"modbus\"", "source = \"none\"")
        .replace("max_model_runs = 400", "max_model_runs = 150");
    assert!(text.contains("max_model_runs = 150"));
    let cfg = dir.path().join("gtwatch.toml");
    std::fs::write(&cfg, text).expect("config");
    chmod(&cfg, 0o644);

    // The daemon diagnoses the pending start-up and keeps running (holding the database).
    let mut daemon = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["run", "--config"])
        .arg(&cfg)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("daemon starts");
    let deadline = Instant::now() + Duration::from_secs(180);
    let (rows, hash) = loop {
        let (rows, hash) = stored(&db);
        if !rows.is_empty() {
            break (rows, hash);
        }
        assert!(Instant::now() < deadline, "no diagnosis within 180 s");
        std::thread::sleep(Duration::from_millis(200));
    };
    assert!(!hash.is_empty());
    let segment: i64 = common::open_db(&db)
        .query_row("SELECT id FROM segments", [], |r| r.get(0))
        .expect("one segment");

    // Beside the running daemon: the same result, bit for bit, with the same config hash.
    let beside = printed(&diagnose_segment(&db, &cfg, segment, false));
    assert!(
        daemon.try_wait().expect("wait").is_none(),
        "daemon still runs"
    );
    assert_eq!(beside, (rows.clone(), hash.clone()));
    assert!(common::sigterm(&mut daemon).success());

    // Directory and file read-only (and not ours when root): the same result again, and the
    // directory is left exactly as it was (no -wal, no -shm, no journal created).
    chmod(&db, 0o444);
    chmod(&dbdir, 0o555);
    let before = common::dir_listing(&dbdir);
    // The daemon closed cleanly: no -wal or -shm left, so SQLite has none to read through.
    assert_eq!(before.len(), 1, "{before:?}");
    let read_only = printed(&diagnose_segment(&db, &cfg, segment, true));
    assert_eq!(common::dir_listing(&dbdir), before);
    chmod(&dbdir, 0o755);
    chmod(&db, 0o644);
    assert_eq!(read_only, (rows, hash));
}
