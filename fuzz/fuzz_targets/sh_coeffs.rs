#![no_main]
//! Fuzz target `sh_coeffs`: see `fuzz/harness.rs`.

#[path = "../harness.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::sh_coeffs(data));
