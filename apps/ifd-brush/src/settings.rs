//! Brush settings (persisted between runs and recorded with every stroke).

use ifd_smooth::{AnisoParams, Mode, SmoothOptions};
use serde::{Deserialize, Serialize};

/// Where each pixel's filter comes from (serialisable mirror of [`Mode`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BrushMode {
    /// One filter per dab, from the Hessian at its centre (the paper's mode).
    Dab,
    /// Every pixel uses the filter from its own Hessian.
    #[default]
    PerPixel,
}

impl From<BrushMode> for Mode {
    fn from(m: BrushMode) -> Self {
        match m {
            BrushMode::Dab => Mode::Dab,
            BrushMode::PerPixel => Mode::PerPixel,
        }
    }
}

/// Ranges of the brush settings (the UI's sliders and [`BrushSettings::clamped`]).
pub mod range {
    /// Dab radius, pixels.
    pub const RADIUS: (f32, f32) = (2.0, 256.0);
    /// Footprint scale `S`, pixels (the smoother supports 2..=128).
    pub const SCALE: (f64, f64) = (2.0, 64.0);
    /// Largest aspect ratio of the anisotropic filter (the bank covers 16).
    pub const MAX_ASPECT: (f64, f64) = (1.0, 16.0);
    /// Dab spacing, as a fraction of the radius.
    pub const SPACING: (f32, f32) = (0.05, 1.0);
}

/// Everything that determines what a stroke does.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BrushSettings {
    /// Dab radius in image pixels.
    pub radius: f32,
    /// Blend of the smoothed value at the dab's centre, 0..=1.
    pub strength: f32,
    /// Fraction of the radius over which the dab fades out, 0..=1.
    pub falloff: f32,
    /// Footprint scale `S` of the smoothing filter (geometric-mean sigma), pixels.
    pub scale: f64,
    /// Largest aspect ratio of the anisotropic filter, 1..=16.
    pub max_aspect: f64,
    /// Dab or per-pixel filters.
    pub mode: BrushMode,
    /// Distance between dabs along a stroke, as a fraction of the radius.
    pub spacing: f32,
}

impl Default for BrushSettings {
    fn default() -> Self {
        Self {
            radius: 32.0,
            strength: 0.6,
            falloff: 0.5,
            scale: 6.0,
            max_aspect: 8.0,
            mode: BrushMode::PerPixel,
            spacing: 0.25,
        }
    }
}

impl BrushSettings {
    /// The settings with every value forced into its range (NaN becomes the default).
    #[must_use]
    pub fn clamped(self) -> Self {
        let d = Self::default();
        let f32c = |v: f32, (lo, hi): (f32, f32), def: f32| {
            if v.is_finite() { v.clamp(lo, hi) } else { def }
        };
        let f64c = |v: f64, (lo, hi): (f64, f64), def: f64| {
            if v.is_finite() { v.clamp(lo, hi) } else { def }
        };
        Self {
            radius: f32c(self.radius, range::RADIUS, d.radius),
            strength: f32c(self.strength, (0.0, 1.0), d.strength),
            falloff: f32c(self.falloff, (0.0, 1.0), d.falloff),
            scale: f64c(self.scale, range::SCALE, d.scale),
            max_aspect: f64c(self.max_aspect, range::MAX_ASPECT, d.max_aspect),
            mode: self.mode,
            spacing: f32c(self.spacing, range::SPACING, d.spacing),
        }
    }

    /// Distance between dabs, pixels (at least half a pixel).
    #[must_use]
    pub fn spacing_px(&self) -> f32 {
        (self.spacing * self.radius).max(0.5)
    }

    /// The smoother options these settings need (the prefiltered stack
    /// depends on `scale`, the orientation field on `max_aspect`).
    #[must_use]
    pub fn smooth_options(&self) -> SmoothOptions {
        SmoothOptions {
            scale: self.scale,
            aniso: AnisoParams {
                max_aspect: self.max_aspect,
                ..AnisoParams::default()
            },
            ..SmoothOptions::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clamping_and_serde_defaults() {
        let s = BrushSettings {
            radius: 1e6,
            strength: f32::NAN,
            scale: 0.1,
            ..BrushSettings::default()
        }
        .clamped();
        assert_eq!(s.radius, range::RADIUS.1);
        assert_eq!(s.strength, BrushSettings::default().strength);
        assert_eq!(s.scale, range::SCALE.0);
        // Missing fields take their defaults.
        let p: BrushSettings = serde_json::from_str(r#"{"radius": 10}"#).expect("json");
        assert_eq!(p.radius, 10.0);
        assert_eq!(p.mode, BrushMode::PerPixel);
        let m: BrushSettings = serde_json::from_str(r#"{"mode": "dab"}"#).expect("json");
        assert_eq!(Mode::from(m.mode), Mode::Dab);
    }
}
