//! A CPU renderer for objects lit by an environment map, the testbed of ISD
//! shading (ISD Sec. 6.1, Eq. 20-22): analytic scenes ray cast through a
//! pinhole camera (world `z` up), shaded per pixel centre by ISD, by its SH
//! reference, by Monte Carlo, or by an exact texel quadrature of the same (downsampled,
//! piecewise-constant) environment. Unshadowed unless the job carries
//! [`Shadows`] (self-shadowing of a mesh, Eq. 25); no
//! interreflection. Mirrors, anti-aliased by ISD's filter (Eq. 26-29), are
//! [`render_mirror`]'s.
//!
//! ```
//! use glam::DVec3;
//! use ifd_render::{Camera, EnvMap, Job, Method, Scene, render};
//! use ifd_shade::{Brdf, Material};
//! let env = EnvMap::new(ifd_image::Image::from_vec(8, 4, 1, vec![1.0; 32])?, 0.0)?;
//! let brdf = Brdf::parse("lambert")?;
//! let material = Material::new(&brdf, 4, None)?;
//! let camera = Camera::new(DVec3::new(0.0, -4.0, 0.0), DVec3::ZERO, DVec3::Z, 40.0, 16, 16)?;
//! let job = Job::new(Scene::Sphere, camera, &env, &brdf, Some(&material), Method::Isd);
//! let r = render(&job, &|_, _| {})?;
//! // the white furnace: a white Lambertian sphere in a uniform unit light is 1
//! let centre = r.image.get(8, 8, 0);
//! assert!((centre - 1.0).abs() < 1e-6, "{centre}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # The API
//! The modules are private; the API is re-exported here, by task:
//! - **the scene**: [`Scene`] (sphere, torus, plane, OBJ [`Mesh`]es, their
//!   [`Hit`]s), [`Camera`] (pinhole, `z` up), [`EnvMap`] (equirect maps read
//!   as piecewise constant: rotation, downsampling, lookups, exact SH);
//!   surface maps ([`SurfaceMaps`], [`Texture`], [`perturb_normal`],
//!   [`RoughnessFamily`], [`alpha_of`]);
//! - **glTF 2.0 assets**: [`GltfAsset`] (`.gltf`/`.glb`: the default
//!   scene's triangles as a [`Mesh`], its metallic-roughness materials and
//!   textures evaluated at a [`Hit`] as a [`GltfPoint`], its [`GltfCamera`]);
//! - **rendering**: [`render`] a [`Job`] by a [`Method`] into a [`Rendered`]
//!   image, compared with a reference by [`relative_rms`] and
//!   [`Difference`] (the per-pixel relative difference error maps show);
//!   the degree a stated accuracy needs ([`degree_for`] a [`TolMaterial`]:
//!   a [`DegreeChoice`] or why it is [`Unreachable`], the measured rule of
//!   `ifd render --tol`);
//!   what each pixel's ray sees
//!   ([`pixel`], [`pixels`], [`Pixel`], [`Surface`]: the G-buffer the GPU path
//!   shades too); the references: the exact texel quadrature ([`Oracle`],
//!   [`ORACLE_TOLERANCE`], [`ORACLE_MAX_K`]) and Monte Carlo ([`EnvSampler`],
//!   [`estimate_mc`], [`pixel_seed`]);
//! - **self-shadowing** (Eq. 25, Appendix A): [`Shadows`], built from
//!   [`VertexVisibility`] and the lighting's [`ProductMatrix`]
//!   ([`shade_visible`]), with its ray-traced reference
//!   ([`shadowed_reference`], [`texel_nodes`], [`TexelNode`]); [`torus_mesh`];
//! - **mirrors** (Eq. 26-29): [`render_mirror`] a [`MirrorScene`] of any
//!   [`Reflector`] ([`SceneMirror`]: a scene's surface, bumpy through a
//!   normal map) by an [`AaMethod`] ([`IsdFilter`] with its [`EnvPyramid`]
//!   fallback, supersampling), over a [`PixelFilter`], into an [`AaImage`];
//! - **the engines' approximation**: [`SplitSum`] (the prefiltered chain,
//!   irradiance and DFG table of the split sum, baked in memory by
//!   `ifd-ibl`) in its [`SplitSumVariant`]s, the methods
//!   [`Method::SplitSum`] and [`Method::SplitSumSampleRenderer`];
//! - **display**: [`Tonemap`] (exposure, tone curves, sRGB).

mod camera;
mod difference;
mod envmap;
mod equirect_grid;
mod error;
mod gbuffer;
mod gltf;
mod hit;
mod job;
mod mc;
mod mesh;
mod mirror;
mod oracle;
mod render;
mod scene;
mod split_sum;
mod textures;
mod tolerance;
mod tonemap;
mod visibility;

pub use crate::camera::Camera;
pub use crate::difference::{Difference, FULL_SCALE_PERCENTILE, RELATIVE_FLOOR, relative_rms};
pub use crate::envmap::EnvMap;
pub use crate::error::{RenderError, Result};
pub use crate::gbuffer::{Pixel, Surface, pixel, pixels};
pub use crate::gltf::{GltfAsset, GltfCamera, GltfPoint};
pub use crate::hit::Hit;
pub use crate::job::{Job, Method, Rendered};
pub use crate::mc::{EnvSampler, estimate as estimate_mc, pixel_seed};
pub use crate::mesh::Mesh;
pub use crate::mirror::{
    AaImage, AaMethod, EnvPyramid, IsdFilter, MirrorScene, PixelFilter, Reflector, SceneMirror,
    render as render_mirror,
};
pub use crate::oracle::{MAX_K as ORACLE_MAX_K, Oracle, TOLERANCE as ORACLE_TOLERANCE};
pub use crate::render::render;
pub use crate::scene::Scene;
pub use crate::split_sum::{SplitSum, SplitSumVariant};
pub use crate::textures::{RoughnessFamily, SurfaceMaps, Texture, alpha_of, perturb_normal};
pub use crate::tolerance::{
    DegreeChoice, GRAZING_COS, MARGIN as TOL_MARGIN, TolMaterial, Unreachable, degree_for,
    degree_for_range, degree_for_render,
};
pub use crate::tonemap::Tonemap;
pub use crate::visibility::{
    ProductMatrix, Shadows, TexelNode, VertexVisibility, reference as shadowed_reference,
    shade_visible, texel_nodes, torus_mesh,
};
