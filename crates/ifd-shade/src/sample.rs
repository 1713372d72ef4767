//! Importance sampling of BRDF slices for Monte Carlo references: each model's
//! sampler draws `wi` for a view `wo` (local frame) from two uniforms and
//! reports its density (per solid angle), for multiple importance sampling.
//!
//! | model | strategy | `pdf(wi)` |
//! |---|---|---|
//! | Lambert, MERL | cosine | `max(wi_z, 0) / pi` |
//! | Phong | the lobe about `r`: `cos = u1^(1/(s+1))` | `(s+1)/(2 pi) max(r.wi, 0)^s` |
//! | Blinn-Phong | `h` about `n` with `(s+1)/(2 pi) h_z^s`, `wi = reflect(wo, h)` | `(s+1)/(2 pi) h_z^s / (4 wo.h)` |
//! | GGX | visible normals (Heitz 2018) | `G1(wo) D(h) / (4 wo_z)` |
//! | glTF | visible GGX normals with probability `p = (1 + metallic) / 2`, else cosine | `p pdf_GGX + (1 - p) max(wi_z, 0) / pi` |
//! | Ward | Walter's half-vector sampling (2005) | `exp(-tan^2 t_h (c^2/ax^2 + s^2/ay^2)) / (pi ax ay cos^3 t_h) / (4 wo.h)` |

use std::f64::consts::PI;

use crate::brdf::{Brdf, Model};
use glam::DVec3;

use crate::brdf::{half, unit_or_z};

/// `wo` mirrored about `h`: `2 (wo . h) h - wo`.
fn reflect(wo: [f64; 3], h: [f64; 3]) -> [f64; 3] {
    let (wo, h) = (DVec3::from(wo), DVec3::from(h));
    (2.0 * wo.dot(h) * h - wo).to_array()
}

/// A direction at angle `acos(c)` from `axis`, azimuth `phi` around it.
fn around(axis: [f64; 3], c: f64, phi: f64) -> [f64; 3] {
    let s = (1.0 - c * c).max(0.0).sqrt();
    // an orthonormal basis around the axis (Duff et al. 2017)
    let sign = if axis[2] >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + axis[2]);
    let b = axis[0] * axis[1] * a;
    let t = [
        1.0 + sign * axis[0] * axis[0] * a,
        sign * b,
        -sign * axis[0],
    ];
    let bt = [b, sign + axis[1] * axis[1] * a, -axis[1]];
    let (sp, cp) = phi.sin_cos();
    [
        s * cp * t[0] + s * sp * bt[0] + c * axis[0],
        s * cp * t[1] + s * sp * bt[1] + c * axis[1],
        s * cp * t[2] + s * sp * bt[2] + c * axis[2],
    ]
}

/// Smith's `Lambda` of GGX for a direction.
fn ggx_lambda(ax: f64, ay: f64, v: [f64; 3]) -> f64 {
    let t = ((ax * v[0]).powi(2) + (ay * v[1]).powi(2)) / (v[2] * v[2]);
    0.5 * (-1.0 + (1.0 + t).sqrt())
}

/// The density of [`ggx_visible`]: `G1(wo) D(h) / (4 wo_z)`.
fn ggx_visible_pdf(ax: f64, ay: f64, wi: [f64; 3], wo: [f64; 3], h: [f64; 3], oh: f64) -> f64 {
    if wi[2] <= 0.0 || wo[2] <= 0.0 || oh <= 0.0 {
        return 0.0;
    }
    let g1 = 1.0 / (1.0 + ggx_lambda(ax, ay, wo));
    g1 * ggx_d(ax, ay, h) / (4.0 * wo[2])
}

fn ggx_d(ax: f64, ay: f64, h: [f64; 3]) -> f64 {
    let q = (h[0] / ax).powi(2) + (h[1] / ay).powi(2) + h[2] * h[2];
    1.0 / (PI * ax * ay * q * q)
}

/// Heitz's (2018) sampling of the GGX normals visible from `wo`, `wi`
/// reflected about the drawn normal; `None` for a view below the horizon.
fn ggx_visible(ax: f64, ay: f64, wo: [f64; 3], u0: f64, phi: f64) -> Option<[f64; 3]> {
    if wo[2] <= 0.0 {
        return None;
    }
    let vh = unit_or_z(DVec3::new(ax * wo[0], ay * wo[1], wo[2])).to_array();
    let lensq = vh[0] * vh[0] + vh[1] * vh[1];
    let t1 = if lensq > 0.0 {
        let l = lensq.sqrt();
        [-vh[1] / l, vh[0] / l, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let t2 = [
        vh[1] * t1[2] - vh[2] * t1[1],
        vh[2] * t1[0] - vh[0] * t1[2],
        vh[0] * t1[1] - vh[1] * t1[0],
    ];
    let r = u0.sqrt();
    let (a, mut b) = (r * phi.cos(), r * phi.sin());
    let s = 0.5 * (1.0 + vh[2]);
    b = (1.0 - s) * (1.0 - a * a).max(0.0).sqrt() + s * b;
    let c = (1.0 - a * a - b * b).max(0.0).sqrt();
    let nh = [
        a * t1[0] + b * t2[0] + c * vh[0],
        a * t1[1] + b * t2[1] + c * vh[1],
        a * t1[2] + b * t2[2] + c * vh[2],
    ];
    let h = unit_or_z(DVec3::new(ax * nh[0], ay * nh[1], nh[2].max(0.0))).to_array();
    Some(reflect(wo, h))
}

impl Brdf {
    /// Draws `wi` for view `wo` from uniforms `u = (u1, u2)` in `[0, 1)`;
    /// `None` when the draw falls below the horizon of a model that vanishes
    /// there (the sample then contributes 0).
    #[must_use]
    pub fn sample(&self, wo: [f64; 3], u: [f64; 2]) -> Option<[f64; 3]> {
        let phi = 2.0 * PI * u[1];
        let wi = match *self.model() {
            Model::Lambert | Model::Merl(_) => around([0.0, 0.0, 1.0], u[0].sqrt(), phi),
            Model::Phong { s } => {
                let r = [-wo[0], -wo[1], wo[2]];
                return Some(around(r, u[0].powf(1.0 / (s + 1.0)), phi));
            }
            Model::BlinnPhong { s, .. } => {
                let h = around([0.0, 0.0, 1.0], u[0].powf(1.0 / (s + 1.0)), phi);
                reflect(wo, h)
            }
            Model::Ggx { ax, ay, .. } => ggx_visible(ax, ay, wo, u[0], phi)?,
            Model::Gltf(_) | Model::GltfLobes { .. } => {
                let (alpha, p) = self.gltf_lobe_choice();
                if u[0] < p {
                    ggx_visible(alpha, alpha, wo, u[0] / p, phi)?
                } else {
                    around([0.0, 0.0, 1.0], ((u[0] - p) / (1.0 - p)).sqrt(), phi)
                }
            }
            Model::Ward { ax, ay } => {
                // phi_h = atan(ay/ax tan(2 pi u2)) in the quadrant of 2 pi u2
                let ph = (ay * phi.sin()).atan2(ax * phi.cos());
                let (sp, cp) = ph.sin_cos();
                let k = cp * cp / (ax * ax) + sp * sp / (ay * ay);
                let tan2 = -(1.0 - u[0]).max(f64::MIN_POSITIVE).ln() / k;
                let ch = 1.0 / (1.0 + tan2).sqrt();
                let sh = (1.0 - ch * ch).max(0.0).sqrt();
                let h = [sh * cp, sh * sp, ch];
                reflect(wo, h)
            }
        };
        (wi[2] > 0.0).then_some(wi)
    }

    /// The glTF BRDF's GGX `alpha` and the probability of drawing from its
    /// specular lobe rather than the cosine: `(1 + metallic) / 2` (metals
    /// have no diffuse part), one half for the parts.
    fn gltf_lobe_choice(&self) -> (f64, f64) {
        match *self.model() {
            Model::Gltf(m) => (m.alpha(), 0.5 * (1.0 + m.metallic)),
            Model::GltfLobes { roughness } => (roughness * roughness, 0.5),
            _ => unreachable!("glTF models only"),
        }
    }

    /// The density (per solid angle) with which [`Self::sample`] draws `wi`.
    #[must_use]
    pub fn pdf(&self, wi: [f64; 3], wo: [f64; 3]) -> f64 {
        let h_and_oh = || {
            let h = half(wi, wo);
            (h, DVec3::from(wo).dot(DVec3::from(h)))
        };
        match *self.model() {
            Model::Lambert | Model::Merl(_) => wi[2].max(0.0) / PI,
            Model::Phong { s } => {
                let rw = -wo[0] * wi[0] - wo[1] * wi[1] + wo[2] * wi[2];
                (s + 1.0) / (2.0 * PI) * rw.max(0.0).powf(s)
            }
            Model::BlinnPhong { s, .. } => {
                let (h, oh) = h_and_oh();
                if wi[2] <= 0.0 || h[2] <= 0.0 || oh <= 0.0 {
                    return 0.0;
                }
                (s + 1.0) / (2.0 * PI) * h[2].powf(s) / (4.0 * oh)
            }
            Model::Ggx { ax, ay, .. } => {
                let (h, oh) = h_and_oh();
                ggx_visible_pdf(ax, ay, wi, wo, h, oh)
            }
            Model::Gltf(_) | Model::GltfLobes { .. } => {
                let (alpha, p) = self.gltf_lobe_choice();
                let (h, oh) = h_and_oh();
                p * ggx_visible_pdf(alpha, alpha, wi, wo, h, oh) + (1.0 - p) * wi[2].max(0.0) / PI
            }
            Model::Ward { ax, ay } => {
                let (h, oh) = h_and_oh();
                if wi[2] <= 0.0 || h[2] <= 0.0 || oh <= 0.0 {
                    return 0.0;
                }
                let c2 = h[2] * h[2];
                let e = ((h[0] / ax).powi(2) + (h[1] / ay).powi(2)) / c2;
                (-e).exp() / (PI * ax * ay * c2 * h[2]) / (4.0 * oh)
            }
        }
    }
}
