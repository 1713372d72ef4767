//! From `f32` images to display textures: 8-bit sRGB tiles of at most
//! [`DISPLAY_TILE`] pixels a side (GPU texture size limits), and partial
//! updates of the tiles a dab touched.
//!
//! Integer files (PNG, JPEG, TIFF) hold sRGB-encoded values mapped linearly
//! to `[0, 1]`: they are shown as they are. Float files (EXR, HDR) hold
//! linear light: they are shown through the sRGB transfer function. Values
//! are clamped to `[0, 1]`; one channel is grey, two are grey and alpha
//! (alpha ignored), three RGB, four RGBA (alpha ignored).

use egui::{Color32, ColorImage};
use ifd_image::Image;
use ifd_planar::PixelRect;

/// Largest side of a display tile, pixels.
pub const DISPLAY_TILE: usize = 2048;

/// The tiles covering a `width x height` image, row by row.
#[must_use]
pub fn tile_rects(width: usize, height: usize) -> Vec<PixelRect> {
    PixelRect::tiles(width, height, DISPLAY_TILE)
}

fn to_byte(v: f32, float_source: bool) -> u8 {
    let v = if float_source {
        ifd_image::linear_to_srgb(v.max(0.0))
    } else {
        v
    };
    // NaN maps to 0.
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// The display colour of pixel `(x, y)`.
#[must_use]
pub fn pixel_color(image: &Image, x: usize, y: usize, float_source: bool) -> Color32 {
    let c = image.channels();
    let i = (y * image.width() + x) * c;
    let px = &image.data()[i..i + c];
    if c >= 3 {
        Color32::from_rgb(
            to_byte(px[0], float_source),
            to_byte(px[1], float_source),
            to_byte(px[2], float_source),
        )
    } else {
        Color32::from_gray(to_byte(px[0], float_source))
    }
}

/// The display pixels of `rect`.
#[must_use]
pub fn color_image(image: &Image, rect: PixelRect, float_source: bool) -> ColorImage {
    let mut pixels = Vec::with_capacity(rect.area());
    for y in rect.y0..rect.y0 + rect.height {
        for x in rect.x0..rect.x0 + rect.width {
            pixels.push(pixel_color(image, x, y, float_source));
        }
    }
    ColorImage::new([rect.width, rect.height], pixels)
}

/// An update of one display tile.
#[derive(Clone, Debug)]
pub struct TilePatch {
    /// Index into [`tile_rects`].
    pub tile: usize,
    /// Position of the patch inside the tile.
    pub pos: [usize; 2],
    /// The new pixels.
    pub image: ColorImage,
}

/// The tile updates that show the pixels of `rect`.
#[must_use]
pub fn tile_patches(image: &Image, rect: PixelRect, float_source: bool) -> Vec<TilePatch> {
    tile_rects(image.width(), image.height())
        .into_iter()
        .enumerate()
        .filter_map(|(tile, t)| {
            let r = t.intersect(rect)?;
            Some(TilePatch {
                tile,
                pos: [r.x0 - t.x0, r.y0 - t.y0],
                image: color_image(image, r, float_source),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_image_once() {
        let t = tile_rects(5000, 2049);
        assert_eq!(t.len(), 6);
        assert_eq!(t.iter().map(|r| r.area()).sum::<usize>(), 5000 * 2049);
        let img = Image::from_vec(3000, 10, 1, vec![0.5; 30_000]).expect("image");
        let p = tile_patches(
            &img,
            PixelRect {
                x0: 2000,
                y0: 2,
                width: 100,
                height: 3,
            },
            false,
        );
        assert_eq!(p.len(), 2);
        assert_eq!(p[1].pos, [0, 2]);
        assert_eq!(p[0].image.size, [48, 3]);
        assert_eq!(p[0].image.pixels[0], Color32::from_gray(128));
    }

    #[test]
    fn float_sources_are_srgb_encoded() {
        assert_eq!(to_byte(0.0, true), 0);
        assert_eq!(to_byte(1.0, true), 255);
        assert!(to_byte(0.2, true) > to_byte(0.2, false));
        assert_eq!(to_byte(f32::NAN, false), 0);
        assert_eq!(to_byte(7.0, true), 255);
    }
}
