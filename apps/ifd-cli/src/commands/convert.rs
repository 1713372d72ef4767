//! `ifd convert IN OUT`.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::input::InputOptions;
use crate::output::{Encoding, write_output};

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
    #[command(flatten)]
    encoding: Encoding,
    #[command(flatten)]
    input: InputOptions,
}

impl Convert {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let img = self.input.read(&self.input_path)?.image;
        write_output(&self.output, &img, &self.encoding.write_options())
    }
}
