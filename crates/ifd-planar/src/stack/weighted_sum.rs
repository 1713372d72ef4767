//! `out[k] = sum_d w[d] src[offsets[d] + k]`: the inner loop of the
//! direct separable prefilter ([`super::separable`]), written once as plain
//! lane-wise loops and compiled for AVX-512 (blocks of 128 outputs), AVX2
//! (64) and the baseline (32), chosen by [`ifd_simd::isa`].
//!
//! # Bits
//! Every output is the sum over taps in tap order. The AVX-512 and AVX2
//! kernels fuse each multiply-add and agree bit for bit (tested); the
//! baseline kernel rounds each product (a software fused multiply-add would
//! be slow) and agrees with them to rounding.
#![allow(
    unsafe_code,
    reason = "calling AVX2/AVX-512-compiled code after run-time detection; see `weighted_sum`"
)]

use ifd_simd::Isa;

/// `out[k] = sum_d w[d] src[offsets[d] + k]`, summed in tap order: fused
/// multiply-adds in the AVX-512 and AVX2 kernels (the same bits in both),
/// each product rounded in the baseline one (the module's "Bits").
///
/// # Panics
/// When `src` ends before `offsets[d] + out.len()` for some `d`.
///
/// # The `unsafe` here
/// Calling a function compiled for AVX2 or AVX-512 is `unsafe` in stable
/// Rust; each call is made only after [`ifd_simd::isa`] chose the
/// instruction set (which the CPU has). The kernels are safe code.
pub(super) fn weighted_sum(w: &[f32], src: &[f32], offsets: &[usize], out: &mut [f32]) {
    debug_assert_eq!(w.len(), offsets.len());
    #[cfg(target_arch = "x86_64")]
    match ifd_simd::isa() {
        Isa::Avx512 => {
            // SAFETY: the CPU has AVX-512F (detected at run time).
            unsafe { weighted_sum_avx512(w, src, offsets, out) };
            return;
        }
        Isa::Avx2 => {
            // SAFETY: the CPU has AVX2 (detected at run time).
            unsafe { weighted_sum_avx2(w, src, offsets, out) };
            return;
        }
        Isa::Baseline => {}
    }
    weighted_sum_body::<32, false>(w, src, offsets, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
fn weighted_sum_avx512(w: &[f32], src: &[f32], offsets: &[usize], out: &mut [f32]) {
    weighted_sum_body::<128, true>(w, src, offsets, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn weighted_sum_avx2(w: &[f32], src: &[f32], offsets: &[usize], out: &mut [f32]) {
    weighted_sum_body::<64, true>(w, src, offsets, out);
}

/// Blocks of `B` outputs (`B / lanes` vector accumulators), then blocks of
/// 16, then one output at a time; every output in tap order.
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target_feature caller, for its instruction set"
)]
fn weighted_sum_body<const B: usize, const FMA: bool>(
    w: &[f32],
    src: &[f32],
    offsets: &[usize],
    out: &mut [f32],
) {
    let n = out.len();
    let mut k0 = 0;
    while k0 + B <= n {
        block::<B, FMA>(w, src, offsets, k0, &mut out[k0..k0 + B]);
        k0 += B;
    }
    while k0 + 16 <= n {
        block::<16, FMA>(w, src, offsets, k0, &mut out[k0..k0 + 16]);
        k0 += 16;
    }
    for (k, o) in out.iter_mut().enumerate().skip(k0) {
        let mut acc = 0.0f32;
        for (wd, &off) in w.iter().zip(offsets) {
            acc = madd::<FMA>(*wd, src[off + k], acc);
        }
        *o = acc;
    }
}

#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target_feature caller, for its instruction set"
)]
fn block<const B: usize, const FMA: bool>(
    w: &[f32],
    src: &[f32],
    offsets: &[usize],
    k0: usize,
    out: &mut [f32],
) {
    let mut acc = [0.0f32; B];
    for (wd, &off) in w.iter().zip(offsets) {
        let s: &[f32; B] = src[off + k0..off + k0 + B].try_into().expect("B samples");
        for k in 0..B {
            acc[k] = madd::<FMA>(*wd, s[k], acc[k]);
        }
    }
    out.copy_from_slice(&acc);
}

/// `a b + c`, fused (one rounding) where the kernel is compiled with FMA.
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target_feature caller, for its instruction set"
)]
fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kernel this CPU runs against an `f64` sum, and the two fused
    /// kernels against each other bit for bit (same taps, same order).
    #[test]
    fn weighted_sum_kernels_agree() {
        let taps = 23;
        let n = 300; // 2 blocks of 128, then 16s, then single outputs
        let src: Vec<f32> = (0..n + 3 * taps)
            .map(|i| ((i * 37 % 101) as f32 - 50.0) / 7.0)
            .collect();
        let w: Vec<f32> = (0..taps).map(|d| 1.0 / (1.0 + d as f32)).collect();
        let offsets: Vec<usize> = (0..taps).map(|d| 3 * d).collect();
        let exact: Vec<f64> = (0..n)
            .map(|k| {
                w.iter()
                    .zip(&offsets)
                    .map(|(&wd, &o)| f64::from(wd) * f64::from(src[o + k]))
                    .sum()
            })
            .collect();
        let check = |name: &str, out: &[f32]| {
            for (k, (&o, &e)) in out.iter().zip(&exact).enumerate() {
                assert!(
                    (f64::from(o) - e).abs() < 1e-5 * (1.0 + e.abs()),
                    "{name} {k}: {o} vs {e}"
                );
            }
        };
        let mut base = vec![0.0f32; n];
        weighted_sum_body::<32, false>(&w, &src, &offsets, &mut base);
        check("baseline", &base);
        #[cfg(target_arch = "x86_64")]
        {
            let mut avx2 = vec![0.0f32; n];
            if ifd_simd::has(Isa::Avx2) {
                // SAFETY: AVX2 and FMA detected.
                unsafe { weighted_sum_avx2(&w, &src, &offsets, &mut avx2) };
                check("avx2", &avx2);
            }
            if ifd_simd::has(Isa::Avx512) {
                let mut avx512 = vec![0.0f32; n];
                // SAFETY: AVX-512F and FMA detected.
                unsafe { weighted_sum_avx512(&w, &src, &offsets, &mut avx512) };
                check("avx512", &avx512);
                assert_eq!(avx512, avx2, "the fused kernels differ");
            }
        }
    }
}
