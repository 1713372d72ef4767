//! The glTF 2.0 metallic-roughness BRDF, whole (for the oracle and Monte
//! Carlo) and split into the three view-dependent parts ISD shades with.
//!
//! The derivation is documented on [`GltfMaterial`].

use std::f64::consts::PI;

use crate::error::{Result, ShadeError};

/// The smallest glTF roughness ISD shades: `alpha = roughness^2 = 1e-3`, the
/// narrowest GGX lobe [`crate::Brdf`] accepts. Smaller values (glTF allows 0,
/// a mirror) are raised to it.
pub const MIN_ROUGHNESS: f64 = 0.031_622_776_601_683_79;

/// The Fresnel reflectance of glTF's dielectrics at normal incidence.
pub const DIELECTRIC_F0: f64 = 0.04;

/// A glTF metallic-roughness material at one surface point: base colour
/// (linear RGB), metallic and perceptual roughness (`alpha = roughness^2`).
///
/// # The BRDF (glTF 2.0, Appendix B)
/// With `h` the half vector, `w = (1 - |wo . h|)^5` and the GGX specular
/// term `S = D(h) V(wi, wo)` (isotropic, `alpha = roughness^2`,
/// height-correlated Smith visibility, as [`crate::Brdf`]'s `ggx`):
///
/// ```text
/// dielectric = mix(c_base / pi, S, F_d),  F_d = 0.04 + 0.96 w
/// metal      = S F_m,                     F_m = c_base + (1 - c_base) w
/// f          = mix(dielectric, metal, metallic)
/// ```
///
/// Expanding the mixes, with `f0 = 0.04 (1 - m) + m c_base` and
/// `c_diff = c_base (1 - m)`:
///
/// ```text
/// specular: (1 - m) (0.04 + 0.96 w) S + m (c_base + (1 - c_base) w) S
///         = [0.04 (1 - m) + m c_base] S + [0.96 (1 - m) + m (1 - c_base)] w S
///         = f0 S + (1 - f0) w S = f0 S (1 - w) + S w
/// diffuse:  (1 - m) (1 - F_d) c_base / pi = 0.96 c_diff (1 - w) / pi
/// ```
///
/// so per channel
///
/// ```text
/// f cos = f0 [S (1 - w) cos] + [S w cos] + 0.96 c_diff [(1 - w) cos / pi]
/// ```
///
/// The three bracketed slices depend on the view and the roughness only,
/// not on the colour or the metalness: [`crate::Brdf`]'s `gltf-lobes`
/// model has them as its three channels, one lobe table holds all three
/// (they share the in-plane lobes, so one environment lookup per lobe serves
/// the three), and the integral of the environment against the whole BRDF
/// is the same combination of three integrals ([`Self::combine`]), exactly,
/// for every texel's colour and metalness. No split-sum approximation is
/// involved: the Fresnel weights stay inside the integrals. The diffuse part
/// keeps the `1 - F` weighting, which a plain irradiance lookup would drop.
///
/// ```
/// use ifd_shade::{Brdf, GltfMaterial};
/// let m = GltfMaterial::new([0.9, 0.6, 0.2], 0.3, 0.5)?;
/// let (whole, parts) = (Brdf::gltf(&m), Brdf::gltf_lobes(0.5)?);
/// let (wi, wo) = ([0.3, 0.2, 0.93], [-0.5, 0.1, 0.86]);
/// let (mut f, mut p) = ([0.0; 3], [0.0; 3]);
/// whole.slice(wi, wo, &mut f);
/// parts.slice(wi, wo, &mut p);
/// let mut combined = [0.0; 3];
/// m.combine(&p, 1, &mut combined);
/// for c in 0..3 {
///     assert!((f[c] - combined[c]).abs() < 1e-12 * f[c].abs().max(1.0));
/// }
/// # Ok::<(), ifd_shade::ShadeError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GltfMaterial {
    /// Base colour, linear RGB in `[0, 1]`.
    pub base: [f64; 3],
    /// Metalness in `[0, 1]`.
    pub metallic: f64,
    /// Perceptual roughness in `[MIN_ROUGHNESS, 1]`.
    pub roughness: f64,
}

impl GltfMaterial {
    /// A material, checked: every value finite and in `[0, 1]`; roughness
    /// below [`MIN_ROUGHNESS`] is raised to it.
    ///
    /// # Errors
    /// [`ShadeError::Parameter`] naming the value out of range.
    pub fn new(base: [f64; 3], metallic: f64, roughness: f64) -> Result<Self> {
        let check = |name: &'static str, v: f64| {
            if v.is_finite() && (0.0..=1.0).contains(&v) {
                Ok(v)
            } else {
                Err(ShadeError::Parameter {
                    name,
                    value: v.to_string(),
                    reason: "glTF factors lie in [0, 1]".into(),
                })
            }
        };
        for b in base {
            check("base colour", b)?;
        }
        Ok(Self {
            base,
            metallic: check("metallic", metallic)?,
            roughness: check("roughness", roughness)?.max(MIN_ROUGHNESS),
        })
    }

    /// GGX `alpha = roughness^2`.
    #[must_use]
    pub fn alpha(&self) -> f64 {
        self.roughness * self.roughness
    }

    /// `f0 = 0.04 (1 - m) + m c_base` of channel `c`.
    #[must_use]
    pub fn f0(&self, c: usize) -> f64 {
        DIELECTRIC_F0 * (1.0 - self.metallic) + self.metallic * self.base[c.min(2)]
    }

    /// `c_diff = c_base (1 - m)` of channel `c`.
    #[must_use]
    pub fn c_diff(&self, c: usize) -> f64 {
        self.base[c.min(2)] * (1.0 - self.metallic)
    }

    /// Combines the three parts' integrals into the whole BRDF's, per
    /// channel: `out[c] = f0_c parts[c] + parts[C + c] + 0.96 c_diff_c
    /// parts[2 C + c]`, `C = channels` (a grey environment, `C = 1`, gives
    /// three coloured channels when `out` has room for them). `parts` is
    /// part-major, as [`crate::Material::shade_isd_parts`] writes it.
    ///
    /// # Panics
    /// If `parts` has fewer than `3 C` values or `out` fewer than `C`.
    pub fn combine(&self, parts: &[f64], channels: usize, out: &mut [f64]) {
        let n = out.len().min(3).max(channels);
        for (c, o) in out.iter_mut().enumerate().take(n) {
            let k = c.min(channels - 1);
            *o = self.f0(c) * parts[k]
                + parts[channels + k]
                + (1.0 - DIELECTRIC_F0) * self.c_diff(c) * parts[2 * channels + k];
        }
    }

    /// The spec `gltf:roughness=..,metallic=..,base=R:G:B` of this material.
    #[must_use]
    pub fn spec(&self) -> String {
        let b = self.base;
        format!(
            "gltf:roughness={},metallic={},base={}:{}:{}",
            self.roughness, self.metallic, b[0], b[1], b[2]
        )
    }
}

/// The isotropic GGX term `S cos = D(h) V(wi, wo) wi_z` (zero below either
/// horizon) and `w = (1 - wo . h)^5`.
pub(crate) fn ggx_and_schlick(alpha: f64, wi: [f64; 3], wo: [f64; 3]) -> (f64, f64) {
    if wi[2] <= 0.0 || wo[2] <= 0.0 {
        return (0.0, 0.0);
    }
    let h = (glam::DVec3::from(wi) + glam::DVec3::from(wo))
        .try_normalize()
        .unwrap_or(glam::DVec3::Z)
        .to_array();
    let a2 = alpha * alpha;
    let q = (h[0] * h[0] + h[1] * h[1]) / a2 + h[2] * h[2];
    let d = 1.0 / (PI * a2 * q * q);
    let lv = (a2 * (wo[0] * wo[0] + wo[1] * wo[1]) + wo[2] * wo[2]).sqrt();
    let ll = (a2 * (wi[0] * wi[0] + wi[1] * wi[1]) + wi[2] * wi[2]).sqrt();
    let v = 0.5 / (wi[2] * lv + wo[2] * ll);
    let c = (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]).clamp(0.0, 1.0);
    (d * v * wi[2], (1.0 - c).powi(5))
}

/// The three parts' slices `[S (1 - w) cos, S w cos, (1 - w) cos / pi]`.
pub(crate) fn parts(alpha: f64, wi: [f64; 3], wo: [f64; 3], out: &mut [f64]) {
    if wi[2] <= 0.0 || wo[2] <= 0.0 {
        out[..3].fill(0.0);
        return;
    }
    let (s, w) = ggx_and_schlick(alpha, wi, wo);
    out[0] = s * (1.0 - w);
    out[1] = s * w;
    out[2] = (1.0 - w) * wi[2] / PI;
}

/// Parses the arguments of `gltf:` (`roughness=`, `metallic=`, `base=B` or
/// `base=R:G:B`; glTF's defaults 1, 1, 1).
pub(crate) fn parse_material(
    args: &str,
    err: &dyn Fn(String) -> ShadeError,
) -> Result<GltfMaterial> {
    let (mut roughness, mut metallic, mut base) = (None, None, None);
    for part in args.split(',').filter(|s| !s.trim().is_empty()) {
        let (k, v) = part
            .split_once('=')
            .ok_or_else(|| err(format!("{part:?}: expected key=value")))?;
        let (key, v) = (k.trim(), v.trim());
        let num = |s: &str| -> Result<f64> {
            let x: f64 = s
                .trim()
                .parse()
                .map_err(|_| err(format!("{key}={v}: not a number")))?;
            if !(0.0..=1.0).contains(&x) {
                return Err(err(format!("{key}={v} is outside [0, 1]")));
            }
            Ok(x)
        };
        let slot_taken = match key {
            "roughness" => roughness.replace(num(v)?).is_some(),
            "metallic" => metallic.replace(num(v)?).is_some(),
            "base" => {
                let c: Vec<&str> = v.split(':').collect();
                let rgb = match c.as_slice() {
                    [g] => [num(g)?; 3],
                    [r, g, b] => [num(r)?, num(g)?, num(b)?],
                    _ => return Err(err(format!("base={v}: give one value or R:G:B"))),
                };
                base.replace(rgb).is_some()
            }
            _ => {
                return Err(err(format!(
                    "gltf takes no parameter {key:?} (it takes roughness, metallic, base)"
                )));
            }
        };
        if slot_taken {
            return Err(err(format!("{key} given twice")));
        }
    }
    let roughness = roughness.unwrap_or(1.0);
    if roughness * roughness < 1e-3 * (1.0 - 1e-9) {
        return Err(err(format!(
            "roughness={roughness} is below {MIN_ROUGHNESS:.4} (alpha = roughness^2 = 1e-3, the \
             narrowest lobe shaded)"
        )));
    }
    GltfMaterial::new(base.unwrap_or([1.0; 3]), metallic.unwrap_or(1.0), roughness)
}

/// Parses the arguments of `gltf-lobes:` (`roughness=`, default 1).
pub(crate) fn parse_lobes(args: &str, err: &dyn Fn(String) -> ShadeError) -> Result<f64> {
    let mut roughness = None;
    for part in args.split(',').filter(|s| !s.trim().is_empty()) {
        match part.split_once('=') {
            Some((k, v)) if k.trim() == "roughness" => {
                let r: f64 = v
                    .trim()
                    .parse()
                    .map_err(|_| err(format!("roughness={}: not a number", v.trim())))?;
                if roughness.replace(r).is_some() {
                    return Err(err("roughness given twice".into()));
                }
            }
            _ => {
                return Err(err(format!("{part:?}: gltf-lobes takes roughness= only")));
            }
        }
    }
    let r = roughness.unwrap_or(1.0);
    if !(r * r >= 1e-3 * (1.0 - 1e-9) && r <= 1.0) {
        return Err(err(format!(
            "roughness={r} is outside [{MIN_ROUGHNESS:.4}, 1]"
        )));
    }
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Brdf;

    /// The glTF specification's form, mixes as written, independently of
    /// [`parts`]: `mix(mix(diffuse, S, F_d), S F_m, m)`.
    fn spec_form(m: &GltfMaterial, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        let a = m.alpha();
        let h = (glam::DVec3::from(wi) + glam::DVec3::from(wo))
            .normalize()
            .to_array();
        let vh = (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]).abs();
        let nl = wi[2];
        let nv = wo[2];
        let nh = h[2];
        let a2 = a * a;
        let dd = nh * nh * (a2 - 1.0) + 1.0;
        let d = a2 / (PI * dd * dd);
        let v = 0.5
            / (nl * (nv * nv * (1.0 - a2) + a2).sqrt() + nv * (nl * nl * (1.0 - a2) + a2).sqrt());
        let s = d * v;
        let w = (1.0 - vh).powi(5);
        m.base.map(|b| {
            let fd = 0.04 + 0.96 * w;
            let dielectric = (1.0 - fd) * b / PI + fd * s;
            let metal = s * (b + (1.0 - b) * w);
            ((1.0 - m.metallic) * dielectric + m.metallic * metal) * nl
        })
    }

    #[test]
    fn whole_brdf_is_the_specification_mix_and_the_parts_combination() {
        let mut seed = 7u64;
        let mut u = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let dir = |u0: f64, u1: f64| {
            let z: f64 = 0.02 + 0.98 * u0;
            let r = (1.0 - z * z).sqrt();
            let p = 2.0 * PI * u1;
            [r * p.cos(), r * p.sin(), z]
        };
        for _ in 0..200 {
            let m = GltfMaterial::new([u(), u(), u()], u(), 0.05 + 0.95 * u()).unwrap();
            let (wi, wo) = (dir(u(), u()), dir(u(), u()));
            let want = spec_form(&m, wi, wo);
            let (whole, lobes) = (Brdf::gltf(&m), Brdf::gltf_lobes(m.roughness).unwrap());
            let (mut f, mut p, mut comb) = ([0.0; 3], [0.0; 3], [0.0; 3]);
            whole.slice(wi, wo, &mut f);
            lobes.slice(wi, wo, &mut p);
            m.combine(&p, 1, &mut comb);
            for c in 0..3 {
                let tol = 1e-12 * want[c].abs().max(1.0);
                assert!(
                    (f[c] - want[c]).abs() < tol,
                    "{m:?} {c}: {} vs {}",
                    f[c],
                    want[c]
                );
                assert!((comb[c] - want[c]).abs() < tol, "{m:?} {c}");
            }
        }
    }

    #[test]
    fn specs_parse_with_defaults_and_refuse_bad_values() {
        let b = Brdf::parse("gltf:roughness=0.5,metallic=0,base=0.9:0.5:0.1").unwrap();
        assert_eq!(b.channels(), 3);
        assert!(b.is_isotropic());
        let m = b.gltf_material().unwrap();
        assert_eq!(m.base, [0.9, 0.5, 0.1]);
        let d = Brdf::parse("gltf").unwrap().gltf_material().unwrap();
        assert_eq!((d.base, d.metallic, d.roughness), ([1.0; 3], 1.0, 1.0));
        for bad in [
            "gltf:roughness=2",
            "gltf:roughness=0.01",
            "gltf:metallic=-1",
            "gltf:base=1:1",
            "gltf:base=nan",
            "gltf:albedo=1",
            "gltf:roughness=0.5,roughness=0.4",
            "gltf-lobes:roughness=0",
            "gltf-lobes:metallic=1",
        ] {
            assert!(Brdf::parse(bad).is_err(), "{bad}");
        }
        // the spec round-trips
        let again = Brdf::parse(&m.spec()).unwrap().gltf_material().unwrap();
        assert_eq!(again, m);
    }
}
