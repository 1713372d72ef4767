//! The per-pixel paths' inner loop, vectorised across pixels: a row's
//! lookups `N` neighbouring pixels at a time (AVX2: eight, AVX-512:
//! sixteen), from contiguous rows of the level where the block's stencils
//! lie close together and with the CPU's gathers where they do not, and
//! the per-pixel rules the rows need (the rotations, a scale map's level
//! positions, each sigma group's levels and weights). CPUs without them, or `IFD_SIMD=baseline`, take the scalar
//! loop, with the same results.
//!
//! # Layout
//! - this file: the row types ([`FixedTerm`], [`ScaledTerm`],
//!   [`RowLevels`], [`RowOut`]), what the kernels can read ([`supports`]), and the
//!   dispatch: each entry point runs the widest kernels [`ifd_simd::isa`]
//!   allows, then the narrower ones over the blocks left, and returns the
//!   pixels done (the caller's scalar loop does the rest);
//! - `lanes.rs`: the `Lanes` trait, the primitives the kernels are written
//!   in;
//! - `kernels.rs`: the lookups, written once over `Lanes`; `rules.rs`: the
//!   per-pixel rules (rotations, scale positions, levels) likewise;
//! - `avx2.rs`, `avx512.rs`: each instruction set's primitives (a few
//!   intrinsics each) and the kernels' `#[target_feature]` entry points.
//!
//! # Why vectors across pixels
//! With a per-pixel angle (or scale) every term of every pixel reads its own
//! displaced position, so nothing is shared between the lookups of one
//! pixel; but the positions of neighbouring pixels for one term are a few
//! multiply-adds apart. One term for `N` pixels is then one vector of
//! positions, one vector of indices and weights, and four gathers (two when
//! the level has one channel: each gather reads the two horizontal
//! neighbours as one 64-bit element). The scalar loop spends most of its
//! instructions on exactly that address and weight arithmetic, one pixel at
//! a time.
//!
//! # Windows instead of gathers
//! A gather costs a load per lane, and on some CPUs much more: on AMD Zen 4
//! one sixteen-lane lookup's gathers took about 100 cycles. But an angle
//! or scale map that varies slowly along the row moves each term's
//! stencils by about one level sample per pixel, so a block's stencils lie
//! within a few rows and a few dozen columns. Where every lane's columns
//! fit a window of `2 N` samples and its rows are the first lane's or one
//! either side, the one-channel kernels load each row the block touches as
//! `2 N` contiguous samples and permute each lane's out of them
//! (`permutex2var` in AVX-512; two `permutevar8x32` and a blend in AVX2):
//! 1.3-1.4x faster bilinear rows and 1.8-2.4x faster cubic ones on the Zen 4
//! (BENCHMARKS.md). The samples are the ones the gathers would read, so the
//! sums are the same bits; blocks spread wider (a fast-turning map, a level
//! at the border) gather as before.
//!
//! # Several filters on one stack
//! A bank of decompositions blended per pixel (the smoother's aspect bank, a
//! sigma map) runs one filter at a time over the image with a weight per
//! pixel ([`RowOut`]): each row's pixels of non-zero weight are packed into
//! whole blocks (their columns and outputs from a list), so that a filter
//! serving scattered pixels of a row does not run blocks for one lane of
//! sixteen. A packed lane reads and adds exactly what it would unpacked.
//!
//! # Same results as the scalar loop
//! The kernels evaluate the scalar loop's expressions in the same order with
//! separate multiplies and adds (no fused multiply-add), and a block with a
//! lane whose stencil leaves the stored level hands that term's lookups to
//! the scalar, border-resolving lookup in lane order. So the output is bit
//! for bit the scalar loop's on every CPU and at every width (tested),
//! whatever the thread count.
//!
//! # The `unsafe` here
//! The workspace denies `unsafe`; this module is the one exception in
//! `ifd-planar`, for two things stable Rust only offers as `unsafe`: calling
//! a function compiled for AVX2 or AVX-512 (after [`ifd_simd::has`] said the
//! CPU has it), and the loads through a raw pointer (the gathers and the
//! windows' contiguous loads). The intrinsics are only in `avx2.rs` and
//! `avx512.rs`. Memory safety does not rest on the interior test that
//! chooses the vector path: the gather indices are clamped (integer
//! min/max) into the range every read of a stencil stays in, a window is
//! loaded only after its first and last rows were checked to lie in the
//! level's samples, and the levels' sizes are checked ([`supports`])
//! before any kernel runs.
#![allow(
    unsafe_code,
    reason = "calls of the AVX2/AVX-512 entry points after run-time detection; see the module documentation"
)]

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
#[cfg(target_arch = "x86_64")]
mod kernels;
#[cfg(target_arch = "x86_64")]
mod lanes;
#[cfg(target_arch = "x86_64")]
mod rules;
#[cfg(test)]
mod tests;

use super::{Interpolation, LevelRule, ScalePosition, ScaleStack};
use crate::field::Field;
use ifd_simd::Isa;

/// One term at a constant scale: displacement, its one or two levels and
/// their weights (`wb == 0` for one lookup).
#[derive(Clone, Copy, Debug)]
pub(crate) struct FixedTerm {
    pub(crate) cx: f32,
    pub(crate) cy: f32,
    pub(crate) a: usize,
    pub(crate) b: usize,
    pub(crate) wa: f32,
    pub(crate) wb: f32,
}

/// One term with a per-pixel scale: displacement, weight and the index of
/// its sigma among the decomposition's distinct sigmas.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ScaledTerm {
    pub(crate) cx: f32,
    pub(crate) cy: f32,
    pub(crate) weight: f32,
    pub(crate) group: usize,
}

/// The levels of each sigma group at each pixel of a row, group-major
/// (`g * w + x`), one array per part: pixel `x` of group `g` reads level
/// `a` with weight `wa` and, where `wb != 0`, level `a + 1` with `wb` (the
/// scalar loop's `(a, b, wa, wb)` of [`LevelRule`], whose `b` is `a + 1`
/// or, with `wb == 0`, `a`; the term weight not included).
#[derive(Clone, Debug)]
pub(crate) struct RowLevels {
    pub(super) w: usize,
    /// The sigma groups it has room for, `room` pixels each.
    pub(super) groups: usize,
    room: usize,
    pub(super) a: Vec<u32>,
    pub(super) wa: Vec<f32>,
    pub(super) wb: Vec<f32>,
    /// The largest [`LevelRule::last`] a group was filled with: no pixel
    /// reads a level past it (the rule clamps `a + 1` where `wb != 0`, and
    /// `a`, to it), so the kernels check it once instead of every pixel.
    pub(super) last: u32,
}

impl RowLevels {
    /// Room for `groups` sigma groups over `w` pixels.
    pub(crate) fn new(groups: usize, w: usize) -> Self {
        let n = groups * w;
        Self {
            w,
            groups,
            room: w,
            a: vec![0; n],
            wa: vec![0.0; n],
            wb: vec![0.0; n],
            last: 0,
        }
    }

    /// Pixel `x`'s `(a, b, wa, wb)` in group `g`.
    pub(super) fn at(&self, g: usize, x: usize) -> (usize, usize, f32, f32) {
        let i = g * self.w + x;
        let a = self.a[i] as usize;
        let b = if self.wb[i] == 0.0 { a } else { a + 1 };
        (a, b, self.wa[i], self.wb[i])
    }

    /// Sets the row's length to `w` pixels (a packed row's entries), within
    /// the room it was made with.
    ///
    /// # Panics
    /// If `w` pixels of every group do not fit.
    pub(crate) fn set_width(&mut self, w: usize) {
        assert!(
            w <= self.room,
            "{w} pixels in a row of room for {}",
            self.room
        );
        self.w = w;
    }

    /// Pixel `i`'s (group-major index) levels from `(a, b, wa, wb)`.
    #[inline]
    fn set(&mut self, i: usize, (a, _, wa, wb): (u32, u32, f32, f32)) {
        (self.a[i], self.wa[i], self.wb[i]) = (a, wa, wb);
    }
}

/// Where a row's sums go: `row[x * C + k] += sum` for each pixel `x` and
/// channel `k`, or, with per-pixel `weight`s, `+= weight[x] * sum` (the
/// scalar loop's expression), the blocks whose weights are all zero
/// skipped. Lanes of weight zero in a block that runs add `0 * sum`, except
/// in a packed row, where they add nothing (its padding).
///
/// A packed row (`pixels`) lists some of the row's pixels: entry `k` of the
/// kernels' inputs (rotations, levels, weights) is pixel `pixels[k]`, where
/// its sum goes; without it entry `k` is pixel `k`.
#[derive(Debug)]
pub(crate) struct RowOut<'o> {
    pub(crate) row: &'o mut [f32],
    pub(crate) weight: Option<&'o [f32]>,
    pub(crate) pixels: Option<&'o [u32]>,
}

#[cfg(test)]
impl<'o> RowOut<'o> {
    /// A row's pixels in order, unweighted.
    pub(crate) fn dense(row: &'o mut [f32]) -> Self {
        Self {
            row,
            weight: None,
            pixels: None,
        }
    }
}

impl RowOut<'_> {
    /// Whether it holds `n` entries of `C` channels (and `n` weights and
    /// pixels, each pixel in the row).
    fn holds<const C: usize>(&self, n: usize) -> bool {
        self.weight.is_none_or(|p| p.len() >= n)
            && match self.pixels {
                None => self.row.len() >= n * C,
                Some(p) => {
                    p.len() >= n
                        && p[..n]
                            .iter()
                            .all(|&x| (x as usize + 1) * C <= self.row.len())
                }
            }
    }

    /// The same row and weights, borrowed again (for one kernel call).
    fn reborrow(&mut self) -> RowOut<'_> {
        RowOut {
            row: self.row,
            weight: self.weight,
            pixels: self.pixels,
        }
    }
}

/// Whether the kernels can read `stack` with `channels = C` on this CPU:
/// [`fits`], and vector kernels chosen ([`ifd_simd::isa`] is not the
/// baseline).
pub(crate) fn supports<const C: usize>(stack: &ScaleStack) -> bool {
    ifd_simd::isa() != Isa::Baseline && fits::<C>(stack)
}

/// Whether the kernels can read `stack` with `channels = C`: every level at
/// least as large as a stencil (2x2 samples bilinear, 4x4 cubic), stored as
/// `nx * ny * C` samples addressable with 32-bit indices.
fn fits<const C: usize>(stack: &ScaleStack) -> bool {
    let least = match stack.interpolation {
        Interpolation::Linear => 2,
        Interpolation::Cubic => 4,
    };
    C > 0
        && stack.channels == C
        && stack.levels.iter().all(|l| {
            let (nx, ny) = (l.layout.nx, l.layout.ny);
            nx >= least
                && ny >= least
                && l.data.len() == nx * ny * C
                && l.data.len() < i32::MAX as usize
        })
}

/// Runs `$f` of `avx512` then of `avx2` (each from the pixel the one
/// before stopped at) where `$isa` allows them and the CPU has them: the
/// pixels done. The one place the entry points are called.
macro_rules! widest_first {
    ($isa:expr, $f:ident $(::<$c:ident>)? ($($arg:expr),* $(,)?)) => {{
        let isa: Isa = $isa;
        let mut done = 0;
        #[cfg(target_arch = "x86_64")]
        {
            if isa >= Isa::Avx512 && ifd_simd::has(Isa::Avx512) {
                // SAFETY: the CPU has AVX-512F with AVX2 and FMA (`has`).
                done = unsafe { $crate::stack::rows::avx512::$f $(::<$c>)? ($($arg,)* done) };
            }
            if isa >= Isa::Avx2 && ifd_simd::has(Isa::Avx2) {
                // SAFETY: the CPU has AVX2 and FMA (`has`).
                done = unsafe { $crate::stack::rows::avx2::$f $(::<$c>)? ($($arg,)* done) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = (&isa, $(&$arg,)*);
        }
        done
    }};
}

/// Adds the filtered values of the entries `0..n` of row `y` (its pixels
/// `0..n`, or a packed row's listed pixels: [`RowOut`]) into `out` (`C`
/// interleaved channels) for per-entry rotations `cs[k] = s cos`, `ss[k] = s
/// sin` at a constant scale, where `n` is the returned count (0 when the
/// kernels cannot run). The caller filters the remaining entries.
pub(crate) fn rotated_row<const C: usize>(
    stack: &ScaleStack,
    terms: &[FixedTerm],
    y: usize,
    cs: &[f32],
    ss: &[f32],
    out: RowOut<'_>,
) -> usize {
    rotated_row_on::<C>(ifd_simd::isa(), stack, terms, y, (cs, ss), out)
}

/// [`rotated_row`] on the kernels of `isa` and narrower ones.
fn rotated_row_on<const C: usize>(
    isa: Isa,
    stack: &ScaleStack,
    terms: &[FixedTerm],
    y: usize,
    (cs, ss): (&[f32], &[f32]),
    mut out: RowOut<'_>,
) -> usize {
    if !fits::<C>(stack) || cs.len() != ss.len() || !out.holds::<C>(cs.len()) {
        return 0;
    }
    widest_first!(
        isa,
        rotated_row::<C>(stack, terms, y, (cs, ss), out.reborrow())
    )
}

/// As [`rotated_row`] with a per-pixel scale: `levels` gives the levels and
/// weights of the terms of each sigma group at each pixel, `w = cs.len()`.
pub(crate) fn scaled_row<const C: usize>(
    stack: &ScaleStack,
    terms: &[ScaledTerm],
    levels: &RowLevels,
    y: usize,
    cs: &[f32],
    ss: &[f32],
    out: RowOut<'_>,
) -> usize {
    scaled_row_on::<C>(ifd_simd::isa(), stack, terms, levels, y, (cs, ss), out)
}

/// [`scaled_row`] on the kernels of `isa` and narrower ones.
fn scaled_row_on<const C: usize>(
    isa: Isa,
    stack: &ScaleStack,
    terms: &[ScaledTerm],
    levels: &RowLevels,
    y: usize,
    (cs, ss): (&[f32], &[f32]),
    mut out: RowOut<'_>,
) -> usize {
    let w = cs.len();
    if !fits::<C>(stack)
        || ss.len() != w
        || levels.w != w
        || !out.holds::<C>(w)
        || terms.iter().any(|t| t.group >= levels.groups || (t.group + 1) * w > levels.a.len())
        // the highest level any pixel reads
        || levels.last as usize >= stack.levels.len()
    {
        return 0;
    }
    widest_first!(
        isa,
        scaled_row::<C>(stack, terms, levels, y, (cs, ss), out.reborrow())
    )
}

/// `cs[x] = s cos theta[x]` and `ss[x] = s sin theta[x]` over a row of
/// angles in degrees, `s` the row's `scale` (a map's row or a constant):
/// [`crate::trig::sin_cos_degrees`]'s operations, in vector lanes where the
/// CPU has them, so the same bits as the scalar loop's rotations.
///
/// # Panics
/// If the slices' lengths differ (a map's row included).
pub(crate) fn rotations(theta: &[f32], scale: Field<'_>, cs: &mut [f32], ss: &mut [f32]) {
    let w = theta.len();
    assert!(cs.len() == w && ss.len() == w);
    if let Field::Map(m) = scale {
        assert_eq!(m.len(), w);
    }
    let done = widest_first!(ifd_simd::isa(), rotations(theta, scale, cs, ss));
    for x in done..w {
        let (sin, cos) = crate::trig::sin_cos_degrees(theta[x]);
        let s = scale.at(x);
        (cs[x], ss[x]) = (cos * s, sin * s);
    }
}

/// Each pixel's `(t_s, widen)` of the row's `scales` by `rule`
/// ([`ScalePosition::at`]; in vector lanes where the CPU has them, the
/// same values).
///
/// # Panics
/// If the slices' lengths differ.
pub(crate) fn scale_positions(
    rule: ScalePosition,
    scales: &[f32],
    t_s: &mut [f32],
    widen: &mut [f32],
) {
    let w = scales.len();
    assert!(t_s.len() == w && widen.len() == w);
    let done = widest_first!(ifd_simd::isa(), scale_positions(rule, scales, t_s, widen));
    for x in done..w {
        (t_s[x], widen[x]) = rule.at(scales[x]);
    }
}

/// Group `g`'s levels over the row by `rule` from each pixel's `t_s` and
/// `widen` ([`LevelRule`]): in vector lanes where the CPU has them (each
/// lane's widening by its series or, where it needs one, its logarithm,
/// [`crate::ln::ln`]'s operations in the lanes), [`LevelRule::at`] for the
/// pixels left; the same values as [`LevelRule::at`] pixel by pixel.
///
/// # Panics
/// If `t_s` or `widen` is not one value per pixel, or `g` is past the
/// groups.
pub(crate) fn fill_levels(
    rule: LevelRule,
    t_s: &[f32],
    widen: &[f32],
    levels: &mut RowLevels,
    g: usize,
) {
    let w = levels.w;
    assert!(t_s.len() == w && widen.len() == w && (g + 1) * w <= levels.a.len());
    levels.last = levels.last.max(rule.last);
    let done = widest_first!(ifd_simd::isa(), fill_levels(rule, t_s, widen, levels, g));
    for x in done..w {
        levels.set(g * w + x, rule.at(t_s[x], widen[x]));
    }
}

/// The vector passes alone on `isa` and narrower kernels (no scalar tail),
/// for the tests that compare the widths: the pixels done.
#[cfg(test)]
mod on_isa {
    use super::{Field, Isa, LevelRule, RowLevels, ScalePosition};

    pub(super) fn rotations(
        isa: Isa,
        theta: &[f32],
        scale: Field<'_>,
        cs: &mut [f32],
        ss: &mut [f32],
    ) -> usize {
        widest_first!(isa, rotations(theta, scale, cs, ss))
    }

    pub(super) fn scale_positions(
        isa: Isa,
        rule: ScalePosition,
        scales: &[f32],
        t_s: &mut [f32],
        widen: &mut [f32],
    ) -> usize {
        widest_first!(isa, scale_positions(rule, scales, t_s, widen))
    }

    pub(super) fn fill_levels(
        isa: Isa,
        rule: LevelRule,
        t_s: &[f32],
        widen: &[f32],
        levels: &mut RowLevels,
        g: usize,
    ) -> usize {
        widest_first!(isa, fill_levels(rule, t_s, widen, levels, g))
    }
}
