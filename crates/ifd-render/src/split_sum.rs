//! The split-sum approximation that engines shade environments with, for
//! the glTF BRDF: the prefiltered radiance chain and irradiance that
//! `ifd envmap prefilter` bakes (computed in memory by `ifd-ibl`), the DFG
//! table of `ifd envmap dfg`, and the per-pixel combination, in two variants.
//!
//! The derivation is documented on [`SplitSum`].

use std::f64::consts::PI;

use glam::DVec3;
use ifd_ibl::{BakeOptions, Baker, CubeLevel, Lobe, RoughnessMapping, face_coords};
use ifd_shade::{GLTF_DIELECTRIC_F0, GltfMaterial};

use crate::envmap::EnvMap;
use crate::error::{RenderError, Result};

/// Which split-sum shading.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitSumVariant {
    /// The approximation itself, for the same BRDF as ISD and the oracle:
    /// `specular = P(r, roughness) (f0 A + B)`,
    /// `diffuse = 0.96 c_diff (E(n) / pi) D(n . v)`.
    Consistent,
    /// glTF-Sample-Renderer's shader as written (Khronos Group,
    /// `source/Renderer/shaders/pbr.frag` at 07d2ba65 and `ibl.glsl` at
    /// 4e170c47): the roughness-dependent Fresnel of Fdez-Agüera with its
    /// multiple-scattering term, and the diffuse `E(n) / pi` times the base
    /// colour, mixed by that Fresnel.
    SampleRenderer,
}

/// A baked environment ready for split-sum shading.
///
/// # The approximation
/// The exact radiance of the glTF BRDF (see [`ifd_shade::GltfMaterial`]) is
///
/// ```text
/// I = f0 int L S (1 - w) cos + int L S w cos + 0.96 c_diff int L (1 - w) cos / pi
/// ```
///
/// The split sum replaces each integral of a product by a product of
/// integrals, `int L g ≈ (int L g_0 / int g_0) int g`, with a lobe `g_0`
/// that does not depend on the view:
///
/// - specular: `g_0` is GGX's `D(h) (n . l)` with `n = v = r` (the lobe
///   `ifd_ibl::Lobe::Ggx` prefilters with), so `int L S (1 - w) cos ≈ P(r) A`
///   and `int L S w cos ≈ P(r) B`, `P` the prefiltered radiance at the
///   reflection vector `r` (the chain's mip at `lod = roughness (M - 1)`,
///   trilinear) and `(A, B)` the DFG table ([`ifd_ibl::dfg`], the same
///   height-correlated GGX, exact for a uniform environment);
/// - diffuse: `g_0 = cos / pi` (the irradiance map holds `E(n) / pi`) and
///   `int (1 - w) cos / pi = D(n . v)`, a one-dimensional table computed
///   here by quadrature.
///
/// Both are exact for a constant environment and err where the lighting
/// varies across the lobe: at grazing views, where the true lobe is
/// stretched and tilted off `r`, and for rough surfaces, whose lobe is wide.
///
/// [`SplitSumVariant::SampleRenderer`] follows an engine's shader instead
/// (its approximations on top: `k_S = f0 + (max(1 - r, f0) - f0)(1 - n.v)^5`
/// in place of Schlick's average, a multiple-scattering term, and the
/// diffuse mixed as `mix(E/pi base, specular, F)` rather than weighted by
/// `1 - F` under the integral).
#[derive(Clone, Debug)]
pub struct SplitSum {
    chain: Vec<CubeLevel>,
    irradiance: CubeLevel,
    mapping: RoughnessMapping,
    dfg: Vec<[f32; 2]>,
    dfg_size: usize,
    /// `D(n . v)` at `n . v = (i + 0.5) / DIFFUSE_ENTRIES`.
    diffuse: Vec<f64>,
    rotation: f64,
}

/// Entries of the diffuse-albedo table over `n . v`.
const DIFFUSE_ENTRIES: usize = 64;

impl SplitSum {
    /// Bakes `env` (as the other methods see it: downsampled, rotated) as
    /// `ifd envmap prefilter` does by default: a `face`-texel radiance chain
    /// (linear roughness mapping, `floor(log2 face)` levels), a 32-texel
    /// irradiance map, and the 128-texel DFG table of `ifd envmap dfg`.
    ///
    /// # Errors
    /// [`RenderError::Parameter`] for a face size that is not a power of two
    /// from 4 to 2048, or an environment the baker refuses.
    pub fn bake(env: &EnvMap, face: usize) -> Result<Self> {
        let bad = |reason: String| RenderError::Parameter {
            name: "split-sum face size",
            value: face.to_string(),
            reason,
        };
        if !face.is_power_of_two() || !(4..=2048).contains(&face) {
            return Err(bad("a power of two from 4 to 2048".into()));
        }
        let mapping = RoughnessMapping::Linear;
        let levels = mapping.default_levels(face);
        let mut lobes = Vec::with_capacity(levels + 1);
        for m in 0..levels {
            lobes.push(
                Lobe::ggx_from_roughness(mapping.roughness(m, levels))
                    .map_err(|e| bad(e.to_string()))?,
            );
        }
        lobes.push(Lobe::Lambert);
        let baker = Baker::new(env.image(), &BakeOptions::default(), &lobes)
            .map_err(|e| bad(format!("baking the environment: {e}")))?;
        let mut chain = Vec::with_capacity(levels);
        for (m, lobe) in lobes[..levels].iter().enumerate() {
            let (level, _) = baker
                .level(lobe, (face >> m).max(1))
                .map_err(|e| bad(e.to_string()))?;
            chain.push(level);
        }
        let (irradiance, _) = baker
            .level(&Lobe::Lambert, 32)
            .map_err(|e| bad(e.to_string()))?;
        let dfg_size = 128;
        Ok(Self {
            chain,
            irradiance,
            mapping,
            dfg: ifd_ibl::dfg_table(dfg_size),
            dfg_size,
            diffuse: (0..DIFFUSE_ENTRIES)
                .map(|i| diffuse_albedo((i as f64 + 0.5) / DIFFUSE_ENTRIES as f64))
                .collect(),
            rotation: env.rotation(),
        })
    }

    /// Levels of the radiance chain.
    #[must_use]
    pub fn levels(&self) -> usize {
        self.chain.len()
    }

    /// The radiance leaving a point of material `m` with shading normal `n`
    /// towards `wo` (unit, world, ifd's frame), RGB.
    #[must_use]
    pub fn shade(
        &self,
        variant: SplitSumVariant,
        m: &GltfMaterial,
        n: [f64; 3],
        wo: [f64; 3],
    ) -> [f64; 3] {
        let (n, v) = (DVec3::from(n), DVec3::from(wo));
        let nv = n.dot(v);
        if nv <= 0.0 {
            return [0.0; 3];
        }
        let r = (2.0 * nv * n - v).normalize_or_zero();
        let levels = self.chain.len();
        let lod = self.mapping_lod(m.roughness, levels);
        let spec = self.radiance(r, lod);
        let irr = lookup(&self.irradiance, self.cube_dir(n));
        let (a, b) = self.dfg_at(nv, m.roughness);
        let mut out = [0.0; 3];
        match variant {
            SplitSumVariant::Consistent => {
                let d = self.diffuse_at(nv);
                for c in 0..3 {
                    out[c] = spec[c] * (m.f0(c) * a + b)
                        + (1.0 - GLTF_DIELECTRIC_F0) * m.c_diff(c) * irr[c] * d;
                }
            }
            SplitSumVariant::SampleRenderer => {
                // getIBLGGXFresnel(n, v, roughness, F0, specularWeight = 1)
                let fresnel = |f0: f64| {
                    let fr = (1.0 - m.roughness).max(f0) - f0;
                    let k_s = f0 + fr * (1.0 - nv).powi(5);
                    let fss_ess = k_s * a + b;
                    let ems = 1.0 - (a + b);
                    let f_avg = f0 + (1.0 - f0) / 21.0;
                    fss_ess + ems * fss_ess * f_avg / (1.0 - f_avg * ems)
                };
                let fd = fresnel(GLTF_DIELECTRIC_F0);
                for c in 0..3 {
                    let base = m.base[c];
                    let diffuse = irr[c] * base;
                    let dielectric = (1.0 - fd) * diffuse + fd * spec[c];
                    let metal = fresnel(base) * spec[c];
                    out[c] = (1.0 - m.metallic) * dielectric + m.metallic * metal;
                }
            }
        }
        out
    }

    /// The mip level (fractional) holding perceptual roughness `r`.
    fn mapping_lod(&self, r: f64, levels: usize) -> f64 {
        match self.mapping {
            RoughnessMapping::Linear => r * (levels - 1) as f64,
            // lod = r (2 - r), the inverse of the cmgen mapping's roughness
            RoughnessMapping::Cmgen => r * (2.0 - r) * (levels - 1) as f64,
        }
    }

    /// The prefiltered radiance at direction `d` (ifd frame), trilinear.
    fn radiance(&self, d: DVec3, lod: f64) -> [f64; 3] {
        let w = self.cube_dir(d);
        let lod = lod.clamp(0.0, (self.chain.len() - 1) as f64);
        let m0 = lod.floor() as usize;
        let m1 = (m0 + 1).min(self.chain.len() - 1);
        let t = lod - m0 as f64;
        let (a, b) = (lookup(&self.chain[m0], w), lookup(&self.chain[m1], w));
        [0, 1, 2].map(|c| (1.0 - t) * a[c] + t * b[c])
    }

    /// A direction of ifd's (rotated) frame as the baked cube's world
    /// direction (y up): undo the environment's rotation about `z`, then the
    /// inverse of `ifd_ibl::world_to_ifd`.
    fn cube_dir(&self, d: DVec3) -> [f64; 3] {
        let (s, c) = (-self.rotation).sin_cos();
        let e = [c * d.x - s * d.y, s * d.x + c * d.y, d.z];
        [-e[0], e[2], -e[1]]
    }

    /// `(A, B)` of the DFG table, bilinear (texel centres at `(i + 0.5) / N`).
    fn dfg_at(&self, nv: f64, r: f64) -> (f64, f64) {
        let n = self.dfg_size;
        let (x, y) = (nv * n as f64 - 0.5, r * n as f64 - 0.5);
        let x = x.clamp(0.0, (n - 1) as f64);
        let y = y.clamp(0.0, (n - 1) as f64);
        let (i0, j0) = (x.floor() as usize, y.floor() as usize);
        let (i1, j1) = ((i0 + 1).min(n - 1), (j0 + 1).min(n - 1));
        let (fx, fy) = (x - i0 as f64, y - j0 as f64);
        let at = |i: usize, j: usize| self.dfg[j * n + i];
        let mix = |k: usize| {
            let top = (1.0 - fx) * f64::from(at(i0, j0)[k]) + fx * f64::from(at(i1, j0)[k]);
            let bottom = (1.0 - fx) * f64::from(at(i0, j1)[k]) + fx * f64::from(at(i1, j1)[k]);
            (1.0 - fy) * top + fy * bottom
        };
        (mix(0), mix(1))
    }

    /// `D(n . v)`, linear between the table's entries.
    fn diffuse_at(&self, nv: f64) -> f64 {
        let x = (nv * DIFFUSE_ENTRIES as f64 - 0.5).clamp(0.0, (DIFFUSE_ENTRIES - 1) as f64);
        let i0 = x.floor() as usize;
        let i1 = (i0 + 1).min(DIFFUSE_ENTRIES - 1);
        let t = x - i0 as f64;
        (1.0 - t) * self.diffuse[i0] + t * self.diffuse[i1]
    }
}

/// `int (1 - w) cos / pi dl` over the hemisphere for `n . v = nv`, `w = (1 -
/// v . h)^5`: Gauss-Legendre in `cos theta_l` (the integrand is smooth) and
/// the midpoint rule in `phi` over half the circle (symmetric about the plane
/// of `v`); exact to about 1e-12 for a constant environment.
fn diffuse_albedo(nv: f64) -> f64 {
    const NT: usize = 48;
    const NP: usize = 96;
    let v = DVec3::new((1.0 - nv * nv).max(0.0).sqrt(), 0.0, nv);
    let (x, w) = ifd_sphere::gauss_legendre(NT);
    let mut sum = 0.0;
    for (xi, wi) in x.iter().zip(&w) {
        let ct = 0.5 * (1.0 + xi);
        let st = (1.0 - ct * ct).max(0.0).sqrt();
        for p in 0..NP {
            let phi = PI * (p as f64 + 0.5) / NP as f64;
            let l = DVec3::new(st * phi.cos(), st * phi.sin(), ct);
            let h = (l + v).normalize_or_zero();
            let fw = (1.0 - v.dot(h).clamp(0.0, 1.0)).powi(5);
            // dl = d(cos) dphi; x in [-1, 1] -> cos in [0, 1]: factor 1/2;
            // phi over [0, pi], doubled
            sum += 0.5 * wi * (PI / NP as f64) * 2.0 * (1.0 - fw) * ct / PI;
        }
    }
    sum
}

/// Bilinear lookup of a cube level in world direction `d` (y up), seamless
/// as engines filter cube maps: a tap beyond the face's edge reads the
/// texel of the neighbouring face in that direction.
fn lookup(level: &CubeLevel, d: [f64; 3]) -> [f64; 3] {
    let (face, s, t) = face_coords(d);
    let n = level.size;
    let (x, y) = (s * n as f64 - 0.5, t * n as f64 - 0.5);
    let (i0, j0) = (x.floor(), y.floor());
    let (fx, fy) = (x - i0, y - j0);
    let tap = |di: f64, dj: f64| -> [f32; 3] {
        let (i, j) = (i0 + di, j0 + dj);
        if i >= 0.0 && j >= 0.0 && i < n as f64 && j < n as f64 {
            return level.get(face, i as usize, j as usize);
        }
        // the texel centre's direction, off the face, on the OpenGL table
        let sc = 2.0 * (i + 0.5) / n as f64 - 1.0;
        let tc = 2.0 * (j + 0.5) / n as f64 - 1.0;
        let (f2, s2, t2) = face_coords(ifd_sphere::cube_face_direction(face, sc, tc));
        let i2 = ((s2 * n as f64) as usize).min(n - 1);
        let j2 = ((t2 * n as f64) as usize).min(n - 1);
        level.get(f2, i2, j2)
    };
    let (a, b, c, e) = (tap(0.0, 0.0), tap(1.0, 0.0), tap(0.0, 1.0), tap(1.0, 1.0));
    [0, 1, 2].map(|k| {
        let top = (1.0 - fx) * f64::from(a[k]) + fx * f64::from(b[k]);
        let bottom = (1.0 - fx) * f64::from(c[k]) + fx * f64::from(e[k]);
        (1.0 - fy) * top + fy * bottom
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diffuse_albedo_is_the_brute_force_integral() {
        // an independent midpoint rule over (theta, phi)
        for nv in [0.05, 0.3, 0.7, 1.0] {
            let v = DVec3::new((1.0f64 - nv * nv).sqrt(), 0.0, nv);
            let (nt, np) = (400, 800);
            let mut s = 0.0;
            for i in 0..nt {
                let t = (i as f64 + 0.5) * 0.5 * PI / nt as f64;
                for j in 0..np {
                    let p = (j as f64 + 0.5) * 2.0 * PI / np as f64;
                    let l = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
                    let h = (l + v).normalize();
                    let w = (1.0 - v.dot(h)).powi(5);
                    s += (1.0 - w) * t.cos() / PI * t.sin();
                }
            }
            s *= (0.5 * PI / nt as f64) * (2.0 * PI / np as f64);
            let got = diffuse_albedo(nv);
            assert!((got - s).abs() < 1e-5, "{nv}: {got} vs {s}");
            assert!(got < 1.0 && got > 0.9 * (1.0 - 0.04), "{nv}: {got}");
        }
    }

    #[test]
    fn a_uniform_environment_is_shaded_exactly() {
        // for a constant environment the split sum is exact: the consistent
        // variant gives the BRDF's directional albedo (f0 A + B + 0.96
        // c_diff D), every texel of every level being the constant
        let img = ifd_image::Image::from_vec(16, 8, 3, vec![1.0; 16 * 8 * 3]).unwrap();
        let env = EnvMap::new(img, 20.0).unwrap();
        let ss = SplitSum::bake(&env, 16).unwrap();
        let m = GltfMaterial::new([0.9, 0.5, 0.2], 0.3, 0.6).unwrap();
        let n = [0.0, 0.0, 1.0];
        for nv in [0.2f64, 0.6, 0.95] {
            let wo = [(1.0 - nv * nv).sqrt(), 0.0, nv];
            let got = ss.shade(SplitSumVariant::Consistent, &m, n, wo);
            let (a, b) = ifd_ibl::dfg(nv, 0.6);
            for (c, g) in got.iter().enumerate() {
                let want = m.f0(c) * a + b + 0.96 * m.c_diff(c) * diffuse_albedo(nv);
                // the tables' interpolation only
                assert!((g - want).abs() < 2e-3, "{nv} {c}: {g} vs {want}");
            }
        }
    }
}

#[cfg(test)]
mod frame_tests {
    use super::*;

    #[test]
    fn the_mirror_level_looks_up_the_environment_in_its_frame() {
        // a smooth map, different along every axis, rotated: mip 0 (the
        // mirror) at a direction is the rotated map there (a reflected or
        // mis-rotated lookup errs by about 1)
        let (w, h) = (128, 64);
        let f = |x: f64, y: f64, z: f64| 2.0 + 0.9 * x + 0.6 * y + 0.3 * z;
        let mut data = Vec::with_capacity(w * h * 3);
        for v in 0..h {
            let t = PI * (v as f64 + 0.5) / h as f64;
            for u in 0..w {
                let p = 2.0 * PI * (u as f64 + 0.5) / w as f64;
                let val = f(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()) as f32;
                data.extend([val, val, val]);
            }
        }
        let rot = 40.0f64;
        let env = EnvMap::new(ifd_image::Image::from_vec(w, h, 3, data).unwrap(), rot).unwrap();
        let ss = SplitSum::bake(&env, 64).unwrap();
        let mut worst = 0.0f64;
        for k in 0..200 {
            let z = -0.9 + 1.8 * ((k * 37) % 200) as f64 / 200.0;
            let p = 0.7 + k as f64 * 2.39996;
            let r = (1.0 - z * z).sqrt();
            let d = DVec3::new(r * p.cos(), r * p.sin(), z);
            // the rotated map: E'(d) = E(Rz(-a) d)
            let a = -rot.to_radians();
            let e = [
                a.cos() * d.x - a.sin() * d.y,
                a.sin() * d.x + a.cos() * d.y,
                d.z,
            ];
            let want = f(e[0], e[1], e[2]);
            let got = ss.radiance(d, 0.0);
            worst = worst.max((got[0] - want).abs());
        }
        assert!(worst < 0.05, "{worst}");
    }
}
