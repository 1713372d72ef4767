//! The condition-number study of ISD Fig. 13 (`ifd paper isd-condition`):
//! [`condition_study`] computes the 2-norm condition number of the full ISD
//! matrix `M` (Eq. 17) for every [`Profile`], degrees `1..=L`, with per-band
//! and with shared Fibonacci directions. The plot of it is
//! `ifd_plot::condition_plot`.

use crate::error::Result;
use crate::profile::{Profile, isd_matrix};
use crate::zhf::{Chooser, DirectionSet, Sharing, condition_number};

/// Condition numbers at or above this (about `1 / f64::EPSILON`) count as singular.
pub const SINGULAR_COND: f64 = 1e16;

/// One curve of Fig. 13: `cond[i]` is the condition number of `M` at `L = i + 1`.
#[derive(Clone, Debug, PartialEq)]
pub struct ConditionSeries {
    /// The mother functions.
    pub profile: Profile,
    /// Per-band or shared directions.
    pub sharing: Sharing,
    /// Condition numbers for `L = 1, 2, ...` (infinite when singular).
    pub cond: Vec<f64>,
}

/// Whether a condition number is beyond what `f64` can resolve.
#[must_use]
pub fn is_singular(cond: f64) -> bool {
    !cond.is_finite() || cond >= SINGULAR_COND
}

/// Computes Fig. 13: every profile, per-band and shared Fibonacci directions,
/// `L = 1..=l_max`.
///
/// # Errors
/// [`crate::SphereError::IsdTooLarge`] above [`crate::profile::MAX_ISD_DEGREE`].
pub fn condition_study(l_max: usize) -> Result<Vec<ConditionSeries>> {
    crate::profile::check_isd_degree(l_max)?;
    let mut out = Vec::new();
    for profile in Profile::ALL {
        for sharing in [Sharing::PerBand, Sharing::Shared] {
            let mut cond = Vec::with_capacity(l_max);
            for l in 1..=l_max {
                let dirs = DirectionSet::new(l, sharing, Chooser::Fibonacci)?;
                let (m, _) = isd_matrix(profile, &dirs)?;
                cond.push(condition_number(&m));
            }
            out.push(ConditionSeries {
                profile,
                sharing,
                cond,
            });
        }
    }
    Ok(out)
}
