//! Several filters on one image through one stack: each decomposition
//! serves the pixels a weight map gives it ([`FilterSetPlan`]). The image is
//! prefiltered once for all of them; a pixel pays only for the terms of the
//! filters it is weighted by.

use ifd_image::{Image, ImageView};

use crate::accuracy::EvalPlan;
use crate::filter::Filter;
use crate::pipeline::{
    MAX_TERMS, build_for_reads, build_planned, check_dc_gain, check_kernel_fits, kernel_norm,
    planned_scales,
};
use crate::stack::MAX_EXACT_LEVELS;
use crate::stack::for_decomposition::stack_plan_for_set;
use crate::{
    CheckedField, Decomposition, FilterError, FilterOptions, PreparedDecomposition, ScaleStack,
    StackOptions, StackPlan, level_sigmas,
};

/// The plan for filtering one image with several decompositions, each
/// weighted per pixel (a filter per region of a label map, or filters
/// blended by weight maps), through one stack that covers them all.
///
/// Every term is read from the stack (no term is evaluated directly): at
/// a constant scale from levels at exactly the sigmas of every
/// decomposition's terms, else from log-uniform levels blended per pixel.
/// The stack's interpolation, pyramid factor and levels are one plan for
/// all ([`EvalPlan::choose_shared`]), each decomposition within its own
/// budget where one stack can hold them all to it (with a scale map, a
/// shared stack's levels fall off a filter's own sigmas; the plan then
/// keeps the worst filter closest to its budget, and
/// [`FilterSetPlan::evals`] says what each gets). Each pixel's value is `sum_i
/// weights[i][p] * filter_i(p)`: pixels of weight zero for a filter cost it
/// almost nothing ([`Filter::accumulate_weighted`]).
///
/// ```
/// use ifd_image::Image;
/// use ifd_planar::{CheckField, Decomposition, Field, FieldKind, FilterOptions, FilterSetPlan, Term};
/// let t = |weight, x, sigma| Term { weight, x, y: 0.0, sigma };
/// let streak = Decomposition::from_terms(vec![t(0.5, -6.0, 2.0), t(0.5, 6.0, 2.0)]);
/// let blob = Decomposition::from_terms(vec![t(1.0, 0.0, 4.0)]);
/// let img = Image::from_vec(64, 48, 1, (0..64 * 48).map(|i| (i % 13) as f32).collect())?;
/// // the left half filtered with the streak, the right half with the blob
/// let labels: Vec<f32> = (0..64 * 48).map(|i| if i % 64 < 32 { 0.0 } else { 1.0 }).collect();
/// let weights = FilterSetPlan::weights_from_labels(&labels, 2, 64)?;
/// let angle = Field::Constant(30.0).check(FieldKind::Angle, 64, 48)?;
/// let scale = Field::Constant(1.0).check(FieldKind::Scale, 64, 48)?;
/// let plan = FilterSetPlan::new((64, 48, 1), &[&streak, &blob], &scale, &FilterOptions::default())?;
/// let stack = plan.build_stack(&img)?;
/// let out = plan.evaluate(&stack, angle, scale, &weights)?;
/// assert_eq!((out.width(), out.height()), (64, 48));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct FilterSetPlan {
    /// The decompositions, checked, in order.
    pub decompositions: Vec<PreparedDecomposition>,
    /// Each decomposition's plan: one stack for all, each its own estimate.
    pub evals: Vec<EvalPlan>,
    /// The budget each was planned within ([`FilterOptions::eval_budget`]
    /// or the decomposition's own, [`EvalPlan::budget_for`]).
    pub eval_budgets: Vec<f64>,
    /// The log-uniform stack over every decomposition's sigmas at the
    /// scales used (its layout bounds memory even when `level_sigmas` is
    /// used).
    pub stack: StackPlan,
    /// Levels at exactly these sigmas, every decomposition's at a constant
    /// scale (one lookup per term); `None`: the levels of `stack`.
    pub level_sigmas: Option<Vec<f64>>,
    /// As [`FilterOptions::vector_kernels`].
    pub vector_kernels: bool,
}

impl FilterSetPlan {
    /// Plans the filtering of a `(width, height, channels)` image with
    /// `decompositions` at the scales of `scale` (the plan does not depend
    /// on the angles; no term is evaluated directly, so
    /// `options.direct_terms` does not apply).
    ///
    /// # Errors
    /// As [`crate::FilterPlan::new`] for each decomposition (the message
    /// names which, counting from 0), and [`FilterError::InvalidParameter`]
    /// for an empty list.
    pub fn new(
        (width, height, channels): (usize, usize, usize),
        decompositions: &[&Decomposition],
        scale: &CheckedField<'_>,
        options: &FilterOptions,
    ) -> Result<Self, FilterError> {
        if decompositions.is_empty() {
            return Err(FilterError::InvalidParameter(
                "filtering with several filters needs at least one decomposition".into(),
            ));
        }
        let (smin, smax) = planned_scales(scale, options)?;
        let which = |i: usize, e: FilterError| match e {
            FilterError::InvalidParameter(m) => {
                FilterError::InvalidParameter(format!("filter {i}: {m}"))
            }
            other => other,
        };
        let mut prepared = Vec::with_capacity(decompositions.len());
        for (i, d) in decompositions.iter().enumerate() {
            if d.terms.len() > MAX_TERMS {
                return Err(FilterError::InvalidParameter(format!(
                    "filter {i}: the decomposition has {} terms; filtering takes at most \
                     {MAX_TERMS}",
                    d.terms.len()
                )));
            }
            check_kernel_fits(d, smax, width, height).map_err(|e| which(i, e))?;
            prepared.push(PreparedDecomposition::new(d).map_err(|e| which(i, e))?);
        }
        let eval_budgets: Vec<f64> = decompositions
            .iter()
            .map(|d| {
                options
                    .eval_budget
                    .unwrap_or_else(|| EvalPlan::budget_for(d))
            })
            .collect();
        // A constant scale reads levels at exactly the terms' sigmas, every
        // decomposition's (one lookup per term), unless there are more
        // distinct ones than a stack at given sigmas holds.
        let exact: Option<Vec<f64>> = (smin == smax && !scale.is_map() && !options.log_uniform)
            .then(|| {
                let mut sigmas: Vec<f64> = decompositions
                    .iter()
                    .flat_map(|d| level_sigmas(d, smin, 0.0))
                    .collect();
                sigmas.sort_by(f64::total_cmp);
                sigmas.dedup();
                sigmas
            })
            .filter(|s| s.len() <= MAX_EXACT_LEVELS);
        let evals = EvalPlan::choose_shared(
            decompositions,
            &eval_budgets,
            (smin, smax),
            exact.is_none(),
            options.interpolation,
        )?;
        for (i, (d, eval)) in decompositions.iter().zip(&evals).enumerate() {
            check_dc_gain(d, kernel_norm(d, eval), None, scale.range(), 0.0)
                .map_err(|e| which(i, e))?;
        }
        let refs: Vec<&PreparedDecomposition> = prepared.iter().collect();
        let stack = stack_plan_for_set(
            (width, height, channels),
            &refs,
            (smin, smax),
            options.border,
            evals[0].apply(StackOptions::default()),
        )?;
        Ok(Self {
            decompositions: prepared,
            evals,
            eval_budgets,
            stack,
            level_sigmas: exact,
            vector_kernels: options.vector_kernels,
        })
    }

    /// Prefilters `image` into the planned stack.
    ///
    /// # Errors
    /// As [`StackPlan::build`] and [`ScaleStack::with_sigmas`].
    pub fn build_stack<'a>(
        &self,
        image: impl Into<ImageView<'a>>,
    ) -> Result<ScaleStack, FilterError> {
        build_planned(&self.stack, self.level_sigmas.as_deref(), image.into())
    }

    /// Prefilters `image` into the planned stack, computing of each level
    /// only the samples that some filter of the set reads at the scales of
    /// `scale` (the union of their reads, as
    /// [`crate::FilterPlan::build_stack_for`] builds for one filter):
    /// [`Self::evaluate`] with this `scale` gives [`Self::build_stack`]'s
    /// output to the builds' 2e-6 of the image's range; it is refused for
    /// another scale map whose reads it does not hold and for lookups
    /// anywhere else (as one filter's stack is). The whole stack where the
    /// windows do not apply: a constant scale, levels at the terms'
    /// sigmas, decompositions sampled differently, a wrapping border.
    ///
    /// ```
    /// use ifd_image::Image;
    /// use ifd_planar::{CheckField, Decomposition, Field, FieldKind, FilterOptions, FilterSetPlan, Term};
    /// let t = |weight, x, sigma| Term { weight, x, y: 0.0, sigma };
    /// let streak = Decomposition::from_terms(vec![t(0.5, -6.0, 2.0), t(0.5, 6.0, 2.0)]);
    /// let blob = Decomposition::from_terms(vec![t(1.0, 0.0, 4.0)]);
    /// let (w, h) = (96, 64);
    /// let img = Image::from_vec(w, h, 1, (0..w * h).map(|i| ((i * 37) % 23) as f32).collect())?;
    /// // Scale 0.25 in the left quarter, 1 elsewhere; the streak left, the blob right.
    /// let scales: Vec<f32> = (0..w * h).map(|i| if i % w < w / 4 { 0.25 } else { 1.0 }).collect();
    /// let labels: Vec<f32> = (0..w * h).map(|i| if i % w < w / 2 { 0.0 } else { 1.0 }).collect();
    /// let weights = FilterSetPlan::weights_from_labels(&labels, 2, w)?;
    /// let angle = Field::Constant(0.0).check(FieldKind::Angle, w, h)?;
    /// let scale = Field::Map(&scales).check(FieldKind::Scale, w, h)?;
    /// let plan = FilterSetPlan::new((w, h, 1), &[&streak, &blob], &scale, &FilterOptions::default())?;
    /// let stack = plan.build_stack_for(&img, &scale)?;
    /// assert!(stack.computed_share() < 1.0);
    /// let out = plan.evaluate(&stack, angle, scale, &weights)?;
    /// let full = plan.evaluate(&plan.build_stack(&img)?, angle, scale, &weights)?;
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
        let sampling = self.decompositions[0].sampling();
        if self.decompositions.iter().any(|d| d.sampling() != sampling) {
            // (one rule of reads per stack)
            return self.build_stack(image);
        }
        let terms: Vec<&[crate::Term]> = self
            .decompositions
            .iter()
            .map(PreparedDecomposition::terms)
            .collect();
        build_for_reads(
            &self.stack,
            self.level_sigmas.as_deref(),
            image.into(),
            scale,
            (sampling, &terms),
        )
    }

    /// Evaluates `sum_i weights[i][p] * filter_i(p)` at every pixel `p` on
    /// the CPU, one pass per decomposition over the pixels it is weighted
    /// by.
    ///
    /// # Errors
    /// [`FilterError::Shape`] when `weights` does not hold one map of one
    /// value per pixel for each decomposition, and the errors of
    /// [`Filter::accumulate_weighted`].
    pub fn evaluate(
        &self,
        stack: &ScaleStack,
        angle: CheckedField<'_>,
        scale: CheckedField<'_>,
        weights: &[Vec<f32>],
    ) -> Result<Image, FilterError> {
        if weights.len() != self.decompositions.len() {
            return Err(FilterError::Shape(format!(
                "{} weight maps for {} filters (one each)",
                weights.len(),
                self.decompositions.len()
            )));
        }
        let mut out = Image::new(stack.width(), stack.height(), stack.channels())
            .map_err(|e| FilterError::Shape(e.to_string()))?;
        // (a filter of no weight anywhere costs a pass over its blocks, all
        // skipped, and checks the fields and its scales all the same)
        for (d, w) in self.decompositions.iter().zip(weights) {
            Filter::new(stack, d)?
                .with_vector_kernels(self.vector_kernels)
                .with_runs_in_place(true)
                .accumulate_weighted(angle, scale, w, &mut out)?;
        }
        Ok(out)
    }

    /// One weight map per filter from a label map (one value per pixel,
    /// row-major, `width` a row): weight 1 for the filter whose index the
    /// pixel's label is, 0 for the others.
    ///
    /// ```
    /// use ifd_planar::FilterSetPlan;
    /// let w = FilterSetPlan::weights_from_labels(&[0.0, 1.0, 1.0, 0.0], 2, 2)?;
    /// assert_eq!(w, vec![vec![1.0, 0.0, 0.0, 1.0], vec![0.0, 1.0, 1.0, 0.0]]);
    /// assert!(FilterSetPlan::weights_from_labels(&[0.0, 2.0], 2, 2).is_err());
    /// # Ok::<(), ifd_planar::FilterError>(())
    /// ```
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] naming the first pixel whose label
    /// is not an integer from 0 to `filters - 1`, or for `filters == 0`.
    pub fn weights_from_labels(
        labels: &[f32],
        filters: usize,
        width: usize,
    ) -> Result<Vec<Vec<f32>>, FilterError> {
        if filters == 0 {
            return Err(FilterError::InvalidParameter(
                "a label map needs at least one filter".into(),
            ));
        }
        let valid =
            |v: f32| v.is_finite() && v >= 0.0 && v.fract() == 0.0 && (v as usize) < filters;
        if let Some(i) = labels.iter().position(|&v| !valid(v)) {
            return Err(FilterError::InvalidParameter(format!(
                "label {}{}: labels are the filters' indices, integers from 0 to {}",
                labels[i],
                crate::field::pixel_location(i, width.max(1)),
                filters - 1
            )));
        }
        Ok((0..filters)
            .map(|f| {
                labels
                    .iter()
                    .map(|&v| if v as usize == f { 1.0 } else { 0.0 })
                    .collect()
            })
            .collect())
    }
}

#[cfg(test)]
#[path = "filter_set_tests.rs"]
mod tests;
