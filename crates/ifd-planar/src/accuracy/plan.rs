//! The evaluation plan: the stack a decomposition is applied through
//! ([`EvalPlan`]), chosen on its expected error and cost.

use super::cost::read_cost;
use super::norm::checked_kernel_norm;
use super::read_error::{level_blend_error, lookup_error, nearest_level_error};
use super::white_noise::{Levels, SCREEN_MARGIN, STALL_SLACK, WhiteNoise};
use crate::decomposition::Decomposition;
use crate::error::FilterError;
use crate::stack::for_decomposition::evaluated_directly;
use crate::stack::{Interpolation, StackOptions, pyramid_step};

/// ([`EvalPlan::choose`] with [`PlanOptions::log_uniform`]).
pub(super) const FEWEST_PER_OCTAVE: usize = 2;

/// The pyramid factors [`EvalPlan::choose`] tries, coarsest first, half
/// an octave apart (unsubsampled last).
pub(super) const FACTORS: [f64; 8] = [
    1.0,
    std::f64::consts::SQRT_2,
    2.0,
    2.0 * std::f64::consts::SQRT_2,
    4.0,
    4.0 * std::f64::consts::SQRT_2,
    8.0,
    f64::INFINITY,
];

/// The most levels per octave a log-uniform stack read at the nearest level
/// is planned with: at 8, its level error (3.5%, [`nearest_level_error`])
/// is still above the blend's at 2 (3.0%), so the nearest level only serves
/// budgets of a few per cent, and past 8 the levels cost more than the
/// lookups they save for all but large decompositions.
pub(super) const NEAREST_MOST_PER_OCTAVE: usize = 8;
/// The stack a decomposition is applied through, and the error it is
/// expected to add (see the module docs for the rule and the bound).
///
/// ```
/// use ifd_planar::{Decomposition, EvalPlan, Interpolation, PlanOptions, Term};
/// // A second-derivative-like kernel: a centre and two side lobes that cancel.
/// let t = |weight, x, sigma| Term { weight, x, y: 0.0, sigma };
/// let d = Decomposition::from_terms(vec![t(-1.0, 0.0, 6.0), t(0.5, -9.0, 6.0), t(0.5, 9.0, 6.0)]);
/// let plan = EvalPlan::choose(&d, 1.0, 1.0, PlanOptions::default())?;
/// assert_eq!(plan.interpolation, Interpolation::Cubic);
/// assert!(plan.error_estimate <= EvalPlan::DEFAULT_BUDGET);
/// assert!(plan.error_estimate < plan.error_bound);
/// # Ok::<(), ifd_planar::FilterError>(())
/// ```
///
/// How accurately a decomposition is applied, and the stack that applies it
/// accurately enough: the evaluation plan.
///
/// # Where the evaluation error comes from
/// Through the stack, term `t` is one lookup of level `s sigma_t` at the
/// displaced point `p + s R_theta c_t`, which is rarely a stored sample. The
/// level is the image correlated with a Gaussian of `r = s sigma_t / step`
/// stored samples (`step = 2^j`, the pyramid subsampling), and reading it at
/// a fractional position is a filter that only approximates the ideal shift.
/// For white-noise input and a fractional phase `phi`, the relative error of
/// one lookup along one axis is
///
/// ```text
/// e(r)^2 = mean_phi  int |I(nu, phi) - exp(2 pi i nu phi)|^2 G_r(nu)^2 dnu / int G_r(nu)^2 dnu
/// ```
///
/// with `G_r` the transfer of the sampled Gaussian (`nu` in cycles per
/// sample, `|nu| <= 1/2`) and `I` the interpolator's response:
/// `1 - phi + phi e^{2 pi i nu}` for bilinear, `B(nu, phi) / B(nu, 0)` for the
/// interpolating cubic B-spline (`B(nu, phi) = sum_k beta3(k - phi) e^{2 pi i nu k}`).
/// `lookup_error` integrates this numerically. It falls as `r^-2` for
/// bilinear and `r^-4` for the cubic B-spline (1.95% and 0.037% at `r = 2`).
///
/// # The bound
/// In 2D both axes are interpolated: `sqrt(2) e(r)` per lookup. Term errors
/// add at most linearly, so relative to the filtered result
///
/// ```text
/// error <= sum_t |w_t| ||g_{s sigma_t}|| sqrt(2) e(r_t) / ||k_s||
/// ```
///
/// (L2 norms, white noise; `||g_sigma|| = 1 / (2 sqrt(pi) sigma)`, and
/// `||k_s||^2 = sum_{t,u} w_t w_u g_{sqrt(sigma_t^2 + sigma_u^2)}(c_t - c_u) / s^2`
/// in closed form). The ratio `A = sum_t |w_t| ||g_t|| / ||k||` is the
/// decomposition's *amplification*: about 1-4 for positive kernels, 10-60
/// for derivative and band-pass kernels whose weights cancel, and hundreds
/// for hard-edged kernels fitted with sub-pixel atoms. The bound is a bound:
/// measured errors are 2-50 times lower (`docs/planar-accuracy.md`), because
/// the terms' errors are high-frequency patterns tied to their own positions:
/// patterns of terms apart are nearly uncorrelated and add nearly in
/// quadrature, not linearly.
///
/// # The estimate
/// The plan does not lean on the bound: the expected error on white noise
/// has a closed form per pose (each term's error is a few shifted Gaussians:
/// its level's at the samples a read weighs, minus the exact one; and
/// Gaussians' inner products are Gaussians), averaged over rotations,
/// translations and, with a per-pixel scale, scales and level blends
/// ([`EvalPlan::error_estimate`]; derivation in the `white_noise` module).
/// Filtering white noise measures within 15% of it.
///
/// # The rule
/// [`EvalPlan::choose`] takes the first of bilinear at pyramid factor 1,
/// sqrt 2, 2, 2 sqrt 2 and 4, then the cubic B-spline at factor 1 to 8 in
/// the same half-octave steps and unsubsampled,
/// whose estimate is within the budget (default [`EvalPlan::budget_for`])
/// over the scales used; when none is, the one with the lowest estimate (a
/// later candidate replaces an earlier one only if 5% lower; a factor that
/// improves on the one an octave coarser by less than 5% ends that
/// interpolation's candidates; a candidate whose estimate over every fourth
/// pose is over 1.3 times the budget is rejected on it, and estimated
/// over every pose only where a stall or the choice among rejected ones
/// could turn on it: the choice the full estimates make unless a quarter of
/// the poses errs by more than those margins, at a fraction of the sums).
/// Factor 1 stores a level of sigma 2-4 px at
/// every other pixel, 4-8 px at every fourth (one to two samples per
/// sigma): a quarter of factor 2's samples, for loose budgets. On a
/// log-uniform stack (a per-pixel scale, [`PlanOptions::log_uniform`])
/// each candidate takes the fewest levels per octave, 2 to the default 4,
/// whose estimate (the blend of neighbouring levels included) is within the
/// budget; then, where reading each term's nearest level alone (one lookup
/// instead of two) from 2 to 8 levels per octave is also within the budget
/// and costs less (a cost model of lookups and levels measured on this
/// project's benchmark machine), the nearest level. Memory, for 4 levels per octave:
/// about 5.3 image-sized levels at factor 2, 8.5 at 4, 14 at 8 (every level
/// below `factor` pixels is stored at full resolution); a cubic lookup
/// costs four times the arithmetic of a bilinear one. Terms narrower than
/// about 1.5 px are the floor: no interpolation of integer-sampled levels
/// reproduces a Gaussian that narrow at a fractional position, and the
/// estimate says so.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalPlan {
    /// How levels are read.
    pub interpolation: Interpolation,
    /// [`StackOptions::pyramid_factor`].
    pub pyramid_factor: f64,
    /// Bound on the relative RMS evaluation error of the lookups on white
    /// noise, the largest over the scales used.
    pub error_bound: f64,
    /// The expected relative RMS evaluation error on white noise, the
    /// lookups and (log-uniform stacks) the level blend together, averaged
    /// over poses and scales (see the type's docs). The plan is chosen on
    /// it.
    pub error_estimate: f64,
    /// `sum |w_t| ||g_t|| / ||k||` (scale-invariant).
    pub amplification: f64,
    /// Terms whose scaled sigma is below this are evaluated directly (0:
    /// none); they add no interpolation error.
    pub direct_sigma: f64,
    /// Levels per octave of sigma ([`StackOptions::samples_per_octave`]).
    pub samples_per_octave: usize,
    /// Each term reads the level nearest its sigma alone
    /// ([`StackOptions::nearest_level`]): one lookup instead of two, on a
    /// log-uniform stack with more levels per octave.
    pub nearest_level: bool,
    /// Bound on the relative RMS error of blending neighbouring levels of
    /// a log-uniform stack ([`level_blend_error`], or
    /// [`nearest_level_error`] when read at the nearest level, times the
    /// amplification); 0 when the levels are the terms' own sigmas (a
    /// constant scale).
    pub level_error: f64,
}

/// What [`EvalPlan::choose`] plans for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanOptions {
    /// Budget on [`EvalPlan::error_estimate`]. Default [`EvalPlan::DEFAULT_BUDGET`].
    pub budget: f64,
    /// Fix the interpolation (only the pyramid factor is chosen). Default
    /// `None`: either.
    pub interpolation: Option<Interpolation>,
    /// Terms whose scaled sigma is below this will be evaluated directly
    /// (pass [`crate::DIRECT_SIGMA`] for a constant pose filtered with
    /// [`crate::Filter::with_direct`]). Default 0: none.
    pub direct_sigma: f64,
    /// The stack's levels are log-uniform in sigma (a per-pixel scale, or
    /// [`crate::FilterOptions::log_uniform`]), read by blending the two
    /// levels around each sigma: the plan also chooses how many levels per
    /// octave. Default `false`: levels at the terms' own sigmas.
    pub log_uniform: bool,
}

impl Default for PlanOptions {
    fn default() -> Self {
        Self {
            budget: EvalPlan::DEFAULT_BUDGET,
            interpolation: None,
            direct_sigma: 0.0,
            log_uniform: false,
        }
    }
}

impl EvalPlan {
    /// The default budget on [`EvalPlan::error_estimate`]: 0.1%.
    pub const DEFAULT_BUDGET: f64 = 0.001;

    /// The budget a decomposition is applied within unless told otherwise:
    /// a third of the relative L2 error its fit left (the larger of the
    /// kernel grid's and, when measured, the finer grid's), and no less than
    /// [`EvalPlan::DEFAULT_BUDGET`] (a decomposition without a fit report:
    /// that default).
    ///
    /// Why a third: the evaluation error adds to the fit's, and the two are
    /// uncorrelated, so they add in quadrature; an expected evaluation error
    /// of a third of the fit's adds 5% to the total (`sqrt(1 + 1/9)`), while
    /// a tighter budget buys little the fit has not already given up, at the
    /// price of finer levels (more prefiltering and memory) or cubic lookups
    /// (four times the arithmetic). At `--tol 0.1` on the 8:1 Gaussian this
    /// plans bilinear at pyramid factor 2 (the bound would have asked for 4:
    /// levels four times the size) for the same PSNR against the exact filter
    /// (BENCHMARKS.md).
    ///
    /// ```
    /// use ifd_planar::{Decomposition, EvalPlan, Term};
    /// // Terms written by hand carry no fit report: the default budget.
    /// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 0.0, y: 0.0, sigma: 3.0 }]);
    /// assert_eq!(EvalPlan::budget_for(&d), EvalPlan::DEFAULT_BUDGET);
    /// ```
    #[must_use]
    pub fn budget_for(decomposition: &Decomposition) -> f64 {
        decomposition
            .report
            .as_ref()
            .map_or(Self::DEFAULT_BUDGET, |r| {
                let fit = r.rel_l2_error.max(r.fine_rel_l2_error.unwrap_or(0.0));
                if fit.is_finite() {
                    (fit / 3.0).max(Self::DEFAULT_BUDGET)
                } else {
                    Self::DEFAULT_BUDGET
                }
            })
    }

    /// The cheapest plan whose estimate is within `options.budget` over
    /// `[scale_min, scale_max]`, else the most accurate one.
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] for a decomposition without terms,
    /// a kernel of zero norm, non-finite or non-positive scales or budget.
    pub fn choose(
        decomposition: &Decomposition,
        scale_min: f32,
        scale_max: f32,
        options: PlanOptions,
    ) -> Result<Self, FilterError> {
        let PlanOptions {
            budget,
            interpolation: only,
            direct_sigma,
            log_uniform,
        } = options;
        if !(budget.is_finite() && budget > 0.0) {
            return Err(FilterError::InvalidParameter(format!(
                "error budget {budget} must be finite and positive"
            )));
        }
        // Factors half an octave apart (a level's samples per sigma grow by
        // sqrt 2 a step), so that the accuracy, and the cost, grow in small
        // steps with the budget instead of doubling.
        // Bilinear up to factor 4, then the cubic B-spline at every factor.
        let fixed: Vec<(Interpolation, f64)> = match only {
            None => FACTORS[..=4]
                .iter()
                .map(|&f| (Interpolation::Linear, f))
                .chain(FACTORS.iter().map(|&f| (Interpolation::Cubic, f)))
                .collect(),
            Some(i) => FACTORS.iter().map(|&f| (i, f)).collect(),
        };
        let scales = (f64::from(scale_min), f64::from(scale_max));
        let mut noise: Option<WhiteNoise<'_>> = None;
        // the kernel's norm, a sum over pairs of terms: once per plan
        let mut norm: Option<f64> = None;
        // Every candidate estimated so far, in order: its plan before the
        // estimate, the plan, and whether the estimate is the full one (a
        // candidate far over the budget is rejected on a screen of its
        // poses, `WhiteNoise::screened`, and estimated in full only where
        // a stall or the choice among rejected ones below could turn on it).
        let mut tried: Vec<(Self, Self, bool)> = Vec::new();
        // The interpolations whose finer factors stopped helping (the blend
        // of levels, or terms too narrow for any read, dominate): those are
        // not tried further.
        let mut stalled: Vec<Interpolation> = Vec::new();
        for (interpolation, factor) in fixed {
            if stalled.contains(&interpolation) {
                continue;
            }
            let norm = match norm {
                Some(n) => n,
                None => *norm.insert(checked_kernel_norm(decomposition)?),
            };
            let bounded = Self::bounded(
                decomposition,
                norm,
                (scale_min, scale_max),
                interpolation,
                factor,
                direct_sigma,
            )?;
            let noise =
                noise.get_or_insert_with(|| WhiteNoise::new(decomposition, scales, direct_sigma));
            let (plan, full) = bounded.estimated(noise, log_uniform, budget, true);
            if plan.error_estimate <= budget {
                // (a screened estimate is never within the budget)
                return Ok(plan);
            }
            tried.push((bounded, plan, full));
            // Against the candidate an octave coarser (the unsubsampled one:
            // against the last), so that two half-octave steps must gain
            // what one octave step did; on full estimates.
            let last = tried.len() - 1;
            let back = tried[..last].iter().rposition(|(_, p, _)| {
                p.interpolation == interpolation
                    && (p.pyramid_factor == factor / 2.0 || factor.is_infinite())
            });
            if let Some(b) = back {
                // On a screen that could be off either way, decide near the
                // line on full estimates (which may turn out within budget).
                let ratio =
                    |t: &[(Self, Self, bool)]| t[last].1.error_estimate / t[b].1.error_estimate;
                if !(tried[b].2 && tried[last].2) && ratio(&tried) >= 0.95 / STALL_SLACK {
                    for i in [b, last] {
                        Self::estimate_in_full(&mut tried[i], noise, log_uniform, budget);
                    }
                    if let Some(plan) = Self::first_within(&tried, budget) {
                        return Ok(plan);
                    }
                }
                if ratio(&tried) >= 0.95 {
                    stalled.push(interpolation);
                }
            }
        }
        // None within the budget: the one with the lowest estimate (a later
        // one replaces an earlier one only if 5% lower), on full estimates of
        // every candidate a screen leaves near enough the lowest to matter
        // (the final choice is within 1/0.95 of the lowest, and a candidate
        // that keeps it from replacing an earlier one within 1/0.95 of it:
        // three such steps are allowed for, times the screen's margin).
        let noise = noise.as_ref().expect("at least one candidate");
        loop {
            let lowest = tried
                .iter()
                .map(|(_, p, _)| p.error_estimate)
                .fold(f64::INFINITY, f64::min);
            let near = tried.iter().position(|(_, p, full)| {
                !full && p.error_estimate <= SCREEN_MARGIN * lowest / 0.95f64.powi(3)
            });
            match near {
                Some(i) => {
                    Self::estimate_in_full(&mut tried[i], noise, log_uniform, budget);
                    if let Some(plan) = Self::first_within(&tried, budget) {
                        return Ok(plan);
                    }
                }
                None => break,
            }
        }
        let mut best: Option<Self> = None;
        for (_, plan, _) in tried {
            if best.is_none_or(|b| plan.error_estimate < 0.95 * b.error_estimate) {
                best = Some(plan);
            }
        }
        Ok(best.expect("at least one candidate"))
    }

    /// The first candidate tried whose (full) estimate is within the
    /// budget: where a screen rejected a candidate that its full estimate
    /// keeps, the one the search would have returned at its turn.
    fn first_within(tried: &[(Self, Self, bool)], budget: f64) -> Option<Self> {
        tried
            .iter()
            .find(|(_, p, full)| *full && p.error_estimate <= budget)
            .map(|(_, p, _)| *p)
    }

    /// Replaces a screened estimate of a candidate [`Self::choose`] tried
    /// with the full one.
    fn estimate_in_full(
        (bounded, plan, full): &mut (Self, Self, bool),
        noise: &WhiteNoise<'_>,
        log_uniform: bool,
        budget: f64,
    ) {
        if !*full {
            (*plan, *full) = bounded.estimated(noise, log_uniform, budget, false);
        }
    }

    /// The estimate, the levels per octave and how a sigma between levels
    /// is read: on a log-uniform stack (`log_uniform`) the fewest levels per
    /// octave, from [`FEWEST_PER_OCTAVE`] up to the default 4, whose
    /// estimate with the blend of the two levels around each sigma stays
    /// within `budget` (the default 4 when that does not), so a coarse fit
    /// is read from fewer levels (less prefiltering and memory) and no
    /// blending plan gets more levels than the default; then, when the blend
    /// is within budget, the fewest levels per octave up to
    /// [`NEAREST_MOST_PER_OCTAVE`] at which reading the nearest level alone
    /// is too, if that costs less ([`read_cost`]: half the lookups, more
    /// levels). Otherwise the default levels at the terms' sigmas.
    ///
    /// With `screen`, an estimate over the budget may be a screen's
    /// ([`WhiteNoise::screened`]); the flag returned says whether the plan's
    /// estimate is the full one (always, within the budget).
    fn estimated(
        self,
        noise: &WhiteNoise<'_>,
        log_uniform: bool,
        budget: f64,
        screen: bool,
    ) -> (Self, bool) {
        let default = StackOptions::default().samples_per_octave;
        let estimate = |levels| {
            noise.screened(
                (self.interpolation, self.pyramid_factor),
                levels,
                screen.then_some(budget),
            )
        };
        if !log_uniform {
            let (e, full) = estimate(Levels::AtSigmas);
            let plan = Self {
                samples_per_octave: default,
                level_error: 0.0,
                error_estimate: e,
                ..self
            };
            return (plan, full);
        }
        let at_flagged = |per_octave, nearest| {
            estimate(Levels::LogUniform {
                per_octave,
                nearest,
            })
        };
        // A screened estimate is over the budget: only a rejection rests on
        // one, and the plan's own estimate is the full one unless the most
        // levels miss the budget.
        let at = |per_octave, nearest| at_flagged(per_octave, nearest).0;
        let blending = |n, e| Self {
            samples_per_octave: n,
            nearest_level: false,
            level_error: self.amplification * level_blend_error(n),
            error_estimate: e,
            ..self
        };
        // The most levels first: when they miss the budget, fewer will too.
        let (most, most_full) = at_flagged(default, false);
        if most > budget {
            return (blending(default, most), most_full);
        }
        let (n, e) = (FEWEST_PER_OCTAVE..default)
            .map(|n| (n, at(n, false)))
            .find(|&(_, e)| e <= budget)
            .unwrap_or((default, most));
        let blend = blending(n, e);
        let cost = |n, blend| {
            read_cost(
                noise.terms_read(),
                blend,
                (self.interpolation, self.pyramid_factor),
                &noise.level_sigmas(n),
            )
        };
        // The level counts at which reading the nearest level costs less
        // than the blend (more levels cost more); the most of them first:
        // when it misses the budget, fewer will too.
        let blend_cost = cost(n, true);
        let cheaper: Vec<usize> = (FEWEST_PER_OCTAVE..=NEAREST_MOST_PER_OCTAVE)
            .take_while(|&n| cost(n, false) < blend_cost)
            .collect();
        let Some((&most, fewer)) = cheaper.split_last() else {
            return (blend, true);
        };
        let e_most = at(most, true);
        if e_most > budget {
            return (blend, true);
        }
        let (n, e) = fewer
            .iter()
            .map(|&n| (n, at(n, true)))
            .find(|&(_, e)| e <= budget)
            .unwrap_or((most, e_most));
        let nearest = Self {
            samples_per_octave: n,
            nearest_level: true,
            level_error: self.amplification * nearest_level_error(n),
            error_estimate: e,
            ..self
        };
        (nearest, true)
    }

    /// The bound on the whole evaluation error: the lookups'
    /// ([`Self::error_bound`]) and the level blend's ([`Self::level_error`])
    /// in quadrature.
    #[must_use]
    pub fn total_bound(&self) -> f64 {
        self.error_bound.hypot(self.level_error)
    }

    /// The bound (and the estimate, levels at the terms' sigmas) of a given
    /// interpolation and pyramid factor, for scales in
    /// `[scale_min, scale_max]`, terms that
    /// [`crate::evaluated_directly`] with `direct_sigma` being
    /// evaluated exactly ([`crate::Filter::with_direct`]).
    ///
    /// # Errors
    /// As [`EvalPlan::choose`].
    pub fn with(
        decomposition: &Decomposition,
        (scale_min, scale_max): (f32, f32),
        interpolation: Interpolation,
        pyramid_factor: f64,
        direct_sigma: f64,
    ) -> Result<Self, FilterError> {
        let plan = Self::bounded(
            decomposition,
            checked_kernel_norm(decomposition)?,
            (scale_min, scale_max),
            interpolation,
            pyramid_factor,
            direct_sigma,
        )?;
        let scales = (f64::from(scale_min), f64::from(scale_max));
        Ok(plan
            .estimated(
                &WhiteNoise::new(decomposition, scales, direct_sigma),
                false,
                0.0,
                false,
            )
            .0)
    }

    /// [`Self::with`] before its estimate (the bound in its place).
    pub(super) fn bounded(
        decomposition: &Decomposition,
        norm: f64,
        (scale_min, scale_max): (f32, f32),
        interpolation: Interpolation,
        pyramid_factor: f64,
        direct_sigma: f64,
    ) -> Result<Self, FilterError> {
        let terms = &decomposition.terms;
        crate::stack::for_decomposition::check_scale_range(scale_min, scale_max)?;
        let g_norm = |sigma: f64| 1.0 / (2.0 * std::f64::consts::PI.sqrt() * sigma);
        let amplification = terms
            .iter()
            .map(|t| t.weight.abs() * g_norm(t.sigma))
            .sum::<f64>()
            / norm;
        // Scales sampled geometrically over the range (the subsampling, hence
        // r, jumps with the scale).
        let (lo, hi) = (f64::from(scale_min), f64::from(scale_max));
        let n = if hi > lo * 1.0001 { 9 } else { 1 };
        // lookup errors by r (to 1e-6): few distinct values for fitted
        // decompositions, thousands for hand-made ones
        let mut cache: std::collections::HashMap<u64, f64> = std::collections::HashMap::new();
        let mut error_bound: f64 = 0.0;
        for i in 0..n {
            let s = if n == 1 {
                lo
            } else {
                lo * (hi / lo).powf(i as f64 / (n - 1) as f64)
            };
            let mut sum = 0.0;
            for t in terms {
                if evaluated_directly(decomposition.sampling, t, s, direct_sigma) {
                    continue;
                }
                let sigma = decomposition.sampling.effective_sigma(t.sigma, s);
                let r = sigma / pyramid_step(sigma, pyramid_factor) as f64;
                let key = (r * 1e6).round() / 1e6;
                let e = *cache
                    .entry(key.to_bits())
                    .or_insert_with(|| lookup_error(interpolation, key));
                // ||g_sigma_eff|| / ||k_s|| = ||g_{sigma_eff / s}|| / ||k||.
                sum += t.weight.abs() * g_norm(sigma / s) * std::f64::consts::SQRT_2 * e;
            }
            error_bound = error_bound.max(sum / norm);
        }
        Ok(Self {
            interpolation,
            pyramid_factor,
            error_bound,
            error_estimate: error_bound,
            amplification,
            direct_sigma,
            samples_per_octave: StackOptions::default().samples_per_octave,
            nearest_level: false,
            level_error: 0.0,
        })
    }

    /// `options` with this plan's interpolation, pyramid factor, levels
    /// per octave and level reads.
    #[must_use]
    pub fn apply(&self, options: StackOptions) -> StackOptions {
        StackOptions {
            interpolation: self.interpolation,
            pyramid_factor: self.pyramid_factor,
            samples_per_octave: self.samples_per_octave,
            nearest_level: self.nearest_level,
            ..options
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::term::Term;

    /// A fit's budget follows its error, and the estimate, not the bound,
    /// is held to it: the 8:1 Gaussian at `--tol 0.1` (18 terms, 4.8 to
    /// 6.7 px) is read bilinearly at pyramid factor 2 within a third of its
    /// fit error, where the bound would have stored the levels at full
    /// resolution (factor 4), as the fixed default budget does.
    #[test]
    fn a_fit_plans_within_a_third_of_its_error() {
        let spec: crate::KernelSpec = "gauss:sx=32,sy=4,theta=0".parse().unwrap();
        let opts = crate::DecomposeOptions {
            tol: 0.1,
            ..crate::DecomposeOptions::default()
        };
        let d = crate::decompose_spec(&spec, &opts, None, |_, _, _| {}).unwrap();
        let fit = d.report.as_ref().unwrap().rel_l2_error;
        assert!(fit > 0.05 && fit <= 0.1, "{fit}");
        assert_eq!(EvalPlan::budget_for(&d), fit / 3.0);
        let linear = |budget| {
            let options = PlanOptions {
                budget,
                interpolation: Some(Interpolation::Linear),
                direct_sigma: 0.0,
                log_uniform: false,
            };
            EvalPlan::choose(&d, 1.0, 1.0, options).unwrap()
        };
        let own = linear(EvalPlan::budget_for(&d));
        assert_eq!(own.pyramid_factor, 2.0);
        assert!(own.error_estimate <= fit / 3.0, "{own:?}");
        assert!(own.error_bound > fit / 3.0, "{own:?}");
        let fine = linear(EvalPlan::DEFAULT_BUDGET);
        assert_eq!(fine.pyramid_factor, 4.0);
        assert!(fine.error_estimate < own.error_estimate / 2.0);
        // Without a fit report, the default.
        let bare = Decomposition::from_terms(d.terms.clone());
        assert_eq!(EvalPlan::budget_for(&bare), EvalPlan::DEFAULT_BUDGET);
    }

    /// A per-pixel scale plans fewer levels per octave where the budget
    /// leaves room for their blend, never more than the default.
    #[test]
    fn log_uniform_levels_follow_the_budget() {
        let d = Decomposition::from_terms(vec![Term {
            weight: 1.0,
            x: 0.0,
            y: 0.0,
            sigma: 6.0,
        }]);
        let plan = |budget, log_uniform| {
            let options = PlanOptions {
                budget,
                interpolation: Some(Interpolation::Linear),
                direct_sigma: 0.0,
                log_uniform,
            };
            EvalPlan::choose(&d, 0.5, 1.0, options).unwrap()
        };
        // Looser budgets, fewer levels: every count from 2 to 4 is taken,
        // each plan with fewer than 4 within its budget.
        let (mut seen, mut factors) = (Vec::new(), Vec::<(f64, usize)>::new());
        for budget in [
            0.1,
            0.03,
            0.02,
            0.015,
            0.01,
            0.006,
            EvalPlan::DEFAULT_BUDGET,
        ] {
            let p = plan(budget, true);
            if p.samples_per_octave < 4 {
                assert!(p.error_estimate <= budget, "{budget}: {p:?}");
            }
            assert!(p.level_error > 0.0);
            // a tighter budget never reads coarser levels, nor, at the same
            // pyramid factor, fewer of them
            assert!(
                factors.last().is_none_or(|&(f, n)| f < p.pyramid_factor
                    || (f == p.pyramid_factor && n <= p.samples_per_octave)),
                "{budget}: {p:?} after {factors:?}"
            );
            factors.push((p.pyramid_factor, p.samples_per_octave));
            seen.push(p.samples_per_octave);
        }
        assert_eq!((seen[0], *seen.last().unwrap()), (2, 4), "{seen:?}");
        assert!(seen.contains(&3), "{seen:?}");
        let coarse = plan(0.1, true);
        let exact = plan(0.1, false);
        assert_eq!((exact.samples_per_octave, exact.level_error), (4, 0.0));
        assert_eq!(exact.total_bound(), exact.error_bound);
        assert_eq!(coarse.apply(StackOptions::default()).samples_per_octave, 2);
    }

    #[test]
    fn one_wide_gaussian_needs_no_more_than_cubic_at_factor_2() {
        let d = Decomposition::from_terms(vec![Term {
            weight: 1.0,
            x: 0.0,
            y: 0.0,
            sigma: 40.0,
        }]);
        let plan = EvalPlan::choose(&d, 1.0, 1.0, PlanOptions::default()).unwrap();
        assert_eq!(plan.interpolation, Interpolation::Cubic);
        assert!(plan.pyramid_factor <= 2.0, "{plan:?}");
        assert!(
            plan.error_estimate <= PlanOptions::default().budget,
            "{plan:?}"
        );
        assert!((plan.amplification - 1.0).abs() < 1e-9);
        // Bilinear at factor 2 reads it at r in [2, 4): about 1% per axis.
        let lin = EvalPlan::with(&d, (1.0, 1.0), Interpolation::Linear, 2.0, 0.0).unwrap();
        assert!(lin.error_bound > 0.01 && lin.error_bound < 0.03, "{lin:?}");
    }
}
