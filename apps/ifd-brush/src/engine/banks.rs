//! The decomposition banks the smoother needs (aspect ratios, Hessian
//! filters), fitted once and cached on disk.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;
use ifd_smooth::{AspectBank, BankOptions, HessianBank};

/// The decompositions in use and what the UI shows about them.
#[derive(Clone, Debug)]
pub struct Banks {
    /// Anisotropic Gaussians over aspect ratio.
    pub aspect: Arc<AspectBank>,
    /// Second-derivative filters for the Hessian.
    pub hessian: Arc<HessianBank>,
    /// Summary for the decomposition panel.
    pub info: BankInfo,
}

/// Number of terms and fit error of each decomposition.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BankInfo {
    /// Tabulated aspect ratios.
    pub aspects: Vec<f64>,
    /// Terms of each entry.
    pub terms: Vec<usize>,
    /// Relative L2 error of each entry against its sampled Gaussian.
    pub errors: Vec<f64>,
    /// Terms of the `xx` and `xy` Hessian filters.
    pub hessian_terms: [usize; 2],
    /// Where the aspect bank came from (a file, or "fitted").
    pub source: String,
}

/// Fit tolerance of the Hessian filters.
pub(super) const HESSIAN_TOL: f64 = 0.01;

impl Banks {
    /// Loads the aspect bank from `cache` when it holds a valid one with the
    /// default options, else fits it (a few seconds; `progress(done, total)`)
    /// and writes it there; fits the Hessian filters.
    ///
    /// # Errors
    /// Failed fits. A cache that cannot be written is not an error.
    pub fn load_or_build(
        cache: Option<&Path>,
        mut progress: impl FnMut(usize, usize),
    ) -> anyhow::Result<Self> {
        let (aspect, source) =
            AspectBank::load_or_build(BankOptions::default(), cache, &mut progress)
                .context("fitting the aspect bank")?;
        let hessian = HessianBank::new(HESSIAN_TOL).context("fitting the Hessian filters")?;
        let errors = aspect
            .aspects
            .iter()
            .map(|&a| aspect.blend_error(a).unwrap_or(f64::NAN))
            .collect();
        let info = BankInfo {
            aspects: aspect.aspects.clone(),
            terms: aspect.terms.iter().map(Vec::len).collect(),
            errors,
            hessian_terms: [hessian.xx.terms.len(), hessian.xy.terms.len()],
            source,
        };
        Ok(Self {
            aspect: Arc::new(aspect),
            hessian: Arc::new(hessian),
            info,
        })
    }

    /// The default cache file ([`AspectBank::default_cache`], shared with
    /// `ifd smooth`).
    #[must_use]
    pub fn default_cache() -> Option<PathBuf> {
        AspectBank::default_cache()
    }
}
