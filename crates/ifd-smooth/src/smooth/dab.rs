//! Brush dabs and the dab grid: a [`Dab`]'s weight and region, the grid
//! centres a pixel blends in whole-image [`super::Mode::Dab`] smoothing.

use crate::error::{SmoothError, check_range};

/// One brush dab.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dab {
    /// Centre, column.
    pub x: f32,
    /// Centre, row.
    pub y: f32,
    /// Radius in pixels.
    pub radius: f32,
    /// Fraction of the radius over which the effect fades to zero (0: hard edge, 1: from the centre).
    pub falloff: f32,
    /// Blend of the smoothed result into the image at the centre, 0..=1.
    pub strength: f32,
}

impl Dab {
    /// The dab's weight at distance `d` from its centre.
    #[must_use]
    pub fn weight(&self, d: f32) -> f32 {
        let inner = self.radius * (1.0 - self.falloff);
        if d >= self.radius {
            0.0
        } else if d <= inner {
            self.strength
        } else {
            let t = (self.radius - d) / (self.radius - inner);
            self.strength * t * t * (3.0 - 2.0 * t)
        }
    }

    pub(super) fn validate(&self) -> Result<(), SmoothError> {
        check_range("dab x", f64::from(self.x), -1e7, 1e7)?;
        check_range("dab y", f64::from(self.y), -1e7, 1e7)?;
        check_range("dab radius", f64::from(self.radius), 0.5, 4096.0)?;
        check_range("dab falloff", f64::from(self.falloff), 0.0, 1.0)?;
        check_range("dab strength", f64::from(self.strength), 0.0, 1.0)
    }

    /// The pixels of a `width x height` image the dab can change: its
    /// bounding box clipped to the image (`None` when it misses the image),
    /// as [`Smoother::apply_dab`](crate::Smoother::apply_dab) uses it.
    ///
    /// ```
    /// use ifd_smooth::Dab;
    /// let dab = Dab { x: 2.0, y: 50.0, radius: 10.0, falloff: 0.5, strength: 1.0 };
    /// let r = dab.region(100, 80)?.expect("inside");
    /// assert_eq!((r.x0, r.y0, r.width, r.height), (0, 40, 13, 21));
    /// # Ok::<(), ifd_smooth::SmoothError>(())
    /// ```
    ///
    /// # Errors
    /// [`SmoothError::OutOfRange`] for bad dab parameters.
    pub fn region(&self, width: usize, height: usize) -> Result<Option<DabRegion>, SmoothError> {
        self.validate()?;
        let x0 = (self.x - self.radius).floor().max(0.0) as usize;
        let y0 = (self.y - self.radius).floor().max(0.0) as usize;
        let x1 = ((self.x + self.radius).ceil().max(-1.0) as i64).min(width as i64 - 1);
        let y1 = ((self.y + self.radius).ceil().max(-1.0) as i64).min(height as i64 - 1);
        if x1 < x0 as i64 || y1 < y0 as i64 {
            return Ok(None);
        }
        Ok(Some(DabRegion {
            x0,
            y0,
            width: x1 as usize - x0 + 1,
            height: y1 as usize - y0 + 1,
        }))
    }
}

/// Index of the pixel nearest `(x, y)`, clamped into a `width x height`
/// image (row-major), as [`Smoother::orientation_at`](crate::Smoother::orientation_at) looks the field up.
#[must_use]
pub fn nearest_pixel(x: f32, y: f32, width: usize, height: usize) -> usize {
    let xi = (x.round().max(0.0) as usize).min(width - 1);
    let yi = (y.round().max(0.0) as usize).min(height - 1);
    yi * width + xi
}

/// The four centres of the dab grid of spacing `g` around pixel `(x, y)`
/// and their bilinear weights, in the order whole-image [`Mode::Dab`](crate::Mode::Dab)
/// smoothing sums them.
///
/// ```
/// let c = ifd_smooth::dab_grid_corners(3.0, 8.0, 4.0);
/// assert_eq!(c[0], ((0.0, 8.0), 0.25));
/// assert_eq!(c[1], ((4.0, 8.0), 0.75));
/// assert_eq!(c[2].1 + c[3].1, 0.0);
/// ```
#[must_use]
pub fn dab_grid_corners(x: f32, y: f32, g: f32) -> [((f32, f32), f32); 4] {
    let (gx, gy) = (x / g, y / g);
    let (i0, fx) = (gx.floor(), gx - gx.floor());
    let (j0, fy) = (gy.floor(), gy - gy.floor());
    [
        ((i0 * g, j0 * g), (1.0 - fx) * (1.0 - fy)),
        (((i0 + 1.0) * g, j0 * g), fx * (1.0 - fy)),
        ((i0 * g, (j0 + 1.0) * g), (1.0 - fx) * fy),
        (((i0 + 1.0) * g, (j0 + 1.0) * g), fx * fy),
    ]
}

/// [`dab_grid_corners`] for a tile whose pixel (0, 0) lies at `origin` in
/// the image whose grid it follows: `(x, y)` and the returned centres in the
/// tile's coordinates.
///
/// ```
/// use ifd_smooth::{anchored_dab_grid_corners, dab_grid_corners};
/// let tile = anchored_dab_grid_corners(3.0, 1.0, 4.0, (8, 4));
/// let whole = dab_grid_corners(11.0, 5.0, 4.0);
/// assert_eq!(tile[0], ((0.0, 0.0), whole[0].1));
/// assert_eq!(whole[0].0, (8.0, 4.0));
/// ```
#[must_use]
pub fn anchored_dab_grid_corners(
    x: f32,
    y: f32,
    g: f32,
    origin: (usize, usize),
) -> [((f32, f32), f32); 4] {
    let (ox, oy) = (origin.0 as f32, origin.1 as f32);
    dab_grid_corners(x + ox, y + oy, g).map(|((cx, cy), w)| ((cx - ox, cy - oy), w))
}

/// What [`Smoother::apply_dab`](crate::Smoother::apply_dab) touched: a [`PixelRect`](ifd_planar::PixelRect).
pub use ifd_planar::PixelRect as DabRegion;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dab_weight_profile() {
        let d = Dab {
            x: 0.0,
            y: 0.0,
            radius: 10.0,
            falloff: 0.5,
            strength: 0.8,
        };
        assert_eq!(d.weight(0.0), 0.8);
        assert_eq!(d.weight(5.0), 0.8);
        assert!(d.weight(7.5) > 0.0 && d.weight(7.5) < 0.8);
        assert_eq!(d.weight(10.0), 0.0);
    }
}
