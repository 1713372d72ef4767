//! glTF 2.0 assets (`.gltf` with external or embedded buffers, `.glb`): the
//! default scene's triangles as one [`Mesh`], its metallic-roughness
//! materials and textures, evaluated at a ray's [`Hit`] ([`GltfPoint`]),
//! and its first perspective camera.
//!
//! Parsing and validation of the JSON are `gltf-json`'s; everything that
//! touches bytes (GLB chunks, buffers, accessors, images) is checked here,
//! sized against the memory budget before it is allocated, and every refusal
//! is a [`RenderError::Asset`] naming the file and the part.

mod accessor;
mod document;
mod geometry;
mod material;
mod tangents;
#[cfg(test)]
mod tests;

use std::path::Path;
use std::sync::Arc;

use glam::DVec3;
use ifd_image::MemoryBudget;
use ifd_shade::{GLTF_MIN_ROUGHNESS, GltfMaterial};

use self::document::{Ctx, Document};
use self::material::{Mat, Tex, TexRef};
use crate::error::{RenderError, Result};
use crate::hit::Hit;
use crate::mesh::Mesh;

/// A glTF camera, in the mesh's coordinates (z up, the unit bounding
/// sphere's placement applied, as [`Mesh::placement`] says).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GltfCamera {
    /// The camera's position.
    pub eye: DVec3,
    /// `eye` plus the unit view direction.
    pub target: DVec3,
    /// The camera's unit up vector.
    pub up: DVec3,
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
    /// Width over height, when the file gives it.
    pub aspect: Option<f64>,
}

/// The glTF material's values at a surface point ([`GltfAsset::point`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GltfPoint {
    /// Base colour (`baseColorFactor` × `baseColorTexture`, sRGB-decoded, ×
    /// `COLOR_0`), metallic (factor × the metallic-roughness texture's B)
    /// and roughness (factor × its G), each clamped to `[0, 1]`; roughness
    /// raised to [`GLTF_MIN_ROUGHNESS`].
    pub material: GltfMaterial,
    /// The shading normal: the interpolated vertex normal perturbed by the
    /// normal texture (tangent space, `x` and `y` scaled by the texture's
    /// `scale`, bitangent `w n × t`), unit.
    pub normal: DVec3,
    /// A unit tangent orthogonal to `normal` (the vertex tangent, else
    /// `dP/du`, else any).
    pub tangent: DVec3,
    /// Ambient occlusion: `1 + strength (R - 1)` of the occlusion texture, 1
    /// without one.
    pub occlusion: f64,
    /// Emitted radiance: `emissiveFactor` × `emissiveTexture` (sRGB-decoded)
    /// × `KHR_materials_emissive_strength`.
    pub emissive: [f64; 3],
    /// Whether the material is double-sided.
    pub double_sided: bool,
}

/// A glTF 2.0 asset: the default scene's geometry, materials, textures and
/// camera.
///
/// - **Files**: `.gltf` (JSON; buffers and images in files next to it,
///   relative URIs, or in base64 `data:` URIs) or `.glb` (binary chunk).
///   Other URI schemes (no network access) and absolute paths are refused.
///   Images are PNG or JPEG, decoded by `ifd-image` under the budget.
/// - **Geometry**: every mesh primitive of the default scene (scene 0 when
///   none is named): root nodes and their children, node matrices or
///   translation × rotation × scale composed; triangles, strips and fans,
///   indexed or not, sparse accessors applied. Points and lines are skipped
///   with a note. Normals computed (area-weighted, as OBJ files get) when
///   absent; tangents from the file, else `MikkTSpace` where the material has
///   a normal texture; `TEXCOORD_0`/`_1` (float or normalized integers),
///   `COLOR_0` (where some primitives lack an attribute others have, their
///   vertices get zero texture coordinates, no tangent, white). A
///   negative-determinant transform flips the winding. glTF's
///   y-up becomes ifd's z-up (`(x, y, z) -> (x, -z, y)`), then the mesh is
///   placed in the unit bounding sphere ([`Mesh::placement`]).
/// - **Materials**: glTF's metallic-roughness model with its defaults (a
///   primitive without a material gets base colour 1, metallic 1,
///   roughness 1); textures sampled bilinearly with their sampler's wrap
///   modes (`REPEAT`, `MIRRORED_REPEAT`, `CLAMP_TO_EDGE`).
/// - **Extensions**: `KHR_materials_emissive_strength` is read; any other in
///   `extensionsRequired` refuses the file, naming it; other used ones
///   (such as `KHR_texture_transform`) are ignored with a note.
///
/// Malformed JSON or GLB chunks, missing or truncated buffers, accessors
/// and buffer views out of range or misaligned, indices out of range,
/// non-finite positions, sizes beyond the budget and images that do not
/// decode are refused with a [`RenderError::Asset`] (or, for images, a
/// [`RenderError::Image`]) naming the file and the part.
#[derive(Debug)]
pub struct GltfAsset {
    mesh: Arc<Mesh>,
    /// The file's materials, then the default one.
    materials: Vec<Mat>,
    textures: Vec<Tex>,
    camera: Option<GltfCamera>,
    notes: Vec<String>,
    roughness: (f64, f64),
}

impl GltfAsset {
    /// Reads a `.gltf` or `.glb` file; every allocation the file asks for is
    /// checked against `budget` first.
    ///
    /// # Errors
    /// [`RenderError::Asset`] naming the file and the part for every problem
    /// of the file (see the type's docs), [`RenderError::Image`] naming the
    /// file and the image for images that do not decode.
    pub fn load(path: &Path, budget: MemoryBudget) -> Result<Self> {
        let mut ctx = Ctx::new(path, budget);
        let mut notes = Vec::new();
        let doc = Document::load(&mut ctx, &mut notes)?;
        let n_materials = doc.root.materials.len();
        let normal_uv = |m: usize| material::normal_uv(&doc, m);
        let (parts, raw_camera) =
            geometry::gather(&mut ctx, &doc, &mut notes, n_materials, &normal_uv)?;
        let mut used = vec![false; n_materials + 1];
        for &m in parts.materials.iter().flatten() {
            if let Some(u) = used.get_mut(m as usize) {
                *u = true;
            }
        }
        let (materials, textures) = material::load(&mut ctx, &doc, &used, &mut notes)?;
        let scene = doc.root.scene.map_or(0, |s| s.value());
        let mesh = Mesh::from_parts(parts).map_err(|e| match e {
            RenderError::Parameter { reason, .. } => ctx.err(format!("scene {scene}"), reason),
            other => other,
        })?;
        let (c, r) = mesh.placement();
        let camera = raw_camera.map(|k| {
            let eye = (k.eye - c) / r;
            GltfCamera {
                eye,
                target: eye + k.forward,
                up: k.up,
                fov_deg: k.yfov,
                aspect: k.aspect,
            }
        });
        let roughness = roughness_range(&materials, &textures, &used);
        Ok(Self {
            mesh: Arc::new(mesh),
            materials,
            textures,
            camera,
            notes,
            roughness,
        })
    }

    /// The default scene's triangles (z up, in the unit bounding sphere),
    /// with per-triangle material indices.
    #[must_use]
    pub fn mesh(&self) -> &Arc<Mesh> {
        &self.mesh
    }

    /// The default scene's first perspective camera node (depth first from
    /// the scene's roots), moved as the mesh is.
    #[must_use]
    pub fn camera(&self) -> Option<GltfCamera> {
        self.camera
    }

    /// What was skipped or ignored, one sentence each (points and lines
    /// primitives, unsupported optional extensions, ...).
    #[must_use]
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The smallest and largest perceptual roughness the mesh's materials
    /// can take: factor × the metallic-roughness texture's G over its texels
    /// (bilinear lookups stay within them), in `[GLTF_MIN_ROUGHNESS, 1]`.
    #[must_use]
    pub fn roughness_range(&self) -> (f64, f64) {
        self.roughness
    }

    /// The glTF material values at a hit of [`Self::mesh`]: `hit.material`
    /// selects the material (the default one when `None`), textures are
    /// sampled at `hit.uv` or `hit.uv1` as each texture's `texCoord` says.
    #[must_use]
    pub fn point(&self, hit: &Hit) -> GltfPoint {
        let default = Mat::default();
        let m = hit
            .material
            .and_then(|i| self.materials.get(i as usize))
            .or(self.materials.last())
            .unwrap_or(&default);
        let uv_of = |t: TexRef| match t.set {
            0 => hit.uv,
            1 => hit.uv1,
            _ => None,
        };
        let sample = |t: Option<TexRef>, c: usize| -> Option<f64> {
            let t = t?;
            Some(self.textures.get(t.tex)?.sample(uv_of(t)?, c))
        };
        let unit = |v: f64| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
        let base = [0, 1, 2].map(|c| {
            unit(m.base[c] * sample(m.base_tex, c).unwrap_or(1.0) * hit.color.map_or(1.0, |k| k[c]))
        });
        let metallic = unit(m.metallic * sample(m.mr_tex, 2).unwrap_or(1.0));
        let roughness = unit(m.roughness * sample(m.mr_tex, 1).unwrap_or(1.0));
        let material =
            GltfMaterial::new(base, metallic, roughness).unwrap_or_else(|_| GltfMaterial {
                base,
                metallic,
                roughness: roughness.max(GLTF_MIN_ROUGHNESS),
            });
        let n = hit.n;
        let frame = hit.tangent.and_then(|t| {
            let t3 = t.truncate();
            (t3 - n.dot(t3) * n).try_normalize().map(|x| (x, t.w))
        });
        let mut normal = n;
        if let (Some(tex), Some((t, w))) = (m.normal_tex, frame)
            && let (Some(uv), Some(img)) = (uv_of(tex), self.textures.get(tex.tex))
        {
            let v = [0, 1, 2].map(|c| 2.0 * img.sample(uv, c) - 1.0);
            let b = w * n.cross(t);
            let s = m.normal_scale;
            if let Some(p) = (s * v[0] * t + s * v[1] * b + v[2] * n).try_normalize() {
                normal = p;
            }
        }
        let tangent = frame
            .map(|(t, _)| t)
            .into_iter()
            .chain(std::iter::once(hit.dpdu))
            .find_map(|t| (t - normal.dot(t) * normal).try_normalize())
            .unwrap_or_else(|| normal.any_orthonormal_vector());
        let occlusion = match sample(m.occlusion_tex, 0) {
            Some(r) => 1.0 + m.occlusion_strength * (r - 1.0),
            None => 1.0,
        };
        let emissive = [0, 1, 2].map(|c| m.emissive[c] * sample(m.emissive_tex, c).unwrap_or(1.0));
        GltfPoint {
            material,
            normal,
            tangent,
            occlusion,
            emissive,
            double_sided: m.double_sided,
        }
    }
}

/// Smallest and largest roughness over the used materials' factors times
/// their metallic-roughness textures' G texels.
fn roughness_range(materials: &[Mat], textures: &[Tex], used: &[bool]) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (m, _) in materials.iter().zip(used).filter(|(_, u)| **u) {
        let (a, b) = m
            .mr_tex
            .and_then(|t| textures.get(t.tex))
            .map_or((1.0, 1.0), |t| t.range(1));
        for v in [m.roughness * a, m.roughness * b] {
            let v = if v.is_nan() { 1.0 } else { v };
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if lo > hi {
        return (1.0, 1.0);
    }
    let fix = |v: f64| v.clamp(GLTF_MIN_ROUGHNESS, 1.0);
    (fix(lo), fix(hi))
}
