//! Options shared by every command that writes an image, flattened into
//! each (`-o/--output`, `--sixteen-bit`, `--srgb-out`), and the one writer
//! they all go through.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;
use ifd_image::{BitDepth, WriteOptions};

/// How an output image is encoded (8/16-bit formats only; EXR, HDR and
/// `.npy` keep floats).
#[derive(Debug, Args, Clone, Copy)]
pub struct Encoding {
    /// Write 16-bit PNG/TIFF instead of 8-bit.
    #[arg(long)]
    pub sixteen_bit: bool,
    /// Encode 8/16-bit outputs with the sRGB transfer function (default:
    /// values in [0, 1] are stored linearly).
    #[arg(long)]
    pub srgb_out: bool,
}

impl Encoding {
    /// The image crate's write options.
    pub fn write_options(self) -> WriteOptions {
        WriteOptions {
            bit_depth: if self.sixteen_bit {
                BitDepth::Sixteen
            } else {
                BitDepth::Eight
            },
            srgb_encode: self.srgb_out,
            ..WriteOptions::default()
        }
    }
}

/// The output image of a command and its encoding.
#[derive(Debug, Args, Clone)]
pub struct ImageOutput {
    /// Output image (.png, .tif, .exr, .hdr, .npy, .jpg); the format follows the extension.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    #[command(flatten)]
    pub encoding: Encoding,
}

impl ImageOutput {
    /// Writes `image` to the output, atomically.
    pub fn write(&self, image: &ifd_image::Image) -> Result<()> {
        write_output(&self.output, image, &self.encoding.write_options())
    }
}

/// Writes a text file (a table, a report, a page) atomically: on failure the
/// error names the file and nothing is left at `path`.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    use std::io::Write as _;
    ifd_image::atomic_write(path, |w| {
        w.write_all(text.as_bytes()).map_err(|e| e.to_string())
    })?;
    Ok(())
}

/// Writes an image atomically, reporting clipped samples on stderr.
#[expect(
    clippy::trivially_copy_pass_by_ref,
    reason = "write options may grow; every command passes a reference"
)]
pub fn write_output(path: &Path, image: &ifd_image::Image, opts: &WriteOptions) -> Result<()> {
    let report = ifd_image::write_image(path, image, opts)?;
    if report.clipped > 0 {
        eprintln!(
            "note: {}: clipped {} of {} values to [0, 1]",
            path.display(),
            report.clipped,
            report.samples
        );
    }
    Ok(())
}

/// Refuses an output image path before any work: an unknown extension, or a
/// folder that does not exist (or is a file). Writing still checks again.
pub fn check_output_path(path: &Path) -> Result<()> {
    ifd_image::FileFormat::from_path(path)?;
    check_output_folder(path)
}

/// Refuses, before any work, a data output (coefficients, SH values, a
/// field of angles) whose name does not end in `.npy`: it is written as
/// `.npy` whatever the name says, and an image format would clip it. Also
/// refuses a folder that does not exist.
pub fn check_npy_output(path: &Path, option: &str, what: &str) -> Result<()> {
    let npy = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    if !npy {
        anyhow::bail!(
            "{option} {}: {what} is data, written as .npy only",
            path.display()
        );
    }
    check_output_folder(path)
}

/// Refuses an output file (of any kind) whose folder does not exist or is a
/// file, before any work.
pub fn check_output_folder(path: &Path) -> Result<()> {
    if let Some(why) = ifd_image::output_folder_problem(path) {
        anyhow::bail!("{}: {why}", path.display());
    }
    Ok(())
}
