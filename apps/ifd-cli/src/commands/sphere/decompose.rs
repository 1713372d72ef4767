//! `ifd sphere decompose`: decompose a spherical filter into rotated isotropic lobes.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use ifd_sphere::read_npy_f64;

use ifd_sphere::Decomposition;
use ifd_sphere::ShCoeffs;
use ifd_sphere::{DirectionSet, Sharing};
use ifd_sphere::{IsdBasis, Profile, check_isd_degree};
use ifd_sphere::{Kernel, project_function};
use ifd_sphere::{Negatives, analyze_map, project_samples};
use serde_json::json;

use super::sharing_name;
use crate::input::InputOptions;
use crate::options::ReportOptions;

#[derive(Debug, Clone, Copy, ValueEnum)]
pub(super) enum Directions {
    /// Per-band spherical Fibonacci sets ((L+1)^2 lobes).
    Fibonacci,
    /// One nested set of 2L+1 Fibonacci directions shared by all bands (lobe sharing).
    Shared,
    /// Per-band sets optimised for the conditioning of each `M_l`.
    Optimized,
    /// Shared nested set optimised for the worst `M_l`.
    OptimizedShared,
    /// Per-band uniformly random directions (--seed).
    Random,
}

impl Directions {
    fn build(self, l_max: usize, seed: u64) -> Result<DirectionSet> {
        let name = self
            .to_possible_value()
            .map(|v| v.get_name().to_string())
            .unwrap_or_default();
        Ok(DirectionSet::by_name(&name, l_max, seed)?)
    }
}

/// `ifd sphere decompose SPEC --lmax L -o rzh.json`.
///
/// SPEC is a kernel centred on +z: `phong:s=32` (max(cos,0)^s), `vmf:kappa=50`,
/// `gauss:s=0.2`, `aniso-gauss:s1=0.3,s2=0.05` (radians); or a file: an (N, 4)
/// .npy of samples x,y,z,value (equal weights 4 pi / N), an (N, 5) .npy with a
/// quadrature weight in the last column, a ((L+1)^2, C) or ((L+1)^2,) .npy of SH
/// coefficients (name ending in `.sh.npy`; one set of weights per column), or an
/// image of the kernel, 2:1 equirectangular or a 6:1 cube strip (first channel,
/// projected as --projection says).
///
/// M is dense, (L+1)^2 square, and factorised with an SVD: L is limited to 40.
#[derive(Debug, Args)]
pub(super) struct DecomposeCmd {
    /// Kernel spec or file (see above).
    spec: String,
    /// Maximum degree L (at most 40: M is a dense (L+1)^2 x (L+1)^2 matrix).
    #[arg(long, value_name = "L")]
    lmax: usize,
    /// Lobe directions.
    #[arg(long, value_enum, default_value_t = Directions::Fibonacci)]
    directions: Directions,
    /// Lobe directions from a file instead: an (N, 3) .npy with N = (L+1)^2 (per band, band l
    /// owns rows l^2 .. (l+1)^2) or N = 2L+1 (shared, band l uses the first 2l+1 rows).
    #[arg(long, value_name = "NPY", conflicts_with = "directions")]
    dirs: Option<PathBuf>,
    /// Mother functions: zonal (= rzh), legendre, phong, gauss, vmf, hybrid.
    #[arg(long, default_value = "zonal",
          value_parser = ["zonal", "rzh", "legendre", "phong", "gauss", "vmf", "hybrid"])]
    profile: String,
    /// Seed for random and optimised direction sets.
    #[arg(long, value_name = "N", default_value_t = 1)]
    seed: u64,
    /// Largest accepted condition number of M.
    #[arg(long, default_value_t = 1e10)]
    max_cond: f64,
    /// How a kernel image's texels are projected onto SH: centre (the default: pixel-centre
    /// quadrature with exact solid angles; a kernel image samples a smooth function, whose
    /// weights it recovers to 0.1% on a 64x32 vMF image) or texel (each texel integrated
    /// exactly, the map read as piecewise constant as `ifd sphere sh` and the renderer read
    /// environment maps; 1% on the same image, the texels' box blur kept; 2:1 maps only).
    #[arg(long, value_enum)]
    projection: Option<super::ProjectionArg>,
    /// Output JSON file.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    input: InputOptions,
    #[command(flatten)]
    report: ReportOptions,
}

impl DecomposeCmd {
    fn kernel_coeffs(&self) -> Result<ShCoeffs> {
        let p = Path::new(&self.spec);
        let npy = p.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy"));
        if self.projection.is_some() && (npy || !p.exists()) {
            anyhow::bail!(
                "--projection applies to a kernel image, not to {:?} (a closed-form spec or \
                 an .npy)",
                self.spec
            );
        }
        if p.exists() {
            let name = p.to_string_lossy().to_lowercase();
            if name.ends_with(".sh.npy") {
                return Ok(ShCoeffs::read_npy(p)?.resized(self.lmax)?);
            }
            if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy")) {
                let (shape, data) = read_npy_f64(p)?;
                if let [n, cols @ (4 | 5)] = shape.as_slice() {
                    let (n, cols) = (*n, *cols);
                    let dirs: Vec<[f64; 3]> = (0..n)
                        .map(|i| [data[i * cols], data[i * cols + 1], data[i * cols + 2]])
                        .collect();
                    let vals: Vec<f64> = (0..n).map(|i| data[i * cols + 3]).collect();
                    let w: Vec<f64> = if cols == 5 {
                        (0..n).map(|i| data[i * cols + 4]).collect()
                    } else {
                        vec![4.0 * std::f64::consts::PI / n as f64; n]
                    };
                    return project_samples(self.lmax, &dirs, &w, &vals, 1)
                        .with_context(|| format!("{}", p.display()));
                }
            }
            let img = self.input.read(p)?.image;
            let (a, _) = analyze_map(
                &img,
                self.lmax,
                Negatives::Keep,
                Some(self.projection.map_or(
                    ifd_sphere::Projection::Centre,
                    super::ProjectionArg::projection,
                )),
            )
            .with_context(|| format!("{}", p.display()))?;
            return Ok(ShCoeffs::from_vec(self.lmax, 1, a.coeffs.channel(0))?);
        }
        let k = Kernel::parse(&self.spec)?;
        Ok(project_function(
            self.lmax,
            |w| k.eval(w),
            k.suggested_nodes(self.lmax),
        )?)
    }

    fn direction_set(&self) -> Result<DirectionSet> {
        let Some(path) = &self.dirs else {
            return self.directions.build(self.lmax, self.seed);
        };
        let (shape, data) = read_npy_f64(path)?;
        let l = self.lmax;
        let (per_band, shared) = ((l + 1) * (l + 1), 2 * l + 1);
        let sharing = match shape.as_slice() {
            [n, 3] if *n == per_band => Sharing::PerBand,
            [n, 3] if *n == shared => Sharing::Shared,
            _ => bail!(
                "{}: lobe directions for L = {l} must be a ({per_band}, 3) (per band) or \
                 ({shared}, 3) (shared) array, got shape {shape:?}",
                path.display()
            ),
        };
        let dirs: Vec<[f64; 3]> = data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        DirectionSet::from_dirs(l, sharing, &dirs).with_context(|| format!("{}", path.display()))
    }

    pub(super) fn run(self) -> Result<()> {
        // size check first: the kernel projection and the direction optimiser
        // would otherwise run for a long time before M is refused
        check_isd_degree(self.lmax).with_context(|| format!("--lmax {}", self.lmax))?;
        // a condition number is at least 1; NaN would switch the guard off
        if !(self.max_cond.is_finite() && self.max_cond >= 1.0) {
            bail!(
                "--max-cond {}: the largest accepted condition number must be finite and at least 1",
                ifd_image::short_number(self.max_cond)
            );
        }
        let profile = Profile::parse(&self.profile)?;
        let kc = self.kernel_coeffs()?;
        let dirs = self.direction_set()?;
        let basis = IsdBasis::with_limit(profile, dirs.clone(), self.max_cond).map_err(|e| {
            let per_band = dirs.condition_numbers();
            let (l, c) = per_band
                .iter()
                .enumerate()
                .fold((0, 0.0f64), |a, (l, &c)| if c > a.1 { (l, c) } else { a });
            anyhow::Error::new(e).context(format!(
                "decompose with {} lobe directions (worst band of the direction set: \
                 l = {l}, cond(M_l) = {c:.3e})",
                dirs.all().len()
            ))
        })?;
        let dec = Decomposition::new(&basis, &kc)?;
        let text = dec.to_json()?;
        crate::output::write_text(&self.output, &text)?;
        let channels = dec.weights.channels;
        // seven lines: kept as the summary
        let report = json!({"lmax": self.lmax, "profile": profile.name(),
               "sharing": sharing_name(dec.directions.sharing()),
               "lobes": dec.weights.data.len() / channels.max(1),
               "directions": dec.directions.all().len(),
               "channels": channels,
               "condition_number": dec.condition_number});
        self.report.emit(&report)?;
        Ok(())
    }
}
