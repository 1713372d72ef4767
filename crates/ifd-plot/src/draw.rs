//! Drawing primitives on RGB [`Image`]s (values in `[0, 1]`, white
//! background): points, lines, text in a small built-in 5x7 bitmap font
//! (digits, letters and the punctuation the plots need, scaled by two),
//! colour maps and colour bars.

use ifd_image::Image;

/// Black.
pub const BLACK: [f32; 3] = [0.0, 0.0, 0.0];
/// Light grey, for grid lines.
pub const GREY: [f32; 3] = [0.85, 0.85, 0.85];

/// A white `width x height` RGB canvas.
///
/// # Errors
/// Only if the image cannot be allocated.
pub fn canvas(width: usize, height: usize) -> Result<Image, ifd_image::ImageError> {
    Image::from_vec(width, height, 3, vec![1.0; width * height * 3])
}

/// Sets pixel `(x, y)` to `rgb`; outside the image nothing happens.
pub fn put(img: &mut Image, x: usize, y: usize, rgb: [f32; 3]) {
    if x < img.width() && y < img.height() {
        for (c, v) in rgb.into_iter().enumerate() {
            img.set(x, y, c, v);
        }
    }
}

/// [`put`] at the pixel nearest `(x, y)`; negative coordinates are ignored.
pub fn put_f(img: &mut Image, x: f64, y: f64, rgb: [f32; 3]) {
    if x >= 0.0 && y >= 0.0 {
        put(img, x.round() as usize, y.round() as usize, rgb);
    }
}

/// A horizontal line from `x0` to `x1` (inclusive) on row `y`.
pub fn hline(img: &mut Image, x0: usize, x1: usize, y: usize, rgb: [f32; 3]) {
    (x0..=x1).for_each(|x| put(img, x, y, rgb));
}

/// A vertical line from `y0` to `y1` (inclusive) on column `x`.
pub fn vline(img: &mut Image, x: usize, y0: usize, y1: usize, rgb: [f32; 3]) {
    (y0..=y1).for_each(|y| put(img, x, y, rgb));
}

/// A 2-pixel-wide line; dotted (4 on, 4 off) when `dotted`.
pub fn segment(img: &mut Image, a: (f64, f64), b: (f64, f64), rgb: [f32; 3], dotted: bool) {
    let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
    for k in 0..=steps {
        if dotted && (k / 4) % 2 == 1 {
            continue;
        }
        let t = k as f64 / steps as f64;
        let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            put_f(img, x + dx, y + dy, rgb);
        }
    }
}

/// Pixel scale of the font.
const SCALE: usize = 2;
/// Height of a text line in pixels (7 rows above the baseline, scaled).
pub const TEXT_HEIGHT: usize = 7 * SCALE;
/// Horizontal advance of one character in pixels.
const ADVANCE: usize = 6 * SCALE;

/// Width in pixels of `text` drawn by [`draw_text`].
#[must_use]
pub fn text_width(text: &str) -> usize {
    (text.chars().count() * ADVANCE).saturating_sub(SCALE)
}

/// Draws `text` with its top-left corner at `(x, y)` (descenders go below
/// [`TEXT_HEIGHT`]). Characters without a glyph are drawn as a box.
pub fn draw_text(img: &mut Image, x: usize, y: usize, text: &str, rgb: [f32; 3]) {
    for (i, ch) in text.chars().enumerate() {
        let g = glyph(ch).unwrap_or(BOX);
        for (row, bits) in g.split(' ').enumerate() {
            for (col, b) in bits.bytes().enumerate() {
                if b != b'#' {
                    continue;
                }
                for sy in 0..SCALE {
                    for sx in 0..SCALE {
                        put(
                            img,
                            x + i * ADVANCE + col * SCALE + sx,
                            y + row * SCALE + sy,
                            rgb,
                        );
                    }
                }
            }
        }
    }
}

/// Draws `text` centred on column `x`, top at `y` (clipped at the left
/// edge).
pub fn draw_text_centred(img: &mut Image, x: usize, y: usize, text: &str, rgb: [f32; 3]) {
    draw_text(img, x.saturating_sub(text_width(text) / 2), y, text, rgb);
}

const BOX: &str = "##### #...# #...# #...# #...# #...# #####";

/// 5-wide glyphs, rows top to bottom separated by spaces; 7 rows, plus 2
/// descender rows for `g j p q y`.
#[must_use]
pub fn glyph(c: char) -> Option<&'static str> {
    Some(match c {
        ' ' => "..... ..... ..... ..... ..... ..... .....",
        '0' => ".###. #...# #..## #.#.# ##..# #...# .###.",
        '1' => "..#.. .##.. ..#.. ..#.. ..#.. ..#.. .###.",
        '2' => ".###. #...# ....# ...#. ..#.. .#... #####",
        '3' => "##### ...#. ..#.. ...#. ....# #...# .###.",
        '4' => "...#. ..##. .#.#. #..#. ##### ...#. ...#.",
        '5' => "##### #.... ####. ....# ....# #...# .###.",
        '6' => "..##. .#... #.... ####. #...# #...# .###.",
        '7' => "##### ....# ...#. ..#.. .#... .#... .#...",
        '8' => ".###. #...# #...# .###. #...# #...# .###.",
        '9' => ".###. #...# #...# .#### ....# ...#. .##..",
        'a' => "..... ..... .###. ....# .#### #...# .####",
        'b' => "#.... #.... #.##. ##..# #...# #...# ####.",
        'c' => "..... ..... .###. #.... #.... #...# .###.",
        'd' => "....# ....# .##.# #..## #...# #...# .####",
        'e' => "..... ..... .###. #...# ##### #.... .###.",
        'f' => "..##. .#..# .#... ###.. .#... .#... .#...",
        'g' => "..... ..... .#### #...# #...# .#### ....# #...# .###.",
        'h' => "#.... #.... #.##. ##..# #...# #...# #...#",
        'i' => "..#.. ..... .##.. ..#.. ..#.. ..#.. .###.",
        'j' => "...#. ..... ..##. ...#. ...#. ...#. ...#. #..#. .##..",
        'k' => "#.... #.... #..#. #.#.. ##... #.#.. #..#.",
        'l' => ".##.. ..#.. ..#.. ..#.. ..#.. ..#.. .###.",
        'm' => "..... ..... ##.#. #.#.# #.#.# #...# #...#",
        'n' => "..... ..... #.##. ##..# #...# #...# #...#",
        'o' => "..... ..... .###. #...# #...# #...# .###.",
        'p' => "..... ..... ####. #...# #...# ####. #.... #.... #....",
        'q' => "..... ..... .#### #...# #...# .#### ....# ....# ....#",
        'r' => "..... ..... #.##. ##..# #.... #.... #....",
        's' => "..... ..... .###. #.... .###. ....# ####.",
        't' => ".#... .#... ###.. .#... .#... .#..# ..##.",
        'u' => "..... ..... #...# #...# #...# #..## .##.#",
        'v' => "..... ..... #...# #...# #...# .#.#. ..#..",
        'w' => "..... ..... #...# #...# #.#.# #.#.# .#.#.",
        'x' => "..... ..... #...# .#.#. ..#.. .#.#. #...#",
        'y' => "..... ..... #...# #...# #...# .#### ....# #...# .###.",
        'z' => "..... ..... ##### ...#. ..#.. .#... #####",
        'A' => ".###. #...# #...# ##### #...# #...# #...#",
        'B' => "####. #...# #...# ####. #...# #...# ####.",
        'C' => ".###. #...# #.... #.... #.... #...# .###.",
        'D' => "###.. #..#. #...# #...# #...# #..#. ###..",
        'E' => "##### #.... #.... ####. #.... #.... #####",
        'F' => "##### #.... #.... ####. #.... #.... #....",
        'G' => ".###. #...# #.... #.### #...# #...# .####",
        'H' => "#...# #...# #...# ##### #...# #...# #...#",
        'I' => ".###. ..#.. ..#.. ..#.. ..#.. ..#.. .###.",
        'L' => "#.... #.... #.... #.... #.... #.... #####",
        'M' => "#...# ##.## #.#.# #.#.# #...# #...# #...#",
        'N' => "#...# #...# ##..# #.#.# #..## #...# #...#",
        'O' => ".###. #...# #...# #...# #...# #...# .###.",
        'P' => "####. #...# #...# ####. #.... #.... #....",
        'R' => "####. #...# #...# ####. #.#.. #..#. #...#",
        'S' => ".#### #.... #.... .###. ....# ....# ####.",
        'T' => "##### ..#.. ..#.. ..#.. ..#.. ..#.. ..#..",
        'Z' => "##### ....# ...#. ..#.. .#... #.... #####",
        '(' => "...#. ..#.. .#... .#... .#... ..#.. ...#.",
        ')' => ".#... ..#.. ...#. ...#. ...#. ..#.. .#...",
        '-' => "..... ..... ..... ##### ..... ..... .....",
        '+' => "..... ..#.. ..#.. ##### ..#.. ..#.. .....",
        '=' => "..... ..... ##### ..... ##### ..... .....",
        '>' => ".#... ..#.. ...#. ....# ...#. ..#.. .#...",
        '<' => "...#. ..#.. .#... #.... .#... ..#.. ...#.",
        '.' => "..... ..... ..... ..... ..... .##.. .##..",
        ',' => "..... ..... ..... ..... .##.. ..#.. .#...",
        ':' => "..... .##.. .##.. ..... .##.. .##.. .....",
        '/' => "....# ....# ...#. ..#.. .#... #.... #....",
        '^' => "..#.. .#.#. #...# ..... ..... ..... .....",
        '_' => "..... ..... ..... ..... ..... ..... #####",
        _ => return None,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn dark_pixels(img: &Image, x0: usize, x1: usize, y0: usize, y1: usize) -> usize {
        let mut n = 0;
        for y in y0..y1 {
            for x in x0..x1 {
                if img.get(x, y, 0) < 0.5 {
                    n += 1;
                }
            }
        }
        n
    }

    #[test]
    fn glyphs_are_well_formed() {
        for c in (' '..='~').filter_map(|c| glyph(c).map(|g| (c, g))) {
            let rows: Vec<&str> = c.1.split(' ').collect();
            assert!(rows.len() == 7 || rows.len() == 9, "{:?}", c.0);
            assert!(
                rows.iter()
                    .all(|r| r.len() == 5 && r.bytes().all(|b| b == b'#' || b == b'.')),
                "{:?}",
                c.0
            );
            // descenders only where the glyph has one
            assert_eq!(rows.len() == 9, "gjpqy".contains(c.0), "{:?}", c.0);
        }
    }

    #[test]
    fn text_is_drawn_where_asked() {
        let mut img = canvas(100, 40).unwrap();
        draw_text(&mut img, 10, 5, "1e16", BLACK);
        let w = text_width("1e16");
        assert_eq!(w, 4 * ADVANCE - SCALE);
        let inside = dark_pixels(&img, 10, 10 + w, 5, 5 + TEXT_HEIGHT);
        let all = dark_pixels(&img, 0, 100, 0, 40);
        assert!(inside > 40 && inside == all, "{inside} of {all}");
        // '1' has 2 * 2 scaled pixels per lit font pixel: 10 lit pixels
        let mut one = canvas(20, 20).unwrap();
        draw_text(&mut one, 0, 0, "1", BLACK);
        assert_eq!(dark_pixels(&one, 0, 20, 0, 20), 10 * SCALE * SCALE);
    }
}
