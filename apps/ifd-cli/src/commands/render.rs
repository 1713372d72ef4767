//! `ifd render`: objects lit by an environment map, shaded by ISD (Eq. 22,
//! from SH or from prefiltered maps), its SH reference, Monte Carlo or the
//! exact texel quadrature.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use ifd_render::Shadows;
use ifd_render::{Job, Method, render};
use ifd_render::{RoughnessFamily, SurfaceMaps, Texture};
use ifd_shade::Brdf;
use ifd_shade::{LobeTable, default_theta_entries};
use ifd_shade::{Material, Precision};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use crate::input::InputOptions;
use crate::options::{CameraOptions, DisplayOptions, EnvOptions, ReportOptions, SceneOptions};

/// Render an analytic object or a mesh lit by an environment map (one ray per
/// pixel centre; unshadowed unless --shadows).
///
/// Frames: world z up, as the SH code and the equirectangular convention.
/// Every method integrates the same environment, averaged down to --env-size
/// by solid angle and read as constant over each texel: `isd` and `sh` use its
/// exact SH projection up to L, `quadrature` integrates each texel against the
/// exact BRDF (Gauss-Legendre per texel, each texel refined until its value
/// changes by less than 1e-6 of the pixel). Anisotropic BRDFs align `ax` with dP/du of the
/// surface (the sphere's and torus' azimuth, the plane's x). Lambert and Phong
/// shade with closed-form weights; other BRDFs need a lobe table (--table, or
/// one is built at the default resolution). The background shows the full
/// resolution map (nearest texel).
///
/// Output: .exr/.hdr/.npy are linear radiance; .png (8-bit sRGB) gets
/// --exposure and --tonemap.
#[derive(Debug, Args)]
#[expect(
    clippy::struct_excessive_bools,
    reason = "independent command-line switches"
)]
pub struct Render {
    #[command(flatten)]
    env: EnvOptions,
    /// BRDF spec: lambert, phong:s=.., blinn:s=.., blinn-exact:s=.., ggx:alpha=.. or
    /// ggx:ax=..,ay=.., ward:.., merl:FILE, gltf:roughness=..,metallic=..,base=R:G:B (the glTF
    /// 2.0 metallic-roughness BRDF, shaded exactly: ISD integrates its three view-dependent
    /// parts, the table of gltf-lobes:roughness=..); or mirror, a perfect mirror reflecting the full
    /// resolution map (bilinear), anti-aliased over the pixel filter (a Gaussian of 0.5 pixel
    /// over [-1, 1]^2) by --method: isd filters the footprint's reflected directions as one
    /// spherical Gaussian (ISD Eq. 26-29, from the map's SH up to --lmax; a mip lookup where
    /// the footprint is narrower than pi/L), quadrature averages a regular sqrt(N)xsqrt(N)
    /// grid of --spp N samples (--spp 1: the pixel centre, no anti-aliasing), mc a jittered
    /// stratified one (the reference).
    ///
    /// Default for a glTF asset (--scene FILE.gltf/.glb): gltf, each point shaded with the
    /// asset's own materials and textures; another spec shades its geometry with that BRDF.
    #[arg(long, value_name = "SPEC")]
    brdf: Option<String>,
    /// Maximum SH degree L: required by --method isd, isd-maps and sh (and by
    /// isd with --brdf mirror).
    #[arg(long, value_name = "L")]
    lmax: Option<usize>,
    /// Lobe table from `ifd sphere brdf` (built on the fly when needed and absent).
    #[arg(long, value_name = "FILE")]
    table: Option<PathBuf>,
    #[command(flatten)]
    scene: SceneOptions,
    #[command(flatten)]
    camera: CameraOptions,
    /// Shading algorithm.
    #[arg(long, value_enum, default_value_t = RenderMethod::Isd)]
    method: RenderMethod,
    /// Arithmetic of the CPU's isd lookups at the lobes (--method isd without --gpu): f32
    /// (sixteen lanes a vector on AVX-512; within 1e-5 of the image maximum of f64's, tested
    /// to L = 60, 5e-7 measured at L = 100; without AVX2 + FMA it runs the f64 lanes) or f64 (the reference: isd and
    /// sh agree to 1e-9). IFD_SIMD=avx2|baseline caps the instruction set.
    #[arg(long, value_enum, default_value_t = RenderPrecision::F32)]
    precision: RenderPrecision,
    /// Shade on the GPU (wgpu, Vulkan: a hardware adapter when there is one,
    /// else lavapipe) with the WGSL kernels of the environment renderer
    /// (shaders/isd_shade.wgsl); methods isd and isd-maps. Rays are cast on the
    /// CPU. f32 arithmetic: agrees with the CPU path to 1e-3 of the object's
    /// maximum (measured 1e-5 or better). Fails, naming the problem, without an
    /// adapter or beyond the device's limits.
    #[arg(long)]
    gpu: bool,
    /// With --gpu: shade the frame N times and report the median GPU time per
    /// frame and frames per second (benchmarks; the image is the last frame).
    #[arg(long, value_name = "N", default_value_t = 1, requires = "gpu")]
    frames: usize,
    /// Monte Carlo samples per pixel (each: one environment and one BRDF sample); with --brdf
    /// mirror, the samples of the pixel filter (a square number).
    #[arg(long, value_name = "N", default_value_t = 64)]
    spp: usize,
    /// Random seed.
    #[arg(long, value_name = "N", default_value_t = 1)]
    seed: u64,
    /// Monte Carlo: also write the per-pixel standard error (linear; .exr or .npy).
    #[arg(long, value_name = "FILE")]
    stderr: Option<PathBuf>,
    /// Black background instead of the environment.
    #[arg(long)]
    no_background: bool,
    #[command(flatten)]
    display: DisplayOptions,
    /// Albedo map over the surface's texture coordinates (multiplies the BRDF, or the base
    /// colour of --brdf gltf; 8/16-bit files are sRGB-encoded as glTF's base colour, float
    /// files linear).
    #[arg(long, value_name = "IMAGE")]
    albedo_map: Option<PathBuf>,
    /// Roughness map (first channel, linear, alpha = roughness^2 as glTF) for an isotropic GGX,
    /// Ward or glTF BRDF; ISD blends lobe tables at --roughness-tables values over the map's range.
    #[arg(long, value_name = "IMAGE")]
    roughness_map: Option<PathBuf>,
    /// Tangent-space normal map over the surface's texture coordinates (RGB, linear, glTF's
    /// convention: x along dP/du, y along N x T, z along the normal, encoded as (n + 1) / 2);
    /// perturbs the shading frame of every method and the reflection of --brdf mirror.
    #[arg(long, value_name = "IMAGE")]
    normal_map: Option<PathBuf>,
    /// Lobe tables across the roughness map's range (ISD methods).
    #[arg(long, value_name = "K", default_value_t = 8)]
    roughness_tables: usize,
    /// A local spherical light added to the environment (ISD Sec. 7.3): centre, radius and the
    /// radiance of its surface, `x,y,z,radius,L` or `x,y,z,radius,R,G,B`; repeat for several.
    /// isd, isd-maps and sh shade it as zonal lighting per point (Eq. 33-34, at the same L),
    /// quadrature integrates its cap exactly; not with mc or --gpu. Unshadowed; the light is
    /// drawn where the camera sees it.
    #[arg(long, value_name = "X,Y,Z,R,L", allow_hyphen_values = true)]
    light: Vec<String>,
    /// Self-shadowing of a mesh scene (ISD Eq. 25, Appendix A): the visibility of every vertex
    /// is cast with --shadow-rays rays and projected on SH up to --lmax; isd shades by the
    /// three steps of Appendix A (the visibility interpolated over each triangle), quadrature
    /// traces the visibility of 2x2 nodes per texel from each pixel's point (the reference).
    /// Not with other methods, --light, --roughness-map or --gpu.
    #[arg(long)]
    shadows: bool,
    /// Rays per vertex for the visibility of --shadows (at least (L+1)^2).
    #[arg(long, value_name = "N", default_value_t = 4096, requires = "shadows",
          value_parser = clap::value_parser!(u32).range(1..=1 << 20))]
    shadow_rays: u32,
    /// Look through the glTF asset's camera (its first perspective camera in the default
    /// scene) instead of --eye, --target, --up and --fov.
    #[arg(long)]
    scene_camera: bool,
    /// Also write the object mask (1 on the object, 0 elsewhere).
    #[arg(long, value_name = "FILE")]
    mask: Option<PathBuf>,
    /// Also write what each pixel's ray sees, as .npy (height x width x 6): the shading normal
    /// (x, y, z), n.v, and the roughness and metalness the point is shaded with (the glTF
    /// material's, else the roughness map's; NaN where the BRDF has none); zeros off the object.
    #[arg(long, value_name = "FILE.npy")]
    gbuffer: Option<PathBuf>,
    /// Also render the exact oracle (--method quadrature, same scene) and write the per-pixel
    /// difference of the image to it: signed RGB radiance in .exr/.npy; in .png a diverging
    /// map of the difference relative to the oracle (to its value, or to 5% of its mean over
    /// the object where darker), averaged over channels (red: brighter than the oracle, blue:
    /// darker), full scale the 95th percentile of the object's relative differences, printed
    /// and in the --json report.
    #[arg(long, value_name = "FILE")]
    error_map: Option<PathBuf>,
    /// Output image.
    #[arg(short, long, value_name = "IMAGE")]
    output: PathBuf,
    #[command(flatten)]
    report: ReportOptions,
    #[command(flatten)]
    input: InputOptions,
}

/// `ifd render --precision` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RenderPrecision {
    /// f32 lanes: the fast path.
    F32,
    /// f64 lanes: the reference.
    F64,
}

/// `ifd render --method` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RenderMethod {
    /// ISD (Eq. 22) from the environment's SH.
    Isd,
    /// ISD from per-band prefiltered maps.
    IsdMaps,
    /// The rotated slice's SH, same weights (ISD's reference).
    Sh,
    /// The exact oracle: each texel integrated against the exact BRDF.
    Quadrature,
    /// Monte Carlo: environment and BRDF importance sampling, MIS, low-discrepancy points.
    Mc,
    /// The split-sum approximation engines use, for --brdf gltf: the prefiltered chain and
    /// irradiance of `ifd envmap prefilter` (256 faces, baked in memory) and the DFG table.
    SplitSum,
    /// glTF-Sample-Renderer's split-sum shader as written (KhronosGroup, pbr.frag at 07d2ba65).
    SplitSumSampleRenderer,
}

impl RenderMethod {
    /// The renderer's method.
    pub fn method(self) -> Method {
        match self {
            Self::Isd => Method::Isd,
            Self::IsdMaps => Method::IsdMaps,
            Self::Sh => Method::Sh,
            Self::Quadrature => Method::Quadrature,
            Self::Mc => Method::Mc,
            Self::SplitSum => Method::SplitSum,
            Self::SplitSumSampleRenderer => Method::SplitSumSampleRenderer,
        }
    }

    /// The value's name on the command line.
    pub fn name(self) -> String {
        self.to_possible_value()
            .map_or_else(String::new, |v| v.get_name().to_owned())
    }
}

/// Whether the output gets the display transform (8-bit formats).
pub(crate) fn is_display(path: &std::path::Path) -> Result<bool> {
    use ifd_image::FileFormat;
    Ok(matches!(
        FileFormat::from_path(path)?,
        FileFormat::Png | FileFormat::Jpeg | FileFormat::Tiff
    ))
}

impl Render {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let output = self.output.clone();
        let method = self.method.method();
        let scene = self.scene.scene_with(self.input.budget())?;
        let asset = match &scene {
            ifd_render::Scene::Gltf(a) => {
                for note in a.notes() {
                    eprintln!("note: {}: {note}", self.scene.scene);
                }
                Some(a.clone())
            }
            _ => None,
        };
        let brdf_spec = match (&self.brdf, &asset) {
            (Some(b), _) => b.clone(),
            (None, Some(_)) => "gltf".to_string(),
            (None, None) => bail!(
                "--brdf SPEC is needed (a glTF asset, --scene FILE.glb, brings its own materials)"
            ),
        };
        let asset_materials = asset.is_some() && brdf_spec.starts_with("gltf");
        if asset_materials {
            for (set, flag) in [
                (self.albedo_map.is_some(), "--albedo-map"),
                (self.roughness_map.is_some(), "--roughness-map"),
                (self.normal_map.is_some(), "--normal-map"),
            ] {
                if set {
                    bail!(
                        "{flag}: the glTF asset {} brings its own textures (pass another --brdf \
                         to shade its geometry with maps)",
                        self.scene.scene
                    );
                }
            }
        }
        if self.scene_camera && asset.as_ref().is_none_or(|a| a.camera().is_none()) {
            bail!(
                "--scene-camera: {} has no perspective camera",
                self.scene.scene
            );
        }
        let tonemap = self.display.tonemap()?;
        let display = is_display(&output)?;
        if let Some(m) = &self.mask {
            is_display(m)?;
        }
        if let Some(g) = &self.gbuffer
            && ifd_image::FileFormat::from_path(g)? != ifd_image::FileFormat::Npy
        {
            bail!("--gbuffer {}: write six channels as .npy", g.display());
        }
        if let Some(p) = &self.error_map {
            if matches!(
                ifd_image::FileFormat::from_path(p)?,
                ifd_image::FileFormat::Hdr
                    | ifd_image::FileFormat::Jpeg
                    | ifd_image::FileFormat::Tiff
            ) {
                bail!(
                    "--error-map {}: use .exr or .npy (signed differences) or .png (a diverging map)",
                    p.display()
                );
            }
            if method == Method::Quadrature {
                bail!("--error-map compares with the oracle, which --method quadrature is");
            }
            if self.gpu {
                bail!("--error-map: the oracle is a CPU render; drop --gpu");
            }
            if self.shadows {
                bail!(
                    "--error-map: not with --shadows (compare with --method quadrature --shadows)"
                );
            }
        }
        let camera = match asset
            .as_ref()
            .and_then(|a| a.camera())
            .filter(|_| self.scene_camera)
        {
            Some(c) => {
                let (w, h) = crate::input::parse_size(&self.camera.size, "--size")?;
                ifd_render::Camera::new(c.eye, c.target, c.up, c.fov_deg, w, h)?
            }
            None => self.camera.camera()?,
        };
        let (w, h) = (camera.width(), camera.height());
        // the image, its row buffers and the mask, before any work
        let bytes = (w as u64)
            .saturating_mul(h as u64)
            .saturating_mul(3 * 4 * 2 + 1);
        self.input
            .budget()
            .check(bytes)
            .with_context(|| format!("--size {w}x{h}"))?;
        if brdf_spec == "mirror" {
            return self.run_mirror(&scene, camera, tonemap, display);
        }
        let brdf = Brdf::parse(&brdf_spec).map_err(|e| {
            let message = e.to_string();
            if message.contains("unknown BRDF") {
                anyhow::anyhow!("{message}; ifd render also takes mirror")
            } else {
                e.into()
            }
        })?;
        if !brdf.is_isotropic() && !scene.has_tangents() {
            bail!(
                "--brdf {}: an anisotropic BRDF needs tangents, and {} has no texture coordinates",
                brdf.spec(),
                self.scene.scene
            );
        }
        if method == Method::Mc && !(1..=1 << 24).contains(&self.spp) {
            bail!("--spp {}: use 1..=16777216 samples per pixel", self.spp);
        }
        if self.stderr.is_some() && method != Method::Mc {
            bail!("--stderr is written by --method mc only");
        }
        if self.stderr.is_some() && self.spp < 2 {
            bail!("--stderr needs --spp 2 or more (a variance from one sample is undefined)");
        }
        if let Some(p) = &self.stderr {
            is_display(p)?;
        }
        let l_max = match (method, self.lmax) {
            (
                Method::Quadrature | Method::Mc | Method::SplitSum | Method::SplitSumSampleRenderer,
                l,
            ) => l,
            (_, Some(l)) => Some(l),
            (_, None) => bail!("--lmax L is needed for --method {}", self.method.name()),
        };
        if let Some(l) = l_max.filter(|&l| l > ifd_shade::MAX_TABLE_DEGREE) {
            bail!(
                "--lmax {l}: shading supports L <= {}",
                ifd_shade::MAX_TABLE_DEGREE
            );
        }
        let lights = self
            .light
            .iter()
            .map(|l| ifd_shade::SphericalLight::parse(l))
            .collect::<Result<Vec<_>, _>>()?;
        if self.gpu && !lights.is_empty() {
            bail!("--light: spherical lights are shaded on the CPU only (drop --gpu)");
        }
        if method == Method::Mc && !lights.is_empty() {
            bail!(
                "--light: the Monte Carlo renderer does not sample spherical lights; use \
                 --method quadrature for their reference"
            );
        }
        if self.shadows {
            if !matches!(scene, ifd_render::Scene::Mesh(_)) {
                bail!(
                    "--shadows: self-shadowing needs a triangle mesh (--scene FILE.obj), not {}",
                    self.scene.scene
                );
            }
            if !matches!(method, Method::Isd | Method::Quadrature) {
                bail!(
                    "--shadows is shaded by --method isd (Eq. 25) or quadrature (ray traced), \
                     not {}",
                    self.method.name()
                );
            }
            for (set, flag) in [
                (self.gpu, "--gpu"),
                (!lights.is_empty(), "--light"),
                (self.roughness_map.is_some(), "--roughness-map"),
            ] {
                if set {
                    bail!(
                        "--shadows: not with {flag} (shadows are shaded on the CPU, for the environment, with one material)"
                    );
                }
            }
            if let Some(l) = l_max
                && (self.shadow_rays as usize) < (l + 1) * (l + 1)
            {
                bail!(
                    "--shadow-rays {}: the visibility at L = {l} needs at least (L+1)^2 = {}",
                    self.shadow_rays,
                    (l + 1) * (l + 1)
                );
            }
        }
        if self.gpu && !matches!(method, Method::Isd | Method::IsdMaps) {
            bail!(
                "--gpu shades --method isd or isd-maps, not {}",
                self.method.name()
            );
        }
        if !(1..=10_000).contains(&self.frames) {
            bail!("--frames {}: use 1..=10000", self.frames);
        }
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
                        let bar = progress_bar("table");
                        let t = LobeTable::build(&tabulated, l, nt, np, &|d, n| {
                            bar.set_length(n as u64);
                            bar.set_position(d as u64);
                        })?;
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
        let asset_range = asset
            .as_ref()
            .filter(|_| asset_materials)
            .map(|a| a.roughness_range());
        let family = match (&surface.roughness, method, l_max) {
            (rough, Method::Isd | Method::IsdMaps | Method::Sh, Some(l))
                if rough.is_some() || asset_range.is_some() =>
            {
                if !(2..=64).contains(&self.roughness_tables) {
                    bail!("--roughness-tables {}: use 2..=64", self.roughness_tables);
                }
                // a roughness map's range, else the glTF asset's
                let range = match rough {
                    Some(t) => {
                        brdf.with_roughness(0.5).context("--roughness-map")?;
                        t.range()
                    }
                    None => asset_range.unwrap_or((1.0, 1.0)),
                };
                let bar = progress_bar("roughness tables");
                let f = RoughnessFamily::build(
                    &tabulated,
                    l,
                    range,
                    self.roughness_tables,
                    &|d, n| {
                        bar.set_length(n as u64);
                        bar.set_position(d as u64);
                    },
                )?;
                bar.finish_and_clear();
                Some(f)
            }
            (Some(_), _, _) => {
                brdf.with_roughness(0.5).context("--roughness-map")?;
                None
            }
            _ => None,
        };
        let shadows = match (&scene, self.shadows) {
            (ifd_render::Scene::Mesh(mesh), true) => Some(match l_max {
                Some(l) if method == Method::Isd => {
                    let bar = progress_bar("visibility");
                    let s =
                        Shadows::new(mesh.clone(), &env, l, self.shadow_rays as usize, &|d, n| {
                            bar.set_length(n as u64);
                            bar.set_position(d as u64);
                        })?;
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
            let bar = progress_bar("render");
            let r = render(&job, &|d, n| {
                bar.set_length(n as u64);
                bar.set_position(d as u64);
            })?;
            bar.finish_and_clear();
            (r, None)
        };
        let render_secs = t_render.elapsed().as_secs_f64();
        if let Some(p) = &self.gbuffer {
            write_gbuffer(p, &job)?;
        }
        let error_map = match &self.error_map {
            Some(p) => {
                let bar = progress_bar("oracle");
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
                let oracle = render(&oracle_job, &|d, n| {
                    bar.set_length(n as u64);
                    bar.set_position(d as u64);
                })?;
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
        crate::output::write_output(&output, &img, &ifd_image::WriteOptions::default())?;
        self.report.emit(&json!({
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
            }))?;
        Ok(())
    }
}

impl Render {
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
        let bar = progress_bar("frames");
        bar.set_length(self.frames as u64);
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

    /// `--brdf mirror`: the surface as a perfect mirror, anti-aliased by
    /// ISD's filter (Eq. 26-29) or by supersampling the pixel filter.
    fn run_mirror(
        &self,
        scene: &ifd_render::Scene,
        camera: ifd_render::Camera,
        tonemap: ifd_render::Tonemap,
        display: bool,
    ) -> Result<()> {
        use ifd_render::{AaMethod, IsdFilter, MirrorScene, PixelFilter, SceneMirror};
        for (set, flag) in [
            (self.table.is_some(), "--table"),
            (self.albedo_map.is_some(), "--albedo-map"),
            (self.roughness_map.is_some(), "--roughness-map"),
            (!self.light.is_empty(), "--light"),
            (self.shadows, "--shadows"),
            (self.gpu, "--gpu"),
            (self.stderr.is_some(), "--stderr"),
        ] {
            if set {
                bail!("--brdf mirror: not with {flag} (a mirror reflects the environment only)");
            }
        }
        let grid = |what: &str| -> Result<usize> {
            let n = (self.spp as f64).sqrt().round() as usize;
            if n * n != self.spp || !(1..=256).contains(&n) {
                bail!(
                    "--spp {}: --brdf mirror with --method {what} takes a square number of \
                     samples per pixel, 1 to 65536 (N x N)",
                    self.spp
                );
            }
            Ok(n)
        };
        let method = match self.method {
            RenderMethod::Isd => AaMethod::Isd,
            RenderMethod::Quadrature => AaMethod::Supersample(grid("quadrature")?),
            RenderMethod::Mc => AaMethod::Reference(grid("mc")?),
            m => bail!(
                "--brdf mirror is anti-aliased by --method isd, quadrature or mc, not {}",
                m.name()
            ),
        };
        let l_max = match (method, self.lmax) {
            (AaMethod::Isd, None) => bail!("--lmax L is needed for --method isd"),
            (AaMethod::Isd, Some(l)) if !(1..=ifd_sphere::MAX_DEGREE).contains(&l) => {
                bail!("--lmax {l}: use 1..={}", ifd_sphere::MAX_DEGREE)
            }
            (_, l) => l,
        };
        let maps = self.surface_maps()?;
        if maps.normal.is_some() && !scene.has_tangents() {
            bail!(
                "--normal-map: {} has no texture coordinates to map it with",
                self.scene.scene
            );
        }
        let (full, _) = self.env.environments(&self.input)?;
        let start = std::time::Instant::now();
        let isd = match (method, l_max) {
            (AaMethod::Isd, Some(l)) => {
                eprintln!("projecting the map on SH up to L = {l}...");
                Some(IsdFilter::new(&full, l)?)
            }
            _ => None,
        };
        let reflector = SceneMirror {
            scene,
            normal_map: maps.normal.as_ref(),
        };
        let job = MirrorScene {
            mirror: &reflector,
            camera,
            env: &full,
            filter: PixelFilter::default(),
        };
        let t_render = std::time::Instant::now();
        let r = ifd_render::render_mirror(&job, method, isd.as_ref())?;
        let render_secs = t_render.elapsed().as_secs_f64();
        let object_pixels = r.mask.iter().filter(|m| **m).count();
        if object_pixels == 0 {
            bail!(
                "no ray of the {}x{} image hits the {} (check --eye, --target, --fov)",
                camera.width(),
                camera.height(),
                self.scene.scene
            );
        }
        let mut img = r.image;
        let ch = img.channels();
        if self.no_background {
            for (i, m) in r.mask.iter().enumerate() {
                if !m {
                    img.data_mut()[i * ch..(i + 1) * ch].fill(0.0);
                }
            }
        }
        if display {
            for v in img.data_mut() {
                *v = tonemap.display(*v, self.display.exposure);
            }
        }
        if let Some(m) = &self.mask {
            let data = r.mask.iter().map(|x| f32::from(u8::from(*x))).collect();
            let mask = ifd_image::Image::from_vec(camera.width(), camera.height(), 1, data)?;
            crate::output::write_output(m, &mask, &ifd_image::WriteOptions::default())?;
        }
        crate::output::write_output(&self.output, &img, &ifd_image::WriteOptions::default())?;
        self.report.emit(&json!({
            "method": self.method.name(), "brdf": "mirror", "lmax": l_max,
            "scene": self.scene.scene, "width": camera.width(), "height": camera.height(),
            "env_size": [full.image().width(), full.image().height()],
            "object_pixels": object_pixels,
            "eq29_pixels": isd.as_ref().map(|_| r.filtered),
            "isd_threshold_radians": isd.as_ref().map(IsdFilter::threshold),
            "samples_per_pixel": match method { AaMethod::Isd => None, _ => Some(self.spp) },
            "seconds": start.elapsed().as_secs_f64(), "render_seconds": render_secs,
        }))?;
        Ok(())
    }

    /// The albedo and roughness maps.
    fn surface_maps(&self) -> Result<SurfaceMaps> {
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

pub(crate) fn progress_bar(what: &str) -> ProgressBar {
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{what} {{bar:30}} {{pos}}/{{len}} [{{elapsed}}<{{eta}}]"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
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
    crate::output::write_output(path, &img, &ifd_image::WriteOptions::default())?;
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
