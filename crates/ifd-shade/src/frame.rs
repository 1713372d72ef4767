//! The orthonormal frame at a surface point: [`Frame`].

use glam::DVec3;
use ifd_sphere::Rotation;

/// A right-handed orthonormal frame at a surface point, in world coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Tangent (the local `+x`, direction of `ax`).
    pub t: [f64; 3],
    /// Bitangent `n x t` (the local `+y`).
    pub b: [f64; 3],
    /// Normal (the local `+z`).
    pub n: [f64; 3],
}

impl Frame {
    /// The frame of a unit normal and a tangent hint (made orthogonal to the
    /// normal; any perpendicular direction when the hint is parallel to it).
    #[must_use]
    pub fn new(n: [f64; 3], tangent_hint: [f64; 3]) -> Self {
        let (nv, hint) = (DVec3::from(n), DVec3::from(tangent_hint));
        let mut t = hint - hint.dot(nv) * nv;
        let mut len = t.length();
        if len.is_nan() || len <= 1e-12 {
            // any perpendicular: cross with the axis least aligned with n
            let a = if n[0].abs() < 0.6 { DVec3::X } else { DVec3::Y };
            t = nv.cross(a).cross(nv);
            len = t.length();
        }
        let t = t * len.recip();
        Self {
            t: t.to_array(),
            b: nv.cross(t).to_array(),
            n,
        }
    }

    /// World to local: `(t . w, b . w, n . w)`.
    #[must_use]
    pub fn to_local(&self, w: [f64; 3]) -> [f64; 3] {
        let w = DVec3::from(w);
        [
            DVec3::from(self.t).dot(w),
            DVec3::from(self.b).dot(w),
            DVec3::from(self.n).dot(w),
        ]
    }

    /// The rotation local to world (columns `t, b, n`).
    #[must_use]
    pub fn rotation(&self) -> Rotation {
        Rotation {
            m: [
                [self.t[0], self.b[0], self.n[0]],
                [self.t[1], self.b[1], self.n[1]],
                [self.t[2], self.b[2], self.n[2]],
            ],
        }
    }
}
