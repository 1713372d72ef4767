//! Measured BRDFs in the MERL binary format (Matusik et al. 2003).
//!
//! The derivation and conventions are documented on [`Merl`].

use std::f64::consts::{FRAC_PI_2, PI};
use std::io::{Read, Write};
use std::path::Path;

use crate::error::{Result, ShadeError};

/// Bins of `theta_h`.
pub const THETA_H: usize = 90;
/// Bins of `theta_d`.
pub const THETA_D: usize = 90;
/// Bins of `phi_d` (over `[0, pi)`).
pub const PHI_D: usize = 180;
/// Samples per channel.
pub const SAMPLES: usize = THETA_H * THETA_D * PHI_D;
/// Channel scales (red, green, blue).
pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// Size of a MERL file in bytes.
pub const FILE_BYTES: usize = 12 + 3 * SAMPLES * 8;

/// A measured BRDF: the scaled RGB values of every bin, invalid ones as 0.
///
/// # Format
/// Three little-endian `int32` dimensions `{90, 90, 180}` (`theta_h`,
/// `theta_d`, `phi_d`), then `3 n` little-endian `f64`, `n = 90 * 90 * 180 =
/// 1 458 000`, channel-planar (all red values, then green, then blue): a file
/// of exactly 34 992 012 bytes. A stored value times the channel's scale (red
/// `1 / 1500`, green `1.15 / 1500`, blue `1.66 / 1500`) is the BRDF; negative
/// values mark invalid samples and read as 0.
///
/// # Lookup (nearest bin, as the reference reader `BRDFRead.cpp`)
/// Rusinkiewicz coordinates of `(wi, wo)`: `h = normalize(wi + wo)`,
/// `theta_h = acos(h_z)`, `phi_h = atan2(h_y, h_x)`, `d = Ry(-theta_h)
/// Rz(-phi_h) wi`, `theta_d = acos(d_z)`, `phi_d = atan2(d_y, d_x)` (plus `pi`
/// when negative: reciprocity halves the range). Bins:
/// `i_h = floor(sqrt(theta_h / (pi / 2)) * 90)` (denser near the specular
/// peak), `i_d = floor(theta_d / (pi / 2) * 90)`, `i_p = floor(phi_d / pi *
/// 180)`, each clamped to its range; the sample is at `i_p + 180 (i_d + 90
/// i_h)`.
#[derive(Clone)]
pub struct Merl {
    /// `[r, g, b]` per bin, already scaled.
    values: Vec<[f32; 3]>,
    /// How many stored values (over all three channels) were negative (invalid).
    invalid: usize,
    /// Per bin, whether all three channels were valid (`None`: all were).
    valid: Option<Vec<bool>>,
}

impl std::fmt::Debug for Merl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Merl")
            .field("invalid", &self.invalid)
            .finish_non_exhaustive()
    }
}

impl Merl {
    /// Reads a MERL file.
    ///
    /// # Errors
    /// [`ShadeError::File`] naming the file when it cannot be read, has another
    /// size or other dimensions, or holds NaN/infinite values.
    pub fn read(path: &Path) -> Result<Self> {
        let ferr = |reason: String| ShadeError::File {
            path: path.to_path_buf(),
            reason,
        };
        let meta = std::fs::metadata(path).map_err(|e| ferr(format!("cannot read: {e}")))?;
        if meta.len() != FILE_BYTES as u64 {
            return Err(ferr(format!(
                "not a MERL BRDF file: {} bytes, a MERL file has exactly {FILE_BYTES} \
                 (12-byte header of dimensions 90 x 90 x 180, then 3 x {SAMPLES} float64)",
                meta.len()
            )));
        }
        let mut bytes = Vec::with_capacity(FILE_BYTES);
        std::fs::File::open(path)
            .and_then(|mut f| f.read_to_end(&mut bytes))
            .map_err(|e| ferr(format!("cannot read: {e}")))?;
        if bytes.len() != FILE_BYTES {
            return Err(ferr(format!(
                "truncated while reading: {} of {FILE_BYTES} bytes",
                bytes.len()
            )));
        }
        let dims: Vec<i32> = bytes[..12]
            .chunks_exact(4)
            .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if dims != [THETA_H as i32, THETA_D as i32, PHI_D as i32] {
            return Err(ferr(format!(
                "MERL dimensions {dims:?}, expected [90, 90, 180]"
            )));
        }
        let value = |i: usize| {
            let o = 12 + 8 * i;
            let mut b = [0u8; 8];
            b.copy_from_slice(&bytes[o..o + 8]);
            f64::from_le_bytes(b)
        };
        let mut values = vec![[0.0f32; 3]; SAMPLES];
        let mut valid = vec![true; SAMPLES];
        let mut invalid = 0;
        for c in 0..3 {
            for (i, v) in values.iter_mut().enumerate() {
                let x = value(c * SAMPLES + i);
                if !x.is_finite() {
                    return Err(ferr(format!(
                        "non-finite value {x} at sample {i} of channel {c}"
                    )));
                }
                // (the BRDF is kept in f32; measured values are below 1e4)
                if x * SCALE[c] > 1e30 {
                    return Err(ferr(format!(
                        "value {x:e} at sample {i} of channel {c} is too large for a BRDF"
                    )));
                }
                if x < 0.0 {
                    invalid += 1;
                    valid[i] = false;
                }
                v[c] = (x.max(0.0) * SCALE[c]) as f32;
            }
        }
        Ok(Self {
            values,
            invalid,
            valid: (invalid > 0).then_some(valid),
        })
    }

    /// Tabulates `f(theta_h, theta_d, phi_d) -> [r, g, b]` at the centre of
    /// every bin ([`bin_centre`]), as a MERL file would store it.
    #[must_use]
    pub fn tabulate(f: impl Fn(f64, f64, f64) -> [f64; 3] + Sync) -> Self {
        use rayon::prelude::*;
        let values = (0..SAMPLES)
            .into_par_iter()
            .map(|i| {
                let (th, td, pd) = bin_centre(i);
                let v = f(th, td, pd);
                [v[0] as f32, v[1] as f32, v[2] as f32]
            })
            .collect();
        Self {
            values,
            invalid: 0,
            valid: None,
        }
    }

    /// Writes the BRDF in the MERL format (atomically).
    ///
    /// # Errors
    /// [`ShadeError::File`] when the file cannot be written.
    pub fn write(&self, path: &Path) -> Result<()> {
        ifd_image::atomic_write(path, |w| {
            let e = |e: std::io::Error| e.to_string();
            for d in [THETA_H, THETA_D, PHI_D] {
                w.write_all(&(d as i32).to_le_bytes()).map_err(e)?;
            }
            for c in 0..3 {
                for v in &self.values {
                    w.write_all(&(f64::from(v[c]) / SCALE[c]).to_le_bytes())
                        .map_err(e)?;
                }
            }
            Ok(())
        })
        .map_err(|e| ShadeError::File {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
    }

    /// The bytes of every stored value (for digests identifying the data).
    pub fn digest_bytes(&self) -> impl Iterator<Item = u8> + '_ {
        self.values
            .iter()
            .flat_map(|v| v.iter().flat_map(|x| x.to_le_bytes()))
    }

    /// How many stored values of the file (over all three channels) were
    /// negative (invalid, read as 0).
    #[must_use]
    pub fn invalid_values(&self) -> usize {
        self.invalid
    }

    /// Whether the bin of `(wi, wo)` holds valid data in every channel (a
    /// negative stored value marks a hole).
    #[must_use]
    pub fn is_valid(&self, wi: [f64; 3], wo: [f64; 3]) -> bool {
        self.valid.as_ref().is_none_or(|v| {
            let (th, _, td, pd) = half_diff(wi, wo);
            v[bin_index(th, td, pd)]
        })
    }

    /// The BRDF value `[r, g, b]` for light `wi` and view `wo` (local frame,
    /// unit vectors in the upper hemisphere), nearest bin.
    #[must_use]
    pub fn eval(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        let (th, _, td, pd) = half_diff(wi, wo);
        let v = self.values[bin_index(th, td, pd)];
        [f64::from(v[0]), f64::from(v[1]), f64::from(v[2])]
    }
}

/// Rusinkiewicz coordinates `(theta_h, phi_h, theta_d, phi_d)` of `(wi, wo)`.
#[must_use]
pub fn half_diff(wi: [f64; 3], wo: [f64; 3]) -> (f64, f64, f64, f64) {
    let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let n = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    let h = if n > 0.0 {
        [h[0] / n, h[1] / n, h[2] / n]
    } else {
        [0.0, 0.0, 1.0]
    };
    let th = h[2].clamp(-1.0, 1.0).acos();
    let ph = h[1].atan2(h[0]);
    // d = Ry(-theta_h) Rz(-phi_h) wi
    let (s, c) = (-ph).sin_cos();
    let a = [c * wi[0] - s * wi[1], s * wi[0] + c * wi[1], wi[2]];
    let (s, c) = (-th).sin_cos();
    let d = [c * a[0] + s * a[2], a[1], -s * a[0] + c * a[2]];
    let td = d[2].clamp(-1.0, 1.0).acos();
    let pd = d[1].atan2(d[0]);
    (th, ph, td, pd)
}

/// `(wi, wo)` of Rusinkiewicz coordinates: the inverse of [`half_diff`].
#[must_use]
pub fn from_half_diff(th: f64, ph: f64, td: f64, pd: f64) -> ([f64; 3], [f64; 3]) {
    let d = [td.sin() * pd.cos(), td.sin() * pd.sin(), td.cos()];
    // wi = Rz(phi_h) Ry(theta_h) d
    let (s, c) = th.sin_cos();
    let a = [c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]];
    let (s, c) = ph.sin_cos();
    let wi = [c * a[0] - s * a[1], s * a[0] + c * a[1], a[2]];
    let h = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
    let k = 2.0 * (h[0] * wi[0] + h[1] * wi[1] + h[2] * wi[2]);
    let wo = [k * h[0] - wi[0], k * h[1] - wi[1], k * h[2] - wi[2]];
    (wi, wo)
}

/// Flat index of the bin of `(theta_h, theta_d, phi_d)` (see the module docs).
#[must_use]
pub fn bin_index(th: f64, td: f64, pd: f64) -> usize {
    let clamp = |x: f64, n: usize| (x.max(0.0) as usize).min(n - 1);
    let ih = if th <= 0.0 {
        0
    } else {
        clamp((th / FRAC_PI_2 * 8100.0).sqrt(), THETA_H)
    };
    let id = clamp(td / FRAC_PI_2 * 90.0, THETA_D);
    let pd = if pd < 0.0 { pd + PI } else { pd };
    let ip = clamp(pd / PI * 180.0, PHI_D);
    ip + PHI_D * (id + THETA_D * ih)
}

/// The angles `(theta_h, theta_d, phi_d)` at the centre of bin `i`.
#[must_use]
pub fn bin_centre(i: usize) -> (f64, f64, f64) {
    let ip = i % PHI_D;
    let id = (i / PHI_D) % THETA_D;
    let ih = i / (PHI_D * THETA_D);
    let u = (ih as f64 + 0.5) / 90.0;
    (
        u * u * FRAC_PI_2,
        (id as f64 + 0.5) / 90.0 * FRAC_PI_2,
        (ip as f64 + 0.5) / 180.0 * PI,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_diff_round_trips_and_bins_invert() {
        for i in [0, 17, 1000, 700_000, SAMPLES - 1] {
            let (th, td, pd) = bin_centre(i);
            let (wi, wo) = from_half_diff(th, 0.7, td, pd);
            let (a, b, c, d) = half_diff(wi, wo);
            assert!((a - th).abs() < 1e-9 && (b - 0.7).abs() < 1e-9, "{i}");
            assert!((c - td).abs() < 1e-9 && (d - pd).abs() < 1e-9, "{i}");
            assert_eq!(bin_index(a, c, d), i);
        }
    }
}
