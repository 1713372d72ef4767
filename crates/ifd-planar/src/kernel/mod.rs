//! Sampled 2D filters ([`Kernel`]) and the built-in filter specs ([`KernelSpec`]).

use std::str::FromStr;

mod raster;
mod spec;

/// The largest accepted kernel half-size `R` (the grid is `(2R+1)^2`).
pub const MAX_RADIUS: usize = 2048;

/// Samples per pixel along each axis when area-sampling hard-edged shapes.
const SUPERSAMPLE: usize = 16;

/// Everything that can be wrong with a kernel or a kernel spec.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KernelError {
    /// Width or height is even (or zero): the kernel would have no centre pixel.
    #[error(
        "kernel is {width}x{height}, expected odd width and height (the centre is the middle pixel)"
    )]
    EvenSize {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
    },
    /// The sample count does not match the size.
    #[error("kernel is {width}x{height} but {len} samples were given")]
    SizeMismatch {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
        /// Samples given.
        len: usize,
    },
    /// A sample is NaN or infinite.
    #[error("kernel sample at column {x}, row {y} is {value} (not finite)")]
    NonFinite {
        /// Column.
        x: usize,
        /// Row.
        y: usize,
        /// The value.
        value: f64,
    },
    /// Every sample is zero.
    #[error("kernel is all zero ({width}x{height})")]
    AllZero {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
    },
    /// An image with more than one channel was given as a kernel.
    #[error("kernel image has {channels} channels, expected 1")]
    Channels {
        /// The channel count.
        channels: usize,
    },
    /// The kernel would be larger than [`MAX_RADIUS`].
    #[error("kernel half-size {radius} px is larger than the limit {MAX_RADIUS} px")]
    TooLarge {
        /// The half-size asked for.
        radius: f64,
    },
    /// The spec name is not one of the built-in filters.
    #[error("unknown kernel spec {name:?} (known: gauss, dgauss, log, gabor, box, disk, line)")]
    UnknownSpec {
        /// The name given.
        name: String,
    },
    /// A key the spec does not take.
    #[error("spec {spec:?} has no key {key:?} (keys: {known})")]
    UnknownKey {
        /// The spec name.
        spec: String,
        /// The key given.
        key: String,
        /// The keys it takes.
        known: String,
    },
    /// A required key is missing.
    #[error("spec {spec:?} needs {key}=")]
    MissingKey {
        /// The spec name.
        spec: String,
        /// The missing key.
        key: &'static str,
    },
    /// A value could not be parsed or is out of range.
    #[error("bad value {key}={value:?}: {reason}")]
    BadValue {
        /// The key.
        key: String,
        /// The value given.
        value: String,
        /// Why it is rejected.
        reason: String,
    },
    /// The spec string is not `name:key=value,...`.
    #[error("cannot parse kernel spec {spec:?}: {reason}")]
    Syntax {
        /// The spec string.
        spec: String,
        /// Why.
        reason: String,
    },
}

/// Which second derivative [`KernelSpec::DGauss`] takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DerivOrder {
    /// `d^2/dx^2` (x = column).
    Xx,
    /// `d^2/dxdy`.
    Xy,
    /// `d^2/dy^2` (y = row).
    Yy,
}

/// A built-in filter, parsed from a spec string such as `gauss:sx=24,sy=3,theta=30`.
///
/// `radius` is the grid half-size `R` when given; `None` picks the default.
/// Lengths are in pixels, angles in degrees (see the spec strings below).
///
/// Sampled 2D filters ([`Kernel`]) and the built-in filter specs ([`KernelSpec`]).
///
/// A kernel has odd width and height; its centre is the middle pixel and it is
/// addressed by offset from the centre, `x` = column (right), `y` = row (down).
///
/// # Spec strings
/// `name:key=value,key=value`, parsed by [`KernelSpec`]'s `FromStr` (and by
/// [`Kernel`]'s, which also samples it):
///
/// | spec | keys (defaults) | filter |
/// |---|---|---|
/// | `gauss` | `sx`, `sy` (= `sx`), `theta` (0) | anisotropic Gaussian, std devs in px along the rotated axes, normalised to sum 1 |
/// | `dgauss` | `order` = `xx`/`xy`/`yy`, `sigma`, `theta` (0) | second derivative of the normalised Gaussian `g_sigma` |
/// | `log` | `sigma` | Laplacian of `g_sigma` (`g_xx + g_yy`) |
/// | `gabor` | `sigma`, `freq` (cycles/px), `theta` (0) | `g_sigma(d) cos(2 pi freq u)`, `u` along the rotated `x` axis |
/// | `box` | `w`, `h` (= `w`), `theta` (0) | rectangle `w x h` px, area-sampled, sum 1 |
/// | `disk` | `r` | disk of radius `r` px, area-sampled, sum 1 |
/// | `line` | `len`, `width` (1), `theta` (0) | motion blur: a `len x width` rectangle along `theta`, area-sampled, sum 1 |
///
/// Every spec also takes `radius=` (alias `r=` except for `disk`, where `r` is
/// the disk radius): the half-size `R` of the `(2R+1) x (2R+1)` grid. By default
/// `R = ceil(4 * largest sigma)` for the smooth filters and the smallest `R`
/// holding the shape for the hard-edged ones.
///
/// Angles are degrees, counter-clockwise on screen. With
/// `R_theta = [[cos, sin], [-sin, cos]]` in `(x right, y down)` coordinates, a
/// filter rotated by `theta` is `k_theta(d) = k(R_{-theta} d)`: its local
/// coordinates are `(u, v) = R_{-theta} d = (cos x - sin y, sin x + cos y)`.
///
/// ```
/// use ifd_planar::Kernel;
/// let k: Kernel = "gauss:sx=6,sy=2,theta=30".parse()?;
/// assert_eq!((k.width(), k.height()), (49, 49)); // R = ceil(4 * 6) = 24
/// assert!((k.sum() - 1.0).abs() < 1e-12);
/// assert!(k.get(0, 0) > k.get(0, 3));
/// # Ok::<(), ifd_planar::KernelError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub enum KernelSpec {
    /// Anisotropic Gaussian normalised to sum 1.
    Gauss {
        /// Std dev along the rotated `x` axis.
        sx: f64,
        /// Std dev along the rotated `y` axis.
        sy: f64,
        /// Rotation, degrees CCW.
        theta: f64,
        /// Grid half-size.
        radius: Option<usize>,
    },
    /// Second derivative of the normalised isotropic Gaussian.
    DGauss {
        /// Which derivative.
        order: DerivOrder,
        /// Std dev.
        sigma: f64,
        /// Rotation, degrees CCW.
        theta: f64,
        /// Grid half-size.
        radius: Option<usize>,
    },
    /// Laplacian of the normalised Gaussian.
    Log {
        /// Std dev.
        sigma: f64,
        /// Grid half-size.
        radius: Option<usize>,
    },
    /// Gabor filter `g_sigma(d) cos(2 pi freq u)`.
    Gabor {
        /// Std dev of the envelope.
        sigma: f64,
        /// Frequency, cycles per pixel.
        freq: f64,
        /// Rotation, degrees CCW.
        theta: f64,
        /// Grid half-size.
        radius: Option<usize>,
    },
    /// Rotated rectangle, area-sampled, sum 1.
    Box {
        /// Width along the rotated `x` axis.
        w: f64,
        /// Height along the rotated `y` axis.
        h: f64,
        /// Rotation, degrees CCW.
        theta: f64,
        /// Grid half-size.
        radius: Option<usize>,
    },
    /// Disk, area-sampled, sum 1.
    Disk {
        /// Disk radius.
        r: f64,
        /// Grid half-size.
        radius: Option<usize>,
    },
    /// Motion blur: a `len x width` segment along `theta`, area-sampled, sum 1.
    Line {
        /// Length.
        len: f64,
        /// Width.
        width: f64,
        /// Direction, degrees CCW.
        theta: f64,
        /// Grid half-size.
        radius: Option<usize>,
    },
}

/// A sampled 2D filter: odd width and height, centre at the middle pixel,
/// `f64` samples row-major (row = `y`, down; column = `x`, right).
#[derive(Clone, Debug, PartialEq)]
pub struct Kernel {
    width: usize,
    height: usize,
    data: Vec<f64>,
    spec: Option<String>,
    sampling: Sampling,
}

/// How a kernel's values relate to the continuous filter they sample, which
/// decides how its decomposition is applied at other scales
/// ([`Sampling::footprint_variance`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sampling {
    /// The decomposition is a continuous filter in its own right (terms
    /// given directly, the smoother's and the Hessian's Gaussians): applied
    /// at any scale as its scaled sum of Gaussians sampled at pixel centres.
    #[default]
    Continuous,
    /// Values of the continuous filter at pixel centres (smooth built-in
    /// specs, kernels read from files).
    Point,
    /// Averages of the continuous filter over each pixel (hard-edged specs:
    /// `box`, `line`, `disk`).
    Area,
    /// A continuous filter (terms given directly) applied as its averages
    /// over each output pixel at every scale: the smoother's Gaussians,
    /// which must stay meaningful below a pixel's width.
    Averaged,
}

impl Sampling {
    /// The variance (px^2) added to every atom at scale `s`:
    /// `sigma_eff^2 = (s sigma)^2 + footprint_variance(s)`.
    ///
    /// `ifd filter` applies at scale `s` the continuous filter scaled by `s`,
    /// averaged over each output pixel where the kernel was fitted that way
    /// (`Area`) or where `s < 1` (a kernel shrunk below its sampling would
    /// alias), and sampled at pixel centres otherwise. Averaging over a pixel
    /// is, to second order, a Gaussian blur of variance `1/12` px^2 per axis;
    /// a decomposition fitted to pixel averages already carries that blur,
    /// scaled by `s` (variance `s^2 / 12`). Hence
    /// `target - s^2 fitted`, with `target` and `fitted` each `1/12` or `0`:
    /// `(1 - s^2) / 12` for `Area`, `1/12` below scale 1 for `Point`, `1/12`
    /// at every scale for `Averaged`, and `0` otherwise.
    ///
    /// ```
    /// use ifd_planar::Sampling;
    /// assert_eq!(Sampling::Point.footprint_variance(2.0), 0.0);
    /// assert_eq!(Sampling::Point.footprint_variance(0.5), 1.0 / 12.0);
    /// assert_eq!(Sampling::Area.footprint_variance(1.0), 0.0);
    /// assert!((Sampling::Area.footprint_variance(2.0) + 0.25).abs() < 1e-12);
    /// assert_eq!(Sampling::Continuous.footprint_variance(0.5), 0.0);
    /// assert_eq!(Sampling::Averaged.footprint_variance(3.0), 1.0 / 12.0);
    /// ```
    #[must_use]
    pub fn footprint_variance(self, s: f64) -> f64 {
        const BOX: f64 = 1.0 / 12.0;
        match self {
            Self::Point if s < 1.0 => BOX,
            Self::Continuous | Self::Point => 0.0,
            Self::Area => BOX * (1.0 - s * s),
            Self::Averaged => BOX,
        }
    }

    /// [`Self::footprint_variance`]`(s) / s^2` as `(v, c, below)`: `v / s^2 + c`
    /// for `s < below`, 0 from `below` on (the per-pixel level rule's
    /// widening, one expression for every sampling).
    pub(crate) fn footprint_over_s2(self) -> (f64, f64, f64) {
        const BOX: f64 = 1.0 / 12.0;
        match self {
            Self::Point => (BOX, 0.0, 1.0),
            Self::Continuous => (0.0, 0.0, 0.0),
            Self::Area => (BOX, -BOX, f64::INFINITY),
            Self::Averaged => (BOX, 0.0, f64::INFINITY),
        }
    }

    /// The effective standard deviation of an atom of `sigma` at scale `s`:
    /// `sqrt((s sigma)^2 + footprint_variance(s))`, kept at least `s sigma / 2`.
    #[must_use]
    pub fn effective_sigma(self, sigma: f64, s: f64) -> f64 {
        let ss = s * sigma;
        (ss * ss + self.footprint_variance(s))
            .max(MIN_VARIANCE_RATIO * ss * ss)
            .sqrt()
    }
}

/// The least `sigma_eff^2 / (s sigma)^2` of [`Sampling::effective_sigma`]:
/// an atom keeps at least half its scaled width.
const MIN_VARIANCE_RATIO: f64 = 0.25;

/// The floor [`ln_widening`] (both branches) and [`widening_needs_log`] put
/// on their `x`: `MIN_VARIANCE_RATIO - 1` (the vector lanes of the level
/// rule take the same floor).
pub(crate) const WIDENING_FLOOR: f32 = (MIN_VARIANCE_RATIO - 1.0) as f32;

/// `ln(sigma_eff / (s sigma))` of [`Sampling::effective_sigma`] for
/// `x = footprint_variance(s) / (s sigma)^2`: `ln(max(1 + x, 1/4)) / 2`
/// (the same floor), in `f32`, the precision of the per-pixel level rule
/// that reads it. For `|x| < 0.03` (atoms a few pixels wide) a series to
/// `x^4` that costs no logarithm, so a per-pixel scale map's level choice
/// takes none per term: the terms left out sum to at most
/// `|x|^5 / 10 / (1 - |x|) < 2.6e-9`, below the `f32` rounding of the level
/// position it is added to. From `|x| = 0.03` on (the pixel footprint of a
/// point-sampled atom at scales well below 1), [`crate::ln::ln`] of the
/// `f32` sum `1 + x`: one sequence of IEEE operations that the vector rows
/// follow too (`fill_levels`), so that no pixel's level takes a scalar
/// call. The sum's rounding (half a unit of `1 + x`) and the logarithm's
/// few units leave the result within a few `f32` units of the exact value
/// (`1.2e-7` for `|x| <= 2`, tested to `x = 1e4`), far below the snap and
/// the read windows' slack of the level position it enters.
#[inline]
pub(crate) fn ln_widening(x: f32) -> f32 {
    if widening_needs_log(x) {
        0.5 * crate::ln::ln(1.0 + x.max(WIDENING_FLOOR))
    } else {
        ln_widening_series(x)
    }
}

/// Whether [`ln_widening`] at `x` takes the logarithm (`|x| >= 0.03` after
/// the floor), not the series.
#[inline]
pub(crate) fn widening_needs_log(x: f32) -> bool {
    x.max(WIDENING_FLOOR).abs() >= LOG_FROM
}

/// Where [`ln_widening`] leaves its series for the logarithm: `|x|` from
/// here on.
pub(crate) const LOG_FROM: f32 = 0.03;

/// [`ln_widening`]'s series branch, branch-free (its value wherever
/// [`widening_needs_log`] is false): `(x - x^2/2 + x^3/3 - x^4/4) / 2` as
/// odd and even parts. The per-pixel level rule over a row evaluates it in
/// vector lanes (`stack::rows::rules::fill_levels` writes these operations
/// in this order) and selects the logarithm in the lanes that need it.
#[inline]
pub(crate) fn ln_widening_series(x: f32) -> f32 {
    let x = x.max(WIDENING_FLOOR);
    let x2 = x * x;
    // constant factors, not divisions
    let odd = x * (1.0 + x2 * (1.0 / 3.0));
    let even = x2 * (0.5 + x2 * 0.25);
    0.5 * (odd - even)
}

impl Kernel {
    /// A kernel from row-major samples.
    ///
    /// ```
    /// use ifd_planar::Kernel;
    /// let k = Kernel::new(3, 1, vec![1.0, 2.0, 3.0])?;
    /// assert_eq!(k.get(-1, 0), 1.0);
    /// assert_eq!(k.get(1, 0), 3.0);
    /// assert_eq!(k.get(2, 0), 0.0); // outside
    /// assert!(Kernel::new(2, 1, vec![1.0, 1.0]).is_err());
    /// # Ok::<(), ifd_planar::KernelError>(())
    /// ```
    ///
    /// # Errors
    /// [`KernelError::EvenSize`], [`KernelError::SizeMismatch`],
    /// [`KernelError::NonFinite`], [`KernelError::AllZero`], or
    /// [`KernelError::TooLarge`] for a half-size above [`MAX_RADIUS`].
    pub fn new(width: usize, height: usize, data: Vec<f64>) -> Result<Self, KernelError> {
        if width.is_multiple_of(2) || height.is_multiple_of(2) {
            return Err(KernelError::EvenSize { width, height });
        }
        if width / 2 > MAX_RADIUS || height / 2 > MAX_RADIUS {
            return Err(KernelError::TooLarge {
                radius: (width.max(height) / 2) as f64,
            });
        }
        if data.len() != width * height {
            return Err(KernelError::SizeMismatch {
                width,
                height,
                len: data.len(),
            });
        }
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            return Err(KernelError::NonFinite {
                x: i % width,
                y: i / width,
                value: data[i],
            });
        }
        if data.iter().all(|&v| v == 0.0) {
            return Err(KernelError::AllZero { width, height });
        }
        Ok(Self {
            width,
            height,
            data,
            spec: None,
            sampling: Sampling::Point,
        })
    }

    /// A kernel from a single-channel image (e.g. loaded from `.npy`, `.png`
    /// or `.exr`), used as is (no normalisation).
    ///
    /// # Errors
    /// [`KernelError::Channels`] for more than one channel, and the errors of [`Kernel::new`].
    pub fn from_image(image: &ifd_image::Image) -> Result<Self, KernelError> {
        if image.channels() != 1 {
            return Err(KernelError::Channels {
                channels: image.channels(),
            });
        }
        Self::new(
            image.width(),
            image.height(),
            image.data().iter().map(|&v| f64::from(v)).collect(),
        )
    }

    /// The kernel with `m` rows and columns of zeros added on every side (the
    /// same spec and sampling).
    ///
    /// ```
    /// use ifd_planar::Kernel;
    /// let k = Kernel::new(3, 1, vec![1.0, 2.0, 3.0])?.padded(2);
    /// assert_eq!((k.width(), k.height()), (7, 5));
    /// assert_eq!((k.get(1, 0), k.get(3, 0), k.get(0, 2)), (3.0, 0.0, 0.0));
    /// # Ok::<(), ifd_planar::KernelError>(())
    /// ```
    #[must_use]
    pub fn padded(&self, m: usize) -> Self {
        let (w, h) = (self.width + 2 * m, self.height + 2 * m);
        let mut data = vec![0.0; w * h];
        for (row, src) in self.data.chunks_exact(self.width).enumerate() {
            let start = (row + m) * w + m;
            data[start..start + self.width].copy_from_slice(src);
        }
        Self {
            width: w,
            height: h,
            data,
            spec: self.spec.clone(),
            sampling: self.sampling,
        }
    }

    /// Width in pixels (odd).
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels (odd).
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Half-width: offsets `dx` run over `-radius_x()..=radius_x()`.
    #[must_use]
    pub fn radius_x(&self) -> usize {
        self.width / 2
    }

    /// Half-height: offsets `dy` run over `-radius_y()..=radius_y()`.
    #[must_use]
    pub fn radius_y(&self) -> usize {
        self.height / 2
    }

    /// The samples, row-major.
    #[must_use]
    pub fn data(&self) -> &[f64] {
        &self.data
    }

    /// The spec string the kernel was made from, if any.
    #[must_use]
    pub fn spec(&self) -> Option<&str> {
        self.spec.as_deref()
    }

    /// Sets or clears the spec string recorded with the kernel.
    pub fn set_spec(&mut self, spec: Option<String>) {
        self.spec = spec;
    }

    /// How the values sample the continuous filter: [`Sampling::Area`] for
    /// the hard-edged built-in specs, [`Sampling::Point`] otherwise.
    #[must_use]
    pub fn sampling(&self) -> Sampling {
        self.sampling
    }

    /// The sample at offset `(dx, dy)` from the centre; zero outside the kernel.
    #[must_use]
    pub fn get(&self, dx: isize, dy: isize) -> f64 {
        let col = dx + self.radius_x() as isize;
        let row = dy + self.radius_y() as isize;
        if col < 0 || row < 0 || col >= self.width as isize || row >= self.height as isize {
            return 0.0;
        }
        self.data[row as usize * self.width + col as usize]
    }

    /// Sum of all samples (the filter's DC gain).
    #[must_use]
    pub fn sum(&self) -> f64 {
        self.data.iter().sum()
    }

    /// L2 norm of the samples.
    #[must_use]
    pub fn l2_norm(&self) -> f64 {
        self.data.iter().map(|v| v * v).sum::<f64>().sqrt()
    }

    /// Largest absolute sample.
    #[must_use]
    pub fn max_abs(&self) -> f64 {
        self.data.iter().fold(0.0, |m, v| m.max(v.abs()))
    }
}

impl FromStr for Kernel {
    type Err = KernelError;

    /// Parses a [`KernelSpec`] and samples it.
    fn from_str(s: &str) -> Result<Self, KernelError> {
        s.parse::<KernelSpec>()?.to_kernel()
    }
}

#[cfg(test)]
mod tests;
