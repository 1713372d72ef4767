//! `ifd sphere ...`: spherical harmonics, rotations, isotropic spherical decompositions.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand, ValueEnum};
use ifd_plot::condition_plot;
use ifd_sphere::coeffs::{read_npy_f64, write_npy_f64};
use ifd_sphere::condition::{condition_study, is_singular};
use ifd_sphere::filter::{Decomposition, MapLayout, Prefiltered};
use ifd_sphere::kernel::{Kernel, project_function};
use ifd_sphere::profile::{IsdBasis, MAX_ISD_DEGREE, Profile, check_isd_degree};
use ifd_sphere::transform::{Negatives, analyze_cubemap, analyze_equirect, project_samples};
use ifd_sphere::zhf::{Chooser, DirectionSet, RzhBasis, Sharing};
use ifd_sphere::{EquirectTransform, Rotation, ShCoeffs, ShEvaluator, ShRotation};
use serde_json::json;

use crate::input::{InputOptions, parse_size};

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
    Sh(ShCmd),
    /// Rotate SH coefficients (.npy) by ZHF (Eq. 10), signal-tailored ZHF (Eq. 11) or the reference rotation.
    Rotate(RotateCmd),
    /// Decompose a spherical filter into rotated isotropic lobes (RZH or another profile); write JSON.
    Decompose(DecomposeCmd),
    /// Condition number of M against L for every profile, per-band and shared directions (ISD Fig. 13).
    Condition(ConditionCmd),
    /// Evaluate all real SH up to L at directions from an (N, 3) .npy; write (N, (L+1)^2) float64 .npy.
    Eval(EvalCmd),
    /// Filter an environment map with a decomposition from `sphere decompose` (ISD Eq. 6, 13, 14).
    Filter(FilterCmd),
    /// Tabulate a BRDF's view-dependent ISD lobe weights (ISD Sec. 6.1, 7.1) into a table file.
    Brdf(BrdfCmd),
    /// Radial reflection map of any BRDF under radially symmetric light (ISD Sec. 6.1, Eq. 23-24).
    Radial(crate::commands::radial::RadialCmd),
    /// Filter noisy or sparse BRDF data with a separable vMF kernel on the 4D SH basis (ISD Sec. 6.3).
    BrdfFilter(crate::commands::brdf_filter::BrdfFilterCmd),
    /// Search lobe directions that make the ZHF matrix sparse (ZHF Sec. 5-6, Table I, Fig. 3).
    Sparsity(crate::commands::sparsity::SparsityCmd),
}

impl Sphere {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        match self.command {
            SphereCommand::Sh(c) => c.run(),
            SphereCommand::Rotate(c) => c.run(),
            SphereCommand::Decompose(c) => c.run(),
            SphereCommand::Condition(c) => c.run(),
            SphereCommand::Eval(c) => c.run(),
            SphereCommand::Filter(c) => c.run(),
            SphereCommand::Brdf(c) => c.run(),
            SphereCommand::Radial(c) => c.run(),
            SphereCommand::BrdfFilter(c) => c.run(),
            SphereCommand::Sparsity(c) => c.run(),
        }
    }
}

/// `ifd sphere sh ENVMAP --lmax L -o coeffs.npy [--reconstruct out.hdr]`.
///
/// Layouts, told apart by shape: W = 2H is equirectangular (column u at
/// azimuth 2 pi (u + 0.5) / W, row 0 looking up, +z); W = 6H is a horizontal
/// cubemap strip of six square faces +X, -X, +Y, -Y, +Z, -Z, each in OpenGL's
/// orientation (s to the right, t down). Anything else is refused.
#[derive(Debug, Args)]
struct ShCmd {
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
    #[command(flatten)]
    input: InputOptions,
}

/// Whether a format can store negative samples.
fn stores_negatives(path: &Path) -> Result<bool> {
    use ifd_image::FileFormat;
    Ok(matches!(
        FileFormat::from_path(path)?,
        FileFormat::Exr | FileFormat::Npy
    ))
}

/// Reports negative input samples (clamped, or kept with `--keep-negatives`).
fn note_input_negatives(path: &Path, count: usize, kept: bool) {
    if count > 0 {
        let what = if kept { "kept" } else { "clamped to 0" };
        eprintln!("note: {}: {count} negative samples {what}", path.display());
    }
}

/// Clamps the negatives (ringing) of a band-limited map to 0 when `path`'s
/// format cannot store them, reporting how many; EXR and .npy keep them.
fn clamp_output_negatives(path: &Path, img: &mut ifd_image::Image, what: &str) -> Result<usize> {
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

impl ShCmd {
    fn run(self) -> Result<()> {
        if self.lmax > ifd_sphere::MAX_DEGREE {
            bail!(
                "--lmax {}: at most L = {} is supported",
                self.lmax,
                ifd_sphere::MAX_DEGREE
            );
        }
        // unwritable outputs are refused before the work
        crate::output::check_output_folder(&self.output)?;
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
        let a = if cube {
            analyze_cubemap(&img, self.lmax, neg)
        } else {
            t.analyze(&img, neg)
        }
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
        println!(
            "{}",
            json!({
                "lmax": self.lmax, "channels": a.coeffs.channels(),
                "layout": if cube { "cubemap-strip" } else { "equirect" },
                "width": w, "height": h,
                "negatives": a.negatives_clamped, "seconds": secs,
                "reconstruct_negatives_clamped": rec_clamped,
            })
        );
        Ok(())
    }
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Method {
    /// ZHF standard algorithm (ZHF Eq. 10), shared Fibonacci lobes.
    Zhf,
    /// Signal-tailored ZHF (ZHF Eq. 11), shared Fibonacci lobes.
    Tailored,
    /// Ivanic-Ruedenberg recurrences.
    Reference,
}

/// `ifd sphere rotate coeffs.npy --zyz a,b,c -o out.npy`.
#[derive(Debug, Args)]
struct RotateCmd {
    /// SH coefficients, ((L+1)^2, C) or ((L+1)^2,) .npy (float64 or float32).
    coeffs: PathBuf,
    /// Euler angles a,b,c in radians: R = Rz(a) Ry(b) Rz(c); the result is g(w) = f(R^T w).
    #[arg(long, value_name = "A,B,C", allow_hyphen_values = true)]
    zyz: String,
    /// Rotation algorithm.
    #[arg(long, value_enum, default_value_t = Method::Zhf)]
    method: Method,
    /// Output coefficients (float64 .npy, same shape).
    #[arg(short, long)]
    output: PathBuf,
}

fn parse_triple(s: &str) -> Result<(f64, f64, f64)> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .with_context(|| format!("--zyz {s:?}: expected three numbers a,b,c"))?;
    if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
        bail!("--zyz {s:?}: expected three finite numbers a,b,c (radians)");
    }
    Ok((v[0], v[1], v[2]))
}

impl RotateCmd {
    fn run(self) -> Result<()> {
        let (a, b, c) = parse_triple(&self.zyz)?;
        let f = ShCoeffs::read_npy(&self.coeffs)?;
        let r = Rotation::from_zyz(a, b, c);
        let l = f.l_max();
        let g = match self.method {
            Method::Reference => ShRotation::new(&r, l)?.apply(&f)?,
            Method::Zhf | Method::Tailored => {
                let basis =
                    RzhBasis::new(DirectionSet::new(l, Sharing::Shared, Chooser::Fibonacci)?)?;
                if matches!(self.method, Method::Zhf) {
                    basis.rotate(&f, &r)?
                } else {
                    basis.rotate_tailored(&f, &r)?
                }
            }
        };
        g.write_npy(&self.output)?;
        Ok(())
    }
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Directions {
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
/// equirectangular image (first channel).
///
/// M is dense, (L+1)^2 square, and factorised with an SVD: L is limited to 40.
#[derive(Debug, Args)]
struct DecomposeCmd {
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
    #[arg(long, default_value = "zonal")]
    profile: String,
    /// Seed for random and optimised direction sets.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Largest accepted condition number of M.
    #[arg(long, default_value_t = 1e10)]
    max_cond: f64,
    /// Output JSON file.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    input: InputOptions,
}

impl DecomposeCmd {
    fn kernel_coeffs(&self) -> Result<ShCoeffs> {
        let p = Path::new(&self.spec);
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
            let a = analyze_equirect(&img, self.lmax, Negatives::Keep)
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

    fn run(self) -> Result<()> {
        // size check first: the kernel projection and the direction optimiser
        // would otherwise run for a long time before M is refused
        check_isd_degree(self.lmax).with_context(|| format!("--lmax {}", self.lmax))?;
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
        ifd_image::atomic_write(&self.output, |w| {
            use std::io::Write;
            w.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })?;
        let channels = dec.weights.channels;
        println!(
            "{}",
            json!({"lmax": self.lmax, "profile": profile.name(),
                   "sharing": sharing_name(dec.directions.sharing()),
                   "lobes": dec.weights.data.len() / channels.max(1),
                   "directions": dec.directions.all().len(),
                   "channels": channels,
                   "condition_number": dec.condition_number})
        );
        Ok(())
    }
}

/// `ifd sphere condition --lmax L --plot cond.png` (ISD Fig. 13).
///
/// Plot: x = L (1..=lmax), y = cond(M) on a log scale with a labelled tick every
/// decade; colours (legend on the right): zonal black, legendre blue, phong red,
/// gauss green, vmf orange, hybrid purple; solid = per-band directions, dotted =
/// shared directions. Condition numbers >= 1e16 (beyond f64 precision) or
/// infinite are drawn on a separate top row labelled "> 1e16 (singular)", reported
/// as null in the JSON and flagged in the CSV's `singular` column.
#[derive(Debug, Args)]
struct ConditionCmd {
    /// Largest degree L (1..=40).
    #[arg(long, value_name = "L", default_value_t = 16)]
    lmax: usize,
    /// Write the plot (PNG).
    #[arg(long, value_name = "PNG")]
    plot: Option<PathBuf>,
    /// Write the numbers as CSV (L, profile, sharing, cond, singular).
    #[arg(long, value_name = "CSV")]
    csv: Option<PathBuf>,
}

impl ConditionCmd {
    fn run(self) -> Result<()> {
        if self.lmax == 0 || self.lmax > MAX_ISD_DEGREE {
            bail!(
                "--lmax {}: use 1..={MAX_ISD_DEGREE} (M is a dense (L+1)^2 x (L+1)^2 matrix)",
                self.lmax
            );
        }
        let rows = condition_study(self.lmax)?;
        let lines: Vec<String> = rows
            .iter()
            .flat_map(|r| {
                r.cond.iter().enumerate().map(move |(i, c)| {
                    format!(
                        "{},{},{},{c:e},{}\n",
                        i + 1,
                        r.profile.name(),
                        sharing_name(r.sharing),
                        is_singular(*c)
                    )
                })
            })
            .collect();
        let csv = format!("L,profile,sharing,cond,singular\n{}", lines.concat());
        if let Some(path) = &self.csv {
            ifd_image::atomic_write(path, |w| {
                use std::io::Write;
                w.write_all(csv.as_bytes()).map_err(|e| e.to_string())
            })?;
        }
        if let Some(path) = &self.plot {
            let img = condition_plot(&rows)?;
            crate::output::write_output(path, &img, &ifd_image::WriteOptions::default())?;
        }
        let out: Vec<_> = rows
            .iter()
            .map(|r| {
                json!({"profile": r.profile.name(), "sharing": sharing_name(r.sharing),
                       "cond": r.cond.iter().map(|c| if is_singular(*c) { json!(null) } else { json!(c) }).collect::<Vec<_>>()})
            })
            .collect();
        println!("{}", serde_json::to_string(&out)?);
        Ok(())
    }
}

fn sharing_name(s: Sharing) -> &'static str {
    match s {
        Sharing::PerBand => "per-band",
        Sharing::Shared => "shared",
    }
}

/// `ifd sphere eval --lmax L --dirs dirs.npy -o values.npy`.
#[derive(Debug, Args)]
struct EvalCmd {
    /// Maximum degree L.
    #[arg(long, value_name = "L")]
    lmax: usize,
    /// Directions, (N, 3) .npy (normalised here).
    #[arg(long)]
    dirs: PathBuf,
    /// Use the f32 fast path (values still written as float64).
    #[arg(long)]
    f32: bool,
    /// Output (N, (L+1)^2) float64 .npy.
    #[arg(short, long)]
    output: PathBuf,
}

impl EvalCmd {
    fn run(self) -> Result<()> {
        let (shape, data) = read_npy_f64(&self.dirs)?;
        let [n, 3] = shape.as_slice() else {
            bail!(
                "{}: expected an (N, 3) array, got {shape:?}",
                self.dirs.display()
            );
        };
        let sh = ShEvaluator::new(self.lmax).with_context(|| format!("--lmax {}", self.lmax))?;
        let k = sh.count();
        ifd_image::MemoryBudget::default_for_machine()
            .check((n.saturating_mul(k) as u64).saturating_mul(8))
            .with_context(|| format!("{} directions at --lmax {}", n, self.lmax))?;
        let mut out = vec![0.0; n * k];
        let mut y32 = vec![0.0f32; k];
        for i in 0..*n {
            let d = [data[3 * i], data[3 * i + 1], data[3 * i + 2]];
            ifd_sphere::zhf::check_direction(i, d)
                .with_context(|| format!("--dirs {}", self.dirs.display()))?;
            if self.f32 {
                sh.eval_f32_into([d[0] as f32, d[1] as f32, d[2] as f32], &mut y32);
                for (o, v) in out[i * k..(i + 1) * k].iter_mut().zip(&y32) {
                    *o = f64::from(*v);
                }
            } else {
                sh.eval_into(d, &mut out[i * k..(i + 1) * k]);
            }
        }
        write_npy_f64(&self.output, &[*n, k], &out)?;
        Ok(())
    }
}

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
struct FilterCmd {
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
    /// Output map.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    input: InputOptions,
}

/// Reads a decomposition file, naming the file in every error.
fn read_decomposition(path: &Path) -> Result<Decomposition> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the decomposition", path.display()))?;
    Decomposition::from_json(&text).with_context(|| format!("{}", path.display()))
}

impl FilterCmd {
    fn run(self) -> Result<()> {
        use indicatif::{ProgressBar, ProgressStyle};
        let dec = read_decomposition(&self.decomp)?;
        let l = dec.l_max();
        stores_negatives(&self.output)?;
        let img = self.input.read(&self.envmap)?.image;
        let (w, h) = (img.width(), img.height());
        let in_layout = MapLayout::from_size(w, h).map_err(|_| {
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
        let a = match in_layout {
            MapLayout::Equirect => analyze_equirect(&img, l, neg),
            MapLayout::CubemapStrip => analyze_cubemap(&img, l, neg),
        }
        .with_context(|| format!("{}", self.envmap.display()))?;
        note_input_negatives(&self.envmap, a.negatives_clamped, self.keep_negatives);
        let integral = dec.kernel_integral()?;
        let l1: f64 = dec.weights.data.iter().map(|v| v.abs()).sum();
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
        let bar = ProgressBar::new(oh as u64);
        bar.set_style(
            ProgressStyle::with_template("filtering {bar:30} {pos}/{len} rows [{elapsed}]")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let mut out = dec.filter_map(&pre, ow, oh, scale, &|done, _| {
            bar.set_position(done as u64);
        })?;
        bar.finish_and_clear();
        let secs = start.elapsed().as_secs_f64();
        let clamped = clamp_output_negatives(&self.output, &mut out, "result")?;
        crate::output::write_output(&self.output, &out, &ifd_image::WriteOptions::default())?;
        println!(
            "{}",
            json!({
                "lmax": l, "channels": out.channels(),
                "layout": match MapLayout::from_size(ow, oh)? {
                    MapLayout::Equirect => "equirect",
                    MapLayout::CubemapStrip => "cubemap-strip",
                },
                "width": ow, "height": oh,
                "kernel_integral": integral, "scale": scale,
                "input_negatives": a.negatives_clamped,
                "output_negatives_clamped": clamped,
                "seconds": secs,
            })
        );
        Ok(())
    }
}

/// `ifd sphere brdf SPEC --lmax L -o table.lobes`.
///
/// SPEC is a BRDF (not a kernel of `sphere decompose`): `lambert`, `phong:s=32`
/// (normalised, about the mirror direction, cosine folded in), `blinn:s=64`
/// ((s+8)/(8 pi)) or `blinn-exact:s=64` (normalised exactly at normal view),
/// `ggx:alpha=0.3` or `ggx:ax=0.1,ay=0.4` (optional `f0=` for Schlick
/// Fresnel), `ward:ax=0.1,ay=0.3`, `merl:FILE`; each but merl takes
/// `albedo=` (default 1). Formulas: `cargo doc -p ifd-shade` (module `brdf`).
///
/// For each view direction of the table, the cosine-weighted slice
/// `k_wo(wi) = rho(wi, wo) max(cos, 0)` is projected on SH up to L and
/// decomposed into rotated zonal lobes shared by all bands. Isotropic BRDFs
/// get a 1D table over theta_o (frame rotated to phi_o = 0, where the slice is
/// even across the plane of the normal and the view, so L+1 lobes in that
/// plane suffice), anisotropic ones a 2D table over (theta_o, phi_o) with 2L+1
/// lobes. The interpolation error (relative L2
/// of the interpolated slice at the midpoints between entries) is measured and
/// reported. The file is binary with a JSON header (2D tables reach tens of
/// MB, which JSON text would triple), versioned and self-describing.
#[derive(Debug, Args)]
struct BrdfCmd {
    /// BRDF spec (see above).
    spec: String,
    /// Maximum SH degree L (at most 100).
    #[arg(long, value_name = "L")]
    lmax: usize,
    /// Entries over theta_o (default: from the lobe width, 16..=512).
    #[arg(long, value_name = "N")]
    theta_entries: Option<usize>,
    /// Entries over phi_o for anisotropic BRDFs (default: 2x the theta entries, at most 128).
    #[arg(long, value_name = "N")]
    phi_entries: Option<usize>,
    /// Lobe layout: auto (in-plane for isotropic BRDFs, shared for anisotropic
    /// ones), shared (2L+1 directions, any BRDF; for comparison) or in-plane
    /// (L+1 directions, isotropic BRDFs only).
    #[arg(long, value_name = "LAYOUT", default_value = "auto",
          value_parser = ["auto", "shared", "in-plane"])]
    lobes: String,
    /// Output table file (binary, conventionally .lobes).
    #[arg(short, long)]
    output: PathBuf,
}

impl BrdfCmd {
    fn run(self) -> Result<()> {
        use ifd_shade::table::{LobeTable, MAX_TABLE_DEGREE, default_theta_entries};
        use indicatif::{ProgressBar, ProgressStyle};
        if self.lmax > MAX_TABLE_DEGREE {
            bail!(
                "--lmax {}: lobe tables support L <= {MAX_TABLE_DEGREE}",
                self.lmax
            );
        }
        let brdf = ifd_shade::Brdf::parse(&self.spec)?;
        // an unwritable output is refused before the work
        crate::output::check_output_folder(&self.output)?;
        let nt = self
            .theta_entries
            .unwrap_or_else(|| default_theta_entries(&brdf));
        let np = self.phi_entries.unwrap_or((2 * nt).min(128));
        let start = std::time::Instant::now();
        let bar = ProgressBar::new(0);
        bar.set_style(
            ProgressStyle::with_template("slices {bar:30} {pos}/{len} [{elapsed}<{eta}]")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let kind = match self.lobes.as_str() {
            "shared" => ifd_shade::table::LobeKind::Shared,
            "in-plane" => ifd_shade::table::LobeKind::InPlane,
            _ => ifd_shade::table::LobeKind::default_for(&brdf),
        };
        let table = LobeTable::build_with(&brdf, self.lmax, nt, np, kind, &|done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })?;
        bar.finish_and_clear();
        table.write(&self.output)?;
        let h = table.header();
        let albedo = table.entry_albedos();
        let (amin, amax) = albedo
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        println!(
            "{}",
            json!({
                "brdf": h.brdf, "lmax": h.l_max, "isotropic": h.isotropic,
                "channels": h.channels, "theta_entries": h.n_theta, "phi_entries": h.n_phi,
                "lobes": table.basis().directions().len(),
                "lobe_layout": h.lobes.name(),
                "weight_bytes": table.weight_bytes(),
                "interpolation_error": h.interpolation_error,
                "interpolation_rms": h.interpolation_rms,
                "albedo_min": amin, "albedo_max": amax,
                "seconds": start.elapsed().as_secs_f64(),
            })
        );
        Ok(())
    }
}
