//! The separable Gaussian blur of the structure tensor's planes and its
//! radius, which region refreshes and tiles add as a halo.

use ifd_planar::Border;
use rayon::prelude::*;

/// The radius, in pixels, of the tensor blur of sigma `sigma`: `ceil(3
/// sigma)`, 0 (no blur) below 0.3 px. What [`gaussian_blur`] reads and what
/// region refreshes and tiles add for it.
pub(crate) fn blur_radius(sigma: f64) -> usize {
    if sigma < 0.3 {
        0
    } else {
        (3.0 * sigma).ceil() as usize
    }
}

/// The normalised taps `-r..=r` of the Gaussian of sigma `sigma`.
pub(super) fn blur_kernel(sigma: f64, r: i64) -> Vec<f32> {
    let k: Vec<f32> = (-r..=r)
        .map(|i| (-0.5 * (i * i) as f64 / (sigma * sigma)).exp() as f32)
        .collect();
    let ks: f32 = k.iter().sum();
    k.into_iter().map(|v| v / ks).collect()
}

/// Reflect-101 index of `i` into `0..n` (the blur's border; `n >= 1`).
pub(super) fn reflect(i: i64, n: usize) -> usize {
    Border::Reflect101.resolve(i, n).unwrap_or(0)
}

/// Separable Gaussian blur of a plane (reflect-101 border, radius
/// [`blur_radius`]).
pub(super) fn gaussian_blur(p: &[f32], w: usize, h: usize, sigma: f64) -> Vec<f32> {
    let r = blur_radius(sigma) as i64;
    if r == 0 {
        return p.to_vec();
    }
    let k = blur_kernel(sigma, r);
    let mut tmp = vec![0.0f32; w * h];
    tmp.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let src = &p[y * w..(y + 1) * w];
        for (x, o) in row.iter_mut().enumerate() {
            *o = k
                .iter()
                .enumerate()
                .map(|(j, kv)| kv * src[reflect(x as i64 + j as i64 - r, w)])
                .sum();
        }
    });
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            *o = k
                .iter()
                .enumerate()
                .map(|(j, kv)| kv * tmp[reflect(y as i64 + j as i64 - r, h) * w + x])
                .sum();
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blur_preserves_constants() {
        let p = vec![2.0f32; 30 * 20];
        let b = gaussian_blur(&p, 30, 20, 2.5);
        assert!(b.iter().all(|v| (v - 2.0).abs() < 1e-5));
    }
}
