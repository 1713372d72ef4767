//! The work of `ifd render` with a BRDF, its flags checked: the lobe
//! tables, the render (on the CPU or the GPU), the oracle of --error-map,
//! the outputs and the report.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use ifd_render::{Job, Method, RoughnessFamily, Shadows, SurfaceMaps, Texture, render};
use ifd_shade::{LobeTable, Material, Precision, default_theta_entries};
use serde_json::json;

use super::config::{BrdfConfig, View};
use super::{Render, RenderPrecision, is_display};
use crate::options::number;

impl Render {
    /// Renders the scene with the BRDF of `c`, writes the outputs and the
    /// report.
    #[expect(
        clippy::too_many_lines,
        reason = "one linear render: tables, render, oracle, outputs, report"
    )]
    pub(super) fn render_brdf(&self, view: View, c: BrdfConfig) -> Result<()> {
        let View {
            scene,
            camera,
            tonemap,
            display,
        } = view;
        let BrdfConfig {
            brdf,
            method,
            l_max,
            lights,
            asset_materials,
            asset_range,
            tol,
        } = c;
        let (w, h) = (camera.width(), camera.height());
        let output = &self.output;
        // the device first: no adapter is an error before any slow work
        let gpu = if self.gpu {
            let ctx = ifd_gpu::GpuContext::new().context("--gpu")?;
            eprintln!(
                "note: --gpu: shading on {} ({:?})",
                ctx.adapter_info().name,
                ctx.adapter_info().device_type
            );
            Some(ctx)
        } else {
            None
        };
        // what ISD tabulates: the glTF BRDF's three parts, else the BRDF
        let tabulated = brdf.tabulated()?;
        let (full, env) = self.env.environments(&self.input)?;
        let (ew, eh) = (env.image().width(), env.image().height());
        let start = std::time::Instant::now();
        // with a roughness map the ISD methods shade with the roughness family
        // built below, not with one material
        let material = match (method, l_max) {
            (
                Method::Quadrature | Method::Mc | Method::SplitSum | Method::SplitSumSampleRenderer,
                _,
            )
            | (_, None) => None,
            _ if self.roughness_map.is_some() || asset_materials => None,
            (_, Some(l)) => {
                let table = match &self.table {
                    Some(p) => Some(LobeTable::read(p)?),
                    None if Material::new(&tabulated, l, None).is_err() => {
                        let nt = default_theta_entries(&tabulated);
                        let np = (2 * nt).min(128);
                        eprintln!(
                            "note: building the lobe table of {} at L = {l} (save one with \
                             `ifd sphere brdf` and pass --table to skip this)",
                            tabulated.spec()
                        );
                        let bar = crate::progress::bar("table", "", 0);
                        let t =
                            LobeTable::build(&tabulated, l, nt, np, &crate::progress::track(&bar))?;
                        bar.finish_and_clear();
                        Some(t)
                    }
                    None => None,
                };
                let m = Material::new(&tabulated, l, table);
                Some(m.with_context(|| match &self.table {
                    Some(p) => format!("{}", p.display()),
                    None => "--brdf".into(),
                })?)
            }
        };
        let surface = self.surface_maps()?;
        let family = match (&surface.roughness, method, l_max) {
            (rough, Method::Isd | Method::IsdMaps | Method::Sh, Some(l))
                if rough.is_some() || asset_range.is_some() =>
            {
                // a roughness map's range, else the glTF asset's
                let range = match rough {
                    Some(t) => t.range(),
                    None => asset_range.unwrap_or((1.0, 1.0)),
                };
                let bar = crate::progress::bar("roughness tables", "", 0);
                let f = RoughnessFamily::build(
                    &tabulated,
                    l,
                    range,
                    self.roughness_tables,
                    &crate::progress::track(&bar),
                )?;
                bar.finish_and_clear();
                Some(f)
            }
            _ => None,
        };
        let shadows = match (&scene, self.shadows) {
            (ifd_render::Scene::Mesh(mesh), true) => Some(match l_max {
                Some(l) if method == Method::Isd => {
                    let bar = crate::progress::bar("visibility", "", 0);
                    let s = Shadows::new(
                        mesh.clone(),
                        &env,
                        l,
                        self.shadow_rays as usize,
                        &crate::progress::track(&bar),
                    )?;
                    bar.finish_and_clear();
                    s
                }
                _ => Shadows::traced(mesh.clone(), &env)?,
            }),
            _ => None,
        };
        let job = Job {
            scene,
            camera,
            env: &env,
            background: (!self.no_background).then_some(&full),
            brdf: &brdf,
            material: material.as_ref(),
            method,
            spp: self.spp,
            seed: self.seed,
            maps: Some(&surface),
            family: family.as_ref(),
            lights: &lights,
            shadows: shadows.as_ref(),
            split_sum: None,
            precision: match self.precision {
                RenderPrecision::F32 => Precision::F32,
                RenderPrecision::F64 => Precision::F64,
            },
        };
        let t_render = std::time::Instant::now();
        let (r, gpu_report) = if let Some(ctx) = &gpu {
            let (r, report) = self.render_gpu(ctx, &job)?;
            (r, Some(report))
        } else {
            let bar = crate::progress::bar("render", "", 0);
            let r = render(&job, &crate::progress::track(&bar))?;
            bar.finish_and_clear();
            (r, None)
        };
        let render_secs = t_render.elapsed().as_secs_f64();
        if let Some(p) = &self.gbuffer {
            write_gbuffer(p, &job)?;
        }
        let error_map = match &self.error_map {
            Some(p) => {
                let bar = crate::progress::bar("oracle", "", 0);
                let oracle_job = Job {
                    scene: job.scene.clone(),
                    camera: job.camera,
                    env: job.env,
                    background: None,
                    brdf: job.brdf,
                    material: None,
                    method: Method::Quadrature,
                    spp: job.spp,
                    seed: job.seed,
                    maps: job.maps,
                    family: None,
                    lights: job.lights,
                    shadows: None,
                    split_sum: None,
                    precision: job.precision,
                };
                let oracle = render(&oracle_job, &crate::progress::track(&bar))?;
                bar.finish_and_clear();
                Some(write_error_map(p, &r.image, &oracle.image, &r.mask)?)
            }
            None => None,
        };
        let secs = start.elapsed().as_secs_f64();
        let mut img = r.image;
        if display {
            for v in img.data_mut() {
                *v = tonemap.display(*v, self.display.exposure);
            }
        }
        if let Some(m) = &self.mask {
            let data = r.mask.iter().map(|x| f32::from(u8::from(*x))).collect();
            let mask = ifd_image::Image::from_vec(w, h, 1, data)?;
            crate::output::write_output(m, &mask, &ifd_image::WriteOptions::default())?;
        }
        if let (Some(p), Some(se)) = (&self.stderr, &r.stderr) {
            crate::output::write_output(p, se, &ifd_image::WriteOptions::default())?;
        }
        crate::output::write_output(output, &img, &ifd_image::WriteOptions::default())?;
        let summary = || {
            let spp = (method == Method::Mc).then_some(self.spp);
            let mut text = self.summary_head((w, h), l_max, brdf.spec(), spp, secs);
            if let Some(t) = &tol {
                let _ = writeln!(text, "{}", t.line());
            }
            let f = |v: &serde_json::Value, k: &str, scale: f64| {
                v[k].as_f64()
                    .map_or_else(|| "-".to_owned(), |x| number(scale * x))
            };
            if method == Method::Quadrature {
                let _ = writeln!(
                    text,
                    "quadrature: {} pixel(s) not converged, largest residual {}",
                    r.not_converged,
                    number(r.max_residual)
                );
            }
            if let Some(g) = &gpu_report {
                let _ = writeln!(
                    text,
                    "GPU {}: {} frame(s), median {} ms per frame ({} ms GPU time)",
                    g["adapter"].as_str().unwrap_or("?"),
                    g["frames"],
                    f(g, "frame_seconds_median", 1e3),
                    f(g, "gpu_seconds_median", 1e3),
                );
            }
            if let Some(e) = &error_map {
                let _ = writeln!(
                    text,
                    "against the oracle: relative RMS {}, largest difference {}",
                    f(e, "relative_rms", 1.0),
                    f(e, "max_abs_difference", 1.0),
                );
            }
            text
        };
        let report = json!({
            "method": self.method.name(), "brdf": brdf.spec(), "lmax": l_max,
            "scene": self.scene.scene, "width": w, "height": h, "shadows": self.shadows,
            "env_size": [ew, eh], "object_pixels": r.object_pixels,
            "closed_form": material.as_ref().map(Material::is_closed_form),
            "quadrature_max_k": (method == Method::Quadrature).then_some(r.max_k),
            "quadrature_unconverged_pixels": (method == Method::Quadrature).then_some(r.not_converged),
            "quadrature_max_residual": (method == Method::Quadrature).then_some(r.max_residual),
            "spp": (method == Method::Mc).then_some(self.spp),
            // the CPU's isd lanes as they ran (f32 falls back to f64
            // without AVX2 + FMA) and the instruction set
            "lanes": (method == Method::Isd && gpu_report.is_none()).then(|| {
                match job.precision.effective() {
                    Precision::F32 => "f32",
                    Precision::F64 => "f64",
                }
            }),
            "vector_isa": gpu_report.is_none().then(|| ifd_simd::isa().name()),
            "seconds": secs, "render_seconds": render_secs,
            "gpu": gpu_report,
            "error_map": error_map,
            "tol": tol.as_ref().map(super::config::TolChoice::json),
        });
        self.report.emit_summary(&report, summary)?;
        Ok(())
    }

    /// The `--gpu` path: upload, shade `--frames` times, read the last frame.
    /// Returns the image and a JSON report (adapter, median GPU and wall
    /// times per frame, frames per second, bytes on the device).
    fn render_gpu(
        &self,
        ctx: &ifd_gpu::GpuContext,
        job: &Job<'_>,
    ) -> Result<(ifd_render::Rendered, serde_json::Value)> {
        use std::time::Instant;
        let t = Instant::now();
        let prepared = ifd_gpu::GpuRender::new(ctx, job).context("--gpu")?;
        let upload = t.elapsed().as_secs_f64();
        let bar = crate::progress::bar("frames", "", self.frames as u64);
        let (mut gpu_times, mut wall_times) = (Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..self.frames {
            let t = Instant::now();
            let shaded = prepared.shade(ctx)?;
            // waits for the frame
            if let Some(g) = shaded.gpu_time(ctx)? {
                gpu_times.push(g.as_secs_f64());
            }
            let r = prepared.rendered(ctx, &shaded)?;
            wall_times.push(t.elapsed().as_secs_f64());
            last = Some(r);
            bar.inc(1);
        }
        bar.finish_and_clear();
        let Some(r) = last else {
            bail!("--frames 0");
        };
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            (!v.is_empty()).then(|| v[v.len() / 2])
        };
        let gpu_median = median(&mut gpu_times);
        let wall_median = median(&mut wall_times);
        let (env_bytes, material_bytes) = prepared.device_bytes();
        let info = ctx.adapter_info();
        Ok((
            r,
            json!({
                "adapter": info.name, "device_type": format!("{:?}", info.device_type),
                "frames": self.frames, "upload_seconds": upload,
                "gpu_seconds_median": gpu_median,
                "frame_seconds_median": wall_median,
                "fps_gpu": gpu_median.map(|s| 1.0 / s),
                "env_bytes": env_bytes, "material_bytes": material_bytes,
            }),
        ))
    }

    /// The albedo and roughness maps.
    pub(super) fn surface_maps(&self) -> Result<SurfaceMaps> {
        let read = |p: &PathBuf, srgb: bool, what: &'static str| -> Result<Texture> {
            let opts = ifd_image::ReadOptions {
                srgb_decode: srgb,
                ..Default::default()
            };
            let img = ifd_image::read_image(p, &opts)?.image;
            Texture::new(img, what).with_context(|| format!("{}", p.display()))
        };
        Ok(SurfaceMaps {
            albedo: self
                .albedo_map
                .as_ref()
                .map(|p| read(p, true, "--albedo-map"))
                .transpose()?,
            roughness: self
                .roughness_map
                .as_ref()
                .map(|p| read(p, false, "--roughness-map"))
                .transpose()?,
            normal: self
                .normal_map
                .as_ref()
                .map(|p| read(p, false, "--normal-map"))
                .transpose()?,
        })
    }
}

/// `--gbuffer`: normal, n.v, roughness and metalness per pixel (six
/// channels, zeros off the object).
fn write_gbuffer(path: &std::path::Path, job: &Job<'_>) -> Result<()> {
    let (w, h) = (job.camera.width(), job.camera.height());
    let gltf = job.brdf.gltf_material();
    let px = ifd_render::pixels(&job.scene, &job.camera, job.maps)?;
    let data = px
        .iter()
        .flat_map(|p| {
            let Some(s) = &p.surface else {
                return [0.0; 6];
            };
            let n = s.frame.n;
            let nv = n[0] * s.wo[0] + n[1] * s.wo[1] + n[2] * s.wo[2];
            let point = gltf.map(|g| s.gltf_material(&g));
            let rough = point.map(|m| m.roughness).or(s.roughness);
            let metal = point.map(|m| m.metallic);
            [
                n[0],
                n[1],
                n[2],
                nv,
                rough.unwrap_or(f64::NAN),
                metal.unwrap_or(f64::NAN),
            ]
            .map(|v| v as f32)
        })
        .collect();
    let img = ifd_image::Image::from_vec(w, h, 6, data)?;
    // NaN is the documented value where the BRDF has no roughness or
    // metalness (a .npy holds it as such)
    let options = ifd_image::WriteOptions {
        allow_non_finite: true,
        ..ifd_image::WriteOptions::default()
    };
    crate::output::write_output(path, &img, &options)?;
    Ok(())
}

/// Writes the difference of `image` to the oracle (see `--error-map`) and
/// returns its summary: the relative RMS error over the object, the largest
/// absolute difference, the PNG's full scale.
fn write_error_map(
    path: &std::path::Path,
    image: &ifd_image::Image,
    oracle: &ifd_image::Image,
    mask: &[bool],
) -> Result<serde_json::Value> {
    let ch = image.channels();
    let (w, h) = (image.width(), image.height());
    let d = ifd_render::Difference::new(image, oracle, mask)?;
    // the PNG shows the difference relative to the exact value, full scale
    // its 95th percentile over the object
    let scale = d.full_scale;
    let out = if is_display(path)? {
        let rgb = d
            .relative
            .iter()
            .flat_map(|m| ifd_plot::diverging(m / scale))
            .collect();
        ifd_image::Image::from_vec(w, h, 3, rgb)?
    } else {
        let diff = image
            .data()
            .iter()
            .zip(oracle.data())
            .enumerate()
            .map(|(i, (a, o))| if mask[i / ch] { a - o } else { 0.0 })
            .collect();
        ifd_image::Image::from_vec(w, h, ch, diff)?
    };
    crate::output::write_output(path, &out, &ifd_image::WriteOptions::default())?;
    let (rms, max) = (d.relative_rms, d.max_abs);
    eprintln!(
        "note: --error-map {}: relative RMS {rms:.3e} against the oracle, largest difference \
         {max:.3e}; the PNG's full scale is a relative difference of {scale:.3e} (95th percentile)",
        path.display()
    );
    Ok(json!({"relative_rms": rms, "max_abs_difference": max, "png_full_scale": scale}))
}
