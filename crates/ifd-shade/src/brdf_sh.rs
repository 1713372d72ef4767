//! BRDFs on the 4D SH basis and their filtering with a separable von
//! Mises-Fisher kernel (ISD Sec. 6.3, Eq. 30-32): denoising measured data,
//! filling its holes.
//!
//! The derivation and conventions are documented on [`BrdfSh`].

use ifd_sphere::vmf_factors;
use ifd_sphere::{ShEvaluator, gauss_legendre};
use rayon::prelude::*;

use crate::brdf::Brdf;
use crate::error::{Result, ShadeError};

/// A BRDF's coefficients on the even-extension 4D SH basis (module docs),
/// with those of its validity mask when it has holes.
///
/// # The basis
/// A BRDF lives on the upper hemisphere in both arguments. Projecting it as
/// it is onto SH would expand its jump to zero at the horizon; it is
/// projected instead as its **even extension** in `z` (`rho(x, y, |z|)` in
/// each argument), the reflective boundary of image filtering. Since
/// `y_l^m(x, y, -z) = (-1)^(l+m) y_l^m(x, y, z)`, only the `M = (L + 1)(L +
/// 2) / 2` functions with `l + m` even are used, and their coefficients are
/// twice the hemisphere's integrals:
///
/// ```text
/// C_ab = 4 int_{H} int_{H} rho(wi, wo) y_a(wi) y_b(wo) dwi dwo      (Eq. 30)
/// ```
///
/// by Gauss-Legendre quadrature in `cos theta` times the trapezoid rule in
/// `phi` (exact for the basis; `n_theta >= L + 1` nodes, `2 n_theta` in
/// azimuth) on the same node set for both arguments, so that a reciprocal
/// BRDF gives a symmetric `C` (reciprocity kept, Sec. 6.3; the projection is then made exactly symmetric, [`BrdfSh::asymmetry`]). A BRDF that is a
/// polynomial of degree `<= L` in `(x, y, z^2)` of each argument is
/// reproduced exactly (a constant, Lambert, at `L = 0`).
///
/// # Filtering (Eq. 31-32)
/// The separable kernel `m(wi, wo) = K exp(kappa (wi . zi + wo . zo))`,
/// each factor a normalised vMF lobe, multiplies `C_ab` by `Lambda_{l_a}
/// Lambda_{l_b}` ([`ifd_sphere::vmf_factors`]; Eq. 32's factors
/// `Lambda_l = pi_l k_l`, with `k_l` the lobe's zonal coefficients). Holes (bins a
/// measurement marks invalid) are treated as missing, not as zero, by
/// **normalised convolution**: the data times the validity mask and the mask
/// itself are projected and filtered alike, and the filtered BRDF is their
/// ratio (where the filtered mask is at least 1e-3; without holes the mask is
/// exactly 1 and this is plain filtering). Values are clamped at 0 and to
/// zero below the horizon.
#[derive(Clone, Debug)]
pub struct BrdfSh {
    l_max: usize,
    channels: usize,
    /// Flat SH indices `l (l + 1) + m` of the basis (`l + m` even).
    basis: Vec<usize>,
    /// Degree of each basis function.
    degree: Vec<usize>,
    /// `C[(a M + b) C + c]`.
    coeffs: Vec<f64>,
    /// The validity mask's `C[a M + b]` (`None`: no holes).
    mask: Option<Vec<f64>>,
    /// The data's asymmetry before symmetrisation ([`Self::asymmetry`]).
    asymmetry: f64,
}

/// A BRDF as data: `f(wi, wo, out)` writes the values per channel and says
/// whether the sample is valid (`false`: a hole).
pub type BrdfSampler<'a> = dyn Fn([f64; 3], [f64; 3], &mut [f64]) -> bool + Sync + 'a;

/// One row of the projection: `T[b, c]`, the mask's `T[b]`, whether it had holes.
type Row = (Vec<f64>, Vec<f64>, bool);

/// The nodes and weights of the hemisphere quadrature.
fn hemisphere_nodes(n_theta: usize) -> Vec<([f64; 3], f64)> {
    let (x, w) = gauss_legendre(n_theta);
    let n_phi = 2 * n_theta;
    let mut out = Vec::with_capacity(n_theta * n_phi);
    for (t, wt) in x.iter().zip(&w) {
        // cos theta on [0, 1]
        let z = 0.5 * (t + 1.0);
        let s = (1.0 - z * z).max(0.0).sqrt();
        for j in 0..n_phi {
            let p = std::f64::consts::TAU * (j as f64 + 0.5) / n_phi as f64;
            out.push((
                [s * p.cos(), s * p.sin(), z],
                0.5 * wt * std::f64::consts::TAU / n_phi as f64,
            ));
        }
    }
    out
}

impl BrdfSh {
    /// Projects `f(wi, wo, out) -> valid` (values per channel in `out`;
    /// `false` for a hole) on the basis of degree `l_max` with `n_theta`
    /// nodes in `cos theta` (and `2 n_theta` in azimuth) per argument.
    /// `progress(done, total)` per row of nodes.
    ///
    /// # Errors
    /// [`ShadeError::Parameter`] for `n_theta < L + 1`, more than 4096 nodes
    /// per argument or `L > 40`; non-finite values.
    pub fn project(
        f: &BrdfSampler<'_>,
        channels: usize,
        l_max: usize,
        n_theta: usize,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self> {
        if l_max > 40 || n_theta < l_max + 1 || 2 * n_theta * n_theta > 4096 || channels == 0 {
            return Err(ShadeError::Parameter {
                name: "4D SH projection",
                value: format!("L = {l_max}, {n_theta} nodes in theta, {channels} channels"),
                reason: "needs L <= 40, L + 1 <= nodes, 2 nodes^2 <= 4096 per argument".into(),
            });
        }
        // flat index l (l + 1) + m = l^2 + k with k = l + m even
        let basis: Vec<usize> = (0..=l_max)
            .flat_map(|l| (0..=2 * l).step_by(2).map(move |k| l * l + k))
            .collect();
        let degree: Vec<usize> = basis.iter().map(|i| i.isqrt()).collect();
        let nodes = hemisphere_nodes(n_theta);
        let n = nodes.len();
        let nb = basis.len();
        let sh = ShEvaluator::new(l_max)?;
        // A[k, a] = w_k y_a(w_k)
        let mut a = vec![0.0; n * nb];
        let mut y = vec![0.0; (l_max + 1) * (l_max + 1)];
        for (k, (d, wk)) in nodes.iter().enumerate() {
            sh.eval_into(*d, &mut y);
            for (j, &i) in basis.iter().enumerate() {
                a[k * nb + j] = wk * y[i];
            }
        }
        // T[i, b, c] = sum_o f(wi, wo) A[o, b], and the mask's, per row wi
        let done = std::sync::atomic::AtomicUsize::new(0);
        let rows: Vec<Result<Row>> = (0..n)
            .into_par_iter()
            .map(|i| {
                let mut t = vec![0.0; nb * channels];
                let mut tm = vec![0.0; nb];
                let mut v = vec![0.0; channels.max(3)];
                let mut holes = false;
                for (o, (wo, _)) in nodes.iter().enumerate() {
                    let ok = f(nodes[i].0, *wo, &mut v);
                    if v[..channels].iter().any(|x| !x.is_finite()) {
                        return Err(ShadeError::Parameter {
                            name: "BRDF value",
                            value: format!("{:?}", &v[..channels]),
                            reason: "non-finite".into(),
                        });
                    }
                    let ao = &a[o * nb..(o + 1) * nb];
                    if ok {
                        for (b, &ab) in ao.iter().enumerate() {
                            tm[b] += ab;
                            for c in 0..channels {
                                t[b * channels + c] += v[c] * ab;
                            }
                        }
                    } else {
                        holes = true;
                    }
                }
                let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(d, n);
                Ok((t, tm, holes))
            })
            .collect();
        let mut coeffs = vec![0.0; nb * nb * channels];
        let mut mask = vec![0.0; nb * nb];
        let mut any_hole = false;
        for (i, r) in rows.into_iter().enumerate() {
            let (t, tm, holes) = r?;
            any_hole |= holes;
            let ai = &a[i * nb..(i + 1) * nb];
            for (ia, &aa) in ai.iter().enumerate() {
                for b in 0..nb {
                    mask[ia * nb + b] += 4.0 * aa * tm[b];
                    for c in 0..channels {
                        coeffs[(ia * nb + b) * channels + c] += 4.0 * aa * t[b * channels + c];
                    }
                }
            }
        }
        let mut out = Self {
            l_max,
            channels,
            basis,
            degree,
            coeffs,
            mask: any_hole.then_some(mask),
            asymmetry: 0.0,
        };
        out.asymmetry = out.measure_asymmetry();
        out.symmetrise();
        Ok(out)
    }

    /// Projects a BRDF (a MERL file's holes as missing data).
    ///
    /// # Errors
    /// [`ShadeError::Spec`] for `phong` (the SHRM lobe with the cosine folded
    /// in: divided by the cosine it is not a reciprocal BRDF, and the
    /// projection keeps the reciprocal part); otherwise as [`Self::project`].
    pub fn from_brdf(
        brdf: &Brdf,
        l_max: usize,
        n_theta: usize,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self> {
        if let crate::brdf::Model::Phong { .. } = brdf.model() {
            return Err(ShadeError::Spec {
                spec: brdf.spec().to_owned(),
                reason: "phong is a shading lobe with the cosine folded in, not a reciprocal \
                         BRDF, so its 4D projection (which keeps the reciprocal part) would not \
                         be it; use blinn, ggx, ward, lambert or merl:FILE"
                    .to_owned(),
            });
        }
        let ch = brdf.channels();
        let f = |wi: [f64; 3], wo: [f64; 3], out: &mut [f64]| -> bool {
            // the BRDF, not its cosine-weighted slice
            brdf.slice(wi, wo, out);
            for v in out.iter_mut().take(ch) {
                *v /= wi[2].max(1e-300);
            }
            match brdf.model() {
                crate::brdf::Model::Merl(m) => m.is_valid(wi, wo),
                _ => true,
            }
        };
        Self::project(&f, ch, l_max, n_theta, progress)
    }

    /// The degree `L`.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// Channels.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Whether the data had holes (then values are normalised by the mask).
    #[must_use]
    pub fn has_holes(&self) -> bool {
        self.mask.is_some()
    }

    /// Basis functions per argument, `M`.
    #[must_use]
    pub fn basis_len(&self) -> usize {
        self.basis.len()
    }

    /// The coefficients `C[(a M + b) C + c]`.
    #[must_use]
    pub fn coeffs(&self) -> &[f64] {
        &self.coeffs
    }

    /// Eq. 32: the coefficients (and the mask's) times `Lambda_{l_a}
    /// Lambda_{l_b}` of the normalised vMF lobe of concentration `kappa`
    /// (`kappa <= 0` keeps only the constant).
    #[must_use]
    pub fn filtered(&self, kappa: f64) -> Self {
        let lam = vmf_factors(kappa, self.l_max);
        let nb = self.basis.len();
        let mut out = self.clone();
        for a in 0..nb {
            for b in 0..nb {
                let f = lam[self.degree[a]] * lam[self.degree[b]];
                for c in 0..self.channels {
                    out.coeffs[(a * nb + b) * self.channels + c] *= f;
                }
                if let Some(m) = &mut out.mask {
                    m[a * nb + b] *= f;
                }
            }
        }
        out
    }

    /// Scratch for [`Self::eval`].
    #[must_use]
    pub fn scratch(&self) -> Vec<f64> {
        vec![0.0; 2 * (self.l_max + 1) * (self.l_max + 1) + 2 * self.basis.len()]
    }

    /// The reconstructed BRDF at `(wi, wo)` (local frame), 0 below the
    /// horizon and clamped at 0; divided by the reconstructed mask when the
    /// data had holes (0 where the mask is below 1e-3: no data near).
    pub fn eval(
        &self,
        sh: &ShEvaluator,
        wi: [f64; 3],
        wo: [f64; 3],
        scratch: &mut [f64],
        out: &mut [f64],
    ) {
        let ch = self.channels;
        out[..ch].fill(0.0);
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return;
        }
        let n = (self.l_max + 1) * (self.l_max + 1);
        let nb = self.basis.len();
        let (yi, rest) = scratch.split_at_mut(n);
        let (yo, rest) = rest.split_at_mut(n);
        let (bi, bo) = rest.split_at_mut(nb);
        sh.eval_into(wi, yi);
        sh.eval_into(wo, yo);
        for (j, &i) in self.basis.iter().enumerate() {
            bi[j] = yi[i];
            bo[j] = yo[i];
        }
        let mut m = 0.0;
        for a in 0..nb {
            let ya = bi[a];
            let row = &self.coeffs[a * nb * ch..(a + 1) * nb * ch];
            for b in 0..nb {
                let w = ya * bo[b];
                for c in 0..ch {
                    out[c] += w * row[b * ch + c];
                }
            }
            if let Some(mk) = &self.mask {
                for b in 0..nb {
                    m += ya * bo[b] * mk[a * nb + b];
                }
            }
        }
        if self.mask.is_some() {
            for o in &mut out[..ch] {
                *o = if m >= 1e-3 { *o / m } else { 0.0 };
            }
        }
        for o in &mut out[..ch] {
            *o = o.max(0.0);
        }
    }

    /// The largest `|C_ab - C_ba|` relative to the largest `|C_ab|` of the
    /// projected data before it was made reciprocal (`C <- (C + C^T) / 2`,
    /// the reciprocal part; measured data are not exactly reciprocal: MERL's
    /// nearest bins of `(wi, wo)` and `(wo, wi)` differ where `phi_d` wraps).
    #[must_use]
    pub fn asymmetry(&self) -> f64 {
        self.asymmetry
    }

    fn symmetrise(&mut self) {
        let nb = self.basis.len();
        let ch = self.channels;
        for a in 0..nb {
            for b in a + 1..nb {
                for c in 0..ch {
                    let (i, j) = ((a * nb + b) * ch + c, (b * nb + a) * ch + c);
                    let m = 0.5 * (self.coeffs[i] + self.coeffs[j]);
                    self.coeffs[i] = m;
                    self.coeffs[j] = m;
                }
                if let Some(mk) = &mut self.mask {
                    let m = 0.5 * (mk[a * nb + b] + mk[b * nb + a]);
                    mk[a * nb + b] = m;
                    mk[b * nb + a] = m;
                }
            }
        }
    }

    fn measure_asymmetry(&self) -> f64 {
        let nb = self.basis.len();
        let ch = self.channels;
        let (mut d, mut m) = (0.0f64, 0.0f64);
        for a in 0..nb {
            for b in 0..nb {
                for c in 0..ch {
                    let x = self.coeffs[(a * nb + b) * ch + c];
                    let y = self.coeffs[(b * nb + a) * ch + c];
                    d = d.max((x - y).abs());
                    m = m.max(x.abs());
                }
            }
        }
        d / m.max(1e-300)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A polynomial BRDF of degree 2 in (x, y, z^2) is reproduced exactly at
    /// L = 4, and filtering scales its bands as the vMF factors say.
    #[test]
    fn polynomial_brdf_is_reproduced() {
        let rho = |wi: [f64; 3], wo: [f64; 3]| {
            (0.55 + 0.35 * wi[2] * wi[2] * wo[2] * wo[2] - 0.15 * (wi[0] * wo[0] + wi[1] * wo[1]))
                / std::f64::consts::PI
        };
        let f = |wi: [f64; 3], wo: [f64; 3], out: &mut [f64]| {
            out[0] = rho(wi, wo);
            true
        };
        let p = BrdfSh::project(&f, 1, 4, 12, &|_, _| {}).unwrap();
        assert!(!p.has_holes());
        assert!(p.asymmetry() < 1e-12, "{}", p.asymmetry());
        let sh = ShEvaluator::new(4).unwrap();
        let mut s = p.scratch();
        let mut out = [0.0];
        for (wi, wo) in [
            ([0.0, 0.0, 1.0], [0.6, 0.0, 0.8]),
            ([0.36, -0.48, 0.8], [-0.6, 0.64, 0.48]),
        ] {
            p.eval(&sh, wi, wo, &mut s, &mut out);
            assert!(
                (out[0] - rho(wi, wo)).abs() < 1e-12,
                "{} vs {}",
                out[0],
                rho(wi, wo)
            );
            p.eval(&sh, wi, [wo[0], wo[1], -wo[2]], &mut s, &mut out);
            assert_eq!(out[0], 0.0);
        }
    }

    /// Holes are missing data: a constant BRDF with a hole is still the
    /// constant after normalised filtering.
    #[test]
    fn holes_are_filled_by_normalised_convolution() {
        let f = |wi: [f64; 3], wo: [f64; 3], out: &mut [f64]| {
            out[0] = 0.3;
            // a hole where both directions are near the normal
            !(wi[2] > 0.9 && wo[2] > 0.9)
        };
        let p = BrdfSh::project(&f, 1, 6, 16, &|_, _| {}).unwrap();
        assert!(p.has_holes());
        let q = p.filtered(20.0);
        let sh = ShEvaluator::new(6).unwrap();
        let mut s = q.scratch();
        let mut out = [0.0];
        q.eval(&sh, [0.0, 0.0, 1.0], [0.1, 0.0, 0.995], &mut s, &mut out);
        assert!((out[0] - 0.3).abs() < 1e-9, "{}", out[0]);
    }
}
