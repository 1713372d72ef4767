//! ISD shading on the GPU (ISD Eq. 22): a G-buffer of surface points shaded
//! by `shaders/isd_shade.wgsl`, in both variants (the per-band environment
//! from SH at each rotated lobe direction, or from per-band prefiltered
//! maps), with the CPU path's conventions (`ifd_shade::Material::shade_isd`).
//!
//! The derivation and conventions are documented on [`GpuShader`].

mod environment;
mod material;
mod render;
mod surface;

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ifd_image::Image;

pub use environment::{EnvVariant, GpuEnvironment};
pub use material::GpuMaterial;
pub use render::GpuRender;
pub use surface::{GpuSurfaces, SurfacePoint};

use crate::context::GpuContext;
use crate::error::GpuError;
use crate::pipelines::{compute_pipeline, rgba8_target_entry, storage_entry, uniform_entry};
use crate::shaders::{self, shade_codes};
use crate::wgpu_helpers::{
    Timestamps, buffer_init, entry, read_buffer, read_gpu_time, read_rgba8, rgba8_texture,
    submit_pass,
};

/// The `struct Params` of `shaders/isd_shade.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    width: u32,
    height: u32,
    variant: u32,
    material: u32,
    isotropic: u32,
    in_plane: u32,
    n_lobes: u32,
    count: u32,
    kc: u32,
    n_tables: u32,
    map_w: u32,
    map_h: u32,
    row0: u32,
    pad: [u32; 3],
}

/// The `struct Params` of `shaders/tonemap.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct DisplayParams {
    width: u32,
    height: u32,
    curve: u32,
    row0: u32,
    scale: f32,
    pad1: [f32; 3],
}

/// The tone curve of [`GpuShader::display`] (as `ifd_render::Tonemap`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToneCurve {
    /// Clip to `[0, 1]`.
    None,
    /// `x / (1 + x)`.
    Reinhard,
    /// Narkowicz's fit of the ACES filmic curve.
    Aces,
}

impl From<ifd_render::Tonemap> for ToneCurve {
    fn from(t: ifd_render::Tonemap) -> Self {
        use ifd_render::Tonemap;
        match t {
            Tonemap::None => Self::None,
            Tonemap::Reinhard => Self::Reinhard,
            Tonemap::Aces => Self::Aces,
        }
    }
}

/// The shading pipelines of one device (compiled per degree on first use).
///
/// ```no_run
/// use ifd_gpu::GpuContext;
/// use ifd_gpu::{GpuEnvironment, GpuMaterial, GpuShader, GpuSurfaces, SurfacePoint};
/// use ifd_render::{Camera, Scene, pixels};
/// use ifd_shade::{Brdf, Environment, Material};
/// let ctx = GpuContext::new()?;
/// let camera = Camera::new(glam::DVec3::new(0.0, -4.0, 0.0), glam::DVec3::ZERO, glam::DVec3::Z, 40.0, 64, 64)?;
/// let px = pixels(&Scene::Sphere, &camera, None)?;
/// let points: Vec<SurfacePoint> = px.iter().map(|p| SurfacePoint::from_pixel(p, None)).collect();
/// let surfaces = GpuSurfaces::upload(&ctx, 64, 64, &points)?;
/// let mut e = ifd_sphere::ShCoeffs::zeros(8, 3)?;
/// e.data_mut()[..3].fill(1.0); // a constant environment
/// let env = GpuEnvironment::sh(&ctx, &Environment::new(e)?)?;
/// let material = GpuMaterial::new(&ctx, &Material::new(&Brdf::parse("phong:s=20")?, 8, None)?)?;
/// let shader = GpuShader::new(&ctx)?;
/// let (image, mask) = shader.shade(&ctx, &surfaces, &env, &material)?.read(&ctx)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Design
/// - **The G-buffer comes from outside** ([`SurfacePoint`]: normal, tangent,
///   view, roughness, albedo or background radiance per pixel): the CPU ray
///   caster of `ifd-render` (`ifd render --gpu`), or any renderer that writes
///   the same records on the device.
/// - **One kernel per degree**: the source is compiled with `NB = L + 1`
///   prepended, which sizes the private per-band sums (a WGSL function array
///   needs a constant size) and lets the compiler unroll; pipelines are cached
///   per degree.
/// - **f32 with the CPU's recurrences**, except that `sin^m theta` is folded
///   into the sectoral start values (the CPU's reduced values overflow `f32`
///   beyond `L` about 38). Weights are interpolated in the kernel from the
///   tables' `f32` entries, map taps are computed in the kernel (no hardware
///   filtering, whose weights have 8 fractional bits). GPU and CPU agree
///   within `1e-3` of the image maximum (`tests/gpu.rs`).
/// - **RGB always**: a grey environment is repeated in three channels; the
///   result is read back as RGB plus the object mask.
#[derive(Debug)]
pub struct GpuShader {
    layout: wgpu::BindGroupLayout,
    pipelines: Mutex<HashMap<usize, Arc<wgpu::ComputePipeline>>>,
    display_layout: wgpu::BindGroupLayout,
    display_pipeline: wgpu::ComputePipeline,
}

impl GpuShader {
    /// The bind group layout; pipelines are compiled when first needed.
    ///
    /// # Errors
    /// [`GpuError::Device`] when wgpu refuses the layout.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let (uniform, storage) = (uniform_entry, storage_entry);
        let layout = ctx.scoped("creating the shading layout", || {
            Ok(ctx
                .device()
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("isd_shade"),
                    entries: &[
                        uniform(0),
                        storage(1, true),
                        uniform(2),
                        uniform(3),
                        uniform(4),
                        storage(5, true),
                        uniform(6),
                        storage(7, true),
                        storage(8, false),
                    ],
                }))
        })?;
        let device = ctx.device();
        let (display_layout, display_pipeline) = ctx.scoped("building the display pass", || {
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("isd tonemap"),
                entries: &[uniform(0), storage(1, true), rgba8_target_entry(2)],
            });
            let pipeline = compute_pipeline(device, "isd tonemap", shaders::TONEMAP, &layout);
            Ok((layout, pipeline))
        })?;
        Ok(Self {
            layout,
            pipelines: Mutex::new(HashMap::new()),
            display_layout,
            display_pipeline,
        })
    }

    /// The pipeline for degree `l_max` (compiled and cached on first use).
    ///
    /// # Errors
    /// [`GpuError::Device`] when the kernel fails to compile on this device.
    pub fn pipeline(
        &self,
        ctx: &GpuContext,
        l_max: usize,
    ) -> Result<Arc<wgpu::ComputePipeline>, GpuError> {
        let mut cache = self
            .pipelines
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(p) = cache.get(&l_max) {
            return Ok(Arc::clone(p));
        }
        let name = format!("compiling the shading kernel for L = {l_max}");
        let p = ctx.scoped(&name, || {
            Ok(compute_pipeline(
                ctx.device(),
                "isd_shade",
                &shaders::isd_shade_source(l_max),
                &self.layout,
            ))
        })?;
        let p = Arc::new(p);
        cache.insert(l_max, Arc::clone(&p));
        Ok(p)
    }

    /// Shades every pixel of `surfaces` (Eq. 22; the background records are
    /// copied through), into a new output buffer on the device.
    ///
    /// # Errors
    /// [`GpuError::Unsupported`] for an environment and material of different
    /// degrees, or an RGB (MERL) material under a grey environment;
    /// [`GpuError::Limit`] beyond the device's limits.
    pub fn shade(
        &self,
        ctx: &GpuContext,
        surfaces: &GpuSurfaces,
        env: &GpuEnvironment,
        material: &GpuMaterial,
    ) -> Result<GpuShaded, GpuError> {
        let mut out = self.output(ctx, surfaces.width, surfaces.height)?;
        self.shade_rows(ctx, surfaces, env, material, &mut out, 0..surfaces.height)?;
        Ok(out)
    }

    /// A `width x height` output buffer for [`Self::shade_rows`].
    ///
    /// # Errors
    /// [`GpuError::Limit`] beyond the device's limits.
    pub fn output(
        &self,
        ctx: &GpuContext,
        width: usize,
        height: usize,
    ) -> Result<GpuShaded, GpuError> {
        let (w32, h32) = (
            u32::try_from(width).unwrap_or(u32::MAX),
            u32::try_from(height).unwrap_or(u32::MAX),
        );
        ctx.check_dispatch("the shading", w32, h32)?;
        let bytes = (width * height * 16) as u64;
        ctx.check_buffer("the shaded image", bytes, true)?;
        let buffer = ctx.scoped("allocating the shaded image", || {
            Ok(ctx.device().create_buffer(&wgpu::BufferDescriptor {
                label: Some("isd shaded"),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }))
        })?;
        Ok(GpuShaded {
            buffer,
            width,
            height,
            timestamps: None,
        })
    }

    /// Shades the rows `rows` of `surfaces` into `out` (of the same size):
    /// frames shaded in bands, one band per UI frame, keep a slow adapter
    /// from holding the queue (and the window) for a whole frame's shading.
    /// The pass is timed into `out` (the last band's time).
    ///
    /// # Errors
    /// As [`Self::shade`]; [`GpuError::Unsupported`] for an output of another
    /// size or rows beyond the image.
    pub fn shade_rows(
        &self,
        ctx: &GpuContext,
        surfaces: &GpuSurfaces,
        env: &GpuEnvironment,
        material: &GpuMaterial,
        out: &mut GpuShaded,
        rows: std::ops::Range<usize>,
    ) -> Result<(), GpuError> {
        if env.l_max != material.l_max {
            return Err(GpuError::Unsupported(format!(
                "an environment of L = {} with a material of L = {}",
                env.l_max, material.l_max
            )));
        }
        if material.kc == 3 && env.channels == 1 {
            return Err(GpuError::Unsupported(
                "an RGB (MERL) BRDF under a grey environment".into(),
            ));
        }
        let (w, h) = (surfaces.width, surfaces.height);
        if (out.width, out.height) != (w, h) || rows.start >= rows.end || rows.end > h {
            return Err(GpuError::Unsupported(format!(
                "rows {rows:?} of a {w}x{h} frame into a {}x{} output",
                out.width, out.height
            )));
        }
        let pipeline = self.pipeline(ctx, material.l_max)?;
        let device = ctx.device();
        let n_rows = (rows.end - rows.start) as u32;
        ctx.scoped("shading", || {
            let params = Params {
                width: w as u32,
                height: h as u32,
                variant: match env.variant {
                    EnvVariant::Sh => shade_codes::VARIANT_SH,
                    EnvVariant::Maps => shade_codes::VARIANT_MAPS,
                },
                material: material.code,
                isotropic: u32::from(material.isotropic),
                in_plane: u32::from(material.in_plane),
                n_lobes: material.n_lobes as u32,
                count: material.count as u32,
                kc: material.kc as u32,
                n_tables: material.n_tables as u32,
                map_w: env.map_size.0 as u32,
                map_h: env.map_size.1 as u32,
                row0: rows.start as u32,
                pad: [0; 3],
            };
            let pb = buffer_init(
                device,
                "isd params",
                bytemuck::bytes_of(&params),
                wgpu::BufferUsages::UNIFORM,
            );
            let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("isd_shade"),
                layout: &self.layout,
                entries: &[
                    entry(0, &pb),
                    entry(1, &surfaces.buffer),
                    entry(2, &env.sh),
                    entry(3, &material.consts),
                    entry(4, &material.lobes),
                    entry(5, &material.weights),
                    entry(6, &material.tables),
                    entry(7, &env.maps),
                    entry(8, &out.buffer),
                ],
            });
            let timing = Timestamps::new(ctx, "isd timestamps");
            let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("isd_shade"),
            });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("isd_shade"),
                    timestamp_writes: timing.as_ref().map(Timestamps::writes),
                });
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(0, &bind, &[]);
                pass.dispatch_workgroups((w as u32).div_ceil(8), n_rows.div_ceil(8), 1);
            }
            if let Some(t) = &timing {
                t.resolve(&mut enc);
            }
            ctx.queue().submit([enc.finish()]);
            out.timestamps = timing.map(|t| t.resolve);
            Ok(())
        })
    }

    /// Submits the display transform of `shaded` (`2^exposure`, `curve`,
    /// sRGB, as `ifd render` writes 8-bit files) into `target`, an
    /// `rgba8unorm` texture of the image's size with `STORAGE_BINDING`
    /// usage, for a renderer on the same device (no readback).
    ///
    /// # Errors
    /// [`GpuError::Unsupported`] for a target of another size or format.
    pub fn display(
        &self,
        ctx: &GpuContext,
        shaded: &GpuShaded,
        curve: ToneCurve,
        exposure: f32,
        target: &wgpu::Texture,
    ) -> Result<(), GpuError> {
        self.display_rows(ctx, shaded, curve, exposure, target, 0..shaded.height)
    }

    /// [`Self::display`] for the rows `rows` only (the band just shaded).
    ///
    /// # Errors
    /// As [`Self::display`]; [`GpuError::Unsupported`] for rows beyond the image.
    pub fn display_rows(
        &self,
        ctx: &GpuContext,
        shaded: &GpuShaded,
        curve: ToneCurve,
        exposure: f32,
        target: &wgpu::Texture,
        rows: std::ops::Range<usize>,
    ) -> Result<(), GpuError> {
        if rows.start >= rows.end || rows.end > shaded.height {
            return Err(GpuError::Unsupported(format!(
                "display rows {rows:?} of a {}-row image",
                shaded.height
            )));
        }
        let (w, h) = (shaded.width as u32, shaded.height as u32);
        if target.width() != w
            || target.height() != h
            || target.format() != wgpu::TextureFormat::Rgba8Unorm
        {
            return Err(GpuError::Unsupported(format!(
                "a {}x{} {:?} display texture for a {w}x{h} image (rgba8unorm of the same size)",
                target.width(),
                target.height(),
                target.format()
            )));
        }
        let device = ctx.device();
        ctx.scoped("converting the shaded image for display", || {
            let params = DisplayParams {
                width: w,
                height: h,
                curve: match curve {
                    ToneCurve::None => 0,
                    ToneCurve::Reinhard => 1,
                    ToneCurve::Aces => 2,
                },
                row0: rows.start as u32,
                scale: exposure.exp2(),
                pad1: [0.0; 3],
            };
            let pb = buffer_init(
                device,
                "isd tonemap params",
                bytemuck::bytes_of(&params),
                wgpu::BufferUsages::UNIFORM,
            );
            let view = target.create_view(&wgpu::TextureViewDescriptor::default());
            let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("isd tonemap"),
                layout: &self.display_layout,
                entries: &[
                    entry(0, &pb),
                    entry(1, &shaded.buffer),
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&view),
                    },
                ],
            });
            let n = (rows.end - rows.start) as u32;
            submit_pass(ctx, "isd tonemap", &self.display_pipeline, &bind, (w, n));
            Ok(())
        })
    }

    /// Reads a display texture back (tests, screenshots without a window).
    ///
    /// # Errors
    /// [`GpuError::Readback`] when mapping fails.
    pub fn read_display(
        ctx: &GpuContext,
        texture: &wgpu::Texture,
    ) -> Result<Vec<[u8; 4]>, GpuError> {
        read_rgba8(ctx, texture, "a display texture")
    }

    /// A `width x height` `rgba8unorm` texture for [`Self::display`] (usages
    /// `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`).
    #[must_use]
    pub fn display_texture(ctx: &GpuContext, width: usize, height: usize) -> wgpu::Texture {
        rgba8_texture(ctx.device(), "isd display", width as u32, height as u32)
    }
}

/// A shaded image on the device: `vec4<f32>` per pixel, RGB radiance and 1
/// on the object (0 on the background), row-major.
#[derive(Debug)]
pub struct GpuShaded {
    buffer: wgpu::Buffer,
    width: usize,
    height: usize,
    timestamps: Option<wgpu::Buffer>,
}

impl GpuShaded {
    /// The output buffer (usage `STORAGE | COPY_SRC`), for a renderer on the
    /// same device.
    #[must_use]
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Image size `(width, height)`.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Reads the result back: the RGB image and the object mask (row-major).
    ///
    /// # Errors
    /// [`GpuError::Readback`] when mapping fails.
    pub fn read(&self, ctx: &GpuContext) -> Result<(Image, Vec<bool>), GpuError> {
        let bytes = read_buffer(ctx, &self.buffer, "the shaded image")?;
        let v: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
        let n = self.width * self.height;
        let mut rgb = Vec::with_capacity(n * 3);
        let mut mask = Vec::with_capacity(n);
        for p in v.chunks_exact(4).take(n) {
            rgb.extend_from_slice(&p[..3]);
            mask.push(p[3] > 0.5);
        }
        let img =
            Image::from_vec(self.width, self.height, 3, rgb).map_err(|e| GpuError::Readback {
                what: "the shaded image",
                reason: e.to_string(),
            })?;
        Ok((img, mask))
    }

    /// GPU time of the shading pass, from timestamp queries; `None` when the
    /// device has no timestamp queries.
    ///
    /// # Errors
    /// As [`Self::read`].
    pub fn gpu_time(&self, ctx: &GpuContext) -> Result<Option<Duration>, GpuError> {
        read_gpu_time(ctx, self.timestamps.as_ref())
    }
}

#[cfg(test)]
mod layout_tests {
    use super::{DisplayParams, Params};
    use crate::layout::mirror;

    #[test]
    fn the_mirrors_match_isd_shade_and_tonemap_wgsl() {
        for l in [0, 7, 100] {
            mirror!(crate::shaders::isd_shade_source(l), "Params", Params, [
                "width" => width, "height" => height, "variant" => variant,
                "material" => material, "isotropic" => isotropic, "in_plane" => in_plane,
                "n_lobes" => n_lobes, "count" => count, "kc" => kc, "n_tables" => n_tables,
                "map_w" => map_w, "map_h" => map_h, "row0" => row0,
                "pad0" => pad, "pad1" => pad + 4, "pad2" => pad + 8,
            ]);
        }
        mirror!(crate::shaders::TONEMAP, "Params", DisplayParams, [
            "width" => width, "height" => height, "curve" => curve, "row0" => row0,
            "scale" => scale, "pad1" => pad1, "pad2" => pad1 + 4, "pad3" => pad1 + 8,
        ]);
    }
}
