//! Planning a stack: its options, the sigmas of its levels and their
//! storage (pyramid steps, margins, FFT sizes) before any sample is computed.

use ifd_image::ImageView;

use super::ScaleStack;
use crate::border::Border;
use crate::error::FilterError;

/// Smallest accepted standard deviation, in pixels.
pub const MIN_SIGMA: f64 = 0.05;
/// Largest accepted standard deviation, in pixels.
pub const MAX_SIGMA: f64 = 1.0e5;
/// Largest accepted FFT domain (complex samples per buffer).
pub(super) const MAX_FFT_ELEMENTS: usize = 1 << 29;
/// Largest pyramid subsampling exponent.
pub(super) const MAX_PYRAMID_LEVEL: u32 = 12;
/// The most levels a stack at given sigmas ([`StackLayout::with_sigmas`])
/// holds; a filter whose terms have more distinct widths reads log-uniform
/// levels instead.
pub(crate) const MAX_EXACT_LEVELS: usize = 256;

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
    /// A sigma between two levels of a log-uniform stack reads the level
    /// nearest it in `ln sigma` alone (one lookup, the sigma off by up to
    /// half a level spacing) instead of blending the two around it (two
    /// lookups). [`EvalPlan`](crate::EvalPlan) chooses it with a scale map
    /// where the expected error allows, with more levels per octave.
    /// Default false.
    pub nearest_level: bool,
}

impl Default for StackOptions {
    fn default() -> Self {
        Self {
            samples_per_octave: 4,
            pyramid_factor: 2.0,
            margin: 0,
            interpolation: Interpolation::Linear,
            nearest_level: false,
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

/// The sigmas of a log-uniform stack over `[sigma_min, sigma_max]`: a whole
/// number of equal steps in `ln sigma`, the fewest at most
/// `1 / samples_per_octave` of an octave each (one level when the range is
/// one sigma). [`StackLayout::new`] stores these levels; the evaluation plan
/// estimates its error on them.
pub(crate) fn log_uniform_sigmas(
    sigma_min: f64,
    sigma_max: f64,
    samples_per_octave: usize,
) -> Vec<f64> {
    let octaves = (sigma_max / sigma_min).log2();
    let n = if octaves <= 1e-9 {
        0
    } else {
        (octaves * samples_per_octave as f64 - 1e-9).ceil() as usize
    };
    (0..=n)
        .map(|i| {
            if n == 0 {
                sigma_min
            } else if i == n {
                sigma_max
            } else {
                sigma_min * (octaves * i as f64 / n as f64).exp2()
            }
        })
        .collect()
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

/// Terms of the cubic B-spline prefilter kept on each side by the direct
/// builds: the prefilter is `sqrt 3 z^|k|`, `z = sqrt 3 - 2`, so the
/// neglected tail is `2 sqrt 3 z^(K + 1) / (1 - z) < 2e-7` of the samples'
/// range, and a change moves coefficients at most `K` samples away by more
/// than that.
pub const CUBIC_TAPS: usize = 12;

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
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) channels: usize,
    pub(super) levels: Vec<LevelLayout>,
    pub(super) pad: usize,
    pub(super) fft_width: usize,
    pub(super) fft_height: usize,
    pub(super) interpolation: Interpolation,
    /// Levels log-uniformly spaced (else at given sigmas).
    pub(super) uniform: bool,
    /// Read at the nearest level ([`StackOptions::nearest_level`]).
    pub(super) nearest_level: bool,
}

impl StackLayout {
    /// Where sigmas lie among the levels, as the stack built on this
    /// layout locates them.
    pub(crate) fn locator(&self) -> super::LevelLocator {
        let sigmas: Vec<f64> = self.levels.iter().map(|l| l.sigma).collect();
        super::LevelLocator::new(&sigmas, self.uniform, self.nearest_level)
    }

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
        let sigmas = log_uniform_sigmas(sigma_min, sigma_max, options.samples_per_octave);
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
        if sigmas.len() > MAX_EXACT_LEVELS || sigmas.windows(2).any(|p| p[1] <= p[0]) {
            return Err(FilterError::InvalidRange(format!(
                "{} level sigmas must be strictly increasing and at most {MAX_EXACT_LEVELS}",
                sigmas.len()
            )));
        }
        Self::from_sigmas(width, height, channels, sigmas, options, false)
    }

    pub(super) fn from_sigmas(
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
            CUBIC_TAPS * max_step
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
            nearest_level: options.nearest_level,
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
pub(super) fn next_smooth(n: usize) -> usize {
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
