//! Prefiltering and IFD filtering benchmarks.
//!
//! `cargo bench -p ifd-planar --bench filtering`. Groups:
//! - `prefilter`: scale stack of a 1024x1024 single-channel image over sigma
//!   1..32 px at 4 levels per octave (throughput in pixels: time per megapixel).
//! - `terms`: filtering a 256x256 image as a function of the number of terms
//!   `s`, constant angle and scale, and per-pixel angle (throughput in
//!   pixels; lookups/s = pixels/s * s, each lookup trilinear).
//! - `extent`: spatially varying (smooth angle field) 8:1 anisotropic Gaussian
//!   on a 1024x1024 image at kernel extents 31, 63, 127, 255. IFD filters the
//!   whole image (prefiltering excluded, it is in `prefilter`); brute force
//!   (`reference::correlate_varying_rows`, one closure call per tap) is timed
//!   on a **sample of rows only** — the bench id says how many of the 1024
//!   rows — so compare the reported throughputs (pixels/s), not the times.
//!   The PSNR of IFD against brute force on those rows is printed at setup.
//!
//! - `throughput`: term evaluations per second (the throughput unit is one
//!   term at one pixel) of the per-pixel paths on a 1024x1024 image, 57-term
//!   8:1 line of Gaussians at extent 255 with a smooth angle field: per-pixel
//!   angle at a constant scale (levels at the terms' exact sigmas, one lookup
//!   per term, bilinear and cubic B-spline), per-pixel angle and scale
//!   (log-uniform stack, two lookups per term), and `gather_limit_bilinear`,
//!   the machine's limit for the first: the same bilinear lookups at the same
//!   positions of the same stack with no filter logic (no border handling,
//!   level chosen beforehand, one channel), and `gather_limit_avx2`, the same
//!   loop eight pixels at a time with AVX2 gathers (the limit of ifd's vector
//!   kernels; skipped without AVX2) and `gather_limit_avx2_l1`, that loop with
//!   every term at the pixel itself (all lookups in L1: the difference is
//!   what the memory hierarchy costs). Each ifd path runs twice: with the vector
//!   gathers (the default) and with the scalar loop (`_scalar`). Report ifd as
//!   a fraction of the limits. Run with `RAYON_NUM_THREADS=1` for per-thread
//!   numbers.
//!
//! Both sides use rayon's default thread count.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ifd_planar::internals::reference::correlate_varying_rows;
use ifd_planar::{
    Border, Decomposition, Field, Filter, Interpolation, ScaleStack, StackOptions, Term,
    stack_for_decomposition, stack_plan_for_decomposition,
};
use rayon::prelude::*;

#[path = "../../../tests/support/images.rs"]
mod images;

use images::disk_noise as test_image;

/// An 8:1 anisotropic Gaussian along x with `sigma_x = 5`, `sigma_y = 0.625`
/// (extent 31 = support of `+-3 sigma_x`): a line of isotropic Gaussians of
/// sigma `sigma_y` at spacing `sigma_y`, weighted by a Gaussian profile.
fn line_decomposition() -> (Decomposition, f64, f64) {
    let (sx, sy) = (5.0f64, 0.625f64);
    let profile = (sx * sx - sy * sy).sqrt();
    let mut terms = Vec::new();
    let n = (3.5 * sx / sy).ceil() as i32;
    for i in -n..=n {
        let x = f64::from(i) * sy;
        terms.push(Term {
            weight: (-(x * x) / (2.0 * profile * profile)).exp(),
            x,
            y: 0.0,
            sigma: sy,
        });
    }
    let total: f64 = terms.iter().map(|t| t.weight).sum();
    for t in &mut terms {
        t.weight /= total;
    }
    (Decomposition::from_terms(terms), sx, sy)
}

/// `s` displaced Gaussians of varied sigma spread over a 30 px disc.
fn random_decomposition(s: usize) -> Decomposition {
    let mut next = images::xorshift(0x9e37_79b9_7f4a_7c15);
    Decomposition::from_terms(
        (0..s)
            .map(|_| Term {
                weight: next() - 0.3,
                x: 30.0 * (next() - 0.5),
                y: 30.0 * (next() - 0.5),
                sigma: 1.0 + 4.0 * next(),
            })
            .collect(),
    )
}

fn angle_field(w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 / w as f32, (i / w) as f32 / h as f32);
            180.0 * x + 45.0 * (std::f32::consts::PI * y).sin()
        })
        .collect()
}

fn prefilter(c: &mut Criterion) {
    let img = test_image(1024, 1024);
    let mut g = c.benchmark_group("prefilter");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    g.throughput(Throughput::Elements(1024 * 1024));
    g.bench_function("1024x1024x1_sigma_1_to_32_4_per_octave", |b| {
        b.iter(|| {
            ScaleStack::new(
                black_box(&img),
                1.0,
                32.0,
                Border::Reflect101,
                StackOptions::default(),
            )
            .expect("stack")
        });
    });
    g.finish();
}

fn terms(c: &mut Criterion) {
    let (w, h) = (256, 256);
    let img = test_image(w, h);
    let angles = angle_field(w, h);
    let mut g = c.benchmark_group("terms");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(500));
    g.throughput(Throughput::Elements((w * h) as u64));
    for s in [4usize, 16, 64, 256] {
        let d = random_decomposition(s);
        let stack = stack_for_decomposition(
            &img,
            &d,
            1.0,
            1.0,
            Border::Reflect101,
            StackOptions::default(),
        )
        .expect("stack");
        let f = Filter::new(&stack, &d).expect("filter");
        g.bench_with_input(BenchmarkId::new("constant_angle", s), &s, |b, _| {
            b.iter(|| {
                f.apply(Field::Constant(30.0), Field::Constant(1.0))
                    .expect("apply")
            });
        });
        g.bench_with_input(BenchmarkId::new("per_pixel_angle", s), &s, |b, _| {
            b.iter(|| {
                f.apply(Field::Map(&angles), Field::Constant(1.0))
                    .expect("apply")
            });
        });
    }
    g.finish();
}

fn psnr(a: &[f32], b: &[f32]) -> f64 {
    let mse = a
        .iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
        .sum::<f64>()
        / a.len() as f64;
    10.0 * (1.0 / mse.max(1e-30)).log10()
}

fn extent(c: &mut Criterion) {
    let (w, h) = (1024usize, 1024usize);
    let img = test_image(w, h);
    let angles = angle_field(w, h);
    let (d, sx, sy) = line_decomposition();
    let mut g = c.benchmark_group("extent");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_millis(500));
    for extent in [31usize, 63, 127, 255] {
        let s = (extent - 1) as f32 / 30.0;
        let radius = (extent - 1) / 2;
        let stack =
            stack_for_decomposition(&img, &d, s, s, Border::Reflect101, StackOptions::default())
                .expect("stack");
        let f = Filter::new(&stack, &d).expect("filter");
        g.throughput(Throughput::Elements((w * h) as u64));
        g.bench_with_input(
            BenchmarkId::new("ifd_full_image", extent),
            &extent,
            |b, _| {
                b.iter(|| {
                    f.apply(Field::Map(&angles), Field::Constant(s))
                        .expect("apply")
                });
            },
        );
        // The analytic kernel: k(u, v) = exp(-(u^2/sx^2 + v^2/sy^2)/2) / (2 pi sx sy).
        let (a, b) = (1.0 / (2.0 * sx * sx), 1.0 / (2.0 * sy * sy));
        let norm = 1.0 / (2.0 * std::f64::consts::PI * sx * sy);
        let kernel = move |u: f64, v: f64| norm * (-(a * u * u + b * v * v)).exp();
        let rows = (64 * 31 * 31 / (extent * extent)).max(1);
        let first = h / 2 - rows / 2;
        let brute = || {
            correlate_varying_rows(
                &img,
                radius,
                Field::Map(&angles),
                Field::Constant(s),
                Border::Reflect101,
                kernel,
                first..first + rows,
            )
            .expect("reference")
        };
        // PSNR printed once, only when this bench is selected.
        let report = std::sync::Once::new();
        let check = || {
            let want = brute();
            let got = f
                .apply(Field::Map(&angles), Field::Constant(s))
                .expect("apply");
            let p = psnr(&got.data()[first * w..(first + rows) * w], want.data());
            eprintln!(
                "extent {extent}: {} terms, IFD vs brute force on {rows} rows: PSNR {p:.1} dB",
                f.len()
            );
        };
        g.throughput(Throughput::Elements((w * rows) as u64));
        g.bench_with_input(
            BenchmarkId::new(format!("brute_force_{rows}_of_1024_rows"), extent),
            &extent,
            |bch, _| {
                report.call_once(check);
                bch.iter(brute);
            },
        );
    }
    g.finish();
}

/// Every level of `stack` as `(samples, origin, 1 / step, nx, ny)`.
fn level_views(stack: &ScaleStack) -> Vec<LevelView<'_>> {
    stack
        .level_layouts()
        .enumerate()
        .map(|(i, l)| {
            (
                stack.level_data(i).expect("level"),
                l.origin as f32,
                1.0 / l.step as f32,
                l.nx,
                l.ny,
            )
        })
        .collect()
}

/// A level as the plain gather loops read it.
type LevelView<'a> = (&'a [f32], f32, f32, usize, usize);

/// The plain gather loop: for every pixel and term, the bilinear lookup of
/// the term's level (index in `levels`) at the pixel displaced by the
/// rotated, scaled centre, weighted and summed; indices clamped into the
/// level instead of any border logic.
fn gather_bilinear(
    stack: &ScaleStack,
    terms: &[(f32, f32, f32, usize)],
    angles: &[f32],
    scale: f32,
) -> Vec<f32> {
    let w = stack.width();
    let levels = level_views(stack);
    let mut out = vec![0.0f32; w * stack.height()];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let (sin, cos) = angles[y * w + x].to_radians().sin_cos();
            let (cs, ss) = (cos * scale, sin * scale);
            let (xf, yf) = (x as f32, y as f32);
            let mut acc = 0.0;
            for &(weight, cx, cy, li) in terms {
                let (data, origin, inv, nx, ny) = levels[li];
                let u = (xf + cs * cx + ss * cy - origin) * inv;
                let v = (yf - ss * cx + cs * cy - origin) * inv;
                let iu = (u.max(0.0) as usize).min(nx - 2);
                let iv = (v.max(0.0) as usize).min(ny - 2);
                let (fu, fv) = (u - iu as f32, v - iv as f32);
                let i = iv * nx + iu;
                let (a, b, c, d) = (data[i], data[i + 1], data[i + nx], data[i + nx + 1]);
                let top = a + fu * (b - a);
                let bottom = c + fu * (d - c);
                acc += weight * (top + fv * (bottom - top));
            }
            *o = acc;
        }
    });
    out
}

fn throughput(c: &mut Criterion) {
    let (w, h) = (1024usize, 1024usize);
    let img = test_image(w, h);
    let angles = angle_field(w, h);
    let (d, _, _) = line_decomposition();
    let s = 254.0f32 / 30.0;
    // From s / 2 at the centre to s in the corners.
    let scales: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 / w as f32, (i / w) as f32 / h as f32);
            s * (0.5 + 0.5 * (x - 0.5).hypot(y - 0.5) / 0.5f32.hypot(0.5))
        })
        .collect();
    let n = d.terms.len();
    let mut g = c.benchmark_group("throughput");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(10))
        .warm_up_time(Duration::from_millis(500));
    g.throughput(Throughput::Elements((w * h * n) as u64));
    let sigmas = ifd_planar::level_sigmas(&d, s, 0.0);
    for interpolation in [Interpolation::Linear, Interpolation::Cubic] {
        // The stored margin `ifd filter` plans (covering the kernel's reach
        // where memory allows, so lookups near the border stay on the fast
        // path), with levels at the terms' exact sigmas.
        let options = stack_plan_for_decomposition(
            (w, h, 1),
            &d,
            s,
            s,
            Border::Reflect101,
            StackOptions {
                interpolation,
                ..StackOptions::default()
            },
        )
        .expect("plan")
        .options;
        let stack =
            ScaleStack::with_sigmas(&img, &sigmas, Border::Reflect101, options).expect("stack");
        let f = Filter::new(&stack, &d).expect("filter");
        g.bench_function(
            format!("angle_map_{}_{n}_terms", interpolation.name()),
            |b| {
                b.iter(|| {
                    f.apply(Field::Map(&angles), Field::Constant(s))
                        .expect("apply")
                });
            },
        );
        {
            let scalar = f.clone().with_vector_kernels(false);
            let name = interpolation.name();
            g.bench_function(format!("angle_map_{name}_scalar_{n}_terms"), |b| {
                b.iter(|| {
                    scalar
                        .apply(Field::Map(&angles), Field::Constant(s))
                        .expect("apply")
                });
            });
        }
        if interpolation == Interpolation::Linear {
            let level_of = |sigma: f64| {
                stack
                    .sigmas()
                    .iter()
                    .position(|&l| (l.ln() - sigma.ln()).abs() < 1e-6)
                    .expect("a level at the term's sigma")
            };
            let terms: Vec<(f32, f32, f32, usize)> = d
                .terms
                .iter()
                .map(|t| {
                    let li = level_of(f64::from(s) * t.sigma);
                    (t.weight as f32, t.x as f32, t.y as f32, li)
                })
                .collect();
            // The same result up to border handling: checked once.
            let got = f
                .apply(Field::Map(&angles), Field::Constant(s))
                .expect("apply");
            let want = gather_bilinear(&stack, &terms, &angles, s);
            let inner = |v: &[f32]| -> Vec<f32> {
                (300..700)
                    .flat_map(|y| v[y * w + 300..y * w + 700].to_vec())
                    .collect()
            };
            eprintln!(
                "gather loop vs ifd (interior): PSNR {:.1} dB",
                psnr(&inner(got.data()), &inner(&want))
            );
            g.bench_function(format!("gather_limit_bilinear_{n}_terms"), |b| {
                b.iter(|| gather_bilinear(&stack, &terms, &angles, s));
            });
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                let want = gather_bilinear(&stack, &terms, &angles, s);
                let got = vector_limit::gather(&stack, &terms, &angles, s);
                eprintln!(
                    "avx2 gather loop vs scalar gather loop: PSNR {:.1} dB",
                    psnr(&got, &want)
                );
                g.bench_function(format!("gather_limit_avx2_{n}_terms"), |b| {
                    b.iter(|| vector_limit::gather(&stack, &terms, &angles, s));
                });
                // The same loop with every term at the pixel itself: all
                // lookups of a pixel read the same few cache lines (L1), so
                // the difference to the line above is what the real access
                // pattern costs in the memory hierarchy.
                let at_pixel: Vec<(f32, f32, f32, usize)> = terms
                    .iter()
                    .map(|&(w, _, _, li)| (w, 0.0, 0.0, li))
                    .collect();
                g.bench_function(format!("gather_limit_avx2_l1_{n}_terms"), |b| {
                    b.iter(|| vector_limit::gather(&stack, &at_pixel, &angles, s));
                });
            }
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx512f") {
                let want = gather_bilinear(&stack, &terms, &angles, s);
                let got = vector_limit::gather512(&stack, &terms, &angles, s);
                eprintln!(
                    "avx512 gather loop vs scalar gather loop: PSNR {:.1} dB",
                    psnr(&got, &want)
                );
                g.bench_function(format!("gather_limit_avx512_{n}_terms"), |b| {
                    b.iter(|| vector_limit::gather512(&stack, &terms, &angles, s));
                });
            }
        }
    }
    let stack = stack_for_decomposition(
        &img,
        &d,
        0.5 * s,
        s,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let f = Filter::new(&stack, &d).expect("filter");
    g.bench_function(format!("angle_and_scale_maps_linear_{n}_terms"), |b| {
        b.iter(|| {
            f.apply(Field::Map(&angles), Field::Map(&scales))
                .expect("apply")
        });
    });
    let scalar = f.clone().with_vector_kernels(false);
    g.bench_function(
        format!("angle_and_scale_maps_linear_scalar_{n}_terms"),
        |b| {
            b.iter(|| {
                scalar
                    .apply(Field::Map(&angles), Field::Map(&scales))
                    .expect("apply")
            });
        },
    );
    g.finish();
}

/// The plain gather loop of [`gather_bilinear`] eight pixels at a time with
/// AVX2: rotation, positions, indices and weights as vectors, each bilinear
/// lookup as two 64-bit gathers per row pair (the two horizontal
/// neighbours at once), no border logic (indices clamped); and sixteen at a
/// time with AVX-512 (each row's pairs as two 64-bit gathers of eight
/// lanes). The limits of ifd's vector kernels, which add the interior test,
/// the scalar fallback and the scalar loop's order of operations (no FMA).
#[cfg(target_arch = "x86_64")]
#[allow(
    unsafe_code,
    reason = "AVX2 gathers, as in ifd_planar's vector kernels"
)]
mod vector_limit {
    use std::arch::x86_64::{
        _mm256_add_epi32, _mm256_add_ps, _mm256_castsi256_ps, _mm256_castsi256_si128,
        _mm256_cvtepi32_ps, _mm256_cvttps_epi32, _mm256_extracti128_si256, _mm256_fmadd_ps,
        _mm256_fnmadd_ps, _mm256_i32gather_epi64, _mm256_loadu_ps, _mm256_max_ps, _mm256_min_ps,
        _mm256_mul_ps, _mm256_mullo_epi32, _mm256_permute2x128_si256, _mm256_permutevar8x32_epi32,
        _mm256_set1_epi32, _mm256_set1_ps, _mm256_setr_epi32, _mm256_setr_ps, _mm256_setzero_ps,
        _mm256_storeu_ps, _mm256_sub_ps,
    };

    use ifd_planar::ScaleStack;
    use rayon::prelude::*;
    use std::arch::x86_64::{
        _mm512_add_epi32, _mm512_add_ps, _mm512_castsi512_ps, _mm512_castsi512_si256,
        _mm512_cvtepi32_ps, _mm512_cvttps_epi32, _mm512_extracti64x4_epi64, _mm512_fmadd_ps,
        _mm512_fnmadd_ps, _mm512_i32gather_epi64, _mm512_loadu_ps, _mm512_max_ps, _mm512_min_ps,
        _mm512_mul_ps, _mm512_mullo_epi32, _mm512_permutex2var_epi32, _mm512_set1_epi32,
        _mm512_set1_ps, _mm512_setr_epi32, _mm512_setr_ps, _mm512_setzero_ps, _mm512_storeu_ps,
        _mm512_sub_ps,
    };

    /// [`gather`] sixteen pixels at a time with AVX-512F (the caller checks
    /// the CPU has it).
    pub fn gather512(
        stack: &ScaleStack,
        terms: &[(f32, f32, f32, usize)],
        angles: &[f32],
        scale: f32,
    ) -> Vec<f32> {
        let w = stack.width();
        let levels = super::level_views(stack);
        let mut out = vec![0.0f32; w * stack.height()];
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            // SAFETY: the caller checked that the CPU has AVX-512F.
            unsafe { gather_row512(&levels, terms, &angles[y * w..(y + 1) * w], scale, y, row) };
        });
        out
    }

    #[target_feature(enable = "avx512f")]
    fn gather_row512(
        levels: &[super::LevelView<'_>],
        terms: &[(f32, f32, f32, usize)],
        angles: &[f32],
        scale: f32,
        y: usize,
        row: &mut [f32],
    ) {
        let first = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
        let second = _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31);
        let lane = _mm512_setr_ps(
            0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0,
        );
        let zero = _mm512_setzero_ps();
        for x0 in (0..row.len() / 16 * 16).step_by(16) {
            let mut c = [0.0f32; 16];
            let mut s = [0.0f32; 16];
            for k in 0..16 {
                let (sin, cos) = angles[x0 + k].to_radians().sin_cos();
                (c[k], s[k]) = (cos * scale, sin * scale);
            }
            // SAFETY: sixteen floats each.
            let (c, s) = unsafe { (_mm512_loadu_ps(c.as_ptr()), _mm512_loadu_ps(s.as_ptr())) };
            let xf = _mm512_add_ps(_mm512_set1_ps(x0 as f32), lane);
            let yf = _mm512_set1_ps(y as f32);
            let mut acc = zero;
            for &(weight, cx, cy, li) in terms {
                let (data, origin, inv, nx, ny) = levels[li];
                let (nx, ny) = (nx as i32, ny as i32);
                let (cx, cy) = (_mm512_set1_ps(cx), _mm512_set1_ps(cy));
                let px = _mm512_fmadd_ps(s, cy, _mm512_fmadd_ps(c, cx, xf));
                let py = _mm512_fmadd_ps(c, cy, _mm512_fnmadd_ps(s, cx, yf));
                let u = _mm512_mul_ps(
                    _mm512_sub_ps(px, _mm512_set1_ps(origin)),
                    _mm512_set1_ps(inv),
                );
                let v = _mm512_mul_ps(
                    _mm512_sub_ps(py, _mm512_set1_ps(origin)),
                    _mm512_set1_ps(inv),
                );
                let u = _mm512_min_ps(_mm512_max_ps(u, zero), _mm512_set1_ps((nx - 2) as f32));
                let v = _mm512_min_ps(_mm512_max_ps(v, zero), _mm512_set1_ps((ny - 2) as f32));
                let (iu, iv) = (_mm512_cvttps_epi32(u), _mm512_cvttps_epi32(v));
                let fu = _mm512_sub_ps(u, _mm512_cvtepi32_ps(iu));
                let fv = _mm512_sub_ps(v, _mm512_cvtepi32_ps(iv));
                let idx = _mm512_add_epi32(_mm512_mullo_epi32(iv, _mm512_set1_epi32(nx)), iu);
                let (lo, hi) = (
                    _mm512_castsi512_si256(idx),
                    _mm512_extracti64x4_epi64::<1>(idx),
                );
                let p = data.as_ptr();
                // SAFETY: u and v are clamped to the level's interior, so
                // every 8-byte read at idx (row 0) and idx + nx (row 1) is in it.
                #[allow(clippy::cast_ptr_alignment, reason = "gathers need no alignment")]
                let (r0l, r0h, r1l, r1h) = unsafe {
                    let q = p.add(nx as usize);
                    (
                        _mm512_i32gather_epi64::<4>(lo, p.cast()),
                        _mm512_i32gather_epi64::<4>(hi, p.cast()),
                        _mm512_i32gather_epi64::<4>(lo, q.cast()),
                        _mm512_i32gather_epi64::<4>(hi, q.cast()),
                    )
                };
                let split = |l, h, k| _mm512_castsi512_ps(_mm512_permutex2var_epi32(l, k, h));
                let (a, b) = (split(r0l, r0h, first), split(r0l, r0h, second));
                let (cc, d) = (split(r1l, r1h, first), split(r1l, r1h, second));
                let top = _mm512_fmadd_ps(fu, _mm512_sub_ps(b, a), a);
                let bottom = _mm512_fmadd_ps(fu, _mm512_sub_ps(d, cc), cc);
                let value = _mm512_fmadd_ps(fv, _mm512_sub_ps(bottom, top), top);
                acc = _mm512_fmadd_ps(_mm512_set1_ps(weight), value, acc);
            }
            // SAFETY: sixteen floats of the row.
            unsafe { _mm512_storeu_ps(row[x0..x0 + 16].as_mut_ptr(), acc) };
        }
    }

    pub fn gather(
        stack: &ScaleStack,
        terms: &[(f32, f32, f32, usize)],
        angles: &[f32],
        scale: f32,
    ) -> Vec<f32> {
        let w = stack.width();
        let levels = super::level_views(stack);
        let mut out = vec![0.0f32; w * stack.height()];
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            // SAFETY: the caller checked that the CPU has AVX2.
            unsafe { gather_row(&levels, terms, &angles[y * w..(y + 1) * w], scale, y, row) };
        });
        out
    }

    #[target_feature(enable = "avx2,fma")]
    fn gather_row(
        levels: &[super::LevelView<'_>],
        terms: &[(f32, f32, f32, usize)],
        angles: &[f32],
        scale: f32,
        y: usize,
        row: &mut [f32],
    ) {
        let split = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
        let lane = _mm256_setr_ps(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0);
        let zero = _mm256_setzero_ps();
        for x0 in (0..row.len() / 8 * 8).step_by(8) {
            let mut c = [0.0f32; 8];
            let mut s = [0.0f32; 8];
            for k in 0..8 {
                let (sin, cos) = angles[x0 + k].to_radians().sin_cos();
                (c[k], s[k]) = (cos * scale, sin * scale);
            }
            // SAFETY: eight floats each.
            let (c, s) = unsafe { (_mm256_loadu_ps(c.as_ptr()), _mm256_loadu_ps(s.as_ptr())) };
            let xf = _mm256_add_ps(_mm256_set1_ps(x0 as f32), lane);
            let yf = _mm256_set1_ps(y as f32);
            let mut acc = zero;
            for &(weight, cx, cy, li) in terms {
                let (data, origin, inv, nx, ny) = levels[li];
                let (nx, ny) = (nx as i32, ny as i32);
                let (cx, cy) = (_mm256_set1_ps(cx), _mm256_set1_ps(cy));
                let px = _mm256_fmadd_ps(s, cy, _mm256_fmadd_ps(c, cx, xf));
                let py = _mm256_fmadd_ps(c, cy, _mm256_fnmadd_ps(s, cx, yf));
                let u = _mm256_mul_ps(
                    _mm256_sub_ps(px, _mm256_set1_ps(origin)),
                    _mm256_set1_ps(inv),
                );
                let v = _mm256_mul_ps(
                    _mm256_sub_ps(py, _mm256_set1_ps(origin)),
                    _mm256_set1_ps(inv),
                );
                let u = _mm256_min_ps(_mm256_max_ps(u, zero), _mm256_set1_ps((nx - 2) as f32));
                let v = _mm256_min_ps(_mm256_max_ps(v, zero), _mm256_set1_ps((ny - 2) as f32));
                let (iu, iv) = (_mm256_cvttps_epi32(u), _mm256_cvttps_epi32(v));
                let fu = _mm256_sub_ps(u, _mm256_cvtepi32_ps(iu));
                let fv = _mm256_sub_ps(v, _mm256_cvtepi32_ps(iv));
                let idx = _mm256_add_epi32(_mm256_mullo_epi32(iv, _mm256_set1_epi32(nx)), iu);
                let (lo, hi) = (
                    _mm256_castsi256_si128(idx),
                    _mm256_extracti128_si256::<1>(idx),
                );
                let p = data.as_ptr();
                // SAFETY: u and v are clamped to the level's interior, so
                // every 8-byte read at idx (row 0) and idx + nx (row 1) is in it.
                #[allow(clippy::cast_ptr_alignment, reason = "gathers need no alignment")]
                let (r0l, r0h, r1l, r1h) = unsafe {
                    let q = p.add(nx as usize);
                    (
                        _mm256_i32gather_epi64::<4>(p.cast(), lo),
                        _mm256_i32gather_epi64::<4>(p.cast(), hi),
                        _mm256_i32gather_epi64::<4>(q.cast(), lo),
                        _mm256_i32gather_epi64::<4>(q.cast(), hi),
                    )
                };
                let (r0l, r0h) = (
                    _mm256_permutevar8x32_epi32(r0l, split),
                    _mm256_permutevar8x32_epi32(r0h, split),
                );
                let (r1l, r1h) = (
                    _mm256_permutevar8x32_epi32(r1l, split),
                    _mm256_permutevar8x32_epi32(r1h, split),
                );
                let a = _mm256_castsi256_ps(_mm256_permute2x128_si256::<0x20>(r0l, r0h));
                let b = _mm256_castsi256_ps(_mm256_permute2x128_si256::<0x31>(r0l, r0h));
                let cc = _mm256_castsi256_ps(_mm256_permute2x128_si256::<0x20>(r1l, r1h));
                let d = _mm256_castsi256_ps(_mm256_permute2x128_si256::<0x31>(r1l, r1h));
                let top = _mm256_fmadd_ps(fu, _mm256_sub_ps(b, a), a);
                let bottom = _mm256_fmadd_ps(fu, _mm256_sub_ps(d, cc), cc);
                let value = _mm256_fmadd_ps(fv, _mm256_sub_ps(bottom, top), top);
                acc = _mm256_fmadd_ps(_mm256_set1_ps(weight), value, acc);
            }
            // SAFETY: eight floats of the row.
            unsafe { _mm256_storeu_ps(row[x0..x0 + 8].as_mut_ptr(), acc) };
        }
    }
}

criterion_group!(benches, prefilter, terms, extent, throughput);
criterion_main!(benches);
