#![no_main]
//! Fuzz target `sphere_decomposition`: see `fuzz/harness.rs`.

#[path = "../harness.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::sphere_decomposition(data));
