//! The primitives the row kernels are written in: one vector of `N` `f32`
//! lanes ([`Lanes::F`]), of `N` `i32` lanes ([`Lanes::I`]) and an `N`-lane
//! mask ([`Lanes::M`]), with the operations [`super::kernels`] needs and
//! nothing more. Each instruction set implements them in a small file of its
//! own (`avx2.rs`: eight lanes, masks as vectors; `avx512.rs`: sixteen
//! lanes, masks as `k` registers), each primitive one or a few intrinsics.
//!
//! Every primitive is an IEEE operation lane by lane (no fused
//! multiply-add, no approximate reciprocal), so a kernel written once over
//! [`Lanes`] gives the same bits on each instruction set, and the scalar
//! loop's bits where it evaluates the scalar loop's expressions in their
//! order.
//!
//! # Safety
//! Every method is an `unsafe fn` compiled for its instruction set
//! (`#[target_feature]`): call it only from code compiled for that
//! instruction set too (the entry points in each instruction set's file),
//! which runs only after [`ifd_simd`] found it on the CPU. [`Lanes::gather`],
//! [`Lanes::gather_pairs`] and [`Lanes::load_ptr`] read through a raw
//! pointer: their callers keep every index in bounds.

/// `N` lanes of one instruction set (see the module documentation).
pub(super) trait Lanes: Copy {
    /// Lanes per vector.
    const N: usize;
    /// `N` floats.
    type F: Copy;
    /// `N` 32-bit integers.
    type I: Copy;
    /// `N` booleans.
    type M: Copy;
    /// `N` floats in memory (`[f32; N]`).
    type Floats: Copy + Default + AsRef<[f32]> + AsMut<[f32]>;

    // floats
    /// `x` in every lane.
    unsafe fn splat(x: f32) -> Self::F;
    /// `0.0` in every lane.
    unsafe fn zero() -> Self::F;
    /// `x0, x0 + 1, ..., x0 + N - 1` (exact below 2^24).
    unsafe fn columns(x0: usize) -> Self::F;
    /// The first `N` floats of `s`.
    unsafe fn load(s: &[f32]) -> Self::F;
    /// `v` into the first `N` floats of `d`.
    unsafe fn store(v: Self::F, d: &mut [f32]);
    /// `a + b`.
    unsafe fn add(a: Self::F, b: Self::F) -> Self::F;
    /// `a - b`.
    unsafe fn sub(a: Self::F, b: Self::F) -> Self::F;
    /// `a * b`.
    unsafe fn mul(a: Self::F, b: Self::F) -> Self::F;
    /// `a / b`.
    unsafe fn div(a: Self::F, b: Self::F) -> Self::F;
    /// `min(a, b)` (`b` where either is NaN, as `minps`).
    unsafe fn min(a: Self::F, b: Self::F) -> Self::F;
    /// `max(a, b)` (`b` where either is NaN, as `maxps`).
    unsafe fn max(a: Self::F, b: Self::F) -> Self::F;
    /// `|a|` (the sign bit cleared).
    unsafe fn abs(a: Self::F) -> Self::F;
    /// Rounded towards minus infinity.
    unsafe fn floor(a: Self::F) -> Self::F;
    /// Rounded to the nearest integer, ties to even.
    unsafe fn round(a: Self::F) -> Self::F;
    /// Converted to integers, rounding to nearest (exact for integral
    /// values; NaN and values past `i32` give `i32::MIN`).
    unsafe fn to_int(a: Self::F) -> Self::I;
    /// Converted to integers, truncating.
    unsafe fn trunc_int(a: Self::F) -> Self::I;
    /// The bits of each float.
    unsafe fn to_bits(a: Self::F) -> Self::I;
    /// Floats from their bits.
    unsafe fn from_bits(a: Self::I) -> Self::F;

    // integers
    /// `x` in every lane.
    unsafe fn splat_i(x: i32) -> Self::I;
    /// The first `N` integers of `s`.
    unsafe fn load_u32(s: &[u32]) -> Self::I;
    /// `v` into the first `N` integers of `d`.
    unsafe fn store_u32(v: Self::I, d: &mut [u32]);
    /// Integers converted to floats.
    unsafe fn to_float(a: Self::I) -> Self::F;
    /// `a + b`, wrapping.
    unsafe fn add_i(a: Self::I, b: Self::I) -> Self::I;
    /// `a - b`, wrapping.
    unsafe fn sub_i(a: Self::I, b: Self::I) -> Self::I;
    /// `a * b`, the low 32 bits.
    unsafe fn mul_i(a: Self::I, b: Self::I) -> Self::I;
    /// `min(a, b)`, signed.
    unsafe fn min_i(a: Self::I, b: Self::I) -> Self::I;
    /// `max(a, b)`, signed.
    unsafe fn max_i(a: Self::I, b: Self::I) -> Self::I;
    /// `a & b`.
    unsafe fn and_i(a: Self::I, b: Self::I) -> Self::I;
    /// `a ^ b`.
    unsafe fn xor_i(a: Self::I, b: Self::I) -> Self::I;
    /// `a << 30`.
    unsafe fn shl30(a: Self::I) -> Self::I;
    /// `a >> 23`, arithmetic.
    unsafe fn sra23(a: Self::I) -> Self::I;
    /// `a + 1` in the lanes of `m`, `a` elsewhere.
    unsafe fn inc_where(a: Self::I, m: Self::M) -> Self::I;
    /// The least lane, signed.
    unsafe fn reduce_min(a: Self::I) -> i32;
    /// The largest lane, signed.
    unsafe fn reduce_max(a: Self::I) -> i32;
    /// Lane 0.
    unsafe fn first_i(a: Self::I) -> i32;

    // masks
    /// `a < b` (ordered: false where either is NaN).
    unsafe fn lt(a: Self::F, b: Self::F) -> Self::M;
    /// `a > b` (ordered).
    unsafe fn gt(a: Self::F, b: Self::F) -> Self::M;
    /// `a >= b` (ordered).
    unsafe fn ge(a: Self::F, b: Self::F) -> Self::M;
    /// `a != b` (ordered: false where either is NaN).
    unsafe fn ne(a: Self::F, b: Self::F) -> Self::M;
    /// `a == b`, integers.
    unsafe fn eq_i(a: Self::I, b: Self::I) -> Self::M;
    /// `a <= b`, as unsigned integers.
    unsafe fn le_u(a: Self::I, b: Self::I) -> Self::M;
    /// `a & b`.
    unsafe fn and_m(a: Self::M, b: Self::M) -> Self::M;
    /// `a | b`.
    unsafe fn or_m(a: Self::M, b: Self::M) -> Self::M;
    /// `!a & b`.
    unsafe fn andnot_m(a: Self::M, b: Self::M) -> Self::M;
    /// Whether every lane is set.
    unsafe fn all(m: Self::M) -> bool;
    /// Whether some lane is set.
    unsafe fn any(m: Self::M) -> bool;
    /// `t` in the lanes of `m`, `f` elsewhere.
    unsafe fn select(m: Self::M, t: Self::F, f: Self::F) -> Self::F;
    /// `v` in the lanes of `m`, `0.0` elsewhere.
    unsafe fn zero_unless(m: Self::M, v: Self::F) -> Self::F;

    /// Lane `k` of the `2 N` floats `lo` then `hi` at `idx[k]` (each in
    /// `0 .. 2 N`; higher bits ignored).
    unsafe fn permute2(lo: Self::F, hi: Self::F, idx: Self::I) -> Self::F;

    // loads through a pointer
    /// The `N` floats from `p`.
    ///
    /// # Safety
    /// `p .. p + N` inside one allocation.
    unsafe fn load_ptr(p: *const f32) -> Self::F;
    /// The floats at `p + idx` (per lane).
    ///
    /// # Safety
    /// Every `p + idx` inside one allocation.
    unsafe fn gather(p: *const f32, idx: Self::I) -> Self::F;
    /// The floats at `p + idx` and `p + idx + 1` (per lane), read as one
    /// 64-bit element each (half the loads of two 32-bit gathers).
    ///
    /// # Safety
    /// Every `p + idx` and `p + idx + 1` inside one allocation.
    unsafe fn gather_pairs(p: *const f32, idx: Self::I) -> (Self::F, Self::F);
}

/// The end of the whole blocks of `V::N` pixels from `from` in `w` pixels.
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each `#[target_feature]` entry point"
)]
pub(super) fn block_end<V: Lanes>(from: usize, w: usize) -> usize {
    from + w.saturating_sub(from) / V::N * V::N
}
