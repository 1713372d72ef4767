//! Cube maps as engines load them, and the frame conversion to ifd's maps.
//!
//! The derivation and conventions are documented on [`CubeLevel`].

use ifd_image::Image;
use ifd_sphere::cube_texel;

/// Face names in storage order.
pub const FACE_NAMES: [&str; 6] = ["+X", "-X", "+Y", "-Y", "+Z", "-Z"];

/// Short face names for file names (`px`, `nx`, ...).
pub const FACE_FILE_NAMES: [&str; 6] = ["px", "nx", "py", "ny", "pz", "nz"];

/// World direction (y up, unit length) of the centre of texel `(i, j)` of
/// face `face` of an `n x n` cube, and the texel's exact solid angle.
///
/// ```
/// use ifd_ibl::face_texel;
/// // the centre texel of +Y looks straight up
/// let (d, _) = face_texel(2, 1, 1, 3);
/// assert!((d[1] - 1.0).abs() < 1e-12);
/// // the solid angles of all texels add up to 4 pi
/// let n = 8;
/// let total: f64 = (0..6)
///     .flat_map(|f| (0..n * n).map(move |k| face_texel(f, k % n, k / n, n).1))
///     .sum();
/// assert!((total - 4.0 * std::f64::consts::PI).abs() < 1e-12);
/// ```
#[must_use]
pub fn face_texel(face: usize, i: usize, j: usize, n: usize) -> ([f64; 3], f64) {
    let (d, sa) = cube_texel(face, i, j, n);
    let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    ([d[0] / r, d[1] / r, d[2] / r], sa)
}

/// Direction in ifd's equirectangular frame (z up) of a world direction
/// (y up, glTF); see the module docs.
#[must_use]
pub fn world_to_ifd(d: [f64; 3]) -> [f64; 3] {
    [-d[0], -d[2], d[1]]
}

/// One mip level of a cube map: six `size x size` faces of RGB, `f32`,
/// face-major, rows from the top.
///
/// # Conventions
/// - Faces in the order `+X, -X, +Y, -Y, +Z, -Z`, **y up** (glTF, Vulkan,
///   OpenGL, Bevy). Texel `(i, j)` of an `N x N` face (column `i`, row `j`
///   from the top) has face coordinates `sc = 2 (i + 0.5) / N - 1`,
///   `tc = 2 (j + 0.5) / N - 1` and looks along the OpenGL cube-map table:
///   `+X: (1, -tc, -sc)`, `-X: (-1, -tc, sc)`, `+Y: (sc, 1, tc)`,
///   `-Y: (sc, -1, -tc)`, `+Z: (sc, -tc, 1)`, `-Z: (-sc, -tc, -1)`.
/// - An equirectangular source is read as glTF-IBL-Sampler reads it: the
///   world direction `d` (y up) samples texture coordinates
///   `u = 0.5 + atan2(d.z, d.x) / (2 pi)`, `v = acos(d.y) / pi` (v from the
///   top row). In ifd's own equirectangular frame (z up, column azimuth
///   `2 pi (u + 0.5) / W`, see `ifd_sphere::EquirectTransform`) that is the direction
///   [`world_to_ifd`]`(d) = (-d.x, -d.z, d.y)`. Derivation: ifd's azimuth
///   `phi = 2 pi u = pi + atan2(d.z, d.x) = atan2(-d.z, -d.x)` and polar angle
///   `theta = pi v = acos(d.y)`. (The map is a reflection, determinant -1:
///   it does not matter for the isotropic lobes baked here, and SH
///   coefficients written by the baker stay in ifd's frame, as stated in
///   `sh.json`.)
#[derive(Clone, Debug, PartialEq)]
pub struct CubeLevel {
    /// Face size in texels.
    pub size: usize,
    /// `6 * size * size * 3` values.
    pub data: Vec<f32>,
}

impl CubeLevel {
    /// A black level.
    #[must_use]
    pub fn zeros(size: usize) -> Self {
        Self {
            size,
            data: vec![0.0; 6 * size * size * 3],
        }
    }

    /// The RGB value of texel `(i, j)` of `face`.
    #[must_use]
    pub fn get(&self, face: usize, i: usize, j: usize) -> [f32; 3] {
        let k = ((face * self.size + j) * self.size + i) * 3;
        [self.data[k], self.data[k + 1], self.data[k + 2]]
    }

    /// One face as an RGB image.
    ///
    /// # Errors
    /// If the image cannot be allocated.
    pub fn face_image(&self, face: usize) -> Result<Image, ifd_image::ImageError> {
        let n = self.size * self.size * 3;
        Image::from_vec(
            self.size,
            self.size,
            3,
            self.data[face * n..(face + 1) * n].to_vec(),
        )
    }

    /// The six faces side by side (a `6N x N` strip, the layout
    /// `ifd sphere` reads as a cubemap).
    ///
    /// # Errors
    /// If the image cannot be allocated.
    pub fn strip(&self) -> Result<Image, ifd_image::ImageError> {
        let n = self.size;
        let mut img = Image::new(6 * n, n, 3)?;
        let out = img.data_mut();
        for face in 0..6 {
            for j in 0..n {
                let src = ((face * n + j) * n) * 3;
                let dst = (j * 6 * n + face * n) * 3;
                out[dst..dst + 3 * n].copy_from_slice(&self.data[src..src + 3 * n]);
            }
        }
        Ok(img)
    }
}

/// Catmull-Rom (bicubic) lookup of an equirectangular map (ifd's layout) in
/// direction `d` of ifd's frame, the first three channels
/// ([`ifd_sphere::bicubic_taps`]: wraps in azimuth, continues
/// across the poles, `O(h^4)` for a smooth field).
#[must_use]
pub fn sample_bicubic(img: &Image, d: [f64; 3]) -> [f32; 3] {
    let ch = img.channels();
    let data = img.data();
    let mut out = [0.0f64; 3];
    for (t, wt) in ifd_sphere::bicubic_taps(d, img.width(), img.height()) {
        for (c, o) in out.iter_mut().enumerate().take(ch.min(3)) {
            *o += wt * f64::from(data[t * ch + c]);
        }
    }
    out.map(|x| x as f32)
}

/// Continuous texel coordinates `(u, v)` in `[0, W) x [0, H]` of direction
/// `d` (ifd frame) on a `W x H` equirectangular map (texel centres at `+0.5`).
#[must_use]
pub fn equirect_coords(d: [f64; 3], w: usize, h: usize) -> (f64, f64) {
    use std::f64::consts::PI;
    let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let theta = (d[2] / r).clamp(-1.0, 1.0).acos();
    let mut phi = d[1].atan2(d[0]);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    (phi / (2.0 * PI) * w as f64, theta / PI * h as f64)
}

/// The face and continuous face coordinates `(s, t)` in `[0, 1]` (from the
/// left and the top) that world direction `d` (y up) hits: the inverse of
/// the OpenGL table of the module docs.
#[must_use]
pub fn face_coords(d: [f64; 3]) -> (usize, f64, f64) {
    let (ax, ay, az) = (d[0].abs(), d[1].abs(), d[2].abs());
    let (face, ma, sc, tc) = if ax >= ay && ax >= az {
        if d[0] > 0.0 {
            (0, ax, -d[2], -d[1])
        } else {
            (1, ax, d[2], -d[1])
        }
    } else if ay >= az {
        if d[1] > 0.0 {
            (2, ay, d[0], d[2])
        } else {
            (3, ay, d[0], -d[2])
        }
    } else if d[2] > 0.0 {
        (4, az, d[0], -d[1])
    } else {
        (5, az, -d[0], -d[1])
    };
    (face, 0.5 * (sc / ma + 1.0), 0.5 * (tc / ma + 1.0))
}

/// Resamples a cube-map strip (`6N x N`, faces `+X, -X, +Y, -Y, +Z, -Z`, y
/// up, the layout [`CubeLevel::strip`] writes) to a `4N x 2N`
/// equirectangular map in ifd's frame, each texel the mean of `4 x 4`
/// nearest-texel samples (a box filter; the strip is read as piecewise
/// constant).
///
/// # Errors
/// A strip that is not 6:1; allocation.
pub fn strip_to_equirect(strip: &Image) -> Result<Image, crate::IblError> {
    use std::f64::consts::PI;
    const K: usize = 4;
    let (w, n, ch) = (strip.width(), strip.height(), strip.channels());
    if n == 0 || w != 6 * n {
        return Err(crate::error::param(
            "cube strip",
            format!("must be 6:1 (six square faces side by side); got {w}x{n}"),
        ));
    }
    let (ow, oh) = (4 * n, 2 * n);
    let mut out = Image::new(ow, oh, ch)?;
    let src = strip.data();
    for (v, row) in out.data_mut().chunks_exact_mut(ow * ch).enumerate() {
        for u in 0..ow {
            let px = &mut row[u * ch..(u + 1) * ch];
            for a in 0..K {
                let theta = PI * (v as f64 + (a as f64 + 0.5) / K as f64) / oh as f64;
                for b in 0..K {
                    let phi = 2.0 * PI * (u as f64 + (b as f64 + 0.5) / K as f64) / ow as f64;
                    // ifd frame -> world: x_w = -x, y_w = z, z_w = -y
                    let d = [
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    ];
                    let (face, s, t) = face_coords([-d[0], d[2], -d[1]]);
                    let i = ((s * n as f64) as usize).min(n - 1);
                    let j = ((t * n as f64) as usize).min(n - 1);
                    let sp = &src[(j * w + face * n + i) * ch..][..ch];
                    for (o, x) in px.iter_mut().zip(sp) {
                        *o += x / (K * K) as f32;
                    }
                }
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn face_centres_sample_the_map_as_gltf_ibl_sampler_does() {
        // glTF-IBL-Sampler: u = 0.5 + atan2(z, x) / 2pi, v = acos(y) / pi
        let (w, h) = (64, 32);
        for face in 0..6 {
            for (i, j) in [(0, 0), (3, 1), (7, 7), (4, 4)] {
                let (d, _) = face_texel(face, i, j, 8);
                let want_u = 0.5 + d[2].atan2(d[0]) / (2.0 * std::f64::consts::PI);
                let want_v = d[1].acos() / std::f64::consts::PI;
                let (u, v) = equirect_coords(world_to_ifd(d), w, h);
                let du = (u / w as f64 - want_u).rem_euclid(1.0);
                assert!(du.min(1.0 - du) < 1e-12, "face {face} ({i},{j}) u");
                assert!(
                    (v / h as f64 - want_v).abs() < 1e-12,
                    "face {face} ({i},{j}) v"
                );
            }
        }
    }

    #[test]
    fn faces_follow_the_opengl_table() {
        // centre of each face: +X, -X, +Y, -Y, +Z, -Z
        let axes = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        for (face, a) in axes.iter().enumerate() {
            let (d, _) = face_texel(face, 1, 1, 3);
            for k in 0..3 {
                assert!((d[k] - a[k]).abs() < 1e-12);
            }
        }
        // the top row of a side face looks up (+y), of +Y looks towards -z
        assert!(face_texel(0, 4, 0, 9).0[1] > 0.5);
        assert!(face_texel(2, 4, 0, 9).0[2] < -0.5);
        // +X: column 0 looks towards +z (sc = -z)
        assert!(face_texel(0, 0, 4, 9).0[2] > 0.5);
    }

    #[test]
    fn face_coords_invert_the_table() {
        let n = 16;
        for face in 0..6 {
            for (i, j) in [(0, 0), (5, 11), (15, 15), (8, 2)] {
                let (d, _) = face_texel(face, i, j, n);
                let (f, s, t) = face_coords(d);
                assert_eq!(f, face);
                assert!((s * n as f64 - (i as f64 + 0.5)).abs() < 1e-9);
                assert!((t * n as f64 - (j as f64 + 0.5)).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn a_strip_round_trips_through_the_equirect_frame() {
        // faces of distinct constant colours: the equirect map's texels near
        // each axis hold that face's colour
        let n = 8;
        let mut level = CubeLevel::zeros(n);
        for (k, v) in level.data.iter_mut().enumerate() {
            *v = (k / (n * n * 3)) as f32;
        }
        let eq = strip_to_equirect(&level.strip().expect("strip")).expect("resample");
        let (w, h) = (eq.width(), eq.height());
        for face in 0..6 {
            let (d, _) = face_texel(face, n / 2, n / 2, n);
            let (u, v) = equirect_coords(world_to_ifd(d), w, h);
            let (u, v) = ((u as usize).min(w - 1), (v as usize).min(h - 1));
            assert_eq!(eq.data()[(v * w + u) * 3], face as f32, "face {face}");
        }
    }
}
