//! The exact shading oracle: every texel of the (downsampled) environment
//! integrated over its solid angle against the exact BRDF slice,

use std::f64::consts::PI;

use ifd_shade::Brdf;
use ifd_shade::Frame;
use ifd_sphere::gauss_legendre;

use crate::envmap::EnvMap;

/// A texel's accepted change, relative to the pixel's total.
pub const TOLERANCE: f64 = 1e-6;
/// The most Gauss-Legendre nodes per texel side.
pub const MAX_K: usize = 64;

/// The oracle over one environment.
///
/// The exact shading oracle: every texel of the (downsampled) environment
/// integrated over its solid angle against the exact BRDF slice,
///
/// ```text
/// I(wo) = sum_texels E_t int_texel k_wo(F^T w) dw.
/// ```
///
/// Each texel's integral is a `k x k` Gauss-Legendre product rule in
/// `(theta, phi)` over the texel (the `sin(theta)` of the solid angle in the
/// integrand), `k` doubled from `k0` until that texel's value changes by less
/// than [`TOLERANCE`] times the pixel's total (estimated at `k0`), up to
/// [`MAX_K`]. `k0` (at least 2) puts about four nodes across the BRDF's lobe
/// width ([`ifd_shade::Brdf::lobe_width`]) in a texel, so that a lobe narrower
/// than a texel cannot fall between the nodes of both starting rules. The
/// criterion is per texel: a pixel's error is bounded by about a third of the
/// sum of its texels' last changes, at most `TOLERANCE / 3` times the number
/// of refined texels (a few tens: those under the lobe). Texels far from the
/// lobe stop at `k0`, those under it refine;
/// the rule converges spectrally where the slice is smooth over the texel and
/// as `1/k^2` across the horizon's kink. (A midpoint rule, tried first, needs
/// `k > 64` for 1e-6 on a 0.2 rad texel under a Phong-8 lobe.) A pixel with a
/// texel that reached [`MAX_K`] unconverged is counted.
#[derive(Debug)]
pub struct Oracle {
    width: usize,
    height: usize,
    channels: usize,
    rotation: f64,
    /// Gauss-Legendre rules on `[0, 1]` for `k = 1, 2, 4, ..., MAX_K`.
    rules: Vec<(Vec<f64>, Vec<f64>)>,
}

impl Oracle {
    /// The oracle of `env`.
    #[must_use]
    pub fn new(env: &EnvMap) -> Self {
        Self {
            width: env.image().width(),
            height: env.image().height(),
            channels: env.channels(),
            rotation: env.rotation(),
            rules: (0..=MAX_K.trailing_zeros())
                .map(|i| {
                    let (x, w) = gauss_legendre(1 << i);
                    (
                        x.iter().map(|x| 0.5 * (x + 1.0)).collect(),
                        w.iter().map(|w| 0.5 * w).collect(),
                    )
                })
                .collect(),
        }
    }

    /// `int_texel k_wo dw` of texel `(u, v)` with a `k x k` Gauss-Legendre
    /// rule (`k` a power of two), per slice channel into `acc`.
    #[allow(clippy::too_many_arguments)]
    fn texel(
        &self,
        brdf: &Brdf,
        frame: &Frame,
        wl: [f64; 3],
        u: usize,
        v: usize,
        k: usize,
        acc: &mut [f64; 3],
    ) {
        let (dp, dt) = (2.0 * PI / self.width as f64, PI / self.height as f64);
        let (x, wg) = &self.rules[k.trailing_zeros() as usize];
        let mut slice = [0.0; 3];
        *acc = [0.0; 3];
        for (xa, wa) in x.iter().zip(wg) {
            let t = dt * (v as f64 + xa);
            let (st, ct) = t.sin_cos();
            let wt = wa * dt * st;
            for (xb, wb) in x.iter().zip(wg) {
                let p = dp * (u as f64 + xb) + self.rotation;
                let (sp, cp) = p.sin_cos();
                brdf.slice(frame.to_local([st * cp, st * sp, ct]), wl, &mut slice);
                let q = wt * wb * dp;
                for (o, s) in acc.iter_mut().zip(&slice) {
                    *o += q * s;
                }
            }
        }
    }

    /// `I(wo)` at a point with frame `frame` (world `wo`, unit), into `out`
    /// (one value per environment channel). Returns the largest `k` used,
    /// whether every texel converged, and the residual estimate: the last
    /// changes of the texels that did not converge, summed, relative to the
    /// pixel's value (0 when all converged).
    pub fn shade(
        &self,
        env: &EnvMap,
        brdf: &Brdf,
        frame: &Frame,
        wo: [f64; 3],
        out: &mut [f64],
    ) -> (usize, bool, f64) {
        let (w, h, ch) = (self.width, self.height, self.channels);
        let kc = brdf.channels();
        let wl = frame.to_local(wo);
        let texels = env.image().data();
        let contrib = |acc: &[f64; 3], t: usize, out: &mut [f64]| {
            for c in 0..ch {
                out[c] = acc[if kc == 1 { 0 } else { c }] * f64::from(texels[t * ch + c]);
            }
        };
        // k0 / 2 and k0 for every texel; the total at k0 sets the scale
        let texel_angle = std::f64::consts::PI / h as f64;
        let k0 = ((4.0 * texel_angle / brdf.lobe_width()).ceil() as usize)
            .next_power_of_two()
            .clamp(2, MAX_K);
        let mut first = vec![[0.0; 3]; w * h];
        let mut second = vec![[0.0; 3]; w * h];
        let mut total = vec![0.0; ch];
        let mut tmp = vec![0.0; ch];
        for v in 0..h {
            for u in 0..w {
                let t = v * w + u;
                self.texel(brdf, frame, wl, u, v, k0 / 2, &mut first[t]);
                self.texel(brdf, frame, wl, u, v, k0, &mut second[t]);
                contrib(&second[t], t, &mut tmp);
                for (a, b) in total.iter_mut().zip(&tmp) {
                    *a += b;
                }
            }
        }
        let scale = total.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let tol = TOLERANCE * scale;
        out[..ch].fill(0.0);
        let (mut max_k, mut converged, mut residual) = (k0, true, 0.0);
        let mut a = vec![0.0; ch];
        let mut b = vec![0.0; ch];
        for t in 0..w * h {
            let (u, v) = (t % w, t / w);
            let mut prev = first[t];
            let mut cur = second[t];
            let mut k = k0;
            loop {
                contrib(&prev, t, &mut a);
                contrib(&cur, t, &mut b);
                let change = a
                    .iter()
                    .zip(&b)
                    .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
                if change <= tol {
                    break;
                }
                if k >= MAX_K {
                    converged = false;
                    residual += change;
                    break;
                }
                k *= 2;
                prev = cur;
                self.texel(brdf, frame, wl, u, v, k, &mut cur);
            }
            max_k = max_k.max(k);
            contrib(&cur, t, &mut b);
            for (o, x) in out.iter_mut().zip(&b) {
                *o += x;
            }
        }
        (max_k, converged, residual / scale.max(f64::MIN_POSITIVE))
    }
}
