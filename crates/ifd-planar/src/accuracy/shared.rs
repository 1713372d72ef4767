//! One evaluation plan for several decompositions read from one stack
//! ([`EvalPlan::choose_shared`]).

use super::norm::checked_kernel_norm;
use super::plan::{FACTORS, FEWEST_PER_OCTAVE, NEAREST_MOST_PER_OCTAVE};
use super::read_error::{level_blend_error, nearest_level_error};
use super::white_noise::{Levels, WhiteNoise, stack_sigmas};
use super::{EvalPlan, PlanOptions};
use crate::decomposition::Decomposition;
use crate::error::FilterError;
use crate::stack::{Interpolation, StackOptions};

/// A decomposition whose own plan misses its budget (the level blend of a
/// per-pixel scale alone can be over a tight one) is held to its own
/// plan's estimate times this: a shared stack whose factor differs from the
/// own plan's gives an estimate a few per cent either way (1% over in the
/// tests' case).
const MISSED_MARGIN: f64 = 1.1;

/// How the levels of a log-uniform stack are read, least accurate first:
/// the nearest level at 2 to [`NEAREST_MOST_PER_OCTAVE`] levels per octave
/// (its level error at 8, 3.5% times the amplification, is above the
/// blend's at 2, 3.0%), then the blend of the two around each sigma at 2
/// to 8 levels per octave: past a single plan's 4, because a stack shared
/// with wider or narrower filters puts its levels off a filter's own
/// sigmas, where a stack of its own would have put one.
fn level_ladder() -> Vec<(usize, bool)> {
    (FEWEST_PER_OCTAVE..=NEAREST_MOST_PER_OCTAVE)
        .map(|n| (n, true))
        .chain((FEWEST_PER_OCTAVE..=SHARED_BLEND_MOST).map(|n| (n, false)))
        .collect()
}

/// The most levels per octave a shared stack blends.
const SHARED_BLEND_MOST: usize = 8;

impl EvalPlan {
    /// One plan for several decompositions applied through one stack (a
    /// filter per region of an image, [`crate::FilterSetPlan`]): the same
    /// interpolation, pyramid factor and levels for all, every term read
    /// from the stack (no direct terms). With `log_uniform` the levels are
    /// log-uniform over `[scale_min, scale_max]` (as
    /// [`PlanOptions::log_uniform`]: a per-pixel scale); else `scale_min ==
    /// scale_max` and the stack holds a level at each term's sigma, of every
    /// decomposition. The plans differ only in their own estimates, bounds
    /// and amplification; one plan per decomposition is returned, in order.
    /// Each estimate is made on the shared stack's levels (log-uniform
    /// over every decomposition's sigmas at these scales).
    ///
    /// The rule: each decomposition's own plan ([`EvalPlan::choose`] within
    /// its budget, `budgets[i]`, with `interpolation` fixed or not); the
    /// shared interpolation is the cubic B-spline when any own plan reads
    /// cubic, else bilinear; the shared plan starts from the finest pyramid
    /// factor among the own plans of that interpolation and the most
    /// accurate level reading among all own plans (nearest-level reads at
    /// 2-8 levels per octave below blends at 2-4), and steps up, first the
    /// level reading, then the factor by half an octave, until every
    /// decomposition's estimate is within its budget (a decomposition
    /// whose own plan missed its budget: within 10% of that plan's
    /// estimate); when no candidate keeps them all, the one whose worst
    /// estimate over its target is lowest. With one decomposition this is
    /// its own plan. (The own plans, estimated on stacks of their own, only
    /// give the starting point and the targets.)
    ///
    /// ```
    /// use ifd_planar::{Decomposition, EvalPlan, PlanOptions, Term};
    /// let t = |weight, x, sigma| Term { weight, x, y: 0.0, sigma };
    /// let streak = Decomposition::from_terms(vec![t(0.5, -12.0, 3.0), t(0.5, 12.0, 3.0)]);
    /// let blob = Decomposition::from_terms(vec![t(1.0, 0.0, 8.0)]);
    /// let plans = EvalPlan::choose_shared(&[&streak, &blob], &[0.01, 0.01], (0.5, 1.0), true, None)?;
    /// assert_eq!(plans.len(), 2);
    /// assert_eq!(plans[0].pyramid_factor, plans[1].pyramid_factor);
    /// assert!(plans.iter().all(|p| p.error_estimate <= 0.01));
    /// // one decomposition: its own plan
    /// let options = PlanOptions { budget: 0.01, log_uniform: true, ..Default::default() };
    /// let own = EvalPlan::choose(&blob, 0.5, 1.0, options)?;
    /// assert_eq!(EvalPlan::choose_shared(&[&blob], &[0.01], (0.5, 1.0), true, None)?, vec![own]);
    /// # Ok::<(), ifd_planar::FilterError>(())
    /// ```
    ///
    /// # Errors
    /// As [`EvalPlan::choose`]; [`FilterError::InvalidParameter`] when no
    /// decomposition is given, `budgets` is not one per decomposition, or
    /// levels at the terms' sigmas are asked for over a range of scales.
    pub fn choose_shared(
        decompositions: &[&Decomposition],
        budgets: &[f64],
        (scale_min, scale_max): (f32, f32),
        log_uniform: bool,
        interpolation: Option<Interpolation>,
    ) -> Result<Vec<Self>, FilterError> {
        if decompositions.is_empty() || budgets.len() != decompositions.len() {
            return Err(FilterError::InvalidParameter(format!(
                "a shared plan needs at least one decomposition and one budget each ({} \
                 decompositions, {} budgets)",
                decompositions.len(),
                budgets.len()
            )));
        }
        if !log_uniform && scale_min != scale_max {
            return Err(FilterError::InvalidParameter(format!(
                "levels at the terms' sigmas serve one scale, not [{scale_min}, {scale_max}]"
            )));
        }
        // The distinct (decomposition, budget) pairs, each planned once.
        let mut distinct: Vec<usize> = Vec::new();
        let first_of: Vec<usize> = (0..decompositions.len())
            .map(|i| {
                let same =
                    |&j: &usize| budgets[j] == budgets[i] && decompositions[j] == decompositions[i];
                if let Some(j) = distinct.iter().copied().find(same) {
                    j
                } else {
                    distinct.push(i);
                    i
                }
            })
            .collect();
        let mut own: Vec<Option<Self>> = vec![None; decompositions.len()];
        for &i in &distinct {
            let options = PlanOptions {
                budget: budgets[i],
                interpolation,
                direct_sigma: 0.0,
                log_uniform,
            };
            let plan = Self::choose(decompositions[i], scale_min, scale_max, options);
            own[i] = Some(plan.map_err(|e| match e {
                FilterError::InvalidParameter(m) => {
                    FilterError::InvalidParameter(format!("filter {i}: {m}"))
                }
                other => other,
            })?);
        }
        let own: Vec<Self> = first_of.iter().map(|&j| own[j].expect("planned")).collect();
        if distinct.len() == 1 {
            return Ok(own);
        }
        // What each decomposition must stay within.
        let targets: Vec<f64> = own
            .iter()
            .zip(budgets)
            .map(|(p, &b)| {
                if p.error_estimate <= b {
                    b
                } else {
                    MISSED_MARGIN * p.error_estimate
                }
            })
            .collect();
        let shared = if own.iter().any(|p| p.interpolation == Interpolation::Cubic) {
            Interpolation::Cubic
        } else {
            Interpolation::Linear
        };
        let position = |factor: f64| {
            FACTORS
                .iter()
                .position(|&f| f == factor)
                .unwrap_or(FACTORS.len() - 1)
        };
        let first_factor = own
            .iter()
            .filter(|p| p.interpolation == shared)
            .map(|p| position(p.pyramid_factor))
            .max()
            .unwrap_or(0);
        // How levels are read, least accurate first (at the terms' sigmas:
        // one way).
        let ladder = if log_uniform {
            level_ladder()
        } else {
            vec![(StackOptions::default().samples_per_octave, false)]
        };
        let rung = |p: &Self| {
            ladder
                .iter()
                .position(|&(n, nearest)| n == p.samples_per_octave && nearest == p.nearest_level)
                .unwrap_or(ladder.len() - 1)
        };
        let first_rung = own.iter().map(rung).max().unwrap_or(0);
        // The candidates in order: the level reading up at the first
        // factor, then the factor up with the first level reading.
        let candidates = (first_rung..ladder.len())
            .map(|r| (first_factor, r))
            .chain((first_factor + 1..FACTORS.len()).map(|f| (f, first_rung)));
        let scales = (f64::from(scale_min), f64::from(scale_max));
        // The shared log-uniform stack spans every decomposition's sigmas:
        // each is estimated on its levels, not on those of a stack of its
        // own (levels at the terms' sigmas are each term's own either way).
        let union = decompositions
            .iter()
            .map(|d| stack_sigmas(d, scales))
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), (l, h)| {
                (lo.min(l), hi.max(h))
            });
        let mut noises: Vec<Option<WhiteNoise<'_>>> = Vec::new();
        noises.resize_with(decompositions.len(), || None);
        let mut norms: Vec<Option<f64>> = vec![None; decompositions.len()];
        // (the worst estimate over its target, the plans)
        let mut best: Option<(f64, Vec<Self>)> = None;
        for (f, r) in candidates {
            let (per_octave, nearest) = ladder[r];
            let mut plans: Vec<Self> = Vec::with_capacity(decompositions.len());
            let mut worst: f64 = 0.0;
            for (i, d) in decompositions.iter().enumerate() {
                let j = first_of[i];
                let plan = if j < i {
                    // the same decomposition and budget as an earlier one
                    plans[j]
                } else if !log_uniform
                    && own[i].interpolation == shared
                    && own[i].pyramid_factor == FACTORS[f]
                {
                    own[i]
                } else {
                    let norm = match norms[i] {
                        Some(n) => n,
                        None => *norms[i].insert(checked_kernel_norm(d)?),
                    };
                    let bounded =
                        Self::bounded(d, norm, (scale_min, scale_max), shared, FACTORS[f], 0.0)?;
                    let noise = noises[i].get_or_insert_with(|| {
                        WhiteNoise::new(d, scales, 0.0).with_stack_sigmas(union)
                    });
                    let (levels, level) = if log_uniform {
                        let error = if nearest {
                            nearest_level_error(per_octave)
                        } else {
                            level_blend_error(per_octave)
                        };
                        (
                            Levels::LogUniform {
                                per_octave,
                                nearest,
                            },
                            bounded.amplification * error,
                        )
                    } else {
                        (Levels::AtSigmas, 0.0)
                    };
                    let (e, _) = noise.screened((shared, FACTORS[f]), levels, None);
                    Self {
                        samples_per_octave: per_octave,
                        nearest_level: nearest,
                        level_error: level,
                        error_estimate: e,
                        ..bounded
                    }
                };
                worst = worst.max(plan.error_estimate / targets[i]);
                plans.push(plan);
            }
            if worst <= 1.0 {
                return Ok(plans);
            }
            if best.as_ref().is_none_or(|(w, _)| worst < *w) {
                best = Some((worst, plans));
            }
        }
        Ok(best.expect("at least one candidate").1)
    }
}
