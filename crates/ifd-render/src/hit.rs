//! The record of a ray hitting a surface, shared by the analytic shapes
//! ([`crate::scene`]) and triangle meshes ([`crate::mesh`]).

use glam::DVec3;

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
}
