//! NumPy `.npy` files (format versions 1.0-3.0): float32/float64 (and, for
//! convenience, uint8/uint16 read as-is), `HxW` or `HxWxC`, C or Fortran order,
//! either byte order.

use std::io::{Read, Write};
use std::path::Path;

use crate::budget::MemoryBudget;
use crate::{Image, ImageError};

const MAGIC: &[u8] = b"\x93NUMPY";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dtype {
    F32,
    F64,
    U8,
    U16,
}

impl Dtype {
    fn size(self) -> usize {
        match self {
            Self::F32 => 4,
            Self::F64 => 8,
            Self::U8 => 1,
            Self::U16 => 2,
        }
    }
}

pub(crate) fn read_npy(
    path: &Path,
    mut file: std::fs::File,
    budget: MemoryBudget,
) -> Result<Image, ImageError> {
    let bad = |reason: String| ImageError::Decode {
        path: path.to_path_buf(),
        format: "NumPy",
        reason,
    };
    let io = |e: std::io::Error| bad(format!("truncated or unreadable: {e}"));
    let mut head = [0u8; 8];
    file.read_exact(&mut head).map_err(io)?;
    if &head[..6] != MAGIC {
        return Err(bad("missing the \\x93NUMPY magic string".into()));
    }
    let header_len = match head[6] {
        1 => {
            let mut b = [0u8; 2];
            file.read_exact(&mut b).map_err(io)?;
            usize::from(u16::from_le_bytes(b))
        }
        2 | 3 => {
            let mut b = [0u8; 4];
            file.read_exact(&mut b).map_err(io)?;
            u32::from_le_bytes(b) as usize
        }
        v => return Err(bad(format!("unsupported format version {v}"))),
    };
    if header_len > 1 << 20 {
        return Err(bad(format!("header of {header_len} bytes is implausible")));
    }
    let mut header = vec![0u8; header_len];
    file.read_exact(&mut header).map_err(io)?;
    let header = String::from_utf8_lossy(&header);
    let descr = dict_value(&header, "descr").ok_or_else(|| bad("header has no 'descr'".into()))?;
    let descr = descr.trim_matches(|c| c == '\'' || c == '"');
    let (big_endian, dtype) = parse_descr(descr).ok_or_else(|| {
        bad(format!(
            "dtype {descr:?} is not supported (use float32 or float64)"
        ))
    })?;
    let fortran = dict_value(&header, "fortran_order")
        .ok_or_else(|| bad("header has no 'fortran_order'".into()))?
        .starts_with("True");
    let shape_s =
        dict_value(&header, "shape").ok_or_else(|| bad("header has no 'shape'".into()))?;
    let shape: Vec<usize> = shape_s
        .trim_matches(|c| c == '(' || c == ')')
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|_| bad(format!("cannot parse shape {shape_s}")))?;
    let (h, w, c) = match shape.as_slice() {
        [h, w] => (*h, *w, 1),
        [h, w, c] => (*h, *w, *c),
        _ => {
            return Err(bad(format!(
                "shape {shape:?} is not an image (expected HxW or HxWxC)"
            )));
        }
    };
    if h == 0 || w == 0 || c == 0 {
        return Err(ImageError::Empty {
            path: Some(path.to_path_buf()),
            width: w,
            height: h,
            channels: c,
        });
    }
    let n = h
        .checked_mul(w)
        .and_then(|v| v.checked_mul(c))
        .ok_or_else(|| bad(format!("shape {shape:?} overflows")))?;
    budget.check((n as u64).saturating_mul(4 + dtype.size() as u64))?;
    let mut raw = vec![0u8; n * dtype.size()];
    file.read_exact(&mut raw).map_err(|_| {
        bad(format!(
            "truncated: shape {shape:?} needs {} data bytes",
            n * dtype.size()
        ))
    })?;
    let values: Vec<f32> = raw
        .chunks_exact(dtype.size())
        .map(|b| decode_value(b, dtype, big_endian))
        .collect();
    let data = if fortran {
        // Fortran order: the first index varies fastest.
        let mut out = vec![0.0; n];
        for (i, v) in values.into_iter().enumerate() {
            let y = i % h;
            let x = (i / h) % w;
            let ch = i / (h * w);
            out[(y * w + x) * c + ch] = v;
        }
        out
    } else {
        values
    };
    Image::from_vec(w, h, c, data)
}

fn decode_value(b: &[u8], dtype: Dtype, big: bool) -> f32 {
    match dtype {
        Dtype::U8 => f32::from(b[0]),
        Dtype::U16 => {
            let a = [b[0], b[1]];
            f32::from(if big {
                u16::from_be_bytes(a)
            } else {
                u16::from_le_bytes(a)
            })
        }
        Dtype::F32 => {
            let a = [b[0], b[1], b[2], b[3]];
            if big {
                f32::from_be_bytes(a)
            } else {
                f32::from_le_bytes(a)
            }
        }
        Dtype::F64 => {
            let a = [b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]];
            (if big {
                f64::from_be_bytes(a)
            } else {
                f64::from_le_bytes(a)
            }) as f32
        }
    }
}

fn parse_descr(d: &str) -> Option<(bool, Dtype)> {
    let (order, ty) = d.split_at(1);
    let big = match order {
        "<" | "|" | "=" => false,
        ">" => true,
        _ => return None,
    };
    let dtype = match ty {
        "f4" => Dtype::F32,
        "f8" => Dtype::F64,
        "u1" => Dtype::U8,
        "u2" => Dtype::U16,
        _ => return None,
    };
    Some((big, dtype))
}

/// Extracts the textual value of `key` from a Python dict literal.
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let pat1 = format!("'{key}':");
    let pat2 = format!("\"{key}\":");
    let start = header
        .find(&pat1)
        .map(|i| i + pat1.len())
        .or_else(|| header.find(&pat2).map(|i| i + pat2.len()))?;
    let rest = header[start..].trim_start();
    let end = if rest.starts_with('(') {
        rest.find(')')? + 1
    } else {
        rest.find([',', '}'])?
    };
    Some(rest[..end].trim())
}

pub(crate) fn write_npy<W: Write>(out: &mut W, image: &Image) -> Result<(), String> {
    let shape = if image.channels() == 1 {
        format!("({}, {})", image.height(), image.width())
    } else {
        format!(
            "({}, {}, {})",
            image.height(),
            image.width(),
            image.channels()
        )
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
    // Pad so that magic + version + length + header is a multiple of 64.
    let unpadded = MAGIC.len() + 2 + 2 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let len = u16::try_from(header.len()).map_err(|_| "npy header too long".to_string())?;
    let e = |e: std::io::Error| e.to_string();
    out.write_all(MAGIC).map_err(e)?;
    out.write_all(&[1, 0]).map_err(e)?;
    out.write_all(&len.to_le_bytes()).map_err(e)?;
    out.write_all(header.as_bytes()).map_err(e)?;
    for v in image.data() {
        out.write_all(&v.to_le_bytes()).map_err(e)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_values() {
        let h = "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 4, 2), }";
        assert_eq!(dict_value(h, "descr"), Some("'<f8'"));
        assert_eq!(dict_value(h, "fortran_order"), Some("False"));
        assert_eq!(dict_value(h, "shape"), Some("(3, 4, 2)"));
        assert_eq!(parse_descr("<f8"), Some((false, Dtype::F64)));
        assert_eq!(parse_descr("<c8"), None);
    }

    #[test]
    fn written_header_is_aligned() {
        let img = Image::new(3, 2, 1).unwrap();
        let mut buf = Vec::new();
        write_npy(&mut buf, &img).unwrap();
        let hl = u16::from_le_bytes([buf[8], buf[9]]) as usize;
        assert_eq!((10 + hl) % 64, 0);
        assert_eq!(buf.len(), 10 + hl + 6 * 4);
    }
}
