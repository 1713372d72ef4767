//! The dab API: a [`Filter`] at one scale and angle for many points
//! ([`ScaledFilter`]), the [`Rotation`] it turns by, and the fixed taps
//! ([`Taps`]) of its terms, located once, for brushes that apply the same
//! filter at many places.

use crate::error::FilterError;
use crate::field::{CheckField, Field, FieldKind};
use crate::filter::Filter;
use crate::stack::lookup::Taps;

/// A [`Filter`] at one fixed scale: the stack levels of every term are
/// resolved once, so a lookup at any point and rotation costs `s` bilinear
/// samples (two per term when `scale * sigma_t` falls between stack
/// levels) and no per-term setup. This is the per-pixel path of spatially
/// varying smoothing, where the scale is fixed and the angle varies.
///
/// ```
/// use ifd_image::{Image, ImageView};
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
        let (sin, cos) = crate::trig::sin_cos_degrees(theta);
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
        let checked = Field::Constant(scale).check(FieldKind::Scale, 1, 1)?;
        // Its lookups read every term from the stack, anywhere.
        self.check_scales(&checked, false)?;
        self.stack.check_whole("a filter at points")?;
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
