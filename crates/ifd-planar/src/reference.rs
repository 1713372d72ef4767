//! Brute-force references, written independently of the scale stack: the
//! ground truth for tests and the brute-force side of benchmarks.
//!
//! Both compute correlation (`out(p) = sum_d k(d) f(p + d)`, as
//! `cv2.filter2D`) over the border-extended image.
//!
//! ```
//! use ifd_image::Image;
//! use ifd_planar::{Border, internals::reference};
//! let mut img = Image::new(5, 5, 1)?;
//! img.set(2, 2, 0, 1.0);
//! // Correlation with a kernel that is 1 at offset (+1, 0) fetches the right neighbour.
//! let k = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
//! let out = reference::correlate(&img, &k, 3, 3, Border::Reflect101)?;
//! assert_eq!(out.get(1, 2, 0), 1.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::ops::Range;

use ifd_image::Image;
use rayon::prelude::*;

use crate::border::{Border, extend};
use crate::error::FilterError;
use crate::field::{CheckField, FieldKind};
use crate::stack::check_finite;

/// Largest kernel radius the references accept.
const MAX_RADIUS: usize = 4096;

fn check_image(image: &Image, border: Border) -> Result<(), FilterError> {
    check_finite(image.data(), image.width(), image.channels())?;
    if !border.constant().is_finite() {
        return Err(FilterError::InvalidBorder(border.to_string()));
    }
    Ok(())
}

/// Correlates every channel of `image` with a constant `kw x kh` kernel
/// (row-major, odd sizes, centre at `(kw / 2, kh / 2)`):
/// `out(x, y) = sum_{i,j} kernel[j][i] f(x + i - kw/2, y + j - kh/2)`.
///
/// Rayon-parallel over rows; each kernel tap is an `axpy` over a whole row.
///
/// # Errors
/// [`FilterError::Shape`] for even, zero or inconsistent kernel sizes,
/// [`FilterError::NonFinite`] for a NaN in the image or kernel.
pub fn correlate(
    image: &Image,
    kernel: &[f32],
    kw: usize,
    kh: usize,
    border: Border,
) -> Result<Image, FilterError> {
    if kw.is_multiple_of(2)
        || kh.is_multiple_of(2)
        || kernel.len() != kw * kh
        || kw / 2 > MAX_RADIUS
        || kh / 2 > MAX_RADIUS
    {
        return Err(FilterError::Shape(format!(
            "kernel is {kw}x{kh} with {} values; expected odd sizes up to {} and {} values",
            kernel.len(),
            2 * MAX_RADIUS + 1,
            kw * kh
        )));
    }
    check_finite(kernel, kw, 1).map_err(|e| match e {
        FilterError::NonFinite { count, x, y, .. } => FilterError::NonFinite {
            what: "kernel",
            count,
            x,
            y,
            channel: 0,
        },
        other => other,
    })?;
    check_image(image, border)?;
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let (rx, ry) = (kw / 2, kh / 2);
    let (ext, ew) = extend(image, rx, ry, border);
    let mut out = vec![0.0f32; w * h * c];
    out.par_chunks_mut(w * c).enumerate().for_each(|(y, row)| {
        for j in 0..kh {
            let erow = &ext[(y + j) * ew * c..(y + j + 1) * ew * c];
            for i in 0..kw {
                let k = kernel[j * kw + i];
                if k == 0.0 {
                    continue;
                }
                let src = &erow[i * c..i * c + w * c];
                for (o, &v) in row.iter_mut().zip(src) {
                    *o += k * v;
                }
            }
        }
    });
    Image::from_vec(w, h, c, out).map_err(|e| FilterError::Shape(e.to_string()))
}

/// Samples `k_{theta,s}(d) = k(R_{-theta} d / s) / s^2` on the
/// `(2 radius + 1)^2` grid of integer offsets (row-major, centre in the
/// middle), for use with [`correlate`].
///
/// `R_{-theta} d = (cos theta dx - sin theta dy, sin theta dx + cos theta dy)`
/// in `(x right, y down)` coordinates, `theta` in degrees counter-clockwise on
/// screen.
#[must_use]
pub fn sample_kernel<K: Fn(f64, f64) -> f64>(k: K, theta: f64, s: f64, radius: usize) -> Vec<f32> {
    let (sin, cos) = theta.to_radians().sin_cos();
    let r = radius as i64;
    let inv_s = 1.0 / s;
    let norm = inv_s * inv_s;
    let mut out = Vec::with_capacity((2 * radius + 1) * (2 * radius + 1));
    for dy in -r..=r {
        for dx in -r..=r {
            let (dx, dy) = (dx as f64, dy as f64);
            let u = (cos * dx - sin * dy) * inv_s;
            let v = (sin * dx + cos * dy) * inv_s;
            out.push((k(u, v) * norm) as f32);
        }
    }
    out
}

/// Spatially varying correlation: at pixel `p` the kernel is
/// `k_{theta(p), s(p)}(d) = k(R_{-theta} d / s) / s^2`, evaluated from the
/// closure for every integer offset `d` with `|dx|, |dy| <= radius`.
///
/// Costs `(2 radius + 1)^2` closure calls per pixel; rayon-parallel over rows.
///
/// # Errors
/// As [`correlate_varying_rows`].
pub fn correlate_varying<'f, K: Fn(f64, f64) -> f64 + Sync>(
    image: &Image,
    radius: usize,
    angle: impl CheckField<'f>,
    scale: impl CheckField<'f>,
    border: Border,
    k: K,
) -> Result<Image, FilterError> {
    correlate_varying_rows(image, radius, angle, scale, border, k, 0..image.height())
}

/// As [`correlate_varying`], for the rows `rows` only (the result has
/// `rows.len()` rows): lets benchmarks time a sample of rows of a large image.
///
/// # Errors
/// [`FilterError::MapSize`]/[`FilterError::InvalidValue`] for bad angle or
/// scale fields, [`FilterError::NonFinite`] for NaN pixels,
/// [`FilterError::InvalidParameter`] for a radius over 4096 or rows outside
/// the image.
pub fn correlate_varying_rows<'f, K: Fn(f64, f64) -> f64 + Sync>(
    image: &Image,
    radius: usize,
    angle: impl CheckField<'f>,
    scale: impl CheckField<'f>,
    border: Border,
    k: K,
    rows: Range<usize>,
) -> Result<Image, FilterError> {
    let (w, h, c) = (image.width(), image.height(), image.channels());
    if radius > MAX_RADIUS {
        return Err(FilterError::InvalidParameter(format!(
            "radius {radius} is larger than {MAX_RADIUS}"
        )));
    }
    if rows.start >= rows.end || rows.end > h {
        return Err(FilterError::InvalidParameter(format!(
            "rows {rows:?} are not a non-empty range inside 0..{h}"
        )));
    }
    let angle = angle.check(FieldKind::Angle, w, h)?;
    let scale = scale.check(FieldKind::Scale, w, h)?;
    check_image(image, border)?;
    let (ext, ew) = extend(image, radius, radius, border);
    let n = 2 * radius + 1;
    let r = radius as i64;
    let mut out = vec![0.0f32; w * rows.len() * c];
    let first = rows.start;
    // Parallel over pixels, not rows: a benchmark timing a few rows of a
    // large kernel then uses every core, as the filter it is compared with.
    out.par_chunks_mut(c).enumerate().for_each_init(
        || vec![0.0f64; c],
        |acc, (k_px, px)| {
            let (y, x) = (first + k_px / w, k_px % w);
            let i = y * w + x;
            let (sin, cos) = f64::from(angle.at(i)).to_radians().sin_cos();
            let s = f64::from(scale.at(i));
            let inv_s = 1.0 / s;
            let norm = inv_s * inv_s;
            acc.fill(0.0);
            for j in 0..n {
                let dy = (j as i64 - r) as f64;
                let erow = &ext[((y + j) * ew + x) * c..((y + j) * ew + x + n) * c];
                for (ii, src) in erow.chunks_exact(c).enumerate() {
                    let dx = (ii as i64 - r) as f64;
                    let u = (cos * dx - sin * dy) * inv_s;
                    let v = (sin * dx + cos * dy) * inv_s;
                    let kv = k(u, v);
                    if kv == 0.0 {
                        continue;
                    }
                    for (a, &f) in acc.iter_mut().zip(src) {
                        *a += kv * f64::from(f);
                    }
                }
            }
            for (o, a) in px.iter_mut().zip(acc.iter()) {
                *o = (a * norm) as f32;
            }
        },
    );
    Image::from_vec(w, rows.len(), c, out).map_err(|e| FilterError::Shape(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Field;

    #[test]
    fn correlate_is_correlation_not_convolution() {
        let mut img = Image::new(7, 5, 1).expect("image");
        img.set(3, 2, 0, 1.0);
        // Kernel with a single 1 at (dx, dy) = (1, -1).
        let mut k = vec![0.0f32; 9];
        k[2] = 1.0;
        let out = correlate(&img, &k, 3, 3, Border::Constant(0.0)).expect("ok");
        // out(p) = f(p + (1, -1)), so the impulse appears at (2, 3).
        assert_eq!(out.get(2, 3, 0), 1.0);
        assert_eq!(out.data().iter().sum::<f32>(), 1.0);
    }

    #[test]
    fn varying_matches_constant() {
        let img = Image::from_vec(9, 8, 2, (0..144).map(|i| ((i * 37) % 11) as f32).collect())
            .expect("image");
        let kf = |u: f64, v: f64| (-(u * u / 4.0 + v * v)).exp() * (1.0 + 0.3 * u);
        for border in [
            Border::Reflect101,
            Border::Replicate,
            Border::Wrap,
            Border::Constant(2.0),
        ] {
            let k = sample_kernel(kf, 30.0, 1.5, 3);
            let a = correlate(&img, &k, 7, 7, border).expect("ok");
            let b = correlate_varying(
                &img,
                3,
                Field::Constant(30.0),
                Field::Constant(1.5),
                border,
                kf,
            )
            .expect("ok");
            for (x, y) in a.data().iter().zip(b.data()) {
                assert!((x - y).abs() < 1e-4, "{border}: {x} vs {y}");
            }
        }
    }

    #[test]
    fn bad_inputs() {
        let img = Image::new(4, 4, 1).expect("image");
        assert!(correlate(&img, &[1.0; 4], 2, 2, Border::Reflect101).is_err());
        assert!(correlate(&img, &[1.0; 8], 3, 3, Border::Reflect101).is_err());
        assert!(correlate(&img, &[f32::NAN; 1], 1, 1, Border::Reflect101).is_err());
        let kf = |_: f64, _: f64| 1.0;
        assert!(matches!(
            correlate_varying(
                &img,
                1,
                Field::Map(&[0.0; 3]),
                Field::Constant(1.0),
                Border::Wrap,
                kf
            ),
            Err(FilterError::MapSize { .. })
        ));
        assert!(
            correlate_varying(
                &img,
                1,
                Field::Constant(0.0),
                Field::Constant(-1.0),
                Border::Wrap,
                kf
            )
            .is_err()
        );
        assert!(
            correlate_varying_rows(
                &img,
                1,
                Field::Constant(0.0),
                Field::Constant(1.0),
                Border::Wrap,
                kf,
                2..9
            )
            .is_err()
        );
    }
}
