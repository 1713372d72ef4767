//! Which roughness each mip level of a prefiltered chain holds.

use crate::error::{Result, param};

/// The mip-to-roughness mapping of a radiance chain.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RoughnessMapping {
    /// Mip `m` of `M` holds perceptual roughness `m / (M - 1)` (glTF-IBL-Sampler,
    /// Bevy); `M = floor(log2 N)` levels by default (8 at 256: 256 ... 2).
    #[default]
    Linear,
    /// Filament `cmgen`: `lod = m / (M - 1)`, roughness `1 - sqrt(1 - lod)`
    /// (the inverse of its quadratic fit `lod = r (2 - r)`); the chain stops at
    /// 16 texels by default (5 levels at 256).
    Cmgen,
}

impl RoughnessMapping {
    /// Parses `linear` or `cmgen`.
    ///
    /// # Errors
    /// Any other name.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "linear" => Ok(Self::Linear),
            "cmgen" => Ok(Self::Cmgen),
            _ => Err(param(
                "--roughness",
                format!("unknown mapping {s:?}; use linear or cmgen"),
            )),
        }
    }

    /// The default number of levels for `n`-texel faces.
    #[must_use]
    pub fn default_levels(self, n: usize) -> usize {
        let log2 = n.max(1).ilog2() as usize;
        match self {
            Self::Linear => log2.max(1),
            Self::Cmgen => log2.saturating_sub(4) + 1,
        }
    }

    /// Perceptual roughness of mip `m` of an `levels`-level chain.
    ///
    /// ```
    /// use ifd_ibl::RoughnessMapping;
    /// assert_eq!(RoughnessMapping::Linear.roughness(2, 8), 2.0 / 7.0);
    /// // cmgen: lod 0.5 -> 1 - sqrt(0.5)
    /// let r = RoughnessMapping::Cmgen.roughness(2, 5);
    /// assert!((r * (2.0 - r) - 0.5).abs() < 1e-12);
    /// ```
    #[must_use]
    pub fn roughness(self, m: usize, levels: usize) -> f64 {
        if levels <= 1 {
            return 0.0;
        }
        let lod = m as f64 / (levels - 1) as f64;
        match self {
            Self::Linear => lod,
            Self::Cmgen => (1.0 - (1.0 - lod).max(0.0).sqrt()).clamp(0.0, 1.0),
        }
    }
}

/// Checks a face size (a power of two, 1 to 16384) and a level count (at
/// most `log2 N + 1`).
///
/// # Errors
/// Names the option and the allowed range.
pub fn check_chain(n: usize, levels: usize) -> Result<()> {
    if !n.is_power_of_two() || n > 16384 {
        return Err(param(
            "--face-size",
            format!("{n} must be a power of two from 1 to 16384"),
        ));
    }
    let max = n.ilog2() as usize + 1;
    if levels == 0 || levels > max {
        return Err(param(
            "--mips",
            format!("{levels} levels requested; a {n}-texel face has 1 to {max} ({n} down to 1)"),
        ));
    }
    Ok(())
}
