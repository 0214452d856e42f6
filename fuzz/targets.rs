//! Fuzz harness bodies, one per parser of outside input. Shared by the cargo-fuzz targets in
//! `fuzz_targets/` and by `tests/fuzz_regressions.rs`, which replays every saved input in
//! `fuzz/regressions/<target>/` through the same function on every `cargo test`.
//!
//! Each body must return normally for any input: an error value is the parser doing its job; a
//! panic, a hang or an abort is a defect. Nothing here writes outside a temporary directory.

use gtwatch::acquire::modbus::{decode_request, PollPlan};
use gtwatch::config::Config;
use gtwatch::diagnosis::csv_input::read_recording;
use gtwatch::engine::config::EngineConfig;
use gtwatch::engine::Engine;
use gtwatch::ingest::{replay_file, Progress, ReplayConfig};
use gtwatch::maps::gasturb;
use gtwatch::store::Store;
use gtwatch::time::TimeFormat;
use std::collections::HashMap;

/// A harness body: takes any bytes, must return normally.
pub type Harness = fn(&[u8]);

/// The targets by name, for the regression runner.
pub const TARGETS: &[(&str, Harness)] = &[
    ("gasturb_map", gasturb_map),
    ("engine_config", engine_config),
    ("daemon_config", daemon_config),
    ("replay_csv", replay_csv),
    ("diagnose_csv", diagnose_csv),
    ("modbus_decode", modbus_decode),
];

/// A GasTurb map file (compressor or turbine).
pub fn gasturb_map(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(file) = gasturb::parse(&text, "fuzz") {
        // Touch what a parsed file exposes, so lazily-checked fields are exercised.
        let _ = format!("{file:?}");
    }
}

/// An engine file: parse, validate, and build the engine (design calibration) when valid.
pub fn engine_config(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(cfg) = EngineConfig::from_toml_str(&text, "fuzz.toml") {
        if cfg.validate("fuzz.toml").is_ok() {
            let _ = Engine::new(cfg);
        }
    }
}

/// The daemon configuration: parse and check (what `check-config` does).
pub fn daemon_config(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(cfg) = Config::parse(&text, "fuzz.toml") {
        let _ = cfg.check();
    }
}

/// A replay log: the bytes are written to a temporary CSV file and replayed into an in-memory
/// database, once with ISO-8601 times and once with epoch seconds (first byte chooses).
pub fn replay_csv(data: &[u8]) {
    let Some((&mode, body)) = data.split_first() else {
        return;
    };
    let Ok(dir) = tempfile::tempdir() else {
        return;
    };
    let path = dir.path().join("log.csv");
    if std::fs::write(&path, body).is_err() {
        return;
    }
    let Ok(mut store) = Store::open(&dir.path().join("fuzz.db")) else {
        return;
    };
    let cfg = ReplayConfig {
        time_column: if mode & 1 == 0 { "time" } else { "time_s" }.into(),
        time_format: if mode & 1 == 0 {
            TimeFormat::Iso8601
        } else {
            TimeFormat::EpochS
        },
        ..ReplayConfig::default()
    };
    let _ = replay_file(&mut store, &cfg, &path, Progress::Silent);
}

/// A `gtwatch diagnose --input` CSV: read into a recording and checked for a start-up.
pub fn diagnose_csv(data: &[u8]) {
    if let Ok(rec) = read_recording(data, &HashMap::new()) {
        let _ = rec.check_startup();
    }
}

/// Modbus register words decoded through the shipped register map (every request).
pub fn modbus_decode(data: &[u8]) {
    static SHIPPED: &str = include_str!("../config/gtwatch.toml");
    let Ok(cfg) = Config::parse(SHIPPED, "config/gtwatch.toml") else {
        return;
    };
    let Some(map) = cfg.modbus.as_ref() else {
        return;
    };
    let tags: Vec<i64> = (1..=map.fields().count() as i64).collect();
    let Ok(plan) = PollPlan::new(map, &tags) else {
        return;
    };
    let words: Vec<u16> = data
        .chunks(2)
        .map(|c| u16::from_be_bytes([c[0], *c.get(1).unwrap_or(&0)]))
        .collect();
    let mut out = Vec::new();
    for req in &plan.requests {
        decode_request(req, &words, 0, &mut out);
        let tail = words.get(1..).unwrap_or(&[]);
        decode_request(req, tail, i64::MAX, &mut out);
    }
}
