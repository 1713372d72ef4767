//! Rotated zonal harmonics (RZH), direction sets and zonal harmonic
//! factorisation (ZHF): ISD Eq. 8-12, ZHF Eq. 5-7 and 9-11.
//!
//! # The basis
//! For band `l` and `2l + 1` directions `z_l^j`, the rotated zonal harmonics
//! `phi_l^j(w) = y_l^0((R_l^j)^-1 w) = K_l^0 P_l(z_l^j . w)` span the same space as
//! the band-`l` SH (for a non-singular set). By the addition theorem
//! (ISD Eq. 9, ZHF Eq. 6) `phi_l^j = pi_l sum_m y_l^m(z_l^j) y_l^m`, hence
//!
//! ```text
//! c_l = M_l Lambda_l,   (M_l)_{m j} = pi_l y_l^m(z_l^j)      (ISD Eq. 10)
//! ```
//!
//! between the SH coefficients `c_l` and the RZH coefficients `Lambda_l` of a
//! function. [`RzhBasis::zhf`] computes `Lambda = M^-1 c` (ZHF), [`RzhBasis::zhe`]
//! computes `c = M Lambda` (ZHE).
//!
//! Note on the ZHF paper: it writes `z = A^T f` with `A = Y^-1`,
//! `Y_{jm} = y_l^m(w_j)`, and `f = Y^T z` (its Sec. 4), which leaves out the factor
//! `n_l* = pi_l` of its own Eq. 6; the two are consistent with each other, so
//! its lobe weights are `pi_l` times ours. We follow ISD Eq. 10-11.
//!
//! # Rotation
//! Rotating the function (`g(w) = f(R^T w)`) rotates the lobes and keeps the
//! weights (ZHF Eq. 9), so `c'_l = M_l(R z) Lambda_l` (ZHF Eq. 10, the "standard"
//! algorithm, [`RzhBasis::rotate`]). Sampling the band-`l` part of `f` at the
//! inversely rotated lobe directions gives the "signal-tailored" form (ZHF Eq. 11,
//! [`RzhBasis::rotate_tailored`]): with `Y_l = M_l^T / pi_l`,
//! `g_l(z_j) = f_l(R^T z_j) = (Y_l c'_l)_j`, so `c'_l = pi_l (M_l^-1)^T [f_l(R^T z_j)]_j`.
//!
//! # Direction sets
//! Per band (`(L + 1)^2` directions, band `l` owns `2l + 1`), or shared across
//! bands (lobe sharing, ZHF Sec. 6): `2L + 1` nested directions, band `l` uses
//! the first `2l + 1`. Choosers: random (seeded), spherical Fibonacci, and an
//! optimiser that lowers the condition numbers of the `M_l`.
//!
//! Fibonacci sets take the upper half of a `2n`-point spherical Fibonacci set:
//! a plain `n`-point set is exactly singular for odd bands (its points pair up
//! under a half-turn; the 3-point set is coplanar with the origin), and since
//! band-`l` functions are even or odd, a set on one hemisphere loses nothing
//! (`w` and `-w` give the same row of `M_l` up to sign). Shared sets are then
//! reordered greedily, farthest point (in `|w . w'|`) first, so every prefix
//! is well spread.

use nalgebra::DMatrix;

use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError, check_degree};
use crate::rotation::Rotation;
use crate::sh::{ShEvaluator, pi_l, sh_count};

/// Default largest accepted condition number of an `M_l`.
pub const DEFAULT_COND_LIMIT: f64 = 1e10;

/// Whether bands own their directions or share one nested set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sharing {
    /// `2l + 1` directions per band, `(L + 1)^2` in all.
    PerBand,
    /// `2L + 1` nested directions; band `l` uses the first `2l + 1`.
    Shared,
}

/// How directions are chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Chooser {
    /// Uniformly random on the sphere, reproducible from the seed.
    Random {
        /// Seed of the generator.
        seed: u64,
    },
    /// Spherical Fibonacci points.
    Fibonacci,
    /// Start from Fibonacci points and move single directions at random
    /// (seeded), keeping moves that lower the condition number(s).
    Optimized {
        /// Seed of the generator.
        seed: u64,
        /// Proposals per band (per-band sets) or in all (shared sets).
        iterations: usize,
    },
}

/// Deterministic generator (`SplitMix64`), enough for direction sampling.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator from a seed.
    #[must_use]
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Uniform random unit vector.
    pub fn direction(&mut self) -> [f64; 3] {
        let z = 2.0 * self.uniform() - 1.0;
        let p = std::f64::consts::TAU * self.uniform();
        let s = (1.0 - z * z).max(0.0).sqrt();
        [s * p.cos(), s * p.sin(), z]
    }
}

/// Normalises `d`, or reports it as [`SphereError::BadDirection`].
///
/// # Errors
/// For zero-length or non-finite vectors.
pub fn check_direction(index: usize, d: [f64; 3]) -> Result<[f64; 3]> {
    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if n.is_nan() || n <= 1e-300 || !n.is_finite() {
        return Err(SphereError::BadDirection {
            index,
            x: d[0],
            y: d[1],
            z: d[2],
        });
    }
    Ok([d[0] / n, d[1] / n, d[2] / n])
}

/// `n` spherical Fibonacci points (`z_i = 1 - (2i + 1) / n`, golden-angle azimuths).
#[must_use]
pub fn fibonacci(n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let s = (1.0 - z * z).max(0.0).sqrt();
            let p = golden * i as f64;
            [s * p.cos(), s * p.sin(), z]
        })
        .collect()
}

/// Reorders points so that each is the farthest (largest minimal angle) from
/// the ones before it; the first stays first.
#[must_use]
pub fn farthest_point_order(points: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let n = points.len();
    if n == 0 {
        return Vec::new();
    }
    let mut used = vec![false; n];
    let mut best_dot = vec![f64::NEG_INFINITY; n];
    let mut out = Vec::with_capacity(n);
    let mut cur = 0;
    for _ in 0..n {
        used[cur] = true;
        out.push(points[cur]);
        let p = points[cur];
        let mut next = None;
        let mut next_val = f64::INFINITY;
        for i in 0..n {
            if used[i] {
                continue;
            }
            let q = points[i];
            // |dot| treats antipodal points as close: y_l(-w) = +-y_l(w).
            let d = (p[0] * q[0] + p[1] * q[1] + p[2] * q[2]).abs();
            best_dot[i] = best_dot[i].max(d);
            if best_dot[i] < next_val {
                next_val = best_dot[i];
                next = Some(i);
            }
        }
        match next {
            Some(i) => cur = i,
            None => break,
        }
    }
    out
}

/// The lobe directions of an RZH (or ISD) basis up to degree `L`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DirectionSet {
    l_max: usize,
    sharing: Sharing,
    dirs: Vec<[f64; 3]>,
}

impl DirectionSet {
    /// Number of directions a set needs.
    #[must_use]
    pub fn required(l_max: usize, sharing: Sharing) -> usize {
        match sharing {
            Sharing::PerBand => sh_count(l_max),
            Sharing::Shared => 2 * l_max + 1,
        }
    }

    /// Wraps given directions (normalised here).
    ///
    /// # Errors
    /// [`SphereError::Length`] for the wrong count, [`SphereError::BadDirection`].
    pub fn from_dirs(l_max: usize, sharing: Sharing, dirs: &[[f64; 3]]) -> Result<Self> {
        check_degree(l_max)?;
        let need = Self::required(l_max, sharing);
        if dirs.len() != need {
            return Err(SphereError::Length {
                what: "lobe directions",
                got: dirs.len(),
                expected: need,
            });
        }
        let dirs = dirs
            .iter()
            .enumerate()
            .map(|(i, d)| check_direction(i, *d))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            l_max,
            sharing,
            dirs,
        })
    }

    /// The direction sets by the names `ifd sphere decompose --directions`
    /// and the Python module use: `fibonacci` (per band), `shared`
    /// (nested Fibonacci), `optimized` (per band, 300 seeded proposals per
    /// band), `optimized-shared` (300 in all) and `random` (per band).
    ///
    /// ```
    /// use ifd_sphere::zhf::DirectionSet;
    /// assert_eq!(DirectionSet::by_name("shared", 4, 1)?.all().len(), 9);
    /// assert!(DirectionSet::by_name("spiral", 4, 1).is_err());
    /// # Ok::<(), ifd_sphere::SphereError>(())
    /// ```
    ///
    /// # Errors
    /// [`SphereError::Parameter`] for an unknown name, and as
    /// [`DirectionSet::new`].
    pub fn by_name(name: &str, l_max: usize, seed: u64) -> Result<Self> {
        let iterations = 300;
        let (sharing, chooser) = match name {
            "fibonacci" => (Sharing::PerBand, Chooser::Fibonacci),
            "shared" => (Sharing::Shared, Chooser::Fibonacci),
            "optimized" => (Sharing::PerBand, Chooser::Optimized { seed, iterations }),
            "optimized-shared" => (Sharing::Shared, Chooser::Optimized { seed, iterations }),
            "random" => (Sharing::PerBand, Chooser::Random { seed }),
            other => {
                return Err(SphereError::Parameter {
                    name: "directions",
                    value: other.to_string(),
                    reason: "expected fibonacci, shared, optimized, optimized-shared or random",
                });
            }
        };
        Self::new(l_max, sharing, chooser)
    }

    /// Chooses directions.
    ///
    /// ```
    /// use ifd_sphere::zhf::{Chooser, DirectionSet, Sharing};
    /// let d = DirectionSet::new(4, Sharing::Shared, Chooser::Fibonacci)?;
    /// assert_eq!(d.band(2).len(), 5);
    /// assert_eq!(d.all().len(), 9);
    /// # Ok::<(), ifd_sphere::SphereError>(())
    /// ```
    ///
    /// # Errors
    /// [`SphereError::DegreeTooHigh`].
    pub fn new(l_max: usize, sharing: Sharing, chooser: Chooser) -> Result<Self> {
        check_degree(l_max)?;
        let per_band_fib = |l: usize| -> Vec<[f64; 3]> {
            // The upper half of a 2(2l + 1)-point Fibonacci set. (A plain
            // (2l + 1)-point set is exactly singular for odd l: its points come in
            // pairs symmetric under a half-turn, e.g. the 3 points are coplanar
            // with the origin. Functions of band l are even or odd, so a set
            // spread over one hemisphere loses nothing.) A fixed band-dependent
            // tilt keeps the bands' poles apart.
            let r = Rotation::from_zyz(0.7 * l as f64, 0.3 + 0.1 * l as f64, 0.0);
            fibonacci(2 * (2 * l + 1))
                .into_iter()
                .take(2 * l + 1)
                .map(|d| r.apply(d))
                .collect()
        };
        let dirs = match (chooser, sharing) {
            (Chooser::Random { seed }, _) => {
                let mut rng = SplitMix64::new(seed);
                (0..Self::required(l_max, sharing))
                    .map(|_| rng.direction())
                    .collect()
            }
            (Chooser::Fibonacci | Chooser::Optimized { .. }, Sharing::PerBand) => {
                (0..=l_max).flat_map(per_band_fib).collect()
            }
            (Chooser::Fibonacci | Chooser::Optimized { .. }, Sharing::Shared) => {
                let r = Rotation::from_zyz(0.4, 0.3, 0.0);
                let n = 2 * l_max + 1;
                let pts: Vec<_> = fibonacci(2 * n)
                    .into_iter()
                    .take(n)
                    .map(|d| r.apply(d))
                    .collect();
                farthest_point_order(&pts)
            }
        };
        let mut set = Self {
            l_max,
            sharing,
            dirs,
        };
        if let Chooser::Optimized { seed, iterations } = chooser {
            set.optimize(seed, iterations);
        }
        Ok(set)
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// Per band or shared.
    #[must_use]
    pub fn sharing(&self) -> Sharing {
        self.sharing
    }

    /// All stored directions (band-major for per-band sets).
    #[must_use]
    pub fn all(&self) -> &[[f64; 3]] {
        &self.dirs
    }

    /// The `2l + 1` directions of band `l`.
    ///
    /// # Panics
    /// If `l > L`.
    #[must_use]
    pub fn band(&self, l: usize) -> &[[f64; 3]] {
        assert!(l <= self.l_max);
        match self.sharing {
            Sharing::PerBand => &self.dirs[l * l..(l + 1) * (l + 1)],
            Sharing::Shared => &self.dirs[..=2 * l],
        }
    }

    /// This set with every direction rotated by `rot`.
    #[must_use]
    pub fn rotated(&self, rot: &Rotation) -> Self {
        Self {
            l_max: self.l_max,
            sharing: self.sharing,
            dirs: self.dirs.iter().map(|d| rot.apply(*d)).collect(),
        }
    }

    /// Checks a set that did not come from a constructor (deserialised from a
    /// file): a supported degree, the count its sharing needs, and unit
    /// directions (to 1e-6).
    ///
    /// # Errors
    /// [`SphereError::DegreeTooHigh`], [`SphereError::Length`],
    /// [`SphereError::BadDirection`].
    pub fn check(&self) -> Result<()> {
        check_degree(self.l_max)?;
        let need = Self::required(self.l_max, self.sharing);
        if self.dirs.len() != need {
            return Err(SphereError::Length {
                what: "lobe directions",
                got: self.dirs.len(),
                expected: need,
            });
        }
        for (i, d) in self.dirs.iter().enumerate() {
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if !n.is_finite() || (n - 1.0).abs() > 1e-6 {
                return Err(SphereError::BadDirection {
                    index: i,
                    x: d[0],
                    y: d[1],
                    z: d[2],
                });
            }
        }
        Ok(())
    }

    /// Condition numbers of every `M_l` (infinite when singular).
    #[must_use]
    pub fn condition_numbers(&self) -> Vec<f64> {
        let sh = ShEvaluator::new(self.l_max).ok();
        (0..=self.l_max)
            .map(|l| {
                sh.as_ref().map_or(f64::INFINITY, |sh| {
                    condition_number(&band_matrix(sh, l, self.band(l)))
                })
            })
            .collect()
    }

    /// Improves this set in place: moves single directions at random (seeded),
    /// with steps shrinking over the `iterations` proposals, keeping moves that
    /// lower the condition number of `M_l` (per band, `iterations` proposals
    /// per band) or, for shared sets, the worst band's condition number and then
    /// the sum of their logarithms (`iterations` proposals in all). It never makes
    /// a band worse, so it can start from any set ([`Chooser::Optimized`] starts
    /// from the Fibonacci set).
    ///
    /// ```
    /// use ifd_sphere::zhf::{Chooser, DirectionSet, Sharing};
    /// let mut d = DirectionSet::new(4, Sharing::PerBand, Chooser::Random { seed: 1 })?;
    /// let before = d.condition_numbers();
    /// d.optimize(7, 50);
    /// assert!(d.condition_numbers().iter().zip(&before).all(|(a, b)| a <= b));
    /// # Ok::<(), ifd_sphere::SphereError>(())
    /// ```
    pub fn optimize(&mut self, seed: u64, iterations: usize) {
        let Ok(sh) = ShEvaluator::new(self.l_max) else {
            return;
        };
        let mut rng = SplitMix64::new(seed);
        let cond_of = |dirs: &[[f64; 3]], l: usize| condition_number(&band_matrix(&sh, l, dirs));
        match self.sharing {
            Sharing::PerBand => {
                for l in 1..=self.l_max {
                    let off = l * l;
                    let n = 2 * l + 1;
                    let mut best = cond_of(&self.dirs[off..off + n], l);
                    for it in 0..iterations {
                        let step =
                            0.5 / (n as f64).sqrt() * (1.0 - it as f64 / iterations as f64) + 1e-3;
                        let j = (rng.next_u64() % n as u64) as usize;
                        let old = self.dirs[off + j];
                        self.dirs[off + j] = perturb(&mut rng, old, step);
                        let c = cond_of(&self.dirs[off..off + n], l);
                        if c < best {
                            best = c;
                        } else {
                            self.dirs[off + j] = old;
                        }
                    }
                }
            }
            Sharing::Shared => {
                // Objective: the worst band's log condition number, then their sum.
                let score = |dirs: &[[f64; 3]]| -> (f64, f64) {
                    let mut worst: f64 = 0.0;
                    let mut sum = 0.0;
                    for l in 1..=self.l_max {
                        let c = cond_of(&dirs[..=2 * l], l).ln();
                        worst = worst.max(c);
                        sum += c;
                    }
                    (worst, sum)
                };
                let n = self.dirs.len();
                let mut best = score(&self.dirs);
                for it in 0..iterations {
                    let step =
                        0.5 / (n as f64).sqrt() * (1.0 - it as f64 / iterations as f64) + 1e-3;
                    let j = (rng.next_u64() % n as u64) as usize;
                    let old = self.dirs[j];
                    self.dirs[j] = perturb(&mut rng, old, step);
                    let s = score(&self.dirs);
                    if s.0 < best.0 - 1e-12 || (s.0 <= best.0 + 1e-12 && s.1 < best.1) {
                        best = s;
                    } else {
                        self.dirs[j] = old;
                    }
                }
            }
        }
    }
}

fn perturb(rng: &mut SplitMix64, d: [f64; 3], step: f64) -> [f64; 3] {
    let q = [
        d[0] + step * rng.normal(),
        d[1] + step * rng.normal(),
        d[2] + step * rng.normal(),
    ];
    check_direction(0, q).unwrap_or(d)
}

/// `(M_l)_{m j} = pi_l y_l^m(z_j)` for the given band-`l` directions.
pub(crate) fn band_matrix(sh: &ShEvaluator, l: usize, dirs: &[[f64; 3]]) -> DMatrix<f64> {
    let n = 2 * l + 1;
    let mut y = vec![0.0; sh_count(sh.l_max())];
    let mut m = DMatrix::zeros(n, dirs.len());
    let p = pi_l(l);
    let sub = ShEvaluator::new(l).ok();
    let ev = sub.as_ref().unwrap_or(sh);
    for (j, d) in dirs.iter().enumerate() {
        ev.eval_into(*d, &mut y);
        for i in 0..n {
            m[(i, j)] = p * y[l * l + i];
        }
    }
    m
}

/// The inverse and condition number of band `band`'s matrix, refused as
/// [`SphereError::Degenerate`] when the condition number exceeds `limit` or
/// the inversion fails.
pub(crate) fn checked_inverse(
    m: &DMatrix<f64>,
    band: usize,
    limit: f64,
) -> Result<(DMatrix<f64>, f64)> {
    let cond = condition_number(m);
    let inv = if cond <= limit {
        m.clone().try_inverse()
    } else {
        None
    };
    inv.map(|i| (i, cond))
        .ok_or(SphereError::Degenerate { band, cond, limit })
}

/// 2-norm condition number (ratio of extreme singular values; infinite when singular).
#[must_use]
pub fn condition_number(m: &DMatrix<f64>) -> f64 {
    if m.is_empty() {
        return 1.0;
    }
    let sv = m.clone().svd(false, false).singular_values;
    let max = sv.iter().copied().fold(0.0, f64::max);
    let min = sv.iter().copied().fold(f64::INFINITY, f64::min);
    if min.is_nan() || min <= 0.0 || !max.is_finite() {
        f64::INFINITY
    } else {
        max / min
    }
}

/// Coefficients in a rotated-zonal-harmonic (or ISD) basis: `Lambda_l^j` for each
/// band `l` and lobe `j` of the band, flat index `l^2 + j`, `C` channels
/// (`((L + 1)^2, C)` row-major, like [`ShCoeffs`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RzhCoeffs {
    /// Maximum degree.
    pub l_max: usize,
    /// Channel count.
    pub channels: usize,
    /// Values, `((L + 1)^2, C)` row-major.
    pub data: Vec<f64>,
}

#[derive(Clone)]
struct Band {
    /// `M_l`, row-major `(2l+1)^2`.
    m: Vec<f64>,
    /// `M_l^-1`, row-major.
    minv: Vec<f64>,
    cond: f64,
}

/// An RZH basis: directions with the matrices `M_l`, their inverses and
/// condition numbers (the expensive, reusable setup).
///
/// ```
/// use ifd_sphere::zhf::{Chooser, DirectionSet, RzhBasis, Sharing};
/// use ifd_sphere::{Rotation, ShCoeffs, ShRotation};
/// let dirs = DirectionSet::new(6, Sharing::Shared, Chooser::Fibonacci)?;
/// let basis = RzhBasis::new(dirs)?;
/// let mut f = ShCoeffs::zeros(6, 1)?;
/// for (i, v) in f.data_mut().iter_mut().enumerate() { *v = (i as f64 * 0.37).sin(); }
/// let back = basis.zhe(&basis.zhf(&f)?)?;                      // ZHF then ZHE
/// assert!(back.data().iter().zip(f.data()).all(|(a, b)| (a - b).abs() < 1e-12));
/// let r = Rotation::from_zyz(0.3, 1.1, -0.4);
/// let g = basis.rotate(&f, &r)?;                               // ZHF Eq. 10
/// let h = ShRotation::new(&r, 6)?.apply(&f)?;                  // reference
/// assert!(g.data().iter().zip(h.data()).all(|(a, b)| (a - b).abs() < 1e-11));
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
#[derive(Clone)]
pub struct RzhBasis {
    dirs: DirectionSet,
    sh: ShEvaluator,
    bands: Vec<Band>,
}

impl std::fmt::Debug for RzhBasis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RzhBasis")
            .field("dirs", &self.dirs)
            .field("conds", &self.condition_numbers())
            .finish_non_exhaustive()
    }
}

impl RzhBasis {
    /// Builds `M_l` and `M_l^-1` for every band, refusing condition numbers above
    /// [`DEFAULT_COND_LIMIT`].
    ///
    /// # Errors
    /// [`SphereError::Degenerate`] naming the band and its condition number.
    pub fn new(dirs: DirectionSet) -> Result<Self> {
        Self::with_limit(dirs, DEFAULT_COND_LIMIT)
    }

    /// [`Self::new`] with a custom condition-number limit.
    ///
    /// # Errors
    /// [`SphereError::Degenerate`].
    pub fn with_limit(dirs: DirectionSet, cond_limit: f64) -> Result<Self> {
        let sh = ShEvaluator::new(dirs.l_max())?;
        let mut bands = Vec::with_capacity(dirs.l_max() + 1);
        for l in 0..=dirs.l_max() {
            let m = band_matrix(&sh, l, dirs.band(l));
            let (inv, cond) = checked_inverse(&m, l, cond_limit)?;
            bands.push(Band {
                m: m.transpose().as_slice().to_vec(),
                minv: inv.transpose().as_slice().to_vec(),
                cond,
            });
        }
        Ok(Self { dirs, sh, bands })
    }

    /// The directions.
    #[must_use]
    pub fn directions(&self) -> &DirectionSet {
        &self.dirs
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.dirs.l_max()
    }

    /// Condition number of each `M_l`.
    #[must_use]
    pub fn condition_numbers(&self) -> Vec<f64> {
        self.bands.iter().map(|b| b.cond).collect()
    }

    /// `M_l` as a row-major `(2l + 1)^2` slice (rows `m`, columns lobes).
    ///
    /// # Panics
    /// If `l > L`.
    #[must_use]
    pub fn m_band(&self, l: usize) -> &[f64] {
        &self.bands[l].m
    }

    /// `M_l^-1`, row-major.
    ///
    /// # Panics
    /// If `l > L`.
    #[must_use]
    pub fn m_inv_band(&self, l: usize) -> &[f64] {
        &self.bands[l].minv
    }

    fn check(&self, l_max: usize) -> Result<()> {
        if l_max != self.l_max() {
            return Err(SphereError::Mismatch(format!(
                "coefficients of degree {l_max} with an RZH basis of degree {}",
                self.l_max()
            )));
        }
        Ok(())
    }

    /// ZHF: RZH coefficients `Lambda_l = M_l^-1 c_l` of an SH expansion.
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn zhf(&self, f: &ShCoeffs) -> Result<RzhCoeffs> {
        self.check(f.l_max())?;
        let ch = f.channels();
        let mut out = vec![0.0; f.data().len()];
        for (l, b) in self.bands.iter().enumerate() {
            block_mul(
                &b.minv,
                2 * l + 1,
                &f.data()[l * l * ch..],
                &mut out[l * l * ch..],
                ch,
            );
        }
        Ok(RzhCoeffs {
            l_max: f.l_max(),
            channels: ch,
            data: out,
        })
    }

    /// ZHE: SH coefficients `c_l = M_l Lambda_l` of an RZH expansion.
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn zhe(&self, z: &RzhCoeffs) -> Result<ShCoeffs> {
        self.check(z.l_max)?;
        let ch = z.channels;
        let mut out = ShCoeffs::zeros(z.l_max, ch)?;
        for (l, b) in self.bands.iter().enumerate() {
            block_mul(
                &b.m,
                2 * l + 1,
                &z.data[l * l * ch..],
                &mut out.data_mut()[l * l * ch..],
                ch,
            );
        }
        Ok(out)
    }

    /// Evaluates an RZH expansion directly: `sum_lj Lambda_l^j K_l^0 P_l(z_l^j . w)`
    /// (independent of the SH machinery; for checks).
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn eval_rzh(&self, z: &RzhCoeffs, w: [f64; 3]) -> Result<Vec<f64>> {
        self.check(z.l_max)?;
        let w = check_direction(0, w)?;
        let mut out = vec![0.0; z.channels];
        let mut p = vec![0.0; self.l_max() + 1];
        for l in 0..=self.l_max() {
            let k = (((2 * l + 1) as f64) / (4.0 * std::f64::consts::PI)).sqrt();
            for (j, d) in self.dirs.band(l).iter().enumerate() {
                let t = d[0] * w[0] + d[1] * w[1] + d[2] * w[2];
                crate::sh::legendre_all(l, t, &mut p);
                let v = k * p[l];
                for (c, o) in out.iter_mut().enumerate() {
                    *o += z.data[(l * l + j) * z.channels + c] * v;
                }
            }
        }
        Ok(out)
    }

    /// Rotates an SH expansion by ZHF (ZHF Eq. 10): `c'_l = M_l(R z) M_l^-1 c_l`,
    /// giving the coefficients of `g(w) = f(R^T w)`.
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn rotate(&self, f: &ShCoeffs, rot: &Rotation) -> Result<ShCoeffs> {
        let z = self.zhf(f)?;
        self.rotate_rzh(&z, rot)
    }

    /// SH coefficients of an RZH expansion whose lobes are rotated by `rot`
    /// (the second half of ZHF Eq. 10: `[Y^R]^T z`).
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn rotate_rzh(&self, z: &RzhCoeffs, rot: &Rotation) -> Result<ShCoeffs> {
        self.check(z.l_max)?;
        let ch = z.channels;
        let l_max = self.l_max();
        let mut out = ShCoeffs::zeros(l_max, ch)?;
        let o = out.data_mut();
        let mut y = vec![0.0; sh_count(l_max)];
        let mut acc = |l0: usize, l1: usize, j: usize, y: &[f64]| {
            // lobe j contributes to bands l0..=l1
            for l in l0..=l1 {
                let p = pi_l(l);
                for i in 0..=2 * l {
                    let yi = p * y[l * l + i];
                    for c in 0..ch {
                        o[(l * l + i) * ch + c] += yi * z.data[(l * l + j) * ch + c];
                    }
                }
            }
        };
        match self.dirs.sharing() {
            Sharing::Shared => {
                for (j, d) in self.dirs.all().iter().enumerate() {
                    self.sh.eval_into(rot.apply(*d), &mut y);
                    acc(j.div_ceil(2), l_max, j, &y);
                }
            }
            Sharing::PerBand => {
                for l in 0..=l_max {
                    for (j, d) in self.dirs.band(l).iter().enumerate() {
                        self.sh.eval_into(rot.apply(*d), &mut y);
                        acc(l, l, j, &y);
                    }
                }
            }
        }
        Ok(out)
    }

    /// Signal-tailored rotation (ZHF Eq. 11): samples the band-`l` expansion of
    /// `f` at the inversely rotated lobe directions `R^T z_l^j` and maps the
    /// samples back with `pi_l (M_l^-1)^T`. Same result as [`Self::rotate`].
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn rotate_tailored(&self, f: &ShCoeffs, rot: &Rotation) -> Result<ShCoeffs> {
        self.check(f.l_max())?;
        let ch = f.channels();
        let l_max = self.l_max();
        let src = f.data();
        let mut y = vec![0.0; sh_count(l_max)];
        // samples s[l^2 + j][c] = f_l(R^T z_l^j)
        let mut s = vec![0.0; src.len()];
        let mut sample_bands = |l0: usize, l1: usize, j: usize, y: &[f64]| {
            for l in l0..=l1 {
                for i in 0..=2 * l {
                    let yi = y[l * l + i];
                    for c in 0..ch {
                        s[(l * l + j) * ch + c] += yi * src[(l * l + i) * ch + c];
                    }
                }
            }
        };
        let rt = rot.transpose();
        match self.dirs.sharing() {
            Sharing::Shared => {
                for (j, d) in self.dirs.all().iter().enumerate() {
                    self.sh.eval_into(rt.apply(*d), &mut y);
                    sample_bands(j.div_ceil(2), l_max, j, &y);
                }
            }
            Sharing::PerBand => {
                for l in 0..=l_max {
                    for (j, d) in self.dirs.band(l).iter().enumerate() {
                        self.sh.eval_into(rt.apply(*d), &mut y);
                        sample_bands(l, l, j, &y);
                    }
                }
            }
        }
        self.tailored_from_samples(&s, ch)
    }

    /// The last step of [`Self::rotate_tailored`] for pre-tabulated band
    /// expansions: `samples[(l^2 + j) * C + c] = f_l(R^T z_l^j)` of channel `c`.
    ///
    /// # Errors
    /// [`SphereError::Length`] when `samples` is not `(L + 1)^2 x C`.
    pub fn tailored_from_samples(&self, samples: &[f64], channels: usize) -> Result<ShCoeffs> {
        let l_max = self.l_max();
        let mut out = ShCoeffs::zeros(l_max, channels)?;
        if samples.len() != sh_count(l_max) * channels {
            return Err(SphereError::Length {
                what: "band samples",
                got: samples.len(),
                expected: sh_count(l_max) * channels,
            });
        }
        let o = out.data_mut();
        for (l, b) in self.bands.iter().enumerate() {
            let n = 2 * l + 1;
            let p = pi_l(l);
            for i in 0..n {
                for c in 0..channels {
                    let mut a = 0.0;
                    for j in 0..n {
                        // (M^-1)^T[i][j] = M^-1[j][i]
                        a += b.minv[j * n + i] * samples[(l * l + j) * channels + c];
                    }
                    o[(l * l + i) * channels + c] = p * a;
                }
            }
        }
        Ok(out)
    }
}

/// `out[i][c] = sum_j a[i][j] x[j][c]` for an `n x n` row-major block.
pub(crate) fn block_mul(a: &[f64], n: usize, x: &[f64], out: &mut [f64], ch: usize) {
    for i in 0..n {
        for c in 0..ch {
            let mut s = 0.0;
            for j in 0..n {
                s += a[i * n + j] * x[j * ch + c];
            }
            out[i * ch + c] = s;
        }
    }
}
