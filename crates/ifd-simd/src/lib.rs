//! The vector instruction set ifd's kernels run on: one choice for the whole
//! process and every crate (the planar row kernels and direct prefilter, the
//! spherical-harmonic recurrences, the shading lanes, the IBL sums).
//!
//! # The rule
//! On x86-64 the choice is the widest of
//! - [`Isa::Avx512`]: AVX-512F, with AVX2, FMA and F16C (every AVX-512 CPU
//!   has them; checked all the same);
//! - [`Isa::Avx2`]: AVX2 with FMA;
//! - [`Isa::Baseline`]: the build's baseline (SSE2), and every other CPU;
//!
//! that the CPU has (`is_x86_feature_detected!`, once per process), capped by
//! the environment variable `IFD_SIMD`: `baseline` or `avx2` (any other
//! value, or none, caps nothing). [`set_isa`] caps it again for the whole
//! process, for tests that compare the paths.
//!
//! Every kernel gives the same bits on every path except where its
//! documentation says otherwise (the direct prefilter fuses multiply-adds on
//! AVX2 and AVX-512, not on the baseline).
//!
//! ```
//! use ifd_simd::{Isa, isa, set_isa};
//! // cap at the baseline code: the CPU's vectors are not used
//! assert_eq!(set_isa(Isa::Baseline), Isa::Baseline);
//! assert_eq!(isa(), Isa::Baseline);
//! // allow everything again: whatever this CPU has
//! let best = set_isa(Isa::Avx512);
//! assert!(best <= Isa::Avx512);
//! println!("vector path: {}", isa().name());
//! ```
//!
//! # The `unsafe` in this crate
//! The workspace denies `unsafe`; [`run_vectorized`] is an exception for the
//! one thing stable Rust only offers as `unsafe`: calling a function compiled
//! for AVX2 or AVX-512, which it does only after [`isa`] said the CPU has the
//! instruction set. The kernels it runs are safe code.
#![allow(
    unsafe_code,
    reason = "calling AVX2/AVX-512-compiled code after run-time detection; see the crate documentation"
)]

use std::sync::atomic::{AtomicU8, Ordering};

/// The instruction sets the kernels are compiled for, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Isa {
    /// The build's baseline (SSE2 on x86-64; every other architecture).
    Baseline,
    /// AVX2 with FMA: 256-bit vectors.
    Avx2,
    /// AVX-512F (with AVX2, FMA and F16C): 512-bit vectors.
    Avx512,
}

impl Isa {
    /// The name `IFD_SIMD` and the reports use: `baseline`, `avx2`, `avx512`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Baseline => "baseline",
            Self::Avx2 => "avx2",
            Self::Avx512 => "avx512",
        }
    }

    /// `f32` lanes per vector: 4 (SSE2), 8 or 16.
    #[must_use]
    pub fn f32_lanes(self) -> usize {
        match self {
            Self::Baseline => 4,
            Self::Avx2 => 8,
            Self::Avx512 => 16,
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

impl std::fmt::Display for Isa {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// 0: not decided yet, else `Isa::code`.
static CHOICE: AtomicU8 = AtomicU8::new(0);

/// The widest instruction set of this CPU, at most `max`.
fn detect(max: Isa) -> Isa {
    #[cfg(target_arch = "x86_64")]
    {
        let avx2 = std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma");
        if max >= Isa::Avx512
            && avx2
            && std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("f16c")
        {
            return Isa::Avx512;
        }
        if max >= Isa::Avx2 && avx2 {
            return Isa::Avx2;
        }
    }
    let _ = max;
    Isa::Baseline
}

/// The CPU's widest instruction set, detected once: `Isa::code`, 0 before.
static BEST: AtomicU8 = AtomicU8::new(0);

/// Whether this CPU has `isa` (whatever `IFD_SIMD` or [`set_isa`] cap):
/// code compiled for it may run. Detected once per process.
///
/// ```
/// assert!(ifd_simd::has(ifd_simd::Isa::Baseline));
/// ```
#[must_use]
pub fn has(isa: Isa) -> bool {
    let best = match BEST.load(Ordering::Relaxed) {
        0 => {
            let c = detect(Isa::Avx512).code();
            BEST.store(c, Ordering::Relaxed);
            c
        }
        c => c,
    };
    isa <= Isa::from_code(best)
}

/// The cap `IFD_SIMD` sets: `baseline`, `avx2`; any other value or none caps
/// nothing.
#[must_use]
pub fn env_cap() -> Isa {
    match std::env::var("IFD_SIMD").as_deref() {
        Ok("baseline") => Isa::Baseline,
        Ok("avx2") => Isa::Avx2,
        _ => Isa::Avx512,
    }
}

/// The instruction set every kernel runs on now (decided on first use: the
/// CPU's widest within `IFD_SIMD`'s cap, or what [`set_isa`] set).
#[must_use]
pub fn isa() -> Isa {
    match CHOICE.load(Ordering::Relaxed) {
        0 => {
            // first use: decide, unless a concurrent set_isa did
            let c = detect(env_cap()).code();
            match CHOICE.compare_exchange(0, c, Ordering::Relaxed, Ordering::Relaxed) {
                Ok(_) => Isa::from_code(c),
                Err(set) => Isa::from_code(set),
            }
        }
        c => Isa::from_code(c),
    }
}

/// Caps the instruction set at `max` for the whole process (the CPU's widest
/// up to `max`, `IFD_SIMD` not consulted) and returns the one now in use.
pub fn set_isa(max: Isa) -> Isa {
    let c = detect(max);
    CHOICE.store(c.code(), Ordering::Relaxed);
    c
}

/// A lane-wise kernel to run on the instruction set [`isa`] names
/// ([`run_vectorized`]): its [`VectorKernel::run`] is marked
/// `#[inline(always)]` and calls `#[inline(always)]` code only, so that all
/// of it is compiled into each target. (A closure would not do: the compiler
/// may leave a large one out of line, compiled for the baseline.)
///
/// ```
/// use ifd_simd::{VectorKernel, run_vectorized};
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

/// Runs `k` compiled for the instruction set [`isa`] names. Lane-wise IEEE
/// arithmetic gives the same bits on each: Rust does not contract `a * b + c`
/// into a fused multiply-add, and `mul_add` is exactly rounded everywhere (a
/// libm call in the baseline code, slow).
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target of `run_vectorized`"
)]
pub fn run_vectorized<K: VectorKernel>(k: K) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    {
        match isa() {
            // SAFETY: the CPU has AVX-512F, AVX2, FMA and F16C (`detect`).
            Isa::Avx512 => return unsafe { kernel_avx512(k) },
            // SAFETY: the CPU has AVX2 and FMA (`detect`).
            Isa::Avx2 => return unsafe { kernel_avx2(k) },
            Isa::Baseline => {}
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
#[target_feature(enable = "avx2,fma,f16c,avx512f")]
unsafe fn kernel_avx512<K: VectorKernel>(k: K) -> K::Output {
    k.run()
}

#[cfg(test)]
mod tests {
    use super::{Isa, detect, isa, set_isa};

    /// A cap is never exceeded, and capping at the CPU's best gives it back.
    #[test]
    fn caps_hold() {
        let best = detect(Isa::Avx512);
        for cap in [Isa::Baseline, Isa::Avx2, Isa::Avx512] {
            let got = set_isa(cap);
            assert!(
                got <= cap && got <= best,
                "{got} under cap {cap}, best {best}"
            );
            assert_eq!(isa(), got);
        }
        assert_eq!(set_isa(Isa::Avx512), best);
        assert!(super::has(best) && super::has(Isa::Baseline));
        assert_eq!(super::has(Isa::Avx512), best == Isa::Avx512);
    }

    /// Names and lane counts as documented.
    #[test]
    fn names() {
        assert_eq!(
            [Isa::Baseline, Isa::Avx2, Isa::Avx512].map(Isa::name),
            ["baseline", "avx2", "avx512"]
        );
        assert_eq!(Isa::Avx512.f32_lanes(), 16);
        assert_eq!(Isa::Avx2.to_string(), "avx2");
    }
}
