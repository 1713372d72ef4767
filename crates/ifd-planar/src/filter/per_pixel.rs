//! The per-pixel paths of [`Filter::apply`] (an angle or scale map): the
//! scalar loop that is the reference, one pixel at a time, and the vector
//! rows ([`rows`]), which give the same values.

use rayon::prelude::*;

use super::{Filter, Prepared};
use crate::field::Field;
use crate::stack::LevelRule;
use crate::stack::rows::{self, FixedTerm, RowLevels, RowOut};
use crate::trig::sin_cos_degrees;

impl Filter<'_> {
    /// Per-pixel angle and/or scale over the whole image. `C` is the channel
    /// count when it is 1 to 4 (accumulators in registers), 0 for any count.
    /// Rows go eight or sixteen pixels at a time through the vector rows
    /// where they can ([`rows`]), the rest of each row through the scalar
    /// loop; both give the same values. With per-pixel `weight`s (one a
    /// pixel) each pixel adds `weight *` its value and pixels of weight zero
    /// are skipped: a row with some packs the others into whole blocks
    /// ([`Filter::packed_row`]), or, with [`Filter::with_runs_in_place`]
    /// and runs of weighted pixels ([`packing_pays`]), runs in place, its
    /// blocks without weight skipped.
    pub(super) fn per_pixel<const C: usize>(
        &self,
        angle: Field<'_>,
        scale: Field<'_>,
        weight: Option<&[f32]>,
        out: &mut [f32],
    ) {
        let (w, c) = (self.stack.width(), self.stack.channels());
        let constant_scale = match scale {
            Field::Constant(s) => Some((s, self.term_levels(s))),
            Field::Map(_) => None,
        };
        let vector = self.vector && rows::supports::<C>(self.stack);
        let fixed: Vec<FixedTerm> = constant_scale
            .as_ref()
            .map(|(_, levels)| {
                self.terms
                    .iter()
                    .zip(levels)
                    .map(|(t, &(a, b, wa, wb))| FixedTerm {
                        cx: t.cx,
                        cy: t.cy,
                        a,
                        b,
                        wa,
                        wb,
                    })
                    .collect()
            })
            .unwrap_or_default();
        // A scale map on the vector path needs the log-uniform level rule.
        let scaled_vector = vector && self.stack.is_uniform() && self.stack.sigmas().len() > 1;
        let groups = self.sigma_groups.len();
        let scratch = || RowScratch::new(w, if scaled_vector { groups } else { 0 });
        out.par_chunks_mut(w * c)
            .enumerate()
            .for_each_init(scratch, |scr, (y, row)| {
                let weights = weight.map(|wt| &wt[y * w..(y + 1) * w]);
                if vector && let Some(weights) = weights {
                    let n = weights.iter().filter(|&&v| v != 0.0).count();
                    if n < w && (!self.runs_in_place || packing_pays(weights, n)) {
                        let row_in = (&fixed[..], constant_scale.as_ref(), scaled_vector);
                        self.packed_row::<C>(y, (angle, scale), weights, row_in, scr, row);
                        return;
                    }
                }
                let mut done = 0;
                if vector {
                    let out = RowOut {
                        row,
                        weight: weights,
                        pixels: None,
                    };
                    let theta = row_field(angle, y, w);
                    let scales = row_field(scale, y, w);
                    done =
                        self.vector_row::<C>(y, (theta, scales), &fixed, scaled_vector, scr, out);
                }
                for (x, px) in row.chunks_exact_mut(c).enumerate().skip(done) {
                    let wt = weights.map_or(1.0, |r| r[x]);
                    if wt != 0.0 {
                        self.pixel::<C>((x, y), (angle, scale), constant_scale.as_ref(), wt, px);
                    }
                }
            });
    }

    /// One pixel `(x, y)` through the scalar loop: adds `weight *` its
    /// filtered value into `out`.
    #[inline]
    fn pixel<const C: usize>(
        &self,
        (x, y): (usize, usize),
        (angle, scale): (Field<'_>, Field<'_>),
        constant_scale: Option<&(f32, TermLevels)>,
        weight: f32,
        out: &mut [f32],
    ) {
        let i = y * self.stack.width() + x;
        let (sin, cos) = sin_cos_degrees(angle.at(i));
        let (xf, yf) = (x as f32, y as f32);
        match constant_scale {
            Some((s, levels)) => {
                self.pixel_rotated::<C>(levels, xf, yf, cos * s, sin * s, weight, out);
            }
            None => self.pixel_general::<C>(xf, yf, cos, sin, scale.at(i), weight, out),
        }
    }

    /// A weighted row with some weights zero: its weighted pixels packed
    /// together ([`RowOut::pixels`]), so that every block of the vector
    /// rows is full of pixels that count (a bank's entry serves scattered
    /// pixels of a row; blocks would otherwise run for one of their sixteen),
    /// any rest through the scalar loop. The same values as the unpacked
    /// row, bit for bit (the padding's lanes add nothing, as the scalar loop
    /// skips pixels of weight zero).
    fn packed_row<const C: usize>(
        &self,
        y: usize,
        (angle, scale): (Field<'_>, Field<'_>),
        weights: &[f32],
        (fixed, constant_scale, scaled_vector): (&[FixedTerm], Option<&(f32, TermLevels)>, bool),
        scr: &mut RowScratch,
        row: &mut [f32],
    ) {
        let w = self.stack.width();
        let mut packed = std::mem::take(&mut scr.packed);
        packed.clear();
        let push = |packed: &mut Packed, x: usize, wt: f32| {
            let i = y * w + x;
            packed.pixels.push(x as u32);
            packed.weights.push(wt);
            packed.theta.push(angle.at(i));
            if let Field::Map(_) = scale {
                packed.scales.push(scale.at(i));
            }
        };
        for (x, &wt) in weights.iter().enumerate() {
            if wt != 0.0 {
                push(&mut packed, x, wt);
            }
        }
        // Padded to whole blocks (sixteen or eight, within the row's
        // room) with the last pixel again at weight zero, which the
        // kernels skip as the scalar loop does: no entry is left to it.
        let n = packed.pixels.len();
        if let Some(&last) = packed.pixels.last() {
            let to = [n.next_multiple_of(16), n.next_multiple_of(8)]
                .into_iter()
                .find(|&to| to <= w)
                .unwrap_or(n);
            for _ in n..to {
                push(&mut packed, last as usize, 0.0);
            }
        }
        let n = packed.pixels.len();
        let scales = match scale {
            Field::Constant(s) => Field::Constant(s),
            Field::Map(_) => Field::Map(&packed.scales),
        };
        let out = RowOut {
            row,
            weight: Some(&packed.weights),
            pixels: Some(&packed.pixels),
        };
        let theta = Field::Map(&packed.theta);
        let done = self.vector_row::<C>(y, (theta, scales), fixed, scaled_vector, scr, out);
        let c = self.stack.channels();
        for k in done..n {
            let (x, wt) = (packed.pixels[k] as usize, packed.weights[k]);
            if wt != 0.0 {
                let px = &mut row[x * c..(x + 1) * c];
                self.pixel::<C>((x, y), (angle, scale), constant_scale, wt, px);
            }
        }
        scr.packed = packed;
    }

    /// The entries of row `y` through the vector rows, `theta` and `scale`
    /// the row's (a map of one value per entry, or a constant): the entries
    /// done (a prefix, possibly none).
    fn vector_row<const C: usize>(
        &self,
        y: usize,
        (theta, scale): (Field<'_>, Field<'_>),
        fixed: &[FixedTerm],
        scaled_vector: bool,
        scr: &mut RowScratch,
        out: RowOut<'_>,
    ) -> usize {
        let n = match (theta, scale) {
            (Field::Map(m), _) | (_, Field::Map(m)) => m.len(),
            _ => self.stack.width(),
        };
        let (cs, ss) = (&mut scr.cs[..n], &mut scr.ss[..n]);
        match scale {
            Field::Constant(_) => {
                row_rotations(theta, scale, cs, ss);
                rows::rotated_row::<C>(self.stack, fixed, y, cs, ss, out)
            }
            Field::Map(scales) if scaled_vector => {
                // Per pixel: the rotation, t_s and the widening; then the
                // levels and weights per distinct sigma, group-major, by
                // the scalar loop's rule (the same values).
                let (t_s, widen) = (&mut scr.t_s[..n], &mut scr.widen[..n]);
                let levels = &mut scr.levels;
                levels.set_width(n);
                row_rotations(theta, scale, cs, ss);
                rows::scale_positions(self.scale_position, scales, t_s, widen);
                for (g, rep) in self.sigma_groups.iter().enumerate() {
                    rows::fill_levels(self.level_rule(rep), t_s, widen, levels, g);
                }
                rows::scaled_row::<C>(self.stack, &self.scaled_terms, levels, y, cs, ss, out)
            }
            Field::Map(_) => 0,
        }
    }

    /// The level rule of terms of `t`'s sigma on this (log-uniform, several
    /// levels) stack.
    fn level_rule(&self, t: &Prepared) -> LevelRule {
        let (_, inv) = self.stack.ln_params();
        LevelRule {
            ln_sigma: t.ln_sigma,
            inv_sigma2: t.inv_sigma2,
            inv: inv as f32,
            last: (self.stack.sigmas().len() - 1) as u32,
            snap: self.stack.pixel_snap(),
        }
    }

    /// Term `t`'s levels and weights at scale `s` on a log-uniform stack of
    /// several levels: `t_s = (ln s - ln sigma_0) / ln r`, `widen` the pixel
    /// footprint's variance at `s` over `s^2` ([`LevelRule`]; the vector
    /// path's rows take the same values).
    #[inline]
    fn uniform_level(&self, t: &Prepared, t_s: f32, widen: f32) -> (usize, usize, f32, f32) {
        let (a, b, wa, wb) = self.level_rule(t).at(t_s, widen);
        (a as usize, b as usize, wa, wb)
    }

    /// One pixel with constant scale (levels precomputed) and a per-pixel
    /// rotation; `cs = s cos theta`, `ss = s sin theta`. Adds `weight *` the
    /// filtered value into `out`.
    #[inline]
    #[expect(clippy::too_many_arguments, reason = "hot inner call, all scalars")]
    pub(crate) fn pixel_rotated<const C: usize>(
        &self,
        levels: &[(usize, usize, f32, f32)],
        x: f32,
        y: f32,
        cs: f32,
        ss: f32,
        weight: f32,
        out: &mut [f32],
    ) {
        let mut acc = [0.0f32; C];
        for (t, &(a, b, wa, wb)) in self.terms.iter().zip(levels) {
            let px = x + cs * t.cx + ss * t.cy;
            let py = y - ss * t.cx + cs * t.cy;
            // With `C == 0` the lookups add straight into `out`, so the
            // weight goes into each tap; otherwise into the sum below.
            let (wa, wb) = if C == 0 {
                (wa * weight, wb * weight)
            } else {
                (wa, wb)
            };
            self.add::<C>(a, px, py, wa, &mut acc, out);
            if wb != 0.0 {
                self.add::<C>(b, px, py, wb, &mut acc, out);
            }
        }
        for (o, a) in out.iter_mut().zip(acc) {
            *o += weight * a;
        }
    }

    /// Adds `weight *` the bilinear lookup of level `li` to `acc` when
    /// `C > 0`, else to `out`.
    #[inline]
    fn add<const C: usize>(
        &self,
        li: usize,
        x: f32,
        y: f32,
        weight: f32,
        acc: &mut [f32; C],
        out: &mut [f32],
    ) {
        if C == 0 {
            self.stack.accumulate(li, x, y, weight, out);
        } else {
            self.stack.accumulate_fixed::<C>(li, x, y, weight, acc);
        }
    }

    /// One pixel, everything per pixel. Adds `weight *` the filtered value
    /// into `out`.
    #[inline]
    #[expect(clippy::too_many_arguments, reason = "hot inner call, all scalars")]
    pub(super) fn pixel_general<const C: usize>(
        &self,
        x: f32,
        y: f32,
        cos: f32,
        sin: f32,
        s: f32,
        weight: f32,
        out: &mut [f32],
    ) {
        let last = self.stack.sigmas().len() - 1;
        let uniform = self.stack.is_uniform();
        let (t_s, widen) = if uniform {
            self.scale_position.at(s)
        } else {
            (0.0, 0.0)
        };
        let cs = cos * s;
        let ss = sin * s;
        let mut acc = [0.0f32; C];
        // With `C == 0` the lookups add straight into `out`, so the weight
        // goes into each tap; otherwise into the sum below.
        let tap = |v: f32| if C == 0 { v * weight } else { v };
        for t in &self.terms {
            let px = x + cs * t.cx + ss * t.cy;
            let py = y - ss * t.cx + cs * t.cy;
            if last == 0 {
                self.add::<C>(0, px, py, tap(t.weight), &mut acc, out);
                continue;
            }
            if !uniform {
                // Levels at given sigmas: bisection.
                let sigma = self.sampling.effective_sigma(t.sigma, f64::from(s));
                let (a, b, wa, wb) = self.stack.locate_ln(sigma.ln());
                self.add::<C>(a, px, py, tap(t.weight * wa), &mut acc, out);
                if wb != 0.0 {
                    self.add::<C>(b, px, py, tap(t.weight * wb), &mut acc, out);
                }
                continue;
            }
            let (a, b, wa, wb) = self.uniform_level(t, t_s, widen);
            self.add::<C>(a, px, py, tap(t.weight * wa), &mut acc, out);
            if wb != 0.0 {
                self.add::<C>(b, px, py, tap(t.weight * wb), &mut acc, out);
            }
        }
        if C > 0 {
            for (o, a) in out.iter_mut().zip(acc) {
                *o += weight * a;
            }
        }
    }
}

/// The distinct sigmas of `terms` (a representative term each, in order of
/// first appearance) and each term's index among them.
pub(super) fn sigma_groups(terms: &[Prepared]) -> (Vec<Prepared>, Vec<usize>) {
    let mut groups: Vec<Prepared> = Vec::new();
    let group_of = terms
        .iter()
        .map(|t| {
            if let Some(g) = groups
                .iter()
                .position(|r| r.sigma.to_bits() == t.sigma.to_bits())
            {
                g
            } else {
                groups.push(*t);
                groups.len() - 1
            }
        })
        .collect();
    (groups, group_of)
}

/// Each term's `(level a, level b, weight a, weight b)` at a constant
/// scale ([`Filter::term_levels`]).
type TermLevels = Vec<(usize, usize, f32, f32)>;

/// One thread's buffers for [`Filter::per_pixel`]'s vector rows, reused
/// from row to row (every row overwrites what it reads): each pixel's
/// scaled rotation, scale position and widening, and the levels of each
/// sigma group.
struct RowScratch {
    cs: Vec<f32>,
    ss: Vec<f32>,
    t_s: Vec<f32>,
    widen: Vec<f32>,
    levels: RowLevels,
    packed: Packed,
}

/// A packed row's pixels and their weights, angles and scales (scales only
/// with a scale map).
#[derive(Default)]
struct Packed {
    pixels: Vec<u32>,
    weights: Vec<f32>,
    theta: Vec<f32>,
    scales: Vec<f32>,
}

impl Packed {
    fn clear(&mut self) {
        self.pixels.clear();
        self.weights.clear();
        self.theta.clear();
        self.scales.clear();
    }
}

impl RowScratch {
    /// Buffers for rows of `w` pixels and `groups` sigma groups (0 without
    /// a scale map).
    fn new(w: usize, groups: usize) -> Self {
        let per_pixel_scale = if groups > 0 { w } else { 0 };
        Self {
            cs: vec![0.0; w],
            ss: vec![0.0; w],
            t_s: vec![0.0; per_pixel_scale],
            widen: vec![0.0; per_pixel_scale],
            levels: RowLevels::new(groups, w),
            packed: Packed::default(),
        }
    }
}

/// Row `y` of a whole-image field: its `w` values, or the constant.
fn row_field(f: Field<'_>, y: usize, w: usize) -> Field<'_> {
    match f {
        Field::Map(m) => Field::Map(&m[y * w..(y + 1) * w]),
        Field::Constant(v) => Field::Constant(v),
    }
}

/// A row's rotations by `theta` (the row's angles, one per entry of `cs`,
/// or a constant) scaled by `scale` (likewise): `cs = s cos`, `ss = s
/// sin`, as the scalar loop computes them ([`sin_cos_degrees`]).
fn row_rotations(theta: Field<'_>, scale: Field<'_>, cs: &mut [f32], ss: &mut [f32]) {
    match theta {
        Field::Map(m) => rows::rotations(m, scale, cs, ss),
        Field::Constant(theta) => {
            let (sin, cos) = sin_cos_degrees(theta);
            for (x, (c, sn)) in cs.iter_mut().zip(ss.iter_mut()).enumerate() {
                let s = scale.at(x);
                (*c, *sn) = (cos * s, sin * s);
            }
        }
    }
}

/// How many times the blocks a weighted row runs in place may outnumber
/// its blocks packed before packing pays. In place, a block of
/// neighbouring pixels reads row windows (contiguous loads); packed, the
/// pixels of a block are apart and their lookups mostly gather, which on
/// this project's AMD EPYC costs about three times as much, where the
/// angle map turns slowly enough for windows (three filters over the
/// terciles of a smoothed 1024x1024 photograph, runs of 24 px on average,
/// along a swirl: filtering 25-42 ms packed, 18-32 ms in place).
const PACK_RATIO: usize = 2;

/// Whether a weighted row with `n` pixels of non-zero weight goes packed
/// ([`Filter::packed_row`]: scattered pixels, a bank's entry) rather than
/// in place, its blocks without weight skipped (regions: runs of pixels).
fn packing_pays(weights: &[f32], n: usize) -> bool {
    let lanes = ifd_simd::isa().f32_lanes().max(1);
    let in_place = weights
        .chunks(lanes)
        .filter(|b| b.iter().any(|&v| v != 0.0))
        .count();
    in_place > PACK_RATIO * n.div_ceil(lanes)
}
