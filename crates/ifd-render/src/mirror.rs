//! Anti-aliased mirror reflections of an environment map (ISD Sec. 6.2,
//! Eq. 26-29) off any [`Reflector`]: a scene's surface, bumpy through a
//! normal map ([`SceneMirror`], `ifd render --brdf mirror`), or the studies'
//! procedural bumps (`ifd-paper isd-mirror`).

use std::f64::consts::PI;

use glam::DVec3;
use ifd_image::Image;
use ifd_shade::Environment;
use ifd_sphere::pi_l;
use ifd_sphere::vmf_factors;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::envmap::EnvMap;
use crate::error::{RenderError, Result};
use crate::scene::Scene;
use crate::textures::{Texture, perturb_normal};

/// What a mirror reflects at image point `(x, y)` (pixels, not centres).
pub trait Reflector: Sync {
    /// The mirror-reflected direction and the hit point, or `Err(d)` with
    /// the ray's own direction when it misses the mirror.
    ///
    /// # Errors
    /// `Err(d)`, the ray's direction, when the ray misses (not a failure:
    /// the pixel sees the environment).
    fn trace(&self, camera: &Camera, x: f64, y: f64) -> std::result::Result<(DVec3, DVec3), DVec3>;
}

/// A scene's surface as a perfect mirror, its normals perturbed by a
/// tangent-space normal map when there is one
/// ([`crate::textures::perturb_normal`]).
#[derive(Clone, Copy, Debug)]
pub struct SceneMirror<'a> {
    /// The surface.
    pub scene: &'a Scene,
    /// Tangent-space normals over the surface's texture coordinates.
    pub normal_map: Option<&'a Texture>,
}

impl Reflector for SceneMirror<'_> {
    fn trace(&self, camera: &Camera, x: f64, y: f64) -> std::result::Result<(DVec3, DVec3), DVec3> {
        let (o, d) = camera.ray(x, y);
        let Some(hit) = self.scene.intersect(o, d) else {
            return Err(d);
        };
        let n = match (self.normal_map, hit.uv) {
            (Some(t), Some(uv)) => perturb_normal(hit.n, hit.dpdu, uv, t),
            _ => hit.n,
        };
        Ok((d - 2.0 * d.dot(n) * n, hit.p))
    }
}

/// The pixel filter `g`: a Gaussian of `sigma` pixels over the square
/// `|dx|, |dy| <= radius`, normalised.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelFilter {
    /// Standard deviation in pixels.
    pub sigma: f64,
    /// Half-width of the square support in pixels.
    pub radius: f64,
}

impl Default for PixelFilter {
    fn default() -> Self {
        Self {
            sigma: 0.5,
            radius: 1.0,
        }
    }
}

impl PixelFilter {
    /// The (unnormalised) weight at offset `(dx, dy)`.
    #[must_use]
    pub fn weight(&self, dx: f64, dy: f64) -> f64 {
        (-(dx * dx + dy * dy) / (2.0 * self.sigma * self.sigma)).exp()
    }

    /// The variance per axis of the truncated Gaussian, `sigma^2 (1 - 2 a
    /// phi(a) / (2 Phi(a) - 1))` with `a = radius / sigma`, by quadrature.
    #[must_use]
    pub fn variance(&self) -> f64 {
        let (x, w) = ifd_sphere::gauss_legendre(64);
        let (mut m0, mut m2) = (0.0, 0.0);
        for (t, wt) in x.iter().zip(&w) {
            let d = t * self.radius;
            let g = (-(d * d) / (2.0 * self.sigma * self.sigma)).exp() * wt;
            m0 += g;
            m2 += g * d * d;
        }
        m2 / m0
    }
}

/// A mip pyramid of an equirectangular map (exact solid-angle averages of
/// 2x2 texels per level), looked up by footprint: the fallback of ISD's
/// filter for footprints too narrow for a band-limited lobe.
#[derive(Debug)]
pub struct EnvPyramid {
    levels: Vec<EnvMap>,
}

impl EnvPyramid {
    /// Levels halving the map while its height stays even and at least 4.
    ///
    /// # Errors
    /// As [`EnvMap::downsampled`].
    pub fn new(env: &EnvMap) -> Result<Self> {
        let mut levels = vec![env.clone()];
        loop {
            let last = &levels[levels.len() - 1];
            let (w, h) = (last.image().width(), last.image().height());
            if h % 2 != 0 || h / 2 < 4 {
                break;
            }
            let next = last.downsampled(w / 2, h / 2)?;
            levels.push(next);
        }
        Ok(Self { levels })
    }

    /// The map filtered by an isotropic footprint of `sigma` radians at `d`:
    /// bilinear lookups in the two levels whose texels bracket `sqrt(12)
    /// sigma` (a box of the Gaussian's variance), blended by the fraction of
    /// the level; `tmp` is scratch of `C` values.
    pub fn lookup(&self, d: DVec3, sigma: f64, tmp: &mut [f64], out: &mut [f64]) {
        let h0 = self.levels[0].image().height() as f64;
        let lod = ((12f64.sqrt() * sigma) / (PI / h0)).max(1.0).log2();
        let top = (self.levels.len() - 1) as f64;
        let lod = lod.min(top);
        let i = lod.floor() as usize;
        let t = lod - i as f64;
        let ch = self.levels[0].channels();
        self.levels[i].lookup_bilinear(d.to_array(), out);
        if t > 0.0 && i + 1 < self.levels.len() {
            self.levels[i + 1].lookup_bilinear(d.to_array(), tmp);
            for c in 0..ch {
                out[c] = (1.0 - t) * out[c] + t * tmp[c];
            }
        }
    }
}

/// ISD's anti-aliasing filter (Eq. 29) for one environment.
#[derive(Debug)]
pub struct IsdFilter {
    /// The environment's SH truncated to each degree `0..=L`.
    envs: Vec<Environment>,
    /// The fallback for narrow footprints.
    pyramid: EnvPyramid,
    /// The footprint (radians) below which a pixel is a direct lookup.
    threshold: f64,
}

impl IsdFilter {
    /// The filter at degree `l_max` (the map's exact SH), with the lookup
    /// threshold `pi / L`.
    ///
    /// # Errors
    /// Degrees beyond the SH code's limit; `l_max = 0`.
    pub fn new(env: &EnvMap, l_max: usize) -> Result<Self> {
        if l_max == 0 {
            return Err(RenderError::Parameter {
                name: "--lmax",
                value: "0".into(),
                reason: "needs L >= 1".into(),
            });
        }
        let sh = env.sh(l_max)?;
        let envs = (0..=l_max)
            .map(|l| Ok(Environment::new(sh.resized(l)?)?))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            envs,
            pyramid: EnvPyramid::new(env)?,
            threshold: PI / l_max as f64,
        })
    }

    /// The footprint below which a pixel is a direct lookup (`pi / L`).
    #[must_use]
    pub fn threshold(&self) -> f64 {
        self.threshold
    }

    /// The degree `L`.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.envs.len() - 1
    }

    /// Eq. 29 at direction `d` for a footprint of `sigma_w` radians
    /// (`>= threshold`): `out[c]`. `y` and `bands` are scratch of `(L + 1)^2`
    /// and `(L + 1) C` values.
    pub fn filter(
        &self,
        d: DVec3,
        sigma_w: f64,
        y: &mut [f64],
        bands: &mut [f64],
        out: &mut [f64],
    ) {
        let l_max = self.l_max();
        // the degree where Lambda_l ~ exp(-l^2 sigma^2 / 2) < 1e-4
        let l = ((4.3 / sigma_w).ceil() as usize).clamp(1, l_max);
        let env = &self.envs[l];
        let ch = env.channels();
        let lambda = vmf_factors(1.0 / (sigma_w * sigma_w), l);
        env.bands_into(d.to_array(), y, bands);
        out[..ch].fill(0.0);
        for (k, lam) in lambda.iter().enumerate() {
            let f = lam / pi_l(k);
            for c in 0..ch {
                out[c] += f * bands[k * ch + c];
            }
        }
    }
}

/// How a pixel is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AaMethod {
    /// One ray through the pixel centre (no anti-aliasing).
    Centre,
    /// `N x N` rays at cell centres of the filter's square, weighted by `g`.
    Supersample(usize),
    /// `N x N` jittered stratified rays, weighted by `g` (the reference).
    Reference(usize),
    /// ISD's filter (Eq. 29), a lookup in the map's mip pyramid below the
    /// threshold.
    Isd,
    /// ISD's filter (Eq. 29), a direct lookup below the threshold.
    IsdDirect,
}

impl AaMethod {
    /// A short name: `none`, `ss4x4`, `ref64x64`, `isd`.
    #[must_use]
    pub fn name(&self) -> String {
        match self {
            Self::Centre => "none".into(),
            Self::Supersample(n) => format!("ss{n}x{n}"),
            Self::Reference(n) => format!("ref{n}x{n}"),
            Self::Isd => "isd".into(),
            Self::IsdDirect => "isd-direct".into(),
        }
    }
}

/// A rendered image.
#[derive(Debug)]
pub struct AaImage {
    /// Linear radiance.
    pub image: Image,
    /// Pixels ISD filtered by Eq. 29 (the others were direct lookups).
    pub filtered: usize,
    /// Whether each pixel's centre ray meets the mirror (row-major).
    pub mask: Vec<bool>,
}

/// What to render.
pub struct MirrorScene<'a> {
    /// The mirror.
    pub mirror: &'a dyn Reflector,
    /// The camera.
    pub camera: Camera,
    /// The environment (full resolution: looked up bilinearly).
    pub env: &'a EnvMap,
    /// The pixel filter.
    pub filter: PixelFilter,
}

/// A per-pixel seed for the reference's jitter.
fn hash(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn unit_float(h: u64) -> f64 {
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Renders the scene with `method` (`isd` needs `isd`); rows in parallel.
///
/// # Errors
/// [`RenderError::Parameter`] for `Isd` without a filter, or `N = 0`
/// supersampling.
///
/// Anti-aliased mirror reflections of an environment map (ISD Sec. 6.2,
/// Eq. 26-29) off any [`Reflector`]: a scene's surface, bumpy through a
/// normal map ([`SceneMirror`], `ifd render --brdf mirror`), or the studies'
/// procedural bumps (`ifd-paper isd-mirror`).
///
/// # What a pixel integrates
/// Eq. 26: `I(p) = int g(dp) E(r(n(p + dp), wo)) ddp`, the environment seen
/// by mirror reflection over the pixel's footprint, weighted by the pixel
/// filter `g`. Here `g` is a Gaussian of `sigma = 0.5` pixel truncated to the
/// square `|dx|, |dy| <= 1` and normalised ([`PixelFilter`]); the reference
/// integrates it with `N x N` jittered stratified samples
/// ([`AaMethod::Reference`]), supersampling with `N x N` cell centres
/// ([`AaMethod::Supersample`]), both weighted by `g`.
///
/// # ISD's filter (Eq. 27-29)
/// To first order the reflected direction is `r(p + dp) = r(p) + J dp`, with
/// `J = dr/dp` (3x2) the screen-space derivative of the reflection (the
/// paper's `H grad(n)`), here by central differences of rays `h = 0.5` pixel
/// apart, as a GPU's `dFdx`/`dFdy` would give. The pixel filter, a Gaussian
/// of covariance `s^2 I` in the pixel (`s^2 = 0.1934`, the variance of the
/// truncated `g` per axis), becomes on the sphere the anisotropic Gaussian of
/// covariance `S = s^2 J J^T` about `r(p)` (Eq. 28). Option 3 of the paper:
/// replace it by the isotropic Gaussian with the same second moment, `sigma_w^2
/// = tr(S) / 2 = s^2 (|J_x|^2 + |J_y|^2) / 2`, i.e. a von Mises-Fisher lobe of
/// `kappa = 1 / sigma_w^2`, whose convolution factors `Lambda_l`
/// ([`ifd_sphere::vmf_factors`]) give Eq. 29:
///
/// ```text
/// I(p) = sum_l Lambda_l sum_m e_l^m y_l^m(r(p)) = sum_l (Lambda_l / pi_l) Ehat_l(r(p)).
/// ```
///
/// A band-limited lobe cannot be narrower than about `pi / L`: below that
/// footprint ([`IsdFilter::threshold`]) the pixel is a direct (bilinear)
/// lookup of the map, as without anti-aliasing. Above it the sum stops at the
/// degree where `Lambda_l` has fallen below `1e-4` (`l ~ 4.3 / sigma_w`), so
/// wide footprints cost less than `(L + 1)^2` terms.
pub fn render(
    scene: &MirrorScene<'_>,
    method: AaMethod,
    isd: Option<&IsdFilter>,
) -> Result<AaImage> {
    let (w, h) = (scene.camera.width(), scene.camera.height());
    let ch = scene.env.channels();
    match method {
        AaMethod::Supersample(0) | AaMethod::Reference(0) => {
            return Err(RenderError::Parameter {
                name: "samples",
                value: "0".into(),
                reason: "needs at least 1x1".into(),
            });
        }
        AaMethod::Isd | AaMethod::IsdDirect if isd.is_none() => {
            return Err(RenderError::Parameter {
                name: "method",
                value: "isd".into(),
                reason: "needs an IsdFilter".into(),
            });
        }
        _ => {}
    }
    let var = scene.filter.variance();
    let rows: Vec<(Vec<f32>, usize, Vec<bool>)> = (0..h)
        .into_par_iter()
        .map(|yi| {
            let mut px = vec![0.0f32; w * ch];
            let mut mask = vec![false; w];
            let mut filtered = 0;
            let mut out = vec![0.0; ch];
            let mut acc = vec![0.0; ch];
            let l = isd.map_or(0, IsdFilter::l_max);
            let mut y = vec![0.0; (l + 1) * (l + 1)];
            let mut bands = vec![0.0; (l + 1) * ch];
            for xi in 0..w {
                let (cx, cy) = (xi as f64 + 0.5, yi as f64 + 0.5);
                let look = |d: DVec3, out: &mut [f64]| scene.env.lookup_bilinear(d.to_array(), out);
                let trace = |dx: f64, dy: f64| scene.mirror.trace(&scene.camera, cx + dx, cy + dy);
                let sample = |dx: f64, dy: f64, out: &mut [f64]| match trace(dx, dy) {
                    Ok((r, _)) | Err(r) => look(r, out),
                };
                // the centre ray: the mask, and the sample of Centre and ISD
                let centre = trace(0.0, 0.0);
                mask[xi] = centre.is_ok();
                match method {
                    AaMethod::Centre => match centre {
                        Ok((r, _)) | Err(r) => look(r, &mut out),
                    },
                    AaMethod::Supersample(n) | AaMethod::Reference(n) => {
                        let jitter = matches!(method, AaMethod::Reference(_));
                        let seed = hash((yi * w + xi) as u64);
                        acc.fill(0.0);
                        let mut wsum = 0.0;
                        let cell = 2.0 * scene.filter.radius / n as f64;
                        for j in 0..n {
                            for i in 0..n {
                                let (ju, jv) = if jitter {
                                    let hh = hash(seed ^ (j * n + i) as u64);
                                    (unit_float(hh), unit_float(hash(hh)))
                                } else {
                                    (0.5, 0.5)
                                };
                                let dx = -scene.filter.radius + (i as f64 + ju) * cell;
                                let dy = -scene.filter.radius + (j as f64 + jv) * cell;
                                let g = scene.filter.weight(dx, dy);
                                sample(dx, dy, &mut out);
                                for c in 0..ch {
                                    acc[c] += g * out[c];
                                }
                                wsum += g;
                            }
                        }
                        for c in 0..ch {
                            out[c] = acc[c] / wsum;
                        }
                    }
                    AaMethod::Isd | AaMethod::IsdDirect => {
                        let Some(f) = isd else {
                            unreachable!("checked above")
                        };
                        match centre {
                            Err(d) => look(d, &mut out),
                            Ok((r0, _)) => {
                                // J by central differences half a pixel apart
                                // (one-sided where a ray misses)
                                let hstep = 0.5;
                                let deriv = |a: (f64, f64), b: (f64, f64)| {
                                    let ra = trace(a.0, a.1).ok().map(|t| t.0);
                                    let rb = trace(b.0, b.1).ok().map(|t| t.0);
                                    match (ra, rb) {
                                        (Some(ra), Some(rb)) => (rb - ra) / (2.0 * hstep),
                                        (None, Some(rb)) => (rb - r0) / hstep,
                                        (Some(ra), None) => (r0 - ra) / hstep,
                                        (None, None) => DVec3::ZERO,
                                    }
                                };
                                let jx = deriv((-hstep, 0.0), (hstep, 0.0));
                                let jy = deriv((0.0, -hstep), (0.0, hstep));
                                let sigma_w = (var * (jx.length_squared() + jy.length_squared())
                                    / 2.0)
                                    .sqrt();
                                if sigma_w >= f.threshold() {
                                    filtered += 1;
                                    f.filter(r0, sigma_w, &mut y, &mut bands, &mut out);
                                } else if method == AaMethod::Isd {
                                    f.pyramid.lookup(r0, sigma_w, &mut acc, &mut out);
                                } else {
                                    look(r0, &mut out);
                                }
                            }
                        }
                    }
                }
                for c in 0..ch {
                    px[xi * ch + c] = out[c] as f32;
                }
            }
            (px, filtered, mask)
        })
        .collect();
    let mut data = Vec::with_capacity(w * h * ch);
    let mut mask = Vec::with_capacity(w * h);
    let mut filtered = 0;
    for (p, f, m) in rows {
        data.extend(p);
        mask.extend(m);
        filtered += f;
    }
    Ok(AaImage {
        image: Image::from_vec(w, h, ch, data)?,
        filtered,
        mask,
    })
}
