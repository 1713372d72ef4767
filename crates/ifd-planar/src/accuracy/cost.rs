//! What filtering through a stack costs: the model [`super::EvalPlan`]
//! weighs blending two levels against reading the nearest one with.

use crate::stack::Interpolation;

/// What filtering through a stack costs, in units of one term read with
/// one bilinear lookup at every pixel: `terms` terms read at the nearest
/// level (`blend` false) or blending two ([`BLEND_TERM_COST`]; a cubic
/// read costs [`CUBIC_TERM_COST`] times either), and prefiltering the levels
/// at `sigmas` stored at `factor` (each [`LEVEL_COST`] plus
/// [`LEVEL_SAMPLE_COST`] over its subsampling squared). Only its
/// comparisons matter: [`EvalPlan::choose`](super::EvalPlan::choose)
/// weighs blending against reading the nearest level with it.
pub(super) fn read_cost(
    terms: usize,
    blend: bool,
    (interpolation, factor): (Interpolation, f64),
    sigmas: &[f64],
) -> f64 {
    let per_term = match interpolation {
        Interpolation::Linear => 1.0,
        Interpolation::Cubic => CUBIC_TERM_COST,
    } * if blend { BLEND_TERM_COST } else { 1.0 };
    let levels: f64 = sigmas
        .iter()
        .map(|&sigma| {
            let step = crate::stack::pyramid_step(sigma, factor) as f64;
            LEVEL_COST + LEVEL_SAMPLE_COST / (step * step)
        })
        .sum();
    terms as f64 * per_term + levels
}

/// [`read_cost`]'s constants, measured with `ifd filter -v` (1024x1024, a
/// per-pixel angle and scale, one thread, the AVX-512 rows, 2026-12-06): a
/// term read at the nearest level took about 2.3 ms over the image, one
/// blending two levels 1.3 times that (the two reads share the term's
/// position and, on one grid, its stencil); a directly built level about
/// 1.5 ms plus 3.7 ms per image-sized level of samples (margins, chained
/// links and first touches of its memory included); cubic reads about 3.4
/// times bilinear ones.
const BLEND_TERM_COST: f64 = 1.3;
/// See [`BLEND_TERM_COST`].
const LEVEL_COST: f64 = 0.63;
/// See [`BLEND_TERM_COST`].
const LEVEL_SAMPLE_COST: f64 = 1.6;
/// See [`BLEND_TERM_COST`].
const CUBIC_TERM_COST: f64 = 3.4;
