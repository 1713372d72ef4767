//! Code only the reproductions of the papers' tables and figures need, kept
//! out of the product crates (its binary, `ifd-paper`, is their front end).
//!
//! - [`convergence`]: ISD Fig. 4, the error of ISD shading and of its SH
//!   reference against the exact texel quadrature as `L` grows, as CSV and a
//!   plot.
//! - [`condition`]: ISD Fig. 13, the condition number of the ISD matrix
//!   per profile and degree, and its plot.
//! - [`sparsity`]: ZHF Table I and Fig. 3, the genetic search for lobe
//!   directions that make the factorisation sparse.
//! - [`visibility`]: ISD Fig. 7, self-shadowed ISD on a mesh against its
//!   ray-traced reference as `L` grows.
//! - [`mirror`]: ISD Fig. 6, anti-aliased reflections off a bumpy mirror
//!   sphere, ISD's filter against supersampling.
//! - [`shrm`], [`shrm_general`]: SHRM Tables 4 and 5, prefiltering in angular
//!   against frequency space (Phong; the microfacet BRDF of its Eq. 11), timed
//!   side by side.
//!
//! The product crates do not depend on this crate, nor on `ifd-plot` for a
//! study's figure.

pub mod condition;
pub mod convergence;
pub mod mirror;
pub mod shrm;
pub mod shrm_general;
pub mod sparsity;
pub mod visibility;

/// An invalid parameter of a study, as `ifd-ibl` reports its own.
pub(crate) fn param(what: &'static str, why: impl Into<String>) -> ifd_ibl::IblError {
    ifd_ibl::IblError::Param {
        what,
        why: why.into(),
    }
}
