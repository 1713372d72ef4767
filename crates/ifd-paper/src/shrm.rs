//! The SHRM paper's prefiltering comparison (Ramamoorthi and Hanrahan 2002,
//! Sec. 6.3 and 7.4, Table 4, App. D): a normalised Phong reflection map
//! `B(r) = int L(l) (s + 1) / (2 pi) max(r . l, 0)^s dl` computed in the
//! frequency domain and in the angular domain, on the same equirectangular
//! grid, with the same threads.
//!
//! - **Frequency** ([`phong_frequency`]): the lighting coefficients `L_lm` to
//!   `F_B` (the pixel-centre projection of [`EquirectTransform::analyze`], the
//!   same quadrature the angular side uses), the zonal factors `lambda_l`
//!   ([`Lobe::zonal`], part of the timing), `B_lm = lambda_l L_lm` (Eq. 5) and
//!   the synthesis on the output grid. The paper's order: `F_B = 1 + sqrt(6 s)`
//!   (its `eps = 0.01`, conservatively).
//! - **Angular** ([`phong_angular`]): for every output texel, the sum over the
//!   input texels inside the lobe's eps-support `r . l >= eps^(1 / (s + 1))`
//!   (App. D: `1 - eps` of the lobe's energy; the paper's angular side used
//!   `eps = 0.05`), each row visited only over the azimuth interval the cap
//!   covers (computed in closed form), the kernel `t^s` by repeated squaring
//!   for integer `s`, rows of the output in parallel; the lobe is normalised
//!   over its support (divided by `1 - eps`, its captured energy). Its cost is
//!   `W S_L^2` per output texel with `W = (1 - eps^(1/(s+1))) / 2`.
//!
//! Both compute the same convolution of the same texel-centre quadrature: they
//! differ by the frequency side's truncation at `F_B` and the angular side's
//! truncation of the support, which [`PhongTiming::rel_diff`] reports.

use std::f64::consts::PI;
use std::time::Instant;

use ifd_image::Image;
use ifd_sphere::{EquirectTransform, Negatives};
use rayon::prelude::*;

use ifd_ibl::Result;

use crate::param;
use ifd_ibl::Lobe;

/// The paper's frequency-space order for Phong exponent `s`: `1 + sqrt(6 s)`.
#[must_use]
pub fn paper_order(s: f64) -> usize {
    (1.0 + (6.0 * s).sqrt()).floor() as usize
}

/// App. D's order for Phong exponent `s` and BRDF energy tolerance `eps`:
/// with `rho_l ~ exp(-l^2 / 2s)`, `sum_{l <= F} l exp(-l^2/s) = (1 - eps)
/// sum_l ...` gives `F = sqrt(-s ln eps)` (rounded up).
///
/// ```
/// // s = 64, eps = 0.01: sqrt(64 ln 100) = 17.2
/// assert_eq!(ifd_paper::shrm::phong_order(64.0, 0.01), 18);
/// ```
#[must_use]
pub fn phong_order(s: f64, eps: f64) -> usize {
    (-s * eps.ln()).max(0.0).sqrt().ceil() as usize
}

/// SHRM App. B's conservative error estimate for a radially symmetric lobe
/// truncated at `F`, from the lighting's band powers `light[l] = sum_m
/// L_lm^2` (up to some degree above `F`) and its total energy `light_total =
/// int L^2` (which the bands below it may not exhaust), and the lobe's zonal
/// factors `lambda` (up to a degree where it has decayed). With the lobe's
/// own SH energy per band `rho_l^2 = lambda_l^2 (2l + 1) / 4 pi` (its zonal
/// coefficients, `lambda_l = Lambda_l rho_l`), the missing fractions
/// `eps_L`, `eps_rho` beyond `F`, and the worst case of all residual energy
/// in mode `F + 1`:
///
/// ```text
/// B_res = Lambda_{F+1}^2 (eps_L L_tot)(eps_rho rho_tot),
/// eps_B <= B_res / (sum_{l <= F} lambda_l^2 light_l + B_res)
/// ```
///
/// (the paper writes `Lambda_{F+1}` where energies need its square).
#[must_use]
pub fn residual_bound(light: &[f64], light_total: f64, lambda: &[f64], f: usize) -> f64 {
    let f = f
        .min(light.len().saturating_sub(1))
        .min(lambda.len().saturating_sub(1));
    let kept_light: f64 = light[..=f].iter().sum();
    let eps_l = ((light_total - kept_light) / light_total).max(0.0);
    let rho2 = |l: usize| lambda[l] * lambda[l] * (2 * l + 1) as f64 / (4.0 * PI);
    let rho_tot: f64 = (0..lambda.len()).map(rho2).sum();
    let kept_rho: f64 = (0..=f).map(rho2).sum();
    let eps_rho = ((rho_tot - kept_rho) / rho_tot).max(0.0);
    let lam2 = 4.0 * PI / (2 * f + 3) as f64;
    let b_res = lam2 * (eps_l * light_total) * (eps_rho * rho_tot);
    let kept_b: f64 = (0..=f).map(|l| lambda[l] * lambda[l] * light[l]).sum();
    b_res / (kept_b + b_res)
}

/// The Phong reflection map by SH convolution to degree `f_b`, on the input's
/// grid.
///
/// # Errors
/// A map that is not 2:1; degrees beyond [`ifd_sphere::MAX_DEGREE`].
pub fn phong_frequency(env: &Image, s: f64, f_b: usize) -> Result<Image> {
    let (w, h) = (env.width(), env.height());
    let t = EquirectTransform::new(f_b, w, h)?;
    let mut c = t.analyze(env, Negatives::Keep)?.coeffs;
    let ch = c.channels();
    let lam = Lobe::Phong { s }.zonal(f_b);
    for (l, lam_l) in lam.iter().enumerate() {
        for v in &mut c.data_mut()[l * l * ch..(l + 1) * (l + 1) * ch] {
            *v *= lam_l;
        }
    }
    Ok(t.synthesize(&c)?)
}

/// The Phong reflection map by direct summation over the eps-support of the
/// lobe; returns the map and the mean number of input texels summed per
/// output texel.
///
/// # Errors
/// A map that is not 2:1, or `eps` outside `(0, 1)`.
pub fn phong_angular(env: &Image, s: f64, eps: f64) -> Result<(Image, f64)> {
    let (w, h, ch) = (env.width(), env.height(), env.channels());
    if h < 2 || w != 2 * h {
        return Err(param(
            "environment map",
            format!("must be 2:1; got {w}x{h}"),
        ));
    }
    if !(eps > 0.0 && eps < 1.0) {
        return Err(param("--eps", format!("{eps} is outside (0, 1)")));
    }
    let cos_star = eps.powf(1.0 / (s + 1.0));
    let theta_star = cos_star.acos();
    // the lobe normalised over its support: int_cap (s+1)/(2 pi) t^s = 1 - eps
    let norm = (s + 1.0) / (2.0 * PI) / (1.0 - eps);
    let dphi = 2.0 * PI / w as f64;
    let rows = grid_rows(w, h);
    let (cu, su): (Vec<f64>, Vec<f64>) = (0..w)
        .map(|u| {
            let p = dphi * (u as f64 + 0.5);
            (p.cos(), p.sin())
        })
        .unzip();
    let integer = s.fract() == 0.0 && s <= f64::from(i32::MAX);
    let data = env.data();
    let mut out = Image::new(w, h, ch)?;
    let counted: u64 = out
        .data_mut()
        .par_chunks_mut(w * ch)
        .enumerate()
        .map(|(vr, orow)| {
            let (zr, sr, _) = rows[vr];
            let tr = PI * (vr as f64 + 0.5) / h as f64;
            let mut n = 0u64;
            let mut acc = vec![0.0f64; ch];
            let mut k = vec![0.0f64; w];
            // input rows whose polar band meets the cap
            let v_lo = (((tr - theta_star) / PI * h as f64).floor().max(0.0)) as usize;
            let v_hi = (((tr + theta_star) / PI * h as f64).ceil() as usize).min(h);
            for ur in 0..w {
                let pr = dphi * (ur as f64 + 0.5);
                let (cr, sr_) = (pr.cos(), pr.sin());
                acc.fill(0.0);
                for (v, &(z, st, sa)) in rows.iter().enumerate().take(v_hi).skip(v_lo) {
                    let Some((u0, len)) = cap_interval(z, st, zr, sr, cos_star, ur as i64, w)
                    else {
                        continue;
                    };
                    let a = z * zr;
                    let b = st * sr;
                    n += len as u64;
                    // kernel values over the interval (contiguous, wrapping)
                    let kk = &mut k[..len];
                    for (j, kv) in kk.iter_mut().enumerate() {
                        let u = (u0 + j) % w;
                        let t = a + b * (cu[u] * cr + su[u] * sr_);
                        // exactly the eps-support: the interval is rounded out
                        // to whole texels
                        *kv = if t < cos_star {
                            0.0
                        } else if integer {
                            t.powi(s as i32)
                        } else {
                            t.powf(s)
                        };
                    }
                    let row = &data[v * w * ch..(v + 1) * w * ch];
                    for (j, kv) in kk.iter().enumerate() {
                        let u = (u0 + j) % w;
                        let wgt = kv * sa;
                        for (c, a) in acc.iter_mut().enumerate() {
                            *a += wgt * f64::from(row[u * ch + c]);
                        }
                    }
                }
                for (c, a) in acc.iter().enumerate() {
                    orow[ur * ch + c] = (a * norm) as f32;
                }
            }
            n
        })
        .sum();
    Ok((out, counted as f64 / (w * h) as f64))
}

/// `(cos t, sin t, solid angle)` of every row of a `w x h` equirect grid
/// (texel centres, exact row areas).
pub(crate) fn grid_rows(w: usize, h: usize) -> Vec<(f64, f64, f64)> {
    let dphi = 2.0 * PI / w as f64;
    (0..h)
        .map(|v| {
            let t0 = PI * v as f64 / h as f64;
            let t1 = PI * (v + 1) as f64 / h as f64;
            let t = 0.5 * (t0 + t1);
            (t.cos(), t.sin(), (t0.cos() - t1.cos()) * dphi)
        })
        .collect()
}

/// The columns of a grid row (polar `cos t = z`, `sin t = st`) inside the
/// cap `d . r >= cos_star` about a direction with polar `cos = zr`,
/// `sin = sr` whose azimuth falls in column `centre`: the first column and
/// the count (wrapping), rounded out to whole texels, or `None` when the row
/// misses the cap. From `z zr + st sr cos(dphi) >= cos_star`.
pub(crate) fn cap_interval(
    z: f64,
    st: f64,
    zr: f64,
    sr: f64,
    cos_star: f64,
    centre: i64,
    w: usize,
) -> Option<(usize, usize)> {
    let dphi = 2.0 * PI / w as f64;
    let a = z * zr;
    let b = st * sr;
    if b <= 1e-300 {
        return (a >= cos_star).then_some((0, w));
    }
    let q = (cos_star - a) / b;
    if q > 1.0 {
        None
    } else if q <= -1.0 {
        Some((0, w))
    } else {
        let span = ((q.acos() / dphi).ceil() as usize + 1).min(w / 2);
        Some((
            (centre - span as i64).rem_euclid(w as i64) as usize,
            (2 * span + 1).min(w),
        ))
    }
}

/// `sum (a - b)^2` and `sum b^2` over two sample slices of equal length
/// (a relative RMS difference is the square root of their ratio).
pub(crate) fn squared_errors(a: &[f32], b: &[f32]) -> (f64, f64) {
    a.iter().zip(b).fold((0.0, 0.0), |(num, den), (x, y)| {
        let (x, y) = (f64::from(*x), f64::from(*y));
        (num + (x - y) * (x - y), den + y * y)
    })
}

/// One row of Table 4.
#[derive(Clone, Debug, PartialEq)]
pub struct PhongTiming {
    /// Phong exponent.
    pub s: f64,
    /// Frequency-space order `F_B`.
    pub order: usize,
    /// Angular-space seconds (median of the runs).
    pub angular: f64,
    /// Frequency-space seconds (median of the runs).
    pub frequency: f64,
    /// Mean input texels summed per output texel on the angular side.
    pub support: f64,
    /// Relative RMS difference between the two maps.
    pub rel_diff: f64,
    /// App. B's bound on the frequency side's relative error energy.
    pub residual_bound: f64,
}

/// Times both sides for exponent `s`: each measurement repeats the
/// computation until at least `min_seconds` have passed and takes the mean
/// per run (sub-millisecond runs are below the timer's and the thread pool's
/// noise otherwise); `runs` measurements, medians. One untimed warm-up run of
/// each side comes first.
///
/// # Errors
/// As [`phong_frequency`] and [`phong_angular`].
pub fn time_phong(
    env: &Image,
    s: f64,
    eps_angular: f64,
    runs: usize,
    min_seconds: f64,
) -> Result<PhongTiming> {
    let order = paper_order(s);
    let residual = {
        // the lighting's band powers to well beyond F_B, and its total energy
        let (w, h) = (env.width(), env.height());
        let lb = (4 * order).min(h - 1);
        let c = EquirectTransform::new(lb, w, h)?
            .analyze(env, Negatives::Keep)?
            .coeffs;
        let ch = c.channels();
        let light: Vec<f64> = (0..=lb)
            .map(|l| {
                c.data()[l * l * ch..(l + 1) * (l + 1) * ch]
                    .iter()
                    .map(|v| v * v)
                    .sum()
            })
            .collect();
        let rows = grid_rows(w, h);
        let total: f64 = env
            .data()
            .chunks_exact(w * ch)
            .zip(&rows)
            .map(|(row, r)| r.2 * row.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>())
            .sum();
        residual_bound(&light, total, &Lobe::Phong { s }.zonal(8 * order), order)
    };
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let freq = phong_frequency(env, s, order)?;
    let (ang, support) = phong_angular(env, s, eps_angular)?;
    let measure = |f: &dyn Fn() -> Result<()>| -> Result<f64> {
        let start = Instant::now();
        let mut n = 0u32;
        loop {
            f()?;
            n += 1;
            let t = start.elapsed().as_secs_f64();
            if t >= min_seconds {
                return Ok(t / f64::from(n));
            }
        }
    };
    let mut tf = Vec::new();
    let mut ta = Vec::new();
    for _ in 0..runs.max(1) {
        tf.push(measure(&|| phong_frequency(env, s, order).map(|_| ()))?);
        ta.push(measure(&|| phong_angular(env, s, eps_angular).map(|_| ()))?);
    }
    let (num, den) = squared_errors(freq.data(), ang.data());
    Ok(PhongTiming {
        s,
        order,
        angular: median(ta),
        frequency: median(tf),
        support,
        rel_diff: (num / den.max(f64::MIN_POSITIVE)).sqrt(),
        residual_bound: residual,
    })
}

/// Least-squares slope of `log y` against `log x` and its intercept.
#[must_use]
pub fn loglog_fit(x: &[f64], y: &[f64]) -> (f64, f64) {
    let n = x.len().min(y.len()) as f64;
    let lx: Vec<f64> = x.iter().map(|v| v.ln()).collect();
    let ly: Vec<f64> = y.iter().map(|v| v.ln()).collect();
    let mx = lx.iter().sum::<f64>() / n;
    let my = ly.iter().sum::<f64>() / n;
    let sxy: f64 = lx.iter().zip(&ly).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = lx.iter().map(|a| (a - mx) * (a - mx)).sum();
    let slope = sxy / sxx;
    (slope, my - slope * mx)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_map() -> Image {
        let (w, h) = (64, 32);
        let data: Vec<f32> = (0..w * h)
            .flat_map(|k| {
                let (u, v) = (k % w, k / w);
                let x = 1.0 + ((u * 7 + v * 3) % 11) as f32 * 0.2;
                [x, 0.5 * x, if v < 6 && u < 8 { 20.0 } else { 0.3 }]
            })
            .collect();
        Image::from_vec(w, h, 3, data).expect("map")
    }

    #[test]
    fn angular_and_frequency_sides_compute_the_same_map() {
        let env = test_map();
        for s in [4.0, 16.0] {
            let f = phong_frequency(&env, s, 30).expect("frequency");
            // a tiny eps: the angular side sums (nearly) the whole hemisphere
            let (a, _) = phong_angular(&env, s, 1e-9).expect("angular");
            let (num, den) = squared_errors(f.data(), a.data());
            let rel = (num / den).sqrt();
            assert!(rel < 2e-3, "s = {s}: {rel}");
        }
    }

    #[test]
    fn the_cap_intervals_miss_no_texel_of_the_support() {
        // brute force: every input texel, the kernel masked to the eps-support
        let env = test_map();
        let (w, h) = (env.width(), env.height());
        let (s, eps) = (12.0, 0.01);
        let (got, support) = phong_angular(&env, s, eps).expect("angular");
        let cos_star = f64::powf(eps, 1.0 / (s + 1.0));
        let dir = |u: usize, v: usize| {
            let t = PI * (v as f64 + 0.5) / h as f64;
            let p = 2.0 * PI * (u as f64 + 0.5) / w as f64;
            [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
        };
        let sa = |v: usize| {
            (2.0 * PI / w as f64)
                * ((PI * v as f64 / h as f64).cos() - (PI * (v + 1) as f64 / h as f64).cos())
        };
        let mut inside = 0usize;
        for (vr, ur) in [(0, 0), (3, 17), (16, 40), (31, 63), (20, 5)] {
            let r = dir(ur, vr);
            let mut want = [0.0f64; 3];
            for v in 0..h {
                for u in 0..w {
                    let l = dir(u, v);
                    let t = r[0] * l[0] + r[1] * l[1] + r[2] * l[2];
                    if t >= cos_star {
                        inside += 1;
                        let k = t.powf(s) * sa(v) * (s + 1.0) / (2.0 * PI) / (1.0 - eps);
                        for (c, wv) in want.iter_mut().enumerate() {
                            *wv += k * f64::from(env.data()[(v * w + u) * 3 + c]);
                        }
                    }
                }
            }
            for (c, wv) in want.iter().enumerate() {
                let g = f64::from(got.data()[(vr * w + ur) * 3 + c]);
                assert!(
                    (g - wv).abs() <= 1e-5 * wv.abs().max(1e-3),
                    "({vr},{ur}) {g} vs {wv}"
                );
            }
        }
        // the intervals visited cover the cap with a little slack
        assert!(
            support >= inside as f64 / 5.0 * 0.9,
            "{support} vs {inside}"
        );
    }
}
