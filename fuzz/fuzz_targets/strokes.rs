#![no_main]
//! Fuzz target `strokes`: see `fuzz/harness_brush.rs`.

#[path = "../harness_brush.rs"]
mod harness_brush;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness_brush::strokes(data));
