//! `ifd sphere sh`: project an environment map onto SH.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use ifd_sphere::EquirectTransform;
use ifd_sphere::{Negatives, analyze_map};
use serde_json::json;

use super::{ProjectionArg, clamp_output_negatives, note_input_negatives, stores_negatives};
use crate::input::InputOptions;
use crate::options::{ReportOptions, seconds, written};

/// `ifd sphere sh ENVMAP --lmax L -o coeffs.npy [--reconstruct out.hdr]`.
///
/// Layouts, told apart by shape: W = 2H is equirectangular (column u at
/// azimuth 2 pi (u + 0.5) / W, row 0 looking up, +z); W = 6H is a horizontal
/// cubemap strip of six square faces +X, -X, +Y, -Y, +Z, -Z, each in OpenGL's
/// orientation (s to the right, t down). Anything else is refused.
#[derive(Debug, Args)]
pub(super) struct ShCmd {
    /// Environment map, 2:1 equirectangular or 6:1 cubemap strip; EXR, HDR, PNG, ... or .npy.
    envmap: PathBuf,
    /// Maximum SH degree L.
    #[arg(long, value_name = "L")]
    lmax: usize,
    /// Output coefficients, ((L+1)^2, C) float64 .npy.
    #[arg(short, long)]
    output: PathBuf,
    /// Also write the band-limited reconstruction, equirectangular (the input's size for an
    /// equirectangular map, 4H x 2H for a cubemap strip of H x H faces). It rings negative near
    /// bright spots: formats that cannot store negatives (HDR, PNG, TIFF, JPEG) get them clamped
    /// to 0, and the count is reported; EXR and .npy keep them.
    #[arg(long, value_name = "IMAGE")]
    reconstruct: Option<PathBuf>,
    /// Keep negative samples (default: clamp them to 0 and report how many).
    #[arg(long)]
    keep_negatives: bool,
    /// How the map's texels are projected onto SH: texel (each texel integrated exactly, the
    /// function `ifd render` and `ifd envmap prefilter` integrate; the default for 2:1 maps) or
    /// centre (pixel-centre quadrature with exact solid angles, as ducc0; the only rule for
    /// cube strips).
    #[arg(long, value_enum)]
    projection: Option<ProjectionArg>,
    #[command(flatten)]
    input: InputOptions,
    #[command(flatten)]
    report: ReportOptions,
}

impl ShCmd {
    pub(super) fn run(self) -> Result<()> {
        if self.lmax > ifd_sphere::MAX_DEGREE {
            bail!(
                "--lmax {}: at most L = {} is supported",
                self.lmax,
                ifd_sphere::MAX_DEGREE
            );
        }
        // unwritable outputs are refused before the work
        crate::output::check_npy_output(&self.output, "-o", "the SH coefficient table")?;
        if let Some(path) = &self.reconstruct {
            stores_negatives(path)?;
            crate::output::check_output_path(path).context("--reconstruct")?;
        }
        let img = self.input.read(&self.envmap)?.image;
        let (w, h) = (img.width(), img.height());
        let cube = w == 6 * h && h > 0;
        // an equirectangular map of the right size for the reconstruction
        let t = if cube {
            EquirectTransform::new(self.lmax, 4 * h.max(1), 2 * h.max(1))
        } else {
            EquirectTransform::new(self.lmax, w, h)
        };
        let t = t.map_err(|e| match e {
            ifd_sphere::SphereError::NotEquirect { .. } => anyhow::anyhow!(
                "{}: a map must be 2:1 (equirectangular, W = 2H, H >= 2) or 6:1 (cubemap \
                     strip +X,-X,+Y,-Y,+Z,-Z); got {w}x{h}",
                self.envmap.display()
            ),
            e => anyhow::Error::new(e).context(format!("{}", self.envmap.display())),
        })?;
        let neg = if self.keep_negatives {
            Negatives::Keep
        } else {
            Negatives::Clamp
        };
        let start = std::time::Instant::now();
        let (a, projection) = analyze_map(
            &img,
            self.lmax,
            neg,
            self.projection.map(ProjectionArg::projection),
        )
        .with_context(|| format!("{}", self.envmap.display()))?;
        let secs = start.elapsed().as_secs_f64();
        note_input_negatives(&self.envmap, a.negatives_clamped, self.keep_negatives);
        a.coeffs.write_npy(&self.output)?;
        let mut rec_clamped = 0usize;
        if let Some(path) = &self.reconstruct {
            let mut rec = t.synthesize(&a.coeffs)?;
            rec_clamped = clamp_output_negatives(path, &mut rec, "reconstruction")?;
            crate::output::write_output(path, &rec, &ifd_image::WriteOptions::default())?;
        }
        let layout = if cube { "cubemap-strip" } else { "equirect" };
        self.report.emit_summary(
            &json!({
                "lmax": self.lmax, "channels": a.coeffs.channels(),
                "layout": layout,
                "projection": projection.name(),
                "width": w, "height": h,
                "negatives": a.negatives_clamped, "seconds": secs,
                "reconstruct_negatives_clamped": rec_clamped,
            }),
            || {
                let mut text = format!(
                    "wrote {}: SH up to L = {}, {} channel(s), of {} ({w}x{h} {layout}, {} \
                     projection)\n",
                    written(&self.output),
                    self.lmax,
                    a.coeffs.channels(),
                    self.envmap.display(),
                    projection.name(),
                );
                if let Some(p) = &self.reconstruct {
                    let _ = writeln!(text, "wrote {}: the reconstruction", written(p));
                }
                text + &format!("time {}\n", seconds(secs))
            },
        )?;
        Ok(())
    }
}
