//! `gtwatch check-config`: the reference config passes; broken configs get every problem
//! explained with its key path (exact messages).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use std::process::Command;

fn check(file: &str) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["check-config", file])
        .output()
        .expect("run gtwatch");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn reference_config_passes() {
    let (ok, stdout, stderr) = check("config/gtwatch.toml");
    assert!(ok, "{stderr}");
    assert!(stdout.starts_with("config/gtwatch.toml: OK"), "{stdout}");
    assert!(stdout.contains("2 request(s), 13 tag(s)"), "{stdout}");
}

#[test]
fn register_map_mistakes_are_all_explained() {
    let (ok, _, stderr) = check("tests/data/config_bad_map.toml");
    assert!(!ok);
    let expected = "\
tests/data/config_bad_map.toml: 8 problem(s)
  modbus.request[0].start_address: 40001 looks like the 1-based Modicon notation for holding register 1 (4xxxx); addresses here are 0-based, so write 0
  modbus.request[0].field[0].address: 40001 looks like the 1-based Modicon notation for holding register 1 (4xxxx); addresses here are 0-based, so write 0
  modbus.request[1].slave_id: slave id 0 is the broadcast address and cannot be read; use 1–255 (255 or 1 for most TCP devices)
  modbus.request[1].field[1].address: registers 1–2 (f32 input, slave 0) overlap field 't2_k' (modbus.request[1].field[0])
  modbus.request[1].field[2].type: f32 needs 2 registers (4–5) but the request reads only 0–4 (count = 5): the type is wider than the registers left
  modbus.request[2].count: request spans 131 registers (100–230); one Modbus read may ask for at most 125: split it into several requests
  modbus.request[2].field[1].max: max (5) must be greater than min (10)
  modbus.request: missing required tags for diagnosis: fuel_flow (add a field with signal = \"…\" for each)
";
    assert_eq!(stderr, expected);
}

#[test]
fn problems_in_every_section_are_listed() {
    let (ok, _, stderr) = check("tests/data/config_bad_sections.toml");
    assert!(!ok);
    let expected = "\
tests/data/config_bad_sections.toml: 6 problem(s)
  plant.name: must not be empty
  storage.batch_size: must be at least 1
  detector.light_off_speed_rpm: must not be above purge_speed_rpm (2500 > 2300)
  acquisition.poll_period_ms: 0 ms is outside 1 ms … 1 h
  acquisition.backoff_max_ms: cap 100 ms is below backoff_initial_ms 1000 ms
  daemon.detect_interval_ms: must be at least 100 ms
";
    assert_eq!(stderr, expected);
}

#[test]
fn unknown_key_names_file_line_and_column() {
    let (ok, _, stderr) = check("tests/data/config_unknown_key.toml");
    assert!(!ok);
    assert!(
        stderr.starts_with(
            "tests/data/config_unknown_key.toml:6:1: unknown field `request_timout_ms`, \
             expected one of `source`, `poll_period_ms`"
        ),
        "{stderr}"
    );
}
