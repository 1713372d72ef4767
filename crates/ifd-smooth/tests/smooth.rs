//! Hessian and smoothing checked against analytic identities and brute force.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] functions: a panic is the failure report"
)]

use std::sync::{Arc, OnceLock};

#[path = "../../../tests/support/images.rs"]
mod images;

use ifd_image::Image;
use ifd_planar::{Border, Filter};
use ifd_smooth::{
    AnisoGaussian, AspectBank, BankLookups, BankOptions, Dab, HessianBank, Mode, PixelGaussians,
    SmoothError, SmoothOptions, Smoother, hessian_image,
};
use images::edge_waves as test_image;

fn banks() -> &'static (Arc<AspectBank>, HessianBank) {
    static B: OnceLock<(Arc<AspectBank>, HessianBank)> = OnceLock::new();
    B.get_or_init(|| {
        let bank = AspectBank::build(BankOptions::default(), |_, _| {}).unwrap();
        (Arc::new(bank), HessianBank::new(0.01).unwrap())
    })
}

fn smoother(img: &Image, scale: f64) -> Smoother {
    let (bank, hbank) = banks();
    let opts = SmoothOptions {
        scale,
        ..SmoothOptions::default()
    };
    Smoother::with_banks(img, &opts, bank.clone(), hbank).unwrap()
}

#[test]
fn hessian_of_a_quadratic_is_exact() {
    // f = a x^2 + b x y + c y^2 has Hxx = 2a, Hxy = b, Hyy = 2c everywhere.
    let (w, h) = (96, 80);
    let (a, b, c) = (3e-4, -2e-4, 1e-4);
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64 - 48.0, (i / w) as f64 - 40.0);
            (a * x * x + b * x * y + c * y * y) as f32
        })
        .collect();
    let img = Image::from_vec(w, h, 1, data).unwrap();
    let (_, hbank) = banks();
    for sigma in [2.0, 4.0] {
        let hes = hessian_image(&img, sigma, hbank, Border::Reflect101).unwrap();
        // Away from the border (reflection bends the parabola there).
        let (x, y) = (48, 40);
        let got = [hes.get(x, y, 0), hes.get(x, y, 1), hes.get(x, y, 2)];
        let want = [2.0 * a, b, 2.0 * c];
        for k in 0..3 {
            let err = (f64::from(got[k]) - want[k]).abs();
            assert!(
                err < 0.03 * 2.0 * a,
                "sigma {sigma} component {k}: {got:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn point_hessian_equals_whole_image() {
    let img = test_image(64, 64);
    let (_, hbank) = banks();
    let whole = hessian_image(&img, 3.0, hbank, Border::Reflect101).unwrap();
    let stack = ifd_planar::ScaleStack::new(
        &img,
        hbank.stack_sigmas(3.0, 3.0).0,
        hbank.stack_sigmas(3.0, 3.0).1,
        Border::Reflect101,
        ifd_smooth::hessian_stack_options(),
    )
    .unwrap();
    let f = hbank.bind(&stack).unwrap();
    for (x, y) in [(10, 20), (33, 33), (60, 5)] {
        let p = f.at(x as f32, y as f32, 3.0).unwrap();
        for (k, &pk) in p.iter().enumerate() {
            let d = (pk - f64::from(whole.get(x, y, k))).abs();
            assert!(
                d < 1e-5,
                "({x}, {y}) component {k}: {} vs {}",
                pk,
                whole.get(x, y, k)
            );
        }
    }
}

#[test]
fn blending_bank_entries_costs_little_accuracy() {
    let (bank, _) = banks();
    for w in bank.aspects.windows(2) {
        let mid = (w[0] * w[1]).sqrt();
        let e = bank.blend_error(mid).unwrap();
        // Measured at most 1.05% at the midpoints (docs/smoothing.md); the
        // entries themselves are 1%.
        assert!(e < 0.015, "aspect {mid}: blended error {e}");
    }
    assert!(bank.blend_error(bank.aspects[2]).unwrap() < 0.0105);
}

#[test]
fn constant_image_stays_constant() {
    let img = Image::from_vec(48, 40, 2, vec![0.25; 48 * 40 * 2]).unwrap();
    let s = smoother(&img, 4.0);
    for mode in [Mode::PerPixel, Mode::Dab] {
        let out = s.smooth_image(mode).unwrap();
        // Flat images give a zero Hessian: isotropic filters, never NaN.
        assert!(
            s.orientation_field()
                .iter()
                .all(|o| o.aspect < 1.001 && o.theta.is_finite())
        );
        let err = out
            .data()
            .iter()
            .map(|v| (v - 0.25).abs())
            .fold(0.0f32, f32::max);
        assert!(err < 0.01 * 0.25, "{mode:?}: {err}");
    }
}

#[test]
fn smoothing_runs_along_edges() {
    // A vertical step edge: smoothing along it keeps it sharp.
    let (w, h) = (64, 64);
    let data: Vec<f32> = (0..w * h)
        .map(|i| if i % w < 32 { 0.0 } else { 1.0 })
        .collect();
    let img = Image::from_vec(w, h, 1, data).unwrap();
    let s = smoother(&img, 4.0);
    let o = s.orientation_at(31.5, 32.0);
    assert!((o.theta.rem_euclid(180.0) - 90.0).abs() < 5.0, "{o:?}");
    assert!(o.aspect > 4.0, "{o:?}");
    let out = s.smooth_image(Mode::PerPixel).unwrap();
    let gauss = |u: f64, v: f64| (-(u * u + v * v) / 32.0).exp() / (32.0 * std::f64::consts::PI);
    let k = ifd_planar::internals::reference::sample_kernel(gauss, 0.0, 1.0, 16);
    let iso =
        ifd_planar::internals::reference::correlate(&img, &k, 33, 33, Border::Reflect101).unwrap();
    // The anisotropic result keeps more contrast across the edge than an isotropic Gaussian.
    let contrast = |im: &Image| im.get(34, 32, 0) - im.get(29, 32, 0);
    assert!(
        contrast(&out) > contrast(&iso) + 0.1,
        "{} vs {}",
        contrast(&out),
        contrast(&iso)
    );
}

#[test]
fn dab_matches_whole_image_inside() {
    let img = test_image(80, 72);
    let s = smoother(&img, 3.0);
    let whole = s.smooth_image(Mode::PerPixel).unwrap();
    let mut target = img.clone();
    let dab = Dab {
        x: 40.0,
        y: 36.0,
        radius: 16.0,
        falloff: 0.0,
        strength: 1.0,
    };
    let region = s
        .apply_dab(&dab, Mode::PerPixel, &mut target)
        .unwrap()
        .unwrap();
    assert!(region.width <= 34 && region.height <= 34);
    for (x, y) in [(40, 36), (50, 40), (30, 30)] {
        assert!((target.get(x, y, 0) - whole.get(x, y, 0)).abs() < 1e-6);
    }
    // Outside the dab nothing changes.
    assert_eq!(target.get(5, 5, 0), img.get(5, 5, 0));
    // A dab far outside the image touches nothing.
    let off = Dab { x: -100.0, ..dab };
    assert!(s.apply_dab(&off, Mode::Dab, &mut target).unwrap().is_none());
}

/// The whole image and any rectangle of it, per pixel and in dabs (the
/// bank's weighted passes on the vector rows), equal each pixel's Gaussians
/// applied through the per-point lookups ([`PixelGaussians::accumulate`]
/// at the footprint scale; in dabs, the four corners' orientations with
/// their bilinear weights) bit for bit, one channel and three.
#[test]
fn whole_image_passes_equal_the_per_point_lookups() {
    let grey = test_image(83, 61);
    let (w, h) = (grey.width(), grey.height());
    let rgb: Vec<f32> = grey
        .data()
        .iter()
        .enumerate()
        .flat_map(|(i, &v)| [v, 1.0 - v, 0.5 * v + 0.25 * ((i % 7) as f32 / 7.0)])
        .collect();
    let rgb = Image::from_vec(w, h, 3, rgb).unwrap();
    for (img, scale) in [(&grey, 2.5), (&grey, 6.0), (&rgb, 4.0)] {
        let c = img.channels();
        let s = smoother(img, scale);
        let filters: Vec<Filter<'_>> = s
            .prepared_bank()
            .iter()
            .map(|d| Filter::new(s.stack(), d).unwrap())
            .collect();
        let at = (scale / s.bank().options.sigma_ref) as f32;
        let scaled = filters.iter().map(|f| f.at_scale(at).unwrap()).collect();
        let gauss = PixelGaussians::new(
            s.bank(),
            Some(BankLookups::Fixed(scaled)),
            None,
            Border::Reflect101,
        );
        let gaussian = |o: ifd_smooth::Orientation| AnisoGaussian {
            theta: o.theta,
            aspect: o.aspect,
            footprint: scale as f32,
        };
        for mode in [Mode::PerPixel, Mode::Dab] {
            let whole = s.smooth_image(mode).unwrap();
            for y in 0..h {
                for x in 0..w {
                    let (xf, yf) = (x as f32, y as f32);
                    let mut want = vec![0.0f32; c];
                    match mode {
                        Mode::PerPixel => {
                            let o = s.orientation_field()[y * w + x];
                            gauss.accumulate(xf, yf, gaussian(o), 1.0, &mut want);
                        }
                        Mode::Dab => {
                            for ((cx, cy), wgt) in s.dab_corners(xf, yf) {
                                let o = s.orientation_at(cx, cy);
                                gauss.accumulate(xf, yf, gaussian(o), wgt, &mut want);
                            }
                        }
                    }
                    for (ch, v) in want.iter().enumerate() {
                        let got = whole.get(x, y, ch);
                        assert_eq!(
                            got.to_bits(),
                            v.to_bits(),
                            "S = {scale}, {mode:?}, ({x}, {y}) channel {ch}: {got} != {v}"
                        );
                    }
                }
            }
            // a tile's rectangle (passes) and a small one (the per-point loop)
            for (x0, y0, rw, rh) in [(7, 11, 50, 23), (30, 20, 9, 7)] {
                let rect = ifd_smooth::DabRegion {
                    x0,
                    y0,
                    width: rw,
                    height: rh,
                };
                let part = s.smooth_rect(mode, rect).unwrap();
                assert_eq!(
                    part.data(),
                    whole.crop(x0, y0, rw, rh).data(),
                    "S = {scale}, {mode:?}"
                );
            }
        }
    }
}

#[test]
fn bad_input_is_refused() {
    let (bank, hbank) = banks();
    let mut img = test_image(32, 32);
    let opts = SmoothOptions {
        scale: 500.0,
        ..SmoothOptions::default()
    };
    let e = Smoother::with_banks(&img, &opts, bank.clone(), hbank).unwrap_err();
    assert!(
        matches!(e, SmoothError::OutOfRange { name: "scale", .. }),
        "{e}"
    );
    img.set(3, 4, 0, f32::NAN);
    let e = Smoother::with_banks(&img, &SmoothOptions::default(), bank.clone(), hbank).unwrap_err();
    assert!(e.to_string().contains("NaN"), "{e}");
    let img = test_image(32, 32);
    let s = smoother(&img, 3.0);
    let mut wrong = Image::new(10, 10, 1).unwrap();
    let dab = Dab {
        x: 5.0,
        y: 5.0,
        radius: 3.0,
        falloff: 0.5,
        strength: 1.0,
    };
    assert!(s.apply_dab(&dab, Mode::Dab, &mut wrong).is_err());
    let mut ok = img.clone();
    let bad = Dab {
        strength: 2.0,
        ..dab
    };
    assert!(s.apply_dab(&bad, Mode::Dab, &mut ok).is_err());
    assert!(hessian_image(&img, 0.1, hbank, Border::Reflect101).is_err());
}

#[test]
fn small_footprints_are_evaluated_directly() {
    // Below 2 px the pixel-integrated Gaussians are applied tap by tap.
    let img = test_image(64, 56);
    let s = smoother(&img, 0.5);
    assert!(s.direct_kernels().is_some());
    assert!(smoother(&img, 2.0).direct_kernels().is_none());
    // The whole image, a dab and a constant image agree with each other.
    let whole = s.smooth_image(Mode::PerPixel).unwrap();
    let mut target = img.clone();
    let dab = Dab {
        x: 30.0,
        y: 28.0,
        radius: 12.0,
        falloff: 0.0,
        strength: 1.0,
    };
    s.apply_dab(&dab, Mode::PerPixel, &mut target).unwrap();
    for (x, y) in [(30, 28), (36, 33), (22, 24)] {
        assert!((target.get(x, y, 0) - whole.get(x, y, 0)).abs() < 1e-6);
    }
    // At S = 0.5 the filter keeps about half of each pixel (the step of
    // the test image is 0.6).
    let change = whole
        .data()
        .iter()
        .zip(img.data())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(change > 1e-3 && change < 0.45, "{change}");
    let flat = Image::from_vec(40, 30, 1, vec![0.75; 1200]).unwrap();
    for scale in [0.5, 1.3] {
        let out = smoother(&flat, scale).smooth_image(Mode::Dab).unwrap();
        assert!(out.data().iter().all(|v| (v - 0.75).abs() < 1e-5));
    }
}

#[test]
fn direct_refresh_follows_the_edited_image() {
    let (bank, hbank) = banks();
    let img = test_image(48, 48);
    let mut s = smoother(&img, 1.0);
    let mut edited = img.clone();
    for y in 10..20 {
        for x in 12..30 {
            edited.set(x, y, 0, 0.9);
        }
    }
    let rect = ifd_planar::PixelRect {
        x0: 12,
        y0: 10,
        width: 18,
        height: 10,
    };
    s.refresh_region(&edited, rect, hbank).unwrap();
    let opts = SmoothOptions {
        scale: 1.0,
        ..SmoothOptions::default()
    };
    let fresh = Smoother::with_banks(&edited, &opts, bank.clone(), hbank).unwrap();
    let (a, b) = (
        s.smooth_image(Mode::PerPixel).unwrap(),
        fresh.smooth_image(Mode::PerPixel).unwrap(),
    );
    let worst = a
        .data()
        .iter()
        .zip(b.data())
        .map(|(p, q)| (p - q).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-4, "{worst}");
}

/// Tiles (each with its own stack, field and dab grid) give the whole
/// image's result: both modes, a stack-based and a direct footprint, tiles
/// smaller than the filters' reach.
#[test]
fn tiled_smoothing_equals_whole_image() {
    use ifd_planar::PixelRect;
    use ifd_smooth::{SmoothTiles, smooth_tiled};
    let (bank, hbank) = banks();
    let (w, h) = (420, 400);
    // Two channels: the Hessian of the channel mean, smoothing per channel.
    let base = test_image(w, h);
    let data = base
        .data()
        .iter()
        .enumerate()
        .flat_map(|(i, &v)| [v, 0.5 + 0.3 * ((i % w) as f32 / 5.0).sin() * v])
        .collect();
    let img = Image::from_vec(w, h, 2, data).unwrap();
    for (scale, mode) in [
        (5.0, Mode::PerPixel),
        (5.0, Mode::Dab),
        (1.5, Mode::Dab),
        (1.5, Mode::PerPixel),
    ] {
        let opts = SmoothOptions {
            scale,
            ..SmoothOptions::default()
        };
        let whole = Smoother::with_banks(&img, &opts, bank.clone(), hbank)
            .unwrap()
            .smooth_image(mode)
            .unwrap();
        let tiles = SmoothTiles::new((w, h, 2), &opts, mode, bank, hbank, 1).unwrap();
        let t = tiles.tiling;
        assert!(t.tiles().len() >= 4, "scale {scale}: {t:?}");
        let mut out = Image::new(w, h, 2).unwrap();
        let mut n = 0;
        smooth_tiled(
            &tiles,
            &opts,
            bank,
            hbank,
            &mut |r: PixelRect| Ok(img.crop(r.x0, r.y0, r.width, r.height)),
            |tile| -> Result<(), SmoothError> {
                out.paste(tile.inner.x0, tile.inner.y0, &tile.smooth(mode)?);
                Ok(())
            },
            |done, _| n = done,
        )
        .unwrap();
        assert_eq!(n, t.tiles().len());
        let diff = out
            .data()
            .iter()
            .zip(whole.data())
            .fold(0f32, |m, (a, b)| m.max((a - b).abs()));
        eprintln!("scale {scale} {mode:?}: {t:?}: max difference {diff:e}");
        assert!(
            diff < 1e-5,
            "scale {scale} {mode:?}: tiles of {} px (halo {}) differ by {diff}",
            t.tile,
            t.halo
        );
    }
}

/// A cached bank is reused only when the current fitting code made it: one
/// recorded with an older `FIT_REVISION` (or none, as files written before
/// it was recorded) is refitted and the cache rewritten, so an upgrade does
/// not keep smoothing with fits the new code would not make.
#[test]
fn a_cached_bank_from_older_fitting_code_is_refitted() {
    let dir = std::env::temp_dir().join(format!("ifd-smooth-bank-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bank.json");
    let (bank, _) = banks();
    bank.save(&path).unwrap();
    let (same, source) = AspectBank::load_or_build(bank.options, Some(&path), |_, _| {}).unwrap();
    assert_eq!(source, path.display().to_string());
    assert_eq!(&same, bank.as_ref());
    // The same bank, as older code would have recorded it: altered weights
    // that a refit cannot reproduce, and no revision.
    let mut old = (**bank).clone();
    old.fit_revision = 0;
    for t in old.terms.iter_mut().flatten() {
        t.weight *= 1.01;
    }
    old.save(&path).unwrap();
    let (fresh, source) = AspectBank::load_or_build(bank.options, Some(&path), |_, _| {}).unwrap();
    assert_eq!(source, "fitted");
    assert_eq!(fresh.fit_revision, ifd_planar::FIT_REVISION);
    assert_eq!(&fresh, bank.as_ref());
    assert_eq!(&AspectBank::load(&path).unwrap(), bank.as_ref());
    // A damaged file of the current revision (weights ten times too large,
    // an absurd sigma) is not trusted: refused by `load`, refitted.
    for damage in 0..2 {
        let mut bad = (**bank).clone();
        if damage == 0 {
            for t in bad.terms.iter_mut().flatten() {
                t.weight *= 10.0;
            }
        } else {
            bad.terms[1][0].sigma = 1e300;
        }
        bad.save(&path).unwrap();
        let e = AspectBank::load(&path).unwrap_err().to_string();
        assert!(e.contains("bank.json") && e.contains("entry"), "{e}");
        let (fresh, source) =
            AspectBank::load_or_build(bank.options, Some(&path), |_, _| {}).unwrap();
        assert_eq!(source, "fitted");
        assert_eq!(&fresh, bank.as_ref());
    }
    std::fs::remove_dir_all(&dir).ok();
}
