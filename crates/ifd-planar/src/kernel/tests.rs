//! Unit tests of `kernel/mod.rs`.

use super::raster::to_local;
use super::*;

/// The series and the logarithm branch against `ln(max(1 + x, 1/4)) / 2`
/// in `f64`, across the switch and the floor, and against
/// `effective_sigma`: within the `f32` rounding of the values (the
/// series' values are below 0.016, its truncation below 2.6e-9; the
/// logarithm's, `f32` throughout, a few units of its values, to x = 1e4).
#[test]
fn ln_widening_matches_the_logarithm() {
    for i in -1000..=1000 {
        let x = (f64::from(i) * 1e-4 * (1.0 + f64::from(i).abs() / 50.0)) as f32;
        let exact = 0.5 * (1.0 + f64::from(x)).max(0.25).ln();
        let tol = if widening_needs_log(x) { 1.2e-7 } else { 6e-9 };
        assert!(
            (f64::from(ln_widening(x)) - exact).abs() < tol,
            "{x}: {} vs {exact}",
            ln_widening(x)
        );
    }
    // Wide footprints of small scales (x up to 1e4, values to 4.6): a few
    // f32 units of the value.
    for x in [3.0f32, 10.0, 57.3, 1e2, 1e3, 1e4] {
        let exact = 0.5 * (1.0 + f64::from(x)).ln();
        let got = f64::from(ln_widening(x));
        assert!((got - exact).abs() < 4e-7 * exact, "{x}: {got} vs {exact}");
    }
    for (sampling, sigma, s) in [
        (Sampling::Point, 3.0, 0.5),
        (Sampling::Point, 6.0, 0.5),
        (Sampling::Area, 0.3, 2.0),
    ] {
        let ss = s * sigma;
        let x = sampling.footprint_variance(s) / (ss * ss);
        let direct = (sampling.effective_sigma(sigma, s) / ss).ln();
        // and the rounding of x to f32 (x = -0.69 here for Area, where
        // the logarithm's slope is 1.6)
        let got = f64::from(ln_widening(x as f32));
        assert!((got - direct).abs() < 2e-7, "{sampling:?} {sigma}");
    }
}

/// The parts of `footprint_variance(s) / s^2` give it back for every
/// sampling, on both sides of scale 1.
#[test]
fn footprint_parts_give_the_variance() {
    for sampling in [
        Sampling::Continuous,
        Sampling::Point,
        Sampling::Area,
        Sampling::Averaged,
    ] {
        let (v, c, below) = sampling.footprint_over_s2();
        for s in [0.1, 0.5, 0.999, 1.0, 1.5, 4.0] {
            let parts = if s < below { v / (s * s) + c } else { 0.0 };
            let want = sampling.footprint_variance(s) / (s * s);
            assert!((parts - want).abs() < 1e-12, "{sampling:?} at {s}");
        }
    }
}

/// The skip of whole-inside and whole-outside pixels changes nothing:
/// every sample equals the plain supersampled coverage (before the
/// normalisation, compared as ratios to the centre pixel).
#[test]
fn hard_edged_coverage_equals_plain_supersampling() {
    type Inside<'a> = &'a dyn Fn(f64, f64) -> bool;
    let cases: [(&str, Inside); 3] = [
        ("disk:r=6.3", &|x, y| x * x + y * y <= 6.3 * 6.3),
        ("box:w=7,h=3.5,theta=30", &|x, y| {
            let (s, c) = 30f64.to_radians().sin_cos();
            let (u, v) = to_local(x, y, c, s);
            u.abs() <= 3.5 && v.abs() <= 1.75
        }),
        ("line:len=11,width=0.4,theta=-20", &|x, y| {
            let (s, c) = (-20f64).to_radians().sin_cos();
            let (u, v) = to_local(x, y, c, s);
            u.abs() <= 5.5 && v.abs() <= 0.2
        }),
    ];
    for (spec, inside) in cases {
        let spec: KernelSpec = spec.parse().unwrap();
        for q in [1, 2] {
            let (k, factor) = spec.sample(q).unwrap();
            let r = (k.width() / 2) as f64;
            let ss = SUPERSAMPLE as f64;
            for row in 0..k.height() {
                for col in 0..k.width() {
                    let (cx, cy) = ((col as f64 - r) / q as f64, (row as f64 - r) / q as f64);
                    let mut count = 0;
                    for sy in 0..SUPERSAMPLE {
                        for sx in 0..SUPERSAMPLE {
                            let x = cx - 0.5 + (sx as f64 + 0.5) / ss;
                            let y = cy - 0.5 + (sy as f64 + 0.5) / ss;
                            count += usize::from(inside(x, y));
                        }
                    }
                    let want = count as f64 / (ss * ss) * factor;
                    let got = k.get(col as isize - r as isize, row as isize - r as isize);
                    assert!(
                        (got - want).abs() <= 1e-15,
                        "{spec} q={q} ({col}, {row}): {got} vs {want}"
                    );
                }
            }
        }
    }
}

#[test]
fn gauss_rotation_convention() {
    // theta = 90: the long axis points up on screen (negative y).
    let k: Kernel = "gauss:sx=6,sy=1,theta=90".parse().unwrap();
    assert!(k.get(0, -8) > 100.0 * k.get(8, 0));
    let k: Kernel = "gauss:sx=6,sy=1,theta=45".parse().unwrap();
    // CCW on screen by 45 degrees: towards (+x, -y).
    assert!(k.get(5, -5) > 100.0 * k.get(5, 5));
    assert_eq!(k.width(), 49);
}

#[test]
fn dgauss_signs_and_symmetry() {
    let k: Kernel = "dgauss:order=xx,sigma=4".parse().unwrap();
    assert!(k.get(0, 0) < 0.0);
    assert!(k.get(8, 0) > 0.0);
    assert!((k.get(3, 2) - k.get(-3, -2)).abs() < 1e-15);
    let k: Kernel = "dgauss:order=xy,sigma=4".parse().unwrap();
    assert!(k.get(3, 3) > 0.0 && k.get(3, -3) < 0.0);
    let yy: Kernel = "dgauss:order=yy,sigma=4".parse().unwrap();
    let xx: Kernel = "dgauss:order=xx,sigma=4".parse().unwrap();
    assert!((yy.get(2, 5) - xx.get(5, 2)).abs() < 1e-15);
    let log: Kernel = "log:sigma=4".parse().unwrap();
    assert!((log.get(2, 5) - xx.get(2, 5) - yy.get(2, 5)).abs() < 1e-15);
}

#[test]
fn hard_edged_shapes() {
    let b: Kernel = "box:w=5,h=3".parse().unwrap();
    assert_eq!(b.width(), 5);
    assert!((b.sum() - 1.0).abs() < 1e-12);
    assert!((b.get(2, 1) - 1.0 / 15.0).abs() < 1e-12);
    let d: Kernel = "disk:r=10".parse().unwrap();
    assert_eq!(d.width(), 21);
    let l: Kernel = "line:len=21,theta=90".parse().unwrap();
    assert!(l.get(0, -10) > 0.0 && l.get(3, 0) == 0.0);
    let g: Kernel = "gabor:sigma=4,freq=0.1,theta=30,r=5".parse().unwrap();
    assert_eq!(g.width(), 11);
}

#[test]
fn spec_errors() {
    let err = |s: &str| s.parse::<Kernel>().unwrap_err();
    assert!(matches!(err("blob:x=1"), KernelError::UnknownSpec { .. }));
    assert!(matches!(
        err("gauss:sx=1,q=2"),
        KernelError::UnknownKey { .. }
    ));
    assert!(matches!(err("gauss:sy=1"), KernelError::MissingKey { .. }));
    assert!(matches!(err("gauss:sx=-1"), KernelError::BadValue { .. }));
    assert!(matches!(err("gauss:sx=0"), KernelError::BadValue { .. }));
    assert!(matches!(err("gauss:sx=nan"), KernelError::BadValue { .. }));
    assert!(matches!(err("gauss:sx=1e6"), KernelError::TooLarge { .. }));
    assert!(matches!(err("gauss:sx"), KernelError::Syntax { .. }));
    assert!(matches!(
        err("dgauss:order=zz,sigma=1"),
        KernelError::BadValue { .. }
    ));
    assert!(err("gauss:sx=abc").to_string().contains("abc"));
    assert!(
        err("gauss:sx=2,theta=1e300")
            .to_string()
            .contains("1e6 degrees")
    );
    assert!(
        err("gabor:sigma=4,freq=0.6")
            .to_string()
            .contains("Nyquist")
    );
    assert!(matches!(
        Kernel::new(3, 3, vec![0.0; 9]),
        Err(KernelError::AllZero { .. })
    ));
    let mut v = vec![1.0; 9];
    v[4] = f64::NAN;
    assert!(matches!(
        Kernel::new(3, 3, v),
        Err(KernelError::NonFinite { x: 1, y: 1, .. })
    ));
    assert!(matches!(
        Kernel::new(4, 3, vec![1.0; 12]),
        Err(KernelError::EvenSize { .. })
    ));
}

#[test]
fn spec_display_round_trip() {
    for s in [
        "gauss:sx=24,sy=3,theta=30",
        "dgauss:order=xy,sigma=4",
        "disk:r=5,radius=9",
    ] {
        let spec: KernelSpec = s.parse().unwrap();
        let again: KernelSpec = spec.to_string().parse().unwrap();
        assert_eq!(spec, again);
    }
}

#[test]
fn from_image_checks() {
    let img = ifd_image::Image::new(3, 3, 2).unwrap();
    assert!(matches!(
        Kernel::from_image(&img),
        Err(KernelError::Channels { channels: 2 })
    ));
    let mut img = ifd_image::Image::new(3, 5, 1).unwrap();
    img.set(1, 2, 0, 1.0);
    let k = Kernel::from_image(&img).unwrap();
    assert_eq!(k.get(0, 0), 1.0);
}
