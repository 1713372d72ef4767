//! Option groups used by several commands, each defined once and flattened
//! into the commands (`#[command(flatten)]`): the report, the camera, the
//! display transform, the scene and the environment. A command whose
//! defaults differ (a study's camera) overrides them with `mut_arg`, so the
//! flags keep one name, one meaning and one value shape everywhere.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context as _, Result, bail};
use clap::{Args, ValueEnum};
use glam::DVec3;
use ifd_render::EnvMap;
use serde_json::Value;

use crate::input::{InputOptions, parse_size};

/// The most lines a command's default summary prints: what it wrote, sizes,
/// the time and the accuracy. The rest is for `--json` and `-v`.
pub const SUMMARY_LINES: usize = 8;

/// How a command reports its figures: a short summary by default (at most
/// [`SUMMARY_LINES`] lines), every figure with `-v`, the machine-readable
/// JSON report with `--json`.
#[derive(Debug, Args, Clone, Copy)]
pub struct ReportOptions {
    /// Print the report as one JSON object (machine-readable) instead of the
    /// human summary.
    #[arg(long)]
    pub json: bool,
    /// Print the whole report (every figure: per level, per channel, the
    /// timings) instead of the short summary.
    #[arg(short, long)]
    pub verbose: bool,
}

impl ReportOptions {
    /// Prints `report`: pretty JSON with `--json`, else every figure as
    /// aligned `name value` lines ([`human`]), for a report short enough to
    /// be its own summary.
    pub fn emit(self, report: &Value) -> Result<()> {
        self.emit_with(report, || human(report))
    }

    /// Prints `report` with `--json`, else the text `summary` writes (with
    /// or without `-v`: it holds every figure).
    pub fn emit_with(self, report: &Value, summary: impl FnOnce() -> String) -> Result<()> {
        if self.json {
            println!("{}", serde_json::to_string_pretty(report)?);
        } else {
            print!("{}", summary());
        }
        Ok(())
    }

    /// Prints `report`: pretty JSON with `--json`, with `-v` every figure as
    /// aligned `name value` lines ([`human`]), else the short summary
    /// `summary` writes.
    pub fn emit_summary(self, report: &Value, summary: impl FnOnce() -> String) -> Result<()> {
        self.emit_detailed(report, summary, || human(report))
    }

    /// Prints `report` with `--json`, the text `detail` writes with `-v`,
    /// else the short summary `summary` writes (at most [`SUMMARY_LINES`]
    /// lines).
    pub fn emit_detailed(
        self,
        report: &Value,
        summary: impl FnOnce() -> String,
        detail: impl FnOnce() -> String,
    ) -> Result<()> {
        if self.json {
            println!("{}", serde_json::to_string_pretty(report)?);
        } else if self.verbose {
            print!("{}", detail());
        } else {
            print!("{}", summary());
        }
        Ok(())
    }
}

/// `PATH (SIZE)`: a file written and its size on disk (the path alone when
/// its size cannot be read).
#[must_use]
pub fn written(path: &std::path::Path) -> String {
    match std::fs::metadata(path) {
        Ok(m) => format!("{} ({})", path.display(), ifd_image::fmt_bytes(m.len())),
        Err(_) => path.display().to_string(),
    }
}

/// Seconds for a summary: `0.84 s`, `12.3 s`, `152 s`.
#[must_use]
pub fn seconds(s: f64) -> String {
    if s < 10.0 {
        format!("{s:.2} s")
    } else if s < 100.0 {
        format!("{s:.1} s")
    } else {
        format!("{s:.0} s")
    }
}

/// A JSON report as aligned `key  value` lines: nested objects indented,
/// lists of numbers on one line, lists of objects as numbered entries, nulls
/// left out, numbers with 6 significant digits.
#[must_use]
pub fn human(report: &Value) -> String {
    let mut out = String::new();
    write_human(report, 0, &mut out);
    out
}

fn write_human(v: &Value, indent: usize, out: &mut String) {
    let pad = " ".repeat(indent);
    match v {
        Value::Object(map) => {
            let shown: Vec<(&String, &Value)> = map.iter().filter(|(_, v)| !v.is_null()).collect();
            let width = shown
                .iter()
                .filter(|(_, v)| is_inline(v))
                .map(|(k, _)| k.len())
                .max()
                .unwrap_or(0);
            for (k, v) in shown {
                let key = k.replace('_', " ");
                if is_inline(v) {
                    let _ = writeln!(out, "{pad}{key:<width$}  {}", inline(v));
                } else {
                    let _ = writeln!(out, "{pad}{key}:");
                    write_human(v, indent + 2, out);
                }
            }
        }
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                if is_inline(item) {
                    let _ = writeln!(out, "{pad}[{i}] {}", inline(item));
                } else {
                    let _ = writeln!(out, "{pad}[{i}]");
                    write_human(item, indent + 2, out);
                }
            }
        }
        v => {
            let _ = writeln!(out, "{pad}{}", inline(v));
        }
    }
}

fn is_inline(v: &Value) -> bool {
    match v {
        Value::Object(_) => false,
        Value::Array(items) => items.iter().all(|i| !i.is_object() && !i.is_array()),
        _ => true,
    }
}

fn inline(v: &Value) -> String {
    match v {
        Value::Null => "-".to_owned(),
        Value::Bool(b) => if *b { "yes" } else { "no" }.to_owned(),
        Value::Number(n) => match (n.as_i64(), n.as_u64(), n.as_f64()) {
            (Some(i), _, _) => i.to_string(),
            (_, Some(u), _) => u.to_string(),
            (_, _, Some(f)) => number(f),
            _ => n.to_string(),
        },
        Value::String(s) => s.clone(),
        Value::Array(items) => {
            let parts: Vec<String> = items.iter().map(inline).collect();
            if parts.len() > 16 {
                format!("{} ... ({} values)", parts[..16].join(", "), parts.len())
            } else {
                parts.join(", ")
            }
        }
        Value::Object(_) => String::new(),
    }
}

/// A float with 6 significant digits, trailing zeros dropped, in scientific
/// notation outside `[1e-3, 1e6)`.
pub fn number(f: f64) -> String {
    if f == 0.0 || !f.is_finite() {
        return f.to_string();
    }
    let a = f.abs();
    if !(1e-3..1e6).contains(&a) {
        return format!("{f:.4e}");
    }
    let decimals = (5 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{f:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    }
}

/// Parses `X,Y,Z` given to `option`: three finite numbers.
pub fn parse_vec(text: &str, option: &str) -> Result<DVec3> {
    let v: Vec<f64> = text
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("{option} {text:?}: expected three numbers X,Y,Z"))?;
    if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
        bail!("{option} {text:?}: expected three finite numbers X,Y,Z");
    }
    Ok(DVec3::new(v[0], v[1], v[2]))
}

/// A pinhole camera looking at the scene (world z up).
#[derive(Debug, Args, Clone)]
pub struct CameraOptions {
    /// Image size WxH.
    #[arg(long, value_name = "WxH", default_value = "256x256")]
    pub size: String,
    /// Camera position.
    #[arg(
        long,
        value_name = "X,Y,Z",
        default_value = "3,-2.5,1.2",
        allow_hyphen_values = true
    )]
    pub eye: String,
    /// Point looked at.
    #[arg(
        long,
        value_name = "X,Y,Z",
        default_value = "0,0,0",
        allow_hyphen_values = true
    )]
    pub target: String,
    /// Up direction.
    #[arg(
        long,
        value_name = "X,Y,Z",
        default_value = "0,0,1",
        allow_hyphen_values = true
    )]
    pub up: String,
    /// Vertical field of view in degrees.
    #[arg(long, value_name = "DEG", default_value_t = 40.0)]
    pub fov: f64,
}

impl CameraOptions {
    /// The camera the options describe.
    pub fn camera(&self) -> Result<ifd_render::Camera> {
        let (w, h) = parse_size(&self.size, "--size")?;
        Ok(ifd_render::Camera::new(
            parse_vec(&self.eye, "--eye")?,
            parse_vec(&self.target, "--target")?,
            parse_vec(&self.up, "--up")?,
            self.fov,
            w,
            h,
        )?)
    }
}

/// The tone curve of 8-bit (display) outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ToneCurve {
    /// Clamp to [0, 1].
    None,
    /// x / (1 + x).
    Reinhard,
    /// The ACES filmic fit.
    Aces,
}

impl From<ToneCurve> for ifd_render::Tonemap {
    fn from(t: ToneCurve) -> Self {
        match t {
            ToneCurve::None => Self::None,
            ToneCurve::Reinhard => Self::Reinhard,
            ToneCurve::Aces => Self::Aces,
        }
    }
}

/// How linear radiance is shown in 8-bit outputs (PNG, JPEG, TIFF); float
/// outputs (EXR, HDR, NPY) keep linear radiance.
#[derive(Debug, Args, Clone, Copy)]
pub struct DisplayOptions {
    /// Tone curve for 8-bit outputs.
    #[arg(long, value_enum, default_value_t = ToneCurve::Aces)]
    pub tonemap: ToneCurve,
    /// Exposure in stops for 8-bit outputs.
    #[arg(
        long,
        value_name = "EV",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub exposure: f32,
}

impl DisplayOptions {
    /// The tone curve, after checking the exposure.
    pub fn tonemap(self) -> Result<ifd_render::Tonemap> {
        // +-64 stops is a factor of 1.8e19 either way, far past what a
        // display shows; beyond it bright radiance overflows f32
        if !(self.exposure.is_finite() && self.exposure.abs() <= 64.0) {
            bail!("--exposure {}: use -64 to 64 stops", self.exposure);
        }
        Ok(self.tonemap.into())
    }
}

/// The up axis of an OBJ file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ObjUp {
    /// y up (the OBJ convention; rotated to ifd's z up).
    Y,
    /// z up, as ifd.
    Z,
}

/// The object shaded.
#[derive(Debug, Args, Clone)]
pub struct SceneOptions {
    /// A built-in shape, an OBJ file or a glTF asset: sphere (unit), torus (radii 1 and 0.4
    /// around z), plane (z = 0, [-2, 2]^2), a path to an .obj (centred and scaled to a unit
    /// bounding sphere; smooth normals computed when it has none; anisotropic BRDFs need its
    /// texture coordinates), or a .gltf/.glb (the default scene's triangles with their
    /// metallic-roughness materials and textures, y up turned z up, placed the same way).
    #[arg(long, value_name = "SCENE", default_value = "sphere")]
    pub scene: String,
    /// The up axis of an OBJ file.
    #[arg(long, value_enum, default_value_t = ObjUp::Y)]
    pub obj_up: ObjUp,
}

impl SceneOptions {
    /// The scene the options name, a glTF asset read under `budget`.
    pub fn scene_with(&self, budget: ifd_image::MemoryBudget) -> Result<ifd_render::Scene> {
        Ok(ifd_render::Scene::parse_with(
            &self.scene,
            self.obj_up == ObjUp::Z,
            budget,
        )?)
    }
}

/// The environment map lighting the scene.
#[derive(Debug, Args, Clone)]
pub struct EnvOptions {
    /// Environment map, 2:1 equirectangular (EXR, HDR, ...), or SH coefficients (.npy of shape
    /// ((L+1)^2, 1 or 3): the sh.npy of `ifd envmap prefilter` or `ifd sphere sh`), which isd
    /// and sh use as they are (L up to theirs), and the oracle, Monte Carlo and the background
    /// read synthesised on --env-size (default 128x64), negatives set to 0.
    #[arg(long, value_name = "FILE")]
    pub env: PathBuf,
    /// Size the environment is averaged down to by solid angle (2:1, dividing the map's size);
    /// default 128x64 when it divides the map, else the map's own size.
    #[arg(long, value_name = "WxH")]
    pub env_size: Option<String>,
    /// Rotate the environment about +z by this many degrees.
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub env_rotate: f64,
}

impl EnvOptions {
    /// The full-resolution map (background) and the one every method integrates.
    pub fn environments(&self, input: &InputOptions) -> Result<(EnvMap, EnvMap)> {
        if !(self.env_rotate.is_finite() && self.env_rotate.abs() <= 1e6) {
            bail!(
                "--env-rotate {}: use an angle within +-1e6 degrees",
                self.env_rotate
            );
        }
        // SH coefficients ((L+1)^2 x 1 or 3 .npy, from `ifd envmap prefilter`
        // or `ifd sphere sh`): the ISD and SH methods use them as they are
        if self
            .env
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
            && let Ok(c) = ifd_sphere::ShCoeffs::read_npy(&self.env)
            && matches!(c.channels(), 1 | 3)
        {
            let l = c.l_max();
            let (ew, eh) = match &self.env_size {
                Some(s) => parse_size(s, "--env-size")?,
                None if l < 64 => (128, 64),
                None => (4 * (l + 1), 2 * (l + 1)),
            };
            let (env, clamped) = EnvMap::from_sh(c, ew, eh, self.env_rotate)
                .with_context(|| format!("{}", self.env.display()))?;
            if clamped > 0 {
                eprintln!(
                    "note: {}: the SH environment synthesised on {ew}x{eh} (for the \
                     oracle, Monte Carlo and the background) rings below 0 at {clamped} \
                     samples, set to 0 there",
                    self.env.display()
                );
            }
            return Ok((env.clone(), env));
        }
        let full =
            EnvMap::new(input.read(&self.env)?.image, self.env_rotate).with_context(|| {
                // a .npy that is neither: say what it lacks as SH coefficients too
                let as_sh = self
                    .env
                    .extension()
                    .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
                    .then(|| ifd_sphere::ShCoeffs::read_npy(&self.env).err())
                    .flatten()
                    .map(|e| format!(" (nor SH coefficients: {e})"))
                    .unwrap_or_default();
                format!("{}{as_sh}", self.env.display())
            })?;
        let (mw, mh) = (full.image().width(), full.image().height());
        let (ew, eh) = match &self.env_size {
            Some(s) => parse_size(s, "--env-size")?,
            None if mw % 128 == 0 && mh % 64 == 0 => (128, 64),
            None => (mw, mh),
        };
        let env = full.downsampled(ew, eh)?;
        Ok((full, env))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_human_summary_aligns_keys_and_drops_nulls() {
        let text = human(&json!({
            "psnr_db": 41.234_567_8, "gone": null, "n": 3,
            "gpu": {"fps": 12.5}, "rows": [{"a": 1}], "list": [1, 2.5],
        }));
        assert!(text.contains("psnr db  41.2346\n"), "{text}");
        assert!(!text.contains("gone"), "{text}");
        assert!(text.contains("gpu:\n  fps  12.5\n"), "{text}");
        assert!(text.contains("rows:\n  [0]\n    a  1\n"), "{text}");
        assert!(text.contains("list     1, 2.5\n"), "{text}");
        assert_eq!(number(1.5e-7), "1.5000e-7");
        assert_eq!(number(123_456.0), "123456");
    }
}
