#![no_main]
//! cargo-fuzz target `replay_csv`: see `fuzz/targets.rs`.

#[path = "../targets.rs"]
#[allow(dead_code)]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| targets::replay_csv(data));
