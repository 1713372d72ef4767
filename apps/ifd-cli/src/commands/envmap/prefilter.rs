//! `ifd envmap prefilter`: bake the IBL assets engines load.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use ifd_ibl::Lobe;
use ifd_ibl::{BakeOptions, Baker};
use ifd_ibl::{CubeLevel, FACE_FILE_NAMES, strip_to_equirect};
use ifd_ibl::{RoughnessMapping, check_chain};
use serde_json::json;

use crate::input::InputOptions;
use crate::options::{ReportOptions, seconds};

/// Bakes what engines load for image-based lighting, from an equirectangular
/// (2:1) map or a cube strip (6:1, faces +X,-X,+Y,-Y,+Z,-Z, y up):
///
///   DIR/radiance.ktx2    RGBA16F cube, mip m = GGX with roughness m/(M-1)
///   DIR/irradiance.ktx2  RGBA16F cube, one level, E/pi (what glTF/Bevy hold)
///   DIR/sh.json, sh.npy  SH of the radiance (ifd's frame and basis, stated in the JSON)
///
/// With --format exr the cubes are EXR faces instead: radiance_m{m}_{px,nx,py,ny,pz,nz}.exr
/// and irradiance_{face}.exr. Faces are in the order and orientation engines expect
/// (y up); the map is read as glTF-IBL-Sampler reads it. The prefilter runs in
/// frequency space (SH convolution with the lobe's zonal factors) with the
/// brightest texels summed exactly, so suns do not ring; see docs/ibl.md.
#[derive(Debug, Args)]
pub(super) struct PrefilterCmd {
    /// Environment map (HDR, EXR, ...): 2:1 equirectangular or a 6:1 cube strip.
    envmap: PathBuf,
    /// Radiance face size, a power of two.
    #[arg(long, default_value_t = 256, value_name = "N")]
    face_size: usize,
    /// Number of radiance mip levels (default: floor(log2 N) for linear, down to 16 texels for cmgen).
    #[arg(long, value_name = "M")]
    mips: Option<usize>,
    /// Mip-to-roughness mapping: linear (m/(M-1), glTF-IBL-Sampler, Bevy) or cmgen (Filament).
    #[arg(long, default_value = "linear", value_parser = ["linear", "cmgen"])]
    roughness: String,
    /// Lobe: ggx (the split-sum GGX lobe), phong (the Phong lobe matching each mip's GGX
    /// width, s = 1/(2 alpha^2) - 1/2), or phong:s=S (one level filtered with exponent S).
    #[arg(long, value_name = "ggx|phong|phong:s=S", default_value = "ggx")]
    lobe: String,
    /// Irradiance face size (0: no irradiance map).
    #[arg(long, default_value_t = 32, value_name = "N")]
    irradiance_size: usize,
    /// Maximum SH degree of sh.json / sh.npy.
    #[arg(long, default_value_t = 2, value_name = "L")]
    sh_lmax: usize,
    /// Output format of the cubes: ktx2 or exr.
    #[arg(long, default_value = "ktx2", value_parser = ["ktx2", "exr"])]
    format: String,
    /// Band truncation: each lobe keeps the bands whose zonal factor is at least eps.
    #[arg(long, default_value_t = 1e-3)]
    eps: f64,
    /// Output folder (created if missing; files in it are replaced).
    #[arg(long, value_name = "DIR")]
    out_dir: PathBuf,
    #[command(flatten)]
    input: InputOptions,
    #[command(flatten)]
    report: ReportOptions,
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
                format!("--lobe {brdf:?}: expected phong:s=S with 0 < S <= 1e6, e.g. phong:s=64")
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
            _ => bail!("--lobe {brdf:?}: unknown lobe; use ggx, phong or phong:s=S"),
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
    pub(super) fn run(self) -> Result<()> {
        let mapping = RoughnessMapping::parse(&self.roughness)?;
        let n = self.face_size;
        let single = self.lobe.starts_with("phong:");
        let levels = if single {
            if self.mips.is_some_and(|m| m != 1) {
                bail!("--mips: --lobe {} writes one level", self.lobe);
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
        let lobes = chain_lobes(&self.lobe, mapping, levels)?;
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
        let bar = crate::progress::bar("prefiltering", "levels", all.len() as u64);
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
        let files = Staging::new(&self.out_dir)?;
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
            "basis": "real orthonormal SH, Condon-Shortley phase, flat index l(l+1)+m (ifd_sphere::ShEvaluator; pyshtools 'ortho', csphase=-1); rows are coefficients, columns R, G, B",
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
        let total_s = start.elapsed().as_secs_f64();
        let capped = report.iter().filter(|l| l["capped"] == true).count();
        let summary = || {
            let mut text = files_summary(&self.out_dir, &written);
            let truncated = if capped > 0 {
                format!(", {capped} truncated at --eps {}", self.eps)
            } else {
                String::new()
            };
            let irradiance = irradiance
                .as_ref()
                .map(|(l, _, _)| format!(", irradiance {0}x{0}", l.size))
                .unwrap_or_default();
            let _ = writeln!(
                text,
                "{levels} radiance level(s) of {n}x{n} to {m}x{m} faces ({} lobe, {} roughness{truncated}){irradiance}, SH L = {}",
                self.lobe,
                self.roughness,
                self.sh_lmax,
                m = (n >> levels.saturating_sub(1)).max(1),
            );
            text + &format!(
                "time {} (read {}, analysis {}, bake {})\n",
                seconds(total_s),
                seconds(read_s),
                seconds(analysis_s),
                seconds(bake_s)
            )
        };
        let report = json!({
            "input": self.envmap.display().to_string(),
            "width": env.width(), "height": env.height(),
            "face_size": n, "mips": levels,
            "roughness_mapping": self.roughness,
            "lobe": self.lobe, "eps": self.eps,
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
                "total": total_s,
            },
        });
        self.report.emit_summary(&report, summary)?;
        Ok(())
    }
}

/// The files written into `dir`: their count and total size, then one line
/// per kind (the faces of a level as one `radiance_*.exr` entry).
fn files_summary(dir: &Path, names: &[String]) -> String {
    let size = |name: &str| std::fs::metadata(dir.join(name)).map_or(0, |m| m.len());
    let mut groups: Vec<(String, usize, u64)> = Vec::new();
    for name in names {
        let key = match name.split_once('_') {
            Some((stem, _)) if name.to_ascii_lowercase().ends_with(".exr") => {
                format!("{stem}_*.exr")
            }
            _ => name.clone(),
        };
        match groups.iter_mut().find(|g| g.0 == key) {
            Some(g) => {
                g.1 += 1;
                g.2 += size(name);
            }
            None => groups.push((key, 1, size(name))),
        }
    }
    let total: u64 = groups.iter().map(|g| g.2).sum();
    let mut text = format!(
        "wrote {} file(s) to {} ({})\n",
        names.len(),
        dir.display(),
        ifd_image::fmt_bytes(total)
    );
    for (key, count, bytes) in groups {
        let count = if count > 1 {
            format!("{count} files, ")
        } else {
            String::new()
        };
        let _ = writeln!(text, "  {key} ({count}{})", ifd_image::fmt_bytes(bytes));
    }
    text
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
        Ok(ifd_ibl::write_ktx2_cube(&p, levels)?)
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
