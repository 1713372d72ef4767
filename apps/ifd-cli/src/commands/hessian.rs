//! `ifd hessian IMAGE --sigma S -o h.npy`.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use ifd_planar::Border;
use ifd_smooth::{HessianBank, hessian_image};

use crate::input::InputOptions;
use crate::output::write_output;

/// Hessian of an image at scale sigma, computed with IFD.
///
/// Writes an HxWx3 float32 array with channels (Hxx, Hxy, Hyy), x = column,
/// y = row, not scale-normalised (multiply by sigma^2 for that); colour images
/// give the Hessian of the channel mean. Agrees with
/// `skimage.feature.hessian_matrix(img, sigma, mode='mirror',
/// use_gaussian_derivatives=True)`, whose order is (Hrr, Hrc, Hcc) = (Hyy, Hxy, Hxx).
#[derive(Debug, Args)]
pub struct Hessian {
    /// The image.
    image: PathBuf,
    /// Scale: the standard deviation of the Gaussian derivatives, in pixels.
    #[arg(long, value_name = "PX")]
    sigma: f64,
    /// Border handling: reflect101, constant or constant:VALUE, replicate, wrap.
    #[arg(long, default_value = "reflect101")]
    border: Border,
    /// Output (.npy keeps the signed float values).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    input: InputOptions,
}

impl Hessian {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let border = self.border;
        ifd_smooth::check_sigma(self.sigma)
            .map_err(|e| super::smooth::name_option(e, Some("--sigma")))?;
        crate::output::check_output_path(&self.output)?;
        let img = self.input.read(&self.image)?.image;
        let bank = HessianBank::new(0.01)?;
        let h = hessian_image(&img, self.sigma, &bank, border)?;
        write_output(&self.output, &h, &ifd_image::WriteOptions::default())
    }
}
