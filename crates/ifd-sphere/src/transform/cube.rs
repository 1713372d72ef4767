//! Cube maps: the OpenGL face table, texel directions with exact solid
//! angles, and the projection of a horizontal strip of six faces.

use ifd_image::Image;

use super::{Analysis, Negatives, count_negatives_of_finite_map};
use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError};
use crate::sh::{ShEvaluator, sh_count};

/// The (unnormalised) direction at face coordinates `sc, tc` in `[-1, 1]`
/// (`tc` growing downwards in the image) of cube face `face` (`0..6` =
/// `+X, -X, +Y, -Y, +Z, -Z`): the OpenGL cube-map table,
/// `direction = major + sc s_axis + tc t_axis`.
#[must_use]
pub fn cube_face_direction(face: usize, sc: f64, tc: f64) -> [f64; 3] {
    match face {
        0 => [1.0, -tc, -sc],
        1 => [-1.0, -tc, sc],
        2 => [sc, 1.0, tc],
        3 => [sc, -1.0, -tc],
        4 => [sc, -tc, 1.0],
        _ => [-sc, -tc, -1.0],
    }
}

/// Direction of texel `(i, j)` (column, row from the top) of cube face `face`
/// (`0..6` = `+X, -X, +Y, -Y, +Z, -Z`) of size `n`, and its exact solid angle.
#[must_use]
pub fn cube_texel(face: usize, i: usize, j: usize, n: usize) -> ([f64; 3], f64) {
    let nf = n as f64;
    let sc = 2.0 * (i as f64 + 0.5) / nf - 1.0;
    let tc = 2.0 * (j as f64 + 0.5) / nf - 1.0;
    let d = cube_face_direction(face, sc, tc);
    let f = |a: f64, b: f64| (a * b).atan2((a * a + b * b + 1.0).sqrt());
    let (a0, a1) = (2.0 * i as f64 / nf - 1.0, 2.0 * (i as f64 + 1.0) / nf - 1.0);
    let (b0, b1) = (2.0 * j as f64 / nf - 1.0, 2.0 * (j as f64 + 1.0) / nf - 1.0);
    let sa = f(a1, b1) - f(a0, b1) - f(a1, b0) + f(a0, b0);
    (d, sa)
}

/// Projects a cubemap strip (`W = 6H`, faces `+X, -X, +Y, -Y, +Z, -Z`) onto SH.
///
/// # Errors
/// [`SphereError::NotCubemap`] for other shapes, [`SphereError::NonFinite`] for NaN.
pub fn analyze_cubemap(img: &Image, l_max: usize, negatives: Negatives) -> Result<Analysis> {
    let (w, h, ch) = (img.width(), img.height(), img.channels());
    if w != 6 * h {
        return Err(SphereError::NotCubemap {
            width: w,
            height: h,
        });
    }
    let data = img.data();
    let negatives_clamped = count_negatives_of_finite_map(data, "cubemap")?;
    let sh = ShEvaluator::new(l_max)?;
    let mut coeffs = ShCoeffs::zeros(l_max, ch)?;
    let o = coeffs.data_mut();
    let mut y = vec![0.0; sh_count(l_max)];
    for face in 0..6 {
        for j in 0..h {
            for i in 0..h {
                let (d, sa) = cube_texel(face, i, j, h);
                sh.eval_into(d, &mut y);
                let px = (j * w + face * h + i) * ch;
                for c in 0..ch {
                    let mut v = f64::from(data[px + c]);
                    if negatives == Negatives::Clamp {
                        v = v.max(0.0);
                    }
                    let wv = sa * v;
                    for (k, yk) in y.iter().enumerate() {
                        o[k * ch + c] += wv * yk;
                    }
                }
            }
        }
    }
    Ok(Analysis {
        coeffs,
        negatives_clamped,
    })
}
