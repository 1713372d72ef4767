//! `.npy` images read and written by region, for images larger than memory:
//! [`NpyReader`] reads any rectangle with positioned reads (one per row),
//! [`NpyWriter`] writes rectangles into a float32 file of the whole size,
//! created beside the output and renamed over it only when complete, so an
//! interrupted run leaves no partial output. No memory maps: the workspace
//! denies `unsafe`.
//!
//! The derivation and conventions are documented on [`NpyReader`].

use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::npy::{
    Dtype, decode_value, image_shape, npy_error, padded_header, read_header, write_preamble,
};
use crate::{Image, ImageError};

/// An `HxW` or `HxWxC` `.npy` file read by region.
///
/// Streaming needs C-order arrays (`numpy.ascontiguousarray`); the element
/// types are those of the whole-file reader (float32, float64, uint8 and
/// uint16 read as their values, either byte order).
///
/// ```
/// use ifd_image::{Image, NpyReader, NpyWriter};
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("big.npy");
/// let mut w = NpyWriter::create(&path, 5, 4, 2)?;
/// let tile = Image::from_vec(2, 2, 2, (0..8).map(|v| v as f32).collect())?;
/// w.write_region(3, 2, &tile)?;
/// w.finish()?;
/// let mut r = NpyReader::open(&path, None)?;
/// assert_eq!((r.width(), r.height(), r.channels()), (5, 4, 2));
/// assert_eq!(r.read_region(3, 2, 2, 2)?.data(), tile.data());
/// assert_eq!(r.read_region(0, 0, 1, 1)?.data(), &[0.0, 0.0]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct NpyReader {
    file: File,
    path: PathBuf,
    dtype: Dtype,
    big_endian: bool,
    width: usize,
    height: usize,
    channels: usize,
    data_start: u64,
    replace_non_finite: Option<f32>,
}

impl NpyReader {
    /// Opens `path` and checks its header and length. NaN and infinite
    /// samples are refused when regions are read, unless
    /// `replace_non_finite` gives a value for them.
    ///
    /// # Errors
    /// A missing or unreadable file, a bad header, a Fortran-ordered or
    /// non-image array, a file shorter than its header declares.
    pub fn open(path: &Path, replace_non_finite: Option<f32>) -> Result<Self, ImageError> {
        let mut file = crate::files::open(path)?;
        let bad = |reason| npy_error(path, reason);
        let header = read_header(&mut file, &bad)?;
        if header.fortran {
            return Err(bad(
                "a Fortran-ordered array cannot be read by region (tiled filtering); \
                 save it with numpy.save(path, numpy.ascontiguousarray(a))"
                    .into(),
            ));
        }
        let (height, width, channels) = image_shape(path, &header.shape, &bad)?;
        let data_start = file
            .stream_position()
            .map_err(|e| bad(format!("unreadable: {e}")))?;
        let need = (height as u64)
            .checked_mul(width as u64)
            .and_then(|n| n.checked_mul(channels as u64))
            .and_then(|n| n.checked_mul(header.dtype.size() as u64))
            .ok_or_else(|| bad(format!("shape {:?} overflows", header.shape)))?;
        let len = file
            .metadata()
            .map_err(|e| bad(format!("unreadable: {e}")))?
            .len();
        if len < data_start + need {
            return Err(bad(format!(
                "truncated: shape {:?} needs {need} data bytes, the file has {}",
                header.shape,
                len.saturating_sub(data_start)
            )));
        }
        Ok(Self {
            file,
            path: path.to_path_buf(),
            dtype: header.dtype,
            big_endian: header.big_endian,
            width,
            height,
            channels,
            data_start,
            replace_non_finite,
        })
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Channels.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The file.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The `width x height` rectangle at `(x0, y0)`, as `f32`.
    ///
    /// # Errors
    /// A rectangle outside the image, a failed read, NaN or infinite
    /// samples (unless replaced), naming the file and the pixel.
    pub fn read_region(
        &mut self,
        x0: usize,
        y0: usize,
        width: usize,
        height: usize,
    ) -> Result<Image, ImageError> {
        let bad = |reason| npy_error(&self.path, reason);
        if width == 0 || height == 0 || x0 + width > self.width || y0 + height > self.height {
            return Err(bad(format!(
                "region {width}x{height} at ({x0}, {y0}) is not inside the {}x{} image",
                self.width, self.height
            )));
        }
        let size = self.dtype.size();
        let c = self.channels;
        let mut row = vec![0u8; width * c * size];
        let mut data = Vec::with_capacity(width * height * c);
        for y in y0..y0 + height {
            let offset = self.data_start + ((y * self.width + x0) * c * size) as u64;
            self.file
                .seek(SeekFrom::Start(offset))
                .and_then(|_| self.file.read_exact(&mut row))
                .map_err(|e| bad(format!("reading row {y}: {e}")))?;
            for (i, b) in row.chunks_exact(size).enumerate() {
                let mut v = decode_value(b, self.dtype, self.big_endian);
                if !v.is_finite() {
                    match self.replace_non_finite {
                        Some(r) => v = r,
                        None => {
                            return Err(bad(format!(
                                "non-finite value {v} at x={}, y={y}, channel {}; pass \
                                 --replace-nonfinite to replace such values",
                                x0 + i / c,
                                i % c
                            )));
                        }
                    }
                }
                data.push(v);
            }
        }
        Image::from_vec(width, height, c, data)
    }
}

/// A float32 `HxW` or `HxWxC` `.npy` file written by region.
#[derive(Debug)]
pub struct NpyWriter {
    tmp: tempfile::NamedTempFile,
    /// Registered for [`crate::remove_pending_outputs`] while it lives.
    _pending: crate::files::Pending,
    path: PathBuf,
    width: usize,
    height: usize,
    channels: usize,
    data_start: u64,
}

impl NpyWriter {
    /// Starts a `width x height x channels` float32 file at `path` (an `HxW`
    /// array for one channel), as a temporary file in its folder, filled
    /// with zeros until regions are written.
    ///
    /// # Errors
    /// A missing folder, a failed write.
    pub fn create(
        path: &Path,
        width: usize,
        height: usize,
        channels: usize,
    ) -> Result<Self, ImageError> {
        let werr = |reason: String| ImageError::Write {
            path: path.to_path_buf(),
            reason,
        };
        if let Some(problem) = crate::files::output_folder_problem(path) {
            return Err(werr(problem));
        }
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let mut builder = tempfile::Builder::new();
        builder.prefix(".ifd-tmp-");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let tmp = builder
            .tempfile_in(&dir)
            .map_err(|e| werr(format!("cannot create a file in {}: {e}", dir.display())))?;
        let shape = if channels == 1 {
            format!("({height}, {width})")
        } else {
            format!("({height}, {width}, {channels})")
        };
        let header = padded_header("<f4", &shape);
        {
            let mut out = BufWriter::new(tmp.as_file());
            write_preamble(&mut out, &header).map_err(werr)?;
            out.flush().map_err(|e| werr(e.to_string()))?;
        }
        let data_start = tmp
            .as_file()
            .stream_position()
            .map_err(|e| werr(e.to_string()))?;
        let total = data_start + (width * height * channels * 4) as u64;
        tmp.as_file()
            .set_len(total)
            .map_err(|e| werr(format!("cannot size the file to {total} bytes: {e}")))?;
        Ok(Self {
            _pending: crate::files::Pending::new(tmp.path()),
            tmp,
            path: path.to_path_buf(),
            width,
            height,
            channels,
            data_start,
        })
    }

    /// Writes `tile` with its top-left corner at `(x0, y0)`.
    ///
    /// # Errors
    /// A tile outside the image or with other channels, a failed write.
    pub fn write_region(&mut self, x0: usize, y0: usize, tile: &Image) -> Result<(), ImageError> {
        let werr = |reason: String| ImageError::Write {
            path: self.path.clone(),
            reason,
        };
        if tile.channels() != self.channels
            || x0 + tile.width() > self.width
            || y0 + tile.height() > self.height
        {
            return Err(werr(format!(
                "a {}x{}x{} tile at ({x0}, {y0}) does not fit the {}x{}x{} image",
                tile.width(),
                tile.height(),
                tile.channels(),
                self.width,
                self.height,
                self.channels
            )));
        }
        let c = self.channels;
        let mut bytes = Vec::with_capacity(tile.width() * c * 4);
        let mut file = self.tmp.as_file();
        for (j, row) in tile.data().chunks_exact(tile.width() * c).enumerate() {
            bytes.clear();
            for v in row {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
            let offset = self.data_start + (((y0 + j) * self.width + x0) * c * 4) as u64;
            file.seek(SeekFrom::Start(offset))
                .and_then(|_| file.write_all(&bytes))
                .map_err(|e| werr(e.to_string()))?;
        }
        Ok(())
    }

    /// Flushes the file to disk and renames it over the output.
    ///
    /// # Errors
    /// A failed sync or rename.
    pub fn finish(self) -> Result<(), ImageError> {
        let werr = |reason: String| ImageError::Write {
            path: self.path.clone(),
            reason,
        };
        self.tmp
            .as_file()
            .sync_all()
            .map_err(|e| werr(e.to_string()))?;
        self.tmp
            .persist(&self.path)
            .map_err(|e| werr(e.error.to_string()))?;
        Ok(())
    }
}
