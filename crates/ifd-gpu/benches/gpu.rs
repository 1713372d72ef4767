//! CPU against GPU evaluation, and storage buffer against texture array.
//!
//! `cargo bench -p ifd-gpu --bench gpu`. Groups (the adapter is printed first;
//! on a machine without a GPU it is lavapipe, which runs on the CPU cores):
//! - `eval`: filtering a 256x256 single-channel image with `s` = 16 and 64
//!   terms (small, because lavapipe takes seconds per evaluation; set
//!   `IFD_GPU_BENCH_SIZE=1024 IFD_GPU_BENCH_TERMS=51,256` on a real GPU):
//!   the CPU path (`Filter::apply`, rayon) against the GPU path, both from a
//!   prebuilt stack, for three poses: `constant` (angle and scale constant,
//!   log-uniform levels: two lookups for most terms), `exact` (the same pose
//!   on a stack at exactly the terms' sigmas, what `ifd filter` builds at a
//!   constant scale: one lookup per term) and `maps` (per-pixel angle and
//!   scale). `gpu` is submit + wait (result left on the device), `gpu+read`
//!   adds the readback. Setup also prints the GPU time of the pass from
//!   timestamp queries when the adapter has them.
//! - `fetch`: `shaders/bench_fetch.wgsl`, the same lookups reading a stack of
//!   full-resolution levels from a storage buffer or an r32float texture
//!   array (textureLoad, manual bilinear), 512x512, 8 levels, 128 terms.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ifd_gpu::{GpuContext, GpuDecomposition, GpuPose, GpuStack};
use ifd_image::Image;
use ifd_planar::{
    Border, Decomposition, Field, Filter, ScaleStack, StackOptions, Term, stack_for_decomposition,
};
use wgpu::util::DeviceExt as _;

fn image(w: usize, h: usize) -> Image {
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            0.5 + 0.3 * (0.05 * x + 0.03 * y).sin() + 0.2 * (0.31 * x * y / 512.0).cos()
        })
        .collect();
    Image::from_vec(w, h, 1, data).expect("valid image")
}

fn decomposition(n: usize) -> Decomposition {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    Decomposition::from_terms(
        (0..n)
            .map(|_| Term {
                weight: 1.0 / n as f64,
                x: (next() * 2.0 - 1.0) * 24.0,
                y: (next() * 2.0 - 1.0) * 24.0,
                sigma: 1.0 + 4.0 * next(),
            })
            .collect(),
    )
}

fn ctx() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(c) => {
            eprintln!("{}", c.describe());
            Some(c)
        }
        Err(e) => {
            eprintln!("no GPU benchmarks: {e}");
            None
        }
    }
}

fn eval(c: &mut Criterion) {
    let Some(ctx) = ctx() else { return };
    let side = std::env::var("IFD_GPU_BENCH_SIZE")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .unwrap_or(256);
    let term_counts: Vec<usize> = std::env::var("IFD_GPU_BENCH_TERMS").ok().map_or_else(
        || vec![16, 64],
        |v| v.split(',').filter_map(|n| n.trim().parse().ok()).collect(),
    );
    let (w, h) = (side, side);
    let img = image(w, h);
    let angles: Vec<f32> = (0..w * h).map(|i| (i % w) as f32 * 0.7).collect();
    let scales: Vec<f32> = (0..w * h)
        .map(|i| 0.75 + 0.5 * (i / w) as f32 / h as f32)
        .collect();
    let mut group = c.benchmark_group("eval");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(4));
    group.throughput(Throughput::Elements((w * h) as u64));
    for n in term_counts {
        let d = decomposition(n);
        let stack = stack_for_decomposition(
            &img,
            &d,
            0.75,
            1.25,
            Border::Reflect101,
            StackOptions::default(),
        )
        .expect("stack");
        let exact_stack = ScaleStack::with_sigmas(
            &img,
            &ifd_planar::level_sigmas(&d, 1.0, 0.0),
            Border::Reflect101,
            StackOptions {
                margin: 32,
                ..StackOptions::default()
            },
        )
        .expect("stack at the terms' sigmas");
        let uniform = (
            Filter::new(&stack, &d).expect("filter"),
            GpuStack::upload(&ctx, &stack).expect("upload"),
        );
        let exact = (
            Filter::new(&exact_stack, &d).expect("filter"),
            GpuStack::upload(&ctx, &exact_stack).expect("upload"),
        );
        let gd = GpuDecomposition::new(&ctx, &d).expect("terms");
        for (name, angle, scale, (filter, gs)) in [
            (
                "constant",
                Field::Constant(30.0),
                Field::Constant(1.0),
                &uniform,
            ),
            ("exact", Field::Constant(30.0), Field::Constant(1.0), &exact),
            ("maps", Field::Map(&angles), Field::Map(&scales), &uniform),
        ] {
            let pose = GpuPose::new(&ctx, gs, angle, scale, Field::Constant(0.0)).expect("pose");
            // GPU time by timestamps (median of 5), when available.
            let mut times: Vec<Duration> = (0..5)
                .filter_map(|_| {
                    let out = ctx.evaluate(gs, &gd, &pose, None).expect("eval");
                    out.gpu_time(&ctx).expect("timestamps")
                })
                .collect();
            times.sort();
            if let Some(t) = times.get(times.len() / 2) {
                eprintln!(
                    "GPU time (timestamps), {n} terms, {name}: {:.2} ms on {}",
                    t.as_secs_f64() * 1e3,
                    ctx.adapter_info().name
                );
            }
            let id = format!("{name}/{n}");
            group.bench_function(BenchmarkId::new("cpu", &id), |b| {
                b.iter(|| black_box(filter.apply(angle, scale).expect("cpu")));
            });
            group.bench_function(BenchmarkId::new("gpu", &id), |b| {
                b.iter(|| {
                    let out = ctx.evaluate(gs, &gd, &pose, None).expect("eval");
                    ctx.device()
                        .poll(wgpu::PollType::wait_indefinitely())
                        .expect("poll");
                    black_box(out)
                });
            });
            group.bench_function(BenchmarkId::new("gpu+read", &id), |b| {
                b.iter(|| {
                    let out = ctx.evaluate(gs, &gd, &pose, None).expect("eval");
                    black_box(out.read(&ctx).expect("read"))
                });
            });
        }
    }
    group.finish();
}

/// Storage buffer against texture array for the same lookups.
fn fetch(c: &mut Criterion) {
    let Some(ctx) = ctx() else { return };
    let (w, h, levels, n_terms) = (512u32, 512u32, 8u32, 128u32);
    let device = ctx.device();
    let data: Vec<f32> = (0..w * h * levels)
        .map(|i| ((i % 977) as f32 * 0.001).sin())
        .collect();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let terms: Vec<[f32; 4]> = (0..n_terms)
        .map(|_| {
            [
                1.0 / n_terms as f32,
                (next() * 2.0 - 1.0) * 24.0,
                (next() * 2.0 - 1.0) * 24.0,
                (next() * levels as f32).floor(),
            ]
        })
        .collect();
    let (s, co) = 30f32.to_radians().sin_cos();
    let params: [u32; 8] = [w, h, levels, n_terms, co.to_bits(), s.to_bits(), 0, 0];
    let init = |label, contents: &[u8], usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage,
        })
    };
    let pbuf = init(
        "params",
        bytemuck::cast_slice(&params),
        wgpu::BufferUsages::UNIFORM,
    );
    let tbuf = init(
        "terms",
        bytemuck::cast_slice(&terms),
        wgpu::BufferUsages::STORAGE,
    );
    let dbuf = init(
        "data",
        bytemuck::cast_slice(&data),
        wgpu::BufferUsages::STORAGE,
    );
    let obuf = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("out"),
        size: u64::from(w * h * 4),
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let texture = device.create_texture_with_data(
        ctx.queue(),
        &wgpu::TextureDescriptor {
            label: Some("levels"),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: levels,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::R32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        bytemuck::cast_slice(&data),
    );
    let view = texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..wgpu::TextureViewDescriptor::default()
    });
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("bench_fetch"),
        source: wgpu::ShaderSource::Wgsl(include_str!("../../../shaders/bench_fetch.wgsl").into()),
    });
    let mut group = c.benchmark_group("fetch");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(6));
    group.throughput(Throughput::Elements(u64::from(w * h)));
    for entry in ["buffer_main", "texture_main"] {
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: None,
            module: &module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            cache: None,
        });
        let source = if entry == "buffer_main" {
            dbuf.as_entire_binding()
        } else {
            wgpu::BindingResource::TextureView(&view)
        };
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(entry),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: pbuf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: tbuf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: obuf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: if entry == "buffer_main" { 3 } else { 4 },
                    resource: source,
                },
            ],
        });
        group.bench_function(entry.trim_end_matches("_main"), |b| {
            b.iter(|| {
                let mut enc =
                    device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
                {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
                    pass.set_pipeline(&pipeline);
                    pass.set_bind_group(0, &bind, &[]);
                    pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
                }
                ctx.queue().submit([enc.finish()]);
                device
                    .poll(wgpu::PollType::wait_indefinitely())
                    .expect("poll");
            });
        });
    }
    group.finish();
}

criterion_group!(benches, eval, fetch);
criterion_main!(benches);
