//! From the Hessian to the smoothing filter's orientation and aspect ratio.
//!
//! The derivation and conventions are documented on [`Orientation`].

use serde::{Deserialize, Serialize};

use crate::error::{SmoothError, check_range};

/// Parameters of the Hessian-to-filter mapping.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AnisoParams {
    /// Largest aspect ratio (long / short axis of the Gaussian), 1..=16.
    pub max_aspect: f64,
    /// Exponent `gamma` of the anisotropy (larger: anisotropic only at strong structures).
    pub gamma: f64,
    /// Noise floor `epsilon` in scale-normalised Hessian units.
    pub epsilon: f64,
}

impl Default for AnisoParams {
    fn default() -> Self {
        Self {
            max_aspect: 8.0,
            gamma: 1.0,
            epsilon: 0.02,
        }
    }
}

impl AnisoParams {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`SmoothError::OutOfRange`] naming the parameter.
    pub fn validate(&self) -> Result<(), SmoothError> {
        check_range("max aspect", self.max_aspect, 1.0, 16.0)?;
        check_range("gamma", self.gamma, 0.05, 20.0)?;
        check_range("epsilon", self.epsilon, 1e-9, 1e3)?;
        Ok(())
    }
}

/// The smoothing filter at one place.
///
/// At an edge or a ridge the Hessian's eigenvector of largest `|lambda|`
/// points across the structure; smoothing should run along it (perpendicular
/// to that eigenvector) and not across.
///
/// **Tensor averaging.** At the centre of a step edge the second derivative
/// across the edge crosses zero, so the raw Hessian there is nearly zero and
/// would give an isotropic filter exactly where the edge must be kept. We
/// therefore use the *Hessian tensor* `T = H^2` (same eigenvectors,
/// eigenvalues `lambda^2 >= 0`), averaged over a small Gaussian neighbourhood
/// (sigma `rho`), in the spirit of the structure tensor: the strong responses
/// on both sides of the zero crossing fill it in.
///
/// **Mapping.** With `mu1 >= mu2 >= 0` the eigenvalues of `T`, and
/// `n1 = sigma^2 sqrt(mu1)`, `n2 = sigma^2 sqrt(mu2)` the scale-normalised
/// magnitudes, the anisotropy is
/// `A = (n1 - n2) / (n1 + n2 + epsilon)` in `[0, 1)`, and the filter's aspect
/// ratio is `1 + (max_aspect - 1) A^gamma`. `epsilon` (in image units, default
/// 0.02 for images in `[0, 1]`) makes flat and noisy regions isotropic: a
/// zero Hessian gives aspect 1, never NaN.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orientation {
    /// Direction of the long axis, degrees counter-clockwise on screen.
    pub theta: f32,
    /// Aspect ratio, `>= 1`.
    pub aspect: f32,
}

impl Orientation {
    /// The isotropic filter.
    pub const ISOTROPIC: Self = Self {
        theta: 0.0,
        aspect: 1.0,
    };

    /// From the (averaged) Hessian tensor `T = (Txx, Txy, Tyy)` measured at
    /// Hessian scale `sigma`.
    #[must_use]
    pub fn from_tensor(t: [f64; 3], sigma: f64, p: &AnisoParams) -> Self {
        let [txx, txy, tyy] = t;
        if !(txx.is_finite() && txy.is_finite() && tyy.is_finite()) {
            return Self::ISOTROPIC;
        }
        let half_tr = 0.5 * (txx + tyy);
        let d = (0.25 * (txx - tyy) * (txx - tyy) + txy * txy).sqrt();
        let mu1 = (half_tr + d).max(0.0);
        let mu2 = (half_tr - d).max(0.0);
        let s2 = sigma * sigma;
        let (n1, n2) = (s2 * mu1.sqrt(), s2 * mu2.sqrt());
        let a = ((n1 - n2) / (n1 + n2 + p.epsilon)).clamp(0.0, 1.0);
        let aspect = 1.0 + (p.max_aspect - 1.0) * a.powf(p.gamma);
        // Eigenvector of mu1 (across the structure) at angle psi in y-down
        // coordinates; the filter runs along psi + 90 deg. A y-down angle psi
        // is -psi counter-clockwise on screen.
        let psi = 0.5 * (2.0 * txy).atan2(txx - tyy);
        let theta = -(psi.to_degrees() + 90.0);
        Self {
            theta: theta as f32,
            aspect: aspect as f32,
        }
    }

    /// From a single Hessian `(Hxx, Hxy, Hyy)` (no averaging): `T = H^2`.
    #[must_use]
    pub fn from_hessian(h: [f64; 3], sigma: f64, p: &AnisoParams) -> Self {
        Self::from_tensor(tensor(h), sigma, p)
    }
}

/// `H^2` for a symmetric `H = [[a, b], [b, c]]`: `(a^2 + b^2, b (a + c), b^2 + c^2)`.
#[must_use]
pub fn tensor(h: [f64; 3]) -> [f64; 3] {
    let [a, b, c] = h;
    [a * a + b * b, b * (a + c), b * b + c * c]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertical_edge_smooths_vertically() {
        // Intensity varying along x only: Hxx != 0, the filter runs along y (90 deg).
        let o = Orientation::from_hessian([0.5, 0.0, 0.0], 2.0, &AnisoParams::default());
        assert!((o.theta.rem_euclid(180.0) - 90.0).abs() < 1e-4, "{o:?}");
        assert!(o.aspect > 7.0);
    }

    #[test]
    fn horizontal_ridge_smooths_horizontally() {
        let o = Orientation::from_hessian([0.0, 0.0, -0.5], 2.0, &AnisoParams::default());
        assert!(
            o.theta
                .rem_euclid(180.0)
                .min(180.0 - o.theta.rem_euclid(180.0))
                < 1e-4,
            "{o:?}"
        );
    }

    #[test]
    fn diagonal_structure() {
        // f = (x + y)^2 / 2 in y-down coordinates varies along (1, 1)/sqrt 2,
        // i.e. down-right on screen (-45 deg); smoothing runs along (1, -1),
        // up-right on screen: +45 deg.
        let o = Orientation::from_hessian([1.0, 1.0, 1.0], 2.0, &AnisoParams::default());
        assert!((o.theta.rem_euclid(180.0) - 45.0).abs() < 1e-4, "{o:?}");
    }

    #[test]
    fn flat_is_isotropic_never_nan() {
        let o = Orientation::from_hessian([0.0, 0.0, 0.0], 2.0, &AnisoParams::default());
        assert_eq!(o.aspect, 1.0);
        assert!(o.theta.is_finite());
        let o = Orientation::from_hessian([f64::NAN, 0.0, 0.0], 2.0, &AnisoParams::default());
        assert_eq!(o, Orientation::ISOTROPIC);
        // Umbilic point: equal eigenvalues, isotropic.
        let o = Orientation::from_hessian([0.3, 0.0, 0.3], 2.0, &AnisoParams::default());
        assert!((o.aspect - 1.0).abs() < 1e-6);
    }

    #[test]
    fn params_are_checked() {
        let p = AnisoParams {
            max_aspect: 40.0,
            ..AnisoParams::default()
        };
        assert!(p.validate().unwrap_err().to_string().contains("max aspect"));
    }
}
