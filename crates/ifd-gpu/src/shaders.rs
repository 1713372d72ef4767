//! The WGSL sources (in the workspace's top-level `shaders/` folder), compiled
//! into the library. A test parses and validates every `.wgsl` file there
//! with naga.

/// The IFD evaluation kernel (`shaders/ifd_eval.wgsl`).
pub const IFD_EVAL: &str = include_str!("../../../shaders/ifd_eval.wgsl");

/// Result to `rgba8unorm` texture (`shaders/to_rgba8.wgsl`).
pub const TO_RGBA8: &str = include_str!("../../../shaders/to_rgba8.wgsl");

/// Brush-dab blend into an image on the device (`shaders/dab_blend.wgsl`).
pub const DAB_BLEND: &str = include_str!("../../../shaders/dab_blend.wgsl");
