//! Shared helpers of the brush tests.
#![allow(dead_code, reason = "each test binary uses a subset")]

use std::path::{Path, PathBuf};

use ifd_brush::engine::Banks;
use ifd_image::Image;

/// The aspect-bank cache shared by the test binaries (fitted once).
pub fn bank_cache() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("ifd-brush-test-bank.json")
}

/// The banks, from the shared cache.
pub fn banks() -> Banks {
    Banks::load_or_build(Some(&bank_cache()), |_, _| {}).expect("banks")
}

/// A crop of the bundled photo.
pub fn crop(x0: usize, y0: usize, w: usize, h: usize) -> Image {
    let img = ifd_image::read(ifd_brush::app::bundled_image()).expect("bundled image");
    let data = (0..w * h)
        .map(|i| img.get(x0 + i % w, y0 + i / w, 0))
        .collect();
    Image::from_vec(w, h, 1, data).expect("crop")
}

/// Largest absolute difference.
pub fn max_diff(a: &Image, b: &Image) -> f32 {
    assert!(a.same_shape(b));
    a.data()
        .iter()
        .zip(b.data())
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f32::max)
}
