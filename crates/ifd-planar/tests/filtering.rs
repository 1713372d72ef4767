//! Prefiltering and IFD evaluation against the brute-force references.
//!
//! Run with `--nocapture` to see the measured PSNRs.

use ifd_image::Image;
use ifd_planar::internals::reference::{correlate, correlate_varying, sample_kernel};
use ifd_planar::{
    Border, Decomposition, Field, Filter, FilterError, Interpolation, ScaleStack, StackOptions,
    Term, stack_for_decomposition,
};
use proptest::prelude::*;

const BORDERS: [Border; 4] = [
    Border::Reflect101,
    Border::Replicate,
    Border::Wrap,
    Border::Constant(0.25),
];

/// Deterministic pseudo-random numbers in [0, 1).
#[path = "../../../tests/support/images.rs"]
mod images;

use images::shapes as test_image;

fn psnr(a: &Image, b: &Image) -> f64 {
    assert!(a.same_shape(b));
    let mse = a
        .data()
        .iter()
        .zip(b.data())
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
        .sum::<f64>()
        / a.data().len() as f64;
    10.0 * (1.0 / mse.max(1e-30)).log10()
}

fn max_abs_diff(a: &Image, b: &Image) -> f32 {
    a.data()
        .iter()
        .zip(b.data())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// A realistic anisotropic kernel (about 4:1): a line of sigma-2 Gaussians
/// weighted by a Gaussian profile, plus a small negative side lobe and a
/// finer atom off-axis so several sigmas are involved.
fn anisotropic_decomposition() -> Decomposition {
    let mut terms = Vec::new();
    let mut total = 0.0;
    for i in -10..=10 {
        let x = 2.0 * f64::from(i);
        let w = (-(x * x) / (2.0 * 8.0 * 8.0)).exp();
        total += w;
        terms.push(Term {
            weight: w,
            x,
            y: 0.0,
            sigma: 2.0,
        });
    }
    for t in &mut terms {
        t.weight /= total;
    }
    terms.push(Term {
        weight: -0.08,
        x: 0.0,
        y: 4.0,
        sigma: 3.0,
    });
    terms.push(Term {
        weight: 0.05,
        x: 5.0,
        y: -3.0,
        sigma: 1.2,
    });
    Decomposition::from_terms(terms)
}

/// A few displaced Gaussians of varied sigma.
fn small_decomposition() -> Decomposition {
    Decomposition::from_terms(vec![
        Term {
            weight: 0.6,
            x: -2.0,
            y: 1.0,
            sigma: 1.0,
        },
        Term {
            weight: 0.3,
            x: 3.0,
            y: 0.5,
            sigma: 1.6,
        },
        Term {
            weight: -0.2,
            x: 0.0,
            y: -3.0,
            sigma: 2.4,
        },
        Term {
            weight: 0.3,
            x: 1.5,
            y: 2.5,
            sigma: 1.3,
        },
    ])
}

fn kernel_radius(d: &Decomposition, s: f64) -> usize {
    d.terms
        .iter()
        .map(|t| s * (t.x.hypot(t.y) + 6.0 * t.sigma))
        .fold(0.0, f64::max)
        .ceil() as usize
}

/// Direct sum of the sampled Gaussian against the border-extended image at one pixel.
fn brute_gauss_at(img: &Image, border: Border, sigma: f64, px: i64, py: i64, ch: usize) -> f64 {
    brute_gauss_at_f(img, border, sigma, px as f32, py as f32, ch)
}

#[test]
fn stack_levels_match_brute_force_gaussian() {
    let img = test_image(40, 33, 3, 7);
    for border in BORDERS {
        let stack = ScaleStack::new(
            &img,
            0.5,
            12.0,
            border,
            StackOptions {
                margin: 6,
                ..StackOptions::default()
            },
        )
        .expect("stack");
        let mut worst_grid = 0.0f64;
        let mut worst_any = 0.0f64;
        for l in stack.level_layouts() {
            let step = l.step as i64;
            // Points inside, on the margin and far outside the image.
            for py in (-9..42).step_by(3) {
                for px in (-8..48).step_by(5) {
                    let v = stack
                        .sample(px as f32, py as f32, l.sigma)
                        .expect("covered sigma");
                    for (ch, &got) in v.iter().enumerate() {
                        let want = brute_gauss_at(&img, border, l.sigma, px, py, ch);
                        let err = (f64::from(got) - want).abs();
                        let in_margin = (-6..=39 + 6).contains(&px) && (-6..=32 + 6).contains(&py);
                        let exact_mode = matches!(border, Border::Reflect101 | Border::Wrap);
                        if px % step == 0 && py % step == 0 && (in_margin || exact_mode) {
                            worst_grid = worst_grid.max(err);
                        }
                        if in_margin || exact_mode {
                            worst_any = worst_any.max(err);
                        }
                    }
                }
            }
        }
        eprintln!(
            "{border}: levels {}, max error on stored samples {worst_grid:.2e}, anywhere {worst_any:.2e}",
            stack.sigmas().len()
        );
        assert!(
            worst_grid < 2e-5,
            "{border}: stored samples off by {worst_grid}"
        );
        // Off-grid samples of subsampled levels are bilinear interpolations.
        assert!(
            worst_any < 2e-2,
            "{border}: interpolated samples off by {worst_any}"
        );
    }
}

#[test]
fn stack_sample_errors() {
    let img = test_image(16, 16, 1, 3);
    let stack = ScaleStack::new(&img, 1.0, 4.0, Border::Reflect101, StackOptions::default())
        .expect("stack");
    assert!(matches!(
        stack.sample(1.0, 1.0, 5.0),
        Err(FilterError::SigmaOutOfRange { .. })
    ));
    assert!(stack.sample(1.0, 1.0, 0.5).is_err());
    assert!(stack.sample(f32::NAN, 1.0, 2.0).is_err());
    let msg = stack.sample(1.0, 1.0, 5.0).err().map(|e| e.to_string());
    assert!(msg.is_some_and(|m| m.contains("sigma 5")));
    // Interpolating in log sigma between levels stays between them.
    let a = stack.sample(5.0, 5.0, stack.sigmas()[2]).expect("ok")[0];
    let b = stack.sample(5.0, 5.0, stack.sigmas()[3]).expect("ok")[0];
    let mid = stack
        .sample(5.0, 5.0, (stack.sigmas()[2] * stack.sigmas()[3]).sqrt())
        .expect("ok")[0];
    assert!((mid - 0.5 * (a + b)).abs() < 1e-5);
    // NaN pixels and empty images.
    let mut bad = img.clone();
    bad.set(3, 4, 0, f32::NAN);
    let e = ScaleStack::new(&bad, 1.0, 4.0, Border::Reflect101, StackOptions::default());
    assert!(matches!(e, Err(FilterError::NonFinite { x: 3, y: 4, .. })));
    let e = ScaleStack::from_interleaved(
        0,
        4,
        1,
        &[],
        1.0,
        2.0,
        Border::Wrap,
        StackOptions::default(),
    );
    assert!(matches!(e, Err(FilterError::EmptyImage { .. })));
    let e = ScaleStack::new(&img, 1.0, 1e7, Border::Wrap, StackOptions::default());
    assert!(matches!(e, Err(FilterError::InvalidRange(_))));
    assert!(stack.bytes() > 0);
}

#[test]
fn constant_filter_matches_brute_force_each_border() {
    let img = test_image(72, 60, 3, 11);
    let d = anisotropic_decomposition();
    for border in BORDERS {
        for (theta, s) in [(30.0f32, 1.0f32), (-75.0, 1.5), (0.0, 0.7)] {
            let stack = stack_for_decomposition(&img, &d, s, s, border, StackOptions::default())
                .expect("stack");
            let out = Filter::new(&stack, &d)
                .expect("filter")
                .apply(Field::Constant(theta), Field::Constant(s))
                .expect("apply");
            let r = kernel_radius(&d, f64::from(s));
            let k = sample_kernel(|u, v| d.eval(u, v), f64::from(theta), f64::from(s), r);
            let want = correlate(&img, &k, 2 * r + 1, 2 * r + 1, border).expect("reference");
            let p = psnr(&out, &want);
            eprintln!(
                "constant filter, {border}, theta {theta}, s {s}: PSNR {p:.1} dB, max error {:.2e}",
                max_abs_diff(&out, &want)
            );
            assert!(p >= 40.0, "{border} theta {theta} s {s}: PSNR {p:.1} dB");
        }
    }
}

#[test]
fn filter_at_matches_whole_image() {
    let img = test_image(40, 30, 2, 5);
    let d = small_decomposition();
    let stack = stack_for_decomposition(
        &img,
        &d,
        0.8,
        2.0,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let f = Filter::new(&stack, &d).expect("filter");
    let out = f
        .apply(Field::Constant(20.0), Field::Constant(1.3))
        .expect("apply");
    for (x, y) in [(0, 0), (5, 7), (39, 29), (20, 3)] {
        let v = f
            .filter_at(x as f32, y as f32, 20.0, 1.3)
            .expect("filter_at");
        for (ch, &got) in v.iter().enumerate() {
            assert!((got - out.get(x, y, ch)).abs() < 1e-5);
        }
    }
    assert!(matches!(
        f.filter_at(1.0, 1.0, 0.0, 10.0),
        Err(FilterError::ScaleOutOfRange { .. })
    ));
    assert!(f.filter_at(1.0, 1.0, f32::NAN, 1.0).is_err());
}

/// The fast paths of a filter bound to one scale (`ScaledFilter::accumulate`
/// per point, `Taps::apply_region` over a rectangle, a weighted sum of two
/// filters as one tap list) equal the whole-image evaluation, for 1, 3 and 5
/// channels (the generic path) and rectangles touching the borders.
#[test]
fn scaled_filter_and_region_taps_match_whole_image() {
    use ifd_planar::Rotation;
    for c in [1usize, 3, 5] {
        let img = test_image(48, 36, c, 11 + c as u64);
        let (d1, d2) = (small_decomposition(), anisotropic_decomposition());
        let stack = stack_for_decomposition(
            &img,
            &d2,
            0.8,
            1.6,
            Border::Reflect101,
            StackOptions::default(),
        )
        .expect("stack");
        let (f1, f2) = (
            Filter::new(&stack, &d1).expect("filter"),
            Filter::new(&stack, &d2).expect("filter"),
        );
        let (theta, s, t) = (-33.0f32, 1.3f32, 0.3f32);
        let w1 = f1
            .apply(Field::Constant(theta), Field::Constant(s))
            .expect("apply");
        let w2 = f2
            .apply(Field::Constant(theta), Field::Constant(s))
            .expect("apply");
        let want =
            |x: usize, y: usize, ch: usize| (1.0 - t) * w1.get(x, y, ch) + t * w2.get(x, y, ch);
        let (s1, s2) = (
            f1.at_scale(s).expect("scale"),
            f2.at_scale(s).expect("scale"),
        );
        let mut taps = s1.taps(theta, 1.0 - t);
        taps.extend(s2.taps(theta, t));
        assert!(taps.len() >= f1.len() + f2.len());
        for (x0, y0, rw, rh) in [(0, 0, 48, 36), (30, 2, 18, 20), (0, 25, 7, 11)] {
            let region = taps.apply_region(&stack, x0, y0, rw, rh).expect("region");
            for y in y0..y0 + rh {
                for x in x0..x0 + rw {
                    for ch in 0..c {
                        let got = region[((y - y0) * rw + x - x0) * c + ch];
                        assert!(
                            (got - want(x, y, ch)).abs() < 1e-5,
                            "{c} channels, region at ({x}, {y}): {got} vs {}",
                            want(x, y, ch)
                        );
                    }
                }
            }
        }
        let rot = Rotation::degrees(theta);
        for (x, y) in [(0, 0), (5, 7), (47, 35), (20, 3)] {
            let mut v = vec![0.0f32; c];
            s1.accumulate(x as f32, y as f32, 1.0 - t, rot, &mut v);
            s2.accumulate(x as f32, y as f32, t, rot, &mut v);
            for (ch, &got) in v.iter().enumerate() {
                assert!(
                    (got - want(x, y, ch)).abs() < 1e-5,
                    "{got} vs {}",
                    want(x, y, ch)
                );
            }
        }
        assert!(taps.apply_region(&stack, 40, 0, 9, 1).is_err());
        assert!(f1.at_scale(f32::NAN).is_err());
        assert!(f1.at_scale(50.0).is_err());
    }
}

fn angle_field(w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 / w as f32, (i / w) as f32 / h as f32);
            150.0 * x + 60.0 * (std::f32::consts::PI * y).sin() - 40.0
        })
        .collect()
}

#[test]
fn varying_angle_matches_brute_force() {
    let (w, h) = (64, 56);
    let img = test_image(w, h, 1, 21);
    let d = anisotropic_decomposition();
    let angles = angle_field(w, h);
    let r = kernel_radius(&d, 1.0);
    let want = correlate_varying(
        &img,
        r,
        Field::Map(&angles),
        Field::Constant(1.0),
        Border::Reflect101,
        |u, v| d.eval(u, v),
    )
    .expect("reference");
    let stack = stack_for_decomposition(
        &img,
        &d,
        1.0,
        1.0,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let out = Filter::new(&stack, &d)
        .expect("filter")
        .apply(Field::Map(&angles), Field::Constant(1.0))
        .expect("apply");
    let p = psnr(&out, &want);
    eprintln!(
        "varying angle: PSNR {p:.1} dB, max error {:.2e}",
        max_abs_diff(&out, &want)
    );
    assert!(p >= 40.0, "PSNR {p:.1} dB");
}

#[test]
fn varying_angle_and_scale_matches_brute_force() {
    let (w, h) = (48, 40);
    let img = test_image(w, h, 2, 33);
    let d = small_decomposition();
    let angles = angle_field(w, h);
    let scales: Vec<f32> = (0..w * h)
        .map(|i| 0.8 + 1.2 * (i / w) as f32 / h as f32 + 0.3 * (i % w) as f32 / w as f32)
        .collect();
    let r = kernel_radius(&d, 2.3);
    let want = correlate_varying(
        &img,
        r,
        Field::Map(&angles),
        Field::Map(&scales),
        Border::Reflect101,
        |u, v| d.eval(u, v),
    )
    .expect("reference");
    let stack = stack_for_decomposition(
        &img,
        &d,
        0.8,
        2.3,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let out = Filter::new(&stack, &d)
        .expect("filter")
        .apply(Field::Map(&angles), Field::Map(&scales))
        .expect("apply");
    let p = psnr(&out, &want);
    eprintln!(
        "varying angle and scale: PSNR {p:.1} dB, max error {:.2e}",
        max_abs_diff(&out, &want)
    );
    assert!(p >= 40.0, "PSNR {p:.1} dB");
}

#[test]
fn filter_errors() {
    let img = test_image(20, 10, 1, 1);
    let d = small_decomposition();
    let stack = stack_for_decomposition(
        &img,
        &d,
        1.0,
        2.0,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let f = Filter::new(&stack, &d).expect("filter");
    let e = f.apply(Field::Map(&[0.0; 199]), Field::Constant(1.0));
    assert!(matches!(
        e,
        Err(FilterError::MapSize {
            len: 199,
            expected: 200,
            ..
        })
    ));
    let mut scales = vec![1.5f32; 200];
    scales[47] = 3.5;
    let e = f.apply(Field::Constant(0.0), Field::Map(&scales));
    let msg = e.err().map(|e| e.to_string()).unwrap_or_default();
    assert!(msg.contains("scale 3.5") && msg.contains("(7, 2)"), "{msg}");
    scales[47] = -1.0;
    assert!(matches!(
        f.apply(Field::Constant(0.0), Field::Map(&scales)),
        Err(FilterError::InvalidValue { .. })
    ));
    let mut angles = vec![0.0f32; 200];
    angles[3] = f32::NAN;
    assert!(f.apply(Field::Map(&angles), Field::Constant(1.0)).is_err());
    assert!(Filter::new(&stack, &Decomposition::from_terms(vec![])).is_err());
    let bad = Decomposition::from_terms(vec![Term {
        weight: 1.0,
        x: 0.0,
        y: 0.0,
        sigma: -1.0,
    }]);
    assert!(matches!(
        Filter::new(&stack, &bad),
        Err(FilterError::InvalidTerm { index: 0, .. })
    ));
}

/// Rotates an interleaved image 90 degrees counter-clockwise on screen:
/// `g(y, w - 1 - x) = f(x, y)`.
fn rot90(data: &[f32], w: usize, h: usize, c: usize) -> Vec<f32> {
    let mut out = vec![0.0; data.len()];
    for y in 0..h {
        for x in 0..w {
            let (gx, gy) = (y, w - 1 - x);
            for ch in 0..c {
                out[(gy * h + gx) * c + ch] = data[(y * w + x) * c + ch];
            }
        }
    }
    out
}

fn no_pyramid() -> StackOptions {
    StackOptions {
        pyramid_factor: f64::INFINITY,
        ..StackOptions::default()
    }
}

fn border_strategy() -> impl Strategy<Value = Border> {
    prop_oneof![
        Just(Border::Reflect101),
        Just(Border::Replicate),
        Just(Border::Wrap),
        (-1.0f32..1.0).prop_map(Border::Constant),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn filtering_is_linear(
        w in 8usize..20,
        h in 8usize..20,
        seed in 1u64..1000,
        a in -2.0f32..2.0,
        b in -2.0f32..2.0,
        theta in -180.0f32..180.0,
        s in 0.8f32..1.6,
        border in border_strategy(),
    ) {
        let f = test_image(w, h, 2, seed);
        let g = test_image(w, h, 2, seed + 17);
        let d = small_decomposition();
        // Linearity holds for a zero constant border only (the constant is not scaled).
        let border = if let Border::Constant(_) = border { Border::Constant(0.0) } else { border };
        let mix: Vec<f32> = f.data().iter().zip(g.data()).map(|(x, y)| a * x + b * y).collect();
        let mix = Image::from_vec(w, h, 2, mix).expect("image");
        let run = |img: &Image| {
            let stack = stack_for_decomposition(img, &d, 0.8, 1.6, border, StackOptions::default()).expect("stack");
            Filter::new(&stack, &d).expect("filter").apply(Field::Constant(theta), Field::Constant(s)).expect("apply")
        };
        let (ff, fg, fm) = (run(&f), run(&g), run(&mix));
        for ((x, y), m) in ff.data().iter().zip(fg.data()).zip(fm.data()) {
            prop_assert!((a * x + b * y - m).abs() < 1e-4 * (1.0 + m.abs()));
        }
    }

    #[test]
    fn rotating_image_and_angle_field_commutes(
        w in 6usize..18,
        h in 6usize..18,
        seed in 1u64..1000,
        theta0 in -180.0f32..180.0,
        slope in -20.0f32..20.0,
        s in 0.8f32..1.5,
        border in border_strategy(),
    ) {
        let c = 2;
        let f = test_image(w, h, c, seed);
        let d = small_decomposition();
        let angles: Vec<f32> = (0..w * h).map(|i| theta0 + slope * (i % w) as f32 - 0.5 * slope * (i / w) as f32).collect();
        let run = |img: &Image, angles: &[f32]| {
            let stack = stack_for_decomposition(img, &d, s, s, border, no_pyramid()).expect("stack");
            Filter::new(&stack, &d).expect("filter").apply(Field::Map(angles), Field::Constant(s)).expect("apply")
        };
        let out = run(&f, &angles);
        let g = Image::from_vec(h, w, c, rot90(f.data(), w, h, c)).expect("image");
        let g_angles: Vec<f32> = rot90(&angles, w, h, 1).iter().map(|a| a + 90.0).collect();
        let out_g = run(&g, &g_angles);
        let want = rot90(out.data(), w, h, c);
        for (x, y) in want.iter().zip(out_g.data()) {
            prop_assert!((x - y).abs() < 2e-4, "{} vs {}", x, y);
        }
    }
}

/// CPU seconds used by this process so far (user + system), from `/proc/self/stat`.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit(')').next().unwrap_or_default();
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks: f64 = fields.get(11..13).map_or(0.0, |f| {
        f.iter().filter_map(|v| v.parse::<f64>().ok()).sum()
    });
    ticks / 100.0
}

/// Cost per lookup in CPU time (robust to a machine shared with other jobs;
/// the criterion bench reports wall time). `cargo test -p ifd-planar --release
/// --test filtering -- --ignored --nocapture timing_probe`
#[test]
#[ignore = "timing, not a check"]
fn timing_probe() {
    let (w, h) = (512, 512);
    let img = test_image(w, h, 1, 3);
    let angles = angle_field(w, h);
    let d = anisotropic_decomposition();
    let stack = stack_for_decomposition(
        &img,
        &d,
        1.0,
        2.0,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let f = Filter::new(&stack, &d).expect("filter");
    let scales: Vec<f32> = (0..w * h)
        .map(|i| 1.0 + (i % w) as f32 / w as f32)
        .collect();
    for (name, angle, scale) in [
        (
            "constant angle+scale",
            Field::Constant(30.0),
            Field::Constant(1.3),
        ),
        ("per-pixel angle", Field::Map(&angles), Field::Constant(1.3)),
        (
            "per-pixel angle+scale",
            Field::Map(&angles),
            Field::Map(&scales),
        ),
    ] {
        let reps = 10;
        let t0 = cpu_seconds();
        for _ in 0..reps {
            std::hint::black_box(f.apply(angle, scale).expect("apply"));
        }
        let cpu = (cpu_seconds() - t0) / f64::from(reps);
        let lookups = (w * h * f.len()) as f64;
        eprintln!(
            "{name}: {:.1} ms CPU per 512x512 image, {} terms, {:.2} ns CPU per term lookup",
            cpu * 1e3,
            f.len(),
            cpu * 1e9 / lookups
        );
    }
}

fn cubic() -> StackOptions {
    StackOptions {
        interpolation: Interpolation::Cubic,
        ..StackOptions::default()
    }
}

/// Cubic B-spline levels reproduce the Gaussian-filtered image at any
/// position (not only at stored samples), on subsampled levels too, and the
/// border modes resolve their coefficients as they resolve samples.
#[test]
fn cubic_levels_match_brute_force_gaussian_off_grid() {
    let img = test_image(40, 33, 2, 9);
    for border in BORDERS {
        let stack = ScaleStack::new(
            &img,
            2.0,
            12.0,
            border,
            StackOptions {
                margin: 6,
                ..cubic()
            },
        )
        .expect("stack");
        assert_eq!(stack.interpolation(), Interpolation::Cubic);
        let mut worst = 0.0f64;
        for l in stack.level_layouts() {
            for py in (-9..42).step_by(3) {
                for px in (-8..48).step_by(5) {
                    // Off every grid: quarter and third pixel offsets.
                    let (x, y) = (px as f32 + 0.25, py as f32 + 0.3);
                    let in_margin = (-6..=39 + 6).contains(&px) && (-6..=32 + 6).contains(&py);
                    if !(in_margin || matches!(border, Border::Reflect101 | Border::Wrap)) {
                        continue;
                    }
                    let v = stack.sample(x, y, l.sigma).expect("covered sigma");
                    for (ch, &got) in v.iter().enumerate() {
                        // The exact value at (x, y): the continuous Gaussian
                        // centred there, summed over the pixels.
                        let want = brute_gauss_at_f(&img, border, l.sigma, x, y, ch);
                        let e = (f64::from(got) - want).abs();
                        worst = worst.max(e);
                    }
                }
            }
        }
        eprintln!("{border}: cubic levels off grid, max error {worst:.2e}");
        // Bilinear reads of the same levels are off by about 1e-2.
        assert!(worst < 2e-4, "{border}: cubic lookups off by {worst}");
    }
}

/// Direct sum of the continuous Gaussian centred at a real position, to 7 sigma.
fn brute_gauss_at_f(img: &Image, border: Border, sigma: f64, x: f32, y: f32, ch: usize) -> f64 {
    let r = (7.0 * sigma).ceil() as i64;
    let (cx, cy) = (x.floor() as i64, y.floor() as i64);
    let mut acc = 0.0;
    for qy in cy - r..=cy + r + 1 {
        for qx in cx - r..=cx + r + 1 {
            let (dx, dy) = (qx as f64 - f64::from(x), qy as f64 - f64::from(y));
            let g = (-(dx * dx + dy * dy) / (2.0 * sigma * sigma)).exp()
                / (2.0 * std::f64::consts::PI * sigma * sigma);
            let v = match (
                border.resolve(qx, img.width()),
                border.resolve(qy, img.height()),
            ) {
                (Some(a), Some(b)) => img.get(a, b, ch),
                _ => border.constant(),
            };
            acc += g * f64::from(v);
        }
    }
    acc
}

/// Through cubic levels, the constant-pose filter (whose full-resolution
/// taps run as fixed 4x4 stencils) and the per-pixel path agree with the
/// brute-force correlation more closely than through bilinear levels.
#[test]
fn cubic_filter_matches_brute_force_much_closer_than_bilinear() {
    let img = test_image(72, 60, 3, 11);
    let d = anisotropic_decomposition();
    for border in BORDERS {
        let (theta, s) = (30.0f32, 1.5f32);
        let r = kernel_radius(&d, f64::from(s));
        let k = sample_kernel(|u, v| d.eval(u, v), f64::from(theta), f64::from(s), r);
        let want = correlate(&img, &k, 2 * r + 1, 2 * r + 1, border).expect("reference");
        let mut p = [0.0; 2];
        for (i, options) in [StackOptions::default(), cubic()].into_iter().enumerate() {
            let stack = stack_for_decomposition(&img, &d, s, s, border, options).expect("stack");
            let filter = Filter::new(&stack, &d).expect("filter");
            let out = filter
                .apply(Field::Constant(theta), Field::Constant(s))
                .expect("apply");
            p[i] = psnr(&out, &want);
            // The per-pixel path reads the same lookups.
            let angles = vec![theta; 72 * 60];
            let per_pixel = filter
                .apply(Field::Map(&angles), Field::Constant(s))
                .expect("apply");
            assert!(max_abs_diff(&out, &per_pixel) < 1e-5, "{border}");
        }
        eprintln!(
            "{border}: PSNR bilinear {:.1} dB, cubic {:.1} dB",
            p[0], p[1]
        );
        // What remains with cubic levels is the interpolation in ln sigma
        // (the sigmas 1.8 and 3 fall between levels here).
        assert!(p[1] >= 77.0 && p[1] >= p[0] + 6.0, "{border}: {p:?}");
    }
}

/// A stack with levels only for the terms a constant pose reads from it
/// (`level_sigmas`): the constant pose evaluates the narrow term directly;
/// a per-pixel angle, which reads every term from the stack, is refused as
/// out of range rather than reading a level it does not have.
#[test]
fn direct_terms_need_no_level_at_a_constant_pose_only() {
    let img = test_image(40, 32, 1, 5);
    let t = |weight, x, sigma| Term {
        weight,
        x,
        y: 0.0,
        sigma,
    };
    let d = Decomposition::from_terms(vec![t(0.6, 0.0, 3.0), t(0.4, 2.5, 0.6)]);
    let sigmas = ifd_planar::level_sigmas(&d, 1.0, ifd_planar::DIRECT_SIGMA);
    assert_eq!(sigmas, vec![3.0]);
    let stack = ScaleStack::with_sigmas(&img, &sigmas, Border::Reflect101, StackOptions::default())
        .expect("stack");
    let filter = Filter::new(&stack, &d)
        .expect("filter")
        .with_direct(&img, ifd_planar::DIRECT_SIGMA)
        .expect("direct");
    let out = filter
        .apply(Field::Constant(20.0), Field::Constant(1.0))
        .expect("constant pose");
    let r = kernel_radius(&d, 1.0);
    let k = sample_kernel(|u, v| d.eval(u, v), 20.0, 1.0, r);
    let want = correlate(&img, &k, 2 * r + 1, 2 * r + 1, Border::Reflect101).expect("reference");
    assert!(max_abs_diff(&out, &want) < 1e-4);
    let angles = vec![20.0; 40 * 32];
    assert!(matches!(
        filter.apply(Field::Map(&angles), Field::Constant(1.0)),
        Err(FilterError::ScaleOutOfRange { .. })
    ));
    assert!(matches!(
        filter.at_scale(1.0),
        Err(FilterError::ScaleOutOfRange { .. })
    ));
}

/// The per-pixel paths through the vector gathers and through the scalar
/// loop, on the same stack: they must agree bit for bit (where the CPU has no
/// vector kernels both runs take the scalar loop and this checks nothing, so
/// it says so).
fn vector_and_scalar(
    img: &Image,
    d: &Decomposition,
    angles: &[f32],
    scale: Field<'_>,
    (lo, hi): (f32, f32),
    border: Border,
    options: StackOptions,
) -> (Image, Image) {
    let stack = stack_for_decomposition(img, d, lo, hi, border, options).expect("stack");
    let run = |vector: bool| {
        Filter::new(&stack, d)
            .expect("filter")
            .with_vector_kernels(vector)
            .apply(Field::Map(angles), scale)
            .expect("apply")
    };
    if ifd_simd::isa() == ifd_simd::Isa::Baseline {
        eprintln!("no vector kernels on this CPU: vector and scalar runs are the same loop");
    }
    (run(true), run(false))
}

fn assert_same_bits(a: &Image, b: &Image) {
    let diff = a
        .data()
        .iter()
        .zip(b.data())
        .position(|(x, y)| x.to_bits() != y.to_bits() && x != y);
    assert!(diff.is_none(), "first difference at sample {diff:?}");
}

#[test]
fn vector_gathers_equal_the_scalar_loop_on_a_realistic_case() {
    // Wide enough for many 8-pixel blocks, a width that leaves a remainder,
    // a kernel that reaches past the borders, pyramid levels (steps > 1) and
    // a constant scale between levels (two lookups per term).
    let (w, h) = (203, 61);
    let d = anisotropic_decomposition();
    let angles = angle_field(w, h);
    // Also a stack read at the nearest level, at pyramid factor 1 (what
    // loose plans take with a scale map).
    let nearest = StackOptions {
        nearest_level: true,
        samples_per_octave: 3,
        pyramid_factor: 1.0,
        ..StackOptions::default()
    };
    for (c, options) in
        (1..=4).flat_map(|c| [(c, StackOptions::default()), (c, cubic()), (c, nearest)])
    {
        let img = test_image(w, h, c, 5 + c as u64);
        let (v, s) = vector_and_scalar(
            &img,
            &d,
            &angles,
            Field::Constant(2.7),
            (2.7, 2.7),
            Border::Reflect101,
            options,
        );
        assert_same_bits(&v, &s);
        let scales: Vec<f32> = (0..w * h)
            .map(|i| 0.6 + 2.4 * (i % w) as f32 / w as f32 + 0.5 * (i / w) as f32 / h as f32)
            .collect();
        let (v, s) = vector_and_scalar(
            &img,
            &d,
            &angles,
            Field::Map(&scales),
            (0.6, 3.5),
            Border::Reflect101,
            options,
        );
        assert_same_bits(&v, &s);
        // scales that jump within 8-pixel blocks: blocks spanning two to
        // five levels (vector lookups on up to four, lane by lane beyond)
        let jumpy: Vec<f32> = (0..w * h)
            .map(|i| 0.6 * 1.5f32.powi(((i % w) % 5 + (i / w) % 3) as i32))
            .collect();
        let (v, s) = vector_and_scalar(
            &img,
            &d,
            &angles,
            Field::Map(&jumpy),
            (0.6, 0.6 * 1.5f32.powi(6)),
            Border::Reflect101,
            options,
        );
        assert_same_bits(&v, &s);
    }
}

/// `Filter::accumulate_weighted` adds `weight *` what `apply` gives at every
/// pixel, bit for bit (one to four channels: the sum times the weight, as the
/// scalar loop writes it), through the vector rows and the scalar loop
/// alike, and leaves the pixels of weight zero as they were: rows with runs
/// of zeros and isolated zeros, scattered pixels (packed; runs in place are
/// `FilterSetPlan`'s, tested there), rows without zeros, negative weights, a constant scale and a scale map, bilinear and
/// cubic levels. Five channels (the general loop,
/// the weight in each tap) agree within rounding.
#[test]
fn weighted_accumulation_adds_weight_times_apply() {
    let (w, h) = (203, 37);
    let d = anisotropic_decomposition();
    let angles = angle_field(w, h);
    let scales: Vec<f32> = (0..w * h)
        .map(|i| 0.6 + 2.4 * (i % w) as f32 / w as f32 + 0.5 * (i / w) as f32 / h as f32)
        .collect();
    let weight: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if y % 5 == 4 {
                // a row without zeros
                return 0.5 + (x % 3) as f32;
            }
            if y % 5 == 3 {
                // scattered pixels
                return if x % 17 == 5 { 0.75 } else { 0.0 };
            }
            match (x / 24 + y) % 4 {
                0 => 0.0,                         // runs of zeros
                1 if x % 3 == 0 => 0.0,           // isolated zeros
                2 => -0.5 + (x % 7) as f32 / 7.0, // negative too
                _ => 0.25 + ((x * 31 + y * 17) % 13) as f32 / 13.0,
            }
        })
        .collect();
    for (c, options) in (1..=5).flat_map(|c| [(c, StackOptions::default()), (c, cubic())]) {
        let img = test_image(w, h, c, 9 + c as u64);
        let stack = stack_for_decomposition(&img, &d, 0.6, 3.5, Border::Reflect101, options)
            .expect("stack");
        for scale in [Field::Constant(2.7), Field::Map(&scales)] {
            for vector in [true, false] {
                let filter = Filter::new(&stack, &d)
                    .expect("filter")
                    .with_vector_kernels(vector);
                let full = filter.apply(Field::Map(&angles), scale).expect("apply");
                let prefill: Vec<f32> = (0..w * h * c).map(|i| 1.0 + (i % 11) as f32).collect();
                let mut out = Image::from_vec(w, h, c, prefill.clone()).expect("image");
                filter
                    .accumulate_weighted(Field::Map(&angles), scale, &weight, &mut out)
                    .expect("accumulate");
                for (i, ((&got, &was), &f)) in
                    out.data().iter().zip(&prefill).zip(full.data()).enumerate()
                {
                    let wt = weight[i / c];
                    let want = was + wt * f;
                    let ok = if wt == 0.0 {
                        got.to_bits() == was.to_bits()
                    } else if c <= 4 {
                        got.to_bits() == want.to_bits()
                    } else {
                        (got - want).abs() <= 1e-5 * want.abs().max(1.0)
                    };
                    assert!(
                        ok,
                        "{c} channels, vector {vector}, sample {i}: {got} != {was} + {wt} * {f}"
                    );
                }
            }
        }
    }
    // bad weights and shapes are refused
    let img = test_image(w, h, 1, 3);
    let stack = stack_for_decomposition(
        &img,
        &d,
        1.0,
        1.0,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let filter = Filter::new(&stack, &d).expect("filter");
    let mut out = Image::new(w, h, 1).expect("image");
    let mut bad = weight.clone();
    bad[w + 5] = f32::NAN;
    let err = filter
        .accumulate_weighted(Field::Constant(0.0), Field::Constant(1.0), &bad, &mut out)
        .unwrap_err();
    assert!(
        err.to_string().contains("weight NaN at pixel (5, 1)"),
        "{err}"
    );
    let err = filter
        .accumulate_weighted(
            Field::Constant(0.0),
            Field::Constant(1.0),
            &weight[1..],
            &mut out,
        )
        .unwrap_err();
    assert!(err.to_string().contains("one weight a pixel"), "{err}");
    assert!(
        out.data().iter().all(|&v| v == 0.0),
        "a refused call wrote its output"
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    #[test]
    fn vector_gathers_equal_the_scalar_loop(
        w in 1usize..40,
        h in 1usize..12,
        c in 1usize..6,
        seed in 1u64..1000,
        theta0 in -180.0f32..180.0,
        slope in -40.0f32..40.0,
        s0 in 0.5f32..2.0,
        varying_scale in any::<bool>(),
        cubic_levels in any::<bool>(),
        nearest_level in any::<bool>(),
        border in border_strategy(),
    ) {
        let img = test_image(w, h, c, seed);
        let d = small_decomposition();
        let angles: Vec<f32> = (0..w * h)
            .map(|i| theta0 + slope * (i % w) as f32 + 0.7 * slope * (i / w) as f32)
            .collect();
        let scales: Vec<f32> = (0..w * h)
            .map(|i| s0 * (1.0 + 0.05 * (i % 7) as f32 + 0.03 * (i / w) as f32))
            .collect();
        let hi = scales.iter().copied().fold(s0, f32::max);
        let (scale, range) = if varying_scale {
            (Field::Map(&scales), (s0, hi))
        } else {
            (Field::Constant(s0), (s0, s0))
        };
        let options = if cubic_levels { cubic() } else { StackOptions::default() };
        let options = StackOptions { nearest_level, ..options };
        let (v, s) = vector_and_scalar(&img, &d, &angles, scale, range, border, options);
        for (x, y) in v.data().iter().zip(s.data()) {
            prop_assert!(x == y, "{} vs {}", x, y);
        }
    }
}

/// The plan's expected error (`EvalPlan::error_estimate`, computed without
/// a pixel) is what filtering white noise measures against the exact sum of
/// Gaussians: bilinear and cubic levels at the terms' sigmas at the coarsest
/// and the most accurate pyramid factor under a per-pixel angle, and
/// log-uniform levels at 2 and 4 per octave under a per-pixel angle and
/// scale. The decomposition's weights cancel
/// (side lobes), so the terms' errors interfere, which the bound ignores.
#[test]
fn the_planned_error_estimate_is_what_white_noise_measures() {
    use ifd_planar::{CheckedField, FieldKind, FilterOptions, FilterPlan};
    let t = |weight, x, y, sigma| Term {
        weight,
        x,
        y,
        sigma,
    };
    let d = Decomposition::from_terms(vec![
        t(1.0, 0.0, 0.0, 5.0),
        t(-0.45, -7.0, 0.0, 4.5),
        t(-0.45, 7.0, 0.0, 4.5),
        t(0.3, 0.0, -6.0, 6.0),
        t(0.3, 0.0, 6.0, 6.0),
    ]);
    let n = 512;
    // Uniform white noise, angles uniform over the half turn and scales
    // log-uniform over [0.7, 1.4], independent per pixel.
    let mut next = images::xorshift(0x9e37_79b9_7f4a_7c15);
    let noise: Vec<f32> = (0..n * n).map(|_| (next() - 0.5) as f32).collect();
    let angles: Vec<f32> = (0..n * n).map(|_| (180.0 * next()) as f32).collect();
    let scales: Vec<f32> = (0..n * n)
        .map(|_| (0.7 * 2f64.powf(next())) as f32)
        .collect();
    let img = Image::from_vec(n, n, 1, noise).expect("image");
    // The exact correlation at pixel (px, py): each term's Gaussian centred
    // at p + s R_theta c (the convention of `sample_kernel`).
    let exact = |px: usize, py: usize, theta: f64, s: f64| {
        let (sin, cos) = theta.to_radians().sin_cos();
        let mut acc = 0.0;
        for term in &d.terms {
            let sigma = s * term.sigma;
            let qx = px as f64 + s * (cos * term.x + sin * term.y);
            let qy = py as f64 + s * (-sin * term.x + cos * term.y);
            let r = (6.0 * sigma).ceil() as i64;
            let (cx, cy) = (qx.round() as i64, qy.round() as i64);
            let mut sum = 0.0;
            for y in cy - r..=cy + r {
                for x in cx - r..=cx + r {
                    let (dx, dy) = (x as f64 - qx, y as f64 - qy);
                    let g = (-(dx * dx + dy * dy) / (2.0 * sigma * sigma)).exp()
                        / (2.0 * std::f64::consts::PI * sigma * sigma);
                    sum += g * f64::from(img.get(x as usize, y as usize, 0));
                }
            }
            acc += term.weight * sum;
        }
        acc
    };
    let cases = [Interpolation::Linear, Interpolation::Cubic]
        .into_iter()
        .flat_map(|i| [false, true].map(|scaled| (i, scaled)));
    for (interpolation, scaled) in cases {
        for budget in [1.0, 0.06, 1e-6] {
            let angle = CheckedField::new(Field::Map(&angles), FieldKind::Angle, n, n).unwrap();
            let scale = if scaled {
                CheckedField::new(Field::Map(&scales), FieldKind::Scale, n, n).unwrap()
            } else {
                CheckedField::new(Field::Constant(1.0), FieldKind::Scale, n, n).unwrap()
            };
            let options = FilterOptions {
                interpolation: Some(interpolation),
                eval_budget: Some(budget),
                ..FilterOptions::default()
            };
            let plan = FilterPlan::new((n, n, 1), &d, &angle, &scale, &options).expect("plan");
            let stack = plan.build_stack(&img).expect("stack");
            let out = plan.evaluate(&img, &stack, angle, scale).expect("evaluate");
            // Interior pixels only (the reference reaches 61 px at scale 1.4), on
            // an odd stride (an even one would see one phase of the steps).
            let (mut err2, mut ref2) = (0.0, 0.0);
            for py in (72..n - 72).step_by(7) {
                for px in (72..n - 72).step_by(7) {
                    let i = py * n + px;
                    let s = if scaled { f64::from(scales[i]) } else { 1.0 };
                    let want = exact(px, py, f64::from(angles[i]), s);
                    err2 += (f64::from(out.get(px, py, 0)) - want).powi(2);
                    ref2 += want * want;
                }
            }
            let measured = (err2 / ref2).sqrt();
            let e = plan.eval;
            eprintln!(
                "{interpolation:?}, scale map {scaled}, factor {}, {} per octave, nearest {}: \
                 measured {:.4}%, estimate {:.4}%, bound {:.4}%",
                e.pyramid_factor,
                e.samples_per_octave,
                e.nearest_level,
                100.0 * measured,
                100.0 * e.error_estimate,
                100.0 * e.total_bound()
            );
            // The loosest budget takes the first candidate and the fewest
            // levels; the tightest the most accurate (bilinear: factor 4).
            if budget > 0.5 {
                assert_eq!(e.pyramid_factor, 1.0);
            } else if interpolation == Interpolation::Linear && budget < 1e-3 {
                assert_eq!(e.pyramid_factor, 4.0);
            }
            // With a scale map the loosest budget reads each term's nearest
            // level (one lookup) from the fewest levels; the tightest blends
            // two of the most.
            if scaled && budget > 0.5 {
                assert_eq!((e.samples_per_octave, e.nearest_level), (2, true));
            } else if scaled && budget < 1e-3 {
                assert_eq!((e.samples_per_octave, e.nearest_level), (4, false));
            }
            assert!(!e.nearest_level || scaled);
            // Within 15% either way.
            let ratio = e.error_estimate / measured;
            assert!(
                ratio > 0.85 && ratio < 1.15,
                "estimate {} against measured {measured}",
                e.error_estimate
            );
            assert!(e.total_bound() > 1.5 * e.error_estimate);
        }
    }
}
