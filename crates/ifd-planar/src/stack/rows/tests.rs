//! The row kernels against the scalar rules and each other: every width
//! bit for bit the scalar loop's (the integration tests check whole
//! filters end to end).

use super::{
    FixedTerm, LevelRule, RowLevels, RowOut, ScalePosition, ScaledTerm, fill_levels, on_isa,
    rotated_row_on, rotations, scale_positions, scaled_row_on,
};
use crate::field::Field;
use crate::stack::locate::{NEAREST_SNAP, PIXEL_SNAP};
use crate::stack::{Interpolation, ScaleStack, StackOptions};
use crate::trig::sin_cos_degrees;
use crate::{Border, Sampling};
use ifd_image::Image;
use ifd_simd::Isa;

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
            on_isa::rotations(Isa::Avx2, &theta, scale, &mut cs, &mut ss)
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
        let n = on_isa::scale_positions(Isa::Avx2, rule, &scales, &mut t_2, &mut widen_2);
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

/// Every pixel's levels and weights, from the vector rows (the widest
/// the CPU has, and AVX2), bit for bit [`LevelRule::at`]'s: positions below the first level and past the
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
            // needs the logarithm: just past the switch to wide footprints
            3 => [0.5, 0.06, 3.0, 40.0, 900.0][x / 5 % 5],
            _ => -0.999, // past the floor
        })
        .collect();
    let (mut snapped, mut read) = (0, 0);
    // fill_levels (sixteen lanes where the CPU has AVX-512), and the
    // eight AVX2 lanes whatever wider ones the CPU has (then the scalar
    // rule for the row's tail)
    let passes = 2;
    for pass in 0..passes {
        let mut levels = RowLevels::new(2, w);
        if pass == 0 {
            fill_levels(rule, &t_s, &widen, &mut levels, 1);
        } else {
            let done = on_isa::fill_levels(Isa::Avx2, rule, &t_s, &widen, &mut levels, 1);
            for x in done..w {
                levels.set(w + x, rule.at(t_s[x], widen[x]));
            }
        }
        for x in 0..w {
            let (a, b, wa, wb) = rule.at(t_s[x], widen[x]);
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
    assert!(
        snap < 0.5 || snapped + 2 * passes >= read,
        "{snapped} of {read}"
    );
}

/// A stack of a `w x h x c` test pattern at `sigmas`.
fn patterned_stack(
    (w, h, c): (usize, usize, usize),
    sigmas: &[f64],
    interpolation: Interpolation,
) -> ScaleStack {
    let mut img = Image::new(w, h, c).expect("image");
    for (i, v) in img.data_mut().iter_mut().enumerate() {
        *v = ((i * 7919) % 1013) as f32 / 1013.0 - 0.3;
    }
    let options = StackOptions {
        interpolation,
        ..StackOptions::default()
    };
    ScaleStack::with_sigmas(&img, sigmas, Border::Reflect101, options).expect("stack")
}

/// Row terms from `(cx, cy, a, b, wa, wb)`.
fn fixed_terms(terms: &[(f32, f32, usize, usize, f32, f32)]) -> Vec<FixedTerm> {
    terms
        .iter()
        .map(|&(cx, cy, a, b, wa, wb)| FixedTerm {
            cx,
            cy,
            a,
            b,
            wa,
            wb,
        })
        .collect()
}

/// The AVX-512 rows bit for bit the AVX2 rows (each the scalar loop's,
/// as the integration tests check end to end): lanes inside and outside
/// the stored levels (a kernel reaching past the borders), a level pair
/// and single levels, pyramid steps.
#[test]
fn sixteen_lanes_equal_eight() {
    if !ifd_simd::has(Isa::Avx512) {
        // counted as skipped, not passed (tests/support/skip.rs)
        crate::test_skip::skip("no AVX-512F: nothing to compare");
        return;
    }
    let (w, h) = (83, 37);
    let stack = patterned_stack((w, h, 1), &[1.5, 3.0, 6.0], Interpolation::Linear);
    // pyramid steps 1, 1 and 2 (factor 2): the kernel reads each grid
    assert!(stack.level_layouts().any(|l| l.step > 1));
    let terms = fixed_terms(&[
        (0.0, 0.0, 0, 0, 1.0, 0.0),
        (5.5, -2.25, 0, 1, 0.7, 0.3),
        (-30.0, 12.0, 1, 2, 0.25, 0.75),
        (60.0, 41.0, 2, 2, -0.5, 0.0),
    ]);
    let width = 5 * 16;
    for y in [0, 5, 18, 36] {
        let (cs, ss): (Vec<f32>, Vec<f32>) = (0..width)
            .map(|x| {
                let (sin, cos) = sin_cos_degrees(x as f32 * 7.3 - 40.0 + y as f32);
                (cos * 0.9, sin * 0.9)
            })
            .unzip();
        let (mut wide, mut narrow) = (vec![0.25f32; width], vec![0.25f32; width]);
        let done = rotated_row_on::<1>(
            Isa::Avx512,
            &stack,
            &terms,
            y,
            (&cs, &ss),
            RowOut::dense(&mut wide),
        );
        assert_eq!(done, width);
        let done = rotated_row_on::<1>(
            Isa::Avx2,
            &stack,
            &terms,
            y,
            (&cs, &ss),
            RowOut::dense(&mut narrow),
        );
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
    if !ifd_simd::has(Isa::Avx512) {
        // counted as skipped, not passed (tests/support/skip.rs)
        crate::test_skip::skip("no AVX-512F: nothing to compare");
        return;
    }
    let (w, h) = (97, 41);
    let sigmas = [1.2, 1.7, 2.4, 3.4, 4.8, 6.8];
    let stack = patterned_stack((w, h, 1), &sigmas, Interpolation::Linear);
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
    let width = 6 * 16;
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
            let block = x / 16;
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
        let done = scaled_row_on::<1>(
            Isa::Avx512,
            &stack,
            &terms,
            &levels,
            y,
            (&cs, &ss),
            RowOut::dense(&mut wide),
        );
        assert_eq!(done, width);
        let done = scaled_row_on::<1>(
            Isa::Avx2,
            &stack,
            &terms,
            &levels,
            y,
            (&cs, &ss),
            RowOut::dense(&mut narrow),
        );
        assert_eq!(done, width);
        for x in 0..width {
            assert_eq!(wide[x].to_bits(), narrow[x].to_bits(), "row {y}, pixel {x}");
        }
    }
}

/// The scalar lookups' sum at pixel `(x, y)` with rotation `(cs, ss)`: each
/// term's levels in order, one or three channels (the stack's), as the
/// scalar loop sums them.
fn scalar_sum(
    stack: &ScaleStack,
    terms: &[FixedTerm],
    (x, y): (usize, usize),
    (cs, ss): (f32, f32),
) -> [f32; 3] {
    let mut sum = [0.0f32; 3];
    for t in terms {
        let sx = x as f32 + cs * t.cx + ss * t.cy;
        let sy = y as f32 - ss * t.cx + cs * t.cy;
        for (li, wl) in [(t.a, t.wa), (t.b, t.wb)] {
            if wl != 0.0 {
                match stack.channels {
                    1 => stack.accumulate_fixed::<1>(
                        li,
                        sx,
                        sy,
                        wl,
                        (&mut sum[..1]).try_into().expect("one"),
                    ),
                    _ => stack.accumulate_fixed::<3>(li, sx, sy, wl, &mut sum),
                }
            }
        }
    }
    sum
}

/// A packed, weighted row ([`RowOut`] with `pixels` and `weight`): each
/// entry's sum, times its weight, lands on its listed pixel, bit for bit the
/// scalar lookups', at sixteen lanes (then eight) and at eight alone: a
/// whole block of zero weights (skipped), zero weights inside blocks,
/// pixels out of order, and padding entries that repeat the last pixel with
/// weight zero (they add nothing: not even `0 * sum`).
#[test]
fn packed_weighted_rows_equal_the_scalar_lookups() {
    if !ifd_simd::has(Isa::Avx2) {
        crate::test_skip::skip("no AVX2: nothing to compare");
        return;
    }
    let (w, h) = (71, 29);
    let pixels: Vec<u32> = (0..16)
        .map(|k| 3 + k)
        .chain((0..14).map(|k| 60 - 3 * k))
        .chain([5, 70, 0, 1, 2, 70, 70, 70, 70, 70])
        .collect();
    let weight: Vec<f32> = (0..pixels.len())
        .map(|k| match k {
            0..16 => 0.0,
            _ if k % 5 == 0 => 0.0,
            _ if k >= 35 => 0.0,
            _ => 0.25 + (k % 7) as f32 * 0.5 - 1.0,
        })
        .collect();
    for (channels, interpolation) in [
        (1, Interpolation::Linear),
        (1, Interpolation::Cubic),
        (3, Interpolation::Linear),
    ] {
        let stack = patterned_stack((w, h, channels), &[1.5, 3.0], interpolation);
        let terms = fixed_terms(&[(0.0, 0.0, 0, 0, 1.0, 0.0), (9.5, -2.25, 0, 1, 0.6, 0.4)]);
        let y = 14;
        let (cs, ss): (Vec<f32>, Vec<f32>) = pixels
            .iter()
            .map(|&x| {
                let (sin, cos) = sin_cos_degrees(x as f32 * 11.0 + y as f32);
                (cos * 1.1, sin * 1.1)
            })
            .unzip();
        let mut want = vec![0.25f32; w * channels];
        for (k, &x) in pixels.iter().enumerate() {
            if weight[k] == 0.0 {
                continue;
            }
            let x = x as usize;
            let sum = scalar_sum(&stack, &terms, (x, y), (cs[k], ss[k]));
            for (o, s) in want[x * channels..(x + 1) * channels].iter_mut().zip(sum) {
                *o += weight[k] * s;
            }
        }
        for isa in [Isa::Avx512, Isa::Avx2] {
            if !ifd_simd::has(isa) {
                continue;
            }
            let mut got = vec![0.25f32; w * channels];
            let out = RowOut {
                row: &mut got,
                weight: Some(&weight),
                pixels: Some(&pixels),
            };
            let done = match channels {
                1 => rotated_row_on::<1>(isa, &stack, &terms, y, (&cs, &ss), out),
                _ => rotated_row_on::<3>(isa, &stack, &terms, y, (&cs, &ss), out),
            };
            assert_eq!(done, pixels.len(), "{isa}");
            for (i, (g, v)) in got.iter().zip(&want).enumerate() {
                assert_eq!(
                    g.to_bits(),
                    v.to_bits(),
                    "{isa}, {channels} channels {interpolation:?}, sample {i}"
                );
            }
        }
        // a listed pixel outside the row: the kernels refuse the row
        let bad: Vec<u32> = pixels.iter().map(|&x| x + 1).collect();
        let mut got = vec![0.0f32; w * channels];
        let out = RowOut {
            row: &mut got,
            weight: Some(&weight),
            pixels: Some(&bad),
        };
        let done = match channels {
            1 => rotated_row_on::<1>(Isa::Avx2, &stack, &terms, y, (&cs, &ss), out),
            _ => rotated_row_on::<3>(Isa::Avx2, &stack, &terms, y, (&cs, &ss), out),
        };
        assert_eq!(done, 0);
    }
}

/// The kernels' other shapes at both widths and against the scalar
/// lookups, bit for bit: three channels read bilinearly and one and three
/// read with cubic B-splines (sixteen lanes, then eight, then the scalar
/// lookup of each pixel), lanes inside and outside the stored levels.
#[test]
fn channels_and_cubic_equal_the_scalar_lookups() {
    if !ifd_simd::has(Isa::Avx2) {
        crate::test_skip::skip("no AVX2: nothing to compare");
        return;
    }
    for (channels, interpolation) in [
        (3, Interpolation::Linear),
        (1, Interpolation::Cubic),
        (3, Interpolation::Cubic),
    ] {
        let (w, h) = (71, 29);
        let stack = patterned_stack((w, h, channels), &[1.5, 3.0], interpolation);
        let terms = fixed_terms(&[(0.0, 0.0, 0, 0, 1.0, 0.0), (9.5, -2.25, 0, 1, 0.6, 0.4)]);
        // 3 blocks of 16 and one of 8
        let width = 56;
        for y in [0, 14, 28] {
            let (cs, ss): (Vec<f32>, Vec<f32>) = (0..width)
                .map(|x| {
                    let (sin, cos) = sin_cos_degrees(x as f32 * 11.0 + y as f32);
                    (cos * 1.1, sin * 1.1)
                })
                .unzip();
            let mut want = vec![0.25f32; width * channels];
            for (x, px) in want.chunks_exact_mut(channels).enumerate() {
                // the scalar loop's order: every term's lookups summed, then
                // added to the output
                let sum = scalar_sum(&stack, &terms, (x, y), (cs[x], ss[x]));
                for (o, s) in px.iter_mut().zip(sum) {
                    *o += s;
                }
            }
            for isa in [Isa::Avx512, Isa::Avx2] {
                if !ifd_simd::has(isa) {
                    continue;
                }
                let mut got = vec![0.25f32; width * channels];
                let done = match channels {
                    1 => rotated_row_on::<1>(
                        isa,
                        &stack,
                        &terms,
                        y,
                        (&cs, &ss),
                        RowOut::dense(&mut got),
                    ),
                    _ => rotated_row_on::<3>(
                        isa,
                        &stack,
                        &terms,
                        y,
                        (&cs, &ss),
                        RowOut::dense(&mut got),
                    ),
                };
                assert_eq!(done, width, "{isa}");
                for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                    assert_eq!(
                        g.to_bits(),
                        w.to_bits(),
                        "{isa}, {channels} channels {interpolation:?}, row {y}, sample {i}"
                    );
                }
            }
        }
    }
}

/// The contiguous-window lookups (rows loaded whole, each lane's samples
/// permuted out of them) bit for bit the scalar lookups, bilinear and cubic,
/// on a rotation that varies slowly along the row as real angle maps do:
/// blocks whose lanes read one row pair, blocks that straddle a row either
/// way, and blocks spread too wide, which gather.
#[test]
fn window_lookups_equal_the_scalar_lookups() {
    if !ifd_simd::has(Isa::Avx2) {
        crate::test_skip::skip("no AVX2: nothing to compare");
        return;
    }
    for interpolation in [Interpolation::Linear, Interpolation::Cubic] {
        let (w, h) = (211, 64);
        let stack = patterned_stack((w, h, 1), &[1.5, 3.0, 6.0], interpolation);
        assert!(stack.level_layouts().any(|l| l.step > 1));
        let terms = fixed_terms(&[
            (0.0, 0.0, 0, 0, 1.0, 0.0),
            (5.5, -2.25, 0, 1, 0.6, 0.4),
            (40.0, -12.0, 1, 2, 0.25, 0.75),
            (-30.0, 17.0, 2, 2, -0.5, 0.0),
        ]);
        let width = 12 * 16;
        let mut paths = [[0usize; 4]; 2];
        for y in [0, 9, 31, 50, 63] {
            // 0.15 degrees a pixel, faster near the row's end: lanes drift
            // across level rows within a block, and spread past the window
            let (cs, ss): (Vec<f32>, Vec<f32>) = (0..width)
                .map(|x| {
                    let xf = x as f32;
                    let turn = if x < 160 {
                        0.15 * xf
                    } else {
                        24.0 + 6.0 * (xf - 160.0)
                    };
                    let (sin, cos) = sin_cos_degrees(30.0 + turn + 2.0 * y as f32);
                    (cos * 0.9, sin * 0.9)
                })
                .unzip();
            let mut want = vec![0.25f32; width];
            for (x, o) in want.iter_mut().enumerate() {
                let mut sum = [0.0f32];
                for t in &terms {
                    let sx = x as f32 + cs[x] * t.cx + ss[x] * t.cy;
                    let sy = y as f32 - ss[x] * t.cx + cs[x] * t.cy;
                    for (li, wl) in [(t.a, t.wa), (t.b, t.wb)] {
                        if wl != 0.0 {
                            stack.accumulate_fixed::<1>(li, sx, sy, wl, &mut sum);
                        }
                    }
                }
                *o += sum[0];
            }
            for isa in [Isa::Avx512, Isa::Avx2] {
                if !ifd_simd::has(isa) {
                    continue;
                }
                let mut got = vec![0.25f32; width];
                let before = super::kernels::LOOKUPS.with(std::cell::Cell::get);
                let done = rotated_row_on::<1>(
                    isa,
                    &stack,
                    &terms,
                    y,
                    (&cs, &ss),
                    RowOut::dense(&mut got),
                );
                let after = super::kernels::LOOKUPS.with(std::cell::Cell::get);
                let counts = &mut paths[usize::from(isa == Isa::Avx2)];
                for (c, (a, b)) in counts.iter_mut().zip(after.iter().zip(before)) {
                    *c += a - b;
                }
                assert_eq!(done, width, "{isa}");
                for (x, (g, w)) in got.iter().zip(&want).enumerate() {
                    assert_eq!(
                        g.to_bits(),
                        w.to_bits(),
                        "{isa}, {interpolation:?}, row {y}, pixel {x}"
                    );
                }
            }
        }
        // every path served some lookups at each width the CPU has: windows
        // on one row pair, with lanes above and below, and gathers
        for (isa, counts) in [Isa::Avx512, Isa::Avx2].into_iter().zip(paths) {
            if ifd_simd::has(isa) {
                assert!(
                    counts.iter().all(|&n| n > 0),
                    "{isa}, {interpolation:?}: lookups by path (window, above, below, gather) {counts:?}"
                );
            }
        }
    }
}
