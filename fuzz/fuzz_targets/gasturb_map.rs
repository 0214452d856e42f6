#![no_main]
//! cargo-fuzz target `gasturb_map`: see `fuzz/targets.rs`.

#[path = "../targets.rs"]
#[allow(dead_code)]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| targets::gasturb_map(data));
