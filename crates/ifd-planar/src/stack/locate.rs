//! Locating a sigma among the levels: the bracketing pair and its weights,
//! snapped to a level within `LEVEL_SNAP` (`PIXEL_SNAP` for the per-pixel
//! rule's `f32` positions), and where a per-pixel scale puts the levels.

/// Locates sigmas among the levels of a [`ScaleStack`](super::ScaleStack)
/// ([`ScaleStack::locator`](super::ScaleStack::locator)) exactly as the stack's own lookups do.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelLocator {
    pub(super) ln_sigma0: f64,
    pub(super) inv_ln_ratio: f64,
    pub(super) ln_sigmas: Vec<f64>,
    /// Within this fraction of the spacing a sigma reads one level:
    /// [`LEVEL_SNAP`], or [`NEAREST_SNAP`] for a stack read at the nearest
    /// level ([`StackOptions::nearest_level`](super::StackOptions::nearest_level)).
    pub(super) snap: f64,
}

impl LevelLocator {
    /// The locator of levels at `sigmas` (increasing, at least one):
    /// log-uniformly spaced (`uniform`: a position is one multiply away) or
    /// not (bisection); `nearest`: a sigma reads the level nearest it in
    /// `ln sigma` alone ([`NEAREST_SNAP`]) instead of blending the two
    /// around it.
    pub(crate) fn new(sigmas: &[f64], uniform: bool, nearest: bool) -> Self {
        let ln_sigmas: Vec<f64> = sigmas.iter().map(|s| s.ln()).collect();
        let ln_sigma0 = ln_sigmas[0];
        let inv_ln_ratio = if !uniform {
            f64::NAN
        } else if sigmas.len() > 1 {
            (sigmas.len() - 1) as f64 / (ln_sigmas[sigmas.len() - 1] - ln_sigma0)
        } else {
            0.0
        };
        Self {
            ln_sigma0,
            inv_ln_ratio,
            ln_sigmas,
            snap: if nearest { NEAREST_SNAP } else { LEVEL_SNAP },
        }
    }

    /// `(a, b, wa, wb)`: the levels bracketing `sigma` and their weights,
    /// linear in `ln sigma`, clamped to the levels; a sigma on a level (to a
    /// relative 1e-6 of the spacing) reads that level alone (`b == a`,
    /// `wb == 0`), as does every sigma on a stack read at the nearest level
    /// (but for one exactly half-way, which takes both halves).
    #[must_use]
    pub fn locate(&self, sigma: f64) -> (usize, usize, f32, f32) {
        self.locate_ln(sigma.ln())
    }

    /// [`Self::locate`] of `exp(ln_sigma)`.
    pub(crate) fn locate_ln(&self, ln_sigma: f64) -> (usize, usize, f32, f32) {
        let (n, snap) = (self.ln_sigmas.len() - 1, self.snap);
        if n == 0 {
            return (0, 0, 1.0, 0.0);
        }
        let (i, f) = if self.inv_ln_ratio.is_nan() {
            // Levels at given sigmas: the bracketing pair by bisection,
            // linear in ln sigma between them (exact on a level, to 1e-9).
            let l = &self.ln_sigmas;
            let i = l.partition_point(|&v| v <= ln_sigma).clamp(1, n) - 1;
            (i, ((ln_sigma - l[i]) / (l[i + 1] - l[i])).clamp(0.0, 1.0))
        } else {
            let t = ((ln_sigma - self.ln_sigma0) * self.inv_ln_ratio).clamp(0.0, n as f64);
            let i = (t.floor() as usize).min(n - 1);
            (i, t - i as f64)
        };
        let (a, b, wa, wb) = snap_to_level(i as u32, f, snap);
        (a as usize, b as usize, wa, wb)
    }

    /// Whether a sigma reads the level nearest it alone
    /// ([`StackOptions::nearest_level`](super::StackOptions::nearest_level)).
    #[must_use]
    pub fn reads_nearest_level(&self) -> bool {
        self.snap == NEAREST_SNAP
    }

    /// Whether the levels are log-uniformly spaced ([`ScaleStack::is_uniform`](super::ScaleStack::is_uniform)).
    #[must_use]
    pub fn is_uniform(&self) -> bool {
        !self.inv_ln_ratio.is_nan()
    }
}

/// Within this fraction of a level's spacing (in ln sigma), a sigma is
/// read from that level alone: one lookup instead of two, for an error of at
/// most this fraction of the difference between neighbouring levels. Sigmas
/// that are levels up to rounding (a decomposition's sigmas on a stack built
/// for them, or on a log-uniform stack whose ratio they share) then cost one
/// lookup per term.
pub(crate) const LEVEL_SNAP: f64 = 1e-6;

/// The snap of a stack read at the nearest level
/// ([`StackOptions::nearest_level`](super::StackOptions::nearest_level)): every
/// position within half a spacing of a level, that is every position but one
/// exactly half-way between two (which takes both, half each), reads one
/// level.
pub(crate) const NEAREST_SNAP: f64 = 0.5;

/// `(a, b, wa, wb)` for position `i + f` (`0 <= f <= 1`) between levels `i`
/// and `i + 1`, snapped to a level within `snap` ([`LEVEL_SNAP`] or
/// [`NEAREST_SNAP`]): then `wb == 0` (and `b == a`), so callers that skip
/// zero weights do one lookup. Written with selects, no branches (the
/// per-pixel [`LevelRule`] makes the same selects on `f32` positions);
/// 32-bit levels (a stack has a few dozen).
#[inline]
fn snap_to_level(i: u32, f: f64, snap: f64) -> (u32, u32, f32, f32) {
    let (lo, hi) = (f < snap, f > 1.0 - snap);
    let a = if hi { i + 1 } else { i };
    let b = if lo { i } else { i + 1 };
    let snapped = lo || hi;
    let wa = if snapped { 1.0 } else { (1.0 - f) as f32 };
    let wb = if snapped { 0.0 } else { f as f32 };
    (a, b, wa, wb)
}

/// Within this fraction of a level's spacing, the per-pixel level rule
/// ([`LevelRule`]) reads a position from that level alone. Its positions
/// are `f32` sums of a few rounded terms, a few units of `2^-23` times the
/// level index (at most a few dozen) off, so its snap is wider than
/// [`LEVEL_SNAP`]: a sigma on a level up to that rounding still costs one
/// lookup, for an error of at most this fraction of the difference between
/// neighbouring levels.
pub(crate) const PIXEL_SNAP: f32 = 3e-5;

/// How far (in level spacings) [`LevelRule::levels_read`] moves the ends
/// of a range of positions out: far above their rounding (`1e-6`), far
/// below a spacing.
const READ_SLACK: f32 = 1e-3;

/// Where a per-pixel scale `s` puts the levels of a log-uniform stack, in
/// `f32`: `t_s = (ln s - ln sigma_0) / ln r` and `widen`, the pixel
/// footprint's variance at `s` over `s^2`
/// ([`Sampling::footprint_variance`](crate::Sampling::footprint_variance)),
/// the two per-pixel inputs of [`LevelRule`]. One sequence of operations
/// ([`crate::ln::ln`], then a multiply and an add; a division for the
/// widening) that the scalar loop ([`Self::at`]) and the vector rows
/// (`rows::rules::scale_positions`, in vector lanes) both follow.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ScalePosition {
    /// `ln sigma_0`.
    pub(crate) ln0: f32,
    /// `1 / ln r`.
    pub(crate) inv: f32,
    /// `widen = var / s^2 + shift` for `s < below`, 0 from `below` on.
    pub(crate) var: f32,
    pub(crate) shift: f32,
    pub(crate) below: f32,
}

impl ScalePosition {
    /// The rule for `sampling` on a stack with `(ln sigma_0, 1 / ln r)`.
    pub(crate) fn new(sampling: crate::Sampling, (ln0, inv): (f64, f64)) -> Self {
        let (var, shift, below) = sampling.footprint_over_s2();
        Self {
            ln0: ln0 as f32,
            inv: inv as f32,
            var: var as f32,
            shift: shift as f32,
            below: below as f32,
        }
    }

    /// `(t_s, widen)` at scale `s`.
    #[inline]
    pub(crate) fn at(self, s: f32) -> (f32, f32) {
        let t_s = (crate::ln::ln(s) - self.ln0) * self.inv;
        let widen = if s < self.below {
            self.var / (s * s) + self.shift
        } else {
            0.0
        };
        (t_s, widen)
    }
}

/// The per-pixel level rule of one sigma on a log-uniform stack of several
/// levels, for a per-pixel scale `s`: position `t_s + (ln sigma + ln w) /
/// ln r` among the levels (`t_s` and `widen` from [`ScalePosition`], `w =
/// sigma_eff / (s sigma)` the pixel footprint's widening,
/// [`crate::kernel::ln_widening`] of `widen` times `1 / sigma^2`),
/// clamped, then bracketed and snapped within `snap`, branch-free,
/// all in `f32` (the positions' rounding moves a weight by about `1e-6`,
/// below what the `f32` weights carry anyway past a few levels). The
/// scalar loop ([`Self::at`]) and the vector path's rows
/// (`rows::rules::fill_levels`: the widening's series, or in the lanes
/// that need it its logarithm, then the bracket, [`Self::at`]'s
/// operations in its order) take the same values bit for bit; the pixels
/// a row's vectors leave take [`Self::at`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct LevelRule {
    /// `ln sigma`.
    pub(crate) ln_sigma: f32,
    /// `1 / sigma^2`.
    pub(crate) inv_sigma2: f32,
    /// `1 / ln r`.
    pub(crate) inv: f32,
    /// The last level's index (at least 1).
    pub(crate) last: u32,
    /// Within this fraction of the spacing a position reads one level:
    /// [`PIXEL_SNAP`], or `0.5` ([`NEAREST_SNAP`]) on a stack read at the
    /// nearest level.
    pub(crate) snap: f32,
}

impl LevelRule {
    /// `(a, b, wa, wb)` at `t_s` and `widen`.
    #[inline]
    pub(crate) fn at(self, t_s: f32, widen: f32) -> (u32, u32, f32, f32) {
        let lw = crate::kernel::ln_widening(widen * self.inv_sigma2);
        self.bracket(t_s + (self.ln_sigma + lw) * self.inv)
    }

    /// The position among the levels that [`Self::at`] brackets.
    #[inline]
    pub(crate) fn position(self, t_s: f32, widen: f32) -> f32 {
        let lw = crate::kernel::ln_widening(widen * self.inv_sigma2);
        t_s + (self.ln_sigma + lw) * self.inv
    }

    /// The first and the last level read at any position in `[u_lo, u_hi]`
    /// ([`Self::position`]s): the bracket's levels grow with the position,
    /// so these are the lower level at `u_lo` and the upper at `u_hi`, each
    /// position moved out by [`READ_SLACK`] of a spacing for the rounding
    /// of positions between them (a position of the scalar loop or of the
    /// vector rows, `f32`, a few `1e-6` off).
    pub(crate) fn levels_read(self, u_lo: f32, u_hi: f32) -> (u32, u32) {
        (
            self.bracket(u_lo - READ_SLACK).0,
            self.bracket(u_hi + READ_SLACK).1,
        )
    }

    /// The levels bracketing position `u` and their weights: `u` clamped
    /// to the levels, the level below it (32-bit conversions: vector lanes
    /// convert 32-bit integers) and the fraction above that level, snapped
    /// within `snap` ([`PIXEL_SNAP`] or [`NEAREST_SNAP`]) as
    /// [`snap_to_level`] snaps within [`LEVEL_SNAP`] (or [`NEAREST_SNAP`]).
    #[inline]
    fn bracket(self, u: f32) -> (u32, u32, f32, f32) {
        let u = u.clamp(0.0, self.last as f32);
        let i = (u as u32).min(self.last - 1);
        let f = u - i as f32;
        let (lo, hi) = (f < self.snap, f > 1.0 - self.snap);
        let a = if hi { i + 1 } else { i };
        let b = if lo { i } else { i + 1 };
        let snapped = lo || hi;
        let wa = if snapped { 1.0 } else { 1.0 - f };
        let wb = if snapped { 0.0 } else { f };
        (a, b, wa, wb)
    }
}
