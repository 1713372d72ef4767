//! SH analysis (projection) and synthesis of environment maps.
//!
//! # Equirectangular maps
//! A `W x H` map with `W = 2H`: column `u` has azimuth `p = 2 pi (u + 0.5) / W`,
//! row `v` (row 0 at the top) has polar angle `t = pi (v + 0.5) / H`, so the top
//! row looks up (`+z`). The projection is the quadrature
//!
//! ```text
//! c_l^m = sum_pixels f(w_uv) y_l^m(w_uv) dA_v,
//! dA_v  = (2 pi / W) (cos(pi v / H) - cos(pi (v + 1) / H))
//! ```
//!
//! where `dA_v` is the *exact* solid angle of the pixel (the weights sum to
//! `4 pi` exactly). It is computed as an FFT over each row (giving the
//! azimuthal Fourier coefficients for every `m` at once) followed by the
//! Legendre recurrences of [`crate::sh`] over `l`, processing the rows `v` and
//! `H - 1 - v` together (`P_l^m(-z) = (-1)^(l+m) P_l^m(z)`; two real rows share
//! one complex FFT). Cost `O(H W log W + H L^2)` per channel.
//! Synthesis runs the same steps backwards and evaluates the expansion exactly
//! at the pixel centres.
//!
//! # Cubemaps
//! [`analyze_cubemap`] projects a horizontal strip of six square faces in the
//! order `+X, -X, +Y, -Y, +Z, -Z`, each face laid out as in OpenGL (face
//! coordinates `sc, tc` of the OpenGL cube-map table, `tc` growing downwards
//! in the image), with exact per-texel solid angles. It evaluates the SH per
//! texel (`O(texels L^2)`).
//!
//! # Bad input
//! NaN or infinite samples are an error ([`crate::SphereError::NonFinite`]).
//! Negative samples (the bundled DWAB files have a few tiny ones) are clamped to
//! zero by default and counted in [`Analysis::negatives_clamped`].

use std::f64::consts::PI;
use std::sync::Arc;

use ifd_image::Image;
use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError, check_degree};
use crate::sh::{LegendreTable, ShEvaluator, gauss_legendre, sh_count};

/// Rows processed together by the analyses (their Legendre recurrences
/// vectorise across rows).
const ANALYSIS_LANES: usize = 4;

/// What to do with negative samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Negatives {
    /// Clamp them to zero and count them (the default: radiance is never negative).
    #[default]
    Clamp,
    /// Keep them as they are.
    Keep,
}

/// The result of a projection.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// The SH coefficients, one column per image channel.
    pub coeffs: ShCoeffs,
    /// How many samples were negative (and clamped, with [`Negatives::Clamp`]).
    pub negatives_clamped: usize,
}

/// A reusable plan for SH analysis/synthesis of `W x H` equirectangular maps
/// up to degree `L` (FFT plans and recurrence tables).
///
/// ```
/// use ifd_sphere::{EquirectTransform, Negatives, ShCoeffs};
/// let t = EquirectTransform::new(8, 128, 64)?;
/// let mut f = ShCoeffs::zeros(8, 1)?;
/// f.set(3, -2, 0, 1.0);
/// let img = t.synthesize(&f)?;
/// // keep negatives: the default clamps them (radiance is never negative)
/// let back = t.analyze(&img, Negatives::Keep)?.coeffs;
/// // band-limited maps round-trip up to the quadrature error of the pixel grid
/// assert!((back.get(3, -2, 0) - 1.0).abs() < 1e-3);
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
pub struct EquirectTransform {
    l_max: usize,
    width: usize,
    height: usize,
    table: LegendreTable,
    fwd: Arc<dyn Fft<f64>>,
    inv: Arc<dyn Fft<f64>>,
    /// `cos t_v`, `sin t_v`, `dA_v` of the northern rows `v < ceil(H / 2)`.
    rows: Vec<(f64, f64, f64)>,
    /// `e^{-i pi m / W}` for `m = 0..=L`.
    phase: Vec<Complex64>,
}

impl std::fmt::Debug for EquirectTransform {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EquirectTransform")
            .field("l_max", &self.l_max)
            .field("width", &self.width)
            .field("height", &self.height)
            .finish_non_exhaustive()
    }
}

impl EquirectTransform {
    /// Plans transforms of `width x height` maps (`width = 2 height`) up to degree `l_max`.
    ///
    /// # Errors
    /// [`SphereError::NotEquirect`] unless `width == 2 height` and `height >= 2`;
    /// [`SphereError::DegreeTooHigh`].
    pub fn new(l_max: usize, width: usize, height: usize) -> Result<Self> {
        check_degree(l_max)?;
        if height < 2 || width != 2 * height {
            return Err(SphereError::NotEquirect { width, height });
        }
        let mut planner = FftPlanner::new();
        let hf = height as f64;
        let rows = (0..height.div_ceil(2))
            .map(|v| {
                let t = PI * (v as f64 + 0.5) / hf;
                let da = (2.0 * PI / width as f64)
                    * ((PI * v as f64 / hf).cos() - (PI * (v as f64 + 1.0) / hf).cos());
                (t.cos(), t.sin(), da)
            })
            .collect();
        let phase = (0..=l_max)
            .map(|m| Complex64::from_polar(1.0, -PI * m as f64 / width as f64))
            .collect();
        Ok(Self {
            l_max,
            width,
            height,
            table: LegendreTable::new(l_max),
            fwd: planner.plan_fft_forward(width),
            inv: planner.plan_fft_inverse(width),
            rows,
            phase,
        })
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// Map width.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Map height.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Exact solid angle of a pixel of row `v`.
    ///
    /// # Panics
    /// If `v >= H`.
    #[must_use]
    pub fn pixel_solid_angle(&self, v: usize) -> f64 {
        assert!(v < self.height);
        let vn = v.min(self.height - 1 - v);
        self.rows[vn].2
    }

    /// Checks that `img` has the plan's size and finite samples; returns how
    /// many are negative.
    fn check_map(&self, img: &Image) -> Result<usize> {
        if img.width() != self.width || img.height() != self.height {
            return Err(SphereError::NotEquirect {
                width: img.width(),
                height: img.height(),
            });
        }
        count_negatives_of_finite_map(img.data(), "environment map")
    }

    /// Adds the Legendre sums of one block of `LANES` (virtual) rows to the
    /// coefficients `out`: `P_l^m(z)` of the northern rows (`zs`, `sin t` in
    /// `ss`) met with the even (`l + m` even) or odd combination of each row
    /// pair's Fourier sums, `even`/`odd[(m C + c) LANES + lane]`.
    #[expect(clippy::too_many_arguments, reason = "one block's inputs and scratch")]
    fn legendre_sums(
        &self,
        zs: &[f64; ANALYSIS_LANES],
        ss: &[f64; ANALYSIS_LANES],
        even: &[Complex64],
        odd: &[Complex64],
        ch: usize,
        col: &mut [[f64; ANALYSIS_LANES]],
        out: &mut [f64],
    ) {
        const LANES: usize = ANALYSIS_LANES;
        let l_max = self.l_max;
        let mut sm = [1.0; LANES];
        for m in 0..=l_max {
            if m > 0 {
                for (a, b) in sm.iter_mut().zip(ss) {
                    *a *= b;
                }
            }
            self.table.column(m, zs, &sm, col);
            for l in m..=l_max {
                let p = &col[l - m];
                let src = if (l + m) % 2 == 0 { even } else { odd };
                let base = l * (l + 1);
                for c in 0..ch {
                    let x = &src[(m * ch + c) * LANES..][..LANES];
                    let (mut re, mut im) = (0.0, 0.0);
                    for (p, x) in p.iter().zip(x) {
                        re += p * x.re;
                        im += p * x.im;
                    }
                    if m == 0 {
                        out[base * ch + c] += re;
                    } else {
                        out[(base + m) * ch + c] += std::f64::consts::SQRT_2 * re;
                        out[(base - m) * ch + c] -= std::f64::consts::SQRT_2 * im;
                    }
                }
            }
        }
    }

    /// Projects an equirectangular map (any channel count) onto SH up to `L`.
    ///
    /// # Errors
    /// [`SphereError::NotEquirect`] when the image size differs from the plan;
    /// [`SphereError::NonFinite`] for NaN/infinite samples.
    pub fn analyze(&self, img: &Image, negatives: Negatives) -> Result<Analysis> {
        const LANES: usize = ANALYSIS_LANES;
        let negatives_clamped = self.check_map(img)?;
        let data = img.data();
        let clamp = negatives == Negatives::Clamp;
        let (w, h, ch) = (self.width, self.height, img.channels());
        let l_max = self.l_max;
        let mut coeffs = ShCoeffs::zeros(l_max, ch)?;
        let out = coeffs.data_mut();
        let mut buf = vec![Complex64::default(); w];
        let mut scratch = vec![Complex64::default(); self.fwd.get_inplace_scratch_len()];
        // Row pairs are processed LANES at a time: their even/odd Fourier
        // combinations per (m, channel, lane), then the Legendre sums of all
        // lanes together (`LegendreTable::column` vectorises the recurrence across
        // rows, and each coefficient is updated once per block).
        let mut even = vec![Complex64::default(); (l_max + 1) * ch * LANES];
        let mut odd = vec![Complex64::default(); (l_max + 1) * ch * LANES];
        let mut col = vec![[0.0; LANES]; l_max + 1];
        let row = |v: usize| &data[v * w * ch..(v + 1) * w * ch];
        let load = |x: f32| {
            let x = f64::from(x);
            if clamp { x.max(0.0) } else { x }
        };
        for (bi, block) in self.rows.chunks(LANES).enumerate() {
            let first = bi * LANES;
            // Unused lanes of the last block: zero data, harmless arguments.
            let mut zs = [0.0; LANES];
            let mut ss = [1.0; LANES];
            even.fill(Complex64::default());
            odd.fill(Complex64::default());
            for (lane, &(z, s, da)) in block.iter().enumerate() {
                zs[lane] = z;
                ss[lane] = s;
                let vn = first + lane;
                let vs = h - 1 - vn;
                let north = row(vn);
                // The southern row of the pair rides in the imaginary part
                // (one complex FFT for two real rows); the equator row of an
                // odd height has no partner.
                let south = (vs != vn).then(|| row(vs));
                for c in 0..ch {
                    match south {
                        Some(south) => {
                            for ((b, n), s) in buf
                                .iter_mut()
                                .zip(north.iter().skip(c).step_by(ch))
                                .zip(south.iter().skip(c).step_by(ch))
                            {
                                *b = Complex64::new(load(*n), load(*s));
                            }
                        }
                        None => {
                            for (b, n) in buf.iter_mut().zip(north.iter().skip(c).step_by(ch)) {
                                *b = Complex64::new(load(*n), 0.0);
                            }
                        }
                    }
                    self.fwd.process_with_scratch(&mut buf, &mut scratch);
                    for m in 0..=l_max {
                        let k = m % w;
                        let zk = buf[k];
                        let zmk = buf[(w - k) % w].conj();
                        let fn_ = (zk + zmk) * 0.5 * self.phase[m];
                        let fs = (zk - zmk) * Complex64::new(0.0, -0.5) * self.phase[m];
                        let i = (m * ch + c) * LANES + lane;
                        even[i] = (fn_ + fs) * da;
                        odd[i] = (fn_ - fs) * da;
                    }
                }
            }
            // Legendre sums: P_l^m(z) of the northern rows, with the even
            // (l + m even) or odd combination of each row pair.
            self.legendre_sums(&zs, &ss, &even, &odd, ch, &mut col, out);
        }
        Ok(Analysis {
            coeffs,
            negatives_clamped,
        })
    }

    /// Projects the map read as **piecewise constant** over its texels, the
    /// fast form of [`analyze_equirect_box`] (same result to quadrature
    /// rounding): `c_l^m = sum_texels E_uv int_texel y_l^m(w) dw`.
    ///
    /// The azimuthal texel integral is exact: the row's FFT sums times
    /// `d sinc(m d / 2)` (`d = 2 pi / W`). The polar integral of each row runs
    /// on `n = max(3, 2 + ceil(x / 2))` Gauss-Legendre nodes, `x = (L + 1) pi /
    /// H` the top band's phase across a row (the Gauss error bound
    /// `x^(2n) (n!)^4 / ((2n + 1) ((2n)!)^3)` stays below about `5e-6` of the
    /// row integral at the top band, and falls fast below it), each node a
    /// "virtual row" of the pixel-centre algorithm of [`Self::analyze`]
    /// (mirrored nodes of rows `v` and `H - 1 - v` still pair up). Rows run in
    /// parallel. Cost `O(H W log W + n H L^2)` per channel.
    ///
    /// ```
    /// use ifd_sphere::{EquirectTransform, Negatives};
    /// // a constant map projects to c_00 = sqrt(4 pi), nothing else (to the
    /// // polar quadrature's few 1e-6 at the top band of so small a map)
    /// let img = ifd_image::Image::from_vec(16, 8, 1, vec![1.0; 128])?;
    /// let t = EquirectTransform::new(6, 16, 8)?;
    /// let c = t.analyze_texels(&img, Negatives::Keep)?.coeffs;
    /// assert!((c.get(0, 0, 0) - (4.0 * std::f64::consts::PI).sqrt()).abs() < 1e-8);
    /// assert!(c.data()[1..].iter().all(|v| v.abs() < 2e-5));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`Self::analyze`].
    pub fn analyze_texels(&self, img: &Image, negatives: Negatives) -> Result<Analysis> {
        use rayon::prelude::*;
        const LANES: usize = ANALYSIS_LANES;
        let negatives_clamped = self.check_map(img)?;
        let data = img.data();
        let clamp = negatives == Negatives::Clamp;
        let (w, h, ch) = (self.width, self.height, img.channels());
        let l_max = self.l_max;
        let d = 2.0 * PI / w as f64;
        let boxf: Vec<f64> = (0..=l_max)
            .map(|m| {
                let x = 0.5 * m as f64 * d;
                if m == 0 { d } else { d * x.sin() / x }
            })
            .collect();
        let load = |x: f32| {
            let x = f64::from(x);
            if clamp { x.max(0.0) } else { x }
        };
        // 1. Azimuthal texel integrals of every row pair: (north, south) per (m, c).
        let n_pairs = self.rows.len();
        let fourier: Vec<Vec<(Complex64, Complex64)>> = (0..n_pairs)
            .into_par_iter()
            .map_init(
                || {
                    (
                        vec![Complex64::default(); w],
                        vec![Complex64::default(); self.fwd.get_inplace_scratch_len()],
                    )
                },
                |(buf, scratch), vn| {
                    let vs = h - 1 - vn;
                    let north = &data[vn * w * ch..(vn + 1) * w * ch];
                    let south = (vs != vn).then(|| &data[vs * w * ch..(vs + 1) * w * ch]);
                    let mut out =
                        vec![(Complex64::default(), Complex64::default()); (l_max + 1) * ch];
                    for c in 0..ch {
                        for (u, b) in buf.iter_mut().enumerate() {
                            let s = south.map_or(0.0, |s| load(s[u * ch + c]));
                            *b = Complex64::new(load(north[u * ch + c]), s);
                        }
                        self.fwd.process_with_scratch(buf, scratch);
                        for m in 0..=l_max {
                            let k = m % w;
                            let zk = buf[k];
                            let zmk = buf[(w - k) % w].conj();
                            let ph = self.phase[m] * boxf[m];
                            let fn_ = (zk + zmk) * 0.5 * ph;
                            let fs = (zk - zmk) * Complex64::new(0.0, -0.5) * ph;
                            out[m * ch + c] = (fn_, fs);
                        }
                    }
                    out
                },
            )
            .collect();
        // 2. Polar integrals: Gauss-Legendre nodes of each northern row.
        let n_g = (2 + ((l_max + 1) as f64 * PI / (2.0 * h as f64)).ceil() as usize).clamp(3, 64);
        let (gx, gw) = gauss_legendre(n_g);
        let dt = PI / h as f64;
        let mut nodes = Vec::with_capacity(n_pairs * n_g);
        for vn in 0..n_pairs {
            // (an odd height's equator row has no southern partner: its
            // Fourier sums have fs = 0, so even = odd and any z is right)
            for (x, wg) in gx.iter().zip(&gw) {
                let t = dt * (vn as f64 + 0.5 + 0.5 * x);
                let (s, z) = t.sin_cos();
                nodes.push((vn, z, s, 0.5 * dt * wg * s));
            }
        }
        let n_coef = sh_count(l_max) * ch;
        let sums = nodes
            .par_chunks(LANES * 8)
            .fold(
                || vec![0.0; n_coef],
                |mut out, chunk| {
                    let mut even = vec![Complex64::default(); (l_max + 1) * ch * LANES];
                    let mut odd = vec![Complex64::default(); (l_max + 1) * ch * LANES];
                    let mut col = vec![[0.0; LANES]; l_max + 1];
                    for block in chunk.chunks(LANES) {
                        let mut zs = [0.0; LANES];
                        let mut ss = [1.0; LANES];
                        even.fill(Complex64::default());
                        odd.fill(Complex64::default());
                        for (lane, &(vn, z, s, wt)) in block.iter().enumerate() {
                            zs[lane] = z;
                            ss[lane] = s;
                            let f = &fourier[vn];
                            for (i, &(fn_, fs)) in f.iter().enumerate() {
                                even[i * LANES + lane] = (fn_ + fs) * wt;
                                odd[i * LANES + lane] = (fn_ - fs) * wt;
                            }
                        }
                        self.legendre_sums(&zs, &ss, &even, &odd, ch, &mut col, &mut out);
                    }
                    out
                },
            )
            .reduce(
                || vec![0.0; n_coef],
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(&b) {
                        *x += y;
                    }
                    a
                },
            );
        Ok(Analysis {
            coeffs: ShCoeffs::from_vec(l_max, ch, sums)?,
            negatives_clamped,
        })
    }

    /// Evaluates an SH expansion at the pixel centres of a `W x H` map, one
    /// image channel per coefficient channel. Coefficients above the plan's
    /// degree are ignored; missing ones count as zero.
    ///
    /// # Errors
    /// [`SphereError::Image`] if the image cannot be allocated.
    pub fn synthesize(&self, f: &ShCoeffs) -> Result<Image> {
        use rayon::prelude::*;
        let (w, h, ch) = (self.width, self.height, f.channels());
        let l_max = self.l_max.min(f.l_max());
        let src = f.data();
        let mut img = Image::new(w, h, ch)?;
        let sqrt2 = std::f64::consts::SQRT_2;
        // each northern row and its mirror, in parallel
        let pairs: Vec<Vec<Complex64>> = self
            .rows
            .par_iter()
            .map_init(
                || {
                    (
                        vec![[0.0; 1]; self.l_max + 1],
                        vec![Complex64::default(); self.inv.get_inplace_scratch_len()],
                    )
                },
                |(col, scratch), &(z, s, _)| {
                    let mut spec = vec![Complex64::default(); w * ch];
                    let mut sm = 1.0;
                    for m in 0..=l_max {
                        if m > 0 {
                            sm *= s;
                        }
                        self.table.column(m, &[z], &[sm], col);
                        let ph = self.phase[m].conj();
                        for c in 0..ch {
                            // even/odd (in l + m) partial sums of the cos and sin parts
                            let (mut ae, mut ao, mut be, mut bo) = (0.0, 0.0, 0.0, 0.0);
                            for l in m..=l_max {
                                let [p] = col[l - m];
                                let base = l * (l + 1);
                                let a = src[(base + m) * ch + c] * p;
                                let b = if m > 0 {
                                    src[(base - m) * ch + c] * p
                                } else {
                                    0.0
                                };
                                if (l + m) % 2 == 0 {
                                    ae += a;
                                    be += b;
                                } else {
                                    ao += a;
                                    bo += b;
                                }
                            }
                            let k = if m == 0 { 1.0 } else { sqrt2 };
                            // G = A - i B, shifted by e^{+i pi m / W}
                            let gn = Complex64::new(k * (ae + ao), -k * (be + bo)) * ph;
                            let gs = Complex64::new(k * (ae - ao), -k * (be - bo)) * ph;
                            // Hermitian spectra H^n, H^s packed as Z = H^n + i H^s
                            let i = Complex64::new(0.0, 1.0);
                            if m == 0 {
                                spec[c] += Complex64::new(gn.re, 0.0) + i * gs.re;
                            } else {
                                let kp = m % w;
                                let km = (w - kp) % w;
                                spec[kp * ch + c] += (gn + i * gs) * 0.5;
                                spec[km * ch + c] += (gn.conj() + i * gs.conj()) * 0.5;
                            }
                        }
                    }
                    // one inverse FFT per channel: row values, channel-major
                    let mut rows = vec![Complex64::default(); w * ch];
                    for c in 0..ch {
                        let buf = &mut rows[c * w..(c + 1) * w];
                        for (k, b) in buf.iter_mut().enumerate() {
                            *b = spec[k * ch + c];
                        }
                        self.inv.process_with_scratch(buf, scratch);
                    }
                    rows
                },
            )
            .collect();
        let data = img.data_mut();
        for (vn, rows) in pairs.iter().enumerate() {
            let vs = h - 1 - vn;
            for c in 0..ch {
                for (u, b) in rows[c * w..(c + 1) * w].iter().enumerate() {
                    data[(vn * w + u) * ch + c] = b.re as f32;
                    if vs != vn {
                        data[(vs * w + u) * ch + c] = b.im as f32;
                    }
                }
            }
        }
        Ok(img)
    }
}

/// The number of negative samples of a map, after checking that all are
/// finite ([`SphereError::NonFinite`] names the count and the first index);
/// one branch-free (vectorisable) pass for both counts.
fn count_negatives_of_finite_map(data: &[f32], what: &'static str) -> Result<usize> {
    let (bad, negatives) = data
        .chunks(1 << 12)
        .fold((0usize, 0usize), |(bad, neg), chunk| {
            let (mut b, mut n) = (0u32, 0u32);
            for &v in chunk {
                b += u32::from(!v.is_finite());
                n += u32::from(v < 0.0);
            }
            (bad + b as usize, neg + n as usize)
        });
    if bad > 0 {
        let first = data.iter().position(|v| !v.is_finite()).unwrap_or(0);
        return Err(SphereError::NonFinite {
            what,
            count: bad,
            first,
        });
    }
    Ok(negatives)
}

/// Projects an equirectangular image (`W = 2H`) onto SH up to `l_max`
/// (plans an [`EquirectTransform`] and runs it once).
///
/// # Errors
/// As [`EquirectTransform::new`] and [`EquirectTransform::analyze`].
pub fn analyze_equirect(img: &Image, l_max: usize, negatives: Negatives) -> Result<Analysis> {
    EquirectTransform::new(l_max, img.width(), img.height())?.analyze(img, negatives)
}

/// Projects an equirectangular map read as **piecewise constant** over its
/// texels: `c_l^m = sum_texels E_uv int_texel y_l^m(w) dw`, exactly (to
/// rounding), rather than the pixel-centre rule of [`EquirectTransform`].
///
/// This is the projection of the very function a texel-exact quadrature (the
/// shading oracle of `ifd render`) integrates, so the two differ only by the
/// band limit. Derivation: with `y_l^m(theta, phi) = Y_l^|m|(theta) c_m(phi)`
/// (`c_m = cos(m phi)` for `m >= 0`, `sin(|m| phi)` for `m < 0`, and
/// `Y_l^|m|(theta) = y_l^|m|(theta, 0)`), a texel `[phi_u -+ d/2] x [theta_v,
/// theta_v+1]` integrates to
///
/// ```text
/// int c_m dphi = c_m(phi_u) d sinc(m d / 2),   sinc(x) = sin(x) / x,
/// int Y_l^|m|(theta) sin(theta) dtheta          (Gauss-Legendre in theta),
/// ```
///
/// so each row's pixel-centre Fourier sums are scaled by `d sinc(m d / 2)`
/// and met with the row integral of `Y_l^|m|`; `Y_l^|m|(theta) sin(theta)` is
/// a trigonometric polynomial of degree `l + 1`, which
/// `max(3, 2 + ceil((L + 1) pi / (2 H)))` Gauss nodes per row integrate to
/// about `5e-6` relative at the top band (far better below). It runs as
/// [`EquirectTransform::analyze_texels`] (FFT rows, cost
/// `O(H W log W + n H L^2)` per channel).
///
/// ```
/// use ifd_sphere::transform::{Negatives, analyze_equirect_box};
/// // a constant map projects to c_00 = sqrt(4 pi), nothing else (to the
/// // polar quadrature's few 1e-6 at the top band of so small a map)
/// let img = ifd_image::Image::from_vec(16, 8, 1, vec![1.0; 128])?;
/// let c = analyze_equirect_box(&img, 6, Negatives::Keep)?.coeffs;
/// assert!((c.get(0, 0, 0) - (4.0 * std::f64::consts::PI).sqrt()).abs() < 1e-8);
/// assert!(c.data()[1..].iter().all(|v| v.abs() < 2e-5));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`SphereError::NotEquirect`], [`SphereError::NonFinite`],
/// [`SphereError::DegreeTooHigh`].
pub fn analyze_equirect_box(img: &Image, l_max: usize, negatives: Negatives) -> Result<Analysis> {
    check_degree(l_max)?;
    let (w, h) = (img.width(), img.height());
    if h < 2 || w != 2 * h {
        return Err(SphereError::NotEquirect {
            width: w,
            height: h,
        });
    }
    EquirectTransform::new(l_max, w, h)?.analyze_texels(img, negatives)
}

/// The 16 Catmull-Rom taps of a `w x h` equirectangular map (ifd's layout)
/// in direction `d` (any length): texel index `v w + u` and weight. Wraps in
/// azimuth and continues across the poles (row `-1 - v` is row `v` half a
/// turn away), so a smooth field is interpolated to `O(h^4)`.
///
/// ```
/// use ifd_sphere::transform::bicubic_taps;
/// // the weights of any lookup sum to 1
/// let taps = bicubic_taps([0.3, -0.2, 0.9], 64, 32);
/// assert!((taps.iter().map(|t| t.1).sum::<f64>() - 1.0).abs() < 1e-12);
/// ```
#[must_use]
pub fn bicubic_taps(d: [f64; 3], w: usize, h: usize) -> [(usize, f64); 16] {
    let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let t = (d[2] / r).clamp(-1.0, 1.0).acos();
    let p = d[1].atan2(d[0]).rem_euclid(2.0 * PI);
    // continuous pixel coordinates of the centres: u + 0.5 = p W / 2 pi
    let x = p / (2.0 * PI) * w as f64 - 0.5;
    let y = t / PI * h as f64 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (wx, wy) = (catmull_rom(x - x0), catmull_rom(y - y0));
    let (x0, y0) = (x0 as i64, y0 as i64);
    let (wi, hi) = (w as i64, h as i64);
    let mut taps = [(0usize, 0.0f64); 16];
    for (a, wya) in wy.iter().enumerate() {
        let mut v = y0 - 1 + a as i64;
        let mut shift = 0;
        if v < 0 {
            v = -1 - v;
            shift = wi / 2;
        } else if v >= hi {
            v = 2 * hi - 1 - v;
            shift = wi / 2;
        }
        let v = v.clamp(0, hi - 1);
        for (b, wxb) in wx.iter().enumerate() {
            let u = (x0 - 1 + b as i64 + shift).rem_euclid(wi);
            taps[a * 4 + b] = ((v * wi + u) as usize, wya * wxb);
        }
    }
    taps
}

/// Catmull-Rom weights for a fractional position `f` in `[0, 1)`.
fn catmull_rom(f: f64) -> [f64; 4] {
    let f2 = f * f;
    let f3 = f2 * f;
    [
        0.5 * (-f3 + 2.0 * f2 - f),
        0.5 * (3.0 * f3 - 5.0 * f2 + 2.0),
        0.5 * (-3.0 * f3 + 4.0 * f2 + f),
        0.5 * (f3 - f2),
    ]
}

/// An equirectangular map averaged down by an integer factor to
/// `width x height` (2:1, dividing the map's size): each new texel is the
/// solid-angle-weighted mean of the texels it covers, so the map read as
/// piecewise constant keeps its integral over every new texel.
///
/// ```
/// use ifd_sphere::transform::downsample_equirect;
/// let img = ifd_image::Image::from_vec(8, 4, 1, (0..32).map(|i| i as f32).collect())?;
/// let small = downsample_equirect(&img, 4, 2)?;
/// assert_eq!((small.width(), small.height()), (4, 2));
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
///
/// # Errors
/// [`SphereError::NotEquirect`] for a source or target that is not 2:1, or a
/// target that does not divide the source.
pub fn downsample_equirect(img: &Image, width: usize, height: usize) -> Result<Image> {
    let (w, h, ch) = (img.width(), img.height(), img.channels());
    if h < 2 || w != 2 * h {
        return Err(SphereError::NotEquirect {
            width: w,
            height: h,
        });
    }
    if height < 1 || width != 2 * height || w % width != 0 || h % height != 0 {
        return Err(SphereError::NotEquirect { width, height });
    }
    let f = h / height;
    let row_sa =
        |v: usize| (PI * v as f64 / h as f64).cos() - (PI * (v + 1) as f64 / h as f64).cos();
    let src = img.data();
    let mut out = vec![0.0f32; width * height * ch];
    let mut acc = vec![0.0f64; ch];
    for vv in 0..height {
        for uu in 0..width {
            acc.fill(0.0);
            let mut wsum = 0.0;
            for v in vv * f..(vv + 1) * f {
                let wv = row_sa(v);
                for u in uu * f..(uu + 1) * f {
                    for (c, a) in acc.iter_mut().enumerate() {
                        *a += wv * f64::from(src[(v * w + u) * ch + c]);
                    }
                    wsum += wv;
                }
            }
            for (c, a) in acc.iter().enumerate() {
                out[(vv * width + uu) * ch + c] = (a / wsum) as f32;
            }
        }
    }
    Ok(Image::from_vec(width, height, ch, out)?)
}

/// Projects weighted samples: `c_l^m = sum_i w_i f_i y_l^m(d_i)` (any quadrature
/// rule; `values` is `n x C` row-major).
///
/// # Errors
/// [`SphereError::Length`] for inconsistent lengths, [`SphereError::NonFinite`]
/// for NaN values or weights, [`SphereError::BadDirection`] for zero/NaN directions.
pub fn project_samples(
    l_max: usize,
    dirs: &[[f64; 3]],
    weights: &[f64],
    values: &[f64],
    channels: usize,
) -> Result<ShCoeffs> {
    let mut out = ShCoeffs::zeros(l_max, channels)?;
    if weights.len() != dirs.len() || values.len() != dirs.len() * channels {
        return Err(SphereError::Length {
            what: "samples (weights, values = directions x channels)",
            got: values.len(),
            expected: dirs.len() * channels,
        });
    }
    if let Some(first) = values.iter().chain(weights).position(|v| !v.is_finite()) {
        return Err(SphereError::NonFinite {
            what: "sample values or weights",
            count: values
                .iter()
                .chain(weights)
                .filter(|v| !v.is_finite())
                .count(),
            first,
        });
    }
    let sh = ShEvaluator::new(l_max)?;
    let mut y = vec![0.0; sh_count(l_max)];
    let o = out.data_mut();
    for (i, d) in dirs.iter().enumerate() {
        crate::zhf::check_direction(i, *d)?;
        sh.eval_into(*d, &mut y);
        for (k, yk) in y.iter().enumerate() {
            let wy = weights[i] * yk;
            for c in 0..channels {
                o[k * channels + c] += wy * values[i * channels + c];
            }
        }
    }
    Ok(out)
}

/// The (unnormalised) direction at face coordinates `sc, tc` in `[-1, 1]`
/// (`tc` growing downwards in the image) of cube face `face` (`0..6` =
/// `+X, -X, +Y, -Y, +Z, -Z`): the OpenGL cube-map table,
/// `direction = major + sc s_axis + tc t_axis`.
#[must_use]
pub fn cube_face_direction(face: usize, sc: f64, tc: f64) -> [f64; 3] {
    match face {
        0 => [1.0, -tc, -sc],
        1 => [-1.0, -tc, sc],
        2 => [sc, 1.0, tc],
        3 => [sc, -1.0, -tc],
        4 => [sc, -tc, 1.0],
        _ => [-sc, -tc, -1.0],
    }
}

/// Direction of texel `(i, j)` (column, row from the top) of cube face `face`
/// (`0..6` = `+X, -X, +Y, -Y, +Z, -Z`) of size `n`, and its exact solid angle.
#[must_use]
pub fn cube_texel(face: usize, i: usize, j: usize, n: usize) -> ([f64; 3], f64) {
    let nf = n as f64;
    let sc = 2.0 * (i as f64 + 0.5) / nf - 1.0;
    let tc = 2.0 * (j as f64 + 0.5) / nf - 1.0;
    let d = cube_face_direction(face, sc, tc);
    let f = |a: f64, b: f64| (a * b).atan2((a * a + b * b + 1.0).sqrt());
    let (a0, a1) = (2.0 * i as f64 / nf - 1.0, 2.0 * (i as f64 + 1.0) / nf - 1.0);
    let (b0, b1) = (2.0 * j as f64 / nf - 1.0, 2.0 * (j as f64 + 1.0) / nf - 1.0);
    let sa = f(a1, b1) - f(a0, b1) - f(a1, b0) + f(a0, b0);
    (d, sa)
}

/// How a map's texels are projected onto SH.
///
/// One rule for every front end (`ifd sphere sh`, `ifd sphere filter`, the
/// Python module), chosen by [`analyze_map`]: an equirectangular map is
/// projected texel-exactly by default, the very function `ifd render`'s oracle
/// and the IBL baker integrate, so SH read from `ifd sphere sh` agree with
/// them up to the band limit; the pixel-centre rule is there for comparison
/// with SH transforms that sample at pixel centres (ducc0, HEALPix-style
/// codes). A cubemap strip is projected at its texel centres with each
/// texel's exact solid angle: a texel-exact cube projection is not
/// implemented, and asking for one is an error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Projection {
    /// The map read as piecewise constant over its texels, each texel's
    /// integral exact ([`EquirectTransform::analyze_texels`]).
    Texel,
    /// Pixel-centre quadrature with each texel's exact solid angle
    /// ([`EquirectTransform::analyze`], [`analyze_cubemap`]).
    Centre,
}

impl Projection {
    /// The rule's name, as the CLI spells it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Texel => "texel",
            Self::Centre => "centre",
        }
    }
}

/// Projects a map onto SH up to `l_max`: a 2:1 equirectangular map or a 6:1
/// cubemap strip, told apart by shape, with `projection` (`None`: texel for
/// an equirectangular map, centre for a cube strip; see [`Projection`]).
/// Returns the analysis and the projection used.
///
/// ```
/// use ifd_sphere::transform::{Negatives, Projection, analyze_map};
/// let img = ifd_image::Image::from_vec(16, 8, 1, vec![1.0; 128])?;
/// let (a, used) = analyze_map(&img, 4, Negatives::Keep, None)?;
/// assert_eq!(used, Projection::Texel);
/// assert!((a.coeffs.get(0, 0, 0) - (4.0 * std::f64::consts::PI).sqrt()).abs() < 1e-8);
/// // a cube strip has no texel-exact projection
/// let strip = ifd_image::Image::from_vec(24, 4, 1, vec![1.0; 96])?;
/// assert!(analyze_map(&strip, 4, Negatives::Keep, Some(Projection::Texel)).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`SphereError::NotEquirect`] for other shapes, [`SphereError::Parameter`]
/// for a texel projection of a cube strip, and the errors of the transforms.
pub fn analyze_map(
    img: &Image,
    l_max: usize,
    negatives: Negatives,
    projection: Option<Projection>,
) -> Result<(Analysis, Projection)> {
    let (w, h) = (img.width(), img.height());
    if h >= 1 && w == 6 * h {
        if projection == Some(Projection::Texel) {
            return Err(SphereError::Parameter {
                name: "projection",
                value: "texel".into(),
                reason: "a cube strip is projected at its texel centres (exact solid angles); \
                         a texel-exact cube projection is not implemented",
            });
        }
        return Ok((analyze_cubemap(img, l_max, negatives)?, Projection::Centre));
    }
    let t = EquirectTransform::new(l_max, w, h)?;
    match projection.unwrap_or(Projection::Texel) {
        Projection::Texel => Ok((t.analyze_texels(img, negatives)?, Projection::Texel)),
        Projection::Centre => Ok((t.analyze(img, negatives)?, Projection::Centre)),
    }
}

/// Projects a cubemap strip (`W = 6H`, faces `+X, -X, +Y, -Y, +Z, -Z`) onto SH.
///
/// # Errors
/// [`SphereError::NotCubemap`] for other shapes, [`SphereError::NonFinite`] for NaN.
pub fn analyze_cubemap(img: &Image, l_max: usize, negatives: Negatives) -> Result<Analysis> {
    let (w, h, ch) = (img.width(), img.height(), img.channels());
    if w != 6 * h {
        return Err(SphereError::NotCubemap {
            width: w,
            height: h,
        });
    }
    let data = img.data();
    let negatives_clamped = count_negatives_of_finite_map(data, "cubemap")?;
    let sh = ShEvaluator::new(l_max)?;
    let mut coeffs = ShCoeffs::zeros(l_max, ch)?;
    let o = coeffs.data_mut();
    let mut y = vec![0.0; sh_count(l_max)];
    for face in 0..6 {
        for j in 0..h {
            for i in 0..h {
                let (d, sa) = cube_texel(face, i, j, h);
                sh.eval_into(d, &mut y);
                let px = (j * w + face * h + i) * ch;
                for c in 0..ch {
                    let mut v = f64::from(data[px + c]);
                    if negatives == Negatives::Clamp {
                        v = v.max(0.0);
                    }
                    let wv = sa * v;
                    for (k, yk) in y.iter().enumerate() {
                        o[k * ch + c] += wv * yk;
                    }
                }
            }
        }
    }
    Ok(Analysis {
        coeffs,
        negatives_clamped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_analysis_matches_subsampled_texels() {
        // even and odd heights (an odd height's equator row has no partner)
        box_analysis_case(12, 6);
        box_analysis_case(14, 7);
    }

    fn box_analysis_case(w: usize, h: usize) {
        // brute force: every texel split into k x k sub-texels (centres, exact
        // sub-texel solid angles), k large enough for 1e-6
        let (l_max, k) = (7usize, 64usize);
        let vals: Vec<f32> = (0..w * h).map(|i| ((i * 37 % 11) as f32) * 0.3).collect();
        let img = Image::from_vec(w, h, 1, vals.clone()).expect("image");
        let got = analyze_equirect_box(&img, l_max, Negatives::Keep)
            .expect("analysis")
            .coeffs;
        let sh = ShEvaluator::new(l_max).expect("evaluator");
        let mut want = vec![0.0; sh_count(l_max)];
        let mut y = vec![0.0; sh_count(l_max)];
        let (dp, dt) = (2.0 * PI / w as f64, PI / h as f64);
        for v in 0..h {
            for u in 0..w {
                let e = f64::from(vals[v * w + u]);
                for a in 0..k {
                    let t0 = dt * (v as f64 + a as f64 / k as f64);
                    let t1 = t0 + dt / k as f64;
                    let t = 0.5 * (t0 + t1);
                    let sa = (t0.cos() - t1.cos()) * dp / k as f64;
                    for b in 0..k {
                        let p = dp * (u as f64 + (b as f64 + 0.5) / k as f64);
                        sh.eval_into([t.sin() * p.cos(), t.sin() * p.sin(), t.cos()], &mut y);
                        for (o, yi) in want.iter_mut().zip(&y) {
                            *o += e * sa * yi;
                        }
                    }
                }
            }
        }
        let scale = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (i, (g, e)) in got.data().iter().zip(&want).enumerate() {
            assert!((g - e).abs() < 2e-5 * scale, "{i}: {g} vs {e}");
        }
        // and it differs from the pixel-centre rule at high degree
        let centre = analyze_equirect(&img, l_max, Negatives::Keep)
            .expect("analysis")
            .coeffs;
        let diff = centre
            .data()
            .iter()
            .zip(got.data())
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(diff > 1e-2 * scale, "{diff}");
    }
}
