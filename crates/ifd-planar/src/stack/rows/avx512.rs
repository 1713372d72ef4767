//! [`Lanes`] in AVX-512F: sixteen lanes, masks in `k` registers, and the row
//! kernels' entry points compiled for AVX-512F (with AVX2 and FMA, which
//! change no bits: the compiler does not contract multiplies and adds).
#![allow(
    unsafe_code,
    reason = "AVX-512 intrinsics; see the `rows` module documentation"
)]

use std::arch::x86_64::{
    __m512, __m512i, __mmask16, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LT_OQ, _CMP_NEQ_OQ, _MM_FROUND_NO_EXC,
    _MM_FROUND_TO_NEAREST_INT, _MM_FROUND_TO_NEG_INF, _mm_cvtsi128_si32, _mm512_abs_ps,
    _mm512_add_epi32, _mm512_add_ps, _mm512_and_si512, _mm512_castps_si512, _mm512_castsi512_ps,
    _mm512_castsi512_si128, _mm512_castsi512_si256, _mm512_cmp_ps_mask, _mm512_cmpeq_epi32_mask,
    _mm512_cmple_epu32_mask, _mm512_cvtepi32_ps, _mm512_cvtps_epi32, _mm512_cvttps_epi32,
    _mm512_div_ps, _mm512_extracti64x4_epi64, _mm512_i32gather_epi64, _mm512_i32gather_ps,
    _mm512_loadu_ps, _mm512_loadu_si512, _mm512_mask_add_epi32, _mm512_mask_mov_ps,
    _mm512_maskz_mov_ps, _mm512_max_epi32, _mm512_max_ps, _mm512_min_epi32, _mm512_min_ps,
    _mm512_mul_ps, _mm512_mullo_epi32, _mm512_permutex2var_epi32, _mm512_permutex2var_ps,
    _mm512_reduce_max_epi32, _mm512_reduce_min_epi32, _mm512_roundscale_ps, _mm512_set1_epi32,
    _mm512_set1_ps, _mm512_setr_epi32, _mm512_setr_ps, _mm512_setzero_ps, _mm512_slli_epi32,
    _mm512_srai_epi32, _mm512_storeu_ps, _mm512_storeu_si512, _mm512_sub_epi32, _mm512_sub_ps,
    _mm512_xor_si512,
};

use super::lanes::Lanes;

/// Sixteen AVX-512 lanes.
#[derive(Clone, Copy)]
pub(super) struct Avx512;

impl Lanes for Avx512 {
    const N: usize = 16;
    type F = __m512;
    type I = __m512i;
    type M = __mmask16;
    type Floats = [f32; 16];

    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn splat(x: f32) -> __m512 {
        _mm512_set1_ps(x)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn zero() -> __m512 {
        _mm512_setzero_ps()
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn columns(x0: usize) -> __m512 {
        let lanes = _mm512_setr_ps(
            0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0,
        );
        _mm512_add_ps(_mm512_set1_ps(x0 as f32), lanes)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn load(s: &[f32]) -> __m512 {
        let s: &[f32; 16] = s[..16].try_into().expect("sixteen lanes");
        // SAFETY: reads exactly the sixteen floats of `s`.
        unsafe { _mm512_loadu_ps(s.as_ptr()) }
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn store(v: __m512, d: &mut [f32]) {
        let d: &mut [f32; 16] = (&mut d[..16]).try_into().expect("sixteen lanes");
        // SAFETY: writes exactly the sixteen floats of `d`.
        unsafe { _mm512_storeu_ps(d.as_mut_ptr(), v) }
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn add(a: __m512, b: __m512) -> __m512 {
        _mm512_add_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn sub(a: __m512, b: __m512) -> __m512 {
        _mm512_sub_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn mul(a: __m512, b: __m512) -> __m512 {
        _mm512_mul_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn div(a: __m512, b: __m512) -> __m512 {
        _mm512_div_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn min(a: __m512, b: __m512) -> __m512 {
        _mm512_min_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn max(a: __m512, b: __m512) -> __m512 {
        _mm512_max_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn abs(a: __m512) -> __m512 {
        _mm512_abs_ps(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn floor(a: __m512) -> __m512 {
        _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn round(a: __m512) -> __m512 {
        _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn to_int(a: __m512) -> __m512i {
        _mm512_cvtps_epi32(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn trunc_int(a: __m512) -> __m512i {
        _mm512_cvttps_epi32(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn to_bits(a: __m512) -> __m512i {
        _mm512_castps_si512(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn from_bits(a: __m512i) -> __m512 {
        _mm512_castsi512_ps(a)
    }

    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn splat_i(x: i32) -> __m512i {
        _mm512_set1_epi32(x)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn load_u32(s: &[u32]) -> __m512i {
        let s: &[u32; 16] = s[..16].try_into().expect("sixteen lanes");
        // SAFETY: reads exactly the sixteen integers of `s`.
        unsafe { _mm512_loadu_si512(s.as_ptr().cast()) }
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn store_u32(v: __m512i, d: &mut [u32]) {
        let d: &mut [u32; 16] = (&mut d[..16]).try_into().expect("sixteen lanes");
        // SAFETY: writes exactly the sixteen integers of `d`.
        unsafe { _mm512_storeu_si512(d.as_mut_ptr().cast(), v) }
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn to_float(a: __m512i) -> __m512 {
        _mm512_cvtepi32_ps(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn add_i(a: __m512i, b: __m512i) -> __m512i {
        _mm512_add_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn sub_i(a: __m512i, b: __m512i) -> __m512i {
        _mm512_sub_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn mul_i(a: __m512i, b: __m512i) -> __m512i {
        _mm512_mullo_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn min_i(a: __m512i, b: __m512i) -> __m512i {
        _mm512_min_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn max_i(a: __m512i, b: __m512i) -> __m512i {
        _mm512_max_epi32(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn and_i(a: __m512i, b: __m512i) -> __m512i {
        _mm512_and_si512(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn xor_i(a: __m512i, b: __m512i) -> __m512i {
        _mm512_xor_si512(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn shl30(a: __m512i) -> __m512i {
        _mm512_slli_epi32::<30>(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn sra23(a: __m512i) -> __m512i {
        _mm512_srai_epi32::<23>(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn inc_where(a: __m512i, m: __mmask16) -> __m512i {
        _mm512_mask_add_epi32(a, m, a, _mm512_set1_epi32(1))
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn reduce_min(a: __m512i) -> i32 {
        _mm512_reduce_min_epi32(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn reduce_max(a: __m512i) -> i32 {
        _mm512_reduce_max_epi32(a)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn first_i(a: __m512i) -> i32 {
        _mm_cvtsi128_si32(_mm512_castsi512_si128(a))
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn permute2(lo: __m512, hi: __m512, idx: __m512i) -> __m512 {
        _mm512_permutex2var_ps(lo, idx, hi)
    }

    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn lt(a: __m512, b: __m512) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn gt(a: __m512, b: __m512) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_GT_OQ>(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn ge(a: __m512, b: __m512) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_GE_OQ>(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn ne(a: __m512, b: __m512) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_NEQ_OQ>(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn eq_i(a: __m512i, b: __m512i) -> __mmask16 {
        _mm512_cmpeq_epi32_mask(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn le_u(a: __m512i, b: __m512i) -> __mmask16 {
        _mm512_cmple_epu32_mask(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn and_m(a: __mmask16, b: __mmask16) -> __mmask16 {
        a & b
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn or_m(a: __mmask16, b: __mmask16) -> __mmask16 {
        a | b
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn andnot_m(a: __mmask16, b: __mmask16) -> __mmask16 {
        !a & b
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn all(m: __mmask16) -> bool {
        m == u16::MAX
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn any(m: __mmask16) -> bool {
        m != 0
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn select(m: __mmask16, t: __m512, f: __m512) -> __m512 {
        _mm512_mask_mov_ps(f, m, t)
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn zero_unless(m: __mmask16, v: __m512) -> __m512 {
        _mm512_maskz_mov_ps(m, v)
    }

    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn load_ptr(p: *const f32) -> __m512 {
        // SAFETY: as the caller promises.
        unsafe { _mm512_loadu_ps(p) }
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn gather(p: *const f32, idx: __m512i) -> __m512 {
        // SAFETY: as the caller promises.
        unsafe { _mm512_i32gather_ps::<4>(idx, p) }
    }
    #[inline]
    #[target_feature(enable = "avx512f")]
    #[expect(
        clippy::cast_ptr_alignment,
        reason = "gathers need no alignment; the pointer type is the intrinsic's signature"
    )]
    unsafe fn gather_pairs(p: *const f32, idx: __m512i) -> (__m512, __m512) {
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
}

super::kernels::entry_points!(Avx512, "avx512f,avx2,fma");
