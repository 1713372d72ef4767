//! `ifd decompose SPEC|FILE`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use ifd_planar::decompose_spec;
use ifd_planar::{DecomposeOptions, Decomposition, Kernel, KernelSpec, decompose};
use serde_json::json;

use crate::input::InputOptions;
use crate::options::{ReportOptions, written};
use crate::output::write_output;

/// Decompose a 2D filter into a sparse sum of displaced isotropic Gaussians.
///
/// The filter is a built-in spec (sampled on a (2R+1)^2 grid, R = ceil(4 x the
/// largest sigma) unless `r=` is given) or a kernel file (.npy, .png, .exr;
/// odd sizes, centre at the middle):
///
///   gauss:sx=24,sy=3,theta=30       anisotropic Gaussian (sigmas in px, sum 1)
///   dgauss:order=xx|xy|yy,sigma=4   second derivative of a Gaussian
///   log:sigma=4                     Laplacian of Gaussian
///   gabor:sigma=8,freq=0.1,theta=0  Gabor (frequency in cycles/px)
///   box:w=31,h=5,theta=20           rotated box (sum 1)
///   disk:r=12                       disk (sum 1)
///   line:len=41,width=1,theta=30    motion blur (sum 1)
///
/// Angles are degrees, counter-clockwise on screen.
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct Decompose {
    /// A filter spec such as `gauss:sx=24,sy=3,theta=30`, or a kernel file.
    filter: String,
    /// Where to write the decomposition (JSON, versioned).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Number of bandwidth levels b (default: chosen from the kernel).
    #[arg(long, value_name = "B")]
    levels: Option<usize>,
    /// Most terms allowed.
    #[arg(long, value_name = "S")]
    max_terms: Option<usize>,
    /// Target relative L2 error of the fit.
    #[arg(long, value_name = "E", default_value_t = 0.01)]
    tol: f64,
    /// Regularisation weight relative to ||A^T k||_inf, in (0, 1) (default: chosen from --tol).
    #[arg(long, value_name = "A")]
    alpha: Option<f64>,
    /// Also write a plot: kernel, reconstruction, error, log-histogram of weights per level.
    #[arg(long, value_name = "PNG")]
    plot: Option<PathBuf>,
    #[command(flatten)]
    report: crate::options::ReportOptions,
    /// Fit a built-in spec on a grid this many times finer than the pixels
    /// (1 to 8), so that the sum of Gaussians also matches the filter between
    /// pixel centres, which rotated and scaled copies sample (default: 2 for
    /// the hard-edged box, line and disk, 1 otherwise). Kernel files are
    /// fitted on their own grid.
    #[arg(long, value_name = "Q")]
    oversample: Option<usize>,
    /// The finest atom width, px, that the automatic choice of levels goes
    /// down to (default 0.7).
    #[arg(long, value_name = "PX")]
    min_sigma: Option<f64>,
    /// Pixels of zeros around the kernel's window that the fit also matches
    /// (so that the sum of Gaussians vanishes outside the window too;
    /// default: the kernel's half-size, at least 2).
    #[arg(long, value_name = "PX")]
    margin: Option<usize>,
    /// Fit the L2 error alone. By default every refit is constrained so
    /// that the filter's DC gain (what it multiplies a constant image by)
    /// equals the kernel's sum exactly: flat regions then come out exact,
    /// for at most a term or two more.
    #[arg(long)]
    free_dc: bool,
    #[command(flatten)]
    input: InputOptions,
}

/// Loads a kernel from a spec string or a file (with the spec, if any).
pub fn load_kernel(filter: &str, input: &InputOptions) -> Result<(Kernel, Option<KernelSpec>)> {
    let path = Path::new(filter);
    if path.exists() {
        let img = input.read(path)?.image;
        let k = Kernel::from_image(&img).with_context(|| format!("kernel file {filter}"))?;
        return Ok((k, None));
    }
    if !filter.contains(':') && path.extension().is_some() {
        bail!("{filter}: no such file");
    }
    let spec: KernelSpec = filter
        .parse()
        .with_context(|| format!("filter spec {filter:?}"))?;
    let k = spec
        .to_kernel()
        .with_context(|| format!("filter spec {filter:?}"))?;
    Ok((k, Some(spec)))
}

/// Refuses invalid fit options, naming the option as the command line does
/// (`--max-terms`).
fn check_options(opts: &DecomposeOptions) -> Result<()> {
    if let Err(ifd_planar::DecomposeError::Invalid {
        name,
        value,
        reason,
    }) = opts.validate()
    {
        bail!("--{} {value}: {reason}", name.replace('_', "-"));
    }
    Ok(())
}

/// The fit options at `--tol tol`, refused where the fit would refuse them:
/// for `ifd filter --kernel`, and for the aspect bank of `--sigma-map`.
pub(super) fn fit_options(tol: f64) -> Result<DecomposeOptions> {
    let opts = DecomposeOptions {
        tol,
        ..DecomposeOptions::default()
    };
    check_options(&opts)?;
    Ok(opts)
}

impl Decompose {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let mut opts = DecomposeOptions {
            alpha: self.alpha,
            max_terms: self.max_terms,
            tol: self.tol,
            exact_dc: !self.free_dc,
            ..DecomposeOptions::default()
        };
        // Options first, named as the command line names them.
        check_options(&opts)?;
        if let Some(plot) = &self.plot {
            // the plot's format and folder, before the fit writes anything
            crate::output::check_output_path(plot).context("--plot")?;
        }
        let (kernel, spec) = load_kernel(&self.filter, &self.input)?;
        if let Some(b) = self.levels {
            opts.dictionary.levels = Some(b);
        }
        if let Some(m) = self.min_sigma {
            opts.dictionary.min_sigma = m;
        }
        opts.margin = self.margin;
        let bar = crate::progress::spinner("fitting");
        let tick = |iter: usize, objective: f64, nnz: usize| {
            if iter.is_multiple_of(10) {
                bar.set_message(format!(
                    "iteration {iter}, objective {objective:.3e}, {nnz} non-zero"
                ));
                bar.tick();
            }
        };
        if let Some(q) = self.oversample
            && !(1..=8).contains(&q)
        {
            bail!("--oversample {q}: expected 1 to 8");
        }
        let decomposition = if let Some(s) = &spec {
            decompose_spec(s, &opts, self.oversample, tick)
                .with_context(|| format!("decomposing {s}"))?
        } else {
            if let Some(q) = self.oversample.filter(|&q| q != 1) {
                bail!("--oversample {q}: only built-in specs can be sampled between pixels");
            }
            decompose(&kernel, &opts, tick).context("decomposition failed")?
        };
        bar.finish_and_clear();
        decomposition
            .save(&self.output)
            .with_context(|| format!("writing {}", self.output.display()))?;
        if let Some(plot) = &self.plot {
            let img = ifd_plot::decomposition_plot(&kernel, &decomposition)?;
            write_output(plot, &img, &ifd_image::WriteOptions::default())?;
        }
        let mut wrote = vec![self.output.as_path()];
        wrote.extend(self.plot.as_deref());
        report(&decomposition, self.report, &wrote)
    }
}

fn report(d: &Decomposition, options: ReportOptions, wrote: &[&Path]) -> Result<()> {
    let Some(r) = &d.report else {
        bail!("the fit produced no report");
    };
    let v = json!({
        "terms": r.terms,
        "rel_l2_error": r.rel_l2_error,
        "max_error": r.max_error,
        "dc_error": r.dc_error,
        "iterations": r.iterations,
        "seconds": r.seconds,
        "dictionary_atoms": r.dictionary_atoms,
        "oversample": r.oversample,
        "kernel_sum": r.kernel_sum,
        "dc_gain": r.dc_gain,
        "full_plane_dc_error": r.full_plane_dc_error(),
        "fine_rel_l2_error": r.fine_rel_l2_error,
        "kernel_size": d.kernel_size,
        "spec": d.spec,
    });
    // the listing, every line (-v); the summary leaves out the DC error in
    // the window and the iterations, and says what was written
    let listing = |detail: bool| {
        let mut text = String::new();
        if !detail {
            let files: Vec<String> = wrote.iter().map(|p| written(p)).collect();
            let _ = writeln!(text, "wrote         {}", files.join(", "));
        }
        if let Some((w, h)) = d.kernel_size {
            let _ = writeln!(
                text,
                "kernel        {w}x{h}{}",
                d.spec
                    .as_ref()
                    .map(|s| format!(" ({s})"))
                    .unwrap_or_default()
            );
        }
        let _ = writeln!(
            text,
            "terms         {} (of {} atoms)",
            r.terms, r.dictionary_atoms
        );
        let _ = writeln!(text, "rel. L2 error {:.3}%", 100.0 * r.rel_l2_error);
        if let Some(e) = r.fine_rel_l2_error {
            let _ = writeln!(
                text,
                "  between px  {:.3}% (fitted on a grid {}x finer)",
                100.0 * e,
                r.oversample
            );
        }
        let _ = writeln!(text, "max error     {:.3}% of max |k|", 100.0 * r.max_error);
        if detail {
            let _ = writeln!(text, "DC error      {:.3e} (in the window)", r.dc_error);
        }
        if let (Some(e), Some(k), Some(g)) = (r.full_plane_dc_error(), r.kernel_sum, r.dc_gain) {
            let _ = writeln!(
                text,
                "DC gain       {g:.6} (kernel {k:.6}): a constant image changes by {e:.3e} of its value"
            );
        }
        if detail {
            let _ = writeln!(text, "iterations    {}", r.iterations);
        }
        let _ = writeln!(text, "time          {:.2} s", r.seconds);
        text
    };
    options.emit_detailed(&v, || listing(false), || listing(true))
}
