//! What a [`super::Smoother`] is asked to do: the footprint scale range,
//! the [`Mode`] and the [`SmoothOptions`].

use ifd_planar::Border;

use crate::bank::BankOptions;
use crate::direct::DIRECT_BELOW;
use crate::error::{SmoothError, check_range};
use crate::orientation::AnisoParams;

/// Smallest and largest footprint scale `S` (pixels) supported. Below
/// [`crate::DIRECT_BELOW`] the filters are evaluated directly ([`crate::DirectKernels`]).
pub const SCALE_RANGE: (f64, f64) = (0.5, 128.0);

/// Where the filter of a pixel comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Mode {
    /// The paper's mode: the Hessian at the dab's centre gives one filter for
    /// the whole dab. For whole images, the image is covered by a grid of
    /// dabs (spacing `2 S`) whose results are blended bilinearly.
    Dab,
    /// Every pixel uses the filter from its own (tensor-averaged) Hessian.
    #[default]
    PerPixel,
}

/// Parameters of [`Smoother`](crate::Smoother).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmoothOptions {
    /// Footprint scale `S`: the geometric mean of the Gaussian's two standard
    /// deviations, in pixels (`sx sy = S^2`, so the noise reduction equals an
    /// isotropic Gaussian of sigma `S` whatever the aspect ratio).
    pub scale: f64,
    /// Hessian scale, pixels (default `max(1.5, S / 2)`).
    pub hessian_sigma: Option<f64>,
    /// Sigma of the tensor averaging, pixels (default: the Hessian scale).
    pub tensor_sigma: Option<f64>,
    /// The Hessian-to-filter mapping.
    pub aniso: AnisoParams,
    /// Border handling.
    pub border: Border,
    /// Fit tolerance of the derivative filters.
    pub hessian_tol: f64,
    /// How the aspect-ratio bank is built (when not given).
    pub bank: BankOptions,
}

impl Default for SmoothOptions {
    fn default() -> Self {
        Self {
            scale: 6.0,
            hessian_sigma: None,
            tensor_sigma: None,
            aniso: AnisoParams::default(),
            border: Border::Reflect101,
            hessian_tol: 0.01,
            bank: BankOptions::default(),
        }
    }
}

impl SmoothOptions {
    /// The Hessian scale in use.
    #[must_use]
    pub fn hessian_sigma(&self) -> f64 {
        self.hessian_sigma.unwrap_or((self.scale / 2.0).max(1.5))
    }

    /// Whether the smoothing filters are evaluated directly (footprint
    /// below [`crate::DIRECT_BELOW`], [`crate::DirectKernels`]) rather than from the
    /// scale stack; the GPU path supports only the latter.
    #[must_use]
    pub fn evaluated_directly(&self) -> bool {
        self.scale < DIRECT_BELOW
    }

    /// Spacing of the dab grid of whole-image [`Mode::Dab`] smoothing:
    /// `max(2 S, 4)` pixels.
    #[must_use]
    pub fn dab_grid_spacing(&self) -> f32 {
        (2.0 * self.scale).max(4.0) as f32
    }

    /// The tensor averaging sigma in use.
    #[must_use]
    pub fn tensor_sigma(&self) -> f64 {
        self.tensor_sigma.unwrap_or_else(|| self.hessian_sigma())
    }

    /// Checks every parameter's range (what the smoother checks first), so
    /// that front ends can refuse them before any work.
    ///
    /// # Errors
    /// [`SmoothError::OutOfRange`] naming the parameter (`scale`, `hessian
    /// sigma`, `tensor sigma`, `max aspect`, `gamma`, `epsilon`).
    pub fn validate(&self) -> Result<(), SmoothError> {
        check_range("scale", self.scale, SCALE_RANGE.0, SCALE_RANGE.1)?;
        crate::hessian::check_sigma(self.hessian_sigma())?;
        check_range("tensor sigma", self.tensor_sigma(), 0.0, 64.0)?;
        self.aniso.validate()
    }
}
