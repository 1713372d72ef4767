//! Real spherical harmonics in the graphics (Sloan) convention.
//!
//! The derivation and conventions are documented on [`ShEvaluator`].

use std::f64::consts::PI;

use crate::error::{Result, check_degree};

/// Number of real SH coefficients up to degree `l_max`: `(l_max + 1)^2`.
#[must_use]
pub const fn sh_count(l_max: usize) -> usize {
    (l_max + 1) * (l_max + 1)
}

/// Flat index `l (l + 1) + m` of `y_l^m`.
///
/// `m` must lie in `-l..=l`; this is checked in debug builds only.
#[must_use]
pub const fn sh_index(l: usize, m: i64) -> usize {
    debug_assert!(m.unsigned_abs() as usize <= l);
    ((l * (l + 1)) as i64 + m) as usize
}

/// `pi_l = sqrt(4 pi / (2l + 1))`, the convolution factor of the addition
/// theorem (ISD Eq. 9, ZHF Eq. 3 `n_l*`).
#[must_use]
pub fn pi_l(l: usize) -> f64 {
    (4.0 * PI / (2 * l + 1) as f64).sqrt()
}

/// Index of `(l, m)`, `0 <= m <= l`, in a triangular table.
#[inline]
pub(crate) const fn tri(l: usize, m: usize) -> usize {
    l * (l + 1) / 2 + m
}

/// Recurrence coefficients shared by the evaluators and the transforms.
#[derive(Clone, Debug)]
pub(crate) struct LegendreTable {
    pub(crate) l_max: usize,
    /// `a_lm` at `tri(l, m)` (valid for `l >= m + 2`).
    pub(crate) a: Vec<f64>,
    /// `b_lm` at `tri(l, m)` (valid for `l >= m + 2`).
    pub(crate) b: Vec<f64>,
    /// `Q_m^m` (the reduced sectoral start values), index `m`.
    pub(crate) qmm: Vec<f64>,
    /// `sqrt(2m + 3)`, index `m`.
    pub(crate) c1: Vec<f64>,
}

impl LegendreTable {
    pub(crate) fn new(l_max: usize) -> Self {
        let n = tri(l_max, l_max) + 1;
        let mut a = vec![0.0; n];
        let mut b = vec![0.0; n];
        for m in 0..=l_max {
            for l in m + 2..=l_max {
                let (lf, mf) = (l as f64, m as f64);
                a[tri(l, m)] = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt();
                let l1 = lf - 1.0;
                b[tri(l, m)] = ((l1 * l1 - mf * mf) / (4.0 * l1 * l1 - 1.0)).sqrt();
            }
        }
        let mut qmm = vec![0.0; l_max + 1];
        qmm[0] = 0.5 / PI.sqrt();
        for m in 1..=l_max {
            let mf = m as f64;
            qmm[m] = -((2.0 * mf + 1.0) / (2.0 * mf)).sqrt() * qmm[m - 1];
        }
        let c1 = (0..=l_max).map(|m| (2.0 * m as f64 + 3.0).sqrt()).collect();
        Self {
            l_max,
            a,
            b,
            qmm,
            c1,
        }
    }

    /// Fully normalised `K_l^m P_l^m(z)` (with `sin^m t` included) for `l >= m`
    /// of one order `m`, for `N` arguments at once: lane `k` of `out[l - m]`
    /// is the value at `z[k]`, with `sm[k] = sin^m t_k`. Written lane-wise so
    /// that the recurrence vectorises across arguments (`N = 1` for one).
    #[inline(always)]
    #[expect(
        clippy::inline_always,
        reason = "compiled into each target of `ifd_simd::run_vectorized`"
    )]
    pub(crate) fn column<const N: usize>(
        &self,
        m: usize,
        z: &[f64; N],
        sm: &[f64; N],
        out: &mut [[f64; N]],
    ) {
        let l_max = self.l_max;
        let mut p2: [f64; N] = std::array::from_fn(|k| self.qmm[m] * sm[k]);
        out[0] = p2;
        if m == l_max {
            return;
        }
        let c1 = self.c1[m];
        let mut p1: [f64; N] = std::array::from_fn(|k| c1 * z[k] * p2[k]);
        out[1] = p1;
        for l in m + 2..=l_max {
            let t = tri(l, m);
            let (a, b) = (self.a[t], self.b[t]);
            let p: [f64; N] = std::array::from_fn(|k| a * (z[k] * p1[k] - b * p2[k]));
            out[l - m] = p;
            p2 = p1;
            p1 = p;
        }
    }
}

/// Shared body of the `f64`/`f32` evaluators (one source, two precisions).
macro_rules! eval_body {
    ($l_max:expr, $x:expr, $y:expr, $z:expr, $qmm:expr, $c1:expr, $a:expr, $b:expr, $out:expr, $t:ty) => {{
        let l_max: usize = $l_max;
        let out = &mut $out[..(l_max + 1) * (l_max + 1)];
        let sqrt2: $t = std::f64::consts::SQRT_2 as $t;
        let (x, y, z): ($t, $t, $t) = ($x, $y, $z);
        // (c, s) = (x + i y)^m
        let mut c: $t = 1.0;
        let mut s: $t = 0.0;
        for m in 0..=l_max {
            if m > 0 {
                let cn = c * x - s * y;
                s = c * y + s * x;
                c = cn;
            }
            let (fc, fs) = if m == 0 {
                (1.0, 0.0)
            } else {
                (sqrt2 * c, sqrt2 * s)
            };
            let mut p2: $t = $qmm[m];
            let mut put = |l: usize, p: $t| {
                let base = l * (l + 1);
                if m == 0 {
                    out[base] = p;
                } else {
                    out[base + m] = p * fc;
                    out[base - m] = p * fs;
                }
            };
            put(m, p2);
            if m < l_max {
                let mut p1: $t = $c1[m] * z * p2;
                put(m + 1, p1);
                for l in m + 2..=l_max {
                    let t = l * (l + 1) / 2 + m;
                    let p = $a[t] * (z * p1 - $b[t] * p2);
                    put(l, p);
                    p2 = p1;
                    p1 = p;
                }
            }
        }
    }};
}

/// Evaluates all real SH up to a fixed degree at a direction; reusable setup.
///
/// ```
/// use ifd_sphere::{ShEvaluator, sh_index};
/// let sh = ShEvaluator::new(2)?;
/// let y = sh.eval([1.0, 0.0, 0.0]);
/// assert!((y[sh_index(1, 1)] + 0.488_602_511_902_919_9).abs() < 1e-15); // y_1^1 = -0.4886 x
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
///
/// # Convention
/// `y_l^m` for `-l <= m <= l`, flat index `l (l + 1) + m`, orthonormal on the unit
/// sphere, Condon-Shortley phase included:
///
/// ```text
/// y_l^m  = sqrt(2) K_l^m P_l^m(cos t) cos(m p)      m > 0
/// y_l^0  =         K_l^0 P_l^0(cos t)
/// y_l^m  = sqrt(2) K_l^|m| P_l^|m|(cos t) sin(|m| p)  m < 0
/// K_l^m  = sqrt((2l + 1) / (4 pi) (l - m)! / (l + m)!)
/// ```
///
/// with `P_l^m` carrying the `(-1)^m` phase, so `y_1^-1 = -0.488603 y`,
/// `y_1^0 = 0.488603 z`, `y_1^1 = -0.488603 x`. This is pyshtools'
/// `spharm_lm(l, m, t, p, normalization='ortho', kind='real', csphase=-1)`.
///
/// # Evaluation
/// The formula above (ISD Eq. 7) is unstable for large `l` when evaluated with
/// factorials. We use the Cartesian form of Sloan ("Stupid SH tricks", 2008):
/// `sin^m t cos(m p) = Re (x + i y)^m` and `sin^m t sin(m p) = Im (x + i y)^m`,
/// and run the standard three-term recurrences on the *normalised, reduced*
/// Legendre functions `Q_l^m(z) = K_l^m P_l^m(z) / sin^m t`, which stay of
/// moderate size for every degree:
///
/// ```text
/// Q_0^0     = 1 / sqrt(4 pi)
/// Q_m^m     = -sqrt((2m + 1) / (2m)) Q_{m-1}^{m-1}
/// Q_{m+1}^m = sqrt(2m + 3) z Q_m^m
/// Q_l^m     = a_lm (z Q_{l-1}^m - b_lm Q_{l-2}^m),
///   a_lm = sqrt((4l^2 - 1) / (l^2 - m^2)),
///   b_lm = sqrt(((l - 1)^2 - m^2) / (4 (l - 1)^2 - 1)).
/// ```
///
/// (Derivation: divide the classical recurrence
/// `(l - m) P_l^m = (2l - 1) z P_{l-1}^m - (l + m - 1) P_{l-2}^m` by `sin^m t` and
/// fold in the ratios `K_l^m / K_{l-1}^m`.) Errors stay at a few ulps times `l`
/// (checked against pyshtools to `L = 100`).
#[derive(Clone, Debug)]
pub struct ShEvaluator {
    table: LegendreTable,
    a32: Vec<f32>,
    b32: Vec<f32>,
    qmm32: Vec<f32>,
    c132: Vec<f32>,
}

impl ShEvaluator {
    /// Precomputes the recurrence coefficients for degrees `0..=l_max`.
    ///
    /// # Errors
    /// [`crate::SphereError::DegreeTooHigh`] beyond [`crate::MAX_DEGREE`].
    pub fn new(l_max: usize) -> Result<Self> {
        check_degree(l_max)?;
        let table = LegendreTable::new(l_max);
        let to32 = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<_>>();
        Ok(Self {
            a32: to32(&table.a),
            b32: to32(&table.b),
            qmm32: to32(&table.qmm),
            c132: to32(&table.c1),
            table,
        })
    }

    /// The maximum degree `L`.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.table.l_max
    }

    /// Number of coefficients `(L + 1)^2`.
    #[must_use]
    pub fn count(&self) -> usize {
        sh_count(self.table.l_max)
    }

    /// All `y_l^m(d)`, `l <= L`, in flat order.
    ///
    /// `d` is normalised first; a zero or non-finite vector yields NaN for every `l >= 1`.
    #[must_use]
    pub fn eval(&self, d: [f64; 3]) -> Vec<f64> {
        let mut out = vec![0.0; self.count()];
        self.eval_into(d, &mut out);
        out
    }

    /// [`Self::eval`] into a caller buffer of at least `(L + 1)^2` values.
    ///
    /// # Panics
    /// If `out` is shorter than `(L + 1)^2`.
    pub fn eval_into(&self, d: [f64; 3], out: &mut [f64]) {
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let inv = if n > 0.0 { 1.0 / n } else { f64::NAN };
        let (x, y, z) = (d[0] * inv, d[1] * inv, d[2] * inv);
        let t = &self.table;
        eval_body!(t.l_max, x, y, z, t.qmm, t.c1, t.a, t.b, out, f64);
    }

    /// The `f32` fast path of [`Self::eval_into`] (same recurrences, `f32`
    /// arithmetic; relative accuracy about `1e-6 * l`).
    ///
    /// # Panics
    /// If `out` is shorter than `(L + 1)^2`.
    pub fn eval_f32_into(&self, d: [f32; 3], out: &mut [f32]) {
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let inv = if n > 0.0 { 1.0 / n } else { f32::NAN };
        let (x, y, z) = (d[0] * inv, d[1] * inv, d[2] * inv);
        eval_body!(
            self.table.l_max,
            x,
            y,
            z,
            self.qmm32,
            self.c132,
            self.a32,
            self.b32,
            out,
            f32
        );
    }

    /// Per-band sums of an SH expansion at `N` directions at once:
    /// `out[(k (L + 1) + l) C + c] = sum_m f_l^m y_l^m(d_k)` for `l >= l0`
    /// (entries of lower bands are left as they are), with `coeffs` flat
    /// `((L + 1)^2, C)` row-major. The recurrences of [`Self::eval_into`] run
    /// lane-wise across the directions and meet the coefficients as they go,
    /// without storing the `(L + 1)^2` values, so the loops vectorise over the
    /// lanes. Directions are normalised first.
    ///
    /// ```
    /// use ifd_sphere::ShEvaluator;
    /// let sh = ShEvaluator::new(3)?;
    /// let f: Vec<f64> = (0..16).map(|i| (i as f64 * 0.3).sin()).collect();
    /// let d = [[0.3, -0.2, 0.9], [0.0, 1.0, 0.0]];
    /// let mut out = vec![0.0; 2 * 4];
    /// sh.band_sums(0, &d, &f, 1, &mut out);
    /// let y = sh.eval(d[1]);
    /// let band2: f64 = (4..9).map(|i| f[i] * y[i]).sum();
    /// assert!((out[4 + 2] - band2).abs() < 1e-14);
    /// # Ok::<(), ifd_sphere::SphereError>(())
    /// ```
    ///
    /// # Panics
    /// If `coeffs` holds fewer than `(L + 1)^2 C` values or `out` fewer than
    /// `N (L + 1) C`.
    pub fn band_sums<const N: usize>(
        &self,
        l0: usize,
        dirs: &[[f64; 3]; N],
        coeffs: &[f64],
        channels: usize,
        out: &mut [f64],
    ) {
        ifd_simd::run_vectorized(BandSums {
            sh: self,
            l0,
            dirs,
            coeffs,
            channels,
            out,
        });
    }

    /// [`Self::band_sums`]' loops, compiled into each of its dispatch targets.
    #[inline(always)]
    #[expect(
        clippy::inline_always,
        reason = "compiled into each target of `ifd_simd::run_vectorized`"
    )]
    fn band_sums_kernel<const N: usize>(
        &self,
        l0: usize,
        dirs: &[[f64; 3]; N],
        coeffs: &[f64],
        channels: usize,
        out: &mut [f64],
    ) {
        let t = &self.table;
        let l_max = t.l_max;
        let ch = channels;
        let nb = l_max + 1;
        assert!(coeffs.len() >= nb * nb * ch && out.len() >= N * nb * ch);
        let mut x = [0.0; N];
        let mut y = [0.0; N];
        let mut z = [0.0; N];
        for k in 0..N {
            let d = dirs[k];
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let inv = if n > 0.0 { 1.0 / n } else { f64::NAN };
            (x[k], y[k], z[k]) = (d[0] * inv, d[1] * inv, d[2] * inv);
        }
        // accumulators [l][c] of lanes, contiguous over the lanes
        let mut acc = vec![[0.0f64; N]; nb * ch];
        let sqrt2 = std::f64::consts::SQRT_2;
        let mut c = [1.0; N];
        let mut s = [0.0; N];
        for m in 0..=l_max {
            if m > 0 {
                for k in 0..N {
                    let cn = c[k] * x[k] - s[k] * y[k];
                    s[k] = c[k] * y[k] + s[k] * x[k];
                    c[k] = cn;
                }
            }
            let (fc, fs): ([f64; N], [f64; N]) = if m == 0 {
                ([1.0; N], [0.0; N])
            } else {
                (
                    std::array::from_fn(|k| sqrt2 * c[k]),
                    std::array::from_fn(|k| sqrt2 * s[k]),
                )
            };
            let mut p2 = [t.qmm[m]; N];
            let mut p1 = [0.0; N];
            for l in m..=l_max {
                // p_l^m lane-wise (sin^m theta is carried by (c, s) = (x + i y)^m)
                let p: [f64; N] = if l == m {
                    p2
                } else if l == m + 1 {
                    p1 = std::array::from_fn(|k| t.c1[m] * z[k] * p2[k]);
                    p1
                } else {
                    let ti = l * (l + 1) / 2 + m;
                    let (a, b) = (t.a[ti], t.b[ti]);
                    let p = std::array::from_fn(|k| a * (z[k] * p1[k] - b * p2[k]));
                    p2 = p1;
                    p1 = p;
                    p
                };
                if l < l0 {
                    continue;
                }
                let base = l * (l + 1);
                let pc: [f64; N] = std::array::from_fn(|k| p[k] * fc[k]);
                let ps: [f64; N] = std::array::from_fn(|k| p[k] * fs[k]);
                for cc in 0..ch {
                    let a = coeffs[(base + m) * ch + cc];
                    let b = if m > 0 {
                        coeffs[(base - m) * ch + cc]
                    } else {
                        0.0
                    };
                    let slot = &mut acc[l * ch + cc];
                    for k in 0..N {
                        slot[k] += pc[k] * a + ps[k] * b;
                    }
                }
            }
        }
        for k in 0..N {
            for l in l0.min(nb)..nb {
                for cc in 0..ch {
                    out[(k * nb + l) * ch + cc] = acc[l * ch + cc][k];
                }
            }
        }
    }

    /// The `f32` fast path of [`Self::band_sums`], lane-major: `acc[l C +
    /// c][k] = sum_m f_l^m y_l^m(d_k)` for every band (zero below `l0`), with
    /// `coeffs` flat `((L + 1)^2, C)` row-major in `f32`. The same lane-wise
    /// recurrences in `f32` arithmetic, each lane's result the same whatever
    /// `N` and whichever instruction set runs it (the lanes never mix), so `N`
    /// can follow the vector width: 16 fills one AVX-512 register. Relative
    /// accuracy of each `y_l^m` about `1e-6 l`; the sums' error against
    /// [`Self::band_sums`] is measured where it is used (`ifd-shade`'s
    /// `Precision::F32`).
    ///
    /// ```
    /// use ifd_sphere::ShEvaluator;
    /// let sh = ShEvaluator::new(3)?;
    /// let f: Vec<f64> = (0..16).map(|i| (i as f64 * 0.3).sin()).collect();
    /// let f32s: Vec<f32> = f.iter().map(|&v| v as f32).collect();
    /// let d = [[0.3, -0.2, 0.9], [0.0, 1.0, 0.0]];
    /// let mut acc = vec![[0.0f32; 2]; 4];
    /// sh.band_sums_f32(0, &d, &f32s, 1, &mut acc);
    /// let y = sh.eval([0.0, 1.0, 0.0]);
    /// let band2: f64 = (4..9).map(|i| f[i] * y[i]).sum();
    /// assert!((f64::from(acc[2][1]) - band2).abs() < 1e-6);
    /// # Ok::<(), ifd_sphere::SphereError>(())
    /// ```
    ///
    /// # Panics
    /// If `coeffs` holds fewer than `(L + 1)^2 C` values or `acc` fewer than
    /// `(L + 1) C` lanes.
    pub fn band_sums_f32<const N: usize>(
        &self,
        l0: usize,
        dirs: &[[f32; 3]; N],
        coeffs: &[f32],
        channels: usize,
        acc: &mut [[f32; N]],
    ) {
        ifd_simd::run_vectorized(BandSumsF32 {
            sh: self,
            l0,
            dirs,
            coeffs,
            channels,
            acc,
        });
    }

    /// [`Self::band_sums_f32`] without the dispatch, to call from inside a
    /// [`ifd_simd::VectorKernel`] (it is `#[inline(always)]`: compiled into the
    /// caller's target). Literal channel counts (1, 3) get their own
    /// unrolled loops.
    #[inline(always)]
    #[expect(
        clippy::inline_always,
        reason = "compiled into each target of `ifd_simd::run_vectorized`"
    )]
    pub fn band_sums_f32_lanes<const N: usize>(
        &self,
        l0: usize,
        dirs: &[[f32; 3]; N],
        coeffs: &[f32],
        channels: usize,
        acc: &mut [[f32; N]],
    ) {
        match channels {
            1 => self.band_sums_f32_kernel(l0, dirs, coeffs, 1, acc),
            3 => self.band_sums_f32_kernel(l0, dirs, coeffs, 3, acc),
            ch => self.band_sums_f32_kernel(l0, dirs, coeffs, ch, acc),
        }
    }

    /// [`Self::band_sums_f32`]'s loops. The recurrence's first two steps are
    /// peeled off the loop over `l`; lanes accumulate `p_l^m (fc a + fs b)`
    /// per band and channel.
    #[inline(always)]
    #[expect(
        clippy::inline_always,
        reason = "compiled into each target of `ifd_simd::run_vectorized`"
    )]
    fn band_sums_f32_kernel<const N: usize>(
        &self,
        l0: usize,
        dirs: &[[f32; 3]; N],
        coeffs: &[f32],
        ch: usize,
        acc: &mut [[f32; N]],
    ) {
        let l_max = self.table.l_max;
        let nb = l_max + 1;
        assert!(coeffs.len() >= nb * nb * ch && acc.len() >= nb * ch);
        let acc = &mut acc[..nb * ch];
        acc.fill([0.0; N]);
        let mut x = [0.0f32; N];
        let mut y = [0.0f32; N];
        let mut z = [0.0f32; N];
        for k in 0..N {
            let d = dirs[k];
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let inv = if n > 0.0 { 1.0 / n } else { f32::NAN };
            (x[k], y[k], z[k]) = (d[0] * inv, d[1] * inv, d[2] * inv);
        }
        let sqrt2 = std::f32::consts::SQRT_2;
        let mut c = [1.0f32; N];
        let mut s = [0.0f32; N];
        for m in 0..=l_max {
            let (fc, fs): ([f32; N], [f32; N]) = if m == 0 {
                ([1.0; N], [0.0; N])
            } else {
                for k in 0..N {
                    let cn = c[k] * x[k] - s[k] * y[k];
                    s[k] = c[k] * y[k] + s[k] * x[k];
                    c[k] = cn;
                }
                (
                    std::array::from_fn(|k| sqrt2 * c[k]),
                    std::array::from_fn(|k| sqrt2 * s[k]),
                )
            };
            // the recurrence's start Q_m^m (sin^m t is in fc, fs)
            let mut p2 = [self.qmm32[m]; N];
            if m >= l0 {
                add_band(acc, coeffs, ch, m, m, &p2, &fc, &fs);
            }
            if m == l_max {
                break;
            }
            let c1 = self.c132[m];
            let mut p1: [f32; N] = std::array::from_fn(|k| c1 * z[k] * p2[k]);
            if m + 1 >= l0 {
                add_band(acc, coeffs, ch, m + 1, m, &p1, &fc, &fs);
            }
            for l in m + 2..=l_max {
                let ti = tri(l, m);
                let (a, b) = (self.a32[ti], self.b32[ti]);
                let p: [f32; N] = std::array::from_fn(|k| a * z[k].mul_add(p1[k], -(b * p2[k])));
                p2 = p1;
                p1 = p;
                if l >= l0 {
                    add_band(acc, coeffs, ch, l, m, &p, &fc, &fs);
                }
            }
        }
    }

    /// Values of the band-`l` functions only, `y_l^{-l..=l}(d)`, into `out[..2l+1]`.
    /// Costs as much as a full evaluation up to `l`.
    ///
    /// # Panics
    /// If `l > L` or `out` is shorter than `2l + 1`.
    pub fn eval_band_into(&self, l: usize, d: [f64; 3], scratch: &mut [f64], out: &mut [f64]) {
        self.eval_into(d, scratch);
        out[..=2 * l].copy_from_slice(&scratch[l * l..(l + 1) * (l + 1)]);
    }
}

/// [`ShEvaluator::band_sums`]' arguments, run as a [`ifd_simd::VectorKernel`].
struct BandSums<'a, const N: usize> {
    sh: &'a ShEvaluator,
    l0: usize,
    dirs: &'a [[f64; 3]; N],
    coeffs: &'a [f64],
    channels: usize,
    out: &'a mut [f64],
}

impl<const N: usize> ifd_simd::VectorKernel for BandSums<'_, N> {
    type Output = ();
    #[inline(always)]
    #[allow(
        clippy::inline_always,
        reason = "the kernel is compiled into each target of `run_vectorized`"
    )]
    fn run(self) {
        let Self {
            sh,
            l0,
            dirs,
            coeffs,
            channels,
            out,
        } = self;
        sh.band_sums_kernel(l0, dirs, coeffs, channels, out);
    }
}

/// [`ShEvaluator::band_sums_f32`]'s arguments, run as a [`ifd_simd::VectorKernel`].
struct BandSumsF32<'a, const N: usize> {
    sh: &'a ShEvaluator,
    l0: usize,
    dirs: &'a [[f32; 3]; N],
    coeffs: &'a [f32],
    channels: usize,
    acc: &'a mut [[f32; N]],
}

impl<const N: usize> ifd_simd::VectorKernel for BandSumsF32<'_, N> {
    type Output = ();
    #[inline(always)]
    #[allow(
        clippy::inline_always,
        reason = "the kernel is compiled into each target of `run_vectorized`"
    )]
    fn run(self) {
        let Self {
            sh,
            l0,
            dirs,
            coeffs,
            channels,
            acc,
        } = self;
        sh.band_sums_f32_lanes(l0, dirs, coeffs, channels, acc);
    }
}

/// One band's accumulation for order `m` in [`ShEvaluator::band_sums_f32`]:
/// `acc[l C + c][k] += p_k (fc_k a_c + fs_k b_c)`, `(a, b)` the coefficients
/// of `(l, m)` and `(l, -m)` (`fs` unused for `m = 0`).
#[expect(clippy::too_many_arguments, reason = "one band's inputs")]
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target of `ifd_simd::run_vectorized`"
)]
fn add_band<const N: usize>(
    acc: &mut [[f32; N]],
    coeffs: &[f32],
    ch: usize,
    l: usize,
    m: usize,
    p: &[f32; N],
    fc: &[f32; N],
    fs: &[f32; N],
) {
    let base = l * (l + 1);
    let pc: [f32; N] = std::array::from_fn(|k| p[k] * fc[k]);
    if m == 0 {
        for cc in 0..ch {
            let a = coeffs[base * ch + cc];
            let slot = &mut acc[l * ch + cc];
            for k in 0..N {
                slot[k] = pc[k].mul_add(a, slot[k]);
            }
        }
    } else {
        let ps: [f32; N] = std::array::from_fn(|k| p[k] * fs[k]);
        for cc in 0..ch {
            let a = coeffs[(base + m) * ch + cc];
            let b = coeffs[(base - m) * ch + cc];
            let slot = &mut acc[l * ch + cc];
            for k in 0..N {
                slot[k] = pc[k].mul_add(a, ps[k].mul_add(b, slot[k]));
            }
        }
    }
}

/// Convenience: all `y_l^m(d)` up to `l_max` (builds an evaluator each call;
/// keep a [`ShEvaluator`] for repeated use).
///
/// # Errors
/// [`crate::SphereError::DegreeTooHigh`] beyond [`crate::MAX_DEGREE`].
pub fn eval_sh(l_max: usize, d: [f64; 3]) -> Result<Vec<f64>> {
    Ok(ShEvaluator::new(l_max)?.eval(d))
}

/// Direction `(sin t cos p, sin t sin p, cos t)` of polar angle `t` and azimuth `p`.
#[must_use]
pub fn direction(theta: f64, phi: f64) -> [f64; 3] {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    [st * cp, st * sp, ct]
}
