//! Shading with ISD (ISD Eq. 22): the radiance leaving a surface point
//! towards `wo`, lit by a distant environment given by its SH coefficients.
//!
//! The derivation and conventions are documented on [`Environment`].

use ifd_sphere::{Rotation, ShCoeffs, ShRotation};
use ifd_sphere::{ShEvaluator, pi_l};

use crate::brdf::Brdf;
use crate::error::{Result, ShadeError};
use crate::slice::project_slice;
use crate::table::{LobeTable, view_frame_angle};
use crate::zonal::zonal_slice;
use glam::DVec3;

/// A source of the per-band prefiltered environment `Ehat_l(d)` of Eq. 22.
pub trait Bands: Sync {
    /// Maximum degree `L`.
    fn l_max(&self) -> usize;
    /// Channels.
    fn channels(&self) -> usize;
    /// `Ehat_l(d)` for every band: `out[l C + c]`; `y` is scratch of
    /// `(L + 1)^2` values.
    fn bands_into(&self, d: [f64; 3], y: &mut [f64], out: &mut [f64]) {
        self.bands_from(0, d, y, out);
    }
    /// [`Self::bands_into`] for the bands `l >= l0` only (the others of `out`
    /// are left as they are): a lobe serves the bands from
    /// [`crate::table::LobeBasis::first_band`] up.
    fn bands_from(&self, l0: usize, d: [f64; 3], y: &mut [f64], out: &mut [f64]);
    /// The weighted sum of the bands at every lobe of a point (Eq. 22's
    /// double sum): `out[p C + c] = sum_k sum_{l >= l0[k]} w[(k (L + 1) + l)
    /// P + p] Ehat_l(d_k)[c]` for `P = parts` weights per lobe and band
    /// (overwritten; `bands` is scratch of `4 (L + 1) C` values, `y` of
    /// `(L + 1)^2`). The default runs [`Self::bands_from`] per lobe;
    /// [`Environment`] runs its lobes in vector lanes.
    #[expect(
        clippy::too_many_arguments,
        reason = "one point's lobes, weights and scratch"
    )]
    fn lobe_sums(
        &self,
        l0: &[usize],
        d: &[[f64; 3]],
        w: &[f64],
        parts: usize,
        y: &mut [f64],
        bands: &mut [f64],
        out: &mut [f64],
    ) {
        let (nb, ch) = (self.l_max() + 1, self.channels());
        out[..parts * ch].fill(0.0);
        for (k, (&l0, &d)) in l0.iter().zip(d).enumerate() {
            let l0 = l0.min(nb);
            self.bands_from(l0, d, y, bands);
            add_weighted(
                &w[k * nb * parts..],
                l0,
                nb,
                parts,
                ch,
                &bands[..nb * ch],
                out,
            );
        }
    }
}

/// `out[p C + c] += w[l P + p] b[l C + c]` over `l0 <= l < nb`, in order of
/// `l` (the reference order of the weighted sums).
fn add_weighted(
    w: &[f64],
    l0: usize,
    nb: usize,
    parts: usize,
    ch: usize,
    b: &[f64],
    out: &mut [f64],
) {
    for l in l0..nb {
        let band = &b[l * ch..(l + 1) * ch];
        for (p, o) in out[..parts * ch].chunks_exact_mut(ch).enumerate() {
            let lam = w[l * parts + p];
            for (o, b) in o.iter_mut().zip(band) {
                *o += lam * b;
            }
        }
    }
}

/// The values a shading call returns from the weighted sums `sums[p C + c]`
/// (BRDF channel `p` against environment channel `c`) into `out`: every pair
/// (`OUTER`, `kc C` values), else per environment channel the one BRDF
/// channel (`kc = 1`) or the matching one (`kc = C`).
fn pick_sums<const OUTER: bool>(sums: &[f64], kc: usize, ch: usize, out: &mut [f64]) {
    if OUTER {
        out[..kc * ch].copy_from_slice(&sums[..kc * ch]);
    } else {
        for (c, o) in out[..ch].iter_mut().enumerate() {
            *o = sums[if kc == 1 { c } else { c * ch + c }];
        }
    }
}

/// The arithmetic of [`Environment`]'s lookups at many lobes at once
/// ([`Bands::lobe_sums`]).
///
/// `F64` is the reference (four lanes of `f64`, agreeing with the SH route
/// to 1e-9). `F32` runs sixteen lanes of `f32` (one AVX-512 register; eight
/// when a point has at most eight lobes) with fused multiply-adds, the lanes'
/// weighted sums in the lanes too, only the lanes' totals in `f64`: its
/// results stay within 1e-5 of the largest `F64` value (tested on both lobe
/// layouts, 1, 2 and 3 channels, up to L = 60; 3-5e-7 of the image maximum
/// on the bundled forest and sunrise maps at L = 7 to 100), the GPU path's
/// accuracy. On
/// x86-64 without AVX2 and FMA (or with `IFD_SIMD=baseline`) `F32` runs the
/// `F64` lanes: `f32` fused multiply-adds would be a libm call per lane.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// `f64` lanes: the reference.
    #[default]
    F64,
    /// `f32` lanes: the fast path.
    F32,
}

impl Precision {
    /// The arithmetic this precision runs in on this CPU now: `F32` needs
    /// fused multiply-adds in hardware, so on the x86-64 baseline (no AVX2 +
    /// FMA, or `IFD_SIMD=baseline`) it runs the `F64` lanes (a libm call per
    /// lane would be slower than them).
    ///
    /// ```
    /// use ifd_shade::Precision;
    /// assert_eq!(Precision::F64.effective(), Precision::F64);
    /// let p = Precision::F32.effective();
    /// let baseline = ifd_simd::isa() == ifd_simd::Isa::Baseline;
    /// assert_eq!(p == Precision::F64, cfg!(target_arch = "x86_64") && baseline);
    /// ```
    #[must_use]
    pub fn effective(self) -> Self {
        let no_fma = cfg!(target_arch = "x86_64") && ifd_simd::isa() == ifd_simd::Isa::Baseline;
        if no_fma { Self::F64 } else { self }
    }
}

/// An environment's SH coefficients, ready for per-band lookups `Ehat_l(d)`.
///
/// ```text
/// I(wo) = int E(w) k_wo(R^-1 w) dw
///       = sum_{l, j} lambda_l^j(wo) Ehat_l(R z_j),   Ehat_l(d) = pi_l sum_m e_l^m y_l^m(d)
/// ```
///
/// with `R` the rotation from the local frame of the point to the world
/// (columns tangent, bitangent, normal), further rotated about the normal by
/// `phi_o` for isotropic tables (whose slices are taken at `phi_o = 0`). Two
/// ways to get the weights:
/// - **closed form** (Lambert, Phong): the slice is zonal about an axis `a`
///   (the normal, the mirror direction) with weights `k_l`, one lobe per band:
///   `I = sum_l k_l Ehat_l(R a)`, `L + 1` bands from one SH evaluation;
/// - **table** ([`crate::table::LobeTable`]): for isotropic BRDFs `L + 1`
///   in-plane lobes, band `l` using the first `l + 1` (the slice is even in
///   `y` in the rotated frame); for anisotropic ones `2L + 1` shared lobes,
///   band `l` using the first `2l + 1`: one SH evaluation per lobe.
///
/// [`Material::shade_sh`] is the SH reference of the same band-limited slice:
/// its SH coefficients rotated by `R` (Ivanic-Ruedenberg) and dotted with
/// `e`. Both give the same number up to rounding.
#[derive(Clone, Debug)]
pub struct Environment {
    coeffs: ShCoeffs,
    sh: ShEvaluator,
    precision: Precision,
    /// `pi_l e_l^m` in `f32` (for [`Precision::F32`]; empty otherwise).
    scaled32: Vec<f32>,
}

impl Environment {
    /// Wraps the coefficients `e_l^m` of the lighting (any channel count).
    ///
    /// # Errors
    /// Degrees beyond [`ifd_sphere::MAX_DEGREE`].
    pub fn new(coeffs: ShCoeffs) -> Result<Self> {
        let sh = ShEvaluator::new(coeffs.l_max())?;
        Ok(Self {
            coeffs,
            sh,
            precision: Precision::F64,
            scaled32: Vec::new(),
        })
    }

    /// The same environment whose lobe lookups ([`Bands::lobe_sums`]) run
    /// in `precision` (single lookups, [`Self::bands_from`], stay `f64`).
    ///
    /// ```
    /// use ifd_shade::{Environment, Precision};
    /// use ifd_sphere::ShCoeffs;
    /// let e = ShCoeffs::from_vec(1, 1, vec![1.0, 0.2, 0.5, -0.1])?;
    /// let env = Environment::new(e)?.with_precision(Precision::F32);
    /// assert_eq!(env.precision(), Precision::F32);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    #[must_use]
    pub fn with_precision(mut self, precision: Precision) -> Self {
        self.precision = precision;
        self.scaled32 = match precision {
            Precision::F64 => Vec::new(),
            Precision::F32 => {
                let ch = self.coeffs.channels();
                let mut v = Vec::with_capacity(self.coeffs.data().len());
                for l in 0..=self.coeffs.l_max() {
                    let p = pi_l(l);
                    let band = &self.coeffs.data()[l * l * ch..(l + 1) * (l + 1) * ch];
                    v.extend(band.iter().map(|&e| (p * e) as f32));
                }
                v
            }
        };
        self
    }

    /// The arithmetic of the lobe lookups.
    #[must_use]
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// The coefficients.
    #[must_use]
    pub fn coeffs(&self) -> &ShCoeffs {
        &self.coeffs
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.coeffs.l_max()
    }

    /// Channels.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.coeffs.channels()
    }

    /// `Ehat_l(d) = pi_l sum_m e_l^m y_l^m(d)` for every band: `out[l C + c]`.
    /// `y` is scratch of `(L + 1)^2` values.
    pub fn bands_into(&self, d: [f64; 3], y: &mut [f64], out: &mut [f64]) {
        self.bands_from(0, d, y, out);
    }

    /// [`Self::bands_into`] for the bands `l >= l0` only. One direction: the
    /// SH values, then a contiguous dot product per band (1.37x faster, in a
    /// same-process A/B at L = 15, than [`ShEvaluator::band_sums`] run with one lane, which pays for
    /// its accumulators and strided coefficients; [`Bands::lobe_sums`] uses it
    /// with four).
    pub fn bands_from(&self, l0: usize, d: [f64; 3], y: &mut [f64], out: &mut [f64]) {
        let ch = self.channels();
        self.sh.eval_into(d, y);
        let e = self.coeffs.data();
        for l in l0..=self.l_max() {
            let p = pi_l(l);
            for c in 0..ch {
                let mut acc = 0.0;
                for i in l * l..(l + 1) * (l + 1) {
                    acc += y[i] * e[i * ch + c];
                }
                out[l * ch + c] = p * acc;
            }
        }
    }

    /// [`Bands::lobe_sums`] in `f32`: the lobes `N` at a time in vector
    /// lanes, each lane's bands weighted in its lane, the lanes' sums added
    /// in `f64`.
    fn lobe_sums_f32<const N: usize>(
        &self,
        l0: &[usize],
        d: &[[f64; 3]],
        w: &[f64],
        parts: usize,
        owner: Option<(&[u32], &[usize])>,
        out: &mut [f64],
    ) {
        thread_local! {
            /// The kernel's lane accumulators and weights, kept between points.
            static LANES: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        let ch = self.channels();
        let nb = self.l_max() + 1;
        LANES.with_borrow_mut(|buf| {
            buf.resize((nb * ch + nb * parts + parts * ch) * N, 0.0);
            let (lanes, _) = buf.as_chunks_mut::<N>();
            ifd_simd::run_vectorized(LobeSumsF32 {
                env: self,
                l0,
                d,
                w,
                parts,
                lanes,
                owner,
                out,
            });
        });
    }

    /// [`Bands::lobe_sums`] for the lobes of several points at once: lobe
    /// `k` belongs to point `owner[k]` (each point's lobes contiguous, points
    /// numbered from 0 in order), whose sums go to `out[point P C..]`
    /// (overwritten). With [`Precision::F32`] the points share vector lanes
    /// (sixteen lobes a chunk: two points of eight lobes fill one AVX-512
    /// register); with `F64` each point runs as [`Bands::lobe_sums`] does.
    #[expect(
        clippy::too_many_arguments,
        reason = "the points' lobes, weights and scratch"
    )]
    pub fn lobe_sums_batch(
        &self,
        l0: &[usize],
        d: &[[f64; 3]],
        w: &[f64],
        parts: usize,
        owner: &[u32],
        y: &mut [f64],
        bands: &mut [f64],
        out: &mut [f64],
    ) {
        let pc = parts * self.channels();
        let points = owner.last().map_or(0, |&p| p as usize + 1);
        out[..points * pc].fill(0.0);
        if self.precision.effective() == Precision::F32 {
            thread_local! {
                /// The lobe-major order and its scratch, kept between batches.
                static ORDER: std::cell::RefCell<(Vec<usize>, Vec<usize>)> =
                    const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
            }
            ORDER.with_borrow_mut(|(counts, order)| {
                lobe_major(owner, counts, order);
                self.lobe_sums_f32::<16>(l0, d, w, parts, Some((owner, order)), out);
            });
            return;
        }
        let nb = self.l_max() + 1;
        let mut start = 0;
        while start < owner.len() {
            let pt = owner[start] as usize;
            let end = start
                + owner[start..]
                    .iter()
                    .take_while(|&&p| p as usize == pt)
                    .count();
            self.lobe_sums(
                &l0[start..end],
                &d[start..end],
                &w[start * nb * parts..end * nb * parts],
                parts,
                y,
                bands,
                &mut out[pt * pc..(pt + 1) * pc],
            );
            start = end;
        }
    }
}

/// The lobe-major order of a batch's lobes (each point's lobes
/// contiguous, `owner[k]` the point of lobe `k`): the first lobe of every
/// point, then the second of every point, and so on (a counting sort by
/// the rank within the point, stable). A chunk of lanes then holds the
/// same lobe of sixteen points, whose first bands agree, so the chunk's SH
/// sums skip the bands below it (an in-plane table's lobe `j` serves bands
/// `j..=L`), where chunks of mixed lobes skip none. Each point still
/// receives its lobes' sums in its own order: the same bits.
fn lobe_major(owner: &[u32], counts: &mut Vec<usize>, order: &mut Vec<usize>) {
    let n = owner.len();
    order.clear();
    // lobes per point, when every point has as many (a material's batch)
    let per = owner.iter().take_while(|&&p| p == owner[0]).count();
    let uniform = per > 0
        && n.is_multiple_of(per)
        && owner
            .chunks(per)
            .zip(owner[0]..)
            .all(|(c, point)| c.iter().all(|&p| p == point));
    if uniform {
        let points = n / per;
        order.extend((0..per).flat_map(|r| (0..points).map(move |p| p * per + r)));
        return;
    }
    // counts of each rank, then their first positions; then place
    counts.clear();
    let mut start = 0;
    for k in 0..n {
        if owner[k] != owner[start] {
            start = k;
        }
        let r = k - start;
        if r == counts.len() {
            counts.push(0);
        }
        counts[r] += 1;
    }
    let mut at = 0;
    for c in counts.iter_mut() {
        (*c, at) = (at, at + *c);
    }
    order.resize(n, 0);
    start = 0;
    for k in 0..n {
        if owner[k] != owner[start] {
            start = k;
        }
        let r = k - start;
        order[counts[r]] = k;
        counts[r] += 1;
    }
}

/// [`Environment::lobe_sums_f32`]'s work for one point, compiled for the
/// CPU's vectors as a whole ([`ifd_simd::VectorKernel`]): per chunk of `N`
/// lobes the SH kernel, the lanes' weights (zero below each lobe's first
/// band), their weighted sums per part and channel in the lanes, and the
/// lanes' sums in `f64`.
struct LobeSumsF32<'a, const N: usize> {
    env: &'a Environment,
    l0: &'a [usize],
    d: &'a [[f64; 3]],
    w: &'a [f64],
    parts: usize,
    /// Scratch: `(L + 1) C` accumulators, `(L + 1) P` weights, `P C` sums.
    lanes: &'a mut [[f32; N]],
    /// The point of each lobe and the order the lanes take the lobes in
    /// (`None`: one point, in order); a point's `P C` sums start at
    /// `out[point P C]`.
    owner: Option<(&'a [u32], &'a [usize])>,
    out: &'a mut [f64],
}

impl<const N: usize> ifd_simd::VectorKernel for LobeSumsF32<'_, N> {
    type Output = ();
    #[inline(always)]
    #[allow(
        clippy::inline_always,
        reason = "the kernel is compiled into each target of `run_vectorized`"
    )]
    fn run(self) {
        let Self {
            env,
            l0,
            d,
            w,
            parts,
            lanes,
            owner,
            out,
        } = self;
        let ch = env.channels();
        let nb = env.l_max() + 1;
        let (acc, rest) = lanes.split_at_mut(nb * ch);
        let (wl, sums) = rest.split_at_mut(nb * parts);
        let n = d.len();
        for q0 in (0..n).step_by(N) {
            let len = N.min(n - q0);
            // the chunk's lobes (the last one again past `len`, unused)
            let lobes: [usize; N] = std::array::from_fn(|k| {
                let q = q0 + k.min(len - 1);
                owner.map_or(q, |(_, order)| order[q])
            });
            let lobes = &lobes[..len];
            let lo = lobes.iter().map(|&i| l0[i]).min().unwrap_or(nb).min(nb);
            let mut dirs = [[0.0f32, 0.0, 1.0]; N];
            for (v, &i) in dirs.iter_mut().zip(lobes) {
                *v = d[i].map(|x| x as f32);
            }
            env.sh
                .band_sums_f32_lanes(lo, &dirs, &env.scaled32, ch, acc);
            wl[lo * parts..].fill([0.0; N]);
            for (k, &i) in lobes.iter().enumerate() {
                let wk = &w[i * nb * parts..(i + 1) * nb * parts];
                for (j, &v) in wk.iter().enumerate().skip(l0[i].min(nb) * parts) {
                    wl[j][k] = v as f32;
                }
            }
            for p in 0..parts {
                for c in 0..ch {
                    let mut s = [0.0f32; N];
                    for l in lo..nb {
                        let (a, b) = (&wl[l * parts + p], &acc[l * ch + c]);
                        for k in 0..N {
                            s[k] = a[k].mul_add(b[k], s[k]);
                        }
                    }
                    sums[p * ch + c] = s;
                }
            }
            match owner {
                None => {
                    for (o, s) in out[..parts * ch].iter_mut().zip(sums.iter()) {
                        *o += s.iter().map(|&v| f64::from(v)).sum::<f64>();
                    }
                }
                Some((own, _)) => {
                    for (k, &i) in lobes.iter().enumerate() {
                        let pt = own[i] as usize;
                        let o = &mut out[pt * parts * ch..(pt + 1) * parts * ch];
                        for (o, s) in o.iter_mut().zip(sums.iter()) {
                            *o += f64::from(s[k]);
                        }
                    }
                }
            }
        }
    }
}

impl Bands for Environment {
    fn l_max(&self) -> usize {
        self.coeffs.l_max()
    }
    fn channels(&self) -> usize {
        self.coeffs.channels()
    }
    fn bands_from(&self, l0: usize, d: [f64; 3], y: &mut [f64], out: &mut [f64]) {
        Environment::bands_from(self, l0, d, y, out);
    }
    fn lobe_sums(
        &self,
        l0: &[usize],
        d: &[[f64; 3]],
        w: &[f64],
        parts: usize,
        _y: &mut [f64],
        bands: &mut [f64],
        out: &mut [f64],
    ) {
        let (nb, ch) = (self.l_max() + 1, self.channels());
        out[..parts * ch].fill(0.0);
        let f32_lanes = self.precision.effective() == Precision::F32;
        match (f32_lanes, d.len() <= 8) {
            (true, true) => self.lobe_sums_f32::<8>(l0, d, w, parts, None, out),
            (true, false) => self.lobe_sums_f32::<16>(l0, d, w, parts, None, out),
            (false, _) => {
                // four lanes at a time, fusing the SH recurrences with the coefficients
                for (j0, (l0s, ds)) in l0.chunks(4).zip(d.chunks(4)).enumerate() {
                    let lo = l0s.iter().copied().min().unwrap_or(nb).min(nb);
                    let dirs: [[f64; 3]; 4] =
                        std::array::from_fn(|k| ds.get(k).copied().unwrap_or([0.0, 0.0, 1.0]));
                    let b = &mut bands[..4 * nb * ch];
                    self.sh.band_sums(lo, &dirs, self.coeffs.data(), ch, b);
                    for (k, &l0k) in l0s.iter().enumerate() {
                        let l0k = l0k.min(nb);
                        let lane = &mut b[k * nb * ch..(k + 1) * nb * ch];
                        for l in l0k..nb {
                            let p = pi_l(l);
                            for v in &mut lane[l * ch..(l + 1) * ch] {
                                *v *= p;
                            }
                        }
                        let wk = &w[(j0 * 4 + k) * nb * parts..];
                        add_weighted(wk, l0k, nb, parts, ch, lane, out);
                    }
                }
            }
        }
    }
}

/// The per-band prefiltered environment tabulated on equirectangular maps
/// (the variant of Eq. 22's middle line): band `l`'s map holds `Ehat_l` at the
/// pixel centres (exact synthesis, FFT + Legendre), and lookups are bicubic
/// (Catmull-Rom), wrapping in azimuth and across the poles (row `-1 - v` is
/// row `v` half a turn away). Maps are `2N x N` with `N = 8 (L + 1)` (at least
/// 32): about 16 samples per wavelength of the highest band, where the
/// Catmull-Rom error is below 1e-3 of the band's amplitude. Memory: `(L + 1)
/// 2 N^2 C` f32 values (`L = 30`, RGB: 46 MB).
#[derive(Clone, Debug)]
pub struct BandMaps {
    l_max: usize,
    channels: usize,
    width: usize,
    height: usize,
    /// `[band][row][column][channel]`.
    data: Vec<f32>,
}

impl BandMaps {
    /// Tabulates the bands of `env`.
    ///
    /// # Errors
    /// Degrees beyond [`ifd_sphere::MAX_DEGREE`].
    pub fn new(env: &Environment) -> Result<Self> {
        let l_max = env.l_max();
        let ch = env.channels();
        let h = (8 * (l_max + 1)).max(32);
        let w = 2 * h;
        let t = ifd_sphere::EquirectTransform::new(l_max, w, h)?;
        let mut data = Vec::with_capacity((l_max + 1) * w * h * ch);
        for l in 0..=l_max {
            let mut band = ShCoeffs::zeros(l_max, ch)?;
            let p = pi_l(l);
            let range = l * l * ch..(l + 1) * (l + 1) * ch;
            for (o, e) in band.data_mut()[range.clone()]
                .iter_mut()
                .zip(&env.coeffs().data()[range])
            {
                *o = p * e;
            }
            data.extend_from_slice(t.synthesize(&band)?.data());
        }
        Ok(Self {
            l_max,
            channels: ch,
            width: w,
            height: h,
            data,
        })
    }

    /// Map size `(W, H)`.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The maps, `[band][row][column][channel]` f32 (rows from the zenith).
    #[must_use]
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// Channels.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Bytes of the maps.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.data.len() * 4
    }
}

impl Bands for BandMaps {
    fn l_max(&self) -> usize {
        self.l_max
    }
    fn channels(&self) -> usize {
        self.channels
    }
    fn bands_from(&self, l0: usize, d: [f64; 3], _y: &mut [f64], out: &mut [f64]) {
        let (w, h, ch) = (self.width, self.height, self.channels);
        let taps = ifd_sphere::bicubic_taps(d, w, h);
        let band_len = w * h * ch;
        for l in l0..=self.l_max {
            let base = &self.data[l * band_len..(l + 1) * band_len];
            for c in 0..ch {
                let mut acc = 0.0;
                for (t, wt) in &taps {
                    acc += wt * f64::from(base[t * ch + c]);
                }
                out[l * ch + c] = acc;
            }
        }
    }
}

/// A right-handed orthonormal frame at a surface point, in world coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Tangent (the local `+x`, direction of `ax`).
    pub t: [f64; 3],
    /// Bitangent `n x t` (the local `+y`).
    pub b: [f64; 3],
    /// Normal (the local `+z`).
    pub n: [f64; 3],
}

impl Frame {
    /// The frame of a unit normal and a tangent hint (made orthogonal to the
    /// normal; any perpendicular direction when the hint is parallel to it).
    #[must_use]
    pub fn new(n: [f64; 3], tangent_hint: [f64; 3]) -> Self {
        let (nv, hint) = (DVec3::from(n), DVec3::from(tangent_hint));
        let mut t = hint - hint.dot(nv) * nv;
        let mut len = t.length();
        if len.is_nan() || len <= 1e-12 {
            // any perpendicular: cross with the axis least aligned with n
            let a = if n[0].abs() < 0.6 { DVec3::X } else { DVec3::Y };
            t = nv.cross(a).cross(nv);
            len = t.length();
        }
        let t = t * len.recip();
        Self {
            t: t.to_array(),
            b: nv.cross(t).to_array(),
            n,
        }
    }

    /// World to local: `(t . w, b . w, n . w)`.
    #[must_use]
    pub fn to_local(&self, w: [f64; 3]) -> [f64; 3] {
        let w = DVec3::from(w);
        [
            DVec3::from(self.t).dot(w),
            DVec3::from(self.b).dot(w),
            DVec3::from(self.n).dot(w),
        ]
    }

    /// The rotation local to world (columns `t, b, n`).
    #[must_use]
    pub fn rotation(&self) -> Rotation {
        Rotation {
            m: [
                [self.t[0], self.b[0], self.n[0]],
                [self.t[1], self.b[1], self.n[1]],
                [self.t[2], self.b[2], self.n[2]],
            ],
        }
    }
}

/// Where a material's lobe weights come from.
#[derive(Clone, Debug)]
enum Lobes {
    /// Closed-form zonal slices (Lambert, Phong).
    Zonal,
    /// A lobe table.
    Table(Box<LobeTable>),
}

/// A BRDF ready to shade at degree `L`.
#[derive(Debug)]
pub struct Material {
    brdf: Brdf,
    l_max: usize,
    lobes: Lobes,
    /// With a table: each lobe's first band (`<= L + 1`), and where each
    /// of a point's lobe weights comes from and goes, `(source, target)`:
    /// the table entry's weight `basis.index(l, j) P` and the lobes'
    /// layout `(j (L + 1) + l) P`, for the bands each lobe serves (so the
    /// per-point blend is one flat loop). Empty without a table.
    firsts: Vec<usize>,
    slots: Vec<(usize, usize)>,
}

/// Scratch buffers for one thread's shading.
#[derive(Clone, Debug)]
pub struct Scratch {
    y: Vec<f64>,
    bands: Vec<f64>,
    weights: Vec<f64>,
    /// A point's rotated lobe directions, their first bands, their weights
    /// per band (`[(j (L + 1) + l) P + p]`) and the weighted sums.
    dirs: Vec<[f64; 3]>,
    first: Vec<usize>,
    lobe_weights: Vec<f64>,
    sums: Vec<f64>,
    /// For a batch of points: each lobe's point among the lit ones, and the
    /// lit points' indices.
    owner: Vec<u32>,
    lit: Vec<usize>,
}

impl Scratch {
    /// Buffers for materials of degree `l_max` under an environment of
    /// `channels` channels.
    #[must_use]
    pub fn new(l_max: usize, channels: usize) -> Self {
        let n = (l_max + 1) * (l_max + 1);
        Self {
            y: vec![0.0; n],
            bands: vec![0.0; 4 * (l_max + 1) * channels.max(3)],
            weights: vec![0.0; n * 3],
            dirs: Vec::with_capacity(2 * l_max + 1),
            first: Vec::with_capacity(2 * l_max + 1),
            lobe_weights: Vec::with_capacity((2 * l_max + 1) * (l_max + 1) * 3),
            sums: vec![0.0; 3 * channels.max(3)],
            owner: Vec::new(),
            lit: Vec::new(),
        }
    }
}

impl Material {
    /// A material at degree `l_max`: closed form for Lambert and Phong,
    /// otherwise the given table (checked against the BRDF and degree).
    ///
    /// # Errors
    /// [`ShadeError::Mismatch`] for a table of another BRDF or degree;
    /// [`ShadeError::Parameter`] when a table is needed and none is given.
    pub fn new(brdf: &Brdf, l_max: usize, table: Option<LobeTable>) -> Result<Self> {
        let closed = zonal_slice(brdf, [0.0, 0.0, 1.0], 0).is_some();
        let lobes = match (closed, table) {
            (true, None) => Lobes::Zonal,
            (_, Some(t)) => {
                t.check_for(brdf, l_max)?;
                Lobes::Table(Box::new(t))
            }
            (false, None) => {
                return Err(ShadeError::Parameter {
                    name: "lobe table",
                    value: brdf.spec().to_string(),
                    reason: "this BRDF has no closed-form weights: build a table with \
                             `ifd sphere brdf` (or LobeTable::build)"
                        .into(),
                });
            }
        };
        let (mut firsts, mut slots) = (Vec::new(), Vec::new());
        if let Lobes::Table(t) = &lobes {
            let (kc, nb, basis) = (brdf.channels(), l_max + 1, t.basis());
            for j in 0..basis.directions().len() {
                let first = basis.first_band(j).min(nb);
                firsts.push(first);
                slots.extend((first..nb).map(|l| (basis.index(l, j) * kc, (j * nb + l) * kc)));
            }
        }
        Ok(Self {
            brdf: brdf.clone(),
            l_max,
            lobes,
            firsts,
            slots,
        })
    }

    /// The BRDF.
    #[must_use]
    pub fn brdf(&self) -> &Brdf {
        &self.brdf
    }

    /// The degree `L`.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// The lobe table (`None` for closed-form weights).
    #[must_use]
    pub fn table(&self) -> Option<&LobeTable> {
        match &self.lobes {
            Lobes::Zonal => None,
            Lobes::Table(t) => Some(t),
        }
    }

    /// Whether the weights are closed-form (one lobe per band).
    #[must_use]
    pub fn is_closed_form(&self) -> bool {
        matches!(self.lobes, Lobes::Zonal)
    }

    /// Scratch buffers for [`Self::shade_isd`].
    #[must_use]
    pub fn scratch(&self, channels: usize) -> Scratch {
        Scratch::new(self.l_max, channels)
    }

    /// The rotation of the slice and the local view: `R` (local -> world,
    /// rotated by `phi_o` for isotropic tables) and `(theta_o, phi_o)`
    /// (`phi_o = 0` for isotropic tables, whose weights do not depend on it:
    /// their rotation by `phi_o` takes its cosine and sine from the view,
    /// `(x, y) / |(x, y)|`, without the angle).
    fn placement(&self, frame: &Frame, wo: [f64; 3]) -> (Rotation, [f64; 3], f64, f64) {
        let wl = frame.to_local(wo);
        let theta = wl[2].clamp(-1.0, 1.0).acos();
        let r = frame.rotation();
        match &self.lobes {
            Lobes::Table(t) if t.header().isotropic => {
                // on the axis (rho = 0) the angle is taken as 0
                let rho = (wl[0] * wl[0] + wl[1] * wl[1]).sqrt();
                let (c, s) = if rho > 0.0 && rho.is_finite() {
                    (wl[0] / rho, wl[1] / rho)
                } else {
                    (1.0, 0.0)
                };
                (r.mul(&Rotation::rz_cos_sin(c, s)), wl, theta, 0.0)
            }
            _ => {
                let on_axis = wl[0] == 0.0 && wl[1] == 0.0;
                let phi = if on_axis { 0.0 } else { view_frame_angle(wl) };
                (r, wl, theta, phi)
            }
        }
    }

    /// The channel count of the result for an environment of `env_channels`.
    fn out_channels(&self, env_channels: usize) -> Result<usize> {
        let kc = self.brdf.channels();
        if kc != 1 && kc != env_channels {
            return Err(ShadeError::Mismatch(format!(
                "a {kc}-channel BRDF under a {env_channels}-channel environment"
            )));
        }
        Ok(env_channels)
    }

    /// Eq. 22 at one point: `frame` at the point, `wo` the unit direction
    /// towards the viewer (world). Returns one value per environment channel
    /// in `out`. A view below the surface gives 0 (but for Phong, whose slice
    /// is defined everywhere).
    ///
    /// # Errors
    /// [`ShadeError::Mismatch`] for a MERL (RGB) BRDF under a map of other
    /// than 3 channels, or an environment of another degree.
    pub fn shade_isd(
        &self,
        env: &impl Bands,
        frame: &Frame,
        wo: [f64; 3],
        s: &mut Scratch,
        out: &mut [f64],
    ) -> Result<()> {
        self.isd_into::<false>(env, frame, wo, s, out)
    }

    /// [`Self::shade_isd`] at several points at once: `points[i]` is the
    /// frame and view of point `i`, its value goes to `out[i C..]` (`C` the
    /// environment's channels). With a lobe table and [`Precision::F32`] the
    /// points' lobes share the vector lanes (at L = 7 two points fill the
    /// sixteen of an AVX-512 register where one fills eight); otherwise each
    /// point is shaded alone. Equal to [`Self::shade_isd`] point by point to
    /// `f32` rounding (`F32`) or exactly (`F64`).
    ///
    /// ```
    /// use ifd_shade::{Brdf, Environment, Frame, LobeTable, Material, Precision};
    /// use ifd_sphere::ShCoeffs;
    /// let l = 7;
    /// let mut e = ShCoeffs::zeros(l, 1)?;
    /// for (i, v) in e.data_mut().iter_mut().enumerate() {
    ///     *v = 1.0 / (1.0 + i as f64);
    /// }
    /// let env = Environment::new(e)?.with_precision(Precision::F32);
    /// let b = Brdf::parse("ggx:alpha=0.3")?;
    /// let m = Material::new(&b, l, Some(LobeTable::build(&b, l, 8, 1, &|_, _| {})?))?;
    /// let f = Frame::new([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    /// let points = [(f, [0.0, 0.6, 0.8]), (f, [0.6, 0.0, 0.8]), (f, [0.0, 0.0, -1.0])];
    /// let mut s = m.scratch(1);
    /// let mut batch = [0.0; 3];
    /// m.shade_isd_batch(&env, &points, &mut s, &mut batch)?;
    /// for (i, (f, wo)) in points.iter().enumerate() {
    ///     let mut one = [0.0];
    ///     m.shade_isd(&env, f, *wo, &mut s, &mut one)?;
    ///     assert!((batch[i] - one[0]).abs() <= 1e-6 * one[0].abs().max(1e-3));
    /// }
    /// assert_eq!(batch[2], 0.0); // a view below the surface
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn shade_isd_batch(
        &self,
        env: &Environment,
        points: &[(Frame, [f64; 3])],
        s: &mut Scratch,
        out: &mut [f64],
    ) -> Result<()> {
        let ch = self.out_channels(env.channels())?;
        self.check_env(env)?;
        let Lobes::Table(t) = &self.lobes else {
            for (i, (f, wo)) in points.iter().enumerate() {
                self.shade_isd(env, f, *wo, s, &mut out[i * ch..(i + 1) * ch])?;
            }
            return Ok(());
        };
        let kc = self.brdf.channels();
        s.dirs.clear();
        s.first.clear();
        s.lobe_weights.clear();
        s.owner.clear();
        s.lit.clear();
        for (i, (frame, wo)) in points.iter().enumerate() {
            out[i * ch..(i + 1) * ch].fill(0.0);
            let (r, wl, theta, phi) = self.placement(frame, *wo);
            if wl[2] <= 0.0 {
                continue;
            }
            let point = s.lit.len() as u32;
            s.lit.push(i);
            s.owner
                .extend(std::iter::repeat_n(point, t.basis().directions().len()));
            self.push_lobes(t, &r, theta, phi, s);
        }
        let pc = kc * ch;
        s.sums.resize(s.lit.len().max(1) * pc, 0.0);
        env.lobe_sums_batch(
            &s.first,
            &s.dirs,
            &s.lobe_weights,
            kc,
            &s.owner,
            &mut s.y,
            &mut s.bands,
            &mut s.sums,
        );
        for (li, &i) in s.lit.iter().enumerate() {
            let sums = &s.sums[li * pc..(li + 1) * pc];
            pick_sums::<false>(sums, kc, ch, &mut out[i * ch..(i + 1) * ch]);
        }
        Ok(())
    }

    /// Appends the lobes of one point to `s`: each lobe's direction `R z_j`,
    /// first band, and weights per band (the table's entries at `(theta,
    /// phi)` blended as [`LobeTable::weights_into`] blends them) in the
    /// layout of [`Bands::lobe_sums`] (`[(j (L + 1) + l) P + p]`, zero below
    /// the first band).
    #[inline]
    fn push_lobes(&self, t: &LobeTable, r: &Rotation, theta: f64, phi: f64, s: &mut Scratch) {
        let kc = self.brdf.channels();
        let nb = self.l_max + 1;
        let basis = t.basis();
        let dirs = basis.directions();
        // the table's entries blended straight into the lobes' layout (the
        // sums of `LobeTable::weights_into`, term for term)
        let mut entries = [(&[][..], 0.0); 4];
        let mut ne = 0;
        for (e, w) in t.blend(theta, phi) {
            entries[ne] = (t.entry(e), w);
            ne += 1;
        }
        let entries = &entries[..ne];
        let first_lobe = s.dirs.len();
        s.dirs.extend(dirs.iter().map(|&d| r.apply(d)));
        s.first.extend_from_slice(&self.firsts);
        s.lobe_weights.resize(s.dirs.len() * nb * kc, 0.0);
        let lobes = &mut s.lobe_weights[first_lobe * nb * kc..];
        match entries {
            // an isotropic table's two entries, unrolled, the choice made
            // once per point
            [(a, wa), (b, wb)] => {
                for &(src, dst) in &self.slots {
                    let (a, b) = (&a[src..src + kc], &b[src..src + kc]);
                    for ((o, &x), &y) in lobes[dst..dst + kc].iter_mut().zip(a).zip(b) {
                        *o = wa * f64::from(x) + wb * f64::from(y);
                    }
                }
            }
            _ => {
                for &(src, dst) in &self.slots {
                    for (p, o) in lobes[dst..dst + kc].iter_mut().enumerate() {
                        *o = entries
                            .iter()
                            .fold(0.0, |v, (e, w)| v + w * f64::from(e[src + p]));
                    }
                }
            }
        }
    }

    /// Eq. 22 for every channel of a multi-channel BRDF against every
    /// channel of the environment: `out[p C + c]` is BRDF channel `p`'s slice
    /// integrated against environment channel `c` (`C` environment channels,
    /// `P C` values in all). The glTF BRDF's three parts (`gltf-lobes`) this
    /// way share every environment lookup; [`crate::GltfMaterial::combine`]
    /// makes the whole BRDF's radiance of them.
    ///
    /// ```
    /// use ifd_shade::{Brdf, Environment, Frame, GltfMaterial, LobeTable, Material};
    /// use ifd_sphere::ShCoeffs;
    /// // a uniform white environment: each part integrates to its albedo
    /// let mut e = ShCoeffs::zeros(4, 1)?;
    /// e.data_mut()[0] = (4.0 * std::f64::consts::PI).sqrt();
    /// let env = Environment::new(e)?;
    /// let parts = Brdf::gltf_lobes(0.7)?;
    /// let table = LobeTable::build(&parts, 4, 32, 1, &|_, _| {})?;
    /// let m = Material::new(&parts, 4, Some(table))?;
    /// let frame = Frame::new([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    /// let mut s = m.scratch(1);
    /// let mut out = [0.0; 3];
    /// m.shade_isd_parts(&env, &frame, [0.0, 0.6, 0.8], &mut s, &mut out)?;
    /// // a white metal (f0 = 1): the GGX albedo, below 1, as the whole
    /// // BRDF's slice integrates
    /// let metal = GltfMaterial::new([1.0; 3], 1.0, 0.7)?;
    /// let mut rgb = [0.0; 3];
    /// metal.combine(&out, 1, &mut rgb);
    /// let whole = ifd_shade::project_slice(&Brdf::gltf(&metal), [0.0, 0.6, 0.8], 0, None)?;
    /// let albedo = whole.get(0, 0, 0) * (4.0 * std::f64::consts::PI).sqrt();
    /// assert!(rgb[0] < 1.0 && (rgb[0] - albedo).abs() < 1e-3, "{rgb:?} vs {albedo}");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn shade_isd_parts(
        &self,
        env: &impl Bands,
        frame: &Frame,
        wo: [f64; 3],
        s: &mut Scratch,
        out: &mut [f64],
    ) -> Result<()> {
        self.isd_into::<true>(env, frame, wo, s, out)
    }

    /// [`Self::shade_isd`] (`OUTER = false`: BRDF channel `c`, or the only
    /// one, against environment channel `c`) and [`Self::shade_isd_parts`]
    /// (`OUTER`: every BRDF channel against every environment channel).
    fn isd_into<const OUTER: bool>(
        &self,
        env: &impl Bands,
        frame: &Frame,
        wo: [f64; 3],
        s: &mut Scratch,
        out: &mut [f64],
    ) -> Result<()> {
        let kc = self.brdf.channels();
        let ch = if OUTER {
            env.channels()
        } else {
            self.out_channels(env.channels())?
        };
        let parts = if OUTER { kc } else { 1 };
        self.check_env(env)?;
        out[..parts * ch].fill(0.0);
        let (r, wl, theta, phi) = self.placement(frame, wo);
        match &self.lobes {
            Lobes::Zonal => {
                let Some((axis, k)) = zonal_slice(&self.brdf, wl, self.l_max) else {
                    return Ok(());
                };
                env.bands_into(r.apply(axis), &mut s.y, &mut s.bands);
                for (l, kl) in k.iter().enumerate() {
                    for (o, b) in out[..ch].iter_mut().zip(&s.bands[l * ch..(l + 1) * ch]) {
                        *o += kl * b;
                    }
                }
            }
            Lobes::Table(t) => {
                if wl[2] <= 0.0 {
                    return Ok(());
                }
                s.dirs.clear();
                s.first.clear();
                s.lobe_weights.clear();
                self.push_lobes(t, &r, theta, phi, s);
                env.lobe_sums(
                    &s.first,
                    &s.dirs,
                    &s.lobe_weights,
                    kc,
                    &mut s.y,
                    &mut s.bands,
                    &mut s.sums,
                );
                pick_sums::<OUTER>(&s.sums, kc, ch, out);
            }
        }
        Ok(())
    }

    /// Step 1 of shading with visibility (ISD Appendix A): the slice's SH
    /// coefficients in the world frame, `rho_l^m = pi_l sum_j lambda_l^j(wo)
    /// y_l^m(R z_j)`, straight from the rotated lobes (no SH rotation);
    /// `None` for a view below the surface (tables). One value per BRDF
    /// channel.
    ///
    /// # Errors
    /// Degrees beyond [`ifd_sphere::MAX_DEGREE`].
    pub fn world_sh(
        &self,
        frame: &Frame,
        wo: [f64; 3],
        s: &mut Scratch,
    ) -> Result<Option<ShCoeffs>> {
        let (r, wl, theta, phi) = self.placement(frame, wo);
        let kc = self.brdf.channels();
        let sh = ShEvaluator::new(self.l_max)?;
        let mut c = ShCoeffs::zeros(self.l_max, kc)?;
        let n = (self.l_max + 1) * (self.l_max + 1);
        match &self.lobes {
            Lobes::Zonal => {
                let Some((axis, k)) = zonal_slice(&self.brdf, wl, self.l_max) else {
                    return Ok(None);
                };
                sh.eval_into(r.apply(axis), &mut s.y[..n]);
                let d = c.data_mut();
                for (l, kl) in k.iter().enumerate() {
                    let band = l * l..(l + 1) * (l + 1);
                    for (di, yi) in d[band.clone()].iter_mut().zip(&s.y[band]) {
                        *di = kl * pi_l(l) * yi;
                    }
                }
            }
            Lobes::Table(t) => {
                if wl[2] <= 0.0 {
                    return Ok(None);
                }
                let ne = t.entry_len();
                t.weights_into(theta, phi, &mut s.weights[..ne]);
                let basis = t.basis();
                let d = c.data_mut();
                for (j, dir) in basis.directions().iter().enumerate() {
                    sh.eval_into(r.apply(*dir), &mut s.y[..n]);
                    for l in basis.first_band(j)..=self.l_max {
                        let base = basis.index(l, j) * kc;
                        for i in l * l..(l + 1) * (l + 1) {
                            for cc in 0..kc {
                                d[i * kc + cc] += pi_l(l) * s.weights[base + cc] * s.y[i];
                            }
                        }
                    }
                }
            }
        }
        Ok(Some(c))
    }

    fn check_env(&self, env: &impl Bands) -> Result<()> {
        if env.l_max() != self.l_max {
            return Err(ShadeError::Mismatch(format!(
                "an environment projected to L = {} for a material of L = {}",
                env.l_max(),
                self.l_max
            )));
        }
        Ok(())
    }

    /// The band-limited slice for the view `wo` at this frame, as SH
    /// coefficients in the local frame used by [`Self::shade_isd`] (rotated
    /// by `phi_o` for isotropic tables), from the same weights.
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn slice_sh(&self, frame: &Frame, wo: [f64; 3]) -> Result<(Rotation, Option<ShCoeffs>)> {
        let (r, wl, theta, phi) = self.placement(frame, wo);
        let l = self.l_max;
        let c = match &self.lobes {
            // the closed form, as the tables' slices are projected
            Lobes::Zonal => project_slice(&self.brdf, wl, l, None)?,
            Lobes::Table(t) => {
                if wl[2] <= 0.0 {
                    return Ok((r, None));
                }
                t.basis()
                    .zhe(&t.weights_at(theta, phi), t.header().channels)?
            }
        };
        Ok((r, Some(c)))
    }

    /// The SH reference of Eq. 22: the slice's SH coefficients (from the same
    /// weights as [`Self::shade_isd`]) rotated by `R` with the
    /// Ivanic-Ruedenberg recurrences, dotted with the environment's.
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn shade_sh(
        &self,
        env: &Environment,
        frame: &Frame,
        wo: [f64; 3],
        out: &mut [f64],
    ) -> Result<()> {
        let ch = self.out_channels(env.channels())?;
        self.sh_into(env, frame, wo, false, &mut out[..ch])
    }

    /// The SH reference of [`Self::shade_isd_parts`]: `out[p C + c]`.
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn shade_sh_parts(
        &self,
        env: &Environment,
        frame: &Frame,
        wo: [f64; 3],
        out: &mut [f64],
    ) -> Result<()> {
        let n = self.brdf.channels() * env.channels();
        self.sh_into(env, frame, wo, true, &mut out[..n])
    }

    fn sh_into(
        &self,
        env: &Environment,
        frame: &Frame,
        wo: [f64; 3],
        outer: bool,
        out: &mut [f64],
    ) -> Result<()> {
        let ch = env.channels();
        self.check_env(env)?;
        out.fill(0.0);
        let (r, c) = self.slice_sh(frame, wo)?;
        let Some(c) = c else {
            return Ok(());
        };
        let g = ShRotation::new(&r, self.l_max)?.apply(&c)?;
        let kc = g.channels();
        let e = env.coeffs().data();
        for i in 0..g.data().len() / kc {
            for cc in 0..ch {
                if outer {
                    for p in 0..kc {
                        out[p * ch + cc] += g.data()[i * kc + p] * e[i * ch + cc];
                    }
                } else {
                    out[cc] += g.data()[i * kc + if kc == 1 { 0 } else { cc }] * e[i * ch + cc];
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::lobe_major;

    /// Lobe-major order: by rank within the point, points in order within
    /// a rank, for points of different lobe counts.
    #[test]
    fn lobe_major_orders_by_rank_then_point() {
        let owner = [0, 0, 0, 1, 2, 2, 2, 2, 3, 3];
        let (mut counts, mut order) = (Vec::new(), Vec::new());
        lobe_major(&owner, &mut counts, &mut order);
        assert_eq!(order, [0, 3, 4, 8, 1, 5, 9, 2, 6, 7]);
        // as many lobes per point: the direct order
        lobe_major(&[0, 0, 0, 1, 1, 1], &mut counts, &mut order);
        assert_eq!(order, [0, 3, 1, 4, 2, 5]);
        // equal runs that are not points' (a point split in two) take the sort
        lobe_major(&[0, 0, 1, 1, 1, 1], &mut counts, &mut order);
        assert_eq!(order, [0, 2, 1, 3, 4, 5]);
        lobe_major(&[], &mut counts, &mut order);
        assert!(order.is_empty());
    }
}
