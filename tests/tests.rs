//! Integration tests of the `ifd` facade: one test binary, one module per area.

mod fuzz_corpus;
mod image_io;
