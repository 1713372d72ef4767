//! A CPU render job (`ifd_render::Job`) shaded on the GPU: rays cast
//! on the CPU into a G-buffer, the environment, material and G-buffer
//! uploaded once, then shaded as often as asked (benchmarks shade one frame
//! many times).

use ifd_image::Image;
use ifd_render::{Job, Method, Rendered};
use ifd_shade::{BandMaps, Environment};

use super::{GpuEnvironment, GpuMaterial, GpuShaded, GpuShader, GpuSurfaces, SurfacePoint};
use crate::context::GpuContext;
use crate::error::GpuError;

/// Everything a job needs on the device.
#[derive(Debug)]
pub struct GpuRender {
    shader: GpuShader,
    surfaces: GpuSurfaces,
    env: GpuEnvironment,
    material: GpuMaterial,
    channels: usize,
    object_pixels: usize,
}

impl GpuRender {
    /// Casts the job's rays (CPU) and uploads the G-buffer, the environment
    /// (SH for [`Method::Isd`], per-band maps for [`Method::IsdMaps`]) and
    /// the material (or the roughness family, with a roughness map).
    ///
    /// # Errors
    /// [`GpuError::Unsupported`] for the other methods, for jobs without a
    /// material and for shadows or spherical lights; render errors (nothing visible, maps on a mesh without
    /// texture coordinates); device limits.
    pub fn new(ctx: &GpuContext, job: &Job<'_>) -> Result<Self, GpuError> {
        if !matches!(job.method, Method::Isd | Method::IsdMaps) {
            return Err(GpuError::Unsupported(format!(
                "the {:?} method (the GPU shades isd and isd-maps)",
                job.method
            )));
        }
        if job.shadows.is_some() || !job.lights.is_empty() {
            return Err(GpuError::Unsupported(
                "self-shadowing and spherical lights (shaded on the CPU only)".into(),
            ));
        }
        let gltf = job.brdf.gltf_material();
        let asset = matches!(job.scene, ifd_render::Scene::Gltf(_)) && gltf.is_some();
        let rough = job.maps.is_some_and(|m| m.roughness.is_some()) || asset;
        let material = match (job.family, job.material) {
            (Some(f), _) if rough => GpuMaterial::family(ctx, f)?,
            (_, Some(m)) => GpuMaterial::new(ctx, m)?,
            _ => {
                return Err(GpuError::Unsupported(
                    "a job without a material (or roughness family)".into(),
                ));
            }
        };
        let kc = job.brdf.channels();
        let ch = job.env.channels();
        if kc != 1 && kc != ch {
            return Err(GpuError::Unsupported(format!(
                "a {kc}-channel BRDF under a {ch}-channel environment"
            )));
        }
        let e = Environment::new(job.env.sh(material.l_max)?)?;
        let env = if job.method == Method::IsdMaps {
            GpuEnvironment::maps(ctx, &BandMaps::new(&e)?)?
        } else {
            GpuEnvironment::sh(ctx, &e)?
        };
        let (w, h) = (job.camera.width(), job.camera.height());
        let px = ifd_render::pixels(&job.scene, &job.camera, job.maps)?;
        let object_pixels = px.iter().filter(|p| p.surface.is_some()).count();
        let points: Vec<SurfacePoint> = px
            .iter()
            .map(|p| SurfacePoint::from_pixel_with(p, job.background, gltf.as_ref()))
            .collect();
        let surfaces = GpuSurfaces::upload(ctx, w, h, &points)?;
        let shader = GpuShader::new(ctx)?;
        // compile now, so that the first frame's time is the shading's
        shader.pipeline(ctx, material.l_max)?;
        Ok(Self {
            shader,
            surfaces,
            env,
            material,
            channels: ch,
            object_pixels,
        })
    }

    /// Shades the frame (asynchronously: read it, or its time, to wait).
    ///
    /// # Errors
    /// As [`GpuShader::shade`].
    pub fn shade(&self, ctx: &GpuContext) -> Result<GpuShaded, GpuError> {
        self.shader
            .shade(ctx, &self.surfaces, &self.env, &self.material)
    }

    /// Bytes of the environment and material on the device.
    #[must_use]
    pub fn device_bytes(&self) -> (u64, u64) {
        (self.env.bytes(), self.material.bytes())
    }

    /// Reads a shaded frame back as the CPU renderer's result (the
    /// environment's channel count: a grey environment gives one channel).
    ///
    /// # Errors
    /// As [`GpuShaded::read`].
    pub fn rendered(&self, ctx: &GpuContext, shaded: &GpuShaded) -> Result<Rendered, GpuError> {
        let (rgb, mask) = shaded.read(ctx)?;
        let image = if self.channels == 1 {
            let grey = rgb.data().chunks_exact(3).map(|p| p[0]).collect();
            Image::from_vec(rgb.width(), rgb.height(), 1, grey).map_err(|e| GpuError::Readback {
                what: "the shaded image",
                reason: e.to_string(),
            })?
        } else {
            rgb
        };
        Ok(Rendered {
            image,
            mask,
            object_pixels: self.object_pixels,
            max_k: 0,
            not_converged: 0,
            max_residual: 0.0,
            stderr: None,
        })
    }
}
