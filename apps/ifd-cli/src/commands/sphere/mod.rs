//! `ifd sphere ...`: spherical harmonics, rotations, isotropic spherical
//! decompositions. One module per subcommand.

mod brdf;
pub mod brdf_filter;
mod decompose;
mod eval;
mod filter;
pub mod radial;
mod rotate;
mod sh;

use std::path::Path;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};

use ifd_sphere::Decomposition;
use ifd_sphere::Sharing;

/// Spherical harmonics (graphics/Sloan convention, flat index l(l+1)+m), rotations
/// (`--zyz a,b,c` = Rz(a) Ry(b) Rz(c), g(w) = f(R^T w)) and isotropic spherical
/// decompositions of spherical filters.
#[derive(Debug, Args)]
pub struct Sphere {
    #[command(subcommand)]
    command: SphereCommand,
}

#[derive(Debug, Subcommand)]
enum SphereCommand {
    /// Project an environment map (2:1 equirectangular or 6:1 cubemap strip) onto SH; write ((L+1)^2, C) float64 .npy.
    Sh(sh::ShCmd),
    /// Rotate SH coefficients (.npy) by ZHF (Eq. 10), signal-tailored ZHF (Eq. 11) or the reference rotation.
    Rotate(rotate::RotateCmd),
    /// Decompose a spherical filter into rotated isotropic lobes (RZH or another profile); write JSON.
    Decompose(decompose::DecomposeCmd),
    /// Evaluate all real SH up to L at directions from an (N, 3) .npy; write (N, (L+1)^2) float64 .npy.
    Eval(eval::EvalCmd),
    /// Filter an environment map with a decomposition from `sphere decompose` (ISD Eq. 6, 13, 14).
    Filter(filter::FilterCmd),
    /// Tabulate a BRDF's view-dependent ISD lobe weights (ISD Sec. 6.1, 7.1) into a table file.
    Brdf(brdf::BrdfCmd),
    /// Radial reflection map of any BRDF under radially symmetric light (ISD Sec. 6.1, Eq. 23-24).
    Radial(radial::RadialCmd),
    /// Filter noisy or sparse BRDF data with a separable vMF kernel on the 4D SH basis (ISD Sec. 6.3).
    BrdfFilter(brdf_filter::BrdfFilterCmd),
    /// Moved: `ifd-paper isd-condition`.
    #[command(hide = true, disable_help_flag = true)]
    Condition(crate::commands::paper::Moved),
    /// Moved: `ifd-paper zhf-sparsity`.
    #[command(hide = true, disable_help_flag = true)]
    Sparsity(crate::commands::paper::Moved),
}

impl Sphere {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        match self.command {
            SphereCommand::Sh(c) => c.run(),
            SphereCommand::Rotate(c) => c.run(),
            SphereCommand::Decompose(c) => c.run(),
            SphereCommand::Eval(c) => c.run(),
            SphereCommand::Filter(c) => c.run(),
            SphereCommand::Brdf(c) => c.run(),
            SphereCommand::Radial(c) => c.run(),
            SphereCommand::BrdfFilter(c) => c.run(),
            SphereCommand::Condition(_) => crate::commands::paper::Moved::refuse(
                "ifd sphere condition",
                "ifd-paper isd-condition",
                "",
            ),
            SphereCommand::Sparsity(_) => crate::commands::paper::Moved::refuse(
                "ifd sphere sparsity",
                "ifd-paper zhf-sparsity",
                "",
            ),
        }
    }
}

/// Whether a format can store negative samples.
pub(super) fn stores_negatives(path: &Path) -> Result<bool> {
    use ifd_image::FileFormat;
    Ok(matches!(
        FileFormat::from_path(path)?,
        FileFormat::Exr | FileFormat::Npy
    ))
}

/// Reports negative input samples (clamped, or kept with `--keep-negatives`).
pub(super) fn note_input_negatives(path: &Path, count: usize, kept: bool) {
    if count > 0 {
        let what = if kept { "kept" } else { "clamped to 0" };
        eprintln!("note: {}: {count} negative samples {what}", path.display());
    }
}

/// Clamps the negatives (ringing) of a band-limited map to 0 when `path`'s
/// format cannot store them, reporting how many; EXR and .npy keep them.
pub(super) fn clamp_output_negatives(
    path: &Path,
    img: &mut ifd_image::Image,
    what: &str,
) -> Result<usize> {
    if stores_negatives(path)? {
        return Ok(0);
    }
    let mut clamped = 0usize;
    for v in img.data_mut() {
        if *v < 0.0 {
            *v = 0.0;
            clamped += 1;
        }
    }
    if clamped > 0 {
        eprintln!(
            "note: {}: {clamped} negative samples of the band-limited {what} (ringing) clamped \
             to 0; write .exr or .npy to keep them",
            path.display()
        );
    }
    Ok(clamped)
}

pub(crate) fn sharing_name(s: Sharing) -> &'static str {
    match s {
        Sharing::PerBand => "per-band",
        Sharing::Shared => "shared",
    }
}

/// Reads a decomposition file, naming the file in every error.
pub(super) fn read_decomposition(path: &Path) -> Result<Decomposition> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the decomposition", path.display()))?;
    Decomposition::from_json(&text).with_context(|| format!("{}", path.display()))
}

/// `--projection` values of `sphere sh`, `sphere filter` and `sphere decompose`.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub(super) enum ProjectionArg {
    /// Each texel integrated exactly (the map read as piecewise constant).
    Texel,
    /// Pixel-centre quadrature with each texel's exact solid angle.
    Centre,
}

impl ProjectionArg {
    fn projection(self) -> ifd_sphere::Projection {
        match self {
            Self::Texel => ifd_sphere::Projection::Texel,
            Self::Centre => ifd_sphere::Projection::Centre,
        }
    }
}
