//! The parameters of a dictionary for a kernel ([`DictionaryParams`]):
//! its levels, widths and grids, chosen from [`DictionaryOptions`].

use serde::{Deserialize, Serialize};

use crate::kernel::Kernel;

/// The most levels accepted.
pub const MAX_LEVELS: usize = 12;
/// The most atoms a dictionary may have.
pub const MAX_ATOMS: usize = 4_000_000;

/// How to build a dictionary for a kernel; see [`DictionaryParams::for_kernel`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DictionaryOptions {
    /// Number of levels `b`; `None` chooses from the kernel (finest width at or
    /// below `feature_factor` times the kernel's feature width, not below `min_sigma`).
    pub levels: Option<usize>,
    /// `sigma_l / h_l`.
    pub ratio: f64,
    /// Widths per level (1 = one per octave).
    pub sigmas_per_octave: usize,
    /// Grid points per nominal spacing `h_l`.
    pub oversampling: usize,
    /// The automatic level choice stops refining below this width, px.
    pub min_sigma: f64,
    /// The automatic level choice wants the finest width at or below this
    /// fraction of the kernel's feature width (see [`feature_width`]).
    pub feature_factor: f64,
    /// When set, the automatic level choice also goes down to this width,
    /// px, whatever the feature width (a pixel-averaged filter's finest
    /// feature is the pixel's own blur, `1 / sqrt(12)` px, which its
    /// gradient energy does not show).
    #[serde(default)]
    pub finest_at_most: Option<f64>,
    /// Widths below this (px) are left out of the dictionary (0: none):
    /// a fit on a grid of spacing `h` constrains no atom narrower than
    /// about `h`.
    #[serde(default)]
    pub min_width: f64,
}

impl Default for DictionaryOptions {
    /// The defaults chosen by the dictionary study (`docs/dictionary-study.md`).
    fn default() -> Self {
        Self {
            levels: None,
            ratio: 0.5,
            sigmas_per_octave: 4,
            oversampling: 1,
            min_sigma: 0.7,
            feature_factor: 0.7,
            finest_at_most: None,
            min_width: 0.0,
        }
    }
}

/// The resolved parameters of a dictionary (stored in decomposition files).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DictionaryParams {
    /// Number of levels `b`.
    pub levels: usize,
    /// `sigma_l / h_l`.
    pub ratio: f64,
    /// Widths per level.
    pub sigmas_per_octave: usize,
    /// Grid points per nominal spacing.
    pub oversampling: usize,
    /// `D`: the nominal spacing of level 1, px.
    pub half_width: f64,
    /// Widths below this (px) are left out of the finest level (0: none).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub min_width: f64,
}

#[expect(
    clippy::trivially_copy_pass_by_ref,
    reason = "serde's skip_serializing_if signature"
)]
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// Invalid dictionary parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DictionaryError {
    /// A parameter is out of range.
    #[error("invalid dictionary parameter {name} = {value}: {reason}")]
    Invalid {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Why it is rejected.
        reason: &'static str,
    },
    /// The dictionary would be too large.
    #[error("dictionary would have {atoms} atoms (limit {MAX_ATOMS}); use fewer levels")]
    TooLarge {
        /// Atom count.
        atoms: usize,
    },
}

/// The kernel's feature width: `sqrt(||k||^2 / (2 ||grad k||^2))`, px (finite
/// differences). It is exactly `s` for a 1D Gaussian of std dev `s`, and about
/// the smaller std dev for an elongated 2D Gaussian.
#[must_use]
pub fn feature_width(kernel: &Kernel) -> f64 {
    let (w, h) = (kernel.width(), kernel.height());
    let d = kernel.data();
    let e: f64 = d.iter().map(|v| v * v).sum();
    let mut g = 0.0;
    for row in 0..h {
        for col in 0..w {
            let v = d[row * w + col];
            let right = if col + 1 < w {
                d[row * w + col + 1]
            } else {
                0.0
            };
            let down = if row + 1 < h {
                d[(row + 1) * w + col]
            } else {
                0.0
            };
            g += (right - v).powi(2) + (down - v).powi(2);
        }
    }
    // Pixels at the left/top border see a zero neighbour too.
    g += (0..h).map(|row| d[row * w].powi(2)).sum::<f64>();
    g += d[..w].iter().map(|v| v * v).sum::<f64>();
    if g <= 0.0 {
        return f64::INFINITY;
    }
    (e / (2.0 * g)).sqrt()
}

impl DictionaryParams {
    /// Resolves `opts` for `kernel`.
    ///
    /// ```
    /// use ifd_planar::{Kernel, internals::dictionary::{DictionaryOptions, DictionaryParams}};
    /// let k: Kernel = "gauss:sx=12,sy=3,theta=30".parse()?;
    /// let p = DictionaryParams::for_kernel(&k, &DictionaryOptions::default())?;
    /// assert_eq!(p.half_width, 48.0);
    /// assert!(p.finest_sigma() <= 3.0);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`DictionaryError`] for out-of-range options or a dictionary above [`MAX_ATOMS`].
    pub fn for_kernel(kernel: &Kernel, opts: &DictionaryOptions) -> Result<Self, DictionaryError> {
        let check = |name, value: f64, ok: bool, reason| {
            if ok {
                Ok(())
            } else {
                Err(DictionaryError::Invalid {
                    name,
                    value,
                    reason,
                })
            }
        };
        check(
            "ratio",
            opts.ratio,
            opts.ratio.is_finite() && opts.ratio > 0.0 && opts.ratio <= 8.0,
            "expected 0 < ratio <= 8",
        )?;
        check(
            "sigmas_per_octave",
            opts.sigmas_per_octave as f64,
            (1..=8).contains(&opts.sigmas_per_octave),
            "expected 1..=8",
        )?;
        check(
            "oversampling",
            opts.oversampling as f64,
            (1..=4).contains(&opts.oversampling),
            "expected 1..=4",
        )?;
        check(
            "min_sigma",
            opts.min_sigma,
            opts.min_sigma.is_finite() && opts.min_sigma > 0.0,
            "expected a positive width",
        )?;
        check(
            "feature_factor",
            opts.feature_factor,
            opts.feature_factor.is_finite() && opts.feature_factor > 0.0,
            "expected a positive factor",
        )?;
        let half_width = kernel.radius_x().max(kernel.radius_y()).max(1) as f64;
        let levels = if let Some(b) = opts.levels {
            check(
                "levels",
                b as f64,
                (1..=MAX_LEVELS).contains(&b),
                "expected 1..=12",
            )?;
            b
        } else {
            let mut target = (opts.feature_factor * feature_width(kernel)).max(opts.min_sigma);
            if let Some(f) = opts.finest_at_most {
                target = target.min(f);
            }
            let mut b = 1;
            while b < MAX_LEVELS && opts.ratio * half_width / f64::powi(2.0, b as i32 - 1) > target
            {
                b += 1;
            }
            b
        };
        let p = Self {
            levels,
            ratio: opts.ratio,
            sigmas_per_octave: opts.sigmas_per_octave,
            oversampling: opts.oversampling,
            half_width,
            min_width: opts.min_width,
        };
        let atoms = p.atom_count(kernel.width(), kernel.height());
        if atoms > MAX_ATOMS {
            return Err(DictionaryError::TooLarge { atoms });
        }
        Ok(p)
    }

    /// The nominal spacing `h_l` of level `l` (1-based).
    #[must_use]
    pub fn spacing(&self, level: usize) -> f64 {
        self.half_width / f64::powi(2.0, level as i32 - 1)
    }

    /// The base width `sigma_l = ratio h_l` of level `l`.
    #[must_use]
    pub fn sigma(&self, level: usize) -> f64 {
        self.ratio * self.spacing(level)
    }

    /// The narrowest atom width.
    #[must_use]
    pub fn finest_sigma(&self) -> f64 {
        self.sigma(self.levels)
    }

    /// Every atom width with its level, widest first.
    #[must_use]
    pub fn sigmas(&self) -> Vec<(usize, f64)> {
        let n = self.sigmas_per_octave;
        let mut out = Vec::new();
        for l in 1..=self.levels {
            for j in (0..n).rev() {
                let sigma = self.sigma(l) * f64::powf(2.0, j as f64 / n as f64);
                if sigma >= self.min_width * (1.0 - 1e-9) || l == 1 {
                    out.push((l, sigma));
                }
            }
        }
        out
    }

    /// The level (1-based) that an atom of width `sigma` belongs to.
    #[must_use]
    pub fn level_of(&self, sigma: f64) -> usize {
        // Level l holds the widths sigma_l 2^(j/n), j = 0..n-1, in (sigma_{l-1}, sigma_l].
        let l = 1.0 + ((self.sigma(1) / sigma).log2() - 1e-6).ceil();
        (l.max(1.0) as usize).min(self.levels.max(1))
    }

    pub(super) fn grid(&self, level: usize, radius: usize) -> Vec<f64> {
        let step = self.spacing(level) / self.oversampling as f64;
        let m = ((radius as f64 + 1e-9) / step).floor() as i64;
        (-m..=m).map(|k| k as f64 * step).collect()
    }

    fn atom_count(&self, width: usize, height: usize) -> usize {
        (1..=self.levels)
            .map(|l| self.grid(l, width / 2).len() * self.grid(l, height / 2).len())
            .sum::<usize>()
            * self.sigmas_per_octave
    }
}
