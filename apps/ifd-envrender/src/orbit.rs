//! The orbit camera: a point looked at, a distance and two angles, with
//! `z` up (the renderer's convention).

use glam::DVec3;
use ifd_render::Camera;
use serde::{Deserialize, Serialize};

/// An orbit around `target`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Orbit {
    /// The point looked at.
    pub target: [f64; 3],
    /// Distance from the target.
    pub distance: f64,
    /// Azimuth of the eye about `+z`, radians.
    pub yaw: f64,
    /// Elevation of the eye, radians (kept inside `(-pi/2, pi/2)`).
    pub pitch: f64,
    /// Vertical field of view, degrees.
    pub fov: f64,
}

impl Default for Orbit {
    /// `ifd render`'s default view: eye `(3, -2.5, 1.2)`, target the origin, 40 degrees.
    fn default() -> Self {
        Self::looking(DVec3::new(3.0, -2.5, 1.2), DVec3::ZERO, 40.0)
    }
}

impl Orbit {
    /// The orbit whose eye is `eye`.
    #[must_use]
    pub fn looking(eye: DVec3, target: DVec3, fov: f64) -> Self {
        let d = eye - target;
        let distance = d.length().max(1e-6);
        Self {
            target: target.to_array(),
            distance,
            yaw: d.y.atan2(d.x),
            pitch: (d.z / distance).clamp(-1.0, 1.0).asin(),
            fov,
        }
    }

    /// The eye position.
    #[must_use]
    pub fn eye(&self) -> DVec3 {
        let (cp, sp) = (self.pitch.cos(), self.pitch.sin());
        DVec3::from_array(self.target)
            + self.distance * DVec3::new(cp * self.yaw.cos(), cp * self.yaw.sin(), sp)
    }

    /// Turns the orbit by a drag of `(dx, dy)` pixels.
    pub fn drag(&mut self, dx: f64, dy: f64) {
        self.yaw -= dx * 0.01;
        self.pitch = (self.pitch + dy * 0.01).clamp(-1.5, 1.5);
    }

    /// Zooms by a wheel of `scroll` points (positive: closer).
    pub fn zoom(&mut self, scroll: f64) {
        self.distance = (self.distance * (-scroll * 0.002).exp()).clamp(0.05, 1e4);
    }

    /// Frames a bounding sphere of `radius` about the origin.
    pub fn frame(&mut self, radius: f64) {
        self.target = [0.0; 3];
        let half = (self.fov.to_radians() * 0.5).sin().max(1e-3);
        self.distance = 1.1 * radius / half;
    }

    /// The camera for a `width x height` image.
    ///
    /// # Errors
    /// As [`Camera::new`] (an empty image, a field of view out of range).
    pub fn camera(&self, width: usize, height: usize) -> ifd_render::Result<Camera> {
        Camera::new(
            self.eye(),
            DVec3::from_array(self.target),
            DVec3::Z,
            self.fov,
            width,
            height,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn looking_round_trips_the_eye() {
        let o = Orbit::looking(DVec3::new(3.0, -2.5, 1.2), DVec3::new(0.1, 0.0, 0.2), 40.0);
        assert!((o.eye() - DVec3::new(3.0, -2.5, 1.2)).length() < 1e-12);
        let mut f = o;
        f.frame(1.0);
        // the framed sphere fits the vertical field of view
        assert!(f.distance * (20f64.to_radians()).sin() > 1.0);
    }
}
