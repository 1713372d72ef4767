//! `ifd sphere filter`: filter an environment map with a decomposition.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use ifd_sphere::{MapLayout, Prefiltered};
use ifd_sphere::{Negatives, analyze_map};
use serde_json::json;

use super::{
    ProjectionArg, clamp_output_negatives, note_input_negatives, read_decomposition,
    stores_negatives,
};
use crate::input::{InputOptions, parse_size};
use crate::options::{ReportOptions, number, seconds, written};

/// `ifd sphere filter ENV --decomp d.json [--size WxH] [--raw] -o OUT`.
///
/// Projects the map onto SH up to the decomposition's degree L, prefilters it
/// per band (Eq. 13) and evaluates, at every output texel direction w,
/// `fhat(R(w)) = int k(R(w)^-1 w') E(w') dw'` with `(L+1)^2` SH lookups per
/// lobe direction (Eq. 6, 14). The frame is `R(w) = Rz(phi) Ry(theta)`: the
/// kernel's +z axis on w, its +x axis along the meridian towards the south,
/// +y towards the east; an anisotropic kernel's orientation is undefined at the
/// poles (there phi = 0 is used). The kernel is scaled to unit integral unless
/// `--raw` (the kernels of `sphere decompose` are unnormalised: vmf:kappa=50
/// peaks at 1). Only the kernel's first channel is used.
///
/// The output layout follows --size: W = 2H equirectangular, W = 6H a cubemap
/// strip (+X,-X,+Y,-Y,+Z,-Z); the default is the input's size. The result is
/// band-limited and may ring negative near bright spots: formats that cannot
/// store negatives (HDR, PNG, TIFF, JPEG) get them clamped to 0 and counted;
/// EXR and .npy keep them.
#[derive(Debug, Args)]
pub(super) struct FilterCmd {
    /// Environment map, 2:1 equirectangular or 6:1 cubemap strip.
    envmap: PathBuf,
    /// Decomposition JSON written by `ifd sphere decompose`.
    #[arg(long, value_name = "JSON")]
    decomp: PathBuf,
    /// Output size WxH (2:1 or 6:1); default: the input's size.
    #[arg(long, value_name = "WxH")]
    size: Option<String>,
    /// Use the kernel as decomposed, without scaling it to unit integral.
    #[arg(long)]
    raw: bool,
    /// Keep negative input samples (default: clamp them to 0 and report how many).
    #[arg(long)]
    keep_negatives: bool,
    /// How the map's texels are projected onto SH: texel (each texel integrated exactly, the
    /// function `ifd render` and `ifd envmap prefilter` integrate; the default for 2:1 maps) or
    /// centre (pixel-centre quadrature with exact solid angles, as ducc0; the only rule for
    /// cube strips).
    #[arg(long, value_enum)]
    projection: Option<ProjectionArg>,
    /// Output map.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    input: InputOptions,
    #[command(flatten)]
    report: ReportOptions,
}

impl FilterCmd {
    pub(super) fn run(self) -> Result<()> {
        let dec = read_decomposition(&self.decomp)?;
        let l = dec.l_max();
        stores_negatives(&self.output)?;
        let img = self.input.read(&self.envmap)?.image;
        let (w, h) = (img.width(), img.height());
        MapLayout::from_size(w, h).map_err(|_| {
            anyhow::anyhow!(
                "{}: a map must be 2:1 (equirectangular, W = 2H, H >= 2) or 6:1 (cubemap \
                 strip +X,-X,+Y,-Y,+Z,-Z); got {w}x{h}",
                self.envmap.display()
            )
        })?;
        let (ow, oh) = match &self.size {
            Some(s) => parse_size(s, "--size")?,
            None => (w, h),
        };
        if MapLayout::from_size(ow, oh).is_err() {
            bail!(
                "--size {ow}x{oh}: the output must be 2:1 (equirectangular, H >= 2) or 6:1 (cubemap strip)"
            );
        }
        // the output's size against the memory budget, before any work
        let budget = self.input.budget();
        let bytes = (ow as u64)
            .saturating_mul(oh as u64)
            .saturating_mul(img.channels() as u64)
            .saturating_mul(4);
        budget
            .check(bytes)
            .with_context(|| format!("--size {ow}x{oh}"))?;
        let neg = if self.keep_negatives {
            Negatives::Keep
        } else {
            Negatives::Clamp
        };
        let start = std::time::Instant::now();
        let (a, projection) =
            analyze_map(&img, l, neg, self.projection.map(ProjectionArg::projection))
                .with_context(|| format!("{}", self.envmap.display()))?;
        note_input_negatives(&self.envmap, a.negatives_clamped, self.keep_negatives);
        let integral = dec.kernel_integral()?;
        let l1: f64 = dec.weights.data.iter().map(|v| v.abs()).sum();
        if !integral.is_finite() || !l1.is_finite() {
            let largest = dec.weights.data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            bail!(
                "{}: the kernel's integral overflows (the weights are too large, the largest \
                 |weight| being {}): scale them down",
                self.decomp.display(),
                ifd_image::short_number(largest)
            );
        }
        let scale = if self.raw {
            1.0
        } else if integral.abs() > 1e-9 * l1.max(f64::MIN_POSITIVE) {
            1.0 / integral
        } else {
            bail!(
                "{}: the kernel integrates to {integral:.3e} (zero-mean or cancelling): it cannot \
                 be normalised to unit integral; use --raw",
                self.decomp.display()
            );
        };
        let pre = Prefiltered::new(&a.coeffs, &dec)?;
        let bar = crate::progress::bar("filtering", "rows", oh as u64);
        let mut out = dec.filter_map(&pre, ow, oh, scale, &|done, _| {
            bar.set_position(done as u64);
        })?;
        bar.finish_and_clear();
        let overflowed = out.data().iter().filter(|v| !v.is_finite()).count();
        if overflowed > 0 {
            let hint = if self.raw {
                "the kernel, used --raw (unnormalised), is too large: scale its weights down or \
                 drop --raw"
            } else {
                "the map or the kernel is too large"
            };
            bail!(
                "{}: {overflowed} of the result's {} values overflow float32: {hint}",
                self.decomp.display(),
                out.data().len()
            );
        }
        let secs = start.elapsed().as_secs_f64();
        let clamped = clamp_output_negatives(&self.output, &mut out, "result")?;
        crate::output::write_output(&self.output, &out, &ifd_image::WriteOptions::default())?;
        let layout = match MapLayout::from_size(ow, oh)? {
            MapLayout::Equirect => "equirect",
            MapLayout::CubemapStrip => "cubemap-strip",
        };
        self.report.emit_summary(
            &json!({
                "lmax": l, "channels": out.channels(), "projection": projection.name(),
                "layout": layout,
                "width": ow, "height": oh,
                "kernel_integral": integral, "scale": scale,
                "input_negatives": a.negatives_clamped,
                "output_negatives_clamped": clamped,
                "seconds": secs,
            }),
            || {
                format!(
                    "wrote {}: {ow}x{oh} {layout}, {} channel(s), filtered at L = {l}\n\
                     kernel integral {}, scaled by {}\n\
                     time {}\n",
                    written(&self.output),
                    out.channels(),
                    number(integral),
                    number(scale),
                    seconds(secs),
                )
            },
        )?;
        Ok(())
    }
}
