//! Criterion benchmarks of `ifd-sphere`: SH evaluation, equirectangular SH
//! analysis/synthesis of a 1024x512 RGB map, and SH rotations (reference
//! Ivanic-Ruedenberg vs ZHF Eq. 10 vs signal-tailored ZHF Eq. 11) at orders
//! N = L + 1 = 3..20. Numbers are recorded in BENCHMARKS.md ("Spherical").
#![expect(clippy::unwrap_used, reason = "benchmark setup")]

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use ifd_image::Image;
use ifd_sphere::{Chooser, DirectionSet, RzhBasis, Sharing, SplitMix64};
use ifd_sphere::{EquirectTransform, Negatives, Rotation, ShCoeffs, ShEvaluator, ShRotation};

fn sh_eval(c: &mut Criterion) {
    let mut g = c.benchmark_group("sh_eval");
    for l in [8usize, 32, 100] {
        let sh = ShEvaluator::new(l).unwrap();
        let mut out = vec![0.0; sh.count()];
        let mut out32 = vec![0.0f32; sh.count()];
        g.bench_with_input(BenchmarkId::new("f64", l), &l, |b, _| {
            b.iter(|| sh.eval_into(black_box([0.3, -0.4, 0.866]), &mut out));
        });
        g.bench_with_input(BenchmarkId::new("f32", l), &l, |b, _| {
            b.iter(|| sh.eval_f32_into(black_box([0.3, -0.4, 0.866]), &mut out32));
        });
    }
    g.finish();
}

fn equirect(c: &mut Criterion) {
    let (w, h) = (1024, 512);
    let mut rng = SplitMix64::new(1);
    let img = Image::from_vec(
        w,
        h,
        3,
        (0..w * h * 3).map(|_| rng.uniform() as f32).collect(),
    )
    .unwrap();
    let mut g = c.benchmark_group("equirect_1024x512_rgb");
    g.sample_size(10);
    for l in [8usize, 16, 32, 64] {
        let t = EquirectTransform::new(l, w, h).unwrap();
        g.bench_with_input(BenchmarkId::new("analyze", l), &l, |b, _| {
            b.iter(|| t.analyze(black_box(&img), Negatives::Keep).unwrap());
        });
        let coeffs = t.analyze(&img, Negatives::Keep).unwrap().coeffs;
        g.bench_with_input(BenchmarkId::new("synthesize", l), &l, |b, _| {
            b.iter(|| t.synthesize(black_box(&coeffs)).unwrap());
        });
    }
    g.finish();
}

fn rotation(c: &mut Criterion) {
    let mut g = c.benchmark_group("rotate");
    g.sample_size(20)
        .measurement_time(Duration::from_millis(700))
        .warm_up_time(Duration::from_millis(200));
    let r = Rotation::from_zyz(0.3, 1.1, -0.7);
    for n in 3usize..=20 {
        let l = n - 1;
        let mut rng = SplitMix64::new(n as u64);
        let f = ShCoeffs::from_vec(l, 1, (0..n * n).map(|_| rng.uniform()).collect()).unwrap();
        let basis =
            RzhBasis::new(DirectionSet::new(l, Sharing::Shared, Chooser::Fibonacci).unwrap())
                .unwrap();
        g.bench_with_input(BenchmarkId::new("reference", n), &n, |b, _| {
            b.iter(|| {
                ShRotation::new(black_box(&r), l)
                    .unwrap()
                    .apply(&f)
                    .unwrap()
            });
        });
        g.bench_with_input(BenchmarkId::new("zhf", n), &n, |b, _| {
            b.iter(|| basis.rotate(black_box(&f), black_box(&r)).unwrap());
        });
        g.bench_with_input(BenchmarkId::new("tailored", n), &n, |b, _| {
            b.iter(|| basis.rotate_tailored(black_box(&f), black_box(&r)).unwrap());
        });
        // ZHF Eq. 11 with the band expansions tabulated (512 rows)
        let tables = ifd_sphere::BandTables::new(&f, 512).unwrap();
        g.bench_with_input(BenchmarkId::new("tabulated", n), &n, |b, _| {
            b.iter(|| tables.rotate(black_box(&basis), black_box(&r)).unwrap());
        });
    }
    g.finish();
}

criterion_group!(benches, sh_eval, equirect, rotation);
criterion_main!(benches);
