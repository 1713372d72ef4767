//! `ifd sphere ...`: spherical harmonics, rotations, isotropic spherical decompositions.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand, ValueEnum};
use ifd_image::Image;
use ifd_sphere::coeffs::{read_npy_f64, write_npy_f64};
use ifd_sphere::filter::Decomposition;
use ifd_sphere::kernel::{Kernel, project_function};
use ifd_sphere::profile::{IsdBasis, Profile};
use ifd_sphere::transform::{Negatives, analyze_equirect, project_samples};
use ifd_sphere::zhf::{Chooser, DirectionSet, RzhBasis, Sharing};
use ifd_sphere::{EquirectTransform, Rotation, ShCoeffs, ShEvaluator, ShRotation};
use serde_json::json;

use crate::input::InputOptions;

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
    /// Project an equirectangular (2:1) environment map onto SH; write ((L+1)^2, C) float64 .npy.
    Sh(ShCmd),
    /// Rotate SH coefficients (.npy) by ZHF (Eq. 10), signal-tailored ZHF (Eq. 11) or the reference rotation.
    Rotate(RotateCmd),
    /// Decompose a spherical filter into rotated isotropic lobes (RZH or another profile); write JSON.
    Decompose(DecomposeCmd),
    /// Condition number of M against L for every profile, per-band and shared directions (ISD Fig. 13).
    Condition(ConditionCmd),
    /// Evaluate all real SH up to L at directions from an (N, 3) .npy; write (N, (L+1)^2) float64 .npy.
    Eval(EvalCmd),
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
        }
    }
}

/// `ifd sphere sh ENVMAP --lmax L -o coeffs.npy`.
#[derive(Debug, Args)]
struct ShCmd {
    /// Equirectangular map (2:1; row 0 looks up, +z); EXR, HDR, PNG, ... or .npy.
    envmap: PathBuf,
    /// Maximum SH degree L.
    #[arg(long, value_name = "L")]
    lmax: usize,
    /// Output coefficients, ((L+1)^2, C) float64 .npy.
    #[arg(short, long)]
    output: PathBuf,
    /// Also write the band-limited reconstruction (same size as the input).
    #[arg(long, value_name = "IMAGE")]
    reconstruct: Option<PathBuf>,
    /// Keep negative samples (default: clamp them to 0 and report how many).
    #[arg(long)]
    keep_negatives: bool,
    #[command(flatten)]
    input: InputOptions,
}

impl ShCmd {
    fn run(self) -> Result<()> {
        let img = self.input.read(&self.envmap)?.image;
        let t = EquirectTransform::new(self.lmax, img.width(), img.height())
            .with_context(|| format!("{}", self.envmap.display()))?;
        let neg = if self.keep_negatives {
            Negatives::Keep
        } else {
            Negatives::Clamp
        };
        let start = std::time::Instant::now();
        let a = t
            .analyze(&img, neg)
            .with_context(|| format!("{}", self.envmap.display()))?;
        let secs = start.elapsed().as_secs_f64();
        if a.negatives_clamped > 0 {
            eprintln!(
                "note: {}: {} negative samples {}",
                self.envmap.display(),
                a.negatives_clamped,
                if self.keep_negatives {
                    "kept"
                } else {
                    "clamped to 0"
                }
            );
        }
        a.coeffs.write_npy(&self.output)?;
        if let Some(path) = &self.reconstruct {
            let rec = t.synthesize(&a.coeffs)?;
            crate::input::write_output(path, &rec, &ifd_image::WriteOptions::default())?;
        }
        println!(
            "{}",
            json!({
                "lmax": self.lmax, "channels": a.coeffs.channels(),
                "width": img.width(), "height": img.height(),
                "negatives": a.negatives_clamped, "seconds": secs,
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
        let iterations = 300;
        Ok(match self {
            Self::Fibonacci => DirectionSet::new(l_max, Sharing::PerBand, Chooser::Fibonacci)?,
            Self::Shared => DirectionSet::new(l_max, Sharing::Shared, Chooser::Fibonacci)?,
            Self::Optimized => DirectionSet::new(
                l_max,
                Sharing::PerBand,
                Chooser::Optimized { seed, iterations },
            )?,
            Self::OptimizedShared => DirectionSet::new(
                l_max,
                Sharing::Shared,
                Chooser::Optimized { seed, iterations },
            )?,
            Self::Random => DirectionSet::new(l_max, Sharing::PerBand, Chooser::Random { seed })?,
        })
    }
}

/// `ifd sphere decompose SPEC --lmax L -o rzh.json`.
///
/// SPEC is a kernel centred on +z: `phong:s=32` (max(cos,0)^s), `vmf:kappa=50`,
/// `gauss:s=0.2`, `aniso-gauss:s1=0.3,s2=0.05` (radians); or a file: an (N, 4)
/// .npy of samples x,y,z,value (equal weights 4 pi / N), an (N, 5) .npy with a
/// quadrature weight in the last column, a ((L+1)^2,) .npy of SH coefficients
/// (name ending in `.sh.npy`), or an equirectangular image.
#[derive(Debug, Args)]
struct DecomposeCmd {
    /// Kernel spec or file (see above).
    spec: String,
    /// Maximum degree L.
    #[arg(long, value_name = "L")]
    lmax: usize,
    /// Lobe directions.
    #[arg(long, value_enum, default_value_t = Directions::Fibonacci)]
    directions: Directions,
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

    fn run(self) -> Result<()> {
        let profile = Profile::parse(&self.profile)?;
        let kc = self.kernel_coeffs()?;
        let dirs = self.directions.build(self.lmax, self.seed)?;
        let basis = IsdBasis::with_limit(profile, dirs, self.max_cond)?;
        let dec = Decomposition::new(&basis, &kc)?;
        let text = dec.to_json()?;
        ifd_image::atomic_write(&self.output, |w| {
            use std::io::Write;
            w.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })?;
        println!(
            "{}",
            json!({"lmax": self.lmax, "profile": profile.name(), "lobes": dec.weights.data.len(),
                   "condition_number": dec.condition_number})
        );
        Ok(())
    }
}

/// `ifd sphere condition --lmax L --plot cond.png` (ISD Fig. 13).
///
/// Plot: x = L (1..=lmax), y = log10 cond(M) (grid line every decade). Colours:
/// zonal black, legendre blue, phong red, gauss green, vmf orange, hybrid purple;
/// solid = per-band directions, dotted = shared directions.
#[derive(Debug, Args)]
struct ConditionCmd {
    /// Largest degree L.
    #[arg(long, value_name = "L", default_value_t = 16)]
    lmax: usize,
    /// Write the plot (PNG).
    #[arg(long, value_name = "PNG")]
    plot: Option<PathBuf>,
    /// Write the numbers as CSV (L, profile, sharing, cond).
    #[arg(long, value_name = "CSV")]
    csv: Option<PathBuf>,
}

impl ConditionCmd {
    fn run(self) -> Result<()> {
        if self.lmax == 0 || self.lmax > 40 {
            bail!("--lmax {}: use 1..=40 (M is (L+1)^2 square)", self.lmax);
        }
        let mut rows = Vec::new();
        for profile in Profile::ALL {
            for sharing in [Sharing::PerBand, Sharing::Shared] {
                let mut series = Vec::new();
                for l in 1..=self.lmax {
                    let dirs = DirectionSet::new(l, sharing, Chooser::Fibonacci)?;
                    let (m, _) = ifd_sphere::profile::isd_matrix(profile, &dirs)?;
                    series.push(ifd_sphere::zhf::condition_number(&m));
                }
                rows.push((profile, sharing, series));
            }
        }
        let lines: Vec<String> = rows
            .iter()
            .flat_map(|(p, s, series)| {
                series.iter().enumerate().map(move |(i, c)| {
                    format!("{},{},{},{c:e}\n", i + 1, p.name(), sharing_name(*s))
                })
            })
            .collect();
        let csv = format!("L,profile,sharing,cond\n{}", lines.concat());
        if let Some(path) = &self.csv {
            ifd_image::atomic_write(path, |w| {
                use std::io::Write;
                w.write_all(csv.as_bytes()).map_err(|e| e.to_string())
            })?;
        }
        if let Some(path) = &self.plot {
            let img = plot(&rows, self.lmax)?;
            crate::input::write_output(path, &img, &ifd_image::WriteOptions::default())?;
        }
        let out: Vec<_> = rows
            .iter()
            .map(|(p, s, v)| {
                json!({"profile": p.name(), "sharing": sharing_name(*s),
                       "cond": v.iter().map(|c| if c.is_finite() { json!(c) } else { json!(null) }).collect::<Vec<_>>()})
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

/// Draws the Fig. 13 curves into an RGB image.
fn plot(rows: &[(Profile, Sharing, Vec<f64>)], l_max: usize) -> Result<Image> {
    let (w, h, pad) = (900usize, 600usize, 50usize);
    let mut img = Image::from_vec(w, h, 3, vec![1.0; w * h * 3])?;
    let finite: Vec<f64> = rows
        .iter()
        .flat_map(|r| r.2.iter().copied())
        .filter(|c| c.is_finite() && *c > 0.0)
        .collect();
    let ymax = finite
        .iter()
        .fold(1.0f64, |a, b| a.max(b.log10()))
        .ceil()
        .max(1.0);
    let to_px = |l: f64, c: f64| -> (f64, f64) {
        let x = pad as f64 + (l - 1.0) / ((l_max.max(2) - 1) as f64) * (w - 2 * pad) as f64;
        let y = (h - pad) as f64 - c.max(1.0).log10().min(ymax) / ymax * (h - 2 * pad) as f64;
        (x, y)
    };
    let put = |img: &mut Image, x: f64, y: f64, col: [f32; 3]| {
        let (xi, yi) = (x.round() as i64, y.round() as i64);
        if xi >= 0 && yi >= 0 && (xi as usize) < w && (yi as usize) < h {
            for (c, v) in col.iter().enumerate() {
                img.set(xi as usize, yi as usize, c, *v);
            }
        }
    };
    // decade grid and axes
    for d in 0..=ymax as usize {
        let (_, y) = to_px(1.0, 10f64.powi(d as i32));
        for x in pad..w - pad {
            put(
                &mut img,
                x as f64,
                y,
                if d == 0 { [0.0; 3] } else { [0.85; 3] },
            );
        }
    }
    for l in 1..=l_max {
        let (x, _) = to_px(l as f64, 1.0);
        for y in pad..h - pad {
            if l == 1 || y % 6 == 0 {
                put(
                    &mut img,
                    x,
                    y as f64,
                    if l == 1 { [0.0; 3] } else { [0.9; 3] },
                );
            }
        }
    }
    for (p, s, series) in rows {
        let col = match p {
            Profile::Zonal => [0.0, 0.0, 0.0],
            Profile::Legendre => [0.1, 0.3, 0.9],
            Profile::Phong => [0.9, 0.1, 0.1],
            Profile::Gauss => [0.1, 0.7, 0.2],
            Profile::Vmf => [1.0, 0.6, 0.0],
            Profile::Hybrid => [0.6, 0.2, 0.8],
        };
        for (i, pair) in series.windows(2).enumerate() {
            let (x0, y0) = to_px(
                (i + 1) as f64,
                if pair[0].is_finite() { pair[0] } else { 1e300 },
            );
            let (x1, y1) = to_px(
                (i + 2) as f64,
                if pair[1].is_finite() { pair[1] } else { 1e300 },
            );
            let steps = ((x1 - x0).abs().max((y1 - y0).abs()) as usize).max(1);
            for k in 0..=steps {
                if *s == Sharing::Shared && (k / 4) % 2 == 1 {
                    continue;
                }
                let t = k as f64 / steps as f64;
                let (x, y) = (x0 + t * (x1 - x0), y0 + t * (y1 - y0));
                for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)] {
                    put(&mut img, x + dx, y + dy, col);
                }
            }
        }
    }
    Ok(img)
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
        let sh = ShEvaluator::new(self.lmax)?;
        let k = sh.count();
        let mut out = vec![0.0; n * k];
        let mut y32 = vec![0.0f32; k];
        for i in 0..*n {
            let d = [data[3 * i], data[3 * i + 1], data[3 * i + 2]];
            ifd_sphere::zhf::check_direction(i, d)?;
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
