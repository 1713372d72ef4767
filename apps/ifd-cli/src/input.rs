//! Options shared by every command that reads images.

use std::path::Path;

use anyhow::Result;
use clap::Args;
use ifd_image::{LoadedImage, MemoryBudget, NonFinitePolicy, ReadOptions};

/// How input images are read.
#[derive(Debug, Args, Clone)]
pub struct InputOptions {
    /// Decode 8/16-bit inputs from sRGB to linear light (default: values map linearly to [0, 1]).
    #[arg(long)]
    pub srgb: bool,
    /// Replace NaN/Inf input values by this value (and report how many) instead of refusing the file.
    #[arg(long, value_name = "VALUE", value_parser = finite_f32)]
    pub replace_nonfinite: Option<f32>,
    /// Memory budget for one image, in MiB (default: 75% of physical memory).
    #[arg(long, value_name = "MIB")]
    pub memory_budget: Option<u64>,
}

/// A finite 32-bit float (NaN, infinities and values beyond `f32::MAX`
/// refused): `--replace-nonfinite` must not put back what it replaces.
fn finite_f32(text: &str) -> Result<f32, String> {
    match text.trim().parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => {
            Err("must be a finite 32-bit float (the value that replaces NaN and infinities)".into())
        }
        Err(e) => Err(e.to_string()),
    }
}

impl InputOptions {
    fn read_options(&self) -> ReadOptions {
        ReadOptions {
            srgb_decode: self.srgb,
            non_finite: self
                .replace_nonfinite
                .map_or(NonFinitePolicy::Error, NonFinitePolicy::Replace),
            budget: self.budget(),
        }
    }

    /// The memory budget for one image (`--memory-budget`, else 75% of physical memory).
    pub fn budget(&self) -> MemoryBudget {
        self.memory_budget
            .map_or_else(MemoryBudget::default_for_machine, |m| {
                MemoryBudget::bytes(m.saturating_mul(1 << 20))
            })
    }

    /// Reads an image, reporting replaced non-finite values on stderr.
    pub fn read(&self, path: &Path) -> Result<LoadedImage> {
        Self::read_with(path, &self.read_options())
    }

    /// Reads with `opts`, reporting replaced non-finite values on stderr.
    fn read_with(path: &Path, opts: &ReadOptions) -> Result<LoadedImage> {
        // The error already names the file.
        let loaded = ifd_image::read_image(path, opts)?;
        if loaded.replaced_non_finite > 0 {
            eprintln!(
                "note: {}: replaced {} non-finite values",
                path.display(),
                loaded.replaced_non_finite
            );
        }
        Ok(loaded)
    }

    /// Reads a parameter map (angles, scales): values as stored, with no
    /// range mapping or sRGB decoding. `.npy` (float or integer dtypes, read
    /// as their values) and floating-point EXR/TIFF/HDR are accepted (the
    /// image crate reads float files as RGB(A) only, so a single-channel map
    /// must be `.npy`); integer
    /// image formats (PNG, JPEG, 8/16-bit TIFF), which images map to
    /// `[0, 1]`, are refused with a message saying how to write a map.
    pub fn read_map(&self, path: &Path, what: &str) -> Result<ifd_image::Image> {
        let opts = ReadOptions {
            srgb_decode: false,
            ..self.read_options()
        };
        let loaded = Self::read_with(path, &opts)?;
        if let Some(bits) = loaded.integer_bits {
            anyhow::bail!(
                "{what} {}: a {bits}-bit {} stores integers that are read as image values in \
                 [0, 1] (45 would become {:.4}), not as data; write the map as .npy \
                 (numpy.save('map.npy', a.astype('float32')))",
                path.display(),
                loaded.format.name(),
                45.0 / f64::from((1u32 << bits) - 1)
            );
        }
        Ok(loaded.image)
    }
}

/// Parses an image size `WxH` given to `option`: positive integers up to
/// 16384 each (larger images are also checked against the memory budget by
/// the commands).
pub fn parse_size(text: &str, option: &str) -> Result<(usize, usize)> {
    let parsed = text.split_once(['x', 'X']).and_then(|(w, h)| {
        Some((
            w.trim().parse::<usize>().ok()?,
            h.trim().parse::<usize>().ok()?,
        ))
    });
    match parsed {
        Some((w, h)) if (1..=16384).contains(&w) && (1..=16384).contains(&h) => Ok((w, h)),
        _ => anyhow::bail!(
            "{option} {text:?}: expected WxH with integers in 1..=16384, e.g. 512x256"
        ),
    }
}
