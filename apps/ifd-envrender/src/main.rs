//! The `ifd-envrender` program: the environment renderer's window.

use ifd_app::{DeviceArg, Shell};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};

use anyhow::Context as _;
use clap::Parser;
use glam::DVec3;
use ifd_envrender::app::{
    Automation, EnvApp, ReferenceReport, ScreenReport, SplitSumReport, StartOptions,
};
use ifd_envrender::orbit::Orbit;
use ifd_envrender::settings::{Compare, STORAGE_KEY, Settings, Variant, is_gltf};
use ifd_gpu::DeviceChoice;

/// Look at an object lit by an environment map, shaded by ISD (Eq. 22) on
/// the GPU: orbit the camera, change the BRDF, L, the variant, the map.
///
/// Options given here override the stored settings of the last session.
#[derive(Parser, Debug)]
#[command(version)]
// command-line switches are bools by nature
#[allow(clippy::struct_excessive_bools)]
struct Args {
    /// Environment map, 2:1 equirectangular (HDR, EXR, ...); default: the bundled forest.hdr.
    #[arg(long, value_name = "FILE")]
    env: Option<PathBuf>,
    /// BRDF spec, as `ifd render --brdf`.
    #[arg(long, value_name = "SPEC")]
    brdf: Option<String>,
    /// Maximum SH degree L.
    #[arg(long, value_name = "L")]
    lmax: Option<usize>,
    /// Instead of --lmax: L chosen for a relative RMS error within E of the exact integral
    /// (0 < E < 1), over the object and its grazing views alike, by the measured rule of
    /// `ifd render --tol` (docs/render-tol.csv), at most 63; refused with the smallest
    /// reachable E when the material cannot reach it.
    #[arg(long, value_name = "E", conflicts_with = "lmax")]
    tol: Option<f64>,
    /// A built-in shape (sphere, torus, plane), an .obj file, or a glTF asset
    /// (.gltf/.glb: shaded with its own materials, --brdf gltf, unless --brdf
    /// says otherwise). A file is framed.
    #[arg(long, value_name = "SCENE")]
    scene: Option<String>,
    /// Evaluation of the per-band environment.
    #[arg(long, value_enum)]
    variant: Option<VariantArg>,
    /// Viewport size `WxH`.
    #[arg(long, value_name = "WxH")]
    size: Option<String>,
    /// Camera position (with --target and --fov: the orbit's start).
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    eye: Option<String>,
    /// Point looked at.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    target: Option<String>,
    /// Vertical field of view, degrees.
    #[arg(long, value_name = "DEG")]
    fov: Option<f64>,
    /// Exposure in stops.
    #[arg(long, value_name = "EV", allow_hyphen_values = true)]
    exposure: Option<f32>,
    /// Tone curve.
    #[arg(long, value_enum)]
    tonemap: Option<ToneCurve>,
    /// Rotate the environment about +z, degrees.
    #[arg(long, value_name = "DEG", allow_hyphen_values = true)]
    env_rotate: Option<f64>,
    /// Black background.
    #[arg(long)]
    no_background: bool,
    /// Albedo map over the surface's texture coordinates (as `ifd render`).
    #[arg(long, value_name = "IMAGE")]
    albedo_map: Option<PathBuf>,
    /// Roughness map (as `ifd render`; isotropic GGX or Ward; 6 lobe tables
    /// over its range, `ifd render --roughness-tables 6`).
    #[arg(long, value_name = "IMAGE")]
    roughness_map: Option<PathBuf>,
    /// Where the frame is shaded: auto (a hardware GPU when there is one; a
    /// software adapter such as lavapipe is slower than the CPU renderer), gpu
    /// (any adapter, software included), cpu.
    #[arg(long, value_enum, default_value_t = DeviceArg::Auto)]
    device: DeviceArg,
    /// Save a screenshot of the window (PNG) once the frame is shown; prints
    /// the viewport's rectangle in it (JSON with --json).
    #[arg(long, value_name = "PATH.png")]
    screenshot: Option<PathBuf>,
    /// Exit when done (after --screenshot, or after the first frame).
    #[arg(long)]
    exit: bool,
    /// Start from the defaults instead of the stored settings.
    #[arg(long)]
    reset: bool,
    /// Show the Monte Carlo reference beside the ISD image, with the error.
    #[arg(long)]
    reference: bool,
    /// With --exit: wait for the reference to reach N samples per pixel (and,
    /// from 64, the error-against-L curve); prints the errors (JSON with --json).
    #[arg(long, value_name = "N", requires = "reference")]
    reference_spp: Option<usize>,
    /// Show an engine's split-sum approximation of the frame beside ISD's
    /// (its difference, or the image with --compare-image), the numbers in
    /// the status bar; glTF BRDF only. With --exit: wait for it and print
    /// them.
    #[arg(long, value_enum, conflicts_with = "reference")]
    compare: Option<CompareArg>,
    /// With --compare: show the split-sum image instead of its difference.
    #[arg(long, requires = "compare")]
    compare_image: bool,
    /// Print the report as JSON (machine-readable) instead of a human
    /// summary: the window's size and each view's rectangle in it, the
    /// viewport's in the screenshot, and the numbers of --reference-spp and
    /// --compare.
    #[arg(long)]
    json: bool,
}

/// `--variant` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum VariantArg {
    /// The per-band environment synthesised from SH.
    Sh,
    /// Per-band prefiltered maps.
    Maps,
}

/// `--compare` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum CompareArg {
    /// No comparison (overrides the stored setting).
    Off,
    /// The split sum with ISD's own BRDF split: the approximation's own
    /// error (`ifd render --method split-sum`).
    SplitSum,
    /// glTF-Sample-Renderer's shader as written (`ifd render --method
    /// split-sum-sample-renderer`).
    SampleRenderer,
}

/// `--tonemap` values (as `ifd render --tonemap`).
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum ToneCurve {
    /// Clamp to [0, 1].
    None,
    /// x / (1 + x).
    Reinhard,
    /// The ACES filmic fit.
    Aces,
}

fn parse_vec(text: &str, option: &str) -> anyhow::Result<DVec3> {
    let v: Vec<f64> = text
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{option} {text:?}: expected X,Y,Z"))?;
    if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
        anyhow::bail!("{option} {text:?}: expected three finite numbers X,Y,Z");
    }
    Ok(DVec3::new(v[0], v[1], v[2]))
}

/// The settings: stored ones (unless --reset), then the options.
fn settings(args: &Args, stored: Option<Settings>) -> anyhow::Result<Settings> {
    let mut s = if args.reset { None } else { stored }.unwrap_or_default();
    if let Some(e) = &args.env {
        s.env = Some(e.clone());
    }
    if let Some(b) = &args.brdf {
        ifd_shade::Brdf::parse(b).with_context(|| format!("--brdf {b}"))?;
        s.brdf.clone_from(b);
    }
    if let Some(l) = args.lmax {
        if !(1..=63).contains(&l) {
            anyhow::bail!("--lmax {l}: use 1..=63");
        }
        s.l_max = l;
    }
    if let Some(sc) = &args.scene {
        if is_gltf(sc) || sc.to_lowercase().ends_with(".obj") {
            // framed; a glTF asset brings its materials
            s.open_scene(std::path::Path::new(sc));
            if let Some(b) = &args.brdf {
                s.brdf.clone_from(b);
            }
        } else {
            s.scene.clone_from(sc);
        }
    }
    if let Some(c) = args.compare {
        s.compare = match c {
            CompareArg::Off => Compare::Off,
            CompareArg::SplitSum => Compare::SplitSum,
            CompareArg::SampleRenderer => Compare::SampleRenderer,
        };
        if s.compare != Compare::Off {
            s.reference = false;
        }
    }
    if args.compare_image {
        s.compare_image = true;
    }
    let gltf = ifd_shade::Brdf::parse(&s.brdf).is_ok_and(|b| b.gltf_material().is_some());
    if s.compare != Compare::Off && !gltf && args.compare.is_none() {
        // a stored comparison, for a BRDF that has none
        s.compare = Compare::Off;
    }
    if s.compare != Compare::Off && !gltf {
        anyhow::bail!(
            "--compare: the split sum shades the glTF BRDF, not {} (--brdf gltf:.. or a glTF \
             asset, --scene FILE.glb)",
            s.brdf
        );
    }
    if let Some(v) = args.variant {
        s.variant = match v {
            VariantArg::Sh => Variant::Sh,
            VariantArg::Maps => Variant::Maps,
        };
    }
    if let Some(sz) = &args.size {
        let (w, h) = sz
            .split_once('x')
            .and_then(|(w, h)| Some((w.parse::<usize>().ok()?, h.parse::<usize>().ok()?)))
            .with_context(|| format!("--size {sz:?}: expected WxH"))?;
        if !(16..=4096).contains(&w) || !(16..=4096).contains(&h) {
            anyhow::bail!("--size {sz}: use 16..=4096 pixels a side");
        }
        s.size = [w, h];
    }
    if args.eye.is_some() || args.target.is_some() || args.fov.is_some() {
        let eye = match &args.eye {
            Some(e) => parse_vec(e, "--eye")?,
            None => s.camera.eye(),
        };
        let target = match &args.target {
            Some(t) => parse_vec(t, "--target")?,
            None => DVec3::from_array(s.camera.target),
        };
        let fov = args.fov.unwrap_or(s.camera.fov);
        if !(fov > 0.0 && fov < 180.0) {
            anyhow::bail!("--fov {fov}: use 0 < fov < 180 degrees");
        }
        if (eye - target).length() < 1e-9 {
            anyhow::bail!("--eye equals --target");
        }
        s.camera = Orbit::looking(eye, target, fov);
    }
    if let Some(e) = args.exposure {
        s.exposure = e;
    }
    if let Some(t) = args.tonemap {
        match t {
            ToneCurve::None => "none",
            ToneCurve::Reinhard => "reinhard",
            ToneCurve::Aces => "aces",
        }
        .clone_into(&mut s.tonemap);
    }
    if let Some(r) = args.env_rotate {
        s.env_rotate = r;
    }
    if args.no_background {
        s.background = false;
    }
    if args.reference {
        s.reference = true;
        s.compare = Compare::Off;
    }
    if let Some(p) = &args.albedo_map {
        s.albedo_map = Some(p.clone());
    }
    if let Some(p) = &args.roughness_map {
        s.roughness_map = Some(p.clone());
    }
    if let Some(e) = args.tol {
        s.l_max = tol_degree(e, &s)?;
    }
    if let Some(n) = args.reference_spp
        && !(1..=ifd_envrender::reference::MAX_SPP).contains(&n)
    {
        anyhow::bail!(
            "--reference-spp {n}: use 1..={}",
            ifd_envrender::reference::MAX_SPP
        );
    }
    Ok(s)
}

/// `--tol E`: the degree of `ifd render --tol`'s measured rule for the
/// settings' BRDF (held over every roughness of a roughness map or of a glTF
/// asset's materials), at most the kernel's 63.
fn tol_degree(tol: f64, s: &Settings) -> anyhow::Result<usize> {
    // the settings are read before the window opens and again in it: one note
    static NOTE: std::sync::Once = std::sync::Once::new();
    if !(tol.is_finite() && tol > 0.0 && tol < 1.0) {
        anyhow::bail!("--tol {tol}: a relative RMS error between 0 and 1 (0.01 is 1%)");
    }
    let brdf = ifd_shade::Brdf::parse(&s.brdf).with_context(|| format!("--brdf {}", s.brdf))?;
    let asset = s.scene_is_gltf() && brdf.gltf_material().is_some();
    let roughness = if let Some(p) = &s.roughness_map {
        let img = ifd_image::read_image(p, &ifd_image::ReadOptions::default())?.image;
        let t = ifd_render::Texture::new(img, "--roughness-map")
            .with_context(|| format!("{}", p.display()))?;
        Some(t.range())
    } else if asset {
        match ifd_render::Scene::parse(&s.scene, false)
            .with_context(|| format!("--scene {}", s.scene))?
        {
            ifd_render::Scene::Gltf(a) => Some(a.roughness_range()),
            _ => None,
        }
    } else {
        None
    };
    let (material, c) =
        ifd_render::degree_for_render(&brdf, roughness, asset, tol, 63).context("--tol")?;
    NOTE.call_once(|| {
        eprintln!(
            "note: --tol {tol}: L = {} for {} (measured at most {:.2e} there, \
             docs/render-tol.csv)",
            c.l_max,
            material.describe(),
            c.measured
        );
    });
    Ok(c.l_max)
}

fn run(args: &Args) -> anyhow::Result<()> {
    // check the options before a window opens
    settings(args, None)?;
    if let Some(sc) = args.scene.as_deref().filter(|sc| is_gltf(sc)) {
        // a bad asset is reported here, not in a window
        let scene = ifd_render::Scene::parse(sc, false).with_context(|| format!("--scene {sc}"))?;
        if let ifd_render::Scene::Gltf(a) = scene {
            for note in a.notes() {
                eprintln!("note: {sc}: {note}");
            }
        }
    }
    let split_sum = Arc::new(Mutex::new(None::<SplitSumReport>));
    let failure = Arc::new(Mutex::new(None::<String>));
    let screen = Arc::new(Mutex::new(None::<ScreenReport>));
    let reference = Arc::new(Mutex::new(None::<ReferenceReport>));
    let automation = Automation {
        screenshot: args.screenshot.clone(),
        exit: args.exit,
        failure: Arc::clone(&failure),
        screen: Arc::clone(&screen),
        reference_spp: args.reference_spp,
        reference: Arc::clone(&reference),
        split_sum: Arc::clone(&split_sum),
    };
    let gpu = DeviceChoice::from(args.device);
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("ifd envrender")
            .with_inner_size([1180.0, 760.0])
            .with_drag_and_drop(true),
        persistence_path: std::env::var_os("IFD_ENVRENDER_STATE_DIR")
            .map(|d| PathBuf::from(d).join("app.ron")),
        wgpu_options: ifd_app::wgpu_options(),
        ..eframe::NativeOptions::default()
    };
    let mut err = None;
    let args_ref = args;
    eframe::run_native(
        "ifd-envrender",
        options,
        Box::new(|cc| {
            let stored: Option<Settings> = cc
                .storage
                .and_then(|s| eframe::get_value(s, STORAGE_KEY))
                .filter(|s: &Settings| s.format == STORAGE_KEY);
            let s = match settings(args_ref, stored) {
                Ok(s) => s,
                Err(e) => {
                    err = Some(e);
                    Settings::default()
                }
            };
            if automation.active() {
                // the viewport at one screen pixel per image pixel
                cc.egui_ctx.set_pixels_per_point(1.0);
            }
            Ok(Box::new(Shell::new(
                EnvApp::new(
                    &cc.egui_ctx,
                    s,
                    StartOptions {
                        render_state: cc.wgpu_render_state.clone(),
                        gpu,
                        automation,
                    },
                ),
                STORAGE_KEY,
            )))
        }),
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    if let Some(e) = err {
        return Err(e);
    }
    if let Some(msg) = failure.lock().ok().and_then(|mut f| f.take()) {
        anyhow::bail!(msg);
    }
    let mut report = serde_json::json!({});
    if let Some(r) = screen.lock().ok().and_then(|mut v| v.take()) {
        let rect = |p: &ifd_app::PixelRect| serde_json::json!({"x": p.x, "y": p.y, "width": p.width, "height": p.height});
        if args.screenshot.is_some()
            && let Some((_, isd)) = r.views.first()
        {
            // ISD's view in the screenshot (the first of `views`)
            report["viewport"] = rect(isd);
        }
        report["window"] = serde_json::json!({"width": r.window[0], "height": r.window[1]});
        report["area"] = rect(&r.area);
        report["views"] = r
            .views
            .iter()
            .map(|(name, p)| {
                let mut v = rect(p);
                v["name"] = serde_json::json!(name);
                v
            })
            .collect();
        report["shading"] = serde_json::json!(if r.gpu { "gpu" } else { "cpu" });
    }
    if let Some((spp, rel, psnr, curve)) = reference.lock().ok().and_then(|mut r| r.take()) {
        report["reference"] = serde_json::json!({
            "spp": spp, "rel_rms": rel, "psnr_db": psnr,
            "curve": curve.iter().map(|(l, e)| serde_json::json!({"lmax": l, "rel_rms": e})).collect::<Vec<_>>(),
        });
    }
    if let Some(r) = split_sum.lock().ok().and_then(|mut r| r.take()) {
        let d = &r.difference;
        report["split_sum"] = serde_json::json!({
            "rel_rms": d.relative_rms, "psnr_db": d.psnr_db, "max_abs": d.max_abs,
            "relative_p95": d.full_scale, "seconds": r.seconds,
        });
    }
    if report.as_object().is_some_and(|o| !o.is_empty()) {
        if args.json {
            println!("{report}");
        } else {
            print!("{}", human(&report));
        }
    }
    Ok(())
}

/// The report as aligned `name  value` lines (the viewport, the window and
/// its views, the split sum's difference, the reference's errors and its
/// error-against-L curve).
fn human(report: &serde_json::Value) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    if let Some(v) = report.get("viewport") {
        let _ = writeln!(
            s,
            "viewport   {}x{} at {},{}",
            v["width"], v["height"], v["x"], v["y"]
        );
    }
    if let Some(w) = report.get("window") {
        let _ = write!(s, "window     {}x{}", w["width"], w["height"]);
        for v in report["views"].as_array().into_iter().flatten() {
            let _ = write!(
                s,
                "; {} {}x{} at {},{}",
                v["name"].as_str().unwrap_or("?"),
                v["width"],
                v["height"],
                v["x"],
                v["y"]
            );
        }
        let _ = writeln!(
            s,
            " ({} shading)",
            report["shading"].as_str().unwrap_or("?")
        );
    }
    if let Some(r) = report.get("split_sum") {
        let _ = writeln!(
            s,
            "split sum  against ISD: relative RMS {:.4e}, PSNR {:.2} dB, 95% of pixels within \
             {:.2}%, largest difference {:.4e} ({:.2} s)",
            r["rel_rms"].as_f64().unwrap_or(f64::NAN),
            r["psnr_db"].as_f64().unwrap_or(f64::NAN),
            100.0 * r["relative_p95"].as_f64().unwrap_or(f64::NAN),
            r["max_abs"].as_f64().unwrap_or(f64::NAN),
            r["seconds"].as_f64().unwrap_or(f64::NAN),
        );
    }
    if let Some(r) = report.get("reference") {
        let _ = writeln!(
            s,
            "reference  {} spp: relative RMS {:.4e}, PSNR {:.2} dB",
            r["spp"],
            r["rel_rms"].as_f64().unwrap_or(f64::NAN),
            r["psnr_db"].as_f64().unwrap_or(f64::NAN)
        );
        for p in r["curve"].as_array().into_iter().flatten() {
            let _ = writeln!(
                s,
                "  L = {:<3} relative RMS {:.4e}",
                p["lmax"],
                p["rel_rms"].as_f64().unwrap_or(f64::NAN)
            );
        }
    }
    s
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory as _;

    /// `docs/reference/cli/ifd-envrender.json` is what this binary defines, and its
    /// flags follow the grammar (the three binaries together are checked by
    /// `ifd-clidoc`'s tests, against the checked-in files).
    #[test]
    fn the_command_line_matches_its_checked_in_schema_and_the_grammar() {
        if let Err(e) = ifd_clidoc::check_binary(super::Args::command().name("ifd-envrender")) {
            panic!("{e}");
        }
    }
}
