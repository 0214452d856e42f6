#![no_main]
//! cargo-fuzz target `engine_config`: see `fuzz/targets.rs`.

#[path = "../targets.rs"]
#[allow(dead_code)]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| targets::engine_config(data));
