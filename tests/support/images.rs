//! The synthetic test images the Rust tests and benches share, one
//! generator per kind of content, deterministic from their arguments.
//!
//! Included where needed with
//! `#[path = "<up to the workspace>/tests/support/images.rs"] mod images;`
//! (the crates' tests, benches and unit tests; no crate of its own, so no
//! extra test binary to link).

#![allow(dead_code, reason = "each includer uses the images it needs")]

use ifd_image::Image;

/// A `c`-channel image in `[0, 1]`: smooth shading, a hard-edged disk,
/// stripes that differ per channel and mild xorshift noise (the planar
/// filtering tests).
pub fn shapes(w: usize, h: usize, c: usize, seed: u64) -> Image {
    let mut state = seed | 1;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut data = Vec::with_capacity(w * h * c);
    for y in 0..h {
        for x in 0..w {
            for ch in 0..c {
                let (xf, yf) = (x as f32, y as f32);
                let mut v = 0.3 + 0.2 * (0.11 * xf + 0.07 * yf + ch as f32).sin();
                let (dx, dy) = (xf - 0.4 * w as f32, yf - 0.55 * h as f32);
                if dx * dx + dy * dy < (0.2 * w as f32).powi(2) {
                    v += 0.3;
                }
                if (x / 7 + y / 11) % 3 == ch % 3 {
                    v += 0.15;
                }
                v += 0.05 * next();
                data.push(v.clamp(0.0, 1.0));
            }
        }
    }
    Image::from_vec(w, h, c, data).expect("valid image")
}

/// A one-channel image: smooth shading, a raised disk of radius 150 at
/// `(400, 600)` and mild xorshift noise (the planar benches' large images).
pub fn disk_noise(w: usize, h: usize) -> Image {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let data = (0..w * h)
        .map(|i| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let noise = (state >> 40) as f32 / (1u64 << 24) as f32;
            let disk = if (x - 400.0).hypot(y - 600.0) < 150.0 {
                0.3
            } else {
                0.0
            };
            0.4 + 0.2 * (0.05 * x + 0.03 * y).sin() + disk + 0.05 * noise
        })
        .collect();
    Image::from_vec(w, h, 1, data).expect("valid image")
}

/// A one-channel image: smooth waves plus a sharp diagonal edge (the
/// smoothing tests: the edge gives the Hessian a direction).
pub fn edge_waves(w: usize, h: usize) -> Image {
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let edge = if x + 0.5 * y > 40.0 { 0.8 } else { 0.2 };
            edge + 0.1 * (x / 7.0).sin() * (y / 9.0).cos()
        })
        .collect();
    Image::from_vec(w, h, 1, data).expect("valid image")
}

/// A xorshift64 generator's draws in `[0, 1)` (53 bits each), from `seed`
/// (not zero): the planar tests' and benches' random decompositions, fields
/// and noise.
pub fn xorshift(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Noise from `uniform` (a generator's draws in `[0, 1)`, e.g.
/// `ifd_sphere::SplitMix64::uniform`), `ch` channels (the spherical
/// transform tests).
pub fn uniform_noise(w: usize, h: usize, ch: usize, mut uniform: impl FnMut() -> f64) -> Image {
    let data = (0..w * h * ch).map(|_| uniform() as f32).collect();
    Image::from_vec(w, h, ch, data).expect("valid image")
}

/// Uniform noise in `[0, 1)` from a 32-bit linear congruential generator,
/// `c` channels (the stack refresh's unit tests).
pub fn lcg_noise(w: usize, h: usize, c: usize, seed: u32) -> Image {
    let mut s = seed;
    let data = (0..w * h * c)
        .map(|_| {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 8) as f32 / (1u32 << 24) as f32
        })
        .collect();
    Image::from_vec(w, h, c, data).expect("valid image")
}
