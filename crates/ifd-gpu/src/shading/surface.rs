//! The per-pixel surface records the shading kernel reads (a G-buffer).

use bytemuck::{Pod, Zeroable};
use ifd_render::EnvMap;
use ifd_render::Pixel;
use ifd_shade::GltfMaterial;

use crate::context::GpuContext;
use crate::error::GpuError;
use crate::wgpu_helpers::buffer_init;

/// One pixel of the G-buffer, as `shaders/isd_shade.wgsl` reads it (five
/// `vec4<f32>`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct SurfacePoint {
    /// Unit normal.
    pub normal: [f32; 3],
    /// 1 on the object, 0 for the background.
    pub hit: f32,
    /// Unit tangent, orthogonal to the normal (`ifd_shade::Frame`).
    pub tangent: [f32; 3],
    /// The roughness map's value (unused without a roughness family).
    pub roughness: f32,
    /// Unit direction towards the viewer.
    pub wo: [f32; 3],
    /// The glTF BRDF's metalness (unused by other materials).
    pub metallic: f32,
    /// The albedo map's value on the object (multiplies the shading; the
    /// base colour of the glTF BRDF), the background's radiance elsewhere.
    pub color: [f32; 3],
    /// A glTF asset's ambient occlusion (scales the environment's light; 1
    /// elsewhere; read by the glTF BRDF only).
    pub occlusion: f32,
    /// A glTF asset's emitted radiance, added after the occlusion (0
    /// elsewhere; read by the glTF BRDF only).
    pub emissive: [f32; 3],
    /// Unused.
    pub pad: f32,
}

impl Default for SurfacePoint {
    /// A background pixel (black), with the neutral occlusion 1.
    fn default() -> Self {
        Self {
            occlusion: 1.0,
            ..Zeroable::zeroed()
        }
    }
}

fn f32x3(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

impl SurfacePoint {
    /// The record of one pixel; `background` gives the radiance behind the
    /// object (bilinear, [`EnvMap::background`], as the CPU renderer's;
    /// black without one; channel 0 repeated for a grey map).
    #[must_use]
    pub fn from_pixel(p: &Pixel, background: Option<&EnvMap>) -> Self {
        Self::from_pixel_with(p, background, None)
    }

    /// [`Self::from_pixel`] for the glTF BRDF `gltf` (the job's material):
    /// the point's base colour, metalness and roughness, as the CPU renderer
    /// takes them (a glTF asset's own material, else the BRDF's factors with
    /// the albedo map's colour and the roughness map's value), and a glTF
    /// asset's occlusion and emission.
    #[must_use]
    pub fn from_pixel_with(
        p: &Pixel,
        background: Option<&EnvMap>,
        gltf: Option<&GltfMaterial>,
    ) -> Self {
        if let Some(s) = &p.surface {
            let point = gltf.map(|g| s.gltf_material(g));
            let asset = s.gltf.filter(|_| gltf.is_some());
            return Self {
                normal: f32x3(s.frame.n),
                hit: 1.0,
                tangent: f32x3(s.frame.t),
                roughness: point.map_or(s.roughness.unwrap_or(0.0), |m| m.roughness) as f32,
                wo: f32x3(s.wo),
                metallic: point.map_or(0.0, |m| m.metallic) as f32,
                color: f32x3(point.map_or(s.albedo, |m| m.base)),
                occlusion: asset.map_or(1.0, |a| a.occlusion) as f32,
                emissive: f32x3(asset.map_or([0.0; 3], |a| a.emissive)),
                pad: 0.0,
            };
        }
        let mut c = [0.0; 3];
        if let Some(bg) = background {
            let mut v = vec![0.0; bg.channels()];
            bg.background(p.dir, &mut v);
            c = std::array::from_fn(|k| v[k.min(v.len() - 1)]);
        }
        Self {
            color: f32x3(c),
            ..Self::default()
        }
    }
}

/// A G-buffer on the device: `width x height` [`SurfacePoint`]s, row-major.
#[derive(Debug)]
pub struct GpuSurfaces {
    pub(crate) buffer: wgpu::Buffer,
    pub(crate) width: usize,
    pub(crate) height: usize,
}

impl GpuSurfaces {
    /// Uploads the records of a `width x height` image.
    ///
    /// # Errors
    /// [`GpuError::Unsupported`] when `points` does not hold `width x height`
    /// records; [`GpuError::Limit`] beyond the device's buffer limits.
    pub fn upload(
        ctx: &GpuContext,
        width: usize,
        height: usize,
        points: &[SurfacePoint],
    ) -> Result<Self, GpuError> {
        if width == 0 || height == 0 || points.len() != width * height {
            return Err(GpuError::Unsupported(format!(
                "{} surface records for a {width}x{height} image",
                points.len()
            )));
        }
        let bytes = std::mem::size_of_val(points) as u64;
        ctx.check_buffer("the surface records", bytes, true)?;
        let buffer = ctx.scoped("uploading the surface records", || {
            Ok(buffer_init(
                ctx.device(),
                "isd surfaces",
                bytemuck::cast_slice(points),
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ))
        })?;
        Ok(Self {
            buffer,
            width,
            height,
        })
    }

    /// Image size `(width, height)`.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
}
