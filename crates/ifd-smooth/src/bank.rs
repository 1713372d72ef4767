//! Decompositions of anisotropic Gaussians tabulated over aspect ratio.
//!
//! The derivation and conventions are documented on [`AspectBank`].

use std::path::Path;

use ifd_planar::Sampling;
use ifd_planar::{DecomposeOptions, Decomposition, KernelSpec, Term, decompose};
use serde::{Deserialize, Serialize};

use crate::error::{SmoothError, check_range};

/// How the bank's Gaussians are applied: as their averages over each output
/// pixel ([`Sampling::Averaged`], atom variance plus `1/12` px^2), so that
/// the smoothing filter is the pixel-integrated Gaussian at every footprint
/// scale, as the directly evaluated small footprints ([`crate::DirectKernels`]) are.
pub const BANK_SAMPLING: Sampling = Sampling::Averaged;

/// How to build an [`AspectBank`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BankOptions {
    /// Largest tabulated aspect ratio (1..=16).
    pub max_aspect: f64,
    /// Entries per doubling of the aspect ratio.
    pub steps_per_octave: usize,
    /// Geometric-mean sigma of every entry, in pixels.
    pub sigma_ref: f64,
    /// Target relative L2 error of each decomposition.
    pub tol: f64,
}

impl Default for BankOptions {
    fn default() -> Self {
        Self {
            max_aspect: 16.0,
            steps_per_octave: 2,
            sigma_ref: 6.0,
            tol: 0.01,
        }
    }
}

/// Aspect ratios from 1 to `max_aspect`, log-spaced with at least
/// `per_octave` per doubling, both ends included (`[1]` when `max_aspect`
/// is 1).
///
/// ```
/// let a = ifd_smooth::log_spaced_aspects(16.0, 2.0);
/// assert_eq!(a.len(), 9);
/// assert!((a[1] - 2f64.sqrt()).abs() < 1e-12 && (a[8] - 16.0).abs() < 1e-12);
/// ```
#[must_use]
pub fn log_spaced_aspects(max_aspect: f64, per_octave: f64) -> Vec<f64> {
    let octaves = max_aspect.max(1.0).log2();
    let n = (octaves * per_octave).ceil() as usize + 1;
    (0..n)
        .map(|i| {
            if n == 1 {
                1.0
            } else {
                2f64.powf(octaves * i as f64 / (n - 1) as f64)
            }
        })
        .collect()
}

/// The entry `i` below aspect ratio `a` in log-spaced `aspects` and the
/// blend weight `t` of entry `i + 1` (linear in `log a`, clamped to the
/// table; `(0, 0)` for one entry, `a <= 1` or NaN).
#[must_use]
pub fn locate_aspect(aspects: &[f64], a: f64) -> (usize, f64) {
    let n = aspects.len();
    if n < 2 || !a.is_finite() || a <= 1.0 {
        return (0, 0.0);
    }
    let top = aspects[n - 1];
    let la = a.min(top).ln();
    let step = top.ln() / (n - 1) as f64;
    let f = (la / step).clamp(0.0, (n - 1) as f64);
    let i = (f.floor() as usize).min(n - 2);
    (i, f - i as f64)
}

/// Decompositions of `gauss:sx=sigma_ref sqrt(a),sy=sigma_ref/sqrt(a)` for
/// log-spaced aspect ratios `a`.
///
/// Entry `i` is the decomposition of the Gaussian with standard deviations
/// `sx = sigma_ref sqrt(a_i)`, `sy = sigma_ref / sqrt(a_i)` along `x` and `y`
/// (`sx sy = sigma_ref^2`: every entry has the same footprint area, and an
/// anisotropic Gaussian with `sx sy = S^2` attenuates white noise exactly as
/// much as an isotropic one of sigma `S`, since `sum k^2 = 1 / (4 pi sx sy)`).
/// The aspect ratios `a_i` are log-spaced from 1 to `max_aspect`.
///
/// Between entries the weights are blended linearly in `log a`: filtering is
/// linear, so `(1 - t) F_i + t F_{i+1}` is exactly the filter of the blended
/// decomposition `(1 - t) D_i + t D_{i+1}` (the union of both term lists with
/// scaled weights). The blended kernel is not exactly the Gaussian of the
/// intermediate aspect ratio; [`AspectBank::blend_error`] measures by how much
/// (see the tests and `docs/smoothing.md`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AspectBank {
    /// The options it was built with.
    pub options: BankOptions,
    /// The tabulated aspect ratios, increasing, starting at 1.
    pub aspects: Vec<f64>,
    /// One decomposition per aspect ratio (terms only).
    pub terms: Vec<Vec<Term>>,
    /// [`ifd_planar::FIT_REVISION`] of the code that fitted it (0 in
    /// files written before it was recorded): a cached bank fitted by
    /// older code is refitted.
    #[serde(default)]
    pub fit_revision: u32,
}

impl AspectBank {
    /// Fits every entry; `progress(done, total)` after each.
    ///
    /// # Errors
    /// [`SmoothError::OutOfRange`] for bad options, [`SmoothError::Decompose`]
    /// when a fit fails.
    pub fn build(
        options: BankOptions,
        mut progress: impl FnMut(usize, usize),
    ) -> Result<Self, SmoothError> {
        check_range("bank max aspect", options.max_aspect, 1.0, 16.0)?;
        check_range("bank sigma_ref", options.sigma_ref, 2.0, 32.0)?;
        check_range("bank tolerance", options.tol, 1e-4, 0.5)?;
        check_range(
            "bank steps per octave",
            options.steps_per_octave as f64,
            1.0,
            8.0,
        )?;
        let aspects = log_spaced_aspects(options.max_aspect, options.steps_per_octave as f64);
        let n = aspects.len();
        let mut terms = Vec::with_capacity(n);
        for (i, &a) in aspects.iter().enumerate() {
            let spec_s = Self::spec(options.sigma_ref, a);
            let kernel = spec_s.parse::<KernelSpec>()?.to_kernel()?;
            let opts = DecomposeOptions {
                tol: options.tol,
                ..DecomposeOptions::default()
            };
            let d = decompose(&kernel, &opts, |_, _, _| {}).map_err(|source| {
                SmoothError::Decompose {
                    spec: spec_s.clone(),
                    source,
                }
            })?;
            // Unit DC gain: the fit leaves the sum of weights (the
            // full-plane integral of the sum of unit Gaussians) off by up
            // to a few 1e-3, which would brighten or darken flat areas.
            let sum: f64 = d.terms.iter().map(|t| t.weight).sum();
            let terms_i: Vec<Term> = d
                .terms
                .into_iter()
                .map(|t| Term {
                    weight: t.weight / sum,
                    ..t
                })
                .collect();
            terms.push(terms_i);
            progress(i + 1, n);
        }
        Ok(Self {
            options,
            aspects,
            terms,
            fit_revision: ifd_planar::FIT_REVISION,
        })
    }

    /// The filter spec of the entry with aspect ratio `a`.
    #[must_use]
    pub fn spec(sigma_ref: f64, a: f64) -> String {
        format!(
            "gauss:sx={},sy={},theta=0",
            sigma_ref * a.sqrt(),
            sigma_ref / a.sqrt()
        )
    }

    /// Index `i` and blend weight `t` for aspect ratio `a` (clamped to the
    /// table): the filter is `(1 - t) D_i + t D_{i+1}`.
    #[must_use]
    pub fn locate(&self, a: f64) -> (usize, f64) {
        locate_aspect(&self.aspects, a)
    }

    /// The blended decomposition for aspect ratio `a`.
    #[must_use]
    pub fn blended(&self, a: f64) -> Decomposition {
        let (i, t) = self.locate(a);
        let mut terms: Vec<Term> = self.terms[i]
            .iter()
            .map(|x| Term {
                weight: x.weight * (1.0 - t),
                ..*x
            })
            .collect();
        if t > 0.0 {
            terms.extend(self.terms[i + 1].iter().map(|x| Term {
                weight: x.weight * t,
                ..*x
            }));
        }
        Decomposition::from_terms(terms)
    }

    /// Relative L2 error of the blended decomposition for aspect ratio `a`
    /// against the exactly sampled Gaussian of that aspect ratio.
    ///
    /// # Errors
    /// [`SmoothError::Kernel`] if the kernel cannot be sampled.
    pub fn blend_error(&self, a: f64) -> Result<f64, SmoothError> {
        let kernel = Self::spec(self.options.sigma_ref, a)
            .parse::<KernelSpec>()?
            .to_kernel()?;
        let d = self.blended(a);
        let (rx, ry) = (kernel.radius_x() as isize, kernel.radius_y() as isize);
        let (mut num, mut den) = (0.0, 0.0);
        for dy in -ry..=ry {
            for dx in -rx..=rx {
                let k = kernel.get(dx, dy);
                let e = d.eval(dx as f64, dy as f64) - k;
                num += e * e;
                den += k * k;
            }
        }
        Ok((num / den).sqrt())
    }

    /// The largest distance of an atom's centre from the origin over all
    /// entries, in pixels at `sigma_ref` (scale it by `S / sigma_ref`).
    #[must_use]
    pub fn reach(&self) -> f64 {
        self.terms
            .iter()
            .flatten()
            .map(|t| t.x.hypot(t.y))
            .fold(0.0, f64::max)
    }

    /// Smallest and largest atom sigma over all entries.
    #[must_use]
    pub fn sigma_range(&self) -> (f64, f64) {
        self.terms
            .iter()
            .flatten()
            .map(|t| t.sigma)
            .fold((f64::INFINITY, 0.0), |(lo, hi), s| (lo.min(s), hi.max(s)))
    }

    /// Writes the bank as JSON (atomically).
    ///
    /// # Errors
    /// [`SmoothError::Image`] wrapping the write error.
    pub fn save(&self, path: &Path) -> Result<(), SmoothError> {
        let text = serde_json::to_string(self)
            .map_err(|e| SmoothError::BadImage(format!("serialising the bank: {e}")))?;
        ifd_image::atomic_write(path, |w| {
            use std::io::Write;
            w.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })?;
        Ok(())
    }

    /// The bank with `options` from the cache file `cache` when it holds a
    /// valid one built with them by the current fitting code
    /// ([`ifd_planar::FIT_REVISION`]), else fitted (a few seconds;
    /// `progress(done, total)` after each entry) and written there (best
    /// effort: a cache that cannot be written is reported on stderr, not an
    /// error). Returns the bank and where it came from (the file, or
    /// `"fitted"`).
    ///
    /// # Errors
    /// As [`AspectBank::build`].
    pub fn load_or_build(
        options: BankOptions,
        cache: Option<&Path>,
        progress: impl FnMut(usize, usize),
    ) -> Result<(Self, String), SmoothError> {
        if let Some(p) = cache
            && p.exists()
        {
            match Self::load(p) {
                Ok(b)
                    if b.options == options
                        && b.fit_revision == ifd_planar::FIT_REVISION
                        && b.aspects
                            == log_spaced_aspects(
                                options.max_aspect,
                                options.steps_per_octave as f64,
                            ) =>
                {
                    return Ok((b, p.display().to_string()));
                }
                // another version or other options: refitted quietly
                Ok(_) => {}
                Err(e) => eprintln!("note: ignoring the cached aspect bank: {e}; refitting"),
            }
        }
        let b = Self::build(options, progress)?;
        if let Some(p) = cache {
            if let Some(dir) = p.parent() {
                // Best effort: a cache is an optimisation.
                std::fs::create_dir_all(dir).ok();
            }
            if let Err(e) = b.save(p) {
                eprintln!("warning: cannot cache the aspect bank: {e}");
            }
        }
        Ok((b, "fitted".to_string()))
    }

    /// The cache file of the default bank shared by ifd's tools:
    /// `aspect-bank-v1.json` in [`ifd_planar::cache_root`] (`$IFD_CACHE_DIR`,
    /// else `$XDG_CACHE_HOME/ifd`, else `~/.cache/ifd`; `None` without any),
    /// beside the fit cache of `ifd filter --kernel`.
    #[must_use]
    pub fn default_cache() -> Option<std::path::PathBuf> {
        ifd_planar::cache_root().map(|root| root.join("aspect-bank-v1.json"))
    }

    /// Reads a bank written by [`AspectBank::save`], checking it.
    ///
    /// # Errors
    /// [`SmoothError::BadImage`] naming the file and the problem.
    pub fn load(path: &Path) -> Result<Self, SmoothError> {
        let bad = |why: String| SmoothError::BadImage(format!("{}: {why}", path.display()));
        let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
        let bank: Self = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
        if bank.aspects.is_empty() || bank.aspects.len() != bank.terms.len() {
            return Err(bad("aspect table and terms differ in length".into()));
        }
        let finite =
            bank.terms.iter().flatten().all(|t| {
                t.weight.is_finite() && t.x.is_finite() && t.y.is_finite() && t.sigma > 0.0
            });
        if !finite || bank.terms.iter().any(Vec::is_empty) {
            return Err(bad(
                "invalid terms (non-finite, non-positive sigma or empty)".into(),
            ));
        }
        // Every entry is a normalised Gaussian a few sigma_ref wide: its
        // weights sum to 1 (its atoms are wider than a pixel, where sampled
        // and continuous sums agree to 1e-3), its atoms lie within a few
        // of its widths. A file that says otherwise was altered or damaged.
        let width = bank.options.sigma_ref * bank.options.max_aspect;
        for (i, (terms, a)) in bank.terms.iter().zip(&bank.aspects).enumerate() {
            let dc: f64 = terms.iter().map(|t| t.weight).sum();
            if (dc - 1.0).abs() > 1e-2 {
                return Err(bad(format!(
                    "entry {i} (aspect {a}) has weights summing to {dc:.4}, not 1"
                )));
            }
            if let Some(t) = terms
                .iter()
                .find(|t| t.sigma > 4.0 * width || t.x.hypot(t.y) > 8.0 * width)
            {
                return Err(bad(format!(
                    "entry {i} (aspect {a}) has a term of sigma {:e} at ({:e}, {:e}), far \
                     outside a Gaussian of {width} px",
                    t.sigma, t.x, t.y
                )));
            }
        }
        Ok(bank)
    }
}
