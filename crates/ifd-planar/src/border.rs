//! Border modes: how an image is extended beyond its edges.

use std::fmt;
use std::str::FromStr;

use ifd_image::ImageView;
use rayon::prelude::*;

use crate::error::FilterError;

/// How pixels outside the image are defined.
///
/// ```
/// use ifd_planar::Border;
/// let b: Border = "reflect101".parse()?;
/// assert_eq!(b, Border::Reflect101);
/// // gfedcb|abcdefgh|gfedcba
/// assert_eq!(b.resolve(-1, 8), Some(1));
/// assert_eq!(b.resolve(8, 8), Some(6));
/// assert_eq!("constant:0.5".parse::<Border>()?, Border::Constant(0.5));
/// assert_eq!(Border::Constant(0.0).resolve(-1, 8), None);
/// # Ok::<(), ifd_planar::FilterError>(())
/// ```
///
/// Border modes: how an image is extended beyond its edges.
///
/// The names and semantics follow `OpenCV`'s `BorderTypes`. For an image row
/// `abcdefgh` the extensions are:
///
/// | mode | left extension | `|` image `|` | right extension |
/// |---|---|---|---|
/// | [`Border::Reflect101`] (default, `BORDER_DEFAULT`) | `gfedcb` | `abcdefgh` | `gfedcba` |
/// | [`Border::Replicate`] | `aaaaaa` | `abcdefgh` | `hhhhhhh` |
/// | [`Border::Wrap`] | `cdefgh` | `abcdefgh` | `abcdefg` |
/// | [`Border::Constant`]`(v)` | `vvvvvv` | `abcdefgh` | `vvvvvvv` |
///
/// Reflection repeats for offsets further than one image width outside
/// (the extension is periodic with period `2 (n - 1)`), so any integer index
/// resolves.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Border {
    /// Mirror without repeating the edge pixel: `gfedcb|abcdefgh|gfedcba`
    /// (`OpenCV` `BORDER_REFLECT_101` = `BORDER_DEFAULT`, scipy `'mirror'`).
    #[default]
    Reflect101,
    /// A constant value outside the image: `vvvvvv|abcdefgh|vvvvvvv`
    /// (`OpenCV` `BORDER_CONSTANT`).
    Constant(f32),
    /// The edge pixel repeated: `aaaaaa|abcdefgh|hhhhhhh` (`OpenCV` `BORDER_REPLICATE`).
    Replicate,
    /// Periodic: `cdefgh|abcdefgh|abcdefg` (`OpenCV` `BORDER_WRAP`).
    Wrap,
}

impl Border {
    /// Resolves index `i` (possibly far outside) of a row of length `n`.
    ///
    /// Returns the index inside `0..n` whose value the position takes, or
    /// `None` for [`Border::Constant`] outside the image (the value is then the
    /// constant). Returns `None` for `n == 0`.
    #[must_use]
    pub fn resolve(self, i: i64, n: usize) -> Option<usize> {
        if n == 0 {
            return None;
        }
        let n_i = n as i64;
        if (0..n_i).contains(&i) {
            return Some(i as usize);
        }
        match self {
            Border::Constant(_) => None,
            Border::Replicate => Some(i.clamp(0, n_i - 1) as usize),
            Border::Wrap => Some(i.rem_euclid(n_i) as usize),
            Border::Reflect101 => Some(reflect101(i, n_i) as usize),
        }
    }

    /// The value of pixel `i` of `row` under this border mode.
    ///
    /// Returns `0.0` for an empty row.
    #[must_use]
    pub fn value(self, row: &[f32], i: i64) -> f32 {
        match self.resolve(i, row.len()) {
            Some(j) => row[j],
            None => self.constant(),
        }
    }

    /// The constant of [`Border::Constant`], `0.0` for the other modes.
    #[must_use]
    pub fn constant(self) -> f32 {
        match self {
            Border::Constant(v) => v,
            _ => 0.0,
        }
    }

    /// Maps a continuous coordinate `x` into `[0, n - 1]` (reflect-101, about
    /// the centres of the first and last pixels), into `[0, n)` (wrap) or clamps
    /// it (replicate). Constant mode returns `x` unchanged.
    pub(crate) fn map_continuous(self, x: f32, n: usize) -> f32 {
        let last = (n.max(1) - 1) as f32;
        match self {
            Border::Constant(_) => x,
            Border::Replicate => x.clamp(0.0, last),
            Border::Wrap => {
                let r = x.rem_euclid(n.max(1) as f32);
                // rem_euclid may round up to exactly n for tiny negative x.
                if r >= n as f32 { 0.0 } else { r }
            }
            Border::Reflect101 => {
                if n <= 1 {
                    return 0.0;
                }
                // One reflection suffices for most lookups; fall back to the
                // periodic reduction only far outside.
                let once = if x < 0.0 {
                    -x
                } else if x > last {
                    2.0 * last - x
                } else {
                    x
                };
                if (0.0..=last).contains(&once) {
                    return once;
                }
                let period = 2.0 * last;
                let r = x.rem_euclid(period);
                let r = if r > last { period - r } else { r };
                r.clamp(0.0, last)
            }
        }
    }
}

/// Reflect-101 index for `i` outside `0..n`, `n >= 1`, any distance away.
fn reflect101(i: i64, n: i64) -> i64 {
    if n == 1 {
        return 0;
    }
    let period = 2 * (n - 1);
    let r = i.rem_euclid(period);
    if r >= n { period - r } else { r }
}

impl fmt::Display for Border {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Border::Reflect101 => write!(f, "reflect101"),
            Border::Constant(v) => write!(f, "constant:{v}"),
            Border::Replicate => write!(f, "replicate"),
            Border::Wrap => write!(f, "wrap"),
        }
    }
}

impl FromStr for Border {
    type Err = FilterError;

    /// Parses `reflect101`, `replicate`, `wrap`, `constant` (value 0) or
    /// `constant:V` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let lower = s.trim().to_ascii_lowercase();
        let bad = || FilterError::InvalidBorder(s.to_string());
        match lower.as_str() {
            "reflect101" | "reflect_101" | "reflect-101" | "default" => Ok(Border::Reflect101),
            "replicate" => Ok(Border::Replicate),
            "wrap" => Ok(Border::Wrap),
            "constant" => Ok(Border::Constant(0.0)),
            other => {
                let v = other.strip_prefix("constant:").ok_or_else(bad)?;
                let not_finite = || {
                    FilterError::InvalidParameter(format!(
                        "border {s:?}: the constant must be a finite 32-bit float"
                    ))
                };
                match v.trim().parse::<f32>() {
                    Ok(v) if v.is_finite() => Ok(Border::Constant(v)),
                    Ok(_) => Err(not_finite()),
                    Err(_) => Err(bad()),
                }
            }
        }
    }
}

/// `image` extended by `rx` columns and `ry` rows on each side by `border`
/// (row-major, interleaved), and the extended width.
pub(crate) fn extend<'a>(
    image: impl Into<ImageView<'a>>,
    rx: usize,
    ry: usize,
    border: Border,
) -> (Vec<f32>, usize) {
    let image = image.into();
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let ew = w + 2 * rx;
    let eh = h + 2 * ry;
    let data = image.data();
    let cval = border.constant();
    let xmap: Vec<Option<usize>> = (0..ew)
        .map(|i| border.resolve(i as i64 - rx as i64, w))
        .collect();
    let mut ext = vec![0.0f32; ew * eh * c];
    ext.par_chunks_mut(ew * c)
        .enumerate()
        .for_each(|(ey, row)| {
            let sy = border.resolve(ey as i64 - ry as i64, h);
            for (ex, px) in row.chunks_exact_mut(c).enumerate() {
                match (sy, xmap[ex]) {
                    (Some(y), Some(x)) => {
                        px.copy_from_slice(&data[(y * w + x) * c..(y * w + x + 1) * c]);
                    }
                    _ => px.fill(cval),
                }
            }
        });
    (ext, ew)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Resolves indices `from..to` of the row "abcdefgh" into a string.
    fn ext(b: Border, from: i64, to: i64) -> String {
        let row = b"abcdefgh";
        (from..to)
            .map(|i| match b.resolve(i, row.len()) {
                Some(j) => row[j] as char,
                None => 'v',
            })
            .collect()
    }

    #[test]
    fn opencv_sequences() {
        assert_eq!(ext(Border::Reflect101, -6, 15), "gfedcbabcdefghgfedcba");
        assert_eq!(ext(Border::Replicate, -6, 15), "aaaaaaabcdefghhhhhhhh");
        assert_eq!(ext(Border::Wrap, -6, 15), "cdefghabcdefghabcdefg");
        assert_eq!(ext(Border::Constant(0.0), -6, 15), "vvvvvvabcdefghvvvvvvv");
    }

    #[test]
    fn far_outside_repeats() {
        // Reflect-101 is periodic with period 2(n-1) = 14.
        assert_eq!(
            ext(Border::Reflect101, -20, 22),
            "gfedcbabcdefghgfedcbabcdefghgfedcbabcdefgh"
        );
        // 1_000_000 mod 14 = 8 -> g, 9 -> f, 10 -> e.
        assert_eq!(ext(Border::Reflect101, 1_000_000, 1_000_003), "gfe");
        assert_eq!(ext(Border::Wrap, -17, -13), "habc");
        assert_eq!(Border::Wrap.resolve(-17, 8), Some(7));
        assert_eq!(Border::Replicate.resolve(i64::MIN / 2, 8), Some(0));
        // A single pixel reflects onto itself.
        assert_eq!(Border::Reflect101.resolve(-5, 1), Some(0));
        assert_eq!(Border::Reflect101.resolve(7, 2), Some(1));
        assert_eq!(Border::Reflect101.resolve(2, 2), Some(0));
        assert_eq!(Border::Reflect101.resolve(0, 0), None);
    }

    #[test]
    fn continuous_mapping() {
        let b = Border::Reflect101;
        assert!((b.map_continuous(-0.5, 8) - 0.5).abs() < 1e-6);
        assert!((b.map_continuous(7.5, 8) - 6.5).abs() < 1e-6);
        assert!((b.map_continuous(-14.25, 8) - 0.25).abs() < 1e-5);
        assert!((Border::Wrap.map_continuous(-0.5, 8) - 7.5).abs() < 1e-6);
        assert_eq!(Border::Replicate.map_continuous(-3.0, 8), 0.0);
        assert_eq!(b.map_continuous(123.0, 1), 0.0);
    }

    #[test]
    fn parse_and_display() {
        for b in [
            Border::Reflect101,
            Border::Replicate,
            Border::Wrap,
            Border::Constant(0.0),
            Border::Constant(-1.5),
        ] {
            assert_eq!(b.to_string().parse::<Border>().ok(), Some(b));
        }
        assert_eq!(
            "Constant".parse::<Border>().ok(),
            Some(Border::Constant(0.0))
        );
        assert_eq!(
            "REFLECT101".parse::<Border>().ok(),
            Some(Border::Reflect101)
        );
        assert!("mirror2".parse::<Border>().is_err());
        assert!("constant:abc".parse::<Border>().is_err());
        for v in ["nan", "inf", "1e39"] {
            let e = format!("constant:{v}")
                .parse::<Border>()
                .unwrap_err()
                .to_string();
            assert!(e.contains("must be a finite"), "{e}");
        }
        let msg = "bogus".parse::<Border>().err().map(|e| e.to_string());
        assert!(msg.is_some_and(|m| m.contains("bogus")));
    }
}
