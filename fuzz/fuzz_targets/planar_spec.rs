#![no_main]
//! Fuzz target `planar_spec`: see `fuzz/harness.rs`.

#[path = "../harness.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::planar_spec(data));
