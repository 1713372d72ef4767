//! The render loop: one ray per pixel centre (all methods alike), shading by
//! ISD (Eq. 22), its SH reference or the quadrature oracle, the environment
//! behind. Rows run in parallel; every pixel is computed the same way
//! whatever the thread count, so images do not depend on it.

use ifd_image::Image;
use ifd_shade::Brdf;
use ifd_shade::SphericalLight;
use ifd_shade::{BandMaps, Environment, Frame, Material, Scratch};
use rayon::prelude::*;

use crate::error::{RenderError, Result};
use crate::gbuffer::{Pixel, Surface, check_maps, nothing_visible, pixel};
use crate::job::{Job, Method, Rendered};
use crate::mc::{EnvSampler, estimate, pixel_seed};
use crate::oracle::Oracle;
use crate::scene::Scene;
use crate::split_sum::{SplitSum, SplitSumVariant};
use crate::textures::alpha_of;

/// One rendered row: pixels, mask, largest oracle `k`, unconverged pixels,
/// largest residual, standard errors.
type Row = (Vec<f32>, Vec<bool>, usize, usize, f64, Vec<f32>);

/// Renders `job`; `progress(done_rows, rows)` after each row.
///
/// # Errors
/// [`RenderError::NothingVisible`] when no pixel sees the object; shading
/// errors (a material of another degree than the environment, channels).
pub fn render(job: &Job<'_>, progress: &(dyn Fn(usize, usize) + Sync)) -> Result<Rendered> {
    let (w, h) = (job.camera.width(), job.camera.height());
    let ch = job.env.channels();
    let rough_map = job.maps.and_then(|m| m.roughness.as_ref());
    let albedo_map = job.maps.and_then(|m| m.albedo.as_ref());
    check_maps(&job.scene, job.maps)?;
    let kc = job.brdf.channels();
    if kc != 1 && kc != ch {
        return Err(RenderError::Parameter {
            name: "--brdf",
            value: job.brdf.spec().to_string(),
            reason: format!("a {kc}-channel BRDF needs a {kc}-channel environment, not {ch}"),
        });
    }
    if !job.lights.is_empty() && job.method == Method::Mc {
        return Err(RenderError::Parameter {
            name: "--light",
            value: format!("{} lights", job.lights.len()),
            reason: "the Monte Carlo renderer does not sample spherical lights; use \
                     --method quadrature for their reference"
                .into(),
        });
    }
    let eye = job.camera.eye().to_array();
    for l in job.lights {
        l.radiance_for(ch)?;
        // the camera inside a light sees nothing else
        l.cap_at(eye).map_err(|_| RenderError::Parameter {
            name: "--light",
            value: format!("centre {:?}, radius {}", l.centre, l.radius),
            reason: "the camera (--eye) is inside the light".into(),
        })?;
    }
    // a glTF asset shaded with its own materials (the job's BRDF `gltf`):
    // roughness varies per point, as with a roughness map
    let asset_materials = matches!(job.scene, Scene::Gltf(_)) && job.brdf.gltf_material().is_some();
    if (rough_map.is_some() || asset_materials)
        && job.family.is_none()
        && matches!(job.method, Method::Isd | Method::IsdMaps | Method::Sh)
    {
        return Err(RenderError::Parameter {
            name: if asset_materials {
                "--scene"
            } else {
                "--roughness-map"
            },
            value: format!("{:?}", job.method),
            reason: "ISD methods need a RoughnessFamily for a roughness map or a glTF \
                     asset's materials"
                .into(),
        });
    }
    if asset_materials && rough_map.is_some() {
        return Err(RenderError::Parameter {
            name: "--roughness-map",
            value: "a glTF asset".into(),
            reason: "a glTF asset's materials carry their own textures".into(),
        });
    }
    check_shadows(job, rough_map.is_some())?;
    // the glTF BRDF: ISD shades its three parts and combines them per pixel
    // with the point's colour and metalness (GltfMaterial::combine)
    let gltf = job.brdf.gltf_material();
    let np = if gltf.is_some() { 3 * ch } else { ch };
    if gltf.is_some() {
        let parts = job.brdf.tabulated()?;
        let tabulated = |m: &Material| m.brdf().spec() == parts.spec();
        let family_ok = job.family.is_none_or(|f| {
            f.materials()
                .iter()
                .all(|m| matches!(m.brdf().model(), ifd_shade::Model::GltfLobes { .. }))
        });
        if !job.material.is_none_or(tabulated) || !family_ok {
            return Err(RenderError::Parameter {
                name: "--table",
                value: job
                    .material
                    .map_or("a roughness family", |m| m.brdf().spec())
                    .into(),
                reason: format!(
                    "the glTF BRDF {} is shaded with the table of its parts, {}",
                    job.brdf.spec(),
                    parts.spec()
                ),
            });
        }
    }
    let degree = match (job.material, job.family) {
        (_, Some(f)) if rough_map.is_some() || asset_materials => Some(f.l_max()),
        (Some(m), _) => Some(m.l_max()),
        _ => None,
    };
    let baked = match job.method {
        Method::SplitSum | Method::SplitSumSampleRenderer => {
            if gltf.is_none() {
                return Err(RenderError::Parameter {
                    name: "--method",
                    value: format!("{:?}", job.method),
                    reason: format!(
                        "the split-sum methods shade the glTF BRDF (gltf:..), not {}",
                        job.brdf.spec()
                    ),
                });
            }
            if !job.lights.is_empty() || job.shadows.is_some() {
                return Err(RenderError::Parameter {
                    name: "--method",
                    value: format!("{:?}", job.method),
                    reason: "the split sum shades the environment alone (no lights, no shadows)"
                        .into(),
                });
            }
            match job.split_sum {
                Some(_) => None,
                None => Some(SplitSum::bake(job.env, 256)?),
            }
        }
        _ => None,
    };
    let split = match job.method {
        Method::SplitSum | Method::SplitSumSampleRenderer => job.split_sum.or(baked.as_ref()),
        _ => None,
    };
    let env_sh = match (job.method, degree) {
        (
            Method::Quadrature | Method::Mc | Method::SplitSum | Method::SplitSumSampleRenderer,
            _,
        ) => None,
        (_, Some(l)) => Some(Environment::new(job.env.sh(l)?)?.with_precision(job.precision)),
        (_, None) => {
            return Err(RenderError::Parameter {
                name: "--method",
                value: format!("{:?}", job.method),
                reason: "needs a material (or, with a roughness map, a roughness family)".into(),
            });
        }
    };
    let maps = match (&env_sh, job.method) {
        (Some(e), Method::IsdMaps) => Some(BandMaps::new(e)?),
        _ => None,
    };
    let oracle = (job.method == Method::Quadrature).then(|| Oracle::new(job.env));
    let sampler = (job.method == Method::Mc).then(|| EnvSampler::new(job.env));
    // one ISD-side shading of a material into `out`: the environment, then
    // each light as zonal lighting at the point (`tmp`: scratch)
    let shade = |m: &Material,
                 surface: &Surface,
                 s: &mut Scratch,
                 tmp: &mut [f64],
                 out: &mut [f64]|
     -> Result<()> {
        let (frame, wo) = (&surface.frame, surface.wo);
        let parts = gltf.is_some();
        match (job.method, &env_sh, &maps, parts) {
            (Method::Isd, Some(e), _, false) => m.shade_isd(e, frame, wo, s, out)?,
            (Method::Isd, Some(e), _, true) => m.shade_isd_parts(e, frame, wo, s, out)?,
            (Method::IsdMaps, _, Some(bm), false) => m.shade_isd(bm, frame, wo, s, out)?,
            (Method::IsdMaps, _, Some(bm), true) => m.shade_isd_parts(bm, frame, wo, s, out)?,
            (Method::Sh, Some(e), _, false) => m.shade_sh(e, frame, wo, out)?,
            (Method::Sh, Some(e), _, true) => m.shade_sh_parts(e, frame, wo, out)?,
            _ => unreachable!("ISD-side methods have their environment"),
        }
        for light in job.lights {
            let z = light.at(surface.p, m.l_max(), ch)?;
            match (job.method, parts) {
                (Method::Sh, false) => {
                    m.shade_sh(&Environment::new(z.to_sh()?)?, frame, wo, tmp)?;
                }
                (Method::Sh, true) => {
                    m.shade_sh_parts(&Environment::new(z.to_sh()?)?, frame, wo, tmp)?;
                }
                (_, false) => m.shade_isd(&z, frame, wo, s, tmp)?,
                (_, true) => m.shade_isd_parts(&z, frame, wo, s, tmp)?,
            }
            for c in 0..np {
                out[c] += tmp[c];
            }
        }
        Ok(())
    };
    // the plain case (one material, ISD from SH, nothing per point but the
    // albedo map): a row's points are shaded together, sharing vector lanes
    let batched = match (job.method, &env_sh, job.material) {
        (Method::Isd, Some(e), Some(m)) => (job.family.is_none()
            && job.lights.is_empty()
            && job.shadows.is_none()
            && gltf.is_none())
        .then_some((e, m)),
        _ => None,
    };
    let done = std::sync::atomic::AtomicUsize::new(0);
    let rows: Vec<Result<Row>> = (0..h)
        .into_par_iter()
        .map(|y| {
            if let Some((e, m)) = batched {
                let row = batched_row(job, e, m, albedo_map.is_some(), y)?;
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(n, h);
                return Ok(row);
            }
            let mut px = vec![0.0f32; w * ch];
            let mut mask = vec![false; w];
            let mut se = vec![0.0f32; if sampler.is_some() { w * ch } else { 0 }];
            let mut err = vec![0.0; ch.max(3)];
            let (mut max_k, mut bad, mut resid) = (0, 0, 0.0f64);
            let mut out = vec![0.0; 3 * ch.max(3)];
            let mut out2 = vec![0.0; 3 * ch.max(3)];
            let mut tmp = vec![0.0; 3 * ch.max(3)];
            let l = degree.unwrap_or(0);
            let mut scratch = Scratch::new(l, ch);
            let mut vis = vec![0.0; job.shadows.map_or(0, |s| (s.l_max() + 1).pow(2))];
            for x in 0..w {
                let Pixel { dir: d, surface } = pixel(&job.scene, &job.camera, job.maps, x, y);
                out.fill(0.0);
                if let Some(light) = light_in_front(job, d, surface.as_ref()) {
                    let r = light.radiance_for(ch)?;
                    for c in 0..ch {
                        px[x * ch + c] = r[c] as f32;
                    }
                    continue;
                }
                if let Some(surface) = surface {
                    mask[x] = true;
                    let Surface {
                        frame,
                        wo,
                        roughness: rough,
                        albedo,
                        p,
                        ..
                    } = surface;
                    // the glTF material of this point: the BRDF's factors,
                    // the albedo map's colour multiplying the base colour,
                    // the roughness map's value replacing the roughness
                    let point_gltf = gltf.map(|g| surface.gltf_material(&g));
                    // the roughness the ISD family is read at
                    let rough = match (surface.gltf, gltf) {
                        (Some(p), Some(_)) => Some(p.material.roughness),
                        _ => rough,
                    };
                    // the exact BRDF of this point (oracle, Monte Carlo)
                    let exact = matches!(job.method, Method::Quadrature | Method::Mc);
                    let local = match (rough, point_gltf) {
                        (_, Some(g)) if exact => Some(Brdf::gltf(&g)),
                        (Some(r), None) if exact => Some(job.brdf.with_roughness(alpha_of(r))?),
                        _ => None,
                    };
                    let brdf = local.as_ref().unwrap_or(job.brdf);
                    match job.method {
                        Method::Isd | Method::IsdMaps | Method::Sh => {
                            if let (Some(r), Some(f)) = (rough, job.family) {
                                let (m0, m1, t) = f.locate(r);
                                shade(m0, &surface, &mut scratch, &mut tmp, &mut out)?;
                                shade(m1, &surface, &mut scratch, &mut tmp, &mut out2)?;
                                for c in 0..np {
                                    out[c] = (1.0 - t) * out[c] + t * out2[c];
                                }
                            } else if let (Some(m), Some(sh)) = (job.material, job.shadows) {
                                let (o, d) = job.camera.ray(x as f64 + 0.5, y as f64 + 0.5);
                                sh.shade_isd(
                                    m,
                                    o,
                                    d,
                                    &frame,
                                    wo,
                                    &mut scratch,
                                    &mut vis,
                                    &mut out[..ch],
                                )?;
                            } else if let Some(m) = job.material {
                                shade(m, &surface, &mut scratch, &mut tmp, &mut out)?;
                            }
                            if let Some(g) = point_gltf {
                                let mut rgb = [0.0; 3];
                                g.combine(&out[..np], ch, &mut rgb);
                                out[..ch].copy_from_slice(&rgb[..ch]);
                            }
                        }
                        Method::Mc => {
                            let Some(smp) = &sampler else {
                                unreachable!("the sampler exists for mc")
                            };
                            let seed = pixel_seed(job.seed, x, y);
                            estimate(
                                job.env, smp, brdf, &frame, wo, job.spp, seed, &mut out, &mut err,
                            );
                            for c in 0..ch {
                                se[x * ch + c] = err[c] as f32;
                            }
                        }
                        Method::SplitSum | Method::SplitSumSampleRenderer => {
                            let (Some(ss), Some(g)) = (&split, point_gltf) else {
                                unreachable!("the split sum is baked for the glTF BRDF")
                            };
                            let variant = if job.method == Method::SplitSum {
                                SplitSumVariant::Consistent
                            } else {
                                SplitSumVariant::SampleRenderer
                            };
                            let rgb = ss.shade(variant, &g, frame.n, wo);
                            out[..3].copy_from_slice(&rgb);
                        }
                        Method::Quadrature => {
                            let Some(or) = &oracle else {
                                unreachable!("the oracle exists for quadrature")
                            };
                            if let Some(sh) = job.shadows {
                                let p = glam::DVec3::from_array(p);
                                sh.shade_reference(job.env, brdf, p, &frame, wo, &mut out);
                                for c in 0..ch {
                                    px[x * ch + c] = out[c] as f32;
                                }
                                continue;
                            }
                            let (k, ok, r) = or.shade(job.env, brdf, &frame, wo, &mut out);
                            max_k = max_k.max(k);
                            bad += usize::from(!ok);
                            resid = resid.max(r);
                            for light in job.lights {
                                let ok =
                                    light_quadrature(light, brdf, &frame, p, wo, ch, &mut tmp)?;
                                bad += usize::from(!ok);
                                for c in 0..ch {
                                    out[c] += tmp[c];
                                }
                            }
                        }
                    }
                    // a glTF asset's ambient occlusion (scaling the
                    // environment's light, as engines apply it) and emission
                    if let (Some(p), Some(_)) = (surface.gltf, gltf) {
                        for (c, o) in out[..ch].iter_mut().enumerate() {
                            *o = *o * p.occlusion + p.emissive[c.min(2)];
                        }
                    }
                    if albedo_map.is_some() && gltf.is_none() {
                        for c in 0..ch {
                            let k = albedo[c];
                            out[c] *= k;
                            if !se.is_empty() {
                                se[x * ch + c] *= k as f32;
                            }
                        }
                    }
                } else if let Some(bg) = job.background {
                    bg.background(d, &mut out);
                }
                for c in 0..ch {
                    px[x * ch + c] = out[c] as f32;
                }
            }
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, h);
            Ok((px, mask, max_k, bad, resid, se))
        })
        .collect();
    let mut data = Vec::with_capacity(w * h * ch);
    let mut mask = Vec::with_capacity(w * h);
    let (mut max_k, mut not_converged, mut max_residual) = (0, 0, 0.0f64);
    let mut se = Vec::new();
    for r in rows {
        let (p, m, k, b, res, e) = r?;
        se.extend(e);
        max_residual = max_residual.max(res);
        data.extend(p);
        mask.extend(m);
        max_k = max_k.max(k);
        not_converged += b;
    }
    let object_pixels = mask.iter().filter(|m| **m).count();
    if object_pixels == 0 {
        if !job.lights.is_empty() {
            return Err(RenderError::NothingVisible(format!(
                "no ray of the {w}x{h} image reaches the {}: the --light spheres hide or \
                 contain it, or the camera misses it (check --eye, --target, --fov)",
                job.scene.describe()
            )));
        }
        return Err(nothing_visible(&job.scene, &job.camera));
    }
    Ok(Rendered {
        image: Image::from_vec(w, h, ch, data)?,
        mask,
        object_pixels,
        max_k,
        not_converged,
        max_residual,
        stderr: if sampler.is_some() {
            Some(Image::from_vec(w, h, ch, se)?)
        } else {
            None
        },
    })
}

/// Row `y` of the plain ISD case ([`render`]'s `batched`): the row's points
/// shaded a few at a time ([`Material::shade_isd_batch`]: as many as fill
/// 128 lobe lanes, eight vectors of sixteen, so the per-call work is shared),
/// times the albedo map where there is one, the background elsewhere.
fn batched_row(
    job: &Job<'_>,
    env: &Environment,
    m: &Material,
    albedo: bool,
    y: usize,
) -> Result<Row> {
    let (w, ch) = (job.camera.width(), job.env.channels());
    let mut px = vec![0.0f32; w * ch];
    let mut mask = vec![false; w];
    let mut out = vec![0.0; 3 * ch.max(3)];
    let mut scratch = m.scratch(ch);
    let per = m
        .table()
        .map_or(1, |t| (128 / t.basis().directions().len().max(1)).max(1));
    // (column, albedo) and (frame, view) of the points waiting
    let mut waiting: Vec<(usize, [f64; 3])> = Vec::with_capacity(per);
    let mut points: Vec<(Frame, [f64; 3])> = Vec::with_capacity(per);
    let mut shaded = vec![0.0; per * ch];
    let mut flush = |waiting: &mut Vec<(usize, [f64; 3])>,
                     points: &mut Vec<(Frame, [f64; 3])>,
                     px: &mut [f32]|
     -> Result<()> {
        m.shade_isd_batch(env, points, &mut scratch, &mut shaded)?;
        for (i, &(x, k)) in waiting.iter().enumerate() {
            for c in 0..ch {
                let k = if albedo { k[c] } else { 1.0 };
                px[x * ch + c] = (shaded[i * ch + c] * k) as f32;
            }
        }
        waiting.clear();
        points.clear();
        Ok(())
    };
    for x in 0..w {
        let p = pixel(&job.scene, &job.camera, job.maps, x, y);
        match &p.surface {
            Some(surface) => {
                mask[x] = true;
                waiting.push((x, surface.albedo));
                points.push((surface.frame, surface.wo));
                if points.len() == per {
                    flush(&mut waiting, &mut points, &mut px)?;
                }
            }
            None => {
                if let Some(bg) = job.background {
                    bg.background(p.dir, &mut out);
                    for (o, v) in px[x * ch..(x + 1) * ch].iter_mut().zip(&out) {
                        *o = *v as f32;
                    }
                }
            }
        }
    }
    if !points.is_empty() {
        flush(&mut waiting, &mut points, &mut px)?;
    }
    Ok((px, mask, 0, 0, 0.0, Vec::new()))
}

/// Shadows need their mesh, `isd` or `quadrature`, a material of at most
/// their degree, and neither lights nor a roughness map.
fn check_shadows(job: &Job<'_>, roughness_map: bool) -> Result<()> {
    let Some(sh) = job.shadows else {
        return Ok(());
    };
    let bad = |reason: String| {
        Err(RenderError::Parameter {
            name: "--shadows",
            value: format!("{:?}", job.method),
            reason,
        })
    };
    match &job.scene {
        Scene::Mesh(m) if sh.is_of(m) => {}
        Scene::Mesh(_) => return bad("the shadows were computed for another mesh".into()),
        s => {
            return bad(format!(
                "self-shadowing needs a triangle mesh (an .obj scene), not the {s:?}"
            ));
        }
    }
    if !matches!(job.method, Method::Isd | Method::Quadrature) {
        return bad("shadows are shaded by isd (Eq. 25) and quadrature (ray traced)".into());
    }
    if !job.lights.is_empty() {
        return bad("spherical lights are not shadowed; drop --light".into());
    }
    if roughness_map {
        return bad("a roughness map is not shadowed; drop --roughness-map".into());
    }
    if job.brdf.gltf_material().is_some() {
        return bad("the glTF BRDF is not shadowed (Eq. 25 shades one material's slice)".into());
    }
    if let Some(m) = job.material.filter(|m| m.l_max() > sh.l_max()) {
        return bad(format!(
            "the material's L = {} exceeds the visibility's L = {}",
            m.l_max(),
            sh.l_max()
        ));
    }
    Ok(())
}

/// The light the ray `d` from the camera meets before the surface, if any.
fn light_in_front<'a>(
    job: &Job<'a>,
    d: [f64; 3],
    surface: Option<&Surface>,
) -> Option<&'a SphericalLight> {
    if job.lights.is_empty() {
        return None;
    }
    let o = job.camera.eye().to_array();
    let t_surface = surface.map_or(f64::INFINITY, |s| {
        ((s.p[0] - o[0]).powi(2) + (s.p[1] - o[1]).powi(2) + (s.p[2] - o[2]).powi(2)).sqrt()
    });
    job.lights
        .iter()
        .filter_map(|l| l.intersect(o, d).map(|t| (t, l)))
        .filter(|(t, _)| *t < t_surface)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, l)| l)
}

/// The exact reference of one light at a point: the cap's quadrature in the
/// local frame (tolerance 1e-6 of the pixel). Returns whether it converged.
fn light_quadrature(
    light: &SphericalLight,
    brdf: &Brdf,
    frame: &Frame,
    p: [f64; 3],
    wo: [f64; 3],
    ch: usize,
    out: &mut [f64],
) -> Result<bool> {
    let (axis, cos_alpha) = light.cap_at(p)?;
    let radiance = light.radiance_for(ch)?;
    let kc = brdf.channels();
    let mut k = vec![0.0; kc];
    let ok = ifd_shade::zonal_quadrature(
        brdf,
        frame.to_local(wo),
        frame.to_local(axis),
        &|_| 1.0,
        (cos_alpha, 1.0),
        &[],
        1e-6,
        &mut k,
    );
    for c in 0..ch {
        out[c] = radiance[c] * k[if kc == 1 { 0 } else { c }];
    }
    Ok(ok)
}
