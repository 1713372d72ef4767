//! Bilinear lookups for eight neighbouring pixels at once: the per-pixel
//! paths' inner loop, vectorised across pixels with AVX2 gathers (detected at
//! run time; other CPUs take the scalar loop).
#![allow(
    unsafe_code,
    reason = "AVX2 gathers and run-time dispatch; see the module documentation"
)]

use super::{Interpolation, LevelRule, ScalePosition, ScaleStack};
use crate::field::Field;

/// Pixels per vector block.
pub(crate) const LANES: usize = 8;

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

/// The vector instruction set the per-pixel kernels use on this CPU, if
/// any: `Some("avx2")` on x86-64 CPUs with AVX2, `None` elsewhere (the scalar
/// loop, same results).
///
/// ```
/// let isa = ifd_planar::vector_kernels();
/// assert!(isa.is_none() || isa == Some("avx2"));
/// ```
///
/// Bilinear lookups for eight neighbouring pixels at once: the per-pixel
/// paths' inner loop, vectorised across pixels with AVX2 gathers (detected at
/// run time; other CPUs take the scalar loop).
///
/// # Why vectors across pixels
/// With a per-pixel angle (or scale) every term of every pixel reads its own
/// displaced position, so nothing is shared between the lookups of one pixel;
/// but the positions of eight neighbouring pixels for one term are a few
/// multiply-adds apart. One term for eight pixels is then one vector of
/// positions, one vector of indices and weights, and four gathers (two when
/// the level has one channel: each gather reads the two horizontal
/// neighbours as one 64-bit element). The scalar loop spends most of its
/// instructions on exactly that address and weight arithmetic, one pixel at
/// a time.
///
/// # Same results as the scalar loop
/// The kernels evaluate the scalar loop's expressions in the same order with
/// separate multiplies and adds (no fused multiply-add), and a block with a
/// lane whose stencil leaves the stored level hands that term's eight lookups
/// to the scalar, border-resolving lookup in lane order. So the output is
/// bit for bit the scalar loop's on every CPU (tested), whatever the thread
/// count.
///
/// # The `unsafe` in this module
/// The workspace denies `unsafe`; this module is the one exception, for two
/// things stable Rust only offers as `unsafe`: calling a function compiled
/// for AVX2 (after `is_x86_feature_detected!` said the CPU has it), and the
/// gather instructions, which take a raw pointer. Memory safety does not rest
/// on the interior test that chooses the vector path: the gather indices are
/// clamped (integer min/max) into the range every read of a stencil stays in,
/// and the levels' sizes are checked once (`supports`) before any kernel
/// runs.
#[must_use]
pub fn vector_kernels() -> Option<&'static str> {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            return Some("avx2");
        }
    }
    None
}

/// Whether the kernels can read `stack` with `channels = C`: every level at
/// least as large as a stencil (2x2 samples bilinear, 4x4 cubic), stored as
/// `nx * ny * C` samples addressable with 32-bit indices, and a CPU that has
/// them.
pub(crate) fn supports<const C: usize>(stack: &ScaleStack) -> bool {
    let least = match stack.interpolation {
        Interpolation::Linear => 2,
        Interpolation::Cubic => 4,
    };
    C > 0
        && stack.channels == C
        && vector_kernels().is_some()
        && stack.levels.iter().all(|l| {
            let (nx, ny) = (l.layout.nx, l.layout.ny);
            nx >= least
                && ny >= least
                && l.data.len() == nx * ny * C
                && l.data.len() < i32::MAX as usize
        })
}

/// Adds the filtered values of the pixels `0..n` of row `y` into `out` (the
/// row, `C` interleaved channels) for per-pixel rotations `cs[x] = s cos`,
/// `ss[x] = s sin` at a constant scale, where `n` is the returned count (a
/// multiple of [`LANES`]; 0 when the kernels cannot run). The caller
/// filters the remaining pixels.
pub(crate) fn rotated_row<const C: usize>(
    stack: &ScaleStack,
    terms: &[FixedTerm],
    y: usize,
    cs: &[f32],
    ss: &[f32],
    out: &mut [f32],
) -> usize {
    if !supports::<C>(stack) || cs.len() != ss.len() || out.len() < cs.len() * C {
        return 0;
    }
    if C == 1 {
        // sixteen lanes where the CPU has AVX-512F; the row's last
        // `w % 16` pixels go to the caller's scalar loop
        let done = super::gather512::rotated_row(stack, terms, y, cs, ss, out);
        if done > 0 {
            return done;
        }
    }
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: `supports` checked that the CPU has AVX2.
        unsafe { avx2::rotated_row::<C>(stack, terms, y, cs, ss, out) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (terms, y);
        0
    }
}

/// The AVX2 kernels whatever wider vectors the CPU has, for the tests that
/// compare them with the AVX-512 kernels and the scalar rules: each returns
/// the pixels done (0 without AVX2; the row kernels, one channel, assert
/// that the CPU has it).
#[cfg(test)]
pub(crate) mod avx2_for_tests {
    use super::{Field, FixedTerm, LevelRule, RowLevels, ScalePosition, ScaleStack, ScaledTerm};

    pub(crate) fn rotated_row(
        stack: &ScaleStack,
        terms: &[FixedTerm],
        y: usize,
        cs: &[f32],
        ss: &[f32],
        out: &mut [f32],
    ) -> usize {
        assert!(super::supports::<1>(stack) && cs.len() == ss.len() && out.len() >= cs.len());
        // SAFETY: `supports` checked that the CPU has AVX2.
        unsafe { super::avx2::rotated_row::<1>(stack, terms, y, cs, ss, out) }
    }

    pub(crate) fn scaled_row(
        stack: &ScaleStack,
        terms: &[ScaledTerm],
        levels: &RowLevels,
        y: usize,
        cs: &[f32],
        ss: &[f32],
        out: &mut [f32],
    ) -> usize {
        assert!(super::supports::<1>(stack) && cs.len() == ss.len() && out.len() >= cs.len());
        // SAFETY: `supports` checked that the CPU has AVX2.
        unsafe { super::avx2::scaled_row::<1>(stack, terms, levels, y, cs, ss, out) }
    }

    pub(crate) fn rotations(
        theta: &[f32],
        scale: Field<'_>,
        cs: &mut [f32],
        ss: &mut [f32],
    ) -> usize {
        #[cfg(target_arch = "x86_64")]
        if super::vector_kernels().is_some() {
            // SAFETY: the CPU has AVX2 (checked just now).
            return unsafe { super::avx2::rotations(theta, scale, cs, ss) };
        }
        let _ = (theta, scale, cs, ss);
        0
    }

    pub(crate) fn scale_positions(
        rule: ScalePosition,
        scales: &[f32],
        t_s: &mut [f32],
        widen: &mut [f32],
    ) -> usize {
        #[cfg(target_arch = "x86_64")]
        if super::vector_kernels().is_some() {
            // SAFETY: the CPU has AVX2 (checked just now).
            return unsafe { super::avx2::scale_positions(rule, scales, t_s, widen) };
        }
        let _ = (rule, scales, t_s, widen);
        0
    }

    pub(crate) fn fill_levels(
        rule: LevelRule,
        t_s: &[f32],
        widen: &[f32],
        levels: &mut RowLevels,
        g: usize,
    ) -> usize {
        #[cfg(target_arch = "x86_64")]
        if super::vector_kernels().is_some() {
            // SAFETY: the CPU has AVX2 (checked just now).
            return unsafe { super::avx2::fill_levels(rule, t_s, widen, levels, g) };
        }
        let _ = (rule, t_s, widen, levels, g);
        0
    }
}

/// `cs[x] = s cos theta[x]` and `ss[x] = s sin theta[x]` over a row of
/// angles in degrees, `s` the row's `scale` (a map's row or a constant):
/// [`crate::trig::sin_cos_degrees`]'s operations, in AVX2 lanes where the
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
    // sixteen lanes where the CPU has AVX-512F, else eight with AVX2
    let mut done = super::gather512::rotations(theta, scale, cs, ss);
    #[cfg(target_arch = "x86_64")]
    if done == 0 && vector_kernels().is_some() {
        // SAFETY: the CPU has AVX2 (checked just now).
        done = unsafe { avx2::rotations(theta, scale, cs, ss) };
    }
    for x in done..w {
        let (sin, cos) = crate::trig::sin_cos_degrees(theta[x]);
        let s = scale.at(x);
        (cs[x], ss[x]) = (cos * s, sin * s);
    }
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

    /// Pixel `i`'s (group-major index) levels from `(a, b, wa, wb)`.
    #[inline]
    fn set(&mut self, i: usize, (a, _, wa, wb): (u32, u32, f32, f32)) {
        (self.a[i], self.wa[i], self.wb[i]) = (a, wa, wb);
    }
}

/// Each pixel's `(t_s, widen)` of the row's `scales` by `rule`
/// ([`ScalePosition::at`]; in AVX2 lanes where the CPU has them, the same
/// values).
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
    // sixteen lanes where the CPU has AVX-512F, else eight with AVX2
    let mut done = super::gather512::scale_positions(rule, scales, t_s, widen);
    #[cfg(target_arch = "x86_64")]
    if done == 0 && vector_kernels().is_some() {
        // SAFETY: the CPU has AVX2 (checked just now).
        done = unsafe { avx2::scale_positions(rule, scales, t_s, widen) };
    }
    for x in done..w {
        (t_s[x], widen[x]) = rule.at(scales[x]);
    }
}

/// Group `g`'s levels over the row by `rule` from each pixel's `t_s` and
/// `widen` ([`LevelRule`]): the series branch for every pixel (in AVX2
/// lanes where the CPU has them), then [`LevelRule::at`] again for the
/// pixels whose widening needs the logarithm (the vector lanes find them
/// with the same test in their lanes); the same values as
/// [`LevelRule::at`] pixel by pixel.
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
    // sixteen lanes where the CPU has AVX-512F
    let mut done = super::gather512::fill_levels(rule, t_s, widen, levels, g);
    #[cfg(target_arch = "x86_64")]
    if done == 0 && vector_kernels().is_some() {
        // SAFETY: the CPU has AVX2 (checked just now).
        done = unsafe { avx2::fill_levels(rule, t_s, widen, levels, g) };
    }
    series_levels(rule, &t_s[done..], &widen[done..], levels, g * w + done);
    for x in done..w {
        if crate::kernel::widening_needs_log(widen[x] * rule.inv_sigma2) {
            levels.set(g * w + x, rule.at(t_s[x], widen[x]));
        }
    }
}

/// [`fill_levels`]' series pass over pixels from group-major index `at`
/// on (the row's tail, or all of it on CPUs without AVX2).
fn series_levels(rule: LevelRule, t_s: &[f32], widen: &[f32], levels: &mut RowLevels, at: usize) {
    let r = at..at + t_s.len();
    let (a, wa, wb) = (
        &mut levels.a[r.clone()],
        &mut levels.wa[r.clone()],
        &mut levels.wb[r],
    );
    for x in 0..t_s.len() {
        (a[x], _, wa[x], wb[x]) = rule.series(t_s[x], widen[x]);
    }
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
    out: &mut [f32],
) -> usize {
    let w = cs.len();
    let n_levels = stack.levels.len();
    if !supports::<C>(stack)
        || ss.len() != w
        || levels.w != w
        || out.len() < w * C
        || terms.iter().any(|t| (t.group + 1) * w > levels.a.len())
        // the highest level any pixel reads
        || levels.last as usize >= n_levels
    {
        return 0;
    }
    if C == 1 {
        // sixteen lanes where the CPU has AVX-512F (one channel, bilinear);
        // the row's last `w % 16` pixels go to the caller's scalar loop
        let done = super::gather512::scaled_row(stack, terms, levels, y, cs, ss, out);
        if done > 0 {
            return done;
        }
    }
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: `supports` checked that the CPU has AVX2.
        unsafe { avx2::scaled_row::<C>(stack, terms, levels, y, cs, ss, out) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (terms, levels, y);
        0
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::{
        __m256, __m256i, _CMP_GE_OQ, _CMP_NEQ_OQ, _mm256_add_epi32, _mm256_add_ps, _mm256_and_ps,
        _mm256_and_si256, _mm256_andnot_si256, _mm256_castps_si256, _mm256_castsi256_ps,
        _mm256_castsi256_si128, _mm256_cmp_ps, _mm256_cmpeq_epi32, _mm256_cvtepi32_ps,
        _mm256_cvtsi256_si32, _mm256_cvttps_epi32, _mm256_extracti128_si256,
        _mm256_i32gather_epi64, _mm256_i32gather_ps, _mm256_loadu_ps, _mm256_loadu_si256,
        _mm256_max_epi32, _mm256_min_epi32, _mm256_movemask_epi8, _mm256_movemask_ps,
        _mm256_mul_ps, _mm256_mullo_epi32, _mm256_permute2x128_si256, _mm256_permutevar8x32_epi32,
        _mm256_set1_epi32, _mm256_set1_ps, _mm256_setr_epi32, _mm256_setr_ps, _mm256_setzero_ps,
        _mm256_setzero_si256, _mm256_shuffle_epi32, _mm256_storeu_ps, _mm256_sub_epi32,
        _mm256_sub_ps,
    };

    use std::arch::x86_64::{
        _CMP_GT_OQ, _CMP_LT_OQ, _mm256_andnot_ps, _mm256_div_ps, _mm256_max_ps, _mm256_min_epu32,
        _mm256_min_ps, _mm256_or_ps, _mm256_srai_epi32, _mm256_storeu_si256,
    };

    use super::{FixedTerm, LANES, LevelRule, RowLevels, ScalePosition, ScaledTerm};
    use crate::field::Field;
    use crate::kernel::{LOG_FROM, WIDENING_FLOOR};
    use crate::stack::{Interpolation, Level, ScaleStack};
    use std::arch::x86_64::{
        _MM_FROUND_NO_EXC, _MM_FROUND_TO_NEAREST_INT, _MM_FROUND_TO_NEG_INF, _mm256_blendv_ps,
        _mm256_cvtps_epi32, _mm256_round_ps, _mm256_slli_epi32, _mm256_xor_ps,
    };

    /// Eight floats into a vector.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn load(v: &[f32; LANES]) -> __m256 {
        // SAFETY: reads exactly the eight floats of `v`.
        unsafe { _mm256_loadu_ps(v.as_ptr()) }
    }

    /// A vector into eight floats.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn store(v: __m256) -> [f32; LANES] {
        let mut out = [0.0f32; LANES];
        // SAFETY: writes exactly the eight floats of `out`.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), v) };
        out
    }

    /// Eight consecutive floats of `s` from `at`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn load_at(s: &[f32], at: usize) -> __m256 {
        let v: &[f32; LANES] = s[at..at + LANES].try_into().expect("eight lanes");
        load(v)
    }

    /// Adds `w *` the lookups of level `li` at `(px, py)` to `acc` when
    /// every lane's stencil lies in the stored level (the scalar lookup's
    /// interior test, lane by lane); returns false, touching nothing,
    /// otherwise.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn lookup<const C: usize>(
        stack: &ScaleStack,
        li: usize,
        px: __m256,
        py: __m256,
        w: __m256,
        acc: &mut [__m256; C],
    ) -> bool {
        let level = &stack.levels[li];
        match stack.interpolation {
            Interpolation::Linear => bilinear::<C>(level, px, py, w, acc),
            Interpolation::Cubic => cubic::<C>(level, px, py, w, acc),
        }
    }

    /// The fractions `(fu, fv)` of the level coordinates `(u, v)` of
    /// `(px, py)` and their floors `(iu, iv)` when every lane's stencil,
    /// `before` samples before and `after` after the one below the point (0
    /// and 1 bilinear, 1 and 2 cubic), lies in the stored level: the scalar
    /// lookups' test `u >= before`, `v >= before`, `iu + after < nx`,
    /// `iv + after < ny`, lane by lane, as one unsigned compare per axis of
    /// `floor(u) - before` against `nx - 1 - after - before` (a negative
    /// floor wraps above it; NaN and values past `i32` convert to
    /// `i32::MIN`, which does too). Where it holds, `u >= 0` (or `-0`), so
    /// `u - floor(u)` is the scalar lookup's `u - trunc(u)` (at `u = -0` a
    /// zero of the other sign, which leaves every sum it enters unchanged).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn stencil_inside(
        level: &Level,
        px: __m256,
        py: __m256,
        before: i32,
        after: i32,
    ) -> Option<(__m256, __m256, __m256i, __m256i)> {
        let (nx, ny) = (level.layout.nx as i32, level.layout.ny as i32);
        let origin = _mm256_set1_ps(level.origin);
        let inv = _mm256_set1_ps(level.inv_step);
        let u = _mm256_mul_ps(_mm256_sub_ps(px, origin), inv);
        let v = _mm256_mul_ps(_mm256_sub_ps(py, origin), inv);
        let (fl_u, fl_v) = (
            _mm256_round_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(u),
            _mm256_round_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(v),
        );
        let (iu, iv) = (_mm256_cvtps_epi32(fl_u), _mm256_cvtps_epi32(fl_v));
        let within = |i: __m256i, n: i32| {
            let d = _mm256_sub_epi32(i, _mm256_set1_epi32(before));
            _mm256_cmpeq_epi32(
                _mm256_min_epu32(d, _mm256_set1_epi32(n - 1 - after - before)),
                d,
            )
        };
        let inside = _mm256_and_si256(within(iu, nx), within(iv, ny));
        (_mm256_movemask_epi8(inside) == -1)
            .then(|| (_mm256_sub_ps(u, fl_u), _mm256_sub_ps(v, fl_v), iu, iv))
    }

    /// The bilinear lookups of `level` (see [`lookup`]).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn bilinear<const C: usize>(
        level: &Level,
        px: __m256,
        py: __m256,
        w: __m256,
        acc: &mut [__m256; C],
    ) -> bool {
        let Some(at) = bilinear_stencil(level, px, py) else {
            return false;
        };
        bilinear_at::<C>(level, at, w, acc);
        true
    }

    /// Where a bilinear lookup of `level` at `(px, py)` reads, when every
    /// lane's stencil lies in the stored level: the fractions `(fu, fv)`
    /// and each lane's first sample (see [`lookup`]). Levels on the same
    /// grid share it.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn bilinear_stencil(
        level: &Level,
        px: __m256,
        py: __m256,
    ) -> Option<(__m256, __m256, __m256i)> {
        let (nx, ny) = (level.layout.nx as i32, level.layout.ny as i32);
        let (fu, fv, iu, iv) = stencil_inside(level, px, py, 0, 1)?;
        let idx = _mm256_add_epi32(_mm256_mullo_epi32(iv, _mm256_set1_epi32(nx)), iu);
        // Memory safety: every read of `bilinear_at` is at most `nx + 1`
        // samples (times C, plus C - 1) past `idx <= nx (ny - 1) - 2`, inside
        // the level's `nx ny C` samples (`supports` checked the length).
        let idx = _mm256_min_epi32(
            _mm256_max_epi32(idx, _mm256_setzero_si256()),
            _mm256_set1_epi32(nx * (ny - 1) - 2),
        );
        Some((fu, fv, idx))
    }

    /// Adds `w *` the bilinear lookups of `level` at `stencil` (from
    /// [`bilinear_stencil`] on this level's grid) to `acc`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn bilinear_at<const C: usize>(
        level: &Level,
        (fu, fv, idx): (__m256, __m256, __m256i),
        w: __m256,
        acc: &mut [__m256; C],
    ) {
        let nx = level.layout.nx as i32;
        let data = level.data.as_slice();
        let p = data.as_ptr();
        let row = nx as usize * C;
        if C == 1 {
            // (a, b) and (c, d) as pairs of neighbouring floats.
            // SAFETY: the pairs read at `idx` from `p` and `p + nx` end at
            // `idx + nx + 1 < nx ny = data.len()` (above).
            let ((a, b), (c, d)) = unsafe { (pairs(p, idx), pairs(p.add(nx as usize), idx)) };
            acc[0] = blend(acc[0], w, fu, fv, [a, b, c, d]);
            return;
        }
        let idx = _mm256_mullo_epi32(idx, _mm256_set1_epi32(C as i32));
        for (k, a) in acc.iter_mut().enumerate() {
            // SAFETY: the largest index read is `idx + row + C + k <=
            // nx ny C - 1` (above); the base pointers are inside `data`.
            let corners = unsafe {
                [
                    _mm256_i32gather_ps::<4>(p.add(k), idx),
                    _mm256_i32gather_ps::<4>(p.add(C + k), idx),
                    _mm256_i32gather_ps::<4>(p.add(row + k), idx),
                    _mm256_i32gather_ps::<4>(p.add(row + C + k), idx),
                ]
            };
            *a = blend(*a, w, fu, fv, corners);
        }
    }

    /// The cubic B-spline weights of the samples at `-1, 0, 1, 2` for
    /// fractions `t` in `[0, 1)`, as `bspline_weights` computes them.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn bspline(t: __m256) -> [__m256; 4] {
        let k = _mm256_set1_ps;
        let sixth = k(1.0 / 6.0);
        let t2 = _mm256_mul_ps(t, t);
        let t3 = _mm256_mul_ps(t2, t);
        let s = _mm256_sub_ps(k(1.0), t);
        [
            _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(s, s), s), sixth),
            _mm256_mul_ps(
                _mm256_add_ps(
                    _mm256_sub_ps(_mm256_mul_ps(k(3.0), t3), _mm256_mul_ps(k(6.0), t2)),
                    k(4.0),
                ),
                sixth,
            ),
            _mm256_mul_ps(
                _mm256_add_ps(
                    _mm256_add_ps(
                        _mm256_add_ps(_mm256_mul_ps(k(-3.0), t3), _mm256_mul_ps(k(3.0), t2)),
                        _mm256_mul_ps(k(3.0), t),
                    ),
                    k(1.0),
                ),
                sixth,
            ),
            _mm256_mul_ps(t3, sixth),
        ]
    }

    /// The floats at `idx` and `idx + 1` (per lane) from `p`, by two 64-bit
    /// gathers of four lanes each.
    ///
    /// # Safety
    /// Every `p + idx` and `p + idx + 1` must be inside one allocation.
    #[inline]
    #[target_feature(enable = "avx2")]
    #[expect(
        clippy::cast_ptr_alignment,
        reason = "gathers need no alignment; the pointer type is the intrinsic's signature"
    )]
    unsafe fn pairs(p: *const f32, idx: __m256i) -> (__m256, __m256) {
        let lo = _mm256_castsi256_si128(idx);
        let hi = _mm256_extracti128_si256::<1>(idx);
        // SAFETY: as the caller promises.
        let (l, h) = unsafe {
            (
                _mm256_i32gather_epi64::<4>(p.cast::<i64>(), lo),
                _mm256_i32gather_epi64::<4>(p.cast::<i64>(), hi),
            )
        };
        let split = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
        let (l, h) = (
            _mm256_permutevar8x32_epi32(l, split),
            _mm256_permutevar8x32_epi32(h, split),
        );
        (
            _mm256_castsi256_ps(_mm256_permute2x128_si256::<0x20>(l, h)),
            _mm256_castsi256_ps(_mm256_permute2x128_si256::<0x31>(l, h)),
        )
    }

    /// The cubic B-spline lookups of `level` (see [`lookup`]): 4x4
    /// coefficients around each lane's position, in the scalar lookup's
    /// order of operations.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn cubic<const C: usize>(
        level: &Level,
        px: __m256,
        py: __m256,
        w: __m256,
        acc: &mut [__m256; C],
    ) -> bool {
        let (nx, ny) = (level.layout.nx as i32, level.layout.ny as i32);
        let Some((fu, fv, iu, iv)) = stencil_inside(level, px, py, 1, 2) else {
            return false;
        };
        let (wx, wy) = (bspline(fu), bspline(fv));
        // Sample (iu - 1, iv - 1) of each lane. Memory safety: every read
        // below is at most `3 nx + 3` samples (times C, plus C - 1) past
        // `base <= nx ny - 3 nx - 4`, inside the level's `nx ny C` samples.
        let base = _mm256_add_epi32(
            _mm256_mullo_epi32(
                _mm256_sub_epi32(iv, _mm256_set1_epi32(1)),
                _mm256_set1_epi32(nx),
            ),
            _mm256_sub_epi32(iu, _mm256_set1_epi32(1)),
        );
        let base = _mm256_min_epi32(
            _mm256_max_epi32(base, _mm256_setzero_si256()),
            _mm256_set1_epi32(nx * ny - 3 * nx - 4),
        );
        let p = level.data.as_ptr();
        let row = nx as usize * C;
        let dot = |r: [__m256; 4]| {
            _mm256_add_ps(
                _mm256_add_ps(
                    _mm256_add_ps(_mm256_mul_ps(wx[0], r[0]), _mm256_mul_ps(wx[1], r[1])),
                    _mm256_mul_ps(wx[2], r[2]),
                ),
                _mm256_mul_ps(wx[3], r[3]),
            )
        };
        if C == 1 {
            let mut sum = _mm256_setzero_ps();
            for (j, wyj) in wy.iter().enumerate() {
                // SAFETY: `p + j nx` is inside the level (j <= 3 < ny) and
                // every pair read is within the bound above.
                let (r0, r1, r2, r3) = unsafe {
                    let q = p.add(j * row);
                    let (r0, r1) = pairs(q, base);
                    let (r2, r3) = pairs(q.add(2), base);
                    (r0, r1, r2, r3)
                };
                sum = _mm256_add_ps(sum, _mm256_mul_ps(*wyj, dot([r0, r1, r2, r3])));
            }
            acc[0] = _mm256_add_ps(acc[0], _mm256_mul_ps(w, sum));
            return true;
        }
        let base = _mm256_mullo_epi32(base, _mm256_set1_epi32(C as i32));
        for (j, wyj) in wy.iter().enumerate() {
            let wj = _mm256_mul_ps(w, *wyj);
            for (k, a) in acc.iter_mut().enumerate() {
                // SAFETY: the largest index read is `base + 3 row + 3 C + k
                // <= nx ny C - 1` (above); the base pointer is inside `data`.
                let r = unsafe {
                    let q = p.add(j * row + k);
                    [
                        _mm256_i32gather_ps::<4>(q, base),
                        _mm256_i32gather_ps::<4>(q.add(C), base),
                        _mm256_i32gather_ps::<4>(q.add(2 * C), base),
                        _mm256_i32gather_ps::<4>(q.add(3 * C), base),
                    ]
                };
                *a = _mm256_add_ps(*a, _mm256_mul_ps(wj, dot(r)));
            }
        }
        true
    }

    /// `acc + w * bilinear(corners)`, in the scalar lookup's order of
    /// operations.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn blend(acc: __m256, w: __m256, fu: __m256, fv: __m256, [a, b, c, d]: [__m256; 4]) -> __m256 {
        let r0 = _mm256_add_ps(a, _mm256_mul_ps(fu, _mm256_sub_ps(b, a)));
        let r1 = _mm256_add_ps(c, _mm256_mul_ps(fu, _mm256_sub_ps(d, c)));
        let value = _mm256_add_ps(r0, _mm256_mul_ps(fv, _mm256_sub_ps(r1, r0)));
        _mm256_add_ps(acc, _mm256_mul_ps(w, value))
    }

    /// The eight lanes' accumulators as arrays, lane-major.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn spill<const C: usize>(acc: &[__m256; C]) -> [[f32; C]; LANES] {
        let mut lanes = [[0.0f32; C]; LANES];
        for (k, v) in acc.iter().enumerate() {
            for (lane, x) in store(*v).into_iter().enumerate() {
                lanes[lane][k] = x;
            }
        }
        lanes
    }

    /// The inverse of [`spill`].
    #[inline]
    #[target_feature(enable = "avx2")]
    fn fill<const C: usize>(lanes: &[[f32; C]; LANES], acc: &mut [__m256; C]) {
        for (k, v) in acc.iter_mut().enumerate() {
            *v = load(&std::array::from_fn(|lane| lanes[lane][k]));
        }
    }

    /// One lookup per lane through the scalar, border-resolving path, in
    /// lane order (each lane's sum in the same order as the scalar loop's);
    /// `acc` by value, so that callers keep their sums in registers.
    #[inline(never)]
    #[target_feature(enable = "avx2")]
    fn scalar_lanes<const C: usize>(
        stack: &ScaleStack,
        lookups: &[(usize, f32); LANES],
        px: __m256,
        py: __m256,
        mut acc: [__m256; C],
    ) -> [__m256; C] {
        let (px, py) = (store(px), store(py));
        let mut lanes = spill(&acc);
        for (lane, sum) in lanes.iter_mut().enumerate() {
            let (li, w) = lookups[lane];
            if w != 0.0 {
                stack.accumulate_fixed::<C>(li, px[lane], py[lane], w, sum);
            }
        }
        fill(&lanes, &mut acc);
        acc
    }

    /// Adds the block's sums into `out` (pixels `x0..x0 + 8`, interleaved).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn add_out<const C: usize>(acc: &[__m256; C], out: &mut [f32], x0: usize) {
        let lanes = spill(acc);
        let dst = &mut out[x0 * C..(x0 + LANES) * C];
        for (px, sum) in dst.chunks_exact_mut(C).zip(&lanes) {
            for (o, v) in px.iter_mut().zip(sum) {
                *o += v;
            }
        }
    }

    /// The block's positions for displacement `(cx, cy)`: `x + cs cx + ss
    /// cy`, `y - ss cx + cs cy`, in the scalar loop's order.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn positions(
        xf: __m256,
        yf: __m256,
        c: __m256,
        s: __m256,
        cx: f32,
        cy: f32,
    ) -> (__m256, __m256) {
        let (cx, cy) = (_mm256_set1_ps(cx), _mm256_set1_ps(cy));
        let px = _mm256_add_ps(
            _mm256_add_ps(xf, _mm256_mul_ps(c, cx)),
            _mm256_mul_ps(s, cy),
        );
        let py = _mm256_add_ps(
            _mm256_sub_ps(yf, _mm256_mul_ps(s, cx)),
            _mm256_mul_ps(c, cy),
        );
        (px, py)
    }

    /// Pixel coordinates `x0 .. x0 + 7` (exact below 2^24).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn columns(x0: usize) -> __m256 {
        _mm256_add_ps(
            _mm256_set1_ps(x0 as f32),
            _mm256_setr_ps(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0),
        )
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn rotated_row<const C: usize>(
        stack: &ScaleStack,
        terms: &[FixedTerm],
        y: usize,
        cs: &[f32],
        ss: &[f32],
        out: &mut [f32],
    ) -> usize {
        let n = cs.len() / LANES * LANES;
        let yf = _mm256_set1_ps(y as f32);
        for x0 in (0..n).step_by(LANES) {
            let xf = columns(x0);
            let (c, s) = (load_at(cs, x0), load_at(ss, x0));
            let mut acc = [_mm256_setzero_ps(); C];
            for t in terms {
                let (px, py) = positions(xf, yf, c, s, t.cx, t.cy);
                for (li, w) in [(t.a, t.wa), (t.b, t.wb)] {
                    if w == 0.0 {
                        continue;
                    }
                    if !lookup::<C>(stack, li, px, py, _mm256_set1_ps(w), &mut acc) {
                        acc = scalar_lanes::<C>(stack, &[(li, w); LANES], px, py, acc);
                    }
                }
            }
            add_out::<C>(&acc, out, x0);
        }
        n
    }

    /// The most levels one block's vector lookups span (a lookup each);
    /// blocks whose lanes spread wider go lane by lane.
    const SPAN: usize = 4;

    /// One sigma group's levels over a block of eight pixels.
    #[derive(Clone, Copy)]
    enum Block {
        /// Every lane on levels `a .. a + SPAN`: per level, each lane's
        /// weight on it (zero where the lane does not read it), `used`
        /// marking the levels some lane reads. A lane reads its two levels
        /// in the scalar loop's order, lower first, so its sum is the
        /// scalar loop's.
        Vector {
            a: usize,
            used: u8,
            w: [__m256; SPAN],
        },
        /// Lanes spread over more levels: each lane looks up its own.
        Lanes,
    }

    /// [`super::rotations`] for the row's first `w / 8 * 8` pixels: the
    /// count done.
    #[target_feature(enable = "avx2")]
    pub(super) fn rotations(
        theta: &[f32],
        scale: Field<'_>,
        cs: &mut [f32],
        ss: &mut [f32],
    ) -> usize {
        use crate::trig::{COS, INV_RIGHT_ANGLE, RADIANS_PER_DEGREE, SIN};
        let k = _mm256_set1_ps;
        let n = theta.len() / LANES * LANES;
        let (one, two) = (_mm256_set1_epi32(1), _mm256_set1_epi32(2));
        for x0 in (0..n).step_by(LANES) {
            let t = load_at(theta, x0);
            // trig::sin_cos_degrees, operation by operation
            let q = _mm256_round_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(
                _mm256_mul_ps(t, k(INV_RIGHT_ANGLE)),
            );
            let x = _mm256_mul_ps(
                _mm256_sub_ps(t, _mm256_mul_ps(q, k(90.0))),
                k(RADIANS_PER_DEGREE),
            );
            let x2 = _mm256_mul_ps(x, x);
            let horner = |coef: &[f32]| {
                let (last, rest) = coef.split_last().expect("coefficients");
                rest.iter().rev().fold(k(*last), |acc, &c| {
                    _mm256_add_ps(k(c), _mm256_mul_ps(x2, acc))
                })
            };
            let sp = _mm256_add_ps(x, _mm256_mul_ps(_mm256_mul_ps(x, x2), horner(&SIN)));
            let cp = _mm256_add_ps(k(1.0), _mm256_mul_ps(x2, horner(&COS)));
            let qi = _mm256_cvtps_epi32(q);
            let swap = _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(qi, one), one));
            let (s, c) = (
                _mm256_blendv_ps(sp, cp, swap),
                _mm256_blendv_ps(cp, sp, swap),
            );
            // bit 1 of q (of q + 1) moved to the sign bit negates the sine (cosine)
            let s_sign = _mm256_slli_epi32::<30>(_mm256_and_si256(qi, two));
            let c_sign = _mm256_slli_epi32::<30>(_mm256_and_si256(_mm256_add_epi32(qi, one), two));
            let s = _mm256_xor_ps(s, _mm256_castsi256_ps(s_sign));
            let c = _mm256_xor_ps(c, _mm256_castsi256_ps(c_sign));
            let sc = match scale {
                Field::Constant(v) => k(v),
                Field::Map(m) => load_at(m, x0),
            };
            let (cv, sv) = (store(_mm256_mul_ps(c, sc)), store(_mm256_mul_ps(s, sc)));
            cs[x0..x0 + LANES].copy_from_slice(&cv);
            ss[x0..x0 + LANES].copy_from_slice(&sv);
        }
        n
    }

    /// [`super::scale_positions`] for the row's first `w / 8 * 8` pixels:
    /// [`ScalePosition::at`] operation by operation ([`crate::ln::ln`]'s
    /// split of the bits and its series, then the widening's division and
    /// select), so the same bits; the count done.
    #[target_feature(enable = "avx2")]
    pub(super) fn scale_positions(
        rule: ScalePosition,
        scales: &[f32],
        t_s: &mut [f32],
        widen: &mut [f32],
    ) -> usize {
        use crate::ln::{ATANH, LN2_HI, LN2_LO, SQRT_HALF_BITS};
        let k = _mm256_set1_ps;
        let n = scales.len() / LANES * LANES;
        let sqrt_half = _mm256_set1_epi32(SQRT_HALF_BITS as i32);
        let mantissa = _mm256_set1_epi32(0x007f_ffff);
        for x0 in (0..n).step_by(LANES) {
            let s = load_at(scales, x0);
            // ln::ln
            let ix = _mm256_sub_epi32(
                _mm256_castps_si256(_mm256_max_ps(s, k(f32::MIN_POSITIVE))),
                sqrt_half,
            );
            let e = _mm256_cvtepi32_ps(_mm256_srai_epi32::<23>(ix));
            let m =
                _mm256_castsi256_ps(_mm256_add_epi32(_mm256_and_si256(ix, mantissa), sqrt_half));
            let f = _mm256_div_ps(_mm256_sub_ps(m, k(1.0)), _mm256_add_ps(m, k(1.0)));
            let z = _mm256_mul_ps(f, f);
            let r = _mm256_add_ps(f, f);
            let (top, rest) = ATANH.split_last().expect("coefficients");
            let poly = rest.iter().rev().fold(k(*top), |acc, &c| {
                _mm256_add_ps(k(c), _mm256_mul_ps(z, acc))
            });
            let p = _mm256_add_ps(r, _mm256_mul_ps(_mm256_mul_ps(r, z), poly));
            let ln = _mm256_add_ps(
                _mm256_mul_ps(e, k(LN2_HI)),
                _mm256_add_ps(p, _mm256_mul_ps(e, k(LN2_LO))),
            );
            // ScalePosition::at
            let ts = _mm256_mul_ps(_mm256_sub_ps(ln, k(rule.ln0)), k(rule.inv));
            let wd = _mm256_add_ps(
                _mm256_div_ps(k(rule.var), _mm256_mul_ps(s, s)),
                k(rule.shift),
            );
            let wd = _mm256_and_ps(wd, _mm256_cmp_ps::<_CMP_LT_OQ>(s, k(rule.below)));
            t_s[x0..x0 + LANES].copy_from_slice(&store(ts));
            widen[x0..x0 + LANES].copy_from_slice(&store(wd));
        }
        n
    }

    /// [`super::fill_levels`] for the row's first `w / 8 * 8` pixels: the
    /// series pass in AVX2 lanes, [`LevelRule::series`]'s operations in its
    /// order (separate multiplies and adds, as the scalar code rounds
    /// them), so the same bits, then [`LevelRule::at`] for the lanes whose
    /// widening needs the logarithm; the count done.
    #[target_feature(enable = "avx2")]
    pub(super) fn fill_levels(
        rule: LevelRule,
        t_s: &[f32],
        widen: &[f32],
        levels: &mut RowLevels,
        g: usize,
    ) -> usize {
        let k = _mm256_set1_ps;
        let w = levels.w;
        let base = g * w;
        let n = w / LANES * LANES;
        let (floor, needs_log, sign) = (k(WIDENING_FLOOR), k(LOG_FROM), k(-0.0));
        let (one, half, third, quarter) = (k(1.0), k(0.5), k(1.0 / 3.0), k(0.25));
        let (inv_sigma2, ln_sigma, inv) = (k(rule.inv_sigma2), k(rule.ln_sigma), k(rule.inv));
        let last = k(rule.last as f32);
        let below_last = _mm256_set1_epi32((rule.last - 1) as i32);
        let (snap_lo, snap_hi) = (k(rule.snap), k(1.0 - rule.snap));
        for x0 in (0..n).step_by(LANES) {
            let (ts, wd) = (load_at(t_s, x0), load_at(widen, x0));
            // kernel::ln_widening_series
            let x = _mm256_max_ps(_mm256_mul_ps(wd, inv_sigma2), floor);
            // kernel::widening_needs_log: |x| >= LOG_FROM
            let log_lanes = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(
                _mm256_andnot_ps(sign, x),
                needs_log,
            ));
            let x2 = _mm256_mul_ps(x, x);
            let odd = _mm256_mul_ps(x, _mm256_add_ps(one, _mm256_mul_ps(x2, third)));
            let even = _mm256_mul_ps(x2, _mm256_add_ps(half, _mm256_mul_ps(x2, quarter)));
            let lw = _mm256_mul_ps(half, _mm256_sub_ps(odd, even));
            // LevelRule::bracket: the position, clamped (finite positions:
            // max/min are `clamp`), its level below, snapped
            let u = _mm256_add_ps(ts, _mm256_mul_ps(_mm256_add_ps(ln_sigma, lw), inv));
            let u = _mm256_min_ps(_mm256_max_ps(u, _mm256_setzero_ps()), last);
            let i = _mm256_min_epi32(_mm256_cvttps_epi32(u), below_last);
            let f = _mm256_sub_ps(u, _mm256_cvtepi32_ps(i));
            let hi = _mm256_cmp_ps::<_CMP_GT_OQ>(f, snap_hi);
            let snapped = _mm256_or_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(f, snap_lo), hi);
            // a = i + 1 where `hi` is set (an all-ones lane is -1)
            let a = _mm256_sub_epi32(i, _mm256_castps_si256(hi));
            let wa = _mm256_blendv_ps(_mm256_sub_ps(one, f), one, snapped);
            let wb = _mm256_blendv_ps(f, _mm256_setzero_ps(), snapped);
            let at = base + x0;
            let da: &mut [u32; LANES] = (&mut levels.a[at..at + LANES])
                .try_into()
                .expect("eight lanes");
            // SAFETY: writes exactly the eight integers of `da`.
            unsafe { _mm256_storeu_si256(da.as_mut_ptr().cast(), a) };
            levels.wa[at..at + LANES].copy_from_slice(&store(wa));
            levels.wb[at..at + LANES].copy_from_slice(&store(wb));
            if log_lanes != 0 {
                for x in (x0..x0 + LANES).filter(|x| log_lanes & (1 << (x - x0)) != 0) {
                    levels.set(base + x, rule.at(t_s[x], widen[x]));
                }
            }
        }
        n
    }

    /// The least and the largest of eight lanes.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn min_max(lo: __m256i, hi: __m256i) -> (i32, i32) {
        let (mut lo, mut hi) = (
            _mm256_min_epi32(lo, _mm256_permute2x128_si256::<1>(lo, lo)),
            _mm256_max_epi32(hi, _mm256_permute2x128_si256::<1>(hi, hi)),
        );
        lo = _mm256_min_epi32(lo, _mm256_shuffle_epi32::<0b0100_1110>(lo));
        hi = _mm256_max_epi32(hi, _mm256_shuffle_epi32::<0b0100_1110>(hi));
        lo = _mm256_min_epi32(lo, _mm256_shuffle_epi32::<0b1011_0001>(lo));
        hi = _mm256_max_epi32(hi, _mm256_shuffle_epi32::<0b1011_0001>(hi));
        (_mm256_cvtsi256_si32(lo), _mm256_cvtsi256_si32(hi))
    }

    /// The block of eight lanes from pixel `x0` of group `g`: each lane
    /// reads level `a` (weight `wa`) and, where `wb != 0`, `a + 1` (`wb`).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn classify(levels: &RowLevels, g: usize, x0: usize) -> Block {
        let i = g * levels.w + x0;
        let a: &[u32; LANES] = levels.a[i..i + LANES].try_into().expect("eight lanes");
        // SAFETY: reads exactly the eight integers of `a`.
        let la = unsafe { _mm256_loadu_si256(a.as_ptr().cast()) };
        let (wa, wb) = (load_at(&levels.wa, i), load_at(&levels.wb, i));
        // a + 1 where the lane reads a second level (the mask is -1 there)
        let second_ps = _mm256_cmp_ps::<_CMP_NEQ_OQ>(wb, _mm256_setzero_ps());
        let second = _mm256_castps_si256(second_ps);
        if _mm256_movemask_epi8(_mm256_cmpeq_epi32(
            la,
            _mm256_permutevar8x32_epi32(la, _mm256_setzero_si256()),
        )) == -1
        {
            // The common block: every lane on the same level `a` (and
            // `a + 1` where its `wb` is not zero): the general rule below
            // gives level `a` the weights `wa` and level `a + 1` the `wb`
            // of the lanes that read it, zero elsewhere; the same values.
            let used = u8::from(
                _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_NEQ_OQ>(wa, _mm256_setzero_ps())) != 0,
            ) | (u8::from(_mm256_movemask_ps(second_ps) != 0) << 1);
            let mut w = [_mm256_setzero_ps(); SPAN];
            w[0] = wa;
            w[1] = _mm256_and_ps(second_ps, wb);
            return Block::Vector {
                a: a[0] as usize,
                used,
                w,
            };
        }
        let lb = _mm256_sub_epi32(la, second);
        let (lo, hi) = min_max(la, lb);
        let n = (hi - lo) as usize + 1;
        if n > SPAN {
            return Block::Lanes;
        }
        // level lo + k: each lane's weight on it (wa where a is it, wb
        // where a + 1 is; a lane without a second level adds wb = 0)
        let mut w = [_mm256_setzero_ps(); SPAN];
        let mut used = 0u8;
        for (k, wk) in w.iter_mut().enumerate().take(n) {
            let level = _mm256_set1_epi32(lo + k as i32);
            let on_a = _mm256_castsi256_ps(_mm256_cmpeq_epi32(la, level));
            let on_b = _mm256_castsi256_ps(_mm256_andnot_si256(
                _mm256_cmpeq_epi32(la, lb),
                _mm256_cmpeq_epi32(lb, level),
            ));
            *wk = _mm256_add_ps(_mm256_and_ps(on_a, wa), _mm256_and_ps(on_b, wb));
            let nonzero = _mm256_cmp_ps::<_CMP_NEQ_OQ>(*wk, _mm256_setzero_ps());
            used |= u8::from(_mm256_movemask_ps(nonzero) != 0) << k;
        }
        Block::Vector {
            a: lo as usize,
            used,
            w,
        }
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn scaled_row<const C: usize>(
        stack: &ScaleStack,
        terms: &[ScaledTerm],
        levels: &RowLevels,
        y: usize,
        cs: &[f32],
        ss: &[f32],
        out: &mut [f32],
    ) -> usize {
        let w = cs.len();
        let n = w / LANES * LANES;
        let groups = levels.a.len() / w.max(1);
        let yf = _mm256_set1_ps(y as f32);
        let mut blocks = vec![Block::Lanes; groups];
        let linear = matches!(stack.interpolation, Interpolation::Linear);
        // level i and level i + 1 sample the same grid: one bilinear
        // stencil serves both (the same values as computing it twice)
        let same_grid: Vec<bool> = stack
            .levels
            .windows(2)
            .map(|p| {
                let grid = |l: &Level| (l.layout.step, l.layout.origin, l.layout.nx, l.layout.ny);
                grid(&p[0]) == grid(&p[1])
            })
            .collect();
        for x0 in (0..n).step_by(LANES) {
            for (g, b) in blocks.iter_mut().enumerate() {
                *b = classify(levels, g, x0);
            }
            let xf = columns(x0);
            let (c, s) = (load_at(cs, x0), load_at(ss, x0));
            let mut acc = [_mm256_setzero_ps(); C];
            for t in terms {
                let (px, py) = positions(xf, yf, c, s, t.cx, t.cy);
                match &blocks[t.group] {
                    Block::Vector { a, used, w } => {
                        let tw = _mm256_set1_ps(t.weight);
                        if *used == 0b11
                            && linear
                            && same_grid[*a]
                            && let Some(at) = bilinear_stencil(&stack.levels[*a], px, py)
                        {
                            // The common pair: levels a and a + 1 on one
                            // grid share the bilinear stencil (the same
                            // values as computing it for each); a stencil
                            // past the stored level goes through the loop
                            // below, lane by lane.
                            let wv = [_mm256_mul_ps(tw, w[0]), _mm256_mul_ps(tw, w[1])];
                            bilinear_at::<C>(&stack.levels[*a], at, wv[0], &mut acc);
                            bilinear_at::<C>(&stack.levels[a + 1], at, wv[1], &mut acc);
                            continue;
                        }
                        for (k, lw) in w.iter().enumerate() {
                            if used & (1 << k) == 0 {
                                continue;
                            }
                            let li = a + k;
                            let wv = _mm256_mul_ps(tw, *lw);
                            if !lookup::<C>(stack, li, px, py, wv, &mut acc) {
                                let ws = store(wv);
                                let l = std::array::from_fn(|lane| (li, ws[lane]));
                                acc = scalar_lanes::<C>(stack, &l, px, py, acc);
                            }
                        }
                    }
                    Block::Lanes => {
                        // Each lane's two lookups in the scalar order.
                        let (pxs, pys) = (store(px), store(py));
                        let mut lanes = spill(&acc);
                        for (lane, sum) in lanes.iter_mut().enumerate() {
                            let (a, b, wa, wb) = levels.at(t.group, x0 + lane);
                            let (px, py) = (pxs[lane], pys[lane]);
                            stack.accumulate_fixed::<C>(a, px, py, t.weight * wa, sum);
                            if wb != 0.0 {
                                stack.accumulate_fixed::<C>(b, px, py, t.weight * wb, sum);
                            }
                        }
                        fill(&lanes, &mut acc);
                    }
                }
            }
            add_out::<C>(&acc, out, x0);
        }
        n
    }
}

#[cfg(test)]
mod tests {
    use super::{
        LevelRule, RowLevels, ScalePosition, avx2_for_tests, fill_levels, rotations,
        scale_positions, series_levels,
    };
    use crate::Sampling;
    use crate::field::Field;
    use crate::stack::locate::{NEAREST_SNAP, PIXEL_SNAP};
    use crate::trig::sin_cos_degrees;

    /// The row rotations (AVX2 lanes where the CPU has them) bit for bit
    /// the scalar loop's: every quadrant and its boundaries, negative and
    /// large angles, a map's scales and a constant, a row whose length is
    /// not a multiple of the lanes.
    #[test]
    fn row_rotations_equal_the_scalar_rule() {
        let mut theta = vec![
            0.0, 45.0, -45.0, 90.0, 135.0, 180.0, 270.0, -90.0, 1e6, -999_999.9,
        ];
        theta.extend([
            44.999_996, 45.000_004, 134.999_99, 0.001, -0.001, 359.9, 720.5,
        ]);
        let mut state = 0x9e37_79b9_u64;
        while theta.len() < 67 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            theta.push(((state >> 11) as f64 / (1u64 << 53) as f64 * 1440.0 - 720.0) as f32);
        }
        let w = theta.len();
        let scales: Vec<f32> = (0..w).map(|x| 0.25 + x as f32 * 0.031).collect();
        // the dispatched rows (AVX-512 where the CPU has it), then the
        // eight AVX2 lanes alone (their pixels)
        for (scale, avx2) in [Field::Map(&scales), Field::Constant(0.7)]
            .into_iter()
            .flat_map(|s| [(s, false), (s, true)])
        {
            let (mut cs, mut ss) = (vec![0.0; w], vec![0.0; w]);
            let n = if avx2 {
                avx2_for_tests::rotations(&theta, scale, &mut cs, &mut ss)
            } else {
                rotations(&theta, scale, &mut cs, &mut ss);
                w
            };
            for x in 0..n {
                let (sin, cos) = sin_cos_degrees(theta[x]);
                let s = scale.at(x);
                assert_eq!(
                    (cs[x].to_bits(), ss[x].to_bits()),
                    ((cos * s).to_bits(), (sin * s).to_bits()),
                    "pixel {x}, angle {}",
                    theta[x]
                );
            }
        }
    }

    /// Every pixel's `(t_s, widen)` from the vector rows (AVX2 where the
    /// CPU has it) bit for bit [`ScalePosition::at`]'s, for every sampling:
    /// scales across octaves, on both sides of 1, powers of two, tiny and
    /// huge ones, a row whose length is not a multiple of the lanes.
    #[test]
    fn row_scale_positions_equal_the_rule_pixel_by_pixel() {
        let mut scales = vec![
            1.0,
            0.5,
            2.0,
            0.999_999_9,
            1.000_000_1,
            std::f32::consts::FRAC_1_SQRT_2,
            std::f32::consts::SQRT_2,
            1e-30,
            3e30,
        ];
        let mut state = 0x7f4a_7c15_u64;
        while scales.len() < 75 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            scales.push((0.25 * 16f64.powf(u)) as f32);
        }
        let w = scales.len();
        for sampling in [
            Sampling::Continuous,
            Sampling::Point,
            Sampling::Area,
            Sampling::Averaged,
        ] {
            let rule = ScalePosition::new(sampling, (1.5f64.ln(), 1.0 / 2f64.sqrt().ln()));
            let (mut t_s, mut widen) = (vec![0.0; w], vec![0.0; w]);
            scale_positions(rule, &scales, &mut t_s, &mut widen);
            // the AVX2 lanes alone (their pixels) after the dispatched rows
            let (mut t_2, mut widen_2) = (vec![0.0; w], vec![0.0; w]);
            let n = avx2_for_tests::scale_positions(rule, &scales, &mut t_2, &mut widen_2);
            for x in 0..n {
                assert_eq!(
                    (t_2[x].to_bits(), widen_2[x].to_bits()),
                    (t_s[x].to_bits(), widen[x].to_bits()),
                    "{sampling:?}, pixel {x}: AVX2 lanes"
                );
            }
            for x in 0..w {
                let (want_t, want_w) = rule.at(scales[x]);
                assert_eq!(
                    (t_s[x].to_bits(), widen[x].to_bits()),
                    (want_t.to_bits(), want_w.to_bits()),
                    "{sampling:?}, pixel {x}: scale {}",
                    scales[x]
                );
            }
        }
    }

    /// [`ScalePosition`] against the `f64` formulas it stands for: `t_s`
    /// within a few `f32` units, `widen` within `f32` rounding.
    #[test]
    fn scale_positions_match_the_f64_formulas() {
        let (ln0, inv) = (1.5f64.ln(), 1.0 / 2f64.sqrt().ln());
        for sampling in [Sampling::Point, Sampling::Area, Sampling::Averaged] {
            let rule = ScalePosition::new(sampling, (ln0, inv));
            for i in 0..=2000 {
                let s = 0.25 + i as f32 * 0.002;
                let (t_s, widen) = rule.at(s);
                let s64 = f64::from(s);
                let want_t = (s64.ln() - ln0) * inv;
                let want_w = sampling.footprint_variance(s64) / (s64 * s64);
                assert!(
                    (f64::from(t_s) - want_t).abs() < 2e-6,
                    "{sampling:?} {s}: t_s"
                );
                assert!(
                    (f64::from(widen) - want_w).abs() < 1e-6 * want_w.abs().max(0.1),
                    "{sampling:?} {s}: widen {widen} vs {want_w}"
                );
            }
        }
    }

    /// Every pixel's levels and weights, from the vector rows (AVX2 where
    /// the CPU has it) and from the baseline series pass, bit for bit
    /// [`LevelRule::at`]'s: positions below the first level and past the
    /// last (clamped), on levels and within the snap of them, widenings that
    /// take the series and the logarithm, rows whose length is not a multiple
    /// of the lanes; blending levels and reading the nearest one (where only
    /// a position half-way between two reads both).
    #[test]
    fn row_levels_equal_the_rule_pixel_by_pixel() {
        for snap in [PIXEL_SNAP, NEAREST_SNAP as f32] {
            row_levels_with_snap(snap);
        }
    }

    fn row_levels_with_snap(snap: f32) {
        let rule = LevelRule {
            ln_sigma: 1.3_f32.ln(),
            inv_sigma2: 1.0 / (1.3 * 1.3),
            inv: 1.0 / 2f32.sqrt().ln(),
            last: 6,
            snap,
        };
        let on_level = |k: f32| k - rule.ln_sigma * rule.inv;
        let mut t_s = vec![-3.0, -0.7, 9.0, 40.0, on_level(2.0), on_level(3.0) + 2e-5];
        t_s.extend([on_level(3.0) - 2e-5, on_level(4.0) + 6e-5, on_level(0.0)]);
        // just outside the snap, either side of a level
        t_s.extend([
            on_level(3.0) - 4.5e-5,
            on_level(5.0) + 4.5e-5,
            on_level(1.0) + 1.5e-5,
        ]);
        // half-way between levels, and either side of it
        t_s.extend([
            on_level(2.5),
            on_level(2.5) + 2e-6,
            on_level(2.5) - 2e-6,
            on_level(4.5),
        ]);
        let mut state = 0x2545_f491_u64;
        while t_s.len() < 67 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            t_s.push(((state >> 11) as f64 / (1u64 << 53) as f64 * 8.0 - 1.0) as f32);
        }
        let w = t_s.len();
        // no widening for the positions placed above, then each kind
        let widen: Vec<f32> = (0..w)
            .map(|x| match x % 5 {
                _ if x < 16 => 0.0,
                0 => 0.0,
                1 => 1.0 / 12.0,
                2 => 0.02,
                3 => 0.5,    // needs the logarithm
                _ => -0.999, // past the floor
            })
            .collect();
        let (mut snapped, mut read) = (0, 0);
        // fill_levels (sixteen lanes where the CPU has AVX-512), the series
        // pass alone, and the eight AVX2 lanes whatever wider ones the CPU
        // has (then the series pass for the row's tail)
        for pass in 0..3 {
            let mut levels = RowLevels::new(2, w);
            let mut series_from = 0;
            match pass {
                0 => fill_levels(rule, &t_s, &widen, &mut levels, 1),
                1 => series_levels(rule, &t_s, &widen, &mut levels, w),
                _ => {
                    series_from = avx2_for_tests::fill_levels(rule, &t_s, &widen, &mut levels, 1);
                    let tail = series_from..w;
                    series_levels(
                        rule,
                        &t_s[tail.clone()],
                        &widen[tail],
                        &mut levels,
                        w + series_from,
                    );
                }
            }
            for x in 0..w {
                let (a, b, wa, wb) = rule.at(t_s[x], widen[x]);
                if pass > 0
                    && x >= series_from
                    && crate::kernel::widening_needs_log(widen[x] * rule.inv_sigma2)
                {
                    continue; // the series pass leaves these to fill_levels
                }
                snapped += usize::from(wb == 0.0);
                read += 1;
                // read at the nearest level, only a position exactly
                // half-way between two reads both
                assert!(snap < 0.5 || wb == 0.0 || (wa, wb) == (0.5, 0.5));
                let got = levels.at(1, x);
                assert_eq!(
                    (got.0, got.1, got.2.to_bits(), got.3.to_bits()),
                    (a as usize, b as usize, wa.to_bits(), wb.to_bits()),
                    "pass {pass}, pixel {x}: t_s {}, widen {}",
                    t_s[x],
                    widen[x]
                );
            }
            // group 0 untouched
            assert!(levels.at(0, 0) == (0, 0, 0.0, 0.0));
        }
        // the on-level and clamped positions snap (the case is not
        // vacuous); read at the nearest level, all but those half-way
        assert!(snapped >= 6, "{snapped}");
        assert!(snap < 0.5 || snapped + 2 * 3 >= read, "{snapped} of {read}");
    }
}
