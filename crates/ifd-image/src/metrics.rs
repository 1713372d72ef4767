//! Image-quality metrics: PSNR, SSIM, maximum and mean absolute error, per
//! channel and overall.
//!
//! The derivation and conventions are documented on [`compare`].

use crate::{Image, ImageError};

/// The Gaussian SSIM window's standard deviation (scikit-image's default).
pub const SSIM_SIGMA: f64 = 1.5;
/// Truncation of the Gaussian SSIM window, in standard deviations.
pub const SSIM_TRUNCATE: f64 = 3.5;

/// Metrics of one channel (or all channels together).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// Peak signal-to-noise ratio in dB (infinite for identical inputs).
    pub psnr: f64,
    /// Structural similarity.
    pub ssim: f64,
    /// Largest absolute difference.
    pub max_abs: f64,
    /// Mean absolute difference.
    pub mean_abs: f64,
    /// Mean squared difference.
    pub mse: f64,
}

/// The result of [`compare`].
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// Over all channels (PSNR from the pooled MSE, SSIM the mean of channels).
    pub overall: Metrics,
    /// One entry per channel.
    pub channels: Vec<Metrics>,
    /// The data range used.
    pub data_range: f64,
}

/// Radius of the SSIM window (5 for sigma 1.5, as scipy computes it).
#[must_use]
pub fn ssim_radius() -> usize {
    (SSIM_TRUNCATE * SSIM_SIGMA + 0.5) as usize
}

/// Compares two images of the same shape.
///
/// # Errors
/// [`ImageError::Shape`] when the shapes differ or the image is smaller than
/// the 11x11 SSIM window; [`ImageError::InvalidParameter`] for a data range
/// that is not finite and positive.
///
/// The definitions match scikit-image so numbers can be compared directly:
/// - PSNR is `skimage.metrics.peak_signal_noise_ratio`:
///   `10 log10(R^2 / MSE)` with `R` the data range.
/// - SSIM is `skimage.metrics.structural_similarity(gaussian_weights=True,
///   sigma=1.5, use_sample_covariance=False, data_range=R)` (Wang et al. 2004):
///   local statistics under a Gaussian window (sigma 1.5, truncated at 3.5
///   sigma, i.e. an 11x11 window, borders by symmetric reflection as scipy's
///   `mode='reflect'`), `K1 = 0.01`, `K2 = 0.03`, the SSIM map averaged after
///   cropping 5 pixels from each side; for several channels the mean of the
///   per-channel values.
///
/// ```
/// use ifd_image::{Image, compare};
/// let a = Image::from_vec(16, 16, 1, (0..256).map(|i| (i % 16) as f32 / 15.0).collect())?;
/// let m = compare(&a, &a, 1.0)?;
/// assert!(m.overall.psnr.is_infinite());
/// assert!((m.overall.ssim - 1.0).abs() < 1e-12);
/// # Ok::<(), ifd_image::ImageError>(())
/// ```
pub fn compare(a: &Image, b: &Image, data_range: f64) -> Result<Comparison, ImageError> {
    if !a.same_shape(b) {
        return Err(ImageError::Shape(format!(
            "images differ in shape: {}x{} with {} channels vs {}x{} with {} channels",
            a.width(),
            a.height(),
            a.channels(),
            b.width(),
            b.height(),
            b.channels()
        )));
    }
    if !(data_range.is_finite() && data_range > 0.0) {
        return Err(ImageError::InvalidParameter(format!(
            "data range must be finite and positive, got {data_range}"
        )));
    }
    let win = 2 * ssim_radius() + 1;
    if a.width() < win || a.height() < win {
        return Err(ImageError::Shape(format!(
            "image is {}x{}; SSIM needs at least {win}x{win}",
            a.width(),
            a.height()
        )));
    }
    let channels: Vec<Metrics> = (0..a.channels())
        .map(|c| channel_metrics(&a.plane(c), &b.plane(c), a.width(), a.height(), data_range))
        .collect();
    let n = channels.len() as f64;
    let mse = channels.iter().map(|m| m.mse).sum::<f64>() / n;
    let overall = Metrics {
        psnr: psnr_from_mse(mse, data_range),
        ssim: channels.iter().map(|m| m.ssim).sum::<f64>() / n,
        max_abs: channels.iter().map(|m| m.max_abs).fold(0.0, f64::max),
        mean_abs: channels.iter().map(|m| m.mean_abs).sum::<f64>() / n,
        mse,
    };
    Ok(Comparison {
        overall,
        channels,
        data_range,
    })
}

/// PSNR in dB from a mean squared error.
#[must_use]
pub fn psnr_from_mse(mse: f64, data_range: f64) -> f64 {
    10.0 * (data_range * data_range / mse).log10()
}

/// PSNR of two equally long sample slices.
///
/// # Panics
/// When the lengths differ.
#[must_use]
pub fn psnr(a: &[f32], b: &[f32], data_range: f64) -> f64 {
    assert_eq!(a.len(), b.len());
    let mse = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = f64::from(x) - f64::from(y);
            d * d
        })
        .sum::<f64>()
        / a.len() as f64;
    psnr_from_mse(mse, data_range)
}

fn channel_metrics(a: &[f32], b: &[f32], w: usize, h: usize, range: f64) -> Metrics {
    let n = a.len() as f64;
    let (mut se, mut ae, mut max_abs) = (0.0, 0.0, 0.0f64);
    for (&x, &y) in a.iter().zip(b) {
        let d = f64::from(x) - f64::from(y);
        se += d * d;
        ae += d.abs();
        max_abs = max_abs.max(d.abs());
    }
    let mse = se / n;
    Metrics {
        psnr: psnr_from_mse(mse, range),
        ssim: ssim_plane(a, b, w, h, range),
        max_abs,
        mean_abs: ae / n,
        mse,
    }
}

/// SSIM of one plane (see the module docs for the definition).
fn ssim_plane(a: &[f32], b: &[f32], w: usize, h: usize, range: f64) -> f64 {
    let r = ssim_radius();
    let weights = gaussian_weights(SSIM_SIGMA, r);
    let a: Vec<f64> = a.iter().map(|&v| f64::from(v)).collect();
    let b: Vec<f64> = b.iter().map(|&v| f64::from(v)).collect();
    let aa: Vec<f64> = a.iter().map(|v| v * v).collect();
    let bb: Vec<f64> = b.iter().map(|v| v * v).collect();
    let ab: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x * y).collect();
    let [ux, uy, uxx, uyy, uxy] =
        [&a, &b, &aa, &bb, &ab].map(|p| separable_symmetric(p, w, h, &weights));
    let c1 = (0.01 * range).powi(2);
    let c2 = (0.03 * range).powi(2);
    let mut sum = 0.0;
    let mut count = 0usize;
    for y in r..h - r {
        for x in r..w - r {
            let i = y * w + x;
            let vx = uxx[i] - ux[i] * ux[i];
            let vy = uyy[i] - uy[i] * uy[i];
            let vxy = uxy[i] - ux[i] * uy[i];
            let num = (2.0 * ux[i] * uy[i] + c1) * (2.0 * vxy + c2);
            let den = (ux[i] * ux[i] + uy[i] * uy[i] + c1) * (vx + vy + c2);
            sum += num / den;
            count += 1;
        }
    }
    sum / count as f64
}

/// Normalised Gaussian weights `exp(-x^2 / (2 sigma^2))` for `x` in `-r..=r`.
fn gaussian_weights(sigma: f64, r: usize) -> Vec<f64> {
    let w: Vec<f64> = (-(r as i64)..=r as i64)
        .map(|x| (-0.5 * (x * x) as f64 / (sigma * sigma)).exp())
        .collect();
    let s: f64 = w.iter().sum();
    w.into_iter().map(|v| v / s).collect()
}

/// Symmetric reflection (`dcba|abcd`), valid for any offset.
fn reflect_symmetric(i: i64, n: usize) -> usize {
    let n = n as i64;
    let period = 2 * n;
    let m = i.rem_euclid(period);
    (if m < n { m } else { period - 1 - m }) as usize
}

fn separable_symmetric(p: &[f64], w: usize, h: usize, k: &[f64]) -> Vec<f64> {
    let r = (k.len() / 2) as i64;
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        let row = &p[y * w..(y + 1) * w];
        for x in 0..w {
            tmp[y * w + x] = k
                .iter()
                .enumerate()
                .map(|(j, kv)| kv * row[reflect_symmetric(x as i64 + j as i64 - r, w)])
                .sum();
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = k
                .iter()
                .enumerate()
                .map(|(j, kv)| kv * tmp[reflect_symmetric(y as i64 + j as i64 - r, h) * w + x])
                .sum();
        }
    }
    out
}

/// The data range PSNR and SSIM use when none is given (`ifd compare`, the
/// Python module): 1 when every value of both images lies in `[0, 1]` (all
/// 8/16-bit files), else `max - min` of the reference `a`, as scikit-image
/// does for float images outside `[0, 1]`.
///
/// ```
/// assert_eq!(ifd_image::default_data_range(&[0.0, 0.5], &[1.0, 0.2]), 1.0);
/// assert_eq!(ifd_image::default_data_range(&[-1.0, 3.0], &[0.0, 0.0]), 4.0);
/// ```
#[must_use]
pub fn default_data_range(a: &[f32], b: &[f32]) -> f64 {
    let in_unit = |d: &[f32]| d.iter().all(|v| (0.0..=1.0).contains(v));
    if in_unit(a) && in_unit(b) {
        return 1.0;
    }
    let (lo, hi) = a
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    f64::from(hi - lo)
}

/// Crops `n` pixels from every side.
///
/// # Errors
/// [`ImageError::Shape`] when nothing would remain.
pub fn crop_border(img: &Image, n: usize) -> Result<Image, ImageError> {
    if n == 0 {
        return Ok(img.clone());
    }
    let (w, h, c) = (img.width(), img.height(), img.channels());
    if 2 * n >= w || 2 * n >= h {
        return Err(ImageError::Shape(format!(
            "cannot crop {n} pixels from each side of a {w}x{h} image"
        )));
    }
    let (nw, nh) = (w - 2 * n, h - 2 * n);
    let mut data = Vec::with_capacity(nw * nh * c);
    for y in n..h - n {
        let start = (y * w + n) * c;
        data.extend_from_slice(&img.data()[start..start + nw * c]);
    }
    Image::from_vec(nw, nh, c, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflection_matches_scipy_reflect() {
        // scipy 'reflect' on [a b c]: ... c b a | a b c | c b a ...
        let seq: Vec<usize> = (-4..7).map(|i| reflect_symmetric(i, 3)).collect();
        assert_eq!(seq, vec![2, 2, 1, 0, 0, 1, 2, 2, 1, 0, 0]);
    }

    #[test]
    fn psnr_of_known_error() {
        let a = [0.0f32; 100];
        let b = [0.1f32; 100];
        assert!((psnr(&a, &b, 1.0) - 20.0).abs() < 1e-5);
    }

    #[test]
    fn ssim_drops_with_noise_and_is_symmetric() {
        let w = 32;
        let a: Vec<f32> = (0..w * w)
            .map(|i| ((i % w) as f32 / w as f32).sin())
            .collect();
        let b: Vec<f32> = a
            .iter()
            .enumerate()
            .map(|(i, v)| v + 0.05 * ((i * 7919 % 13) as f32 / 13.0 - 0.5))
            .collect();
        let ia = Image::from_vec(w, w, 1, a).unwrap();
        let ib = Image::from_vec(w, w, 1, b).unwrap();
        let ab = compare(&ia, &ib, 1.0).unwrap().overall.ssim;
        let ba = compare(&ib, &ia, 1.0).unwrap().overall.ssim;
        assert!(ab < 0.999 && ab > 0.0);
        assert!((ab - ba).abs() < 1e-12);
    }

    #[test]
    fn shape_errors() {
        let a = Image::new(16, 16, 1).unwrap();
        let b = Image::new(16, 16, 3).unwrap();
        assert!(
            compare(&a, &b, 1.0)
                .unwrap_err()
                .to_string()
                .contains("differ in shape")
        );
        let s = Image::new(8, 8, 1).unwrap();
        assert!(
            compare(&s, &s, 1.0)
                .unwrap_err()
                .to_string()
                .contains("at least 11x11")
        );
        assert!(compare(&a, &a, 0.0).is_err());
        assert!(crop_border(&a, 8).is_err());
        assert_eq!(crop_border(&a, 2).unwrap().width(), 12);
    }
}
