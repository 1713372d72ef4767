//! Display transforms for 8-bit output: exposure, a tone curve, sRGB encoding.

use crate::error::{RenderError, Result};

/// A tone curve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tonemap {
    /// Clip to `[0, 1]`.
    None,
    /// `x / (1 + x)`.
    Reinhard,
    /// Narkowicz's fit of the ACES filmic curve:
    /// `x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14)`, clipped.
    Aces,
}

impl Tonemap {
    /// `none`, `reinhard` or `aces`.
    ///
    /// # Errors
    /// [`RenderError::Parameter`] for other names.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "none" => Ok(Self::None),
            "reinhard" => Ok(Self::Reinhard),
            "aces" => Ok(Self::Aces),
            _ => Err(RenderError::Parameter {
                name: "--tonemap",
                value: s.into(),
                reason: "use none, reinhard or aces".into(),
            }),
        }
    }

    /// Linear radiance times `2^exposure`, tone mapped, sRGB-encoded, in `[0, 1]`.
    ///
    /// ```
    /// use ifd_render::Tonemap;
    /// assert!((Tonemap::None.display(1.0, 0.0) - 1.0).abs() < 1e-6);
    /// assert!((Tonemap::Reinhard.display(1.0, 0.0) - 0.735_357).abs() < 1e-5); // srgb(0.5)
    /// ```
    #[must_use]
    pub fn display(self, v: f32, exposure: f32) -> f32 {
        let x = (v * exposure.exp2()).max(0.0);
        let y = match self {
            Self::None => x,
            Self::Reinhard => x / (1.0 + x),
            Self::Aces => x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14),
        };
        ifd_image::linear_to_srgb(y.clamp(0.0, 1.0))
    }
}
