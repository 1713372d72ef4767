//! `ifd-paper isd-convergence`: ISD Fig. 4, the relative RMS error of ISD and
//! of its SH reference against the exact oracle as L grows, per BRDF.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use ifd_shade::Brdf;

use super::{csv_report, is_display};
use crate::input::InputOptions;
use crate::options::{CameraOptions, DisplayOptions, EnvOptions, ReportOptions, SceneOptions};

/// ISD Fig. 4: render the oracle once per --brdf, then ISD and SH at every
/// degree of --degrees; print the CSV of errors (brdf, L, method, rel_rms,
/// psnr_db; --json: as JSON rows) and write --csv, --plot and --grid.
#[derive(Debug, Args)]
pub struct IsdConvergence {
    #[command(flatten)]
    env: EnvOptions,
    /// BRDF spec (as `ifd render --brdf`); repeat for one curve per BRDF.
    #[arg(long, value_name = "SPEC", required = true)]
    brdf: Vec<String>,
    /// SH degrees: A..B, or A..B:S in steps of S.
    #[arg(long, value_name = "A..B[:S]", default_value = "2..24:2")]
    degrees: String,
    #[command(flatten)]
    scene: SceneOptions,
    #[command(flatten)]
    camera: CameraOptions,
    #[command(flatten)]
    display: DisplayOptions,
    /// The CSV of errors (brdf, L, method, rel_rms, psnr_db).
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
    /// The plot of the relative RMS error against L (PNG).
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
    /// An image grid, one row per BRDF, ISD at a few degrees then the oracle (PNG).
    #[arg(long, value_name = "FILE")]
    grid: Option<PathBuf>,
    /// Skip the SH reference (slow at high L; it equals ISD to rounding).
    #[arg(long)]
    no_sh: bool,
    #[command(flatten)]
    report: ReportOptions,
    #[command(flatten)]
    input: InputOptions,
}

impl IsdConvergence {
    /// Runs the study.
    pub fn run(self) -> Result<()> {
        use ifd_paper::convergence::{Study, csv, plot, run};
        let text = self.degrees.as_str();
        let bad = || {
            anyhow::anyhow!(
                "--degrees {text:?}: expected A..B or A..B:STEP with 0 <= A <= B <= 100"
            )
        };
        let (range, step) = text.split_once(':').unwrap_or((text, "1"));
        let (a, b) = range.split_once("..").ok_or_else(bad)?;
        let (a, b, step): (usize, usize, usize) = (
            a.trim().parse().map_err(|_| bad())?,
            b.trim().parse().map_err(|_| bad())?,
            step.trim().parse().map_err(|_| bad())?,
        );
        if a > b || b > ifd_shade::MAX_TABLE_DEGREE || step == 0 {
            return Err(bad());
        }
        for p in [&self.plot, &self.grid].into_iter().flatten() {
            is_display(p)?;
        }
        let degrees: Vec<usize> = (a..=b).step_by(step).collect();
        let brdfs = self
            .brdf
            .iter()
            .map(|s| Brdf::parse(s))
            .collect::<std::result::Result<Vec<_>, _>>()?;
        let scene = self
            .scene
            .scene_with(ifd_image::MemoryBudget::default_for_machine())?;
        let camera = self.camera.camera()?;
        let tonemap = self.display.tonemap()?;
        let (_, env) = self.env.environments(&self.input)?;
        let study = Study {
            scene,
            camera,
            env: &env,
            brdfs: &brdfs,
            degrees: &degrees,
            with_sh: !self.no_sh,
        };
        let start = std::time::Instant::now();
        let outcome = run(&study, &|m| eprintln!("{m}"))?;
        let table = csv(&outcome.rows);
        if let Some(p) = &self.csv {
            crate::output::write_text(p, &table)?;
        }
        if let Some(p) = &self.plot {
            crate::output::write_output(
                p,
                &plot(&outcome.rows)?,
                &ifd_image::WriteOptions::default(),
            )?;
        }
        if let Some(p) = &self.grid {
            // a few degrees across the range, then the oracle
            let n = degrees.len();
            let pick: Vec<usize> = if n <= 4 {
                (0..n).collect()
            } else {
                (0..4).map(|i| i * (n - 1) / 3).collect()
            };
            let (w, h) = (camera.width(), camera.height());
            let cols = pick.len() + 1;
            let rows = outcome.images.len();
            let mut grid = ifd_image::Image::new(cols * w, rows * h, 3)?;
            for (r, (oracle, isd)) in outcome.images.iter().enumerate() {
                let tiles: Vec<&ifd_image::Image> = pick
                    .iter()
                    .map(|&i| &isd[i])
                    .chain([&oracle.image])
                    .collect();
                for (c, tile) in tiles.into_iter().enumerate() {
                    let ch = tile.channels();
                    for y in 0..h {
                        for x in 0..w {
                            for k in 0..3 {
                                let v = tile.get(x, y, k.min(ch - 1));
                                grid.set(
                                    c * w + x,
                                    r * h + y,
                                    k,
                                    tonemap.display(v, self.display.exposure),
                                );
                            }
                        }
                    }
                }
            }
            crate::output::write_output(p, &grid, &ifd_image::WriteOptions::default())?;
            eprintln!(
                "grid: rows {:?}; columns L = {:?}, then the oracle",
                self.brdf,
                pick.iter().map(|&i| degrees[i]).collect::<Vec<_>>()
            );
        }
        self.report
            .emit_with(&csv_report(&table), || table.clone())?;
        eprintln!("took {:.1} s", start.elapsed().as_secs_f64());
        Ok(())
    }
}
