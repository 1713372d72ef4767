//! The stack a decomposition needs: the sigmas of its terms over a range
//! of scales ([`level_sigmas`], [`sigma_bounds`]) and the stack or plan
//! that covers them ([`stack_for_decomposition`],
//! [`stack_plan_for_decomposition`]).

use crate::border::Border;
use crate::decomposition::Decomposition;
use crate::error::FilterError;
use crate::kernel::Sampling;
use crate::prepared::{Prepare, PreparedDecomposition};
use crate::stack::{MIN_SIGMA, ScaleStack, StackLayout, StackOptions, StackPlan};
use crate::term::Term;
use ifd_image::ImageView;

/// Builds the scale stack a decomposition needs for scales in
/// `[scale_min, scale_max]`: sigmas `[scale_min * min sigma_t, scale_max *
/// max sigma_t]`, and for replicate/constant borders a margin covering the
/// largest displacement `scale_max * max |c_t|`.
///
/// # Errors
/// [`FilterError::InvalidTerm`]/[`FilterError::InvalidParameter`] for a bad
/// decomposition or scale range, and the errors of [`ScaleStack::new`].
pub fn stack_for_decomposition<'a>(
    image: impl Into<ImageView<'a>>,
    decomposition: &(impl Prepare + ?Sized),
    scale_min: f32,
    scale_max: f32,
    border: Border,
    options: StackOptions,
) -> Result<ScaleStack, FilterError> {
    let image = image.into();
    stack_plan_for_decomposition(
        (image.width(), image.height(), image.channels()),
        decomposition,
        scale_min,
        scale_max,
        border,
        options,
    )?
    .build(image)
}

/// The plan of the stack [`stack_for_decomposition`] builds for a `(width,
/// height, channels)` image, without building it (for memory budgets and
/// device limits: [`StackPlan::layout`]).
///
/// ```
/// use ifd_planar::{Border, Decomposition, StackOptions, Term};
/// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 3.0, y: 0.0, sigma: 2.0 }]);
/// let plan = ifd_planar::stack_plan_for_decomposition(
///     (640, 480, 3), &d, 1.0, 4.0, Border::Reflect101, StackOptions::default())?;
/// assert_eq!(plan.sigmas, (2.0, 8.0));
/// let bytes = plan.layout()?.bytes();
/// # Ok::<(), ifd_planar::FilterError>(())
/// ```
///
/// # Errors
/// As [`stack_for_decomposition`], except those of the image's samples.
pub fn stack_plan_for_decomposition(
    (width, height, channels): (usize, usize, usize),
    decomposition: &(impl Prepare + ?Sized),
    scale_min: f32,
    scale_max: f32,
    border: Border,
    options: StackOptions,
) -> Result<StackPlan, FilterError> {
    let d = decomposition.prepare()?;
    stack_plan_for_set(
        (width, height, channels),
        &[&*d],
        (scale_min, scale_max),
        border,
        options,
    )
}

/// [`stack_plan_for_decomposition`] for one stack that several
/// decompositions read ([`crate::FilterSetPlan`]): the sigmas of them all,
/// the margin the widest reach needs.
pub(crate) fn stack_plan_for_set(
    (width, height, channels): (usize, usize, usize),
    decompositions: &[&PreparedDecomposition],
    (scale_min, scale_max): (f32, f32),
    border: Border,
    options: StackOptions,
) -> Result<StackPlan, FilterError> {
    check_scale_range(scale_min, scale_max)?;
    let scales = (f64::from(scale_min), f64::from(scale_max));
    let (need_lo, need_hi) = decompositions
        .iter()
        .map(|d| sigma_bounds(d.sampling(), d.sigma_range(), scales))
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), (l, h)| {
            (lo.min(l), hi.max(h))
        });
    let reach = decompositions.iter().map(|d| d.reach()).fold(0.0, f64::max);
    let mut options = options;
    let need = (f64::from(scale_max) * reach).ceil() as usize + 2;
    if matches!(border, Border::Replicate | Border::Constant(_)) {
        // Beyond the stored margin these borders are approximated: store
        // every sample a lookup can reach.
        options.margin = options.margin.max(need);
    } else {
        // Reflect-101 and wrap are exact beyond the margin too, but through
        // the slow border-resolving lookup; with large kernels a wide band
        // of pixels along the border would take it for most of its taps
        // (43% of a 1024x1024 image for an extent-255 kernel, making it 1.6x
        // slower than an extent-31 one). Store a margin covering the reach
        // as far as memory allows (`StackLayout::affordable_margin`).
        options.margin = StackLayout::affordable_margin(
            width, height, channels, need_lo, need_hi, options, need,
        )?;
    }
    Ok(StackPlan {
        dims: (width, height, channels),
        sigmas: (need_lo, need_hi),
        border,
        options,
    })
}

/// [`FilterError::InvalidParameter`] unless `[scale_min, scale_max]` is a
/// finite, positive, non-empty range.
pub(crate) fn check_scale_range(scale_min: f32, scale_max: f32) -> Result<(), FilterError> {
    if scale_min.is_finite() && scale_max.is_finite() && scale_min > 0.0 && scale_min <= scale_max {
        Ok(())
    } else {
        Err(FilterError::InvalidParameter(format!(
            "scale range [{scale_min}, {scale_max}] must be finite, positive and increasing"
        )))
    }
}

/// The sigmas of the levels that filtering with `decomposition` at the
/// constant scale `scale` reads, the terms that [`evaluated_directly`] with
/// `direct_below` being evaluated directly ([`Filter::with_direct`](crate::Filter::with_direct)): the distinct
/// effective sigmas of the others, increasing, for [`ScaleStack::with_sigmas`]
/// (at least one level).
///
/// ```
/// use ifd_planar::{Decomposition, Term, level_sigmas};
/// let t = |sigma| Term { weight: 1.0, x: 0.0, y: 0.0, sigma };
/// let d = Decomposition::from_terms(vec![t(2.0), t(3.0), t(2.0), t(0.5)]);
/// assert_eq!(level_sigmas(&d, 2.0, 1.5), vec![4.0, 6.0]);
/// ```
#[must_use]
pub fn level_sigmas(decomposition: &Decomposition, scale: f32, direct_below: f64) -> Vec<f64> {
    let s = f64::from(scale);
    let sampling = decomposition.sampling;
    let terms = &decomposition.terms;
    let mut sigmas: Vec<f64> = terms
        .iter()
        .filter(|t| !evaluated_directly(sampling, t, s, direct_below))
        .map(|t| sampling.effective_sigma(t.sigma, s))
        .collect();
    if sigmas.is_empty() {
        // Every term is direct: one level, never read.
        let widest = terms.iter().map(|t| sampling.effective_sigma(t.sigma, s));
        sigmas.push(widest.fold(0.0, f64::max).max(MIN_SIGMA));
    }
    sigmas.sort_by(f64::total_cmp);
    sigmas.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * *b);
    sigmas
}

/// The smallest and largest effective sigma ([`Sampling::effective_sigma`])
/// of atoms with sigmas in `[sigma_lo, sigma_hi]` at scales in `[s_lo,
/// s_hi]`: the range a stack must cover.
///
/// ```
/// use ifd_planar::{Sampling, sigma_bounds};
/// assert_eq!(sigma_bounds(Sampling::Continuous, (1.0, 4.0), (0.5, 2.0)), (0.5, 8.0));
/// // Below scale 1 a point-sampled kernel is averaged over the pixel.
/// let (lo, hi) = sigma_bounds(Sampling::Point, (1.0, 4.0), (0.5, 0.5));
/// assert!((lo - (0.25f64 + 1.0 / 12.0).sqrt()).abs() < 1e-12);
/// ```
#[must_use]
pub fn sigma_bounds(
    sampling: Sampling,
    (sigma_lo, sigma_hi): (f64, f64),
    (s_lo, s_hi): (f64, f64),
) -> (f64, f64) {
    // The effective sigma grows with sigma and with the scale, except that
    // a point-sampled kernel drops its pixel average at scale 1.
    let lo = sampling.effective_sigma(sigma_lo, s_lo);
    let mut hi = sampling.effective_sigma(sigma_hi, s_hi);
    if sampling == Sampling::Point && s_lo < 1.0 && s_hi >= 1.0 {
        hi = hi.max((sigma_hi * sigma_hi + Sampling::Point.footprint_variance(0.5)).sqrt());
    }
    (lo, hi)
}

/// Below this many pixels (after scaling), [`Filter::with_direct`](crate::Filter::with_direct) evaluates
/// a term of a constant pose directly: no interpolation of integer-sampled
/// levels reproduces so narrow a Gaussian at a fractional position (the
/// cubic B-spline is off by 0.15% per axis at 1.5 px, 1.3% at 1 px, 16% at
/// 0.5 px), while its sampled kernel has at most `(2 ceil(5 sigma) + 3)^2`
/// taps.
pub const DIRECT_SIGMA: f64 = 1.5;

/// Terms farther than this (px, after scaling) from the centre are read from
/// the stack however narrow (the direct kernel would border-extend the image
/// by as much).
const MAX_DIRECT_REACH: f64 = 1024.0;

/// Whether [`Filter::with_direct`](crate::Filter::with_direct) with threshold `below` evaluates term `t`
/// of a decomposition sampled as `sampling` directly at the constant scale
/// `s`: its effective sigma is below `below` and it lies within 1024 px of
/// the centre (after scaling). The one rule for the filter, the levels it
/// reads ([`level_sigmas`](crate::level_sigmas)) and the error bound and estimate ([`crate::EvalPlan`]).
#[must_use]
pub fn evaluated_directly(sampling: Sampling, t: &Term, s: f64, below: f64) -> bool {
    is_direct(sampling, t.sigma, t.x.hypot(t.y), s, below)
}

/// [`evaluated_directly`] for a term of width `sigma` at `reach` px from the
/// centre (before scaling).
pub(crate) fn is_direct(sampling: Sampling, sigma: f64, reach: f64, s: f64, below: f64) -> bool {
    sampling.effective_sigma(sigma, s) < below && s * reach <= MAX_DIRECT_REACH
}
