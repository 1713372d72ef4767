//! Comparing a render with a reference over the object's pixels: the
//! relative RMS error, and the per-pixel relative difference that error maps
//! (`ifd render --error-map`, the environment renderer's split-sum view)
//! show.

use ifd_image::Image;

use crate::error::{RenderError, Result};

/// Relative RMS error of `a` against `b` over the masked pixels:
/// `sqrt(sum (a - b)^2 / sum b^2)` over all channels.
#[must_use]
pub fn relative_rms(a: &Image, b: &Image, mask: &[bool]) -> f64 {
    let ch = a.channels();
    let (mut num, mut den) = (0.0, 0.0);
    for (i, m) in mask.iter().enumerate() {
        if !m {
            continue;
        }
        for c in 0..ch {
            let (x, y) = (
                f64::from(a.data()[i * ch + c]),
                f64::from(b.data()[i * ch + c]),
            );
            num += (x - y) * (x - y);
            den += y * y;
        }
    }
    (num / den.max(f64::MIN_POSITIVE)).sqrt()
}

/// The percentile of the object's relative differences that
/// [`Difference::full_scale`] is.
pub const FULL_SCALE_PERCENTILE: usize = 95;

/// The darkest reference value, as a fraction of the object's mean, that
/// [`Difference::relative`] divides by.
pub const RELATIVE_FLOOR: f64 = 0.05;

/// How an image differs from a reference over the object's pixels.
///
/// ```
/// use ifd_image::Image;
/// use ifd_render::Difference;
/// let reference = Image::from_vec(2, 1, 1, vec![1.0, 2.0])?;
/// let image = Image::from_vec(2, 1, 1, vec![1.1, 2.0])?;
/// let d = Difference::new(&image, &reference, &[true, true])?;
/// assert!((d.relative[0] - 0.1).abs() < 1e-6 && d.relative[1] == 0.0);
/// assert!((d.max_abs - 0.1).abs() < 1e-6);
/// assert!((d.relative_rms - (0.01f64 / 5.0).sqrt()).abs() < 1e-6);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Difference {
    /// Per pixel, row-major: the difference summed over the channels,
    /// relative to the reference's sum, or to [`RELATIVE_FLOOR`] times its
    /// mean over the object where the pixel is darker than that (so that
    /// near-black texels do not dominate); 0 off the object.
    pub relative: Vec<f64>,
    /// The [`FULL_SCALE_PERCENTILE`]th percentile of `|relative|` over the
    /// object, the full scale of a colour map that a few hot pixels (a sun's,
    /// a lobe `L` does not resolve) do not wash out (1 when every difference
    /// is 0).
    pub full_scale: f64,
    /// [`relative_rms`] of the image against the reference.
    pub relative_rms: f64,
    /// The largest absolute difference of any channel.
    pub max_abs: f64,
    /// PSNR in dB, the reference's largest object value as the peak.
    pub psnr_db: f64,
}

impl Difference {
    /// `image` against `reference` over the pixels `mask` marks.
    ///
    /// # Errors
    /// [`RenderError::Parameter`] when the sizes or channel counts differ.
    pub fn new(image: &Image, reference: &Image, mask: &[bool]) -> Result<Self> {
        let ch = image.channels();
        if image.width() != reference.width()
            || image.height() != reference.height()
            || ch != reference.channels()
            || mask.len() != image.width() * image.height()
        {
            return Err(RenderError::Parameter {
                name: "the images compared",
                value: format!(
                    "{}x{}x{} against {}x{}x{}",
                    image.width(),
                    image.height(),
                    ch,
                    reference.width(),
                    reference.height(),
                    reference.channels()
                ),
                reason: "the sizes, channel counts and mask must agree".into(),
            });
        }
        let sums = || {
            reference
                .data()
                .chunks_exact(ch)
                .zip(mask)
                .filter(|(_, on)| **on)
                .map(|(r, _)| r.iter().map(|v| f64::from(*v)).sum::<f64>())
        };
        let objects = mask.iter().filter(|m| **m).count();
        let floor = RELATIVE_FLOOR * sums().sum::<f64>() / objects.max(1) as f64;
        let (mut se, mut n, mut peak, mut max_abs) = (0.0, 0usize, 0.0f64, 0.0f64);
        let relative: Vec<f64> = image
            .data()
            .chunks_exact(ch)
            .zip(reference.data().chunks_exact(ch))
            .zip(mask)
            .map(|((a, r), on)| {
                if !on {
                    return 0.0;
                }
                let (mut d, mut s) = (0.0, 0.0);
                for (x, y) in a.iter().zip(r) {
                    let (x, y) = (f64::from(*x), f64::from(*y));
                    se += (x - y) * (x - y);
                    n += 1;
                    peak = peak.max(y.abs());
                    max_abs = max_abs.max((x - y).abs());
                    d += x - y;
                    s += y;
                }
                let s = s.max(floor);
                if s > 0.0 { d / s } else { 0.0 }
            })
            .collect();
        let mut on: Vec<f64> = relative
            .iter()
            .zip(mask)
            .filter(|(_, m)| **m)
            .map(|(v, _)| v.abs())
            .collect();
        on.sort_by(f64::total_cmp);
        let pct = on
            .get((on.len() * FULL_SCALE_PERCENTILE / 100).min(on.len().saturating_sub(1)))
            .copied();
        Ok(Self {
            relative,
            full_scale: pct.filter(|v| *v > 0.0).unwrap_or(1.0),
            relative_rms: relative_rms(image, reference, mask),
            max_abs,
            psnr_db: ifd_image::psnr_from_mse(se / n.max(1) as f64, peak.max(1e-12)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_full_scale_ignores_the_hottest_pixels() {
        // 200 object pixels off by 1%, two off by 50%, one off the object
        let n = 203;
        let reference = Image::from_vec(n, 1, 1, vec![2.0; n]).expect("image");
        let mut v = vec![2.02f32; n];
        v[5] = 3.0;
        v[6] = 3.0;
        v[7] = 100.0;
        let image = Image::from_vec(n, 1, 1, v).expect("image");
        let mut mask = vec![true; n];
        mask[7] = false;
        let d = Difference::new(&image, &reference, &mask).expect("difference");
        assert!((d.full_scale - 0.01).abs() < 1e-6, "{}", d.full_scale);
        assert!((d.max_abs - 1.0).abs() < 1e-6, "{}", d.max_abs);
        assert_eq!(d.relative[7], 0.0, "off the object");
        // PSNR: peak 2, MSE (200 * 0.02^2 + 2 * 1) / 202
        let mse = (200.0 * 0.02f64.powi(2) + 2.0) / 202.0;
        let want = 10.0 * (4.0 / mse).log10();
        assert!((d.psnr_db - want).abs() < 1e-3, "{} vs {want}", d.psnr_db);
    }

    #[test]
    fn dark_pixels_are_measured_against_a_floor() {
        // mean 10.0005 over the object: a black pixel off by 0.1 is 0.1 / 0.5
        let reference = Image::from_vec(2, 1, 1, vec![20.0, 0.001]).expect("image");
        let image = Image::from_vec(2, 1, 1, vec![20.0, 0.101]).expect("image");
        let d = Difference::new(&image, &reference, &[true, true]).expect("difference");
        let want = 0.1 / (RELATIVE_FLOOR * 10.0005);
        assert!(
            (d.relative[1] - want).abs() < 1e-6,
            "{} vs {want}",
            d.relative[1]
        );
    }

    #[test]
    fn mismatched_images_are_refused() {
        let a = Image::from_vec(2, 1, 1, vec![0.0; 2]).expect("image");
        let b = Image::from_vec(1, 2, 1, vec![0.0; 2]).expect("image");
        assert!(Difference::new(&a, &b, &[true, true]).is_err());
        assert!(Difference::new(&a, &a, &[true]).is_err());
    }
}
