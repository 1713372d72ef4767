#![no_main]
//! Fuzz target `brdf_table`: see `fuzz/harness.rs`.

#[path = "../harness.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::brdf_table(data));
