//! The image Hessian at any scale through IFD (Section 5.1 of the IFD paper).
//!
//! The derivation and conventions are documented on [`HessianBank`].

use ifd_image::{Image, ImageView};
use ifd_planar::{
    Border, DecomposeOptions, Decomposition, Field, Filter, KernelSpec, ScaleStack, StackOptions,
    decompose,
};
use rayon::prelude::*;

use crate::error::{SmoothError, check_range};

/// The sigma, in pixels, at which the derivative filters are decomposed.
pub const HESSIAN_SIGMA0: f64 = 2.0;

/// Smallest and largest Hessian scale supported, in pixels.
pub const HESSIAN_SIGMA_RANGE: (f64, f64) = (1.0, 256.0);

/// Stack options for Hessians: second derivatives are small differences of
/// large values, so levels are kept at full resolution up to sigma 8 px
/// (pyramid factor 8): with the default factor 2 the bilinear lookups into
/// subsampled levels cost 10% relative error at sigma 4-8 (measured on the
/// bundled images against exact correlation).
#[must_use]
pub fn hessian_stack_options() -> StackOptions {
    StackOptions {
        pyramid_factor: 8.0,
        interpolation: ifd_planar::Interpolation::Cubic,
        ..StackOptions::default()
    }
}

/// The decomposed second-derivative filters.
///
/// The second derivatives of a normalised Gaussian `g_sigma0` are decomposed
/// once: `k_xx = d^2 g / dx^2` and `k_xy = d^2 g / dx dy`. `k_yy` is `k_xx`
/// rotated by 90 degrees: with `R_{-90} (dx, dy) = (-dy, dx)`,
/// `k_xx(R_{-90} d) = (dy^2 / s0^4 - 1 / s0^2) g(d) = k_yy(d)`.
///
/// **Scale.** Scaling a kernel by `s` in IFD gives `k_s(d) = k(d / s) / s^2`.
/// With `g_sigma(d) = g_sigma0(d / s) / s^2` for `sigma = s sigma0`, the chain
/// rule gives `d^2 g_sigma / dx^2 (d) = (d^2 g_sigma0 / dx^2)(d / s) / s^4 =
/// k_s(d) / s^2`. So the Hessian at scale `sigma` is the IFD response at scale
/// `s = sigma / sigma0` divided by `s^2`. The result is **not**
/// scale-normalised (multiply by `sigma^2` for that), matching
/// `skimage.feature.hessian_matrix(..., use_gaussian_derivatives=True)`.
///
/// Both kernels are even (`k(-d) = k(d)`), so correlation equals convolution
/// and the responses are the derivatives of the Gaussian-smoothed image.
#[derive(Clone, Debug)]
pub struct HessianBank {
    /// Decomposition of `d^2 g_sigma0 / dx^2`.
    pub xx: Decomposition,
    /// Decomposition of `d^2 g_sigma0 / dx dy`.
    pub xy: Decomposition,
    /// The sigma of the decomposed filters.
    pub sigma0: f64,
}

impl HessianBank {
    /// Decomposes the `xx` and `xy` filters at [`HESSIAN_SIGMA0`] to relative L2
    /// error `tol` (0.01 is plenty: the Hessian tests ask for 3%).
    ///
    /// # Errors
    /// [`SmoothError::Decompose`] when a fit fails.
    pub fn new(tol: f64) -> Result<Self, SmoothError> {
        let fit = |order: &str| -> Result<Decomposition, SmoothError> {
            let spec_s = format!("dgauss:order={order},sigma={HESSIAN_SIGMA0}");
            let spec: KernelSpec = spec_s.parse()?;
            let kernel = spec.to_kernel()?;
            let opts = DecomposeOptions {
                tol,
                ..DecomposeOptions::default()
            };
            let mut d = decompose(&kernel, &opts, |_, _, _| {}).map_err(|source| {
                SmoothError::Decompose {
                    spec: spec_s,
                    source,
                }
            })?;
            remove_dc(&mut d);
            // The Hessian at scale sigma samples the derivatives of the
            // continuous Gaussian at pixel centres at every scale, as
            // scikit-image computes it: no pixel averaging below sigma0.
            d.sampling = ifd_planar::Sampling::Continuous;
            Ok(d)
        };
        Ok(Self {
            xx: fit("xx")?,
            xy: fit("xy")?,
            sigma0: HESSIAN_SIGMA0,
        })
    }

    /// The range of stack sigmas needed for Hessians at scales
    /// `[sigma_lo, sigma_hi]`.
    #[must_use]
    pub fn stack_sigmas(&self, sigma_lo: f64, sigma_hi: f64) -> (f64, f64) {
        let (lo, hi) = term_sigma_range([&self.xx, &self.xy]);
        (lo * sigma_lo / self.sigma0, hi * sigma_hi / self.sigma0)
    }

    /// Binds the filters to a stack.
    ///
    /// # Errors
    /// [`SmoothError::Filter`] for invalid decompositions.
    pub fn bind<'a>(&self, stack: &'a ScaleStack) -> Result<HessianFilters<'a>, SmoothError> {
        Ok(HessianFilters {
            xx: Filter::new(stack, &self.xx)?,
            xy: Filter::new(stack, &self.xy)?,
            sigma0: self.sigma0,
            channels: stack.channels(),
        })
    }
}

/// Makes the decomposition's DC response exactly zero, as the derivative
/// filters' is: every atom is a normalised Gaussian (sum 1), so the
/// decomposition's sum is `sum_t w_t`; that residue (a fraction of the fit
/// error) is removed from the weights in proportion to their magnitudes.
/// Without it a constant image would have a small non-zero Hessian.
fn remove_dc(d: &mut Decomposition) {
    let sum: f64 = d.terms.iter().map(|t| t.weight).sum();
    let abs: f64 = d.terms.iter().map(|t| t.weight.abs()).sum();
    if abs > 0.0 {
        for t in &mut d.terms {
            t.weight -= sum * t.weight.abs() / abs;
        }
    }
}

/// Smallest and largest atom sigma over decompositions.
pub(crate) fn term_sigma_range<'a>(ds: impl IntoIterator<Item = &'a Decomposition>) -> (f64, f64) {
    ds.into_iter()
        .flat_map(|d| d.terms.iter().map(|t| t.sigma))
        .fold((f64::INFINITY, 0.0), |(lo, hi), s| (lo.min(s), hi.max(s)))
}

/// The Hessian filters bound to one scale stack.
#[derive(Clone, Debug)]
pub struct HessianFilters<'a> {
    xx: Filter<'a>,
    xy: Filter<'a>,
    sigma0: f64,
    channels: usize,
}

impl HessianFilters<'_> {
    /// `(Hxx, Hxy, Hyy)` at `(x, y)` and scale `sigma`, averaged over
    /// channels (the Hessian of the channel mean): `3 s` lookups.
    ///
    /// # Errors
    /// [`SmoothError::Filter`] when `sigma` needs stack levels that are not there.
    pub fn at(&self, x: f32, y: f32, sigma: f64) -> Result<[f64; 3], SmoothError> {
        let s = (sigma / self.sigma0) as f32;
        let mut buf = vec![0.0f32; self.channels];
        let mut out = [0.0f64; 3];
        for (slot, (filter, angle)) in [(&self.xx, 0.0), (&self.xy, 0.0), (&self.xx, 90.0)]
            .into_iter()
            .enumerate()
        {
            filter.filter_at_into(x, y, angle, s, &mut buf)?;
            out[slot] = buf.iter().map(|&v| f64::from(v)).sum::<f64>() / self.channels as f64;
        }
        let s2 = f64::from(s) * f64::from(s);
        Ok(out.map(|v| v / s2))
    }

    /// Whole-image Hessian at scale `sigma`: three planes `Hxx, Hxy, Hyy`,
    /// each the Hessian of the channel mean.
    ///
    /// # Errors
    /// [`SmoothError::Filter`] when `sigma` needs stack levels that are not there.
    pub fn planes(&self, sigma: f64) -> Result<[Vec<f32>; 3], SmoothError> {
        let s = (sigma / self.sigma0) as f32;
        let inv_s2 = 1.0 / (s * s);
        let c = self.channels;
        let mean = |img: Image| -> Vec<f32> {
            img.data()
                .par_chunks_exact(c)
                .map(|px| px.iter().sum::<f32>() / c as f32 * inv_s2)
                .collect()
        };
        let hxx = mean(self.xx.apply(Field::Constant(0.0), Field::Constant(s))?);
        let hxy = mean(self.xy.apply(Field::Constant(0.0), Field::Constant(s))?);
        let hyy = mean(self.xx.apply(Field::Constant(90.0), Field::Constant(s))?);
        Ok([hxx, hxy, hyy])
    }
}

/// Refuses a Hessian scale outside [`HESSIAN_SIGMA_RANGE`] (or not finite).
///
/// # Errors
/// [`SmoothError::OutOfRange`] named `hessian sigma`.
pub fn check_sigma(sigma: f64) -> Result<(), SmoothError> {
    let (lo, hi) = HESSIAN_SIGMA_RANGE;
    check_range("hessian sigma", sigma, lo, hi)
}

/// The Hessian of `image` (channel mean) at scale `sigma` as an `H x W x 3`
/// image with channels `(Hxx, Hxy, Hyy)`, `x` = column, `y` = row, not
/// scale-normalised. Builds the stack it needs.
///
/// # Errors
/// [`SmoothError::OutOfRange`] for `sigma` outside [`HESSIAN_SIGMA_RANGE`],
/// and the errors of prefiltering (NaN pixels, empty images).
pub fn hessian_image<'a>(
    image: impl Into<ImageView<'a>>,
    sigma: f64,
    bank: &HessianBank,
    border: Border,
) -> Result<Image, SmoothError> {
    let image = image.into();
    check_sigma(sigma)?;
    let (slo, shi) = bank.stack_sigmas(sigma, sigma);
    let stack = ScaleStack::new(image, slo, shi, border, hessian_stack_options())?;
    let [hxx, hxy, hyy] = bank.bind(&stack)?.planes(sigma)?;
    Ok(Image::from_planes(
        image.width(),
        image.height(),
        &[hxx, hxy, hyy],
    )?)
}
