//! SH projection of BRDF slices `k_wo(wi) = rho(wi, wo) max(wi_z, 0)`.
//!
//! Lambert and Phong use their closed-form zonal coefficients
//! ([`crate::zonal`]), rotated onto their axis by the addition theorem
//! (`c_l^m = k_l pi_l y_l^m(axis)`). The other models are integrated over the
//! upper hemisphere only (they vanish below the horizon, where the cosine has
//! its kink) by [`ifd_sphere::project_band`], starting from a
//! resolution set by the lobe's width ([`slice_nodes`]) and doubling it until
//! the coefficients change by less than [`SLICE_TOLERANCE`] (relative L2), up
//! to [`MAX_SLICE_NODES`] rings: near grazing views the lobe hugs the horizon
//! and needs several times the nodes of a normal view (measured: GGX `alpha =
//! 0.1` at `theta_o = 1.5` needs about 320 rings for 1e-4, 80 suffice at 0.8).

use ifd_sphere::ShCoeffs;
use ifd_sphere::project_band;
use ifd_sphere::{ShEvaluator, pi_l};

use crate::brdf::{Brdf, Model};
use crate::error::Result;
use crate::zonal::zonal_slice;

/// Relative L2 change of the coefficients between two resolutions at which a
/// quadrature projection is accepted.
pub const SLICE_TOLERANCE: f64 = 1e-5;
/// The most Gauss-Legendre rings a slice projection uses (then `2 x 1024`
/// azimuths per ring).
pub const MAX_SLICE_NODES: usize = 1024;

/// Gauss-Legendre rings over the hemisphere for a slice of `brdf` at degree
/// `l_max`: `L + 2 + 16 / width` (a lobe of width `w` radians gets about 16
/// nodes across it), at most 2048.
#[must_use]
pub fn slice_nodes(brdf: &Brdf, l_max: usize) -> usize {
    let extra = (16.0 / brdf.lobe_width()).ceil() as usize;
    (l_max + 2 + extra).min(2048)
}

/// The SH coefficients (degree `l_max`, [`Brdf::channels`] channels) of the
/// slice for view `wo` (local frame, unit vector). `n_theta` fixes the
/// quadrature models' resolution instead of the adaptive doubling.
///
/// ```
/// use ifd_shade::{Brdf, project_slice};
/// // Lambert, white: int k = 1, so c_00 = 1 / sqrt(4 pi)
/// let c = project_slice(&Brdf::parse("lambert")?, [0.0, 0.0, 1.0], 4, None)?;
/// assert!((c.get(0, 0, 0) - 0.5 / std::f64::consts::PI.sqrt()).abs() < 1e-15);
/// # Ok::<(), ifd_shade::ShadeError>(())
/// ```
///
/// # Errors
/// Degrees beyond [`ifd_sphere::MAX_DEGREE`]; non-finite BRDF values.
pub fn project_slice(
    brdf: &Brdf,
    wo: [f64; 3],
    l_max: usize,
    n_theta: Option<usize>,
) -> Result<ShCoeffs> {
    if let Some((axis, k)) = zonal_slice(brdf, wo, l_max) {
        let sh = ShEvaluator::new(l_max)?;
        let y = sh.eval(axis);
        let mut c = ShCoeffs::zeros(l_max, 1)?;
        for (i, v) in c.data_mut().iter_mut().enumerate() {
            let l = (i as f64).sqrt() as usize;
            *v = k[l] * pi_l(l) * y[i];
        }
        return Ok(c);
    }
    let project = |n: usize| {
        project_band(l_max, brdf.channels(), (0.0, 1.0), n, |wi, out| {
            brdf.slice(wi, wo, out);
        })
    };
    if let Some(n) = n_theta {
        return Ok(project(n)?);
    }
    // measured data are piecewise constant over their bins: the coefficients
    // converge slowly, so MERL stops at 1e-4 and 512 rings
    let (tol, max) = if matches!(brdf.model(), Model::Merl(_)) {
        (1e-4, MAX_SLICE_NODES / 2)
    } else {
        (SLICE_TOLERANCE, MAX_SLICE_NODES)
    };
    let mut n = slice_nodes(brdf, l_max).min(max / 2);
    let mut c = project(n)?;
    while n < max {
        n = (2 * n).min(max);
        let next = project(n)?;
        let (mut num, mut den) = (0.0, 0.0);
        for (a, b) in c.data().iter().zip(next.data()) {
            num += (a - b) * (a - b);
            den += b * b;
        }
        c = next;
        if num <= tol * tol * den {
            break;
        }
    }
    Ok(c)
}
