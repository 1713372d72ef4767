//! The sparsity search of the ZHF paper (Sec. 5-6, its Table I and Fig. 3):
//! lobe directions that make the factorisation matrix `A_l = Y_l^-1` sparse,
//! so that each SH basis function is a sum of few rotated zonal lobes.
//!
//! # The search
//! `Y_l` is `(2l + 1)^2`, `(Y_l)_{j m} = y_l^m(w_j)` for the band's lobe
//! directions `w_j`; a zero of `A_l = Y_l^-1` (`|a| < 1e-9`, as the paper)
//! is a lobe that SH function does not need. Following the paper, directions
//! are drawn from a discrete candidate set: polar angles at the zeros of the
//! associated Legendre functions `P_k^m(cos theta)` of bands `1..=l` (and the
//! pole), azimuths at the zeros of `cos(m phi)` and `sin(m phi)`, `m =
//! 1..=l` (multiples of `pi / 2m`). An individual is one candidate angle pair
//! per lobe; its fitness is the fraction of zeros in `A_l`, or minus infinity
//! for a singular or ill-conditioned `Y_l` (1-norm condition number above
//! `1e8`). A genetic algorithm searches: tournament selection, uniform
//! crossover for 80% of the children, mutation of each gene with probability
//! `1 / v` (`v` genes), elitism 2, stopped after `stall` generations without
//! improvement, the best of several seeded runs (the paper: population 500,
//! 50 stall generations; ours: [`SearchOptions::default`]).
//!
//! **Shared lobes** (Sec. 6): `2N - 1` nested directions for an order-`N`
//! expansion, band `k` using the first `2k + 1`; the fitness is the zeros of
//! all `A_k`, `k = 1..N-1`, over their total size (band 0's single entry is
//! never zero and is left out).

use nalgebra::DMatrix;

use ifd_sphere::ShEvaluator;
use ifd_sphere::SplitMix64;
use ifd_sphere::{Result, SphereError};

/// Entries below this magnitude count as zeros (the paper's epsilon).
pub const ZERO: f64 = 1e-9;
/// Largest accepted 1-norm condition number of `Y_l`.
pub const COND_LIMIT: f64 = 1e8;

/// The paper's per-band sparsity (Table I, percent of zero entries of `A_l`),
/// for `l = 2..=18`.
pub const PAPER_TABLE_I: [f64; 17] = [
    64.0, 67.0, 62.0, 53.0, 49.0, 46.0, 42.0, 39.0, 38.0, 38.0, 37.0, 37.0, 36.0, 36.0, 36.0, 35.0,
    35.0,
];

/// Candidate angles for lobes of bands up to `l`.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidates {
    /// Polar angles in `[0, pi)`.
    pub theta: Vec<f64>,
    /// Azimuths in `[0, 2 pi)`.
    pub phi: Vec<f64>,
}

/// Sorted, without duplicates closer than `1e-9`.
fn dedup(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    v.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    v
}

/// `P_k^m(cos theta) / sin^m(theta)` (the polynomial part of the associated
/// Legendre function, up to a constant), by the stable recurrence in `k`.
fn alp_poly(k: usize, m: usize, t: f64) -> f64 {
    // P_m^m / sin^m = (-1)^m (2m - 1)!!; the constant does not move zeros
    let mut p0 = 1.0;
    if k == m {
        return p0;
    }
    let mut p1 = t * (2 * m + 1) as f64 * p0;
    for n in m + 2..=k {
        let nf = n as f64;
        let mf = m as f64;
        let p = ((2.0 * nf - 1.0) * t * p1 - (nf + mf - 1.0) * p0) / (nf - mf);
        p0 = p1;
        p1 = p;
    }
    p1
}

/// The candidate set of bands `1..=l` (module docs).
#[must_use]
pub fn candidates(l: usize) -> Candidates {
    let mut theta = vec![0.0];
    let grid = 4096;
    for k in 1..=l {
        for m in 0..=k {
            // zeros of the polynomial part in t = cos(theta) in (-1, 1)
            let f = |th: f64| alp_poly(k, m, th.cos());
            let mut prev = f(1e-9);
            for i in 1..=grid {
                let th = std::f64::consts::PI * i as f64 / grid as f64
                    - 1e-9 * f64::from(u8::from(i == grid));
                let cur = f(th);
                if prev == 0.0 || prev.signum() != cur.signum() {
                    let (mut a, mut b) = (std::f64::consts::PI * (i - 1) as f64 / grid as f64, th);
                    for _ in 0..80 {
                        let c = 0.5 * (a + b);
                        if f(a).signum() == f(c).signum() {
                            a = c;
                        } else {
                            b = c;
                        }
                    }
                    theta.push(0.5 * (a + b));
                }
                prev = cur;
            }
        }
    }
    let mut phi = vec![0.0];
    for m in 1..=l {
        for j in 0..4 * m {
            phi.push(std::f64::consts::PI * j as f64 / (2 * m) as f64);
        }
    }
    Candidates {
        theta: dedup(theta),
        phi: dedup(phi),
    }
}

/// Search settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SearchOptions {
    /// Individuals per generation.
    pub population: usize,
    /// Largest number of generations.
    pub generations: usize,
    /// Stop after this many generations without improvement.
    pub stall: usize,
    /// Seed of the first run.
    pub seed: u64,
    /// Independent runs (seeds `seed..seed + restarts`, in parallel); the best wins.
    pub restarts: usize,
}

impl Default for SearchOptions {
    /// Population 100, up to 20000 generations, 1000 stall generations, 4
    /// restarts: the landscape has long plateaus, and a small population
    /// searched long beats the paper's 500 with 50 stall generations (band 3:
    /// 67.3% against 63%; band 7: 44% after 1500 stall generations, 10% after
    /// 200).
    fn default() -> Self {
        Self {
            population: 100,
            generations: 20000,
            stall: 1000,
            seed: 1,
            restarts: 4,
        }
    }
}

/// What a search found.
#[derive(Clone, Debug, PartialEq)]
pub struct Found {
    /// Fraction of zero entries (all bands of a shared set together).
    pub sparsity: f64,
    /// Per band `1..`: its own fraction of zeros (one value for a band search).
    pub per_band: Vec<f64>,
    /// The lobe directions.
    pub directions: Vec<[f64; 3]>,
    /// For a single band: how many lobes each SH function `m = -l..=l` uses
    /// (the paper's Table I rows).
    pub lobes_per_function: Vec<usize>,
    /// The largest `|Y A - I|` of the found factorisation (exactness).
    pub residual: f64,
    /// Fitness evaluations spent.
    pub evaluations: usize,
    /// Generations run.
    pub generations: usize,
}

/// The band-`l` factorisation of `dirs[..2l+1]`: `A_l = Y_l^-1` and its
/// residual, `None` when `Y_l` is singular or ill-conditioned.
fn factor(
    sh: &ShEvaluator,
    l: usize,
    dirs: &[[f64; 3]],
    scratch: &mut [f64],
) -> Option<(DMatrix<f64>, f64)> {
    let n = 2 * l + 1;
    let mut y = DMatrix::zeros(n, n);
    let mut row = vec![0.0; n];
    for (j, d) in dirs[..n].iter().enumerate() {
        sh.eval_band_into(l, *d, scratch, &mut row);
        for m in 0..n {
            y[(j, m)] = row[m];
        }
    }
    let a = y.clone().try_inverse()?;
    let norm1 = |m: &DMatrix<f64>| {
        (0..m.ncols())
            .map(|c| m.column(c).iter().map(|x| x.abs()).sum::<f64>())
            .fold(0.0, f64::max)
    };
    let cond = norm1(&y) * norm1(&a);
    if !cond.is_finite() || cond > COND_LIMIT {
        return None;
    }
    let r = (&y * &a - DMatrix::identity(n, n)).amax();
    Some((a, r))
}

fn zeros(a: &DMatrix<f64>) -> usize {
    a.iter().filter(|x| x.abs() < ZERO).count()
}

/// Fitness of a genome (pairs of candidate indices) for bands `bands`:
/// `(zeros / entries, per band, largest residual)`, `None` if any band is
/// singular.
fn fitness(
    sh: &ShEvaluator,
    cand: &Candidates,
    genome: &[(u16, u16)],
    bands: std::ops::RangeInclusive<usize>,
    scratch: &mut [f64],
) -> Option<(f64, Vec<f64>, f64)> {
    let dirs: Vec<[f64; 3]> = genome
        .iter()
        .map(|&(t, p)| ifd_sphere::direction(cand.theta[t as usize], cand.phi[p as usize]))
        .collect();
    let (mut z, mut total, mut res) = (0, 0, 0.0f64);
    let mut per = Vec::new();
    for l in bands {
        let (a, r) = factor(sh, l, &dirs, scratch)?;
        let zl = zeros(&a);
        per.push(zl as f64 / a.len() as f64);
        z += zl;
        total += a.len();
        res = res.max(r);
    }
    Some((z as f64 / total as f64, per, res))
}

/// A scored genome.
type Scored = (f64, Vec<(u16, u16)>);

/// [`evolve_once`] from `opts.restarts` seeds in parallel; the sparsest wins
/// (ties: the lower seed), evaluations summed.
fn evolve(
    l_max: usize,
    lobes: usize,
    bands: std::ops::RangeInclusive<usize>,
    opts: SearchOptions,
) -> Result<Found> {
    use rayon::prelude::*;
    let runs: Vec<Result<Found>> = (0..opts.restarts.max(1) as u64)
        .into_par_iter()
        .map(|k| {
            evolve_once(
                l_max,
                lobes,
                bands.clone(),
                SearchOptions {
                    seed: opts.seed.wrapping_add(k),
                    ..opts
                },
            )
        })
        .collect();
    let mut best: Option<Found> = None;
    let mut evaluations = 0;
    for r in runs {
        let f = r?;
        evaluations += f.evaluations;
        if best.as_ref().is_none_or(|b| f.sparsity > b.sparsity) {
            best = Some(f);
        }
    }
    let mut best = best.ok_or_else(|| SphereError::Parameter {
        name: "search",
        value: "0 runs".into(),
        reason: "needs a run",
    })?;
    best.evaluations = evaluations;
    Ok(best)
}

/// The genetic search over genomes of `lobes` lobes whose fitness covers
/// `bands`, one seed.
fn evolve_once(
    l_max: usize,
    lobes: usize,
    bands: std::ops::RangeInclusive<usize>,
    opts: SearchOptions,
) -> Result<Found> {
    if opts.population < 4 || opts.generations == 0 {
        return Err(SphereError::Parameter {
            name: "search",
            value: format!(
                "population {}, generations {}",
                opts.population, opts.generations
            ),
            reason: "needs a population of at least 4 and one generation",
        });
    }
    let cand = candidates(l_max);
    let sh = ShEvaluator::new(l_max)?;
    let mut scratch = vec![0.0; (l_max + 1) * (l_max + 1)];
    let mut rng = SplitMix64::new(opts.seed);
    let (nt, np) = (cand.theta.len(), cand.phi.len());
    let pick = |rng: &mut SplitMix64| {
        (
            (rng.next_u64() % nt as u64) as u16,
            (rng.next_u64() % np as u64) as u16,
        )
    };
    let mut evaluations = 0usize;
    let mut score = |g: &[(u16, u16)], evaluations: &mut usize| -> f64 {
        *evaluations += 1;
        fitness(&sh, &cand, g, bands.clone(), &mut scratch).map_or(f64::NEG_INFINITY, |f| f.0)
    };
    let mut pop: Vec<Scored> = (0..opts.population)
        .map(|_| {
            let g: Vec<(u16, u16)> = (0..lobes).map(|_| pick(&mut rng)).collect();
            (score(&g, &mut evaluations), g)
        })
        .collect();
    let genes = 2 * lobes;
    let (mut best, mut stall, mut gens) = (f64::NEG_INFINITY, 0, 0);
    for _ in 0..opts.generations {
        gens += 1;
        pop.sort_by(|a, b| b.0.total_cmp(&a.0));
        if pop[0].0 > best + 1e-12 {
            best = pop[0].0;
            stall = 0;
        } else {
            stall += 1;
            if stall >= opts.stall {
                break;
            }
        }
        let tournament = |rng: &mut SplitMix64, pop: &[Scored]| -> usize {
            let a = (rng.next_u64() % pop.len() as u64) as usize;
            let b = (rng.next_u64() % pop.len() as u64) as usize;
            if pop[a].0 >= pop[b].0 { a } else { b }
        };
        let mut next: Vec<Scored> = pop[..2].to_vec();
        while next.len() < opts.population {
            let pa = tournament(&mut rng, &pop);
            let mut child = pop[pa].1.clone();
            if rng.uniform() < 0.8 {
                let pb = tournament(&mut rng, &pop);
                for (c, o) in child.iter_mut().zip(&pop[pb].1) {
                    if rng.uniform() < 0.5 {
                        c.0 = o.0;
                    }
                    if rng.uniform() < 0.5 {
                        c.1 = o.1;
                    }
                }
            }
            for c in &mut child {
                if rng.uniform() < 1.0 / genes as f64 {
                    c.0 = pick(&mut rng).0;
                }
                if rng.uniform() < 1.0 / genes as f64 {
                    c.1 = pick(&mut rng).1;
                }
            }
            let f = score(&child, &mut evaluations);
            next.push((f, child));
        }
        pop = next;
    }
    pop.sort_by(|a, b| b.0.total_cmp(&a.0));
    let g = &pop[0].1;
    let Some((sparsity, per_band, residual)) = fitness(&sh, &cand, g, bands.clone(), &mut scratch)
    else {
        return Err(SphereError::Parameter {
            name: "search",
            value: format!("bands {bands:?}"),
            reason: "found no non-singular set: raise the population or generations",
        });
    };
    let directions: Vec<[f64; 3]> = g
        .iter()
        .map(|&(t, p)| ifd_sphere::direction(cand.theta[t as usize], cand.phi[p as usize]))
        .collect();
    let lobes_per_function = if bands.start() == bands.end() {
        let l = *bands.start();
        let (a, _) =
            factor(&sh, l, &directions, &mut scratch).ok_or_else(|| SphereError::Parameter {
                name: "search",
                value: l.to_string(),
                reason: "singular",
            })?;
        (0..a.nrows())
            .map(|m| a.row(m).iter().filter(|x| x.abs() >= ZERO).count())
            .collect()
    } else {
        Vec::new()
    };
    Ok(Found {
        sparsity,
        per_band,
        directions,
        lobes_per_function,
        residual,
        evaluations,
        generations: gens,
    })
}

/// The sparsest band-`l` factorisation the search finds (`l >= 1`): the
/// better of a search on band `l` alone and of band `l` within a shared
/// search of order `l + 1` (whose `2l + 1` directions are a band-`l` set
/// too). Searched alone, bands from 8 on stall near 10% (one sparse function,
/// the others dense: a plateau the mutations do not leave); the shared
/// fitness, which rewards every band's zeros, climbs to 40-45% there.
///
/// # Errors
/// [`SphereError::Parameter`] for `l = 0`, `l > 30` or bad settings.
pub fn search_band(l: usize, opts: SearchOptions) -> Result<Found> {
    if l == 0 || l > 30 {
        return Err(SphereError::Parameter {
            name: "band",
            value: l.to_string(),
            reason: "search bands 1..=30",
        });
    }
    let alone = evolve(l, 2 * l + 1, l..=l, opts)?;
    if l == 1 {
        return Ok(alone);
    }
    let shared = evolve(l, 2 * l + 1, 1..=l, opts)?;
    let sh = ShEvaluator::new(l)?;
    let mut scratch = vec![0.0; (l + 1) * (l + 1)];
    let (a, residual) =
        factor(&sh, l, &shared.directions, &mut scratch).ok_or(SphereError::Parameter {
            name: "search",
            value: String::new(),
            reason: "singular shared set",
        })?;
    let sparsity = zeros(&a) as f64 / a.len() as f64;
    let evaluations = alone.evaluations + shared.evaluations;
    let mut best = if sparsity > alone.sparsity {
        Found {
            sparsity,
            per_band: vec![sparsity],
            lobes_per_function: (0..a.nrows())
                .map(|m| a.row(m).iter().filter(|x| x.abs() >= ZERO).count())
                .collect(),
            residual,
            generations: shared.generations,
            ..shared
        }
    } else {
        alone
    };
    best.evaluations = evaluations;
    Ok(best)
}

/// The sparsest shared (nested) set of `2N - 1` directions for order `N`
/// (bands `1..N-1`; `N >= 2`).
///
/// # Errors
/// As [`search_band`] for `N - 1`.
pub fn search_shared(order: usize, opts: SearchOptions) -> Result<Found> {
    if !(2..=31).contains(&order) {
        return Err(SphereError::Parameter {
            name: "order",
            value: order.to_string(),
            reason: "search orders 2..=31",
        });
    }
    evolve(order - 1, 2 * order - 1, 1..=order - 1, opts)
}

/// Fig. 3's baseline: the mean and largest sparsity of `samples` random
/// genomes over the same candidates (shared, order `N`), singular ones left
/// out, and how many were singular.
///
/// # Errors
/// As [`search_shared`].
pub fn random_shared(order: usize, samples: usize, seed: u64) -> Result<(f64, f64, usize)> {
    if !(2..=31).contains(&order) {
        return Err(SphereError::Parameter {
            name: "order",
            value: order.to_string(),
            reason: "orders 2..=31",
        });
    }
    let l_max = order - 1;
    let cand = candidates(l_max);
    let sh = ShEvaluator::new(l_max)?;
    let mut scratch = vec![0.0; (l_max + 1) * (l_max + 1)];
    let mut rng = SplitMix64::new(seed);
    let (mut sum, mut max, mut n, mut singular) = (0.0, 0.0f64, 0usize, 0usize);
    for _ in 0..samples {
        let g: Vec<(u16, u16)> = (0..2 * order - 1)
            .map(|_| {
                (
                    (rng.next_u64() % cand.theta.len() as u64) as u16,
                    (rng.next_u64() % cand.phi.len() as u64) as u16,
                )
            })
            .collect();
        match fitness(&sh, &cand, &g, 1..=l_max, &mut scratch) {
            Some((s, _, _)) => {
                sum += s;
                max = max.max(s);
                n += 1;
            }
            None => singular += 1,
        }
    }
    Ok((if n > 0 { sum / n as f64 } else { f64::NAN }, max, singular))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The candidates zero the functions they come from.
    #[test]
    fn candidates_are_zeros() {
        let c = candidates(4);
        let sh = ShEvaluator::new(4).unwrap();
        // every interior theta zeroes some P_k^m, k <= 4
        for &t in c.theta.iter().filter(|t| **t > 1e-6) {
            let z = (1..=4).any(|k| (0..=k).any(|m| alp_poly(k, m, t.cos()).abs() < 1e-9));
            assert!(z, "theta {t}");
        }
        assert!(
            c.phi
                .iter()
                .all(|p| (0.0..std::f64::consts::TAU).contains(p))
        );
        assert!(!sh.eval([0.0, 0.0, 1.0]).is_empty());
    }

    /// Bands 2 and 3 reach the paper's Table I sparsity (64%, 67%), exactly
    /// factorised.
    #[test]
    fn small_bands_reach_the_paper() {
        let opts = SearchOptions {
            population: 100,
            generations: 2000,
            stall: 200,
            seed: 1,
            restarts: 8,
        };
        for (l, paper) in [(2, 64.0), (3, 67.0)] {
            let f = search_band(l, opts).unwrap();
            assert!(100.0 * f.sparsity >= paper - 0.5, "l = {l}: {}", f.sparsity);
            assert!(f.residual < 1e-9, "{}", f.residual);
            assert_eq!(f.lobes_per_function.len(), 2 * l + 1);
        }
    }
}
