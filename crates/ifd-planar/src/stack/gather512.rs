//! The commonest per-pixel case, a per-pixel angle at a constant scale on a
//! one-channel stack read bilinearly, sixteen pixels at a time with AVX-512
//! gathers, on CPUs that have AVX-512F (detected at run time;
//! `IFD_SIMD=avx2` or `IFD_SIMD=baseline` leaves it to the eight-lane AVX2
//! kernels of [`super::gather`], which `IFD_SIMD` does not switch off).
//!
//! Twice the lanes halve the position, stencil and blend arithmetic per
//! pixel, which is most of a lookup's instructions once the loads are
//! gathered. The kernel writes [`super::gather`]'s expressions in its order
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

use super::gather::FixedTerm;
use super::{Interpolation, ScaleStack};

/// Pixels per AVX-512 block.
pub(crate) const LANES: usize = 16;

/// The wider kernel a per-pixel angle at a constant scale takes on this
/// CPU for a one-channel stack read bilinearly: `Some("avx512")` (sixteen
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
    if !(available()
        && stack.interpolation == Interpolation::Linear
        && super::gather::supports::<1>(stack))
    {
        return 0;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: `available` checked that the CPU has AVX-512F.
        unsafe { kernel::rotated_row(stack, terms, y, cs, ss, out) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (terms, y, cs, ss, out);
        0
    }
}

#[cfg(target_arch = "x86_64")]
mod kernel {
    use std::arch::x86_64::{
        __m512, _MM_FROUND_NO_EXC, _MM_FROUND_TO_NEG_INF, _mm512_add_epi32, _mm512_add_ps,
        _mm512_cmple_epu32_mask, _mm512_cvtps_epi32, _mm512_i32gather_ps, _mm512_loadu_ps,
        _mm512_max_epi32, _mm512_min_epi32, _mm512_mul_ps, _mm512_mullo_epi32,
        _mm512_roundscale_ps, _mm512_set1_epi32, _mm512_set1_ps, _mm512_setr_ps, _mm512_setzero_ps,
        _mm512_setzero_si512, _mm512_storeu_ps, _mm512_sub_ps,
    };

    use super::LANES;
    use crate::stack::gather::FixedTerm;

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

    /// `acc + w *` the bilinear lookups of `level` at `(px, py)` when every
    /// lane's 2x2 stencil lies in the stored level (the scalar lookup's
    /// interior test), `None` otherwise: `gather`'s AVX2 `bilinear`, in
    /// sixteen lanes.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn bilinear(level: &Level, px: __m512, py: __m512, w: __m512, acc: __m512) -> Option<__m512> {
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
        // Memory safety: every read below is at most `nx + 1` samples past
        // `idx <= nx (ny - 1) - 2`, inside the level's `nx ny` samples
        // (`gather::supports` checked the length).
        let idx = _mm512_min_epi32(
            _mm512_max_epi32(idx, _mm512_setzero_si512()),
            _mm512_set1_epi32(nx * (ny - 1) - 2),
        );
        let p = level.data.as_ptr();
        let row = nx as usize;
        // SAFETY: the reads at `idx` from `p`, `p + 1`, `p + nx` and
        // `p + nx + 1` end at `idx + nx + 1 < nx ny = data.len()` (above).
        let [a, b, c, d] = unsafe {
            [
                _mm512_i32gather_ps::<4>(idx, p),
                _mm512_i32gather_ps::<4>(idx, p.add(1)),
                _mm512_i32gather_ps::<4>(idx, p.add(row)),
                _mm512_i32gather_ps::<4>(idx, p.add(row + 1)),
            ]
        };
        // gather::avx2::blend's order of operations
        let r0 = _mm512_add_ps(a, _mm512_mul_ps(fu, _mm512_sub_ps(b, a)));
        let r1 = _mm512_add_ps(c, _mm512_mul_ps(fu, _mm512_sub_ps(d, c)));
        let value = _mm512_add_ps(r0, _mm512_mul_ps(fv, _mm512_sub_ps(r1, r0)));
        Some(_mm512_add_ps(acc, _mm512_mul_ps(w, value)))
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
        let lanes = _mm512_setr_ps(
            0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0,
        );
        for x0 in (0..n).step_by(LANES) {
            // pixel coordinates, exact below 2^24
            let xf = _mm512_add_ps(_mm512_set1_ps(x0 as f32), lanes);
            let (c, s) = (load_at(cs, x0), load_at(ss, x0));
            let mut acc = _mm512_setzero_ps();
            for t in terms {
                // gather::avx2::positions
                let (cx, cy) = (_mm512_set1_ps(t.cx), _mm512_set1_ps(t.cy));
                let px = _mm512_add_ps(
                    _mm512_add_ps(xf, _mm512_mul_ps(c, cx)),
                    _mm512_mul_ps(s, cy),
                );
                let py = _mm512_add_ps(
                    _mm512_sub_ps(yf, _mm512_mul_ps(s, cx)),
                    _mm512_mul_ps(c, cy),
                );
                for (li, w) in [(t.a, t.wa), (t.b, t.wb)] {
                    if w == 0.0 {
                        continue;
                    }
                    let level = &stack.levels[li];
                    acc = if let Some(sum) = bilinear(level, px, py, _mm512_set1_ps(w), acc) {
                        sum
                    } else {
                        // lane by lane, the scalar lookup resolving borders
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
    use crate::stack::gather::{self, FixedTerm};
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
            let done = gather::avx2_rotated_row_for_tests(&stack, &terms, y, &cs, &ss, &mut narrow);
            assert_eq!(done, width);
            for x in 0..width {
                assert_eq!(wide[x].to_bits(), narrow[x].to_bits(), "row {y}, pixel {x}");
            }
        }
    }
}
