//! Run-time dispatch of the lane-wise kernels (the Legendre recurrences of
//! [`crate::ShEvaluator::band_sums`] and [`crate::ShEvaluator::band_sums_f32`],
//! the equirect projection, and, through [`run_vectorized`], `ifd-shade`'s
//! `f32` lobe lanes and `ifd-ibl`'s moments and bright-texel sums) to code
//! compiled for AVX2 + FMA or AVX-512 when the CPU has it.
//!
//! The kernels are written once, as plain lane-wise loops over `[f64; N]` or
//! `[f32; N]`; the dispatch compiles them again with AVX2 enabled (four `f64`
//! or eight `f32` per vector) and with AVX-512 (eight `f64`, sixteen `f32`)
//! and picks one at run time. All compute the same IEEE operations lane by
//! lane, so their results are equal bit for bit (tested): Rust does not
//! contract `a * b + c` into a fused multiply-add, and where a kernel asks
//! for one (`mul_add`, the `f32` kernels) it is exactly rounded everywhere
//! (in the baseline code a libm call, slow: `ifd-shade` runs its `f64`
//! lanes there instead). `IFD_SIMD=baseline` (or `avx2`) in the environment,
//! or [`set_vector_isa`], caps the instruction set (to compare, or on a CPU
//! where the wide vectors are slow).
//!
//! # The `unsafe` in this module
//! The workspace denies `unsafe`; this module is an exception for the one
//! thing stable Rust only offers as `unsafe`: calling a function compiled for
//! AVX2 or AVX-512, which it does only after `is_x86_feature_detected!` said
//! the CPU has the feature. The kernels themselves are safe code.
#![allow(
    unsafe_code,
    reason = "calling AVX2/AVX-512-compiled code after run-time detection; see the module documentation"
)]

use std::sync::atomic::{AtomicU8, Ordering};

/// The instruction sets the SH kernels are compiled for, in order.
///
/// ```
/// use ifd_sphere::{VectorIsa, set_vector_isa, vector_isa};
/// // cap at the baseline code: the CPU's vectors are not used
/// assert_eq!(set_vector_isa(VectorIsa::Baseline), VectorIsa::Baseline);
/// assert_eq!(vector_isa(), VectorIsa::Baseline);
/// // allow everything again: whatever this CPU has
/// let best = set_vector_isa(VectorIsa::Avx512);
/// assert!(best <= VectorIsa::Avx512);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum VectorIsa {
    /// The build's baseline (SSE2 on x86-64).
    Baseline,
    /// AVX2: 256-bit vectors.
    Avx2,
    /// AVX-512F: 512-bit vectors.
    Avx512,
}

impl VectorIsa {
    /// The name used by `IFD_SIMD` and reports: `baseline`, `avx2`, `avx512`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Baseline => "baseline",
            Self::Avx2 => "avx2",
            Self::Avx512 => "avx512",
        }
    }

    fn code(self) -> u8 {
        self as u8 + 1
    }

    fn from_code(c: u8) -> Self {
        match c {
            3 => Self::Avx512,
            2 => Self::Avx2,
            _ => Self::Baseline,
        }
    }
}

/// 0: not decided yet, else `VectorIsa::code`.
static CHOICE: AtomicU8 = AtomicU8::new(0);

/// The best instruction set of this CPU, at most `max`.
fn detect(max: VectorIsa) -> VectorIsa {
    #[cfg(target_arch = "x86_64")]
    {
        let avx2 = std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma");
        // (rustc's avx512f implies f16c, which every AVX-512 CPU has; checked
        // all the same)
        if max >= VectorIsa::Avx512
            && avx2
            && std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("f16c")
        {
            return VectorIsa::Avx512;
        }
        if max >= VectorIsa::Avx2 && avx2 {
            return VectorIsa::Avx2;
        }
    }
    let _ = max;
    VectorIsa::Baseline
}

/// The cap set by `IFD_SIMD` (`baseline`, `avx2`; anything else: none).
fn env_cap() -> VectorIsa {
    match std::env::var("IFD_SIMD").as_deref() {
        Ok("baseline") => VectorIsa::Baseline,
        Ok("avx2") => VectorIsa::Avx2,
        _ => VectorIsa::Avx512,
    }
}

fn choice() -> VectorIsa {
    match CHOICE.load(Ordering::Relaxed) {
        0 => {
            // first use: decide, unless a concurrent set_vector_isa did
            let c = detect(env_cap()).code();
            match CHOICE.compare_exchange(0, c, Ordering::Relaxed, Ordering::Relaxed) {
                Ok(_) => VectorIsa::from_code(c),
                Err(set) => VectorIsa::from_code(set),
            }
        }
        c => VectorIsa::from_code(c),
    }
}

/// The instruction set the SH kernels run on now.
#[must_use]
pub fn vector_isa() -> VectorIsa {
    choice()
}

/// Caps the instruction set of the SH kernels at `max` for the whole process
/// (the CPU's best up to `max`) and returns the one now in use; the results
/// are the same bit for bit, only the speed differs.
pub fn set_vector_isa(max: VectorIsa) -> VectorIsa {
    let c = detect(max);
    CHOICE.store(c.code(), Ordering::Relaxed);
    c
}

/// The vector kernels the SH kernels run: `Some("avx512")`, `Some("avx2")`,
/// or `None` for the baseline build's code (no wide vectors, or capped).
///
/// ```
/// let k = ifd_sphere::vector_kernels();
/// assert!(k.is_none() || k == Some("avx2") || k == Some("avx512"));
/// ```
#[must_use]
pub fn vector_kernels() -> Option<&'static str> {
    match choice() {
        VectorIsa::Baseline => None,
        isa => Some(isa.name()),
    }
}

/// Allows (`true`: the CPU's best, within an `IFD_SIMD` cap) or forbids
/// (`false`: the baseline code) the vector kernels, for the whole process; as
/// [`set_vector_isa`].
pub fn set_vector_kernels(enabled: bool) {
    set_vector_isa(if enabled {
        env_cap()
    } else {
        VectorIsa::Baseline
    });
}

/// A lane-wise kernel to run on the best instruction set of the CPU
/// ([`run_vectorized`]): its [`VectorKernel::run`] is marked
/// `#[inline(always)]` and calls `#[inline(always)]` code only (such as
/// [`crate::ShEvaluator::band_sums_f32_lanes`]), so that all of it is
/// compiled into each target. (A closure would not do: the compiler may
/// leave a large one out of line, compiled for the baseline.)
///
/// ```
/// use ifd_sphere::{VectorKernel, run_vectorized};
/// struct Dot<'a>(&'a [[f32; 8]], &'a [[f32; 8]]);
/// impl VectorKernel for Dot<'_> {
///     type Output = [f32; 8];
///     #[inline(always)]
///     fn run(self) -> [f32; 8] {
///         let mut s = [0.0; 8];
///         for (a, b) in self.0.iter().zip(self.1) {
///             for k in 0..8 {
///                 s[k] += a[k] * b[k];
///             }
///         }
///         s
///     }
/// }
/// let a = vec![[1.5f32; 8]; 4];
/// let b = vec![[2.0f32; 8]; 4];
/// assert_eq!(run_vectorized(Dot(&a, &b)), [12.0; 8]);
/// ```
pub trait VectorKernel {
    /// The result.
    type Output;
    /// The kernel's body (mark it `#[inline(always)]`).
    fn run(self) -> Self::Output;
}

/// Runs `k` compiled for the instruction set [`vector_isa`] names (lane-wise
/// IEEE arithmetic gives the same bits on each).
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target of `simd::run_vectorized`"
)]
pub fn run_vectorized<K: VectorKernel>(k: K) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    {
        match choice() {
            // SAFETY: the CPU has AVX-512F, AVX2 and FMA (`detect` checked them at run time).
            VectorIsa::Avx512 => return unsafe { kernel_avx512(k) },
            // SAFETY: the CPU has AVX2 and FMA (`detect` checked them at run time).
            VectorIsa::Avx2 => return unsafe { kernel_avx2(k) },
            VectorIsa::Baseline => {}
        }
    }
    k.run()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn kernel_avx2<K: VectorKernel>(k: K) -> K::Output {
    k.run()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f")]
unsafe fn kernel_avx512<K: VectorKernel>(k: K) -> K::Output {
    k.run()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{EquirectTransform, Negatives, ShEvaluator};

    /// The kernels' outputs: `f64` band sums, both projections, `f32` band
    /// sums at 16 and 8 lanes.
    type Outputs = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f32>, Vec<f32>);

    fn run_kernels() -> Outputs {
        let l = 24;
        let sh = ShEvaluator::new(l).expect("evaluator");
        let n = (l + 1) * (l + 1);
        let f: Vec<f64> = (0..n * 3).map(|i| (i as f64 * 0.37).sin()).collect();
        let f32s: Vec<f32> = f.iter().map(|&v| v as f32).collect();
        let dirs = [
            [0.3, -0.2, 0.9],
            [0.0, 1.0, 0.0],
            [-0.5, 0.5, -0.7],
            [1.0, 0.0, 1e-3],
        ];
        let dirs16: [[f32; 3]; 16] = std::array::from_fn(|k| {
            let t = k as f32 * 0.41;
            [t.cos(), (1.3 * t).sin(), 0.2 - 0.1 * k as f32]
        });
        let dirs8: [[f32; 3]; 8] = std::array::from_fn(|k| dirs16[2 * k]);
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
        let mut out = vec![0.0; 4 * (l + 1) * 3];
        sh.band_sums(0, &dirs, &f, 3, &mut out);
        let a = t.analyze(&img, Negatives::Keep).expect("centre").coeffs;
        let b = t
            .analyze_texels(&img, Negatives::Keep)
            .expect("texel")
            .coeffs;
        let mut acc16 = vec![[0.0f32; 16]; (l + 1) * 3];
        sh.band_sums_f32(2, &dirs16, &f32s, 3, &mut acc16);
        let mut acc8 = vec![[0.0f32; 8]; (l + 1) * 3];
        sh.band_sums_f32(0, &dirs8, &f32s, 3, &mut acc8);
        (
            out,
            a.data().to_vec(),
            b.data().to_vec(),
            acc16.concat(),
            acc8.concat(),
        )
    }

    fn same_bits<T: Copy + Into<f64>>(a: &[T], b: &[T]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (*x).into().to_bits() == (*y).into().to_bits())
    }

    /// The AVX-512, AVX2 and baseline kernels agree bit for bit (on a CPU
    /// without the wide vectors the runs take what it has, and the test says
    /// so); the `f32` lanes agree with the `f64` kernel to `1e-5` of the
    /// sums' size, and each lane is the same at 8 lanes as at 16.
    #[test]
    fn vector_and_baseline_kernels_agree_bit_for_bit() {
        assert_eq!(set_vector_isa(VectorIsa::Baseline), VectorIsa::Baseline);
        assert_eq!(vector_kernels(), None);
        let base = run_kernels();
        for isa in [VectorIsa::Avx2, VectorIsa::Avx512] {
            let got = set_vector_isa(isa);
            if got != isa {
                eprintln!("no {} on this CPU: {} ran", isa.name(), got.name());
            }
            let vector = run_kernels();
            assert!(same_bits(&base.0, &vector.0), "{}: band sums", got.name());
            assert!(same_bits(&base.1, &vector.1), "{}: centres", got.name());
            assert!(same_bits(&base.2, &vector.2), "{}: texels", got.name());
            assert!(same_bits(&base.3, &vector.3), "{}: f32 x16", got.name());
            assert!(same_bits(&base.4, &vector.4), "{}: f32 x8", got.name());
        }
        set_vector_kernels(true);
        // lane k of the 8-lane run is lane 2k of the 16-lane run (bands from 2 up)
        let nb = 25;
        for i in 2 * 3..nb * 3 {
            for k in 0..8 {
                assert_eq!(
                    base.4[i * 8 + k].to_bits(),
                    base.3[i * 16 + 2 * k].to_bits()
                );
            }
        }
        // f32 against f64 at the 16-lane directions
        let sh = ShEvaluator::new(24).expect("evaluator");
        let f: Vec<f64> = (0..nb * nb * 3).map(|i| (i as f64 * 0.37).sin()).collect();
        for k in 0..16 {
            let d = {
                let t = k as f32 * 0.41;
                [t.cos(), (1.3 * t).sin(), 0.2 - 0.1 * k as f32].map(f64::from)
            };
            let y = sh.eval(d);
            for l in 2..nb {
                for c in 0..3 {
                    let want: f64 = (l * l..(l + 1) * (l + 1))
                        .map(|i| f[i * 3 + c] * y[i])
                        .sum();
                    let size: f64 = (l * l..(l + 1) * (l + 1))
                        .map(|i| (f[i * 3 + c] * y[i]).abs())
                        .sum();
                    let got = f64::from(base.3[(l * 3 + c) * 16 + k]);
                    assert!(
                        (got - want).abs() <= 1e-5 * size,
                        "lane {k} band {l}: {got} vs {want}"
                    );
                }
            }
        }
    }
}
