//! Dab and whole-image smoothing times (issue: Hessian smoothing, speed).
//!
//! `cargo bench -p ifd-smooth --bench smoothing`
//!
//! - one dab of radius 64 px, paper's mode and per-pixel mode (the app's hot path);
//! - a whole 1024x1024 image, per-pixel mode, scale 16, against a brute-force
//!   spatially varying anisotropic Gaussian of the same footprint (each
//!   pixel's kernel sampled on a (2 * ceil(3 * 4 S) + 1)^2 grid); the brute
//!   force is measured on 16 rows and scaled to the image, which the name
//!   says. Both sides run on rayon's pool (all cores), so the ratio compares
//!   equal thread counts;
//! - a sigma map (per-pixel anisotropic Gaussians, `ifd filter --kernel gauss
//!   --sigma-map`) on 512x512 at footprints 3 and 8 px, against the brute
//!   force of the same Gaussians (16 rows, x32 for the image).

use std::hint::black_box;
use std::sync::Arc;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use ifd_image::Image;
use ifd_smooth::{AspectBank, BankOptions, Dab, HessianBank, Mode, SmoothOptions, Smoother};
use rayon::prelude::*;

fn photo(w: usize, h: usize) -> Image {
    let src = ifd_image::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../testdata/camera.png"
    ))
    .expect("bundled image");
    // Tile the 512x512 photo to the requested size.
    let data = (0..w * h)
        .map(|i| src.get((i % w) % src.width(), (i / w) % src.height(), 0))
        .collect();
    Image::from_vec(w, h, 1, data).expect("image")
}

fn bench(c: &mut Criterion) {
    let bank = Arc::new(AspectBank::build(BankOptions::default(), |_, _| {}).expect("bank"));
    let hbank = HessianBank::new(0.01).expect("hessian bank");
    let mut g = c.benchmark_group("smoothing");
    g.sample_size(10).measurement_time(Duration::from_secs(3));

    let img = photo(512, 512);
    let opts = SmoothOptions {
        scale: 8.0,
        ..SmoothOptions::default()
    };
    let sm = Smoother::with_banks(&img, &opts, bank.clone(), &hbank).expect("smoother");
    let dab = Dab {
        x: 256.0,
        y: 256.0,
        radius: 64.0,
        falloff: 0.3,
        strength: 1.0,
    };
    // The cost of a paper-mode dab depends on the filter at its centre (an
    // isotropic entry has a few terms, an 8:1 one hundreds): also measure at
    // the most anisotropic point at least 64 px from the border.
    let (aniso_dab, aspect) = {
        let field = sm.orientation_field();
        let (w, h) = (img.width(), img.height());
        let (mut best, mut at) = (0.0f32, (0, 0));
        for y in 64..h - 64 {
            for x in 64..w - 64 {
                if field[y * w + x].aspect > best {
                    best = field[y * w + x].aspect;
                    at = (x, y);
                }
            }
        }
        (
            Dab {
                x: at.0 as f32,
                y: at.1 as f32,
                ..dab
            },
            best,
        )
    };
    let centre_aspect = sm.orientation_at(dab.x, dab.y).aspect;
    eprintln!(
        "dab at the centre: aspect {centre_aspect:.2}; most anisotropic dab at ({}, {}): aspect {aspect:.2}",
        aniso_dab.x, aniso_dab.y
    );
    for (name, mode, d) in [
        ("dab r64 paper mode", Mode::Dab, dab),
        ("dab r64 per-pixel", Mode::PerPixel, dab),
        (
            "dab r64 paper mode, most anisotropic point",
            Mode::Dab,
            aniso_dab,
        ),
        (
            "dab r64 per-pixel, most anisotropic point",
            Mode::PerPixel,
            aniso_dab,
        ),
    ] {
        let mut target = img.clone();
        g.bench_function(name, |b| {
            b.iter(|| sm.apply_dab(black_box(&d), mode, &mut target).expect("dab"));
        });
    }

    let big = photo(1024, 1024);
    let opts16 = SmoothOptions {
        scale: 16.0,
        ..SmoothOptions::default()
    };
    g.bench_function("setup 1024x1024 scale 16 (stack + Hessian field)", |b| {
        b.iter(|| {
            Smoother::with_banks(black_box(&big), &opts16, bank.clone(), &hbank).expect("smoother")
        });
    });
    let sm16 = Smoother::with_banks(&big, &opts16, bank.clone(), &hbank).expect("smoother");
    g.bench_function("whole 1024x1024 per-pixel scale 16", |b| {
        b.iter(|| sm16.smooth_image(Mode::PerPixel).expect("smooth"));
    });
    // Brute force: same per-pixel anisotropic Gaussians, sampled directly.
    let field = sm16.orientation_field().to_vec();
    let rows = 16;
    g.bench_function(
        "brute force 1024x1024 per-pixel scale 16 (16 rows, x64 for the image)",
        |b| {
            b.iter(|| brute_rows(&big, &field, 16.0, rows));
        },
    );

    // Per-pixel anisotropic Gaussians from a sigma map (`ifd filter --kernel
    // gauss --sigma-map`): the Hessian field of the 512x512 photo at
    // footprints 3 and 8 px, as major = S sqrt(a), minor = S / sqrt(a),
    // angle theta, against the brute force of the same Gaussians (16 rows,
    // x32 for the image).
    let field = sm.orientation_field().to_vec();
    for s in [3.0f32, 8.0] {
        let map: Vec<f32> = field
            .iter()
            .flat_map(|o| {
                let r = o.aspect.sqrt();
                [s * r, s / r, o.theta]
            })
            .collect();
        let map = Image::from_vec(img.width(), img.height(), 3, map).expect("sigma map");
        g.bench_function(format!("sigma map 512x512 footprint {s}"), |b| {
            b.iter(|| {
                ifd_smooth::filter_sigma_map(
                    &img,
                    map.view(),
                    &bank,
                    ifd_planar::Border::Reflect101,
                )
                .expect("sigma map")
            });
        });
        g.bench_function(
            format!("brute force sigma map 512x512 footprint {s} (16 rows, x32 for the image)"),
            |b| {
                b.iter(|| brute_rows(&img, &field, f64::from(s), rows));
            },
        );
    }
    g.finish();
}

/// Spatially varying anisotropic Gaussian by direct summation over the first
/// `rows` rows; kernel radius 3 x the long sigma.
fn brute_rows(img: &Image, field: &[ifd_smooth::Orientation], scale: f64, rows: usize) -> f32 {
    (0..rows)
        .into_par_iter()
        .map(|y| brute_row(img, field, scale, y))
        .sum()
}

/// One row of [`brute_rows`]; returns the sum of its values.
fn brute_row(img: &Image, field: &[ifd_smooth::Orientation], scale: f64, y: usize) -> f32 {
    let (w, h) = (img.width(), img.height());
    let mut acc = 0.0f32;
    for x in 0..w {
        let o = field[y * w + x];
        let a = f64::from(o.aspect);
        let (sx, sy) = (scale * a.sqrt(), scale / a.sqrt());
        let r = (3.0 * sx).ceil() as i64;
        let (sin, cos) = f64::from(o.theta).to_radians().sin_cos();
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for dy in -r..=r {
            for dx in -r..=r {
                let (fx, fy) = (dx as f64, dy as f64);
                let u = cos * fx - sin * fy;
                let v = sin * fx + cos * fy;
                let k = (-0.5 * (u * u / (sx * sx) + v * v / (sy * sy))).exp();
                let xi = (x as i64 + dx).clamp(0, w as i64 - 1) as usize;
                let yi = (y as i64 + dy).clamp(0, h as i64 - 1) as usize;
                num += k * f64::from(img.get(xi, yi, 0));
                den += k;
            }
        }
        acc += (num / den) as f32;
    }
    acc
}

criterion_group!(benches, bench);
criterion_main!(benches);
