//! `ifd-paper isd-visibility`: self-shadowed ISD shading on a mesh against a
//! ray-traced reference (ISD Sec. 6.1, Eq. 25, Appendix A, Fig. 7).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use ifd_paper::visibility::{VisibilityScene, study};
use ifd_render::EnvMap;
use ifd_render::torus_mesh;
use ifd_shade::Brdf;
use ifd_shade::Material;
use ifd_shade::{LobeTable, default_theta_entries};
use serde_json::json;

use crate::input::parse_size;
use crate::options::CameraOptions;
use crate::options::ReportOptions;

/// Shading with visibility (ISD Eq. 25, Appendix A): `ifd render --shadows`
/// (per-vertex SH visibility by ray casting, the product matrix of the
/// lighting, the paper's gamma, and the three-step shader) against its
/// ray-traced reference (`--method quadrature --shadows`), for increasing L
/// (Fig. 7), beside unshadowed ISD.
///
/// The scene is a torus mesh (`torus`, 96 x 48 quads) or an OBJ file,
/// centred and scaled to the unit bounding sphere. The reference integrates
/// every texel of the map (averaged down to --env-size) with 2 x 2 nodes,
/// tracing the visibility of each node from the pixel's point; ISD
/// interpolates the vertices' visibility. Writes the images, the error
/// against L as CSV and a plot (with the unshadowed ISD error for
/// comparison) into --out-dir, and prints a report (JSON with --json).
///
/// Example: `ifd-paper isd-visibility --env testdata/forest.hdr --brdf phong:s=8 --out-dir vis`
#[derive(Debug, Args)]
#[command(mut_arg("size", |a| a.default_value("96x96")), mut_arg("eye", |a| a.default_value("0,-2.4,1.7")))]
pub struct Visibility {
    /// Environment map (2:1 equirectangular).
    #[arg(long, value_name = "FILE")]
    env: PathBuf,
    /// The size the map is averaged down to (its texels are the reference's quadrature).
    #[arg(long, value_name = "WxH", default_value = "64x32")]
    env_size: String,
    /// BRDF spec (as `ifd render`).
    #[arg(long, value_name = "SPEC", default_value = "phong:s=8")]
    brdf: String,
    /// Degrees: A..B or A..B:S.
    #[arg(long, value_name = "A..B[:S]", default_value = "2..14:2")]
    degrees: String,
    /// Scene: torus (triangulated) or a path to an .obj file.
    #[arg(long, value_name = "SCENE", default_value = "torus")]
    scene: String,
    /// Rays per vertex for the visibility's SH.
    #[arg(long, value_name = "N", default_value_t = 4096)]
    rays: usize,
    #[command(flatten)]
    camera: CameraOptions,
    /// Folder for the images, CSV and plot.
    #[arg(long, value_name = "DIR")]
    out_dir: Option<PathBuf>,
    #[command(flatten)]
    report: ReportOptions,
}

fn parse_degrees(text: &str) -> Result<Vec<usize>> {
    let bad =
        || anyhow::anyhow!("--degrees {text:?}: expected A..B or A..B:S with 1 <= A <= B <= 30");
    let (range, step) = match text.split_once(':') {
        Some((r, s)) => (r, s.trim().parse::<usize>().map_err(|_| bad())?),
        None => (text, 1),
    };
    let (a, b) = range.split_once("..").ok_or_else(bad)?;
    let (a, b) = (
        a.trim().parse::<usize>().map_err(|_| bad())?,
        b.trim().parse::<usize>().map_err(|_| bad())?,
    );
    if a == 0 || a > b || b > 30 || step == 0 {
        return Err(bad());
    }
    Ok((a..=b).step_by(step).collect())
}

impl Visibility {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let degrees = parse_degrees(&self.degrees)?;
        let camera = self.camera.camera()?;
        let (w, h) = (camera.width(), camera.height());
        let (ew, eh) = parse_size(&self.env_size, "--env-size")?;
        if !(64..=1 << 20).contains(&self.rays) {
            bail!("--rays {}: use 64..=1048576", self.rays);
        }
        if let Some(d) = &self.out_dir {
            std::fs::create_dir_all(d)
                .map_err(|e| anyhow::anyhow!("--out-dir {}: {e}", d.display()))?;
        }
        let img = ifd_image::read(&self.env)
            .map_err(|e| anyhow::anyhow!("--env {}: {e}", self.env.display()))?;
        let env = EnvMap::new(img, 0.0)?.downsampled(ew, eh)?;
        let brdf = Brdf::parse(&self.brdf)?;
        let mesh = std::sync::Arc::new(match self.scene.as_str() {
            "torus" => torus_mesh(1.0, 0.4, 96, 48)?,
            s if s.to_lowercase().ends_with(".obj") => {
                ifd_render::Mesh::load(std::path::Path::new(s), false)?
            }
            s => bail!("--scene {s:?}: use torus or an .obj file"),
        });
        let materials = degrees
            .iter()
            .map(|&l| {
                let table = Material::new(&brdf, l, None).is_err().then(|| {
                    eprintln!("building a lobe table at L = {l}...");
                    LobeTable::build(&brdf, l, default_theta_entries(&brdf), 32, &|_, _| {})
                });
                Ok(Material::new(&brdf, l, table.transpose()?)?)
            })
            .collect::<Result<Vec<_>>>()?;
        let scene = VisibilityScene {
            mesh: mesh.clone(),
            camera,
            env: &env,
            brdf: &brdf,
        };
        let s = study(&scene, &materials, self.rays, &|m| {
            eprintln!("{m}");
        })?;
        if let Some(dir) = &self.out_dir {
            super::write_figure(
                dir,
                &[
                    ("unshadowed", &s.unshadowed),
                    ("isd-visibility", &s.shadowed),
                    ("reference", &s.reference),
                ],
                0.0,
            )?;
            let mut csv = String::from("l,isd_visibility,isd_unshadowed\n");
            for (l, a, b) in &s.rows {
                let _ = writeln!(csv, "{l},{a},{b}");
            }
            crate::output::write_text(&dir.join("error.csv"), &csv)?;
            let series = [
                ("with visibility", [0.1, 0.3, 0.9], false, 1),
                ("unshadowed", [0.85, 0.1, 0.1], true, 2),
            ]
            .map(|(name, colour, dotted, k)| ifd_plot::Series {
                name: name.into(),
                colour,
                dotted,
                points: s
                    .rows
                    .iter()
                    .map(|r| (r.0 as f64, if k == 1 { r.1 } else { r.2 }))
                    .collect(),
            });
            let plot = ifd_plot::log_line_plot(
                &series,
                "L (maximum SH degree)",
                "relative RMS error vs ray-traced",
            )?;
            crate::output::write_output(
                &dir.join("error.png"),
                &plot,
                &ifd_image::WriteOptions::default(),
            )?;
        }
        self.report.emit(&json!({
                "brdf": brdf.spec(), "scene": self.scene, "width": w, "height": h,
                "env_size": [ew, eh], "rays": self.rays, "triangles": mesh.triangles(),
                "vertices": mesh.positions().len(),
                "rows": s.rows.iter().map(|(l, a, b)| json!({"l": l, "isd_visibility": a, "isd_unshadowed": b})).collect::<Vec<_>>(),
                "seconds": {"reference": s.seconds[0], "visibility_and_product_matrix": s.seconds[1],
                            "isd_frame": s.seconds[2]},
            }))?;
        Ok(())
    }
}
