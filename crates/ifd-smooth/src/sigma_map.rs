//! A normalised anisotropic Gaussian per pixel, given by a sigma map:
//! `ifd filter IMAGE --kernel gauss --sigma-map M.npy`.
//!
//! The conventions are documented on [`filter_sigma_map`].

use ifd_image::{Image, ImageView};
use ifd_planar::{
    Border, Filter, MAX_FIELD_VALUE, PreparedDecomposition, Sampling, StackPlan, sigma_bounds,
};
use rayon::prelude::*;

use crate::bank::AspectBank;
use crate::error::SmoothError;
use crate::gaussians::{AnisoGaussian, BankLookups, PixelGaussians, SmallFootprints};
use crate::smooth::smoother_stack_options;

/// How the bank's entries are applied on the sigma-map path: as the
/// continuous sum of Gaussians sampled at pixel centres at every scale, so
/// that each pixel's filter is the *sampled* anisotropic Gaussian (what
/// `ifd filter --kernel gauss:sx=..,sy=..` applies), where smoothing applies
/// the pixel-averaged one ([`crate::BANK_SAMPLING`]).
pub const SIGMA_MAP_SAMPLING: Sampling = Sampling::Continuous;

/// Largest standard deviation a sigma map may hold, pixels (and at most a
/// quarter of the image's larger side).
pub const SIGMA_MAP_MAX_SIGMA: f64 = 512.0;

/// The names of a sigma map's channels, for messages.
pub const SIGMA_MAP_CHANNELS: [&str; 3] = ["major sigma", "minor sigma", "angle"];

/// Checks a sigma map for a `width x height` image and reads its
/// Gaussians (row-major).
///
/// The map is `width x height x 3`: per pixel the standard deviation along
/// the major axis, the one along the minor axis (pixels, `0 < minor <=
/// major`) and the major axis' angle in degrees counter-clockwise on screen.
///
/// ```
/// use ifd_image::ImageView;
/// // two pixels: the second has its minor sigma larger than its major one
/// let map = [0.4f32, 0.2, 30.0, 0.1, 0.3, 0.0];
/// let m = ImageView::new(2, 1, 3, &map)?;
/// let err = ifd_smooth::sigma_map_gaussians(m, (2, 1), 16.0).unwrap_err();
/// assert!(err.to_string().contains("(1, 0), channel 1 (minor sigma)"), "{err}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`SmoothError::BadImage`] for a map of another shape, and naming the
/// first bad pixel as `(x, y)` and its channel: a value that is not finite,
/// a sigma that is not positive, a minor sigma larger than the major one
/// (swap them), an absurd sigma (above [`SIGMA_MAP_MAX_SIGMA`] or a quarter
/// of the image's larger side), an aspect ratio `major / minor` above
/// `max_aspect` (the bank's), an absurd angle (magnitude above
/// [`MAX_FIELD_VALUE`]).
pub fn sigma_map_gaussians(
    map: ImageView<'_>,
    (width, height): (usize, usize),
    max_aspect: f64,
) -> Result<Vec<AnisoGaussian>, SmoothError> {
    if (map.width(), map.height(), map.channels()) != (width, height, 3) {
        return Err(SmoothError::BadImage(format!(
            "sigma map is {}x{}x{} (width x height x channels), expected {width}x{height}x3: the \
             image's size, with the channels (major sigma, minor sigma, angle)",
            map.width(),
            map.height(),
            map.channels()
        )));
    }
    let limit = (width.max(height) as f64 / 4.0).min(SIGMA_MAP_MAX_SIGMA);
    let data = map.data();
    let mut out = Vec::with_capacity(width * height);
    for (i, px) in data.chunks_exact(3).enumerate() {
        let (x, y) = (i % width, i / width);
        let bad = |k: usize, why: String| {
            SmoothError::BadImage(format!(
                "sigma map: pixel ({x}, {y}), channel {k} ({}): {why}",
                SIGMA_MAP_CHANNELS[k]
            ))
        };
        for (k, v) in px.iter().enumerate() {
            if !v.is_finite() {
                return Err(bad(k, format!("{v} is not finite (NaN or infinite)")));
            }
        }
        let (major, minor, angle) = (f64::from(px[0]), f64::from(px[1]), px[2]);
        for (k, v) in [(0, major), (1, minor)] {
            if v <= 0.0 {
                return Err(bad(k, format!("{v} px: sigmas must be positive")));
            }
        }
        if minor > major {
            return Err(bad(
                1,
                format!(
                    "{minor} px is larger than the major sigma {major} px: swap channels 0 and 1 \
                     (and turn the angle by 90 degrees)"
                ),
            ));
        }
        if major > limit {
            return Err(bad(
                0,
                format!(
                    "{major} px is absurd: above {limit} px (a quarter of the image's larger side, \
                     at most {SIGMA_MAP_MAX_SIGMA})"
                ),
            ));
        }
        let aspect = major / minor;
        if aspect > max_aspect * (1.0 + 1e-6) {
            return Err(bad(
                1,
                format!(
                    "aspect ratio {major} / {minor} = {} is above the bank's largest, {max_aspect}",
                    ifd_image::short_number(aspect)
                ),
            ));
        }
        if angle.abs() > MAX_FIELD_VALUE {
            return Err(bad(
                2,
                format!("{angle} degrees is absurd (above {MAX_FIELD_VALUE:e} in magnitude)"),
            ));
        }
        out.push(AnisoGaussian::from_sigmas(major, minor, f64::from(angle)));
    }
    Ok(out)
}

/// Filters `image` with a normalised anisotropic Gaussian per pixel, given
/// by the sigma `map` (see [`sigma_map_gaussians`]).
///
/// Each pixel's Gaussian, of footprint `S = sqrt(major minor)`, aspect
/// `major / minor` and angle `theta`, is applied as smoothing applies its
/// Gaussians ([`PixelGaussians`]): the blend of the two bank entries around
/// its aspect ratio, rotated by `theta` and scaled by `S / sigma_ref`, one
/// stack lookup per term, the stack spanning the footprints of the map.
/// Gaussians with `S` below [`crate::SAMPLED_BELOW`] or a minor sigma below
/// [`crate::SAMPLED_MINOR_BELOW`] are sampled and correlated directly. The
/// filter is the sampled Gaussian normalised to sum 1 (the bank's entries
/// have unit DC gain; [`SIGMA_MAP_SAMPLING`]), read as correlation.
///
/// # Errors
/// As [`sigma_map_gaussians`] (with the bank's largest aspect ratio);
/// [`SmoothError::BadImage`] for NaN or infinite pixels; prefiltering
/// errors.
pub fn filter_sigma_map<'a>(
    image: impl Into<ImageView<'a>>,
    map: ImageView<'_>,
    bank: &AspectBank,
    border: Border,
) -> Result<Image, SmoothError> {
    let image = image.into();
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let gaussians = sigma_map_gaussians(map, (w, h), bank.options.max_aspect)?;
    let n_bad = image.count_non_finite();
    if n_bad > 0 {
        return Err(SmoothError::BadImage(format!(
            "image has {n_bad} NaN or infinite values; replace them first"
        )));
    }
    // The footprints read from the stack.
    let (lo, hi) = gaussians
        .iter()
        .filter(|g| !PixelGaussians::sampled_directly(**g))
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), g| {
            let s = f64::from(g.footprint);
            (lo.min(s), hi.max(s))
        });
    let prepared = bank
        .terms
        .iter()
        .map(|t| PreparedDecomposition::from_terms(t, SIGMA_MAP_SAMPLING))
        .collect::<Result<Vec<_>, _>>()?;
    let stack = if hi > 0.0 {
        let r = bank.options.sigma_ref;
        let sigmas = sigma_bounds(SIGMA_MAP_SAMPLING, bank.sigma_range(), (lo / r, hi / r));
        let plan = StackPlan {
            dims: (w, h, c),
            sigmas,
            border,
            options: smoother_stack_options(bank, hi, (w, h, c), sigmas),
        };
        Some(plan.build(image)?)
    } else {
        None
    };
    let filters = match &stack {
        Some(stack) => prepared
            .iter()
            .map(|d| Filter::new(stack, d))
            .collect::<Result<Vec<_>, _>>()?,
        None => Vec::new(),
    };
    let lookups = stack.is_some().then_some(BankLookups::Varying(&filters));
    let gauss = PixelGaussians::new(
        bank,
        lookups,
        Some(SmallFootprints::Sampled { image }),
        border,
    );
    let mut out = vec![0.0f32; w * h * c];
    out.par_chunks_mut(w * c).enumerate().for_each(|(y, row)| {
        for (x, px) in row.chunks_exact_mut(c).enumerate() {
            gauss.accumulate(x as f32, y as f32, gaussians[y * w + x], 1.0, px);
        }
    });
    Ok(Image::from_vec(w, h, c, out)?)
}
