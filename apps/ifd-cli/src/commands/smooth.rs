//! `ifd smooth IMAGE --scale S -o OUT`.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use ifd_planar::Border;
use ifd_smooth::{AnisoParams, AspectBank, HessianBank, Mode, SmoothOptions, Smoother};
use indicatif::{ProgressBar, ProgressStyle};

use crate::input::InputOptions;
use crate::output::{ImageOutput, write_output};

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ModeArg {
    /// One filter per dab from the Hessian at its centre (the paper's brush),
    /// dabs on a grid of spacing 2 x scale, blended bilinearly.
    Dab,
    /// Each pixel uses the filter from its own Hessian.
    PerPixel,
}

/// Edge-respecting anisotropic smoothing driven by the image Hessian.
///
/// At each place the Hessian (computed with IFD) gives the orientation of
/// edges and ridges; an anisotropic Gaussian smooths along them, not across.
/// The Gaussian's footprint is fixed by --scale (sx * sy = scale^2, so the
/// noise reduction equals an isotropic Gaussian of sigma = scale), its aspect
/// ratio grows from 1 (flat or noisy areas) to --max-aspect (strong, straight
/// structures): aspect = 1 + (K - 1) A^gamma with anisotropy
/// A = (n1 - n2) / (n1 + n2 + epsilon), n1 >= n2 the scale-normalised
/// magnitudes of the tensor-averaged Hessian's eigenvalues.
#[derive(Debug, Args)]
pub struct Smooth {
    /// The image.
    image: PathBuf,
    /// Footprint scale S in pixels (0.5 to 128). Below 2 the pixel-integrated
    /// Gaussians are applied directly (a few taps per pixel, CPU only).
    #[arg(long)]
    scale: f64,
    /// Largest aspect ratio K of the Gaussian (1 to 16).
    #[arg(long, default_value_t = 8.0)]
    max_aspect: f64,
    /// Exponent gamma of the anisotropy.
    #[arg(long, default_value_t = 1.0)]
    gamma: f64,
    /// Noise floor epsilon (scale-normalised Hessian units; images in [0, 1]).
    #[arg(long, default_value_t = 0.02)]
    epsilon: f64,
    /// Hessian scale in pixels (default max(1.5, scale / 2)).
    #[arg(long)]
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
            scale: self.scale,
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
                "--gpu: footprint scales below {} px (here {}) are evaluated directly, on the CPU only; drop --gpu",
                ifd_smooth::direct::DIRECT_BELOW,
                self.scale
            );
        }
        opts.validate()
            .map_err(|e| crate::input::name_option(e, None))?;
        crate::output::check_output_path(&self.output.output)?;
        let img = self.input.read(&self.image)?.image;
        let t0 = Instant::now();
        let bar = ProgressBar::new(0);
        bar.set_style(
            ProgressStyle::with_template("{msg} {bar:30} {pos}/{len} [{elapsed}]")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_message("decomposing filters");
        let hbank = HessianBank::new(opts.hessian_tol)?;
        let bank = AspectBank::build(opts.bank, |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })?;
        bar.finish_and_clear();
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
        let smoother = Smoother::with_banks(&img, &opts, Arc::new(bank), &hbank)?;
        let t2 = Instant::now();
        let mode = match self.mode {
            ModeArg::Dab => Mode::Dab,
            ModeArg::PerPixel => Mode::PerPixel,
        };
        let mut out = if let Some(ctx) = ctx {
            if self.verbose {
                eprintln!("GPU: {}", ctx.adapter_info().name);
            }
            ifd_gpu::GpuSmoother::new(&ctx, &smoother)?.smooth_image(&ctx, mode)?
        } else {
            smoother.smooth_image(mode)?
        };
        if self.strength < 1.0 {
            for (o, &i) in out.data_mut().iter_mut().zip(img.data()) {
                *o = i + self.strength * (*o - i);
            }
        }
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
            let field: Vec<f32> = smoother
                .orientation_field()
                .iter()
                .flat_map(|&o| {
                    let (sx, sy) = smoother.footprint(o);
                    [o.theta, sx as f32, sy as f32]
                })
                .collect();
            let field = ifd_image::Image::from_vec(img.width(), img.height(), 3, field)?;
            write_output(path, &field, &ifd_image::WriteOptions::default())?;
        }
        self.output.write(&out)
    }
}
