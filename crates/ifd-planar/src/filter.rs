//! IFD filtering (Eq. 3): `out(p) = sum_t w_t fhat_{s sigma_t}(p + s R_theta c_t)`
//! with one trilinear scale-stack lookup per term and pixel.
//!
//! ```
//! use ifd_image::Image;
//! use ifd_planar::{Border, Decomposition, Field, Filter, StackOptions, Term, stack_for_decomposition};
//! // An anisotropic kernel: two displaced Gaussians along x.
//! let d = Decomposition::from_terms(vec![
//!     Term { weight: 0.5, x: -6.0, y: 0.0, sigma: 1.5 },
//!     Term { weight: 0.5, x: 6.0, y: 0.0, sigma: 1.5 },
//! ]);
//! let mut img = Image::new(64, 48, 1)?;
//! img.set(32, 24, 0, 1.0);
//! let stack = stack_for_decomposition(&img, &d, 1.0, 1.0, Border::Reflect101, StackOptions::default())?;
//! let filter = Filter::new(&stack, &d)?;
//! // Rotated by 90 degrees (counter-clockwise on screen) the lobes lie along
//! // y: the impulse response has its peaks 6 px above and below the impulse.
//! let out = filter.apply(Field::Constant(90.0), Field::Constant(1.0))?;
//! assert!(out.get(32, 18, 0) > 10.0 * out.get(38, 24, 0));
//! assert!(out.get(32, 30, 0) > 10.0 * out.get(26, 24, 0));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use ifd_image::Image;
use rayon::prelude::*;

use crate::border::Border;
use crate::decomposition::Decomposition;
use crate::stack::{Interpolation, ScaleStack, StackLayout, StackOptions, bspline_weights};

/// Errors of prefiltering, filtering and the brute-force references.
#[derive(Debug, thiserror::Error)]
pub enum FilterError {
    /// A zero-sized image.
    #[error("image is empty ({width}x{height} with {channels} channels)")]
    EmptyImage {
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Channels.
        channels: usize,
    },
    /// NaN or infinite values in an image or map.
    #[error(
        "{what} has {count} non-finite (NaN or infinite) values, first at x={x}, y={y}, channel {channel}"
    )]
    NonFinite {
        /// What holds them ("image", "angle map", ...).
        what: &'static str,
        /// How many.
        count: usize,
        /// Column of the first.
        x: usize,
        /// Row of the first.
        y: usize,
        /// Channel of the first.
        channel: usize,
    },
    /// A sigma range or stack option that makes no sense.
    #[error("invalid scale-stack range: {0}")]
    InvalidRange(String),
    /// A lookup at a sigma the stack does not cover.
    #[error("sigma {sigma} px is outside the scale stack's range [{min}, {max}] px")]
    SigmaOutOfRange {
        /// The sigma asked for.
        sigma: f64,
        /// Smallest sigma of the stack.
        min: f64,
        /// Largest sigma of the stack.
        max: f64,
    },
    /// A filter scale whose `s * sigma_t` falls outside the stack.
    #[error(
        "scale {scale}{location} needs sigma {needed} px (term sigma {term_sigma} px), outside the scale stack's range [{min}, {max}] px"
    )]
    ScaleOutOfRange {
        /// The offending scale.
        scale: f64,
        /// `" at pixel (x, y)"` for a map value, empty for a constant.
        location: String,
        /// The term's sigma.
        term_sigma: f64,
        /// `scale * term_sigma`.
        needed: f64,
        /// Smallest sigma of the stack.
        min: f64,
        /// Largest sigma of the stack.
        max: f64,
    },
    /// A per-pixel map of the wrong size.
    #[error("{name} map has {len} values, expected {width}x{height} = {expected}")]
    MapSize {
        /// "angle" or "scale".
        name: &'static str,
        /// Values given.
        len: usize,
        /// Image width.
        width: usize,
        /// Image height.
        height: usize,
        /// `width * height`.
        expected: usize,
    },
    /// An invalid angle or scale value.
    #[error("invalid {name} {value}{location}: {why}")]
    InvalidValue {
        /// "angle" or "scale".
        name: &'static str,
        /// The value.
        value: f32,
        /// `" at pixel (x, y)"` for a map value, empty for a constant.
        location: String,
        /// Why it is invalid.
        why: &'static str,
    },
    /// An unknown border mode name.
    #[error(
        "unknown border mode {0:?} (expected reflect101, constant, constant:VALUE, replicate or wrap)"
    )]
    InvalidBorder(String),
    /// A decomposition term that cannot be evaluated.
    #[error("decomposition term {index} is invalid: {why}")]
    InvalidTerm {
        /// Index of the term.
        index: usize,
        /// Why.
        why: String,
    },
    /// Mismatched shapes or lengths (kernels, buffers).
    #[error("{0}")]
    Shape(String),
    /// Another parameter outside its valid range.
    #[error("{0}")]
    InvalidParameter(String),
    /// The computation would need too much memory.
    #[error("too large: {0}")]
    TooLarge(String),
}

/// A per-pixel parameter (angle in degrees, or scale): a constant or a
/// row-major map of `width * height` values.
#[derive(Clone, Copy, Debug)]
pub enum Field<'a> {
    /// The same value at every pixel.
    Constant(f32),
    /// One value per pixel, row-major.
    Map(&'a [f32]),
}

impl Field<'_> {
    /// The value at pixel index `i` (`y * width + x`).
    #[inline]
    #[must_use]
    pub fn at(&self, i: usize) -> f32 {
        match self {
            Field::Constant(v) => *v,
            Field::Map(m) => m[i],
        }
    }

    /// `(min, max)` of the finite values (for sizing a stack from a scale
    /// map); `None` when there are none.
    ///
    /// ```
    /// use ifd_planar::Field;
    /// assert_eq!(Field::Map(&[1.5, 0.5, 2.0]).range(), Some((0.5, 2.0)));
    /// assert_eq!(Field::Constant(3.0).range(), Some((3.0, 3.0)));
    /// ```
    #[must_use]
    pub fn range(&self) -> Option<(f32, f32)> {
        let values: &[f32] = match self {
            Field::Constant(v) => std::slice::from_ref(v),
            Field::Map(m) => m,
        };
        values
            .iter()
            .filter(|v| v.is_finite())
            .fold(None, |acc, &v| match acc {
                None => Some((v, v)),
                Some((lo, hi)) => Some((v.min(lo), v.max(hi))),
            })
    }

    /// Checks the size and values; returns `(min, max)`.
    ///
    /// `positive` additionally requires values `> 0` (scales).
    pub(crate) fn validate(
        &self,
        name: &'static str,
        width: usize,
        height: usize,
        positive: bool,
    ) -> Result<(f32, f32), FilterError> {
        let bad = |value: f32, location: String, why| FilterError::InvalidValue {
            name,
            value,
            location,
            why,
        };
        let check = |v: f32, location: &dyn Fn() -> String| -> Result<(), FilterError> {
            if !v.is_finite() {
                Err(bad(v, location(), "not finite"))
            } else if positive && v <= 0.0 {
                Err(bad(v, location(), "must be positive"))
            } else if v.abs() > 1e6 {
                Err(bad(v, location(), "absurdly large"))
            } else {
                Ok(())
            }
        };
        match self {
            Field::Constant(v) => {
                check(*v, &String::new)?;
                Ok((*v, *v))
            }
            Field::Map(m) => {
                let expected = width * height;
                if m.len() != expected {
                    return Err(FilterError::MapSize {
                        name,
                        len: m.len(),
                        width,
                        height,
                        expected,
                    });
                }
                let mut lo = f32::INFINITY;
                let mut hi = f32::NEG_INFINITY;
                for (i, &v) in m.iter().enumerate() {
                    check(v, &|| pixel_location(i, width))?;
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
                Ok((lo, hi))
            }
        }
    }

    /// Where a value occurs: `" at pixel (x, y)"` for a map, empty for a constant.
    fn location_of(&self, value: f32, width: usize) -> String {
        match self {
            Field::Constant(_) => String::new(),
            Field::Map(m) => m
                .iter()
                .position(|&v| v == value)
                .map(|i| pixel_location(i, width))
                .unwrap_or_default(),
        }
    }
}

fn pixel_location(i: usize, width: usize) -> String {
    format!(" at pixel ({}, {})", i % width, i / width)
}

/// One decomposition term, prepared for lookups.
#[derive(Clone, Copy, Debug)]
struct Prepared {
    weight: f32,
    cx: f32,
    cy: f32,
    sigma: f64,
    ln_sigma: f64,
}

/// One resolved lookup: level, displacement from the pixel and weight.
#[derive(Clone, Copy, Debug)]
struct Tap {
    level: usize,
    ox: f32,
    oy: f32,
    weight: f32,
}

/// A decomposition bound to a scale stack, ready to filter.
#[derive(Clone, Debug)]
pub struct Filter<'a> {
    stack: &'a ScaleStack,
    terms: Vec<Prepared>,
    sigma_lo: f64,
    sigma_hi: f64,
}

impl<'a> Filter<'a> {
    /// Prepares `decomposition` for lookups into `stack`.
    ///
    /// # Errors
    /// [`FilterError::InvalidTerm`] for non-finite values or a sigma `<= 0`,
    /// [`FilterError::InvalidParameter`] for a decomposition without terms.
    pub fn new(stack: &'a ScaleStack, decomposition: &Decomposition) -> Result<Self, FilterError> {
        let terms = prepare_terms(decomposition)?;
        let sigma_lo = terms.iter().map(|t| t.sigma).fold(f64::INFINITY, f64::min);
        let sigma_hi = terms.iter().map(|t| t.sigma).fold(0.0, f64::max);
        Ok(Self {
            stack,
            terms,
            sigma_lo,
            sigma_hi,
        })
    }

    /// The stack the filter reads.
    #[must_use]
    pub fn stack(&self) -> &ScaleStack {
        self.stack
    }

    /// Number of terms `s` (lookups per pixel, each trilinear).
    #[must_use]
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// Always false: a filter has at least one term.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// Checks that every `scale * sigma_t` is covered by the stack.
    fn check_scales(&self, lo: f32, hi: f32, field: &Field<'_>) -> Result<(), FilterError> {
        let (min, max) = self.stack.sigma_range();
        for (scale, term_sigma) in [(lo, self.sigma_lo), (hi, self.sigma_hi)] {
            let needed = f64::from(scale) * term_sigma;
            if !self.stack.covers(needed) {
                return Err(FilterError::ScaleOutOfRange {
                    scale: f64::from(scale),
                    location: field.location_of(scale, self.stack.width()),
                    term_sigma,
                    needed,
                    min,
                    max,
                });
            }
        }
        Ok(())
    }

    /// Filters the whole image with the decomposed kernel rotated by `angle`
    /// (degrees, counter-clockwise on screen) and scaled by `scale`, each a
    /// constant or a per-pixel map.
    ///
    /// # Errors
    /// [`FilterError::MapSize`] for maps of the wrong size,
    /// [`FilterError::InvalidValue`] for non-finite angles or non-positive
    /// scales, [`FilterError::ScaleOutOfRange`] when some `scale * sigma_t`
    /// is not covered by the stack.
    pub fn apply(&self, angle: Field<'_>, scale: Field<'_>) -> Result<Image, FilterError> {
        let (w, h, c) = (
            self.stack.width(),
            self.stack.height(),
            self.stack.channels(),
        );
        angle.validate("angle", w, h, false)?;
        let (lo, hi) = scale.validate("scale", w, h, true)?;
        self.check_scales(lo, hi, &scale)?;
        let out = match (angle, scale) {
            (Field::Constant(theta), Field::Constant(s)) => Taps {
                taps: self.taps(theta, s),
            }
            .apply_region(self.stack, 0, 0, w, h)?,
            (angle, scale) => {
                let mut out = vec![0.0f32; w * h * c];
                match c {
                    1 => self.per_pixel::<1>(angle, scale, &mut out),
                    2 => self.per_pixel::<2>(angle, scale, &mut out),
                    3 => self.per_pixel::<3>(angle, scale, &mut out),
                    4 => self.per_pixel::<4>(angle, scale, &mut out),
                    _ => self.per_pixel::<0>(angle, scale, &mut out),
                }
                out
            }
        };
        Image::from_vec(w, h, c, out).map_err(|e| FilterError::Shape(e.to_string()))
    }

    /// The filtered value (all channels) at one point `(x, y)` (pixel
    /// coordinates, need not be integers) for angle `theta` (degrees) and
    /// scale `s`: `s` trilinear lookups, for interactive use.
    ///
    /// # Errors
    /// [`FilterError::InvalidValue`] for non-finite input or `s <= 0`,
    /// [`FilterError::ScaleOutOfRange`] when `s * sigma_t` is not covered.
    pub fn filter_at(&self, x: f32, y: f32, theta: f32, s: f32) -> Result<Vec<f32>, FilterError> {
        let mut out = vec![0.0; self.stack.channels()];
        self.filter_at_into(x, y, theta, s, &mut out)?;
        Ok(out)
    }

    /// As [`Filter::filter_at`], writing one value per channel into `out`.
    ///
    /// # Errors
    /// As [`Filter::filter_at`], and [`FilterError::Shape`] when `out.len()`
    /// is not the channel count.
    pub fn filter_at_into(
        &self,
        x: f32,
        y: f32,
        theta: f32,
        s: f32,
        out: &mut [f32],
    ) -> Result<(), FilterError> {
        if out.len() != self.stack.channels() {
            return Err(FilterError::Shape(format!(
                "output has {} channels, the stack {}",
                out.len(),
                self.stack.channels()
            )));
        }
        for (name, v) in [("x", x), ("y", y)] {
            if !v.is_finite() {
                return Err(FilterError::InvalidValue {
                    name,
                    value: v,
                    location: String::new(),
                    why: "not finite",
                });
            }
        }
        Field::Constant(theta).validate("angle", 1, 1, false)?;
        Field::Constant(s).validate("scale", 1, 1, true)?;
        self.check_scales(s, s, &Field::Constant(s))?;
        out.fill(0.0);
        let (sin, cos) = theta.to_radians().sin_cos();
        self.pixel_general::<0>(x, y, cos, sin, s, out);
        Ok(())
    }

    /// Per term: `(level a, level b, weight a, weight b)` for scale `s`.
    fn term_levels(&self, s: f32) -> Vec<(usize, usize, f32, f32)> {
        let ln_s = f64::from(s).ln();
        self.terms
            .iter()
            .map(|t| {
                let (a, b, wa, wb) = self.stack.locate_ln(ln_s + t.ln_sigma);
                (a, b, wa * t.weight, wb * t.weight)
            })
            .collect()
    }

    /// All lookups for a constant angle and scale, zero weights dropped.
    fn taps(&self, theta: f32, s: f32) -> Vec<Tap> {
        self.taps_with_levels(theta, s, &self.term_levels(s))
    }

    /// As [`Self::taps`] with the term levels of `s` given.
    fn taps_with_levels(
        &self,
        theta: f32,
        s: f32,
        levels: &[(usize, usize, f32, f32)],
    ) -> Vec<Tap> {
        let (sin, cos) = theta.to_radians().sin_cos();
        let mut taps = Vec::with_capacity(2 * self.terms.len());
        for (t, &(a, b, wa, wb)) in self.terms.iter().zip(levels) {
            let ox = s * (cos * t.cx + sin * t.cy);
            let oy = s * (-sin * t.cx + cos * t.cy);
            for (level, weight) in [(a, wa), (b, wb)] {
                if weight != 0.0 {
                    taps.push(Tap {
                        level,
                        ox,
                        oy,
                        weight,
                    });
                }
            }
        }
        taps
    }

    /// Per-pixel angle and/or scale over the whole image. `C` is the channel
    /// count when it is 1 to 4 (accumulators in registers), 0 for any count.
    fn per_pixel<const C: usize>(&self, angle: Field<'_>, scale: Field<'_>, out: &mut [f32]) {
        let (w, c) = (self.stack.width(), self.stack.channels());
        let constant_scale = match scale {
            Field::Constant(s) => Some((s, self.term_levels(s))),
            Field::Map(_) => None,
        };
        out.par_chunks_mut(w * c).enumerate().for_each(|(y, row)| {
            for (x, px) in row.chunks_exact_mut(c).enumerate() {
                let i = y * w + x;
                let (sin, cos) = angle.at(i).to_radians().sin_cos();
                let (xf, yf) = (x as f32, y as f32);
                match &constant_scale {
                    Some((s, levels)) => {
                        self.pixel_rotated::<C>(levels, xf, yf, cos * s, sin * s, 1.0, px);
                    }
                    None => self.pixel_general::<C>(xf, yf, cos, sin, scale.at(i), px),
                }
            }
        });
    }

    /// One pixel with constant scale (levels precomputed) and a per-pixel
    /// rotation; `cs = s cos theta`, `ss = s sin theta`. Adds `weight *` the
    /// filtered value into `out`.
    #[inline]
    #[expect(clippy::too_many_arguments, reason = "hot inner call, all scalars")]
    fn pixel_rotated<const C: usize>(
        &self,
        levels: &[(usize, usize, f32, f32)],
        x: f32,
        y: f32,
        cs: f32,
        ss: f32,
        weight: f32,
        out: &mut [f32],
    ) {
        let mut acc = [0.0f32; C];
        for (t, &(a, b, wa, wb)) in self.terms.iter().zip(levels) {
            let px = x + cs * t.cx + ss * t.cy;
            let py = y - ss * t.cx + cs * t.cy;
            // With `C == 0` the lookups add straight into `out`, so the
            // weight goes into each tap; otherwise into the sum below.
            let (wa, wb) = if C == 0 {
                (wa * weight, wb * weight)
            } else {
                (wa, wb)
            };
            self.add::<C>(a, px, py, wa, &mut acc, out);
            if wb != 0.0 {
                self.add::<C>(b, px, py, wb, &mut acc, out);
            }
        }
        for (o, a) in out.iter_mut().zip(acc) {
            *o += weight * a;
        }
    }

    /// Adds `weight *` the bilinear lookup of level `li` to `acc` when
    /// `C > 0`, else to `out`.
    #[inline]
    fn add<const C: usize>(
        &self,
        li: usize,
        x: f32,
        y: f32,
        weight: f32,
        acc: &mut [f32; C],
        out: &mut [f32],
    ) {
        if C == 0 {
            self.stack.accumulate(li, x, y, weight, out);
        } else {
            self.stack.accumulate_fixed::<C>(li, x, y, weight, acc);
        }
    }

    /// One pixel, everything per pixel. Adds into `out`.
    #[inline]
    fn pixel_general<const C: usize>(
        &self,
        x: f32,
        y: f32,
        cos: f32,
        sin: f32,
        s: f32,
        out: &mut [f32],
    ) {
        let (ln0, inv) = self.stack.ln_params();
        let last = self.stack.sigmas().len() - 1;
        let t_s = (f64::from(s).ln() - ln0) * inv;
        let cs = cos * s;
        let ss = sin * s;
        let mut acc = [0.0f32; C];
        for t in &self.terms {
            let px = x + cs * t.cx + ss * t.cy;
            let py = y - ss * t.cx + cs * t.cy;
            if last == 0 {
                self.add::<C>(0, px, py, t.weight, &mut acc, out);
                continue;
            }
            let u = (t_s + t.ln_sigma * inv).clamp(0.0, last as f64);
            let a = (u as usize).min(last - 1);
            let f = (u - a as f64) as f32;
            self.add::<C>(a, px, py, t.weight * (1.0 - f), &mut acc, out);
            if f != 0.0 {
                self.add::<C>(a + 1, px, py, t.weight * f, &mut acc, out);
            }
        }
        if C > 0 {
            for (o, a) in out.iter_mut().zip(acc) {
                *o += a;
            }
        }
    }
}

/// A [`Filter`] at one fixed scale: the stack levels of every term are
/// resolved once, so a lookup at any point and rotation costs `s` bilinear
/// samples (two per term when `scale * sigma_t` falls between stack
/// levels) and no per-term setup. This is the per-pixel path of spatially
/// varying smoothing, where the scale is fixed and the angle varies.
///
/// ```
/// use ifd_image::Image;
/// use ifd_planar::{Border, Decomposition, Filter, StackOptions, Term, stack_for_decomposition};
/// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 3.0, y: 0.0, sigma: 1.0 }]);
/// let img = Image::from_vec(64, 16, 1, (0..1024).map(|i| (i % 64) as f32).collect())?;
/// let stack = stack_for_decomposition(&img, &d, 2.0, 2.0, Border::Reflect101, StackOptions::default())?;
/// let filter = Filter::new(&stack, &d)?;
/// let at2 = filter.at_scale(2.0)?;
/// // The ramp value 6 px to the right of column 5 (the lobe at +3 px, scaled by 2).
/// let mut v = [0.0f32];
/// at2.accumulate(5.0, 8.0, 1.0, 0.0.into(), &mut v);
/// assert!((v[0] - 11.0).abs() < 1e-3);
/// // The same lookup through the checked point API.
/// assert!((filter.filter_at(5.0, 8.0, 0.0, 2.0)?[0] - v[0]).abs() < 1e-5);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct ScaledFilter<'f, 'a> {
    filter: &'f Filter<'a>,
    scale: f32,
    levels: Vec<(usize, usize, f32, f32)>,
}

/// The rotation of a lookup: `cos theta` and `sin theta` (theta in degrees,
/// counter-clockwise on screen), computed once per pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotation {
    /// `cos theta`.
    pub cos: f32,
    /// `sin theta`.
    pub sin: f32,
}

impl Rotation {
    /// The rotation by `theta` degrees.
    #[must_use]
    pub fn degrees(theta: f32) -> Self {
        let (sin, cos) = theta.to_radians().sin_cos();
        Self { cos, sin }
    }
}

impl From<f32> for Rotation {
    /// The rotation by this many degrees.
    fn from(theta: f32) -> Self {
        Self::degrees(theta)
    }
}

impl<'a> Filter<'a> {
    /// Binds the filter to a constant `scale` for fast per-point lookups.
    ///
    /// # Errors
    /// [`FilterError::InvalidValue`] for a non-finite or non-positive scale,
    /// [`FilterError::ScaleOutOfRange`] when some `scale * sigma_t` is not covered.
    pub fn at_scale(&self, scale: f32) -> Result<ScaledFilter<'_, 'a>, FilterError> {
        Field::Constant(scale).validate("scale", 1, 1, true)?;
        self.check_scales(scale, scale, &Field::Constant(scale))?;
        Ok(ScaledFilter {
            filter: self,
            scale,
            levels: self.term_levels(scale),
        })
    }
}

impl<'a> ScaledFilter<'_, 'a> {
    /// The scale this filter is bound to.
    #[must_use]
    pub fn scale(&self) -> f32 {
        self.scale
    }

    /// The underlying filter.
    #[must_use]
    pub fn filter(&self) -> &Filter<'a> {
        self.filter
    }

    /// Adds `weight *` the filtered value at `(x, y)` with the kernel rotated
    /// by `rotation` to `out` (one value per channel; `out.len()` must be
    /// the stack's channel count, else nothing is added). Coordinates must
    /// be finite; outside the image the border mode applies.
    #[inline]
    pub fn accumulate(&self, x: f32, y: f32, weight: f32, rotation: Rotation, out: &mut [f32]) {
        let f = self.filter;
        if out.len() != f.stack.channels() {
            return;
        }
        let (cs, ss) = (rotation.cos * self.scale, rotation.sin * self.scale);
        match out.len() {
            1 => f.pixel_rotated::<1>(&self.levels, x, y, cs, ss, weight, out),
            2 => f.pixel_rotated::<2>(&self.levels, x, y, cs, ss, weight, out),
            3 => f.pixel_rotated::<3>(&self.levels, x, y, cs, ss, weight, out),
            4 => f.pixel_rotated::<4>(&self.levels, x, y, cs, ss, weight, out),
            _ => f.pixel_rotated::<0>(&self.levels, x, y, cs, ss, weight, out),
        }
    }

    /// All lookups for the kernel rotated by `theta` degrees at this scale,
    /// weighted by `weight`, for region evaluation ([`Taps::apply_region`]).
    #[must_use]
    pub fn taps(&self, theta: f32, weight: f32) -> Taps {
        let mut taps = self
            .filter
            .taps_with_levels(theta, self.scale, &self.levels);
        for t in &mut taps {
            t.weight *= weight;
        }
        Taps { taps }
    }
}

/// The lookups of one constant rotation and scale (possibly of several
/// weighted filters on the same stack, e.g. a blend of two
/// decompositions), applied over a rectangle with a vectorised 2x2 stencil
/// per tap: the fast path for a brush dab whose filter is constant.
#[derive(Clone, Debug, Default)]
pub struct Taps {
    taps: Vec<Tap>,
}

impl Taps {
    /// The number of bilinear lookups per pixel.
    #[must_use]
    pub fn len(&self) -> usize {
        self.taps.len()
    }

    /// No lookups.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.taps.is_empty()
    }

    /// Appends `other`'s lookups (their weights already include any blend weight).
    pub fn extend(&mut self, other: Taps) {
        self.taps.extend(other.taps);
    }

    /// Filters the rectangle `x0..x0 + width`, `y0..y0 + height` of `stack`
    /// (which must be the stack the taps were made for): returns
    /// `width * height * channels` values, row-major, interleaved.
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] when the rectangle leaves the image
    /// or a tap refers to a level the stack does not have.
    pub fn apply_region(
        &self,
        stack: &ScaleStack,
        x0: usize,
        y0: usize,
        width: usize,
        height: usize,
    ) -> Result<Vec<f32>, FilterError> {
        if x0 + width > stack.width() || y0 + height > stack.height() {
            return Err(FilterError::InvalidParameter(format!(
                "region {width}x{height} at ({x0}, {y0}) leaves the {}x{} image",
                stack.width(),
                stack.height()
            )));
        }
        if self.taps.iter().any(|t| t.level >= stack.levels.len()) {
            return Err(FilterError::InvalidParameter(
                "the taps were made for another stack".into(),
            ));
        }
        let c = stack.channels();
        let mut out = vec![0.0f32; width * height * c];
        if width == 0 {
            return Ok(out);
        }
        out.par_chunks_mut(width * c)
            .enumerate()
            .for_each(|(j, row)| row_constant(stack, &self.taps, y0 + j, x0..x0 + width, row));
        Ok(out)
    }
}

/// Adds constant taps into `out`, the pixels `xs` of row `y` (`out[(x -
/// xs.start) * c..]`): full-resolution levels are applied as a 2x2 stencil
/// over the stored interior (contiguous, vectorisable), everything else
/// through the general lookup with border handling.
fn row_constant(
    stack: &ScaleStack,
    taps: &[Tap],
    y: usize,
    xs: std::ops::Range<usize>,
    out: &mut [f32],
) {
    let c = stack.channels();
    let (xa, xb) = (xs.start, xs.end);
    let yf = y as f32;
    for tap in taps {
        let level = &stack.levels[tap.level];
        let lay = &level.layout;
        let general = |out: &mut [f32], xs: std::ops::Range<usize>| {
            for x in xs {
                let o = (x - xa) * c;
                stack.accumulate(
                    tap.level,
                    x as f32 + tap.ox,
                    yf + tap.oy,
                    tap.weight,
                    &mut out[o..o + c],
                );
            }
        };
        if lay.step != 1 {
            general(out, xa..xb);
            continue;
        }
        let fx = tap.ox.floor();
        let fy = tap.oy.floor();
        let ax = tap.ox - fx;
        let ay = tap.oy - fy;
        // Stored column of pixel x is x + di, stored row is y + dj.
        let di = fx as i64 - lay.origin;
        let iv = y as i64 + fy as i64 - lay.origin;
        // Samples the stencil reads before and after the one below the point.
        let (before, after) = stack.interpolation().reach();
        let (before, after) = (before as i64, after as i64);
        if iv < before || iv + after >= lay.ny as i64 {
            general(out, xa..xb);
            continue;
        }
        let x0 = (before - di).clamp(xa as i64, xb as i64) as usize;
        let x1 = (lay.nx as i64 - after - di).clamp(x0 as i64, xb as i64) as usize;
        general(out, xa..x0);
        general(out, x1..xb);
        if x1 > x0 && stack.interpolation() == Interpolation::Cubic {
            // 4x4 coefficients with weights fixed for the whole row.
            let wx = bspline_weights(ax);
            let wy = bspline_weights(ay);
            let nxc = lay.nx * c;
            let start = ((x0 as i64 + di - 1) as usize) * c;
            let len = (x1 - x0) * c;
            let dst = &mut out[(x0 - xa) * c..(x1 - xa) * c];
            for (j, wyj) in wy.iter().enumerate() {
                let r = (iv as usize + j - 1) * nxc;
                let row = &level.data[r + start..r + start + len + 3 * c];
                let w = wx.map(|v| v * wyj * tap.weight);
                for (i, o) in dst.iter_mut().enumerate() {
                    *o += w[0] * row[i]
                        + w[1] * row[i + c]
                        + w[2] * row[i + 2 * c]
                        + w[3] * row[i + 3 * c];
                }
            }
        } else if x1 > x0 {
            let nxc = lay.nx * c;
            let r0 = &level.data[iv as usize * nxc..(iv as usize + 1) * nxc];
            let r1 = &level.data[(iv as usize + 1) * nxc..(iv as usize + 2) * nxc];
            let start = ((x0 as i64 + di) as usize) * c;
            let len = (x1 - x0) * c;
            let a00 = tap.weight * (1.0 - ax) * (1.0 - ay);
            let a01 = tap.weight * ax * (1.0 - ay);
            let a10 = tap.weight * (1.0 - ax) * ay;
            let a11 = tap.weight * ax * ay;
            let dst = &mut out[(x0 - xa) * c..(x1 - xa) * c];
            let p00 = &r0[start..start + len];
            let p01 = &r0[start + c..start + c + len];
            let p10 = &r1[start..start + len];
            let p11 = &r1[start + c..start + c + len];
            for ((((o, &v00), &v01), &v10), &v11) in
                dst.iter_mut().zip(p00).zip(p01).zip(p10).zip(p11)
            {
                *o += a00 * v00 + a01 * v01 + a10 * v10 + a11 * v11;
            }
        }
    }
}

fn prepare_terms(decomposition: &Decomposition) -> Result<Vec<Prepared>, FilterError> {
    if decomposition.terms.is_empty() {
        return Err(FilterError::InvalidParameter(
            "the decomposition has no terms".into(),
        ));
    }
    decomposition
        .terms
        .iter()
        .enumerate()
        .map(|(index, t)| {
            if !(t.weight.is_finite() && t.x.is_finite() && t.y.is_finite() && t.sigma.is_finite())
            {
                return Err(FilterError::InvalidTerm {
                    index,
                    why: format!("non-finite value in {t:?}"),
                });
            }
            if t.sigma <= 0.0 {
                return Err(FilterError::InvalidTerm {
                    index,
                    why: format!("sigma {} is not positive", t.sigma),
                });
            }
            Ok(Prepared {
                weight: t.weight as f32,
                cx: t.x as f32,
                cy: t.y as f32,
                sigma: t.sigma,
                ln_sigma: t.sigma.ln(),
            })
        })
        .collect()
}

/// Builds the scale stack a decomposition needs for scales in
/// `[scale_min, scale_max]`: sigmas `[scale_min * min sigma_t, scale_max *
/// max sigma_t]`, and for replicate/constant borders a margin covering the
/// largest displacement `scale_max * max |c_t|`.
///
/// # Errors
/// [`FilterError::InvalidTerm`]/[`FilterError::InvalidParameter`] for a bad
/// decomposition or scale range, and the errors of [`ScaleStack::new`].
pub fn stack_for_decomposition(
    image: &Image,
    decomposition: &Decomposition,
    scale_min: f32,
    scale_max: f32,
    border: Border,
    options: StackOptions,
) -> Result<ScaleStack, FilterError> {
    let ((lo, hi), options) = stack_plan_for_decomposition(
        (image.width(), image.height(), image.channels()),
        decomposition,
        scale_min,
        scale_max,
        border,
        options,
    )?;
    ScaleStack::new(image, lo, hi, border, options)
}

/// The sigma range and options of the stack [`stack_for_decomposition`]
/// builds for a `(width, height, channels)` image, without building it (for
/// memory budgets and device limits: `StackLayout::new(w, h, c, lo, hi,
/// options)` is its layout).
///
/// ```
/// use ifd_planar::{Border, Decomposition, StackLayout, StackOptions, Term};
/// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 3.0, y: 0.0, sigma: 2.0 }]);
/// let ((lo, hi), o) = ifd_planar::stack_plan_for_decomposition(
///     (640, 480, 3), &d, 1.0, 4.0, Border::Reflect101, StackOptions::default())?;
/// assert_eq!((lo, hi), (2.0, 8.0));
/// let bytes = StackLayout::new(640, 480, 3, lo, hi, o)?.bytes();
/// # Ok::<(), ifd_planar::FilterError>(())
/// ```
///
/// # Errors
/// As [`stack_for_decomposition`], except those of the image's samples.
pub fn stack_plan_for_decomposition(
    (width, height, channels): (usize, usize, usize),
    decomposition: &Decomposition,
    scale_min: f32,
    scale_max: f32,
    border: Border,
    options: StackOptions,
) -> Result<((f64, f64), StackOptions), FilterError> {
    let terms = prepare_terms(decomposition)?;
    if !(scale_min.is_finite()
        && scale_max.is_finite()
        && scale_min > 0.0
        && scale_min <= scale_max)
    {
        return Err(FilterError::InvalidParameter(format!(
            "scale range [{scale_min}, {scale_max}] must be finite, positive and increasing"
        )));
    }
    let sigma_lo = terms.iter().map(|t| t.sigma).fold(f64::INFINITY, f64::min);
    let sigma_hi = terms.iter().map(|t| t.sigma).fold(0.0, f64::max);
    let reach = terms
        .iter()
        .map(|t| f64::from(t.cx).hypot(f64::from(t.cy)))
        .fold(0.0, f64::max);
    let mut options = options;
    let need = (f64::from(scale_max) * reach).ceil() as usize + 2;
    if matches!(border, Border::Replicate | Border::Constant(_)) {
        // Beyond the stored margin these borders are approximated: store
        // every sample a lookup can reach.
        options.margin = options.margin.max(need);
    } else {
        // Reflect-101 and wrap are exact beyond the margin too, but through
        // the slow border-resolving lookup; with large kernels a wide band
        // of pixels along the border would take it for most of its taps
        // (43% of a 1024x1024 image for an extent-255 kernel, making it 1.6x
        // slower than an extent-31 one). Store a margin covering the reach
        // as far as memory allows (`StackLayout::affordable_margin`).
        options.margin = StackLayout::affordable_margin(
            width,
            height,
            channels,
            f64::from(scale_min) * sigma_lo,
            f64::from(scale_max) * sigma_hi,
            options,
            need,
        )?;
    }
    Ok((
        (
            f64::from(scale_min) * sigma_lo,
            f64::from(scale_max) * sigma_hi,
        ),
        options,
    ))
}
