//! The row kernels, written once over [`Lanes`]: the lookups (bilinear and cubic B-spline, any channel count;
//! a scale map's blocks classified by the levels their lanes read), `N`
//! pixels of a row at a time. Each instruction set's file compiles them for
//! its lanes through [`entry_points`].
//!
//! Every expression is the scalar loop's, in its order, with separate
//! multiplies and adds (see [`super`]): the lanes' results are the scalar
//! loop's bits. The bodies are `#[inline(always)]` so that they are compiled
//! into each `#[target_feature]` entry point with its instruction set, and
//! call only `#[inline(always)]` helpers and [`Lanes`] primitives (a closure
//! or an out-of-line helper would be compiled for the baseline).
#![allow(
    unsafe_code,
    reason = "the bodies call `Lanes` primitives and gathers; see the `rows` module documentation"
)]
#![expect(
    clippy::inline_always,
    reason = "each body is compiled into the `#[target_feature]` entry points of each instruction set"
)]

use super::lanes::{Lanes, block_end};
use super::{FixedTerm, RowLevels, RowOut, ScaledTerm};
use crate::stack::{Interpolation, Level, ScaleStack};

/// The row kernels' entry points for one instruction set's lanes, each
/// compiled for `$features` (`#[target_feature]`) around the body of the
/// same name below: `rotated_row`, `scaled_row`, `rotations`,
/// `scale_positions`, `fill_levels`. Each does the whole blocks of `N`
/// pixels from pixel `from` and returns the pixel after the last it did.
///
/// # Safety (of each entry point)
/// The CPU has `$features` (the dispatch in [`super`] asks
/// [`ifd_simd::has`]).
macro_rules! entry_points {
    ($lanes:ident, $features:literal) => {
        /// [`super::kernels::rotated_row`] on these lanes.
        #[target_feature(enable = $features)]
        pub(super) unsafe fn rotated_row<const C: usize>(
            stack: &crate::stack::ScaleStack,
            terms: &[super::FixedTerm],
            y: usize,
            (cs, ss): (&[f32], &[f32]),
            out: super::RowOut<'_>,
            from: usize,
        ) -> usize {
            // SAFETY: compiled for the lanes' instruction set (the caller
            // checked the CPU has it).
            unsafe {
                super::kernels::rotated_row::<$lanes, C>(stack, terms, y, (cs, ss), out, from)
            }
        }

        /// [`super::kernels::scaled_row`] on these lanes.
        #[target_feature(enable = $features)]
        pub(super) unsafe fn scaled_row<const C: usize>(
            stack: &crate::stack::ScaleStack,
            terms: &[super::ScaledTerm],
            levels: &super::RowLevels,
            y: usize,
            (cs, ss): (&[f32], &[f32]),
            out: super::RowOut<'_>,
            from: usize,
        ) -> usize {
            // SAFETY: as `rotated_row`.
            unsafe {
                super::kernels::scaled_row::<$lanes, C>(
                    stack,
                    terms,
                    levels,
                    y,
                    (cs, ss),
                    out,
                    from,
                )
            }
        }

        /// [`super::rules::rotations`] on these lanes.
        #[target_feature(enable = $features)]
        pub(super) unsafe fn rotations(
            theta: &[f32],
            scale: crate::field::Field<'_>,
            cs: &mut [f32],
            ss: &mut [f32],
            from: usize,
        ) -> usize {
            // SAFETY: as `rotated_row`.
            unsafe { super::rules::rotations::<$lanes>(theta, scale, cs, ss, from) }
        }

        /// [`super::rules::scale_positions`] on these lanes.
        #[target_feature(enable = $features)]
        pub(super) unsafe fn scale_positions(
            rule: crate::stack::ScalePosition,
            scales: &[f32],
            t_s: &mut [f32],
            widen: &mut [f32],
            from: usize,
        ) -> usize {
            // SAFETY: as `rotated_row`.
            unsafe { super::rules::scale_positions::<$lanes>(rule, scales, t_s, widen, from) }
        }

        /// [`super::rules::fill_levels`] on these lanes.
        #[target_feature(enable = $features)]
        pub(super) unsafe fn fill_levels(
            rule: crate::stack::LevelRule,
            t_s: &[f32],
            widen: &[f32],
            levels: &mut super::RowLevels,
            g: usize,
            from: usize,
        ) -> usize {
            // SAFETY: as `rotated_row`.
            unsafe { super::rules::fill_levels::<$lanes>(rule, t_s, widen, levels, g, from) }
        }
    };
}
pub(super) use entry_points;

/// Adds the filtered values of the row's blocks from `from` into `out`
/// (`C` interleaved channels) for per-pixel rotations `cs[x] = s cos`,
/// `ss[x] = s sin` at a constant scale.
///
/// # Safety
/// Compiled for `V`'s instruction set (see [`Lanes`]); the stack passed
/// `super::fits::<C>` and `out` holds the row's entries (`RowOut::holds`:
/// `cs.len()` weights and pixels, each pixel's `C` samples in the row; the
/// stores index it through checked slices besides).
#[inline(always)]
pub(super) unsafe fn rotated_row<V: Lanes, const C: usize>(
    stack: &ScaleStack,
    terms: &[FixedTerm],
    y: usize,
    rotations: (&[f32], &[f32]),
    out: RowOut<'_>,
    from: usize,
) -> usize {
    // SAFETY: as the caller promises.
    unsafe {
        match stack.interpolation {
            Interpolation::Linear => {
                rotated_row_as::<V, C, false>(stack, terms, y, rotations, out, from)
            }
            Interpolation::Cubic => {
                rotated_row_as::<V, C, true>(stack, terms, y, rotations, out, from)
            }
        }
    }
}

/// [`rotated_row`] for the stack's interpolation (`CUBIC`), chosen once per
/// row so that the loop holds one kind of lookup.
#[inline(always)]
unsafe fn rotated_row_as<V: Lanes, const C: usize, const CUBIC: bool>(
    stack: &ScaleStack,
    terms: &[FixedTerm],
    y: usize,
    (cs, ss): (&[f32], &[f32]),
    RowOut {
        row: out,
        weight,
        pixels,
    }: RowOut<'_>,
    from: usize,
) -> usize {
    let end = block_end::<V>(from, cs.len());
    // SAFETY: as the caller promises.
    unsafe {
        let yf = V::splat(y as f32);
        for x0 in (from..end).step_by(V::N) {
            let Some(pw) = block_weight::<V>(weight, x0) else {
                continue;
            };
            let xf = block_columns::<V>(pixels, x0);
            let (c, s) = (V::load(&cs[x0..]), V::load(&ss[x0..]));
            let mut acc = [V::zero(); C];
            for t in terms {
                let (px, py) = positions::<V>((xf, yf), (c, s), t.cx, t.cy);
                for (li, w) in [(t.a, t.wa), (t.b, t.wb)] {
                    if w == 0.0 {
                        continue;
                    }
                    let wv = V::splat(w);
                    if !lookup::<V, C, CUBIC>(stack, li, (px, py), wv, &mut acc) {
                        acc = scalar_lanes::<V, C>(stack, li, (px, py), wv, &acc);
                    }
                }
            }
            add_out::<V, C>(&acc, pw, (out, pixels), x0);
        }
    }
    end
}

#[cfg(test)]
thread_local! {
    /// The one-channel lookups on this thread, by path: windows on lane 0's
    /// rows only, windows with lanes a row above, a row below, and gathers
    /// ([`Path`]): the tests check that their maps take every path.
    pub(super) static LOOKUPS: std::cell::Cell<[usize; 4]> = const { std::cell::Cell::new([0; 4]) };
}

/// The paths a one-channel lookup takes, counted by the tests.
#[derive(Clone, Copy)]
pub(super) enum Path {
    /// A window whose lanes start on lane 0's row.
    Window = 0,
    /// A window with lanes a row above lane 0's.
    Above = 1,
    /// A window with lanes a row below lane 0's (and maybe above).
    Below = 2,
    /// The gathers.
    Gather = 3,
}

/// Counts a lookup by its path (tests only).
#[inline(always)]
fn count(path: Path) {
    #[cfg(test)]
    LOOKUPS.with(|c| {
        let mut n = c.get();
        n[path as usize] += 1;
        c.set(n);
    });
    #[cfg(not(test))]
    let _ = path;
}

/// The most levels one block's vector lookups span (a lookup each);
/// blocks whose lanes spread wider go lane by lane.
const SPAN: usize = 4;

/// One sigma group's levels over a block (its per-level weights are kept
/// apart, in the group's slot of a buffer that [`classify`] writes in
/// place: a block is rebuilt per group every block, and moving the weights
/// each time cost a seventh of the row's time).
#[derive(Clone, Copy)]
enum Block {
    /// Every lane on levels `a .. a + SPAN`: per level, each lane's weight
    /// on it in the group's weights (zero where the lane does not read it),
    /// `used` marking the levels some lane reads. A lane reads its two
    /// levels in the scalar loop's order, lower first, so its sum is the
    /// scalar loop's.
    Vector { a: usize, used: u8 },
    /// Lanes spread over more levels: each lane looks up its own.
    Lanes,
}

/// As [`rotated_row`] with a per-pixel scale: `levels` gives the levels
/// and weights of the terms of each sigma group at each pixel.
///
/// # Safety
/// As [`rotated_row`]; besides, `levels` covers every term's group over
/// the row and no level past the stack's (`super::scaled_row` checks).
#[inline(always)]
pub(super) unsafe fn scaled_row<V: Lanes, const C: usize>(
    stack: &ScaleStack,
    terms: &[ScaledTerm],
    levels: &RowLevels,
    y: usize,
    rotations: (&[f32], &[f32]),
    out: RowOut<'_>,
    from: usize,
) -> usize {
    // SAFETY: as the caller promises.
    unsafe {
        match stack.interpolation {
            Interpolation::Linear => {
                scaled_row_as::<V, C, false>(stack, terms, levels, y, rotations, out, from)
            }
            Interpolation::Cubic => {
                scaled_row_as::<V, C, true>(stack, terms, levels, y, rotations, out, from)
            }
        }
    }
}

/// [`scaled_row`] for the stack's interpolation (`CUBIC`), chosen once per
/// row.
#[inline(always)]
unsafe fn scaled_row_as<V: Lanes, const C: usize, const CUBIC: bool>(
    stack: &ScaleStack,
    terms: &[ScaledTerm],
    levels: &RowLevels,
    y: usize,
    (cs, ss): (&[f32], &[f32]),
    RowOut {
        row: out,
        weight,
        pixels,
    }: RowOut<'_>,
    from: usize,
) -> usize {
    let w = cs.len();
    let end = block_end::<V>(from, w);
    let groups = levels.groups;
    let linear = !CUBIC;
    // level i and level i + 1 sample the same grid: one bilinear stencil
    // serves both (the same values as computing it twice)
    let same_grid: Vec<bool> = stack
        .levels
        .windows(2)
        .map(|p| {
            let grid = |l: &Level| (l.layout.step, l.layout.origin, l.layout.nx, l.layout.ny);
            grid(&p[0]) == grid(&p[1])
        })
        .collect();
    let mut blocks = vec![Block::Lanes; groups];
    // SAFETY: as the caller promises.
    unsafe {
        let mut weights = vec![[V::zero(); SPAN]; groups];
        let yf = V::splat(y as f32);
        for x0 in (from..end).step_by(V::N) {
            let Some(pw) = block_weight::<V>(weight, x0) else {
                continue;
            };
            for (g, (b, wt)) in blocks.iter_mut().zip(&mut weights).enumerate() {
                *b = classify::<V>(levels, g, x0, wt);
            }
            let xf = block_columns::<V>(pixels, x0);
            let (c, s) = (V::load(&cs[x0..]), V::load(&ss[x0..]));
            let mut acc = [V::zero(); C];
            for t in terms {
                let (px, py) = positions::<V>((xf, yf), (c, s), t.cx, t.cy);
                match blocks[t.group] {
                    Block::Vector { a, used } => {
                        let wt = &weights[t.group];
                        let tw = V::splat(t.weight);
                        if used == 0b11
                            && linear
                            && same_grid[a]
                            && let Some(at) = bilinear_stencil::<V>(&stack.levels[a], px, py)
                        {
                            // The common pair: levels a and a + 1 on one
                            // grid share the bilinear stencil; a stencil
                            // past the stored level goes through the loop
                            // below, lane by lane.
                            bilinear_at::<V, C>(&stack.levels[a], at, V::mul(tw, wt[0]), &mut acc);
                            bilinear_at::<V, C>(
                                &stack.levels[a + 1],
                                at,
                                V::mul(tw, wt[1]),
                                &mut acc,
                            );
                            continue;
                        }
                        for (k, lw) in wt.iter().enumerate() {
                            if used & (1 << k) == 0 {
                                continue;
                            }
                            let li = a + k;
                            let wv = V::mul(tw, *lw);
                            if !lookup::<V, C, CUBIC>(stack, li, (px, py), wv, &mut acc) {
                                acc = scalar_lanes::<V, C>(stack, li, (px, py), wv, &acc);
                            }
                        }
                    }
                    Block::Lanes => {
                        // each lane's two lookups in the scalar order
                        let (mut pxs, mut pys) = (V::Floats::default(), V::Floats::default());
                        V::store(px, pxs.as_mut());
                        V::store(py, pys.as_mut());
                        let mut sums = spill::<V, C>(&acc);
                        lanes_levels::<C, _>(
                            stack,
                            (levels, t, x0),
                            (pxs.as_ref(), pys.as_ref()),
                            &mut sums,
                        );
                        acc = fill::<V, C>(&sums);
                    }
                }
            }
            add_out::<V, C>(&acc, pw, (out, pixels), x0);
        }
    }
    end
}

/// The block of `V::N` lanes from pixel `x0` of group `g`: each lane reads
/// level `a` (weight `wa`) and, where `wb != 0`, `a + 1` (`wb`); the
/// per-level weights written into `w`.
#[inline(always)]
unsafe fn classify<V: Lanes>(
    levels: &RowLevels,
    g: usize,
    x0: usize,
    w: &mut [V::F; SPAN],
) -> Block {
    let i = g * levels.w + x0;
    let a = &levels.a[i..i + V::N];
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let la = V::load_u32(a);
        let (wa, wb) = (V::load(&levels.wa[i..]), V::load(&levels.wb[i..]));
        let zero = V::zero();
        // the lanes that read a second level
        let second = V::ne(wb, zero);
        if V::all(V::eq_i(la, V::splat_i(a[0] as i32))) {
            // The common block: every lane on level `a` (and `a + 1` where
            // its `wb` is not zero); the general rule below gives the same
            // weights.
            let used = u8::from(V::any(V::ne(wa, zero))) | (u8::from(V::any(second)) << 1);
            w[0] = wa;
            w[1] = V::zero_unless(second, wb);
            return Block::Vector {
                a: a[0] as usize,
                used,
            };
        }
        let lb = V::inc_where(la, second);
        let (lo, hi) = (V::reduce_min(la), V::reduce_max(lb));
        let n = (hi - lo) as usize + 1;
        if n > SPAN {
            return Block::Lanes;
        }
        // level lo + k: each lane's weight on it (wa where a is it, wb where
        // a + 1 is; a lane without a second level adds nothing)
        let one_level = V::eq_i(la, lb);
        let mut used = 0u8;
        for (k, wk) in w.iter_mut().enumerate().take(n) {
            let level = V::splat_i(lo + k as i32);
            let on_a = V::eq_i(la, level);
            let on_b = V::andnot_m(one_level, V::eq_i(lb, level));
            *wk = V::add(V::zero_unless(on_a, wa), V::zero_unless(on_b, wb));
            used |= u8::from(V::any(V::ne(*wk, zero))) << k;
        }
        Block::Vector {
            a: lo as usize,
            used,
        }
    }
}

/// Adds `w *` the lookups of level `li` at `(px, py)` to `acc` when every
/// lane's stencil lies in the stored level (the scalar lookup's interior
/// test, lane by lane); returns false, touching nothing, otherwise.
#[inline(always)]
unsafe fn lookup<V: Lanes, const C: usize, const CUBIC: bool>(
    stack: &ScaleStack,
    li: usize,
    (px, py): (V::F, V::F),
    w: V::F,
    acc: &mut [V::F; C],
) -> bool {
    let level = &stack.levels[li];
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        if CUBIC {
            return cubic::<V, C>(level, (px, py), w, acc);
        }
        match bilinear_stencil::<V>(level, px, py) {
            Some(at) => {
                bilinear_at::<V, C>(level, at, w, acc);
                true
            }
            None => false,
        }
    }
}

/// [`stencil_inside`]'s fractions and floors.
type Inside<V> = (
    <V as Lanes>::F,
    <V as Lanes>::F,
    <V as Lanes>::I,
    <V as Lanes>::I,
);

/// The fractions `(fu, fv)` of the level coordinates `(u, v)` of `(px, py)`
/// and their floors `(iu, iv)` when every lane's stencil, `before` samples
/// before and `after` after the one below the point (0 and 1 bilinear, 1
/// and 2 cubic), lies in the stored level: the scalar lookups' test `u >=
/// before`, `v >= before`, `iu + after < nx`, `iv + after < ny`, lane by
/// lane, as one unsigned compare per axis of `floor(u) - before` against
/// `nx - 1 - after - before` (a negative floor wraps above it; NaN and
/// values past `i32` convert to `i32::MIN`, which does too). Where it holds,
/// `u >= 0` (or `-0`), so `u - floor(u)` is the scalar lookup's `u -
/// trunc(u)` (at `u = -0` a zero of the other sign, which leaves every sum
/// it enters unchanged).
#[inline(always)]
unsafe fn stencil_inside<V: Lanes>(
    level: &Level,
    (px, py): (V::F, V::F),
    before: i32,
    after: i32,
) -> Option<Inside<V>> {
    let (nx, ny) = (level.layout.nx as i32, level.layout.ny as i32);
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let (origin, inv) = (V::splat(level.origin), V::splat(level.inv_step));
        let u = V::mul(V::sub(px, origin), inv);
        let v = V::mul(V::sub(py, origin), inv);
        let (fl_u, fl_v) = (V::floor(u), V::floor(v));
        let (iu, iv) = (V::to_int(fl_u), V::to_int(fl_v));
        let first = V::splat_i(before);
        let inside = V::and_m(
            V::le_u(V::sub_i(iu, first), V::splat_i(nx - 1 - after - before)),
            V::le_u(V::sub_i(iv, first), V::splat_i(ny - 1 - after - before)),
        );
        if V::all(inside) {
            Some((V::sub(u, fl_u), V::sub(v, fl_v), iu, iv))
        } else {
            None
        }
    }
}

/// Where a bilinear lookup reads, for every lane (see [`bilinear_stencil`]).
#[derive(Clone, Copy)]
struct Stencil<V: Lanes> {
    /// The fractions of the level coordinates.
    fu: V::F,
    fv: V::F,
    /// The floors of the level coordinates.
    iu: V::I,
    iv: V::I,
}

/// Where a bilinear lookup of `level` at `(px, py)` reads, when every
/// lane's stencil lies in the stored level (see [`stencil_inside`]). Levels
/// on the same grid share it.
#[inline(always)]
unsafe fn bilinear_stencil<V: Lanes>(level: &Level, px: V::F, py: V::F) -> Option<Stencil<V>> {
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let (fu, fv, iu, iv) = stencil_inside::<V>(level, (px, py), 0, 1)?;
        Some(Stencil { fu, fv, iu, iv })
    }
}

/// Each lane's first sample of `st`, `iv nx + iu`, clamped into `level` for
/// the gathers (computed only where they run: the windows do not need it).
/// Memory safety: every read of [`bilinear_at`]'s gathers is at most `nx +
/// 1` samples (times C, plus C - 1) past `idx <= nx (ny - 1) - 2`, inside
/// the level's `nx ny C` samples (`fits` checked the length).
#[inline(always)]
unsafe fn gather_index<V: Lanes>(level: &Level, st: &Stencil<V>) -> V::I {
    let (nx, ny) = (level.layout.nx as i32, level.layout.ny as i32);
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let idx = V::add_i(V::mul_i(st.iv, V::splat_i(nx)), st.iu);
        V::min_i(V::max_i(idx, V::splat_i(0)), V::splat_i(nx * (ny - 1) - 2))
    }
}

/// Adds `w *` the bilinear lookups of `level` at `stencil` (from
/// [`bilinear_stencil`] on this level's grid) to `acc`.
#[inline(always)]
unsafe fn bilinear_at<V: Lanes, const C: usize>(
    level: &Level,
    st: Stencil<V>,
    w: V::F,
    acc: &mut [V::F; C],
) {
    let nx = level.layout.nx;
    let p = level.data.as_ptr();
    let row = nx * C;
    let (fu, fv) = (st.fu, st.fv);
    // SAFETY: compiled for `V`'s instruction set (the caller's promise);
    // the reads are inside the level (the clamp in `gather_index`, the
    // checks in `window_corners`).
    unsafe {
        if C == 1 {
            if let Some(corners) = window_corners::<V>(level, st) {
                acc[0] = blend::<V>(acc[0], w, (fu, fv), corners);
                return;
            }
            count(Path::Gather);
            let idx = gather_index::<V>(level, &st);
            // (a, b) and (c, d) as pairs of neighbouring floats, read at
            // `idx` from `p` and `p + nx`: they end at `idx + nx + 1 < nx
            // ny`.
            let ((a, b), (c, d)) = (V::gather_pairs(p, idx), V::gather_pairs(p.add(nx), idx));
            acc[0] = blend::<V>(acc[0], w, (fu, fv), [a, b, c, d]);
            return;
        }
        let idx = V::mul_i(gather_index::<V>(level, &st), V::splat_i(C as i32));
        for (k, a) in acc.iter_mut().enumerate() {
            // the largest index read is `idx + row + C + k <= nx ny C - 1`
            let corners = [
                V::gather(p.add(k), idx),
                V::gather(p.add(C + k), idx),
                V::gather(p.add(row + k), idx),
                V::gather(p.add(row + C + k), idx),
            ];
            *a = blend::<V>(*a, w, (fu, fv), corners);
        }
    }
}

/// Where a block's window lookups read ([`window`]): the window's first
/// column `u0` and lane 0's row `v0`, each lane's first column in the
/// window `du`, and the lanes starting a row above and a row below lane
/// 0's (`any_*`: whether some lane does).
struct Window<V: Lanes> {
    u0: i32,
    v0: i32,
    du: V::I,
    above: V::M,
    below: V::M,
    any_above: bool,
    any_below: bool,
}

impl<V: Lanes> Window<V> {
    /// The path this window took, for the tests' counts.
    fn path(&self) -> Path {
        match (self.any_above, self.any_below) {
            (_, true) => Path::Below,
            (true, false) => Path::Above,
            (false, false) => Path::Window,
        }
    }
}

/// The window of a one-channel block whose stencils start at columns `iu`
/// and rows `iv` and reach `before` samples before and `after` after them
/// along each axis (0 and 1 bilinear, 1 and 2 cubic): the lanes' columns
/// `iu - before ..= iu + after` within `2 N` samples from lane 0's first
/// column less `N / 4`, their rows lane 0's or one either side. `None`
/// where the block spreads wider or a row read (`2 N` samples from `u0` on
/// each row from the first lane's above to the last's below) would leave
/// `level.data`; otherwise every such read lies in it.
#[inline(always)]
unsafe fn window<V: Lanes>(
    level: &Level,
    (iu, iv): (V::I, V::I),
    before: i32,
    after: i32,
) -> Option<Window<V>> {
    let nx = level.layout.nx as isize;
    let n = V::N as i32;
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let u0 = V::first_i(iu) - before - n / 4;
        let v0 = V::first_i(iv);
        let du = V::sub_i(iu, V::splat_i(u0 + before));
        if !V::all(V::le_u(du, V::splat_i(2 * n - 1 - before - after))) {
            return None;
        }
        let dv = V::sub_i(iv, V::splat_i(v0));
        let (above, below) = (V::eq_i(dv, V::splat_i(-1)), V::eq_i(dv, V::splat_i(1)));
        let on = V::or_m(V::or_m(above, below), V::eq_i(dv, V::splat_i(0)));
        if !V::all(on) {
            return None;
        }
        let (any_above, any_below) = (V::any(above), V::any(below));
        let first = (v0 - before - i32::from(any_above)) as isize * nx + u0 as isize;
        let last = (v0 + after + i32::from(any_below)) as isize * nx + u0 as isize;
        if first < 0 || last + 2 * n as isize > level.data.len() as isize {
            return None;
        }
        Some(Window {
            u0,
            v0,
            du,
            above,
            below,
            any_above,
            any_below,
        })
    }
}

/// The four bilinear corners of every lane of a one-channel level read
/// with contiguous loads instead of gathers, when the block's stencils are
/// close together, as they are where the maps vary slowly along a row (see
/// [`window`]). Each row the stencils touch is loaded as `2 N` contiguous
/// samples and each lane's pair picked from them by a permute
/// ([`Lanes::permute2`]): a gather's loads cost some CPUs (AMD Zen) several
/// times an in-register permute. The corners are the very samples the
/// gathers read, so the sums are the same bits. `None` (the caller gathers)
/// where [`window`] is.
#[inline(always)]
unsafe fn window_corners<V: Lanes>(level: &Level, st: Stencil<V>) -> Option<[V::F; 4]> {
    let nx = level.layout.nx as isize;
    // SAFETY: compiled for `V`'s instruction set (the caller's promise);
    // `window` checked that rows `v0 - 1 ..= v0 + 2` (those read) lie in
    // `level.data`.
    unsafe {
        let win = window::<V>(level, (st.iu, st.iv), 0, 1)?;
        let (du, above, below) = (win.du, win.above, win.below);
        let p = level.data.as_ptr();
        let du1 = V::add_i(du, V::splat_i(1));
        // the samples of row `r` at each lane's column and the next
        let at = |r: isize| p.offset(r * nx + win.u0 as isize);
        let v0 = win.v0 as isize;
        let (a0, b0) = pair_at::<V>(at(v0), du, du1);
        let (c0, d0) = pair_at::<V>(at(v0 + 1), du, du1);
        let [mut a, mut b, mut c, mut d] = [a0, b0, c0, d0];
        if win.any_above {
            let (a1, b1) = pair_at::<V>(at(v0 - 1), du, du1);
            a = V::select(above, a1, a);
            b = V::select(above, b1, b);
            c = V::select(above, a0, c);
            d = V::select(above, b0, d);
        }
        if win.any_below {
            let (c2, d2) = pair_at::<V>(at(v0 + 2), du, du1);
            a = V::select(below, c0, a);
            b = V::select(below, d0, b);
            c = V::select(below, c2, c);
            d = V::select(below, d2, d);
        }
        count(win.path());
        Some([a, b, c, d])
    }
}

/// `acc + w * bilinear(corners)`, in the scalar lookup's order of
/// operations.
#[inline(always)]
unsafe fn blend<V: Lanes>(
    acc: V::F,
    w: V::F,
    (fu, fv): (V::F, V::F),
    [a, b, c, d]: [V::F; 4],
) -> V::F {
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let r0 = V::add(a, V::mul(fu, V::sub(b, a)));
        let r1 = V::add(c, V::mul(fu, V::sub(d, c)));
        let value = V::add(r0, V::mul(fv, V::sub(r1, r0)));
        V::add(acc, V::mul(w, value))
    }
}

/// The cubic B-spline weights of the samples at `-1, 0, 1, 2` for
/// fractions `t` in `[0, 1)`, as `bspline_weights` computes them.
#[inline(always)]
unsafe fn bspline<V: Lanes>(t: V::F) -> [V::F; 4] {
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let sixth = V::splat(1.0 / 6.0);
        let t2 = V::mul(t, t);
        let t3 = V::mul(t2, t);
        let s = V::sub(V::splat(1.0), t);
        [
            V::mul(V::mul(V::mul(s, s), s), sixth),
            V::mul(
                V::add(
                    V::sub(V::mul(V::splat(3.0), t3), V::mul(V::splat(6.0), t2)),
                    V::splat(4.0),
                ),
                sixth,
            ),
            V::mul(
                V::add(
                    V::add(
                        V::add(V::mul(V::splat(-3.0), t3), V::mul(V::splat(3.0), t2)),
                        V::mul(V::splat(3.0), t),
                    ),
                    V::splat(1.0),
                ),
                sixth,
            ),
            V::mul(t3, sixth),
        ]
    }
}

/// `w[0] r[0] + w[1] r[1] + w[2] r[2] + w[3] r[3]`, summed left to right.
#[inline(always)]
unsafe fn dot4<V: Lanes>(w: &[V::F; 4], r: [V::F; 4]) -> V::F {
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        V::add(
            V::add(
                V::add(V::mul(w[0], r[0]), V::mul(w[1], r[1])),
                V::mul(w[2], r[2]),
            ),
            V::mul(w[3], r[3]),
        )
    }
}

/// The cubic B-spline lookups of `level` (see [`lookup`]): 4x4
/// coefficients around each lane's position, in the scalar lookup's order
/// of operations.
#[inline(always)]
unsafe fn cubic<V: Lanes, const C: usize>(
    level: &Level,
    (px, py): (V::F, V::F),
    w: V::F,
    acc: &mut [V::F; C],
) -> bool {
    let (nx, ny) = (level.layout.nx as i32, level.layout.ny as i32);
    // SAFETY: compiled for `V`'s instruction set (the caller's promise);
    // the reads are inside the level (the clamp below).
    unsafe {
        let Some((fu, fv, iu, iv)) = stencil_inside::<V>(level, (px, py), 1, 2) else {
            return false;
        };
        let (wx, wy) = (bspline::<V>(fu), bspline::<V>(fv));
        if C == 1
            && let Some(sum) = cubic_window::<V>(level, (iu, iv), (&wx, &wy))
        {
            acc[0] = V::add(acc[0], V::mul(w, sum));
            return true;
        }
        // Sample (iu - 1, iv - 1) of each lane. Memory safety: every read
        // below is at most `3 nx + 3` samples (times C, plus C - 1) past
        // `base <= nx ny - 3 nx - 4`, inside the level's `nx ny C` samples.
        let one = V::splat_i(1);
        let base = V::add_i(
            V::mul_i(V::sub_i(iv, one), V::splat_i(nx)),
            V::sub_i(iu, one),
        );
        let base = V::min_i(
            V::max_i(base, V::splat_i(0)),
            V::splat_i(nx * ny - 3 * nx - 4),
        );
        let p = level.data.as_ptr();
        let row = nx as usize * C;
        if C == 1 {
            count(Path::Gather);
            let mut sum = V::zero();
            for (j, wyj) in wy.iter().enumerate() {
                let q = p.add(j * row);
                let (r0, r1) = V::gather_pairs(q, base);
                let (r2, r3) = V::gather_pairs(q.add(2), base);
                sum = V::add(sum, V::mul(*wyj, dot4::<V>(&wx, [r0, r1, r2, r3])));
            }
            acc[0] = V::add(acc[0], V::mul(w, sum));
            return true;
        }
        let base = V::mul_i(base, V::splat_i(C as i32));
        for (j, wyj) in wy.iter().enumerate() {
            let wj = V::mul(w, *wyj);
            for (k, a) in acc.iter_mut().enumerate() {
                let q = p.add(j * row + k);
                let r = [
                    V::gather(q, base),
                    V::gather(q.add(C), base),
                    V::gather(q.add(2 * C), base),
                    V::gather(q.add(3 * C), base),
                ];
                *a = V::add(*a, V::mul(wj, dot4::<V>(&wx, r)));
            }
        }
        true
    }
}

/// The samples at `q + du` and `q + du1` (per lane; each below `2 N`).
///
/// # Safety
/// `q .. q + 2 N` inside one allocation; compiled for `V`'s instruction set.
#[inline(always)]
unsafe fn pair_at<V: Lanes>(q: *const f32, du: V::I, du1: V::I) -> (V::F, V::F) {
    // SAFETY: as the caller promises.
    unsafe {
        let (lo, hi) = (V::load_ptr(q), V::load_ptr(q.add(V::N)));
        (V::permute2(lo, hi, du), V::permute2(lo, hi, du1))
    }
}

/// The cubic lookups' sums `sum_j wy[j] dot4(wx, row j)` of a one-channel
/// level read with contiguous loads instead of gathers (as
/// [`window_corners`] for the bilinear corners; each lane's stencil starts
/// a sample before its floor and ends two after). Each row the stencils
/// touch is loaded once, filtered along the row for every lane, and each
/// lane takes its four rows' values; the sums are the gathers' bits. `None`
/// where [`window`] is.
#[inline(always)]
unsafe fn cubic_window<V: Lanes>(
    level: &Level,
    (iu, iv): (V::I, V::I),
    (wx, wy): (&[V::F; 4], &[V::F; 4]),
) -> Option<V::F> {
    let nx = level.layout.nx as isize;
    // SAFETY: compiled for `V`'s instruction set (the caller's promise);
    // `window` checked that the rows read, `v0 - 2 + k` for `k` in `k0 ..=
    // k1` below, lie in `level.data`.
    unsafe {
        let win = window::<V>(level, (iu, iv), 1, 2)?;
        let du = win.du;
        // rows v0 - 2 + k for k in 0..6: k = 0 only for lanes above,
        // k = 5 only for lanes below
        let (k0, k1) = (usize::from(!win.any_above), 5 - usize::from(!win.any_below));
        let p = level.data.as_ptr();
        let cols = [
            du,
            V::add_i(du, V::splat_i(1)),
            V::add_i(du, V::splat_i(2)),
            V::add_i(du, V::splat_i(3)),
        ];
        let mut h = [V::zero(); 6];
        for (k, hk) in h.iter_mut().enumerate().take(k1 + 1).skip(k0) {
            let q = p.offset((win.v0 as isize - 2 + k as isize) * nx + win.u0 as isize);
            let (lo, hi) = (V::load_ptr(q), V::load_ptr(q.add(V::N)));
            let r = [
                V::permute2(lo, hi, cols[0]),
                V::permute2(lo, hi, cols[1]),
                V::permute2(lo, hi, cols[2]),
                V::permute2(lo, hi, cols[3]),
            ];
            *hk = dot4::<V>(wx, r);
        }
        let mut sum = V::zero();
        for (j, wyj) in wy.iter().enumerate() {
            // row iv - 1 + j of each lane: h[j + 1 + dv]
            let mut r = h[j + 1];
            if win.any_above {
                r = V::select(win.above, h[j], r);
            }
            if win.any_below {
                r = V::select(win.below, h[j + 2], r);
            }
            sum = V::add(sum, V::mul(*wyj, r));
        }
        count(win.path());
        Some(sum)
    }
}

/// The block's positions for displacement `(cx, cy)`: `x + cs cx + ss cy`,
/// `y - ss cx + cs cy`, in the scalar loop's order.
#[inline(always)]
unsafe fn positions<V: Lanes>(
    (xf, yf): (V::F, V::F),
    (c, s): (V::F, V::F),
    cx: f32,
    cy: f32,
) -> (V::F, V::F) {
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let (cx, cy) = (V::splat(cx), V::splat(cy));
        let px = V::add(V::add(xf, V::mul(c, cx)), V::mul(s, cy));
        let py = V::add(V::sub(yf, V::mul(s, cx)), V::mul(c, cy));
        (px, py)
    }
}

/// The accumulators' lanes, channel-major.
#[inline(always)]
unsafe fn spill<V: Lanes, const C: usize>(acc: &[V::F; C]) -> [V::Floats; C] {
    let mut sums = [V::Floats::default(); C];
    for (v, s) in acc.iter().zip(&mut sums) {
        // SAFETY: compiled for `V`'s instruction set (the caller's promise).
        unsafe { V::store(*v, s.as_mut()) };
    }
    sums
}

/// The inverse of [`spill`].
#[inline(always)]
unsafe fn fill<V: Lanes, const C: usize>(sums: &[V::Floats; C]) -> [V::F; C] {
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let mut acc = [V::zero(); C];
        for (v, s) in acc.iter_mut().zip(sums) {
            *v = V::load(s.as_ref());
        }
        acc
    }
}

/// The block from pixel `x0`'s per-pixel weights (ones without weights:
/// `1 * sum` is the sum's bits), `None` where every one is zero (the block
/// is skipped).
#[inline(always)]
unsafe fn block_weight<V: Lanes>(weight: Option<&[f32]>, x0: usize) -> Option<V::F> {
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        match weight {
            None => Some(V::splat(1.0)),
            Some(w) => {
                let v = V::load(&w[x0..]);
                V::any(V::ne(v, V::zero())).then_some(v)
            }
        }
    }
}

/// The columns of the block's pixels from entry `x0`: `x0, x0 + 1, ...`,
/// or a packed row's `pixels` (exact below 2^24).
#[inline(always)]
unsafe fn block_columns<V: Lanes>(pixels: Option<&[u32]>, x0: usize) -> V::F {
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        match pixels {
            None => V::columns(x0),
            Some(p) => V::to_float(V::load_u32(&p[x0..])),
        }
    }
}

/// Adds the block's sums times the pixels' weights `pw` (the scalar loop's
/// `weight * sum`) into `out` (entries `x0..x0 + N`, interleaved): pixels
/// `x0..x0 + N`, or a packed row's `pixels` there.
#[inline(always)]
unsafe fn add_out<V: Lanes, const C: usize>(
    acc: &[V::F; C],
    pw: V::F,
    (out, pixels): (&mut [f32], Option<&[u32]>),
    x0: usize,
) {
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let mut acc = *acc;
        for a in &mut acc {
            *a = V::mul(pw, *a);
        }
        if let Some(p) = pixels {
            // lane by lane, the lanes of weight zero (a packed row's
            // padding) skipped as the scalar loop skips those pixels
            let sums = spill::<V, C>(&acc);
            let [weights] = spill::<V, 1>(&[pw]);
            for (lane, &x) in p[x0..x0 + V::N].iter().enumerate() {
                if weights.as_ref()[lane] == 0.0 {
                    continue;
                }
                let px = &mut out[x as usize * C..(x as usize + 1) * C];
                for (o, s) in px.iter_mut().zip(&sums) {
                    *o += s.as_ref()[lane];
                }
            }
            return;
        }
        let acc = &acc;
        if C == 1 {
            let dst = &mut out[x0..x0 + V::N];
            V::store(V::add(V::load(dst), acc[0]), dst);
            return;
        }
        let sums = spill::<V, C>(acc);
        let dst = &mut out[x0 * C..(x0 + V::N) * C];
        for (lane, px) in dst.chunks_exact_mut(C).enumerate() {
            for (o, s) in px.iter_mut().zip(&sums) {
                *o += s.as_ref()[lane];
            }
        }
    }
}

/// One lookup of level `li` per lane through the scalar, border-resolving
/// path, each with its weight in `w` (lanes of weight 0 skipped), in lane
/// order.
#[inline(always)]
unsafe fn scalar_lanes<V: Lanes, const C: usize>(
    stack: &ScaleStack,
    li: usize,
    (px, py): (V::F, V::F),
    w: V::F,
    acc: &[V::F; C],
) -> [V::F; C] {
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let (mut pxs, mut pys, mut ws) = (
            V::Floats::default(),
            V::Floats::default(),
            V::Floats::default(),
        );
        V::store(px, pxs.as_mut());
        V::store(py, pys.as_mut());
        V::store(w, ws.as_mut());
        let mut sums = spill::<V, C>(acc);
        lanes_level::<C, _>(
            stack,
            li,
            (pxs.as_ref(), pys.as_ref(), ws.as_ref()),
            &mut sums,
        );
        fill::<V, C>(&sums)
    }
}

/// [`scalar_lanes`]' loop (plain scalar code, out of line: the rare path
/// of blocks at the borders).
#[inline(never)]
fn lanes_level<const C: usize, A: AsRef<[f32]> + AsMut<[f32]>>(
    stack: &ScaleStack,
    li: usize,
    (px, py, w): (&[f32], &[f32], &[f32]),
    sums: &mut [A; C],
) {
    for lane in 0..px.len() {
        if w[lane] != 0.0 {
            let mut s: [f32; C] = std::array::from_fn(|k| sums[k].as_ref()[lane]);
            stack.accumulate_fixed::<C>(li, px[lane], py[lane], w[lane], &mut s);
            for (sum, v) in sums.iter_mut().zip(s) {
                sum.as_mut()[lane] = v;
            }
        }
    }
}

/// A block of term `t` whose lanes spread over more levels than [`SPAN`]:
/// each lane's one or two lookups in the scalar loop's order.
#[inline(never)]
fn lanes_levels<const C: usize, A: AsRef<[f32]> + AsMut<[f32]>>(
    stack: &ScaleStack,
    (levels, t, x0): (&RowLevels, &ScaledTerm, usize),
    (px, py): (&[f32], &[f32]),
    sums: &mut [A; C],
) {
    for lane in 0..px.len() {
        let (a, b, wa, wb) = levels.at(t.group, x0 + lane);
        let mut s: [f32; C] = std::array::from_fn(|k| sums[k].as_ref()[lane]);
        stack.accumulate_fixed::<C>(a, px[lane], py[lane], t.weight * wa, &mut s);
        if wb != 0.0 {
            stack.accumulate_fixed::<C>(b, px[lane], py[lane], t.weight * wb, &mut s);
        }
        for (sum, v) in sums.iter_mut().zip(s) {
            sum.as_mut()[lane] = v;
        }
    }
}
