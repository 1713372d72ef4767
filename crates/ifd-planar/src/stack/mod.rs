//! The scale stack: an image prefiltered with isotropic Gaussians at
//! log-uniformly spaced standard deviations (the `fhat_l` of Eq. 3).

use std::sync::Arc;

use ifd_image::ImageView;
use rayon::prelude::*;
use rustfft::num_complex::{Complex32, Complex64};
use rustfft::{Fft, FftPlanner};

use crate::border::Border;
use crate::error::FilterError;

/// Smallest accepted standard deviation, in pixels.
pub const MIN_SIGMA: f64 = 0.05;
/// Largest accepted standard deviation, in pixels.
pub const MAX_SIGMA: f64 = 1.0e5;
/// Largest accepted FFT domain (complex samples per buffer).
const MAX_FFT_ELEMENTS: usize = 1 << 29;
/// Largest pyramid subsampling exponent.
const MAX_PYRAMID_LEVEL: u32 = 12;

/// Parameters of a [`ScaleStack`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StackOptions {
    /// Levels per octave of sigma (at least 1, at most 64). Default 4.
    pub samples_per_octave: usize,
    /// A level with `sigma >= pyramid_factor * 2^j` is stored subsampled by
    /// `2^j`. Default 2; `f64::INFINITY` stores every level at full
    /// resolution. Must be at least 1.
    pub pyramid_factor: f64,
    /// Full-resolution pixels of blurred border-extended image stored around
    /// the image (needed for exact lookups outside the image with replicate
    /// and constant borders). Default 0.
    pub margin: usize,
    /// How levels are read between their samples. Default
    /// [`Interpolation::Linear`].
    pub interpolation: Interpolation,
}

impl Default for StackOptions {
    fn default() -> Self {
        Self {
            samples_per_octave: 4,
            pyramid_factor: 2.0,
            margin: 0,
            interpolation: Interpolation::Linear,
        }
    }
}

/// How a level is read at a position between its samples.
///
/// A level is the image correlated with a Gaussian of standard deviation
/// `r` samples (`r = sigma / step`, at least [`StackOptions::pyramid_factor`]
/// on subsampled levels). Reading it at a fractional position is a filter
/// whose transfer differs from the ideal shift `exp(2 pi i nu phi)`; for
/// white-noise input the relative RMS error of one lookup, averaged over the
/// phase `phi` (1D; `docs/planar-accuracy.md` derives and measures it), is
///
/// | `r` | 1 | 1.4 | 2 | 2.8 | 4 | 8 |
/// |---|---|---|---|---|---|---|
/// | linear | 7.5% | 3.9% | 1.95% | 1.0% | 0.49% | 0.12% |
/// | cubic B-spline | 1.3% | 0.21% | 0.037% | 0.008% | 0.002% | 3e-6 |
///
/// Decompositions whose weights cancel (derivative filters, band-pass
/// filters) amplify these errors by the ratio of `sum |w_t| ||g_t||` to the
/// kernel's norm, 10-100 for them, which is why the choice is made per
/// decomposition ([`crate::EvalPlan`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// Bilinear: 2x2 samples per lookup, error `O(r^-2)`.
    #[default]
    Linear,
    /// Interpolating cubic B-spline: the level stores B-spline coefficients
    /// (the prefilter `1 / (2/3 + cos(2 pi nu) / 3)` per axis is folded into
    /// the FFT build at no cost) and a lookup reads 4x4 of them, error
    /// `O(r^-4)`. Four times the arithmetic of a bilinear lookup.
    Cubic,
}

impl Interpolation {
    /// Stored samples a lookup reads before and after the one below it
    /// (`(1, 2)` for cubic, `(0, 1)` for linear).
    pub(crate) fn reach(self) -> (usize, usize) {
        match self {
            Self::Linear => (0, 1),
            Self::Cubic => (1, 2),
        }
    }

    /// The name used in CLI options and reports (`linear`, `cubic`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Linear => "linear",
            Self::Cubic => "cubic",
        }
    }
}

/// The subsampling `2^j` of the level of `sigma` px: the largest with
/// `sigma >= pyramid_factor * 2^j` (1 below `pyramid_factor`), at most
/// `2^MAX_PYRAMID_LEVEL` (see [`StackOptions::pyramid_factor`]).
pub(crate) fn pyramid_step(sigma: f64, pyramid_factor: f64) -> usize {
    let ratio = sigma / pyramid_factor;
    let j = if ratio >= 1.0 {
        (ratio.log2().floor() as u32).min(MAX_PYRAMID_LEVEL)
    } else {
        0
    };
    1usize << j
}

/// The cubic B-spline weights of the four samples at `-1, 0, 1, 2` for a
/// fractional position `t` in `[0, 1)`.
#[inline]
pub(crate) fn bspline_weights(t: f32) -> [f32; 4] {
    let t2 = t * t;
    let t3 = t2 * t;
    let s = 1.0 - t;
    [
        s * s * s * (1.0 / 6.0),
        (3.0 * t3 - 6.0 * t2 + 4.0) * (1.0 / 6.0),
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) * (1.0 / 6.0),
        t3 * (1.0 / 6.0),
    ]
}

/// Geometry of one stored level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelLayout {
    /// Standard deviation of the level's Gaussian, in full-resolution pixels.
    pub sigma: f64,
    /// Subsampling factor `2^j`: stored sample `(i, j)` is at full-resolution
    /// coordinate `(origin + i * step, origin + j * step)`.
    pub step: usize,
    /// Full-resolution coordinate of stored sample 0 (`<= -1`, same on both axes).
    pub origin: i64,
    /// Stored samples per row.
    pub nx: usize,
    /// Stored rows.
    pub ny: usize,
}

/// A scale stack to be built for an image: its size, sigma range, border
/// and options, as a filter or smoother plans it
/// ([`crate::stack_plan_for_decomposition`], `Smoother::stack_plan`) before
/// checking its memory ([`StackPlan::layout`]) and building it
/// ([`StackPlan::build`]).
///
/// ```
/// use ifd_planar::{Border, StackOptions, StackPlan};
/// let plan = StackPlan {
///     dims: (64, 48, 1),
///     sigmas: (1.0, 8.0),
///     border: Border::Reflect101,
///     options: StackOptions::default(),
/// };
/// let bytes = plan.layout()?.bytes();
/// let img = ifd_image::Image::from_vec(64, 48, 1, vec![0.5; 64 * 48])?;
/// let stack = plan.build(&img)?;
/// assert_eq!(stack.sigma_range(), (1.0, 8.0));
/// # let _ = bytes;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StackPlan {
    /// The image's `(width, height, channels)`.
    pub dims: (usize, usize, usize),
    /// The smallest and largest level sigma, pixels.
    pub sigmas: (f64, f64),
    /// Border handling.
    pub border: Border,
    /// Levels per octave, pyramid, margin, interpolation.
    pub options: StackOptions,
}

impl StackPlan {
    /// The stack's layout, without building it (memory budgets, device
    /// limits).
    ///
    /// # Errors
    /// As [`StackLayout::new`].
    pub fn layout(&self) -> Result<StackLayout, FilterError> {
        let (w, h, c) = self.dims;
        StackLayout::new(w, h, c, self.sigmas.0, self.sigmas.1, self.options)
    }

    /// Builds the stack of `image`.
    ///
    /// # Errors
    /// [`FilterError::Shape`] when `image` is not of the planned size, and
    /// the errors of [`ScaleStack::new`].
    pub fn build<'a>(&self, image: impl Into<ImageView<'a>>) -> Result<ScaleStack, FilterError> {
        let image = image.into();
        let dims = (image.width(), image.height(), image.channels());
        if dims != self.dims {
            return Err(FilterError::Shape(format!(
                "image is {}x{}x{}, the stack was planned for {}x{}x{}",
                dims.0, dims.1, dims.2, self.dims.0, self.dims.1, self.dims.2
            )));
        }
        ScaleStack::new(
            image,
            self.sigmas.0,
            self.sigmas.1,
            self.border,
            self.options,
        )
    }
}

/// Where every level of a scale stack lives, computed without allocating the
/// stack (for memory budgeting).
///
/// ```
/// use ifd_planar::{StackLayout, StackOptions, Border};
/// let l = StackLayout::new(4096, 4096, 3, 1.0, 256.0, StackOptions::default())?;
/// assert_eq!(l.levels().len(), 33);
/// assert!(l.bytes() <= 2 << 30);
/// # Ok::<(), ifd_planar::FilterError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct StackLayout {
    width: usize,
    height: usize,
    channels: usize,
    levels: Vec<LevelLayout>,
    pad: usize,
    fft_width: usize,
    fft_height: usize,
    interpolation: Interpolation,
    /// Levels log-uniformly spaced (else at given sigmas).
    uniform: bool,
}

impl StackLayout {
    /// The largest stored margin up to `wanted` pixels that the stack of a
    /// `width x height x channels` image over `[sigma_min, sigma_max]` can
    /// afford: one that grows the stored levels, and separately the
    /// transient FFT buffers of the build (24 bytes per FFT sample), by at
    /// most 25% or 256 MiB each (whichever is more), and never takes the
    /// stored levels past 2 GiB when they fit there without it. A margin whose layout cannot be built at
    /// all (an FFT domain beyond the limit) counts as too dear. A wider
    /// margin makes lookups far outside the image exact (replicate, constant)
    /// or fast (reflect-101, wrap), at the cost of memory.
    ///
    /// # Errors
    /// As [`StackLayout::new`] for the stack without extra margin.
    pub fn affordable_margin(
        width: usize,
        height: usize,
        channels: usize,
        sigma_min: f64,
        sigma_max: f64,
        options: StackOptions,
        wanted: usize,
    ) -> Result<usize, FilterError> {
        const MIB: u64 = 1 << 20;
        let bytes = |margin: usize| {
            Self::new(
                width,
                height,
                channels,
                sigma_min,
                sigma_max,
                StackOptions { margin, ..options },
            )
            .map(|l| {
                let (fw, fh) = l.fft_size();
                (l.bytes(), 24 * (fw * fh) as u64)
            })
        };
        let grow = |b: u64| (b + b / 4).max(b + 256 * MIB);
        let (stored, transient) = bytes(options.margin)?;
        let mut stored_allowed = grow(stored);
        if stored <= 2048 * MIB {
            stored_allowed = stored_allowed.min(2048 * MIB);
        }
        let transient_allowed = grow(transient);
        let mut margin = wanted.clamp(options.margin, options.margin.max(1 << 16));
        while margin > options.margin {
            match bytes(margin) {
                Ok((s, t)) if s <= stored_allowed && t <= transient_allowed => break,
                _ => margin = options.margin.max(margin * 3 / 4),
            }
        }
        Ok(margin)
    }

    /// The layout of the stack of a `width x height x channels` image over
    /// `[sigma_min, sigma_max]`.
    ///
    /// # Errors
    /// [`FilterError::EmptyImage`] for a zero dimension,
    /// [`FilterError::InvalidRange`] for non-finite, non-positive, reversed or
    /// absurd sigmas (outside `[MIN_SIGMA, MAX_SIGMA]`) or options,
    /// [`FilterError::TooLarge`] when the FFT domain would be too large.
    pub fn new(
        width: usize,
        height: usize,
        channels: usize,
        sigma_min: f64,
        sigma_max: f64,
        options: StackOptions,
    ) -> Result<Self, FilterError> {
        if width == 0 || height == 0 || channels == 0 {
            return Err(FilterError::EmptyImage {
                width,
                height,
                channels,
            });
        }
        let range_err = |why: String| FilterError::InvalidRange(why);
        if !(sigma_min.is_finite() && sigma_max.is_finite()) {
            return Err(range_err(format!(
                "sigma range [{sigma_min}, {sigma_max}] is not finite"
            )));
        }
        if sigma_min < MIN_SIGMA || sigma_max > MAX_SIGMA {
            return Err(range_err(format!(
                "sigma range [{sigma_min}, {sigma_max}] px is outside [{MIN_SIGMA}, {MAX_SIGMA}] px"
            )));
        }
        if sigma_min > sigma_max {
            return Err(range_err(format!(
                "sigma_min {sigma_min} is larger than sigma_max {sigma_max}"
            )));
        }
        if options.samples_per_octave == 0 || options.samples_per_octave > 64 {
            return Err(range_err(format!(
                "samples per octave {} is outside 1..=64",
                options.samples_per_octave
            )));
        }
        if options.pyramid_factor.is_nan() || options.pyramid_factor < 1.0 {
            return Err(range_err(format!(
                "pyramid factor {} must be at least 1",
                options.pyramid_factor
            )));
        }
        if options.margin > 1 << 20 {
            return Err(range_err(format!("margin {} px is absurd", options.margin)));
        }
        let octaves = (sigma_max / sigma_min).log2();
        let n = if octaves <= 1e-9 {
            0
        } else {
            (octaves * options.samples_per_octave as f64 - 1e-9).ceil() as usize
        };
        let sigmas: Vec<f64> = (0..=n)
            .map(|i| {
                if n == 0 {
                    sigma_min
                } else if i == n {
                    sigma_max
                } else {
                    sigma_min * (octaves * i as f64 / n as f64).exp2()
                }
            })
            .collect();
        Self::from_sigmas(width, height, channels, &sigmas, options, true)
    }

    /// The layout of a stack whose levels are exactly `sigmas` (increasing,
    /// at most 256): for a filter applied at one constant scale, levels at
    /// the sigmas its terms need make every lookup hit a level, with no
    /// interpolation in `ln sigma`. Such a stack serves constant scales
    /// only ([`ScaleStack::is_uniform`]).
    ///
    /// ```
    /// use ifd_planar::{StackLayout, StackOptions};
    /// let l = StackLayout::with_sigmas(64, 64, 1, &[1.3, 2.0, 2.1, 7.5], StackOptions::default())?;
    /// assert_eq!(l.levels().len(), 4);
    /// assert!(StackLayout::with_sigmas(64, 64, 1, &[2.0, 1.0], StackOptions::default()).is_err());
    /// # Ok::<(), ifd_planar::FilterError>(())
    /// ```
    ///
    /// # Errors
    /// As [`StackLayout::new`], and [`FilterError::InvalidRange`] for sigmas
    /// that are not strictly increasing or too many.
    pub fn with_sigmas(
        width: usize,
        height: usize,
        channels: usize,
        sigmas: &[f64],
        options: StackOptions,
    ) -> Result<Self, FilterError> {
        let (Some(&lo), Some(&hi)) = (sigmas.first(), sigmas.last()) else {
            return Err(FilterError::InvalidRange("no sigmas given".into()));
        };
        // The checks of `new` (sizes, range, options).
        Self::new(width, height, channels, lo, hi, options)?;
        if sigmas.len() > 256 || sigmas.windows(2).any(|p| p[1] <= p[0]) {
            return Err(FilterError::InvalidRange(format!(
                "{} level sigmas must be strictly increasing and at most 256",
                sigmas.len()
            )));
        }
        Self::from_sigmas(width, height, channels, sigmas, options, false)
    }

    fn from_sigmas(
        width: usize,
        height: usize,
        channels: usize,
        sigmas: &[f64],
        options: StackOptions,
        uniform: bool,
    ) -> Result<Self, FilterError> {
        let sigma_max = sigmas[sigmas.len() - 1];
        let margin = options.margin;
        let levels: Vec<LevelLayout> = sigmas
            .iter()
            .map(|&sigma| {
                let step = pyramid_step(sigma, options.pyramid_factor);
                // Samples before pixel 0 and after pixel w-1 so that the
                // coverage includes [-margin-1, w+margin] on each axis, plus
                // the extra samples a cubic lookup reads on each side.
                let (extra, _) = options.interpolation.reach();
                let before = (margin + 1).div_ceil(step) + extra;
                let nx = before + (width + margin).div_ceil(step) + 1 + extra;
                let ny = before + (height + margin).div_ceil(step) + 1 + extra;
                LevelLayout {
                    sigma,
                    step,
                    origin: -((before * step) as i64),
                    nx,
                    ny,
                }
            })
            .collect();
        let max_step = levels.iter().map(|l| l.step).max().unwrap_or(1);
        let reach = (5.0 * sigma_max).ceil() as usize + 1;
        let before = levels
            .iter()
            .map(|l| (-l.origin) as usize)
            .max()
            .unwrap_or(1);
        // Cubic levels: a region refresh reconstructs coefficients from the
        // samples `CUBIC_TAPS` further out, so those must not see the FFT's
        // periodic wrap either.
        let extra = if options.interpolation == Interpolation::Cubic {
            refresh::CUBIC_TAPS * max_step
        } else {
            0
        };
        let pad = (before + reach + extra).div_ceil(max_step) * max_step;
        // Last stored full-resolution coordinate on each axis, plus one.
        let end_x = levels
            .iter()
            .map(|l| l.origin + ((l.nx - 1) * l.step) as i64 + 1)
            .max()
            .unwrap_or(width as i64) as usize;
        let end_y = levels
            .iter()
            .map(|l| l.origin + ((l.ny - 1) * l.step) as i64 + 1)
            .max()
            .unwrap_or(height as i64) as usize;
        let fft_len = |end: usize| -> usize {
            next_smooth((pad + end + reach).div_ceil(max_step)) * max_step
        };
        let fft_width = fft_len(end_x);
        let fft_height = fft_len(end_y);
        if fft_width
            .checked_mul(fft_height)
            .is_none_or(|e| e > MAX_FFT_ELEMENTS)
        {
            return Err(FilterError::TooLarge(format!(
                "a {width}x{height} image with sigma up to {sigma_max} px needs a \
                 {fft_width}x{fft_height} FFT domain (limit {MAX_FFT_ELEMENTS} samples)"
            )));
        }
        Ok(Self {
            width,
            height,
            channels,
            levels,
            pad,
            fft_width,
            fft_height,
            interpolation: options.interpolation,
            uniform,
        })
    }

    /// How the levels are read.
    #[must_use]
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// The levels, by increasing sigma.
    #[must_use]
    pub fn levels(&self) -> &[LevelLayout] {
        &self.levels
    }

    /// Bytes of `f32` samples the stack stores.
    #[must_use]
    pub fn bytes(&self) -> u64 {
        self.levels
            .iter()
            .map(|l| (l.nx * l.ny * self.channels * std::mem::size_of::<f32>()) as u64)
            .sum()
    }

    /// Size `(width, height)` of the padded FFT domain used while building.
    #[must_use]
    pub fn fft_size(&self) -> (usize, usize) {
        (self.fft_width, self.fft_height)
    }
}

/// Smallest integer `>= n` whose prime factors are all in {2, 3, 5, 7}.
fn next_smooth(n: usize) -> usize {
    let mut m = n.max(1);
    loop {
        let mut r = m;
        for p in [2, 3, 5, 7] {
            while r.is_multiple_of(p) {
                r /= p;
            }
        }
        if r == 1 {
            return m;
        }
        m += 1;
    }
}

/// One stored level.
#[derive(Clone, Debug)]
pub(crate) struct Level {
    pub(crate) layout: LevelLayout,
    /// `origin` as `f32`.
    pub(crate) origin: f32,
    /// `1 / step`.
    pub(crate) inv_step: f32,
    /// Interleaved samples `[iy][ix][channel]`.
    pub(crate) data: Vec<f32>,
}

/// An image prefiltered with isotropic Gaussians over a range of sigmas.
///
/// ```
/// use ifd_image::Image;
/// use ifd_planar::{Border, ScaleStack, StackOptions};
/// let mut img = Image::new(32, 24, 1)?;
/// img.set(16, 12, 0, 1.0);
/// let stack = ScaleStack::new(&img, 1.0, 8.0, Border::Reflect101, StackOptions::default())?;
/// // The impulse response at the centre is the Gaussian's peak 1 / (2 pi sigma^2).
/// let v = stack.sample(16.0, 12.0, 2.0)?;
/// assert!((v[0] - 1.0 / (2.0 * std::f32::consts::PI * 4.0)).abs() < 1e-5);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// The scale stack: an image prefiltered with isotropic Gaussians at
/// log-uniformly spaced standard deviations (the `fhat_l` of Eq. 3).
///
/// # Which Gaussian
/// Each level is the correlation of the border-extended image with the
/// **sampled** normalised Gaussian
/// `g_sigma(d) = exp(-|d|^2 / (2 sigma^2)) / (2 pi sigma^2)` at integer
/// offsets `d` — exactly the atom that [`crate::Decomposition::eval`] evaluates, so a
/// decomposition applied through the stack and the brute-force correlation
/// with the kernel `Decomposition::eval` samples agree to interpolation error
/// only. The transfer function used in the FFT is the exact DFT of that
/// sampled kernel (computed by FFT of the periodised samples), not the
/// analytic transform `exp(-2 pi^2 sigma^2 |nu|^2)`. The two differ by the
/// aliases of the analytic transform: the DC gain of the sampled kernel is
/// `(1 + 2 sum_k exp(-2 pi^2 sigma^2 k^2))^2`, i.e. `+2.9 %` at `sigma = 0.5`,
/// `+5e-4` at `0.7` and `1e-8` at `1`, and at the Nyquist frequency the
/// analytic transform is `exp(-pi^2 sigma^2 / 2)` (`0.29` at `sigma = 0.5`,
/// `7e-3` at `1`, `3e-9` at `2`) while the sampled one is twice that. Using the
/// analytic transform would therefore make small-sigma atoms disagree with
/// their definition by up to a few percent; the sampled one costs nothing more.
///
/// # Layout
/// Levels are `sigma_i = sigma_min * r^i`, `r = (sigma_max / sigma_min)^(1/n)`
/// with `n = ceil(octaves * samples_per_octave)`. A level whose sigma is at
/// least `k * 2^j` pixels ([`StackOptions::pyramid_factor`] `k`, default 2) is
/// stored subsampled by `2^j` (a Gaussian pyramid; the subsampling is exact —
/// the coarse spectrum is the alias sum of the fine one — and a Gaussian with
/// `sigma >= 2` coarse pixels has transfer below `3e-9` beyond the coarse
/// Nyquist frequency). Every level also stores a margin of at least one sample
/// (and [`StackOptions::margin`] full-resolution pixels) of the blurred
/// *border-extended* image outside the image.
///
/// # Lookup
/// [`ScaleStack::sample`] interpolates bilinearly in space and linearly in
/// `ln sigma` (trilinear). Outside the stored region, coordinates are resolved
/// by the border mode: for reflect-101 and wrap this is exact (the blurred
/// extension of a symmetric/periodic extension is the symmetric/periodic
/// extension of the blurred image); for replicate and constant the stored
/// margin is exact and beyond it the lookup is clamped (replicate) or returns
/// the constant, so give a margin as large as the largest displacement you
/// will look up (see [`crate::stack_for_decomposition`]).
#[derive(Clone, Debug)]
pub struct ScaleStack {
    width: usize,
    height: usize,
    channels: usize,
    border: Border,
    sigmas: Vec<f64>,
    ln_sigma0: f64,
    /// `1 / ln(r)`, 0 for a single level; NaN for levels at given sigmas.
    inv_ln_ratio: f64,
    /// `ln sigma` of every level (for stacks with levels at given sigmas).
    ln_sigmas: Vec<f64>,
    interpolation: Interpolation,
    pub(crate) levels: Vec<Level>,
}

impl ScaleStack {
    /// Prefilters `image` (every channel) over `[sigma_min, sigma_max]` pixels.
    ///
    /// # Errors
    /// As [`ScaleStack::from_interleaved`].
    pub fn new<'a>(
        image: impl Into<ImageView<'a>>,
        sigma_min: f64,
        sigma_max: f64,
        border: Border,
        options: StackOptions,
    ) -> Result<Self, FilterError> {
        let image = image.into();
        Self::from_interleaved(
            image.width(),
            image.height(),
            image.channels(),
            image.data(),
            sigma_min,
            sigma_max,
            border,
            options,
        )
    }

    /// Prefilters interleaved row-major samples (`height x width x channels`).
    ///
    /// # Errors
    /// [`FilterError::EmptyImage`], [`FilterError::Shape`] for a wrong data
    /// length, [`FilterError::NonFinite`] for NaN or infinite samples, and the
    /// errors of [`StackLayout::new`].
    #[expect(
        clippy::too_many_arguments,
        reason = "plain image description plus stack parameters"
    )]
    pub fn from_interleaved(
        width: usize,
        height: usize,
        channels: usize,
        data: &[f32],
        sigma_min: f64,
        sigma_max: f64,
        border: Border,
        options: StackOptions,
    ) -> Result<Self, FilterError> {
        let layout = StackLayout::new(width, height, channels, sigma_min, sigma_max, options)?;
        Self::build(&layout, data, border)
    }

    /// Prefilters `image` (every channel) with exactly the Gaussians
    /// `sigmas` (strictly increasing, px): see [`StackLayout::with_sigmas`].
    /// A lookup at a level's sigma reads that level alone.
    ///
    /// # Errors
    /// As [`ScaleStack::from_interleaved`] and [`StackLayout::with_sigmas`].
    pub fn with_sigmas<'a>(
        image: impl Into<ImageView<'a>>,
        sigmas: &[f64],
        border: Border,
        options: StackOptions,
    ) -> Result<Self, FilterError> {
        let image = image.into();
        let (w, h, c) = (image.width(), image.height(), image.channels());
        let layout = StackLayout::with_sigmas(w, h, c, sigmas, options)?;
        Self::build(&layout, image.data(), border)
    }

    /// Prefilters interleaved samples into the levels of `layout`.
    fn build(layout: &StackLayout, data: &[f32], border: Border) -> Result<Self, FilterError> {
        let (width, height, channels) = (layout.width, layout.height, layout.channels);
        let expected = width * height * channels;
        if data.len() != expected {
            return Err(FilterError::Shape(format!(
                "{} samples given for a {width}x{height}x{channels} image ({expected} expected)",
                data.len()
            )));
        }
        check_finite(data, width, channels)?;
        if !border.constant().is_finite() {
            return Err(FilterError::InvalidBorder(border.to_string()));
        }
        let mut levels: Vec<Level> = layout
            .levels
            .iter()
            .map(|l| Level {
                layout: *l,
                origin: l.origin as f32,
                inv_step: 1.0 / l.step as f32,
                data: vec![0.0; l.nx * l.ny * channels],
            })
            .collect();
        build_levels(layout, data, border, &mut levels);
        let sigmas: Vec<f64> = layout.levels.iter().map(|l| l.sigma).collect();
        let ln_sigma0 = sigmas[0].ln();
        let inv_ln_ratio = if !layout.uniform {
            f64::NAN
        } else if sigmas.len() > 1 {
            (sigmas.len() - 1) as f64 / (sigmas[sigmas.len() - 1].ln() - ln_sigma0)
        } else {
            0.0
        };
        let ln_sigmas = sigmas.iter().map(|s| s.ln()).collect();
        Ok(Self {
            width,
            height,
            channels,
            border,
            sigmas,
            ln_sigma0,
            inv_ln_ratio,
            ln_sigmas,
            interpolation: layout.interpolation,
            levels,
        })
    }

    /// Image width in pixels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Image height in pixels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of channels.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The border mode the image was extended with.
    #[must_use]
    pub fn border(&self) -> Border {
        self.border
    }

    /// The levels' sigmas, increasing.
    #[must_use]
    pub fn sigmas(&self) -> &[f64] {
        &self.sigmas
    }

    /// `(sigma_min, sigma_max)` covered.
    #[must_use]
    pub fn sigma_range(&self) -> (f64, f64) {
        (self.sigmas[0], self.sigmas[self.sigmas.len() - 1])
    }

    /// The levels' geometry.
    pub fn level_layouts(&self) -> impl Iterator<Item = &LevelLayout> + '_ {
        self.levels.iter().map(|l| &l.layout)
    }

    /// Bytes of samples stored.
    #[must_use]
    pub fn bytes(&self) -> u64 {
        self.levels
            .iter()
            .map(|l| (l.data.len() * std::mem::size_of::<f32>()) as u64)
            .sum()
    }

    /// Whether the levels are log-uniformly spaced ([`ScaleStack::new`]),
    /// which per-pixel scales and the GPU path need, rather than at given
    /// sigmas ([`ScaleStack::with_sigmas`]).
    #[must_use]
    pub fn is_uniform(&self) -> bool {
        !self.inv_ln_ratio.is_nan()
    }

    /// How the levels are read between their samples (what they store:
    /// samples for [`Interpolation::Linear`], B-spline coefficients for
    /// [`Interpolation::Cubic`]).
    #[must_use]
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Whether `sigma` lies in the covered range (with a relative tolerance of 1e-6).
    #[must_use]
    pub fn covers(&self, sigma: f64) -> bool {
        let (lo, hi) = self.sigma_range();
        sigma >= lo * (1.0 - 1e-6) && sigma <= hi * (1.0 + 1e-6)
    }

    /// The two levels bracketing `sigma` and their weights (linear in
    /// `ln sigma`); clamps to the range.
    pub(crate) fn locate_ln(&self, ln_sigma: f64) -> (usize, usize, f32, f32) {
        locate_in(self.ln_sigma0, self.inv_ln_ratio, &self.ln_sigmas, ln_sigma)
    }

    /// What locating sigmas among the levels needs, without the samples
    /// (for evaluators that hold the levels elsewhere, such as the GPU's).
    ///
    /// ```
    /// use ifd_image::Image;
    /// use ifd_planar::{Border, ScaleStack, StackOptions};
    /// let img = Image::from_vec(32, 32, 1, vec![0.5; 32 * 32])?;
    /// let stack = ScaleStack::with_sigmas(&img, &[1.0, 3.0], Border::Reflect101, StackOptions::default())?;
    /// let at = stack.locator();
    /// assert_eq!(at.locate(3.0), (1, 1, 1.0, 0.0)); // on a level: that level alone
    /// let (a, b, wa, wb) = at.locate(3f64.sqrt()); // half-way in ln sigma
    /// assert_eq!((a, b), (0, 1));
    /// assert!((wa - 0.5).abs() < 1e-6 && (wb - 0.5).abs() < 1e-6);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    #[must_use]
    pub fn locator(&self) -> LevelLocator {
        LevelLocator {
            ln_sigma0: self.ln_sigma0,
            inv_ln_ratio: self.inv_ln_ratio,
            ln_sigmas: self.ln_sigmas.clone(),
        }
    }

    /// `ln sigma_0` and `1 / ln r` (for callers that locate many sigmas).
    pub(crate) fn ln_params(&self) -> (f64, f64) {
        (self.ln_sigma0, self.inv_ln_ratio)
    }

    /// All channels of the prefiltered image at `(x, y)` (full-resolution
    /// pixel coordinates, any value: outside the image it is resolved by the
    /// border mode) for Gaussian `sigma`.
    ///
    /// # Errors
    /// [`FilterError::SigmaOutOfRange`] when `sigma` is not covered,
    /// [`FilterError::InvalidParameter`] for non-finite coordinates.
    pub fn sample(&self, x: f32, y: f32, sigma: f64) -> Result<Vec<f32>, FilterError> {
        let mut out = vec![0.0; self.channels];
        self.sample_into(x, y, sigma, &mut out)?;
        Ok(out)
    }

    /// As [`ScaleStack::sample`], writing the channels into `out`
    /// (`out.len()` must equal the channel count).
    ///
    /// # Errors
    /// As [`ScaleStack::sample`], and [`FilterError::Shape`] for a wrong `out` length.
    pub fn sample_into(
        &self,
        x: f32,
        y: f32,
        sigma: f64,
        out: &mut [f32],
    ) -> Result<(), FilterError> {
        if out.len() != self.channels {
            return Err(FilterError::Shape(format!(
                "output has {} channels, the stack {}",
                out.len(),
                self.channels
            )));
        }
        if !(x.is_finite() && y.is_finite()) {
            return Err(FilterError::InvalidParameter(format!(
                "sample position ({x}, {y}) is not finite"
            )));
        }
        if !sigma.is_finite() || !self.covers(sigma) {
            let (min, max) = self.sigma_range();
            return Err(FilterError::SigmaOutOfRange { sigma, min, max });
        }
        out.fill(0.0);
        let (a, b, wa, wb) = self.locate_ln(sigma.ln());
        self.accumulate(a, x, y, wa, out);
        if wb != 0.0 {
            self.accumulate(b, x, y, wb, out);
        }
        Ok(())
    }

    /// Adds `weight *` the interpolated value of level `li` at
    /// full-resolution `(x, y)` to `acc` (one value per channel).
    #[expect(clippy::inline_always, reason = "the hot path of filtering; measured")]
    #[inline(always)]
    pub(crate) fn accumulate(&self, li: usize, x: f32, y: f32, weight: f32, acc: &mut [f32]) {
        if self.interpolation == Interpolation::Cubic {
            self.accumulate_cubic(li, x, y, weight, acc);
            return;
        }
        let level = &self.levels[li];
        let u = (x - level.origin) * level.inv_step;
        let v = (y - level.origin) * level.inv_step;
        // For non-negative values truncation is floor (and avoids a libm call
        // on baseline x86-64).
        if u >= 0.0 && v >= 0.0 {
            // (Huge values saturate and fail the range test below.)
            let (iu, iv) = (u as i32 as usize, v as i32 as usize);
            let (nx, ny) = (level.layout.nx, level.layout.ny);
            if iu + 1 < nx && iv + 1 < ny {
                let fu = u - iu as f32;
                let fv = v - iv as f32;
                let c = self.channels;
                let i00 = (iv * nx + iu) * c;
                let i10 = i00 + nx * c;
                let d = &level.data;
                if c == 1 {
                    let (a0, a1) = (d[i00], d[i00 + 1]);
                    let (b0, b1) = (d[i10], d[i10 + 1]);
                    let r0 = a0 + fu * (a1 - a0);
                    let r1 = b0 + fu * (b1 - b0);
                    acc[0] += weight * (r0 + fv * (r1 - r0));
                    return;
                }
                let top = &d[i00..i00 + 2 * c];
                let bottom = &d[i10..i10 + 2 * c];
                for (k, a) in acc.iter_mut().enumerate() {
                    let r0 = top[k] + fu * (top[c + k] - top[k]);
                    let r1 = bottom[k] + fu * (bottom[c + k] - bottom[k]);
                    *a += weight * (r0 + fv * (r1 - r0));
                }
                return;
            }
        }
        self.accumulate_outside(level, x, y, weight, acc);
    }

    /// As [`Self::accumulate`] for a compile-time channel count `C` (the
    /// accumulator stays in registers).
    #[expect(clippy::inline_always, reason = "the hot path of filtering; measured")]
    #[inline(always)]
    pub(crate) fn accumulate_fixed<const C: usize>(
        &self,
        li: usize,
        x: f32,
        y: f32,
        weight: f32,
        acc: &mut [f32; C],
    ) {
        if self.interpolation == Interpolation::Cubic {
            self.accumulate_cubic(li, x, y, weight, acc.as_mut_slice());
            return;
        }
        let level = &self.levels[li];
        let u = (x - level.origin) * level.inv_step;
        let v = (y - level.origin) * level.inv_step;
        if u >= 0.0 && v >= 0.0 {
            let (iu, iv) = (u as i32 as usize, v as i32 as usize);
            let (nx, ny) = (level.layout.nx, level.layout.ny);
            if iu + 1 < nx && iv + 1 < ny {
                let fu = u - iu as f32;
                let fv = v - iv as f32;
                let i00 = (iv * nx + iu) * C;
                let i10 = i00 + nx * C;
                let top = &level.data[i00..i00 + 2 * C];
                let bottom = &level.data[i10..i10 + 2 * C];
                for k in 0..C {
                    let r0 = top[k] + fu * (top[C + k] - top[k]);
                    let r1 = bottom[k] + fu * (bottom[C + k] - bottom[k]);
                    acc[k] += weight * (r0 + fv * (r1 - r0));
                }
                return;
            }
        }
        self.accumulate_outside(level, x, y, weight, acc.as_mut_slice());
    }

    /// The cubic B-spline lookup: 4x4 coefficients around `(x, y)`.
    #[expect(clippy::inline_always, reason = "the hot path of filtering; measured")]
    #[inline(always)]
    fn accumulate_cubic(&self, li: usize, x: f32, y: f32, weight: f32, acc: &mut [f32]) {
        let level = &self.levels[li];
        let u = (x - level.origin) * level.inv_step;
        let v = (y - level.origin) * level.inv_step;
        if u >= 1.0 && v >= 1.0 {
            let (iu, iv) = (u as i32 as usize, v as i32 as usize);
            let (nx, ny) = (level.layout.nx, level.layout.ny);
            if iu + 2 < nx && iv + 2 < ny {
                let wx = bspline_weights(u - iu as f32);
                let wy = bspline_weights(v - iv as f32);
                let c = self.channels;
                let d = &level.data;
                let row = nx * c;
                let base = ((iv - 1) * nx + iu - 1) * c;
                if c == 1 {
                    let mut sum = 0.0;
                    for (j, wyj) in wy.iter().enumerate() {
                        let r = &d[base + j * row..base + j * row + 4];
                        sum += wyj * (wx[0] * r[0] + wx[1] * r[1] + wx[2] * r[2] + wx[3] * r[3]);
                    }
                    acc[0] += weight * sum;
                    return;
                }
                for (j, wyj) in wy.iter().enumerate() {
                    let r = &d[base + j * row..base + j * row + 4 * c];
                    let wj = weight * wyj;
                    for (k, a) in acc.iter_mut().enumerate() {
                        *a += wj
                            * (wx[0] * r[k]
                                + wx[1] * r[c + k]
                                + wx[2] * r[2 * c + k]
                                + wx[3] * r[3 * c + k]);
                    }
                }
                return;
            }
        }
        self.accumulate_outside(level, x, y, weight, acc);
    }

    /// Slow path of [`Self::accumulate`]: the footprint leaves the stored
    /// region. The position is resolved by the border mode (exact for
    /// reflect-101 and wrap, whose blurred extension, and that of its
    /// B-spline coefficients, is the same extension of the blurred image),
    /// then every sample of the footprint is read, clamped to the stored
    /// region (replicate) or replaced by the constant.
    #[cold]
    #[inline(never)]
    fn accumulate_outside(&self, level: &Level, x: f32, y: f32, weight: f32, acc: &mut [f32]) {
        let step = level.layout.step as f32;
        let lo = level.origin;
        // Positions whose whole footprint is stored: [lo + before step,
        // last - (after - 1) step].
        let (before, after) = self.interpolation.reach();
        let first = lo + before as f32 * step;
        let hi_x = lo + (level.layout.nx - after) as f32 * step;
        let hi_y = lo + (level.layout.ny - after) as f32 * step;
        let map = |p: f32, n: usize, hi: f32| -> f32 {
            if p >= first && p <= hi {
                return p;
            }
            match self.border {
                Border::Constant(_) => p,
                Border::Replicate => p.clamp(first, hi),
                Border::Reflect101 | Border::Wrap => self.border.map_continuous(p, n),
            }
        };
        let x = map(x, self.width, hi_x);
        let y = map(y, self.height, hi_y);
        let u = (x - lo) * level.inv_step;
        let v = (y - lo) * level.inv_step;
        let iu = u.floor();
        let iv = v.floor();
        let axis = |f: f32| -> ([f32; 4], i64, usize) {
            match self.interpolation {
                Interpolation::Linear => ([1.0 - f, f, 0.0, 0.0], 0, 2),
                Interpolation::Cubic => (bspline_weights(f), -1, 4),
            }
        };
        let (wx, ox, n) = axis(u - iu);
        let (wy, oy, _) = axis(v - iv);
        let constant = self.border.constant();
        let c = self.channels;
        let nx = level.layout.nx as i64;
        let ny = level.layout.ny as i64;
        let is_constant = matches!(self.border, Border::Constant(_));
        for (j, &wyj) in wy[..n].iter().enumerate() {
            for (i, &wxi) in wx[..n].iter().enumerate() {
                let w = wxi * wyj;
                if w == 0.0 {
                    continue;
                }
                let mut ix = iu as i64 + ox + i as i64;
                let mut iy = iv as i64 + oy + j as i64;
                let inside = (0..nx).contains(&ix) && (0..ny).contains(&iy);
                if !inside && is_constant {
                    for a in acc.iter_mut() {
                        *a += weight * w * constant;
                    }
                    continue;
                }
                ix = ix.clamp(0, nx - 1);
                iy = iy.clamp(0, ny - 1);
                let k0 = ((iy as usize) * level.layout.nx + ix as usize) * c;
                for (k, a) in acc.iter_mut().enumerate() {
                    *a += weight * w * level.data[k0 + k];
                }
            }
        }
    }
}

/// Raw access for other evaluators of the same stack (the GPU path in
/// `ifd-gpu` uploads exactly these samples and locates levels as
/// [`ScaleStack::sample`] does).
impl ScaleStack {
    /// The samples of level `index`, interleaved `[iy][ix][channel]` with
    /// the geometry of the level's [`LevelLayout`]; `None` past the last level.
    #[must_use]
    pub fn level_data(&self, index: usize) -> Option<&[f32]> {
        self.levels.get(index).map(|l| l.data.as_slice())
    }

    /// `(ln sigma_0, 1 / ln r)`: sigma lies at fractional level
    /// `(ln sigma - ln sigma_0) / ln r`, clamped to the levels (`1 / ln r` is
    /// 0 for a one-level stack, NaN for levels at given sigmas, which have no
    /// such formula: see [`ScaleStack::is_uniform`]).
    #[must_use]
    pub fn ln_sigma_params(&self) -> (f64, f64) {
        self.ln_params()
    }
}

/// Errors on the first non-finite sample.
pub(crate) fn check_finite(data: &[f32], width: usize, channels: usize) -> Result<(), FilterError> {
    let count = data.iter().filter(|v| !v.is_finite()).count();
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        let pixel = i / channels;
        return Err(FilterError::NonFinite {
            what: "image",
            count,
            x: pixel % width,
            y: pixel / width,
            channel: i % channels,
        });
    }
    Ok(())
}

/// The exact DFT (length `n`) of the sampled 1D normalised Gaussian,
/// periodised on `n` samples. The 2D transfer function is the outer product.
fn gaussian_transfer(sigma: f64, n: usize, planner: &mut FftPlanner<f64>) -> Vec<f32> {
    let mut buf = vec![Complex64::new(0.0, 0.0); n];
    let r = (10.0 * sigma).ceil() as i64 + 1;
    let norm = 1.0 / ((2.0 * std::f64::consts::PI).sqrt() * sigma);
    let n_i = n as i64;
    for d in -r..=r {
        let g = norm * (-(d * d) as f64 / (2.0 * sigma * sigma)).exp();
        buf[d.rem_euclid(n_i) as usize].re += g;
    }
    planner.plan_fft_forward(n).process(&mut buf);
    // The kernel is real and even, so its DFT is real.
    buf.iter().map(|c| c.re as f32).collect()
}

/// A planned FFT.
type FftPlan = Arc<dyn Fft<f32>>;

/// The coarse FFT sample (along either axis) of a level's first stored
/// sample: coarse sample `i` is padded index `i * step`, and the level
/// starts `origin` full-resolution pixels from the image, `pad` after the
/// FFT domain's start.
fn first_stored(pad: usize, level: &LevelLayout) -> usize {
    ((pad / level.step) as i64 + level.origin / level.step as i64) as usize
}

/// Row `kx` of a level's coarse spectrum: the image spectrum times the
/// Gaussian's transfer, alias-summed over the `step x step` fine frequencies
/// that fold onto each coarse one (a plain product when `step == 1`).
fn blurred_coarse_row(
    kx: usize,
    row: &mut [Complex32],
    step: usize,
    spec_ref: &[Complex32],
    gx: &[f32],
    gy: &[f32],
) {
    let zero = Complex32::new(0.0, 0.0);
    let my = row.len();
    let nyp = my * step;
    let mx = gx.len() / step;
    if step == 1 {
        let g = gx[kx];
        let srow = &spec_ref[kx * nyp..(kx + 1) * nyp];
        for ((o, s), gyv) in row.iter_mut().zip(srow).zip(gy) {
            *o = s * (g * gyv);
        }
        return;
    }
    row.fill(zero);
    for ax in 0..step {
        let fx = kx + ax * mx;
        let g = gx[fx];
        if g.abs() < 1e-12 {
            continue;
        }
        let srow = &spec_ref[fx * nyp..(fx + 1) * nyp];
        for ay in 0..step {
            let base = ay * my;
            for (ky, o) in row.iter_mut().enumerate() {
                let fy = base + ky;
                *o += srow[fy] * (g * gy[fy]);
            }
        }
    }
}

/// The cubic B-spline prefilter on a periodic grid of `n` samples: the
/// inverse of the sampled B-spline's transfer `2/3 + cos(2 pi k / n) / 3`
/// (never below `1/3`), so that the spline through the stored coefficients
/// interpolates the level's samples.
fn bspline_prefilter(n: usize) -> Vec<f32> {
    (0..n)
        .map(|k| {
            let c = (std::f64::consts::TAU * k as f64 / n as f64).cos();
            (1.0 / (2.0 / 3.0 + c / 3.0)) as f32
        })
        .collect()
}

/// In-place FFT of every consecutive `len`-long row of `data`, in parallel.
fn fft_rows(data: &mut [Complex32], len: usize, fft: &Arc<dyn Fft<f32>>) {
    let rows_per_task = (1usize << 15).div_ceil(len).max(1);
    let scratch_len = fft.get_inplace_scratch_len();
    data.par_chunks_mut(len * rows_per_task).for_each_init(
        || vec![Complex32::new(0.0, 0.0); scratch_len],
        |scratch, chunk| fft.process_with_scratch(chunk, scratch),
    );
}

/// `dst (cols x rows) = transpose(src (rows x cols))`, in parallel, blocked.
fn transpose(src: &[Complex32], rows: usize, cols: usize, dst: &mut [Complex32]) {
    const B: usize = 32;
    dst[..rows * cols]
        .par_chunks_mut(rows * B)
        .enumerate()
        .for_each(|(bi, chunk)| {
            let c0 = bi * B;
            let nc = chunk.len() / rows;
            for r0 in (0..rows).step_by(B) {
                let r1 = (r0 + B).min(rows);
                for dc in 0..nc {
                    let c = c0 + dc;
                    let out = &mut chunk[dc * rows..(dc + 1) * rows];
                    for r in r0..r1 {
                        out[r] = src[r * cols + c];
                    }
                }
            }
        });
}

/// Fills every level: one forward FFT per pair of channels (packed as real
/// and imaginary parts — the Gaussian is real and even, so the two channels
/// do not mix), then per level a product with the transfer function, an
/// alias sum down to the level's resolution and an inverse FFT. A channel
/// without a partner (a grey image, the third of RGB) takes the real-input
/// path, [`build_lone_channel`], at half the cost.
fn build_levels(layout: &StackLayout, data: &[f32], border: Border, levels: &mut [Level]) {
    let (w, h, channels) = (layout.width, layout.height, layout.channels);
    let (nxp, nyp, pad) = (layout.fft_width, layout.fft_height, layout.pad);
    let mut planner = FftPlanner::<f32>::new();
    let mut planner64 = FftPlanner::<f64>::new();
    let fwd_x = planner.plan_fft_forward(nxp);
    let fwd_y = planner.plan_fft_forward(nyp);
    let transfers: Vec<(Vec<f32>, Vec<f32>)> = layout
        .levels
        .iter()
        .map(|l| {
            (
                gaussian_transfer(l.sigma, nxp, &mut planner64),
                gaussian_transfer(l.sigma, nyp, &mut planner64),
            )
        })
        .collect();
    let inverse: Vec<(FftPlan, FftPlan)> = layout
        .levels
        .iter()
        .map(|l| {
            (
                planner.plan_fft_inverse(nxp / l.step),
                planner.plan_fft_inverse(nyp / l.step),
            )
        })
        .collect();
    let xmap: Vec<Option<usize>> = (0..nxp)
        .map(|n| border.resolve(n as i64 - pad as i64, w))
        .collect();
    let ymap: Vec<Option<usize>> = (0..nyp)
        .map(|n| border.resolve(n as i64 - pad as i64, h))
        .collect();
    let cval = border.constant();
    let zero = Complex32::new(0.0, 0.0);
    // The pair buffers (none for a single channel).
    let paired = if channels > 1 { nxp * nyp } else { 0 };
    let mut z = vec![zero; paired];
    let mut spec = vec![zero; paired];
    let mut coarse = vec![zero; paired];
    let scale = 1.0 / (nxp as f64 * nyp as f64);
    for c0 in (0..channels).step_by(2) {
        let c1 = (c0 + 1 < channels).then_some(c0 + 1);
        if c1.is_none() {
            let plans = LonePlans {
                fwd_x: &fwd_x,
                fwd_y: &fwd_y,
                inverse: &inverse,
                transfers: &transfers,
            };
            build_lone_channel(layout, data, c0, (&xmap, &ymap, cval), &plans, levels);
            continue;
        }
        z.par_chunks_mut(nxp).enumerate().for_each(|(py, row)| {
            let sy = ymap[py];
            for (px, v) in row.iter_mut().enumerate() {
                *v = match (sy, xmap[px]) {
                    (Some(y), Some(x)) => {
                        let i = (y * w + x) * channels;
                        Complex32::new(data[i + c0], c1.map_or(0.0, |c1| data[i + c1]))
                    }
                    _ => Complex32::new(cval, if c1.is_some() { cval } else { 0.0 }),
                };
            }
        });
        fft_rows(&mut z, nxp, &fwd_x);
        transpose(&z, nyp, nxp, &mut spec);
        fft_rows(&mut spec, nyp, &fwd_y);
        // spec[kx * nyp + ky]
        for (li, level) in levels.iter_mut().enumerate() {
            let step = level.layout.step;
            let (mx, my) = (nxp / step, nyp / step);
            let (gx, gy) = (&transfers[li].0, &transfers[li].1);
            let cbuf = &mut coarse[..mx * my];
            let spec_ref = &spec;
            let pre = (layout.interpolation == Interpolation::Cubic)
                .then(|| (bspline_prefilter(mx), bspline_prefilter(my)));
            cbuf.par_chunks_mut(my).enumerate().for_each(|(kx, row)| {
                blurred_coarse_row(kx, row, step, spec_ref, gx, gy);
                if let Some((px, py)) = &pre {
                    let p = px[kx];
                    for (o, q) in row.iter_mut().zip(py) {
                        *o *= p * q;
                    }
                }
            });
            let (inv_x, inv_y) = &inverse[li];
            fft_rows(cbuf, my, inv_y);
            let zbuf = &mut z[..mx * my];
            transpose(cbuf, mx, my, zbuf);
            fft_rows(zbuf, mx, inv_x);
            // zbuf[y' * mx + x'], coarse sample i <-> padded index i * step.
            let first = first_stored(pad, &level.layout);
            let nx = level.layout.nx;
            let zref = &*zbuf;
            level
                .data
                .par_chunks_mut(nx * channels)
                .enumerate()
                .for_each(|(iy, row)| {
                    let src = &zref[(first + iy) * mx + first..];
                    for ix in 0..nx {
                        let v = src[ix];
                        row[ix * channels + c0] = (f64::from(v.re) * scale) as f32;
                        if let Some(c1) = c1 {
                            row[ix * channels + c1] = (f64::from(v.im) * scale) as f32;
                        }
                    }
                });
        }
    }
}

/// The plans and transfer functions [`build_lone_channel`] shares with
/// [`build_levels`].
struct LonePlans<'a> {
    fwd_x: &'a FftPlan,
    fwd_y: &'a FftPlan,
    /// Per level: inverse plans of lengths `nxp / step` and `nyp / step`.
    inverse: &'a [(FftPlan, FftPlan)],
    /// Per level: the transfer along x (length `nxp`) and along y (`nyp`).
    transfers: &'a [(Vec<f32>, Vec<f32>)],
}

/// One real channel's levels through half spectra. The spectrum of a real
/// image is Hermitian, `X(-k) = conj X(k)`, so only the columns
/// `kx = 0..=nxp/2` are computed and kept:
///
/// - forward: rows are transformed two at a time, packed as `z = a + i b`;
///   then `A(k) = (Z(k) + conj Z(-k)) / 2` and
///   `B(k) = (Z(k) - conj Z(-k)) / 2i` are the two rows' spectra; the
///   columns `0..=nxp/2` are transformed along y;
/// - per level: the alias sum onto the coarse columns `0..=mx/2` reads
///   fine columns above `nxp/2` as `conj X(nxp - kx, -ky)`; after the
///   inverse transforms along y, two coarse rows `a`, `b` (real, with
///   Hermitian half spectra `A`, `B`) are rebuilt together as one complex
///   row `Z(k) = A(k) + i B(k)` (`k <= mx/2`), `conj A(mx-k) + i conj
///   B(mx-k)` (above), whose inverse transform is `a + i b`.
///
/// Half the transforms of the packed-pair path, for the same samples up to
/// f32 rounding (the stack tests compare both against direct correlation).
fn build_lone_channel(
    layout: &StackLayout,
    data: &[f32],
    c0: usize,
    (xmap, ymap, cval): (&[Option<usize>], &[Option<usize>], f32),
    plans: &LonePlans<'_>,
    levels: &mut [Level],
) {
    let (w, channels) = (layout.width, layout.channels);
    let (nxp, nyp) = (layout.fft_width, layout.fft_height);
    let pad = layout.pad;
    let zero = Complex32::new(0.0, 0.0);
    let hx = nxp / 2 + 1;
    let pairs = nyp.div_ceil(2);
    let value = |py: usize, px: usize| -> f32 {
        match (ymap[py], xmap[px]) {
            (Some(y), Some(x)) => data[(y * w + x) * channels + c0],
            _ => cval,
        }
    };
    // Rows 2r and 2r + 1 as one complex row.
    let mut z = vec![zero; pairs * nxp];
    z.par_chunks_mut(nxp).enumerate().for_each(|(r, row)| {
        let (ya, yb) = (2 * r, 2 * r + 1);
        for (px, v) in row.iter_mut().enumerate() {
            let b = if yb < nyp { value(yb, px) } else { 0.0 };
            *v = Complex32::new(value(ya, px), b);
        }
    });
    fft_rows(&mut z, nxp, plans.fwd_x);
    // Split into the half spectra of the single rows, written transposed:
    // spec[kx * nyp + ky], kx in 0..hx (one pass, no intermediate buffer;
    // buffers are reused across levels below: a fresh one costs a page
    // fault per 4 KiB, which was as much as the transforms).
    let mut spec = vec![zero; hx * nyp];
    let z_ref = &z;
    spec.par_chunks_mut(nyp * COLUMN_BLOCK)
        .enumerate()
        .for_each(|(block, cols)| {
            let k0 = block * COLUMN_BLOCK;
            let kn = cols.len() / nyp;
            for r in 0..pairs {
                let zr = &z_ref[r * nxp..(r + 1) * nxp];
                for j in 0..kn {
                    let k = k0 + j;
                    let zk = zr[k];
                    let zm = zr[(nxp - k) % nxp].conj();
                    let col = &mut cols[j * nyp..(j + 1) * nyp];
                    col[2 * r] = (zk + zm) * 0.5;
                    if 2 * r + 1 < nyp {
                        let d = (zk - zm) * 0.5;
                        // d / i = -i d
                        col[2 * r + 1] = Complex32::new(d.im, -d.re);
                    }
                }
            }
        });
    fft_rows(&mut spec, nyp, plans.fwd_y);
    let mut coarse = vec![zero; hx * nyp];
    let scale = 1.0 / (nxp as f64 * nyp as f64);
    for (li, level) in levels.iter_mut().enumerate() {
        let step = level.layout.step;
        let (mx, my) = (nxp / step, nyp / step);
        let mh = mx / 2 + 1;
        let (gx, gy) = (&plans.transfers[li].0, &plans.transfers[li].1);
        let pre = (layout.interpolation == Interpolation::Cubic)
            .then(|| (bspline_prefilter(mx), bspline_prefilter(my)));
        let cbuf = &mut coarse[..mh * my];
        let spec_ref = &spec;
        cbuf.par_chunks_mut(my).enumerate().for_each(|(kx, row)| {
            blurred_half_row(kx, row, step, spec_ref, gx, gy);
            if let Some((px, py)) = &pre {
                let p = px[kx];
                for (o, q) in row.iter_mut().zip(py) {
                    *o *= p * q;
                }
            }
        });
        let (inv_x, inv_y) = &plans.inverse[li];
        fft_rows(cbuf, my, inv_y);
        // cbuf[kx * my + y'], kx in 0..mh: rebuild rows 2r and 2r + 1 as
        // one complex row, reading the columns directly (blocks of row
        // pairs keep the columns' lines in cache).
        let cols = &*cbuf;
        let row_pairs = my.div_ceil(2);
        let out = &mut z[..row_pairs * mx];
        out.par_chunks_mut(mx * ROW_PAIR_BLOCK)
            .enumerate()
            .for_each(|(block, o)| {
                let r0 = block * ROW_PAIR_BLOCK;
                // A real row's spectrum is real at 0 and at mx / 2 (even
                // mx): drop the rounding there so that it does not leak
                // into the partner row.
                let fix = |mut c: Complex32, k: usize| {
                    if k == 0 || 2 * k == mx {
                        c.im = 0.0;
                    }
                    c
                };
                for (dr, o) in o.chunks_mut(mx).enumerate() {
                    let (ya, yb) = (2 * (r0 + dr), 2 * (r0 + dr) + 1);
                    for (k, v) in o.iter_mut().enumerate() {
                        let (j, conj) = if k < mh { (k, false) } else { (mx - k, true) };
                        let ca = fix(cols[j * my + ya], j);
                        let cb = if yb < my {
                            fix(cols[j * my + yb], j)
                        } else {
                            zero
                        };
                        let (ca, cb) = if conj {
                            (ca.conj(), cb.conj())
                        } else {
                            (ca, cb)
                        };
                        // A + i B
                        *v = Complex32::new(ca.re - cb.im, ca.im + cb.re);
                    }
                }
            });
        fft_rows(out, mx, inv_x);
        let first = first_stored(pad, &level.layout);
        let nx = level.layout.nx;
        let out_ref = &*out;
        level
            .data
            .par_chunks_mut(nx * channels)
            .enumerate()
            .for_each(|(iy, row)| {
                let y = first + iy;
                let src = &out_ref[(y / 2) * mx + first..];
                let odd = y % 2 == 1;
                for ix in 0..nx {
                    let v = src[ix];
                    let v = if odd { v.im } else { v.re };
                    row[ix * channels + c0] = (f64::from(v) * scale) as f32;
                }
            });
    }
}

/// Columns of the half spectrum written per task by the forward split of
/// [`build_lone_channel`].
const COLUMN_BLOCK: usize = 16;
/// Row pairs rebuilt per task by its inverse.
const ROW_PAIR_BLOCK: usize = 8;

/// Row `kx` (`<= mx / 2`) of a level's coarse half spectrum from the fine
/// half spectrum `spec_half[kx * nyp + ky]` (`kx <= nxp / 2`): as
/// [`blurred_coarse_row`], reading the fine columns above `nxp / 2` by
/// Hermitian symmetry, `X(kx, ky) = conj X(nxp - kx, (nyp - ky) mod nyp)`.
fn blurred_half_row(
    kx: usize,
    row: &mut [Complex32],
    step: usize,
    spec_half: &[Complex32],
    gx: &[f32],
    gy: &[f32],
) {
    let my = row.len();
    let nyp = my * step;
    let nxp = gx.len();
    let mx = nxp / step;
    row.fill(Complex32::new(0.0, 0.0));
    for ax in 0..step {
        let fx = kx + ax * mx;
        let g = gx[fx];
        if g.abs() < 1e-12 {
            continue;
        }
        if 2 * fx <= nxp {
            let srow = &spec_half[fx * nyp..(fx + 1) * nyp];
            for ay in 0..step {
                let base = ay * my;
                for (ky, o) in row.iter_mut().enumerate() {
                    let fy = base + ky;
                    *o += srow[fy] * (g * gy[fy]);
                }
            }
        } else {
            let mirror = nxp - fx;
            let srow = &spec_half[mirror * nyp..(mirror + 1) * nyp];
            for ay in 0..step {
                let base = ay * my;
                for (ky, o) in row.iter_mut().enumerate() {
                    let fy = base + ky;
                    *o += srow[(nyp - fy) % nyp].conj() * (g * gy[fy]);
                }
            }
        }
    }
}

/// Locates sigmas among the levels of a [`ScaleStack`]
/// ([`ScaleStack::locator`]) exactly as the stack's own lookups do.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelLocator {
    ln_sigma0: f64,
    inv_ln_ratio: f64,
    ln_sigmas: Vec<f64>,
}

impl LevelLocator {
    /// `(a, b, wa, wb)`: the levels bracketing `sigma` and their weights,
    /// linear in `ln sigma`, clamped to the levels; a sigma on a level (to a
    /// relative 1e-6 of the spacing) reads that level alone (`b == a`,
    /// `wb == 0`).
    #[must_use]
    pub fn locate(&self, sigma: f64) -> (usize, usize, f32, f32) {
        locate_in(
            self.ln_sigma0,
            self.inv_ln_ratio,
            &self.ln_sigmas,
            sigma.ln(),
        )
    }

    /// Whether the levels are log-uniformly spaced ([`ScaleStack::is_uniform`]).
    #[must_use]
    pub fn is_uniform(&self) -> bool {
        !self.inv_ln_ratio.is_nan()
    }
}

/// [`ScaleStack::locate_ln`] on its parts.
fn locate_in(
    ln_sigma0: f64,
    inv_ln_ratio: f64,
    ln_sigmas: &[f64],
    ln_sigma: f64,
) -> (usize, usize, f32, f32) {
    let n = ln_sigmas.len() - 1;
    if n == 0 {
        return (0, 0, 1.0, 0.0);
    }
    if inv_ln_ratio.is_nan() {
        // Levels at given sigmas: the bracketing pair by bisection, linear
        // in ln sigma between them (exact on a level, to 1e-9).
        let l = ln_sigmas;
        let i = l.partition_point(|&v| v <= ln_sigma).clamp(1, n) - 1;
        let f = ((ln_sigma - l[i]) / (l[i + 1] - l[i])).clamp(0.0, 1.0);
        return snap_to_level(i, f);
    }
    let t = ((ln_sigma - ln_sigma0) * inv_ln_ratio).clamp(0.0, n as f64);
    let i = (t.floor() as usize).min(n - 1);
    snap_to_level(i, t - i as f64)
}

pub(crate) mod gather;
pub(crate) mod lookup;
pub mod refresh;

/// Within this fraction of a level's spacing (in ln sigma), a sigma is
/// read from that level alone: one lookup instead of two, for an error of at
/// most this fraction of the difference between neighbouring levels. Sigmas
/// that are levels up to rounding (a decomposition's sigmas on a stack built
/// for them, or on a log-uniform stack whose ratio they share) then cost one
/// lookup per term.
pub(crate) const LEVEL_SNAP: f64 = 1e-6;

/// `(a, b, wa, wb)` for position `i + f` (`0 <= f <= 1`) between levels `i`
/// and `i + 1`, snapped to a level within [`LEVEL_SNAP`]: then `wb == 0`
/// (and `b == a`), so callers that skip zero weights do one lookup.
#[inline]
pub(crate) fn snap_to_level(i: usize, f: f64) -> (usize, usize, f32, f32) {
    if f < LEVEL_SNAP {
        (i, i, 1.0, 0.0)
    } else if f > 1.0 - LEVEL_SNAP {
        (i + 1, i + 1, 1.0, 0.0)
    } else {
        (i, i + 1, (1.0 - f) as f32, f as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigmas_on_a_level_up_to_rounding_read_one_level() {
        let img = ifd_image::Image::from_vec(16, 16, 1, (0..256).map(|i| (i % 7) as f32).collect())
            .unwrap();
        let uniform =
            ScaleStack::new(&img, 1.0, 8.0, Border::Reflect101, StackOptions::default()).unwrap();
        let given = ScaleStack::with_sigmas(
            &img,
            &[1.0, 2.5, 4.0],
            Border::Reflect101,
            StackOptions::default(),
        )
        .unwrap();
        for stack in [&uniform, &given] {
            for (k, &sigma) in stack.sigmas().iter().enumerate() {
                for nudge in [1.0 - 1e-9, 1.0, 1.0 + 1e-9] {
                    let (a, _, wa, wb) = stack.locate_ln((sigma * nudge).ln());
                    assert_eq!((a, wa, wb), (k, 1.0, 0.0), "sigma {sigma} x {nudge}");
                }
            }
            // Between levels: two, weights summing to one.
            let (s0, s1) = (stack.sigmas()[0], stack.sigmas()[1]);
            let (a, b, wa, wb) = stack.locate_ln((0.5 * (s0.ln() + s1.ln())).exp().ln());
            assert_eq!((a, b), (0, 1));
            assert!((wa - 0.5).abs() < 1e-6 && (wb - 0.5).abs() < 1e-6);
        }
    }

    /// The real-input path of a lone channel gives the samples the
    /// packed-pair path gives the same channel (paired with another): odd
    /// and even FFT sizes, subsampled levels, every border, both
    /// interpolations. (Both are also checked against direct correlation by
    /// `refresh::tests::refresh_matches_rebuild`.)
    #[test]
    fn a_lone_channel_matches_the_same_channel_in_a_pair() {
        let (w, h) = (97usize, 70usize);
        let grey: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                (0.37 * x).sin() + (0.21 * y * y / h as f32).cos() + ((i * 7919) % 13) as f32 / 13.0
            })
            .collect();
        let pair: Vec<f32> = grey
            .iter()
            .enumerate()
            .flat_map(|(i, &v)| [v, (i % 5) as f32])
            .collect();
        for interpolation in [Interpolation::Linear, Interpolation::Cubic] {
            for border in [
                Border::Reflect101,
                Border::Constant(0.25),
                Border::Replicate,
                Border::Wrap,
            ] {
                for (smin, smax, factor) in [(0.6, 24.0, 2.0), (1.3, 9.0, 1.0), (2.0, 2.0, 4.0)] {
                    let opts = StackOptions {
                        pyramid_factor: factor,
                        margin: 5,
                        interpolation,
                        ..StackOptions::default()
                    };
                    let lone =
                        ScaleStack::from_interleaved(w, h, 1, &grey, smin, smax, border, opts)
                            .unwrap();
                    let two =
                        ScaleStack::from_interleaved(w, h, 2, &pair, smin, smax, border, opts)
                            .unwrap();
                    let mut steps = Vec::new();
                    for (k, l) in lone.level_layouts().enumerate() {
                        steps.push(l.step);
                        let (a, b) = (lone.level_data(k).unwrap(), two.level_data(k).unwrap());
                        let range = a.iter().fold(0f32, |m, v| m.max(v.abs()));
                        let worst = a
                            .iter()
                            .zip(b.iter().step_by(2))
                            .fold(0f32, |m, (u, v)| m.max((u - v).abs()));
                        assert!(
                            worst <= 2e-6 * range.max(1.0),
                            "{interpolation:?} {border} sigma {} step {}: {worst}",
                            l.sigma,
                            l.step
                        );
                    }
                    if factor == 1.0 {
                        assert!(
                            steps.iter().any(|&s| s > 1),
                            "no subsampled level: {steps:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn smooth_sizes() {
        assert_eq!(next_smooth(1), 1);
        assert_eq!(next_smooth(11), 12);
        assert_eq!(next_smooth(97), 98);
        assert_eq!(next_smooth(121), 125);
    }

    #[test]
    fn rgb_4096_fits_in_2_gib() {
        let layout = StackLayout::new(4096, 4096, 3, 1.0, 256.0, StackOptions::default())
            .expect("valid layout");
        let bytes = layout.bytes();
        // 4 samples per octave over 8 octaves.
        assert_eq!(layout.levels().len(), 33);
        assert!(bytes <= 2 << 30, "stack needs {bytes} bytes");
        // Full resolution alone would need 33 * 192 MiB.
        assert!(bytes > 1 << 30);
        eprintln!(
            "4096x4096 RGB stack, sigma 1..256: {:.3} GiB",
            bytes as f64 / f64::from(1u32 << 30)
        );
        // Every level keeps at least 2 stored samples per sigma.
        for l in layout.levels() {
            assert!(l.sigma >= 2.0 * l.step as f64 || l.step == 1);
        }
    }

    #[test]
    fn affordable_margin_respects_the_memory_limits() {
        let o = StackOptions::default();
        let bytes = |w, h, c, lo, hi, m| {
            StackLayout::new(w, h, c, lo, hi, StackOptions { margin: m, ..o })
                .expect("layout")
                .bytes()
        };
        // Small stacks take the whole margin they ask for (within 256 MiB more).
        let m = StackLayout::affordable_margin(1024, 1024, 1, 0.6, 6.0, o, 129).expect("margin");
        assert_eq!(m, 129);
        // A 4096x4096 RGB stack over sigma 1..256 stays within 2 GiB however
        // wide a margin is asked for, and gets a smaller one.
        let m = StackLayout::affordable_margin(4096, 4096, 3, 1.0, 256.0, o, 1024).expect("margin");
        assert!(m < 1024, "{m}");
        assert!(bytes(4096, 4096, 3, 1.0, 256.0, m) <= 2 << 30);
        // It never goes below the margin the options already ask for.
        let o7 = StackOptions { margin: 7, ..o };
        assert!(StackLayout::affordable_margin(64, 64, 1, 1.0, 2.0, o7, 0).expect("margin") >= 7);
    }

    #[test]
    fn layout_rejects_absurd_ranges() {
        let o = StackOptions::default();
        assert!(StackLayout::new(8, 8, 1, 0.0, 4.0, o).is_err());
        assert!(StackLayout::new(8, 8, 1, 4.0, 1.0, o).is_err());
        assert!(StackLayout::new(8, 8, 1, f64::NAN, 4.0, o).is_err());
        assert!(StackLayout::new(8, 8, 1, 1.0, f64::INFINITY, o).is_err());
        assert!(StackLayout::new(8, 8, 1, 1.0, 1e9, o).is_err());
        assert!(StackLayout::new(0, 8, 1, 1.0, 2.0, o).is_err());
        let bad = StackOptions {
            samples_per_octave: 0,
            ..o
        };
        assert!(StackLayout::new(8, 8, 1, 1.0, 2.0, bad).is_err());
        // Huge sigma on a huge image: FFT domain too large.
        assert!(matches!(
            StackLayout::new(60_000, 60_000, 1, 1.0, 5000.0, o),
            Err(FilterError::TooLarge(_))
        ));
    }
}
