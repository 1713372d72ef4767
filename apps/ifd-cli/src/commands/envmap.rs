//! `ifd envmap`: image-based lighting assets for engines.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use ifd_ibl::chain::{RoughnessMapping, check_chain};
use ifd_ibl::cube::{CubeLevel, FACE_FILE_NAMES, strip_to_equirect};
use ifd_ibl::lobe::Lobe;
use ifd_ibl::{BakeOptions, Baker};
use serde_json::json;

use crate::input::InputOptions;

/// `ifd envmap prefilter|dfg`.
#[derive(Debug, Args)]
pub struct Envmap {
    #[command(subcommand)]
    command: EnvmapCommand,
}

#[derive(Debug, Subcommand)]
enum EnvmapCommand {
    /// Bake GGX-prefiltered radiance mips, an irradiance map and SH coefficients (KTX2 or EXR).
    Prefilter(Box<PrefilterCmd>),
    /// Write the split-sum DFG table (x = N.V, y = roughness; R = scale, G = bias).
    Dfg(DfgCmd),
    /// Reproduce the SHRM paper's Table 4: Phong prefiltering, angular against frequency space.
    Shrm(ShrmCmd),
}

impl Envmap {
    pub fn run(self) -> Result<()> {
        match self.command {
            EnvmapCommand::Prefilter(c) => c.run(),
            EnvmapCommand::Dfg(c) => c.run(),
            EnvmapCommand::Shrm(c) => c.run(),
        }
    }
}

/// Bakes what engines load for image-based lighting, from an equirectangular
/// (2:1) map or a cube strip (6:1, faces +X,-X,+Y,-Y,+Z,-Z, y up):
///
///   OUTDIR/radiance.ktx2    RGBA16F cube, mip m = GGX with roughness m/(M-1)
///   OUTDIR/irradiance.ktx2  RGBA16F cube, one level, E/pi (what glTF/Bevy hold)
///   OUTDIR/sh.json, sh.npy  SH of the radiance (ifd's frame and basis, stated in the JSON)
///
/// With --format exr the cubes are EXR faces instead: radiance_m{m}_{px,nx,py,ny,pz,nz}.exr
/// and irradiance_{face}.exr. Faces are in the order and orientation engines expect
/// (y up); the map is read as glTF-IBL-Sampler reads it. The prefilter runs in
/// frequency space (SH convolution with the lobe's zonal factors) with the
/// brightest texels summed exactly, so suns do not ring; see docs/ibl.md.
#[derive(Debug, Args)]
struct PrefilterCmd {
    /// Environment map (HDR, EXR, ...): 2:1 equirectangular or a 6:1 cube strip.
    envmap: PathBuf,
    /// Radiance face size, a power of two.
    #[arg(long, default_value_t = 256, value_name = "N")]
    face_size: usize,
    /// Number of radiance mip levels (default: floor(log2 N) for linear, down to 16 texels for cmgen).
    #[arg(long, value_name = "M")]
    mips: Option<usize>,
    /// Mip-to-roughness mapping: linear (m/(M-1), glTF-IBL-Sampler, Bevy) or cmgen (Filament).
    #[arg(long, default_value = "linear")]
    roughness: String,
    /// Lobe: ggx (the split-sum GGX lobe), phong (the Phong lobe matching each mip's GGX
    /// width, s = 1/(2 alpha^2) - 1/2), or phong:s=S (one level filtered with exponent S).
    #[arg(long, default_value = "ggx")]
    brdf: String,
    /// Irradiance face size (0: no irradiance map).
    #[arg(long, default_value_t = 32, value_name = "N")]
    irradiance_size: usize,
    /// Maximum SH degree of sh.json / sh.npy.
    #[arg(long, default_value_t = 2, value_name = "L")]
    sh_lmax: usize,
    /// Output format of the cubes: ktx2 or exr.
    #[arg(long, default_value = "ktx2")]
    format: String,
    /// Band truncation: each lobe keeps the bands whose zonal factor is at least eps.
    #[arg(long, default_value_t = 1e-3)]
    eps: f64,
    /// Output folder (created if missing; files in it are replaced).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    input: InputOptions,
}

/// The lobes of the radiance chain and what each mip reports.
fn chain_lobes(brdf: &str, mapping: RoughnessMapping, levels: usize) -> Result<Vec<(f64, Lobe)>> {
    let mut out = Vec::with_capacity(levels);
    if let Some(rest) = brdf.strip_prefix("phong:") {
        let s = rest
            .strip_prefix("s=")
            .and_then(|v| v.parse::<f64>().ok())
            .filter(|s| s.is_finite() && *s > 0.0 && *s <= 1e6)
            .with_context(|| {
                format!("--brdf {brdf:?}: expected phong:s=S with 0 < S <= 1e6, e.g. phong:s=64")
            })?;
        out.push((f64::NAN, Lobe::Phong { s }));
        return Ok(out);
    }
    for m in 0..levels {
        let r = mapping.roughness(m, levels);
        let ggx = Lobe::ggx_from_roughness(r)?;
        let lobe = match (brdf, ggx) {
            ("phong", Lobe::Ggx { alpha }) => Lobe::phong_matching_ggx(alpha),
            ("ggx" | "phong", l) => l,
            _ => bail!("--brdf {brdf:?}: unknown lobe; use ggx, phong or phong:s=S"),
        };
        out.push((r, lobe));
    }
    Ok(out)
}

impl PrefilterCmd {
    #[expect(
        clippy::too_many_lines,
        reason = "one linear bake: read, plan, filter, write"
    )]
    fn run(self) -> Result<()> {
        use indicatif::{ProgressBar, ProgressStyle};
        let mapping = RoughnessMapping::parse(&self.roughness)?;
        let n = self.face_size;
        let single = self.brdf.starts_with("phong:");
        let levels = if single {
            if self.mips.is_some_and(|m| m != 1) {
                bail!("--mips: --brdf {} writes one level", self.brdf);
            }
            1
        } else {
            self.mips.unwrap_or_else(|| mapping.default_levels(n))
        };
        check_chain(n, levels)?;
        if self.irradiance_size > 0
            && (!self.irradiance_size.is_power_of_two() || self.irradiance_size > 4096)
        {
            bail!(
                "--irradiance-size {}: must be 0 (none) or a power of two up to 4096",
                self.irradiance_size
            );
        }
        if self.sh_lmax > 64 {
            bail!("--sh-lmax {}: at most 64", self.sh_lmax);
        }
        let exr = match self.format.as_str() {
            "ktx2" => false,
            "exr" => true,
            f => bail!("--format {f:?}: use ktx2 or exr"),
        };
        if !(self.eps > 0.0 && self.eps < 1.0) {
            bail!("--eps {}: must lie in (0, 1)", self.eps);
        }
        let lobes = chain_lobes(&self.brdf, mapping, levels)?;
        // the outputs against the memory budget, before any work: f32 RGB
        // levels plus their 8-byte RGBA16F encoding
        let texels: u64 = (0..levels)
            .map(|m| 6 * ((n >> m).max(1) as u64).pow(2))
            .sum::<u64>()
            + 6 * (self.irradiance_size as u64).pow(2);
        self.input
            .budget()
            .check(texels.saturating_mul(12 + 8))
            .with_context(|| format!("--face-size {n} with {levels} levels"))?;
        let start = Instant::now();
        let img = self.input.read(&self.envmap)?.image;
        let (w, h) = (img.width(), img.height());
        let env = if w == 2 * h && h >= 2 {
            img
        } else if w == 6 * h && h >= 1 {
            strip_to_equirect(&img).with_context(|| format!("{}", self.envmap.display()))?
        } else {
            bail!(
                "{}: a map must be 2:1 (equirectangular) or 6:1 (cube strip +X,-X,+Y,-Y,+Z,-Z); got {w}x{h}",
                self.envmap.display()
            );
        };
        let read_s = start.elapsed().as_secs_f64();
        let mut all: Vec<Lobe> = lobes.iter().map(|(_, l)| *l).collect();
        if self.irradiance_size > 0 {
            all.push(Lobe::Lambert);
        }
        let opts = BakeOptions {
            eps: self.eps,
            ..BakeOptions::default()
        };
        let t0 = Instant::now();
        let baker =
            Baker::new(&env, &opts, &all).with_context(|| format!("{}", self.envmap.display()))?;
        let analysis_s = t0.elapsed().as_secs_f64();
        if baker.input_negatives() > 0 {
            eprintln!(
                "note: {}: clamped {} negative samples to 0",
                self.envmap.display(),
                baker.input_negatives()
            );
        }
        let bar = ProgressBar::new(all.len() as u64);
        bar.set_style(
            ProgressStyle::with_template("prefiltering {bar:30} {pos}/{len} levels [{elapsed}]")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let mut chain = Vec::with_capacity(levels);
        let mut report = Vec::with_capacity(levels);
        for (m, (r, lobe)) in lobes.iter().enumerate() {
            let t = Instant::now();
            let size = (n >> m).max(1);
            let (level, stats) = baker.level(lobe, size)?;
            if stats.capped {
                eprintln!(
                    "warning: mip {m}: the lobe needs more than degree {} for --eps {}; its sharpest detail is truncated",
                    stats.l_max, self.eps
                );
            }
            report.push(json!({
                "mip": m, "size": size,
                "roughness": if r.is_nan() { None } else { Some(r) },
                "lobe": lobe_json(lobe),
                "lmax": stats.l_max, "capped": stats.capped,
                "bright_samples": stats.bright_samples,
                "negatives_clamped": stats.negatives_clamped,
                "seconds": t.elapsed().as_secs_f64(),
            }));
            chain.push(level);
            bar.inc(1);
        }
        let irradiance = if self.irradiance_size > 0 {
            let t = Instant::now();
            let (level, stats) = baker.level(&Lobe::Lambert, self.irradiance_size)?;
            bar.inc(1);
            Some((level, stats, t.elapsed().as_secs_f64()))
        } else {
            None
        };
        bar.finish_and_clear();
        let sh = baker.source_sh(self.sh_lmax)?;
        let bake_s = t0.elapsed().as_secs_f64();
        // write everything into a staging folder, then move it into place
        let files = Staging::new(&self.output)?;
        let mut half_clamped = 0;
        if exr {
            for (m, level) in chain.iter().enumerate() {
                for (f, name) in FACE_FILE_NAMES.iter().enumerate() {
                    files.write_exr(&format!("radiance_m{m}_{name}.exr"), level, f)?;
                }
            }
            if let Some((level, _, _)) = &irradiance {
                for (f, name) in FACE_FILE_NAMES.iter().enumerate() {
                    files.write_exr(&format!("irradiance_{name}.exr"), level, f)?;
                }
            }
        } else {
            half_clamped += files.write_ktx2("radiance.ktx2", &chain)?;
            if let Some((level, _, _)) = &irradiance {
                half_clamped += files.write_ktx2("irradiance.ktx2", std::slice::from_ref(level))?;
            }
        }
        if half_clamped > 0 {
            eprintln!(
                "note: clamped {half_clamped} values beyond the half-float range (65504) to it"
            );
        }
        let lam = Lobe::Lambert.zonal(self.sh_lmax);
        let bands = |irr: bool| -> Vec<[f64; 3]> {
            (0..sh.data().len() / 3)
                .map(|k| {
                    let l = (k as f64).sqrt() as usize;
                    let f = if irr { lam[l] } else { 1.0 };
                    [0, 1, 2].map(|c| sh.data()[k * 3 + c] * f)
                })
                .collect()
        };
        let sh_json = json!({
            "lmax": self.sh_lmax,
            "basis": "real orthonormal SH, Condon-Shortley phase, flat index l(l+1)+m (ifd_sphere::sh; pyshtools 'ortho', csphase=-1); rows are coefficients, columns R, G, B",
            "frame": "ifd's equirectangular frame: z up, azimuth 2 pi (u + 0.5) / W from +x towards +y; a world (glTF, y up) direction (x, y, z) is (-x, -z, y) here",
            "quadrature": "exact for the map read as piecewise constant over its texels",
            "radiance": bands(false),
            "irradiance_over_pi": bands(true),
        });
        files.write_bytes(
            "sh.json",
            serde_json::to_string_pretty(&sh_json)?.as_bytes(),
        )?;
        files.write_sh_npy("sh.npy", &sh)?;
        let written = files.commit()?;
        let (bright, threshold) = baker.bright_texels();
        println!(
            "{}",
            json!({
                "input": self.envmap.display().to_string(),
                "width": env.width(), "height": env.height(),
                "face_size": n, "mips": levels,
                "roughness_mapping": self.roughness,
                "brdf": self.brdf, "eps": self.eps,
                "bright_texels": bright, "bright_threshold": threshold,
                "levels": report,
                "irradiance": irradiance.as_ref().map(|(l, s, secs)| json!({
                    "size": l.size, "lmax": s.l_max,
                    "negatives_clamped": s.negatives_clamped, "seconds": secs,
                })),
                "half_clamped": half_clamped,
                "files": written,
                "seconds": {
                    "read": read_s, "analysis": analysis_s, "bake": bake_s,
                    "total": start.elapsed().as_secs_f64(),
                },
            })
        );
        Ok(())
    }
}

fn lobe_json(lobe: &Lobe) -> serde_json::Value {
    match *lobe {
        Lobe::Mirror => json!({"kind": "mirror"}),
        Lobe::Ggx { alpha } => json!({"kind": "ggx", "alpha": alpha}),
        Lobe::Phong { s } => json!({"kind": "phong", "s": s}),
        Lobe::Lambert => json!({"kind": "lambert"}),
    }
}

/// Output files written into a hidden staging folder inside the output
/// folder, moved into place only when all are complete.
struct Staging {
    out: PathBuf,
    dir: PathBuf,
    names: std::cell::RefCell<Vec<String>>,
}

impl Staging {
    fn new(out: &Path) -> Result<Self> {
        if out.exists() && !out.is_dir() {
            bail!("{}: exists and is not a folder", out.display());
        }
        std::fs::create_dir_all(out)
            .with_context(|| format!("{}: cannot create the output folder", out.display()))?;
        let dir = out.join(format!(".ifd-staging-{}", std::process::id()));
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("{}: cannot write into the output folder", out.display()))?;
        Ok(Self {
            out: out.to_path_buf(),
            dir,
            names: std::cell::RefCell::new(Vec::new()),
        })
    }

    fn path(&self, name: &str) -> PathBuf {
        self.names.borrow_mut().push(name.to_string());
        self.dir.join(name)
    }

    fn write_bytes(&self, name: &str, bytes: &[u8]) -> Result<()> {
        let p = self.path(name);
        std::fs::write(&p, bytes).with_context(|| format!("{}: cannot write", p.display()))
    }

    fn write_ktx2(&self, name: &str, levels: &[CubeLevel]) -> Result<usize> {
        let p = self.path(name);
        Ok(ifd_ibl::ktx2::write_cube(&p, levels)?)
    }

    fn write_exr(&self, name: &str, level: &CubeLevel, face: usize) -> Result<()> {
        let p = self.path(name);
        let img = level.face_image(face)?;
        ifd_image::write_image(&p, &img, &ifd_image::WriteOptions::default())?;
        Ok(())
    }

    fn write_sh_npy(&self, name: &str, sh: &ifd_sphere::ShCoeffs) -> Result<()> {
        let p = self.path(name);
        sh.write_npy(&p)
            .with_context(|| format!("{}: cannot write", p.display()))
    }

    /// Moves every staged file into the output folder; returns their names.
    fn commit(self) -> Result<Vec<String>> {
        let names = self.names.borrow().clone();
        for name in &names {
            let to = self.out.join(name);
            std::fs::rename(self.dir.join(name), &to)
                .with_context(|| format!("{}: cannot move into place", to.display()))?;
        }
        Ok(names)
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        // on success only the empty folder is left; on failure its partial files
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Writes the split-sum DFG table: texel (i, j) holds N.V = (i + 0.5)/size
/// (left to right) and perceptual roughness (j + 0.5)/size (top to bottom,
/// alpha = roughness^2), R = scale A, G = bias B (specular = F0 A + B), B = 0.
/// Computed by deterministic quadrature (docs/ibl.md). EXR keeps floats; PNG
/// is written with 16 bits.
#[derive(Debug, Args)]
struct DfgCmd {
    /// Table size.
    #[arg(long, default_value_t = 128)]
    size: usize,
    /// Output image (.exr, .png, .npy, ...).
    #[arg(short, long)]
    output: PathBuf,
}

impl DfgCmd {
    fn run(self) -> Result<()> {
        if !(2..=4096).contains(&self.size) {
            bail!("--size {}: must lie in 2..=4096", self.size);
        }
        let t = Instant::now();
        let table = ifd_ibl::dfg::dfg_table(self.size);
        let data: Vec<f32> = table.iter().flat_map(|[a, b]| [*a, *b, 0.0]).collect();
        let img = ifd_image::Image::from_vec(self.size, self.size, 3, data)?;
        let opts = ifd_image::WriteOptions {
            bit_depth: ifd_image::BitDepth::Sixteen,
            ..ifd_image::WriteOptions::default()
        };
        crate::output::write_output(&self.output, &img, &opts)?;
        println!(
            "{}",
            json!({"size": self.size, "output": self.output.display().to_string(),
                   "seconds": t.elapsed().as_secs_f64()})
        );
        Ok(())
    }
}

/// Reproduces Tables 4 and 5 of Ramamoorthi and Hanrahan (2002).
///
/// Table 4: a normalised Phong reflection map prefiltered in frequency space
/// (lighting SH to the paper's order F_B = 1 + sqrt(6 s), zonal scaling,
/// synthesis) and in angular space (per output texel, a sum over the input
/// texels of the lobe's eps-support, App. D), on the same equirectangular grid
/// with the same threads; medians of --runs measurements. The table also shows
/// App. D's order sqrt(-s ln 0.01) and App. B's conservative bound on the
/// truncation's relative error energy, then the log-log slopes (theory: +1/2
/// and -1) and the crossover exponent extrapolated from the fits.
///
/// Table 5: the microfacet BRDF of Eq. 11 (--sigmas): BRDF coefficients and
/// the orders F_B, P_B for 1 - eps of its energy, the SHRM and 10 x 10
/// reflection maps for distant viewers against angular integration of --maps
/// x --maps of them (time extrapolated to 100).
#[derive(Debug, Args)]
struct ShrmCmd {
    /// Environment map (2:1), averaged down to --size by solid angle.
    envmap: PathBuf,
    /// Which table: 4 (Phong) or 5 (the microfacet BRDF of Eq. 11, SHRM against angular maps).
    #[arg(long, default_value_t = 4)]
    table: u32,
    /// Working size WxH (2:1; default 256x128 for Table 4, whose S_L = S_B = 128 is the
    /// number of rows here, and 128x64 for Table 5, whose angular side is slow).
    #[arg(long)]
    size: Option<String>,
    /// Table 5: roughness values sigma.
    #[arg(long, value_delimiter = ',', default_value = "0.1,0.2,0.3,0.4,0.5")]
    sigmas: Vec<f64>,
    /// Table 5: the angular side computes T x T of the paper's T_B x T_B = 10 x 10 maps
    /// and its time is extrapolated to 100 (the frequency side makes all 100).
    #[arg(long, default_value_t = 3)]
    maps: usize,
    /// Table 5: the BRDF energy tolerance choosing F_B, P_B (the paper: 0.03).
    #[arg(long, default_value_t = 0.03)]
    eps: f64,
    /// Phong exponents.
    #[arg(long, value_delimiter = ',', default_value = "8,16,32,64,128,256,512")]
    exponents: Vec<f64>,
    /// The angular side's support tolerance (the paper: 0.05).
    #[arg(long, default_value_t = 0.05)]
    eps_angular: f64,
    /// Measurements per side and exponent (medians); each repeats the work for at least
    /// --min-seconds and takes the mean per run.
    #[arg(long, default_value_t = 5)]
    runs: usize,
    /// Minimum time of one measurement.
    #[arg(long, default_value_t = 0.2)]
    min_seconds: f64,
    /// Also write the rows as CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Also write a log-log plot of both times against s (PNG).
    #[arg(long)]
    plot: Option<PathBuf>,
    #[command(flatten)]
    input: InputOptions,
}

/// SHRM Table 4 (1.4 GHz Pentium IV): (s, angular, frequency).
const PAPER_TABLE4: [(f64, f64, f64); 7] = [
    (8.0, 67.28, 0.081),
    (16.0, 38.03, 0.114),
    (32.0, 21.80, 0.159),
    (64.0, 11.94, 0.227),
    (128.0, 7.17, 0.328),
    (256.0, 3.55, 0.461),
    (512.0, 2.28, 0.686),
];

impl ShrmCmd {
    /// The map averaged down to `--size` (else `default`) by solid angle.
    fn load(&self, default: &str) -> Result<(ifd_image::Image, usize, usize)> {
        let (w, h) = crate::input::parse_size(self.size.as_deref().unwrap_or(default), "--size")?;
        let img = self.input.read(&self.envmap)?.image;
        if img.channels() != 3 {
            bail!(
                "{}: needs RGB; got {} channel(s)",
                self.envmap.display(),
                img.channels()
            );
        }
        let src = ifd_sphere::transform::downsample_equirect(&img, w, h).with_context(|| {
            format!(
                "{}: averaging down to --size {w}x{h}",
                self.envmap.display()
            )
        })?;
        Ok((src, w, h))
    }

    fn run(self) -> Result<()> {
        use ifd_ibl::shrm::{loglog_fit, paper_order, time_phong};
        use std::fmt::Write as _;
        if !(self.eps_angular > 0.0 && self.eps_angular < 1.0) {
            bail!("--eps-angular {}: must lie in (0, 1)", self.eps_angular);
        }
        if self.table == 5 {
            return self.run_table5();
        }
        if self.table != 4 {
            bail!(
                "--table {}: Tables 4 (Phong) and 5 (microfacet) are reproduced",
                self.table
            );
        }
        if self.exponents.is_empty()
            || self
                .exponents
                .iter()
                .any(|s| !(s.is_finite() && *s >= 1.0 && *s <= 1e5))
        {
            bail!("--exponents: each must lie in 1..=100000");
        }
        if !(1..=50).contains(&self.runs) {
            bail!("--runs {}: must lie in 1..=50", self.runs);
        }
        if !(self.min_seconds >= 0.0 && self.min_seconds <= 60.0) {
            bail!("--min-seconds {}: must lie in 0..=60", self.min_seconds);
        }
        let (src, w, h) = self.load("256x128")?;
        let max_order = self
            .exponents
            .iter()
            .map(|s| paper_order(*s))
            .max()
            .unwrap_or(0);
        if max_order >= h {
            bail!("--size {w}x{h}: F_B = {max_order} needs more than {h} rows");
        }
        let threads = rayon::current_num_threads();
        let mut rows = Vec::new();
        for &s in &self.exponents {
            eprintln!("s = {s}: timing ...");
            rows.push(time_phong(
                &src,
                s,
                self.eps_angular,
                self.runs,
                self.min_seconds,
            )?);
        }
        println!(
            "SHRM Table 4 on this machine: {w}x{h} in and out, {threads} threads, medians of {} measurements of at least {} s each, angular eps {}",
            self.runs, self.min_seconds, self.eps_angular
        );
        println!();
        println!(
            "| s | F_B | App. D order | angular (s) | frequency (s) | ratio | support texels | rel. diff | App. B bound | paper ratio |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|");
        for r in &rows {
            let paper = PAPER_TABLE4
                .iter()
                .find(|p| (p.0 - r.s).abs() < 1e-9)
                .map_or_else(|| "-".to_string(), |p| format!("{:.1}", p.1 / p.2));
            println!(
                "| {} | {} | {} | {:.4} | {:.4} | {:.1} | {:.0} | {:.2e} | {:.1e} | {} |",
                r.s,
                r.order,
                ifd_ibl::shrm::phong_order(r.s, 0.01),
                r.angular,
                r.frequency,
                r.angular / r.frequency,
                r.support,
                r.rel_diff,
                r.residual_bound,
                paper
            );
        }
        let xs: Vec<f64> = rows.iter().map(|r| r.s).collect();
        let (fa, ia) = loglog_fit(&xs, &rows.iter().map(|r| r.angular).collect::<Vec<_>>());
        let (ff, iff) = loglog_fit(&xs, &rows.iter().map(|r| r.frequency).collect::<Vec<_>>());
        // crossover: ia + fa ln s = iff + ff ln s
        let crossover = ((iff - ia) / (fa - ff)).exp();
        println!();
        println!(
            "log-log slopes: angular {fa:.2} (theory -1), frequency {ff:.2} (theory +0.5); crossover s* = {crossover:.0} (extrapolated; the paper predicts s* ~ S_L^(4/3) = {:.0} up to constants)",
            (h as f64).powf(4.0 / 3.0)
        );
        if let Some(path) = &self.csv {
            let mut text = String::from(
                "s,order,angular_s,frequency_s,ratio,support_texels,rel_diff,residual_bound\n",
            );
            for r in &rows {
                let ratio = r.angular / r.frequency;
                let _ = writeln!(
                    text,
                    "{},{},{},{},{ratio},{},{},{}",
                    r.s, r.order, r.angular, r.frequency, r.support, r.rel_diff, r.residual_bound
                );
            }
            std::fs::write(path, text)
                .with_context(|| format!("{}: cannot write", path.display()))?;
        }
        if let Some(path) = &self.plot {
            use ifd_plot::{Series, log_line_plot};
            let pts = |f: &dyn Fn(&ifd_ibl::shrm::PhongTiming) -> f64| -> Vec<(f64, f64)> {
                rows.iter().map(|r| (r.s.log2(), f(r))).collect()
            };
            let series = vec![
                Series {
                    name: "angular, ifd".into(),
                    colour: [0.8, 0.2, 0.1],
                    dotted: false,
                    points: pts(&|r| r.angular),
                },
                Series {
                    name: "frequency, ifd".into(),
                    colour: [0.1, 0.3, 0.8],
                    dotted: false,
                    points: pts(&|r| r.frequency),
                },
                Series {
                    name: "angular, paper".into(),
                    colour: [0.8, 0.2, 0.1],
                    dotted: true,
                    points: PAPER_TABLE4.iter().map(|p| (p.0.log2(), p.1)).collect(),
                },
                Series {
                    name: "frequency, paper".into(),
                    colour: [0.1, 0.3, 0.8],
                    dotted: true,
                    points: PAPER_TABLE4.iter().map(|p| (p.0.log2(), p.2)).collect(),
                },
            ];
            let img = log_line_plot(&series, "log2 s (Phong exponent)", "seconds")?;
            crate::output::write_output(path, &img, &ifd_image::WriteOptions::default())?;
        }
        Ok(())
    }
}

/// SHRM Table 5 (1.4 GHz Pentium IV): (sigma, F_B, P_B, angular total for 100
/// maps, frequency total, SHRM alone).
const PAPER_TABLE5: [(f64, usize, usize, f64, f64, f64); 5] = [
    (0.1, 24, 3, 923.0, 2.70, 1.55),
    (0.2, 12, 2, 2744.0, 1.55, 0.72),
    (0.3, 7, 2, 5731.0, 1.49, 0.67),
    (0.4, 5, 2, 9034.0, 1.47, 0.65),
    (0.5, 5, 2, 12580.0, 1.45, 0.64),
];

impl ShrmCmd {
    fn run_table5(&self) -> Result<()> {
        use ifd_ibl::shrm_general::{time_microfacet, view_grid};
        if self.sigmas.is_empty()
            || self
                .sigmas
                .iter()
                .any(|s| !(s.is_finite() && *s >= 0.02 && *s <= 1.5))
        {
            bail!("--sigmas: each must lie in 0.02..=1.5");
        }
        if !(1..=10).contains(&self.maps) {
            bail!("--maps {}: must lie in 1..=10", self.maps);
        }
        if !(self.eps > 0.0 && self.eps < 1.0) {
            bail!("--eps {}: must lie in (0, 1)", self.eps);
        }
        let (src, w, h) = self.load("128x64")?;
        let views = view_grid(self.maps);
        let mut rows = Vec::new();
        for &sigma in &self.sigmas {
            eprintln!(
                "sigma = {sigma}: SHRM, 100 maps, {} angular maps ...",
                views.len()
            );
            rows.push(time_microfacet(
                &src,
                sigma,
                self.eps,
                self.eps_angular,
                10,
                &views,
            )?);
        }
        println!(
            "SHRM Table 5 on this machine: {w}x{h} in and out, {} threads; F_B, P_B for BRDF energy eps {}; angular support eps {}; \
             angular time measured on {} of the 10 x 10 maps and extrapolated to 100",
            rayon::current_num_threads(),
            self.eps,
            self.eps_angular,
            views.len()
        );
        println!();
        println!(
            "| sigma | F_B, P_B | paper | angular per map (s) | angular, 100 maps (s) | SHRM (s) | SHRM + 100 maps (s) | ratio | paper ratio | rel. diff | support texels |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        let mut csv = String::from(
            "sigma,f,p,angular_per_map_s,angular_100_s,shrm_s,frequency_100_s,ratio,rel_diff,support_texels\n",
        );
        for r in &rows {
            let ang100 = 100.0 * r.angular_per_map;
            let freq100 = r.shrm + 100.0 * r.per_map;
            let paper = PAPER_TABLE5.iter().find(|p| (p.0 - r.sigma).abs() < 1e-9);
            println!(
                "| {} | {}, {} | {} | {:.3} | {:.1} | {:.3} | {:.3} | {:.0} | {} | {:.2e} | {:.0} |",
                r.sigma,
                r.f,
                r.p,
                paper.map_or_else(|| "-".into(), |p| format!("{}, {}", p.1, p.2)),
                r.angular_per_map,
                ang100,
                r.shrm,
                freq100,
                ang100 / freq100,
                paper.map_or_else(|| "-".into(), |p| format!("{:.0}", p.3 / p.4)),
                r.rel_diff,
                r.support
            );
            let _ = std::fmt::Write::write_fmt(
                &mut csv,
                format_args!(
                    "{},{},{},{},{},{},{},{},{},{}\n",
                    r.sigma,
                    r.f,
                    r.p,
                    r.angular_per_map,
                    ang100,
                    r.shrm,
                    freq100,
                    ang100 / freq100,
                    r.rel_diff,
                    r.support
                ),
            );
        }
        if let Some(path) = &self.csv {
            std::fs::write(path, csv)
                .with_context(|| format!("{}: cannot write", path.display()))?;
        }
        if self.plot.is_some() {
            eprintln!("note: --plot draws Table 4 only");
        }
        Ok(())
    }
}
