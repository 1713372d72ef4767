//! Scenes: analytic ones ray cast exactly (a unit sphere, a torus and a
//! ground square, all centred at the origin, `z` up) and triangle meshes from
//! OBJ files ([`crate::mesh`]).

use glam::DVec3;

use crate::error::{RenderError, Result};

use crate::hit::Hit;

/// A scene. Texture coordinates: the sphere's are equirectangular (`u =
/// phi / 2 pi`, `v = theta / pi`), the torus' `u` around `z` and `v` around
/// the tube, the plane's `u = (x + 2) / 4`, `v = (2 - y) / 4`, a mesh's from
/// its file.
#[derive(Clone, Debug)]
pub enum Scene {
    /// The unit sphere; `u = phi / 2 pi` (azimuth), so `dP/du` is along `(-y, x, 0)`.
    Sphere,
    /// The torus of radii 1 (ring) and 0.4 (tube) around `z`; `u` the angle
    /// around `z`.
    Torus,
    /// The square `[-2, 2]^2` of the plane `z = 0`, facing `+z`; `u = x`.
    Plane,
    /// A triangle mesh.
    Mesh(std::sync::Arc<crate::mesh::Mesh>),
    /// A glTF 2.0 asset: its triangles, with their metallic-roughness
    /// materials evaluated at every hit ([`crate::GltfAsset::point`]).
    Gltf(std::sync::Arc<crate::gltf::GltfAsset>),
}

/// Torus radii.
const RING: f64 = 1.0;
const TUBE: f64 = 0.4;

impl Scene {
    /// A short name for messages: `sphere`, `torus`, `plane`, `mesh of N
    /// triangles`, `glTF asset of N triangles` (the derived `Debug` prints
    /// every vertex).
    #[must_use]
    pub fn describe(&self) -> String {
        match self {
            Self::Sphere => "sphere".into(),
            Self::Torus => "torus".into(),
            Self::Plane => "plane".into(),
            Self::Mesh(m) => format!("mesh of {} triangles", m.triangles()),
            Self::Gltf(a) => format!("glTF asset of {} triangles", a.mesh().triangles()),
        }
    }

    /// `sphere`, `torus`, `plane`, an `.obj` file (`obj_z_up`: the file is
    /// z-up already; OBJ files are y-up by convention) or a `.gltf`/`.glb`
    /// asset (read with the machine's default memory budget;
    /// [`Self::parse_with`] takes one).
    ///
    /// # Errors
    /// [`RenderError::Parameter`] for other names and bad OBJ files,
    /// [`RenderError::Asset`] for bad glTF files.
    pub fn parse(name: &str, obj_z_up: bool) -> Result<Self> {
        Self::parse_with(
            name,
            obj_z_up,
            ifd_image::MemoryBudget::default_for_machine(),
        )
    }

    /// [`Self::parse`] with the memory budget glTF files are read under.
    ///
    /// # Errors
    /// As [`Self::parse`].
    pub fn parse_with(name: &str, obj_z_up: bool, budget: ifd_image::MemoryBudget) -> Result<Self> {
        let ext = std::path::Path::new(name)
            .extension()
            .map(|e| e.to_string_lossy().to_lowercase());
        if matches!(ext.as_deref(), Some("gltf" | "glb")) {
            return Ok(Self::Gltf(std::sync::Arc::new(
                crate::gltf::GltfAsset::load(std::path::Path::new(name), budget)?,
            )));
        }
        match name {
            "sphere" => Ok(Self::Sphere),
            "torus" => Ok(Self::Torus),
            "plane" => Ok(Self::Plane),
            _ if name.to_lowercase().ends_with(".obj") => Ok(Self::Mesh(std::sync::Arc::new(
                crate::mesh::Mesh::load(std::path::Path::new(name), obj_z_up)?,
            ))),
            _ => Err(RenderError::Parameter {
                name: "--scene",
                value: name.into(),
                reason: "use sphere, torus, plane, an .obj file or a .gltf/.glb asset".into(),
            }),
        }
    }

    /// Whether the surface has tangents everywhere (anisotropic BRDFs need
    /// them): the analytic scenes do, meshes only with texture coordinates.
    #[must_use]
    pub fn has_tangents(&self) -> bool {
        match self {
            Self::Mesh(m) => m.has_uv(),
            Self::Gltf(a) => a.mesh().has_uv(),
            _ => true,
        }
    }

    /// The first hit of the ray `o + t d` (`d` unit, `t > 1e-9`).
    #[must_use]
    pub fn intersect(&self, o: DVec3, d: DVec3) -> Option<Hit> {
        self.intersect_with(o, d, true)
    }

    /// [`Self::intersect`], leaving the texture coordinates of the sphere
    /// and the torus out (`uv: None`; an `atan2` and an `acos` per hit)
    /// unless `uv`; meshes and the plane give theirs either way.
    #[must_use]
    pub(crate) fn intersect_with(&self, o: DVec3, d: DVec3, uv: bool) -> Option<Hit> {
        match self {
            Self::Sphere => {
                let b = o.dot(d);
                let c = o.length_squared() - 1.0;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let s = disc.sqrt();
                let t = if -b - s > 1e-9 { -b - s } else { -b + s };
                if t <= 1e-9 {
                    return None;
                }
                let p = o + t * d;
                let n = p.normalize();
                Some(Hit {
                    t,
                    p,
                    n,
                    dpdu: DVec3::new(-p.y, p.x, 0.0),
                    // u = phi / 2 pi, v = theta / pi (an equirect texture)
                    uv: uv.then(|| {
                        [
                            p.y.atan2(p.x).rem_euclid(std::f64::consts::TAU)
                                / std::f64::consts::TAU,
                            n.z.clamp(-1.0, 1.0).acos() / std::f64::consts::PI,
                        ]
                    }),
                    material: None,
                    tangent: None,
                    uv1: None,
                    color: None,
                })
            }
            Self::Plane => {
                if d.z.abs() < 1e-15 {
                    return None;
                }
                let t = -o.z / d.z;
                let p = o + t * d;
                if t <= 1e-9 || p.x.abs() > 2.0 || p.y.abs() > 2.0 {
                    return None;
                }
                Some(Hit {
                    t,
                    p: DVec3::new(p.x, p.y, 0.0),
                    n: DVec3::Z,
                    dpdu: DVec3::X,
                    uv: Some([(p.x + 2.0) / 4.0, (2.0 - p.y) / 4.0]),
                    material: None,
                    tangent: None,
                    uv1: None,
                    color: None,
                })
            }
            Self::Torus => torus_hit(o, d, uv),
            Self::Mesh(m) => m.intersect(o, d),
            Self::Gltf(a) => a.mesh().intersect(o, d),
        }
    }
}

/// Signed distance to the torus.
fn torus_sdf(p: DVec3) -> f64 {
    let q = (p.x * p.x + p.y * p.y).sqrt() - RING;
    (q * q + p.z * p.z).sqrt() - TUBE
}

/// Sphere tracing to the torus surface, then bisection to 1e-12.
fn torus_hit(o: DVec3, d: DVec3, uv: bool) -> Option<Hit> {
    // the bounding sphere of radius RING + TUBE
    let b = o.dot(d);
    let c = o.length_squared() - (RING + TUBE) * (RING + TUBE);
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let t_far = -b + disc.sqrt();
    let mut t = (-b - disc.sqrt()).max(0.0);
    let mut prev = t;
    for _ in 0..4096 {
        if t > t_far {
            return None;
        }
        let dist = torus_sdf(o + t * d);
        if dist < 1e-10 * t.max(1.0) {
            // bracket [prev, t] contains the crossing: bisect
            let (mut lo, mut hi) = (prev, t);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if torus_sdf(o + mid * d) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let t = hi;
            let p = o + t * d;
            let rxy = (p.x * p.x + p.y * p.y).sqrt();
            let centre = DVec3::new(p.x / rxy * RING, p.y / rxy * RING, 0.0);
            let n = (p - centre).normalize();
            // u around z, v around the tube (from the outer equator, upwards)
            let uv = uv.then(|| {
                let tube = p.z.atan2(rxy - RING).rem_euclid(std::f64::consts::TAU);
                [
                    p.y.atan2(p.x).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU,
                    tube / std::f64::consts::TAU,
                ]
            });
            return Some(Hit {
                t,
                p,
                n,
                dpdu: DVec3::new(-p.y, p.x, 0.0),
                uv,
                material: None,
                tangent: None,
                uv1: None,
                color: None,
            });
        }
        prev = t;
        t += dist.max(1e-9);
    }
    None
}
