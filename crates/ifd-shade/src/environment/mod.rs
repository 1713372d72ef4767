//! An environment's SH coefficients as a [`Bands`] source: per-band lookups
//! `Ehat_l(d)` in `f64`, and many lobes at once in vector lanes
//! ([`Precision`]; the `f32` lanes are in `lanes.rs`).

mod lanes;

use ifd_sphere::{ShCoeffs, ShEvaluator, pi_l};

use crate::bands::{Bands, add_weighted};
use crate::error::Result;

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
/// [`Material::shade_sh`](crate::Material::shade_sh) is the SH reference of the same band-limited slice:
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
                lanes::lobe_major(owner, counts, order);
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
