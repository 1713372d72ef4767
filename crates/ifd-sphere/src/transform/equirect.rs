//! [`EquirectTransform`]: SH analysis of equirectangular maps at pixel
//! centres or texel-exact (one row-pair FFT pass serves both rules) and
//! synthesis at pixel centres.

use std::f64::consts::PI;
use std::sync::Arc;

use ifd_image::Image;
use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use super::{Analysis, Negatives, count_negatives_of_finite_map};
use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError, check_degree};
use crate::legendre::gauss_legendre;
use crate::sh::{LegendreTable, sh_count};

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

    /// Adds the Legendre sums of one block's virtual rows to the
    /// coefficients `out`. The rows sit in `G = zs.len()` groups of
    /// [`ANALYSIS_LANES`] lanes (`zs`, `ss`: `cos t`, `sin t` of the
    /// northern rows; unused lanes hold zero data); `comb[(j 4 + q) G + g]`
    /// holds the even (`q` = 0, 1: real, imaginary) and odd (`q` = 2, 3)
    /// combinations of each row pair's Fourier sums for `j = m C + c`.
    /// Per `(l, m, c)` the lanes accumulate `P_l^m` times the combination
    /// over the groups, then one fixed-order tree adds the lanes.
    #[inline(always)]
    #[allow(
        clippy::inline_always,
        reason = "compiled into each target of `ifd_simd::run_vectorized`"
    )]
    fn legendre_sums(
        &self,
        zs: &[[f64; ANALYSIS_LANES]],
        ss: &[[f64; ANALYSIS_LANES]],
        comb: &[[f64; ANALYSIS_LANES]],
        ch: usize,
        state: &mut [[f64; ANALYSIS_LANES]],
        out: &mut [f64],
    ) {
        const LANES: usize = ANALYSIS_LANES;
        let g_n = zs.len();
        let l_max = self.l_max;
        let t = &self.table;
        let (sm, rest) = state.split_at_mut(g_n);
        let (p1, p2) = rest.split_at_mut(g_n);
        let p2 = &mut p2[..g_n];
        sm.fill([1.0; LANES]);
        let sqrt2 = std::f64::consts::SQRT_2;
        for m in 0..=l_max {
            if m > 0 {
                for (a, b) in sm.iter_mut().zip(ss) {
                    for k in 0..LANES {
                        a[k] *= b[k];
                    }
                }
            }
            for l in m..=l_max {
                // P_l^m of every group: after this step p2 holds degree l, p1 l - 1
                if l == m {
                    for (p, s) in p2.iter_mut().zip(sm.iter()) {
                        *p = std::array::from_fn(|k| t.qmm[m] * s[k]);
                    }
                } else if l == m + 1 {
                    let c1 = t.c1[m];
                    for ((q, p), z) in p1.iter_mut().zip(p2.iter_mut()).zip(zs) {
                        *q = *p;
                        *p = std::array::from_fn(|k| c1 * z[k] * q[k]);
                    }
                } else {
                    let ti = crate::sh::tri(l, m);
                    let (a, b) = (t.a[ti], t.b[ti]);
                    for ((q, p), z) in p1.iter_mut().zip(p2.iter_mut()).zip(zs) {
                        let next: [f64; LANES] =
                            std::array::from_fn(|k| a * (z[k] * p[k] - b * q[k]));
                        *q = *p;
                        *p = next;
                    }
                }
                let q0 = if (l + m) % 2 == 0 { 0 } else { 2 };
                let base = l * (l + 1);
                for c in 0..ch {
                    let j = m * ch + c;
                    let re_src = &comb[(j * 4 + q0) * g_n..(j * 4 + q0 + 1) * g_n];
                    let im_src = &comb[(j * 4 + q0 + 1) * g_n..(j * 4 + q0 + 2) * g_n];
                    let mut re = [0.0; LANES];
                    let mut im = [0.0; LANES];
                    for ((p, xr), xi) in p2.iter().zip(re_src).zip(im_src) {
                        for k in 0..LANES {
                            re[k] += p[k] * xr[k];
                            im[k] += p[k] * xi[k];
                        }
                    }
                    let (re, im) = (lane_sum(re), lane_sum(im));
                    if m == 0 {
                        out[base * ch + c] += re;
                    } else {
                        out[(base + m) * ch + c] += sqrt2 * re;
                        out[(base - m) * ch + c] -= sqrt2 * im;
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
        self.project(img, negatives, Rule::Centre)
    }

    /// Projects the map read as **piecewise constant** over its texels, the
    /// fast form of [`crate::analyze_equirect_box`] (same result to quadrature
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
        self.project(img, negatives, Rule::Texel)
    }

    /// The one projection pass of both rules: each row pair's Fourier sums
    /// (one complex FFT per pair and channel), then the Legendre sums over
    /// the rule's polar nodes, [`ANALYSIS_LANES`] nodes a vector.
    ///
    /// The pairs are cut into at most [`GROUPS`] contiguous groups, run in
    /// parallel, each summing its nodes in order, and the groups' sums are
    /// added in order: the result does not depend on the thread count.
    fn project(&self, img: &Image, negatives: Negatives, rule: Rule) -> Result<Analysis> {
        use rayon::prelude::*;
        let negatives_clamped = self.check_map(img)?;
        let ch = img.channels();
        let l_max = self.l_max;
        let azimuthal = self.azimuthal_factors(rule);
        let nodes = self.polar_nodes(rule);
        let n_pairs = self.rows.len();
        let per_group = n_pairs.div_ceil(GROUPS).max(1);
        let n_coef = sh_count(l_max) * ch;
        let groups: Vec<Vec<f64>> = (0..n_pairs)
            .step_by(per_group)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|first| {
                let last = (first + per_group).min(n_pairs);
                let mut out = vec![0.0; n_coef];
                let mut pass = PairPass::new(self, ch);
                ifd_simd::run_vectorized(GroupPass {
                    t: self,
                    pass: &mut pass,
                    img,
                    negatives,
                    azimuthal: &azimuthal,
                    nodes: &nodes,
                    pairs: first..last,
                    out: &mut out,
                });
                out
            })
            .collect();
        let mut sums = vec![0.0; n_coef];
        for g in &groups {
            for (s, x) in sums.iter_mut().zip(g) {
                *s += x;
            }
        }
        Ok(Analysis {
            coeffs: ShCoeffs::from_vec(l_max, ch, sums)?,
            negatives_clamped,
        })
    }

    /// The azimuthal factor of each order `m`: the pixel-centre rule takes
    /// the row's samples as they are; the texel rule integrates each texel
    /// exactly in azimuth, `d sinc(m d / 2)` with `d = 2 pi / W` (the pixel
    /// centre rule's `2 pi / W` is in its row weight instead).
    fn azimuthal_factors(&self, rule: Rule) -> Vec<f64> {
        let d = 2.0 * PI / self.width as f64;
        (0..=self.l_max)
            .map(|m| match rule {
                Rule::Centre => 1.0,
                Rule::Texel if m == 0 => d,
                Rule::Texel => {
                    let x = 0.5 * m as f64 * d;
                    d * x.sin() / x
                }
            })
            .collect()
    }

    /// The polar nodes of each northern row, `(z, sin t, weight)`, the same
    /// number per row: the row centre with the row's solid angle
    /// (pixel-centre rule), or `n` Gauss-Legendre nodes across the row (texel
    /// rule, `n` as [`Self::analyze_texels`] says).
    fn polar_nodes(&self, rule: Rule) -> Vec<Vec<(f64, f64, f64)>> {
        match rule {
            Rule::Centre => self.rows.iter().map(|&row| vec![row]).collect(),
            Rule::Texel => {
                let h = self.height as f64;
                let n_g =
                    (2 + ((self.l_max + 1) as f64 * PI / (2.0 * h)).ceil() as usize).clamp(3, 64);
                let (gx, gw) = gauss_legendre(n_g);
                let dt = PI / h;
                (0..self.rows.len())
                    .map(|vn| {
                        // (an odd height's equator row has no southern
                        // partner: its Fourier sums have fs = 0, so even =
                        // odd and any z is right)
                        gx.iter()
                            .zip(&gw)
                            .map(|(x, wg)| {
                                let t = dt * (vn as f64 + 0.5 + 0.5 * x);
                                let (s, z) = t.sin_cos();
                                (z, s, 0.5 * dt * wg * s)
                            })
                            .collect()
                    })
                    .collect()
            }
        }
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

/// Nodes whose Legendre recurrences run together (they vectorise across
/// nodes: one AVX-512 vector of `f64`, two AVX2 ones).
const ANALYSIS_LANES: usize = 8;

/// Row pairs whose Fourier sums a worker holds at once: their virtual rows
/// (up to `PAIRS_PER_BLOCK` times the rule's nodes per row) share each
/// `(l, m, c)`'s lane sum.
const PAIRS_PER_BLOCK: usize = 16;

/// The most groups of row pairs a projection is cut into (a fixed number, so
/// that the order of the sums does not depend on the thread count).
const GROUPS: usize = 16;

// `lane_sum`'s tree is written for eight lanes.
const _: () = assert!(ANALYSIS_LANES == 8);

/// The lanes' sum in a fixed tree (the same on every instruction set).
#[inline(always)]
#[allow(
    clippy::inline_always,
    reason = "compiled into each target of `ifd_simd::run_vectorized`"
)]
fn lane_sum(x: [f64; ANALYSIS_LANES]) -> f64 {
    let a = [x[0] + x[4], x[1] + x[5], x[2] + x[6], x[3] + x[7]];
    (a[0] + a[2]) + (a[1] + a[3])
}

/// The two projection rules of [`EquirectTransform`].
#[derive(Clone, Copy, Debug)]
enum Rule {
    /// Pixel centres, each with its texel's exact solid angle.
    Centre,
    /// The map read as piecewise constant, each texel integrated.
    Texel,
}

/// One group of row pairs of [`EquirectTransform::project`], block by
/// block, compiled for the CPU's vectors as a whole.
struct GroupPass<'a> {
    t: &'a EquirectTransform,
    pass: &'a mut PairPass,
    img: &'a Image,
    negatives: Negatives,
    azimuthal: &'a [f64],
    nodes: &'a [Vec<(f64, f64, f64)>],
    pairs: std::ops::Range<usize>,
    out: &'a mut [f64],
}

impl ifd_simd::VectorKernel for GroupPass<'_> {
    type Output = ();
    #[inline(always)]
    #[allow(
        clippy::inline_always,
        reason = "the kernel is compiled into each target of `run_vectorized`"
    )]
    fn run(self) {
        for start in self.pairs.clone().step_by(PAIRS_PER_BLOCK) {
            let end = (start + PAIRS_PER_BLOCK).min(self.pairs.end);
            self.pass.run(
                self.t,
                self.img,
                self.negatives,
                self.azimuthal,
                self.nodes,
                start..end,
                self.out,
            );
        }
    }
}

/// One worker's buffers for [`EquirectTransform::project`].
struct PairPass {
    buf: Vec<Complex64>,
    scratch: Vec<Complex64>,
    /// `(north, south)` Fourier sums per (pair of the block, `m`, channel).
    fourier: Vec<(Complex64, Complex64)>,
    /// Lane-major even/odd combinations (see `legendre_sums`).
    comb: Vec<[f64; ANALYSIS_LANES]>,
    /// `cos t`, `sin t` of the block's virtual rows, by lane group.
    zs: Vec<[f64; ANALYSIS_LANES]>,
    ss: Vec<[f64; ANALYSIS_LANES]>,
    /// The recurrence's state: `sin^m t` and two degrees, per group.
    state: Vec<[f64; ANALYSIS_LANES]>,
}

impl PairPass {
    fn new(t: &EquirectTransform, ch: usize) -> Self {
        let per_pair = (t.l_max + 1) * ch;
        Self {
            buf: vec![Complex64::default(); t.width],
            scratch: vec![Complex64::default(); t.fwd.get_inplace_scratch_len()],
            fourier: vec![Default::default(); PAIRS_PER_BLOCK * per_pair],
            comb: Vec::new(),
            zs: Vec::new(),
            ss: Vec::new(),
            state: Vec::new(),
        }
    }

    /// Adds the Legendre sums of the row pairs `pairs` (at most
    /// [`PAIRS_PER_BLOCK`]) to `out` (compiled into each target of
    /// `ifd_simd::run_vectorized`, as the Legendre sums it calls).
    #[expect(clippy::too_many_arguments, reason = "one block's inputs and output")]
    #[inline(always)]
    #[allow(
        clippy::inline_always,
        reason = "compiled into each target of `ifd_simd::run_vectorized`"
    )]
    fn run(
        &mut self,
        t: &EquirectTransform,
        img: &Image,
        negatives: Negatives,
        azimuthal: &[f64],
        nodes: &[Vec<(f64, f64, f64)>],
        pairs: std::ops::Range<usize>,
        out: &mut [f64],
    ) {
        const LANES: usize = ANALYSIS_LANES;
        let (w, h, ch) = (t.width, t.height, img.channels());
        let l_max = t.l_max;
        let per_pair = (l_max + 1) * ch;
        let data = img.data();
        let clamp = negatives == Negatives::Clamp;
        let load = |x: f32| {
            let x = f64::from(x);
            if clamp { x.max(0.0) } else { x }
        };
        let row = |v: usize| &data[v * w * ch..(v + 1) * w * ch];
        // 1. Fourier sums of each pair: the southern row rides in the
        // imaginary part (one complex FFT for two real rows); the equator
        // row of an odd height has no partner.
        for (i, vn) in pairs.clone().enumerate() {
            let vs = h - 1 - vn;
            let north = row(vn);
            let south = (vs != vn).then(|| row(vs));
            for c in 0..ch {
                match south {
                    Some(south) => {
                        for ((b, n), s) in self
                            .buf
                            .iter_mut()
                            .zip(north.iter().skip(c).step_by(ch))
                            .zip(south.iter().skip(c).step_by(ch))
                        {
                            *b = Complex64::new(load(*n), load(*s));
                        }
                    }
                    None => {
                        for (b, n) in self.buf.iter_mut().zip(north.iter().skip(c).step_by(ch)) {
                            *b = Complex64::new(load(*n), 0.0);
                        }
                    }
                }
                t.fwd.process_with_scratch(&mut self.buf, &mut self.scratch);
                for (m, (phase, az)) in t.phase.iter().zip(azimuthal).enumerate() {
                    let k = m % w;
                    let zk = self.buf[k];
                    let zmk = self.buf[(w - k) % w].conj();
                    let ph = phase * az;
                    let fn_ = (zk + zmk) * 0.5 * ph;
                    let fs = (zk - zmk) * Complex64::new(0.0, -0.5) * ph;
                    self.fourier[i * per_pair + m * ch + c] = (fn_, fs);
                }
            }
        }
        // 2. the block's virtual rows (each pair's polar nodes) in lane
        // groups; unused lanes: zero data, harmless arguments
        let n_rows: usize = pairs.clone().map(|vn| nodes[vn].len()).sum();
        let g_n = n_rows.div_ceil(LANES);
        self.zs.clear();
        self.zs.resize(g_n, [0.0; LANES]);
        self.ss.clear();
        self.ss.resize(g_n, [1.0; LANES]);
        self.comb.clear();
        self.comb.resize(per_pair * 4 * g_n, [0.0; LANES]);
        self.state.resize(3 * g_n, [0.0; LANES]);
        let mut r = 0;
        for (i, vn) in pairs.enumerate() {
            let f = &self.fourier[i * per_pair..(i + 1) * per_pair];
            for &(z, s, wt) in &nodes[vn] {
                let (g, lane) = (r / LANES, r % LANES);
                self.zs[g][lane] = z;
                self.ss[g][lane] = s;
                for (j, &(fn_, fs)) in f.iter().enumerate() {
                    let even = (fn_ + fs) * wt;
                    let odd = (fn_ - fs) * wt;
                    self.comb[(j * 4) * g_n + g][lane] = even.re;
                    self.comb[(j * 4 + 1) * g_n + g][lane] = even.im;
                    self.comb[(j * 4 + 2) * g_n + g][lane] = odd.re;
                    self.comb[(j * 4 + 3) * g_n + g][lane] = odd.im;
                }
                r += 1;
            }
        }
        // 3. the Legendre sums of the whole block
        t.legendre_sums(&self.zs, &self.ss, &self.comb, ch, &mut self.state, out);
    }
}

#[cfg(test)]
#[path = "equirect_tests.rs"]
mod tests;
