//! `ifd filter IMAGE --kernel gauss --sigma-map M.npy`: a normalised
//! anisotropic Gaussian per pixel (`ifd_smooth::filter_sigma_map`), from the
//! aspect bank `ifd smooth` uses and caches.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use ifd_planar::Border;
use ifd_smooth::{AspectBank, BankOptions};

use crate::input::InputOptions;
use crate::output::ImageOutput;

/// The only kernel `--sigma-map` takes.
pub const KERNEL: &str = "gauss";

/// What `ifd filter` passes on when `--sigma-map` is given.
pub struct SigmaMapRun<'a> {
    /// The image.
    pub image: &'a Path,
    /// `--kernel` (must be `gauss`).
    pub kernel: Option<&'a str>,
    /// The H x W x 3 map.
    pub map: &'a Path,
    /// `--tol`: the relative L2 error each bank entry is fitted to (the
    /// shared bank's 1% when not given).
    pub tol: Option<f64>,
    /// `--no-cache`: fit the bank afresh, neither reading nor writing the
    /// cache.
    pub no_cache: bool,
    /// `--border`.
    pub border: Border,
    /// `-o` and its encoding.
    pub output: &'a ImageOutput,
    /// `--verbose`.
    pub verbose: bool,
    /// How the image and the map are read.
    pub input: &'a InputOptions,
}

/// Runs `ifd filter IMAGE --kernel gauss --sigma-map M.npy -o OUT`.
pub fn run(r: &SigmaMapRun<'_>) -> Result<()> {
    match r.kernel {
        Some(KERNEL) => {}
        Some(other) => bail!(
            "--kernel {other:?} with --sigma-map: the sigma map gives each pixel its own \
             Gaussian, so the only kernel it takes is `--kernel {KERNEL}`"
        ),
        None => bail!("--sigma-map needs `--kernel {KERNEL}`"),
    }
    crate::output::check_output_path(&r.output.output)?;
    let image = r.input.read(r.image)?.image;
    let (w, h) = (image.width(), image.height());
    let map_path = r.map.display();
    let map = r.input.read_map(r.map, "sigma map").map_err(|e| {
        // The reader's refusal of non-finite values, in the words of the
        // map's other checks.
        let first = e.chain().find_map(|c| match c.downcast_ref() {
            Some(ifd_image::ImageError::NonFinite {
                count,
                x,
                y,
                channel,
                ..
            }) => Some((*count, *x, *y, *channel)),
            _ => None,
        });
        match first {
            Some((count, x, y, k)) => anyhow::anyhow!(
                "{map_path}: sigma map: pixel ({x}, {y}), channel {k} ({}): not finite (NaN or \
                 infinite; {count} such values in the map)",
                ifd_smooth::SIGMA_MAP_CHANNELS
                    .get(k)
                    .copied()
                    .unwrap_or("extra channel")
            ),
            None => e,
        }
    })?;
    let bank_options = BankOptions {
        tol: r.tol.unwrap_or(BankOptions::default().tol),
        ..BankOptions::default()
    };
    super::decompose::fit_options(bank_options.tol)?;
    // Checked before the bank is loaded or fitted: bad maps are refused at once.
    ifd_smooth::sigma_map_gaussians(map.view(), (w, h), bank_options.max_aspect)
        .with_context(|| format!("{map_path}"))?;
    let t0 = Instant::now();
    let bar = crate::progress::bar("decomposing filters", "", 0);
    let cache = if r.no_cache {
        None
    } else {
        bank_cache(&bank_options)
    };
    let (bank, source) =
        AspectBank::load_or_build(bank_options, cache.as_deref(), crate::progress::track(&bar))?;
    bar.finish_and_clear();
    let t1 = Instant::now();
    let out =
        ifd_smooth::filter_sigma_map(&image, map.view(), &bank, r.border).with_context(|| {
            format!(
                "filtering {} with the sigma map {map_path}",
                r.image.display()
            )
        })?;
    let t2 = Instant::now();
    if r.verbose {
        eprintln!(
            "aspect bank: {source} ({} entries, aspects 1 to {}); bank {:.1} ms, filtering {:.1} ms",
            bank.aspects.len(),
            bank.options.max_aspect,
            (t1 - t0).as_secs_f64() * 1e3,
            (t2 - t1).as_secs_f64() * 1e3
        );
    }
    r.output.write(&out)
}

/// Where the bank fitted with `options` is cached: the shared default
/// bank's file ([`AspectBank::default_cache`], which `ifd smooth` reads too)
/// at the default tolerance, else a file of its own beside it named for the
/// tolerance, so that banks of different tolerances do not replace each
/// other.
fn bank_cache(options: &BankOptions) -> Option<std::path::PathBuf> {
    let shared = AspectBank::default_cache()?;
    if options.tol == BankOptions::default().tol {
        return Some(shared);
    }
    let stem = shared.file_stem()?.to_string_lossy().into_owned();
    Some(shared.with_file_name(format!("{stem}-tol{}.json", options.tol)))
}
