//! Resampling of equirectangular maps: Catmull-Rom lookups in a direction
//! and integer-factor downsampling that keeps texel integrals.

use std::f64::consts::PI;

use ifd_image::Image;

use crate::error::{Result, SphereError};

/// The 16 Catmull-Rom taps of a `w x h` equirectangular map (ifd's layout)
/// in direction `d` (any length): texel index `v w + u` and weight. Wraps in
/// azimuth and continues across the poles (row `-1 - v` is row `v` half a
/// turn away), so a smooth field is interpolated to `O(h^4)`.
///
/// ```
/// use ifd_sphere::bicubic_taps;
/// // the weights of any lookup sum to 1
/// let taps = bicubic_taps([0.3, -0.2, 0.9], 64, 32);
/// assert!((taps.iter().map(|t| t.1).sum::<f64>() - 1.0).abs() < 1e-12);
/// ```
#[must_use]
pub fn bicubic_taps(d: [f64; 3], w: usize, h: usize) -> [(usize, f64); 16] {
    let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let t = (d[2] / r).clamp(-1.0, 1.0).acos();
    let p = d[1].atan2(d[0]).rem_euclid(2.0 * PI);
    // continuous pixel coordinates of the centres: u + 0.5 = p W / 2 pi
    let x = p / (2.0 * PI) * w as f64 - 0.5;
    let y = t / PI * h as f64 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (wx, wy) = (catmull_rom(x - x0), catmull_rom(y - y0));
    let (x0, y0) = (x0 as i64, y0 as i64);
    let (wi, hi) = (w as i64, h as i64);
    let mut taps = [(0usize, 0.0f64); 16];
    for (a, wya) in wy.iter().enumerate() {
        let mut v = y0 - 1 + a as i64;
        let mut shift = 0;
        if v < 0 {
            v = -1 - v;
            shift = wi / 2;
        } else if v >= hi {
            v = 2 * hi - 1 - v;
            shift = wi / 2;
        }
        let v = v.clamp(0, hi - 1);
        for (b, wxb) in wx.iter().enumerate() {
            let u = (x0 - 1 + b as i64 + shift).rem_euclid(wi);
            taps[a * 4 + b] = ((v * wi + u) as usize, wya * wxb);
        }
    }
    taps
}

/// Catmull-Rom weights for a fractional position `f` in `[0, 1)`.
fn catmull_rom(f: f64) -> [f64; 4] {
    let f2 = f * f;
    let f3 = f2 * f;
    [
        0.5 * (-f3 + 2.0 * f2 - f),
        0.5 * (3.0 * f3 - 5.0 * f2 + 2.0),
        0.5 * (-3.0 * f3 + 4.0 * f2 + f),
        0.5 * (f3 - f2),
    ]
}

/// An equirectangular map averaged down by an integer factor to
/// `width x height` (2:1, dividing the map's size): each new texel is the
/// solid-angle-weighted mean of the texels it covers, so the map read as
/// piecewise constant keeps its integral over every new texel.
///
/// ```
/// use ifd_sphere::downsample_equirect;
/// let img = ifd_image::Image::from_vec(8, 4, 1, (0..32).map(|i| i as f32).collect())?;
/// let small = downsample_equirect(&img, 4, 2)?;
/// assert_eq!((small.width(), small.height()), (4, 2));
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
///
/// # Errors
/// [`SphereError::NotEquirect`] for a source or target that is not 2:1, or a
/// target that does not divide the source.
pub fn downsample_equirect(img: &Image, width: usize, height: usize) -> Result<Image> {
    let (w, h, ch) = (img.width(), img.height(), img.channels());
    if h < 2 || w != 2 * h {
        return Err(SphereError::NotEquirect {
            width: w,
            height: h,
        });
    }
    if height < 1 || width != 2 * height || w % width != 0 || h % height != 0 {
        return Err(SphereError::NotEquirect { width, height });
    }
    let f = h / height;
    let row_sa =
        |v: usize| (PI * v as f64 / h as f64).cos() - (PI * (v + 1) as f64 / h as f64).cos();
    let src = img.data();
    let mut out = vec![0.0f32; width * height * ch];
    let mut acc = vec![0.0f64; ch];
    for vv in 0..height {
        for uu in 0..width {
            acc.fill(0.0);
            let mut wsum = 0.0;
            for v in vv * f..(vv + 1) * f {
                let wv = row_sa(v);
                for u in uu * f..(uu + 1) * f {
                    for (c, a) in acc.iter_mut().enumerate() {
                        *a += wv * f64::from(src[(v * w + u) * ch + c]);
                    }
                    wsum += wv;
                }
            }
            for (c, a) in acc.iter().enumerate() {
                out[(vv * width + uu) * ch + c] = (a / wsum) as f32;
            }
        }
    }
    Ok(Image::from_vec(width, height, ch, out)?)
}
