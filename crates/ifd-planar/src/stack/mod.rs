//! The scale stack: an image prefiltered with isotropic Gaussians at
//! log-uniformly spaced standard deviations (the `fhat_l` of Eq. 3).

pub(crate) mod for_decomposition;
pub(crate) mod lookup;
pub mod refresh;
pub(crate) mod rows;

mod build;
mod locate;
mod plan;
pub(crate) mod reads;
mod sample;
mod separable;
mod weighted_sum;

pub(crate) use build::check_finite;
pub use locate::LevelLocator;
pub(crate) use locate::{LevelRule, ScalePosition};
pub use plan::{Interpolation, LevelLayout, MIN_SIGMA, StackLayout, StackOptions, StackPlan};
pub(crate) use plan::{MAX_EXACT_LEVELS, bspline_weights, log_uniform_sigmas, pyramid_step};
pub use separable::StackBuild;

use ifd_image::ImageView;

use crate::border::Border;
use crate::error::FilterError;
use build::build_levels;

/// Stored-sample index ranges `((i0, i1), (j0, j1))`, inclusive, per axis
/// (empty as `((0, -1), (0, -1))`).
pub(crate) type Window = ((i64, i64), (i64, i64));

/// Whether a window holds no sample.
pub(crate) fn is_empty(((i0, i1), (j0, j1)): Window) -> bool {
    i0 > i1 || j0 > j1
}

/// Samples in a window.
pub(crate) fn area(w: Window) -> f64 {
    if is_empty(w) {
        0.0
    } else {
        let ((i0, i1), (j0, j1)) = w;
        ((i1 - i0 + 1) * (j1 - j0 + 1)) as f64
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

impl Level {
    /// A level of `layout` holding `data`.
    pub(crate) fn new(layout: &LevelLayout, data: Vec<f32>) -> Self {
        Self {
            layout: *layout,
            origin: layout.origin as f32,
            inv_step: 1.0 / layout.step as f32,
            data,
        }
    }
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
    /// Where a sigma lies among the levels (its `1 / ln r` is 0 for a
    /// single level, NaN for levels at given sigmas).
    locator: LevelLocator,
    interpolation: Interpolation,
    build_method: StackBuild,
    pub(crate) levels: Vec<Level>,
    /// Per level, the stored samples a filter reads, where the stack was
    /// built for one filter's reads ([`crate::FilterPlan::build_stack_for`]):
    /// it computed those (and what its chains needed); `None`: all.
    computed: Option<Vec<Window>>,
    /// The share of the stored samples computed.
    computed_share: f64,
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
        Self::build(&layout, data, border, None)
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
        Self::build(&layout, image.data(), border, None)
    }

    /// Prefilters interleaved samples into the levels of `layout`: all
    /// their samples, or with `windows` (one per level) those the direct
    /// build computes within them, zeros elsewhere, where it is the cheaper
    /// build for them (else all, by FFT).
    pub(crate) fn build(
        layout: &StackLayout,
        data: &[f32],
        border: Border,
        windows: Option<Vec<Window>>,
    ) -> Result<Self, FilterError> {
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
        let build_method = separable::choose(layout, windows.as_deref());
        let direct = build_method == StackBuild::Direct;
        let computed = windows.filter(|_| direct);
        let computed_share = computed
            .as_deref()
            .map_or(1.0, |w| separable::computed_share(layout, w));
        let src = separable::Source {
            data,
            width,
            height,
            channels,
            border,
        };
        let mut direct_data = if direct {
            separable::build_levels(&src, layout, computed.as_deref())
        } else {
            Vec::new()
        }
        .into_iter();
        let mut levels: Vec<Level> = layout
            .levels
            .iter()
            .map(|l| {
                let data = direct_data.next();
                Level::new(l, data.unwrap_or_else(|| vec![0.0; l.nx * l.ny * channels]))
            })
            .collect();
        if !direct {
            build_levels(layout, data, border, &mut levels);
        }
        let sigmas: Vec<f64> = layout.levels.iter().map(|l| l.sigma).collect();
        let locator = layout.locator();
        Ok(Self {
            width,
            height,
            channels,
            border,
            sigmas,
            locator,
            interpolation: layout.interpolation,
            build_method,
            levels,
            computed,
            computed_share,
        })
    }

    /// The share of the levels' samples computed: 1 but for a stack built
    /// for one filter's reads ([`crate::FilterPlan::build_stack_for`]),
    /// which computes only the samples its lookups read (and what the
    /// levels built from them need).
    #[must_use]
    pub fn computed_share(&self) -> f64 {
        self.computed_share
    }

    /// Per level, the stored samples a filter reads, where the stack was
    /// built for its reads (`None`: all computed).
    pub(crate) fn computed_windows(&self) -> Option<&[Window]> {
        self.computed.as_deref()
    }

    /// [`FilterError::InvalidParameter`] for a stack built for one filter's
    /// reads, whose samples `what` (a lookup anywhere) may not find.
    pub(crate) fn check_whole(&self, what: &str) -> Result<(), FilterError> {
        if self.computed.is_none() {
            return Ok(());
        }
        Err(FilterError::InvalidParameter(format!(
            "this stack holds only the samples that the filters and scale map it was built for read \
             (build_stack_for), not those {what} needs: build it with build_stack"
        )))
    }

    /// How the levels were computed (the cheaper build for the layout).
    #[must_use]
    pub fn build_method(&self) -> StackBuild {
        self.build_method
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
        self.locator.is_uniform()
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

    /// Whether a sigma between two levels reads the one nearest it alone
    /// ([`StackOptions::nearest_level`]) rather than a blend of both.
    #[must_use]
    pub fn reads_nearest_level(&self) -> bool {
        self.locator.reads_nearest_level()
    }

    /// The per-pixel level rule's snap ([`LevelRule::snap`]) on this stack.
    pub(crate) fn pixel_snap(&self) -> f32 {
        if self.reads_nearest_level() {
            locate::NEAREST_SNAP as f32
        } else {
            locate::PIXEL_SNAP
        }
    }

    /// The two levels bracketing `sigma` and their weights (linear in
    /// `ln sigma`); clamps to the range.
    pub(crate) fn locate_ln(&self, ln_sigma: f64) -> (usize, usize, f32, f32) {
        self.locator.locate_ln(ln_sigma)
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
        self.locator.clone()
    }

    /// `ln sigma_0` and `1 / ln r` (for callers that locate many sigmas).
    pub(crate) fn ln_params(&self) -> (f64, f64) {
        (self.locator.ln_sigma0, self.locator.inv_ln_ratio)
    }
}

/// Raw access for other evaluators of the same stack (the GPU path in
/// `ifd-gpu` uploads exactly these samples and locates levels as
/// [`ScaleStack::sample`] does).
impl ScaleStack {
    /// The samples of level `index`, interleaved `[iy][ix][channel]` with
    /// the geometry of the level's [`LevelLayout`]; `None` past the last level.
    /// On a stack built for one filter's reads
    /// ([`crate::FilterPlan::build_stack_for`], [`ScaleStack::computed_share`]
    /// below 1) the samples that filter does not read are zeros.
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

#[cfg(test)]
mod tests {
    use super::plan::next_smooth;
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
