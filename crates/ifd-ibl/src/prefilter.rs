//! Prefiltering an environment map with zonal lobes, in frequency space
//! with the brightest texels summed exactly.
//!
//! The derivation and conventions are documented on [`Baker`].

use std::f64::consts::PI;

use glam::DVec3;
use ifd_image::Image;
use ifd_sphere::{EquirectTransform, Negatives, ShCoeffs};
use rayon::prelude::*;

use crate::cube::{CubeLevel, equirect_coords, face_texel, sample_bicubic, world_to_ifd};
use crate::direct::{Cell, CellLanes, DirectRow, Sample};
use crate::error::{Result, param};
use crate::lobe::{Lobe, band_limit_of};

/// Tuning of [`Baker`]; the defaults are what `ifd envmap prefilter` uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeOptions {
    /// Band truncation: each lobe keeps the fewest bands whose dropped part
    /// carries at most `eps^2` of its filtered residual's energy (a relative
    /// RMS truncation error of `eps`, measured on the map's own spectrum);
    /// the map is projected to the highest degree with `|lambda_l| >= eps`
    /// of any lobe.
    pub eps: f64,
    /// Texels brighter than `T = bright_factor x` the mean of the map clamped
    /// at `T` (max channel, solid-angle weighted) are summed directly.
    pub bright_factor: f64,
    /// At most this many texels are summed directly (the threshold rises).
    pub max_bright: usize,
    /// The highest SH degree any lobe may use.
    pub max_degree: usize,
}

impl Default for BakeOptions {
    fn default() -> Self {
        Self {
            eps: 1e-3,
            bright_factor: 16.0,
            max_bright: 2048,
            max_degree: 512,
        }
    }
}

/// What one prefiltered level took.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelStats {
    /// The lobe.
    pub lobe: Lobe,
    /// SH degree of the frequency part (0 for the mirror).
    pub l_max: usize,
    /// Whether the band limit hit [`BakeOptions::max_degree`].
    pub capped: bool,
    /// Directly summed sub-texel samples of the bright texels.
    pub bright_samples: usize,
    /// Output values below zero, set to zero.
    pub negatives_clamped: usize,
}

/// A bright texel: position and excess.
#[derive(Clone, Copy, Debug)]
struct Bright {
    u: usize,
    v: usize,
    excess: [f64; 3],
}

/// An environment map ready to be prefiltered with any number of lobes.
///
/// ```
/// use ifd_ibl::{Baker, BakeOptions, Lobe};
/// // a constant map stays constant under every normalised lobe (white furnace)
/// let env = ifd_image::Image::from_vec(32, 16, 3, vec![0.5; 32 * 16 * 3])?;
/// let lobes = [Lobe::Ggx { alpha: 0.3 }, Lobe::Lambert];
/// let baker = Baker::new(&env, &BakeOptions::default(), &lobes)?;
/// let (level, _) = baker.level(&lobes[0], 8)?;
/// assert!(level.data.iter().all(|v| (v - 0.5).abs() < 1e-5));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Method
/// The source is read, as the accuracy oracle reads it, as **piecewise
/// constant** over its equirectangular texels. It is split into
///
/// - a **residual**, every channel clamped at a threshold `T`, and
/// - the **excess** `E - min(E, T)` of the few texels brighter than `T`
///   (the sun: `T = bright_factor x` the mean of the map clamped at `T`, the
///   fixed point reached from `bright_factor x` the plain mean, so that a
///   texel dominating the mean cannot hide itself; raised so that at most
///   `max_bright` texels exceed it).
///
/// The residual is projected on SH exactly for piecewise-constant texels
/// ([`EquirectTransform::analyze_texels`], `O(H W log W + n H L^2)`), each
/// lobe's bands are scaled by `lambda_l` ([`Lobe::zonal`]) up to a degree
/// `L` chosen per lobe from the residual's own band powers `P_l`: the
/// smallest `L` with `sum_{l > L} lambda_l^2 P_l <= eps^2 sum_l lambda_l^2
/// P_l`, the sums over every band the analysis holds (by Parseval a
/// relative RMS truncation error of at most `eps`; the analysis runs to the
/// highest degree with `|lambda_l| >= eps` of any lobe), and the result is
/// synthesised on an equirectangular grid (`H_s = max(2 N, 2 L + 2)` rows
/// for `N`-texel faces, at least two rows per output texel and per half
/// wavelength of the top band) and read at every cube texel with
/// Catmull-Rom interpolation. Because the fast transforms make the frequency side cost
/// `O(H L^2)` rather than the `O(pixels L^2)` of the SHRM paper's direct
/// sums, it is cheaper than an angular sum for every lobe with `alpha > 0`
/// at the sizes engines use (see `docs/ibl.md` for the cost model).
///
/// The excess is summed directly: `sum_b e_b int_texel k(r . l) dl / K`, each
/// bright texel split into `n x n` sub-texels when the lobe is narrower than a
/// few texels. Bright texels are grouped in cells of `4 x 4` texels; a cell
/// seen from further than `16` cell radii (and beyond twice the lobe width)
/// contributes through its total at its weighted centroid (the dipole term
/// vanishes there; the relative error of that far tail is below about
/// `(k''/k) rho^2 / 2`, a few percent of a contribution that is itself a
/// small part of the texel). This keeps a truncated SH expansion of a sun
/// from ringing: the residual is bounded by `T`, so its ringing is bounded by
/// `eps`-sized multiples of `T`. Texels still negative after that are set to
/// 0 and counted.
///
/// [`Lobe::Mirror`] (roughness 0) is the source itself: the texel hit by
/// each output texel's centre direction (the exact delta-lobe answer for a
/// piecewise-constant source) while the output texels are at least as large
/// as about half a source texel (`H <= 2 N`); for a source much denser than
/// the faces, a box filter over each output texel instead (`k x k`
/// nearest-texel samples weighted by the cube's solid-angle density,
/// `k = ceil(2 H / N)` up to 16), so that mip 0 does not alias.
#[derive(Debug)]
pub struct Baker {
    source: Image,
    coeffs: ShCoeffs,
    /// Band powers `sum_m,c R_lm,c^2` of the residual.
    power: Vec<f64>,
    bright: Vec<Bright>,
    threshold: f64,
    mean: f64,
    opts: BakeOptions,
    input_negatives: usize,
}

impl Baker {
    /// Validates and splits the map (2:1 equirectangular, RGB or more
    /// channels; the first three are used) and projects its residual to the
    /// highest band limit any of `lobes` needs.
    ///
    /// # Errors
    /// A map that is not 2:1, has fewer than 3 channels, or holds NaN/Inf
    /// samples; options out of range.
    pub fn new(env: &Image, opts: &BakeOptions, lobes: &[Lobe]) -> Result<Self> {
        let (w, h) = (env.width(), env.height());
        if h < 2 || w != 2 * h {
            return Err(param(
                "environment map",
                format!("must be 2:1 equirectangular (W = 2H); got {w}x{h}"),
            ));
        }
        if env.channels() < 3 {
            return Err(param(
                "environment map",
                format!("needs RGB; got {} channel(s)", env.channels()),
            ));
        }
        if !(opts.eps > 0.0 && opts.eps < 1.0) {
            return Err(param("--eps", format!("{} is outside (0, 1)", opts.eps)));
        }
        if !(opts.bright_factor.is_finite() && opts.bright_factor >= 1.0) {
            return Err(param(
                "bright factor",
                format!("{} must be a finite number >= 1", opts.bright_factor),
            ));
        }
        let ch = env.channels();
        // RGB, negatives clamped (radiance is never negative), NaN rejected
        let mut rgb = Vec::with_capacity(w * h * 3);
        let mut input_negatives = 0;
        for (k, px) in env.data().chunks_exact(ch).enumerate() {
            for &v in &px[..3] {
                if !v.is_finite() {
                    return Err(param(
                        "environment map",
                        format!("sample {v} at texel ({}, {}) is not finite", k % w, k / w),
                    ));
                }
                if v < 0.0 {
                    input_negatives += 1;
                }
                rgb.push(v.max(0.0));
            }
        }
        let source = Image::from_vec(w, h, 3, rgb)?;
        let t = EquirectTransform::new(0, w, h)?;
        // the threshold: bright_factor x the mean of the map clamped at the
        // threshold itself (a fixed point, reached from above: a single
        // texel that dominates the plain mean must not hide itself), then
        // raised to keep at most max_bright texels
        let data = source.data();
        let maxc: Vec<f32> = data
            .chunks_exact(3)
            .map(|p| p[0].max(p[1]).max(p[2]))
            .collect();
        let clamped_mean = |cap: f64| {
            let mut m = 0.0;
            for v in 0..h {
                let da = t.pixel_solid_angle(v);
                let row: f64 = maxc[v * w..(v + 1) * w]
                    .iter()
                    .map(|x| f64::from(*x).min(cap))
                    .sum();
                m += da * row;
            }
            m / (4.0 * PI)
        };
        let mean = clamped_mean(f64::INFINITY);
        let mut threshold = opts.bright_factor * mean;
        for _ in 0..32 {
            let next = opts.bright_factor * clamped_mean(threshold);
            if next >= threshold * (1.0 - 1e-6) {
                break;
            }
            threshold = next;
        }
        let above = maxc.iter().filter(|&&m| f64::from(m) > threshold).count();
        if above > opts.max_bright {
            let mut sorted = maxc.clone();
            let k = sorted.len() - 1 - opts.max_bright;
            let (_, kth, _) = sorted.select_nth_unstable_by(k, f32::total_cmp);
            threshold = f64::from(*kth);
        }
        let mut residual = source.clone();
        let mut bright = Vec::new();
        if mean > 0.0 {
            let tf = threshold as f32;
            for (k, px) in residual.data_mut().chunks_exact_mut(3).enumerate() {
                if maxc[k] > tf {
                    let mut excess = [0.0; 3];
                    for c in 0..3 {
                        excess[c] = f64::from((px[c] - tf).max(0.0));
                        px[c] = px[c].min(tf);
                    }
                    bright.push(Bright {
                        u: k % w,
                        v: k / w,
                        excess,
                    });
                }
            }
        }
        let cap = opts.max_degree.min(ifd_sphere::MAX_DEGREE);
        let l_max = lobes
            .iter()
            .filter(|l| **l != Lobe::Mirror)
            .map(|l| l.band_limit(opts.eps, cap).0)
            .max()
            .unwrap_or(0);
        let coeffs = EquirectTransform::new(l_max, w, h)?
            .analyze_texels(&residual, Negatives::Keep)?
            .coeffs;
        let power = (0..=l_max)
            .map(|l| {
                coeffs.data()[l * l * 3..(l + 1) * (l + 1) * 3]
                    .iter()
                    .map(|v| v * v)
                    .sum()
            })
            .collect();
        Ok(Self {
            source,
            coeffs,
            power,
            bright,
            threshold,
            mean,
            opts: *opts,
            input_negatives,
        })
    }

    /// Negative input samples (clamped to zero).
    #[must_use]
    pub fn input_negatives(&self) -> usize {
        self.input_negatives
    }

    /// How many texels are summed directly, and the threshold.
    #[must_use]
    pub fn bright_texels(&self) -> (usize, f64) {
        (self.bright.len(), self.threshold)
    }

    /// The source (RGB, negatives clamped).
    #[must_use]
    pub fn source(&self) -> &Image {
        &self.source
    }

    /// SH coefficients of the whole source (not just the residual) up to
    /// `l_max`, exact for piecewise-constant texels, in ifd's frame.
    ///
    /// # Errors
    /// As [`EquirectTransform::analyze_texels`].
    pub fn source_sh(&self, l_max: usize) -> Result<ShCoeffs> {
        let (w, h) = (self.source.width(), self.source.height());
        Ok(EquirectTransform::new(l_max, w, h)?
            .analyze_texels(&self.source, Negatives::Keep)?
            .coeffs)
    }

    /// The map prefiltered with `lobe` on an `n`-texel cube.
    ///
    /// # Errors
    /// A lobe needing more bands than [`Baker::new`] projected; allocation.
    pub fn level(&self, lobe: &Lobe, n: usize) -> Result<(CubeLevel, LevelStats)> {
        if n == 0 {
            return Err(param("face size", "must be at least 1"));
        }
        if *lobe == Lobe::Mirror {
            return Ok((
                self.mirror(n),
                LevelStats {
                    lobe: *lobe,
                    l_max: 0,
                    capped: false,
                    bright_samples: 0,
                    negatives_clamped: 0,
                },
            ));
        }
        // one quadrature of the lobe serves the band limit, the degree, the
        // band factors and the normalisation
        let cap = self.opts.max_degree.min(ifd_sphere::MAX_DEGREE);
        let moments = lobe.legendre_moments(cap);
        let lam: Vec<f64> = moments.iter().map(|c| c / moments[0]).collect();
        let (cand, capped) = band_limit_of(&lam, self.opts.eps);
        if cand > self.coeffs.l_max() {
            return Err(param(
                "lobe",
                format!(
                    "{lobe:?} needs degree {cand}, the map was projected to {}",
                    self.coeffs.l_max()
                ),
            ));
        }
        // every band the analysis holds is a candidate (the tail of a broad
        // lobe's lambda_l, from the kink at 90 degrees, decays slowly)
        let l = truncation_degree(&lam, &self.power, self.opts.eps);
        // frequency part: scaled bands, synthesised on a fine equirect grid
        let mut scaled = self.coeffs.resized(l)?;
        for (li, lam_l) in lam[..=l].iter().enumerate() {
            let base = li * li;
            for v in &mut scaled.data_mut()[base * 3..(li + 1) * (li + 1) * 3] {
                *v *= lam_l;
            }
        }
        let hs = (2 * n).max(2 * l + 2).next_multiple_of(4);
        let grid = EquirectTransform::new(l, 2 * hs, hs)?.synthesize(&scaled)?;
        // direct part
        let (samples, cells) = self.bright_samples(lobe);
        // int k = 2 pi c_0
        let k_int = 2.0 * PI * moments[0];
        let mut level = CubeLevel::zeros(n);
        let lanes = CellLanes::new(&cells, &samples);
        let negatives: usize = level
            .data
            .par_chunks_mut(n * 3)
            .enumerate()
            .map_init(
                || (vec![[0.0; 3]; n], vec![[0.0; 3]; n]),
                |(dirs, direct), (row, out)| {
                    let (face, j) = (row / n, row % n);
                    for (i, d) in dirs.iter_mut().enumerate() {
                        *d = world_to_ifd(face_texel(face, i, j, n).0);
                    }
                    ifd_simd::run_vectorized(DirectRow {
                        lobe,
                        lanes: &lanes,
                        dirs,
                        out: direct,
                    });
                    let mut neg = 0;
                    for i in 0..n {
                        let f = sample_bicubic(&grid, dirs[i]);
                        let b = direct[i];
                        for c in 0..3 {
                            let v = f64::from(f[c]) + b[c] / k_int;
                            if v < 0.0 {
                                neg += 1;
                            }
                            out[i * 3 + c] = v.max(0.0) as f32;
                        }
                    }
                    neg
                },
            )
            .sum();
        Ok((
            level,
            LevelStats {
                lobe: *lobe,
                l_max: l,
                capped,
                bright_samples: samples.len(),
                negatives_clamped: negatives,
            },
        ))
    }

    /// The bright texels as sub-texel samples for `lobe`, grouped in cells.
    fn bright_samples(&self, lobe: &Lobe) -> (Vec<Sample>, Vec<Cell>) {
        const CELL: usize = 4;
        let (w, h) = (self.source.width(), self.source.height());
        let (dp, dt) = (2.0 * PI / w as f64, PI / h as f64);
        let sub = ((4.0 * dt / lobe.width()).ceil() as usize).clamp(1, 8);
        let mut keyed: Vec<((usize, usize), Bright)> = self
            .bright
            .iter()
            .map(|b| ((b.v / CELL, b.u / CELL), *b))
            .collect();
        keyed.sort_by_key(|(k, _)| *k);
        let mut samples = Vec::with_capacity(keyed.len() * sub * sub);
        let mut cells = Vec::new();
        let mut start = 0;
        while start < keyed.len() {
            let key = keyed[start].0;
            let end = start + keyed[start..].iter().take_while(|(k, _)| *k == key).count();
            let first = samples.len();
            for (_, b) in &keyed[start..end] {
                for a in 0..sub {
                    let t0 = dt * (b.v as f64 + a as f64 / sub as f64);
                    let t1 = t0 + dt / sub as f64;
                    let tm = 0.5 * (t0 + t1);
                    let sa = (t0.cos() - t1.cos()) * dp / sub as f64;
                    for q in 0..sub {
                        let p = dp * (b.u as f64 + (q as f64 + 0.5) / sub as f64);
                        let d = [tm.sin() * p.cos(), tm.sin() * p.sin(), tm.cos()];
                        samples.push(Sample {
                            d,
                            w: [b.excess[0] * sa, b.excess[1] * sa, b.excess[2] * sa],
                        });
                    }
                }
            }
            // the cell: weighted centroid, bounding radius, total
            let cs = &samples[first..];
            let mut centre = [0.0; 3];
            let mut total = [0.0; 3];
            for s in cs {
                let wt = s.w[0] + s.w[1] + s.w[2];
                for k in 0..3 {
                    centre[k] += wt * s.d[k];
                    total[k] += s.w[k];
                }
            }
            let r = (centre[0] * centre[0] + centre[1] * centre[1] + centre[2] * centre[2]).sqrt();
            let centre = if r > 0.0 {
                [centre[0] / r, centre[1] / r, centre[2] / r]
            } else {
                cs[0].d
            };
            let radius = cs
                .iter()
                .map(|s| angle(DVec3::from(s.d).dot(DVec3::from(centre))))
                .fold(0.0, f64::max)
                + 0.5 * dp.max(dt);
            let far = (16.0 * radius).max(2.0 * lobe.width());
            cells.push(Cell {
                centre,
                total,
                samples: first..samples.len(),
                cos_behind: if radius < 0.5 * PI {
                    -radius.sin()
                } else {
                    -2.0
                },
                cos_far: if far < PI { far.cos() } else { -2.0 },
            });
            start = end;
        }
        (samples, cells)
    }

    /// Roughness 0: the source point-sampled, or box-filtered when much denser.
    fn mirror(&self, n: usize) -> CubeLevel {
        let (w, h) = (self.source.width(), self.source.height());
        let k = if h <= 2 * n {
            1
        } else {
            (2 * h).div_ceil(n).min(16)
        };
        let data = self.source.data();
        let mut level = CubeLevel::zeros(n);
        level
            .data
            .par_chunks_mut(n * 3)
            .enumerate()
            .for_each(|(row, out)| {
                let (face, j) = (row / n, row % n);
                for i in 0..n {
                    let mut acc = [0.0f64; 3];
                    let mut wsum = 0.0;
                    for a in 0..k {
                        for b in 0..k {
                            // sub-texel centre in face coordinates
                            let fi = i as f64 + (b as f64 + 0.5) / k as f64 - 0.5;
                            let fj = j as f64 + (a as f64 + 0.5) / k as f64 - 0.5;
                            let d = face_direction(face, fi, fj, n);
                            // solid angle density of the cube parametrisation
                            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                            let wt = 1.0 / (r2 * r2.sqrt());
                            let (u, v) = equirect_coords(world_to_ifd(d), w, h);
                            let uu = (u as usize).min(w - 1);
                            let vv = (v as usize).min(h - 1);
                            let px = &data[(vv * w + uu) * 3..][..3];
                            for c in 0..3 {
                                acc[c] += wt * f64::from(px[c]);
                            }
                            wsum += wt;
                        }
                    }
                    for c in 0..3 {
                        out[i * 3 + c] = (acc[c] / wsum) as f32;
                    }
                }
            });
        level
    }

    /// Mean radiance (max channel, solid-angle weighted).
    #[must_use]
    pub fn mean(&self) -> f64 {
        self.mean
    }
}

/// Unnormalised direction of continuous texel position `(fi, fj)` (texel
/// centres at integers) of a face: the OpenGL table of [`crate::cube`].
fn face_direction(face: usize, fi: f64, fj: f64, n: usize) -> [f64; 3] {
    let nf = n as f64;
    ifd_sphere::cube_face_direction(
        face,
        2.0 * (fi + 0.5) / nf - 1.0,
        2.0 * (fj + 0.5) / nf - 1.0,
    )
}

/// The smallest `L` whose dropped bands carry at most `tol^2` of the
/// filtered residual's energy: `sum_{l > L} lambda_l^2 P_l <= tol^2 sum_l
/// lambda_l^2 P_l` (Parseval: the relative RMS error over the sphere of the
/// truncated expansion is at most `tol`), over the bands the analysis holds.
fn truncation_degree(lam: &[f64], power: &[f64], tol: f64) -> usize {
    let n = lam.len().min(power.len());
    let e: Vec<f64> = (0..n).map(|l| lam[l] * lam[l] * power[l]).collect();
    let total: f64 = e.iter().sum();
    let budget = tol * tol * total;
    let mut tail = 0.0;
    for l in (0..n).rev() {
        tail += e[l];
        if tail > budget {
            return l;
        }
    }
    0
}

fn angle(c: f64) -> f64 {
    c.clamp(-1.0, 1.0).acos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_dominating_texel_is_summed_directly_and_nothing_rings() {
        // a texel so bright that it dominates the map's plain mean: the
        // threshold must still fall to the level of the rest of the map
        let (w, h) = (64, 32);
        let mut data = vec![1.0f32; w * h * 3];
        for c in 0..3 {
            data[(5 * w + 7) * 3 + c] = 1e30;
        }
        let env = Image::from_vec(w, h, 3, data).expect("map");
        let lobes = [Lobe::Ggx { alpha: 0.1 }, Lobe::Lambert];
        let baker = Baker::new(&env, &BakeOptions::default(), &lobes).expect("baker");
        let (n, t) = baker.bright_texels();
        assert_eq!(n, 1);
        assert!(t < 20.0, "threshold {t}");
        for lobe in &lobes {
            let (_, stats) = baker.level(lobe, 8).expect("level");
            assert_eq!(stats.negatives_clamped, 0, "{lobe:?}");
        }
    }
}
