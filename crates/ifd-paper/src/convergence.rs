//! Convergence of ISD and SH shading to the exact oracle as `L` grows (the
//! ISD paper's Fig. 4): relative RMS error and PSNR over object pixels, per
//! BRDF and degree.

use std::fmt::Write as _;

use ifd_image::Image;
use ifd_plot::{Series, log_line_plot};
use ifd_shade::Brdf;
use ifd_shade::Material;
use ifd_shade::{LobeTable, default_theta_entries};

use ifd_render::Camera;
use ifd_render::EnvMap;
use ifd_render::Result;
use ifd_render::Scene;
use ifd_render::{Job, Method, Rendered, relative_rms, render};

/// One measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// The BRDF spec.
    pub brdf: String,
    /// The degree.
    pub l: usize,
    /// `isd` or `sh`.
    pub method: &'static str,
    /// `sqrt(sum (a - b)^2 / sum b^2)` over object pixels and channels.
    pub rel_rms: f64,
    /// `10 log10(max^2 / MSE)`, `max` the oracle's largest object value.
    pub psnr: f64,
}

/// PSNR of `a` against `b` over the masked pixels, with the peak of `b` there.
#[must_use]
pub fn psnr(a: &Image, b: &Image, mask: &[bool]) -> f64 {
    let ch = a.channels();
    let (mut se, mut n, mut peak) = (0.0, 0.0, 0.0f64);
    for (i, m) in mask.iter().enumerate() {
        if *m {
            for c in 0..ch {
                let (x, y) = (
                    f64::from(a.data()[i * ch + c]),
                    f64::from(b.data()[i * ch + c]),
                );
                se += (x - y) * (x - y);
                n += 1.0;
                peak = peak.max(y);
            }
        }
    }
    if se == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (peak * peak / (se / n)).log10()
    }
}

/// What a convergence study renders.
#[derive(Debug)]
pub struct Study<'a> {
    /// The scene.
    pub scene: Scene,
    /// The camera.
    pub camera: Camera,
    /// The (downsampled) environment every method integrates.
    pub env: &'a EnvMap,
    /// The BRDFs.
    pub brdfs: &'a [Brdf],
    /// The degrees.
    pub degrees: &'a [usize],
    /// Whether to also render the SH reference (slow at high `L`).
    pub with_sh: bool,
}

/// The result: rows, and per BRDF the oracle and the ISD images per degree.
#[derive(Debug)]
pub struct Outcome {
    /// Measurements.
    pub rows: Vec<Row>,
    /// `(oracle, [isd image per degree])` per BRDF.
    pub images: Vec<(Rendered, Vec<Image>)>,
}

/// Runs the study; `progress(message)` before each render.
///
/// # Errors
/// As [`render`] and the table builder.
pub fn run(study: &Study<'_>, progress: &dyn Fn(&str)) -> Result<Outcome> {
    let mut rows = Vec::new();
    let mut images = Vec::new();
    for brdf in study.brdfs {
        progress(&format!("{}: oracle", brdf.spec()));
        let oracle = render(&job(study, brdf, Method::Quadrature, None), &|_, _| {})?;
        let mut isd_images = Vec::new();
        for &l in study.degrees {
            progress(&format!("{}: L = {l}", brdf.spec()));
            let table = if Material::new(brdf, l, None).is_err() {
                let nt = default_theta_entries(brdf);
                Some(LobeTable::build(
                    brdf,
                    l,
                    nt,
                    (2 * nt).min(128),
                    &|_, _| {},
                )?)
            } else {
                None
            };
            let m = Material::new(brdf, l, table)?;
            let mut methods = vec![Method::Isd];
            if study.with_sh {
                methods.push(Method::Sh);
            }
            for method in methods {
                let r = render(&job(study, brdf, method, Some(&m)), &|_, _| {})?;
                rows.push(Row {
                    brdf: brdf.spec().to_string(),
                    l,
                    method: if method == Method::Isd { "isd" } else { "sh" },
                    rel_rms: relative_rms(&r.image, &oracle.image, &oracle.mask),
                    psnr: psnr(&r.image, &oracle.image, &oracle.mask),
                });
                if method == Method::Isd {
                    isd_images.push(r.image);
                }
            }
        }
        images.push((oracle, isd_images));
    }
    Ok(Outcome { rows, images })
}

fn job<'b>(
    study: &Study<'b>,
    brdf: &'b Brdf,
    method: Method,
    material: Option<&'b Material>,
) -> Job<'b> {
    Job::new(
        study.scene.clone(),
        study.camera,
        study.env,
        brdf,
        material,
        method,
    )
}

/// The rows as CSV (`brdf,L,method,rel_rms,psnr_db`).
#[must_use]
pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from("brdf,L,method,rel_rms,psnr_db\n");
    for r in rows {
        let _ = writeln!(
            s,
            "\"{}\",{},{},{:e},{:.3}",
            r.brdf, r.l, r.method, r.rel_rms, r.psnr
        );
    }
    s
}

/// The plot: relative RMS error (log scale) against `L`, one colour per BRDF,
/// ISD solid and SH dotted (they coincide: same band-limited slice).
///
/// # Errors
/// Only if the image cannot be allocated.
pub fn plot(rows: &[Row]) -> Result<Image> {
    const COLOURS: [[f32; 3]; 8] = [
        [0.0, 0.0, 0.0],
        [0.1, 0.3, 0.9],
        [0.85, 0.1, 0.1],
        [0.1, 0.6, 0.2],
        [0.95, 0.55, 0.0],
        [0.55, 0.2, 0.7],
        [0.0, 0.6, 0.7],
        [0.6, 0.4, 0.2],
    ];
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.brdf.as_str()) {
            names.push(&r.brdf);
        }
    }
    let mut series = Vec::new();
    for (i, name) in names.iter().enumerate() {
        for (method, dotted) in [("isd", false), ("sh", true)] {
            let points: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.brdf == *name && r.method == method)
                .map(|r| (r.l as f64, r.rel_rms))
                .collect();
            if !points.is_empty() {
                series.push(Series {
                    name: if dotted {
                        format!("{name} sh")
                    } else {
                        (*name).to_string()
                    },
                    colour: COLOURS[i % COLOURS.len()],
                    dotted,
                    points,
                });
            }
        }
    }
    Ok(log_line_plot(
        &series,
        "L (maximum SH degree)",
        "relative RMS error vs the oracle",
    )?)
}
