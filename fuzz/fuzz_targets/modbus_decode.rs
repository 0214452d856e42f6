#![no_main]
//! cargo-fuzz target `modbus_decode`: see `fuzz/targets.rs`.

#[path = "../targets.rs"]
#[allow(dead_code)]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| targets::modbus_decode(data));
