//! [`ShCoeffs`]: real SH coefficients of a (multi-channel) spherical function,
//! and their `.npy` file format.

use std::path::Path;

use crate::error::{Result, SphereError, check_degree};
use crate::sh::{ShEvaluator, sh_count, sh_index};

/// Real SH coefficients `c_l^m` for `l <= L` of a function with `C` channels.
///
/// Layout: `((L + 1)^2, C)` row-major, row `l (l + 1) + m` (see [`crate::ShEvaluator`]
/// for the basis convention). This is also the layout of the `.npy` files
/// written by [`ShCoeffs::write_npy`] (float64).
#[derive(Clone, Debug, PartialEq)]
pub struct ShCoeffs {
    l_max: usize,
    channels: usize,
    data: Vec<f64>,
}

impl ShCoeffs {
    /// All-zero coefficients.
    ///
    /// # Errors
    /// [`SphereError::DegreeTooHigh`], or [`SphereError::Parameter`] for zero channels.
    pub fn zeros(l_max: usize, channels: usize) -> Result<Self> {
        check_degree(l_max)?;
        if channels == 0 {
            return Err(SphereError::Parameter {
                name: "channels",
                value: "0".into(),
                reason: "at least one channel is needed",
            });
        }
        Ok(Self {
            l_max,
            channels,
            data: vec![0.0; sh_count(l_max) * channels],
        })
    }

    /// Wraps `((L + 1)^2, C)` row-major values.
    ///
    /// # Errors
    /// [`SphereError::Length`] when the length does not match.
    pub fn from_vec(l_max: usize, channels: usize, data: Vec<f64>) -> Result<Self> {
        let mut z = Self::zeros(l_max, channels)?;
        if data.len() != z.data.len() {
            return Err(SphereError::Length {
                what: "SH coefficients",
                got: data.len(),
                expected: z.data.len(),
            });
        }
        z.data = data;
        Ok(z)
    }

    /// Builds coefficients from `rows x channels` values, inferring `L` from
    /// `rows = (L + 1)^2`.
    ///
    /// # Errors
    /// [`SphereError::Length`] when `rows` is not a perfect square.
    pub fn from_rows(rows: usize, channels: usize, data: Vec<f64>) -> Result<Self> {
        let l1 = (rows as f64).sqrt().round() as usize;
        if l1 == 0 || l1 * l1 != rows {
            return Err(SphereError::Length {
                what: "SH coefficient rows (must be (L+1)^2)",
                got: rows,
                expected: l1.max(1) * l1.max(1),
            });
        }
        Self::from_vec(l1 - 1, channels, data)
    }

    /// Maximum degree `L`.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// Channel count `C`.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The raw `((L + 1)^2, C)` values.
    #[must_use]
    pub fn data(&self) -> &[f64] {
        &self.data
    }

    /// Mutable raw values.
    pub fn data_mut(&mut self) -> &mut [f64] {
        &mut self.data
    }

    /// `c_l^m` of channel `c`.
    ///
    /// # Panics
    /// If `l > L`, `|m| > l` or `c >= C`.
    #[must_use]
    pub fn get(&self, l: usize, m: i64, c: usize) -> f64 {
        assert!(l <= self.l_max && m.unsigned_abs() as usize <= l && c < self.channels);
        self.data[sh_index(l, m) * self.channels + c]
    }

    /// Sets `c_l^m` of channel `c`.
    ///
    /// # Panics
    /// If `l > L`, `|m| > l` or `c >= C`.
    pub fn set(&mut self, l: usize, m: i64, c: usize, v: f64) {
        assert!(l <= self.l_max && m.unsigned_abs() as usize <= l && c < self.channels);
        self.data[sh_index(l, m) * self.channels + c] = v;
    }

    /// One channel as a flat `(L + 1)^2` vector.
    ///
    /// # Panics
    /// If `c >= C`.
    #[must_use]
    pub fn channel(&self, c: usize) -> Vec<f64> {
        assert!(c < self.channels);
        self.data
            .iter()
            .skip(c)
            .step_by(self.channels)
            .copied()
            .collect()
    }

    /// Copy truncated or zero-padded to degree `l_max`.
    ///
    /// # Errors
    /// [`SphereError::DegreeTooHigh`].
    pub fn resized(&self, l_max: usize) -> Result<Self> {
        let mut out = Self::zeros(l_max, self.channels)?;
        let n = sh_count(l_max.min(self.l_max)) * self.channels;
        out.data[..n].copy_from_slice(&self.data[..n]);
        Ok(out)
    }

    /// Evaluates the expansion at direction `d` with a prepared evaluator of
    /// degree `>= L`; returns one value per channel.
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the evaluator's degree is lower than `L`.
    pub fn eval(&self, sh: &ShEvaluator, d: [f64; 3]) -> Result<Vec<f64>> {
        if sh.l_max() < self.l_max {
            return Err(SphereError::Mismatch(format!(
                "evaluator of degree {} for coefficients of degree {}",
                sh.l_max(),
                self.l_max
            )));
        }
        let y = sh.eval(d);
        let mut out = vec![0.0; self.channels];
        for (i, yi) in y.iter().take(sh_count(self.l_max)).enumerate() {
            for (c, o) in out.iter_mut().enumerate() {
                *o += yi * self.data[i * self.channels + c];
            }
        }
        Ok(out)
    }

    /// Writes a `((L + 1)^2, C)` float64 `.npy` file (atomically).
    ///
    /// # Errors
    /// [`SphereError::Image`] wrapping the I/O error, naming the file.
    pub fn write_npy(&self, path: &Path) -> Result<()> {
        Ok(ifd_image::write_npy_f64(
            path,
            &[sh_count(self.l_max), self.channels],
            &self.data,
        )?)
    }

    /// Reads a float64 or float32 `.npy` file of shape `((L + 1)^2, C)` or
    /// `((L + 1)^2,)` (one channel).
    ///
    /// # Errors
    /// [`SphereError::File`] for unreadable or malformed files and for NaN or
    /// infinite coefficients (naming the count and the first row/column);
    /// [`SphereError::Length`] when the row count is not `(L + 1)^2`.
    pub fn read_npy(path: &Path) -> Result<Self> {
        Ok(Self::read_npy_shaped(path)?.0)
    }

    /// As [`Self::read_npy`], also returning the file's shape (`[(L + 1)^2]`
    /// or `[(L + 1)^2, C]`), so that a result can be written in the same shape.
    ///
    /// # Errors
    /// As [`Self::read_npy`].
    pub fn read_npy_shaped(path: &Path) -> Result<(Self, Vec<usize>)> {
        let (shape, data) = read_npy_f64(path)?;
        let (rows, cols) = match shape.as_slice() {
            [r] => (*r, 1),
            [r, c] => (*r, *c),
            _ => {
                return Err(SphereError::File {
                    path: path.to_path_buf(),
                    reason: format!("expected a 1-D or 2-D array, got shape {shape:?}"),
                });
            }
        };
        if let Some(first) = data.iter().position(|v| !v.is_finite()) {
            let count = data.iter().filter(|v| !v.is_finite()).count();
            return Err(SphereError::File {
                path: path.to_path_buf(),
                reason: format!(
                    "{count} non-finite SH coefficient(s) (NaN or infinity), first at row {}, \
                     column {} ({})",
                    first / cols,
                    first % cols,
                    data[first]
                ),
            });
        }
        let coeffs = Self::from_rows(rows, cols, data).map_err(|e| SphereError::File {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Ok((coeffs, shape))
    }
}

/// Reads a float64 or float32 (or uint8/uint16) `.npy` array of any shape
/// as `f64`, row-major ([`ifd_image::read_npy_array`]: either byte order,
/// C or Fortran order, the machine's default memory budget).
///
/// # Errors
/// [`SphereError::Image`] naming the file for unreadable or malformed files.
pub fn read_npy_f64(path: &Path) -> Result<(Vec<usize>, Vec<f64>)> {
    let a = ifd_image::read_npy_array(path, ifd_image::MemoryBudget::default_for_machine())?;
    Ok((a.shape, a.data))
}
