//! `ifd filter IMAGE --decomp d.json` or `ifd filter IMAGE --kernel SPEC`
//! (several, with `--filter-map`: `set.rs`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use ifd_planar::{
    Border, CheckedField, Decomposition, Field, FieldKind, Interpolation, PreparedDecomposition,
};
use ifd_planar::{FilterOptions, FilterPlan};

use crate::input::InputOptions;
use crate::output::ImageOutput;

mod set;

/// Filter an image with a decomposed filter, rotated and scaled per pixel.
///
/// Each output pixel is sum_t w_t fhat_{s sigma_t}(p + s R_theta c_t): one
/// lookup per term into a scale stack prefiltered once by FFT, whatever the
/// filter's size, angle or scale.
#[derive(Debug, Args)]
#[command(group(
    clap::ArgGroup::new("filter")
        .required(true)
        .multiple(true)
        .args(["decomp", "kernel", "sigma_map"])
))]
#[expect(
    clippy::struct_excessive_bools,
    reason = "each bool is a command-line switch"
)]
pub struct Filter {
    /// The image to filter.
    image: PathBuf,
    /// The decomposition (from `ifd decompose`). Repeat it, with
    /// --filter-map, to filter each region of the image with its own.
    #[arg(long, value_name = "FILE", conflicts_with = "kernel", action = clap::ArgAction::Append)]
    decomp: Vec<PathBuf>,
    /// The filter as a spec (`gauss:sx=16,sy=2,theta=30`; `ifd decompose
    /// --help` lists them) or a kernel file (.npy, .png, .exr; odd sizes, used
    /// as given: a kernel that does not sum to 1 changes the brightness),
    /// fitted on first use at --tol and kept in the fit cache
    /// ($IFD_CACHE_DIR, else $XDG_CACHE_HOME/ifd, else ~/.cache/ifd) for the
    /// next run. Repeat it, with --filter-map, to filter each region of the
    /// image with its own.
    #[arg(long, value_name = "SPEC|FILE", action = clap::ArgAction::Append)]
    kernel: Vec<String>,
    /// Target relative L2 error of the fit of --kernel (with --sigma-map: of
    /// each entry of its aspect bank, cached per tolerance) [default: 0.01]
    #[arg(long, value_name = "E", requires = "kernel")]
    tol: Option<f64>,
    /// Fit --kernel (with --sigma-map: the aspect bank) afresh instead of
    /// reading it from (and keeping it in) the fit cache.
    #[arg(long, requires = "kernel")]
    no_cache: bool,
    /// A normalised anisotropic Gaussian per pixel (with `--kernel gauss`):
    /// an HxWx3 float .npy of the image's size holding, per pixel, the
    /// standard deviation along the major axis, the one along the minor axis
    /// (pixels, 0 < minor <= major, aspect major/minor up to 16, sigmas up
    /// to a quarter of the image's larger side and 512) and the major axis'
    /// angle in degrees counter-clockwise on screen. Uses the aspect bank of
    /// `ifd smooth` (fitted at --tol) and its cache; footprints
    /// sqrt(major*minor) below 2 px or minor sigmas below 1 px are sampled
    /// directly. CPU only.
    #[arg(
        long,
        value_name = "NPY",
        conflicts_with_all = [
            "decomp", "angle", "angle_map", "scale", "scale_map", "gpu", "tile", "interp",
            "eval_budget", "scalar",
        ]
    )]
    sigma_map: Option<PathBuf>,
    /// Which filter each pixel gets, when several are given (--kernel or
    /// --decomp repeated, numbered from 0 in the order given): an HxW .npy of
    /// the image's size holding each pixel's filter number (a label map), or
    /// an HxWxN .npy of N >= 2 weights per pixel, one per filter, the output
    /// being the weighted sum of the filters there (soft region edges). The
    /// image is prefiltered once for all the filters (one stack, planned so
    /// that each filter stays within its --eval-budget), and each pixel reads
    /// only the terms of the filters it is weighted by. CPU only.
    #[arg(
        long = "filter-map",
        value_name = "NPY",
        conflicts_with_all = ["sigma_map", "gpu", "tile"]
    )]
    regions: Option<PathBuf>,
    /// Rotation in degrees, counter-clockwise on screen, for every pixel.
    #[arg(
        long,
        value_name = "DEG",
        conflicts_with = "angle_map",
        allow_hyphen_values = true
    )]
    angle: Option<f32>,
    /// Per-pixel rotation in degrees: an HxW .npy of the image's size, read
    /// as data (integer PNG/JPEG/TIFF are refused: they store image values in
    /// [0, 1]).
    #[arg(long, value_name = "NPY")]
    angle_map: Option<PathBuf>,
    /// Scale factor for every pixel.
    #[arg(long, value_name = "S", conflicts_with = "scale_map")]
    scale: Option<f32>,
    /// Per-pixel scale factors: an HxW .npy of the image's size, read as
    /// data.
    #[arg(long, value_name = "NPY")]
    scale_map: Option<PathBuf>,
    /// Border handling: reflect101 (OpenCV's default), constant or constant:VALUE, replicate, wrap.
    #[arg(long, default_value = "reflect101")]
    border: Border,
    #[command(flatten)]
    output: ImageOutput,
    /// Print the evaluation plan (interpolation, pyramid factor, levels,
    /// expected error), the lookup path and the time of each step.
    #[arg(short, long)]
    verbose: bool,
    /// Evaluate on the GPU (wgpu, Vulkan): a hardware adapter when there is
    /// one, else a software one (lavapipe). Prefiltering stays on the CPU.
    /// Fails, naming the problem, when there is no adapter or the image is
    /// too large for the device's limits. The GPU reads every term from a
    /// log-uniformly spaced stack, as the CPU does for per-pixel maps (agreeing
    /// with it to 1e-4 relative); at a constant pose the CPU is more accurate
    /// (narrowest terms evaluated directly, levels at the exact sigmas).
    #[arg(long)]
    gpu: bool,
    /// How the prefiltered levels are read between samples: `auto` chooses,
    /// per decomposition, the cheapest of bilinear and the cubic B-spline
    /// (and how finely levels are stored; with a scale map, 2 to 4 levels
    /// per octave blended, or up to 8 with each term reading its nearest
    /// level) whose expected evaluation error is within `--eval-budget`;
    /// `linear` or `cubic` fix the interpolation. See
    /// docs/planar-accuracy.md.
    #[arg(long, value_name = "MODE", default_value = "auto")]
    interp: InterpChoice,
    /// Budget on the expected evaluation error (relative RMS on white noise)
    /// that `--interp` plans for [default: a third of the decomposition's
    /// fit error, at least 0.001]
    #[arg(long, value_name = "E")]
    eval_budget: Option<f64>,
    /// Filter tile by tile, output tiles of about PX pixels, streaming the
    /// image, the maps and the output as .npy (images larger than memory;
    /// equal to the whole-image result to float rounding). Chosen by itself,
    /// with tiles sized to --memory-budget, when a .npy image would not fit
    /// it whole.
    #[arg(long, value_name = "PX", conflicts_with = "gpu")]
    tile: Option<usize>,
    /// Evaluate per-pixel maps with the scalar loop instead of the CPU's
    /// vector instructions (AVX2 or AVX-512, detected at run time): the
    /// same output bit for bit, slower; for measuring.
    #[arg(long, conflicts_with = "gpu")]
    scalar: bool,
    #[command(flatten)]
    input: InputOptions,
}

impl Filter {
    /// What filters the image, for messages: the decomposition file or the
    /// --kernel spec.
    fn filter_name(&self) -> String {
        self.filter_names().join(", ")
    }

    /// Each filter's name, in the order given.
    fn filter_names(&self) -> Vec<String> {
        self.decomp
            .iter()
            .map(|d| d.display().to_string())
            .chain(self.kernel.iter().cloned())
            .collect()
    }

    /// The decomposition: read from --decomp, or --kernel fitted (or read
    /// from the fit cache); with `-v`, where it came from.
    fn decomposition(&self) -> Result<Decomposition> {
        let n = self.decomp.len() + self.kernel.len();
        if n > 1 {
            bail!(
                "{n} filters given ({}): several filters need --filter-map, which says which \
                 pixels each one filters (on the CPU, the image whole: not with --gpu or --tile)",
                self.filter_name()
            );
        }
        Ok(self
            .decompositions()?
            .pop()
            .expect("clap requires a filter"))
    }

    /// Every filter given, in order: each --decomp read, each --kernel fitted
    /// (or read from the fit cache); with `-v`, where each fit came from.
    fn decompositions(&self) -> Result<Vec<Decomposition>> {
        if let Some(path) = self.decomp.first() {
            if self.tol.is_some() || self.no_cache {
                bail!(
                    "--tol and --no-cache apply to a fit of --kernel, not to --decomp {}",
                    path.display()
                );
            }
            return self
                .decomp
                .iter()
                .map(|p| Ok(Decomposition::load(p)?))
                .collect();
        }
        if self.kernel.is_empty() {
            bail!("give --decomp FILE or --kernel SPEC");
        }
        self.kernel.iter().map(|k| self.fit_kernel(k)).collect()
    }

    /// `--kernel filter` fitted at --tol, or read from the fit cache.
    fn fit_kernel(&self, filter: &str) -> Result<Decomposition> {
        if filter == super::sigma_map::KERNEL {
            bail!(
                "--kernel {filter}: give its sigmas (`gauss:sx=8,sy=2,theta=30`), or a Gaussian per \
                 pixel with --sigma-map M.npy"
            );
        }
        let opts = super::decompose::fit_options(self.tol.unwrap_or(0.01))?;
        let cache = if self.no_cache {
            ifd_planar::FitCache::off()
        } else {
            ifd_planar::FitCache::shared()
        };
        let (kernel, spec) = super::decompose::load_kernel(filter, &self.input)?;
        let t = Instant::now();
        let bar = crate::progress::spinner(&format!("fitting {filter}"));
        let tick = |iter: usize, _: f64, _: usize| {
            if iter.is_multiple_of(10) {
                bar.tick();
            }
        };
        let (d, source) = match &spec {
            Some(s) => cache.fit_spec(s, &opts, None, tick),
            None => cache.fit_kernel(&kernel, &opts, tick),
        }
        .with_context(|| format!("fitting --kernel {filter}"))?;
        bar.finish_and_clear();
        if self.verbose {
            let r = d.report.as_ref();
            let fit = format!(
                "{} terms, {:.3}% relative L2 error",
                d.terms.len(),
                100.0 * r.map_or(f64::NAN, |r| r.rel_l2_error)
            );
            // (several kernels: each line names its own)
            let what = if self.kernel.len() > 1 {
                format!("fit of {filter}")
            } else {
                "fit".to_string()
            };
            match source {
                ifd_planar::FitSource::Cached(p) => {
                    eprintln!("{what}: {fit}, read from the fit cache ({})", p.display());
                }
                ifd_planar::FitSource::Fitted(kept) => eprintln!(
                    "{what}: {fit}, fitted in {:.2} s{}",
                    t.elapsed().as_secs_f64(),
                    kept.map(|p| format!(", kept in {}", p.display()))
                        .unwrap_or_default()
                ),
            }
        }
        Ok(d)
    }

    fn options(&self) -> FilterOptions {
        FilterOptions {
            border: self.border,
            interpolation: match self.interp {
                InterpChoice::Auto => None,
                InterpChoice::Linear => Some(Interpolation::Linear),
                InterpChoice::Cubic => Some(Interpolation::Cubic),
            },
            eval_budget: self.eval_budget,
            log_uniform: false,
            direct_terms: true,
            scale_range: None,
            vector_kernels: !self.scalar,
        }
    }

    /// The angle and scale maps given (`--angle-map`, `--scale-map`), read
    /// and checked to be of the `w x h` image's size.
    fn read_maps(&self, (w, h): (usize, usize)) -> Result<Maps> {
        let read = |path: &Option<PathBuf>, what| match path {
            Some(p) => load_map(&self.input, p, what, w, h).map(Some),
            None => Ok(None),
        };
        Ok((
            read(&self.angle_map, "angle map")?,
            read(&self.scale_map, "scale map")?,
        ))
    }

    /// The angle and scale fields of a `w x h` image: the maps read by
    /// [`Self::read_maps`], else `--angle` and `--scale`, checked (errors name
    /// the map file or the option).
    fn fields<'a>(
        &self,
        (w, h): (usize, usize),
        (angle_map, scale_map): &'a Maps,
    ) -> Result<(CheckedField<'a>, CheckedField<'a>)> {
        let angle = check_field(
            (w, h),
            angle_map.as_deref(),
            self.angle.unwrap_or(0.0),
            FieldKind::Angle,
            self.angle_map.as_deref(),
            "--angle",
        )?;
        let scale = check_field(
            (w, h),
            scale_map.as_deref(),
            self.scale.unwrap_or(1.0),
            FieldKind::Scale,
            self.scale_map.as_deref(),
            "--scale",
        )?;
        Ok((angle, scale))
    }

    /// The bytes a `.npy` image would need filtered whole, when more than the
    /// memory budget (its samples, the stack, the maps and the result):
    /// then it is filtered tile by tile. Other formats cannot stream; their
    /// reader refuses them over the budget.
    fn too_large_whole(&self, decomposition: &Decomposition) -> Result<Option<u64>> {
        if !super::tiled::streams(&self.image) {
            return Ok(None);
        }
        let r = ifd_image::NpyReader::open(&self.image, self.input.replace_nonfinite)?;
        let (w, h, c) = (r.width(), r.height(), r.channels());
        // A map's range needs a pass over it; the planning only needs to
        // know that scales vary (a range of one octave stands for it).
        let scale_range = if self.scale_map.is_some() {
            (1.0, 2.0)
        } else {
            let s = self.scale.unwrap_or(1.0);
            (s, s)
        };
        let Ok(grid) = ifd_planar::TileGrid::new(
            decomposition,
            (w, h, c),
            self.angle_map.is_some(),
            scale_range,
            &self.options(),
            w.max(h),
        ) else {
            // Planning errors are reported by the whole-image path.
            return Ok(None);
        };
        let bytes = grid.tile_bytes(decomposition)?;
        Ok((bytes > self.input.budget().limit()).then_some(bytes))
    }

    fn run_tiled(&self, decomposition: &Decomposition) -> Result<()> {
        super::tiled::run(&super::tiled::TiledRun {
            image: &self.image,
            decomposition,
            angle: self
                .angle_map
                .as_deref()
                .map_or(Ok(self.angle.unwrap_or(0.0)), Err),
            scale: self
                .scale_map
                .as_deref()
                .map_or(Ok(self.scale.unwrap_or(1.0)), Err),
            output: &self.output.output,
            options: self.options(),
            tile: self.tile,
            budget: self.input.budget().limit(),
            replace_non_finite: self.input.replace_nonfinite,
            verbose: self.verbose,
        })
        .with_context(|| {
            format!(
                "filtering {} with {}",
                self.image.display(),
                self.filter_name()
            )
        })
    }
}

/// `-v`'s last line: the terms, then planning, prefiltering (from `t0` to
/// `t1`, with the stack's levels, memory and build) and filtering (to `t2`).
fn timings(
    terms: &str,
    stack: &ifd_planar::ScaleStack,
    planning: std::time::Duration,
    (t0, t1, t2): (Instant, Instant, Instant),
) -> String {
    let share = stack.computed_share();
    // A stack built for a scale map's reads computes only those samples.
    let over = if share < 1.0 {
        format!(" of the {:.0}% of samples read", 100.0 * share)
    } else {
        String::new()
    };
    format!(
        "{terms}; planning {:.1} ms, prefiltering {:.1} ms ({} levels, {}, {} build{over}), \
         filtering {:.1} ms",
        planning.as_secs_f64() * 1e3,
        (t1 - t0).as_secs_f64() * 1e3,
        stack.sigmas().len(),
        ifd_image::fmt_bytes(stack.bytes()),
        stack.build_method().name(),
        (t2 - t1).as_secs_f64() * 1e3
    )
}

/// The angle and scale maps read from their files, if given.
type Maps = (Option<Vec<f32>>, Option<Vec<f32>>);

/// How the CPU evaluates per-pixel maps, in words (for `-v`).
fn per_pixel_kernel(interpolation: Interpolation, channels: usize, vector: bool) -> String {
    let isa = ifd_simd::isa();
    match isa {
        _ if !vector => "scalar loop (--scalar)".into(),
        ifd_simd::Isa::Baseline => "scalar loop (no AVX2 with FMA, or IFD_SIMD=baseline)".into(),
        _ if channels > 4 => "scalar loop (more than 4 channels)".into(),
        _ => format!(
            "{isa} {}, {} pixels per vector ({} levels)",
            if channels == 1 {
                "row windows or gathers"
            } else {
                "gathers"
            },
            isa.f32_lanes(),
            interpolation.name()
        ),
    }
}

/// `--interp`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum InterpChoice {
    Auto,
    Linear,
    Cubic,
}

fn load_map(input: &InputOptions, path: &Path, what: &str, w: usize, h: usize) -> Result<Vec<f32>> {
    let img = input.read_map(path, what)?;
    if img.channels() != 1 {
        bail!(
            "{what} {} has {} channels, expected 1",
            path.display(),
            img.channels()
        );
    }
    if img.width() != w || img.height() != h {
        bail!(
            "{what} {} is {}x{} but the image is {w}x{h}",
            path.display(),
            img.width(),
            img.height()
        );
    }
    Ok(img.into_vec())
}

/// The angle or scale field of a `w x h` image: the map read from `path`,
/// else the constant given with `flag`, checked as a `kind`; errors name the
/// map file or the option.
fn check_field<'a>(
    (w, h): (usize, usize),
    map: Option<&'a [f32]>,
    constant: f32,
    kind: FieldKind,
    path: Option<&Path>,
    flag: &str,
) -> Result<CheckedField<'a>> {
    let field = map.map_or(Field::Constant(constant), Field::Map);
    CheckedField::new(field, kind, w, h).with_context(|| match path {
        Some(p) => format!("the {} map {}", kind.name(), p.display()),
        None => flag.to_string(),
    })
}

/// The `--gpu` path: upload the stack and the decomposition, evaluate, read
/// back (`device` is how long creating `ctx` took).
fn filter_gpu(
    (ctx, device): (&ifd_gpu::GpuContext, std::time::Duration),
    stack: &ifd_planar::ScaleStack,
    decomposition: &PreparedDecomposition,
    angle: CheckedField<'_>,
    scale: CheckedField<'_>,
    verbose: bool,
) -> Result<ifd_image::Image> {
    use ifd_gpu::{GpuDecomposition, GpuPose, GpuStack};
    let t1 = Instant::now();
    let gs = GpuStack::upload(ctx, stack).context("uploading the scale stack")?;
    let gd = GpuDecomposition::new(ctx, decomposition)?;
    let pose = GpuPose::new(ctx, &gs, angle, scale, Field::Constant(0.0))?;
    let t2 = Instant::now();
    // One evaluation when the result fits in one buffer (with its GPU
    // time), else in bands of rows.
    let (image, out) = match ctx.evaluate(&gs, &gd, &pose, None) {
        Ok(out) => (out.read(ctx)?, Some(out)),
        Err(ifd_gpu::GpuError::Limit { .. }) => (
            ctx.evaluate_image(&gs, &gd, &pose)
                .context("filtering on the GPU")?,
            None,
        ),
        Err(e) => return Err(anyhow::Error::from(e).context("filtering on the GPU")),
    };
    let t3 = Instant::now();
    if verbose {
        let gpu_time = match &out {
            None => "in bands of rows, no GPU time".into(),
            Some(o) => match o.gpu_time(ctx)? {
                Some(t) => format!("{:.2} ms GPU time", t.as_secs_f64() * 1e3),
                None => "no timestamp queries".into(),
            },
        };
        eprintln!(
            "GPU: {} ({:?}); device {:.0} ms, upload {:.1} ms ({} in {} buffer(s)), \
             evaluation + readback {:.1} ms ({gpu_time})",
            ctx.adapter_info().name,
            ctx.adapter_info().device_type,
            device.as_secs_f64() * 1e3,
            (t2 - t1).as_secs_f64() * 1e3,
            ifd_image::fmt_bytes(gs.bytes()),
            gs.buffers(),
            (t3 - t2).as_secs_f64() * 1e3,
        );
    }
    Ok(image)
}

impl Filter {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        if let Some(map) = &self.sigma_map {
            if self.kernel.len() > 1 {
                bail!(
                    "--sigma-map takes one --kernel ({}), given {}",
                    super::sigma_map::KERNEL,
                    self.kernel.len()
                );
            }
            return super::sigma_map::run(&super::sigma_map::SigmaMapRun {
                image: &self.image,
                kernel: self.kernel.first().map(String::as_str),
                map,
                tol: self.tol,
                no_cache: self.no_cache,
                border: self.border,
                output: &self.output,
                verbose: self.verbose,
                input: &self.input,
            });
        }
        crate::output::check_output_path(&self.output.output)?;
        if let Some(b) = self.eval_budget
            && !(b.is_finite() && b > 0.0)
        {
            bail!("--eval-budget {b} must be finite and positive");
        }
        if let Some(map) = &self.regions {
            return self.run_set(map);
        }
        if self.tile == Some(0) {
            bail!("--tile 0: the tile side must be at least 1 pixel");
        }
        let decomposition = self.decomposition()?;
        if self.tile.is_some() {
            return self.run_tiled(&decomposition);
        }
        if !self.gpu
            && let Some(bytes) = self.too_large_whole(&decomposition)?
        {
            if !super::tiled::streams(&self.output.output) {
                bail!(
                    "{}: filtered whole it would need {}, more than the memory budget of {}; \
                     tile by tile it fits, but tiles stream to {} only: write the output as .npy",
                    self.image.display(),
                    ifd_image::fmt_bytes(bytes),
                    ifd_image::fmt_bytes(self.input.budget().limit()),
                    super::tiled::STREAMING
                );
            }
            return self.run_tiled(&decomposition);
        }
        let image = match self.input.read(&self.image) {
            Ok(l) => l.image,
            Err(e) if format!("{e:#}").contains("more than the budget") => bail!(
                "{e:#}; images over the budget are filtered tile by tile when they are {} \
                 (the output too)",
                super::tiled::STREAMING
            ),
            Err(e) => return Err(e),
        };
        let (w, h) = (image.width(), image.height());
        let maps = self.read_maps((w, h))?;
        // Each field is checked once, here, for every path (stack plan, CPU,
        // GPU); errors name the map file or the option.
        let (angle, scale) = self.fields((w, h), &maps)?;
        let options = FilterOptions {
            // The GPU reads every term from the stack: levels at exactly
            // the sigmas a constant scale reads (one lookup per term), else
            // log-uniform levels.
            direct_terms: !self.gpu,
            ..self.options()
        };
        let planning = Instant::now();
        let plan = FilterPlan::new(
            (w, h, image.channels()),
            &decomposition,
            &angle,
            &scale,
            &options,
        )
        .with_context(|| format!("filtering with {}", self.filter_name()))?;
        let planning = planning.elapsed();
        // With --gpu, a stack the device cannot hold is refused before the
        // prefiltering, not after.
        let gpu = if self.gpu {
            let t = Instant::now();
            let ctx = ifd_gpu::GpuContext::new().context("--gpu")?;
            let device = t.elapsed();
            let layout = plan.stack.layout()?;
            ifd_gpu::GpuStack::check_fits(&ctx, (w, h), &layout)?;
            Some((ctx, device))
        } else {
            None
        };
        let per_pixel = (angle.is_map() || scale.is_map()) && gpu.is_none();
        let kernel = per_pixel_kernel(
            plan.eval.interpolation,
            image.channels(),
            plan.vector_kernels,
        );
        let t0 = Instant::now();
        let stack = if gpu.is_some() {
            plan.build_stack(&image)
        } else {
            plan.build_stack_for(&image, &scale)
        }
        .context("prefiltering")?;
        let t1 = Instant::now();
        let out = if let Some((ctx, device)) = &gpu {
            filter_gpu(
                (ctx, *device),
                &stack,
                &plan.decomposition,
                angle,
                scale,
                self.verbose,
            )?
        } else {
            plan.evaluate(&image, &stack, angle, scale)
                .context("filtering")?
        };
        let t2 = Instant::now();
        if self.verbose {
            let levels = if plan.eval.level_error > 0.0 {
                let reads = if plan.eval.nearest_level {
                    "the nearest read"
                } else {
                    "two blended"
                };
                format!(
                    ", {} levels per octave ({reads})",
                    plan.eval.samples_per_octave
                )
            } else {
                String::new()
            };
            eprintln!(
                "evaluation: {} interpolation, pyramid factor {}{levels}, {} terms direct; expected \
                 error {:.3}% on white noise, budget {:.3}% (bound {:.3}%, amplification {:.1})",
                plan.eval.interpolation.name(),
                // 2.828 for 2 sqrt 2; inf: unsubsampled
                (plan.eval.pyramid_factor * 1e3).round() / 1e3,
                plan.direct_terms,
                100.0 * plan.eval.error_estimate,
                100.0 * plan.eval_budget,
                100.0 * plan.eval.total_bound(),
                plan.eval.amplification
            );
            if per_pixel {
                eprintln!("per-pixel lookups: {kernel}");
            }
            let terms = format!("{} terms", decomposition.terms.len());
            eprintln!("{}", timings(&terms, &stack, planning, (t0, t1, t2)));
        }
        self.output.write(&out)
    }
}
