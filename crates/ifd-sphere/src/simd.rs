//! Run-time dispatch of the SH kernels (the lane-wise Legendre recurrences of
//! [`crate::ShEvaluator::band_sums`] and of the equirect projection) to code
//! compiled for AVX2 when the CPU has it.
//!
//! The kernels are written once, as plain lane-wise loops over `[f64; N]`;
//! the dispatch compiles them a second time with AVX2 enabled (four `f64`
//! per vector instead of two) and picks one at run time. Both compute the
//! same IEEE operations lane by lane (Rust does not contract `a * b + c`
//! into fused multiply-adds), so their results are equal bit for bit
//! (tested). `IFD_SIMD=baseline` in the environment, or
//! [`set_vector_kernels`], forces the baseline code (to compare, or on a CPU
//! where AVX2 is slow).
//!
//! # The `unsafe` in this module
//! The workspace denies `unsafe`; this module is an exception for the one
//! thing stable Rust only offers as `unsafe`: calling a function compiled for
//! AVX2, which it does only after `is_x86_feature_detected!("avx2")` said the
//! CPU has it. The kernels themselves are safe code.
#![allow(
    unsafe_code,
    reason = "calling AVX2-compiled code after run-time detection; see the module documentation"
)]

use std::sync::atomic::{AtomicU8, Ordering};

/// 0: not decided yet, 1: baseline, 2: AVX2.
static CHOICE: AtomicU8 = AtomicU8::new(0);

fn detect() -> u8 {
    let forced = std::env::var("IFD_SIMD").is_ok_and(|v| v == "baseline");
    #[cfg(target_arch = "x86_64")]
    {
        if !forced && std::arch::is_x86_feature_detected!("avx2") {
            return 2;
        }
    }
    let _ = forced;
    1
}

fn choice() -> u8 {
    match CHOICE.load(Ordering::Relaxed) {
        0 => {
            let c = detect();
            CHOICE.store(c, Ordering::Relaxed);
            c
        }
        c => c,
    }
}

/// The vector kernels the SH kernels run: `Some("avx2")`, or `None` for the
/// baseline build's code (no AVX2, or forced).
///
/// ```
/// let k = ifd_sphere::vector_kernels();
/// assert!(k.is_none() || k == Some("avx2"));
/// ```
#[must_use]
pub fn vector_kernels() -> Option<&'static str> {
    (choice() == 2).then_some("avx2")
}

/// Allows (`true`: AVX2 where the CPU has it) or forbids (`false`: the
/// baseline code) the vector kernels, for the whole process; the results are
/// the same bit for bit, only the speed differs.
pub fn set_vector_kernels(enabled: bool) {
    let c = if enabled {
        CHOICE.store(0, Ordering::Relaxed);
        detect()
    } else {
        1
    };
    CHOICE.store(c, Ordering::Relaxed);
}

/// Runs `f`, compiled for AVX2 when [`vector_kernels`] says so. `f` should
/// call `#[inline(always)]` kernels, so that they are compiled into it.
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target of `simd::dispatch`"
)]
pub(crate) fn dispatch<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        if choice() == 2 {
            // SAFETY: the CPU has AVX2 (`detect` checked it at run time).
            return unsafe { with_avx2(f) };
        }
    }
    f()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    f()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{EquirectTransform, Negatives, ShEvaluator};

    /// The AVX2 and baseline kernels agree bit for bit (on a CPU without
    /// AVX2 both runs take the baseline and the test says so).
    #[test]
    fn vector_and_baseline_kernels_agree_bit_for_bit() {
        let l = 24;
        let sh = ShEvaluator::new(l).expect("evaluator");
        let n = (l + 1) * (l + 1);
        let f: Vec<f64> = (0..n * 3).map(|i| (i as f64 * 0.37).sin()).collect();
        let dirs = [
            [0.3, -0.2, 0.9],
            [0.0, 1.0, 0.0],
            [-0.5, 0.5, -0.7],
            [1.0, 0.0, 1e-3],
        ];
        let (w, h) = (96, 48);
        let img = ifd_image::Image::from_vec(
            w,
            h,
            3,
            (0..w * h * 3)
                .map(|i| ((i * 7919) % 1000) as f32 / 999.0)
                .collect(),
        )
        .expect("image");
        let t = EquirectTransform::new(l, w, h).expect("plan");
        let run = || {
            let mut out = vec![0.0; 4 * (l + 1) * 3];
            sh.band_sums(0, &dirs, &f, 3, &mut out);
            let a = t.analyze(&img, Negatives::Keep).expect("centre").coeffs;
            let b = t
                .analyze_texels(&img, Negatives::Keep)
                .expect("texel")
                .coeffs;
            (out, a.data().to_vec(), b.data().to_vec())
        };
        set_vector_kernels(false);
        assert_eq!(vector_kernels(), None);
        let base = run();
        set_vector_kernels(true);
        if vector_kernels().is_none() {
            eprintln!("no AVX2 on this CPU: only the baseline kernels ran");
        }
        let vector = run();
        assert!(
            base.0
                .iter()
                .zip(&vector.0)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        assert!(
            base.1
                .iter()
                .zip(&vector.1)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        assert!(
            base.2
                .iter()
                .zip(&vector.2)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
    }
}
