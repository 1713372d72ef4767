//! `ifd smooth IMAGE --sigma PX -o OUT`.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use ifd_planar::Border;
use ifd_smooth::{AnisoParams, AspectBank, HessianBank, Mode, SmoothOptions, Smoother};
use ifd_smooth::{SmoothTiles, smooth_tiled};

use crate::input::InputOptions;
use crate::output::{ImageOutput, write_output};

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ModeArg {
    /// One filter per dab from the Hessian at its centre (the paper's brush),
    /// dabs on a grid of spacing 2 x sigma, blended bilinearly.
    Dab,
    /// Each pixel uses the filter from its own Hessian.
    PerPixel,
}

/// Edge-respecting anisotropic smoothing driven by the image Hessian.
///
/// At each place the Hessian (computed with IFD) gives the orientation of
/// edges and ridges; an anisotropic Gaussian smooths along them, not across.
/// The Gaussian's footprint is fixed by --sigma (sx * sy = sigma^2, so the
/// noise reduction equals an isotropic Gaussian of that sigma), its aspect
/// ratio grows from 1 (flat or noisy areas) to --max-aspect (strong, straight
/// structures): aspect = 1 + (K - 1) A^gamma with anisotropy
/// A = (n1 - n2) / (n1 + n2 + epsilon), n1 >= n2 the scale-normalised
/// magnitudes of the tensor-averaged Hessian's eigenvalues.
#[derive(Debug, Args)]
pub struct Smooth {
    /// The image.
    image: PathBuf,
    /// The footprint: the standard deviation, in pixels, of the isotropic
    /// Gaussian whose noise reduction the anisotropic ones match (sx * sy =
    /// sigma^2), 0.5 to 128. Below 2 the pixel-integrated Gaussians are
    /// applied directly (a few taps per pixel, CPU only).
    #[arg(long, value_name = "PX")]
    sigma: f64,
    /// Largest aspect ratio K of the Gaussian (1 to 16).
    #[arg(long, default_value_t = 8.0)]
    max_aspect: f64,
    /// Exponent gamma of the anisotropy.
    #[arg(long, default_value_t = 1.0)]
    gamma: f64,
    /// Noise floor epsilon (scale-normalised Hessian units; images in [0, 1]).
    #[arg(long, default_value_t = 0.02)]
    epsilon: f64,
    /// Standard deviation of the Hessian's Gaussian derivatives, in pixels
    /// (default max(1.5, sigma / 2)).
    #[arg(long, value_name = "PX")]
    hessian_sigma: Option<f64>,
    /// Blend of the smoothed result into the image (0 to 1).
    #[arg(long, default_value_t = 1.0)]
    strength: f32,
    /// Where each pixel's filter comes from.
    #[arg(long, value_enum, default_value = "per-pixel")]
    mode: ModeArg,
    /// Border handling: reflect101, constant or constant:VALUE, replicate, wrap.
    #[arg(long, default_value = "reflect101")]
    border: Border,
    #[command(flatten)]
    output: ImageOutput,
    /// Also write the filter each pixel used, as an HxWx3 float32 `.npy`:
    /// angle of the long axis (degrees counter-clockwise on screen), sx
    /// (along it) and sy (across), in pixels.
    #[arg(long, value_name = "FIELD.npy")]
    field: Option<PathBuf>,
    /// Smooth tile by tile, output tiles of about PX pixels, streaming the
    /// .npy input and output (and --field); images larger than memory. Without
    /// it, a .npy image that would not fit --memory-budget whole is smoothed
    /// tile by tile anyway, with tiles sized to the budget. The result equals
    /// the whole image's.
    #[arg(long, value_name = "PX")]
    tile: Option<usize>,
    /// Fit the aspect-ratio bank of smoothing filters afresh instead of
    /// reading it from (and writing it to) the cache shared with ifd-brush,
    /// `aspect-bank-v1.json` in `$IFD_CACHE_DIR` (else `$XDG_CACHE_HOME/ifd`,
    /// else `~/.cache/ifd`).
    #[arg(long)]
    no_cache: bool,
    /// Print timings.
    #[arg(short, long)]
    verbose: bool,
    /// Run the smoothing pass on the GPU (wgpu, Vulkan; lavapipe when there
    /// is no GPU), in either mode (dab mode: one evaluation per corner of
    /// the dab grid); decompositions, prefiltering and the Hessian field
    /// stay on the CPU. Fails, naming the problem, when there is no adapter.
    #[arg(long)]
    gpu: bool,
    #[command(flatten)]
    input: InputOptions,
}

impl Smooth {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let border = self.border;
        let sigma = self.sigma;
        if !(0.0..=1.0).contains(&self.strength) {
            anyhow::bail!("--strength {} is outside [0, 1]", self.strength);
        }
        if let Some(f) = &self.field
            && f.extension().and_then(|e| e.to_str()) != Some("npy")
        {
            anyhow::bail!(
                "--field {}: the filter field is data, written as .npy only",
                f.display()
            );
        }
        let opts = SmoothOptions {
            scale: sigma,
            hessian_sigma: self.hessian_sigma,
            aniso: AnisoParams {
                max_aspect: self.max_aspect,
                gamma: self.gamma,
                epsilon: self.epsilon,
            },
            border,
            ..SmoothOptions::default()
        };
        if self.gpu && opts.evaluated_directly() {
            anyhow::bail!(
                "--gpu: footprints (--sigma) below {} px (here {}) are evaluated directly, on the CPU only; drop --gpu",
                ifd_smooth::DIRECT_BELOW,
                sigma
            );
        }
        opts.validate().map_err(|e| {
            // The library's `scale` is this command's --sigma.
            let flag =
                matches!(&e, ifd_smooth::SmoothError::OutOfRange { name, .. } if *name == "scale")
                    .then_some("--sigma");
            name_option(e, flag)
        })?;
        crate::output::check_output_path(&self.output.output)?;
        if self.tile == Some(0) {
            anyhow::bail!("--tile 0: the tile side must be at least 1 pixel");
        }
        let mode = match self.mode {
            ModeArg::Dab => Mode::Dab,
            ModeArg::PerPixel => Mode::PerPixel,
        };
        // Bad images are refused before the filters are decomposed: formats
        // that cannot stream are read now, a .npy header is checked.
        let (mut img, npy_dims) = if super::tiled::streams(&self.image) {
            let r = ifd_image::NpyReader::open(&self.image, self.input.replace_nonfinite)?;
            (None, Some((r.width(), r.height(), r.channels())))
        } else {
            (Some(self.read_whole()?), None)
        };
        let t0 = Instant::now();
        let bar = crate::progress::bar("decomposing filters", "", 0);
        let hbank = HessianBank::new(opts.hessian_tol)?;
        let cache = if self.no_cache {
            None
        } else {
            AspectBank::default_cache()
        };
        let (bank, source) =
            AspectBank::load_or_build(opts.bank, cache.as_deref(), crate::progress::track(&bar))?;
        bar.finish_and_clear();
        if self.verbose {
            eprintln!("aspect bank: {source}");
        }
        let bank = Arc::new(bank);
        if self.tile.is_some() {
            return self.run_tiled(&opts, mode, &bank, &hbank);
        }
        let too_large = match npy_dims {
            Some(dims) => self.too_large_whole(dims, &opts, &bank, &hbank)?,
            None => None,
        };
        if let Some(bytes) = too_large {
            for out in std::iter::once(&self.output.output).chain(&self.field) {
                if !super::tiled::streams(out) {
                    anyhow::bail!(
                        "{}: smoothed whole it would need {}, more than the memory budget of {}; \
                         tile by tile it fits, but tiles stream to {} only: write {} as .npy",
                        self.image.display(),
                        ifd_image::fmt_bytes(bytes),
                        ifd_image::fmt_bytes(self.input.budget().limit()),
                        super::tiled::STREAMING,
                        out.display()
                    );
                }
            }
            return self.run_tiled(&opts, mode, &bank, &hbank);
        }
        let img = match img.take() {
            Some(img) => img,
            None => self.read_whole()?,
        };
        // With --gpu, a stack the device cannot hold is refused before the
        // prefiltering, not after.
        let ctx = if self.gpu {
            let ctx = ifd_gpu::GpuContext::new().context("--gpu")?;
            let dims = (img.width(), img.height(), img.channels());
            let layout = Smoother::stack_layout(dims, &opts, &bank, &hbank)?;
            ifd_gpu::GpuStack::check_fits(&ctx, (dims.0, dims.1), &layout)?;
            Some(ctx)
        } else {
            None
        };
        let t1 = Instant::now();
        let smoother = Smoother::with_banks(&img, &opts, bank, &hbank)?;
        let t2 = Instant::now();
        let mut out = if let Some(ctx) = ctx {
            if self.verbose {
                eprintln!("GPU: {}", ctx.adapter_info().name);
            }
            ifd_gpu::GpuSmoother::new(&ctx, &smoother)?.smooth_image(&ctx, mode)?
        } else {
            smoother.smooth_image(mode)?
        };
        blend(&mut out, &img, self.strength);
        let t3 = Instant::now();
        if self.verbose {
            eprintln!(
                "decompositions {:.2} s, prefiltering + Hessian field {:.0} ms, smoothing {:.0} ms",
                (t1 - t0).as_secs_f64(),
                (t2 - t1).as_secs_f64() * 1e3,
                (t3 - t2).as_secs_f64() * 1e3
            );
        }
        if let Some(path) = &self.field {
            let field = field_image(&smoother, smoother.orientation_field(), img.width())?;
            write_output(path, &field, &ifd_image::WriteOptions::default())?;
        }
        self.output.write(&out)
    }

    /// Reads the whole image (formats that cannot stream say so over the
    /// budget).
    fn read_whole(&self) -> Result<ifd_image::Image> {
        match self.input.read(&self.image) {
            Ok(l) => Ok(l.image),
            Err(e) if format!("{e:#}").contains("more than the budget") => anyhow::bail!(
                "{e:#}; images over the budget are smoothed tile by tile when they are {} \
                 (the output too)",
                super::tiled::STREAMING
            ),
            Err(e) => Err(e),
        }
    }

    /// The bytes a `.npy` image of `(w, h, c)` would need smoothed whole,
    /// when more than the memory budget: then it is smoothed tile by tile.
    /// Other formats cannot stream; their reader refuses them over the
    /// budget.
    fn too_large_whole(
        &self,
        (w, h, c): (usize, usize, usize),
        opts: &SmoothOptions,
        bank: &AspectBank,
        hbank: &HessianBank,
    ) -> Result<Option<u64>> {
        let bytes = match ifd_smooth::smoother_bytes((w, h, c), opts, bank, hbank, w * h) {
            Ok(b) => b,
            // A stack too large to plan whole (its FFT domain) is one to tile.
            Err(ifd_smooth::SmoothError::Filter(ifd_planar::FilterError::TooLarge(_))) => u64::MAX,
            Err(e) => return Err(e.into()),
        };
        Ok((bytes > self.input.budget().limit()).then_some(bytes))
    }

    /// Smooths tile by tile, streaming `.npy` input and outputs.
    fn run_tiled(
        &self,
        opts: &SmoothOptions,
        mode: Mode,
        bank: &Arc<AspectBank>,
        hbank: &HessianBank,
    ) -> Result<()> {
        use super::tiled::{STREAMING, streams};
        if !streams(&self.image) {
            anyhow::bail!(
                "{}: tiled smoothing streams {STREAMING} only; convert the image first",
                self.image.display()
            );
        }
        for out in std::iter::once(&self.output.output).chain(&self.field) {
            if !streams(out) {
                anyhow::bail!("{}: tiled smoothing writes {STREAMING} only", out.display());
            }
        }
        let mut reader = ifd_image::NpyReader::open(&self.image, self.input.replace_nonfinite)?;
        let dims = (reader.width(), reader.height(), reader.channels());
        let budget = self.input.budget().limit();
        let plan = |tile| SmoothTiles::new(dims, opts, mode, bank, hbank, tile);
        let tiles = super::tiled::choose_tiles(
            self.tile,
            budget,
            plan,
            |t| t.tiling,
            |t| Ok(t.tile_bytes(opts, bank, hbank)?),
        )?;
        let count = tiles.tiling.tiles().len();
        if self.verbose {
            eprintln!(
                "tiled: {count} tiles of {} px, halo {} px, aligned to {} px",
                tiles.tiling.tile, tiles.tiling.halo, tiles.tiling.align
            );
        }
        let ctx = if self.gpu {
            let ctx = ifd_gpu::GpuContext::new().context("--gpu")?;
            let (w, h) = tiles.tiling.largest_read();
            let layout = Smoother::stack_layout((w, h, dims.2), opts, bank, hbank)?;
            ifd_gpu::GpuStack::check_fits(&ctx, (w, h), &layout)?;
            Some(ctx)
        } else {
            None
        };
        let (w, h, c) = dims;
        let mut writer = ifd_image::NpyWriter::create(&self.output.output, w, h, c)?;
        let mut field_writer = self
            .field
            .as_deref()
            .map(|p| ifd_image::NpyWriter::create(p, w, h, 3))
            .transpose()?;
        let bar = crate::progress::bar("smoothing tiles", "", count as u64);
        smooth_tiled(
            &tiles,
            opts,
            bank,
            hbank,
            &mut reader,
            |tile| -> Result<()> {
                let mut out = match &ctx {
                    Some(ctx) => {
                        let r = tile.local_inner();
                        ifd_gpu::GpuSmoother::new(ctx, tile.smoother)?
                            .smooth_image(ctx, mode)?
                            .crop(r.x0, r.y0, r.width, r.height)
                    }
                    None => tile.smooth(mode)?,
                };
                blend(&mut out, &tile.input(), self.strength);
                writer.write_region(tile.inner.x0, tile.inner.y0, &out)?;
                if let Some(fw) = &mut field_writer {
                    let f = field_image(tile.smoother, &tile.orientations(), tile.inner.width)?;
                    fw.write_region(tile.inner.x0, tile.inner.y0, &f)?;
                }
                Ok(())
            },
            |done, _| bar.set_position(done as u64),
        )
        .with_context(|| format!("smoothing {} tile by tile", self.image.display()))?;
        bar.finish_and_clear();
        if let Some(fw) = field_writer {
            fw.finish()?;
        }
        writer.finish()?;
        Ok(())
    }
}

/// Moves `out` back towards `input` for a strength below 1.
fn blend(out: &mut ifd_image::Image, input: &ifd_image::Image, strength: f32) {
    if strength < 1.0 {
        for (o, &i) in out.data_mut().iter_mut().zip(input.data()) {
            *o = i + strength * (*o - i);
        }
    }
}

/// The filter field of `orientations` (rows of `width`) as an image of
/// `(angle, sx, sy)`.
fn field_image(
    smoother: &Smoother,
    orientations: &[ifd_smooth::Orientation],
    width: usize,
) -> Result<ifd_image::Image> {
    let field: Vec<f32> = orientations
        .iter()
        .flat_map(|&o| {
            let (sx, sy) = smoother.footprint(o);
            [o.theta, sx as f32, sy as f32]
        })
        .collect();
    Ok(ifd_image::Image::from_vec(
        width,
        orientations.len() / width.max(1),
        3,
        field,
    )?)
}

/// A smoothing library error about a parameter's range, said in terms of the
/// command's option: `flag`, or the parameter's name as a flag (`hessian
/// sigma` -> `--hessian-sigma`); other errors as they are (`ifd smooth` and
/// `ifd hessian`).
pub(crate) fn name_option(e: ifd_smooth::SmoothError, flag: Option<&str>) -> anyhow::Error {
    match e {
        ifd_smooth::SmoothError::OutOfRange { name, value, range } => anyhow::anyhow!(
            "{} {}: outside the supported range {range}",
            flag.map_or_else(|| format!("--{}", name.replace(' ', "-")), str::to_string),
            ifd_image::short_number(value)
        ),
        e => e.into(),
    }
}
