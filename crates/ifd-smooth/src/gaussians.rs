//! One anisotropic Gaussian per pixel, of any angle, aspect ratio and
//! footprint, applied from the aspect bank: what smoothing applies at each
//! pixel (one footprint for the whole image) and what the sigma map
//! (`ifd filter --kernel gauss --sigma-map`, a footprint per pixel) applies.
//!
//! The conventions are documented on [`AnisoGaussian`] and
//! [`PixelGaussians`].

use ifd_image::{Image, ImageView};
use ifd_planar::{Border, Field, Filter, Rotation, ScaledFilter};
use rayon::prelude::*;

use crate::bank::AspectBank;
use crate::direct::{DIRECT_BELOW, DirectKernels, covariance};
use crate::error::SmoothError;

/// An anisotropic Gaussian: the filter of one pixel.
///
/// Its standard deviations are `sx = footprint sqrt(aspect)` along the long
/// axis, at `theta` degrees counter-clockwise on screen (`y` down: the axis
/// points towards `(cos theta, -sin theta)` in pixel coordinates), and
/// `sy = footprint / sqrt(aspect)` across, so `sx sy = footprint^2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnisoGaussian {
    /// Direction of the long axis, degrees counter-clockwise on screen.
    pub theta: f32,
    /// Aspect ratio `sx / sy`, `>= 1`.
    pub aspect: f32,
    /// Footprint `sqrt(sx sy)`, pixels.
    pub footprint: f32,
}

impl AnisoGaussian {
    /// The Gaussian with standard deviations `major` along `theta` (degrees
    /// counter-clockwise on screen) and `minor` across (`minor <= major`,
    /// both positive; not checked here).
    #[must_use]
    pub fn from_sigmas(major: f64, minor: f64, theta: f64) -> Self {
        Self {
            theta: theta as f32,
            aspect: (major / minor) as f32,
            footprint: (major * minor).sqrt() as f32,
        }
    }

    /// The standard deviations `(sx, sy)` along the long axis and across.
    #[must_use]
    pub fn sigmas(self) -> (f64, f64) {
        let (s, a) = (f64::from(self.footprint), f64::from(self.aspect).sqrt());
        (s * a, s / a)
    }
}

/// Footprints below this many pixels, or minor standard deviations below
/// [`SAMPLED_MINOR_BELOW`], are evaluated directly by [`PixelGaussians`]
/// when it samples small Gaussians itself (the sigma map): the bank's
/// narrowest atoms, scaled down, fall below what the stack's levels
/// represent.
pub const SAMPLED_BELOW: f64 = DIRECT_BELOW;

/// Minor standard deviations (pixels) below which the sampled Gaussian is
/// evaluated directly whatever its footprint (see [`SAMPLED_BELOW`]).
pub const SAMPLED_MINOR_BELOW: f64 = 1.0;

/// Mahalanobis radius at which directly sampled Gaussians are truncated.
const SAMPLED_REACH: f64 = 5.0;

/// How the bank's lookups are bound to the stack.
#[derive(Clone, Debug)]
pub enum BankLookups<'f, 'a> {
    /// One footprint for every point (smoothing): the entries bound at
    /// scale `footprint / sigma_ref`, their levels resolved once.
    Fixed(Vec<ScaledFilter<'f, 'a>>),
    /// A footprint per point: each lookup locates its levels (whole
    /// images, the sigma map's included, take weighted passes per entry).
    Varying(&'f [Filter<'a>]),
}

/// How footprints too small for the stack are evaluated.
#[derive(Clone, Copy, Debug)]
pub enum SmallFootprints<'f> {
    /// Smoothing below [`DIRECT_BELOW`]: tables of pixel-integrated kernels
    /// of the one footprint ([`DirectKernels`]) applied to the image;
    /// every point is evaluated this way.
    Tables {
        /// The tables.
        kernels: &'f DirectKernels,
        /// The image they are applied to.
        image: &'f Image,
    },
    /// The sigma map: a Gaussian with footprint below [`SAMPLED_BELOW`] or
    /// minor sigma below [`SAMPLED_MINOR_BELOW`] is sampled at the pixel
    /// offsets within 5 standard deviations (Mahalanobis), normalised to sum
    /// 1 over its samples, and correlated with the image.
    Sampled {
        /// The image.
        image: ImageView<'f>,
    },
}

/// The aspect bank bound to a scale stack (and, for small footprints, to
/// the image): adds any [`AnisoGaussian`] at any point.
///
/// A Gaussian of aspect ratio `a` is the blend `(1 - t) D_i + t D_{i+1}` of
/// the bank's entries around `a` ([`AspectBank::locate`]), rotated by
/// `theta` and scaled by `footprint / sigma_ref`: `s_i + s_{i+1}` lookups
/// (the blend of two decompositions is the decomposition of the blended
/// filter, so blending the results is exact). Small footprints are
/// evaluated directly, as [`SmallFootprints`] says.
#[derive(Clone, Debug)]
pub struct PixelGaussians<'f, 'a> {
    bank: &'f AspectBank,
    lookups: Option<BankLookups<'f, 'a>>,
    small: Option<SmallFootprints<'f>>,
    border: Border,
}

impl<'f, 'a> PixelGaussians<'f, 'a> {
    /// Binds `bank` to its `lookups` (`None` when every point is small) and
    /// the evaluation of `small` footprints; `border` applies to the
    /// directly evaluated ones (the stack has its own).
    #[must_use]
    pub fn new(
        bank: &'f AspectBank,
        lookups: Option<BankLookups<'f, 'a>>,
        small: Option<SmallFootprints<'f>>,
        border: Border,
    ) -> Self {
        Self {
            bank,
            lookups,
            small,
            border,
        }
    }

    /// The bank's filters at one scale, when every point has the same
    /// footprint ([`BankLookups::Fixed`]).
    #[must_use]
    pub fn fixed(&self) -> Option<&[ScaledFilter<'f, 'a>]> {
        match &self.lookups {
            Some(BankLookups::Fixed(s)) => Some(s),
            _ => None,
        }
    }

    /// Whether `g` is sampled directly when small footprints are
    /// [`SmallFootprints::Sampled`]: footprint below [`SAMPLED_BELOW`] or
    /// minor sigma below [`SAMPLED_MINOR_BELOW`].
    #[must_use]
    pub fn sampled_directly(g: AnisoGaussian) -> bool {
        f64::from(g.footprint) < SAMPLED_BELOW || g.sigmas().1 < SAMPLED_MINOR_BELOW
    }

    /// The bank entries of aspect ratio `aspect` and their blend weights:
    /// `(i, 1 - t)` and, unless `t = 0`, `(i + 1, t)` ([`AspectBank::locate`]).
    pub fn blend(&self, aspect: f32) -> impl Iterator<Item = (usize, f32)> + use<> {
        shares_of(self.bank, aspect)
            .into_iter()
            .filter(|&(i, _)| i != NONE)
            .map(|(i, w)| (i as usize, w))
    }

    /// Adds `weight *` the Gaussian `g` applied at `(x, y)` to `out` (one
    /// value per channel). Directly evaluated footprints need pixel
    /// centres (integer `x`, `y`). A footprint the stack does not cover
    /// (the caller sized it from the footprints it applies) adds NaN.
    pub fn accumulate(&self, x: f32, y: f32, g: AnisoGaussian, weight: f32, out: &mut [f32]) {
        match (&self.small, &self.lookups) {
            (Some(SmallFootprints::Tables { kernels, image }), _) => {
                kernels.accumulate(
                    image,
                    self.border,
                    (x as usize, y as usize),
                    (g.theta, g.aspect),
                    weight,
                    out,
                );
            }
            (Some(SmallFootprints::Sampled { image }), _) if Self::sampled_directly(g) => {
                sampled_gaussian(
                    *image,
                    self.border,
                    (x as usize, y as usize),
                    g,
                    weight,
                    out,
                );
            }
            (_, Some(BankLookups::Fixed(scaled))) => {
                let rot = Rotation::degrees(g.theta);
                for (i, wi) in self.blend(g.aspect) {
                    scaled[i].accumulate(x, y, weight * wi, rot, out);
                }
            }
            (_, Some(BankLookups::Varying(filters))) => {
                let s = g.footprint / self.bank.options.sigma_ref as f32;
                let mut buf = [0.0f32; 8];
                let mut heap = Vec::new();
                let tmp: &mut [f32] = if out.len() <= buf.len() {
                    &mut buf[..out.len()]
                } else {
                    heap.resize(out.len(), 0.0);
                    &mut heap
                };
                for (i, wi) in self.blend(g.aspect) {
                    if filters[i].filter_at_into(x, y, g.theta, s, tmp).is_err() {
                        tmp.fill(f32::NAN);
                    }
                    for (o, v) in out.iter_mut().zip(tmp.iter()) {
                        *o += weight * wi * v;
                    }
                }
            }
            (_, None) => out.fill(f32::NAN),
        }
    }
}

/// A pixel's bank entries and their weights in its blend
/// ([`PixelGaussians::blend`]), for [`bank_passes`]: `(entry, weight)`
/// twice (16 bytes a pixel), [`NO_SHARES`] for none.
pub(crate) type Shares = [(u32, f32); 2];

/// The entry of a share that is none.
const NONE: u32 = u32::MAX;

/// No entry: a pixel the stack does not serve.
pub(crate) const NO_SHARES: Shares = [(NONE, 0.0); 2];

/// The shares of the bank's entries in aspect ratio `aspect`
/// ([`PixelGaussians::blend`]'s entries and weights).
pub(crate) fn shares_of(bank: &AspectBank, aspect: f32) -> Shares {
    let (i, t) = bank.locate(f64::from(aspect));
    // a bank has a few dozen entries at most (aspects to 16)
    let i = i as u32;
    let t = t as f32;
    if t > 0.0 {
        [(i, 1.0 - t), (i + 1, t)]
    } else {
        [(i, 1.0), (NONE, 0.0)]
    }
}

/// Adds each pixel's blend of the bank's entries, bound to the stack as
/// `filters` (one per entry) and rotated by its `angle` and scaled by
/// `scale`, into `out`: each entry in turn over the whole image
/// ([`Filter::accumulate_weighted`]), weighted at each pixel by its share
/// ([`Shares`]; zero where the entry has none, pixels that the vector rows
/// leave out). The same sums as [`PixelGaussians::accumulate`] pixel by
/// pixel (entry `i`, then `i + 1`), through the vector rows: a bank of
/// entries blended per pixel is the several-filters case of the rows.
pub(crate) fn bank_passes(
    filters: &[Filter<'_>],
    angle: &[f32],
    scale: Field<'_>,
    shares: &[Shares],
    out: &mut Image,
) -> Result<(), SmoothError> {
    let mut weight = vec![0.0f32; shares.len()];
    for (e, filter) in filters.iter().enumerate() {
        let e = e as u32;
        let share = |sh: &Shares| sh.iter().find(|(i, _)| *i == e).map_or(0.0, |&(_, w)| w);
        weight
            .par_iter_mut()
            .zip(shares)
            .for_each(|(wt, sh)| *wt = share(sh));
        if weight.iter().all(|&v| v == 0.0) {
            continue;
        }
        filter.accumulate_weighted(Field::Map(angle), scale, &weight, out)?;
    }
    Ok(())
}

/// Adds `weight *` the sampled Gaussian `g`, normalised to sum 1 over its
/// samples within [`SAMPLED_REACH`] standard deviations, correlated with
/// `image` at pixel `(x, y)`, to `out`.
fn sampled_gaussian(
    image: ImageView<'_>,
    border: Border,
    (x, y): (usize, usize),
    g: AnisoGaussian,
    weight: f32,
    out: &mut [f32],
) {
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let data = image.data();
    let (sx, sy) = g.sigmas();
    let [a, b, d] = covariance(f64::from(g.theta), sx, sy);
    let det = (a * d - b * b).max(1e-300);
    // Rows within the reach; in row `v`, `u | v` has mean `m v` and
    // standard deviation `cs`.
    let ry = (SAMPLED_REACH * d.sqrt()).floor() as i64;
    let m = b / d;
    let cs = (det / d).sqrt();
    let lim = SAMPLED_REACH * SAMPLED_REACH;
    let mut acc = [0.0f64; 8];
    let mut heap = Vec::new();
    let acc: &mut [f64] = if c <= acc.len() {
        &mut acc[..c]
    } else {
        heap.resize(c, 0.0);
        &mut heap
    };
    let mut total = 0.0f64;
    for dv in -ry..=ry {
        let v = dv as f64;
        // Mahalanobis distance^2 = v^2 / d + (u - m v)^2 / cs^2.
        let rest = lim - v * v / d;
        if rest < 0.0 {
            continue;
        }
        let half = cs * rest.sqrt();
        let (u0, u1) = ((m * v - half).ceil() as i64, (m * v + half).floor() as i64);
        let yy = y as i64 + dv;
        for du in u0..=u1 {
            let u = du as f64;
            let q = (d * u * u - 2.0 * b * u * v + a * v * v) / det;
            let k = (-0.5 * q).exp();
            total += k;
            let xx = x as i64 + du;
            if let (Some(xi), Some(yi)) = (border.resolve(xx, w), border.resolve(yy, h)) {
                let o = (yi * w + xi) * c;
                for (s, v) in acc.iter_mut().zip(&data[o..o + c]) {
                    *s += k * f64::from(*v);
                }
            } else {
                let v = f64::from(border.constant());
                for s in acc.iter_mut() {
                    *s += k * v;
                }
            }
        }
    }
    let scale = f64::from(weight) / total;
    for (o, s) in out.iter_mut().zip(acc.iter()) {
        *o += (s * scale) as f32;
    }
}
