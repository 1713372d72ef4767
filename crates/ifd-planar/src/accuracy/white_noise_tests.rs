//! Unit tests of `white_noise.rs`.

use super::*;
use crate::term::Term;

/// The pair sums (integrals) and the grid (pixel sums) agree where the
/// Gaussians are a few pixels wide, bilinear and cubic, on one level
/// per term and on blended levels with pyramid steps.
#[test]
fn pair_sums_and_the_pixel_grid_agree() {
    let t = |weight, x, y, sigma| Term {
        weight,
        x,
        y,
        sigma,
    };
    // Asymmetric on purpose: offsets off the axes, sigmas 3.2 to 6.5.
    let d = Decomposition::from_terms(vec![
        t(0.8, 1.5, -2.0, 3.2),
        t(-0.6, -9.0, 4.0, 4.1),
        t(0.5, 11.0, 3.5, 6.5),
        t(0.25, -3.0, -12.0, 5.3),
    ]);
    let (mut terms, mut parts) = (Vec::new(), Vec::new());
    for interpolation in [Interpolation::Linear, Interpolation::Cubic] {
        for levels in [
            Placement::AtSigmas,
            Placement::log_uniform((2.0, 9.0), 2, false),
            Placement::log_uniform((2.0, 9.0), 3, true),
        ] {
            for i in 0..6 {
                let pose = Pose::nth(i, 6);
                let s = 0.8 + 0.1 * i as f64;
                place(
                    &d,
                    s,
                    &pose,
                    (interpolation, 2.0),
                    0.0,
                    &levels,
                    &mut terms,
                    &mut parts,
                );
                let (pairs, grid) = (error2(&terms, &parts), error2_on_grid(&parts));
                assert!(
                    (pairs / grid - 1.0).abs() < 1e-3,
                    "{interpolation:?} {levels:?} pose {i}: {pairs} {grid}"
                );
            }
        }
    }
}

/// A grid past `MAX_GRID_CELLS` is never chosen (the pair sums serve),
/// and scales whose norms are not numbers give an infinite estimate,
/// never one within a budget.
#[test]
fn huge_grids_and_absurd_scales_are_refused() {
    let here = Part {
        coef: 1.0,
        var: 4.0,
        x: Axis::point(0.0),
        y: Axis::point(0.0),
    };
    let far = Part {
        x: Axis::point(1e4),
        y: Axis::point(1e4),
        ..here
    };
    assert!(grid_cost(&[here]).is_finite());
    assert_eq!(grid_cost(&[here, far]), f64::INFINITY);
    let d = Decomposition::from_terms(vec![Term {
        weight: 1.0,
        x: 2.0,
        y: 0.0,
        sigma: 3.0,
    }]);
    let noise = WhiteNoise::new(&d, (1e-200, 1e-200), 0.0);
    for i in [Interpolation::Linear, Interpolation::Cubic] {
        assert_eq!(noise.expected((i, 2.0), Levels::AtSigmas), f64::INFINITY);
    }
}

/// The cardinal cubic spline interpolates (1 at 0, 0 at the other
/// integers) and reproduces constants and lines from the kept taps.
#[test]
fn cardinal_cubic_interpolates() {
    assert!((cardinal_cubic(0.0) - 1.0).abs() < 1e-12);
    for k in 1..6 {
        assert!(cardinal_cubic(f64::from(k)).abs() < 1e-12, "{k}");
        assert!(cardinal_cubic(-f64::from(k)).abs() < 1e-12, "{k}");
    }
    for phi in [0.1, 0.37, 0.5, 0.9] {
        let a = Axis::read(3.0 + phi, 1.0, Interpolation::Cubic);
        let sum: f64 = a.w[..a.n].iter().sum();
        let first: f64 = (0..a.n).map(|j| a.w[j] * (a.start + j as f64)).sum();
        assert!((sum - 1.0).abs() < 3e-5, "{phi}: {sum}");
        assert!((first - (3.0 + phi)).abs() < 3e-4, "{phi}: {first}");
    }
}

/// A screen (every fourth pose) never puts the estimate far above what
/// every pose does (measured: at most 8% above, and up to 27% below on a
/// 4-term kernel over a scale range), well within [`SCREEN_MARGIN`], on
/// fitted decompositions of few terms and many, bilinear and cubic, one
/// scale and a range, at pyramid factors a plan weighs; within its budget a
/// screen is the full estimate, bit for bit.
#[test]
fn screens_agree_with_every_pose() {
    let (mut worst, mut least): (f64, f64) = (1.0, 1.0);
    for (spec, tol) in [
        ("gauss:sx=32,sy=4,theta=0", 0.1),
        ("gauss:sx=32,sy=4,theta=0", 0.01),
        ("gauss:sx=6,sy=6", 0.01),
        ("log:sigma=5", 0.03),
        ("box:w=15,h=5", 0.05),
    ] {
        let spec: crate::KernelSpec = spec.parse().unwrap();
        let opts = crate::DecomposeOptions {
            tol,
            ..crate::DecomposeOptions::default()
        };
        let d = crate::decompose_spec(&spec, &opts, None, |_, _, _| {}).unwrap();
        for scales in [(1.0, 1.0), (0.5, 1.0)] {
            let noise = WhiteNoise::new(&d, scales, 0.0);
            for read in [
                (Interpolation::Linear, 1.0),
                (Interpolation::Linear, 2.0),
                (Interpolation::Cubic, 1.0),
                (Interpolation::Cubic, 4.0),
            ] {
                let levels = if scales.0 < scales.1 {
                    Levels::LogUniform {
                        per_octave: 3,
                        nearest: false,
                    }
                } else {
                    Levels::AtSigmas
                };
                let full = noise.expected(read, levels);
                // A budget the screen cannot reject on: the full estimate.
                assert_eq!(
                    noise.screened(read, levels, Some(full)),
                    (full, true),
                    "{spec:?} {read:?}"
                );
                // A budget it rejects on: the screen's own mean (too few
                // poses, from 65 terms: never screened).
                let (partial, exact) = noise.screened(read, levels, Some(1e-12));
                if noise.poses.len() < SCREEN_LEAST * SCREEN_STRIDE {
                    assert_eq!((partial, exact), (full, true));
                    continue;
                }
                assert!(!exact && partial > 1e-12);
                // Above the full estimate a screen could reject what the
                // full estimate accepts; below it, it only costs the rest.
                worst = worst.max(partial / full);
                least = least.min(partial / full);
            }
        }
    }
    assert!(worst < SCREEN_MARGIN / 1.15, "{worst}");
    // Below: the choice re-estimates in full wherever a screen this low
    // could change a stall or the choice among rejected candidates.
    assert!(least > 1.0 / STALL_SLACK, "{least}");
}

/// The recurrence of `gaussian_run` stays on the exponentials it replaces,
/// across re-anchoring, in the tails and for narrow and wide Gaussians.
#[test]
fn gaussian_runs_follow_the_exponential() {
    for (d0, sigma, n) in [
        (-40.3, 5.0, 81),
        (-3.0, 0.6, 7),
        (-700.0, 120.0, 1401),
        (2.5, 3.0, 100),
        // narrow: a cubic read's table starts 16 + 6 sigma out, far in
        // the tail (the anchor is zero in f64), and the exact point of a
        // sub-pixel atom (its ratios overflow)
        (-18.0, 0.45, 37),
        (-1.2, 0.03, 4),
        (-40.0, 0.3, 81),
    ] {
        let inv = -0.5 / (sigma * sigma);
        let mut out = vec![0.0; n];
        gaussian_run(d0, inv, 2.0, &mut out);
        for (i, &o) in out.iter().enumerate() {
            let d = d0 + i as f64;
            let exact = 2.0 * (d * d * inv).exp();
            assert!(
                (o - exact).abs() <= 1e-13 * exact + 1e-250,
                "{d0} {sigma} {i}: {o} {exact}"
            );
        }
    }
}
