//! NumPy `.npy` files (format versions 1.0-3.0): float32/float64 (and, for
//! convenience, uint8/uint16 read as-is), `HxW` or `HxWxC`, C or Fortran order,
//! either byte order.

use std::io::{Read, Seek, Write};
use std::path::Path;

use crate::budget::MemoryBudget;
use crate::{Image, ImageError};

const MAGIC: &[u8] = b"\x93NUMPY";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Dtype {
    F32,
    F64,
    U8,
    U16,
}

impl Dtype {
    pub(crate) fn size(self) -> usize {
        match self {
            Self::F32 => 4,
            Self::F64 => 8,
            Self::U8 => 1,
            Self::U16 => 2,
        }
    }
}

/// A malformed or truncated `.npy` file, named.
pub(crate) fn npy_error(path: &Path, reason: String) -> ImageError {
    ImageError::Decode {
        path: path.to_path_buf(),
        format: "NumPy",
        reason,
    }
}

/// A parsed `.npy` header: element type, byte order, memory order, shape.
pub(crate) struct Header {
    pub(crate) dtype: Dtype,
    pub(crate) big_endian: bool,
    pub(crate) fortran: bool,
    pub(crate) shape: Vec<usize>,
}

pub(crate) fn read_header(
    file: &mut std::fs::File,
    bad: &dyn Fn(String) -> ImageError,
) -> Result<Header, ImageError> {
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
    if descr.trim_start().starts_with('[') {
        return Err(bad(
            "a structured dtype (named record fields) is not supported (use a plain float32 or \
             float64 array)"
                .into(),
        ));
    }
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
    Ok(Header {
        dtype,
        big_endian,
        fortran,
        shape,
    })
}

/// Reads `n` elements of `header`'s type, decoded by `decode` a chunk at a
/// time (appending to the values), checking the memory budget first
/// (`extra` bytes per element for the decoded copy, and the raw bytes as if
/// held whole: a bound above what a chunked read holds).
fn read_values<T>(
    file: &mut std::fs::File,
    header: &Header,
    n: usize,
    budget: MemoryBudget,
    extra: u64,
    bad: &dyn Fn(String) -> ImageError,
    decode: impl Fn(&[u8], Dtype, bool, &mut Vec<T>),
) -> Result<Vec<T>, ImageError> {
    let size = header.dtype.size();
    let need = (n as u64).saturating_mul(size as u64);
    // A header may declare more data than the file holds: check the file's
    // length before allocating for it (a 100-byte file must not make us
    // allocate gigabytes, even within the budget).
    let held = file
        .metadata()
        .and_then(|m| Ok(m.len().saturating_sub(file.stream_position()?)))
        .map_err(|e| bad(format!("unreadable: {e}")))?;
    if held < need {
        return Err(bad(format!(
            "truncated: shape {:?} needs {need} data bytes, the file holds {held}",
            header.shape
        )));
    }
    budget.check((n as u64).saturating_mul(extra + size as u64))?;
    // Read and decode a chunk at a time: no buffer of the whole file's
    // bytes beside the values (a second allocation, and its page faults,
    // as large as the array).
    let mut values = Vec::with_capacity(n);
    let mut raw = vec![0u8; n.min(READ_CHUNK) * size];
    let mut left = n;
    while left > 0 {
        let k = left.min(READ_CHUNK);
        let raw = &mut raw[..k * size];
        file.read_exact(raw).map_err(|_| {
            bad(format!(
                "truncated: shape {:?} needs {} data bytes",
                header.shape,
                n * size
            ))
        })?;
        decode(raw, header.dtype, header.big_endian, &mut values);
        left -= k;
    }
    Ok(values)
}

/// Elements read and decoded at a time.
const READ_CHUNK: usize = 1 << 16;

/// Every element of `raw` as `f32` ([`decode_value`]), appended to `out`;
/// little-endian `float32`, the common case, by a loop of its own (a plain
/// conversion, not a `match` per element).
fn decode_f32_values(raw: &[u8], dtype: Dtype, big: bool, out: &mut Vec<f32>) {
    if dtype == Dtype::F32 && !big {
        // into a filled buffer, lane by lane (this loop vectorises; a
        // collecting iterator did not)
        let start = out.len();
        out.resize(start + raw.len() / 4, 0.0);
        for (o, b) in out[start..].iter_mut().zip(raw.chunks_exact(4)) {
            *o = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        return;
    }
    out.extend(
        raw.chunks_exact(dtype.size())
            .map(|b| decode_value(b, dtype, big)),
    );
}

/// Every element of `raw` as `f64` ([`decode_f64`]), appended to `out`.
fn decode_f64_values(raw: &[u8], dtype: Dtype, big: bool, out: &mut Vec<f64>) {
    out.extend(
        raw.chunks_exact(dtype.size())
            .map(|b| decode_f64(b, dtype, big)),
    );
}

/// `values` stored in Fortran order (first index fastest) for `shape`,
/// reordered row-major (C order); `values` as they are when `fortran` is
/// false, the array has fewer than two axes or no element. (With an element,
/// every stride divides the element count, which fits a `usize`; a zero-size
/// array may have other axes whose product does not: found by fuzzing.)
fn to_c_order<T: Copy + Default>(values: Vec<T>, shape: &[usize], fortran: bool) -> Vec<T> {
    if !fortran || shape.len() < 2 || values.is_empty() {
        return values;
    }
    // C-order stride of each axis.
    let mut strides = vec![1; shape.len()];
    for k in (0..shape.len() - 1).rev() {
        strides[k] = strides[k + 1] * shape[k + 1];
    }
    let mut out = vec![T::default(); values.len()];
    for (i, v) in values.into_iter().enumerate() {
        let (mut rest, mut at) = (i, 0);
        for (&d, &stride) in shape.iter().zip(&strides) {
            at += (rest % d) * stride;
            rest /= d;
        }
        out[at] = v;
    }
    out
}

/// An n-dimensional array read from a `.npy` file, as `f64` in row-major
/// (C) order whatever the file's order and byte order.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    /// The shape, outermost axis first.
    pub shape: Vec<usize>,
    /// The values, row-major.
    pub data: Vec<f64>,
}

/// Reads any `.npy` array of float32, float64, uint8 or uint16 (format
/// versions 1.0-3.0, either byte order, C or Fortran order) as `f64`, with
/// the same checks and messages as images (`ifd_sphere` reads its SH
/// coefficients and direction lists through it).
///
/// ```
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("a.npy");
/// ifd_image::write_npy_f64(&path, &[2, 3], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0])?;
/// let a = ifd_image::read_npy_array(&path, ifd_image::MemoryBudget::default_for_machine())?;
/// assert_eq!(a.shape, vec![2, 3]);
/// assert_eq!(a.data[4], 5.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`ImageError::NotFound`] and [`ImageError::Io`] for missing and
/// unreadable files, [`ImageError::Decode`] naming
/// the file for malformed or truncated ones, [`ImageError::TooLarge`] when the
/// array exceeds `budget`.
pub fn read_npy_array(path: &Path, budget: MemoryBudget) -> Result<NpyArray, ImageError> {
    let mut file = crate::files::open(path)?;
    let bad = |reason| npy_error(path, reason);
    let header = read_header(&mut file, &bad)?;
    let n = header
        .shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| bad(format!("shape {:?} overflows", header.shape)))?;
    let values = read_values(&mut file, &header, n, budget, 8, &bad, decode_f64_values)?;
    let data = to_c_order(values, &header.shape, header.fortran);
    Ok(NpyArray {
        shape: header.shape,
        data,
    })
}

/// Writes a C-order little-endian float64 `.npy` file of shape `shape`
/// atomically (a temporary file, then a rename: never half written).
///
/// # Errors
/// [`ImageError::Write`] naming the file, also when `data`'s length does
/// not match `shape`.
pub fn write_npy_f64(path: &Path, shape: &[usize], data: &[f64]) -> Result<(), ImageError> {
    if shape.iter().product::<usize>() != data.len() {
        return Err(ImageError::Write {
            path: path.to_path_buf(),
            reason: format!("{} values for shape {shape:?}", data.len()),
        });
    }
    let dims: Vec<String> = shape.iter().map(ToString::to_string).collect();
    let shape_txt = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let header = padded_header("<f8", &shape_txt);
    crate::files::atomic_write(path, |w| {
        write_preamble(w, &header)?;
        write_le(w, data, f64::to_le_bytes)
    })
}

/// The header dict padded so that magic, version, length and header make a
/// multiple of 64 bytes, newline-terminated.
pub(crate) fn padded_header(descr: &str, shape: &str) -> String {
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    let unpadded = MAGIC.len() + 2 + 2 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    header
}

pub(crate) fn write_preamble<W: Write>(out: &mut W, header: &str) -> Result<(), String> {
    let len = u16::try_from(header.len()).map_err(|_| "npy header too long".to_string())?;
    let e = |e: std::io::Error| e.to_string();
    out.write_all(MAGIC).map_err(e)?;
    out.write_all(&[1, 0]).map_err(e)?;
    out.write_all(&len.to_le_bytes()).map_err(e)?;
    out.write_all(header.as_bytes()).map_err(e)
}

/// `(height, width, channels)` of an `HxW` or `HxWxC` array with no zero
/// dimension.
pub(crate) fn image_shape(
    path: &Path,
    shape: &[usize],
    bad: &dyn Fn(String) -> ImageError,
) -> Result<(usize, usize, usize), ImageError> {
    let (h, w, c) = match shape {
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
    Ok((h, w, c))
}

pub(crate) fn read_npy(
    path: &Path,
    mut file: std::fs::File,
    budget: MemoryBudget,
) -> Result<Image, ImageError> {
    let bad = |reason| npy_error(path, reason);
    let header = read_header(&mut file, &bad)?;
    let Header {
        fortran, ref shape, ..
    } = header;
    let (h, w, c) = image_shape(path, shape, &bad)?;
    let n = h
        .checked_mul(w)
        .and_then(|v| v.checked_mul(c))
        .ok_or_else(|| bad(format!("shape {shape:?} overflows")))?;
    // float64 values finite but past f32's range would read as infinities
    // and be called non-finite: the first is named as what it is
    let overflow = std::cell::Cell::new(None::<(usize, f64)>);
    let decode = |raw: &[u8], dtype: Dtype, big: bool, out: &mut Vec<f32>| {
        if dtype != Dtype::F64 {
            return decode_f32_values(raw, dtype, big, out);
        }
        // one pass: each value decoded once, checked, narrowed (as
        // `decode_value` narrows it)
        for b in raw.chunks_exact(8) {
            let x = decode_f64(b, dtype, big);
            if overflow.get().is_none() && x.is_finite() && x.abs() > f64::from(f32::MAX) {
                overflow.set(Some((out.len(), x)));
            }
            out.push(x as f32);
        }
    };
    let values = read_values(&mut file, &header, n, budget, 4, &bad, decode)?;
    if let Some((i, x)) = overflow.get() {
        return Err(bad(format!(
            "value {x:e} (element {i} of the file) is beyond the range of the 32-bit floats \
             ifd computes in (3.4e38); rescale the data"
        )));
    }
    // An HxW image is an HxWx1 array: the same reorder.
    let data = to_c_order(values, &[h, w, c], fortran);
    Image::from_vec(w, h, c, data)
}

fn decode_f64(b: &[u8], dtype: Dtype, big: bool) -> f64 {
    match dtype {
        Dtype::F64 => {
            let a = [b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]];
            if big {
                f64::from_be_bytes(a)
            } else {
                f64::from_le_bytes(a)
            }
        }
        _ => f64::from(decode_value(b, dtype, big)),
    }
}

pub(crate) fn decode_value(b: &[u8], dtype: Dtype, big: bool) -> f32 {
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
    let (order, ty) = d.split_at_checked(1)?;
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
    write_preamble(out, &padded_header("<f4", &shape))?;
    write_le(out, image.data(), f32::to_le_bytes)
}

/// `values` as little-endian bytes, encoded a chunk at a time into a buffer
/// and written with one `write_all` per chunk (not one per value).
fn write_le<W: Write, T: Copy, const N: usize>(
    out: &mut W,
    values: &[T],
    bytes: fn(T) -> [u8; N],
) -> Result<(), String> {
    const CHUNK: usize = 4096;
    let mut buf = vec![0u8; CHUNK * N];
    for chunk in values.chunks(CHUNK) {
        let buf = &mut buf[..chunk.len() * N];
        for (b, &v) in buf.chunks_exact_mut(N).zip(chunk) {
            b.copy_from_slice(&bytes(v));
        }
        out.write_all(buf).map_err(|e| e.to_string())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrays_of_any_shape_and_order() {
        let dir = tempfile::tempdir().expect("dir");
        let path = dir.path().join("c.npy");
        let data: Vec<f64> = (0..12).map(f64::from).collect();
        write_npy_f64(&path, &[2, 3, 2], &data).expect("write");
        let a = read_npy_array(&path, MemoryBudget::default_for_machine()).expect("read");
        assert_eq!(
            (a.shape.clone(), a.data.clone()),
            (vec![2, 3, 2], data.clone())
        );
        // The same array in Fortran order, big-endian float32: element
        // (i, j, k) is stored at i + 2 j + 6 k.
        let mut body = Vec::new();
        for k in 0..2 {
            for j in 0..3 {
                for i in 0..2 {
                    body.extend_from_slice(&(data[i * 6 + j * 2 + k] as f32).to_be_bytes());
                }
            }
        }
        let header = "{'descr': '>f4', 'fortran_order': True, 'shape': (2, 3, 2), }\n";
        let fpath = dir.path().join("f.npy");
        let mut bytes = Vec::new();
        write_preamble(&mut bytes, header).expect("preamble");
        bytes.extend_from_slice(&body);
        std::fs::write(&fpath, bytes).expect("write");
        let b = read_npy_array(&fpath, MemoryBudget::default_for_machine()).expect("read");
        assert_eq!((b.shape, b.data), (vec![2, 3, 2], data));
        assert!(write_npy_f64(&path, &[5], &[1.0]).is_err());
    }

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

    /// Float32 and float64 arrays of several write (and read) chunks and a
    /// partial last one come back bit for bit, signed zeros and non-finite values
    /// included (the chunked encoder and the lane-by-lane decoder).
    #[test]
    fn values_round_trip_across_chunks() {
        let (w, h, c) = (101, 47, 3); // 14 241 values: 3 chunks and a part
        let mut img = Image::new(w, h, c).unwrap();
        for (i, v) in img.data_mut().iter_mut().enumerate() {
            *v = match i % 7 {
                0 => -0.0,
                1 => f32::NAN,
                2 => f32::INFINITY,
                _ => (i as f32).sqrt() * if i % 2 == 0 { 1.0 } else { -1e-3 },
            };
        }
        let mut buf = Vec::new();
        write_npy(&mut buf, &img).unwrap();
        let hl = u16::from_le_bytes([buf[8], buf[9]]) as usize;
        let body = &buf[10 + hl..];
        assert_eq!(body.len(), w * h * c * 4);
        let mut back = Vec::new();
        decode_f32_values(body, Dtype::F32, false, &mut back);
        let bits = |d: &[f32]| d.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&back), bits(img.data()));

        let dir = tempfile::tempdir().expect("dir");
        let path = dir.path().join("d.npy");
        // more values than a read chunk, and a partial last chunk
        let n = READ_CHUNK + 1001;
        let data: Vec<f64> = (0..n).map(|i| i as f64 * -0.37).collect();
        write_npy_f64(&path, &[n], &data).expect("write");
        let a = read_npy_array(&path, MemoryBudget::default_for_machine()).expect("read");
        assert_eq!(a.data, data);
    }
}
