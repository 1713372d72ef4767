//! Zonal lighting: light that is rotationally symmetric about an axis, the
//! case where Eq. 22 needs only `L + 1` lighting coefficients. Two uses in
//! the ISD paper: local spherical light sources (Sec. 7.3, Eq. 33-34) and
//! radially symmetric distant lighting (Sec. 6.1, Eq. 23-24, the radial
//! reflection maps of [`crate::radial`]).
//!
//! The derivation and conventions are documented on [`ZonalLighting`].

use ifd_sphere::ShCoeffs;
use ifd_sphere::{ShEvaluator, gauss_legendre, legendre_all, pi_l};

use crate::bands::Bands;
use crate::brdf::Brdf;
use crate::error::{Result, ShadeError};
use crate::frame::Frame;
use glam::DVec3;

/// Lighting `sum_l e_l y_l^0(a . w)` about a unit axis `a`, per channel.
///
/// # Derivation
/// Lighting `E(w) = f(a . w)` about a unit axis `a` expands on zonal
/// harmonics (Eq. 23, 33) as `E(w) = sum_l e_l y_l^0(a . w)` with
///
/// ```text
/// e_l = 2 pi int_{-1}^{1} f(t) y_l^0(t) dt = 2 pi sqrt((2l + 1) / (4 pi)) int f(t) P_l(t) dt.
/// ```
///
/// By the addition theorem `y_l^0(a . w) = pi_l sum_m y_l^m(a) y_l^m(w)`
/// (`pi_l = sqrt(4 pi / (2l + 1))`), so its SH coefficients are
/// `e_l^m = pi_l e_l y_l^m(a)` and the per-band prefiltered light of Eq. 22 is
///
/// ```text
/// Ehat_l(d) = pi_l sum_m e_l^m y_l^m(d) = pi_l^2 e_l sum_m y_l^m(a) y_l^m(d)
///           = pi_l e_l y_l^0(a . d) = e_l P_l(a . d),
/// ```
///
/// since `pi_l sqrt((2l + 1) / (4 pi)) = 1`: one Legendre recurrence per
/// lobe instead of an SH evaluation (Eq. 34 is this with the paper's
/// `sqrt(4 pi / (2l + 1)) e_l y_l^0`). [`ZonalLighting`] implements
/// [`Bands`] this way, so [`crate::Material::shade_isd`] shades under
/// it unchanged.
///
/// **A spherical cap** of half-angle `alpha` and radiance `Le` (a sphere of
/// radius `r` at distance `d` from the shaded point subtends `sin alpha = r /
/// d`): `f(t) = Le` for `t >= cos alpha`, and with `int_x^1 P_l = (P_{l-1}(x) -
/// P_{l+1}(x)) / (2l + 1)` (from `(2l + 1) P_l = P'_{l+1} - P'_{l-1}` and
/// `P_l(1) = 1`),
///
/// ```text
/// e_0 = 2 pi Le sqrt(1 / (4 pi)) (1 - cos alpha),
/// e_l = 2 pi Le sqrt((2l + 1) / (4 pi)) (P_{l-1}(cos alpha) - P_{l+1}(cos alpha)) / (2l + 1).
/// ```
///
/// As `alpha -> 0` with `Le alpha^2` fixed these tend to a point light's
/// `Le pi alpha^2 y_l^0(1)`, and `e_0 sqrt(4 pi)` is the cap's solid angle
/// times `Le`.
#[derive(Clone, Debug, PartialEq)]
pub struct ZonalLighting {
    axis: [f64; 3],
    l_max: usize,
    channels: usize,
    /// `e_l` per channel: `coeffs[l C + c]`.
    coeffs: Vec<f64>,
}

impl ZonalLighting {
    /// Lighting about `axis` (normalised here) with coefficients `e_l`,
    /// `coeffs[l C + c]` for `l = 0..=l_max`.
    ///
    /// # Errors
    /// [`ShadeError::Parameter`] for a zero or non-finite axis, non-finite
    /// coefficients, no channels, or a length other than `(L + 1) C`.
    pub fn new(axis: [f64; 3], l_max: usize, channels: usize, coeffs: Vec<f64>) -> Result<Self> {
        let axis = unit(axis, "light axis")?;
        if channels == 0 || coeffs.len() != (l_max + 1) * channels {
            return Err(ShadeError::Parameter {
                name: "zonal coefficients",
                value: format!("{} values", coeffs.len()),
                reason: format!("expected (L + 1) x C = {} x {channels}", l_max + 1),
            });
        }
        if let Some(v) = coeffs.iter().find(|v| !v.is_finite()) {
            return Err(ShadeError::Parameter {
                name: "zonal coefficient",
                value: v.to_string(),
                reason: "must be finite".into(),
            });
        }
        Ok(Self {
            axis,
            l_max,
            channels,
            coeffs,
        })
    }

    /// A uniform cap of half-angle `acos(cos_alpha)` and radiance
    /// `radiance[c]` about `axis` (see the module docs).
    ///
    /// ```
    /// use ifd_shade::ZonalLighting;
    /// // a hemisphere of unit radiance: e_0 sqrt(4 pi) is its solid angle, 2 pi
    /// let z = ZonalLighting::cap([0.0, 0.0, 1.0], 0.0, &[1.0], 4)?;
    /// let e0 = z.coeffs()[0] * (4.0 * std::f64::consts::PI).sqrt();
    /// assert!((e0 - 2.0 * std::f64::consts::PI).abs() < 1e-12);
    /// # Ok::<(), ifd_shade::ShadeError>(())
    /// ```
    ///
    /// # Errors
    /// `cos_alpha` outside `[-1, 1]`, non-finite or negative radiance, and as
    /// [`Self::new`].
    pub fn cap(axis: [f64; 3], cos_alpha: f64, radiance: &[f64], l_max: usize) -> Result<Self> {
        if !(-1.0..=1.0).contains(&cos_alpha) {
            return Err(ShadeError::Parameter {
                name: "cap cos(alpha)",
                value: cos_alpha.to_string(),
                reason: "must lie in [-1, 1]".into(),
            });
        }
        check_radiance(radiance)?;
        let unit = cap_coefficients(cos_alpha, l_max);
        let coeffs = unit
            .iter()
            .flat_map(|e| radiance.iter().map(move |r| e * r))
            .collect();
        Self::new(axis, l_max, radiance.len(), coeffs)
    }

    /// The zonal part of an environment about `axis`: `e_l = pi_l sum_m
    /// e_l^m y_l^m(a)`, the projection of `E` on `y_l^0(a . w)` (its average
    /// over rotations about `a`, the radially symmetric light of Eq. 23 that
    /// is closest to it).
    ///
    /// # Errors
    /// As [`Self::new`]; degrees beyond [`ifd_sphere::MAX_DEGREE`].
    pub fn radial_part(env: &ShCoeffs, axis: [f64; 3]) -> Result<Self> {
        let a = unit(axis, "radial axis")?;
        let (l_max, ch) = (env.l_max(), env.channels());
        let y = ShEvaluator::new(l_max)?.eval(a);
        let mut coeffs = vec![0.0; (l_max + 1) * ch];
        for (i, yi) in y.iter().enumerate() {
            let l = i.isqrt();
            for c in 0..ch {
                coeffs[l * ch + c] += pi_l(l) * yi * env.data()[i * ch + c];
            }
        }
        Self::new(a, l_max, ch, coeffs)
    }

    /// The unit axis.
    #[must_use]
    pub fn axis(&self) -> [f64; 3] {
        self.axis
    }

    /// The coefficients `e_l`, `[l C + c]`.
    #[must_use]
    pub fn coeffs(&self) -> &[f64] {
        &self.coeffs
    }

    /// The same coefficients about another axis.
    ///
    /// # Errors
    /// A zero or non-finite axis.
    pub fn with_axis(&self, axis: [f64; 3]) -> Result<Self> {
        Ok(Self {
            axis: unit(axis, "light axis")?,
            ..self.clone()
        })
    }

    /// The same light truncated or zero-padded to degree `l_max`.
    #[must_use]
    pub fn with_degree(&self, l_max: usize) -> Self {
        let ch = self.channels;
        let mut coeffs = vec![0.0; (l_max + 1) * ch];
        let n = coeffs.len().min(self.coeffs.len());
        coeffs[..n].copy_from_slice(&self.coeffs[..n]);
        Self {
            axis: self.axis,
            l_max,
            channels: ch,
            coeffs,
        }
    }

    /// The lighting's value `sum_l e_l y_l^0(a . w)` in direction `w`.
    pub fn eval(&self, w: [f64; 3], out: &mut [f64]) {
        let ch = self.channels;
        let mut p = vec![0.0; self.l_max + 1];
        legendre_all(
            self.l_max,
            DVec3::from(self.axis).dot(DVec3::from(w)).clamp(-1.0, 1.0),
            &mut p,
        );
        out[..ch].fill(0.0);
        for (l, pl) in p.iter().enumerate() {
            let y = ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt() * pl;
            for (o, e) in out[..ch].iter_mut().zip(&self.coeffs[l * ch..(l + 1) * ch]) {
                *o += e * y;
            }
        }
    }

    /// The SH coefficients `e_l^m = pi_l e_l y_l^m(a)` (for the SH reference
    /// of Eq. 22).
    ///
    /// # Errors
    /// Degrees beyond [`ifd_sphere::MAX_DEGREE`].
    pub fn to_sh(&self) -> Result<ShCoeffs> {
        let ch = self.channels;
        let y = ShEvaluator::new(self.l_max)?.eval(self.axis);
        let mut data = vec![0.0; y.len() * ch];
        for l in 0..=self.l_max {
            for i in l * l..(l + 1) * (l + 1) {
                for c in 0..ch {
                    data[i * ch + c] = pi_l(l) * self.coeffs[l * ch + c] * y[i];
                }
            }
        }
        Ok(ShCoeffs::from_vec(self.l_max, ch, data)?)
    }
}

impl Bands for ZonalLighting {
    fn l_max(&self) -> usize {
        self.l_max
    }
    fn channels(&self) -> usize {
        self.channels
    }
    /// `Ehat_l(d) = e_l P_l(a . d)` (module docs); `y` holds the Legendre values.
    fn bands_from(&self, l0: usize, d: [f64; 3], y: &mut [f64], out: &mut [f64]) {
        let ch = self.channels;
        legendre_all(
            self.l_max,
            DVec3::from(self.axis).dot(DVec3::from(d)).clamp(-1.0, 1.0),
            y,
        );
        for l in l0..=self.l_max {
            for c in 0..ch {
                out[l * ch + c] = self.coeffs[l * ch + c] * y[l];
            }
        }
    }
}

/// The zonal coefficients `e_l`, `l = 0..=l_max`, of a cap of unit radiance
/// and half-angle `acos(cos_alpha)` (module docs).
#[must_use]
pub fn cap_coefficients(cos_alpha: f64, l_max: usize) -> Vec<f64> {
    let x = cos_alpha.clamp(-1.0, 1.0);
    let mut p = vec![0.0; l_max + 2];
    legendre_all(l_max + 1, x, &mut p);
    (0..=l_max)
        .map(|l| {
            let n = (2 * l + 1) as f64;
            let integral = if l == 0 {
                1.0 - x
            } else {
                (p[l - 1] - p[l + 1]) / n
            };
            2.0 * std::f64::consts::PI * (n / (4.0 * std::f64::consts::PI)).sqrt() * integral
        })
        .collect()
}

/// A local spherical light source (ISD Sec. 7.3): a sphere of uniform
/// radiance, seen from each shaded point as a cap of half-angle
/// `asin(radius / distance)`. Unshadowed, like the rest of the renderer.
#[derive(Clone, Debug, PartialEq)]
pub struct SphericalLight {
    /// Centre (world).
    pub centre: [f64; 3],
    /// Radius (> 0).
    pub radius: f64,
    /// Radiance per channel (1 or 3 values).
    pub radiance: Vec<f64>,
}

impl SphericalLight {
    /// `x,y,z,radius,L` or `x,y,z,radius,R,G,B` (radiance of the surface
    /// of the sphere).
    ///
    /// ```
    /// let s = ifd_shade::SphericalLight::parse("0,0,3,0.5,20")?;
    /// assert_eq!(s.radius, 0.5);
    /// # Ok::<(), ifd_shade::ShadeError>(())
    /// ```
    ///
    /// # Errors
    /// [`ShadeError::Parameter`] naming the problem: count, non-numbers,
    /// non-finite values, a radius that is not positive, negative radiance.
    pub fn parse(s: &str) -> Result<Self> {
        let bad = |reason: String| ShadeError::Parameter {
            name: "--light",
            value: s.into(),
            reason,
        };
        let v: Vec<f64> = s
            .split(',')
            .map(|t| t.trim().parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|e| {
                bad(format!(
                    "expected numbers x,y,z,radius,L or x,y,z,radius,R,G,B ({e})"
                ))
            })?;
        if v.len() != 5 && v.len() != 7 {
            return Err(bad(format!(
                "expected 5 (x,y,z,radius,L) or 7 (x,y,z,radius,R,G,B) numbers, got {}",
                v.len()
            )));
        }
        if v.iter().any(|x| !x.is_finite()) {
            return Err(bad("every value must be finite".into()));
        }
        let light = Self {
            centre: [v[0], v[1], v[2]],
            radius: v[3],
            radiance: v[4..].to_vec(),
        };
        light.check().map_err(|e| bad(e.to_string()))?;
        Ok(light)
    }

    fn check(&self) -> Result<()> {
        if !(self.radius > 0.0 && self.radius.is_finite()) {
            return Err(ShadeError::Parameter {
                name: "light radius",
                value: self.radius.to_string(),
                reason: "must be positive and finite".into(),
            });
        }
        if self.centre.iter().any(|c| !c.is_finite()) {
            return Err(ShadeError::Parameter {
                name: "light centre",
                value: format!("{:?}", self.centre),
                reason: "must be finite".into(),
            });
        }
        check_radiance(&self.radiance)
    }

    /// The radiance for `channels` channels (a grey light repeats its value;
    /// an RGB light under a 1-channel environment is refused).
    ///
    /// # Errors
    /// [`ShadeError::Mismatch`] for an RGB light in a grey render.
    pub fn radiance_for(&self, channels: usize) -> Result<Vec<f64>> {
        match (self.radiance.len(), channels) {
            (1, c) => Ok(vec![self.radiance[0]; c]),
            (n, c) if n == c => Ok(self.radiance.clone()),
            (n, c) => Err(ShadeError::Mismatch(format!(
                "a {n}-channel light in a {c}-channel render"
            ))),
        }
    }

    /// The cap the light subtends at `x`: unit axis towards the centre and
    /// `cos alpha = sqrt(1 - (r / d)^2)`.
    ///
    /// # Errors
    /// [`ShadeError::Parameter`] when `x` lies inside the light (the light
    /// intersects the object).
    pub fn cap_at(&self, x: [f64; 3]) -> Result<([f64; 3], f64)> {
        let v = DVec3::from(self.centre) - DVec3::from(x);
        let d = v.length();
        if d <= self.radius * (1.0 + 1e-9) {
            return Err(ShadeError::Parameter {
                name: "light",
                value: format!("centre {:?}, radius {}", self.centre, self.radius),
                reason: format!(
                    "the shaded point {x:?} lies inside the light (distance {d}): move it \
                     off the object or make it smaller"
                ),
            });
        }
        let s = self.radius / d;
        Ok(([v[0] / d, v[1] / d, v[2] / d], (1.0 - s * s).sqrt()))
    }

    /// The light seen from `x` as zonal lighting of degree `l_max` in
    /// `channels` channels (Eq. 33).
    ///
    /// # Errors
    /// As [`Self::cap_at`] and [`Self::radiance_for`].
    pub fn at(&self, x: [f64; 3], l_max: usize, channels: usize) -> Result<ZonalLighting> {
        let (axis, cos_alpha) = self.cap_at(x)?;
        ZonalLighting::cap(axis, cos_alpha, &self.radiance_for(channels)?, l_max)
    }

    /// Where the ray `o + t d` (unit `d`) enters the light, if it does.
    #[must_use]
    pub fn intersect(&self, o: [f64; 3], d: [f64; 3]) -> Option<f64> {
        let oc = DVec3::from(o) - DVec3::from(self.centre);
        let b = oc.dot(DVec3::from(d));
        let c = oc.length_squared() - self.radius * self.radius;
        let disc = b * b - c;
        if disc < 0.0 {
            return None;
        }
        let t = -b - disc.sqrt();
        (t > 1e-9).then_some(t)
    }
}

/// The reference for zonal lighting: `int f(a . w) k_wo(w) dw` by composite
/// Gauss-Legendre quadrature in `t = a . w` (panels split at `breaks`, where
/// `f` has kinks or jumps, and over `[t_min, 1]`) and in the azimuth about
/// `a`, the panels doubled until the value changes by less than `tol`
/// relative to the largest channel. All vectors in the local frame of the
/// BRDF. Returns whether it converged (`max_panels` reached otherwise).
#[allow(clippy::too_many_arguments)]
pub fn zonal_quadrature(
    brdf: &Brdf,
    wo: [f64; 3],
    axis: [f64; 3],
    profile: &dyn Fn(f64) -> f64,
    t_range: (f64, f64),
    breaks: &[f64],
    tol: f64,
    out: &mut [f64],
) -> bool {
    let ch = brdf.channels();
    let Ok(a) = unit(axis, "axis") else {
        out[..ch].fill(0.0);
        return true;
    };
    // an orthonormal pair about a
    // an orthonormal pair about a: the frame's tangent and bitangent
    let Frame { t: u, b: v, .. } = Frame::new(a, [1.0, 0.0, 0.0]);
    let mut edges = vec![t_range.0];
    edges.extend(
        breaks
            .iter()
            .copied()
            .filter(|b| *b > t_range.0 && *b < t_range.1),
    );
    edges.push(t_range.1);
    let (gx, gw) = gauss_legendre(8);
    let mut k = vec![0.0; ch];
    let mut prev: Option<Vec<f64>> = None;
    let mut panels = 4;
    let max_panels = 256;
    loop {
        let mut acc = vec![0.0; ch];
        for seg in edges.windows(2) {
            let (t0, t1) = (seg[0], seg[1]);
            let dt = (t1 - t0) / panels as f64;
            for pt in 0..panels {
                let lo = t0 + pt as f64 * dt;
                for (x, w) in gx.iter().zip(&gw) {
                    let t = lo + 0.5 * dt * (x + 1.0);
                    let wt = 0.5 * dt * w;
                    let f = profile(t);
                    if f == 0.0 {
                        continue;
                    }
                    let st = (1.0 - t * t).max(0.0).sqrt();
                    let nphi = 2 * panels;
                    let dphi = std::f64::consts::TAU / nphi as f64;
                    for pp in 0..nphi {
                        for (y, wy) in gx.iter().zip(&gw) {
                            let phi = (pp as f64 + 0.5 * (y + 1.0)) * dphi;
                            let (s, c) = phi.sin_cos();
                            let w = [
                                t * a[0] + st * (c * u[0] + s * v[0]),
                                t * a[1] + st * (c * u[1] + s * v[1]),
                                t * a[2] + st * (c * u[2] + s * v[2]),
                            ];
                            brdf.slice(w, wo, &mut k);
                            let q = wt * 0.5 * dphi * wy * f;
                            for c in 0..ch {
                                acc[c] += q * k[c];
                            }
                        }
                    }
                }
            }
        }
        if let Some(p) = &prev {
            let scale = acc.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let change = acc
                .iter()
                .zip(p)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            if change <= tol * scale.max(1e-300) || panels >= max_panels {
                out[..ch].copy_from_slice(&acc);
                return change <= tol * scale.max(1e-300);
            }
        }
        prev = Some(acc);
        panels *= 2;
    }
}

/// Gauss-Legendre integration of `f(t) P_l(t)` on `[-1, 1]` split at
/// `breaks`, into `e_l = 2 pi sqrt((2l + 1) / (4 pi)) int f P_l`, exact for
/// piecewise polynomial `f` of degree below `n_per_segment`.
#[must_use]
pub fn zonal_projection(
    f: &dyn Fn(f64) -> f64,
    breaks: &[f64],
    l_max: usize,
    n_per_segment: usize,
) -> Vec<f64> {
    let mut edges = vec![-1.0];
    edges.extend(breaks.iter().copied().filter(|b| *b > -1.0 && *b < 1.0));
    edges.push(1.0);
    let (gx, gw) = gauss_legendre(n_per_segment.max(l_max + 2));
    let mut p = vec![0.0; l_max + 1];
    let mut e = vec![0.0; l_max + 1];
    for seg in edges.windows(2) {
        let (t0, t1) = (seg[0], seg[1]);
        for (x, w) in gx.iter().zip(&gw) {
            let t = 0.5 * (t0 + t1) + 0.5 * (t1 - t0) * x;
            let fw = f(t) * 0.5 * (t1 - t0) * w;
            if fw == 0.0 {
                continue;
            }
            legendre_all(l_max, t, &mut p);
            for l in 0..=l_max {
                e[l] += fw * p[l];
            }
        }
    }
    for (l, v) in e.iter_mut().enumerate() {
        *v *=
            2.0 * std::f64::consts::PI * ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt();
    }
    e
}

fn unit(v: [f64; 3], what: &'static str) -> Result<[f64; 3]> {
    let n = DVec3::from(v).length();
    if !(n.is_finite() && n > 1e-300) {
        return Err(ShadeError::Parameter {
            name: what,
            value: format!("{v:?}"),
            reason: "must be a finite, non-zero vector".into(),
        });
    }
    Ok([v[0] / n, v[1] / n, v[2] / n])
}

/// The largest radiance a light may have: images are 32-bit floats, and a
/// light's contribution is its radiance times a solid angle and a BRDF.
const MAX_RADIANCE: f64 = 1e30;

fn check_radiance(r: &[f64]) -> Result<()> {
    if r.is_empty() || r.iter().any(|v| !v.is_finite() || *v < 0.0) {
        return Err(ShadeError::Parameter {
            name: "radiance",
            value: format!("{r:?}"),
            reason: "needs finite, non-negative values".into(),
        });
    }
    if let Some(v) = r.iter().find(|&&v| v > MAX_RADIANCE) {
        return Err(ShadeError::Parameter {
            name: "radiance",
            value: format!("{v:e}"),
            reason: format!("at most {MAX_RADIANCE:e} (images are 32-bit floats)"),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::Frame;
    use crate::shade::Material;

    /// The closed-form cap coefficients against Gauss-Legendre projection of
    /// the step profile (independent: quadrature of `P_l` on the cap).
    #[test]
    fn cap_coefficients_match_quadrature() {
        for ca in [0.99, 0.8, 0.3, -0.4] {
            let closed = cap_coefficients(ca, 30);
            let num = zonal_projection(&|t| if t >= ca { 1.0 } else { 0.0 }, &[ca], 30, 64);
            for (l, (a, b)) in closed.iter().zip(&num).enumerate() {
                assert!((a - b).abs() < 1e-12, "cos alpha {ca}, l {l}: {a} vs {b}");
            }
        }
    }

    /// Lambert under a cap wholly above the horizon: the irradiance is
    /// `Le pi sin^2(alpha) cos(theta)` exactly (the cap's form factor), and
    /// ISD at L = 16 is within 1e-3 of it.
    #[test]
    fn lambert_cap_form_factor() {
        let brdf = Brdf::parse("lambert").unwrap();
        let m = Material::new(&brdf, 16, None).unwrap();
        let frame = Frame::new([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
        let mut s = m.scratch(1);
        for (theta, alpha) in [(0.0f64, 0.3f64), (0.7, 0.2), (1.0, 0.4)] {
            let axis = [theta.sin(), 0.0, theta.cos()];
            let z = ZonalLighting::cap(axis, alpha.cos(), &[2.0], 16).unwrap();
            let mut out = [0.0];
            m.shade_isd(&z, &frame, [0.0, 0.0, 1.0], &mut s, &mut out)
                .unwrap();
            // Lambert: radiance = albedo / pi * irradiance
            let exact = 2.0 * alpha.sin().powi(2) * theta.cos();
            assert!(
                (out[0] - exact).abs() < 1e-3 * exact,
                "theta {theta} alpha {alpha}: {} vs {exact}",
                out[0]
            );
        }
    }

    /// The SH route (`to_sh`) evaluates to the same function as the zonal one.
    #[test]
    fn sh_expansion_matches_zonal() {
        let z = ZonalLighting::cap([0.3, -0.5, 0.8], 0.9, &[1.0, 2.0, 0.5], 12).unwrap();
        let sh = z.to_sh().unwrap();
        let ev = ShEvaluator::new(12).unwrap();
        let mut a = [0.0; 3];
        for w in [[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [-0.36, 0.48, 0.8]] {
            z.eval(w, &mut a);
            let b = sh.eval(&ev, w).unwrap();
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() < 1e-10, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn bad_lights_are_refused() {
        for s in [
            "1,2,3",
            "0,0,3,0,1",
            "0,0,3,-1,1",
            "0,0,3,1,-2",
            "0,0,nan,1,1",
            "0,0,3,1,1,1",
            "a,b,c,d,e",
            "0,0,2,0.1,1e300",
            "0,0,2,0.1,1,1e31,1",
        ] {
            assert!(SphericalLight::parse(s).is_err(), "{s}");
        }
        let l = SphericalLight::parse("0,0,2,0.5,1").unwrap();
        assert!(l.cap_at([0.0, 0.0, 1.8]).is_err());
        assert!(l.radiance_for(3).unwrap().len() == 3);
        let rgb = SphericalLight::parse("0,0,2,0.5,1,2,3").unwrap();
        assert!(rgb.radiance_for(1).is_err());
    }
}
