//! End-to-end tests of `ifd decompose`, `ifd filter` and `ifd smooth`: bad
//! input gets exit code 2 and a message naming the problem; good input gives
//! outputs of the right shape.

use std::path::Path;

use ifd_image::Image;

mod common;
use common::ifd;

fn path(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

fn save(dir: &Path, name: &str, w: usize, h: usize, data: Vec<f32>) -> String {
    save_channels(dir, name, (w, h, 1), data)
}

/// As [`save`], with `c` channels.
fn save_channels(
    dir: &Path,
    name: &str,
    (w, h, c): (usize, usize, usize),
    data: Vec<f32>,
) -> String {
    let p = path(dir, name);
    let img = Image::from_vec(w, h, c, data).expect("test image");
    // (inputs may hold NaN: that is what some tests refuse)
    let fixture = ifd_image::WriteOptions {
        allow_non_finite: true,
        ..ifd_image::WriteOptions::default()
    };
    ifd_image::write_image(Path::new(&p), &img, &fixture).expect("write test image");
    p
}

/// Exit code 2, every `needles` in stderr, and no output file left behind.
fn refused(args: &[&str], needles: &[&str], output: Option<&str>) {
    let (code, _, err) = ifd(args);
    assert_eq!(code, 2, "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: expected {n:?} in {err:?}");
    }
    assert!(!err.contains("panicked"), "{err}");
    if let Some(o) = output {
        assert!(!Path::new(o).exists(), "{o} was written");
    }
}

#[test]
fn decompose_refuses_bad_kernels() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = path(d, "d.json");
    let zero = save(d, "zero.npy", 9, 9, vec![0.0; 81]);
    let even = save(d, "even.npy", 8, 9, vec![1.0; 72]);
    let mut nan = vec![1.0; 81];
    nan[40] = f32::NAN;
    let nan = save(d, "nan.npy", 9, 9, nan);
    refused(&["decompose", &zero, "-o", &out], &["zero"], Some(&out));
    refused(&["decompose", &even, "-o", &out], &["odd"], Some(&out));
    refused(&["decompose", &nan, "-o", &out], &["NaN"], Some(&out));
    refused(
        &["decompose", "gauss:sx=4,sy=2", "--levels", "40", "-o", &out],
        &["level"],
        Some(&out),
    );
    refused(
        &["decompose", "gauss:sx=-4,sy=2", "-o", &out],
        &["sx"],
        Some(&out),
    );
    refused(
        &["decompose", "nosuchfilter:a=1", "-o", &out],
        &["nosuchfilter"],
        Some(&out),
    );
}

#[test]
fn decompose_then_filter_a_kernel_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A 3:1 Gaussian written as a kernel file, centre at the middle.
    let r = 12i32;
    let n = (2 * r + 1) as usize;
    let k: Vec<f32> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as i32 - r, (i / n) as i32 - r);
            (-0.5 * ((x * x) as f32 / 9.0 + (y * y) as f32)).exp()
        })
        .collect();
    let kfile = save(d, "k.npy", n, n, k);
    let dec = path(d, "d.json");
    let (code, out, err) = ifd(&["decompose", &kfile, "-o", &dec, "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(v["rel_l2_error"].as_f64().unwrap() < 0.02, "{v}");
    assert!(v["terms"].as_u64().unwrap() > 0, "{v}");
    let img = save(
        d,
        "img.npy",
        64,
        48,
        (0..64 * 48).map(|i| (i % 7) as f32).collect(),
    );
    let o = path(d, "o.npy");
    let (code, _, err) = ifd(&["filter", &img, "--decomp", &dec, "-o", &o]);
    assert_eq!(code, 0, "{err}");
    let res = ifd_image::read(&o).unwrap();
    assert_eq!((res.width(), res.height(), res.channels()), (64, 48, 1));
    assert!(res.data().iter().all(|v| v.is_finite()));
}

#[test]
fn filter_refuses_bad_maps_scales_and_kernels() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let dec = path(d, "d.json");
    let (code, _, err) = ifd(&["decompose", "gauss:sx=6,sy=2", "-o", &dec]);
    assert_eq!(code, 0, "{err}");
    let (w, h) = (80, 60);
    let img = save(d, "img.npy", w, h, vec![0.5; w * h]);
    let small = save(d, "small.npy", 20, 20, vec![0.5; 400]);
    let wrong = save(d, "wrong.npy", w - 1, h, vec![0.0; (w - 1) * h]);
    let mut nan = vec![1.0; w * h];
    nan[123] = f32::NAN;
    let nan_scale = save(d, "nan-scale.npy", w, h, nan);
    let neg = save(d, "neg-scale.npy", w, h, vec![-1.0; w * h]);
    let out = path(d, "out.png");
    let run = |extra: &[&str], needles: &[&str]| {
        let mut args = vec!["filter", &*img, "--decomp", &*dec, "-o", &*out];
        args.extend(extra);
        refused(&args, needles, Some(&out));
    };
    run(&["--angle-map", &wrong], &["angle map", "79x60", "80x60"]);
    run(&["--scale-map", &wrong], &["scale map", "79x60"]);
    run(&["--scale-map", &nan_scale], &["scale"]);
    run(&["--scale-map", &neg], &["scale"]);
    run(&["--scale", "0"], &["scale"]);
    run(&["--scale", "1e9"], &["scale"]);
    run(&["--border", "mirror-ish"], &["--border"]);
    // The 49x49 kernel does not fit a 20x20 image; at scale 3 it outgrows 80x60.
    refused(
        &["filter", &small, "--decomp", &dec, "-o", &out],
        &["larger than the 20x20 image"],
        Some(&out),
    );
    run(&["--scale", "3"], &["larger than the 80x60 image"]);
    let bad_dec = path(d, "bad.json");
    std::fs::write(
        &bad_dec,
        b"{\"format\": \"ifd-decomposition\", \"version\": 99}",
    )
    .unwrap();
    refused(
        &["filter", &img, "--decomp", &bad_dec, "-o", &out],
        &["bad.json"],
        Some(&out),
    );
}

#[test]
fn smooth_writes_a_smoothed_image_and_refuses_bad_options() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (72, 56);
    // A noisy vertical edge: smoothing must keep the edge and reduce the noise.
    let mut seed = 12345u32;
    let mut noise = || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
    };
    let clean = |x: usize| if x < w / 2 { 0.2 } else { 0.8 };
    let data: Vec<f32> = (0..w * h).map(|i| clean(i % w) + 0.2 * noise()).collect();
    let img = save(d, "noisy.npy", w, h, data.clone());
    let out = path(d, "out.npy");
    let (code, _, err) = ifd(&["smooth", &img, "--sigma", "3", "-o", &out]);
    assert_eq!(code, 0, "{err}");
    let res = ifd_image::read(&out).unwrap();
    assert_eq!((res.width(), res.height(), res.channels()), (w, h, 1));
    let rms = |v: &[f32]| {
        let e: f32 = v
            .iter()
            .enumerate()
            .filter(|(i, _)| (i % w).abs_diff(w / 2) > 8 && (i / w) > 8 && (i / w) < h - 8)
            .map(|(i, p)| (p - clean(i % w)).powi(2))
            .sum();
        e.sqrt()
    };
    assert!(
        rms(res.data()) < 0.5 * rms(&data),
        "noise not reduced: {} vs {}",
        rms(res.data()),
        rms(&data)
    );
    // The edge survives: the step across the middle stays large.
    let row = h / 2;
    let step = res.get(w / 2 + 4, row, 0) - res.get(w / 2 - 5, row, 0);
    assert!(step > 0.4, "edge blurred away: step {step}");
    for (extra, needle) in [
        (vec!["--sigma", "0.4"], "--sigma 0.4"),
        (vec!["--sigma", "1000"], "--sigma 1000"),
        (vec!["--sigma", "3", "--strength", "2"], "strength"),
        (vec!["--sigma", "3", "--max-aspect", "100"], "aspect"),
        (vec!["--sigma", "3", "--mode", "sideways"], "mode"),
    ] {
        let mut args = vec!["smooth", &*img, "-o", &*out];
        args.extend(extra);
        let _ = std::fs::remove_file(&out);
        refused(&args, &[needle], Some(&out));
    }
}

/// `ifd filter --kernel SPEC` fits on first use and reads the fit back from
/// the cache the second time; its output is that of `ifd decompose` then
/// `ifd filter --decomp`, bit for bit; `--no-cache` fits again; a damaged
/// entry is refitted with a note; `--tol` without `--kernel`, and both
/// `--kernel` and `--decomp`, are refused.
#[test]
fn filter_with_a_kernel_spec_fits_once_and_caches() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cache = dir.path().join("cache");
    let img = save(
        dir.path(),
        "img.npy",
        48,
        40,
        (0..48 * 40)
            .map(|i| ((i * 7919) % 101) as f32 / 101.0)
            .collect(),
    );
    let spec = "gauss:sx=4,sy=1.5,theta=20";
    let run = |args: &[&str]| {
        common::run(
            common::ifd_command()
                .env("IFD_CACHE_DIR", &cache)
                .args(args),
        )
    };
    let (a, b, c) = (
        path(dir.path(), "a.npy"),
        path(dir.path(), "b.npy"),
        path(dir.path(), "c.npy"),
    );
    let out = run(&[
        "filter", &img, "--kernel", spec, "--angle", "30", "-v", "-o", &a,
    ]);
    assert_eq!(out.0, 0, "{}", out.2);
    assert!(
        out.2.contains("fitted in") && out.2.contains("kept in"),
        "{}",
        out.2
    );
    let out = run(&[
        "filter", &img, "--kernel", spec, "--angle", "30", "-v", "-o", &b,
    ]);
    assert_eq!(out.0, 0, "{}", out.2);
    assert!(out.2.contains("read from the fit cache"), "{}", out.2);
    let d = path(dir.path(), "d.json");
    let (code, _, err) = ifd(&["decompose", spec, "-o", &d]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = ifd(&["filter", &img, "--decomp", &d, "--angle", "30", "-o", &c]);
    assert_eq!(code, 0, "{err}");
    let bytes = |p: &str| std::fs::read(p).expect("output");
    assert_eq!(bytes(&a), bytes(&b), "cached fit, another output");
    assert_eq!(
        bytes(&a),
        bytes(&c),
        "--kernel against decompose + --decomp"
    );
    // --no-cache fits again; a damaged entry is refitted with a note
    let out = run(&[
        "filter",
        &img,
        "--kernel",
        spec,
        "--no-cache",
        "-v",
        "-o",
        &b,
    ]);
    assert!(
        out.0 == 0 && out.2.contains("fitted in") && !out.2.contains("kept in"),
        "{}",
        out.2
    );
    let entries: Vec<_> = std::fs::read_dir(cache.join("decompositions"))
        .expect("cache folder")
        .map(|e| e.expect("entry").path())
        .collect();
    assert_eq!(entries.len(), 1, "{entries:?}");
    let text = std::fs::read_to_string(&entries[0]).expect("entry");
    std::fs::write(
        &entries[0],
        text.replacen("\"weight\": ", "\"weight\": 3", 1),
    )
    .expect("damage");
    let out = run(&[
        "filter", &img, "--kernel", spec, "--angle", "30", "-v", "-o", &b,
    ]);
    assert_eq!(out.0, 0, "{}", out.2);
    assert!(out.2.contains("ignoring the cached fit"), "{}", out.2);
    assert_eq!(bytes(&a), bytes(&b));
    let out = run(&["filter", &img, "--kernel", spec, "-v", "-o", &b]);
    assert!(out.2.contains("read from the fit cache"), "{}", out.2);
    // refusals
    refused(
        &["filter", &img, "--decomp", &d, "--tol", "0.1", "-o", &b],
        &["--kernel"],
        None,
    );
    refused(
        &["filter", &img, "--decomp", &d, "--kernel", spec, "-o", &b],
        &["cannot be used with"],
        None,
    );
    refused(&["filter", &img, "-o", &b], &["--decomp", "--kernel"], None);
    refused(
        &["filter", &img, "--kernel", spec, "--tol", "0", "-o", &b],
        &["--tol 0"],
        None,
    );
    refused(
        &["filter", &img, "--kernel", "gauss:sx=-1", "-o", &b],
        &["gauss:sx=-1"],
        None,
    );
}

#[test]
fn filter_sigma_map_writes_a_gaussian_per_pixel_and_refuses_bad_maps() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (64, 48);
    let img = save(
        d,
        "img.npy",
        w,
        h,
        (0..w * h)
            .map(|i| ((i * 7919) % 101) as f32 / 100.0)
            .collect(),
    );
    // (major, minor, angle) per pixel, with one pixel changed.
    let map = |name: &str, at: (usize, usize), px: [f32; 3]| {
        let mut m: Vec<f32> = (0..w * h).flat_map(|_| [4.0, 2.0, 30.0]).collect();
        let i = (at.1 * w + at.0) * 3;
        m[i..i + 3].copy_from_slice(&px);
        save_channels(d, name, (w, h, 3), m)
    };
    let good = map("good.npy", (10, 20), [6.0, 1.5, -45.0]);
    let out = path(d, "out.npy");
    let (code, _, err) = ifd(&[
        "filter",
        &img,
        "--kernel",
        "gauss",
        "--sigma-map",
        &good,
        "-o",
        &out,
    ]);
    assert_eq!(code, 0, "{err}");
    let res = ifd_image::read(&out).unwrap();
    assert_eq!((res.width(), res.height(), res.channels()), (w, h, 1));
    // Normalised Gaussians: the mean is kept (up to the border).
    let mean = |d: &[f32]| d.iter().map(|v| f64::from(*v)).sum::<f64>() / d.len() as f64;
    let input = ifd_image::read(&img).unwrap();
    assert!((mean(res.data()) - mean(input.data())).abs() < 0.01);

    // `--tol` fits the bank's entries to another error, cached apart from
    // the shared bank; a coarser bank gives another, still normalised, image.
    let cache = tempfile::tempdir().unwrap();
    let coarse = path(d, "coarse.npy");
    let (code, _, err) = common::run(
        common::ifd_command()
            .env("IFD_CACHE_DIR", cache.path())
            .args([
                "filter",
                &img,
                "--kernel",
                "gauss",
                "--sigma-map",
                &good,
                "--tol",
                "0.1",
                "-o",
                &coarse,
            ]),
    );
    assert_eq!(code, 0, "{err}");
    assert!(cache.path().join("aspect-bank-v1-tol0.1.json").is_file());
    assert!(!cache.path().join("aspect-bank-v1.json").exists());
    let coarse = ifd_image::read(&coarse).unwrap();
    assert_ne!(coarse.data(), res.data());
    assert!((mean(coarse.data()) - mean(input.data())).abs() < 0.01);

    let o = path(d, "refused.png");
    let run = |m: &str, needles: &[&str]| {
        refused(
            &[
                "filter",
                &img,
                "--kernel",
                "gauss",
                "--sigma-map",
                m,
                "-o",
                &o,
            ],
            needles,
            Some(&o),
        );
    };
    let narrow = save_channels(d, "narrow.npy", (w - 1, h, 3), vec![2.0; (w - 1) * h * 3]);
    run(&narrow, &["sigma map", "63x48x3", "64x48x3"]);
    let one = save(d, "one.npy", w, h, vec![2.0; w * h]);
    run(&one, &["sigma map", "64x48x1", "64x48x3"]);
    run(
        &map("nan.npy", (5, 2), [4.0, f32::NAN, 0.0]),
        &["(5, 2)", "channel 1 (minor sigma)", "not finite"],
    );
    run(
        &map("inf.npy", (7, 3), [4.0, 2.0, f32::INFINITY]),
        &["(7, 3)", "channel 2 (angle)", "not finite"],
    );
    run(
        &map("zero.npy", (3, 1), [0.0, 0.0, 0.0]),
        &["(3, 1)", "channel 0 (major sigma)", "positive"],
    );
    run(
        &map("neg.npy", (0, 4), [2.0, -1.0, 0.0]),
        &["(0, 4)", "channel 1 (minor sigma)", "positive"],
    );
    run(
        &map("swapped.npy", (9, 9), [1.0, 3.0, 0.0]),
        &["(9, 9)", "channel 1 (minor sigma)", "swap"],
    );
    run(
        &map("aspect.npy", (2, 8), [8.0, 0.4, 0.0]),
        &["(2, 8)", "channel 1", "aspect ratio", "16"],
    );
    run(
        &map("absurd.npy", (4, 0), [20.0, 10.0, 0.0]),
        &["(4, 0)", "channel 0 (major sigma)", "absurd", "16 px"],
    );
    // The 512 px cap, on an image wide enough for a quarter of it to allow more.
    let wide = save(d, "wide.npy", 2100, 1, vec![0.5; 2100]);
    let mut m: Vec<f32> = (0..2100).flat_map(|_| [2.0, 2.0, 0.0]).collect();
    m[3 * 17] = 600.0;
    let wide_map = save_channels(d, "wide-map.npy", (2100, 1, 3), m);
    refused(
        &[
            "filter",
            &wide,
            "--kernel",
            "gauss",
            "--sigma-map",
            &wide_map,
            "-o",
            &o,
        ],
        &["(17, 0)", "channel 0", "absurd", "512"],
        Some(&o),
    );
    // Only `--kernel gauss`, and only the sigma map's options.
    let with = |extra: &[&str], needles: &[&str]| {
        let mut args = vec!["filter", &*img, "-o", &*o];
        args.extend(extra);
        refused(&args, needles, Some(&o));
    };
    with(
        &["--kernel", "box:w=3", "--sigma-map", &good],
        &["box:w=3", "only kernel", "gauss"],
    );
    with(&["--sigma-map", &good], &["--kernel gauss"]);
    with(
        &["--kernel", "gauss", "--sigma-map", &good, "--tol", "0"],
        &["--tol 0"],
    );
    with(&["--kernel", "gauss"], &["--sigma-map"]);
    let dec = path(d, "d.json");
    for extra in [
        ["--decomp", &*dec],
        ["--angle", "10"],
        ["--angle-map", &*one],
        ["--scale", "2"],
        ["--scale-map", &*one],
        // the planner's and the vector rows' switches do not apply to it
        ["--interp", "linear"],
        ["--eval-budget", "0.01"],
        ["--scalar", "-v"],
    ] {
        let mut args = vec!["--kernel", "gauss", "--sigma-map", &*good];
        args.extend(extra);
        with(&args, &["cannot be used with"]);
    }
}

/// `--filter-map`: several filters on one image, each for the pixels its
/// label (or weight) gives it, through one stack: each region equals its
/// filter run alone (within the plans' accuracy), weights blend them, and
/// bad maps and combinations are refused.
#[test]
fn filter_map_filters_each_region_with_its_own_filter() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cache = tempfile::tempdir().unwrap();
    let (w, h) = (96, 64);
    let img = save(
        d,
        "img.npy",
        w,
        h,
        (0..w * h)
            .map(|i| ((i * 7919) % 101) as f32 / 100.0)
            .collect(),
    );
    let angle = save(
        d,
        "angle.npy",
        w,
        h,
        (0..w * h).map(|i| (i % w) as f32 * 3.0).collect(),
    );
    let (a, b) = ("gauss:sx=5,sy=1.5", "gauss:sx=3,sy=3");
    let labels: Vec<f32> = (0..w * h)
        .map(|i| {
            if (i % w) / 8 % 2 == (i / w) / 8 % 2 {
                0.0
            } else {
                1.0
            }
        })
        .collect();
    let lab = save(d, "labels.npy", w, h, labels.clone());
    let run = |extra: &[&str], out: &str| {
        let mut args = vec!["filter", &*img, "--angle-map", &*angle, "-o", out];
        args.extend(extra);
        let (code, _, err) = common::run(
            common::ifd_command()
                .env("IFD_CACHE_DIR", cache.path())
                .args(&args),
        );
        assert_eq!(code, 0, "{args:?}: {err}");
        ifd_image::read(out).unwrap().into_vec()
    };
    let set = run(
        &["--kernel", a, "--kernel", b, "--filter-map", &lab, "-v"],
        &path(d, "set.npy"),
    );
    let alone_a = run(&["--kernel", a], &path(d, "a.npy"));
    let alone_b = run(&["--kernel", b], &path(d, "b.npy"));
    // the two filters differ far more than the plans' errors
    let diff = |x: &[f32], y: &[f32], keep: &dyn Fn(usize) -> bool| {
        x.iter()
            .zip(y)
            .enumerate()
            .filter(|(i, _)| keep(*i))
            .map(|(_, (p, q))| (p - q).abs())
            .fold(0.0f32, f32::max)
    };
    let all = |_: usize| true;
    let apart = diff(&alone_a, &alone_b, &all);
    assert!(apart > 0.02);
    for (label, alone) in [(0.0, &alone_a), (1.0, &alone_b)] {
        let here = |i: usize| labels[i] == label;
        let e = diff(&set, alone, &here);
        assert!(e < 3e-3, "label {label}: {e}");
    }
    // weights: half of each everywhere
    let halves = save_channels(d, "halves.npy", (w, h, 2), vec![0.5; w * h * 2]);
    let blend = run(
        &["--kernel", a, "--kernel", b, "--filter-map", &halves],
        &path(d, "blend.npy"),
    );
    let mean: Vec<f32> = alone_a
        .iter()
        .zip(&alone_b)
        .map(|(p, q)| 0.5 * (p + q))
        .collect();
    let e = diff(&blend, &mean, &all);
    assert!(e < 3e-3, "blend: {e}");

    let o = path(d, "refused.npy");
    let with = |extra: &[&str], needles: &[&str]| {
        let mut args = vec!["filter", &*img, "-o", &*o];
        args.extend(extra);
        refused(&args, needles, Some(&o));
    };
    with(
        &["--kernel", a, "--kernel", b],
        &["2 filters", "--filter-map"],
    );
    let mut three = labels.clone();
    three[5 * w + 7] = 2.0;
    let three = save(d, "three.npy", w, h, three);
    with(
        &["--kernel", a, "--kernel", b, "--filter-map", &three],
        &["label 2 at pixel (7, 5)", "from 0 to 1"],
    );
    let mut half = labels.clone();
    half[w + 1] = 0.5;
    let half = save(d, "half.npy", w, h, half);
    with(
        &["--kernel", a, "--kernel", b, "--filter-map", &half],
        &["label 0.5 at pixel (1, 1)"],
    );
    let narrow = save(d, "narrow.npy", w - 1, h, vec![0.0; (w - 1) * h]);
    with(
        &["--kernel", a, "--kernel", b, "--filter-map", &narrow],
        &["filter map", "95x64", "96x64"],
    );
    let rgb = save_channels(d, "rgb.npy", (w, h, 3), vec![0.0; w * h * 3]);
    with(
        &["--kernel", a, "--kernel", b, "--filter-map", &rgb],
        &["3 channels", "one weight per filter (2)"],
    );
    let mut bad_w = vec![0.5; w * h * 2];
    bad_w[2 * (3 * w + 4) + 1] = f32::INFINITY;
    let bad_w = save_channels(d, "bad_w.npy", (w, h, 2), bad_w);
    with(
        &["--kernel", a, "--kernel", b, "--filter-map", &bad_w],
        &["bad_w.npy", "non-finite", "x=4, y=3, channel 1"],
    );
    with(
        &["--kernel", a, "--kernel", b, "--filter-map", &lab, "--gpu"],
        &["--gpu"],
    );
    with(
        &[
            "--kernel",
            a,
            "--kernel",
            "gauss:sx=400",
            "--filter-map",
            &lab,
        ],
        &["filter 1 (gauss:sx=400)", "larger than the 96x64 image"],
    );
}
