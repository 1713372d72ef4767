//! Spherical harmonic reflection maps for general isotropic BRDFs (SHRM
//! paper Sec. 3-4, 7.1, 7.4, App. A-C) and its Table 5.
//!
//! # Derivation (real SH, our conventions)
//! Reparameterised by the reflection vector `R` (the local `z`), an
//! isotropic transfer function `rho^(w_i, w_o)` (the BRDF times the cosine,
//! SHRM Eq. 2) is invariant under a common rotation about `z` and even in the
//! relative azimuth, so its real-SH expansion is diagonal in the order:
//!
//! ```text
//! rho^(w_i, w_o) = sum_{l, p} sum_{|m| <= min(l, p)} rho_{l p |m|} y_lm(w_i) y_pm(w_o),
//! rho_{l p m} = 2 pi int int Th_lm(t_i) Th_pm(t_o) C_m(t_i, t_o) sin t_i sin t_o dt_i dt_o,
//! C_m(t_i, t_o) = int_0^{2 pi} rho^(t_i, t_o, psi) cos(m psi) dpsi,
//! ```
//!
//! with `y_lm = c_m Th_lm(theta) trig(m phi)`, `c_m = sqrt 2` for `m != 0`
//! (App. A and C, step 1). The reflected light field at a pixel with
//! reflection vector `R = Rz(beta) Ry(alpha) z` is
//!
//! ```text
//! B(R, w_o) = sum_{p, m} B_pm(R) y_pm(w_o),   B_pm(R) = sum_l rho_{l p |m|} L^R_lm,
//! ```
//!
//! where `L^R_lm` are the coefficients of the lighting seen from the pixel's
//! frame, `h(w) = L(R_R w)`: `L^R = M(Ry(-alpha)) M(Rz(-beta)) L` band by band
//! (`M` the real-SH rotation matrices of [`ifd_sphere::ShRotation`]; the
//! `z` part in closed form, `(a, b) -> (a cos m g - b sin m g, a sin m g +
//! b cos m g)` with `g = -beta` on each `(m, -m)` pair; the `y` part shared
//! by a row, only its rows `|m| <= P` needed). The `B_pm` maps are the local
//! SHRM (Eq. 6, 14); a reflection map for a distant viewer `V` is
//! `sum_pm B_pm(R) y_pm(R_R^T V)` (Eq. 7, 12).
//!
//! # The microfacet BRDF of Eq. 11
//! `rho^ = exp(-(theta_h / sigma)^2) / (4 pi sigma^2)` with `theta_h` the
//! angle between the normal and the half vector; in the reparameterised frame
//! the normal bisects `R` and `V` (`N = (z + w_o) / |z + w_o|`), `H = (w_i +
//! w_o) / |w_i + w_o|`; zero where the light is below the surface (`N . w_i
//! <= 0`).

use std::f64::consts::PI;
use std::time::Instant;

use ifd_image::Image;
use ifd_sphere::{EquirectTransform, Negatives, Rotation, ShRotation};
use ifd_sphere::{ShEvaluator, gauss_legendre, sh_count};
use rayon::prelude::*;

use ifd_ibl::Result;

use crate::param;

/// The simplified microfacet BRDF of SHRM Eq. 11, reparameterised by `R`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    /// Roughness `sigma` (radians).
    pub sigma: f64,
}

impl Microfacet {
    /// `rho^(w_i, w_o)` in the frame whose `z` is the reflection vector.
    #[must_use]
    pub fn eval(&self, wi: [f64; 3], wo: [f64; 3]) -> f64 {
        let (wi, wo) = (glam::DVec3::from(wi), glam::DVec3::from(wo));
        let n = wo + glam::DVec3::Z;
        let nn = n.length();
        let h = wi + wo;
        let hn = h.length();
        if nn < 1e-12 || hn < 1e-12 || n.dot(wi) <= 0.0 {
            return 0.0;
        }
        let c = (n.dot(h) / (nn * hn)).clamp(-1.0, 1.0);
        let th = c.acos() / self.sigma;
        (-th * th).exp() / (4.0 * PI * self.sigma * self.sigma)
    }
}

fn dir(theta: f64, phi: f64) -> [f64; 3] {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    [st * cp, st * sp, ct]
}

/// BRDF coefficients `rho_{l p m}` (`l <= F`, `p <= P`, `0 <= m <= min(l, p)`).
#[derive(Clone, Debug)]
pub struct BrdfCoeffs {
    f: usize,
    p: usize,
    rho: Vec<f64>,
    /// `int int rho^2 dw_i dw_o` by the same quadrature.
    pub total_energy: f64,
}

impl BrdfCoeffs {
    fn idx(&self, l: usize, p: usize, m: usize) -> usize {
        (l * (self.p + 1) + p) * (self.p + 1) + m
    }

    /// `rho_{l p m}` (zero where `m > min(l, p)`).
    #[must_use]
    pub fn get(&self, l: usize, p: usize, m: usize) -> f64 {
        if l > self.f || p > self.p || m > l.min(p) {
            0.0
        } else {
            self.rho[self.idx(l, p, m)]
        }
    }

    /// Projects `brdf` (a function of local `w_i`, `w_o`, isotropic about
    /// `z`) to orders `F`, `P`; `width` is the lobe's angular width in
    /// `theta_i` (for the quadrature's grading).
    ///
    /// # Errors
    /// Degrees beyond [`ifd_sphere::MAX_DEGREE`].
    pub fn project(
        brdf: &(dyn Fn([f64; 3], [f64; 3]) -> f64 + Sync),
        width: f64,
        f: usize,
        p: usize,
    ) -> Result<Self> {
        // theta_i: panels graded from width / 8, none wider than pi / (F + 1)
        let (gx, gw) = gauss_legendre(16);
        let mut edges = vec![0.0];
        let mut e = (width / 8.0).max(1e-6);
        while e < PI {
            edges.push(e);
            e *= 1.6;
        }
        edges.push(PI);
        let dmax = PI / (f + 1) as f64;
        let mut ti = Vec::new();
        let mut wi = Vec::new();
        for pair in edges.windows(2) {
            let n = ((pair[1] - pair[0]) / dmax).ceil().max(1.0) as usize;
            let h = (pair[1] - pair[0]) / n as f64;
            for k in 0..n {
                for (x, w) in gx.iter().zip(&gw) {
                    ti.push(pair[0] + h * (k as f64 + 0.5 * (1.0 + x)));
                    wi.push(0.5 * h * w);
                }
            }
        }
        // theta_o: Gauss-Legendre over [0, pi]; psi: the midpoint rule
        let n_o = 32;
        let (ox, ow) = gauss_legendre(n_o);
        let n_psi = 64;
        let p1 = p + 1;
        let sh = ShEvaluator::new(f.max(p))?;
        // Th_lm(theta) = y_lm(theta, 0) / c_m
        let theta_fn = |t: f64| {
            let mut y = vec![0.0; sh_count(f.max(p))];
            sh.eval_into(dir(t, 0.0), &mut y);
            let mut th = vec![0.0; (f.max(p) + 1) * p1];
            for l in 0..=f.max(p) {
                for m in 0..=l.min(p) {
                    let c = if m == 0 {
                        1.0
                    } else {
                        std::f64::consts::SQRT_2
                    };
                    th[l * p1 + m] = y[l * (l + 1) + m] / c;
                }
            }
            th
        };
        let th_i: Vec<Vec<f64>> = ti.iter().map(|&t| theta_fn(t)).collect();
        let to: Vec<f64> = ox.iter().map(|x| 0.5 * PI * (1.0 + x)).collect();
        let th_o: Vec<Vec<f64>> = to.iter().map(|&t| theta_fn(t)).collect();
        // per theta_o node: C_m(t_i, t_o) for every t_i, then the sums
        let parts: Vec<(Vec<f64>, f64)> = (0..n_o)
            .into_par_iter()
            .map(|io| {
                let wo = dir(to[io], 0.0);
                let so = to[io].sin() * 0.5 * PI * ow[io];
                let mut rho = vec![0.0; (f + 1) * p1 * p1];
                let mut energy = 0.0;
                let mut cm = vec![0.0; p1];
                for (ii, &t) in ti.iter().enumerate() {
                    cm.fill(0.0);
                    let mut sq = 0.0;
                    for k in 0..n_psi {
                        let psi = 2.0 * PI * (k as f64 + 0.5) / n_psi as f64;
                        let v = brdf(dir(t, psi), wo);
                        sq += v * v;
                        for (m, c) in cm.iter_mut().enumerate() {
                            *c += v * (m as f64 * psi).cos();
                        }
                    }
                    let dpsi = 2.0 * PI / n_psi as f64;
                    let si = t.sin() * wi[ii];
                    // int over psi of rho^2, then 2 pi over the common azimuth
                    energy += 2.0 * PI * sq * dpsi * si * so;
                    for l in 0..=f {
                        for pp in 0..=p {
                            for m in 0..=l.min(pp) {
                                rho[(l * p1 + pp) * p1 + m] += 2.0
                                    * PI
                                    * th_i[ii][l * p1 + m]
                                    * th_o[io][pp * p1 + m]
                                    * cm[m]
                                    * dpsi
                                    * si
                                    * so;
                            }
                        }
                    }
                }
                (rho, energy)
            })
            .collect();
        let mut rho = vec![0.0; (f + 1) * p1 * p1];
        let mut total_energy = 0.0;
        for (r, e) in parts {
            for (a, b) in rho.iter_mut().zip(r) {
                *a += b;
            }
            total_energy += e;
        }
        Ok(Self {
            f,
            p,
            rho,
            total_energy,
        })
    }

    /// Energy captured by orders `(F, P)`: `sum rho_{l p |m|}^2` over both
    /// signs of `m`.
    #[must_use]
    pub fn energy(&self, f: usize, p: usize) -> f64 {
        let mut e = 0.0;
        for l in 0..=f.min(self.f) {
            for pp in 0..=p.min(self.p) {
                for m in 0..=l.min(pp) {
                    let r = self.get(l, pp, m);
                    e += if m == 0 { r * r } else { 2.0 * r * r };
                }
            }
        }
        e
    }

    /// The smallest `(F, P)` capturing `1 - eps` of the BRDF's energy (the
    /// paper's Sec. 5.1 criterion): first `P` at the full `F`, then `F`.
    #[must_use]
    pub fn orders(&self, eps: f64) -> (usize, usize) {
        let want = (1.0 - eps) * self.total_energy;
        let p = (0..=self.p)
            .find(|&p| self.energy(self.f, p) >= want)
            .unwrap_or(self.p);
        let f = (0..=self.f)
            .find(|&f| self.energy(f, p) >= want)
            .unwrap_or(self.f);
        (f, p)
    }
}

/// A local SHRM: `(P + 1)^2` maps `B_pm(alpha, beta)` on an equirect grid.
#[derive(Clone, Debug)]
pub struct Shrm {
    p: usize,
    width: usize,
    height: usize,
    /// `[pixel][k = p (p + 1) + m][channel]`.
    data: Vec<f64>,
}

impl Shrm {
    /// Builds the SHRM of `env` (equirect, RGB) for `brdf` truncated to
    /// `(F, P)`, on the map's own grid (Eq. 5, 14): the lighting SH by the
    /// pixel-centre projection, then per pixel the lighting in its frame and
    /// `B_pm = sum_l rho_{l p |m|} L^R_lm`.
    ///
    /// # Errors
    /// Maps that are not 2:1 RGB; degrees.
    pub fn build(env: &Image, brdf: &BrdfCoeffs, f: usize, p: usize) -> Result<Self> {
        let (w, h) = (env.width(), env.height());
        if env.channels() != 3 || h < 2 || w != 2 * h {
            return Err(param(
                "environment map",
                format!("must be 2:1 RGB; got {w}x{h}"),
            ));
        }
        let f = f.min(brdf.f);
        let p = p.min(brdf.p).min(f);
        let light = EquirectTransform::new(f, w, h)?
            .analyze(env, Negatives::Keep)?
            .coeffs;
        let src = light.data();
        let np = sh_count(p);
        let rows: Vec<Vec<f64>> = (0..h)
            .into_par_iter()
            .map(|v| {
                let alpha = PI * (v as f64 + 0.5) / h as f64;
                let my = ShRotation::new(&Rotation::ry(-alpha), f).expect("degree checked");
                let mut out = vec![0.0; w * np * 3];
                let mut zc = vec![0.0; sh_count(f) * 3];
                let mut lr = vec![0.0; (f + 1) * (2 * p + 1) * 3];
                for u in 0..w {
                    let beta = 2.0 * PI * (u as f64 + 0.5) / w as f64;
                    // M(Rz(-beta)) L: each (m, -m) pair turned by -m beta
                    for l in 0..=f {
                        let base = l * (l + 1);
                        for c in 0..3 {
                            zc[base * 3 + c] = src[base * 3 + c];
                        }
                        for m in 1..=l {
                            let (s, co) = (-(m as f64) * beta).sin_cos();
                            for c in 0..3 {
                                let a = src[(base + m) * 3 + c];
                                let b = src[(base - m) * 3 + c];
                                zc[(base + m) * 3 + c] = a * co - b * s;
                                zc[(base - m) * 3 + c] = a * s + b * co;
                            }
                        }
                    }
                    // rows |m| <= P of M(Ry(-alpha)): L^R_lm
                    for l in 0..=f {
                        let n = 2 * l + 1;
                        let blk = my.band(l);
                        let mm = l.min(p) as i64;
                        for m in -mm..=mm {
                            let row = (m + l as i64) as usize;
                            for c in 0..3 {
                                let mut acc = 0.0;
                                for j in 0..n {
                                    acc += blk[row * n + j] * zc[(l * l + j) * 3 + c];
                                }
                                lr[(l * (2 * p + 1) + (m + p as i64) as usize) * 3 + c] = acc;
                            }
                        }
                    }
                    // B_pm = sum_l rho_{l p |m|} L^R_lm
                    let o = &mut out[u * np * 3..(u + 1) * np * 3];
                    for pp in 0..=p {
                        for m in -(pp as i64)..=pp as i64 {
                            let k = (pp as i64 * (pp as i64 + 1) + m) as usize;
                            let am = m.unsigned_abs() as usize;
                            for l in am..=f {
                                let r = brdf.get(l, pp, am);
                                if r == 0.0 {
                                    continue;
                                }
                                for c in 0..3 {
                                    o[k * 3 + c] +=
                                        r * lr[(l * (2 * p + 1) + (m + p as i64) as usize) * 3 + c];
                                }
                            }
                        }
                    }
                }
                out
            })
            .collect();
        Ok(Self {
            p,
            width: w,
            height: h,
            data: rows.concat(),
        })
    }

    /// The reflection map for a distant viewer looking from `view` (unit,
    /// ifd frame): `sum_pm B_pm(R) y_pm(R_R^T view)` (Eq. 12).
    ///
    /// # Errors
    /// Allocation.
    pub fn view(&self, view: [f64; 3]) -> Result<Image> {
        let (w, h, p) = (self.width, self.height, self.p);
        let np = sh_count(p);
        let sh = ShEvaluator::new(p)?;
        let mut img = Image::new(w, h, 3)?;
        img.data_mut()
            .par_chunks_mut(w * 3)
            .enumerate()
            .for_each(|(v, orow)| {
                let alpha = PI * (v as f64 + 0.5) / h as f64;
                let mut y = vec![0.0; np];
                for u in 0..w {
                    let beta = 2.0 * PI * (u as f64 + 0.5) / w as f64;
                    let r = Rotation::from_zyz(beta, alpha, 0.0);
                    sh.eval_into(r.apply_inverse(view), &mut y);
                    let b = &self.data[(v * w + u) * np * 3..][..np * 3];
                    for c in 0..3 {
                        let s: f64 = (0..np).map(|k| b[k * 3 + c] * y[k]).sum();
                        orow[u * 3 + c] = s as f32;
                    }
                }
            });
        Ok(img)
    }
}

/// The reflection map for viewer `view` by angular-space integration: per
/// pixel, `sum_texels L(l) rho^(R_R^T l, R_R^T view) dA` over the texels of
/// the BRDF's support `rho^ >= eps max rho^` (a cap about `R` whose radius is
/// tabulated against `theta_o`); returns the map and the mean texels summed.
///
/// # Errors
/// Maps that are not 2:1 RGB.
pub fn microfacet_angular(
    env: &Image,
    brdf: &Microfacet,
    view: [f64; 3],
    eps: f64,
) -> Result<(Image, f64)> {
    let (w, h) = (env.width(), env.height());
    if env.channels() != 3 || h < 2 || w != 2 * h {
        return Err(param(
            "environment map",
            format!("must be 2:1 RGB; got {w}x{h}"),
        ));
    }
    let peak = 1.0 / (4.0 * PI * brdf.sigma * brdf.sigma);
    let cut = eps * peak;
    // cap radius about z against theta_o, by scanning theta_i and psi
    let n_tab = 64;
    let texel = PI / h as f64;
    let cap: Vec<f64> = (0..=n_tab)
        .map(|k| {
            let to = PI * k as f64 / n_tab as f64;
            let wo = dir(to.min(PI - 1e-6), 0.0);
            let mut r: f64 = 0.0;
            for a in 1..=400 {
                let ti = PI * a as f64 / 400.0;
                for b in 0..64 {
                    let psi = 2.0 * PI * b as f64 / 64.0;
                    if brdf.eval(dir(ti, psi), wo) >= cut {
                        r = r.max(ti);
                    }
                }
            }
            r + 2.0 * texel + PI / 400.0
        })
        .collect();
    let cap_at = |to: f64| {
        let x = (to / PI * n_tab as f64).clamp(0.0, n_tab as f64);
        let k = x.floor() as usize;
        cap[k].max(cap[(k + 1).min(n_tab)])
    };
    let dphi = 2.0 * PI / w as f64;
    let rows = crate::shrm::grid_rows(w, h);
    let data = env.data();
    let mut out = Image::new(w, h, 3)?;
    let counted: u64 = out
        .data_mut()
        .par_chunks_mut(w * 3)
        .enumerate()
        .map(|(vr, orow)| {
            let alpha = PI * (vr as f64 + 0.5) / h as f64;
            let mut n = 0u64;
            for ur in 0..w {
                let beta = dphi * (ur as f64 + 0.5);
                let rot = Rotation::from_zyz(beta, alpha, 0.0);
                let wo = rot.apply_inverse(view);
                let rdir = rot.apply([0.0, 0.0, 1.0]);
                let theta_star = cap_at(wo[2].clamp(-1.0, 1.0).acos());
                let cos_star = theta_star.cos();
                let (zr, sr) = (rdir[2], (1.0 - rdir[2] * rdir[2]).max(0.0).sqrt());
                let pr = rdir[1].atan2(rdir[0]);
                let mut acc = [0.0f64; 3];
                let v_lo = (((alpha - theta_star) / PI * h as f64).floor().max(0.0)) as usize;
                let v_hi = (((alpha + theta_star) / PI * h as f64).ceil() as usize).min(h);
                let centre = (pr / dphi - 0.5).round() as i64;
                for (v, &(z, st, sa)) in rows.iter().enumerate().take(v_hi).skip(v_lo) {
                    let Some((u0, len)) =
                        crate::shrm::cap_interval(z, st, zr, sr, cos_star, centre, w)
                    else {
                        continue;
                    };
                    n += len as u64;
                    let row = &data[v * w * 3..(v + 1) * w * 3];
                    for j in 0..len {
                        let u = (u0 + j) % w;
                        let phi = dphi * (u as f64 + 0.5);
                        let l = [st * phi.cos(), st * phi.sin(), z];
                        let k = brdf.eval(rot.apply_inverse(l), wo);
                        if k < cut {
                            continue;
                        }
                        for c in 0..3 {
                            acc[c] += k * sa * f64::from(row[u * 3 + c]);
                        }
                    }
                }
                for c in 0..3 {
                    orow[ur * 3 + c] = acc[c] as f32;
                }
            }
            n
        })
        .sum();
    Ok((out, counted as f64 / (w * h) as f64))
}

/// One row of Table 5.
#[derive(Clone, Debug, PartialEq)]
pub struct MicrofacetTiming {
    /// Roughness.
    pub sigma: f64,
    /// Orders chosen for `1 - eps` of the BRDF energy.
    pub f: usize,
    /// See `f`.
    pub p: usize,
    /// Angular seconds per reflection map (mean over the measured views).
    pub angular_per_map: f64,
    /// Frequency seconds for the SHRM (lighting SH, BRDF coefficients, maps `B_pm`).
    pub shrm: f64,
    /// Frequency seconds per reflection map from the SHRM (Eq. 12).
    pub per_map: f64,
    /// Relative RMS difference of the two sides over the measured views.
    pub rel_diff: f64,
    /// Mean texels summed per pixel on the angular side.
    pub support: f64,
}

/// The `T x T` global view directions of the paper's `T_B x T_B` maps:
/// `theta = (i + 0.5) pi / T`, `phi = (j + 0.5) 2 pi / T`.
#[must_use]
pub fn view_grid(t: usize) -> Vec<[f64; 3]> {
    (0..t * t)
        .map(|k| {
            let (i, j) = (k / t, k % t);
            dir(
                (i as f64 + 0.5) * PI / t as f64,
                (j as f64 + 0.5) * 2.0 * PI / t as f64,
            )
        })
        .collect()
}

/// Times Table 5 for one `sigma`: the BRDF coefficients and orders for
/// `1 - eps` of its energy, the SHRM, all `t_maps^2` reflection maps from it,
/// and `angular_views` of them by angular integration (support `eps_angular`).
///
/// # Errors
/// As [`Shrm::build`] and [`microfacet_angular`].
pub fn time_microfacet(
    env: &Image,
    sigma: f64,
    eps: f64,
    eps_angular: f64,
    t_maps: usize,
    angular_views: &[[f64; 3]],
) -> Result<MicrofacetTiming> {
    let brdf = Microfacet { sigma };
    let t0 = Instant::now();
    let f_max = ((3.0 / sigma).ceil() as usize).clamp(8, 60);
    let coeffs = BrdfCoeffs::project(&|a, b| brdf.eval(a, b), 2.0 * sigma, f_max, 6)?;
    let (f, p) = coeffs.orders(eps);
    let shrm = Shrm::build(env, &coeffs, f, p)?;
    let shrm_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let views = view_grid(t_maps);
    for v in &views {
        let _ = shrm.view(*v)?;
    }
    let per_map = t1.elapsed().as_secs_f64() / views.len().max(1) as f64;
    let (mut num, mut den, mut ta, mut support) = (0.0, 0.0, 0.0, 0.0);
    for v in angular_views {
        let t = Instant::now();
        let (ang, n) = microfacet_angular(env, &brdf, *v, eps_angular)?;
        ta += t.elapsed().as_secs_f64();
        support += n;
        let fr = shrm.view(*v)?;
        let (n2, d2) = crate::shrm::squared_errors(fr.data(), ang.data());
        num += n2;
        den += d2;
    }
    let nv = angular_views.len().max(1) as f64;
    Ok(MicrofacetTiming {
        sigma,
        f,
        p,
        angular_per_map: ta / nv,
        shrm: shrm_s,
        per_map,
        rel_diff: (num / den.max(f64::MIN_POSITIVE)).sqrt(),
        support: support / nv,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_z_rotation_in_closed_form_matches_sh_rotation() {
        // the pairs turned by -m beta are M(Rz(-beta)): compare one band
        let beta = 0.7;
        let rot = ShRotation::new(&Rotation::rz(-beta), 3).expect("rotation");
        let blk = rot.band(3);
        for m in 1..=3usize {
            let (s, c) = (-(m as f64) * beta).sin_cos();
            // column of the cos function (index 3 + m) maps to rows 3 + m, 3 - m
            assert!((blk[(3 + m) * 7 + 3 + m] - c).abs() < 1e-12);
            assert!((blk[(3 - m) * 7 + 3 + m] - s).abs() < 1e-12);
            assert!((blk[(3 + m) * 7 + 3 - m] + s).abs() < 1e-12);
        }
    }

    #[test]
    fn shrm_views_match_angular_integration() {
        // a small smooth map, a broad lobe, generous orders: the SHRM (BRDF
        // coefficients, lighting rotated into each pixel's frame, Eq. 12)
        // against direct integration over every texel
        let (w, h) = (48, 24);
        let data: Vec<f32> = (0..w * h)
            .flat_map(|k| {
                let (u, v) = (k % w, k / w);
                let t = PI * (v as f64 + 0.5) / h as f64;
                let p = 2.0 * PI * (u as f64 + 0.5) / w as f64;
                let x = (1.0 + 0.5 * t.cos() + 0.3 * (t.sin() * p.cos())) as f32;
                [x, 0.5 * x, 1.0]
            })
            .collect();
        let env = Image::from_vec(w, h, 3, data).expect("map");
        let brdf = Microfacet { sigma: 0.5 };
        let coeffs =
            BrdfCoeffs::project(&|a, b| brdf.eval(a, b), 1.0, 16, 6).expect("coefficients");
        let shrm = Shrm::build(&env, &coeffs, 16, 6).expect("shrm");
        for view in [[0.0, 0.0, 1.0], dir(1.1, 2.0)] {
            let fr = shrm.view(view).expect("view");
            let (ang, _) = microfacet_angular(&env, &brdf, view, 1e-9).expect("angular");
            let (num, den) = crate::shrm::squared_errors(fr.data(), ang.data());
            let rel = (num / den).sqrt();
            // measured 0.63% and 0.38% (0.38% and 0.29% at F = 22, P = 10:
            // the cut at the horizon converges slowly in p)
            assert!(rel < 0.01, "{view:?}: {rel}");
        }
    }

    #[test]
    fn energy_orders_grow_as_the_lobe_sharpens() {
        let sharp = Microfacet { sigma: 0.15 };
        let broad = Microfacet { sigma: 0.4 };
        let cs = BrdfCoeffs::project(&|a, b| sharp.eval(a, b), 0.3, 40, 6).expect("coefficients");
        let cb = BrdfCoeffs::project(&|a, b| broad.eval(a, b), 0.8, 40, 6).expect("coefficients");
        let (fs, _) = cs.orders(0.03);
        let (fb, _) = cb.orders(0.03);
        assert!(fs > fb, "{fs} vs {fb}");
        // the captured energy never exceeds the total (Bessel's inequality)
        assert!(cs.energy(40, 6) <= cs.total_energy * (1.0 + 1e-6));
    }
}
