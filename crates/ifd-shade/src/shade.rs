//! Shading with ISD (ISD Eq. 22): the radiance leaving a surface point
//! towards `wo`, lit by a distant environment given by its SH coefficients.
//!
//! ```text
//! I(wo) = int E(w) k_wo(R^-1 w) dw
//!       = sum_{l, j} lambda_l^j(wo) Ehat_l(R z_j),   Ehat_l(d) = pi_l sum_m e_l^m y_l^m(d)
//! ```
//!
//! with `R` the rotation from the local frame of the point to the world
//! (columns tangent, bitangent, normal), further rotated about the normal by
//! `phi_o` for isotropic tables (whose slices are taken at `phi_o = 0`). Two
//! ways to get the weights:
//! - **closed form** (Lambert, Phong): the slice is zonal about an axis `a`
//!   (the normal, the mirror direction) with weights `k_l`, one lobe per band:
//!   `I = sum_l k_l Ehat_l(R a)`, `L + 1` bands from one SH evaluation;
//! - **table** ([`crate::table::LobeTable`]): `2L + 1` shared lobes, band `l`
//!   using the first `2l + 1`: `2L + 1` SH evaluations per point.
//!
//! [`Material::shade_sh`] is the SH reference of the same band-limited slice:
//! its SH coefficients rotated by `R` (Ivanic-Ruedenberg) and dotted with
//! `e`. Both give the same number up to rounding.

use ifd_sphere::sh::{ShEvaluator, pi_l};
use ifd_sphere::zhf::{RzhBasis, RzhCoeffs};
use ifd_sphere::{Rotation, ShCoeffs, ShRotation};

use crate::brdf::Brdf;
use crate::error::{Result, ShadeError};
use crate::table::{LobeTable, view_frame_angle};
use crate::zonal::zonal_slice;

/// An environment's SH coefficients, ready for per-band lookups `Ehat_l(d)`.
#[derive(Clone, Debug)]
pub struct Environment {
    coeffs: ShCoeffs,
    sh: ShEvaluator,
}

impl Environment {
    /// Wraps the coefficients `e_l^m` of the lighting (any channel count).
    ///
    /// # Errors
    /// Degrees beyond [`ifd_sphere::MAX_DEGREE`].
    pub fn new(coeffs: ShCoeffs) -> Result<Self> {
        let sh = ShEvaluator::new(coeffs.l_max())?;
        Ok(Self { coeffs, sh })
    }

    /// The coefficients.
    #[must_use]
    pub fn coeffs(&self) -> &ShCoeffs {
        &self.coeffs
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.coeffs.l_max()
    }

    /// Channels.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.coeffs.channels()
    }

    /// `Ehat_l(d) = pi_l sum_m e_l^m y_l^m(d)` for every band: `out[l C + c]`.
    /// `y` is scratch of `(L + 1)^2` values.
    pub fn bands_into(&self, d: [f64; 3], y: &mut [f64], out: &mut [f64]) {
        let ch = self.channels();
        self.sh.eval_into(d, y);
        let e = self.coeffs.data();
        for l in 0..=self.l_max() {
            let p = pi_l(l);
            for c in 0..ch {
                let mut acc = 0.0;
                for i in l * l..(l + 1) * (l + 1) {
                    acc += y[i] * e[i * ch + c];
                }
                out[l * ch + c] = p * acc;
            }
        }
    }
}

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
        let d = dot(tangent_hint, n);
        let mut t = [
            tangent_hint[0] - d * n[0],
            tangent_hint[1] - d * n[1],
            tangent_hint[2] - d * n[2],
        ];
        let mut len = dot(t, t).sqrt();
        if len.is_nan() || len <= 1e-12 {
            // any perpendicular: cross with the axis least aligned with n
            let a = if n[0].abs() < 0.6 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            t = cross(cross(n, a), n);
            len = dot(t, t).sqrt();
        }
        let t = [t[0] / len, t[1] / len, t[2] / len];
        Self {
            t,
            b: cross(n, t),
            n,
        }
    }

    /// World to local: `(t . w, b . w, n . w)`.
    #[must_use]
    pub fn to_local(&self, w: [f64; 3]) -> [f64; 3] {
        [dot(self.t, w), dot(self.b, w), dot(self.n, w)]
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

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Where a material's lobe weights come from.
#[derive(Clone, Debug)]
enum Lobes {
    /// Closed-form zonal slices (Lambert, Phong).
    Zonal,
    /// A lobe table.
    Table(Box<LobeTable>),
}

/// A BRDF ready to shade at degree `L`.
#[derive(Debug)]
pub struct Material {
    brdf: Brdf,
    l_max: usize,
    lobes: Lobes,
    /// The table's basis (for the SH reference and weights -> SH).
    basis: Option<RzhBasis>,
}

/// Scratch buffers for one thread's shading.
#[derive(Clone, Debug)]
pub struct Scratch {
    y: Vec<f64>,
    bands: Vec<f64>,
    weights: Vec<f64>,
}

impl Material {
    /// A material at degree `l_max`: closed form for Lambert and Phong,
    /// otherwise the given table (checked against the BRDF and degree).
    ///
    /// # Errors
    /// [`ShadeError::Mismatch`] for a table of another BRDF or degree;
    /// [`ShadeError::Parameter`] when a table is needed and none is given.
    pub fn new(brdf: &Brdf, l_max: usize, table: Option<LobeTable>) -> Result<Self> {
        let closed = zonal_slice(brdf, [0.0, 0.0, 1.0], 0).is_some();
        let (lobes, basis) = match (closed, table) {
            (true, None) => (Lobes::Zonal, None),
            (_, Some(t)) => {
                t.check_for(brdf, l_max)?;
                let basis = RzhBasis::new(t.directions().clone())?;
                (Lobes::Table(Box::new(t)), Some(basis))
            }
            (false, None) => {
                return Err(ShadeError::Parameter {
                    name: "lobe table",
                    value: brdf.spec().to_string(),
                    reason: "this BRDF has no closed-form weights: build a table with \
                             `ifd sphere brdf` (or LobeTable::build)"
                        .into(),
                });
            }
        };
        Ok(Self {
            brdf: brdf.clone(),
            l_max,
            lobes,
            basis,
        })
    }

    /// The BRDF.
    #[must_use]
    pub fn brdf(&self) -> &Brdf {
        &self.brdf
    }

    /// The degree `L`.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// Whether the weights are closed-form (one lobe per band).
    #[must_use]
    pub fn is_closed_form(&self) -> bool {
        matches!(self.lobes, Lobes::Zonal)
    }

    /// Scratch buffers for [`Self::shade_isd`].
    #[must_use]
    pub fn scratch(&self, channels: usize) -> Scratch {
        let n = (self.l_max + 1) * (self.l_max + 1);
        Scratch {
            y: vec![0.0; n],
            bands: vec![0.0; (self.l_max + 1) * channels.max(3)],
            weights: vec![0.0; n * 3],
        }
    }

    /// The rotation of the slice and the local view: `R` (local -> world,
    /// rotated by `phi_o` for isotropic tables) and `(theta_o, phi_o)`.
    fn placement(&self, frame: &Frame, wo: [f64; 3]) -> (Rotation, [f64; 3], f64, f64) {
        let wl = frame.to_local(wo);
        let theta = wl[2].clamp(-1.0, 1.0).acos();
        let phi = if wl[0] == 0.0 && wl[1] == 0.0 {
            0.0
        } else {
            view_frame_angle(wl)
        };
        let r = frame.rotation();
        match &self.lobes {
            Lobes::Table(t) if t.header().isotropic => (r.mul(&Rotation::rz(phi)), wl, theta, phi),
            _ => (r, wl, theta, phi),
        }
    }

    /// The channel count of the result for an environment of `env_channels`.
    fn out_channels(&self, env_channels: usize) -> Result<usize> {
        let kc = self.brdf.channels();
        if kc != 1 && kc != env_channels {
            return Err(ShadeError::Mismatch(format!(
                "a {kc}-channel BRDF under a {env_channels}-channel environment"
            )));
        }
        Ok(env_channels)
    }

    /// Eq. 22 at one point: `frame` at the point, `wo` the unit direction
    /// towards the viewer (world). Returns one value per environment channel
    /// in `out`. A view below the surface gives 0 (but for Phong, whose slice
    /// is defined everywhere).
    ///
    /// # Errors
    /// [`ShadeError::Mismatch`] for a MERL (RGB) BRDF under a map of other
    /// than 3 channels, or an environment of another degree.
    pub fn shade_isd(
        &self,
        env: &Environment,
        frame: &Frame,
        wo: [f64; 3],
        s: &mut Scratch,
        out: &mut [f64],
    ) -> Result<()> {
        let ch = self.out_channels(env.channels())?;
        self.check_env(env)?;
        let kc = self.brdf.channels();
        out[..ch].fill(0.0);
        let (r, wl, theta, phi) = self.placement(frame, wo);
        match &self.lobes {
            Lobes::Zonal => {
                let Some((axis, k)) = zonal_slice(&self.brdf, wl, self.l_max) else {
                    return Ok(());
                };
                env.bands_into(r.apply(axis), &mut s.y, &mut s.bands);
                for (l, kl) in k.iter().enumerate() {
                    for (o, b) in out[..ch].iter_mut().zip(&s.bands[l * ch..(l + 1) * ch]) {
                        *o += kl * b;
                    }
                }
            }
            Lobes::Table(t) => {
                if wl[2] <= 0.0 {
                    return Ok(());
                }
                let n = t.entry_len();
                t.weights_into(theta, phi, &mut s.weights[..n]);
                for (j, z) in t.directions().all().iter().enumerate() {
                    env.bands_into(r.apply(*z), &mut s.y, &mut s.bands);
                    for l in j.div_ceil(2)..=self.l_max {
                        let base = (l * l + j) * kc;
                        for (c, o) in out[..ch].iter_mut().enumerate() {
                            let lam = s.weights[base + if kc == 1 { 0 } else { c }];
                            *o += lam * s.bands[l * ch + c];
                        }
                    }
                }
            }
        }
        Ok(())
    }

    fn check_env(&self, env: &Environment) -> Result<()> {
        if env.l_max() != self.l_max {
            return Err(ShadeError::Mismatch(format!(
                "an environment projected to L = {} for a material of L = {}",
                env.l_max(),
                self.l_max
            )));
        }
        Ok(())
    }

    /// The band-limited slice for the view `wo` at this frame, as SH
    /// coefficients in the local frame used by [`Self::shade_isd`] (rotated
    /// by `phi_o` for isotropic tables), from the same weights.
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn slice_sh(&self, frame: &Frame, wo: [f64; 3]) -> Result<(Rotation, Option<ShCoeffs>)> {
        let (r, wl, theta, phi) = self.placement(frame, wo);
        let l = self.l_max;
        let c = match (&self.lobes, &self.basis) {
            (Lobes::Zonal, _) => {
                let Some((axis, k)) = zonal_slice(&self.brdf, wl, l) else {
                    return Ok((r, None));
                };
                let sh = ShEvaluator::new(l)?;
                let y = sh.eval(axis);
                let mut c = ShCoeffs::zeros(l, 1)?;
                for (i, v) in c.data_mut().iter_mut().enumerate() {
                    let li = (i as f64).sqrt() as usize;
                    *v = k[li] * pi_l(li) * y[i];
                }
                c
            }
            (Lobes::Table(t), Some(basis)) => {
                if wl[2] <= 0.0 {
                    return Ok((r, None));
                }
                let lam = RzhCoeffs {
                    l_max: l,
                    channels: t.header().channels,
                    data: t.weights_at(theta, phi),
                };
                basis.zhe(&lam)?
            }
            (Lobes::Table(_), None) => unreachable!("tables always carry their basis"),
        };
        Ok((r, Some(c)))
    }

    /// The SH reference of Eq. 22: the slice's SH coefficients (from the same
    /// weights as [`Self::shade_isd`]) rotated by `R` with the
    /// Ivanic-Ruedenberg recurrences, dotted with the environment's.
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn shade_sh(
        &self,
        env: &Environment,
        frame: &Frame,
        wo: [f64; 3],
        out: &mut [f64],
    ) -> Result<()> {
        let ch = self.out_channels(env.channels())?;
        self.check_env(env)?;
        out[..ch].fill(0.0);
        let (r, c) = self.slice_sh(frame, wo)?;
        let Some(c) = c else {
            return Ok(());
        };
        let g = ShRotation::new(&r, self.l_max)?.apply(&c)?;
        let kc = g.channels();
        let e = env.coeffs().data();
        for i in 0..g.data().len() / kc {
            for (cc, o) in out.iter_mut().enumerate().take(ch) {
                *o += g.data()[i * kc + if kc == 1 { 0 } else { cc }] * e[i * ch + cc];
            }
        }
        Ok(())
    }
}
