//! GPU evaluation of planar isotropic filter decompositions with wgpu
//! (Vulkan; hardware drivers or Mesa's software lavapipe) and a WGSL compute
//! shader (`shaders/ifd_eval.wgsl`).
//!
//! The scale stack is built on the CPU (`ifd_planar::ScaleStack`, by FFT)
//! and uploaded once; then any decomposition is evaluated per pixel as
//! `out(p) = sum_t w_t fhat_{s sigma_t}(p + s R_theta c_t)` with per-pixel
//! angle and scale maps, the conventions and border handling of the CPU path
//! (`ifd_planar::Filter::apply`): correlation, angles in degrees
//! counter-clockwise on screen, `x` = column, `y` = row.
//!
//! ```no_run
//! use ifd_gpu::{GpuContext, filter_stack};
//! use ifd_planar::{Border, Decomposition, Field, StackOptions, stack_for_decomposition};
//! let ctx = GpuContext::new()?; // hardware, else lavapipe; GpuError::NoAdapter if neither
//! let img = ifd_image::read("testdata/camera.png")?;
//! let d = Decomposition::load(std::path::Path::new("d.json"))?;
//! let stack = stack_for_decomposition(&img, &d, 1.0, 1.0, Border::Reflect101, StackOptions::default())?;
//! let out = filter_stack(&ctx, &stack, &d, Field::Constant(30.0), Field::Constant(1.0))?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Lower level, for reuse and for renderers: [`GpuStack::upload`],
//! [`GpuDecomposition`], [`GpuPose`] (per-pixel maps uploaded once),
//! [`GpuContext::evaluate`] over the whole image or a [`Region`] (brush dabs),
//! [`GpuOutput`] (the result stays on the device as a storage buffer; read it
//! back, or convert it to an `rgba8unorm` texture for display). Smoothing and
//! the Hessian of `ifd-smooth`: [`GpuSmoother`], [`GpuHessian`]. Painting
//! without a round trip: [`GpuCanvas`] keeps the image on the device,
//! blends brush dabs into it and converts the changed pixels into display
//! textures that a renderer on the same device draws.
//!
//! # Devices
//! [`GpuContext::new`] creates a headless device: the best enumerated
//! adapter (discrete, integrated, virtual, then CPU), else `request_adapter`
//! without and then with `force_fallback_adapter`. Nothing global is set;
//! `WGPU_BACKEND` is honoured when set. [`GpuContext::from_device`] wraps a
//! device made elsewhere (the brush app's renderer, a test), so device
//! creation and execution are separate.
//!
//! # Design
//! **Storage buffers, not a texture array.** Levels of the stack have
//! different sizes (levels with sigma >= 4 px are subsampled, a Gaussian
//! pyramid), which a texture array cannot hold without padding every layer
//! to full resolution: the 33 levels of a 4096x4096 stack over sigma 1..256
//! take 0.58 GiB per channel as stored and 2.07 GiB padded (3.5x), beyond
//! most devices' limits. Hardware bilinear filtering cannot be used either
//! way (interpolation weights with 8 fractional bits on common GPUs, far
//! from the 1e-4 target, and `r32float` is not filterable without an optional
//! feature), so the shader fetches four samples and interpolates itself
//! whatever holds them. Measured on lavapipe (`benches/gpu.rs`, `fetch`,
//! the case most favourable to textures: 8 equal full-resolution levels,
//! 512x512, 128 lookups per pixel), two runs on the shared, loaded 2-core
//! machine: texture array 0.92 s and 0.56 s, storage buffer 1.17 s and
//! 0.57 s, so textures were 3-21% faster there. That does not pay for 3.5x the
//! memory (or for an atlas and its extra index arithmetic); on real GPUs,
//! where the texture cache may matter more, the comparison has not been
//! measured and should be redone before revisiting this choice. Samples are
//! stored per group of at most four channels, level after level, planar per
//! channel; a stack larger than the device's
//! `max_storage_buffer_binding_size` is split into more groups (down to one
//! channel per buffer, evaluated by one dispatch each).
//!
//! **Same arithmetic as the CPU.** At a constant scale the host locates
//! every term's levels once with the stack's own
//! [`ifd_planar::LevelLocator`] (on a stack at exactly the terms' sigmas,
//! [`ifd_planar::ScaleStack::with_sigmas`], which `ifd filter --gpu` builds
//! then, that is one lookup per term); with a scale map the shader locates
//! them per pixel as `ScaleStack` does (linear in `ln sigma`, log-uniform
//! levels). It takes the same fast bilinear
//! path when the 2x2 footprint is stored and resolves other coordinates with
//! the same border mapping. Angle maps are turned into `(cos, sin)` on the
//! CPU with the same `f32` `sin_cos` (WGSL allows `sin`/`cos` an absolute
//! error of `2^-11`); scale maps carry their level offset computed in `f64`.
//!
//! **Tolerance.** GPU and CPU agree within `1e-4` of the result's largest
//! magnitude (checked in `tests/gpu.rs`). Differences come from `f32`
//! rounding in a different order (fused multiply-adds, the level position
//! `ln sigma_t / ln r + offset` in `f32` rather than `f64`: about `3e-6` of a
//! level), each of order `1e-6` relative per term; a few hundred terms
//! accumulate to well under `1e-5` in practice. `1e-4` leaves a margin for
//! GPUs with less careful float arithmetic, while any real bug (a wrong
//! level, a half-pixel shift, a wrong border) shows up at `1e-2` or more.
//!
//! **Limits.** Every buffer is checked against `max_buffer_size` and
//! `max_storage_buffer_binding_size`, every dispatch against
//! `max_compute_workgroups_per_dimension`, before anything is created; a
//! violation is a [`GpuError::Limit`] naming the limit; whole-image results
//! ([`GpuContext::evaluate_image`]) larger than a binding are evaluated in
//! bands of rows instead. Resource creation and
//! dispatches run inside wgpu error scopes, so a wgpu error becomes a
//! [`GpuError::Device`], never a panic.
//!
//! **Timing.** When the adapter has `TIMESTAMP_QUERY`, the evaluation pass
//! is bracketed by timestamps and [`GpuOutput::gpu_time`] reports the GPU
//! time.

mod canvas;
mod context;
mod error;
mod eval;
#[cfg(test)]
mod layout;
mod pipelines;
pub mod shaders;
mod shading;
mod smooth;
mod stack;
mod wgpu_helpers;

pub use canvas::{DisplayTile, GpuCanvas};
pub use context::{AdapterChoice, DeviceChoice, GpuContext, list_adapters};
pub use error::GpuError;
pub use eval::{GpuDecomposition, GpuOutput, GpuPose, Region};
pub use shading::{
    EnvVariant, GpuEnvironment, GpuMaterial, GpuRender, GpuShaded, GpuShader, GpuSurfaces,
    SurfacePoint, ToneCurve,
};
pub use smooth::{GpuHessian, GpuSmoother, filter_stack};
pub use stack::GpuStack;
