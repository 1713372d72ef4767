//! From an image and a decomposition to the filtered image in one call: the
//! steps that `ifd filter`, the Python module and any other front end share,
//! so that they give the same pixels.

use ifd_image::{Image, ImageView};

use crate::accuracy::{EvalPlan, PlanOptions};
use crate::filter::Filter;
use crate::stack::for_decomposition::{DIRECT_SIGMA, evaluated_directly};
use crate::{
    Border, CheckedField, Decomposition, Field, FieldKind, FilterError, Interpolation,
    PreparedDecomposition, ScaleStack, StackOptions, StackPlan, stack_plan_for_decomposition,
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
        let (smin, smax) = match options.scale_range {
            None => scale.range(),
            Some((lo, hi)) => {
                let (flo, fhi) = scale.range();
                if !(lo <= flo && fhi <= hi) {
                    return Err(FilterError::InvalidParameter(format!(
                        "the planned scale range [{lo}, {hi}] does not contain the scale \
                         field's [{flo}, {fhi}]"
                    )));
                }
                (lo, hi)
            }
        };
        check_kernel_fits(decomposition, smax, width, height)?;
        let prepared = PreparedDecomposition::new(decomposition)?;
        // Levels log-uniform in sigma (read by blending neighbours), or at
        // exactly the terms' sigmas for a constant scale.
        let log_uniform = scale.is_map() || options.log_uniform;
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
        let image = image.into();
        match &self.level_sigmas {
            Some(sigmas) => {
                let dims = (image.width(), image.height(), image.channels());
                if dims != self.stack.dims {
                    return Err(FilterError::Shape(format!(
                        "image is {}x{}x{}, the filter was planned for {}x{}x{}",
                        dims.0,
                        dims.1,
                        dims.2,
                        self.stack.dims.0,
                        self.stack.dims.1,
                        self.stack.dims.2
                    )));
                }
                ScaleStack::with_sigmas(image, sigmas, self.stack.border, self.stack.options)
            }
            None => self.stack.build(image),
        }
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
/// constant: [`FilterPlan::new`], [`FilterPlan::build_stack`],
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
/// 2. [`FilterPlan::build_stack`] prefilters the image (FFT).
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
    let stack = plan.build_stack(image)?;
    plan.evaluate(image, &stack, angle, scale)
}

/// Refuses a filter whose kernel, at the largest scale used, is larger than
/// the image: its lookups would reach past the image on both sides and the
/// border rule would fold the image onto itself more than once. The kernel's
/// longer side is compared with the image's longer side, since a rotation
/// can point it either way.
fn check_kernel_fits(
    decomposition: &Decomposition,
    smax: f32,
    w: usize,
    h: usize,
) -> Result<(), FilterError> {
    let (size, extent) = if let Some((kw, kh)) = decomposition.kernel_size {
        (format!("{kw}x{kh} px"), kw.max(kh) as f32 * smax)
    } else {
        // A hand-made decomposition without a kernel block: its support is
        // where its terms reach, centre distance plus 3 sigma on each side.
        let reach = decomposition
            .terms
            .iter()
            .map(|t| t.x.abs().max(t.y.abs()) + 3.0 * t.sigma)
            .fold(0.0f64, f64::max);
        let side = (2.0 * reach).ceil();
        (
            format!("about {side}x{side} px (its terms' reach)"),
            side as f32 * smax,
        )
    };
    if extent > w.max(h) as f32 {
        return Err(FilterError::InvalidParameter(format!(
            "the filter's kernel is {size}; at scale {smax} it spans {extent:.0} px, \
             larger than the {w}x{h} image (use a smaller scale or a larger image)"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{CheckField, Field, FieldKind, Term};

    /// Constant angle and scale fields of a `w x h` image.
    fn constant_pose(
        angle: f32,
        scale: f32,
        (w, h): (usize, usize),
    ) -> (CheckedField<'static>, CheckedField<'static>) {
        (
            Field::Constant(angle)
                .check(FieldKind::Angle, w, h)
                .expect("angle"),
            Field::Constant(scale)
                .check(FieldKind::Scale, w, h)
                .expect("scale"),
        )
    }

    fn image(w: usize, h: usize) -> Image {
        Image::from_vec(
            w,
            h,
            1,
            (0..w * h)
                .map(|i| ((i * 7919) % 101) as f32 / 101.0)
                .collect(),
        )
        .expect("image")
    }

    /// The pipeline at a constant pose equals the brute-force correlation
    /// with the sampled sum of Gaussians (an independent path), within the
    /// evaluation budget.
    #[test]
    fn constant_pose_matches_brute_force() {
        let img = image(48, 40);
        let d = Decomposition::from_terms(vec![
            Term {
                weight: 0.6,
                x: 3.0,
                y: -1.0,
                sigma: 2.5,
            },
            Term {
                weight: 0.4,
                x: -2.0,
                y: 2.0,
                sigma: 4.0,
            },
        ]);
        let (angle, scale) = constant_pose(25.0, 1.3, (48, 40));
        let out = filter_image(&img, &d, angle, scale, &FilterOptions::default()).expect("filter");
        let k = |x: f64, y: f64| {
            d.terms
                .iter()
                .map(|t| {
                    let s2 = t.sigma.powi(2);
                    let r2 = (x - t.x).powi(2) + (y - t.y).powi(2);
                    t.weight * (-r2 / (2.0 * s2)).exp() / (std::f64::consts::TAU * s2)
                })
                .sum::<f64>()
        };
        let kernel = crate::reference::sample_kernel(k, 25.0, 1.3, 19);
        let reference = crate::reference::correlate(&img, &kernel, 39, 39, Border::Reflect101)
            .expect("reference");
        let err = out
            .data()
            .iter()
            .zip(reference.data())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(err < 2e-3, "max error {err}");
    }

    #[test]
    fn a_kernel_larger_than_the_image_is_refused() {
        let mut d = Decomposition::from_terms(vec![Term {
            weight: 1.0,
            x: 0.0,
            y: 0.0,
            sigma: 2.0,
        }]);
        d.kernel_size = Some((31, 31));
        let (angle, scale) = constant_pose(0.0, 1.0, (20, 20));
        let e = FilterPlan::new((20, 20, 1), &d, &angle, &scale, &FilterOptions::default())
            .expect_err("too large");
        assert!(e.to_string().contains("larger than the 20x20 image"), "{e}");
    }

    #[test]
    fn a_stack_of_another_size_is_refused() {
        let d = Decomposition::from_terms(vec![Term {
            weight: 1.0,
            x: 1.0,
            y: 0.0,
            sigma: 2.0,
        }]);
        let (angle, scale) = constant_pose(0.0, 1.0, (20, 20));
        let plan = FilterPlan::new((20, 20, 1), &d, &angle, &scale, &FilterOptions::default())
            .expect("plan");
        assert!(matches!(
            plan.build_stack(&image(21, 20)),
            Err(FilterError::Shape(_))
        ));
    }
}
