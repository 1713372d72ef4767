//! `ifd sphere radial`: radial reflection maps for any BRDF (ISD Sec. 6.1,
//! Eq. 23-24).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use ifd_image::Image;
use ifd_shade::Brdf;
use ifd_shade::Material;
use ifd_shade::ZonalLighting;
use ifd_shade::{LobeTable, default_theta_entries};
use ifd_shade::{MapSize, RadialMap, RadialProfile};
use serde_json::json;

use crate::options::parse_vec;
use crate::options::{ReportOptions, number, seconds, written};

/// Tabulate a BRDF's reflection under radially symmetric distant light (ISD
/// Eq. 24): a radial reflection map, generalising Stone's (Phong only) to any
/// BRDF.
///
/// The light is `f(zeta . w)` about an axis `zeta`: a profile (`cap:deg=D`, a
/// disk or, at 90, a uniform sky; `overcast`, the CIE overcast sky `(1 + 2
/// cos) / 3`; `power:s=S`, `max(cos, 0)^S`) times --radiance, or the radial
/// part of an environment map about --axis (its average over rotations about
/// the axis). It is stored as L+1 zonal coefficients `e_l`, and the map is
/// Eq. 22 with `Ehat_l(d) = e_l P_l(zeta . d)`: any BRDF, on the fly, from
/// L+1 numbers (written with --coeffs). The map tabulates it over the local
/// view (theta_o in [0, 90) degrees; phi_o over [0, 360) for anisotropic
/// BRDFs) and the local light axis (theta_z in [0, 180], phi_z in [0, 180] for
/// isotropic BRDFs, [0, 360) otherwise), cell centres, as a float64 .npy of
/// shape (T_o, P_o, T_z, P_z, C). --check N compares N entries with the
/// quadrature of the same light and reports the errors.
///
/// Example: `ifd sphere radial --brdf ggx:alpha=0.3 --light-profile overcast --lmax 24 -o sky.npy --preview sky.png --check 50`
#[derive(Debug, Args)]
pub struct RadialCmd {
    /// BRDF spec (as `ifd render`).
    #[arg(long, value_name = "SPEC")]
    brdf: String,
    /// Radially symmetric light: cap:deg=D, overcast or power:s=S (about +z of the light's
    /// frame; the map's axis cells place it).
    #[arg(long, value_name = "PROFILE", conflicts_with = "env")]
    light_profile: Option<String>,
    /// Or: an environment map (2:1 equirectangular) whose radial part about --axis is the light.
    #[arg(long, value_name = "FILE")]
    env: Option<PathBuf>,
    /// The axis of the radial part of --env (world, z up).
    #[arg(
        long,
        value_name = "X,Y,Z",
        default_value = "0,0,1",
        allow_hyphen_values = true,
        requires = "env"
    )]
    axis: String,
    /// Radiance scale of a profile: L or R,G,B.
    #[arg(
        long,
        value_name = "L|R,G,B",
        default_value = "1",
        conflicts_with = "env"
    )]
    radiance: String,
    /// Maximum SH degree L.
    #[arg(long, value_name = "L")]
    lmax: usize,
    /// Lobe table from `ifd sphere brdf` (built at the default resolution when the BRDF needs
    /// one and none is given).
    #[arg(long, value_name = "FILE")]
    table: Option<PathBuf>,
    /// Map cells: T_OxT_ZxP_Z, or T_OxP_OxT_ZxP_Z for anisotropic BRDFs.
    #[arg(long, value_name = "AxBxC[xD]", default_value = "16x32x32")]
    cells: String,
    /// Output map (float64 .npy, shape (T_o, P_o, T_z, P_z, C)).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Also write the zonal coefficients e_l, shape (L+1, C) float64 .npy.
    #[arg(long, value_name = "FILE")]
    coeffs: Option<PathBuf>,
    /// Also write a PNG preview: one tile per theta_o (phi_o = 0), rows theta_z, columns phi_z,
    /// scaled to the map's maximum.
    #[arg(long, value_name = "FILE")]
    preview: Option<PathBuf>,
    /// Compare N map entries (spread over the map) with the quadrature of the same light.
    #[arg(long, value_name = "N", default_value_t = 0)]
    check: usize,
    #[command(flatten)]
    report: ReportOptions,
}

impl RadialCmd {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let brdf = Brdf::parse(&self.brdf)?;
        if self.lmax > ifd_shade::MAX_TABLE_DEGREE {
            bail!(
                "--lmax {}: at most {}",
                self.lmax,
                ifd_shade::MAX_TABLE_DEGREE
            );
        }
        let size = self.parse_size(&brdf)?;
        // every output is checked before any work, so that a bad one leaves nothing behind
        crate::output::check_npy_output(&self.output, "-o", "the radial map")?;
        if let Some(p) = &self.coeffs {
            crate::output::check_npy_output(p, "--coeffs", "the zonal coefficient table")?;
        }
        if let Some(p) = &self.preview {
            crate::output::check_output_path(p).context("--preview")?;
        }
        if self.check > 100_000 {
            bail!("--check {}: at most 100000 entries", self.check);
        }
        let start = std::time::Instant::now();
        // the light: a profile, or the radial part of a map
        let (light, profile) = match (&self.light_profile, &self.env) {
            (Some(spec), None) => {
                let p = RadialProfile::parse(spec)?;
                let radiance = parse_radiance(&self.radiance)?;
                (
                    p.lighting([0.0, 0.0, 1.0], &radiance, self.lmax)?,
                    Some((p, radiance)),
                )
            }
            (None, Some(path)) => {
                let img =
                    ifd_image::read(path).with_context(|| format!("--env {}", path.display()))?;
                let env = ifd_render::EnvMap::new(img, 0.0)?;
                let axis = parse_vec(&self.axis, "--axis")?;
                if axis.length() < 1e-12 {
                    bail!("--axis {:?}: a zero vector", self.axis);
                }
                let sh = env.sh(self.lmax)?;
                (ZonalLighting::radial_part(&sh, axis.to_array())?, None)
            }
            _ => bail!("give --light-profile PROFILE or --env MAP"),
        };
        let ch = light.coeffs().len() / (self.lmax + 1);
        if brdf.channels() != 1 && brdf.channels() != ch {
            bail!(
                "--brdf {}: a {}-channel BRDF under {ch}-channel light (use --radiance R,G,B)",
                self.brdf,
                brdf.channels()
            );
        }
        let table = match &self.table {
            Some(p) => Some(LobeTable::read(p)?),
            None if Material::new(&brdf, self.lmax, None).is_err() => {
                eprintln!("building a lobe table (pass --table to reuse one)...");
                Some(LobeTable::build(
                    &brdf,
                    self.lmax,
                    default_theta_entries(&brdf),
                    (2 * default_theta_entries(&brdf)).min(128),
                    &|_, _| {},
                )?)
            }
            None => None,
        };
        let material = Material::new(&brdf, self.lmax, table)?;
        let bar = crate::progress::bar("map", "views", 0);
        let map = RadialMap::build(&material, &light, size, &crate::progress::track(&bar))?;
        bar.finish_and_clear();
        check_finite(&map, &light, self.env.as_deref(), &self.radiance)?;
        let build_seconds = start.elapsed().as_secs_f64();
        let data: Vec<f64> = map.data.iter().map(|v| f64::from(*v)).collect();
        ifd_image::write_npy_f64(
            &self.output,
            &[size.theta_o, size.phi_o, size.theta_z, size.phi_z, ch],
            &data,
        )?;
        if let Some(p) = &self.coeffs {
            ifd_image::write_npy_f64(p, &[self.lmax + 1, ch], light.coeffs())?;
        }
        if let Some(p) = &self.preview {
            crate::output::write_output(p, &preview(&map)?, &ifd_image::WriteOptions::default())?;
        }
        let check = (self.check > 0)
            .then(|| check(&map, &brdf, &light, profile.as_ref(), self.check))
            .transpose()?;
        let shape = [size.theta_o, size.phi_o, size.theta_z, size.phi_z, ch];
        let summary = || {
            let shape: Vec<String> = shape.iter().map(usize::to_string).collect();
            let mut text = format!(
                "wrote {}: radial map {} of {} at L = {}\n",
                written(&self.output),
                shape.join("x"),
                brdf.spec(),
                self.lmax
            );
            for (p, what) in [
                (&self.coeffs, "the zonal coefficients"),
                (&self.preview, "a preview"),
            ] {
                if let Some(p) = p {
                    let _ = writeln!(text, "wrote {}: {what}", written(p));
                }
            }
            if let Some(c) = &check {
                let f = |k: &str| c[k].as_f64().map_or_else(|| "-".to_owned(), number);
                let _ = writeln!(
                    text,
                    "check: largest error {} of the map's max, relative RMS {} ({} entries)",
                    f("max_error_of_map_max"),
                    f("relative_rms"),
                    c["entries"]
                );
            }
            text + &format!("time {}\n", seconds(build_seconds))
        };
        self.report.emit_summary(
            &json!({
                "brdf": brdf.spec(), "lmax": self.lmax, "channels": ch,
                "light_profile": self.light_profile, "env": self.env, "isotropic": map.isotropic,
                "shape": shape,
                "map_bytes_f32": map.bytes(),
                "coefficient_bytes_f32": 4 * light.coeffs().len(),
                "coefficients": light.coeffs(),
                "build_seconds": build_seconds,
                "check": check,
            }),
            summary,
        )?;
        Ok(())
    }

    fn parse_size(&self, brdf: &Brdf) -> Result<MapSize> {
        let v: Vec<usize> = self
            .cells
            .split(['x', 'X'])
            .map(|t| t.trim().parse::<usize>())
            .collect::<std::result::Result<_, _>>()
            .with_context(|| {
                format!("--cells {:?}: expected integers like 16x32x32", self.cells)
            })?;
        let iso = brdf.is_isotropic();
        let s = match (v.as_slice(), iso) {
            ([to, tz, pz], true) => MapSize {
                theta_o: *to,
                phi_o: 1,
                theta_z: *tz,
                phi_z: *pz,
            },
            ([to, po, tz, pz], false) => MapSize {
                theta_o: *to,
                phi_o: *po,
                theta_z: *tz,
                phi_z: *pz,
            },
            (_, true) => bail!(
                "--cells {:?}: an isotropic BRDF's map is T_OxT_ZxP_Z (3 sizes)",
                self.cells
            ),
            (_, false) => bail!(
                "--cells {:?}: an anisotropic BRDF's map is T_OxP_OxT_ZxP_Z (4 sizes)",
                self.cells
            ),
        };
        if [s.theta_o, s.phi_o, s.theta_z, s.phi_z]
            .iter()
            .any(|d| !(1..=4096).contains(d))
        {
            bail!("--cells {:?}: every size in 1..=4096", self.cells);
        }
        Ok(s)
    }
}

/// The largest accepted `--radiance`: the map is stored as float32 (whose
/// range ends at 3.4e38), and a reflection may exceed the light's radiance.
const MAX_RADIANCE: f64 = 1e30;

/// Parses `--radiance L` or `R,G,B`: finite, non-negative and at most
/// [`MAX_RADIANCE`].
fn parse_radiance(text: &str) -> Result<Vec<f64>> {
    let v: Vec<f64> = text
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .with_context(|| format!("--radiance {text:?}: expected L or R,G,B"))?;
    if !(v.len() == 1 || v.len() == 3) || v.iter().any(|x| !x.is_finite() || *x < 0.0) {
        bail!("--radiance {text:?}: expected one or three finite, non-negative numbers");
    }
    if v.iter().any(|x| *x > MAX_RADIANCE) {
        bail!(
            "--radiance {text:?}: at most {MAX_RADIANCE:e} (the map is stored as float32, whose \
             range ends at 3.4e38)"
        );
    }
    Ok(v)
}

/// Refuses a map or zonal coefficients with non-finite values (a light too
/// bright for float32) before anything is written, naming the option that
/// set the light.
fn check_finite(
    map: &RadialMap,
    light: &ZonalLighting,
    env: Option<&Path>,
    radiance: &str,
) -> Result<()> {
    let bad = map.data.iter().filter(|v| !v.is_finite()).count();
    let bad_coeffs = light.coeffs().iter().filter(|v| !v.is_finite()).count();
    if bad + bad_coeffs == 0 {
        return Ok(());
    }
    let what = if bad > 0 {
        format!(
            "{bad} of the map's {} values overflow float32",
            map.data.len()
        )
    } else {
        format!("{bad_coeffs} zonal coefficients are not finite")
    };
    if let Some(env) = env {
        bail!(
            "--env {}: {what}: the environment map is too bright",
            env.display()
        );
    }
    bail!("--radiance {radiance:?}: {what}: the light is too bright");
}

/// Tiles `theta_o` side by side (phi_o = 0), scaled to the maximum.
fn preview(map: &RadialMap) -> Result<Image> {
    let s = map.size;
    let ch = map.channels;
    let (w, h) = (s.theta_o * (s.phi_z + 1), s.theta_z);
    let max = map.data.iter().fold(0.0f32, |m, v| m.max(*v)).max(1e-30);
    let mut data = vec![0.0f32; w * h * ch];
    for i_o in 0..s.theta_o {
        for i_z in 0..s.theta_z {
            for j_z in 0..s.phi_z {
                let x = i_o * (s.phi_z + 1) + j_z;
                for c in 0..ch {
                    data[(i_z * w + x) * ch + c] = (map.get(i_o, 0, i_z, j_z, c) / max).max(0.0);
                }
            }
        }
    }
    Ok(Image::from_vec(w, h, ch, data)?)
}

/// Compares `n` entries spread over the map with the quadrature of the same
/// light: the profile's, or the band-limited radial part's.
fn check(
    map: &RadialMap,
    brdf: &Brdf,
    light: &ZonalLighting,
    profile: Option<&(RadialProfile, Vec<f64>)>,
    n: usize,
) -> Result<serde_json::Value> {
    let s = map.size;
    let total = s.theta_o * s.phi_o * s.theta_z * s.phi_z;
    let ch = map.channels;
    let kc = brdf.channels();
    let (mut max_rel, mut se, mut sr, mut unconverged) = (0.0f64, 0.0, 0.0, 0usize);
    let scale = map.data.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let mut k = vec![0.0; kc.max(3)];
    let mut e = vec![0.0; ch.max(kc)];
    // the radial part's band-limited profile, about +z (the map's own axis cells place it)
    let about_z = light.with_axis([0.0, 0.0, 1.0])?;
    for i in 0..n.min(total) {
        // a deterministic spread: the golden-ratio sequence over cell indices
        let idx = ((i as f64 * 0.618_033_988_749_894_9).fract() * total as f64) as usize;
        let j_z = idx % s.phi_z;
        let i_z = (idx / s.phi_z) % s.theta_z;
        let j_o = (idx / (s.phi_z * s.theta_z)) % s.phi_o;
        let i_o = idx / (s.phi_z * s.theta_z * s.phi_o);
        let (wo, zeta) = (map.view(i_o, j_o), map.axis(i_z, j_z));
        let ok = if let Some((p, radiance)) = profile {
            let ok = p.reference(brdf, wo, zeta, 1e-7, &mut e[..kc]);
            for (c, kc_) in k.iter_mut().enumerate().take(ch) {
                *kc_ = e[if kc == 1 { 0 } else { c }]
                    * radiance[if radiance.len() == 1 { 0 } else { c }];
            }
            ok
        } else {
            {
                // the band-limited profile f(t) = sum_l e_l y_l^0(t), per channel
                let z = &about_z;
                let mut ok = true;
                for c in 0..ch {
                    let f = |t: f64| {
                        let mut out = vec![0.0; ch];
                        z.eval([(1.0 - t * t).max(0.0).sqrt(), 0.0, t], &mut out);
                        out[c]
                    };
                    ok &= ifd_shade::zonal_quadrature(
                        brdf,
                        wo,
                        zeta,
                        &f,
                        (-1.0, 1.0),
                        &[],
                        1e-7,
                        &mut e[..kc],
                    );
                    k[c] = e[if kc == 1 { 0 } else { c }];
                }
                ok
            }
        };
        unconverged += usize::from(!ok);
        for (c, &reference) in k.iter().enumerate().take(ch) {
            let v = f64::from(map.get(i_o, j_o, i_z, j_z, c));
            let d = (v - reference).abs();
            max_rel = max_rel.max(d / f64::from(scale).max(1e-300));
            se += d * d;
            sr += reference * reference;
        }
    }
    Ok(json!({
        "entries": n.min(total),
        "max_error_of_map_max": max_rel,
        "relative_rms": (se / sr.max(1e-300)).sqrt(),
        "quadrature_unconverged": unconverged,
    }))
}
