//! A pinhole camera: world `z` up, as the SH code and the equirectangular
//! convention.

use glam::DVec3;

use crate::error::{RenderError, Result};

/// A pinhole camera looking from `eye` at `target`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    eye: DVec3,
    /// Right, up and forward unit vectors.
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    /// The image plane's half extents at unit distance, `tan(fov / 2)
    /// aspect` across and `tan(fov / 2)` (vertical) down.
    half: [f64; 2],
    /// Its extent per pixel: `2 half / (W, H)`.
    step: [f64; 2],
    width: usize,
    height: usize,
}

impl Camera {
    /// A camera of vertical field of view `fov_deg` for a `width x height` image.
    ///
    /// ```
    /// use glam::DVec3;
    /// use ifd_render::Camera;
    /// let c = Camera::new(DVec3::new(0.0, -4.0, 0.0), DVec3::ZERO, DVec3::Z, 40.0, 64, 64)?;
    /// let (o, d) = c.ray(32.0, 32.0); // the image centre looks at the target
    /// assert!((d - DVec3::Y).length() < 1e-12 && o == DVec3::new(0.0, -4.0, 0.0));
    /// # Ok::<(), ifd_render::RenderError>(())
    /// ```
    ///
    /// # Errors
    /// [`RenderError::Parameter`] for non-finite vectors, `eye == target`, an
    /// `up` parallel to the view, a field of view outside `(0, 180)` degrees or
    /// an empty image.
    pub fn new(
        eye: DVec3,
        target: DVec3,
        up: DVec3,
        fov_deg: f64,
        width: usize,
        height: usize,
    ) -> Result<Self> {
        let bad = |name: &'static str, value: String, reason: &str| RenderError::Parameter {
            name,
            value,
            reason: reason.into(),
        };
        if !(eye.is_finite() && target.is_finite() && up.is_finite()) {
            return Err(bad(
                "camera",
                format!("eye {eye}, target {target}, up {up}"),
                "not finite",
            ));
        }
        // scene coordinates are of order 1; far beyond, squares overflow
        for (name, p) in [("--eye", eye), ("--target", target), ("--up", up)] {
            if p.abs().max_element() > 1e15 {
                return Err(bad(
                    name,
                    format!("{p}"),
                    "is too large (components up to 1e15)",
                ));
            }
        }
        let f = target - eye;
        if f.length() < 1e-12 {
            return Err(bad("--eye", format!("{eye}"), "equals --target"));
        }
        let forward = f.normalize();
        let r = forward.cross(up);
        if r.length() < 1e-9 * up.length().max(1e-300) || up.length() == 0.0 {
            return Err(bad(
                "--up",
                format!("{up}"),
                "is zero or parallel to the viewing direction",
            ));
        }
        if !(fov_deg > 0.0 && fov_deg < 180.0) {
            return Err(bad(
                "--fov",
                format!("{fov_deg}"),
                "use 0 < fov < 180 degrees",
            ));
        }
        if width == 0 || height == 0 {
            return Err(bad("--size", format!("{width}x{height}"), "empty image"));
        }
        let right = r.normalize();
        let tan_half = (fov_deg.to_radians() * 0.5).tan();
        let aspect = width as f64 / height as f64;
        Ok(Self {
            eye,
            right,
            up: right.cross(forward),
            forward,
            half: [tan_half * aspect, tan_half],
            step: [
                2.0 * tan_half * aspect / width as f64,
                2.0 * tan_half / height as f64,
            ],
            width,
            height,
        })
    }

    /// The eye position.
    #[must_use]
    pub fn eye(&self) -> DVec3 {
        self.eye
    }

    /// Image width.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Image height.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// The ray through image point `(x, y)` (pixel units, `(0, 0)` the top-left
    /// corner; a pixel's centre is `(i + 0.5, j + 0.5)`): origin and unit
    /// direction.
    #[must_use]
    pub fn ray(&self, x: f64, y: f64) -> (DVec3, DVec3) {
        // (2 x / W - 1) tan(fov / 2) aspect and (1 - 2 y / H) tan(fov / 2),
        // without a division per ray
        let sx = x * self.step[0] - self.half[0];
        let sy = self.half[1] - y * self.step[1];
        let d = (self.forward + sx * self.right + sy * self.up).normalize();
        (self.eye, d)
    }
}
