//! A CPU renderer for objects lit by an environment map, the testbed of ISD
//! shading (ISD Sec. 6.1, Eq. 20-22): analytic scenes ray cast through a
//! pinhole camera (world `z` up), shaded per pixel centre by ISD, by its SH
//! reference, by Monte Carlo, or by an exact texel quadrature of the same (downsampled,
//! piecewise-constant) environment. Unshadowed unless the job carries
//! [`visibility::Shadows`] (self-shadowing of a mesh, Eq. 25); no
//! interreflection. Mirrors, anti-aliased by ISD's filter (Eq. 26-29), are
//! [`mirror`]'s.
//!
//! ```
//! use glam::DVec3;
//! use ifd_render::{camera::Camera, envmap::EnvMap, render::{Job, Method, render}, scene::Scene};
//! use ifd_shade::{Brdf, shade::Material};
//! let env = EnvMap::new(ifd_image::Image::from_vec(8, 4, 1, vec![1.0; 32])?, 0.0)?;
//! let brdf = Brdf::parse("lambert")?;
//! let material = Material::new(&brdf, 4, None)?;
//! let camera = Camera::new(DVec3::new(0.0, -4.0, 0.0), DVec3::ZERO, DVec3::Z, 40.0, 16, 16)?;
//! let job = Job { scene: Scene::Sphere, camera, env: &env, background: None, brdf: &brdf,
//!                 material: Some(&material), method: Method::Isd, spp: 0, seed: 0, maps: None, family: None, lights: &[], shadows: None };
//! let r = render(&job, &|_, _| {})?;
//! // the white furnace: a white Lambertian sphere in a uniform unit light is 1
//! let centre = r.image.get(8, 8, 0);
//! assert!((centre - 1.0).abs() < 1e-6, "{centre}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Modules
//! - [`camera`]: the pinhole camera.
//! - [`scene`]: sphere, torus, plane, meshes.
//! - [`mesh`]: OBJ meshes and their BVH.
//! - [`gbuffer`]: what each pixel's ray sees (frame, view, map values), for the CPU and GPU shaders.
//! - [`envmap`]: environment maps (rotation, downsampling, lookups, exact SH, texel samples).
//! - [`oracle`]: the exact texel quadrature.
//! - [`mirror`]: anti-aliased mirror reflections off a scene, bumpy through a normal map (Eq. 26-29).
//! - [`mc`]: the Monte Carlo reference (environment and BRDF sampling, MIS).
//! - [`render`]: the render loop and error measures.
//! - [`textures`]: albedo, roughness and normal maps (spatially varying BRDFs).
//! - [`tonemap`]: exposure, tone curves, sRGB.
//! - [`visibility`]: self-shadowed shading on meshes (Eq. 25, Appendix A).

mod error;

pub mod camera;
pub mod envmap;
pub mod gbuffer;
pub mod hit;
pub mod mc;
pub mod mesh;
pub mod mirror;
pub mod oracle;
pub mod render;
pub mod scene;
pub mod textures;
pub mod tonemap;
pub mod visibility;

pub use crate::error::{RenderError, Result};
