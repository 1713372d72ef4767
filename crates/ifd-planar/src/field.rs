//! Per-pixel parameters of a filter (angle, scale, bank entry): the raw
//! [`Field`] a caller gives, and the [`CheckedField`] that knows its size,
//! kind and range, built once with its checks.

use crate::error::FilterError;

/// Values larger than this in magnitude are refused as absurd (an angle of
/// a million degrees, a scale of a million).
pub const MAX_FIELD_VALUE: f32 = 1e6;

/// Scales below this are refused as absurd: the filter would shrink to a
/// thousandth of its size, far below a pixel, where its terms' widths are
/// below the finest prefiltered level and the result is not the filter's.
pub const MIN_FIELD_SCALE: f32 = 1e-3;

/// A per-pixel parameter (angle in degrees, or scale): a constant or a
/// row-major map of `width * height` values. Unchecked: see [`CheckedField`].
///
/// Per-pixel parameters of a filter (angle, scale, bank entry): the raw
/// [`Field`] a caller gives, and the [`CheckedField`] that knows its size,
/// kind and range, built once with its checks.
///
/// A map is scanned once, when it is checked: the range it reports sizes
/// the scale stack, its checks make the CPU and the GPU evaluations refuse
/// the same values with the same messages, and the positions of its
/// extremes name the pixel when a scale falls outside the stack. Every
/// entry point that takes a field ([`crate::Filter::apply`], the
/// references, `ifd_gpu::GpuPose::new`) takes anything that is
/// [`CheckField`]: a raw [`Field`] is checked there, a [`CheckedField`]
/// only compared with the image's size.
///
/// ```
/// use ifd_planar::{CheckField, CheckedField, Field, FieldKind};
/// let scales = [1.5f32, 0.5, 2.0, 1.0];
/// let scale = CheckedField::new(Field::Map(&scales), FieldKind::Scale, 2, 2)?;
/// assert_eq!(scale.range(), (0.5, 2.0));
/// assert_eq!(scale.location_of_min(), " at pixel (1, 0)");
/// // Checked once: passing it on costs a size comparison.
/// assert!(scale.check(FieldKind::Scale, 2, 2).is_ok());
/// assert!(scale.check(FieldKind::Scale, 4, 1).is_err());
/// // Scales must be positive; angles need only be finite.
/// assert!(Field::Map(&[1.0, -1.0]).check(FieldKind::Scale, 2, 1).is_err());
/// assert!(Field::Map(&[1.0, -1.0]).check(FieldKind::Angle, 2, 1).is_ok());
/// # Ok::<(), ifd_planar::FilterError>(())
/// ```
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

    /// Whether the field is a per-pixel map.
    #[must_use]
    pub fn is_map(&self) -> bool {
        matches!(self, Field::Map(_))
    }
}

/// What a field holds, which sets the values it accepts: every value finite
/// and at most [`MAX_FIELD_VALUE`] in magnitude, and
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldKind {
    /// rotation angles in degrees: any sign;
    Angle,
    /// scale factors: positive, at least [`MIN_FIELD_SCALE`];
    Scale,
    /// bank entries `i + t` (entries `i` and `i + 1` blended with weight
    /// `t`): non-negative.
    Entry,
}

impl FieldKind {
    /// The name used in messages ("angle", "scale", "bank entry").
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            FieldKind::Angle => "angle",
            FieldKind::Scale => "scale",
            FieldKind::Entry => "bank entry",
        }
    }

    /// The least and the largest valid value of this kind: `v` is valid
    /// exactly when `least <= v <= most` ([`Self::why_invalid`] is `None`;
    /// NaN fails both comparisons, infinities one).
    fn valid_range(self) -> (f32, f32) {
        let least = match self {
            FieldKind::Angle => -MAX_FIELD_VALUE,
            FieldKind::Scale => MIN_FIELD_SCALE,
            FieldKind::Entry => 0.0,
        };
        (least, MAX_FIELD_VALUE)
    }

    /// Why `v` is not a valid value of this kind, or `None` when it is
    /// (the rule [`CheckedField::new`] applies to every value).
    #[must_use]
    pub fn why_invalid(self, v: f32) -> Option<&'static str> {
        if !v.is_finite() {
            Some("not finite")
        } else if self == FieldKind::Scale && v <= 0.0 {
            Some("must be positive")
        } else if self == FieldKind::Scale && v < MIN_FIELD_SCALE {
            Some("absurdly small (below 1e-3)")
        } else if self == FieldKind::Entry && v < 0.0 {
            Some("must not be negative")
        } else if v.abs() > MAX_FIELD_VALUE {
            Some("absurdly large")
        } else {
            None
        }
    }
}

/// A [`Field`] checked for one image size and [`FieldKind`]: a map has
/// exactly `width * height` values, every value is valid for its kind, and
/// the range with the pixels where it is reached is known.
#[derive(Clone, Copy, Debug)]
pub struct CheckedField<'a> {
    field: Field<'a>,
    kind: FieldKind,
    width: usize,
    height: usize,
    /// `(value, pixel index)` of the smallest and the largest value.
    min: (f32, usize),
    max: (f32, usize),
}

impl<'a> CheckedField<'a> {
    /// Checks `field` as a `kind` for a `width x height` image, scanning a
    /// map once.
    ///
    /// # Errors
    /// [`FilterError::MapSize`] for a map of the wrong length,
    /// [`FilterError::InvalidValue`] (naming the first bad pixel) for a
    /// value that is not finite, larger than [`MAX_FIELD_VALUE`] in
    /// magnitude, or out of its kind's range.
    pub fn new(
        field: Field<'a>,
        kind: FieldKind,
        width: usize,
        height: usize,
    ) -> Result<Self, FilterError> {
        let name = kind.name();
        let invalid = |value: f32, i: Option<usize>, why| FilterError::InvalidValue {
            name,
            value,
            location: i.map(|i| pixel_location(i, width)).unwrap_or_default(),
            why,
        };
        let (min, max) = match field {
            Field::Constant(v) => {
                if let Some(why) = kind.why_invalid(v) {
                    return Err(invalid(v, None, why));
                }
                ((v, 0), (v, 0))
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
                let mut lo = (f32::INFINITY, 0);
                let mut hi = (f32::NEG_INFINITY, 0);
                let (least, most) = kind.valid_range();
                // Chunk by chunk: validity, least and largest without
                // branches (vector lanes); a chunk with an invalid value is
                // scanned again value by value to name the first one, and
                // an extreme's pixel is its first occurrence, as in a
                // sequential scan.
                for (k, chunk) in m.chunks(CHUNK).enumerate() {
                    let (valid, c_lo, c_hi) = scan_chunk(chunk, least, most);
                    // the first value equal to `target`, and its pixel
                    let first = |target: f32| {
                        let j = chunk.iter().position(|&v| v == target).unwrap_or(0);
                        (chunk[j], k * CHUNK + j)
                    };
                    if !valid {
                        for (j, &v) in chunk.iter().enumerate() {
                            if let Some(why) = kind.why_invalid(v) {
                                return Err(invalid(v, Some(k * CHUNK + j), why));
                            }
                        }
                    }
                    if c_lo < lo.0 {
                        lo = first(c_lo);
                    }
                    if c_hi > hi.0 {
                        hi = first(c_hi);
                    }
                }
                (lo, hi)
            }
        };
        Ok(Self {
            field,
            kind,
            width,
            height,
            min,
            max,
        })
    }

    /// The checked field.
    #[must_use]
    pub fn field(&self) -> Field<'a> {
        self.field
    }

    /// What it holds.
    #[must_use]
    pub fn kind(&self) -> FieldKind {
        self.kind
    }

    /// The image size it was checked for.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The value at pixel index `i` (`y * width + x`).
    #[inline]
    #[must_use]
    pub fn at(&self, i: usize) -> f32 {
        self.field.at(i)
    }

    /// Whether the field is a per-pixel map.
    #[must_use]
    pub fn is_map(&self) -> bool {
        self.field.is_map()
    }

    /// `(min, max)` of the values.
    #[must_use]
    pub fn range(&self) -> (f32, f32) {
        (self.min.0, self.max.0)
    }

    /// `" at pixel (x, y)"` of the (first) smallest value of a map, empty
    /// for a constant: for messages.
    #[must_use]
    pub fn location_of_min(&self) -> String {
        self.location(self.min.1)
    }

    /// As [`CheckedField::location_of_min`], of the largest value.
    #[must_use]
    pub fn location_of_max(&self) -> String {
        self.location(self.max.1)
    }

    fn location(&self, i: usize) -> String {
        if self.is_map() {
            pixel_location(i, self.width)
        } else {
            String::new()
        }
    }
}

/// Anything an entry point accepts as a per-pixel parameter: a raw
/// [`Field`] (checked when passed) or a [`CheckedField`] (only compared
/// with the kind and size asked for).
pub trait CheckField<'a> {
    /// The field checked as a `kind` for a `width x height` image.
    ///
    /// # Errors
    /// As [`CheckedField::new`]; for a [`CheckedField`],
    /// [`FilterError::MapSize`] when it was checked for another size and
    /// [`FilterError::InvalidParameter`] when it was checked as another kind.
    fn check(
        self,
        kind: FieldKind,
        width: usize,
        height: usize,
    ) -> Result<CheckedField<'a>, FilterError>;
}

impl<'a> CheckField<'a> for Field<'a> {
    fn check(
        self,
        kind: FieldKind,
        width: usize,
        height: usize,
    ) -> Result<CheckedField<'a>, FilterError> {
        CheckedField::new(self, kind, width, height)
    }
}

impl<'a> CheckField<'a> for CheckedField<'a> {
    fn check(
        self,
        kind: FieldKind,
        width: usize,
        height: usize,
    ) -> Result<CheckedField<'a>, FilterError> {
        // A constant holds for every size; a map only for its own.
        if let Field::Map(m) = self.field
            && self.size() != (width, height)
        {
            return Err(FilterError::MapSize {
                name: kind.name(),
                len: m.len(),
                width,
                height,
                expected: width * height,
            });
        }
        if self.kind != kind {
            return Err(FilterError::InvalidParameter(format!(
                "a field checked as {} was given as {}",
                self.kind.name(),
                kind.name()
            )));
        }
        Ok(Self {
            width,
            height,
            ..self
        })
    }
}

impl<'a> CheckField<'a> for &CheckedField<'a> {
    fn check(
        self,
        kind: FieldKind,
        width: usize,
        height: usize,
    ) -> Result<CheckedField<'a>, FilterError> {
        (*self).check(kind, width, height)
    }
}

/// The values [`CheckedField::new`] checks at a time.
const CHUNK: usize = 64;

/// Whether every value of `chunk` lies in `least..=most`, and the least
/// and the largest value (meaningful when every value does), in eight
/// independent lanes that the compiler keeps in vector registers.
fn scan_chunk(chunk: &[f32], least: f32, most: f32) -> (bool, f32, f32) {
    const L: usize = 8;
    let mut bad = [0u32; L];
    let (mut lo, mut hi) = ([f32::INFINITY; L], [f32::NEG_INFINITY; L]);
    let mut lanes = chunk.chunks_exact(L);
    for block in &mut lanes {
        for j in 0..L {
            let v = block[j];
            bad[j] |= u32::from(!(least..=most).contains(&v));
            lo[j] = if v < lo[j] { v } else { lo[j] };
            hi[j] = if v > hi[j] { v } else { hi[j] };
        }
    }
    for &v in lanes.remainder() {
        bad[0] |= u32::from(!(least..=most).contains(&v));
        lo[0] = if v < lo[0] { v } else { lo[0] };
        hi[0] = if v > hi[0] { v } else { hi[0] };
    }
    let fold = |a: [f32; L], pick: fn(f32, f32) -> f32| a.into_iter().fold(a[0], pick);
    (
        bad.iter().all(|&b| b == 0),
        fold(lo, f32::min),
        fold(hi, f32::max),
    )
}

/// `" at pixel (x, y)"` of pixel index `i` in an image `width` wide.
pub(crate) fn pixel_location(i: usize, width: usize) -> String {
    format!(" at pixel ({}, {})", i % width, i / width)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_checks_name_the_first_bad_pixel() {
        let m = [1.0, 2.0, f32::NAN, -1.0];
        let e = Field::Map(&m).check(FieldKind::Scale, 2, 2).unwrap_err();
        assert_eq!(
            e.to_string(),
            "invalid scale NaN at pixel (0, 1): not finite"
        );
        let e = Field::Map(&[1.0, -0.5])
            .check(FieldKind::Entry, 2, 1)
            .unwrap_err();
        assert!(e.to_string().contains("must not be negative"), "{e}");
        let e = Field::Constant(2e6)
            .check(FieldKind::Angle, 9, 9)
            .unwrap_err();
        assert!(e.to_string().contains("absurdly large"), "{e}");
        let e = Field::Map(&[1.0; 5])
            .check(FieldKind::Angle, 2, 2)
            .unwrap_err();
        assert!(matches!(
            e,
            FilterError::MapSize {
                len: 5,
                expected: 4,
                ..
            }
        ));
    }

    #[test]
    fn the_valid_range_is_the_rule() {
        let values = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -2e6,
            -1e6,
            -1.0,
            -0.0,
            0.0,
            5e-4,
            1e-3,
            0.5,
            1e6,
            1.000_001e6,
            f32::MAX,
        ];
        for kind in [FieldKind::Angle, FieldKind::Scale, FieldKind::Entry] {
            let (least, most) = kind.valid_range();
            for v in values {
                assert_eq!(
                    least <= v && v <= most,
                    kind.why_invalid(v).is_none(),
                    "{kind:?} {v}"
                );
            }
        }
    }

    #[test]
    fn chunked_scan_matches_a_sequential_one() {
        // extremes repeated across and within chunks: the first pixel of each
        let mut m: Vec<f32> = (0..300)
            .map(|i| ((i * 37) % 101) as f32 * 0.5 + 1.0)
            .collect();
        m[70] = 0.25;
        m[130] = 0.25;
        m[200] = 99.0;
        m[201] = 99.0;
        let f = CheckedField::new(Field::Map(&m), FieldKind::Scale, 20, 15).unwrap();
        assert_eq!((f.min, f.max), ((0.25, 70), (99.0, 200)));
        m[150] = f32::NAN;
        m[260] = -1.0;
        let e = CheckedField::new(Field::Map(&m), FieldKind::Scale, 20, 15).unwrap_err();
        assert!(e.to_string().contains("(10, 7)"), "{e}");
    }

    #[test]
    fn range_and_extreme_positions() {
        let m = [3.0, 0.25, 4.0, 0.25, 1.0, 4.0];
        let f = CheckedField::new(Field::Map(&m), FieldKind::Scale, 3, 2).unwrap();
        assert_eq!(f.range(), (0.25, 4.0));
        assert_eq!(f.location_of_min(), " at pixel (1, 0)");
        assert_eq!(f.location_of_max(), " at pixel (2, 0)");
        let c = CheckedField::new(Field::Constant(2.0), FieldKind::Scale, 3, 2).unwrap();
        assert_eq!(
            (c.range(), c.location_of_max()),
            ((2.0, 2.0), String::new())
        );
    }

    #[test]
    fn a_checked_field_is_compared_not_rescanned() {
        let m = [1.0f32; 6];
        let f = CheckedField::new(Field::Map(&m), FieldKind::Angle, 3, 2).unwrap();
        assert!(f.check(FieldKind::Angle, 3, 2).is_ok());
        assert!(matches!(
            f.check(FieldKind::Angle, 2, 3),
            Err(FilterError::MapSize { .. })
        ));
        assert!(matches!(
            f.check(FieldKind::Scale, 3, 2),
            Err(FilterError::InvalidParameter(_))
        ));
        // A constant holds for any size.
        let c = CheckedField::new(Field::Constant(1.0), FieldKind::Scale, 1, 1).unwrap();
        assert_eq!(
            c.check(FieldKind::Scale, 640, 480).unwrap().size(),
            (640, 480)
        );
    }
}
