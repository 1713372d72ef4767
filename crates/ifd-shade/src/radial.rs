//! Radial reflection maps for any BRDF (ISD Sec. 6.1, Eq. 23-24).
//!
//! The derivation and conventions are documented on [`RadialMap`].

use rayon::prelude::*;

use crate::bands::Bands;
use crate::error::{Result, ShadeError};
use crate::frame::Frame;
use crate::lights::{ZonalLighting, cap_coefficients, zonal_projection, zonal_quadrature};
use crate::shade::Material;
use crate::zonal::legendre_moments;

/// A radially symmetric light profile `f(t)`, `t` the cosine to the axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RadialProfile {
    /// `1` within `half_angle` (radians) of the axis, `0` beyond: a disk
    /// light or, at 90 degrees, a uniform sky.
    Cap {
        /// Half-angle in radians.
        half_angle: f64,
    },
    /// The CIE standard overcast sky, `(1 + 2t) / 3` above the horizon (`t >=
    /// 0`), `0` below (zenith 1).
    Overcast,
    /// `max(t, 0)^s`: a smooth lobe about the axis.
    Power {
        /// Exponent, `>= 0`.
        s: f64,
    },
}

impl RadialProfile {
    /// `cap:deg=D`, `overcast` or `power:s=S`.
    ///
    /// # Errors
    /// [`ShadeError::Parameter`] for other names, missing or invalid values.
    pub fn parse(spec: &str) -> Result<Self> {
        let bad = |reason: &str| ShadeError::Parameter {
            name: "radial light",
            value: spec.into(),
            reason: reason.into(),
        };
        let (name, args) = spec.split_once(':').unwrap_or((spec, ""));
        let get = |key: &str| -> Result<f64> {
            for kv in args.split(',') {
                if let Some((k, v)) = kv.split_once('=')
                    && k.trim() == key
                {
                    let x: f64 = v
                        .trim()
                        .parse()
                        .map_err(|_| bad(&format!("{key} must be a number")))?;
                    if !x.is_finite() {
                        return Err(bad(&format!("{key} must be finite")));
                    }
                    return Ok(x);
                }
            }
            Err(bad(&format!("missing {key}=")))
        };
        match name {
            "cap" => {
                let d = get("deg")?;
                if !(d > 0.0 && d <= 180.0) {
                    return Err(bad("deg must lie in (0, 180]"));
                }
                Ok(Self::Cap {
                    half_angle: d.to_radians(),
                })
            }
            "overcast" => Ok(Self::Overcast),
            "power" => {
                let s = get("s")?;
                if !(0.0..=1e6).contains(&s) {
                    return Err(bad("s must lie in [0, 1e6]"));
                }
                Ok(Self::Power { s })
            }
            _ => Err(bad("unknown profile: use cap:deg=D, overcast or power:s=S")),
        }
    }

    /// `f(t)`.
    #[must_use]
    pub fn eval(&self, t: f64) -> f64 {
        match *self {
            Self::Cap { half_angle } => f64::from(u8::from(t >= half_angle.cos())),
            Self::Overcast => {
                if t >= 0.0 {
                    (1.0 + 2.0 * t) / 3.0
                } else {
                    0.0
                }
            }
            Self::Power { s } => {
                if t > 0.0 {
                    t.powf(s)
                } else if s == 0.0 && t == 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }

    /// Where `f` jumps or has a kink.
    #[must_use]
    pub fn breaks(&self) -> Vec<f64> {
        match *self {
            Self::Cap { half_angle } => vec![half_angle.cos()],
            Self::Overcast | Self::Power { .. } => vec![0.0],
        }
    }

    /// The zonal coefficients `e_l`, `l = 0..=l_max` (Eq. 23), in closed form
    /// (cap, power: [`legendre_moments`]) or by exact Gauss-Legendre
    /// quadrature of the piecewise polynomial (overcast).
    #[must_use]
    pub fn coefficients(&self, l_max: usize) -> Vec<f64> {
        let norm = |l: usize| {
            2.0 * std::f64::consts::PI * ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt()
        };
        match *self {
            Self::Cap { half_angle } => cap_coefficients(half_angle.cos(), l_max),
            Self::Power { s } => legendre_moments(s, l_max)
                .iter()
                .enumerate()
                .map(|(l, i)| norm(l) * i)
                .collect(),
            Self::Overcast => zonal_projection(&|t| self.eval(t), &self.breaks(), l_max, l_max + 4),
        }
    }

    /// The profile as zonal lighting about `axis` with `radiance[c]` times `f`.
    ///
    /// # Errors
    /// As [`ZonalLighting::new`].
    pub fn lighting(
        &self,
        axis: [f64; 3],
        radiance: &[f64],
        l_max: usize,
    ) -> Result<ZonalLighting> {
        let e = self.coefficients(l_max);
        let coeffs = e
            .iter()
            .flat_map(|v| radiance.iter().map(move |r| v * r))
            .collect();
        ZonalLighting::new(axis, l_max, radiance.len(), coeffs)
    }

    /// The quadrature reference of one map entry: `int f(zeta . w) k_wo(w)
    /// dw` times `radiance`, in the local frame (see
    /// [`zonal_quadrature`]). Returns whether it converged to `tol`.
    #[must_use]
    pub fn reference(
        &self,
        brdf: &crate::Brdf,
        wo: [f64; 3],
        zeta: [f64; 3],
        tol: f64,
        out: &mut [f64],
    ) -> bool {
        let t_min = match *self {
            Self::Cap { half_angle } => half_angle.cos(),
            _ => 0.0,
        };
        zonal_quadrature(
            brdf,
            wo,
            zeta,
            &|t| self.eval(t),
            (t_min, 1.0),
            &self.breaks(),
            tol,
            out,
        )
    }
}

/// The sampling of a [`RadialMap`]: cell centres, `theta_o` over `[0, pi/2)`,
/// `phi_o` over `[0, 2 pi)` (anisotropic BRDFs; one value 0 otherwise),
/// `theta_z` over `[0, pi]`, `phi_z` over `[0, pi]` (isotropic) or `[0, 2
/// pi)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MapSize {
    /// View elevations.
    pub theta_o: usize,
    /// View azimuths (1 for isotropic BRDFs).
    pub phi_o: usize,
    /// Axis elevations.
    pub theta_z: usize,
    /// Axis azimuths.
    pub phi_z: usize,
}

/// A tabulated radial reflection map: `data` is a C-order array of shape
/// `(T_o, P_o, T_z, P_z, C)` ([`Self::get`]).
///
/// Stone (2009) shades under distant lighting that is radially symmetric
/// about an axis `zeta` (a sky dome, an overcast sky, a large area light) by
/// precomputing the convolution of a radially symmetric lobe (Phong) with it:
/// a 1D map of the angle between the lobe axis and `zeta`. With ISD the
/// lighting is `L + 1` zonal coefficients `e_l` ([`RadialProfile::coefficients`],
/// Eq. 23) and Eq. 22 becomes Eq. 24,
///
/// ```text
/// I(wo) = sum_{l,m} lambda_l^m(wo) e_l P_l(zeta . R z^m)
/// ```
///
/// (`pi_l e_l y_l^0 = e_l P_l`, see [`crate::ZonalLighting`]): any BRDF, evaluated on
/// the fly from `L + 1` numbers instead of a stored map. [`RadialMap`]
/// tabulates it anyway, for engines that want lookups and for inspection:
/// `I` over the view `(theta_o, phi_o)` and the light axis `(theta_z, phi_z)`
/// in the local frame (`phi_o` only for anisotropic BRDFs; for isotropic
/// ones the map is 3D, `phi_z` over `[0, pi]` by symmetry). Stone's 1D map is
/// the special case of a slice zonal about the mirror direction.
///
/// ```
/// use ifd_shade::RadialProfile;
/// // a uniform sky over the upper hemisphere: e_0 sqrt(4 pi) = 2 pi
/// let e = RadialProfile::parse("cap:deg=90")?.coefficients(4);
/// assert!((e[0] * (4.0 * std::f64::consts::PI).sqrt() - 2.0 * std::f64::consts::PI).abs() < 1e-12);
/// # Ok::<(), ifd_shade::ShadeError>(())
/// ```
#[derive(Clone, Debug)]
pub struct RadialMap {
    /// Sampling.
    pub size: MapSize,
    /// Whether `phi_z` spans `[0, pi]` (isotropic) rather than `[0, 2 pi)`.
    pub isotropic: bool,
    /// Channels.
    pub channels: usize,
    /// Values, linear radiance.
    pub data: Vec<f32>,
}

impl RadialMap {
    /// The local view direction of view cell `(i, j)`.
    #[must_use]
    pub fn view(&self, i: usize, j: usize) -> [f64; 3] {
        let t = (i as f64 + 0.5) / self.size.theta_o as f64 * std::f64::consts::FRAC_PI_2;
        let p = j as f64 / self.size.phi_o as f64 * std::f64::consts::TAU;
        [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
    }

    /// The local light axis of axis cell `(i, j)`.
    #[must_use]
    pub fn axis(&self, i: usize, j: usize) -> [f64; 3] {
        let t = (i as f64 + 0.5) / self.size.theta_z as f64 * std::f64::consts::PI;
        let span = if self.isotropic {
            std::f64::consts::PI
        } else {
            std::f64::consts::TAU
        };
        let p = (j as f64 + 0.5) / self.size.phi_z as f64 * span;
        [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
    }

    /// Tabulates Eq. 24 for `material` under the zonal coefficients `e`
    /// (`e[l C + c]`, from [`RadialProfile::coefficients`] times a radiance or
    /// [`ZonalLighting::radial_part`]); `progress(done, total)` per view row.
    ///
    /// # Errors
    /// [`ShadeError::Parameter`] for empty sizes, more than `2^28` values, or
    /// `phi_o > 1` for an isotropic BRDF; shading errors (channels).
    pub fn build(
        material: &Material,
        light: &ZonalLighting,
        size: MapSize,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self> {
        let isotropic = material.brdf().is_isotropic();
        let dims = [size.theta_o, size.phi_o, size.theta_z, size.phi_z];
        let ch = light.channels();
        let total = dims.iter().try_fold(ch, |a, &d| a.checked_mul(d));
        if dims.contains(&0) || total.is_none_or(|t| t > 1 << 28) {
            return Err(ShadeError::Parameter {
                name: "map size",
                value: format!("{dims:?}"),
                reason: "every size must be at least 1 and the map at most 2^28 values".into(),
            });
        }
        if isotropic && size.phi_o != 1 {
            return Err(ShadeError::Parameter {
                name: "map size",
                value: format!("{dims:?}"),
                reason: "an isotropic BRDF's map has one view azimuth".into(),
            });
        }
        let light = light.with_degree(material.l_max());
        let mut map = Self {
            size,
            isotropic,
            channels: ch,
            data: Vec::new(),
        };
        let frame = Frame::new([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
        let done = std::sync::atomic::AtomicUsize::new(0);
        let rows = size.theta_o * size.phi_o;
        let rows: Vec<Result<Vec<f32>>> = (0..rows)
            .into_par_iter()
            .map(|r| {
                let wo = map.view(r / size.phi_o, r % size.phi_o);
                let mut s = material.scratch(ch);
                let mut out = vec![0.0; ch.max(3)];
                let mut row = Vec::with_capacity(size.theta_z * size.phi_z * ch);
                for i in 0..size.theta_z {
                    for j in 0..size.phi_z {
                        let z = light.with_axis(map.axis(i, j))?;
                        material.shade_isd(&z, &frame, wo, &mut s, &mut out)?;
                        row.extend(out[..ch].iter().map(|v| *v as f32));
                    }
                }
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(n, size.theta_o * size.phi_o);
                Ok(row)
            })
            .collect();
        for r in rows {
            map.data.extend(r?);
        }
        Ok(map)
    }

    /// The value at cell `(i_o, j_o, i_z, j_z)`, channel `c`.
    #[must_use]
    pub fn get(&self, i_o: usize, j_o: usize, i_z: usize, j_z: usize, c: usize) -> f32 {
        let s = self.size;
        self.data[(((i_o * s.phi_o + j_o) * s.theta_z + i_z) * s.phi_z + j_z) * self.channels + c]
    }

    /// Bytes of the map as `f32`.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.data.len() * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Brdf;

    #[test]
    fn profiles_parse_and_refuse() {
        assert!(matches!(
            RadialProfile::parse("overcast"),
            Ok(RadialProfile::Overcast)
        ));
        for bad in [
            "cap",
            "cap:deg=0",
            "cap:deg=200",
            "power:s=-1",
            "power:s=nan",
            "sun",
        ] {
            assert!(RadialProfile::parse(bad).is_err(), "{bad}");
        }
    }

    /// The closed forms against quadrature of the profiles.
    #[test]
    fn coefficients_match_projection() {
        for spec in ["cap:deg=30", "power:s=3.5", "overcast"] {
            let p = RadialProfile::parse(spec).unwrap();
            let a = p.coefficients(20);
            let b = zonal_projection(&|t| p.eval(t), &p.breaks(), 20, 400);
            for (l, (x, y)) in a.iter().zip(&b).enumerate() {
                assert!(
                    (x - y).abs() < 1e-6 * (1.0 + y.abs()),
                    "{spec} l {l}: {x} vs {y}"
                );
            }
        }
    }

    /// Map entries against the quadrature reference of the same light.
    #[test]
    fn map_matches_quadrature() {
        let brdf = Brdf::parse("phong:s=8").unwrap();
        let m = Material::new(&brdf, 24, None).unwrap();
        let p = RadialProfile::parse("power:s=2").unwrap();
        let light = p.lighting([0.0, 0.0, 1.0], &[1.0], 24).unwrap();
        let size = MapSize {
            theta_o: 3,
            phi_o: 1,
            theta_z: 4,
            phi_z: 3,
        };
        let map = RadialMap::build(&m, &light, size, &|_, _| {}).unwrap();
        let mut r = [0.0];
        for i_o in 0..3 {
            for i_z in 0..4 {
                for j_z in 0..3 {
                    assert!(p.reference(&brdf, map.view(i_o, 0), map.axis(i_z, j_z), 1e-8, &mut r));
                    let v = f64::from(map.get(i_o, 0, i_z, j_z, 0));
                    assert!((v - r[0]).abs() < 2e-3 * r[0].max(0.05), "{v} vs {}", r[0]);
                }
            }
        }
    }
}
