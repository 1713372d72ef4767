//! What each pixel's ray sees, before shading: the surface point's frame, the
//! view, the texture maps' values there, or the direction of the background.
//! The CPU render loop ([`crate::render`]) shades these records itself, and
//! the GPU path (`ifd render --gpu`, `ifd_gpu::GpuShader`) uploads them, so both
//! shade the same points.

use ifd_shade::Frame;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::error::{RenderError, Result};
use crate::scene::Scene;
use crate::textures::SurfaceMaps;

/// A surface point seen by a pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// The shading frame (normal, and the tangent anisotropic BRDFs align
    /// `ax` with).
    pub frame: Frame,
    /// The point (world), where local lights are seen from.
    pub p: [f64; 3],
    /// The unit direction towards the viewer.
    pub wo: [f64; 3],
    /// Texture coordinates (`[0, 0]` for meshes without them, and for the
    /// sphere and the torus when no texture map reads them).
    pub uv: [f64; 2],
    /// The roughness map's value, when there is one.
    pub roughness: Option<f64>,
    /// The albedo map's value per channel (a grey map repeats its value),
    /// `[1, 1, 1]` without a map.
    pub albedo: [f64; 3],
    /// A glTF asset's material at the point (its textures applied; the
    /// frame's normal is its shading normal), `None` for other scenes.
    pub gltf: Option<crate::gltf::GltfPoint>,
}

impl Surface {
    /// The glTF material at this point when the job's BRDF is `gltf` with
    /// factors `brdf`: a glTF asset's own material, else the factors with
    /// the albedo map's colour multiplying the base colour and the roughness
    /// map's value replacing the roughness. The CPU renderer and the GPU
    /// G-buffer both take it from here.
    #[must_use]
    pub fn gltf_material(&self, brdf: &ifd_shade::GltfMaterial) -> ifd_shade::GltfMaterial {
        match self.gltf {
            Some(p) => p.material,
            None => ifd_shade::GltfMaterial {
                base: [0, 1, 2].map(|c| (brdf.base[c] * self.albedo[c]).clamp(0.0, 1.0)),
                roughness: self
                    .roughness
                    .map_or(brdf.roughness, |r| crate::textures::alpha_of(r).sqrt()),
                ..*brdf
            },
        }
    }
}

/// One pixel: its ray's direction and what it hits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pixel {
    /// The unit direction of the ray through the pixel's centre.
    pub dir: [f64; 3],
    /// The surface, `None` where the ray sees the background.
    pub surface: Option<Surface>,
}

/// The ray through pixel `(x, y)`'s centre and what it hits.
#[must_use]
#[inline]
pub fn pixel(
    scene: &Scene,
    camera: &Camera,
    maps: Option<&SurfaceMaps>,
    x: usize,
    y: usize,
) -> Pixel {
    let (o, d) = camera.ray(x as f64 + 0.5, y as f64 + 0.5);
    let surface = scene.intersect_with(o, d, textured(maps)).map(|hit| {
        let uv = hit.uv.unwrap_or([0.0, 0.0]);
        let roughness = maps
            .and_then(|m| m.roughness.as_ref())
            .map(|t| t.sample(uv, 0));
        let albedo = match maps.and_then(|m| m.albedo.as_ref()) {
            Some(a) => [a.sample(uv, 0), a.sample(uv, 1), a.sample(uv, 2)],
            None => [1.0; 3],
        };
        let gltf = match scene {
            Scene::Gltf(a) => Some(a.point(&hit)),
            _ => None,
        };
        let (n, tangent) = match (gltf, maps.and_then(|m| m.normal.as_ref())) {
            (Some(g), _) => (g.normal, g.tangent),
            (None, Some(t)) => (
                crate::textures::perturb_normal(hit.n, hit.dpdu, uv, t),
                hit.dpdu,
            ),
            (None, None) => (hit.n, hit.dpdu),
        };
        Surface {
            frame: Frame::new(n.to_array(), tangent.to_array()),
            p: hit.p.to_array(),
            wo: (-d).to_array(),
            uv,
            roughness,
            albedo,
            gltf,
        }
    });
    Pixel {
        dir: d.to_array(),
        surface,
    }
}

/// Every pixel of the camera's image, row-major (rows in parallel).
///
/// # Errors
/// [`RenderError::Parameter`] for texture maps on a mesh without texture
/// coordinates; [`RenderError::NothingVisible`] when no ray hits the object.
pub fn pixels(scene: &Scene, camera: &Camera, maps: Option<&SurfaceMaps>) -> Result<Vec<Pixel>> {
    check_maps(scene, maps)?;
    let (w, h) = (camera.width(), camera.height());
    let px: Vec<Pixel> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| (0..w).map(move |x| pixel(scene, camera, maps, x, y)))
        .collect();
    if px.iter().all(|p| p.surface.is_none()) {
        return Err(nothing_visible(scene, camera));
    }
    Ok(px)
}

/// Whether any texture map is given (and texture coordinates are read).
fn textured(maps: Option<&SurfaceMaps>) -> bool {
    maps.is_some_and(|m| m.roughness.is_some() || m.albedo.is_some() || m.normal.is_some())
}

/// Texture maps need texture coordinates.
pub(crate) fn check_maps(scene: &Scene, maps: Option<&SurfaceMaps>) -> Result<()> {
    if textured(maps) && !scene.has_tangents() {
        return Err(RenderError::Parameter {
            name: "--scene",
            value: "mesh".into(),
            reason: "texture maps need texture coordinates, and the mesh has none".into(),
        });
    }
    Ok(())
}

pub(crate) fn nothing_visible(scene: &Scene, camera: &Camera) -> RenderError {
    RenderError::NothingVisible(format!(
        "no ray of the {}x{} image hits the {} (check --eye, --target, --fov)",
        camera.width(),
        camera.height(),
        scene.describe()
    ))
}
