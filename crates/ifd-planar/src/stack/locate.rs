//! Locating a sigma among the levels: the bracketing pair and its weights,
//! snapped to a level within `LEVEL_SNAP`.

/// Locates sigmas among the levels of a [`ScaleStack`](super::ScaleStack)
/// ([`ScaleStack::locator`](super::ScaleStack::locator)) exactly as the stack's own lookups do.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelLocator {
    pub(super) ln_sigma0: f64,
    pub(super) inv_ln_ratio: f64,
    pub(super) ln_sigmas: Vec<f64>,
}

impl LevelLocator {
    /// `(a, b, wa, wb)`: the levels bracketing `sigma` and their weights,
    /// linear in `ln sigma`, clamped to the levels; a sigma on a level (to a
    /// relative 1e-6 of the spacing) reads that level alone (`b == a`,
    /// `wb == 0`).
    #[must_use]
    pub fn locate(&self, sigma: f64) -> (usize, usize, f32, f32) {
        locate_in(
            self.ln_sigma0,
            self.inv_ln_ratio,
            &self.ln_sigmas,
            sigma.ln(),
        )
    }

    /// Whether the levels are log-uniformly spaced ([`ScaleStack::is_uniform`](super::ScaleStack::is_uniform)).
    #[must_use]
    pub fn is_uniform(&self) -> bool {
        !self.inv_ln_ratio.is_nan()
    }
}

/// [`ScaleStack::locate_ln`] on its parts.
pub(super) fn locate_in(
    ln_sigma0: f64,
    inv_ln_ratio: f64,
    ln_sigmas: &[f64],
    ln_sigma: f64,
) -> (usize, usize, f32, f32) {
    let n = ln_sigmas.len() - 1;
    if n == 0 {
        return (0, 0, 1.0, 0.0);
    }
    if inv_ln_ratio.is_nan() {
        // Levels at given sigmas: the bracketing pair by bisection, linear
        // in ln sigma between them (exact on a level, to 1e-9).
        let l = ln_sigmas;
        let i = l.partition_point(|&v| v <= ln_sigma).clamp(1, n) - 1;
        let f = ((ln_sigma - l[i]) / (l[i + 1] - l[i])).clamp(0.0, 1.0);
        return snapped(i, f);
    }
    let t = ((ln_sigma - ln_sigma0) * inv_ln_ratio).clamp(0.0, n as f64);
    let i = (t.floor() as usize).min(n - 1);
    snapped(i, t - i as f64)
}

/// [`snap_to_level`] with `usize` levels.
fn snapped(i: usize, f: f64) -> (usize, usize, f32, f32) {
    let (a, b, wa, wb) = snap_to_level(i as u32, f);
    (a as usize, b as usize, wa, wb)
}

/// Within this fraction of a level's spacing (in ln sigma), a sigma is
/// read from that level alone: one lookup instead of two, for an error of at
/// most this fraction of the difference between neighbouring levels. Sigmas
/// that are levels up to rounding (a decomposition's sigmas on a stack built
/// for them, or on a log-uniform stack whose ratio they share) then cost one
/// lookup per term.
pub(crate) const LEVEL_SNAP: f64 = 1e-6;

/// `(a, b, wa, wb)` for position `i + f` (`0 <= f <= 1`) between levels `i`
/// and `i + 1`, snapped to a level within [`LEVEL_SNAP`]: then `wb == 0`
/// (and `b == a`), so callers that skip zero weights do one lookup. Written
/// with selects, no branches (`gather::fill_levels` writes the same
/// selects in AVX2 lanes); 32-bit levels (a stack has a few dozen).
#[inline]
fn snap_to_level(i: u32, f: f64) -> (u32, u32, f32, f32) {
    let (lo, hi) = (f < LEVEL_SNAP, f > 1.0 - LEVEL_SNAP);
    let a = if hi { i + 1 } else { i };
    let b = if lo { i } else { i + 1 };
    let snapped = lo || hi;
    let wa = if snapped { 1.0 } else { (1.0 - f) as f32 };
    let wb = if snapped { 0.0 } else { f as f32 };
    (a, b, wa, wb)
}

/// The per-pixel level rule of one sigma on a log-uniform stack of several
/// levels, for a per-pixel scale `s`: position `t_s + (ln sigma + ln w) /
/// ln r` among the levels (`t_s = (ln s - ln sigma_0) / ln r`, `w =
/// sigma_eff / (s sigma)` the pixel footprint's widening,
/// [`crate::kernel::ln_widening`] of `widen = footprint variance / s^2`
/// times `1 / sigma^2`), clamped, then bracketed and snapped by
/// [`snap_to_level`], branch-free. The scalar loop ([`Self::at`]) and
/// the vector path's rows (`gather::fill_levels`: [`Self::series`] over the
/// row, then [`Self::at`] again where the widening needs its logarithm)
/// take the same values bit for bit (the rows write the series and the
/// bracket's operations in AVX2 lanes, in the same order).
#[derive(Clone, Copy, Debug)]
pub(crate) struct LevelRule {
    /// `ln sigma`.
    pub(crate) ln_sigma: f64,
    /// `1 / sigma^2`.
    pub(crate) inv_sigma2: f64,
    /// `1 / ln r`.
    pub(crate) inv: f64,
    /// The last level's index (at least 1).
    pub(crate) last: u32,
}

impl LevelRule {
    /// `(a, b, wa, wb)` at `t_s` and `widen`.
    #[inline]
    pub(crate) fn at(self, t_s: f64, widen: f64) -> (u32, u32, f32, f32) {
        if widen == 0.0 {
            // the series is 0 here: `ln sigma + 0` is `ln sigma`, the same bits
            return self.bracket(t_s + self.ln_sigma * self.inv);
        }
        let x = widen * self.inv_sigma2;
        if crate::kernel::widening_needs_log(x) {
            self.bracket(t_s + (self.ln_sigma + crate::kernel::ln_widening(x)) * self.inv)
        } else {
            self.series(t_s, widen)
        }
    }

    /// [`Self::at`] where the widening takes its series (branch-free, for
    /// vector lanes).
    #[inline]
    pub(crate) fn series(self, t_s: f64, widen: f64) -> (u32, u32, f32, f32) {
        let lw = crate::kernel::ln_widening_series(widen * self.inv_sigma2);
        self.bracket(t_s + (self.ln_sigma + lw) * self.inv)
    }

    /// The levels bracketing position `u` and their weights: [`snap_to_level`]
    /// of `u` clamped to the levels.
    #[inline]
    fn bracket(self, u: f64) -> (u32, u32, f32, f32) {
        let u = u.clamp(0.0, f64::from(self.last));
        // 32-bit conversions (vector lanes convert 32-bit integers)
        let i = (u as u32).min(self.last - 1);
        snap_to_level(i, u - f64::from(i))
    }
}
