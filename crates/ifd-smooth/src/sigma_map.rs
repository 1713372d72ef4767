//! A normalised anisotropic Gaussian per pixel, given by a sigma map:
//! `ifd filter IMAGE --kernel gauss --sigma-map M.npy`.
//!
//! The conventions are documented on [`filter_sigma_map`].

use ifd_image::{Image, ImageView};
use ifd_planar::{
    Border, Field, Filter, MAX_FIELD_VALUE, PreparedDecomposition, Sampling, ScaleStack,
    StackOptions, StackPlan, sigma_bounds,
};
use rayon::prelude::*;

use crate::bank::AspectBank;
use crate::error::SmoothError;
use crate::gaussians::{
    AnisoGaussian, NO_SHARES, PixelGaussians, SmallFootprints, bank_passes, shares_of,
};
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
    let prepared = prepared_bank(bank)?;
    let (stack, footprints) = sigma_map_stack(&gaussians, bank, image, border)?;
    let mut out = Image::new(w, h, c)?;
    if let Some(stack) = &stack {
        bank_lookups(&gaussians, bank, stack, &prepared, footprints, &mut out)?;
    }
    // The small footprints, sampled directly.
    let gauss = PixelGaussians::new(bank, None, Some(SmallFootprints::Sampled { image }), border);
    out.data_mut()
        .par_chunks_mut(w * c)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.chunks_exact_mut(c).enumerate() {
                let g = gaussians[y * w + x];
                if PixelGaussians::sampled_directly(g) {
                    gauss.accumulate(x as f32, y as f32, g, 1.0, px);
                }
            }
        });
    Ok(out)
}

/// The sigma map's stack reads its levels through the cubic B-spline as
/// smoothing does, but at pyramid factor 2 where smoothing takes 8 (for the
/// Hessian's derivative filters, whose weights cancel). For the bank's
/// Gaussians that is enough: the plans [`ifd_planar::EvalPlan::choose`]
/// makes for the entries of a structure-tensor map at bank tolerances 0.01
/// to 0.1 (a budget of a third of the tolerance) read no finer (cubic at
/// factor 2 or coarser, or bilinear), and on that map of `camera.png` the
/// output's PSNR is the same as at factor 8 to 0.1 dB, and 8 px footprints
/// are filtered 1.2-1.7x sooner.
const SIGMA_MAP_PYRAMID_FACTOR: f64 = 2.0;

/// Footprints of a sigma map within this relative spread are one (their
/// geometric mean): a map written as `S sqrt(a)` and `S / sqrt(a)` in
/// `f32` spreads `S` by a few `1e-7` (the filter's relative change is
/// about the spread).
const ONE_FOOTPRINT: f64 = 1e-6;

/// The bank's entries prepared for the sigma map's sampling.
fn prepared_bank(bank: &AspectBank) -> Result<Vec<PreparedDecomposition>, SmoothError> {
    Ok(bank
        .terms
        .iter()
        .map(|t| PreparedDecomposition::from_terms(t, SIGMA_MAP_SAMPLING))
        .collect::<Result<Vec<_>, _>>()?)
}

/// The stack spanning the footprints of the Gaussians not sampled directly,
/// and the least and largest of them (`None` when every one is sampled
/// directly).
fn sigma_map_stack(
    gaussians: &[AnisoGaussian],
    bank: &AspectBank,
    image: ImageView<'_>,
    border: Border,
) -> Result<(Option<ScaleStack>, (f64, f64)), SmoothError> {
    let (lo, hi) = gaussians
        .iter()
        .filter(|g| !PixelGaussians::sampled_directly(**g))
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), g| {
            let s = f64::from(g.footprint);
            (lo.min(s), hi.max(s))
        });
    if hi == 0.0 {
        return Ok((None, (lo, hi)));
    }
    let r = bank.options.sigma_ref;
    let sigmas = sigma_bounds(SIGMA_MAP_SAMPLING, bank.sigma_range(), (lo / r, hi / r));
    let dims = (image.width(), image.height(), image.channels());
    let plan = StackPlan {
        dims,
        sigmas,
        border,
        // the smoother's reads at a coarser pyramid (the sigma map has no
        // Hessian to serve), with the margin memory allows at factor 8
        // (a coarser stack is smaller)
        options: StackOptions {
            pyramid_factor: SIGMA_MAP_PYRAMID_FACTOR,
            ..smoother_stack_options(bank, hi, dims, sigmas)
        },
    };
    Ok((Some(plan.build(image)?), (lo, hi)))
}

/// Adds the Gaussians the stack serves (every one not sampled directly)
/// into `out` through [`bank_passes`]: each pixel's Gaussian rotated by its
/// angle and scaled by its footprint over `sigma_ref` (one constant scale
/// where the footprints `lo..=hi` differ by less than [`ONE_FOOTPRINT`]).
/// The pixels sampled directly have no share of any entry (and scale `lo /
/// sigma_ref`, the smallest the stack covers).
fn bank_lookups(
    gaussians: &[AnisoGaussian],
    bank: &AspectBank,
    stack: &ScaleStack,
    prepared: &[PreparedDecomposition],
    (lo, hi): (f64, f64),
    out: &mut Image,
) -> Result<(), SmoothError> {
    let r = bank.options.sigma_ref as f32;
    let n = gaussians.len();
    let (mut angle, mut scale) = (vec![0.0f32; n], vec![lo as f32 / r; n]);
    let mut shares = vec![NO_SHARES; n];
    (&mut angle, &mut scale, &mut shares, gaussians)
        .into_par_iter()
        .for_each(|(a, s, sh, g)| {
            if !PixelGaussians::sampled_directly(*g) {
                (*a, *s, *sh) = (g.theta, g.footprint / r, shares_of(bank, g.aspect));
            }
        });
    // One footprint everywhere (to float rounding: a map of `S sqrt(a)`
    // and `S / sqrt(a)` in f32): its levels are located once.
    let scale = if hi <= lo * (1.0 + ONE_FOOTPRINT) {
        Field::Constant((lo * hi).sqrt() as f32 / r)
    } else {
        Field::Map(&scale)
    };
    let filters = prepared
        .iter()
        .map(|d| Filter::new(stack, d))
        .collect::<Result<Vec<_>, _>>()?;
    bank_passes(&filters, &angle, scale, &shares, out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bank::BankOptions;
    use crate::gaussians::BankLookups;

    /// The whole-image passes, one bank entry at a time on the vector rows,
    /// give what the per-point lookups give (each pixel's two entries
    /// through [`Filter::filter_at_into`]), within float rounding: a
    /// structure-like map with footprints 2.5 to 6 px (and one of 4 px),
    /// aspects 1 to 8 and angles turning along the row, one and three
    /// channels.
    #[test]
    fn bank_passes_equal_the_per_point_lookups() {
        let opts = BankOptions {
            max_aspect: 8.0,
            tol: 0.05,
            ..BankOptions::default()
        };
        let bank = AspectBank::build(opts, |_, _| {}).unwrap();
        let (w, h) = (71, 23);
        let map = |footprint: &dyn Fn(f32) -> f32| -> Vec<f32> {
            (0..w * h)
                .flat_map(|i| {
                    let (u, v) = ((i % w) as f32 / w as f32, (i / w) as f32 / h as f32);
                    let (s, a) = (footprint(v), 1.0 + 7.0 * u);
                    [s * a.sqrt(), s / a.sqrt(), 400.0 * u * u - 90.0 * v]
                })
                .collect()
        };
        // footprints 2.5 to 6 px; one footprint of 4 px (to f32 rounding:
        // the constant-scale rows)
        let (varying, constant) = (map(&|v| 2.5 + 3.5 * v), map(&|_| 4.0));
        for (map, c, one_footprint) in [
            (&varying, 1, false),
            (&varying, 3, false),
            (&constant, 1, true),
        ] {
            let m = ImageView::new(w, h, 3, map).unwrap();
            let data: Vec<f32> = (0..w * h * c)
                .map(|i| ((i * 7919) % 211) as f32 / 211.0)
                .collect();
            let img = Image::from_vec(w, h, c, data).unwrap();
            let got = filter_sigma_map(&img, m, &bank, Border::Reflect101).unwrap();
            let gaussians = sigma_map_gaussians(m, (w, h), 8.0).unwrap();
            let prepared = prepared_bank(&bank).unwrap();
            let (stack, _) =
                sigma_map_stack(&gaussians, &bank, img.view(), Border::Reflect101).unwrap();
            let stack = stack.unwrap();
            let filters: Vec<Filter<'_>> = prepared
                .iter()
                .map(|d| Filter::new(&stack, d).unwrap())
                .collect();
            let per_point = PixelGaussians::new(
                &bank,
                Some(BankLookups::Varying(&filters)),
                Some(SmallFootprints::Sampled { image: img.view() }),
                Border::Reflect101,
            );
            let mut worst = 0.0f32;
            for (i, px) in got.data().chunks_exact(c).enumerate() {
                let mut want = vec![0.0f32; c];
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                per_point.accumulate(x, y, gaussians[i], 1.0, &mut want);
                for (a, b) in px.iter().zip(&want) {
                    worst = worst.max((a - b).abs());
                }
            }
            assert!(worst < 2e-6, "{c} channels: differs by up to {worst}");
            let footprints: Vec<f32> = gaussians.iter().map(|g| g.footprint).collect();
            let one = footprints
                .iter()
                .all(|&f| (f / footprints[0] - 1.0).abs() < 1e-6);
            assert_eq!(one, one_footprint, "the constant-footprint case");
        }
    }
}
