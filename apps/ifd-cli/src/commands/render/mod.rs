//! `ifd render`: objects lit by an environment map, shaded by ISD (Eq. 22,
//! from SH or from prefiltered maps), its SH reference, Monte Carlo or the
//! exact texel quadrature.
//!
//! The flags become one checked configuration first (`config::check`:
//! every refusal, before any work); the work follows, with a BRDF
//! (`work.rs`) or a mirror (`mirror.rs`).

mod config;
mod mirror;
mod work;

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, ValueEnum};
use ifd_render::Method;

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
    /// isd with --brdf mirror), unless --tol chooses it.
    #[arg(long, value_name = "L")]
    lmax: Option<usize>,
    /// Instead of --lmax: the relative RMS error against the oracle to stay within (0 < E < 1,
    /// e.g. 0.01), over the object and over its grazing pixels (n.v < 0.2) alike. L is chosen
    /// per material (its BRDF and roughness; every roughness a glTF asset or a roughness map holds) by
    /// a measured rule (docs/render-tol.csv: the smallest L whose worst error on the bundled
    /// forest and sunrise maps, times 1.2, is within E) and reported; an E the material cannot
    /// reach (the lobe table's floor at grazing views, or L beyond 100, 63 with --gpu) exits 2
    /// with the smallest reachable. Measured for lambert, phong, isotropic ggx and gltf with
    /// --method isd or isd-maps; not with --table, --light or --shadows.
    #[arg(long, value_name = "E", conflicts_with_all = ["lmax", "table"])]
    tol: Option<f64>,
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
    /// The first lines of the summary: the image written (size on disk, the
    /// method, the BRDF, the scene, the time), then the other files written.
    pub(super) fn summary_head(
        &self,
        (w, h): (usize, usize),
        l_max: Option<usize>,
        brdf: &str,
        samples: Option<usize>,
        secs: f64,
    ) -> String {
        let bytes = std::fs::metadata(&self.output)
            .map(|m| format!(", {}", ifd_image::fmt_bytes(m.len())))
            .unwrap_or_default();
        let degree = l_max.map(|l| format!(" L = {l}")).unwrap_or_default();
        let samples = samples.map(|n| format!(", {n} spp")).unwrap_or_default();
        let mut text = format!(
            "wrote {} ({w}x{h}{bytes}): {}{degree}{samples}, {brdf} on {}, {}\n",
            self.output.display(),
            self.method.name(),
            self.scene.scene,
            crate::options::seconds(secs)
        );
        let others: Vec<String> = [&self.mask, &self.gbuffer, &self.stderr, &self.error_map]
            .into_iter()
            .flatten()
            .filter(|p| p.exists())
            .map(|p| crate::options::written(p))
            .collect();
        if !others.is_empty() {
            let _ = writeln!(text, "also wrote {}", others.join(", "));
        }
        text
    }

    /// Runs the command: the flags checked, then the work.
    pub fn run(self) -> Result<()> {
        let config::RenderConfig { view, shading } = config::check(&self)?;
        match shading {
            config::Shading::Mirror(c) => self.render_mirror(view, c),
            config::Shading::Brdf(c) => self.render_brdf(view, c),
        }
    }
}
