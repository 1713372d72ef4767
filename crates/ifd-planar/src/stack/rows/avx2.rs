//! [`Lanes`] in AVX2: eight lanes, masks as all-ones integer lanes, and the
//! row kernels' entry points compiled for AVX2 with FMA (the compiler does
//! not contract separate multiplies and adds, so FMA changes no bits).
#![allow(
    unsafe_code,
    reason = "AVX2 intrinsics; see the `rows` module documentation"
)]

use std::arch::x86_64::{
    __m256, __m256i, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LT_OQ, _CMP_NEQ_OQ, _MM_FROUND_NO_EXC,
    _MM_FROUND_TO_NEAREST_INT, _MM_FROUND_TO_NEG_INF, _mm256_add_epi32, _mm256_add_ps,
    _mm256_and_ps, _mm256_and_si256, _mm256_andnot_ps, _mm256_andnot_si256, _mm256_blendv_ps,
    _mm256_castps_si256, _mm256_castsi256_ps, _mm256_castsi256_si128, _mm256_cmp_ps,
    _mm256_cmpeq_epi32, _mm256_cvtepi32_ps, _mm256_cvtps_epi32, _mm256_cvtsi256_si32,
    _mm256_cvttps_epi32, _mm256_div_ps, _mm256_extracti128_si256, _mm256_i32gather_epi64,
    _mm256_i32gather_ps, _mm256_loadu_ps, _mm256_loadu_si256, _mm256_max_epi32, _mm256_max_ps,
    _mm256_min_epi32, _mm256_min_epu32, _mm256_min_ps, _mm256_movemask_epi8, _mm256_movemask_ps,
    _mm256_mul_ps, _mm256_mullo_epi32, _mm256_or_si256, _mm256_permute2x128_si256,
    _mm256_permutevar8x32_epi32, _mm256_permutevar8x32_ps, _mm256_round_ps, _mm256_set1_epi32,
    _mm256_set1_ps, _mm256_setr_epi32, _mm256_setr_ps, _mm256_setzero_ps, _mm256_shuffle_epi32,
    _mm256_slli_epi32, _mm256_srai_epi32, _mm256_storeu_ps, _mm256_storeu_si256, _mm256_sub_epi32,
    _mm256_sub_ps, _mm256_xor_si256,
};

use super::lanes::Lanes;

/// Eight AVX2 lanes.
#[derive(Clone, Copy)]
pub(super) struct Avx2;

impl Lanes for Avx2 {
    const N: usize = 8;
    type F = __m256;
    type I = __m256i;
    type M = __m256i;
    type Floats = [f32; 8];

    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn splat(x: f32) -> __m256 {
        _mm256_set1_ps(x)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn zero() -> __m256 {
        _mm256_setzero_ps()
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn columns(x0: usize) -> __m256 {
        let lanes = _mm256_setr_ps(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0);
        _mm256_add_ps(_mm256_set1_ps(x0 as f32), lanes)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn load(s: &[f32]) -> __m256 {
        let s: &[f32; 8] = s[..8].try_into().expect("eight lanes");
        // SAFETY: reads exactly the eight floats of `s`.
        unsafe { _mm256_loadu_ps(s.as_ptr()) }
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn store(v: __m256, d: &mut [f32]) {
        let d: &mut [f32; 8] = (&mut d[..8]).try_into().expect("eight lanes");
        // SAFETY: writes exactly the eight floats of `d`.
        unsafe { _mm256_storeu_ps(d.as_mut_ptr(), v) }
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn add(a: __m256, b: __m256) -> __m256 {
        _mm256_add_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn sub(a: __m256, b: __m256) -> __m256 {
        _mm256_sub_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn mul(a: __m256, b: __m256) -> __m256 {
        _mm256_mul_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn div(a: __m256, b: __m256) -> __m256 {
        _mm256_div_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn min(a: __m256, b: __m256) -> __m256 {
        _mm256_min_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn max(a: __m256, b: __m256) -> __m256 {
        _mm256_max_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn abs(a: __m256) -> __m256 {
        _mm256_andnot_ps(_mm256_set1_ps(-0.0), a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn floor(a: __m256) -> __m256 {
        _mm256_round_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn round(a: __m256) -> __m256 {
        _mm256_round_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn to_int(a: __m256) -> __m256i {
        _mm256_cvtps_epi32(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn trunc_int(a: __m256) -> __m256i {
        _mm256_cvttps_epi32(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn to_bits(a: __m256) -> __m256i {
        _mm256_castps_si256(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn from_bits(a: __m256i) -> __m256 {
        _mm256_castsi256_ps(a)
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn splat_i(x: i32) -> __m256i {
        _mm256_set1_epi32(x)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn load_u32(s: &[u32]) -> __m256i {
        let s: &[u32; 8] = s[..8].try_into().expect("eight lanes");
        // SAFETY: reads exactly the eight integers of `s`.
        unsafe { _mm256_loadu_si256(s.as_ptr().cast()) }
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn store_u32(v: __m256i, d: &mut [u32]) {
        let d: &mut [u32; 8] = (&mut d[..8]).try_into().expect("eight lanes");
        // SAFETY: writes exactly the eight integers of `d`.
        unsafe { _mm256_storeu_si256(d.as_mut_ptr().cast(), v) }
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn to_float(a: __m256i) -> __m256 {
        _mm256_cvtepi32_ps(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn add_i(a: __m256i, b: __m256i) -> __m256i {
        _mm256_add_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn sub_i(a: __m256i, b: __m256i) -> __m256i {
        _mm256_sub_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn mul_i(a: __m256i, b: __m256i) -> __m256i {
        _mm256_mullo_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn min_i(a: __m256i, b: __m256i) -> __m256i {
        _mm256_min_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn max_i(a: __m256i, b: __m256i) -> __m256i {
        _mm256_max_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn and_i(a: __m256i, b: __m256i) -> __m256i {
        _mm256_and_si256(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn xor_i(a: __m256i, b: __m256i) -> __m256i {
        _mm256_xor_si256(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn shl30(a: __m256i) -> __m256i {
        _mm256_slli_epi32::<30>(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn sra23(a: __m256i) -> __m256i {
        _mm256_srai_epi32::<23>(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn inc_where(a: __m256i, m: __m256i) -> __m256i {
        // a set lane of `m` is -1
        _mm256_sub_epi32(a, m)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn reduce_min(a: __m256i) -> i32 {
        let a = _mm256_min_epi32(a, _mm256_permute2x128_si256::<1>(a, a));
        let a = _mm256_min_epi32(a, _mm256_shuffle_epi32::<0b0100_1110>(a));
        let a = _mm256_min_epi32(a, _mm256_shuffle_epi32::<0b1011_0001>(a));
        _mm256_cvtsi256_si32(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn reduce_max(a: __m256i) -> i32 {
        let a = _mm256_max_epi32(a, _mm256_permute2x128_si256::<1>(a, a));
        let a = _mm256_max_epi32(a, _mm256_shuffle_epi32::<0b0100_1110>(a));
        let a = _mm256_max_epi32(a, _mm256_shuffle_epi32::<0b1011_0001>(a));
        _mm256_cvtsi256_si32(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn first_i(a: __m256i) -> i32 {
        _mm256_cvtsi256_si32(a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn permute2(lo: __m256, hi: __m256, idx: __m256i) -> __m256 {
        // each half permuted by the low three bits, then the half chosen
        // by bit 3 (shifted into the sign bit `blendv` reads)
        let (a, b) = (
            _mm256_permutevar8x32_ps(lo, idx),
            _mm256_permutevar8x32_ps(hi, idx),
        );
        _mm256_blendv_ps(a, b, _mm256_castsi256_ps(_mm256_slli_epi32::<28>(idx)))
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn lt(a: __m256, b: __m256) -> __m256i {
        _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LT_OQ>(a, b))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn gt(a: __m256, b: __m256) -> __m256i {
        _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GT_OQ>(a, b))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn ge(a: __m256, b: __m256) -> __m256i {
        _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GE_OQ>(a, b))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn ne(a: __m256, b: __m256) -> __m256i {
        _mm256_castps_si256(_mm256_cmp_ps::<_CMP_NEQ_OQ>(a, b))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn eq_i(a: __m256i, b: __m256i) -> __m256i {
        _mm256_cmpeq_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn le_u(a: __m256i, b: __m256i) -> __m256i {
        _mm256_cmpeq_epi32(_mm256_min_epu32(a, b), a)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn and_m(a: __m256i, b: __m256i) -> __m256i {
        _mm256_and_si256(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn or_m(a: __m256i, b: __m256i) -> __m256i {
        _mm256_or_si256(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn andnot_m(a: __m256i, b: __m256i) -> __m256i {
        _mm256_andnot_si256(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn all(m: __m256i) -> bool {
        _mm256_movemask_epi8(m) == -1
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn any(m: __m256i) -> bool {
        _mm256_movemask_ps(_mm256_castsi256_ps(m)) != 0
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn select(m: __m256i, t: __m256, f: __m256) -> __m256 {
        _mm256_blendv_ps(f, t, _mm256_castsi256_ps(m))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn zero_unless(m: __m256i, v: __m256) -> __m256 {
        _mm256_and_ps(_mm256_castsi256_ps(m), v)
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn load_ptr(p: *const f32) -> __m256 {
        // SAFETY: as the caller promises.
        unsafe { _mm256_loadu_ps(p) }
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn gather(p: *const f32, idx: __m256i) -> __m256 {
        // SAFETY: as the caller promises.
        unsafe { _mm256_i32gather_ps::<4>(p, idx) }
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    #[expect(
        clippy::cast_ptr_alignment,
        reason = "gathers need no alignment; the pointer type is the intrinsic's signature"
    )]
    unsafe fn gather_pairs(p: *const f32, idx: __m256i) -> (__m256, __m256) {
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
}

super::kernels::entry_points!(Avx2, "avx2,fma");
