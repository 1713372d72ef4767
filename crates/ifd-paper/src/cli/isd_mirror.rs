//! `ifd-paper isd-mirror`: anti-aliased environment-map reflections on a bumpy mirror
//! (ISD Sec. 6.2, Fig. 6), ISD's filter against supersampling.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use ifd_paper::mirror::{BumpyMirror, BumpyScene, Study, StudyRow, study};
use ifd_render::EnvMap;
use ifd_render::{AaMethod, IsdFilter, PixelFilter};
use serde_json::json;

use crate::options::CameraOptions;
use crate::options::ReportOptions;

/// Anti-aliased mirror reflections (ISD Sec. 6.2, Eq. 26-29): a unit mirror
/// sphere, bumpy above z = 0.35 and smooth below z = 0.15, reflecting an
/// environment map, rendered without anti-aliasing, with 4x4 and 16x16
/// supersampling and with ISD's filter (the pixel footprint's reflected
/// directions as one isotropic spherical Gaussian, Eq. 29 from the map's SH;
/// a direct lookup where the footprint is narrower than pi / L), against a
/// 64x64 stratified supersampled reference, all with the same pixel filter (a
/// Gaussian of 0.5 pixel over [-1, 1]^2). Prints the table (relative RMS error
/// over interior pixels, the bumpy and the smooth region; median time of
/// --runs interleaved runs, and the ratio to 4x4; JSON with --json), and writes each
/// image (EXR and PNG), a side-by-side strip and table.md into --out-dir.
///
/// Example: `ifd-paper isd-mirror --env testdata/forest.hdr --out-dir mirror-out`
#[derive(Debug, Args)]
#[command(mut_arg("eye", |a| a.default_value("0,-3.2,1.1")), mut_arg("fov", |a| a.default_value("42")))]
pub struct Mirror {
    /// Environment map, 2:1 equirectangular (looked up bilinearly at full resolution).
    #[arg(long, value_name = "FILE")]
    env: PathBuf,
    #[command(flatten)]
    camera: CameraOptions,
    /// SH degree L of ISD's filter.
    #[arg(long, value_name = "L", default_value_t = 32)]
    lmax: usize,
    /// Reference: NxN jittered stratified samples per pixel.
    #[arg(long, value_name = "N", default_value_t = 64)]
    reference_grid: usize,
    /// Supersampling rates to compare (NxN each).
    #[arg(
        long,
        value_name = "N,..",
        default_value = "4,16",
        value_delimiter = ','
    )]
    supersample: Vec<usize>,
    /// Timed runs per method (interleaved; the median is reported).
    #[arg(long, value_name = "N", default_value_t = 5)]
    runs: usize,
    /// Rotate the environment about +z by this many degrees.
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    env_rotate: f64,
    /// Exposure in stops for the PNG images.
    #[arg(
        long,
        value_name = "EV",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    exposure: f32,
    /// Folder for the images and table.md.
    #[arg(long, value_name = "DIR")]
    out_dir: Option<PathBuf>,
    #[command(flatten)]
    report: ReportOptions,
}

impl Mirror {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let camera = self.camera.camera()?;
        let (w, h) = (camera.width(), camera.height());
        if !(1..=200).contains(&self.lmax) {
            bail!("--lmax {}: use 1..=200", self.lmax);
        }
        if !(1..=256).contains(&self.reference_grid) {
            bail!("--reference-grid {}: use 1..=256", self.reference_grid);
        }
        if self.supersample.iter().any(|n| !(1..=64).contains(n)) {
            bail!("--supersample {:?}: each in 1..=64", self.supersample);
        }
        if !(1..=100).contains(&self.runs) {
            bail!("--runs {}: use 1..=100", self.runs);
        }
        if !self.exposure.is_finite() {
            bail!("--exposure {}: not finite", self.exposure);
        }
        if let Some(d) = &self.out_dir {
            std::fs::create_dir_all(d)
                .map_err(|e| anyhow::anyhow!("--out-dir {}: {e}", d.display()))?;
        }
        let img = ifd_image::read(&self.env)
            .map_err(|e| anyhow::anyhow!("--env {}: {e}", self.env.display()))?;
        let env = EnvMap::new(img, self.env_rotate)?;
        let scene = BumpyScene {
            mirror: BumpyMirror::default(),
            camera,
            env: &env,
            filter: PixelFilter::default(),
        };
        let t = std::time::Instant::now();
        eprintln!("projecting the map on SH up to L = {}...", self.lmax);
        let isd = IsdFilter::new(&env, self.lmax)?;
        let setup = t.elapsed().as_secs_f64();
        let mut methods = vec![AaMethod::Centre];
        methods.extend(self.supersample.iter().map(|n| AaMethod::Supersample(*n)));
        methods.push(AaMethod::IsdDirect);
        methods.push(AaMethod::Isd);
        let Study {
            rows,
            images,
            regions,
        } = study(
            &scene,
            &methods,
            AaMethod::Reference(self.reference_grid),
            Some(&isd),
            self.runs,
            &|s| eprintln!("{s}"),
        )?;
        let ss4 = rows.iter().find(|r| r.method == "ss4x4").map(|r| r.seconds);
        let count = |m: &[bool]| m.iter().filter(|b| **b).count();
        let table: Vec<_> = rows
            .iter()
            .map(|r| {
                json!({
                    "method": r.method, "seconds_median": r.seconds, "seconds_runs": r.runs,
                    "time_vs_ss4x4": ss4.map(|s| r.seconds / s),
                    "rel_rms_interior": r.errors[0], "rel_rms_bumpy": r.errors[1],
                    "rel_rms_smooth": r.errors[2],
                    "eq29_pixels": r.method.starts_with("isd").then_some(r.filtered),
                })
            })
            .collect();
        if let Some(dir) = &self.out_dir {
            let named: Vec<(&str, &ifd_image::Image)> =
                images.iter().map(|(n, im)| (n.as_str(), im)).collect();
            super::write_figure(dir, &named, self.exposure)?;
            let table = markdown(&rows, ss4);
            crate::output::write_text(&dir.join("table.md"), &table)?;
        }
        self.report.emit(&json!({
            "env": self.env, "width": w, "height": h, "lmax": self.lmax,
            "reference": format!("{0}x{0} jittered", self.reference_grid),
            "isd_threshold_radians": isd.threshold(), "isd_setup_seconds": setup,
            "interior_pixels": count(&regions.interior), "bumpy_pixels": count(&regions.bumpy),
            "smooth_pixels": count(&regions.smooth), "runs": self.runs,
            "threads": rayon::current_num_threads(),
            "rows": table,
        }))?;
        Ok(())
    }
}

fn markdown(rows: &[StudyRow], ss4: Option<f64>) -> String {
    let mut s = String::from(
        "| method | rel. RMS interior | bumpy | smooth | median s | time / 4x4 |\n|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {:.4} | {:.4} | {:.4} | {:.3} | {} |",
            r.method,
            r.errors[0],
            r.errors[1],
            r.errors[2],
            r.seconds,
            ss4.map_or("-".into(), |t| format!("{:.2}", r.seconds / t))
        );
    }
    s
}
