//! A decomposition checked once for filtering, shared by every evaluation
//! path: the CPU [`crate::Filter`], the stack plan
//! ([`crate::stack_plan_for_decomposition`]), the evaluation plan
//! ([`crate::EvalPlan::choose`]) and the GPU's `GpuDecomposition`.

use std::borrow::Cow;

use crate::decomposition::Decomposition;
use crate::error::FilterError;
use crate::kernel::Sampling;
use crate::term::Term;

/// A decomposition whose terms are all finite with positive sigmas, with at
/// least one term, and the numbers every evaluation path needs from them.
///
/// A decomposition checked once for filtering, shared by every evaluation
/// path: the CPU [`crate::Filter`], the stack plan
/// ([`crate::stack_plan_for_decomposition`]), the evaluation plan
/// ([`crate::EvalPlan::choose`]) and the GPU's `GpuDecomposition`.
///
/// Each of them takes anything that is [`Prepare`]: a [`Decomposition`] is
/// checked where it is passed, a [`PreparedDecomposition`] is borrowed as it
/// is. A program that filters with one decomposition on several paths
/// prepares it once.
///
/// ```
/// use ifd_planar::{Decomposition, Prepare, PreparedDecomposition, Term};
/// let d = Decomposition::from_terms(vec![
///     Term { weight: 0.5, x: 3.0, y: -4.0, sigma: 1.0 },
///     Term { weight: 0.5, x: 0.0, y: 0.0, sigma: 2.0 },
/// ]);
/// let p = PreparedDecomposition::new(&d)?;
/// assert_eq!((p.len(), p.sigma_range(), p.reach()), (2, (1.0, 2.0), 5.0));
/// // A bad term is refused once, with its index.
/// let bad = Decomposition::from_terms(vec![Term { weight: 1.0, x: 0.0, y: 0.0, sigma: 0.0 }]);
/// assert!(bad.prepare().unwrap_err().to_string().contains("term 0"));
/// # Ok::<(), ifd_planar::FilterError>(())
/// ```
#[derive(Clone, Debug)]
pub struct PreparedDecomposition {
    terms: Vec<Term>,
    sampling: Sampling,
    sigma_range: (f64, f64),
    reach: f64,
}

impl PreparedDecomposition {
    /// Checks `decomposition`'s terms.
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] for a decomposition without terms,
    /// [`FilterError::InvalidTerm`] (with its index) for a non-finite value
    /// or a sigma `<= 0`.
    pub fn new(decomposition: &Decomposition) -> Result<Self, FilterError> {
        Self::from_terms(&decomposition.terms, decomposition.sampling)
    }

    /// As [`PreparedDecomposition::new`], for terms and the [`Sampling`]
    /// they are applied with.
    ///
    /// # Errors
    /// As [`PreparedDecomposition::new`].
    pub fn from_terms(terms: &[Term], sampling: Sampling) -> Result<Self, FilterError> {
        if terms.is_empty() {
            return Err(FilterError::InvalidParameter(
                "the decomposition has no terms".into(),
            ));
        }
        let mut sigma_range = (f64::INFINITY, 0.0f64);
        let mut reach = 0.0f64;
        for (index, t) in terms.iter().enumerate() {
            if !(t.weight.is_finite() && t.x.is_finite() && t.y.is_finite() && t.sigma.is_finite())
            {
                return Err(FilterError::InvalidTerm {
                    index,
                    why: format!("non-finite value in {t:?}"),
                });
            }
            if t.sigma <= 0.0 {
                return Err(FilterError::InvalidTerm {
                    index,
                    why: format!("sigma {} is not positive", t.sigma),
                });
            }
            sigma_range = (sigma_range.0.min(t.sigma), sigma_range.1.max(t.sigma));
            // In f32, as the evaluation holds the centres.
            reach = reach.max(f64::from(t.x as f32).hypot(f64::from(t.y as f32)));
        }
        Ok(Self {
            terms: terms.to_vec(),
            sampling,
            sigma_range,
            reach,
        })
    }

    /// The same terms applied with another [`Sampling`] (the smoother's
    /// bank: [`Sampling::Averaged`]).
    #[must_use]
    pub fn with_sampling(mut self, sampling: Sampling) -> Self {
        self.sampling = sampling;
        self
    }

    /// The terms.
    #[must_use]
    pub fn terms(&self) -> &[Term] {
        &self.terms
    }

    /// Number of terms (at least one).
    #[must_use]
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// Always false: a prepared decomposition has at least one term.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// How the terms' atoms are applied at a scale
    /// ([`Sampling::effective_sigma`]).
    #[must_use]
    pub fn sampling(&self) -> Sampling {
        self.sampling
    }

    /// The smallest and the largest term sigma (px, before scaling).
    #[must_use]
    pub fn sigma_range(&self) -> (f64, f64) {
        self.sigma_range
    }

    /// The largest distance of a term's centre from the origin (px, before
    /// scaling).
    #[must_use]
    pub fn reach(&self) -> f64 {
        self.reach
    }
}

/// A decomposition as the evaluation paths take it: checked on the way in
/// ([`Decomposition`]) or already ([`PreparedDecomposition`]).
pub trait Prepare {
    /// The checked decomposition, borrowed when it already is one.
    ///
    /// # Errors
    /// As [`PreparedDecomposition::new`].
    fn prepare(&self) -> Result<Cow<'_, PreparedDecomposition>, FilterError>;
}

impl Prepare for Decomposition {
    fn prepare(&self) -> Result<Cow<'_, PreparedDecomposition>, FilterError> {
        PreparedDecomposition::new(self).map(Cow::Owned)
    }
}

impl Prepare for PreparedDecomposition {
    fn prepare(&self) -> Result<Cow<'_, PreparedDecomposition>, FilterError> {
        Ok(Cow::Borrowed(self))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn term(weight: f64, sigma: f64) -> Term {
        Term {
            weight,
            x: 0.0,
            y: 0.0,
            sigma,
        }
    }

    #[test]
    fn refuses_what_no_path_can_evaluate() {
        let e = PreparedDecomposition::from_terms(&[], Sampling::Continuous).unwrap_err();
        assert!(e.to_string().contains("no terms"), "{e}");
        let e = PreparedDecomposition::from_terms(
            &[term(1.0, 1.0), term(f64::NAN, 1.0)],
            Sampling::Continuous,
        )
        .unwrap_err();
        assert!(
            matches!(e, FilterError::InvalidTerm { index: 1, .. }),
            "{e}"
        );
        let e = PreparedDecomposition::from_terms(&[term(1.0, -2.0)], Sampling::Continuous)
            .unwrap_err();
        assert!(e.to_string().contains("sigma -2 is not positive"), "{e}");
    }

    #[test]
    fn prepared_is_borrowed_decomposition_is_checked() {
        let d = Decomposition::from_terms(vec![term(1.0, 2.0)]);
        let p = d.prepare().unwrap();
        assert!(matches!(p, Cow::Owned(_)));
        let p = p.into_owned();
        assert!(matches!(p.prepare().unwrap(), Cow::Borrowed(_)));
        assert_eq!(p.sampling(), d.sampling);
    }
}
