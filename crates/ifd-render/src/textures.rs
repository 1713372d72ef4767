//! Spatially varying BRDFs (the ISD paper's Fig. 9): albedo and roughness
//! maps over the surface's texture coordinates, as glTF reads them.

use ifd_image::Image;
use ifd_shade::Brdf;
use ifd_shade::Material;
use ifd_shade::{LobeTable, default_theta_entries};

use crate::error::{RenderError, Result};

/// An image read as a function of texture coordinates.
#[derive(Clone, Debug)]
pub struct Texture {
    img: Image,
}

impl Texture {
    /// Wraps an image (any channel count).
    ///
    /// # Errors
    /// [`RenderError::Parameter`] for NaN/infinite or negative samples.
    pub fn new(img: Image, what: &'static str) -> Result<Self> {
        if let Some(i) = img.data().iter().position(|v| !v.is_finite() || *v < 0.0) {
            return Err(RenderError::Parameter {
                name: what,
                value: format!("{}x{}", img.width(), img.height()),
                reason: format!(
                    "sample {i} is {} (finite non-negative values expected)",
                    img.data()[i]
                ),
            });
        }
        Ok(Self { img })
    }

    /// Bilinear value of channel `c` (the last channel when `c` is beyond).
    #[must_use]
    pub fn sample(&self, uv: [f64; 2], c: usize) -> f64 {
        let (w, h, ch) = (self.img.width(), self.img.height(), self.img.channels());
        let c = c.min(ch - 1);
        let x = uv[0].rem_euclid(1.0) * w as f64 - 0.5;
        let y = (uv[1].clamp(0.0, 1.0) * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let xi = |k: f64| ((x0 + k) as i64).rem_euclid(w as i64) as usize;
        let yi = |k: f64| ((y0 + k) as usize).min(h - 1);
        let v = |xx: usize, yy: usize| f64::from(self.img.data()[(yy * w + xx) * ch + c]);
        (1.0 - fy) * ((1.0 - fx) * v(xi(0.0), yi(0.0)) + fx * v(xi(1.0), yi(0.0)))
            + fy * ((1.0 - fx) * v(xi(0.0), yi(1.0)) + fx * v(xi(1.0), yi(1.0)))
    }

    /// The smallest and largest value of channel 0.
    #[must_use]
    pub fn range(&self) -> (f64, f64) {
        let ch = self.img.channels();
        self.img
            .data()
            .iter()
            .step_by(ch)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(f64::from(*v)), b.max(f64::from(*v)))
            })
    }
}

/// The maps of a spatially varying BRDF.
///
/// Spatially varying BRDFs (the ISD paper's Fig. 9): albedo and roughness
/// maps over the surface's texture coordinates, as glTF reads them.
///
/// - **Albedo** (RGB, an 8-bit PNG is sRGB-encoded, as glTF's base colour;
///   float formats are linear): multiplies the BRDF. The slice is linear in
///   its albedo, so every method multiplies its result per channel, exactly.
/// - **Roughness** (the image's first channel, linear; `alpha = roughness^2`
///   as glTF defines it) of an isotropic GGX or Ward BRDF, clamped to
///   `[0.001, 1]`. glTF packs roughness into the green channel of its
///   metallic-roughness texture: extract that channel first.
///   The oracle and Monte Carlo evaluate the BRDF of each point's `alpha`;
///   ISD shades with a family of lobe tables at `K` roughness values spread
///   evenly over the map's range and blends the two nearest linearly in
///   roughness (the result is linear in the weights, so this is the weights'
///   interpolation; its error is measured against the oracle in the tests).
///
/// - **Normals** (RGB, linear: tangent-space normals encoded as `(n + 1) / 2`,
///   glTF's and OpenGL's convention): `x` along the tangent `T` (`dP/du`
///   made orthogonal to the normal `N`), `y` along `B = N x T`, `z` along
///   `N`. The shading frame of every method (and the mirror's reflection)
///   uses the perturbed normal ([`perturb_normal`]).
///
/// Lookups are bilinear, wrapping in `u` and clamped in `v` (`v = 0` at the top
/// row of the image).
#[derive(Clone, Debug, Default)]
pub struct SurfaceMaps {
    /// Albedo (linear RGB or grey).
    pub albedo: Option<Texture>,
    /// Roughness (channel 0).
    pub roughness: Option<Texture>,
    /// Tangent-space normals (RGB).
    pub normal: Option<Texture>,
}

/// The normal `n` (unit) of a surface with tangent `dpdu` perturbed by the
/// normal map at `uv` (see the module docs). Falls back to `n` where the
/// tangent is parallel to the normal or zero (a pole) or the map's normal
/// has no length.
#[must_use]
pub fn perturb_normal(
    n: glam::DVec3,
    dpdu: glam::DVec3,
    uv: [f64; 2],
    map: &Texture,
) -> glam::DVec3 {
    let Some(t) = (dpdu - dpdu.dot(n) * n).try_normalize() else {
        return n;
    };
    let b = n.cross(t);
    let m = [0, 1, 2].map(|c| 2.0 * map.sample(uv, c) - 1.0);
    (m[0] * t + m[1] * b + m[2] * n)
        .try_normalize()
        .unwrap_or(n)
}

/// `alpha` of a roughness value.
#[must_use]
pub fn alpha_of(roughness: f64) -> f64 {
    (roughness * roughness).clamp(1e-3, 1.0)
}

/// ISD materials at `K` roughness values (see the module docs).
#[derive(Debug)]
pub struct RoughnessFamily {
    roughness: Vec<f64>,
    materials: Vec<Material>,
}

impl RoughnessFamily {
    /// Tables for `brdf` (isotropic GGX or Ward) at `count >= 2` roughness
    /// values spread evenly over `[lo, hi]`, degree `l_max`.
    ///
    /// # Errors
    /// [`RenderError::Shade`] for BRDFs without roughness; table errors.
    pub fn build(
        brdf: &Brdf,
        l_max: usize,
        (lo, hi): (f64, f64),
        count: usize,
        progress: &dyn Fn(usize, usize),
    ) -> Result<Self> {
        // the smallest roughness a table is built for (alpha 1e-3); a range
        // wholly below it (an all-zero roughness map) is that one value
        let lo = lo.max(alpha_of(0.0).sqrt());
        let hi = hi.max(lo + 1e-6);
        // one roughness (a single-material asset): two tables bracket it
        let count = if hi - lo < 1e-3 { 2 } else { count.max(2) };
        let mut roughness = Vec::new();
        let mut materials = Vec::new();
        for k in 0..count {
            let r = lo + (hi - lo) * k as f64 / (count - 1) as f64;
            let b = brdf.with_roughness(alpha_of(r))?;
            // a lobe narrower than degree L resolves moves with theta_o as a
            // lobe of width pi / (L + 1): eight entries across that width
            // suffice (4 (L + 1) over theta_o), however narrow the BRDF
            let nt = default_theta_entries(&b).min(4 * (l_max + 1)).max(16);
            let t = LobeTable::build(&b, l_max, nt, 1, &|_, _| {})?;
            materials.push(Material::new(&b, l_max, Some(t))?);
            roughness.push(r);
            progress(k + 1, count);
        }
        Ok(Self {
            roughness,
            materials,
        })
    }

    /// The two materials around `roughness` and the weight of the second.
    #[must_use]
    pub fn locate(&self, roughness: f64) -> (&Material, &Material, f64) {
        let r = &self.roughness;
        let n = r.len();
        let x = roughness.clamp(r[0], r[n - 1]);
        let k = r.partition_point(|v| *v <= x).clamp(1, n - 1) - 1;
        let w = ((x - r[k]) / (r[k + 1] - r[k])).clamp(0.0, 1.0);
        (&self.materials[k], &self.materials[k + 1], w)
    }

    /// The roughness values of the materials, increasing.
    #[must_use]
    pub fn roughness(&self) -> &[f64] {
        &self.roughness
    }

    /// The materials, one per roughness value.
    #[must_use]
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    /// The degree of the materials.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.materials[0].l_max()
    }
}
