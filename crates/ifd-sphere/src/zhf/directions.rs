//! Direction sets of RZH/ISD bases: per band or shared, chosen at random,
//! by spherical Fibonacci points, or by an optimiser that lowers the
//! condition numbers of the `M_l`.
//!
//! The derivation and conventions are documented on [`DirectionSet`].

use super::{band_matrix, condition_number};
use crate::error::{Result, SphereError, check_degree};
use crate::rng::SplitMix64;
use crate::rotation::Rotation;
use crate::sh::{ShEvaluator, sh_count};

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

/// Normalises `d`, or reports it as [`SphereError::BadDirection`], saying
/// why: a NaN or infinite component, a length that overflows `f64` (finite
/// components of about 1e154 or more), the zero vector, or a length of at
/// most 1e-300 (too short to normalise).
///
/// # Errors
/// For zero-length, too short, too long or non-finite vectors.
pub fn check_direction(index: usize, d: [f64; 3]) -> Result<[f64; 3]> {
    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let reason = if d.iter().any(|v| !v.is_finite()) {
        Some("has a NaN or infinite component")
    } else if !n.is_finite() {
        Some("is too long to normalise: its length overflows float64 (scale it down)")
    } else if d == [0.0; 3] {
        Some("is the zero vector")
    } else if n <= 1e-300 {
        Some("is too short to normalise: its length is below 1e-300 (scale it up)")
    } else {
        None
    };
    if let Some(reason) = reason {
        return Err(SphereError::BadDirection {
            index,
            reason,
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
pub(crate) fn farthest_point_order(points: &[[f64; 3]]) -> Vec<[f64; 3]> {
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
///
/// Per band (`(L + 1)^2` directions, band `l` owns `2l + 1`), or shared across
/// bands (lobe sharing, ZHF Sec. 6): `2L + 1` nested directions, band `l` uses
/// the first `2l + 1`. Choosers: random (seeded), spherical Fibonacci, and an
/// optimiser that lowers the condition numbers of the `M_l`.
///
/// Fibonacci sets take the upper half of a `2n`-point spherical Fibonacci set:
/// a plain `n`-point set is exactly singular for odd bands (its points pair up
/// under a half-turn; the 3-point set is coplanar with the origin), and since
/// band-`l` functions are even or odd, a set on one hemisphere loses nothing
/// (`w` and `-w` give the same row of `M_l` up to sign). Shared sets are then
/// reordered greedily, farthest point (in `|w . w'|`) first, so every prefix
/// is well spread.
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
    /// use ifd_sphere::DirectionSet;
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
    /// use ifd_sphere::{Chooser, DirectionSet, Sharing};
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
                    reason: "is not a unit vector (to 1e-6)",
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
    /// use ifd_sphere::{Chooser, DirectionSet, Sharing};
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
