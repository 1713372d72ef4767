//! Footprints too small for the scale stack: the pixel-integrated
//! anisotropic Gaussian evaluated directly, from tables of sparse taps.
//!
//! The derivation and conventions are documented on [`DirectKernels`].

use ifd_image::Image;
use ifd_planar::Border;
use rayon::prelude::*;

/// Footprint scales below this (pixels) are evaluated directly.
pub const DIRECT_BELOW: f64 = 2.0;

/// Aspect-ratio entries per doubling in the direct tables.
const ASPECTS_PER_OCTAVE: f64 = 4.0;

/// Standard deviations of the pixel-averaged kernel covered by the taps.
const REACH_SIGMAS: f64 = 5.0;

/// One weight of a sparse kernel: offset `(dx, dy)` in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tap {
    /// Column offset.
    pub dx: i16,
    /// Row offset.
    pub dy: i16,
    /// Weight.
    pub w: f32,
}

/// `erfc(x)`, fractional error below 1.2e-7 everywhere (the Chebyshev
/// fit of Press et al., Numerical Recipes, section 6.2).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

/// The standard normal cumulative distribution function.
fn norm_cdf(z: f64) -> f64 {
    0.5 * erfc(-z * std::f64::consts::FRAC_1_SQRT_2)
}

/// The covariance `(Sxx, Sxy, Syy)` of a Gaussian with standard deviations
/// `sx` along `theta` (degrees counter-clockwise on screen, `y` down) and
/// `sy` across.
#[must_use]
pub fn covariance(theta_deg: f64, sx: f64, sy: f64) -> [f64; 3] {
    let (s, c) = theta_deg.to_radians().sin_cos();
    // e1 = (c, -s), e2 = (s, c).
    let (a, b) = (sx * sx, sy * sy);
    [
        a * c * c + b * s * s,
        -a * c * s + b * s * c,
        a * s * s + b * c * c,
    ]
}

/// Nodes and weights of 4-point Gauss-Legendre quadrature on `[-1, 1]`.
const NODES: [f64; 4] = [
    -0.861_136_311_594_052_6,
    -0.339_981_043_584_856_3,
    0.339_981_043_584_856_3,
    0.861_136_311_594_052_6,
];
const WEIGHTS: [f64; 4] = [
    0.347_854_845_137_453_9,
    0.652_145_154_862_546_1,
    0.652_145_154_862_546_1,
    0.347_854_845_137_453_9,
];

/// The integral of `N(0, Sigma)` over the rectangle `[x0, x1] x [y0, y1]`
/// (see the module documentation for the formula).
///
/// ```
/// use ifd_smooth::{cell_integral, covariance};
/// // An isotropic Gaussian: the product of two 1D integrals.
/// let w = cell_integral(covariance(0.0, 1.0, 1.0), [-0.5, 0.5], [-0.5, 0.5]);
/// assert!((w - 0.382_924_922_548_026_f64.powi(2)).abs() < 1e-6);
/// ```
#[must_use]
pub fn cell_integral(cov: [f64; 3], xr: [f64; 2], yr: [f64; 2]) -> f64 {
    let [sxx, sxy, syy] = cov;
    // Integrate over the coordinate of larger variance.
    let (var, cross, other, outer, inner) = if syy >= sxx {
        (syy, sxy, sxx, yr, xr)
    } else {
        (sxx, sxy, syy, xr, yr)
    };
    let det = (other * var - cross * cross).max(1e-300);
    let sd = var.sqrt();
    let m = cross / var;
    let c = (det / var).sqrt();
    let lo = outer[0].max(-9.0 * sd);
    let hi = outer[1].min(9.0 * sd);
    if lo >= hi {
        return 0.0;
    }
    // Sub-intervals narrower than the marginal's sd and the bracket's
    // switching width c / |m|.
    let rate = (1.0 / sd).max(m.abs() / c);
    let n = ((hi - lo) * rate * 2.0).ceil().clamp(1.0, 64.0) as usize;
    let h = (hi - lo) / n as f64;
    let norm = 1.0 / (sd * (2.0 * std::f64::consts::PI).sqrt());
    let mut sum = 0.0;
    for k in 0..n {
        let mid = lo + (k as f64 + 0.5) * h;
        for (t, wt) in NODES.iter().zip(WEIGHTS) {
            let y = mid + 0.5 * h * t;
            let marg = norm * (-0.5 * y * y / var).exp();
            let bracket = norm_cdf((inner[1] - m * y) / c) - norm_cdf((inner[0] - m * y) / c);
            sum += wt * marg * bracket;
        }
    }
    sum * 0.5 * h
}

/// The pixel-integrated Gaussian `(theta, sx, sy)` as sparse taps summing
/// to 1 (weights below `1e-7` of the total dropped).
///
/// ```
/// use ifd_smooth::integrated_kernel;
/// let k = integrated_kernel(30.0, 2.0, 0.125);
/// let sum: f32 = k.iter().map(|t| t.w).sum();
/// assert!((sum - 1.0).abs() < 1e-5);
/// assert!(k.len() < 80); // a few taps
/// ```
#[must_use]
pub fn integrated_kernel(theta_deg: f64, sx: f64, sy: f64) -> Vec<Tap> {
    let cov = covariance(theta_deg, sx, sy);
    // Reach: the pixel-averaged kernel's extent along x and y.
    let rx = (REACH_SIGMAS * (cov[0] + 1.0 / 12.0).sqrt() + 0.5).ceil() as i64;
    let ry = (REACH_SIGMAS * (cov[2] + 1.0 / 12.0).sqrt() + 0.5).ceil() as i64;
    // Mahalanobis test on cell centres (with the pixel's own spread added).
    let (a, b, c) = (cov[0] + 0.5, cov[1], cov[2] + 0.5);
    let det = a * c - b * b;
    let lim = REACH_SIGMAS * REACH_SIGMAS;
    let mut taps = Vec::new();
    for dy in -ry..=ry {
        for dx in -rx..=rx {
            let (x, y) = (dx as f64, dy as f64);
            if (c * x * x - 2.0 * b * x * y + a * y * y) / det > lim {
                continue;
            }
            let w = cell_integral(cov, [x - 0.5, x + 0.5], [y - 0.5, y + 0.5]);
            taps.push(Tap {
                dx: dx as i16,
                dy: dy as i16,
                w: w as f32,
            });
        }
    }
    let total: f64 = taps.iter().map(|t| f64::from(t.w)).sum();
    taps.retain(|t| f64::from(t.w) > 1e-7 * total);
    let total: f64 = taps.iter().map(|t| f64::from(t.w)).sum();
    for t in &mut taps {
        t.w = (f64::from(t.w) / total) as f32;
    }
    taps
}

/// The kernels of one aspect ratio at evenly spaced angles over 180 degrees.
#[derive(Clone, Debug)]
struct AspectEntry {
    kernels: Vec<Vec<Tap>>,
}

/// Pixel-integrated anisotropic Gaussians of one footprint scale, tabulated
/// over aspect ratio and angle (see the module documentation).
///
/// Below [`DIRECT_BELOW`] px the smoother's Gaussians are narrower than the
/// stack's finest levels represent (at footprint `S = 0.5` and aspect 16 the
/// short axis has `sigma = 0.125` px), so a pixel's filter is applied as the
/// weights of the continuous Gaussian **integrated over each pixel cell**:
///
/// `w(i, j) = integral over [i - 1/2, i + 1/2] x [j - 1/2, j + 1/2] of
/// N(u; 0, Sigma) du`, `Sigma = sx^2 e1 e1^T + sy^2 e2 e2^T`,
///
/// with `e1 = (cos theta, -sin theta)` the long axis (`theta`
/// counter-clockwise on screen, `y` down) and `e2` perpendicular. At `S = 0.5`
/// a pixel reads a handful of taps; the weights sum to 1 (up to the
/// truncation at 5 standard deviations, renormalised).
///
/// **The cell integral.** A bivariate normal factors into the marginal of
/// one coordinate and the conditional of the other: with `y` the coordinate
/// of larger variance, `x | y ~ N(m y, c^2)`, `m = Sxy / Syy`,
/// `c^2 = det(Sigma) / Syy`, so
///
/// `w = integral_{y0}^{y1} phi(y / sqrt Syy) / sqrt Syy
///      [Phi((x1 - m y) / c) - Phi((x0 - m y) / c)] dy`.
///
/// The outer integrand is smooth (the marginal has the larger standard
/// deviation, at least `S / sqrt 2`) except where the bracket switches on or
/// off, over a width `c / |m|` in `y`; composite 4-point Gauss-Legendre
/// with sub-intervals narrower than that integrates it to about 1e-7
/// (tested against dense supersampling).
///
/// **Tables.** Per pixel the filter changes with the orientation field, so
/// the weights are tabulated over aspect ratio (four entries per octave,
/// blended linearly in `log a` like the IFD bank) and angle (a step that
/// keeps the blend of neighbouring angles within about 0.2% of the exact
/// kernel: finer for longer, thinner kernels; one angle for the isotropic
/// entry). A pixel blends four tabulated kernels.
#[derive(Clone, Debug)]
pub struct DirectKernels {
    scale: f64,
    aspects: Vec<f64>,
    entries: Vec<AspectEntry>,
    reach: usize,
}

impl DirectKernels {
    /// Tables for footprint `scale` (`sx sy = scale^2`) and aspect ratios
    /// `1..=max_aspect`.
    #[must_use]
    pub fn new(scale: f64, max_aspect: f64) -> Self {
        let aspects = crate::bank::log_spaced_aspects(max_aspect, ASPECTS_PER_OCTAVE);
        let entries: Vec<AspectEntry> = aspects
            .par_iter()
            .map(|&a| {
                let (sx, sy) = (scale * a.sqrt(), scale / a.sqrt());
                let n_angles = Self::angles_for(sx, sy);
                let kernels = (0..n_angles)
                    .into_par_iter()
                    .map(|j| integrated_kernel(180.0 * j as f64 / n_angles as f64, sx, sy))
                    .collect();
                AspectEntry { kernels }
            })
            .collect();
        let reach = entries
            .iter()
            .flat_map(|e| e.kernels.iter().flatten())
            .map(|t| t.dx.unsigned_abs().max(t.dy.unsigned_abs()) as usize)
            .max()
            .unwrap_or(0);
        Self {
            scale,
            aspects,
            entries,
            reach,
        }
    }

    /// Angles over 180 degrees for a kernel `(sx, sy)`: the blend of two
    /// neighbouring angles errs by about `(step * ratio)^2 / 8` relative
    /// (ratio of the pixel-averaged axes), kept near 0.2%.
    fn angles_for(sx: f64, sy: f64) -> usize {
        if (sx - sy).abs() < 1e-12 {
            return 1;
        }
        let ratio = ((sx * sx + 1.0 / 12.0) / (sy * sy + 1.0 / 12.0)).sqrt();
        let step = 0.126 / ratio;
        ((std::f64::consts::PI / step).ceil() as usize).clamp(8, 1440)
    }

    /// The footprint scale.
    #[must_use]
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The largest tap offset, pixels.
    #[must_use]
    pub fn reach(&self) -> usize {
        self.reach
    }

    /// The number of stored taps (memory: 8 bytes each).
    #[must_use]
    pub fn taps(&self) -> usize {
        self.entries
            .iter()
            .flat_map(|e| e.kernels.iter())
            .map(Vec::len)
            .sum()
    }

    /// The (up to four) tabulated kernels of filter `(theta, aspect)` and
    /// their blend weights.
    fn blend(&self, theta: f32, aspect: f32) -> impl Iterator<Item = (&[Tap], f32)> {
        let n = self.aspects.len();
        let (i, t) = crate::bank::locate_aspect(&self.aspects, f64::from(aspect));
        let th = f64::from(theta).rem_euclid(180.0);
        [(i, 1.0 - t), (i + 1, t)]
            .into_iter()
            .filter(move |&(k, wk)| k < n && wk > 0.0)
            .flat_map(move |(k, wk)| {
                let ks = &self.entries[k].kernels;
                let m = ks.len();
                let u = th / 180.0 * m as f64;
                let j = (u.floor() as usize).min(m - 1);
                let f = u - j as f64;
                [(j, 1.0 - f), ((j + 1) % m, f)]
                    .into_iter()
                    .filter(move |&(_, wf)| wf > 0.0)
                    .map(move |(jj, wf)| (ks[jj].as_slice(), (wk * wf) as f32))
            })
    }

    /// Adds `weight *` the filter `(theta, aspect)` applied at pixel `(x, y)`
    /// of `image` to `out` (one value per channel).
    pub fn accumulate(
        &self,
        image: &Image,
        border: Border,
        (x, y): (usize, usize),
        (theta, aspect): (f32, f32),
        weight: f32,
        out: &mut [f32],
    ) {
        let (w, h, c) = (image.width(), image.height(), image.channels());
        let data = image.data();
        let r = self.reach;
        let inside = x >= r && y >= r && x + r < w && y + r < h;
        for (taps, wk) in self.blend(theta, aspect) {
            let wk = wk * weight;
            for t in taps {
                let (xx, yy) = (x as i64 + i64::from(t.dx), y as i64 + i64::from(t.dy));
                let wt = wk * t.w;
                let at = if inside {
                    Some((xx as usize, yy as usize))
                } else if let (Some(xi), Some(yi)) = (border.resolve(xx, w), border.resolve(yy, h))
                {
                    Some((xi, yi))
                } else {
                    None
                };
                if let Some((xi, yi)) = at {
                    let o = (yi * w + xi) * c;
                    for (oc, v) in out.iter_mut().zip(&data[o..o + c]) {
                        *oc += wt * v;
                    }
                } else {
                    let v = border.constant();
                    for oc in out.iter_mut() {
                        *oc += wt * v;
                    }
                }
            }
        }
    }

    /// The blended kernel of filter `(theta, aspect)` as dense weights on a
    /// `(2 reach + 1)^2` grid, row-major (tests, plots).
    #[must_use]
    pub fn dense(&self, theta: f32, aspect: f32) -> Vec<f64> {
        let r = self.reach as i64;
        let n = (2 * r + 1) as usize;
        let mut k = vec![0.0; n * n];
        for (taps, wk) in self.blend(theta, aspect) {
            for t in taps {
                let (i, j) = (
                    (i64::from(t.dx) + r) as usize,
                    (i64::from(t.dy) + r) as usize,
                );
                k[j * n + i] += f64::from(wk) * f64::from(t.w);
            }
        }
        k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dense midpoint supersampling of the cell integral.
    fn supersampled(cov: [f64; 3], x: f64, y: f64, n: usize) -> f64 {
        let [a, b, c] = cov;
        let det = a * c - b * b;
        let norm = 1.0 / (2.0 * std::f64::consts::PI * det.sqrt());
        let mut s = 0.0;
        for j in 0..n {
            for i in 0..n {
                let u = x - 0.5 + (i as f64 + 0.5) / n as f64;
                let v = y - 0.5 + (j as f64 + 0.5) / n as f64;
                let q = (c * u * u - 2.0 * b * u * v + a * v * v) / det;
                s += (-0.5 * q).exp();
            }
        }
        s * norm / (n * n) as f64
    }

    #[test]
    fn erfc_matches_known_values() {
        // erfc(0.5), erfc(1), erfc(2), erfc(-1) to 10 digits.
        for (x, v) in [
            (0.5, 0.479_500_122_2),
            (1.0, 0.157_299_207_1),
            (2.0, 0.004_677_734_981),
            (-1.0, 1.842_700_792_9),
        ] {
            assert!(((erfc(x) - v) / v).abs() < 2e-7, "{x}");
        }
    }

    #[test]
    fn cell_integral_matches_supersampling() {
        for (theta, sx, sy) in [
            (0.0, 1.0, 1.0),
            (30.0, 2.0, 0.125),
            (45.0, 8.0, 0.5),
            (-75.0, 0.7, 0.3),
        ] {
            let cov = covariance(theta, sx, sy);
            for (x, y) in [
                (0.0, 0.0),
                (1.0, 0.0),
                (1.0, -1.0),
                (-2.0, 1.0),
                (3.0, -2.0),
            ] {
                let a = cell_integral(cov, [x - 0.5, x + 0.5], [y - 0.5, y + 0.5]);
                let b = supersampled(cov, x, y, 600);
                assert!(
                    (a - b).abs() < 2e-5,
                    "{theta} {sx} {sy} at ({x}, {y}): {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn orientation_convention() {
        // 30 degrees counter-clockwise on screen: the long axis points right
        // and up, i.e. towards (+x, -y) in pixel coordinates.
        let k = DirectKernels::new(1.5, 16.0);
        let d = k.dense(30.0, 16.0);
        let r = k.reach() as i64;
        let n = (2 * r + 1) as usize;
        let at = |x: i64, y: i64| d[((y + r) as usize) * n + (x + r) as usize];
        assert!(at(4, -2) > 10.0 * at(4, 2), "{} {}", at(4, -2), at(4, 2));
    }

    #[test]
    fn blends_stay_close_to_the_exact_kernel() {
        for scale in [0.5, 1.0, 1.9] {
            let k = DirectKernels::new(scale, 16.0);
            let r = k.reach() as i64;
            let n = (2 * r + 1) as usize;
            let mut worst: f64 = 0.0;
            for (theta, aspect) in [
                (13.7f64, 1.3f64),
                (61.1, 3.1),
                (-33.3, 7.7),
                (88.8, 12.9),
                (100.0, 16.0),
            ] {
                let got = k.dense(theta as f32, aspect as f32);
                let (sx, sy) = (scale * aspect.sqrt(), scale / aspect.sqrt());
                let mut want = vec![0.0; n * n];
                for t in integrated_kernel(theta, sx, sy) {
                    let (i, j) = (i64::from(t.dx) + r, i64::from(t.dy) + r);
                    assert!((0..n as i64).contains(&i) && (0..n as i64).contains(&j));
                    want[j as usize * n + i as usize] += f64::from(t.w);
                }
                let num: f64 = got.iter().zip(&want).map(|(a, b)| (a - b).powi(2)).sum();
                let den: f64 = want.iter().map(|b| b * b).sum();
                worst = worst.max((num / den).sqrt());
            }
            assert!(worst < 0.006, "scale {scale}: {worst}");
        }
    }
}
