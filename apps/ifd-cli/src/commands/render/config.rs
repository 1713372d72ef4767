//! The flags of `ifd render` turned into one checked configuration: every
//! refusal of a flag, a combination of flags or a flag against the scene
//! happens here, before any slow work (the environment, the lobe tables,
//! the render).

use anyhow::{Context, Result, bail};
use ifd_render::{AaMethod, Camera, DegreeChoice, Method, Scene, TolMaterial, Tonemap};
use ifd_shade::{Brdf, SphericalLight};

use super::{Render, RenderMethod, is_display};

/// What `ifd render` renders, its flags checked against each other and the
/// scene.
pub(super) struct RenderConfig {
    /// The scene, the camera and the display transform.
    pub view: View,
    /// A mirror or a BRDF.
    pub shading: Shading,
}

/// The scene and how it is seen.
pub(super) struct View {
    /// The scene, read.
    pub scene: Scene,
    /// The camera (the glTF asset's with --scene-camera).
    pub camera: Camera,
    /// The display transform of 8-bit outputs.
    pub tonemap: Tonemap,
    /// Whether the output gets the display transform.
    pub display: bool,
}

/// How the surface is shaded.
pub(super) enum Shading {
    /// `--brdf mirror`.
    Mirror(MirrorConfig),
    /// Any other BRDF.
    Brdf(BrdfConfig),
}

/// `--brdf mirror`: the anti-aliasing and its degree.
#[derive(Clone, Copy)]
pub(super) struct MirrorConfig {
    /// The anti-aliasing of --method.
    pub method: AaMethod,
    /// --lmax (required by ISD's filter).
    pub l_max: Option<usize>,
}

/// A BRDF, its method and what it is shaded with.
pub(super) struct BrdfConfig {
    /// The BRDF, parsed.
    pub brdf: Brdf,
    /// The renderer's method.
    pub method: Method,
    /// The SH degree (required by the ISD methods and sh).
    pub l_max: Option<usize>,
    /// The spherical lights of --light.
    pub lights: Vec<SphericalLight>,
    /// Whether the glTF asset's own materials shade it (--brdf gltf).
    pub asset_materials: bool,
    /// The roughness range of the asset's materials, when they shade it.
    pub asset_range: Option<(f64, f64)>,
    /// The degree --tol chose, and why.
    pub tol: Option<TolChoice>,
}

/// `--tol E`: the tolerance, the material the rule saw and the degree it
/// chose.
pub(super) struct TolChoice {
    /// The tolerance asked for.
    pub tol: f64,
    /// The material kind and roughness the degree was chosen for.
    pub material: TolMaterial,
    /// The rule's answer.
    pub choice: DegreeChoice,
}

impl TolChoice {
    /// The report's `tol` object.
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "tolerance": self.tol, "lmax": self.choice.l_max,
            "material": self.material.describe(), "row": self.choice.row,
            "measured_rel_rms": self.choice.measured, "margin": ifd_render::TOL_MARGIN,
        })
    }

    /// The summary's line.
    pub fn line(&self) -> String {
        format!(
            "--tol {}: L = {} for {} (measured at most {} there on the bundled maps, \
             docs/render-tol.csv)",
            self.tol,
            self.choice.l_max,
            self.material.describe(),
            crate::options::number(self.choice.measured)
        )
    }
}

/// Reads the scene and checks every flag of `r`, with the messages of the
/// command; nothing is rendered or written.
pub(super) fn check(r: &Render) -> Result<RenderConfig> {
    if let Some(e) = r.tol
        && !(e.is_finite() && e > 0.0 && e < 1.0)
    {
        bail!("--tol {e}: a relative RMS error between 0 and 1 (0.01 is 1%)");
    }
    let scene = r.scene.scene_with(r.input.budget())?;
    let asset = match &scene {
        Scene::Gltf(a) => {
            for note in a.notes() {
                eprintln!("note: {}: {note}", r.scene.scene);
            }
            Some(a.clone())
        }
        _ => None,
    };
    let brdf_spec = match (&r.brdf, &asset) {
        (Some(b), _) => b.clone(),
        (None, Some(_)) => "gltf".to_string(),
        (None, None) => bail!(
            "--brdf SPEC is needed (a glTF asset, --scene FILE.glb, brings its own materials)"
        ),
    };
    let asset_materials = asset.is_some() && brdf_spec.starts_with("gltf");
    if asset_materials {
        for (set, flag) in [
            (r.albedo_map.is_some(), "--albedo-map"),
            (r.roughness_map.is_some(), "--roughness-map"),
            (r.normal_map.is_some(), "--normal-map"),
        ] {
            if set {
                bail!(
                    "{flag}: the glTF asset {} brings its own textures (pass another --brdf \
                     to shade its geometry with maps)",
                    r.scene.scene
                );
            }
        }
    }
    if r.scene_camera && asset.as_ref().is_none_or(|a| a.camera().is_none()) {
        bail!(
            "--scene-camera: {} has no perspective camera",
            r.scene.scene
        );
    }
    let tonemap = r.display.tonemap()?;
    let display = is_display(&r.output)?;
    check_extra_outputs(r)?;
    let camera = match asset
        .as_ref()
        .and_then(|a| a.camera())
        .filter(|_| r.scene_camera)
    {
        Some(c) => {
            let (w, h) = crate::input::parse_size(&r.camera.size, "--size")?;
            Camera::new(c.eye, c.target, c.up, c.fov_deg, w, h)?
        }
        None => r.camera.camera()?,
    };
    let (w, h) = (camera.width(), camera.height());
    // the image, its row buffers and the mask, before any work
    let bytes = (w as u64)
        .saturating_mul(h as u64)
        .saturating_mul(3 * 4 * 2 + 1);
    r.input
        .budget()
        .check(bytes)
        .with_context(|| format!("--size {w}x{h}"))?;
    let shading = if brdf_spec == "mirror" {
        Shading::Mirror(check_mirror(r, &scene)?)
    } else {
        let asset_range = asset
            .as_ref()
            .filter(|_| asset_materials)
            .map(|a| a.roughness_range());
        Shading::Brdf(check_brdf(
            r,
            &scene,
            &brdf_spec,
            asset_materials,
            asset_range,
        )?)
    };
    Ok(RenderConfig {
        view: View {
            scene,
            camera,
            tonemap,
            display,
        },
        shading,
    })
}

/// --mask, --gbuffer and --error-map.
fn check_extra_outputs(r: &Render) -> Result<()> {
    if let Some(m) = &r.mask {
        is_display(m)?;
    }
    if let Some(g) = &r.gbuffer
        && ifd_image::FileFormat::from_path(g)? != ifd_image::FileFormat::Npy
    {
        bail!("--gbuffer {}: write six channels as .npy", g.display());
    }
    if let Some(p) = &r.error_map {
        if matches!(
            ifd_image::FileFormat::from_path(p)?,
            ifd_image::FileFormat::Hdr | ifd_image::FileFormat::Jpeg | ifd_image::FileFormat::Tiff
        ) {
            bail!(
                "--error-map {}: use .exr or .npy (signed differences) or .png (a diverging map)",
                p.display()
            );
        }
        if r.method.method() == Method::Quadrature {
            bail!("--error-map compares with the oracle, which --method quadrature is");
        }
        if r.gpu {
            bail!("--error-map: the oracle is a CPU render; drop --gpu");
        }
        if r.shadows {
            bail!("--error-map: not with --shadows (compare with --method quadrature --shadows)");
        }
    }
    Ok(())
}

/// `--brdf mirror`: the flags a mirror takes, its anti-aliasing and degree.
fn check_mirror(r: &Render, scene: &Scene) -> Result<MirrorConfig> {
    for (set, flag) in [
        (r.table.is_some(), "--table"),
        (r.albedo_map.is_some(), "--albedo-map"),
        (r.roughness_map.is_some(), "--roughness-map"),
        (!r.light.is_empty(), "--light"),
        (r.shadows, "--shadows"),
        (r.gpu, "--gpu"),
        (r.stderr.is_some(), "--stderr"),
        (r.tol.is_some(), "--tol"),
    ] {
        if set {
            bail!("--brdf mirror: not with {flag} (a mirror reflects the environment only)");
        }
    }
    let grid = |what: &str| -> Result<usize> {
        let n = (r.spp as f64).sqrt().round() as usize;
        if n * n != r.spp || !(1..=256).contains(&n) {
            bail!(
                "--spp {}: --brdf mirror with --method {what} takes a square number of \
                 samples per pixel, 1 to 65536 (N x N)",
                r.spp
            );
        }
        Ok(n)
    };
    let method = match r.method {
        RenderMethod::Isd => AaMethod::Isd,
        RenderMethod::Quadrature => AaMethod::Supersample(grid("quadrature")?),
        RenderMethod::Mc => AaMethod::Reference(grid("mc")?),
        m => bail!(
            "--brdf mirror is anti-aliased by --method isd, quadrature or mc, not {}",
            m.name()
        ),
    };
    let l_max = match (method, r.lmax) {
        (AaMethod::Isd, None) => bail!("--lmax L is needed for --method isd"),
        (AaMethod::Isd, Some(l)) if !(1..=ifd_sphere::MAX_DEGREE).contains(&l) => {
            bail!("--lmax {l}: use 1..={}", ifd_sphere::MAX_DEGREE)
        }
        (_, l) => l,
    };
    if r.normal_map.is_some() && !scene.has_tangents() {
        bail!(
            "--normal-map: {} has no texture coordinates to map it with",
            r.scene.scene
        );
    }
    Ok(MirrorConfig { method, l_max })
}

/// A BRDF: its spec against the scene, the samples, the degree, the lights,
/// the shadows, the device and the roughness tables.
fn check_brdf(
    r: &Render,
    scene: &Scene,
    spec: &str,
    asset_materials: bool,
    asset_range: Option<(f64, f64)>,
) -> Result<BrdfConfig> {
    let method = r.method.method();
    let brdf = Brdf::parse(spec).map_err(|e| {
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
            r.scene.scene
        );
    }
    if method == Method::Mc && !(1..=1 << 24).contains(&r.spp) {
        bail!("--spp {}: use 1..=16777216 samples per pixel", r.spp);
    }
    if r.stderr.is_some() && method != Method::Mc {
        bail!("--stderr is written by --method mc only");
    }
    if r.stderr.is_some() && r.spp < 2 {
        bail!("--stderr needs --spp 2 or more (a variance from one sample is undefined)");
    }
    if let Some(p) = &r.stderr {
        is_display(p)?;
    }
    let tol = match r.tol {
        Some(e) => Some(tol_degree(r, &brdf, method, asset_range, e)?),
        None => None,
    };
    let l_max = match (method, r.lmax, &tol) {
        (_, _, Some(t)) => Some(t.choice.l_max),
        (
            Method::Quadrature | Method::Mc | Method::SplitSum | Method::SplitSumSampleRenderer,
            l,
            None,
        ) => l,
        (_, Some(l), None) => Some(l),
        (_, None, None) => bail!(
            "--lmax L (or --tol E) is needed for --method {}",
            r.method.name()
        ),
    };
    if let Some(l) = l_max.filter(|&l| l > ifd_shade::MAX_TABLE_DEGREE) {
        bail!(
            "--lmax {l}: shading supports L <= {}",
            ifd_shade::MAX_TABLE_DEGREE
        );
    }
    let lights = r
        .light
        .iter()
        .map(|l| SphericalLight::parse(l))
        .collect::<Result<Vec<_>, _>>()?;
    if r.gpu && !lights.is_empty() {
        bail!("--light: spherical lights are shaded on the CPU only (drop --gpu)");
    }
    if method == Method::Mc && !lights.is_empty() {
        bail!(
            "--light: the Monte Carlo renderer does not sample spherical lights; use \
             --method quadrature for their reference"
        );
    }
    if r.shadows {
        check_shadows(r, scene, method, l_max, &lights)?;
    }
    if r.gpu && !matches!(method, Method::Isd | Method::IsdMaps) {
        bail!(
            "--gpu shades --method isd or isd-maps, not {}",
            r.method.name()
        );
    }
    if !(1..=10_000).contains(&r.frames) {
        bail!("--frames {}: use 1..=10000", r.frames);
    }
    // the ISD methods blend lobe tables across a roughness map's range, or
    // across the glTF asset's
    let blends_tables = matches!(method, Method::Isd | Method::IsdMaps | Method::Sh)
        && l_max.is_some()
        && (r.roughness_map.is_some() || asset_range.is_some());
    if blends_tables && !(2..=64).contains(&r.roughness_tables) {
        bail!("--roughness-tables {}: use 2..=64", r.roughness_tables);
    }
    if r.roughness_map.is_some() {
        brdf.with_roughness(0.5).context("--roughness-map")?;
    }
    Ok(BrdfConfig {
        brdf,
        method,
        l_max,
        lights,
        asset_materials,
        asset_range,
        tol,
    })
}

/// `--tol E`: the degree the measured rule gives the material (held over
/// every roughness of a roughness map or of the asset's materials), or the
/// refusal with the reachable value.
fn tol_degree(
    r: &Render,
    brdf: &Brdf,
    method: Method,
    asset_range: Option<(f64, f64)>,
    tol: f64,
) -> Result<TolChoice> {
    if matches!(method, Method::Sh) {
        bail!(
            "--tol chooses L for --method isd or isd-maps (the rule is measured on ISD); pass --lmax for --method sh"
        );
    }
    if !matches!(method, Method::Isd | Method::IsdMaps) {
        bail!(
            "--tol chooses L for --method isd or isd-maps; --method {} has no L to choose",
            r.method.name()
        );
    }
    for (set, flag) in [(!r.light.is_empty(), "--light"), (r.shadows, "--shadows")] {
        if set {
            bail!("--tol: the rule is measured without {flag}; pass --lmax");
        }
    }
    let roughness = match (&r.roughness_map, asset_range) {
        (Some(p), _) => {
            let opts = ifd_image::ReadOptions::default();
            let img = ifd_image::read_image(p, &opts)?.image;
            let t = ifd_render::Texture::new(img, "--roughness-map")
                .with_context(|| format!("{}", p.display()))?;
            Some(t.range())
        }
        (None, Some(range)) => Some(range),
        (None, None) => None,
    };
    // the GPU kernel's limit, else the lobe tables'
    let max_degree = if r.gpu {
        63
    } else {
        ifd_shade::MAX_TABLE_DEGREE
    };
    let (material, choice) =
        ifd_render::degree_for_render(brdf, roughness, asset_range.is_some(), tol, max_degree)
            .context("--tol")?;
    Ok(TolChoice {
        tol,
        material,
        choice,
    })
}

/// --shadows: a mesh, a method that shades them, what they are not shaded
/// with, and enough rays for the degree.
fn check_shadows(
    r: &Render,
    scene: &Scene,
    method: Method,
    l_max: Option<usize>,
    lights: &[SphericalLight],
) -> Result<()> {
    if !matches!(scene, Scene::Mesh(_)) {
        bail!(
            "--shadows: self-shadowing needs a triangle mesh (--scene FILE.obj), not {}",
            r.scene.scene
        );
    }
    if !matches!(method, Method::Isd | Method::Quadrature) {
        bail!(
            "--shadows is shaded by --method isd (Eq. 25) or quadrature (ray traced), \
             not {}",
            r.method.name()
        );
    }
    for (set, flag) in [
        (r.gpu, "--gpu"),
        (!lights.is_empty(), "--light"),
        (r.roughness_map.is_some(), "--roughness-map"),
    ] {
        if set {
            bail!(
                "--shadows: not with {flag} (shadows are shaded on the CPU, for the environment, with one material)"
            );
        }
    }
    if let Some(l) = l_max
        && (r.shadow_rays as usize) < (l + 1) * (l + 1)
    {
        bail!(
            "--shadow-rays {}: the visibility at L = {l} needs at least (L+1)^2 = {}",
            r.shadow_rays,
            (l + 1) * (l + 1)
        );
    }
    Ok(())
}
