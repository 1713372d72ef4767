//! Where a filter with a scale map reads each level of a log-uniform stack:
//! a rectangle of stored samples per level ([`ReadMap::windows`]), so that
//! a stack built for that map computes only those
//! ([`crate::FilterPlan::build_stack_for`]).
//!
//! # Why
//! With a scale map over a wide range, each level serves the pixels whose
//! scale puts some term's sigma near it: at a 4:1 radial scale the finest
//! levels (full resolution, the dearest to build) are read in a disk around
//! the centre only. Building every level over the whole image spends most
//! of the prefiltering on samples no lookup reads.
//!
//! # The rectangle, and why it holds every read
//! A pixel `p` at scale `s` reads, for each term `t`, the levels that
//! [`LevelRule`] brackets at its position `u_t(s)` among the levels, at
//! `p + s R c_t`, a stencil of `(before, after)` samples
//! ([`super::Interpolation::reach`]) around it. Over a block of pixels with
//! scales in `[s_lo, s_hi]`:
//! - the position is `ln` of the effective sigma, whose square
//!   `max(s^2 sigma^2 + v(s), s^2 sigma^2 / 4)` ([`Sampling::effective_sigma`])
//!   is monotone in `s^2` between breakpoints: none for continuous and
//!   averaged terms, the drop of a point-sampled term's pixel footprint at
//!   `s = 1`, and for an area-sampled term narrower than a third of a pixel
//!   the floor's kink at `s^2 = 1 / (1 - 9 sigma^2)` (its variance
//!   `(1 - s^2) / 12` falls as the scale grows; the square is the larger of
//!   two lines, so the kink is a minimum). The extremes of the position over
//!   the block are therefore among its values at `s_lo`, `s_hi` and the
//!   breakpoints between (either side of a drop), and the block reads levels
//!   from the lower one at the least to the upper one at the greatest
//!   ([`LevelRule::levels_read`], which moves both out by far more than the
//!   positions' rounding);
//! - its lookups lie within `s_hi max_t |c_t|` of the block, plus one pixel
//!   for rounding, and the stencils within `before + 1` and `after + 1`
//!   samples of those positions (the floor of a rounded position can move
//!   by one).
//!
//! Each level's window is the union of those rectangles over the blocks
//! that read it, clipped to the stored samples. A lookup whose stencil
//! leaves the stored samples resolves its position by the border rule
//! first: replicate clamps it to the stored edge and reflect-101 mirrors it
//! about the image edge, to within `s |c_t|` of the pixel on its own side,
//! inside the same window; a constant border reads nothing. Wrap would read
//! the far side: [`ReadMap::new`] refuses it (the full build serves it).

use rayon::prelude::*;

use super::locate::{NEAREST_SNAP, PIXEL_SNAP};
use super::{
    Interpolation, LevelLayout, LevelLocator, LevelRule, ScalePosition, ScaleStack, StackLayout,
    Window, is_empty,
};
use crate::border::Border;
use crate::field::Field;
use crate::kernel::Sampling;

/// Pixels per side of the blocks whose scale ranges are taken.
const BLOCK: usize = 32;

/// What locating a filter's reads needs: the stack's levels and rule, the
/// terms' sigmas and reach.
pub(crate) struct ReadMap {
    levels: Vec<LevelLayout>,
    position: ScalePosition,
    sampling: Sampling,
    /// One rule per term sigma, with its sigma.
    rules: Vec<(LevelRule, f64)>,
    /// The largest `|c_t|` (px, before scaling).
    reach: f64,
    /// Stored samples a lookup reads before and after the one below it.
    stencil: (i64, i64),
}

impl ReadMap {
    /// The reads of `terms` (`(sigma, cx, cy)`: the per-pixel paths'
    /// values) of `sampling` on the log-uniform `levels` (at least two) of
    /// `locator`, read with `interpolation` and extended by `border`,
    /// located by the rule of the per-pixel paths ([`LevelRule`],
    /// [`ScalePosition`]); `None` for a wrapping border (see the module
    /// documentation), a single level or no terms.
    pub(crate) fn new(
        levels: Vec<LevelLayout>,
        locator: &LevelLocator,
        (sampling, terms): (Sampling, &[(f64, f32, f32)]),
        (interpolation, border): (Interpolation, Border),
    ) -> Option<Self> {
        if border == Border::Wrap || levels.len() < 2 || terms.is_empty() || !locator.is_uniform() {
            return None;
        }
        let ln_params = (locator.ln_sigma0, locator.inv_ln_ratio);
        let snap = if locator.reads_nearest_level() {
            NEAREST_SNAP as f32
        } else {
            PIXEL_SNAP
        };
        // One rule per distinct sigma: the terms of a sigma read the same
        // levels.
        let mut sigmas: Vec<f64> = terms.iter().map(|&(sigma, _, _)| sigma).collect();
        sigmas.sort_by(f64::total_cmp);
        sigmas.dedup();
        let rules = sigmas
            .iter()
            .map(|&sigma| {
                let rule = LevelRule {
                    ln_sigma: sigma.ln() as f32,
                    inv_sigma2: (1.0 / (sigma * sigma)) as f32,
                    inv: ln_params.1 as f32,
                    last: (levels.len() - 1) as u32,
                    snap,
                };
                (rule, sigma)
            })
            .collect();
        let reach = terms
            .iter()
            .map(|&(_, cx, cy)| f64::from(cx).hypot(f64::from(cy)))
            .fold(0.0, f64::max);
        let (before, after) = interpolation.reach();
        Some(Self {
            levels,
            position: ScalePosition::new(sampling, ln_params),
            sampling,
            rules,
            reach,
            stencil: (before as i64, after as i64),
        })
    }

    /// [`Self::new`] for `stack`'s levels.
    pub(crate) fn of_stack(
        stack: &ScaleStack,
        sampling: Sampling,
        terms: &[(f64, f32, f32)],
    ) -> Option<Self> {
        Self::new(
            stack.level_layouts().copied().collect(),
            &stack.locator(),
            (sampling, terms),
            (stack.interpolation(), stack.border()),
        )
    }

    /// [`Self::new`] for the levels of `layout`, extended by `border`.
    pub(crate) fn of_layout(
        layout: &StackLayout,
        border: Border,
        sampling: Sampling,
        terms: &[(f64, f32, f32)],
    ) -> Option<Self> {
        Self::new(
            layout.levels().to_vec(),
            &layout.locator(),
            (sampling, terms),
            (layout.interpolation, border),
        )
    }

    /// Per level, the stored samples (indices, inclusive; empty as
    /// `((0, -1), (0, -1))`) that filtering a `width x height` image with
    /// `scale` (a checked field: finite, positive) reads.
    pub(crate) fn windows(&self, scale: Field<'_>, (width, height): (usize, usize)) -> Vec<Window> {
        let ranges = block_ranges(scale, width, height);
        let bw = width.div_ceil(BLOCK);
        // Per level, the pixel rectangle (x0, x1, y0, y1) of its reads.
        let mut rects = vec![
            (
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY
            );
            self.levels.len()
        ];
        for (b, &(s_lo, s_hi)) in ranges.iter().enumerate() {
            // Where the scale puts the levels at the scales every term's
            // extremes are among, once for all terms.
            let shared: Vec<(f32, f32)> = self
                .shared_breaks(s_lo, s_hi)
                .map(|s| self.position.at(s))
                .collect();
            let (first, last) = self
                .rules
                .iter()
                .fold((u32::MAX, 0), |(f, l), &(rule, sigma)| {
                    let own = self
                        .term_breaks(s_lo, s_hi, sigma)
                        .map(|s| self.position.at(s));
                    let (lo, hi) = shared
                        .iter()
                        .copied()
                        .chain(own)
                        .map(|(t_s, widen)| rule.position(t_s, widen))
                        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), u| {
                            (lo.min(u), hi.max(u))
                        });
                    let (a, b) = rule.levels_read(lo, hi);
                    (f.min(a), l.max(b))
                });
            let (bx, by) = ((b % bw) * BLOCK, (b / bw) * BLOCK);
            let d = f64::from(s_hi) * self.reach + 1.0;
            let x0 = bx as f64 - d;
            let x1 = (bx + BLOCK).min(width) as f64 - 1.0 + d;
            let y0 = by as f64 - d;
            let y1 = (by + BLOCK).min(height) as f64 - 1.0 + d;
            for r in &mut rects[first as usize..=last as usize] {
                *r = (r.0.min(x0), r.1.max(x1), r.2.min(y0), r.3.max(y1));
            }
        }
        self.levels
            .iter()
            .zip(rects)
            .map(|(l, (x0, x1, y0, y1))| {
                if x0 > x1 {
                    return ((0, -1), (0, -1));
                }
                let (before, after) = self.stencil;
                let index = |p: f64| ((p - l.origin as f64) / l.step as f64).floor() as i64;
                let axis = |lo: f64, hi: f64, n: usize| {
                    let last = n as i64 - 1;
                    let i0 = (index(lo) - before - 1).clamp(0, last);
                    let i1 = (index(hi) + after + 1).clamp(0, last);
                    (i0, i1)
                };
                (axis(x0, x1, l.nx), axis(y0, y1, l.ny))
            })
            .collect()
    }
}

impl ReadMap {
    /// The scales in `[s_lo, s_hi]` among which a term of `sigma` has the
    /// least and the greatest position (the module documentation): the
    /// ends, and the breakpoints of its sampling between them
    /// ([`Self::shared_breaks`], [`Self::term_breaks`]).
    #[cfg(test)]
    fn extremes(&self, s_lo: f32, s_hi: f32, sigma: f64) -> impl Iterator<Item = f32> {
        self.shared_breaks(s_lo, s_hi)
            .chain(self.term_breaks(s_lo, s_hi, sigma))
    }

    /// The ends, and where a point-sampled footprint drops (at 1: the last
    /// scale below and 1) if it lies between them.
    fn shared_breaks(&self, s_lo: f32, s_hi: f32) -> impl Iterator<Item = f32> + use<> {
        let drop = self.sampling == Sampling::Point && s_lo < 1.0 && 1.0 <= s_hi;
        let at_drop = [1.0f32.next_down().max(s_lo), 1.0];
        [s_lo, s_hi]
            .into_iter()
            .chain(at_drop.into_iter().filter(move |_| drop))
    }

    /// For an area-sampled term narrower than a third of a pixel, the
    /// floor's kink (and the scales either side) where it lies between the
    /// ends; nothing for other terms.
    fn term_breaks(&self, s_lo: f32, s_hi: f32, sigma: f64) -> impl Iterator<Item = f32> + use<> {
        let kink = (self.sampling == Sampling::Area && 9.0 * sigma * sigma < 1.0)
            .then(|| (1.0 / (1.0 - 9.0 * sigma * sigma)).sqrt() as f32);
        kink.into_iter()
            .flat_map(|k| [k.next_down(), k, k.next_up()])
            .filter(move |&s| s_lo < s && s < s_hi)
    }
}

/// The smallest and largest scale of each `BLOCK x BLOCK` block, row-major.
fn block_ranges(scale: Field<'_>, width: usize, height: usize) -> Vec<(f32, f32)> {
    let bw = width.div_ceil(BLOCK);
    let bh = height.div_ceil(BLOCK);
    let mut ranges = vec![(f32::INFINITY, f32::NEG_INFINITY); bw * bh];
    match scale {
        Field::Constant(s) => ranges.fill((s, s)),
        Field::Map(m) => ranges.par_chunks_mut(bw).enumerate().for_each(|(by, out)| {
            // Down the block row's rows pixel by pixel, then across each
            // block; comparisons rather than `f32::min` (which minds NaNs,
            // and a checked field has none), so that the first loop
            // vectorises.
            let rows = by * BLOCK..((by + 1) * BLOCK).min(height);
            let first = &m[rows.start * width..(rows.start + 1) * width];
            let (mut lo, mut hi) = (first.to_vec(), first.to_vec());
            for y in rows.skip(1) {
                let row = &m[y * width..(y + 1) * width];
                for ((l, h), &s) in lo.iter_mut().zip(hi.iter_mut()).zip(row) {
                    *l = if s < *l { s } else { *l };
                    *h = if s > *h { s } else { *h };
                }
            }
            for (r, (l, h)) in out.iter_mut().zip(lo.chunks(BLOCK).zip(hi.chunks(BLOCK))) {
                *r = (
                    l.iter().copied().fold(f32::INFINITY, f32::min),
                    h.iter().copied().fold(f32::NEG_INFINITY, f32::max),
                );
            }
        }),
    }
    ranges
}

/// Whether every level's `computed` window holds its `needed` one.
pub(crate) fn holds(computed: &[Window], needed: &[Window]) -> bool {
    let inside = |(a0, a1): (i64, i64), (b0, b1): (i64, i64)| a0 <= b0 && b1 <= a1;
    computed.len() == needed.len()
        && computed
            .iter()
            .zip(needed)
            .all(|(&c, &n)| is_empty(n) || (inside(c.0, n.0) && inside(c.1, n.1)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decomposition::Decomposition;
    use crate::stack::StackOptions;
    use crate::stack::area;
    use crate::stack::for_decomposition::stack_plan_for_decomposition;
    use crate::term::Term;
    use crate::trig::sin_cos_degrees;

    /// The share of `levels`' stored samples that `windows` hold.
    fn share(levels: &[LevelLayout], windows: &[Window]) -> f64 {
        let all: f64 = levels.iter().map(|l| (l.nx * l.ny) as f64).sum();
        let held: f64 = windows.iter().map(|&w| area(w)).sum();
        held / all
    }

    /// A scale per pixel of a `w x h` image over `[lo, hi]`: radial, hashed
    /// noise, a step (`lo` left, `hi` right), or, about 1, a checkerboard of
    /// 3 px squares of the last scale below 1 and 1 itself.
    fn scale_map(kind: &str, (lo, hi): (f32, f32), (w, h): (usize, usize)) -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                match kind {
                    "radial" => {
                        let r = (x - w as f32 / 2.0).hypot(y - h as f32 / 2.0);
                        lo + (hi - lo) * r / (w as f32 / 2.0).hypot(h as f32 / 2.0)
                    }
                    "noise" => lo + (hi - lo) * ((i * 2_654_435_761) % 1000) as f32 / 999.0,
                    "checks" => {
                        if ((i % w) / 3 + (i / w) / 3) % 2 == 0 {
                            1.0f32.next_down()
                        } else {
                            1.0
                        }
                    }
                    _ => {
                        if x < w as f32 / 3.0 {
                            lo
                        } else {
                            hi
                        }
                    }
                }
            })
            .collect()
    }

    /// Every stored sample that any pixel's lookups read (the per-pixel
    /// rule's levels, the stencils around each term's position under a
    /// per-pixel angle, computed as the scalar loop computes them, clamped
    /// to the stored samples as the border rule clamps them) lies in its
    /// level's window: every sampling (the point-sampled footprint drops at
    /// scale 1, a narrow area-sampled term's position falls and rises with
    /// the scale), both interpolations, blended and nearest levels,
    /// full-resolution and pyramid levels, smooth, noisy, stepped and
    /// checkered maps below and across scale 1.
    #[test]
    fn the_windows_hold_every_read() {
        let (w, h) = (90, 70);
        let terms = vec![
            Term {
                weight: 0.4,
                x: -7.0,
                y: 2.0,
                sigma: 1.2,
            },
            Term {
                weight: 0.3,
                x: 5.0,
                y: -4.5,
                sigma: 2.6,
            },
            Term {
                weight: 0.2,
                x: 0.5,
                y: 9.0,
                sigma: 5.0,
            },
            Term {
                weight: 0.1,
                x: 1.5,
                y: -1.0,
                sigma: 0.25,
            },
        ];
        let angles: Vec<f32> = (0..w * h).map(|i| ((i * 7919) % 360) as f32).collect();
        let mut smallest_share = 1.0f64;
        for sampling in [
            Sampling::Continuous,
            Sampling::Point,
            Sampling::Area,
            Sampling::Averaged,
        ] {
            let mut d = Decomposition::from_terms(terms.clone());
            d.sampling = sampling;
            for (interpolation, nearest_level, pyramid_factor) in [
                (Interpolation::Linear, false, 2.0),
                (Interpolation::Linear, true, 1.0),
                (Interpolation::Cubic, false, 4.0),
            ] {
                let options = StackOptions {
                    samples_per_octave: 3,
                    pyramid_factor,
                    interpolation,
                    nearest_level,
                    ..StackOptions::default()
                };
                for (kind, range) in [
                    ("radial", (0.2, 1.0)),
                    ("noise", (0.2, 1.0)),
                    ("step", (0.2, 1.0)),
                    ("radial", (0.5, 2.0)),
                    ("noise", (0.5, 2.0)),
                    ("checks", (0.99, 1.0)),
                ] {
                    let scales = scale_map(kind, range, (w, h));
                    let plan = stack_plan_for_decomposition(
                        (w, h, 1),
                        &d,
                        range.0,
                        range.1,
                        Border::Reflect101,
                        options,
                    )
                    .expect("plan");
                    let layout = plan.layout().expect("layout");
                    let prepared: Vec<(f64, f32, f32)> = terms
                        .iter()
                        .map(|t| (t.sigma, t.x as f32, t.y as f32))
                        .collect();
                    let reads =
                        ReadMap::of_layout(&layout, Border::Reflect101, sampling, &prepared)
                            .expect("reads");
                    let windows = reads.windows(Field::Map(&scales), (w, h));
                    smallest_share = smallest_share.min(share(layout.levels(), &windows));
                    let (before, after) = interpolation.reach();
                    for (i, (&s, &theta)) in scales.iter().zip(&angles).enumerate() {
                        let (x, y) = ((i % w) as f32, (i / w) as f32);
                        let (t_s, widen) = reads.position.at(s);
                        let (sin, cos) = sin_cos_degrees(theta);
                        let (cs, ss) = (cos * s, sin * s);
                        for t in &terms {
                            let (rule, _) =
                                reads.rules.iter().find(|r| r.1 == t.sigma).expect("rule");
                            let (cx, cy) = (t.x as f32, t.y as f32);
                            let px = x + cs * cx + ss * cy;
                            let py = y - ss * cx + cs * cy;
                            let (a, b, _, wb) = rule.at(t_s, widen);
                            let read = if wb == 0.0 { vec![a] } else { vec![a, b] };
                            for level in read {
                                let l = &layout.levels()[level as usize];
                                let ((i0, i1), (j0, j1)) = windows[level as usize];
                                let index =
                                    |p: f32| ((p - l.origin as f32) / l.step as f32).floor() as i64;
                                let (u, v) = (index(px), index(py));
                                for du in -(before as i64)..=after as i64 {
                                    for dv in -(before as i64)..=after as i64 {
                                        let iu = (u + du).clamp(0, l.nx as i64 - 1);
                                        let iv = (v + dv).clamp(0, l.ny as i64 - 1);
                                        assert!(
                                            (i0..=i1).contains(&iu) && (j0..=j1).contains(&iv),
                                            "{sampling:?} {interpolation:?} nearest {nearest_level} {kind} {range:?}: \
                                             pixel ({x}, {y}) at scale {s} reads level {level} at ({iu}, {iv}), \
                                             outside its window {:?}",
                                            windows[level as usize]
                                        );
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        // Somewhere the windows leave samples out (the test is not vacuous
        // because every window is the whole level).
        assert!(smallest_share < 0.8, "{smallest_share}");
    }

    /// The stack layout of a one-term decomposition (sigma 2) on a
    /// `w x h` image over the scales `range`.
    fn one_term_layout((w, h): (usize, usize), range: (f32, f32), border: Border) -> StackLayout {
        let d = Decomposition::from_terms(vec![Term {
            weight: 1.0,
            x: 3.0,
            y: 0.0,
            sigma: 2.0,
        }]);
        stack_plan_for_decomposition(
            (w, h, 1),
            &d,
            range.0,
            range.1,
            border,
            StackOptions::default(),
        )
        .expect("plan")
        .layout()
        .expect("layout")
    }

    /// The positions at [`ReadMap::extremes`] bound a term's position at
    /// every scale between the ends (a fine grid and the breakpoints
    /// themselves), for every sampling and sigmas either side of the area
    /// kink's third of a pixel, over ranges below, across and above 1.
    #[test]
    fn the_extremes_bound_the_positions_between() {
        let layout = one_term_layout((64, 64), (0.1, 4.0), Border::Reflect101);
        for sampling in [
            Sampling::Continuous,
            Sampling::Point,
            Sampling::Area,
            Sampling::Averaged,
        ] {
            for sigma in [0.2, 0.25, 0.3, 0.34, 0.6, 1.2, 5.0] {
                let reads =
                    ReadMap::of_layout(&layout, Border::Reflect101, sampling, &[(sigma, 0.0, 0.0)])
                        .expect("reads");
                let (rule, _) = reads.rules[0];
                let position = |s: f32| {
                    let (t_s, widen) = reads.position.at(s);
                    rule.position(t_s, widen)
                };
                for (s_lo, s_hi) in [
                    (0.5, 2.0),
                    (0.99, 1.0),
                    (0.999, 1.001),
                    (0.2, 0.9),
                    (1.0, 3.0),
                    (1.2, 1.8),
                    (0.9, 3.5),
                ] {
                    let (lo, hi) = reads
                        .extremes(s_lo, s_hi, sigma)
                        .map(position)
                        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), u| {
                            (lo.min(u), hi.max(u))
                        });
                    let grid = (0..=2000).map(|k| s_lo + (s_hi - s_lo) * k as f32 / 2000.0);
                    let special = [1.0f32.next_down(), 1.0, 1.0f32.next_up()];
                    for s in grid.chain(special).filter(|s| (s_lo..=s_hi).contains(s)) {
                        let u = position(s);
                        assert!(
                            lo - 1e-4 <= u && u <= hi + 1e-4,
                            "{sampling:?} sigma {sigma} on [{s_lo}, {s_hi}]: position {u} at {s} outside [{lo}, {hi}]"
                        );
                    }
                }
            }
        }
    }

    /// A wrapping border reads the far side of the image: no windows.
    #[test]
    fn a_wrapping_border_has_no_windows() {
        let layout = one_term_layout((40, 30), (0.25, 1.0), Border::Wrap);
        let terms = [(2.0, 3.0, 0.0)];
        assert!(ReadMap::of_layout(&layout, Border::Wrap, Sampling::Continuous, &terms).is_none());
        assert!(
            ReadMap::of_layout(&layout, Border::Reflect101, Sampling::Continuous, &terms).is_some()
        );
    }
}
