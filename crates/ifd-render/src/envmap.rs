//! Environment maps for rendering: an equirectangular map read as piecewise
//! constant over its texels, rotated about `z`, downsampled by solid-angle
//! averaging, looked up by direction and projected on SH exactly
//! ([`ifd_sphere::analyze_equirect_box`]).

use std::f64::consts::PI;

use ifd_image::Image;
use ifd_sphere::{Negatives, analyze_equirect_box};
use ifd_sphere::{Rotation, ShCoeffs, ShRotation};

use crate::equirect_grid::{EquirectGrid, atan2_approx};
use crate::error::{RenderError, Result};

/// An equirectangular environment (`W = 2H`, row 0 at the zenith), rotated by
/// `rotation` radians about `+z`: `E'(w) = E(Rz(-a) w)`.
#[derive(Clone, Debug)]
pub struct EnvMap {
    img: Image,
    rotation: f64,
    /// Exact SH coefficients when the environment was given as SH.
    sh: Option<ShCoeffs>,
    /// The texel edges, for direction lookups.
    grid: EquirectGrid,
}

impl EnvMap {
    /// Wraps an equirectangular image (1 or 3 channels; a fourth, alpha,
    /// is dropped) rotated by `rotation_deg` about `+z`.
    ///
    /// # Errors
    /// [`RenderError::Parameter`] when the map is not 2:1, has 2 or more than
    /// 4 channels, or holds NaN/infinite or negative values, or the rotation
    /// is not finite.
    pub fn new(img: Image, rotation_deg: f64) -> Result<Self> {
        let (w, h, ch) = (img.width(), img.height(), img.channels());
        let bad = |reason: String| RenderError::Parameter {
            name: "--env",
            value: format!("{w}x{h}x{ch}"),
            reason,
        };
        if h < 2 || w != 2 * h {
            return Err(bad(
                "an environment must be a 2:1 equirectangular map (W = 2H, H >= 2)".into(),
            ));
        }
        if !rotation_deg.is_finite() {
            return Err(RenderError::Parameter {
                name: "--env-rotate",
                value: rotation_deg.to_string(),
                reason: "not finite".into(),
            });
        }
        let img = match ch {
            1 | 3 => img,
            4 => {
                let data: Vec<f32> = img
                    .data()
                    .chunks_exact(4)
                    .flat_map(|p| [p[0], p[1], p[2]])
                    .collect();
                Image::from_vec(w, h, 3, data)?
            }
            _ => return Err(bad("1, 3 or 4 (RGBA) channels expected".into())),
        };
        if let Some(i) = img.data().iter().position(|v| !v.is_finite() || *v < 0.0) {
            return Err(bad(format!(
                "sample {i} is {} (radiance must be finite and non-negative)",
                img.data()[i]
            )));
        }
        let rotation = rotation_deg.to_radians();
        Ok(Self {
            grid: EquirectGrid::new(w, h, rotation),
            img,
            rotation,
            sh: None,
        })
    }

    /// An environment given by SH coefficients (the `sh.npy` of
    /// `ifd envmap prefilter` or `ifd sphere sh`, 1 or 3 channels): [`Self::sh`]
    /// returns the coefficients themselves (up to their degree), and the map
    /// that the oracle, Monte Carlo and the background read is their
    /// synthesis on a `width x height` grid with negative values (ringing of
    /// the truncated expansion) set to 0; returns the environment and how
    /// many samples were clamped.
    ///
    /// # Errors
    /// [`RenderError::Parameter`] for other channel counts, a grid that is not
    /// 2:1 or a rotation that is not finite.
    pub fn from_sh(
        coeffs: ShCoeffs,
        width: usize,
        height: usize,
        rotation_deg: f64,
    ) -> Result<(Self, usize)> {
        let ch = coeffs.channels();
        if ch != 1 && ch != 3 {
            return Err(RenderError::Parameter {
                name: "--env",
                value: format!("{ch} channels"),
                reason: "SH coefficients need 1 or 3 columns".into(),
            });
        }
        if height < 2 || width != 2 * height {
            return Err(RenderError::Parameter {
                name: "--env-size",
                value: format!("{width}x{height}"),
                reason: "must be 2:1 (W = 2H, H >= 2)".into(),
            });
        }
        let mut img = ifd_sphere::EquirectTransform::new(coeffs.l_max(), width, height)?
            .synthesize(&coeffs)?;
        let mut clamped = 0;
        for v in img.data_mut() {
            if *v < 0.0 {
                *v = 0.0;
                clamped += 1;
            }
        }
        let mut env = Self::new(img, rotation_deg)?;
        env.sh = Some(coeffs);
        Ok((env, clamped))
    }

    /// The image.
    #[must_use]
    pub fn image(&self) -> &Image {
        &self.img
    }

    /// The rotation about `+z`, radians.
    #[must_use]
    pub fn rotation(&self) -> f64 {
        self.rotation
    }

    /// Channels (1 or 3).
    #[must_use]
    pub fn channels(&self) -> usize {
        self.img.channels()
    }

    /// The map averaged down to `width x height` (a divisor of the size, 2:1):
    /// each new texel is the solid-angle-weighted mean of the texels it
    /// covers, so the piecewise-constant function keeps its integral over
    /// every new texel.
    ///
    /// # Errors
    /// [`RenderError::Parameter`] for sizes that are not 2:1 or do not divide
    /// the map's.
    pub fn downsampled(&self, width: usize, height: usize) -> Result<Self> {
        let (w, h) = (self.img.width(), self.img.height());
        if width == w && height == h {
            return Ok(self.clone());
        }
        if height < 2 || width != 2 * height || w % width != 0 || h % height != 0 {
            return Err(RenderError::Parameter {
                name: "--env-size",
                value: format!("{width}x{height}"),
                reason: format!("must be 2:1 and divide the map's size {w}x{h}"),
            });
        }
        Ok(Self {
            img: ifd_sphere::downsample_equirect(&self.img, width, height)?,
            rotation: self.rotation,
            sh: self.sh.clone(),
            grid: EquirectGrid::new(width, height, self.rotation),
        })
    }

    /// The index `v W + u` of the texel seen in direction `d` (unit), after
    /// the rotation: the texel whose polar angles `[v pi / H, (v + 1) pi /
    /// H)` and azimuths `[a + 2 pi u / W, a + 2 pi (u + 1) / W)` hold `d`
    /// (found by comparisons with the texel edges, no inverse trigonometry
    /// per call; the derivation is in `equirect_grid.rs`).
    #[must_use]
    pub fn texel(&self, d: [f64; 3]) -> usize {
        self.grid.texel(d)
    }

    /// Texel `t`'s value (`t` from [`Self::texel`]; panics beyond the map).
    pub(crate) fn texel_value(&self, t: usize, out: &mut [f64]) {
        let ch = self.img.channels();
        for (o, x) in out.iter_mut().zip(&self.img.data()[t * ch..(t + 1) * ch]) {
            *o = f64::from(*x);
        }
    }

    /// The texel value seen in direction `d` (unit), nearest texel.
    pub fn lookup(&self, d: [f64; 3], out: &mut [f64]) {
        self.texel_value(self.texel(d), out);
    }

    /// The map seen in direction `d` (unit), bilinear between texel centres
    /// (wrapping in azimuth, clamped at the poles' rows): the lookup of a
    /// mirror reflection.
    pub fn lookup_bilinear(&self, d: [f64; 3], out: &mut [f64]) {
        self.bilinear_at(d[2].clamp(-1.0, 1.0).acos(), d[1].atan2(d[0]), out);
    }

    /// The background seen in direction `d` (unit): the map bilinear between
    /// texel centres, as [`Self::lookup_bilinear`], with the angles from the
    /// texel search's polynomial `atan2` (within `1e-7` rad: no `acos` or
    /// `atan2` per pixel). A view magnifies the map (a 1024-texel-wide map is
    /// 0.35 degrees a texel, several pixels of a 40-degree view), and the
    /// nearest texel showed its squares; the CPU renderer's background and
    /// the GPU path's G-buffer both read this.
    pub fn background(&self, d: [f64; 3], out: &mut [f64]) {
        let [x, y, z] = d;
        let rho2 = x * x + y * y;
        if !(rho2 > 0.0 && rho2.is_finite() && z.is_finite()) {
            // the poles' axis, or not a direction
            self.lookup_bilinear(d, out);
            return;
        }
        self.bilinear_at(atan2_approx(rho2.sqrt(), z), atan2_approx(y, x), out);
    }

    /// The map at polar angle `theta` and azimuth `phi` (before the
    /// rotation), bilinear between texel centres.
    fn bilinear_at(&self, theta: f64, phi: f64, out: &mut [f64]) {
        let (w, h, ch) = (self.img.width(), self.img.height(), self.img.channels());
        let (t, p) = (theta, (phi - self.rotation).rem_euclid(2.0 * PI));
        let fu = p / (2.0 * PI) * w as f64 - 0.5;
        let fv = (t / PI * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (u0, v0) = (fu.floor(), fv.floor());
        let (a, b) = (fu - u0, fv - v0);
        let u0 = (u0 as i64).rem_euclid(w as i64) as usize;
        let u1 = (u0 + 1) % w;
        let v0 = v0 as usize;
        let v1 = (v0 + 1).min(h - 1);
        let px = self.img.data();
        for (c, o) in out.iter_mut().enumerate().take(ch) {
            let at = |u: usize, v: usize| f64::from(px[(v * w + u) * ch + c]);
            *o = (1.0 - b) * ((1.0 - a) * at(u0, v0) + a * at(u1, v0))
                + b * ((1.0 - a) * at(u0, v1) + a * at(u1, v1));
        }
    }

    /// The exact SH coefficients of the (rotated) piecewise-constant map up to
    /// `l_max`, or the given ones for an environment made by [`Self::from_sh`].
    ///
    /// # Errors
    /// Degrees beyond [`ifd_sphere::MAX_DEGREE`] or beyond those given.
    pub fn sh(&self, l_max: usize) -> Result<ShCoeffs> {
        let c = match &self.sh {
            Some(c) if l_max > c.l_max() => {
                return Err(RenderError::Parameter {
                    name: "--lmax",
                    value: l_max.to_string(),
                    reason: format!(
                        "the SH environment holds degrees up to {} (bake it with a higher \
                         --sh-lmax)",
                        c.l_max()
                    ),
                });
            }
            Some(c) => c.resized(l_max)?,
            None => analyze_equirect_box(&self.img, l_max, Negatives::Keep)?.coeffs,
        };
        if self.rotation == 0.0 {
            return Ok(c);
        }
        Ok(ShRotation::new(&Rotation::rz(self.rotation), l_max)?.apply(&c)?)
    }
}
