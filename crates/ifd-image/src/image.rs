//! The [`Image`] buffer: interleaved `f32` samples, row-major, `height x width x channels`.

use crate::ImageError;

/// An image of `f32` samples stored interleaved and row-major (`H x W x C`, the
/// layout of NumPy's `HxWxC` arrays and of OpenCV's `Mat`).
///
/// Axes: `x` is the column (to the right), `y` is the row (down); row 0 is the
/// top of the image. Values are linear: 8/16-bit files map to `[0, 1]` without
/// any gamma change unless sRGB decoding was asked for when reading.
///
/// ```
/// use ifd_image::Image;
/// let mut img = Image::new(4, 3, 1)?;
/// img.set(2, 1, 0, 0.5);
/// assert_eq!(img.get(2, 1, 0), 0.5);
/// assert_eq!((img.width(), img.height(), img.channels()), (4, 3, 1));
/// # Ok::<(), ifd_image::ImageError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    width: usize,
    height: usize,
    channels: usize,
    data: Vec<f32>,
}

impl Image {
    /// A zero-filled image.
    ///
    /// # Errors
    /// [`ImageError::Empty`] when a dimension is zero, [`ImageError::TooLarge`]
    /// when the sample count overflows `usize`.
    pub fn new(width: usize, height: usize, channels: usize) -> Result<Self, ImageError> {
        let n = checked_len(width, height, channels)?;
        Ok(Self {
            width,
            height,
            channels,
            data: vec![0.0; n],
        })
    }

    /// Wraps interleaved samples (`H x W x C`, row-major).
    ///
    /// # Errors
    /// [`ImageError::Empty`] for a zero dimension, [`ImageError::Shape`] when
    /// `data.len() != width * height * channels`.
    pub fn from_vec(
        width: usize,
        height: usize,
        channels: usize,
        data: Vec<f32>,
    ) -> Result<Self, ImageError> {
        let n = checked_len(width, height, channels)?;
        if data.len() != n {
            return Err(ImageError::Shape(format!(
                "{} samples given for a {width}x{height}x{channels} image ({n} expected)",
                data.len()
            )));
        }
        Ok(Self {
            width,
            height,
            channels,
            data,
        })
    }

    /// Builds an image from one plane per channel (each `width * height`, row-major).
    ///
    /// # Errors
    /// [`ImageError::Empty`] for no planes or a zero dimension,
    /// [`ImageError::Shape`] when a plane has the wrong length.
    pub fn from_planes(
        width: usize,
        height: usize,
        planes: &[Vec<f32>],
    ) -> Result<Self, ImageError> {
        let channels = planes.len();
        let n = checked_len(width, height, channels)?;
        let mut data = vec![0.0; n];
        for (c, plane) in planes.iter().enumerate() {
            if plane.len() != width * height {
                return Err(ImageError::Shape(format!(
                    "plane {c} has {} samples, expected {width}x{height} = {}",
                    plane.len(),
                    width * height
                )));
            }
            for (i, &v) in plane.iter().enumerate() {
                data[i * channels + c] = v;
            }
        }
        Ok(Self {
            width,
            height,
            channels,
            data,
        })
    }

    /// Width in pixels (number of columns).
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels (number of rows).
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of channels (1 gray, 2 gray+alpha, 3 RGB, 4 RGBA, or any count from `.npy`).
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Number of pixels, `width * height`.
    #[must_use]
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }

    /// The interleaved samples.
    #[must_use]
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// The interleaved samples, mutable.
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }

    /// Consumes the image and returns its samples.
    #[must_use]
    pub fn into_vec(self) -> Vec<f32> {
        self.data
    }

    /// Sample at column `x`, row `y`, channel `c`.
    ///
    /// # Panics
    /// When the position is outside the image.
    #[must_use]
    pub fn get(&self, x: usize, y: usize, c: usize) -> f32 {
        assert!(x < self.width && y < self.height && c < self.channels);
        self.data[(y * self.width + x) * self.channels + c]
    }

    /// Sets the sample at column `x`, row `y`, channel `c`.
    ///
    /// # Panics
    /// When the position is outside the image.
    pub fn set(&mut self, x: usize, y: usize, c: usize, v: f32) {
        assert!(x < self.width && y < self.height && c < self.channels);
        self.data[(y * self.width + x) * self.channels + c] = v;
    }

    /// Copies channel `c` out as a row-major plane of `width * height` samples.
    ///
    /// # Panics
    /// When `c >= channels`.
    #[must_use]
    pub fn plane(&self, c: usize) -> Vec<f32> {
        assert!(c < self.channels, "channel {c} of {}", self.channels);
        self.data
            .iter()
            .skip(c)
            .step_by(self.channels)
            .copied()
            .collect()
    }

    /// All channels as planes.
    #[must_use]
    pub fn planes(&self) -> Vec<Vec<f32>> {
        (0..self.channels).map(|c| self.plane(c)).collect()
    }

    /// The `width x height` rectangle with its top-left corner at
    /// `(x0, y0)`, copied.
    ///
    /// ```
    /// let img = ifd_image::Image::from_vec(3, 2, 1, vec![0., 1., 2., 3., 4., 5.]).unwrap();
    /// assert_eq!(img.crop(1, 1, 2, 1).data(), &[4., 5.]);
    /// ```
    ///
    /// # Panics
    /// When the rectangle is empty or not inside the image.
    #[must_use]
    pub fn crop(&self, x0: usize, y0: usize, width: usize, height: usize) -> Image {
        assert!(
            width > 0 && height > 0 && x0 + width <= self.width && y0 + height <= self.height,
            "crop {width}x{height} at ({x0}, {y0}) of a {}x{} image",
            self.width,
            self.height
        );
        let c = self.channels;
        let mut data = Vec::with_capacity(width * height * c);
        for y in y0..y0 + height {
            let i = (y * self.width + x0) * c;
            data.extend_from_slice(&self.data[i..i + width * c]);
        }
        Image {
            width,
            height,
            channels: c,
            data,
        }
    }

    /// Copies `tile` into this image with its top-left corner at `(x0, y0)`.
    ///
    /// # Panics
    /// When `tile` does not fit there or has other channels.
    pub fn paste(&mut self, x0: usize, y0: usize, tile: &Image) {
        assert!(
            tile.channels == self.channels
                && x0 + tile.width <= self.width
                && y0 + tile.height <= self.height,
            "paste a {}x{}x{} tile at ({x0}, {y0}) into a {}x{}x{} image",
            tile.width,
            tile.height,
            tile.channels,
            self.width,
            self.height,
            self.channels
        );
        let c = self.channels;
        let row = tile.width * c;
        for (j, src) in tile.data.chunks_exact(row).enumerate() {
            let i = ((y0 + j) * self.width + x0) * c;
            self.data[i..i + row].copy_from_slice(src);
        }
    }

    /// Whether two images have the same width, height and channel count.
    #[must_use]
    pub fn same_shape(&self, other: &Self) -> bool {
        self.width == other.width && self.height == other.height && self.channels == other.channels
    }

    /// Counts the NaN and infinite samples.
    #[must_use]
    pub fn count_non_finite(&self) -> usize {
        count_non_finite(&self.data)
    }

    /// A borrowed view of the image.
    #[must_use]
    pub fn view(&self) -> ImageView<'_> {
        ImageView {
            width: self.width,
            height: self.height,
            channels: self.channels,
            data: &self.data,
        }
    }
}

/// A borrowed image: the same layout as [`Image`] (interleaved `f32`,
/// row-major, `H x W x C`) over samples someone else owns, such as a NumPy
/// array or a tile of a larger buffer. Filtering entry points take
/// `impl Into<ImageView>`, so an `&Image` and a view of foreign memory are
/// filtered alike, without a copy.
///
/// ```
/// use ifd_image::{Image, ImageView};
/// let samples = vec![0.25_f32; 4 * 3 * 2];
/// let view = ImageView::new(4, 3, 2, &samples)?;
/// assert_eq!((view.width(), view.height(), view.channels()), (4, 3, 2));
/// assert_eq!(view.get(3, 2, 1), 0.25);
/// let owned: Image = view.to_image();
/// assert_eq!(ImageView::from(&owned), view);
/// # Ok::<(), ifd_image::ImageError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageView<'a> {
    width: usize,
    height: usize,
    channels: usize,
    data: &'a [f32],
}

impl<'a> ImageView<'a> {
    /// Views interleaved samples (`H x W x C`, row-major).
    ///
    /// # Errors
    /// As [`Image::from_vec`].
    pub fn new(
        width: usize,
        height: usize,
        channels: usize,
        data: &'a [f32],
    ) -> Result<Self, ImageError> {
        let n = checked_len(width, height, channels)?;
        if data.len() != n {
            return Err(ImageError::Shape(format!(
                "{} samples given for a {width}x{height}x{channels} image ({n} expected)",
                data.len()
            )));
        }
        Ok(Self {
            width,
            height,
            channels,
            data,
        })
    }

    /// Width in pixels (number of columns).
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels (number of rows).
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Channels per pixel.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The interleaved samples.
    #[must_use]
    pub fn data(&self) -> &'a [f32] {
        self.data
    }

    /// Sample at column `x`, row `y`, channel `c`.
    ///
    /// # Panics
    /// When the position is outside the image.
    #[must_use]
    pub fn get(&self, x: usize, y: usize, c: usize) -> f32 {
        assert!(x < self.width && y < self.height && c < self.channels);
        self.data[(y * self.width + x) * self.channels + c]
    }

    /// Counts the NaN and infinite samples.
    #[must_use]
    pub fn count_non_finite(&self) -> usize {
        count_non_finite(self.data)
    }

    /// An owned copy.
    #[must_use]
    pub fn to_image(&self) -> Image {
        Image {
            width: self.width,
            height: self.height,
            channels: self.channels,
            data: self.data.to_vec(),
        }
    }
}

impl<'a> From<&'a Image> for ImageView<'a> {
    fn from(image: &'a Image) -> Self {
        image.view()
    }
}

fn checked_len(width: usize, height: usize, channels: usize) -> Result<usize, ImageError> {
    if width == 0 || height == 0 || channels == 0 {
        return Err(ImageError::Empty {
            path: None,
            width,
            height,
            channels,
        });
    }
    width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(channels))
        .ok_or(ImageError::TooLarge {
            path: None,
            needed_bytes: u64::MAX,
            budget_bytes: 0,
        })
}

/// The NaN and infinite values among `data`, counted in 32-bit lanes a
/// chunk at a time (a chunk's count fits a `u32`; this loop vectorises).
fn count_non_finite(data: &[f32]) -> usize {
    data.chunks(1 << 20)
        .map(|c| c.iter().map(|v| u32::from(!v.is_finite())).sum::<u32>() as usize)
        .sum()
}

#[cfg(test)]
mod tests {
    use super::count_non_finite;

    /// Counts across the counting chunks, at their edges.
    #[test]
    fn non_finite_values_are_counted_in_every_chunk() {
        let n = (1 << 20) + 5;
        let mut data = vec![1.0f32; n];
        for i in [0, (1 << 20) - 1, 1 << 20, n - 1, 77] {
            data[i] = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][i % 3];
        }
        assert_eq!(count_non_finite(&data), 5);
        assert_eq!(count_non_finite(&data[1..n - 1]), 3);
        assert_eq!(count_non_finite(&[]), 0);
    }
}
