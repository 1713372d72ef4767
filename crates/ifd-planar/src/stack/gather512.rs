//! The commonest per-pixel cases, a per-pixel angle (at a constant scale or
//! with a scale map) on a one-channel stack read bilinearly, sixteen pixels
//! at a time with AVX-512 gathers, on CPUs that have AVX-512F (detected at
//! run time; `IFD_SIMD=avx2` or `IFD_SIMD=baseline` leaves them to the
//! eight-lane AVX2 kernels of [`super::gather`], which `IFD_SIMD` does not
//! switch off).
//!
//! Twice the lanes halve the position, stencil and blend arithmetic per
//! pixel, which is most of a lookup's instructions once the loads are
//! gathered; the loads are the AVX2 rows' too, each stencil row's two
//! neighbouring floats as one 64-bit element (two 64-bit gathers of eight
//! lanes per row: half the loads of four 32-bit gathers, which ran the
//! angle case 1.5 times slower). A scale map's rows classify each sigma
//! group's sixteen lanes as the AVX2 rows classify eight (one level, a
//! blended pair sharing one stencil on one grid, up to four levels with
//! per-lane weights, else lane by lane). The rows' per-pixel rules (the
//! rotations, a scale map's level positions and each sigma group's levels
//! and weights) run sixteen lanes wide too. The kernels write [`super::gather`]'s expressions in its order
//! with separate multiplies and adds (the stencil's inside test is the same
//! unsigned compare of the floors, the fractions the same `u - floor(u)`),
//! and hands a block with a lane outside the stored level to the scalar,
//! border-resolving lookup lane by lane, so its output is the scalar loop's
//! bit for bit (tested against the AVX2 kernel, and by the integration tests
//! against the scalar loop).
//!
//! # The `unsafe` here
//! As in [`super::gather`]: calling a function compiled for AVX-512F after
//! run-time detection, and gathers through a raw pointer whose indices are
//! clamped (integer min/max) into the range every read of a stencil stays in;
//! the levels' sizes are checked (`gather::supports`) before the kernel runs.
#![allow(
    unsafe_code,
    reason = "AVX-512 gathers and run-time dispatch; see the module documentation"
)]

use super::gather::{FixedTerm, RowLevels, ScaledTerm};
use super::{Interpolation, ScaleStack};

/// Pixels per AVX-512 block.
pub(crate) const LANES: usize = 16;

/// The wider kernel per-pixel maps take on this CPU for a one-channel
/// stack read bilinearly: `Some("avx512")` (sixteen
/// pixels per vector) where the CPU has AVX-512F (and FMA) and `IFD_SIMD` (`avx2` or
/// `baseline`) does not cap it, else `None` (the
/// [`vector_kernels`](crate::vector_kernels), eight pixels per vector). The
/// same output either way.
///
/// ```
/// let wide = ifd_planar::wide_vector_kernels();
/// assert!(wide.is_none() || wide == Some("avx512"));
/// ```
#[must_use]
pub fn wide_vector_kernels() -> Option<&'static str> {
    available().then_some("avx512")
}

/// Whether the AVX-512 kernel runs on this CPU: the crate's instruction
/// set choice (the direct prefilter's, `separable`: AVX-512F with FMA
/// unless `IFD_SIMD` caps it) is AVX-512.
#[must_use]
pub(crate) fn available() -> bool {
    super::separable::isa() == super::separable::Isa::Avx512
}

/// `kernel::f(args)` where the CPU has AVX-512F ([`available`]), else 0
/// pixels done: the one place the entry points below call the kernels
/// compiled for it.
macro_rules! on_avx512 {
    ($f:ident($($arg:expr),* $(,)?)) => {{
        #[cfg(target_arch = "x86_64")]
        let done = if available() {
            // SAFETY: `available` checked that the CPU has AVX-512F.
            unsafe { kernel::$f($($arg),*) }
        } else {
            0
        };
        #[cfg(not(target_arch = "x86_64"))]
        let done = {
            let _ = ($($arg,)*);
            0
        };
        done
    }};
}

/// [`super::gather::rotated_row`] for a one-channel, bilinear stack on an
/// AVX-512 CPU: the pixels done (a multiple of [`LANES`]; 0 when this kernel
/// does not apply, and the caller takes the AVX2 kernel).
pub(crate) fn rotated_row(
    stack: &ScaleStack,
    terms: &[FixedTerm],
    y: usize,
    cs: &[f32],
    ss: &[f32],
    out: &mut [f32],
) -> usize {
    // `supports`: levels of at least 2x2 samples, `nx ny` of them below
    // `i32::MAX` (the gathers' index clamp relies on both)
    if !(stack.interpolation == Interpolation::Linear && super::gather::supports::<1>(stack)) {
        return 0;
    }
    on_avx512!(rotated_row(stack, terms, y, cs, ss, out))
}

/// [`super::gather::scaled_row`] for a one-channel, bilinear stack on an
/// AVX-512 CPU, after its checks (levels in range, one row of levels per
/// pixel): the pixels done (a multiple of [`LANES`]; 0 when this kernel
/// does not apply, and the caller takes the AVX2 kernel).
pub(crate) fn scaled_row(
    stack: &ScaleStack,
    terms: &[ScaledTerm],
    levels: &RowLevels,
    y: usize,
    cs: &[f32],
    ss: &[f32],
    out: &mut [f32],
) -> usize {
    if !(stack.interpolation == Interpolation::Linear && super::gather::supports::<1>(stack)) {
        return 0;
    }
    on_avx512!(scaled_row(stack, terms, levels, y, cs, ss, out))
}

/// [`super::gather::fill_levels`]' vector pass in sixteen lanes where the
/// CPU has AVX-512F: the pixels done from the row's start (a multiple of
/// [`LANES`]; 0 when this kernel does not run), each pixel's levels and
/// weights bit for bit `LevelRule::series` (the AVX2 pass's operations,
/// wider), and the pixels whose widening needs the logarithm by
/// `LevelRule::at`.
pub(crate) fn fill_levels(
    rule: super::LevelRule,
    t_s: &[f32],
    widen: &[f32],
    levels: &mut RowLevels,
    g: usize,
) -> usize {
    on_avx512!(fill_levels(rule, t_s, widen, levels, g))
}

/// [`super::gather::rotations`] in sixteen lanes where the CPU has
/// AVX-512F: the pixels done from the row's start (a multiple of [`LANES`];
/// 0 when this kernel does not run), bit for bit the scalar rule.
pub(crate) fn rotations(
    theta: &[f32],
    scale: crate::field::Field<'_>,
    cs: &mut [f32],
    ss: &mut [f32],
) -> usize {
    on_avx512!(rotations(theta, scale, cs, ss))
}

/// [`super::gather::scale_positions`] in sixteen lanes where the CPU has
/// AVX-512F: the pixels done from the row's start (a multiple of
/// [`LANES`]; 0 when this kernel does not run), bit for bit
/// `ScalePosition::at`.
pub(crate) fn scale_positions(
    rule: super::ScalePosition,
    scales: &[f32],
    t_s: &mut [f32],
    widen: &mut [f32],
) -> usize {
    on_avx512!(scale_positions(rule, scales, t_s, widen))
}

#[cfg(target_arch = "x86_64")]
mod kernel {
    use std::arch::x86_64::{
        __m512, _MM_FROUND_NO_EXC, _MM_FROUND_TO_NEG_INF, _mm512_add_epi32, _mm512_add_ps,
        _mm512_cmple_epu32_mask, _mm512_cvtps_epi32, _mm512_loadu_ps, _mm512_max_epi32,
        _mm512_min_epi32, _mm512_mul_ps, _mm512_mullo_epi32, _mm512_roundscale_ps,
        _mm512_set1_epi32, _mm512_set1_ps, _mm512_setr_ps, _mm512_setzero_ps, _mm512_setzero_si512,
        _mm512_storeu_ps, _mm512_sub_ps,
    };

    use super::LANES;
    use crate::field::Field;
    use crate::kernel::{LOG_FROM, WIDENING_FLOOR};
    use crate::stack::gather::{FixedTerm, RowLevels, ScaledTerm};
    use crate::stack::{LevelRule, ScalePosition};
    use std::arch::x86_64::{
        __m512i, _CMP_NEQ_OQ, _mm512_castsi512_ps, _mm512_castsi512_si256, _mm512_cmp_ps_mask,
        _mm512_cmpeq_epi32_mask, _mm512_extracti64x4_epi64, _mm512_i32gather_epi64,
        _mm512_loadu_si512, _mm512_mask_add_epi32, _mm512_maskz_mov_ps, _mm512_permutex2var_epi32,
        _mm512_reduce_max_epi32, _mm512_reduce_min_epi32, _mm512_setr_epi32,
    };
    use std::arch::x86_64::{
        _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LT_OQ, _mm512_abs_ps, _mm512_cvtepi32_ps, _mm512_cvttps_epi32,
        _mm512_mask_mov_ps, _mm512_max_ps, _mm512_min_ps, _mm512_storeu_si512,
    };
    use std::arch::x86_64::{
        _MM_FROUND_TO_NEAREST_INT, _mm512_and_si512, _mm512_castps_si512, _mm512_div_ps,
        _mm512_slli_epi32, _mm512_srai_epi32, _mm512_sub_epi32, _mm512_xor_si512,
    };

    /// `roundscale`'s immediate for the floor.
    const FLOOR: i32 = _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC;
    use crate::stack::{Level, ScaleStack};

    /// Sixteen floats into a vector.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn load(v: &[f32; LANES]) -> __m512 {
        // SAFETY: reads exactly the sixteen floats of `v`.
        unsafe { _mm512_loadu_ps(v.as_ptr()) }
    }

    /// A vector's sixteen floats.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn store(v: __m512) -> [f32; LANES] {
        let mut out = [0.0f32; LANES];
        // SAFETY: writes exactly the sixteen floats of `out`.
        unsafe { _mm512_storeu_ps(out.as_mut_ptr(), v) };
        out
    }

    /// Sixteen consecutive floats of `s` from `at`.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn load_at(s: &[f32], at: usize) -> __m512 {
        load(s[at..at + LANES].try_into().expect("sixteen lanes"))
    }

    /// Where a bilinear lookup of `level` at `(px, py)` reads when every
    /// lane's 2x2 stencil lies in the stored level (the scalar lookup's
    /// interior test): the fractions `(fu, fv)` and each lane's first
    /// sample; `None` otherwise. `gather`'s AVX2 `bilinear_stencil`, in
    /// sixteen lanes; levels on one grid share it.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn stencil(level: &Level, px: __m512, py: __m512) -> Option<(__m512, __m512, __m512i)> {
        let (nx, ny) = (level.layout.nx as i32, level.layout.ny as i32);
        let (origin, inv) = (_mm512_set1_ps(level.origin), _mm512_set1_ps(level.inv_step));
        let u = _mm512_mul_ps(_mm512_sub_ps(px, origin), inv);
        let v = _mm512_mul_ps(_mm512_sub_ps(py, origin), inv);
        let (fl_u, fl_v) = (
            _mm512_roundscale_ps::<FLOOR>(u),
            _mm512_roundscale_ps::<FLOOR>(v),
        );
        // floors as integers (exact; NaN and values past i32 give i32::MIN,
        // above every limit as unsigned)
        let (iu, iv) = (_mm512_cvtps_epi32(fl_u), _mm512_cvtps_epi32(fl_v));
        let inside = _mm512_cmple_epu32_mask(iu, _mm512_set1_epi32(nx - 2))
            & _mm512_cmple_epu32_mask(iv, _mm512_set1_epi32(ny - 2));
        if inside != u16::MAX {
            return None;
        }
        let (fu, fv) = (_mm512_sub_ps(u, fl_u), _mm512_sub_ps(v, fl_v));
        let idx = _mm512_add_epi32(_mm512_mullo_epi32(iv, _mm512_set1_epi32(nx)), iu);
        // Memory safety: every read of `bilinear_at` is at most `nx + 1`
        // samples past `idx <= nx (ny - 1) - 2`, inside the level's `nx ny`
        // samples (`gather::supports` checked the length).
        let idx = _mm512_min_epi32(
            _mm512_max_epi32(idx, _mm512_setzero_si512()),
            _mm512_set1_epi32(nx * (ny - 1) - 2),
        );
        Some((fu, fv, idx))
    }

    /// `acc + w *` the bilinear lookups of `level` at `stencil` (from
    /// [`stencil`] on this level's grid), in `gather::avx2::blend`'s order
    /// of operations.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn bilinear_at(
        level: &Level,
        (fu, fv, idx): (__m512, __m512, __m512i),
        w: __m512,
        acc: __m512,
    ) -> __m512 {
        let p = level.data.as_ptr();
        // SAFETY: the pairs read at `idx` from `p` and `p + nx` end at
        // `idx + nx + 1 < nx ny = data.len()` (the clamp in `stencil`).
        let ((a, b), (c, d)) = unsafe { (pairs(p, idx), pairs(p.add(level.layout.nx), idx)) };
        let r0 = _mm512_add_ps(a, _mm512_mul_ps(fu, _mm512_sub_ps(b, a)));
        let r1 = _mm512_add_ps(c, _mm512_mul_ps(fu, _mm512_sub_ps(d, c)));
        let value = _mm512_add_ps(r0, _mm512_mul_ps(fv, _mm512_sub_ps(r1, r0)));
        _mm512_add_ps(acc, _mm512_mul_ps(w, value))
    }

    /// The floats at `idx` and `idx + 1` (per lane) from `p`: two 64-bit
    /// gathers of eight lanes each, split into the lanes' first and second
    /// floats (half the loads of four 32-bit gathers; the AVX2 rows read
    /// the same pairs).
    ///
    /// # Safety
    /// Every `p + idx` and `p + idx + 1` must be inside one allocation.
    #[inline]
    #[target_feature(enable = "avx512f")]
    #[expect(
        clippy::cast_ptr_alignment,
        reason = "gathers need no alignment; the pointer type is the intrinsic's signature"
    )]
    unsafe fn pairs(p: *const f32, idx: __m512i) -> (__m512, __m512) {
        let (lo, hi) = (
            _mm512_castsi512_si256(idx),
            _mm512_extracti64x4_epi64::<1>(idx),
        );
        // SAFETY: as the caller promises.
        let (l, h) = unsafe {
            (
                _mm512_i32gather_epi64::<4>(lo, p.cast::<i64>()),
                _mm512_i32gather_epi64::<4>(hi, p.cast::<i64>()),
            )
        };
        let first = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
        let second = _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31);
        (
            _mm512_castsi512_ps(_mm512_permutex2var_epi32(l, first, h)),
            _mm512_castsi512_ps(_mm512_permutex2var_epi32(l, second, h)),
        )
    }

    /// `acc + w *` the bilinear lookups of `level` at `(px, py)` when every
    /// lane's 2x2 stencil lies in the stored level, `None` otherwise.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn bilinear(level: &Level, px: __m512, py: __m512, w: __m512, acc: __m512) -> Option<__m512> {
        stencil(level, px, py).map(|at| bilinear_at(level, at, w, acc))
    }

    /// Lane by lane through the scalar, border-resolving lookup of level
    /// `li` with each lane's weight in `w` (lanes of weight 0 skipped, as
    /// the AVX2 rows skip them), in lane order.
    #[inline(never)]
    #[target_feature(enable = "avx512f")]
    fn scalar_lanes(
        stack: &ScaleStack,
        li: usize,
        px: __m512,
        py: __m512,
        w: __m512,
        acc: __m512,
    ) -> __m512 {
        let (pxs, pys, ws) = (store(px), store(py), store(w));
        let mut sums = store(acc);
        for (lane, sum) in sums.iter_mut().enumerate() {
            if ws[lane] != 0.0 {
                let mut one = [*sum];
                stack.accumulate_fixed::<1>(li, pxs[lane], pys[lane], ws[lane], &mut one);
                *sum = one[0];
            }
        }
        load(&sums)
    }

    /// The block positions for displacement `(cx, cy)`, in the scalar
    /// loop's order (`gather::avx2::positions`).
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn positions(
        xf: __m512,
        yf: __m512,
        c: __m512,
        s: __m512,
        cx: f32,
        cy: f32,
    ) -> (__m512, __m512) {
        let (cx, cy) = (_mm512_set1_ps(cx), _mm512_set1_ps(cy));
        let px = _mm512_add_ps(
            _mm512_add_ps(xf, _mm512_mul_ps(c, cx)),
            _mm512_mul_ps(s, cy),
        );
        let py = _mm512_add_ps(
            _mm512_sub_ps(yf, _mm512_mul_ps(s, cx)),
            _mm512_mul_ps(c, cy),
        );
        (px, py)
    }

    /// Pixel coordinates `x0 .. x0 + 15` (exact below 2^24).
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn columns(x0: usize) -> __m512 {
        let lanes = _mm512_setr_ps(
            0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0,
        );
        _mm512_add_ps(_mm512_set1_ps(x0 as f32), lanes)
    }

    /// Levels a block of one sigma group can span and still be read in
    /// vector lanes (`gather::avx2`'s `SPAN`).
    const SPAN: usize = 4;

    /// One sigma group's levels over a block of sixteen pixels
    /// (`gather::avx2`'s `Block`, its per-level weights kept apart in the
    /// group's slot of a buffer that [`classify`] writes in place: a block
    /// is rebuilt per group every sixteen pixels, and moving four vectors
    /// each time cost a seventh of the row's time).
    #[derive(Clone, Copy)]
    enum Block {
        /// Every lane on levels `a .. a + SPAN`: per level, each lane's
        /// weight on it in the group's weights (zero where the lane does not
        /// read it), `used` marking the levels some lane reads.
        Vector { a: usize, used: u8 },
        /// Lanes spread over more levels: each lane looks up its own.
        Lanes,
    }

    /// The block of sixteen lanes from pixel `x0` of group `g`
    /// (`gather::avx2::classify`, the same weights, written into `w`): each
    /// lane reads level `a` (weight `wa`) and, where `wb != 0`, `a + 1`
    /// (`wb`).
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn classify(levels: &RowLevels, g: usize, x0: usize, w: &mut [__m512; SPAN]) -> Block {
        let i = g * levels.w + x0;
        let a: &[u32; LANES] = levels.a[i..i + LANES].try_into().expect("sixteen lanes");
        // SAFETY: reads exactly the sixteen integers of `a`.
        let la = unsafe { _mm512_loadu_si512(a.as_ptr().cast()) };
        let (wa, wb) = (load_at(&levels.wa, i), load_at(&levels.wb, i));
        let zero = _mm512_setzero_ps();
        // the lanes that read a second level
        let second = _mm512_cmp_ps_mask::<_CMP_NEQ_OQ>(wb, zero);
        if _mm512_cmpeq_epi32_mask(la, _mm512_set1_epi32(a[0] as i32)) == u16::MAX {
            // The common block: every lane on level `a` (and `a + 1`
            // where its `wb` is not zero).
            let used = u8::from(_mm512_cmp_ps_mask::<_CMP_NEQ_OQ>(wa, zero) != 0)
                | (u8::from(second != 0) << 1);
            w[0] = wa;
            w[1] = _mm512_maskz_mov_ps(second, wb);
            return Block::Vector {
                a: a[0] as usize,
                used,
            };
        }
        let lb = _mm512_mask_add_epi32(la, second, la, _mm512_set1_epi32(1));
        let (lo, hi) = (_mm512_reduce_min_epi32(la), _mm512_reduce_max_epi32(lb));
        let n = (hi - lo) as usize + 1;
        if n > SPAN {
            return Block::Lanes;
        }
        // level lo + k: each lane's weight on it (wa where a is it, wb
        // where a + 1 is)
        let mut used = 0u8;
        let distinct = !_mm512_cmpeq_epi32_mask(la, lb);
        for (k, wk) in w.iter_mut().enumerate().take(n) {
            let level = _mm512_set1_epi32(lo + k as i32);
            let on_a = _mm512_cmpeq_epi32_mask(la, level);
            let on_b = distinct & _mm512_cmpeq_epi32_mask(lb, level);
            *wk = _mm512_add_ps(_mm512_maskz_mov_ps(on_a, wa), _mm512_maskz_mov_ps(on_b, wb));
            used |= u8::from(_mm512_cmp_ps_mask::<_CMP_NEQ_OQ>(*wk, zero) != 0) << k;
        }
        Block::Vector {
            a: lo as usize,
            used,
        }
    }

    /// `gather::avx2::rotations` in sixteen lanes: `trig::sin_cos_degrees`
    /// operation by operation, times the row's scale.
    #[target_feature(enable = "avx512f")]
    pub(super) fn rotations(
        theta: &[f32],
        scale: Field<'_>,
        cs: &mut [f32],
        ss: &mut [f32],
    ) -> usize {
        use crate::trig::{COS, INV_RIGHT_ANGLE, RADIANS_PER_DEGREE, SIN};
        const NEAREST: i32 = _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC;
        let k = _mm512_set1_ps;
        let n = theta.len().min(cs.len()).min(ss.len()) / LANES * LANES;
        let (one, two) = (_mm512_set1_epi32(1), _mm512_set1_epi32(2));
        for x0 in (0..n).step_by(LANES) {
            let t = load_at(theta, x0);
            let q = _mm512_roundscale_ps::<NEAREST>(_mm512_mul_ps(t, k(INV_RIGHT_ANGLE)));
            let x = _mm512_mul_ps(
                _mm512_sub_ps(t, _mm512_mul_ps(q, k(90.0))),
                k(RADIANS_PER_DEGREE),
            );
            let x2 = _mm512_mul_ps(x, x);
            let horner = |coef: &[f32]| {
                let (last, rest) = coef.split_last().expect("coefficients");
                rest.iter().rev().fold(k(*last), |acc, &c| {
                    _mm512_add_ps(k(c), _mm512_mul_ps(x2, acc))
                })
            };
            let sp = _mm512_add_ps(x, _mm512_mul_ps(_mm512_mul_ps(x, x2), horner(&SIN)));
            let cp = _mm512_add_ps(k(1.0), _mm512_mul_ps(x2, horner(&COS)));
            let qi = _mm512_cvtps_epi32(q);
            let swap = _mm512_cmpeq_epi32_mask(_mm512_and_si512(qi, one), one);
            let (s, c) = (
                _mm512_mask_mov_ps(sp, swap, cp),
                _mm512_mask_mov_ps(cp, swap, sp),
            );
            // bit 1 of q (of q + 1) moved to the sign bit negates the sine
            // (cosine)
            let s_sign = _mm512_slli_epi32::<30>(_mm512_and_si512(qi, two));
            let c_sign = _mm512_slli_epi32::<30>(_mm512_and_si512(_mm512_add_epi32(qi, one), two));
            let s = _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(s), s_sign));
            let c = _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(c), c_sign));
            let sc = match scale {
                Field::Constant(v) => k(v),
                Field::Map(m) => load_at(m, x0),
            };
            cs[x0..x0 + LANES].copy_from_slice(&store(_mm512_mul_ps(c, sc)));
            ss[x0..x0 + LANES].copy_from_slice(&store(_mm512_mul_ps(s, sc)));
        }
        n
    }

    /// `gather::avx2::scale_positions` in sixteen lanes: `ln::ln`, then
    /// `ScalePosition::at`, operation by operation.
    #[target_feature(enable = "avx512f")]
    pub(super) fn scale_positions(
        rule: ScalePosition,
        scales: &[f32],
        t_s: &mut [f32],
        widen: &mut [f32],
    ) -> usize {
        use crate::ln::{ATANH, LN2_HI, LN2_LO, SQRT_HALF_BITS};
        let k = _mm512_set1_ps;
        let n = scales.len().min(t_s.len()).min(widen.len()) / LANES * LANES;
        let sqrt_half = _mm512_set1_epi32(SQRT_HALF_BITS as i32);
        let mantissa = _mm512_set1_epi32(0x007f_ffff);
        for x0 in (0..n).step_by(LANES) {
            let s = load_at(scales, x0);
            let ix = _mm512_sub_epi32(
                _mm512_castps_si512(_mm512_max_ps(s, k(f32::MIN_POSITIVE))),
                sqrt_half,
            );
            let e = _mm512_cvtepi32_ps(_mm512_srai_epi32::<23>(ix));
            let m =
                _mm512_castsi512_ps(_mm512_add_epi32(_mm512_and_si512(ix, mantissa), sqrt_half));
            let f = _mm512_div_ps(_mm512_sub_ps(m, k(1.0)), _mm512_add_ps(m, k(1.0)));
            let z = _mm512_mul_ps(f, f);
            let r = _mm512_add_ps(f, f);
            let (top, rest) = ATANH.split_last().expect("coefficients");
            let poly = rest.iter().rev().fold(k(*top), |acc, &c| {
                _mm512_add_ps(k(c), _mm512_mul_ps(z, acc))
            });
            let p = _mm512_add_ps(r, _mm512_mul_ps(_mm512_mul_ps(r, z), poly));
            let ln = _mm512_add_ps(
                _mm512_mul_ps(e, k(LN2_HI)),
                _mm512_add_ps(p, _mm512_mul_ps(e, k(LN2_LO))),
            );
            let ts = _mm512_mul_ps(_mm512_sub_ps(ln, k(rule.ln0)), k(rule.inv));
            let wd = _mm512_add_ps(
                _mm512_div_ps(k(rule.var), _mm512_mul_ps(s, s)),
                k(rule.shift),
            );
            let below = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(s, k(rule.below));
            let wd = _mm512_maskz_mov_ps(below, wd);
            t_s[x0..x0 + LANES].copy_from_slice(&store(ts));
            widen[x0..x0 + LANES].copy_from_slice(&store(wd));
        }
        n
    }

    /// `gather::avx2::fill_levels` in sixteen lanes: the widening's series,
    /// the position clamped, its level below and the snap, operation by
    /// operation as `LevelRule::series` (no fused multiply-adds); lanes
    /// whose widening needs the logarithm take `LevelRule::at` after.
    #[target_feature(enable = "avx512f")]
    pub(super) fn fill_levels(
        rule: LevelRule,
        t_s: &[f32],
        widen: &[f32],
        levels: &mut RowLevels,
        g: usize,
    ) -> usize {
        let k = _mm512_set1_ps;
        let w = levels.w;
        let base = g * w;
        let n = w.min(t_s.len()).min(widen.len()) / LANES * LANES;
        let (floor, needs_log) = (k(WIDENING_FLOOR), k(LOG_FROM));
        let (one, half, third, quarter) = (k(1.0), k(0.5), k(1.0 / 3.0), k(0.25));
        let (inv_sigma2, ln_sigma, inv) = (k(rule.inv_sigma2), k(rule.ln_sigma), k(rule.inv));
        let last = k(rule.last as f32);
        let below_last = _mm512_set1_epi32((rule.last - 1) as i32);
        let (snap_lo, snap_hi) = (k(rule.snap), k(1.0 - rule.snap));
        let zero = _mm512_setzero_ps();
        for x0 in (0..n).step_by(LANES) {
            let (ts, wd) = (load_at(t_s, x0), load_at(widen, x0));
            // kernel::ln_widening_series
            let x = _mm512_max_ps(_mm512_mul_ps(wd, inv_sigma2), floor);
            // kernel::widening_needs_log: |x| >= LOG_FROM
            let log_lanes = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(_mm512_abs_ps(x), needs_log);
            let x2 = _mm512_mul_ps(x, x);
            let odd = _mm512_mul_ps(x, _mm512_add_ps(one, _mm512_mul_ps(x2, third)));
            let even = _mm512_mul_ps(x2, _mm512_add_ps(half, _mm512_mul_ps(x2, quarter)));
            let lw = _mm512_mul_ps(half, _mm512_sub_ps(odd, even));
            // LevelRule::bracket: the position, clamped (finite positions:
            // max/min are `clamp`), its level below, snapped
            let u = _mm512_add_ps(ts, _mm512_mul_ps(_mm512_add_ps(ln_sigma, lw), inv));
            let u = _mm512_min_ps(_mm512_max_ps(u, zero), last);
            let i = _mm512_min_epi32(_mm512_cvttps_epi32(u), below_last);
            let f = _mm512_sub_ps(u, _mm512_cvtepi32_ps(i));
            let hi = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(f, snap_hi);
            let snapped = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(f, snap_lo) | hi;
            // a = i + 1 where `hi` is set
            let a = _mm512_mask_add_epi32(i, hi, i, _mm512_set1_epi32(1));
            let wa = _mm512_mask_mov_ps(_mm512_sub_ps(one, f), snapped, one);
            let wb = _mm512_mask_mov_ps(f, snapped, zero);
            let at = base + x0;
            let da: &mut [u32; LANES] = (&mut levels.a[at..at + LANES])
                .try_into()
                .expect("sixteen lanes");
            // SAFETY: writes exactly the sixteen integers of `da`.
            unsafe { _mm512_storeu_si512(da.as_mut_ptr().cast(), a) };
            levels.wa[at..at + LANES].copy_from_slice(&store(wa));
            levels.wb[at..at + LANES].copy_from_slice(&store(wb));
            if log_lanes != 0 {
                for x in (x0..x0 + LANES).filter(|x| log_lanes & (1 << (x - x0)) != 0) {
                    let (a, _, wa, wb) = rule.at(t_s[x], widen[x]);
                    let i = base + x;
                    (levels.a[i], levels.wa[i], levels.wb[i]) = (a, wa, wb);
                }
            }
        }
        n
    }

    /// `gather::avx2::scaled_row` for one channel read bilinearly, in
    /// sixteen lanes: the same lookups in the same order.
    #[target_feature(enable = "avx512f")]
    pub(super) fn scaled_row(
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
        let yf = _mm512_set1_ps(y as f32);
        let mut blocks = vec![Block::Lanes; groups];
        let mut weights = vec![[_mm512_setzero_ps(); SPAN]; groups];
        // level i and level i + 1 sample the same grid: one stencil serves
        // both (the same values as computing it twice)
        let same_grid: Vec<bool> = stack
            .levels
            .windows(2)
            .map(|p| {
                let grid = |l: &Level| (l.layout.step, l.layout.origin, l.layout.nx, l.layout.ny);
                grid(&p[0]) == grid(&p[1])
            })
            .collect();
        for x0 in (0..n).step_by(LANES) {
            for (g, (b, w)) in blocks.iter_mut().zip(&mut weights).enumerate() {
                *b = classify(levels, g, x0, w);
            }
            let xf = columns(x0);
            let (c, s) = (load_at(cs, x0), load_at(ss, x0));
            let mut acc = _mm512_setzero_ps();
            for t in terms {
                let (px, py) = positions(xf, yf, c, s, t.cx, t.cy);
                match &blocks[t.group] {
                    Block::Vector { a, used } => {
                        let w = &weights[t.group];
                        let tw = _mm512_set1_ps(t.weight);
                        if *used == 0b11
                            && same_grid[*a]
                            && let Some(at) = stencil(&stack.levels[*a], px, py)
                        {
                            acc = bilinear_at(&stack.levels[*a], at, _mm512_mul_ps(tw, w[0]), acc);
                            acc =
                                bilinear_at(&stack.levels[a + 1], at, _mm512_mul_ps(tw, w[1]), acc);
                            continue;
                        }
                        for (k, lw) in w.iter().enumerate() {
                            if used & (1 << k) == 0 {
                                continue;
                            }
                            let li = a + k;
                            let wv = _mm512_mul_ps(tw, *lw);
                            acc = match bilinear(&stack.levels[li], px, py, wv, acc) {
                                Some(sum) => sum,
                                None => scalar_lanes(stack, li, px, py, wv, acc),
                            };
                        }
                    }
                    Block::Lanes => {
                        // each lane's two lookups in the scalar order
                        let (pxs, pys) = (store(px), store(py));
                        let mut sums = store(acc);
                        for (lane, sum) in sums.iter_mut().enumerate() {
                            let (a, b, wa, wb) = levels.at(t.group, x0 + lane);
                            let mut one = [*sum];
                            stack.accumulate_fixed::<1>(
                                a,
                                pxs[lane],
                                pys[lane],
                                t.weight * wa,
                                &mut one,
                            );
                            if wb != 0.0 {
                                stack.accumulate_fixed::<1>(
                                    b,
                                    pxs[lane],
                                    pys[lane],
                                    t.weight * wb,
                                    &mut one,
                                );
                            }
                            *sum = one[0];
                        }
                        acc = load(&sums);
                    }
                }
            }
            let dst: &mut [f32; LANES] = (&mut out[x0..x0 + LANES])
                .try_into()
                .expect("sixteen lanes");
            *dst = store(_mm512_add_ps(load(dst), acc));
        }
        n
    }

    #[target_feature(enable = "avx512f")]
    pub(super) fn rotated_row(
        stack: &ScaleStack,
        terms: &[FixedTerm],
        y: usize,
        cs: &[f32],
        ss: &[f32],
        out: &mut [f32],
    ) -> usize {
        let n = cs.len().min(ss.len()).min(out.len()) / LANES * LANES;
        let yf = _mm512_set1_ps(y as f32);
        for x0 in (0..n).step_by(LANES) {
            let xf = columns(x0);
            let (c, s) = (load_at(cs, x0), load_at(ss, x0));
            let mut acc = _mm512_setzero_ps();
            for t in terms {
                let (px, py) = positions(xf, yf, c, s, t.cx, t.cy);
                for (li, w) in [(t.a, t.wa), (t.b, t.wb)] {
                    if w == 0.0 {
                        continue;
                    }
                    let level = &stack.levels[li];
                    acc = if let Some(sum) = bilinear(level, px, py, _mm512_set1_ps(w), acc) {
                        sum
                    } else {
                        // lane by lane, the scalar lookup resolving borders
                        // (`scalar_lanes`' loop, kept inline: called out of
                        // line here, the whole row measured 5-10% slower)
                        let (pxs, pys) = (store(px), store(py));
                        let mut sums = store(acc);
                        for (lane, sum) in sums.iter_mut().enumerate() {
                            let mut one = [*sum];
                            stack.accumulate_fixed::<1>(li, pxs[lane], pys[lane], w, &mut one);
                            *sum = one[0];
                        }
                        load(&sums)
                    };
                }
            }
            let dst: &mut [f32; LANES] = (&mut out[x0..x0 + LANES])
                .try_into()
                .expect("sixteen lanes");
            *dst = store(_mm512_add_ps(load(dst), acc));
        }
        n
    }
}

#[cfg(test)]
mod tests {
    use super::{LANES, available};
    use crate::stack::gather::{self, FixedTerm, RowLevels, ScaledTerm};
    use crate::stack::{Interpolation, ScaleStack, StackOptions};
    use crate::{Border, trig::sin_cos_degrees};
    use ifd_image::Image;

    /// The AVX-512 rows bit for bit the AVX2 rows (each the scalar loop's,
    /// as the integration tests check end to end): lanes inside and outside
    /// the stored levels (a kernel reaching past the borders), a level pair
    /// and single levels, pyramid steps.
    #[test]
    fn sixteen_lanes_equal_eight() {
        if !available() || gather::vector_kernels().is_none() {
            // counted as skipped, not passed (tests/support/skip.rs)
            crate::test_skip::skip("no AVX-512F (or IFD_SIMD caps it): nothing to compare");
            return;
        }
        let (w, h) = (83, 37);
        let mut img = Image::new(w, h, 1).expect("image");
        for (i, v) in img.data_mut().iter_mut().enumerate() {
            *v = ((i * 7919) % 1013) as f32 / 1013.0 - 0.3;
        }
        let options = StackOptions {
            interpolation: Interpolation::Linear,
            ..StackOptions::default()
        };
        let stack = ScaleStack::with_sigmas(&img, &[1.5, 3.0, 6.0], Border::Reflect101, options)
            .expect("stack");
        // pyramid steps 1, 1 and 2 (factor 2): the kernel reads each grid
        assert!(stack.level_layouts().any(|l| l.step > 1));
        let terms = [
            (0.0, 0.0, 0, 0, 1.0, 0.0),
            (5.5, -2.25, 0, 1, 0.7, 0.3),
            (-30.0, 12.0, 1, 2, 0.25, 0.75),
            (60.0, 41.0, 2, 2, -0.5, 0.0),
        ]
        .map(|(cx, cy, a, b, wa, wb)| FixedTerm {
            cx,
            cy,
            a,
            b,
            wa,
            wb,
        });
        let width = 5 * LANES;
        for y in [0, 5, 18, 36] {
            let (cs, ss): (Vec<f32>, Vec<f32>) = (0..width)
                .map(|x| {
                    let (sin, cos) = sin_cos_degrees(x as f32 * 7.3 - 40.0 + y as f32);
                    (cos * 0.9, sin * 0.9)
                })
                .unzip();
            let (mut wide, mut narrow) = (vec![0.25f32; width], vec![0.25f32; width]);
            let done = super::rotated_row(&stack, &terms, y, &cs, &ss, &mut wide);
            assert_eq!(done, width);
            let done =
                gather::avx2_for_tests::rotated_row(&stack, &terms, y, &cs, &ss, &mut narrow);
            assert_eq!(done, width);
            for x in 0..width {
                assert_eq!(wide[x].to_bits(), narrow[x].to_bits(), "row {y}, pixel {x}");
            }
        }
    }

    /// The sixteen-lane scaled rows bit for bit the AVX2 rows: blocks on one
    /// level and on a blended pair (one grid and two), blocks whose lanes
    /// span up to four levels and more (lane by lane), single reads (a
    /// stack read at the nearest level), lanes whose stencils leave the
    /// stored levels, several sigma groups.
    #[test]
    fn sixteen_scaled_lanes_equal_eight() {
        if !available() || gather::vector_kernels().is_none() {
            // counted as skipped, not passed (tests/support/skip.rs)
            crate::test_skip::skip("no AVX-512F (or IFD_SIMD caps it): nothing to compare");
            return;
        }
        let (w, h) = (97, 41);
        let mut img = Image::new(w, h, 1).expect("image");
        for (i, v) in img.data_mut().iter_mut().enumerate() {
            *v = ((i * 7919) % 1013) as f32 / 1013.0 - 0.3;
        }
        let options = StackOptions {
            interpolation: Interpolation::Linear,
            ..StackOptions::default()
        };
        let sigmas = [1.2, 1.7, 2.4, 3.4, 4.8, 6.8];
        let stack =
            ScaleStack::with_sigmas(&img, &sigmas, Border::Reflect101, options).expect("stack");
        let terms = [
            (0.0, 0.0, 0.6, 0),
            (7.5, -2.25, -0.3, 1),
            (-30.0, 12.0, 0.25, 2),
            (44.0, 31.0, 0.5, 1),
        ]
        .map(|(cx, cy, weight, group)| ScaledTerm {
            cx,
            cy,
            weight,
            group,
        });
        let width = 6 * LANES;
        let mut levels = RowLevels::new(3, width);
        // six levels: reads up to level 5
        levels.last = 5;
        let mut state = 0x9e37_79b9_u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 33) as u32
        };
        for g in 0..3 {
            for x in 0..width {
                let block = x / LANES;
                // block 0: one level; 1: a blended pair; 2: pairs across
                // two levels; 3: lanes over four levels; 4: over all six
                // (lane by lane); 5: single reads of neighbouring levels
                let a = match block {
                    0 | 1 => 2 + g as u32,
                    2 => 1 + (x % 2) as u32,
                    3 => next() % 3,
                    4 => next() % 5,
                    _ => 3 + (x % 2) as u32,
                };
                let f = (next() % 1000) as f32 / 1000.0;
                let (wa, wb) = match block {
                    0 | 5 => (1.0, 0.0),
                    _ if x % 3 == 0 => (1.0, 0.0),
                    _ => (1.0 - f, f),
                };
                let i = g * width + x;
                (levels.a[i], levels.wa[i], levels.wb[i]) = (a, wa, wb);
            }
        }
        for y in [0, 3, 20, 40] {
            let (cs, ss): (Vec<f32>, Vec<f32>) = (0..width)
                .map(|x| {
                    let (sin, cos) = sin_cos_degrees(x as f32 * 7.3 - 40.0 + y as f32);
                    let s = 0.6 + 0.01 * x as f32;
                    (cos * s, sin * s)
                })
                .unzip();
            let (mut wide, mut narrow) = (vec![0.25f32; width], vec![0.25f32; width]);
            let done = super::scaled_row(&stack, &terms, &levels, y, &cs, &ss, &mut wide);
            assert_eq!(done, width);
            let done = gather::avx2_for_tests::scaled_row(
                &stack,
                &terms,
                &levels,
                y,
                &cs,
                &ss,
                &mut narrow,
            );
            assert_eq!(done, width);
            for x in 0..width {
                assert_eq!(wide[x].to_bits(), narrow[x].to_bits(), "row {y}, pixel {x}");
            }
        }
    }
}
