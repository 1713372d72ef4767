//! The per-pixel rules of the rows, written once over [`Lanes`] as the
//! lookups are ([`super::kernels`]): the rotations (`cs = s cos theta`,
//! `ss = s sin theta`), a scale map's level positions and each sigma group's
//! levels and weights, `N` pixels at a time, each the scalar rule operation
//! by operation (the same bits). Their `#[target_feature]` entry points are
//! made by the `entry_points!` macro of `kernels.rs`.
#![allow(
    unsafe_code,
    reason = "the bodies call `Lanes` primitives; see the `rows` module documentation"
)]
#![expect(
    clippy::inline_always,
    reason = "each body is compiled into the `#[target_feature]` entry points of each instruction set"
)]

use super::RowLevels;
use super::lanes::{Lanes, block_end};
use crate::field::Field;
use crate::kernel::{LOG_FROM, WIDENING_FLOOR};
use crate::stack::{LevelRule, ScalePosition};

/// `coef[0] + x (coef[1] + x (coef[2] + ...))`, Horner's rule from the last
/// coefficient, as the scalar rules evaluate their series.
#[inline(always)]
unsafe fn horner<V: Lanes>(x: V::F, coef: &[f32]) -> V::F {
    let (last, rest) = coef.split_last().expect("coefficients");
    // SAFETY: compiled for `V`'s instruction set (the caller's promise).
    unsafe {
        let mut acc = V::splat(*last);
        for &c in rest.iter().rev() {
            acc = V::add(V::splat(c), V::mul(x, acc));
        }
        acc
    }
}

/// `cs[x] = s cos theta[x]`, `ss[x] = s sin theta[x]` for the row's blocks
/// from `from`: [`crate::trig::sin_cos_degrees`] operation by operation,
/// times the row's scale.
///
/// # Safety
/// Compiled for `V`'s instruction set (see [`Lanes`]).
#[inline(always)]
pub(super) unsafe fn rotations<V: Lanes>(
    theta: &[f32],
    scale: Field<'_>,
    cs: &mut [f32],
    ss: &mut [f32],
    from: usize,
) -> usize {
    use crate::trig::{COS, INV_RIGHT_ANGLE, RADIANS_PER_DEGREE, SIN};
    let end = block_end::<V>(from, theta.len().min(cs.len()).min(ss.len()));
    // SAFETY: as the caller promises.
    unsafe {
        let k = |x: f32| V::splat(x);
        let (one, two) = (V::splat_i(1), V::splat_i(2));
        let (inv_right, right, radians) = (k(INV_RIGHT_ANGLE), k(90.0), k(RADIANS_PER_DEGREE));
        let unit = k(1.0);
        for x0 in (from..end).step_by(V::N) {
            let t = V::load(&theta[x0..]);
            // trig::sin_cos_degrees, operation by operation
            let q = V::round(V::mul(t, inv_right));
            let x = V::mul(V::sub(t, V::mul(q, right)), radians);
            let x2 = V::mul(x, x);
            let sp = V::add(x, V::mul(V::mul(x, x2), horner::<V>(x2, &SIN)));
            let cp = V::add(unit, V::mul(x2, horner::<V>(x2, &COS)));
            let qi = V::to_int(q);
            let swap = V::eq_i(V::and_i(qi, one), one);
            let (s, c) = (V::select(swap, cp, sp), V::select(swap, sp, cp));
            // bit 1 of q (of q + 1) moved to the sign bit negates the sine
            // (cosine)
            let s_sign = V::shl30(V::and_i(qi, two));
            let c_sign = V::shl30(V::and_i(V::add_i(qi, one), two));
            let s = V::from_bits(V::xor_i(V::to_bits(s), s_sign));
            let c = V::from_bits(V::xor_i(V::to_bits(c), c_sign));
            let sc = match scale {
                Field::Constant(v) => V::splat(v),
                Field::Map(m) => V::load(&m[x0..]),
            };
            V::store(V::mul(c, sc), &mut cs[x0..]);
            V::store(V::mul(s, sc), &mut ss[x0..]);
        }
    }
    end
}

/// [`crate::ln::ln`] of each lane, operation by operation: the split of
/// the bits and the series.
///
/// # Safety
/// Compiled for `V`'s instruction set (see [`Lanes`]).
#[inline(always)]
unsafe fn ln_lanes<V: Lanes>(x: V::F) -> V::F {
    use crate::ln::{ATANH, LN2_HI, LN2_LO, SQRT_HALF_BITS};
    // SAFETY: as the caller promises.
    unsafe {
        let sqrt_half = V::splat_i(SQRT_HALF_BITS as i32);
        let one = V::splat(1.0);
        let ix = V::sub_i(
            V::to_bits(V::max(x, V::splat(f32::MIN_POSITIVE))),
            sqrt_half,
        );
        let e = V::to_float(V::sra23(ix));
        let m = V::from_bits(V::add_i(V::and_i(ix, V::splat_i(0x007f_ffff)), sqrt_half));
        let f = V::div(V::sub(m, one), V::add(m, one));
        let z = V::mul(f, f);
        let r = V::add(f, f);
        let p = V::add(r, V::mul(V::mul(r, z), horner::<V>(z, &ATANH)));
        V::add(
            V::mul(e, V::splat(LN2_HI)),
            V::add(p, V::mul(e, V::splat(LN2_LO))),
        )
    }
}

/// Each pixel's `(t_s, widen)` of the row's `scales` by `rule` for the
/// blocks from `from`: [`ScalePosition::at`] operation by operation
/// ([`crate::ln::ln`]'s split of the bits and its series, then the
/// widening's division and select).
///
/// # Safety
/// Compiled for `V`'s instruction set (see [`Lanes`]).
#[inline(always)]
pub(super) unsafe fn scale_positions<V: Lanes>(
    rule: ScalePosition,
    scales: &[f32],
    t_s: &mut [f32],
    widen: &mut [f32],
    from: usize,
) -> usize {
    let end = block_end::<V>(from, scales.len().min(t_s.len()).min(widen.len()));
    // SAFETY: as the caller promises.
    unsafe {
        let k = |x: f32| V::splat(x);
        let (ln0, inv, var, shift, below) = (
            k(rule.ln0),
            k(rule.inv),
            k(rule.var),
            k(rule.shift),
            k(rule.below),
        );
        for x0 in (from..end).step_by(V::N) {
            let s = V::load(&scales[x0..]);
            let ln = ln_lanes::<V>(s);
            // ScalePosition::at
            let ts = V::mul(V::sub(ln, ln0), inv);
            let wd = V::add(V::div(var, V::mul(s, s)), shift);
            let wd = V::zero_unless(V::lt(s, below), wd);
            V::store(ts, &mut t_s[x0..]);
            V::store(wd, &mut widen[x0..]);
        }
    }
    end
}

/// Group `g`'s levels over the row's blocks from `from` by `rule`:
/// [`LevelRule::at`]'s operations in its order, the widening's series, or
/// its logarithm in the lanes that need it.
///
/// # Safety
/// Compiled for `V`'s instruction set (see [`Lanes`]).
#[inline(always)]
pub(super) unsafe fn fill_levels<V: Lanes>(
    rule: LevelRule,
    t_s: &[f32],
    widen: &[f32],
    levels: &mut RowLevels,
    g: usize,
    from: usize,
) -> usize {
    let w = levels.w;
    let base = g * w;
    let end = block_end::<V>(from, w.min(t_s.len()).min(widen.len()));
    // SAFETY: as the caller promises.
    unsafe {
        let k = |x: f32| V::splat(x);
        let (floor, needs_log) = (k(WIDENING_FLOOR), k(LOG_FROM));
        let (one, half, third, quarter) = (k(1.0), k(0.5), k(1.0 / 3.0), k(0.25));
        let (inv_sigma2, ln_sigma, inv) = (k(rule.inv_sigma2), k(rule.ln_sigma), k(rule.inv));
        let last = k(rule.last as f32);
        let below_last = V::splat_i((rule.last - 1) as i32);
        let (snap_lo, snap_hi) = (k(rule.snap), k(1.0 - rule.snap));
        let zero = V::zero();
        for x0 in (from..end).step_by(V::N) {
            let (ts, wd) = (V::load(&t_s[x0..]), V::load(&widen[x0..]));
            // kernel::ln_widening_series
            let x = V::max(V::mul(wd, inv_sigma2), floor);
            // kernel::widening_needs_log: |x| >= LOG_FROM
            let log_lanes = V::ge(V::abs(x), needs_log);
            let x2 = V::mul(x, x);
            let odd = V::mul(x, V::add(one, V::mul(x2, third)));
            let even = V::mul(x2, V::add(half, V::mul(x2, quarter)));
            let lw = V::mul(half, V::sub(odd, even));
            // kernel::ln_widening's logarithm where a lane needs it
            let lw = if V::any(log_lanes) {
                V::select(log_lanes, V::mul(half, ln_lanes::<V>(V::add(one, x))), lw)
            } else {
                lw
            };
            // LevelRule::bracket: the position, clamped (finite positions:
            // max/min are `clamp`), its level below, snapped
            let u = V::add(ts, V::mul(V::add(ln_sigma, lw), inv));
            let u = V::min(V::max(u, zero), last);
            let i = V::min_i(V::trunc_int(u), below_last);
            let f = V::sub(u, V::to_float(i));
            let hi = V::gt(f, snap_hi);
            let snapped = V::or_m(V::lt(f, snap_lo), hi);
            let a = V::inc_where(i, hi);
            let wa = V::select(snapped, one, V::sub(one, f));
            let wb = V::select(snapped, zero, f);
            let at = base + x0;
            V::store_u32(a, &mut levels.a[at..]);
            V::store(wa, &mut levels.wa[at..]);
            V::store(wb, &mut levels.wb[at..]);
        }
    }
    end
}
