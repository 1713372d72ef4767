//! Reading and writing image files: PNG, JPEG, TIFF (8 and 16 bit), OpenEXR
//! (all compressions the `exr` crate decodes, DWAB included), Radiance `.hdr`
//! and NumPy `.npy`.
//!
//! The format is chosen by the file extension. Integer samples map to `[0, 1]`
//! (`v / 255`, `v / 65535`) with no gamma change unless
//! [`ReadOptions::srgb_decode`] is set. Writes are atomic: the encoded file is
//! written to a temporary file in the destination folder and renamed over the
//! destination only once complete, so a failed run never leaves a half-written
//! output.

use std::io::{BufRead, BufReader, Cursor, Read, Seek};
use std::path::Path;

use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader};

use crate::budget::MemoryBudget;
use crate::files::{atomic_write, open};
use crate::{Image, ImageError, npy};

/// The file formats ifd reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileFormat {
    /// Portable Network Graphics, 8 or 16 bit.
    Png,
    /// JPEG, 8 bit.
    Jpeg,
    /// TIFF, 8 or 16 bit.
    Tiff,
    /// OpenEXR, 32-bit float.
    Exr,
    /// Radiance RGBE.
    Hdr,
    /// NumPy array, float32 or float64, `HxW` or `HxWxC`.
    Npy,
}

impl FileFormat {
    /// The format named by a path's extension.
    ///
    /// # Errors
    /// [`ImageError::UnsupportedExtension`] for any other extension.
    pub fn from_path(path: &Path) -> Result<Self, ImageError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        Ok(match ext.as_str() {
            "png" => Self::Png,
            "jpg" | "jpeg" => Self::Jpeg,
            "tif" | "tiff" => Self::Tiff,
            "exr" => Self::Exr,
            "hdr" => Self::Hdr,
            "npy" => Self::Npy,
            _ => {
                return Err(ImageError::UnsupportedExtension {
                    path: path.to_path_buf(),
                    ext,
                });
            }
        })
    }

    /// A short name for messages.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Png => "PNG",
            Self::Jpeg => "JPEG",
            Self::Tiff => "TIFF",
            Self::Exr => "OpenEXR",
            Self::Hdr => "Radiance HDR",
            Self::Npy => "NumPy",
        }
    }

    fn image_format(self) -> Option<ImageFormat> {
        match self {
            Self::Png => Some(ImageFormat::Png),
            Self::Jpeg => Some(ImageFormat::Jpeg),
            Self::Tiff => Some(ImageFormat::Tiff),
            Self::Exr => Some(ImageFormat::OpenExr),
            Self::Hdr => Some(ImageFormat::Hdr),
            Self::Npy => None,
        }
    }
}

/// What to do with NaN and infinite samples found when reading.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum NonFinitePolicy {
    /// Refuse the file with [`ImageError::NonFinite`] (the default).
    #[default]
    Error,
    /// Replace each non-finite sample by this value and count them.
    Replace(f32),
}

/// Options for [`read_image`].
#[derive(Clone, Copy, Debug)]
pub struct ReadOptions {
    /// Decode 8/16-bit sRGB-encoded values to linear light (the sRGB transfer
    /// function). Off by default: values map linearly to `[0, 1]`.
    pub srgb_decode: bool,
    /// NaN/Inf handling.
    pub non_finite: NonFinitePolicy,
    /// Largest amount of memory an image may need.
    pub budget: MemoryBudget,
}

impl Default for ReadOptions {
    fn default() -> Self {
        Self {
            srgb_decode: false,
            non_finite: NonFinitePolicy::Error,
            budget: MemoryBudget::default_for_machine(),
        }
    }
}

/// An image read from a file, with what is known about its source.
#[derive(Clone, Debug)]
pub struct LoadedImage {
    /// The samples.
    pub image: Image,
    /// The file's format.
    pub format: FileFormat,
    /// Bits per sample of the file when it stored integers (8 or 16), `None`
    /// for floating-point files.
    pub integer_bits: Option<u8>,
    /// How many non-finite samples were replaced ([`NonFinitePolicy::Replace`]).
    pub replaced_non_finite: usize,
}

/// Reads an image file with default options.
///
/// ```
/// let img = ifd_image::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata/camera.png"))?;
/// assert_eq!((img.width(), img.height(), img.channels()), (512, 512, 1));
/// # Ok::<(), ifd_image::ImageError>(())
/// ```
///
/// # Errors
/// See [`read_image`].
pub fn read(path: impl AsRef<Path>) -> Result<Image, ImageError> {
    Ok(read_image(path.as_ref(), &ReadOptions::default())?.image)
}

/// Reads an image file.
///
/// # Errors
/// A missing file, an unsupported extension, a truncated or corrupt file, a
/// zero-sized image, dimensions beyond the memory budget, and (with
/// [`NonFinitePolicy::Error`]) NaN or infinite samples each give their own
/// [`ImageError`] naming the file.
pub fn read_image(path: &Path, opts: &ReadOptions) -> Result<LoadedImage, ImageError> {
    let format = FileFormat::from_path(path)?;
    let file = open(path)?;
    let decoded = match format.image_format() {
        None => npy::read_npy(path, file, opts.budget).map(|image| (image, None)),
        Some(fmt) => decode_with_image_crate(path, BufReader::new(file), fmt, format, opts),
    };
    finish(path, format, decoded, opts)
}

/// Reads an image held in memory (a texture embedded in a container file,
/// such as a glTF asset's PNG or JPEG images), in the format given, with the
/// checks and options of [`read_image`]: the memory budget checked from the
/// header before the samples are decoded, truncated JPEG scans refused,
/// [`ReadOptions::srgb_decode`] and the non-finite policy. `name` stands
/// for the file in every error message (e.g. `model.glb: image 2
/// (image/png)`). NumPy arrays are read from files only.
///
/// ```
/// use ifd_image::{FileFormat, Image, ReadOptions, read_image_bytes, write};
/// let dir = tempfile::tempdir()?;
/// let file = dir.path().join("a.png");
/// write(&file, &Image::from_vec(2, 1, 1, vec![0.0, 1.0])?)?;
/// let bytes = std::fs::read(&file)?;
/// let name = std::path::Path::new("model.glb: image 0 (image/png)");
/// let img = read_image_bytes(&bytes, name, FileFormat::Png, &ReadOptions::default())?;
/// assert_eq!(img.image.data(), &[0.0, 1.0]);
/// let e = read_image_bytes(&bytes[..20], name, FileFormat::Png, &ReadOptions::default());
/// assert!(e.unwrap_err().to_string().starts_with("model.glb: image 0 (image/png): cannot decode PNG"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`read_image`], each naming `name`; [`ImageError::Decode`] for
/// [`FileFormat::Npy`].
pub fn read_image_bytes(
    bytes: &[u8],
    name: &Path,
    format: FileFormat,
    opts: &ReadOptions,
) -> Result<LoadedImage, ImageError> {
    let decoded = match format.image_format() {
        None => Err(ImageError::Decode {
            path: name.to_path_buf(),
            format: format.name(),
            reason: "NumPy images are read from files only".into(),
        }),
        Some(fmt) => decode_with_image_crate(name, Cursor::new(bytes), fmt, format, opts),
    };
    finish(name, format, decoded, opts)
}

/// Names the file in the errors raised without it and applies the
/// non-finite policy: the last step of [`read_image`] and [`read_image_bytes`].
fn finish(
    path: &Path,
    format: FileFormat,
    decoded: Result<(Image, Option<u8>), ImageError>,
    opts: &ReadOptions,
) -> Result<LoadedImage, ImageError> {
    // The budget and shape checks do not know the file: name it here.
    let (mut image, integer_bits) = decoded.map_err(|e| e.in_file(path))?;
    let replaced_non_finite = handle_non_finite(path, &mut image, opts.non_finite)?;
    Ok(LoadedImage {
        image,
        format,
        integer_bits,
        replaced_non_finite,
    })
}

/// The decoder's message, with "truncated" said plainly: decoders that read
/// past the end of a file report the bare I/O error ("failed to fill whole
/// buffer").
fn decode_reason(e: &image::ImageError) -> String {
    let eof = match e {
        image::ImageError::IoError(io) => io.kind() == std::io::ErrorKind::UnexpectedEof,
        _ => false,
    };
    let text = e.to_string();
    if eof || text.contains("failed to fill whole buffer") {
        format!("truncated: the file ends before its image data does ({text})")
    } else {
        text
    }
}

/// JPEG decoders fill a truncated scan with grey and succeed; a file whose
/// last scan (the final `FF DA` marker) is not followed by the end-of-image
/// marker `FF D9` is refused as truncated instead. Entropy-coded data cannot
/// contain `FF D9` (a data `FF` is stuffed as `FF 00`), and an embedded EXIF
/// thumbnail ends before the main image's scans.
fn check_jpeg_complete<R: Read + Seek>(path: &Path, reader: &mut R) -> Result<(), ImageError> {
    let mut bytes = Vec::new();
    reader
        .read_to_end(&mut bytes)
        .and_then(|_| reader.rewind())
        .map_err(|e| ImageError::Io {
            path: path.to_path_buf(),
            error: e,
        })?;
    let last_scan = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]);
    let complete = match last_scan {
        Some(i) => bytes[i..].windows(2).any(|w| w == [0xFF, 0xD9]),
        // No scan at all: the decoder says what is wrong.
        None => true,
    };
    if complete {
        Ok(())
    } else {
        Err(ImageError::Decode {
            path: path.to_path_buf(),
            format: "JPEG",
            reason: "truncated: no end-of-image marker (FF D9) after the last scan".into(),
        })
    }
}

/// Decodes what `reader` holds (positioned at its start) as `format`; `path`
/// names it in errors (a file, or a part of one).
fn decode_with_image_crate<R: BufRead + Seek>(
    path: &Path,
    mut reader: R,
    fmt: ImageFormat,
    format: FileFormat,
    opts: &ReadOptions,
) -> Result<(Image, Option<u8>), ImageError> {
    let decode_err = |e: image::ImageError| ImageError::Decode {
        path: path.to_path_buf(),
        format: format.name(),
        reason: decode_reason(&e),
    };
    if format == FileFormat::Jpeg {
        check_jpeg_complete(path, &mut reader)?;
    }
    let mut reader = ImageReader::with_format(reader, fmt);
    // Our own budget check below replaces the crate's fixed default limits.
    reader.no_limits();
    let decoder = reader.into_decoder().map_err(decode_err)?;
    let (w, h) = decoder.dimensions();
    let color = decoder.color_type();
    let channels = usize::from(color.channel_count());
    if w == 0 || h == 0 {
        return Err(ImageError::Empty {
            path: Some(path.to_path_buf()),
            width: w as usize,
            height: h as usize,
            channels,
        });
    }
    // The decoder's own buffer plus our f32 copy.
    let samples = u64::from(w) * u64::from(h) * channels as u64;
    let per_sample = u64::from(color.bytes_per_pixel()) / channels as u64 + 4;
    opts.budget.check(samples.saturating_mul(per_sample))?;
    let dynimg = DynamicImage::from_decoder(decoder).map_err(decode_err)?;
    let (w, h) = (w as usize, h as usize);
    let srgb = opts.srgb_decode;
    let map8 = |v: u8| {
        let x = f32::from(v) / 255.0;
        if srgb { srgb_to_linear(x) } else { x }
    };
    let map16 = |v: u16| {
        let x = f32::from(v) / 65535.0;
        if srgb { srgb_to_linear(x) } else { x }
    };
    let (data, channels, bits): (Vec<f32>, usize, Option<u8>) = match dynimg {
        DynamicImage::ImageLuma8(b) => (b.into_raw().into_iter().map(map8).collect(), 1, Some(8)),
        DynamicImage::ImageLumaA8(b) => (b.into_raw().into_iter().map(map8).collect(), 2, Some(8)),
        DynamicImage::ImageRgb8(b) => (b.into_raw().into_iter().map(map8).collect(), 3, Some(8)),
        DynamicImage::ImageRgba8(b) => (b.into_raw().into_iter().map(map8).collect(), 4, Some(8)),
        DynamicImage::ImageLuma16(b) => {
            (b.into_raw().into_iter().map(map16).collect(), 1, Some(16))
        }
        DynamicImage::ImageLumaA16(b) => {
            (b.into_raw().into_iter().map(map16).collect(), 2, Some(16))
        }
        DynamicImage::ImageRgb16(b) => (b.into_raw().into_iter().map(map16).collect(), 3, Some(16)),
        DynamicImage::ImageRgba16(b) => {
            (b.into_raw().into_iter().map(map16).collect(), 4, Some(16))
        }
        DynamicImage::ImageRgb32F(b) => (b.into_raw(), 3, None),
        DynamicImage::ImageRgba32F(b) => (b.into_raw(), 4, None),
        other => (other.to_rgba32f().into_raw(), 4, None),
    };
    Ok((Image::from_vec(w, h, channels, data)?, bits))
}

fn handle_non_finite(
    path: &Path,
    image: &mut Image,
    policy: NonFinitePolicy,
) -> Result<usize, ImageError> {
    let count = image.count_non_finite();
    if count == 0 {
        return Ok(0);
    }
    match policy {
        NonFinitePolicy::Error => {
            let first = image
                .data()
                .iter()
                .position(|v| !v.is_finite())
                .unwrap_or(0);
            let c = image.channels();
            let w = image.width();
            Err(ImageError::NonFinite {
                path: path.to_path_buf(),
                count,
                x: (first / c) % w,
                y: first / c / w,
                channel: first % c,
            })
        }
        NonFinitePolicy::Replace(value) => {
            for v in image.data_mut() {
                if !v.is_finite() {
                    *v = value;
                }
            }
            Ok(count)
        }
    }
}

/// The sRGB electro-optical transfer function: encoded `[0, 1]` to linear.
#[must_use]
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The inverse of [`srgb_to_linear`].
#[must_use]
pub fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Sample depth for integer formats.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BitDepth {
    /// 8 bits per sample (the default for PNG, TIFF; the only one for JPEG).
    #[default]
    Eight,
    /// 16 bits per sample (PNG, TIFF).
    Sixteen,
}

/// Options for [`write_image`].
#[derive(Clone, Copy, Debug, Default)]
pub struct WriteOptions {
    /// Sample depth for PNG and TIFF.
    pub bit_depth: BitDepth,
    /// Encode linear values with the sRGB transfer function before quantising.
    pub srgb_encode: bool,
    /// JPEG quality, 1-100 (default 95).
    pub jpeg_quality: Option<u8>,
    /// Write NaN and infinite samples to the float formats that store them
    /// (EXR, NPY) instead of refusing the image: for test inputs that must
    /// hold them. Default false: a result with such samples is wrong.
    pub allow_non_finite: bool,
}

/// What [`write_image`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WriteReport {
    /// Samples outside `[0, 1]` that an integer format clamped.
    pub clipped: usize,
    /// Total samples written.
    pub samples: usize,
}

/// Writes an image with default options (8-bit for integer formats).
///
/// # Errors
/// See [`write_image`].
pub fn write(path: impl AsRef<Path>, image: &Image) -> Result<WriteReport, ImageError> {
    write_image(path.as_ref(), image, &WriteOptions::default())
}

/// Writes an image, atomically (temporary file in the same folder, then rename).
///
/// Integer formats clamp to `[0, 1]`, round, and report how many samples were
/// clipped. Channel counts: 1 (gray), 2 (gray + alpha), 3 (RGB) or 4 (RGBA) for
/// PNG/TIFF; 1 or 3 for JPEG; 1, 3 or 4 for EXR (gray is written as RGB); 1 or
/// 3 for HDR (gray as RGB); any count for NPY.
///
/// # Errors
/// Unsupported extension or channel count, NaN or infinite samples (unless
/// [`WriteOptions::allow_non_finite`], for EXR and NPY), values beyond what
/// RGBE holds or negative ones for HDR, and any I/O or encoder failure.
pub fn write_image(
    path: &Path,
    image: &Image,
    opts: &WriteOptions,
) -> Result<WriteReport, ImageError> {
    let format = FileFormat::from_path(path)?;
    let c = image.channels();
    let bad_channels = || ImageError::Write {
        path: path.to_path_buf(),
        reason: format!(
            "{} cannot store {c} channels (write .npy for arbitrary channel counts)",
            format.name()
        ),
    };
    let samples = image.data().len();
    let mut clipped = 0;
    // No format gets NaN or infinite samples: a result that has them is
    // wrong (a value or parameter overflowed 32-bit floats), whatever
    // could store it.
    if !(opts.allow_non_finite && matches!(format, FileFormat::Exr | FileFormat::Npy)) {
        check_finite(path, image)?;
    }
    let payload: Payload = match format {
        FileFormat::Npy => Payload::Npy,
        FileFormat::Exr | FileFormat::Hdr => {
            if format == FileFormat::Hdr {
                if let Some(&v) = image.data().iter().find(|&&v| v >= MAX_RGBE) {
                    return Err(ImageError::Write {
                        path: path.to_path_buf(),
                        reason: format!(
                            "Radiance HDR stores values up to {MAX_RGBE:e}, and the image has \
                             {v:e} (write .exr or .npy)"
                        ),
                    });
                }
                if image.data().iter().any(|&v| v < 0.0) {
                    return Err(ImageError::Write {
                        path: path.to_path_buf(),
                        reason: "Radiance HDR cannot store negative values (write .exr or .npy)"
                            .into(),
                    });
                }
            }
            let w = image.width() as u32;
            let h = image.height() as u32;
            let dyn_img = match (c, format) {
                (1 | 3, _) => {
                    let rgb: Vec<f32> = if c == 1 {
                        image.data().iter().flat_map(|&v| [v, v, v]).collect()
                    } else {
                        image.data().to_vec()
                    };
                    image::Rgb32FImage::from_raw(w, h, rgb).map(DynamicImage::ImageRgb32F)
                }
                (4, FileFormat::Exr) => image::Rgba32FImage::from_raw(w, h, image.data().to_vec())
                    .map(DynamicImage::ImageRgba32F),
                _ => return Err(bad_channels()),
            };
            Payload::Image(dyn_img.ok_or_else(bad_channels)?)
        }
        FileFormat::Png | FileFormat::Tiff | FileFormat::Jpeg => {
            if format == FileFormat::Jpeg && !(c == 1 || c == 3) {
                return Err(bad_channels());
            }
            if c > 4 {
                return Err(bad_channels());
            }
            let sixteen = opts.bit_depth == BitDepth::Sixteen && format != FileFormat::Jpeg;
            let scale = if sixteen { 65535.0 } else { 255.0 };
            let quantised: Vec<u16> = image
                .data()
                .iter()
                .map(|&v| {
                    if !(0.0..=1.0).contains(&v) {
                        clipped += 1;
                    }
                    let v = v.clamp(0.0, 1.0);
                    let v = if opts.srgb_encode {
                        linear_to_srgb(v)
                    } else {
                        v
                    };
                    (v * scale).round() as u16
                })
                .collect();
            Payload::Image(
                to_dynamic(image.width(), image.height(), c, sixteen, quantised)
                    .ok_or_else(bad_channels)?,
            )
        }
    };
    atomic_write(path, |file| match &payload {
        Payload::Npy => npy::write_npy(file, image),
        Payload::Image(img) => {
            if format == FileFormat::Jpeg {
                let q = opts.jpeg_quality.unwrap_or(95).clamp(1, 100);
                let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(file, q);
                img.write_with_encoder(enc).map_err(|e| e.to_string())
            } else {
                let fmt = format.image_format().ok_or("no encoder")?;
                img.write_to(file, fmt).map_err(|e| e.to_string())
            }
        }
    })?;
    Ok(WriteReport { clipped, samples })
}

enum Payload {
    Npy,
    Image(DynamicImage),
}

fn to_dynamic(w: usize, h: usize, c: usize, sixteen: bool, q: Vec<u16>) -> Option<DynamicImage> {
    let (w, h) = (w as u32, h as u32);
    if sixteen {
        match c {
            1 => image::ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageLuma16),
            2 => image::ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageLumaA16),
            3 => image::ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageRgb16),
            4 => image::ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageRgba16),
            _ => None,
        }
    } else {
        let q: Vec<u8> = q.into_iter().map(|v| v as u8).collect();
        match c {
            1 => image::ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageLuma8),
            2 => image::ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageLumaA8),
            3 => image::ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageRgb8),
            4 => image::ImageBuffer::from_raw(w, h, q).map(DynamicImage::ImageRgba8),
            _ => None,
        }
    }
}

/// The largest value a Radiance RGBE pixel holds: a mantissa of 255/256 at
/// the largest exponent, `2^127`.
const MAX_RGBE: f32 = 1.69e38;

/// Refuses an image with NaN or infinite samples, naming the first.
fn check_finite(path: &Path, image: &Image) -> Result<(), ImageError> {
    let n = image.count_non_finite();
    if n > 0 {
        let c = image.channels();
        let i = image
            .data()
            .iter()
            .position(|v| !v.is_finite())
            .unwrap_or(0);
        let (x, y, channel) = ((i / c) % image.width(), i / c / image.width(), i % c);
        return Err(ImageError::Write {
            path: path.to_path_buf(),
            reason: format!(
                "the result has {n} non-finite (NaN or infinite) values, first at x={x}, y={y}, \
                 channel {channel}: nothing written (an input or parameter too large for 32-bit \
                 floats?)"
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
#[path = "io_tests.rs"]
mod tests;
