//! SH analysis (projection) and synthesis of environment maps: the
//! equirectangular transform (`equirect.rs`), cube maps (`cube.rs`),
//! resampling of equirectangular maps (`resample.rs`), and here the shared
//! types, the one entry point by map shape ([`analyze_map`]) and the
//! projection of scattered samples.
//!
//! The derivation and conventions are documented on [`analyze_map`].

mod cube;
mod equirect;
mod resample;

use ifd_image::Image;

pub use self::cube::{analyze_cubemap, cube_face_direction, cube_texel};
pub use self::equirect::EquirectTransform;
pub use self::resample::{bicubic_taps, downsample_equirect};
use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError, check_degree};
use crate::sh::{ShEvaluator, sh_count};

/// What to do with negative samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Negatives {
    /// Clamp them to zero and count them (the default: radiance is never negative).
    #[default]
    Clamp,
    /// Keep them as they are.
    Keep,
}

/// The result of a projection.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// The SH coefficients, one column per image channel.
    pub coeffs: ShCoeffs,
    /// How many samples were negative (and clamped, with [`Negatives::Clamp`]).
    pub negatives_clamped: usize,
}

/// How a map's texels are projected onto SH.
///
/// One rule for every front end (`ifd sphere sh`, `ifd sphere filter`, the
/// Python module), chosen by [`analyze_map`]: an equirectangular map is
/// projected texel-exactly by default, the very function `ifd render`'s oracle
/// and the IBL baker integrate, so SH read from `ifd sphere sh` agree with
/// them up to the band limit; the pixel-centre rule is there for comparison
/// with SH transforms that sample at pixel centres (ducc0, HEALPix-style
/// codes). A cubemap strip is projected at its texel centres with each
/// texel's exact solid angle: a texel-exact cube projection is not
/// implemented, and asking for one is an error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Projection {
    /// The map read as piecewise constant over its texels, each texel's
    /// integral exact ([`EquirectTransform::analyze_texels`]).
    Texel,
    /// Pixel-centre quadrature with each texel's exact solid angle
    /// ([`EquirectTransform::analyze`], [`analyze_cubemap`]).
    Centre,
}

impl Projection {
    /// The rule's name, as the CLI spells it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Texel => "texel",
            Self::Centre => "centre",
        }
    }
}

/// Projects a map onto SH up to `l_max`: a 2:1 equirectangular map or a 6:1
/// cubemap strip, told apart by shape, with `projection` (`None`: texel for
/// an equirectangular map, centre for a cube strip; see [`Projection`]).
/// Returns the analysis and the projection used.
///
/// ```
/// use ifd_sphere::{Negatives, Projection, analyze_map};
/// let img = ifd_image::Image::from_vec(16, 8, 1, vec![1.0; 128])?;
/// let (a, used) = analyze_map(&img, 4, Negatives::Keep, None)?;
/// assert_eq!(used, Projection::Texel);
/// assert!((a.coeffs.get(0, 0, 0) - (4.0 * std::f64::consts::PI).sqrt()).abs() < 1e-8);
/// // a cube strip has no texel-exact projection
/// let strip = ifd_image::Image::from_vec(24, 4, 1, vec![1.0; 96])?;
/// assert!(analyze_map(&strip, 4, Negatives::Keep, Some(Projection::Texel)).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`SphereError::NotEquirect`] for other shapes, [`SphereError::Parameter`]
/// for a texel projection of a cube strip, and the errors of the transforms.
///
/// # Equirectangular maps
/// A `W x H` map with `W = 2H`: column `u` has azimuth `p = 2 pi (u + 0.5) / W`,
/// row `v` (row 0 at the top) has polar angle `t = pi (v + 0.5) / H`, so the top
/// row looks up (`+z`). The projection is the quadrature
///
/// ```text
/// c_l^m = sum_pixels f(w_uv) y_l^m(w_uv) dA_v,
/// dA_v  = (2 pi / W) (cos(pi v / H) - cos(pi (v + 1) / H))
/// ```
///
/// where `dA_v` is the *exact* solid angle of the pixel (the weights sum to
/// `4 pi` exactly). It is computed as an FFT over each row (giving the
/// azimuthal Fourier coefficients for every `m` at once) followed by the
/// Legendre recurrences of [`crate::ShEvaluator`] over `l`, processing the rows `v` and
/// `H - 1 - v` together (`P_l^m(-z) = (-1)^(l+m) P_l^m(z)`; two real rows share
/// one complex FFT). Cost `O(H W log W + H L^2)` per channel.
/// Synthesis runs the same steps backwards and evaluates the expansion exactly
/// at the pixel centres.
///
/// # Cubemaps
/// [`analyze_cubemap`] projects a horizontal strip of six square faces in the
/// order `+X, -X, +Y, -Y, +Z, -Z`, each face laid out as in OpenGL (face
/// coordinates `sc, tc` of the OpenGL cube-map table, `tc` growing downwards
/// in the image), with exact per-texel solid angles. It evaluates the SH per
/// texel (`O(texels L^2)`).
///
/// # Bad input
/// NaN or infinite samples are an error ([`crate::SphereError::NonFinite`]).
/// Negative samples (the bundled DWAB files have a few tiny ones) are clamped to
/// zero by default and counted in [`Analysis::negatives_clamped`].
pub fn analyze_map(
    img: &Image,
    l_max: usize,
    negatives: Negatives,
    projection: Option<Projection>,
) -> Result<(Analysis, Projection)> {
    let (w, h) = (img.width(), img.height());
    if h >= 1 && w == 6 * h {
        if projection == Some(Projection::Texel) {
            return Err(SphereError::Parameter {
                name: "projection",
                value: "texel".into(),
                reason: "a cube strip is projected at its texel centres (exact solid angles); \
                         a texel-exact cube projection is not implemented",
            });
        }
        return Ok((analyze_cubemap(img, l_max, negatives)?, Projection::Centre));
    }
    let t = EquirectTransform::new(l_max, w, h)?;
    match projection.unwrap_or(Projection::Texel) {
        Projection::Texel => Ok((t.analyze_texels(img, negatives)?, Projection::Texel)),
        Projection::Centre => Ok((t.analyze(img, negatives)?, Projection::Centre)),
    }
}

/// Projects an equirectangular image (`W = 2H`) onto SH up to `l_max`
/// (plans an [`EquirectTransform`] and runs it once).
///
/// # Errors
/// As [`EquirectTransform::new`] and [`EquirectTransform::analyze`].
pub fn analyze_equirect(img: &Image, l_max: usize, negatives: Negatives) -> Result<Analysis> {
    EquirectTransform::new(l_max, img.width(), img.height())?.analyze(img, negatives)
}

/// Projects an equirectangular map read as **piecewise constant** over its
/// texels: `c_l^m = sum_texels E_uv int_texel y_l^m(w) dw`, exactly (to
/// rounding), rather than the pixel-centre rule of [`EquirectTransform`].
///
/// This is the projection of the very function a texel-exact quadrature (the
/// shading oracle of `ifd render`) integrates, so the two differ only by the
/// band limit. Derivation: with `y_l^m(theta, phi) = Y_l^|m|(theta) c_m(phi)`
/// (`c_m = cos(m phi)` for `m >= 0`, `sin(|m| phi)` for `m < 0`, and
/// `Y_l^|m|(theta) = y_l^|m|(theta, 0)`), a texel `[phi_u -+ d/2] x [theta_v,
/// theta_v+1]` integrates to
///
/// ```text
/// int c_m dphi = c_m(phi_u) d sinc(m d / 2),   sinc(x) = sin(x) / x,
/// int Y_l^|m|(theta) sin(theta) dtheta          (Gauss-Legendre in theta),
/// ```
///
/// so each row's pixel-centre Fourier sums are scaled by `d sinc(m d / 2)`
/// and met with the row integral of `Y_l^|m|`; `Y_l^|m|(theta) sin(theta)` is
/// a trigonometric polynomial of degree `l + 1`, which
/// `max(3, 2 + ceil((L + 1) pi / (2 H)))` Gauss nodes per row integrate to
/// about `5e-6` relative at the top band (far better below). It runs as
/// [`EquirectTransform::analyze_texels`] (FFT rows, cost
/// `O(H W log W + n H L^2)` per channel).
///
/// ```
/// use ifd_sphere::{Negatives, analyze_equirect_box};
/// // a constant map projects to c_00 = sqrt(4 pi), nothing else (to the
/// // polar quadrature's few 1e-6 at the top band of so small a map)
/// let img = ifd_image::Image::from_vec(16, 8, 1, vec![1.0; 128])?;
/// let c = analyze_equirect_box(&img, 6, Negatives::Keep)?.coeffs;
/// assert!((c.get(0, 0, 0) - (4.0 * std::f64::consts::PI).sqrt()).abs() < 1e-8);
/// assert!(c.data()[1..].iter().all(|v| v.abs() < 2e-5));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`SphereError::NotEquirect`], [`SphereError::NonFinite`],
/// [`SphereError::DegreeTooHigh`].
pub fn analyze_equirect_box(img: &Image, l_max: usize, negatives: Negatives) -> Result<Analysis> {
    check_degree(l_max)?;
    let (w, h) = (img.width(), img.height());
    if h < 2 || w != 2 * h {
        return Err(SphereError::NotEquirect {
            width: w,
            height: h,
        });
    }
    EquirectTransform::new(l_max, w, h)?.analyze_texels(img, negatives)
}

/// Projects weighted samples: `c_l^m = sum_i w_i f_i y_l^m(d_i)` (any quadrature
/// rule; `values` is `n x C` row-major).
///
/// # Errors
/// [`SphereError::Length`] for inconsistent lengths, [`SphereError::NonFinite`]
/// for NaN values or weights, [`SphereError::BadDirection`] for zero/NaN directions.
pub fn project_samples(
    l_max: usize,
    dirs: &[[f64; 3]],
    weights: &[f64],
    values: &[f64],
    channels: usize,
) -> Result<ShCoeffs> {
    let mut out = ShCoeffs::zeros(l_max, channels)?;
    if weights.len() != dirs.len() || values.len() != dirs.len() * channels {
        return Err(SphereError::Length {
            what: "samples (weights, values = directions x channels)",
            got: values.len(),
            expected: dirs.len() * channels,
        });
    }
    if let Some(first) = values.iter().chain(weights).position(|v| !v.is_finite()) {
        return Err(SphereError::NonFinite {
            what: "sample values or weights",
            count: values
                .iter()
                .chain(weights)
                .filter(|v| !v.is_finite())
                .count(),
            first,
        });
    }
    let sh = ShEvaluator::new(l_max)?;
    let mut y = vec![0.0; sh_count(l_max)];
    let o = out.data_mut();
    for (i, d) in dirs.iter().enumerate() {
        crate::zhf::check_direction(i, *d)?;
        sh.eval_into(*d, &mut y);
        for (k, yk) in y.iter().enumerate() {
            let wy = weights[i] * yk;
            for c in 0..channels {
                o[k * channels + c] += wy * values[i * channels + c];
            }
        }
    }
    Ok(out)
}

/// The number of negative samples of a map, after checking that all are
/// finite ([`SphereError::NonFinite`] names the count and the first index);
/// one branch-free (vectorisable) pass for both counts.
pub(crate) fn count_negatives_of_finite_map(data: &[f32], what: &'static str) -> Result<usize> {
    let (bad, negatives) = data
        .chunks(1 << 12)
        .fold((0usize, 0usize), |(bad, neg), chunk| {
            let (mut b, mut n) = (0u32, 0u32);
            for &v in chunk {
                b += u32::from(!v.is_finite());
                n += u32::from(v < 0.0);
            }
            (bad + b as usize, neg + n as usize)
        });
    if bad > 0 {
        let first = data.iter().position(|v| !v.is_finite()).unwrap_or(0);
        return Err(SphereError::NonFinite {
            what,
            count: bad,
            first,
        });
    }
    Ok(negatives)
}
