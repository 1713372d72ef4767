//! GPU against CPU on the bundled images, shader validation, limits and bad
//! input.
//!
//! The device tests need a Vulkan adapter; on a machine without a GPU that
//! is Mesa's lavapipe (Debian `mesa-vulkan-drivers`). Without any adapter
//! they fail, unless `IFD_GPU_TESTS=skip` is set.
//!
//! Tolerance: `max |gpu - cpu| <= 1e-4 * max |cpu|` (see the crate docs,
//! "Tolerance"; set for lavapipe, where the measured worst case is printed
//! with `--nocapture`).

use std::path::PathBuf;
use std::sync::OnceLock;

use ifd_gpu::{
    GpuCanvas, GpuContext, GpuDecomposition, GpuError, GpuHessian, GpuPose, GpuSmoother, GpuStack,
    Region, filter_stack,
};
use ifd_image::Image;
use ifd_planar::{
    Border, Decomposition, Field, Filter, FilterError, ScaleStack, StackOptions, Term,
    stack_for_decomposition,
};

const TOL: f32 = 1e-4;

#[path = "../../../tests/support/skip.rs"]
mod skip;

/// The shared device, or `None` (the calling test recorded as skipped) when
/// there is no adapter and `IFD_GPU_TESTS=skip` allows that.
fn ctx() -> Option<&'static GpuContext> {
    static CTX: OnceLock<Option<GpuContext>> = OnceLock::new();
    let ctx = CTX
        .get_or_init(|| match GpuContext::new() {
            Ok(c) => {
                eprintln!("{}", c.describe());
                Some(c)
            }
            Err(e) => {
                assert!(
                    skip::allowed("IFD_GPU_TESTS"),
                    "no GPU device for the GPU tests ({e}); install mesa-vulkan-drivers or set \
                 IFD_GPU_TESTS=skip"
                );
                eprintln!("no GPU adapter: {e}");
                None
            }
        })
        .as_ref();
    if ctx.is_none() {
        skip::skip("no GPU adapter (IFD_GPU_TESTS=skip)");
    }
    ctx
}

fn testdata(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(name)
}

fn read(name: &str) -> Image {
    ifd_image::read(testdata(name)).expect("bundled image")
}

/// Deterministic pseudo-random numbers in [0, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n` terms with displacements up to `reach` px and sigmas in [0.8, 6] px,
/// signed weights summing to about 1.
fn decomposition(n: usize, reach: f64, seed: u64) -> Decomposition {
    let mut r = Rng(seed | 1);
    let terms = (0..n)
        .map(|_| Term {
            weight: (r.next() - 0.3) * 2.0 / n as f64,
            x: (r.next() * 2.0 - 1.0) * reach,
            y: (r.next() * 2.0 - 1.0) * reach,
            sigma: 0.8 + 5.2 * r.next(),
        })
        .collect();
    Decomposition::from_terms(terms)
}

/// `max |a - b| / max |b|`, asserted below `TOL`.
fn assert_close(gpu: &Image, cpu: &Image, what: &str) {
    assert_eq!(
        (gpu.width(), gpu.height(), gpu.channels()),
        (cpu.width(), cpu.height(), cpu.channels()),
        "{what}: shapes differ"
    );
    let scale = cpu.data().iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let (mut worst, mut at) = (0.0f32, 0);
    for (i, (a, b)) in gpu.data().iter().zip(cpu.data()).enumerate() {
        let d = (a - b).abs();
        if d > worst || d.is_nan() {
            worst = d;
            at = i;
        }
    }
    let rel = worst / scale.max(f32::MIN_POSITIVE);
    eprintln!("{what}: max |gpu - cpu| = {worst:.3e} ({rel:.2e} of max |cpu| = {scale:.3})");
    let c = cpu.channels();
    let px = at / c;
    assert!(
        rel <= TOL,
        "{what}: GPU and CPU differ by {rel:.3e} (relative) at x={}, y={}, channel {}: gpu {} cpu {}",
        px % cpu.width(),
        px / cpu.width(),
        at % c,
        gpu.data()[at],
        cpu.data()[at]
    );
}

fn crop(img: &Image, r: Region) -> Image {
    let c = img.channels();
    let mut data = Vec::with_capacity(r.width * r.height * c);
    for y in r.y0..r.y0 + r.height {
        let row = &img.data()[(y * img.width() + r.x0) * c..(y * img.width() + r.x0 + r.width) * c];
        data.extend_from_slice(row);
    }
    Image::from_vec(r.width, r.height, c, data).expect("crop")
}

fn validate(src: &str, path: &std::path::Path) {
    let module = naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("{}: {}", path.display(), e.emit_to_string(src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}: {}", path.display(), e.emit_to_string(src)));
}

#[test]
fn every_shader_parses_and_validates() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shaders");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).expect("shaders/ exists") {
        let path = entry.expect("dir entry").path();
        if path.extension().is_none_or(|e| e != "wgsl") {
            continue;
        }
        let mut src = std::fs::read_to_string(&path).expect("readable shader");
        if path.file_name().is_some_and(|n| n == "ifd_eval.wgsl") {
            // It uses the host's codes, prepended when compiled.
            assert!(ifd_gpu::shaders::ifd_eval_source().ends_with(&src));
            src = ifd_gpu::shaders::ifd_eval_source();
        }
        if path.file_name().is_some_and(|n| n == "isd_shade.wgsl") {
            // It is compiled per degree, with the band count and codes prepended;
            // the extremes of the range are checked here, L = 7 below.
            assert!(ifd_gpu::shaders::isd_shade_source(7).ends_with(&src));
            for l in [0, 100] {
                validate(&ifd_gpu::shaders::isd_shade_source(l), &path);
            }
            src = ifd_gpu::shaders::isd_shade_source(7);
        }
        validate(&src, &path);
        n += 1;
    }
    assert!(n >= 2, "found only {n} shaders in {}", dir.display());
    // The compiled-in sources are the files.
    assert!(ifd_gpu::shaders::IFD_EVAL.contains("fn bilinear"));
}

#[test]
fn constant_filter_matches_cpu_every_border() {
    let Some(ctx) = ctx() else { return };
    let img = read("camera.png");
    // Reach 40 px at scale 1.5: lookups far outside the image at every edge.
    let d = decomposition(48, 40.0, 7);
    for border in [
        Border::Reflect101,
        Border::Replicate,
        Border::Wrap,
        Border::Constant(0.3),
    ] {
        let stack = stack_for_decomposition(&img, &d, 1.5, 1.5, border, StackOptions::default())
            .expect("stack");
        let cpu = Filter::new(&stack, &d)
            .expect("filter")
            .apply(Field::Constant(30.0), Field::Constant(1.5))
            .expect("cpu");
        let gpu = filter_stack(ctx, &stack, &d, Field::Constant(30.0), Field::Constant(1.5))
            .expect("gpu");
        assert_close(
            &gpu,
            &cpu,
            &format!("camera, 48 terms, 30 deg, s=1.5, {border}"),
        );
    }
}

/// Cubic B-spline levels: the shader's 4x4 lookup (fast path and every
/// border's slow path) agrees with the CPU, for a constant pose and per
/// pixel angles and scales.
#[test]
fn cubic_levels_match_cpu() {
    let Some(ctx) = ctx() else { return };
    let img = read("camera.png");
    let (w, h) = (img.width(), img.height());
    let d = decomposition(32, 30.0, 5);
    let options = StackOptions {
        interpolation: ifd_planar::Interpolation::Cubic,
        ..StackOptions::default()
    };
    let angles: Vec<f32> = (0..w * h)
        .map(|i| ((i % w) as f32 * 0.7 - (i / w) as f32 * 0.3) % 360.0)
        .collect();
    for border in [Border::Reflect101, Border::Constant(0.3)] {
        let stack = stack_for_decomposition(&img, &d, 1.3, 1.3, border, options).expect("stack");
        for angle in [Field::Constant(30.0), Field::Map(&angles)] {
            let cpu = Filter::new(&stack, &d)
                .expect("filter")
                .apply(angle, Field::Constant(1.3))
                .expect("cpu");
            let gpu = filter_stack(ctx, &stack, &d, angle, Field::Constant(1.3)).expect("gpu");
            assert_close(&gpu, &cpu, &format!("camera, cubic levels, {border}"));
        }
    }
}

/// A stack at exactly the sigmas a constant scale reads (what `ifd filter
/// --gpu` now builds at a constant scale): the host locates every term's
/// level, one lookup each, and the result agrees with the CPU path for a
/// constant angle and an angle map, both interpolations; a scale map on such
/// a stack is a clear error, not levels read at the wrong sigmas.
#[test]
fn stacks_at_the_terms_sigmas_match_cpu() {
    let Some(ctx) = ctx() else { return };
    let img = read("camera.png");
    let (w, h) = (img.width(), img.height());
    let d = decomposition(40, 30.0, 9);
    let angles: Vec<f32> = (0..w * h)
        .map(|i| ((i % w) as f32 * 0.6 - (i / w) as f32 * 0.35) % 360.0)
        .collect();
    let scale = 1.4;
    let sigmas = ifd_planar::level_sigmas(&d, scale, 0.0);
    assert!(sigmas.len() > 3, "{sigmas:?}");
    for interpolation in [
        ifd_planar::Interpolation::Linear,
        ifd_planar::Interpolation::Cubic,
    ] {
        let options = StackOptions {
            interpolation,
            margin: 48,
            ..StackOptions::default()
        };
        let stack =
            ScaleStack::with_sigmas(&img, &sigmas, Border::Reflect101, options).expect("stack");
        assert!(!stack.is_uniform());
        let filter = Filter::new(&stack, &d).expect("filter");
        for angle in [Field::Constant(-20.0), Field::Map(&angles)] {
            let cpu = filter.apply(angle, Field::Constant(scale)).expect("cpu");
            let gpu = filter_stack(ctx, &stack, &d, angle, Field::Constant(scale)).expect("gpu");
            assert_close(
                &gpu,
                &cpu,
                &format!("camera, levels at the terms' sigmas, {interpolation:?}"),
            );
        }
        let scales = vec![scale; w * h];
        let err = filter_stack(ctx, &stack, &d, Field::Constant(0.0), Field::Map(&scales))
            .expect_err("a scale map on levels at given sigmas");
        assert!(err.to_string().contains("log-uniformly spaced"), "{err}");
        // A scale-map pose made for a log-uniform stack of the same size is
        // refused on this one too, not read with the wrong level formula.
        let uniform = stack_for_decomposition(&img, &d, scale, scale, Border::Reflect101, options)
            .expect("stack");
        let gu = ifd_gpu::GpuStack::upload(ctx, &uniform).expect("upload");
        let ge = ifd_gpu::GpuStack::upload(ctx, &stack).expect("upload");
        let gd = ifd_gpu::GpuDecomposition::new(ctx, &d).expect("terms");
        let pose = ifd_gpu::GpuPose::new(
            ctx,
            &gu,
            Field::Constant(0.0),
            Field::Map(&scales),
            Field::Constant(0.0),
        )
        .expect("pose");
        let err = ctx
            .evaluate(&ge, &gd, &pose, None)
            .expect_err("a scale-map pose on levels at given sigmas");
        assert!(err.to_string().contains("log-uniformly spaced"), "{err}");
    }
}

#[test]
fn rgb_constant_filter_matches_cpu() {
    let Some(ctx) = ctx() else { return };
    let img = read("coffee.png");
    let d = decomposition(64, 24.0, 11);
    let stack = stack_for_decomposition(
        &img,
        &d,
        2.0,
        2.0,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let cpu = Filter::new(&stack, &d)
        .expect("filter")
        .apply(Field::Constant(-75.0), Field::Constant(2.0))
        .expect("cpu");
    let gpu = filter_stack(
        ctx,
        &stack,
        &d,
        Field::Constant(-75.0),
        Field::Constant(2.0),
    )
    .expect("gpu");
    assert_close(&gpu, &cpu, "coffee RGB, 64 terms, -75 deg, s=2");
}

/// Per-pixel angles (a tilted ramp, degrees) and scales (0.5 to 3 along the
/// diagonal) for a `w x h` image.
fn varying_fields(w: usize, h: usize) -> (Vec<f32>, Vec<f32>) {
    let angles = (0..w * h)
        .map(|i| ((i % w) as f32 * 0.9 - (i / w) as f32 * 0.4) % 360.0)
        .collect();
    let scales = (0..w * h)
        .map(|i| 0.5 + 2.5 * ((i % w) + (i / w)) as f32 / (w + h) as f32)
        .collect();
    (angles, scales)
}

#[test]
fn spatially_varying_filter_matches_cpu() {
    let Some(ctx) = ctx() else { return };
    let img = read("astronaut.png");
    let (w, h) = (img.width(), img.height());
    let d = decomposition(32, 16.0, 3);
    let (angles, scales) = varying_fields(w, h);
    for border in [Border::Reflect101, Border::Constant(0.0)] {
        let stack = stack_for_decomposition(&img, &d, 0.5, 3.0, border, StackOptions::default())
            .expect("stack");
        let filter = Filter::new(&stack, &d).expect("filter");
        for (angle, scale, what) in [
            (
                Field::Map(&angles),
                Field::Map(&scales),
                "angle and scale maps",
            ),
            (Field::Map(&angles), Field::Constant(1.25), "angle map"),
            (Field::Constant(10.0), Field::Map(&scales), "scale map"),
        ] {
            let cpu = filter.apply(angle, scale).expect("cpu");
            let gpu = filter_stack(ctx, &stack, &d, angle, scale).expect("gpu");
            assert_close(&gpu, &cpu, &format!("astronaut RGB, {what}, {border}"));
        }
    }
}

/// A log-uniform stack read at the nearest level
/// (`StackOptions::nearest_level`, what `EvalPlan` chooses for loose
/// budgets with a scale map): the shader reads each term's nearest level
/// alone as the CPU does. Where a term's level position lies within f32
/// rounding of half-way between two levels, the two sides may round apart
/// and read neighbouring levels: a few such pixels (at most 1 in 10^4) may
/// differ by up to the difference between the levels, every other pixel
/// agrees to `TOL`.
#[test]
fn nearest_level_reads_match_cpu() {
    let Some(ctx) = ctx() else { return };
    let img = read("astronaut.png");
    let (w, h) = (img.width(), img.height());
    let d = decomposition(32, 16.0, 3);
    let (angles, scales) = varying_fields(w, h);
    let options = StackOptions {
        samples_per_octave: 3,
        nearest_level: true,
        ..StackOptions::default()
    };
    let stack =
        stack_for_decomposition(&img, &d, 0.5, 3.0, Border::Reflect101, options).expect("stack");
    assert!(stack.reads_nearest_level());
    let filter = Filter::new(&stack, &d).expect("filter");
    let (angle, scale) = (Field::Map(&angles), Field::Map(&scales));
    let cpu = filter.apply(angle, scale).expect("cpu");
    let gpu = filter_stack(ctx, &stack, &d, angle, scale).expect("gpu");
    let peak = cpu.data().iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let apart = gpu
        .data()
        .iter()
        .zip(cpu.data())
        .filter(|(a, b)| (*a - *b).abs() > TOL * peak)
        .count();
    eprintln!(
        "nearest level: {apart} of {} values apart",
        cpu.data().len()
    );
    assert!(apart * 10_000 <= cpu.data().len(), "{apart} values apart");
    // The blend of the same levels differs from the nearest reads by far
    // more than `TOL`: the test sees which rule the shader took.
    let blend = StackOptions {
        nearest_level: false,
        ..options
    };
    let blended =
        stack_for_decomposition(&img, &d, 0.5, 3.0, Border::Reflect101, blend).expect("stack");
    let other = filter_stack(ctx, &blended, &d, angle, scale).expect("gpu");
    let differ = other
        .data()
        .iter()
        .zip(cpu.data())
        .filter(|(a, b)| (*a - *b).abs() > TOL * peak)
        .count();
    assert!(differ * 10 > cpu.data().len(), "{differ} values differ");
}

#[test]
fn region_is_the_crop_of_the_full_result() {
    let Some(ctx) = ctx() else { return };
    let img = read("brick.png");
    let d = decomposition(24, 12.0, 5);
    let stack = stack_for_decomposition(&img, &d, 1.0, 1.0, Border::Wrap, StackOptions::default())
        .expect("stack");
    let cpu = Filter::new(&stack, &d)
        .expect("filter")
        .apply(Field::Constant(45.0), Field::Constant(1.0))
        .expect("cpu");
    let gs = GpuStack::upload(ctx, &stack).expect("upload");
    let gd = GpuDecomposition::new(ctx, &d).expect("terms");
    let pose = GpuPose::constant(ctx, &gs, 45.0, 1.0).expect("pose");
    for r in [
        Region {
            x0: 0,
            y0: 0,
            width: 37,
            height: 21,
        },
        Region {
            x0: 480,
            y0: 500,
            width: 32,
            height: 12,
        },
        Region {
            x0: 200,
            y0: 100,
            width: 1,
            height: 1,
        },
    ] {
        let out = ctx.evaluate(&gs, &gd, &pose, Some(r)).expect("region");
        assert_eq!(out.region(), r);
        let gpu = out.read(ctx).expect("read");
        assert_close(&gpu, &crop(&cpu, r), &format!("brick region {r:?}"));
    }
}

#[test]
fn many_channels_split_into_groups() {
    let Some(ctx) = ctx() else { return };
    // 6 channels: two groups of channels (4 + 2), one dispatch each.
    let src = read("coffee.png");
    let (w, h) = (160, 96);
    let mut data = Vec::with_capacity(w * h * 6);
    for y in 0..h {
        for x in 0..w {
            let p = &src.data()[(y * src.width() + x) * 3..(y * src.width() + x) * 3 + 3];
            data.extend_from_slice(&[p[0], p[1], p[2], 1.0 - p[0], p[1] * p[2], 0.5]);
        }
    }
    let img = Image::from_vec(w, h, 6, data).expect("image");
    let d = decomposition(16, 10.0, 9);
    let stack = stack_for_decomposition(
        &img,
        &d,
        1.0,
        1.0,
        Border::Replicate,
        StackOptions::default(),
    )
    .expect("stack");
    let gs = GpuStack::upload(ctx, &stack).expect("upload");
    assert_eq!(gs.buffers(), 2);
    let cpu = Filter::new(&stack, &d)
        .expect("filter")
        .apply(Field::Constant(120.0), Field::Constant(1.0))
        .expect("cpu");
    let gpu = filter_stack(
        ctx,
        &stack,
        &d,
        Field::Constant(120.0),
        Field::Constant(1.0),
    )
    .expect("gpu");
    assert_close(&gpu, &cpu, "6 channels");
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let Some(ctx) = ctx() else { return };
    let img = read("camera.png");
    let d = decomposition(8, 4.0, 1);
    let stack = stack_for_decomposition(
        &img,
        &d,
        1.0,
        2.0,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let gs = GpuStack::upload(ctx, &stack).expect("upload");
    let gd = GpuDecomposition::new(ctx, &d).expect("terms");
    let short = vec![0.0f32; 10];
    let err = GpuPose::new(
        ctx,
        &gs,
        Field::Map(&short),
        Field::Constant(1.0),
        Field::Constant(0.0),
    );
    assert!(matches!(
        err,
        Err(GpuError::Filter(FilterError::MapSize { .. }))
    ));
    let err = GpuPose::constant(ctx, &gs, f32::NAN, 1.0);
    assert!(matches!(
        err,
        Err(GpuError::Filter(FilterError::InvalidValue { .. }))
    ));
    let err = GpuPose::constant(ctx, &gs, 0.0, -1.0);
    assert!(matches!(
        err,
        Err(GpuError::Filter(FilterError::InvalidValue { .. }))
    ));
    // Scale 8 needs sigmas the stack does not have: the CPU's error.
    let pose = GpuPose::constant(ctx, &gs, 0.0, 8.0).expect("pose");
    let err = ctx.evaluate(&gs, &gd, &pose, None);
    assert!(
        matches!(
            err,
            Err(GpuError::Filter(FilterError::ScaleOutOfRange { .. }))
        ),
        "{err:?}"
    );
    let pose = GpuPose::constant(ctx, &gs, 0.0, 1.0).expect("pose");
    for r in [
        Region {
            x0: 500,
            y0: 0,
            width: 20,
            height: 4,
        },
        Region {
            x0: 0,
            y0: 0,
            width: 0,
            height: 4,
        },
    ] {
        let err = ctx.evaluate(&gs, &gd, &pose, Some(r));
        assert!(matches!(
            err,
            Err(GpuError::Filter(FilterError::InvalidParameter(_)))
        ));
    }
    let err = GpuDecomposition::new(ctx, &Decomposition::from_terms(vec![]));
    assert!(matches!(
        err,
        Err(GpuError::Filter(FilterError::InvalidParameter(_)))
    ));
    let bad = Decomposition::from_terms(vec![Term {
        weight: 1.0,
        x: 0.0,
        y: f64::NAN,
        sigma: 1.0,
    }]);
    assert!(matches!(
        GpuDecomposition::new(ctx, &bad),
        Err(GpuError::Filter(FilterError::InvalidTerm { .. }))
    ));
    // A pose made for another stack.
    let small = Image::new(16, 16, 1).expect("image");
    let s2 = stack_for_decomposition(
        &small,
        &d,
        1.0,
        1.0,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let gs2 = GpuStack::upload(ctx, &s2).expect("upload");
    let p2 = GpuPose::constant(ctx, &gs2, 0.0, 1.0).expect("pose");
    assert!(ctx.evaluate(&gs, &gd, &p2, None).is_err());
}

/// A device with deliberately small limits: stacks split into one buffer per
/// channel, and what cannot fit is refused naming the limit.
/// A device on `big`'s adapter with 4 MiB storage bindings and 8 MiB
/// buffers.
fn small_device(big: &GpuContext) -> GpuContext {
    pollster::block_on(async {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
        let adapters = instance.enumerate_adapters(wgpu::Backends::all()).await;
        let adapter = adapters
            .into_iter()
            .find(|a| a.get_info().name == big.adapter_info().name)
            .expect("the same adapter again");
        let info = adapter.get_info();
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: 4 << 20,
            max_buffer_size: 8 << 20,
            ..wgpu::Limits::default()
        };
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("small limits"),
                required_limits: limits,
                ..wgpu::DeviceDescriptor::default()
            })
            .await
            .expect("device with small limits");
        GpuContext::from_device(device, queue, info).expect("pipelines")
    })
}

#[test]
fn small_limits_split_or_fail_clearly() {
    let Some(big) = ctx() else { return };
    let small = small_device(big);
    // 256x256 RGB, sigma 1..2: about 2.7 MiB per channel, so one channel per buffer.
    let img = read("coffee.png");
    let sub = crop(
        &img,
        Region {
            x0: 100,
            y0: 50,
            width: 256,
            height: 256,
        },
    );
    let d = decomposition(12, 6.0, 2);
    let stack = stack_for_decomposition(
        &sub,
        &d,
        1.0,
        1.0,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let gs = GpuStack::upload(&small, &stack).expect("upload split");
    assert_eq!(gs.buffers(), 3, "one channel per buffer");
    let cpu = Filter::new(&stack, &d)
        .expect("filter")
        .apply(Field::Constant(5.0), Field::Constant(1.0))
        .expect("cpu");
    let gpu = filter_stack(
        &small,
        &stack,
        &d,
        Field::Constant(5.0),
        Field::Constant(1.0),
    )
    .expect("gpu");
    assert_close(&gpu, &cpu, "small limits, one channel per buffer");
    // The full-size image: one channel of its stack exceeds the binding limit.
    let stack = ScaleStack::new(&img, 1.0, 2.0, Border::Reflect101, StackOptions::default())
        .expect("stack");
    let err = GpuStack::upload(&small, &stack).expect_err("too large");
    let msg = err.to_string();
    assert!(matches!(err, GpuError::Limit { .. }), "{msg}");
    assert!(msg.contains("max_storage_buffer_binding_size"), "{msg}");
    eprintln!("{msg}");
    // The same verdict from the layout alone, before building anything.
    let layout = |w: usize, h: usize| {
        ifd_planar::StackLayout::new(w, h, 3, 1.0, 2.0, StackOptions::default()).expect("layout")
    };
    let early = GpuStack::check_fits(
        &small,
        (img.width(), img.height()),
        &layout(img.width(), img.height()),
    )
    .expect_err("too large");
    assert_eq!(early.to_string(), msg);
    GpuStack::check_fits(&small, (256, 256), &layout(256, 256)).expect("fits");
}

/// A result larger than a storage binding (4 channels, 600x500: 4.6 MiB
/// against 4 MiB) while each channel's stack fits: evaluated in bands of
/// rows, equal to the CPU; a single evaluation of it is refused. (The
/// 600x400 photo, its last 100 rows repeated mirrored.)
#[test]
fn results_beyond_a_binding_are_evaluated_in_bands() {
    let Some(big) = ctx() else { return };
    let small = small_device(big);
    let img = read("coffee.png");
    let (w, h) = (600, 500);
    let mut data = Vec::with_capacity(w * h * 4);
    for y in 0..h {
        for x in 0..w {
            let yy = if y < 400 { y } else { 799 - y };
            let px = [img.get(x, yy, 0), img.get(x, yy, 1), img.get(x, yy, 2)];
            data.extend_from_slice(&px);
            data.push(px.iter().sum::<f32>() / 3.0);
        }
    }
    let four = Image::from_vec(w, h, 4, data).expect("image");
    let d = Decomposition::from_terms(vec![
        Term {
            weight: 0.6,
            x: 3.0,
            y: -1.5,
            sigma: 1.2,
        },
        Term {
            weight: 0.4,
            x: -2.0,
            y: 4.0,
            sigma: 1.2,
        },
    ]);
    let stack = ScaleStack::new(&four, 1.2, 1.2, Border::Reflect101, StackOptions::default())
        .expect("stack");
    let gs = GpuStack::upload(&small, &stack).expect("upload");
    assert!(
        gs.buffers() >= 2,
        "the stack is split ({} buffers)",
        gs.buffers()
    );
    let gd = GpuDecomposition::new(&small, &d).expect("terms");
    let angle: Vec<f32> = (0..w * h).map(|i| (i % 360) as f32).collect();
    let pose = GpuPose::new(
        &small,
        &gs,
        Field::Map(&angle),
        Field::Constant(1.0),
        Field::Constant(0.0),
    )
    .expect("pose");
    let err = small
        .evaluate(&gs, &gd, &pose, None)
        .expect_err("one buffer for the result is too large");
    assert!(matches!(err, GpuError::Limit { .. }), "{err}");
    let gpu = small.evaluate_image(&gs, &gd, &pose).expect("in bands");
    let cpu = Filter::new(&stack, &d)
        .expect("filter")
        .apply(Field::Map(&angle), Field::Constant(1.0))
        .expect("cpu");
    assert_close(&gpu, &cpu, "600x500x4 in bands of rows");
}

#[test]
fn rgba8_texture_holds_the_result() {
    let Some(ctx) = ctx() else { return };
    let img = read("camera.png");
    let d = decomposition(8, 5.0, 4);
    let stack = stack_for_decomposition(
        &img,
        &d,
        1.0,
        1.0,
        Border::Reflect101,
        StackOptions::default(),
    )
    .expect("stack");
    let gs = GpuStack::upload(ctx, &stack).expect("upload");
    let gd = GpuDecomposition::new(ctx, &d).expect("terms");
    let pose = GpuPose::constant(ctx, &gs, 0.0, 1.0).expect("pose");
    let r = Region {
        x0: 10,
        y0: 20,
        width: 70,
        height: 30,
    };
    let out = ctx.evaluate(&gs, &gd, &pose, Some(r)).expect("eval");
    let values = out.read(ctx).expect("read");
    let tex = out.to_rgba8_texture(ctx, false).expect("texture");
    // Read the texture back (rows padded to 256 bytes).
    let device = ctx.device();
    let row = (r.width as u32 * 4).next_multiple_of(256);
    let buf = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: u64::from(row) * r.height as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    enc.copy_texture_to_buffer(
        tex.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buf,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: None,
            },
        },
        tex.size(),
    );
    ctx.queue().submit([enc.finish()]);
    buf.map_async(wgpu::MapMode::Read, .., |r| r.expect("map"));
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("poll");
    let bytes = buf.get_mapped_range(..).expect("mapped").to_vec();
    let mut checked = 0;
    for y in 0..r.height {
        for x in 0..r.width {
            let v = values.get(x, y, 0).clamp(0.0, 1.0);
            let px = &bytes[y * row as usize + x * 4..y * row as usize + x * 4 + 4];
            let expect = v * 255.0;
            assert!(
                (f32::from(px[0]) - expect).abs() <= 0.51,
                "texel ({x}, {y}): {} for {v}",
                px[0]
            );
            assert_eq!((px[0], px[3]), (px[1], 255));
            checked += 1;
        }
    }
    assert_eq!(checked, r.width * r.height);
}

mod smoothing {
    use std::sync::{Arc, OnceLock};

    use ifd_smooth::HessianFilters;
    use ifd_smooth::{AspectBank, BankOptions, Dab, HessianBank, Mode, SmoothOptions, Smoother};

    use super::*;

    fn banks() -> &'static (Arc<AspectBank>, HessianBank) {
        static BANKS: OnceLock<(Arc<AspectBank>, HessianBank)> = OnceLock::new();
        BANKS.get_or_init(|| {
            let bank = AspectBank::build(
                BankOptions {
                    max_aspect: 4.0,
                    steps_per_octave: 2,
                    ..BankOptions::default()
                },
                |_, _| {},
            )
            .expect("bank");
            (
                Arc::new(bank),
                HessianBank::new(0.01).expect("hessian bank"),
            )
        })
    }

    fn smoother(img: &Image) -> Smoother {
        let (bank, hbank) = banks();
        let opts = SmoothOptions {
            scale: 4.0,
            ..SmoothOptions::default()
        };
        Smoother::with_banks(img, &opts, Arc::clone(bank), hbank).expect("smoother")
    }

    #[test]
    fn per_pixel_smoothing_matches_cpu() {
        let Some(ctx) = ctx() else { return };
        let img = crop(
            &read("camera.png"),
            Region {
                x0: 128,
                y0: 96,
                width: 200,
                height: 160,
            },
        );
        let sm = smoother(&img);
        // The test must exercise the blend between bank entries.
        let blended = sm
            .orientation_field()
            .iter()
            .filter(|o| sm.bank().locate(f64::from(o.aspect)).1 > 0.0)
            .count();
        assert!(blended > 100, "only {blended} pixels blend two entries");
        let cpu = sm.smooth_image(Mode::PerPixel).expect("cpu");
        let gsm = GpuSmoother::new(ctx, &sm).expect("upload");
        let gpu = gsm.smooth_image(ctx, Mode::PerPixel).expect("gpu");
        assert_close(&gpu, &cpu, "camera crop, per-pixel smoothing");
        // The paper's mode over the whole image: a grid of blended dabs.
        let cpu = sm.smooth_image(Mode::Dab).expect("cpu");
        let gpu = gsm.smooth_image(ctx, Mode::Dab).expect("gpu");
        assert_close(&gpu, &cpu, "camera crop, dab-grid smoothing");
        let per_pixel = sm.smooth_image(Mode::PerPixel).expect("cpu");
        assert!(
            cpu.data()
                .iter()
                .zip(per_pixel.data())
                .any(|(a, b)| (a - b).abs() > 1e-3),
            "the two modes must differ for the test to tell them apart"
        );
    }

    /// A 180x140 crop of the RGB photo, its smoother and the upload.
    fn coffee_dab_setup(ctx: &GpuContext) -> (Image, Smoother, GpuSmoother) {
        let img = crop(
            &read("coffee.png"),
            Region {
                x0: 200,
                y0: 100,
                width: 180,
                height: 140,
            },
        );
        let sm = smoother(&img);
        let gsm = GpuSmoother::new(ctx, &sm).expect("upload");
        (img, sm, gsm)
    }

    #[test]
    fn dabs_match_cpu() {
        let Some(ctx) = ctx() else { return };
        let (img, sm, gsm) = coffee_dab_setup(ctx);
        for mode in [Mode::Dab, Mode::PerPixel] {
            let mut cpu = img.clone();
            let mut gpu = img.clone();
            for dab in [
                Dab {
                    x: 60.0,
                    y: 70.0,
                    radius: 25.0,
                    falloff: 0.5,
                    strength: 0.9,
                },
                // Clipped by the image's corner.
                Dab {
                    x: 175.0,
                    y: 2.0,
                    radius: 20.0,
                    falloff: 1.0,
                    strength: 1.0,
                },
            ] {
                let a = sm.apply_dab(&dab, mode, &mut cpu).expect("cpu dab");
                let b = gsm.apply_dab(ctx, &dab, mode, &mut gpu).expect("gpu dab");
                assert_eq!(a, b);
            }
            assert_close(&gpu, &cpu, &format!("coffee crop, two dabs, {mode:?}"));
            assert_ne!(gpu.data(), img.data(), "the dabs changed nothing");
        }
        // A dab that misses, and a bad one.
        let mut t = img.clone();
        let miss = Dab {
            x: -100.0,
            y: -100.0,
            radius: 10.0,
            falloff: 0.5,
            strength: 1.0,
        };
        assert_eq!(
            gsm.apply_dab(ctx, &miss, Mode::Dab, &mut t).expect("miss"),
            None
        );
        let bad = Dab {
            radius: f32::NAN,
            ..miss
        };
        assert!(gsm.apply_dab(ctx, &bad, Mode::Dab, &mut t).is_err());
    }

    /// After an edit, `GpuSmoother::refresh` (rows only) leaves the device
    /// giving exactly (bitwise) the results of a fresh upload of the
    /// refreshed smoother: grey, and RGB (several channels per buffer, and
    /// one channel per buffer on a device with small limits).
    #[test]
    fn refresh_matches_a_fresh_upload() {
        let Some(ctx) = ctx() else { return };
        // Tall, so that the rows a dab near the top changes are a minority.
        let grey = crop(
            &read("camera.png"),
            Region {
                x0: 100,
                y0: 0,
                width: 160,
                height: 512,
            },
        );
        assert_eq!(refresh_case(ctx, &grey), 1);
        let rgb = crop(
            &read("coffee.png"),
            Region {
                x0: 150,
                y0: 0,
                width: 120,
                height: 400,
            },
        );
        assert_eq!(refresh_case(ctx, &rgb), 1, "three channels in one buffer");
        let small = small_device(ctx);
        assert_eq!(refresh_case(&small, &rgb), 3, "one channel per buffer");
    }

    /// Returns the buffers the stack was split into.
    fn refresh_case(ctx: &GpuContext, img: &Image) -> usize {
        let img = img.clone();
        let mut sm = smoother(&img);
        let mut gsm = GpuSmoother::new(ctx, &sm).expect("upload");
        let mut edited = img.clone();
        let dab = Dab {
            x: 80.0,
            y: 40.0,
            radius: 25.0,
            falloff: 0.5,
            strength: 1.0,
        };
        let rect = sm
            .apply_dab(&dab, Mode::PerPixel, &mut edited)
            .expect("dab")
            .expect("inside");
        let stale = gsm.smooth_image(ctx, Mode::PerPixel).expect("stale");
        let (_, hbank) = banks();
        let report = sm
            .refresh_region(&edited, rect, hbank)
            .expect("cpu refresh");
        let written = gsm.refresh(ctx, &sm, rect, &report).expect("gpu refresh");
        let fresh = GpuSmoother::new(ctx, &sm).expect("upload again");
        eprintln!(
            "refresh wrote {written} bytes; the stack is {}",
            fresh.stack().bytes()
        );
        assert!(
            written < fresh.stack().bytes() / 2,
            "the refresh wrote {written} bytes, the whole stack is {}",
            fresh.stack().bytes()
        );
        let a = gsm.smooth_image(ctx, Mode::PerPixel).expect("refreshed");
        let b = fresh.smooth_image(ctx, Mode::PerPixel).expect("fresh");
        assert_ne!(stale.data(), b.data(), "the edit must change the result");
        assert_eq!(
            a.data(),
            b.data(),
            "refreshed upload differs from a fresh one"
        );
        assert_close(
            &a,
            &sm.smooth_image(Mode::PerPixel).expect("cpu"),
            "refreshed smoother",
        );
        // A smoother at another scale is not the one uploaded.
        let (bank, hbank) = banks();
        let other = Smoother::with_banks(
            &edited,
            &SmoothOptions {
                scale: 3.0,
                ..SmoothOptions::default()
            },
            Arc::clone(bank),
            hbank,
        )
        .expect("smoother");
        assert!(matches!(
            gsm.refresh(ctx, &other, rect, &report),
            Err(GpuError::Filter(FilterError::InvalidParameter(_)))
        ));
        gsm.stack().buffers()
    }

    /// The display byte of a sample, as the brush app's CPU display path
    /// (`apps/ifd-brush/src/display.rs`) computes it.
    fn display_byte(v: f32, srgb: bool) -> u8 {
        let v = if srgb {
            ifd_image::linear_to_srgb(v.max(0.0))
        } else {
            v
        };
        (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
    }

    /// Checks every display tile of `canvas` against `expected` (the image
    /// it should show); returns the texels checked.
    fn check_display(ctx: &GpuContext, canvas: &GpuCanvas, expected: &Image, srgb: bool) -> usize {
        let c = expected.channels();
        let mut checked = 0;
        for (i, t) in canvas.tiles().iter().enumerate() {
            let texels = canvas.read_tile(ctx, i).expect("tile");
            let r = t.region;
            assert_eq!(texels.len(), r.width * r.height);
            for y in 0..r.height {
                for x in 0..r.width {
                    let px = texels[y * r.width + x];
                    let rgb = if c >= 3 { [0, 1, 2] } else { [0, 0, 0] };
                    for (k, &ch) in rgb.iter().enumerate() {
                        let want = display_byte(expected.get(r.x0 + x, r.y0 + y, ch), srgb);
                        assert!(
                            px[k].abs_diff(want) <= 1,
                            "tile {i} texel ({x}, {y}) channel {k}: {} for {want}",
                            px[k]
                        );
                    }
                    assert_eq!(px[3], 255, "the display is opaque");
                    checked += 1;
                }
            }
        }
        checked
    }

    /// Dabs painted on a `GpuCanvas` (no readback) give the CPU's pixels,
    /// and its display textures show them as the brush's CPU display does;
    /// small tiles make the dabs cross tile edges.
    #[test]
    fn canvas_dabs_match_cpu_and_show() {
        let Some(ctx) = ctx() else { return };
        let (img, sm, gsm) = coffee_dab_setup(ctx);
        let canvas = GpuCanvas::new(ctx, &img, false, 64).expect("canvas");
        assert_eq!(canvas.tiles().len(), 3 * 3);
        assert_eq!(
            check_display(ctx, &canvas, &img, false),
            180 * 140,
            "the new canvas shows the image"
        );
        let mut cpu = img.clone();
        let dabs = [
            (60.0, 70.0, 25.0, 0.5, 0.9, Mode::Dab),
            (70.0, 60.0, 30.0, 0.3, 1.0, Mode::PerPixel),
            // Clipped by the image's corner.
            (175.0, 2.0, 20.0, 1.0, 1.0, Mode::Dab),
            (120.0, 100.0, 18.0, 0.0, 0.6, Mode::PerPixel),
        ];
        for (x, y, radius, falloff, strength, mode) in dabs {
            let dab = Dab {
                x,
                y,
                radius,
                falloff,
                strength,
            };
            let a = sm.apply_dab(&dab, mode, &mut cpu).expect("cpu dab");
            let b = canvas.apply_dab(ctx, &gsm, &dab, mode).expect("gpu dab");
            assert_eq!(a, b);
        }
        let all = Region::full(180, 140);
        let gpu =
            Image::from_vec(180, 140, 3, canvas.read(ctx, all).expect("read")).expect("image");
        assert_ne!(gpu.data(), img.data(), "the dabs changed nothing");
        assert_close(&gpu, &cpu, "coffee crop, dabs on the canvas");
        check_display(ctx, &canvas, &gpu, false);
        // A sub-region reads as the crop of the whole.
        let r = Region {
            x0: 30,
            y0: 40,
            width: 50,
            height: 20,
        };
        assert_eq!(
            canvas.read(ctx, r).expect("read region"),
            crop(&gpu, r).data().to_vec()
        );
        // A miss changes nothing; bad dabs and regions are errors.
        let miss = Dab {
            x: -100.0,
            y: -100.0,
            radius: 10.0,
            falloff: 0.5,
            strength: 1.0,
        };
        assert_eq!(
            canvas.apply_dab(ctx, &gsm, &miss, Mode::Dab).expect("miss"),
            None
        );
        let bad = Dab {
            strength: f32::NAN,
            ..miss
        };
        assert!(canvas.apply_dab(ctx, &gsm, &bad, Mode::Dab).is_err());
        let outside = Region {
            x0: 170,
            y0: 0,
            width: 20,
            height: 5,
        };
        assert!(canvas.read(ctx, outside).is_err());
        assert!(canvas.write(ctx, outside, &[0.0; 300]).is_err());
        assert!(canvas.write(ctx, r, &[0.0; 7]).is_err());
        assert!(canvas.read_tile(ctx, 9).is_err());
        // Another shape than the smoother's.
        let other = GpuCanvas::new(ctx, &crop(&img, r), false, 64).expect("canvas");
        assert!(matches!(
            other.apply_dab(ctx, &gsm, &miss, Mode::Dab),
            Err(GpuError::Smooth(_))
        ));
    }

    /// Writing into a canvas (the brush's undo) replaces the pixels and the
    /// display; float data is shown sRGB-encoded.
    #[test]
    fn canvas_write_read_and_srgb_display() {
        let Some(ctx) = ctx() else { return };
        let (w, h) = (70, 50);
        let lin: Vec<f32> = (0..w * h).map(|i| (i % 97) as f32 / 80.0 - 0.1).collect();
        let img = Image::from_vec(w, h, 1, lin).expect("image");
        let canvas = GpuCanvas::new(ctx, &img, true, 32).expect("canvas");
        check_display(ctx, &canvas, &img, true);
        let r = Region {
            x0: 20,
            y0: 10,
            width: 30,
            height: 25,
        };
        let patch: Vec<f32> = (0..r.width * r.height)
            .map(|i| (i % 13) as f32 / 12.0)
            .collect();
        canvas.write(ctx, r, &patch).expect("write");
        let mut expected = img.clone();
        for y in 0..r.height {
            for x in 0..r.width {
                expected.set(r.x0 + x, r.y0 + y, 0, patch[y * r.width + x]);
            }
        }
        assert_eq!(
            canvas.read(ctx, Region::full(w, h)).expect("read"),
            expected.data().to_vec()
        );
        check_display(ctx, &canvas, &expected, true);
        let five = Image::from_vec(4, 4, 5, vec![0.0; 80]).expect("image");
        assert!(matches!(
            GpuCanvas::new(ctx, &five, false, 64),
            Err(GpuError::Unsupported(_))
        ));
    }

    #[test]
    fn hessian_matches_cpu() {
        let Some(ctx) = ctx() else { return };
        let img = read("brick.png");
        let (_, hbank) = banks();
        let sigma = 3.0;
        let (lo, hi) = hbank.stack_sigmas(sigma, sigma);
        let stack = ScaleStack::new(
            &img,
            lo,
            hi,
            Border::Reflect101,
            ifd_smooth::hessian_stack_options(),
        )
        .expect("stack");
        let cpu: HessianFilters<'_> = hbank.bind(&stack).expect("bind");
        let cpu = cpu.planes(sigma).expect("cpu");
        let gs = GpuStack::upload(ctx, &stack).expect("upload");
        let gpu = GpuHessian::new(ctx, hbank)
            .expect("terms")
            .planes(ctx, &gs, sigma)
            .expect("gpu");
        for (name, (g, c)) in ["Hxx", "Hxy", "Hyy"].iter().zip(gpu.iter().zip(&cpu)) {
            let (w, h) = (img.width(), img.height());
            let gi = Image::from_vec(w, h, 1, g.clone()).expect("image");
            let ci = Image::from_vec(w, h, 1, c.clone()).expect("image");
            assert_close(&gi, &ci, &format!("brick {name} at sigma {sigma}"));
        }
    }
}

/// Set in the child process of [`no_adapter_is_a_clear_error_not_a_panic`].
const NO_ADAPTER_CHILD: &str = "IFD_GPU_NO_ADAPTER_CHILD";

/// With no Vulkan driver at all, device creation is `GpuError::NoAdapter`
/// with a message saying what to install, not a panic. The Vulkan loader is
/// pointed at a driver manifest that does not exist (`VK_DRIVER_FILES`, and
/// `VK_ICD_FILENAMES` for older loaders) and wgpu to Vulkan only
/// (`WGPU_BACKEND=vulkan`: in a whole-workspace build eframe's features
/// compile wgpu's GL backend in, which would find Mesa's GL llvmpipe), in a
/// child process so the other tests keep their adapter.
#[test]
fn no_adapter_is_a_clear_error_not_a_panic() {
    if std::env::var_os(NO_ADAPTER_CHILD).is_some() {
        let e = GpuContext::new().expect_err("no Vulkan driver, yet an adapter was found");
        assert!(matches!(e, GpuError::NoAdapter(_)), "{e:?}");
        let msg = e.to_string();
        assert!(
            msg.starts_with("no GPU adapter found") && msg.contains("mesa-vulkan-drivers"),
            "{msg}"
        );
        assert!(ifd_gpu::list_adapters().is_empty());
        println!("child saw: {msg}");
        return;
    }
    let missing = "/nonexistent/ifd-no-vulkan-driver.json";
    let out = std::process::Command::new(std::env::current_exe().expect("test binary"))
        .args([
            "--exact",
            "no_adapter_is_a_clear_error_not_a_panic",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(NO_ADAPTER_CHILD, "1")
        .env("VK_DRIVER_FILES", missing)
        .env("VK_ICD_FILENAMES", missing)
        .env_remove("VK_ADD_DRIVER_FILES")
        .env("WGPU_BACKEND", "vulkan")
        .output()
        .expect("run the test binary");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && stdout.contains("child saw: no GPU adapter found"),
        "child failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}

// ---- ISD shading (shaders/isd_shade.wgsl) against the CPU renderer ----

mod shading {
    use glam::DVec3;
    use ifd_gpu::{GpuEnvironment, GpuMaterial, GpuShader, GpuSurfaces, SurfacePoint};
    use ifd_image::Image;
    use ifd_render::Camera;
    use ifd_render::EnvMap;
    use ifd_render::Scene;
    use ifd_render::Tonemap;
    use ifd_render::{Job, Method, render};
    use ifd_render::{RoughnessFamily, SurfaceMaps, Texture};
    use ifd_shade::Brdf;
    use ifd_shade::{BandMaps, Environment, Material};
    use ifd_shade::{LobeKind, LobeTable};

    use super::{ctx, testdata};

    /// GPU (f32) against CPU (f64) shading: `max |gpu - cpu| <= 1e-3 max |cpu|`.
    const SHADE_TOL: f64 = 1e-3;

    /// The forest map averaged down to 64x32 (what the renderer integrates).
    fn forest() -> EnvMap {
        let img = ifd_image::read(testdata("forest.hdr")).expect("forest.hdr");
        let small = ifd_sphere::downsample_equirect(&img, 64, 32).expect("downsample");
        EnvMap::new(small, 30.0).expect("env")
    }

    struct Case<'a> {
        brdf: &'a Brdf,
        material: Option<&'a Material>,
        family: Option<&'a RoughnessFamily>,
        maps: Option<&'a SurfaceMaps>,
        scene: Scene,
        size: usize,
        l_max: usize,
        method: Method,
    }

    /// Renders `case` on the CPU and the GPU and returns the largest
    /// difference relative to the CPU image's maximum.
    fn compare(name: &str, env: &EnvMap, case: &Case<'_>) -> Option<f64> {
        let ctx = ctx()?;
        let camera = Camera::new(
            DVec3::new(3.0, -2.5, 1.2),
            DVec3::ZERO,
            DVec3::Z,
            40.0,
            case.size,
            case.size,
        )
        .expect("camera");
        let job = Job {
            background: Some(env),
            maps: case.maps,
            family: case.family,
            ..Job::new(
                case.scene.clone(),
                camera,
                env,
                case.brdf,
                case.material,
                case.method,
            )
        };
        let cpu = render(&job, &|_, _| {}).expect("cpu render");
        let px = ifd_render::pixels(&case.scene, &camera, case.maps).expect("pixels");
        let gltf = case.brdf.gltf_material();
        let points: Vec<SurfacePoint> = px
            .iter()
            .map(|p| SurfacePoint::from_pixel_with(p, Some(env), gltf.as_ref()))
            .collect();
        let surfaces = GpuSurfaces::upload(ctx, case.size, case.size, &points).expect("upload");
        let e = Environment::new(env.sh(case.l_max).expect("sh")).expect("env");
        let genv = match case.method {
            Method::Isd => GpuEnvironment::sh(ctx, &e).expect("sh upload"),
            Method::IsdMaps => {
                GpuEnvironment::maps(ctx, &BandMaps::new(&e).expect("maps")).expect("maps upload")
            }
            m => panic!("no GPU path for {m:?}"),
        };
        let material = match (case.family, case.material) {
            (Some(f), _) => GpuMaterial::family(ctx, f).expect("family"),
            (None, Some(m)) => GpuMaterial::new(ctx, m).expect("material"),
            _ => panic!("a case needs a material"),
        };
        let shader = GpuShader::new(ctx).expect("shader");
        let shaded = shader
            .shade(ctx, &surfaces, &genv, &material)
            .expect("shade");
        let (gpu, mask) = shaded.read(ctx).expect("read");
        assert_eq!(mask, cpu.mask, "{name}: the object masks differ");
        // the background is copied through exactly; measure the object
        let (diff, max, at) = max_diff(&gpu, &cpu.image, &mask);
        let rel = diff / max;
        eprintln!(
            "{name}: max |gpu - cpu| = {rel:.2e} of the object's maximum {max:.3} (at value {at})"
        );
        assert!(max > 0.0 && rel.is_finite());
        Some(rel)
    }

    /// The largest difference over the object's pixels, the object's
    /// largest value, and where the difference is (flat index).
    fn max_diff(a: &Image, b: &Image, mask: &[bool]) -> (f64, f64, usize) {
        assert_eq!(a.data().len(), b.data().len());
        let ch = a.channels();
        let (mut best, mut max, mut at) = (0.0, 0.0f64, 0);
        for (i, (x, y)) in a.data().iter().zip(b.data()).enumerate() {
            if !mask[i / ch] {
                assert_eq!(x, y, "background value {i}");
                continue;
            }
            max = max.max(f64::from(y.abs()));
            let d = f64::from((x - y).abs());
            if d > best || d.is_nan() {
                (best, at) = (d, i);
            }
        }
        (best, max, at)
    }

    fn table(brdf: &Brdf, l: usize, nt: usize, np: usize, kind: LobeKind) -> Material {
        let t = LobeTable::build_with(brdf, l, nt, np, kind, &|_, _| {}).expect("table");
        Material::new(brdf, l, Some(t)).expect("material")
    }

    /// A `w x h` roughness map and RGB albedo map over the surface's (u, v).
    fn rough_albedo_maps(w: usize, h: usize, rough: Vec<f32>, albedo: Vec<f32>) -> SurfaceMaps {
        let texture = |c, data, what| {
            Texture::new(Image::from_vec(w, h, c, data).expect("img"), what).expect("texture")
        };
        SurfaceMaps {
            roughness: Some(texture(1, rough, "roughness")),
            albedo: Some(texture(3, albedo, "albedo")),
            normal: None,
        }
    }

    fn check(name: &str, env: &EnvMap, case: &Case<'_>) {
        if let Some(rel) = compare(name, env, case) {
            assert!(
                rel <= SHADE_TOL,
                "{name}: GPU and CPU differ by {rel:.2e} of the maximum"
            );
        }
    }

    #[test]
    fn closed_form_materials_match_cpu() {
        let env = forest();
        for (spec, l, method) in [
            ("lambert", 6, Method::Isd),
            ("phong:s=30", 10, Method::Isd),
            ("phong:s=30", 10, Method::IsdMaps),
        ] {
            let brdf = Brdf::parse(spec).expect("brdf");
            let m = Material::new(&brdf, l, None).expect("material");
            let case = Case {
                brdf: &brdf,
                material: Some(&m),
                family: None,
                maps: None,
                scene: Scene::Torus,
                size: 40,
                l_max: l,
                method,
            };
            check(&format!("{spec} L={l} {method:?}"), &env, &case);
        }
    }

    #[test]
    fn lobe_tables_match_cpu_both_variants() {
        let env = forest();
        let iso = Brdf::parse("ggx:alpha=0.3").expect("brdf");
        let aniso = Brdf::parse("ggx:ax=0.2,ay=0.5").expect("brdf");
        let cases = [
            (
                "ggx in-plane",
                &iso,
                table(&iso, 8, 24, 1, LobeKind::InPlane),
                8,
            ),
            (
                "ggx shared",
                &iso,
                table(&iso, 8, 24, 1, LobeKind::Shared),
                8,
            ),
            (
                "ggx anisotropic",
                &aniso,
                table(&aniso, 6, 12, 16, LobeKind::Shared),
                6,
            ),
        ];
        for (name, brdf, m, l) in &cases {
            for method in [Method::Isd, Method::IsdMaps] {
                let case = Case {
                    brdf,
                    material: Some(m),
                    family: None,
                    maps: None,
                    scene: Scene::Sphere,
                    size: 32,
                    l_max: *l,
                    method,
                };
                check(&format!("{name} L={l} {method:?}"), &env, &case);
            }
        }
    }

    #[test]
    fn spatially_varying_brdf_matches_cpu() {
        let env = forest();
        let brdf = Brdf::parse("ggx:alpha=0.3").expect("brdf");
        // roughness stripes and an albedo ramp over the sphere's (u, v)
        let (w, h) = (32, 16);
        let rough: Vec<f32> = (0..w * h)
            .map(|i| {
                0.3 + 0.5
                    * (((i % w) as f32) / w as f32 * std::f32::consts::TAU)
                        .sin()
                        .abs()
            })
            .collect();
        let albedo: Vec<f32> = (0..w * h)
            .flat_map(|i| {
                let v = (i / w) as f32 / h as f32;
                [0.9, 0.3 + 0.6 * v, 0.5]
            })
            .collect();
        let maps = rough_albedo_maps(w, h, rough, albedo);
        let l = 6;
        let range = maps.roughness.as_ref().expect("set").range();
        let family = RoughnessFamily::build(&brdf, l, range, 4, &|_, _| {}).expect("family");
        let case = Case {
            brdf: &brdf,
            material: None,
            family: Some(&family),
            maps: Some(&maps),
            scene: Scene::Sphere,
            size: 32,
            l_max: l,
            method: Method::Isd,
        };
        check("roughness + albedo maps", &env, &case);
    }

    #[test]
    fn the_gltf_brdf_matches_cpu() {
        // the glTF BRDF's three parts against every colour channel, combined
        // with the base colour and metalness in the kernel: one material,
        // then a roughness family with an albedo map (the base colour)
        let env = forest();
        let brdf = Brdf::parse("gltf:roughness=0.6,metallic=0.4,base=0.9:0.6:0.3").expect("brdf");
        let parts = brdf.tabulated().expect("parts");
        let m = table(&parts, 8, 24, 1, LobeKind::InPlane);
        for method in [Method::Isd, Method::IsdMaps] {
            let case = Case {
                brdf: &brdf,
                material: Some(&m),
                family: None,
                maps: None,
                scene: Scene::Sphere,
                size: 32,
                l_max: 8,
                method,
            };
            check(&format!("gltf L=8 {method:?}"), &env, &case);
        }
        let (w, h) = (16, 8);
        let rough: Vec<f32> = (0..w * h)
            .map(|i| 0.5 + 0.4 * (i % w) as f32 / w as f32)
            .collect();
        let albedo: Vec<f32> = (0..w * h)
            .flat_map(|i| [0.3 + 0.6 * (i / w) as f32 / h as f32, 0.8, 0.4])
            .collect();
        let maps = rough_albedo_maps(w, h, rough, albedo);
        let range = maps.roughness.as_ref().expect("set").range();
        let family = RoughnessFamily::build(&parts, 6, range, 3, &|_, _| {}).expect("family");
        let case = Case {
            brdf: &brdf,
            material: None,
            family: Some(&family),
            maps: Some(&maps),
            scene: Scene::Sphere,
            size: 32,
            l_max: 6,
            method: Method::Isd,
        };
        check("gltf roughness + base colour maps", &env, &case);
        // a glTF asset with its own textures: the kernel applies its
        // occlusion and emission (the bundled textured.glb has both)
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata/textured.glb");
        let scene = Scene::parse(path, false).expect("the bundled asset");
        let Scene::Gltf(asset) = &scene else {
            panic!("{path} is not read as a glTF asset")
        };
        let brdf = Brdf::parse("gltf").expect("brdf");
        let parts = brdf.tabulated().expect("parts");
        let family = RoughnessFamily::build(&parts, 6, asset.roughness_range(), 3, &|_, _| {})
            .expect("family");
        let case = Case {
            brdf: &brdf,
            material: None,
            family: Some(&family),
            maps: None,
            scene: scene.clone(),
            size: 48,
            l_max: 6,
            method: Method::Isd,
        };
        check(
            "a glTF asset's materials, occlusion and emission",
            &env,
            &case,
        );
    }

    #[test]
    fn high_degrees_stay_accurate_in_f32() {
        // L = 40: the CPU's reduced Legendre values would overflow f32 here
        let env = forest();
        let brdf = Brdf::parse("phong:s=400").expect("brdf");
        let m = Material::new(&brdf, 40, None).expect("material");
        let case = Case {
            brdf: &brdf,
            material: Some(&m),
            family: None,
            maps: None,
            scene: Scene::Sphere,
            size: 20,
            l_max: 40,
            method: Method::Isd,
        };
        check("phong:s=400 L=40", &env, &case);
    }

    #[test]
    fn bands_of_rows_and_the_display_transform_match() {
        let Some(ctx) = ctx() else { return };
        let env = forest();
        let brdf = Brdf::parse("phong:s=20").expect("brdf");
        let l = 8;
        let m = Material::new(&brdf, l, None).expect("material");
        let camera = Camera::new(
            DVec3::new(3.0, -2.5, 1.2),
            DVec3::ZERO,
            DVec3::Z,
            40.0,
            30,
            22,
        )
        .expect("camera");
        let px = ifd_render::pixels(&Scene::Sphere, &camera, None).expect("pixels");
        let points: Vec<SurfacePoint> = px
            .iter()
            .map(|p| SurfacePoint::from_pixel(p, Some(&env)))
            .collect();
        let surfaces = GpuSurfaces::upload(ctx, 30, 22, &points).expect("upload");
        let e = Environment::new(env.sh(l).expect("sh")).expect("env");
        let genv = GpuEnvironment::sh(ctx, &e).expect("env upload");
        let gm = GpuMaterial::new(ctx, &m).expect("material upload");
        let shader = GpuShader::new(ctx).expect("shader");
        let whole = shader.shade(ctx, &surfaces, &genv, &gm).expect("shade");
        let mut banded = shader.output(ctx, 30, 22).expect("output");
        for r in [0..5, 5..6, 6..22] {
            shader
                .shade_rows(ctx, &surfaces, &genv, &gm, &mut banded, r)
                .expect("band");
        }
        let (a, _) = whole.read(ctx).expect("read");
        let (b, _) = banded.read(ctx).expect("read");
        assert_eq!(a.data(), b.data(), "bands differ from the whole frame");
        assert!(
            shader
                .shade_rows(ctx, &surfaces, &genv, &gm, &mut banded, 20..23)
                .is_err()
        );
        // the display transform, against ifd-render's
        for (tm, ev) in [
            (Tonemap::Aces, 0.0),
            (Tonemap::Reinhard, 1.5),
            (Tonemap::None, -1.0),
        ] {
            let tex = GpuShader::display_texture(ctx, 30, 22);
            shader
                .display(ctx, &whole, tm.into(), ev, &tex)
                .expect("display");
            let texels = GpuShader::read_display(ctx, &tex).expect("read display");
            let mut worst = 0i32;
            for (i, t) in texels.iter().enumerate() {
                for (c, v) in t.iter().take(3).enumerate() {
                    let want = (tm.display(a.data()[i * 3 + c], ev) * 255.0).round() as i32;
                    worst = worst.max((i32::from(*v) - want).abs());
                }
                assert_eq!(t[3], 255);
            }
            assert!(worst <= 1, "{tm:?}: display differs by {worst}/255");
        }
    }

    #[test]
    fn mismatched_degrees_are_refused() {
        let Some(ctx) = ctx() else { return };
        let mut e = ifd_sphere::ShCoeffs::zeros(4, 3).expect("coeffs");
        e.data_mut()[..3].fill(1.0);
        let env = GpuEnvironment::sh(ctx, &Environment::new(e).expect("env")).expect("upload");
        let brdf = Brdf::parse("lambert").expect("brdf");
        let m = GpuMaterial::new(ctx, &Material::new(&brdf, 5, None).expect("m")).expect("upload");
        let points = vec![SurfacePoint::default(); 4];
        let s = GpuSurfaces::upload(ctx, 2, 2, &points).expect("surfaces");
        let err = GpuShader::new(ctx)
            .expect("shader")
            .shade(ctx, &s, &env, &m)
            .expect_err("degrees differ");
        assert!(err.to_string().contains("L = 4"), "{err}");
        assert!(GpuSurfaces::upload(ctx, 3, 2, &points).is_err());
    }
}
