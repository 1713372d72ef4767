//! The spherical kernels on every instruction set `ifd_simd` dispatches to
//! (the Legendre recurrences of [`ShEvaluator::band_sums`] and
//! [`ShEvaluator::band_sums_f32`], the equirect projections): the same bits
//! on each.

use crate::{EquirectTransform, Negatives, ShEvaluator};
use ifd_simd::{Isa, isa, set_isa};

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
    assert_eq!(set_isa(Isa::Baseline), Isa::Baseline);
    assert_eq!(isa(), Isa::Baseline);
    let base = run_kernels();
    for want in [Isa::Avx2, Isa::Avx512] {
        let got = set_isa(want);
        if got != want {
            eprintln!("no {} on this CPU: {} ran", want.name(), got.name());
        }
        let vector = run_kernels();
        assert!(same_bits(&base.0, &vector.0), "{}: band sums", got.name());
        assert!(same_bits(&base.1, &vector.1), "{}: centres", got.name());
        assert!(same_bits(&base.2, &vector.2), "{}: texels", got.name());
        assert!(same_bits(&base.3, &vector.3), "{}: f32 x16", got.name());
        assert!(same_bits(&base.4, &vector.4), "{}: f32 x8", got.name());
    }
    set_isa(ifd_simd::env_cap());
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
