//! `filter_sigma_map` against brute force: the sampled, normalised
//! anisotropic Gaussian of each pixel correlated with the image in f64.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] functions: a panic is the failure report"
)]

use ifd_image::{Image, ImageView};
use ifd_planar::Border;
use ifd_smooth::{AspectBank, BankOptions, covariance, filter_sigma_map};

const W: usize = 64;
const H: usize = 48;

/// Zero-mean white noise (relative errors of the result are relative errors
/// of the filters, Parseval), with `c` channels.
fn noise(c: usize, seed: u64) -> Image {
    let mut s = seed;
    let data = (0..W * H * c)
        .map(|_| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((s >> 40) as f32 / (1u64 << 24) as f32) - 0.5
        })
        .collect();
    Image::from_vec(W, H, c, data).unwrap()
}

/// Brute force: at every pixel the Gaussian `(major, minor, theta)` sampled
/// at every offset of the box within 5 standard deviations along x and y,
/// normalised to sum 1, correlated in f64 (reflect101 border).
fn brute_force(img: &Image, map: &[f32]) -> Vec<f64> {
    let (w, h, c) = (img.width(), img.height(), img.channels());
    let mut out = vec![0.0; w * h * c];
    for y in 0..h {
        for x in 0..w {
            let p = &map[(y * w + x) * 3..][..3];
            let [a, b, d] = covariance(f64::from(p[2]), f64::from(p[0]), f64::from(p[1]));
            let det = a * d - b * b;
            let (rx, ry) = (
                (5.0 * a.sqrt()).ceil() as i64,
                (5.0 * d.sqrt()).ceil() as i64,
            );
            let mut acc = vec![0.0; c];
            let mut total = 0.0;
            for v in -ry..=ry {
                for u in -rx..=rx {
                    let (uf, vf) = (u as f64, v as f64);
                    let k = (-0.5 * (d * uf * uf - 2.0 * b * uf * vf + a * vf * vf) / det).exp();
                    total += k;
                    let xi = Border::Reflect101.resolve(x as i64 + u, w).unwrap();
                    let yi = Border::Reflect101.resolve(y as i64 + v, h).unwrap();
                    for (ch, s) in acc.iter_mut().enumerate() {
                        *s += k * f64::from(img.get(xi, yi, ch));
                    }
                }
            }
            for (ch, s) in acc.iter().enumerate() {
                out[(y * w + x) * c + ch] = s / total;
            }
        }
    }
    out
}

/// Relative RMS error of `got` against `want`.
fn rel_rms(got: &Image, want: &[f64]) -> f64 {
    let num: f64 = got
        .data()
        .iter()
        .zip(want)
        .map(|(g, w)| (f64::from(*g) - w).powi(2))
        .sum();
    let den: f64 = want.iter().map(|w| w * w).sum();
    (num / den).sqrt()
}

/// A map of `(major, minor, angle)` from a function of the pixel.
fn field(f: impl Fn(f64, f64) -> (f64, f64, f64)) -> Vec<f32> {
    let mut m = Vec::with_capacity(W * H * 3);
    for y in 0..H {
        for x in 0..W {
            let (u, v) = (x as f64 / (W - 1) as f64, y as f64 / (H - 1) as f64);
            let (major, minor, angle) = f(u, v);
            m.extend([major as f32, minor as f32, angle as f32]);
        }
    }
    m
}

/// A structure-tensor-like field of `img`: the angle along the local
/// direction of least change (the tensor's minor eigenvector), the major
/// sigma growing with the coherence.
fn tensor_field(img: &Image, (lo, hi): (f64, f64), max_aspect: f64) -> Vec<f32> {
    let g = |x: usize, y: usize| f64::from(img.get(x.min(W - 1), y.min(H - 1), 0));
    let mut t = vec![[0.0f64; 3]; W * H];
    for y in 0..H {
        for x in 0..W {
            let gx = g(x + 1, y) - g(x.saturating_sub(1), y);
            let gy = g(x, y + 1) - g(x, y.saturating_sub(1));
            t[y * W + x] = [gx * gx, gx * gy, gy * gy];
        }
    }
    // A 7x7 box average of the outer products.
    let mut m = Vec::with_capacity(W * H * 3);
    for y in 0..H {
        for x in 0..W {
            let mut s = [0.0; 3];
            for v in y.saturating_sub(3)..(y + 4).min(H) {
                for u in x.saturating_sub(3)..(x + 4).min(W) {
                    for k in 0..3 {
                        s[k] += t[v * W + u][k];
                    }
                }
            }
            let [jxx, jxy, jyy] = s;
            let tr = jxx + jyy;
            let disc = ((jxx - jyy).powi(2) + 4.0 * jxy * jxy).sqrt();
            let coherence = if tr > 0.0 { disc / tr } else { 0.0 };
            // The gradient's direction (major eigenvector of J) in pixel
            // coordinates (y down) is 0.5 atan2(2 jxy, jxx - jyy); the edge
            // runs perpendicular to it; on screen (y up) angles flip sign.
            let across = 0.5 * (2.0 * jxy).atan2(jxx - jyy);
            let along_deg = -(across + std::f64::consts::FRAC_PI_2).to_degrees();
            let aspect = 1.0 + (max_aspect - 1.0) * coherence;
            let footprint = lo + (hi - lo) * (x as f64 / (W - 1) as f64);
            m.extend([
                (footprint * aspect.sqrt()) as f32,
                (footprint / aspect.sqrt()) as f32,
                along_deg as f32,
            ]);
        }
    }
    m
}

fn bank() -> &'static AspectBank {
    static B: std::sync::OnceLock<AspectBank> = std::sync::OnceLock::new();
    B.get_or_init(|| AspectBank::build(BankOptions::default(), |_, _| {}).unwrap())
}

/// Every case's relative RMS error against brute force on white noise,
/// printed (`--nocapture`), must stay below `TOL`.
///
/// Measured (default bank: aspects 1 to 16, two per octave, each entry
/// fitted to 1%; 64x48 white noise): 0.8-1.0% for the Gaussians read from
/// the stack at aspects 4-16 (the bank's fit and its blend between
/// entries), 0.03-0.05% for isotropic ones, 0.3-0.8% over smooth gradients
/// of footprint, aspect and angle up to the bank's limit (aspect 16) and a
/// structure-tensor field, and about 5e-6 for the directly sampled small
/// ones (footprint below 2 px or minor sigma below 1 px; read from the
/// stack instead, a minor sigma of 0.8 px erred by 1.5% and one of 0.5 px by
/// 8.6%). A tolerance of 2% fails a wrong angle convention (the Gaussian
/// turned the other way, or its axes swapped, errs by far more: see
/// `the_brute_force_comparison_detects_wrong_conventions`) or a missing
/// normalisation.
const TOL: f64 = 0.02;

#[test]
fn sigma_maps_match_brute_force() {
    let bank = bank();
    let img = noise(1, 7);
    let rgb = noise(3, 11);
    let cases: Vec<(&str, Vec<f32>)> = vec![
        ("constant 1 px isotropic", field(|_, _| (1.0, 1.0, 0.0))),
        ("constant 2 x 1 px at 30", field(|_, _| (2.0, 1.0, 30.0))),
        ("constant 4 x 1 px at 30", field(|_, _| (4.0, 1.0, 30.0))),
        (
            "constant 8 x 1.25 px at -60",
            field(|_, _| (8.0, 1.25, -60.0)),
        ),
        ("constant 5 x 1.1 px at 10", field(|_, _| (5.0, 1.1, 10.0))),
        (
            "constant 8 x 0.8 px at 80 (direct)",
            field(|_, _| (8.0, 0.8, 80.0)),
        ),
        (
            "constant 12 x 3 px at 100",
            field(|_, _| (12.0, 3.0, 100.0)),
        ),
        ("constant 16 x 2 px at 45", field(|_, _| (16.0, 2.0, 45.0))),
        ("constant 16 x 16 px", field(|_, _| (16.0, 16.0, 0.0))),
        ("constant 6 x 6 px", field(|_, _| (6.0, 6.0, 17.0))),
        (
            "bank limit: 16 x 1 px at 20",
            field(|_, _| (16.0, 1.0, 20.0)),
        ),
        (
            "bank limit: 8 x 0.5 px at 70 (direct)",
            field(|_, _| (8.0, 0.5, 70.0)),
        ),
        (
            "gradient: footprint 1.5-5, aspect 1-8, angle 0-180",
            field(|u, v| {
                let s = 1.5 + 3.5 * u;
                let a: f64 = 1.0 + 7.0 * v;
                (s * a.sqrt(), s / a.sqrt(), 180.0 * (u + v) / 2.0)
            }),
        ),
        (
            "gradient: major 2-16, aspect 2-16, angle -90-90",
            field(|u, v| {
                let major = 2.0 + 14.0 * u;
                let a = 2.0 + 14.0 * v;
                (major, major / a, -90.0 + 180.0 * v)
            }),
        ),
        ("structure tensor", tensor_field(&img, (1.0, 5.0), 8.0)),
    ];
    let mut worst: f64 = 0.0;
    for (name, map) in &cases {
        let m = ImageView::new(W, H, 3, map).unwrap();
        let got = filter_sigma_map(&img, m, bank, Border::Reflect101).unwrap();
        let err = rel_rms(&got, &brute_force(&img, map));
        eprintln!("{name}: relative RMS error {:.4}%", 100.0 * err);
        assert!(err < TOL, "{name}: {err}");
        worst = worst.max(err);
    }
    // Several channels at once: the same as one by one.
    let (name, map) = &cases[10];
    let m = ImageView::new(W, H, 3, map).unwrap();
    let got = filter_sigma_map(&rgb, m, bank, Border::Reflect101).unwrap();
    let err = rel_rms(&got, &brute_force(&rgb, map));
    eprintln!("{name}, 3 channels: relative RMS error {:.4}%", 100.0 * err);
    assert!(err < TOL, "{name}, 3 channels: {err}");
    eprintln!("worst: {:.4}%", 100.0 * worst.max(err));
}

/// The test above can fail: the Gaussian turned by the mirrored angle
/// (clockwise instead of counter-clockwise) or with its axes swapped is far
/// off, and so is a filter that is not normalised.
#[test]
fn the_brute_force_comparison_detects_wrong_conventions() {
    let bank = bank();
    let img = noise(1, 5);
    let map = field(|u, _| (8.0, 1.5, 30.0 + 40.0 * u));
    let m = ImageView::new(W, H, 3, &map).unwrap();
    let got = filter_sigma_map(&img, m, bank, Border::Reflect101).unwrap();
    assert!(rel_rms(&got, &brute_force(&img, &map)) < TOL);
    let mirrored: Vec<f32> = map.chunks(3).flat_map(|p| [p[0], p[1], -p[2]]).collect();
    let err = rel_rms(&got, &brute_force(&img, &mirrored));
    assert!(err > 10.0 * TOL, "mirrored angle: {err}");
    let turned: Vec<f32> = map
        .chunks(3)
        .flat_map(|p| [p[0], p[1], p[2] + 90.0])
        .collect();
    let err = rel_rms(&got, &brute_force(&img, &turned));
    assert!(err > 10.0 * TOL, "axes swapped: {err}");
    let want = brute_force(&img, &map);
    let unnormalised: Vec<f64> = want.iter().map(|v| v * 1.05).collect();
    assert!(rel_rms(&got, &unnormalised) > TOL);
    // Flat images stay flat: the filters sum to 1, at every footprint.
    let flat = Image::from_vec(W, H, 1, vec![0.75; W * H]).unwrap();
    let map = field(|u, v| (1.0 + 15.0 * u, (1.0 + 15.0 * u) / (1.0 + 7.0 * v), 90.0 * v));
    let m = ImageView::new(W, H, 3, &map).unwrap();
    let out = filter_sigma_map(&flat, m, bank, Border::Reflect101).unwrap();
    let dc = out
        .data()
        .iter()
        .map(|v| (v - 0.75).abs())
        .fold(0.0f32, f32::max);
    assert!(dc < 0.75 * 2e-3, "flat image: off by up to {dc}");
}
