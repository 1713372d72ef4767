//! The brush's hot paths (issue 4, "The brush app"):
//!
//! `cargo bench -p ifd-brush --bench brush`
//!
//! - one dab of radius 64 px applied and shown: `Engine::stroke_to` (dab
//!   through `ifd-smooth`, undo tiles) plus the display update of the dirty
//!   region (sRGB tile patch and `TextureHandle::set_partial` on a headless
//!   egui context; the GPU upload of the 129x129 patch is not included), in
//!   the paper's dab mode and per pixel, on the bundled 512x512 photo;
//! - the same per pixel through `ifd-gpu` (on this machine's adapter:
//!   lavapipe, a software Vulkan, so this measures the path, not a GPU),
//!   with each dab read back and shown as on the CPU path;
//! - the GPU display path (the document on a device shared with the
//!   renderer, `Engine::enable_gpu_on`): the dab painted and converted into
//!   the display texture on the device, no readback, timed until the
//!   device is idle, in both modes;
//! - the stack and orientation-field refresh after a stroke (region of one
//!   r64 dab), against a full rebuild of the smoother; on the GPU, the rows
//!   written by `GpuSmoother::refresh` against uploading the whole smoother
//!   again.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use egui::TextureOptions;
use ifd_brush::app::bundled_image;
use ifd_brush::display;
use ifd_brush::engine::{Banks, Engine, SharedDevice};
use ifd_brush::{BrushMode, BrushSettings};
use ifd_gpu::DeviceChoice;
use ifd_image::MemoryBudget;
use ifd_planar::PixelRect;
use ifd_smooth::Smoother;

/// Where a dab is evaluated and how it reaches the screen.
#[derive(Clone, Copy)]
enum Path {
    /// `ifd-smooth` on the CPU, CPU display patch.
    Cpu,
    /// `ifd-gpu`, read back, CPU display patch.
    GpuReadback,
    /// `ifd-gpu` on the renderer's device, shown from there.
    GpuDisplay,
}

fn bench(c: &mut Criterion) {
    let cache = std::env::temp_dir().join("ifd-brush-bench-bank.json");
    let banks = Banks::load_or_build(Some(&cache), |_, _| {}).expect("banks");
    let mut g = c.benchmark_group("brush");
    g.sample_size(20).measurement_time(Duration::from_secs(4));
    let ctx = egui::Context::default();
    // A device standing in for the renderer's, for the display path.
    let device = ifd_gpu::GpuContext::new()
        .map_err(|e| eprintln!("no GPU adapter: skipping the GPU paths ({e})"))
        .ok();
    for (name, mode, gpu) in [
        (
            "dab r64 apply+show, paper (dab) mode",
            BrushMode::Dab,
            Path::Cpu,
        ),
        (
            "dab r64 apply+show, per-pixel mode",
            BrushMode::PerPixel,
            Path::Cpu,
        ),
        (
            "dab r64 apply+show, per-pixel mode, GPU path with readback",
            BrushMode::PerPixel,
            Path::GpuReadback,
        ),
        (
            "dab r64 apply+show, paper (dab) mode, GPU display path",
            BrushMode::Dab,
            Path::GpuDisplay,
        ),
        (
            "dab r64 apply+show, per-pixel mode, GPU display path",
            BrushMode::PerPixel,
            Path::GpuDisplay,
        ),
    ] {
        let mut engine = Engine::new(banks.clone(), MemoryBudget::default_for_machine());
        let shared = device.as_ref().map(|c| SharedDevice {
            device: c.device().clone(),
            queue: c.queue().clone(),
            info: c.adapter_info().clone(),
        });
        let name = match (gpu, &shared) {
            (Path::Cpu, _) => name.to_string(),
            (_, None) => continue,
            (Path::GpuReadback, _) => {
                let (label, _) = engine.enable_gpu(DeviceChoice::Gpu);
                format!("{name} ({label})")
            }
            (Path::GpuDisplay, Some(d)) => {
                let (label, _) = engine.enable_gpu_on(DeviceChoice::Gpu, Some(d.clone()));
                format!("{name} ({label})")
            }
        };
        let path = bundled_image();
        let brush = BrushSettings {
            radius: 64.0,
            spacing: 1.0,
            mode,
            scale: 6.0,
            ..BrushSettings::default()
        };
        let loaded = engine.read(&path, &brush).expect("read");
        let img = loaded.image;
        let rects = display::tile_rects(img.width(), img.height());
        let mut tex: Vec<_> = rects
            .iter()
            .map(|&r| {
                ctx.load_texture(
                    "t",
                    display::color_image(&img, r, false),
                    TextureOptions::default(),
                )
            })
            .collect();
        engine.set_image(img, None, false);
        engine.begin_stroke(brush).expect("stroke");
        // Alternate between two centres 64 px apart: one dab per call.
        let mut k = 0u32;
        g.bench_function(&name, |b| {
            b.iter(|| {
                k += 1;
                let x = if k.is_multiple_of(2) { 224.0 } else { 288.0 };
                let batch = engine.stroke_to(black_box(x), 256.0).expect("dab");
                let rect = batch.rect.expect("inside");
                if engine.displays_on_device() {
                    // Shown once the device has done the submitted work.
                    if let Some(d) = &shared {
                        d.device
                            .poll(eframe::wgpu::PollType::wait_indefinitely())
                            .expect("poll");
                    }
                } else {
                    let image = engine.image().expect("image");
                    for p in display::tile_patches(image, rect, false) {
                        tex[p.tile].set_partial(p.pos, p.image, TextureOptions::default());
                    }
                }
                batch.times.len()
            });
        });
        engine.end_stroke().expect("end");
    }

    let img = ifd_image::read(bundled_image()).expect("read");
    let opts = BrushSettings::default().smooth_options();
    let mut sm =
        Smoother::with_banks(&img, &opts, banks.aspect.clone(), &banks.hessian).expect("smoother");
    let rect = PixelRect {
        x0: 192,
        y0: 192,
        width: 129,
        height: 129,
    };
    let r = sm
        .refresh_region(&img, rect, &banks.hessian)
        .expect("refresh");
    eprintln!(
        "refresh of a 129x129 rectangle: {} of {} stack samples, {} field pixels",
        r.stack.samples, r.stack.total_samples, r.field_pixels
    );
    g.bench_function("refresh after a r64 dab (stack + field)", |b| {
        b.iter(|| {
            sm.refresh_region(black_box(&img), rect, &banks.hessian)
                .expect("refresh")
        });
    });
    let mut stack = sm.stack().clone();
    g.bench_function("refresh after a r64 dab (stack only)", |b| {
        b.iter(|| {
            stack
                .refresh_region(black_box(&img), rect)
                .expect("refresh")
        });
    });
    g.bench_function("full smoother rebuild 512x512 (for comparison)", |b| {
        b.iter(|| {
            Smoother::with_banks(black_box(&img), &opts, banks.aspect.clone(), &banks.hessian)
                .expect("smoother")
        });
    });
    if let Some(ctx) = &device {
        let wait = || {
            ctx.device()
                .poll(eframe::wgpu::PollType::wait_indefinitely())
                .expect("poll");
        };
        let mut gs = ifd_gpu::GpuSmoother::new(ctx, &sm).expect("upload");
        let bytes = gs.refresh(ctx, &sm, rect, &r).expect("gpu refresh");
        eprintln!(
            "GPU refresh of a 129x129 rectangle: {bytes} bytes written; the stack alone is {}",
            gs.stack().bytes()
        );
        g.bench_function("GPU refresh after a r64 dab (rows written)", |b| {
            b.iter(|| {
                gs.refresh(ctx, &sm, rect, &r).expect("gpu refresh");
                wait();
            });
        });
        g.bench_function("GPU smoother uploaded again (for comparison)", |b| {
            b.iter(|| {
                let fresh = ifd_gpu::GpuSmoother::new(ctx, black_box(&sm)).expect("upload");
                wait();
                fresh
            });
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
