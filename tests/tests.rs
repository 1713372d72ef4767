//! Integration tests of the `ifd` facade: one test binary, one module per area.

mod image_io;
