//! `ifd convert IN OUT`.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use ifd_image::{BitDepth, WriteOptions};

use crate::input::{InputOptions, write_output};

/// Convert an image between formats (PNG, JPEG, TIFF, EXR, HDR, NPY).
///
/// Values are carried as linear floats: 8/16-bit inputs map to [0, 1];
/// writing an 8/16-bit format clamps to [0, 1], rounds, and reports how many
/// values were clipped.
#[derive(Debug, Args)]
pub struct Convert {
    /// Input image.
    input_path: PathBuf,
    /// Output image; the format follows the extension.
    output: PathBuf,
    /// Write 16-bit PNG/TIFF instead of 8-bit.
    #[arg(long)]
    sixteen_bit: bool,
    /// Encode the output with the sRGB transfer function (8/16-bit formats).
    #[arg(long)]
    srgb_out: bool,
    #[command(flatten)]
    input: InputOptions,
}

impl Convert {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let img = self.input.read(&self.input_path)?.image;
        let opts = WriteOptions {
            bit_depth: if self.sixteen_bit {
                BitDepth::Sixteen
            } else {
                BitDepth::Eight
            },
            srgb_encode: self.srgb_out,
            jpeg_quality: None,
        };
        write_output(&self.output, &img, &opts)
    }
}
