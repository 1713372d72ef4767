//! The record of a ray hitting a surface, shared by the analytic shapes
//! ([`crate::scene`]) and triangle meshes ([`crate::mesh`]).

use glam::{DVec3, DVec4};

/// What a ray hits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray.
    pub t: f64,
    /// The point.
    pub p: DVec3,
    /// The unit outward normal.
    pub n: DVec3,
    /// `dP/du` of the surface's parameterisation (the tangent anisotropic
    /// BRDFs align `ax` with); may be zero at a singular point.
    pub dpdu: DVec3,
    /// Texture coordinates `(u, v)` in `[0, 1]` (`v = 0` at the top of an
    /// image), `None` for meshes without them.
    pub uv: Option<[f64; 2]>,
    /// The hit triangle's material index (glTF meshes), `None` for the
    /// analytic shapes and OBJ meshes.
    pub material: Option<u32>,
    /// The interpolated vertex tangent, unit `xyz` and the handedness `w =
    /// +-1` (the bitangent is `w n x xyz`), for normal maps; `None` where the
    /// mesh has none. Negated, `w` included, with the normal where the ray
    /// sees a triangle's back.
    pub tangent: Option<DVec4>,
    /// The second set of texture coordinates (glTF `TEXCOORD_1`, as given).
    pub uv1: Option<[f64; 2]>,
    /// The interpolated vertex colour (glTF `COLOR_0`, linear RGB).
    pub color: Option<[f64; 3]>,
}
