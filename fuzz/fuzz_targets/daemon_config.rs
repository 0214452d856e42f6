#![no_main]
//! cargo-fuzz target `daemon_config`: see `fuzz/targets.rs`.

#[path = "../targets.rs"]
#[allow(dead_code)]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| targets::daemon_config(data));
