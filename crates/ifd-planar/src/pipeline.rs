//! From an image and a decomposition to the filtered image in one call: the
//! steps that `ifd filter`, the Python module and any other front end share,
//! so that they give the same pixels.

use ifd_image::{Image, ImageView};

use crate::accuracy::{EvalPlan, PlanOptions};
use crate::filter::Filter;
use crate::stack::for_decomposition::{DIRECT_SIGMA, evaluated_directly};
use crate::stack::reads::ReadMap;
use crate::{
    Border, CheckField, CheckedField, Decomposition, Field, FieldKind, FilterError, Interpolation,
    PreparedDecomposition, Sampling, ScaleStack, StackOptions, StackPlan,
    stack_plan_for_decomposition,
};

/// How [`FilterPlan::new`] plans.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterOptions {
    /// Border handling. Default reflect-101.
    pub border: Border,
    /// Fix the interpolation of levels (`None`: the cheapest within the
    /// budget, see [`EvalPlan::choose`]).
    pub interpolation: Option<Interpolation>,
    /// Budget on the expected evaluation error
    /// ([`EvalPlan::error_estimate`]). Default `None`: the decomposition's
    /// own, [`EvalPlan::budget_for`] (a third of its fit's error, at least
    /// [`EvalPlan::DEFAULT_BUDGET`]).
    pub eval_budget: Option<f64>,
    /// Plan for an evaluator that reads every term from a log-uniformly
    /// spaced stack: no levels at exact sigmas, no direct terms.
    pub log_uniform: bool,
    /// At a constant pose, evaluate the terms narrower than
    /// [`DIRECT_SIGMA`] directly. `false` plans for an evaluator that
    /// reads every term from the stack (the GPU). Default true.
    pub direct_terms: bool,
    /// Plan for scales over this range, which must contain the scale
    /// field's (default: the field's own range). Tiles or chunks of one
    /// image, each with a part of a scale map, pass the whole map's range so
    /// that they all read the same levels and give the whole image's result.
    pub scale_range: Option<(f32, f32)>,
    /// Let per-pixel maps use the CPU's vector gathers where it has them
    /// ([`Filter::with_vector_kernels`]; the same output either way).
    /// Default true.
    pub vector_kernels: bool,
}

impl Default for FilterOptions {
    fn default() -> Self {
        Self {
            border: Border::Reflect101,
            interpolation: None,
            eval_budget: None,
            log_uniform: false,
            direct_terms: true,
            scale_range: None,
            vector_kernels: true,
        }
    }
}

/// Everything decided before the image's samples are read.
#[derive(Clone, Debug)]
pub struct FilterPlan {
    /// The decomposition, checked.
    pub decomposition: PreparedDecomposition,
    /// How levels are read and which terms are evaluated directly.
    pub eval: EvalPlan,
    /// The budget `eval` was planned within ([`FilterOptions::eval_budget`]
    /// or the decomposition's own).
    pub eval_budget: f64,
    /// The log-uniform stack (its layout bounds memory even when
    /// `level_sigmas` is used: the exact levels are no more).
    pub stack: StackPlan,
    /// Levels at exactly these sigmas (a constant scale, not
    /// [`FilterOptions::log_uniform`]); `None`: the levels of `stack`.
    pub level_sigmas: Option<Vec<f64>>,
    /// Terms evaluated directly at the (constant) scale.
    pub direct_terms: usize,
    /// As [`FilterOptions::vector_kernels`].
    pub vector_kernels: bool,
}

impl FilterPlan {
    /// Plans the filtering of a `(width, height, channels)` image with
    /// `decomposition` at the given angle and scale fields.
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] when the kernel at the largest scale
    /// spans more than the image's longer side (lookups would fold the image
    /// onto itself more than once: almost always a wrong scale), a bad
    /// decomposition, an evaluation budget that cannot be met, and the errors
    /// of [`stack_plan_for_decomposition`].
    pub fn new(
        (width, height, channels): (usize, usize, usize),
        decomposition: &Decomposition,
        angle: &CheckedField<'_>,
        scale: &CheckedField<'_>,
        options: &FilterOptions,
    ) -> Result<Self, FilterError> {
        let (smin, smax) = planned_scales(scale, options)?;
        if decomposition.terms.len() > MAX_TERMS {
            return Err(FilterError::InvalidParameter(format!(
                "the decomposition has {} terms; filtering takes at most {MAX_TERMS} (planning \
                 weighs every pair of terms: seconds at 10000, minutes past 30000; fits of real \
                 kernels have hundreds)",
                decomposition.terms.len()
            )));
        }
        check_kernel_fits(decomposition, smax, width, height)?;
        let prepared = PreparedDecomposition::new(decomposition)?;
        // Levels log-uniform in sigma (read by blending neighbours), or at
        // exactly the terms' sigmas for a constant scale.
        // (also when the terms have more distinct widths than a stack at
        // given sigmas holds: hand-made decompositions of thousands)
        let log_uniform = scale.is_map()
            || options.log_uniform
            || crate::stack::for_decomposition::level_sigmas(decomposition, smin, 0.0).len()
                > crate::stack::MAX_EXACT_LEVELS;
        let constant_pose = !angle.is_map() && !log_uniform && options.direct_terms;
        let eval_budget = options
            .eval_budget
            .unwrap_or_else(|| EvalPlan::budget_for(decomposition));
        let eval = EvalPlan::choose(
            decomposition,
            smin,
            smax,
            PlanOptions {
                budget: eval_budget,
                interpolation: options.interpolation,
                direct_sigma: if constant_pose { DIRECT_SIGMA } else { 0.0 },
                log_uniform,
            },
        )?;
        check_dc_gain(
            decomposition,
            kernel_norm(decomposition, &eval),
            (constant_pose && !scale.is_map()).then(|| angle.range().0),
            scale.range(),
            eval.direct_sigma,
        )?;
        let stack = stack_plan_for_decomposition(
            (width, height, channels),
            &prepared,
            smin,
            smax,
            options.border,
            eval.apply(StackOptions::default()),
        )?;
        // A constant scale reads levels at exactly its sigmas.
        let constant_scale = scale.range().0;
        let level_sigmas = (!log_uniform).then(|| {
            crate::stack::for_decomposition::level_sigmas(
                decomposition,
                constant_scale,
                eval.direct_sigma,
            )
        });
        let direct_terms = decomposition
            .terms
            .iter()
            .filter(|t| {
                evaluated_directly(
                    decomposition.sampling,
                    t,
                    f64::from(constant_scale),
                    eval.direct_sigma,
                )
            })
            .count();
        Ok(Self {
            decomposition: prepared,
            eval,
            eval_budget,
            stack,
            level_sigmas,
            direct_terms,
            vector_kernels: options.vector_kernels,
        })
    }

    /// The plan for a `(width, height, channels)` image whose angle is per
    /// pixel or not (`angle_varies`) and whose scales span `scale_range`
    /// (per pixel when the range is not one value), before any field is
    /// read: plans depend on whether fields vary and on their ranges, not on
    /// their values (tiles, chunks and memory estimates plan this way).
    ///
    /// # Errors
    /// As [`FilterPlan::new`].
    pub fn for_ranges(
        dims: (usize, usize, usize),
        decomposition: &Decomposition,
        angle_varies: bool,
        scale_range: (f32, f32),
        options: &FilterOptions,
    ) -> Result<Self, FilterError> {
        // One-pixel stand-ins: a map when the field varies.
        fn stand_in(
            kind: FieldKind,
            value: &[f32; 1],
            varies: bool,
        ) -> Result<CheckedField<'_>, FilterError> {
            let field = if varies {
                Field::Map(value)
            } else {
                Field::Constant(value[0])
            };
            CheckedField::new(field, kind, 1, 1)
        }
        let (lo, hi) = scale_range;
        let (a0, s0) = ([0.0f32], [lo]);
        let angle = stand_in(FieldKind::Angle, &a0, angle_varies)?;
        let scale = stand_in(FieldKind::Scale, &s0, lo != hi)?;
        let options = FilterOptions {
            scale_range: Some(scale_range),
            ..*options
        };
        Self::new(dims, decomposition, &angle, &scale, &options)
    }

    /// Prefilters `image` into the planned stack.
    ///
    /// # Errors
    /// [`FilterError::Shape`] when `image` is not of the planned size, NaN or
    /// infinite samples, and the errors of building a stack.
    pub fn build_stack<'a>(
        &self,
        image: impl Into<ImageView<'a>>,
    ) -> Result<ScaleStack, FilterError> {
        build_planned(&self.stack, self.level_sigmas.as_deref(), image.into())
    }

    /// Prefilters `image` into the planned stack, computing of each level
    /// only the samples that filtering with `scale` reads: with a scale map
    /// over a wide range, a level serves the pixels whose scale puts some
    /// term's sigma near it (the finest ones, the dearest to build, those of
    /// the smallest scales), so most of the samples a full build computes
    /// are never read. [`Self::evaluate`] with this `scale` gives
    /// [`Self::build_stack`]'s result to the stack builds' agreement (2e-6
    /// of the image's range a sample: a level may be summed from the image
    /// where the whole stack chains it from the level before); the stack
    /// is refused for other filters or scales and for lookups anywhere
    /// ([`ScaleStack::sample`], [`ScaleStack::correlate_region`],
    /// [`crate::Taps::apply_region`], [`crate::Filter::at_scale`], the GPU's
    /// upload; [`ScaleStack::computed_share`] says how much was computed).
    /// Without a scale map, with a wrapping border, or where the FFT build
    /// is cheaper, it is [`Self::build_stack`].
    ///
    /// ```
    /// use ifd_image::Image;
    /// use ifd_planar::{CheckField, Decomposition, Field, FieldKind, FilterOptions, FilterPlan, Term};
    /// let d = Decomposition::from_terms(vec![
    ///     Term { weight: 0.5, x: -3.0, y: 0.0, sigma: 2.0 },
    ///     Term { weight: 0.5, x: 3.0, y: 0.0, sigma: 4.0 },
    /// ]);
    /// let (w, h) = (128, 96);
    /// let img = Image::from_vec(w, h, 1, (0..w * h).map(|i| ((i * 37) % 23) as f32).collect())?;
    /// // Scale 0.25 in the left quarter, 1 elsewhere: the finest levels serve the left quarter.
    /// let scales: Vec<f32> = (0..w * h).map(|i| if i % w < w / 4 { 0.25 } else { 1.0 }).collect();
    /// let angle = Field::Constant(0.0).check(FieldKind::Angle, w, h)?;
    /// let scale = Field::Map(&scales).check(FieldKind::Scale, w, h)?;
    /// let plan = FilterPlan::new((w, h, 1), &d, &angle, &scale, &FilterOptions::default())?;
    /// let stack = plan.build_stack_for(&img, &scale)?;
    /// assert!(stack.computed_share() < 1.0);
    /// let out = plan.evaluate(&img, &stack, angle, scale)?;
    /// let full = plan.evaluate(&img, &plan.build_stack(&img)?, angle, scale)?;
    /// let worst = out.data().iter().zip(full.data()).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    /// assert!(worst < 1e-4); // of an image in [0, 22]
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`Self::build_stack`], and [`FilterError::MapSize`] for a scale
    /// map not of the image's size ([`FilterError::InvalidParameter`] for a
    /// field checked as an angle).
    pub fn build_stack_for<'a>(
        &self,
        image: impl Into<ImageView<'a>>,
        scale: &CheckedField<'_>,
    ) -> Result<ScaleStack, FilterError> {
        let d = &self.decomposition;
        build_for_reads(
            &self.stack,
            self.level_sigmas.as_deref(),
            image.into(),
            scale,
            (d.sampling(), &[d.terms()]),
        )
    }

    /// The largest subsampling factor among the levels [`Self::build_stack`]
    /// builds. Level samples lie at multiples of their step from the image
    /// origin, so tiles of an image whose origins are multiples of this
    /// factor (halo included) see the same samples as the whole image: the
    /// tiled and distributed paths align their tiles to it.
    ///
    /// # Errors
    /// As [`crate::StackLayout::new`].
    pub fn alignment(&self) -> Result<usize, FilterError> {
        let layout = match &self.level_sigmas {
            Some(sigmas) => {
                let (w, h, c) = self.stack.dims;
                crate::StackLayout::with_sigmas(w, h, c, sigmas, self.stack.options)?
            }
            None => self.stack.layout()?,
        };
        Ok(layout.levels().iter().map(|l| l.step).max().unwrap_or(1))
    }

    /// Evaluates the filter at every pixel on the CPU (`image` is the one
    /// `stack` was built from: the direct terms read it).
    ///
    /// # Errors
    /// Fields not of the image's size, and the errors of [`Filter::apply`].
    pub fn evaluate<'a>(
        &self,
        image: impl Into<ImageView<'a>>,
        stack: &'a ScaleStack,
        angle: CheckedField<'_>,
        scale: CheckedField<'_>,
    ) -> Result<Image, FilterError> {
        Filter::new(stack, &self.decomposition)?
            .with_direct(image, self.eval.direct_sigma)?
            .with_vector_kernels(self.vector_kernels)
            .apply(angle, scale)
    }
}

/// Filters `image` with `decomposition` rotated by `angle` (degrees,
/// counter-clockwise on screen) and scaled by `scale`, per pixel or
/// constant: [`FilterPlan::new`], [`FilterPlan::build_stack_for`],
/// [`FilterPlan::evaluate`].
///
/// # Errors
/// As those three.
///
/// From an image and a decomposition to the filtered image in one call: the
/// steps that `ifd filter`, the Python module and any other front end share,
/// so that they give the same pixels.
///
/// 1. [`FilterPlan::new`] checks that the kernel fits the image, prepares the
///    decomposition, chooses how levels are read ([`EvalPlan::choose`]) and
///    plans the scale stack: at a constant scale, levels at exactly the sigmas
///    the terms read (one lookup per term), else log-uniform levels; at a
///    constant pose, terms narrower than [`DIRECT_SIGMA`] are evaluated
///    directly.
/// 2. [`FilterPlan::build_stack_for`] prefilters the image (FFT or direct
///    sums; with a scale map only the samples the lookups read).
/// 3. [`FilterPlan::evaluate`] sums the terms at every pixel.
///
/// [`filter_image`] runs the three.
///
/// ```
/// use ifd_image::Image;
/// use ifd_planar::{FilterOptions, filter_image};
/// use ifd_planar::{CheckField, Decomposition, Field, FieldKind, Term};
/// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 2.0, y: 0.0, sigma: 3.0 }]);
/// let img = Image::from_vec(64, 48, 1, (0..64 * 48).map(|i| (i % 13) as f32).collect())?;
/// let angle = Field::Constant(30.0).check(FieldKind::Angle, 64, 48)?;
/// let scale = Field::Constant(1.0).check(FieldKind::Scale, 64, 48)?;
/// let out = filter_image(&img, &d, angle, scale, &FilterOptions::default())?;
/// assert_eq!((out.width(), out.height()), (64, 48));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn filter_image<'a>(
    image: impl Into<ImageView<'a>>,
    decomposition: &Decomposition,
    angle: CheckedField<'_>,
    scale: CheckedField<'_>,
    options: &FilterOptions,
) -> Result<Image, FilterError> {
    let image = image.into();
    let plan = FilterPlan::new(
        (image.width(), image.height(), image.channels()),
        decomposition,
        &angle,
        &scale,
        options,
    )?;
    let stack = plan.build_stack_for(image, &scale)?;
    plan.evaluate(image, &stack, angle, scale)
}

/// The kernel's L2 norm at scale 1, from `eval`'s amplification
/// (`sum |w_t| ||g_t|| / ||k||`, [`EvalPlan::amplification`]).
pub(crate) fn kernel_norm(decomposition: &Decomposition, eval: &EvalPlan) -> f64 {
    decomposition
        .terms
        .iter()
        .map(|t| t.weight.abs() / (2.0 * std::f64::consts::PI.sqrt() * t.sigma))
        .sum::<f64>()
        / eval.amplification
}

/// The scales a plan covers: [`FilterOptions::scale_range`], which must
/// contain the scale field's range, else that range.
pub(crate) fn planned_scales(
    scale: &CheckedField<'_>,
    options: &FilterOptions,
) -> Result<(f32, f32), FilterError> {
    let (flo, fhi) = scale.range();
    match options.scale_range {
        None => Ok((flo, fhi)),
        Some((lo, hi)) if lo <= flo && fhi <= hi => Ok((lo, hi)),
        Some((lo, hi)) => Err(FilterError::InvalidParameter(format!(
            "the planned scale range [{lo}, {hi}] does not contain the scale field's [{flo}, {fhi}]"
        ))),
    }
}

/// Prefilters `image` into `plan`'s log-uniform stack, or into levels at
/// exactly `level_sigmas` (with `plan`'s border and options).
pub(crate) fn build_planned(
    plan: &StackPlan,
    level_sigmas: Option<&[f64]>,
    image: ImageView<'_>,
) -> Result<ScaleStack, FilterError> {
    match level_sigmas {
        Some(sigmas) => {
            let dims = (image.width(), image.height(), image.channels());
            if dims != plan.dims {
                return Err(FilterError::Shape(format!(
                    "image is {}x{}x{}, the filter was planned for {}x{}x{}",
                    dims.0, dims.1, dims.2, plan.dims.0, plan.dims.1, plan.dims.2
                )));
            }
            ScaleStack::with_sigmas(image, sigmas, plan.border, plan.options)
        }
        None => plan.build(image),
    }
}

/// [`build_planned`], but for a log-uniform stack read through a scale map:
/// each level built only where the terms of `filters` (all of `sampling`)
/// read it at the map's scales ([`ReadMap`]), the union of their reads. The
/// whole stack where the windows do not apply: levels at exactly given
/// sigmas, a constant scale, an image of another size (refused there), a
/// border without windows (wrap).
pub(crate) fn build_for_reads(
    plan: &StackPlan,
    level_sigmas: Option<&[f64]>,
    image: ImageView<'_>,
    scale: &CheckedField<'_>,
    (sampling, filters): (Sampling, &[&[crate::Term]]),
) -> Result<ScaleStack, FilterError> {
    let dims = (image.width(), image.height(), image.channels());
    if level_sigmas.is_some() || !scale.is_map() || dims != plan.dims {
        return build_planned(plan, level_sigmas, image);
    }
    let (w, h, _) = dims;
    // Its size and kind (the values were checked when it was made).
    let scale = scale.check(FieldKind::Scale, w, h)?;
    let layout = plan.layout()?;
    // The `f32` offsets `Filter::check_reads` recomputes the windows with.
    let terms: Vec<(f64, f32, f32)> = filters
        .iter()
        .flat_map(|terms| terms.iter())
        .map(|t| (t.sigma, t.x as f32, t.y as f32))
        .collect();
    match ReadMap::of_layout(&layout, plan.border, sampling, &terms) {
        Some(reads) => {
            let windows = reads.windows(scale.field(), (w, h));
            ScaleStack::build(&layout, image.data(), plan.border, Some(windows))
        }
        None => build_planned(plan, level_sigmas, image),
    }
}

/// Refuses a filter whose kernel, at the largest scale used, is larger than
/// the image: its lookups would reach past the image on both sides and the
/// border rule would fold the image onto itself more than once. The kernel's
/// longer side is compared with the image's longer side, since a rotation
/// can point it either way.
pub(crate) fn check_kernel_fits(
    decomposition: &Decomposition,
    smax: f32,
    w: usize,
    h: usize,
) -> Result<(), FilterError> {
    // Where the terms reach, centre distance plus 3 sigma on each side: the
    // support of a hand-made decomposition without a kernel block, and a
    // check on a file whose kernel block is far smaller than its terms (a
    // fit's atoms reach a few sigma past its kernel: only twice the kernel
    // counts).
    let reach = decomposition
        .terms
        .iter()
        .map(|t| t.x.abs().max(t.y.abs()) + 3.0 * t.sigma)
        .fold(0.0f64, f64::max);
    let side = (2.0 * reach).ceil();
    let (size, extent) = match decomposition.kernel_size {
        Some((kw, kh)) if 2.0 * kw.max(kh) as f64 >= side => {
            (format!("{kw}x{kh} px"), kw.max(kh) as f32 * smax)
        }
        Some((kw, kh)) => (
            format!("{kw}x{kh} px, but its terms reach about {side}x{side} px"),
            side as f32 * smax,
        ),
        None => (
            format!("about {side}x{side} px (its terms' reach)"),
            side as f32 * smax,
        ),
    };
    if extent > w.max(h) as f32 {
        return Err(FilterError::InvalidParameter(format!(
            "the filter's kernel is {size}; at scale {smax} it spans {extent:.0} px, \
             larger than the {w}x{h} image (use a smaller scale or a larger image)"
        )));
    }
    Ok(())
}

/// The most terms [`FilterPlan::new`] plans for: its error estimates and
/// the kernel's norm sum over pairs of terms.
pub(crate) const MAX_TERMS: usize = 16_384;

/// The largest change of a fitted filter's DC gain that [`check_dc_gain`]
/// lets through, relative to the larger of the fitted gain and the kernel's
/// L2 norm (its response to white noise: the measure for filters that
/// remove constants, such as derivatives): 2%.
const MAX_DC_CHANGE: f64 = 0.02;

/// `sum_k g_sigma(k - c)` over the integers `k`: the gain along one axis of
/// a normalised Gaussian sampled at integer offsets from `c`, `1 + 2 sum_k
/// cos(2 pi k c) exp(-2 pi^2 sigma^2 k^2)` (Poisson summation). Within
/// `1e-8` of 1 from sigma 1 up; at 0.5 px between 0.986 and 1.014 with `c`,
/// at 0.29 px (every atom of a fitted kernel at tiny scales) 1.38 at `c = 0`.
fn sampled_gaussian_gain(sigma: f64, c: f64) -> f64 {
    let a = 2.0 * std::f64::consts::PI * std::f64::consts::PI * sigma * sigma;
    let w = 2.0 * std::f64::consts::PI * c;
    1.0 + 2.0
        * (1..=12)
            .map(|k| {
                let k = f64::from(k);
                (w * k).cos() * (-a * k * k).exp()
            })
            .sum::<f64>()
}

/// The DC gain (what a flat image is multiplied by) of `decomposition`
/// applied at scale `s`, as the filter computes it: a term read from the
/// stack reads a level of sampled Gaussians centred on pixels, whose gain is
/// `G(sigma_eff, 0)^2` whatever the term's offset; a term evaluated
/// directly at the constant angle `theta` (degrees; `None`: no term is)
/// is its Gaussian sampled at the pixels around its offset, `G(sigma_eff,
/// q_x) G(sigma_eff, q_y)`. At the fitted sampling (scale 1, angle 0,
/// exact offsets) this is the fitted kernel's sum.
fn dc_gain(decomposition: &Decomposition, s: f64, direct: Option<(f64, f64)>) -> f64 {
    let rotation = direct.map(|(theta, _)| theta.to_radians().sin_cos());
    decomposition
        .terms
        .iter()
        .map(|t| {
            let sigma = decomposition.sampling.effective_sigma(t.sigma, s);
            let g = match (rotation, direct) {
                (Some((sin, cos)), Some((_, below)))
                    if evaluated_directly(decomposition.sampling, t, s, below) =>
                {
                    let qx = s * (cos * t.x + sin * t.y);
                    let qy = s * (-sin * t.x + cos * t.y);
                    sampled_gaussian_gain(sigma, qx) * sampled_gaussian_gain(sigma, qy)
                }
                _ => sampled_gaussian_gain(sigma, 0.0).powi(2),
            };
            t.weight * g
        })
        .sum()
}

/// Refuses a fitted kernel (sampled at pixel centres or averaged over
/// pixels) applied where its DC gain moves more than [`MAX_DC_CHANGE`] from
/// the fitted one. A fit's atoms are Gaussians sampled at pixels; below
/// about half a pixel of standard deviation their samples no longer add up
/// to their weights, by an amount that depends on where they fall between
/// pixels. A fit with such atoms (hard-edged kernels fit them, with weights
/// that cancel) is exact at the sampling it was fitted at and can be far
/// off elsewhere: a 9x3 box came out at -0.6 times a flat image at scale
/// 1.2. Any kernel shrunk far enough gets there too (every atom is 0.29 px
/// wide at tiny scales, its samples summing to 1.9). `angle` is the
/// constant angle of a constant pose whose narrow terms are evaluated
/// directly (below `direct_sigma`), `None` otherwise; a scale range is
/// checked at 17 scales; `kernel_norm` is the kernel's L2 norm at scale 1.
/// Continuous decompositions (terms given directly) are sums of sampled
/// Gaussians by definition and are not checked.
pub(crate) fn check_dc_gain(
    decomposition: &Decomposition,
    kernel_norm: f64,
    angle: Option<f32>,
    (smin, smax): (f32, f32),
    direct_sigma: f64,
) -> Result<(), FilterError> {
    if !matches!(decomposition.sampling, Sampling::Point | Sampling::Area) {
        return Ok(());
    }
    // the fitted gain: every term at its own offset, scale 1, angle 0
    let fitted: f64 = decomposition
        .terms
        .iter()
        .map(|t| {
            t.weight * sampled_gaussian_gain(t.sigma, t.x) * sampled_gaussian_gain(t.sigma, t.y)
        })
        .sum();
    let mass: f64 = decomposition.terms.iter().map(|t| t.weight.abs()).sum();
    let direct = angle.map(|a| (f64::from(a), direct_sigma));
    let (lo, hi) = (f64::from(smin), f64::from(smax));
    let scales: Vec<f64> = if hi > lo {
        (0..=16)
            .map(|i| lo * (hi / lo).powf(f64::from(i) / 16.0))
            .collect()
    } else {
        vec![lo]
    };
    // the relative change at each scale (the kernel's norm at scale s is
    // its norm at 1 over s), the worst one
    let change = |s: f64, gain: f64| (gain - fitted).abs() / fitted.abs().max(kernel_norm / s);
    let Some((s, gain)) = scales
        .iter()
        .map(|&s| (s, dc_gain(decomposition, s, direct)))
        .max_by(|a, b| change(a.0, a.1).total_cmp(&change(b.0, b.1)))
    else {
        return Ok(());
    };
    // (NaN, a kernel of no norm: nothing to measure against)
    let worst = change(s, gain);
    if worst.is_nan() || worst <= MAX_DC_CHANGE {
        return Ok(());
    }
    let narrowest = decomposition
        .terms
        .iter()
        .map(|t| decomposition.sampling.effective_sigma(t.sigma, s))
        .fold(f64::INFINITY, f64::min);
    let at = match angle {
        Some(a) if hi <= lo => format!("at angle {a} and scale {}", s as f32),
        _ => format!("at scale {}", s as f32),
    };
    let advice = if mass > 4.0 * fitted.abs().max(kernel_norm) {
        format!(
            "its atoms, down to {narrowest:.2} px with weights that cancel (sum |w| = {mass:.3}), \
             represent the kernel only at the sampling it was fitted at (scale 1, angle 0); \
             fit a smooth kernel, or apply this one there"
        )
    } else {
        format!(
            "its atoms are down to {narrowest:.2} px there, too narrow for Gaussians sampled at \
             pixels; use larger scales"
        )
    };
    Err(FilterError::InvalidParameter(format!(
        "{at} the filter would multiply a flat image by {gain:.4} instead of the fitted \
         {fitted:.4} (more than {:.0}% off): {advice}",
        100.0 * MAX_DC_CHANGE
    )))
}

#[cfg(test)]
#[path = "pipeline_tests.rs"]
mod tests;
