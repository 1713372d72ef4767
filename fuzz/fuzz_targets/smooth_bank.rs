#![no_main]
//! Fuzz target `smooth_bank`: see `fuzz/harness.rs`.

#[path = "../harness.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::smooth_bank(data));
