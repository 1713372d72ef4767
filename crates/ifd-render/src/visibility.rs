//! Shading with visibility (ISD Sec. 6.1, Eq. 25, Appendix A): self-shadowed
//! environment lighting on a mesh.
//!
//! # The three steps
//! Eq. 25 adds the visibility `v` to Eq. 20: `I = int E(w) v(w) k(w) dw`,
//! `k` the cosine-weighted slice rotated to the world. Appendix A expresses
//! it without SH rotations:
//!
//! 1. the slice's world SH coefficients `rho_l^m = pi_l sum_j lambda_l^j
//!    y_l^m(R z_j)` from the rotated lobes
//!    ([`ifd_shade::shade::Material::world_sh`]);
//! 2. the product with the lighting, `(rho E)_b = sum_a rho_a T_ab` with the
//!    precomputed matrix `T_ab = int y_a y_b E` ([`ProductMatrix`]; the paper's
//!    `gamma` are the same numbers expressed on rotated zonal harmonics);
//! 3. the inner product with the visibility's SH, `I = sum_b (rho E)_b v_b`
//!    (the paper evaluates it as Eq. 22 with `e` replaced by `v` and the
//!    lobe weights by `rho E`'s: the same sum, written on RZH).
//!
//! `v` is projected per vertex of the mesh by ray casting (spherical
//! Fibonacci directions, [`VertexVisibility`]) in world coordinates and
//! interpolated with the hit's barycentric weights. Everything is truncated at
//! degree `L`: `I_L = int (k_L)(v_L) E`, which converges to Eq. 25 as `L`
//! grows (up to the vertex interpolation of `v`).
//!
//! The reference ([`reference()`]) traces the visibility of every quadrature
//! direction at the pixel's own point: `2 x 2` Gauss-Legendre nodes per
//! texel of the (piecewise-constant) map.

use glam::DVec3;
use ifd_shade::Brdf;
use ifd_shade::shade::{Frame, Material, Scratch};
use ifd_sphere::ShEvaluator;
use rayon::prelude::*;

use crate::envmap::EnvMap;
use crate::error::{RenderError, Result};
use crate::mesh::Mesh;

/// A torus mesh (ring radius `ring`, tube radius `tube`, about `z`) of `nu x
/// nv` quads, two triangles each, with exact normals.
///
/// # Errors
/// [`RenderError::Parameter`] for fewer than 3 segments either way or radii
/// that are not `0 < tube < ring`.
pub fn torus_mesh(ring: f64, tube: f64, nu: usize, nv: usize) -> Result<Mesh> {
    if nu < 3 || nv < 3 || !(tube > 0.0 && tube < ring && ring.is_finite()) {
        return Err(RenderError::Parameter {
            name: "torus",
            value: format!("radii {ring}, {tube}, {nu}x{nv} segments"),
            reason: "needs 0 < tube < ring and at least 3x3 segments".into(),
        });
    }
    let mut pos = Vec::with_capacity(nu * nv);
    let mut nrm = Vec::with_capacity(nu * nv);
    for i in 0..nu {
        let a = std::f64::consts::TAU * i as f64 / nu as f64;
        for j in 0..nv {
            let b = std::f64::consts::TAU * j as f64 / nv as f64;
            let n = DVec3::new(b.cos() * a.cos(), b.cos() * a.sin(), b.sin());
            pos.push(DVec3::new(ring * a.cos(), ring * a.sin(), 0.0) + tube * n);
            nrm.push(n);
        }
    }
    let id = |i: usize, j: usize| ((i % nu) * nv + (j % nv)) as u32;
    let mut tris = Vec::with_capacity(2 * nu * nv);
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    Mesh::from_triangles(pos, Some(nrm), None, tris)
}

/// Per-vertex SH visibility in world coordinates.
#[derive(Clone, Debug)]
pub struct VertexVisibility {
    l_max: usize,
    /// `[vertex (L + 1)^2 + i]`.
    coeffs: Vec<f64>,
}

impl VertexVisibility {
    /// Casts `n_dirs` rays from every vertex (offset `1e-4` along its
    /// normal) and projects the binary visibility on SH up to `l_max`.
    /// `progress(done, total)` every 256 vertices.
    ///
    /// # Errors
    /// Degrees beyond the SH code's limit; `n_dirs < (L + 1)^2`.
    pub fn compute(
        mesh: &Mesh,
        l_max: usize,
        n_dirs: usize,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self> {
        let n = (l_max + 1) * (l_max + 1);
        if n_dirs < n {
            return Err(RenderError::Parameter {
                name: "visibility directions",
                value: n_dirs.to_string(),
                reason: format!("needs at least (L + 1)^2 = {n}"),
            });
        }
        let sh = ShEvaluator::new(l_max)?;
        let dirs = ifd_sphere::zhf::fibonacci(n_dirs);
        let ydirs: Vec<f64> = dirs.iter().flat_map(|d| sh.eval(*d)).collect();
        let (pos, nrm) = (mesh.positions(), mesh.normals());
        let done = std::sync::atomic::AtomicUsize::new(0);
        let total = pos.len();
        let coeffs: Vec<f64> = (0..total)
            .into_par_iter()
            .flat_map_iter(|v| {
                let o = pos[v] + 1e-4 * nrm[v];
                let mut c = vec![0.0; n];
                for (k, d) in dirs.iter().enumerate() {
                    if !mesh.occluded(o, DVec3::from_array(*d), f64::INFINITY) {
                        for (ci, y) in c.iter_mut().zip(&ydirs[k * n..(k + 1) * n]) {
                            *ci += y;
                        }
                    }
                }
                let w = 4.0 * std::f64::consts::PI / n_dirs as f64;
                for ci in &mut c {
                    *ci *= w;
                }
                let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                if d.is_multiple_of(256) || d == total {
                    progress(d, total);
                }
                c
            })
            .collect();
        Ok(Self { l_max, coeffs })
    }

    /// The degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// The coefficients up to degree `l` (`<= L`) interpolated at barycentric
    /// weights `w` of vertices `v`, into `out` (`(l + 1)^2` values).
    pub fn interpolate(&self, v: [usize; 3], w: [f64; 3], l: usize, out: &mut [f64]) {
        let n = (self.l_max + 1) * (self.l_max + 1);
        let m = (l + 1) * (l + 1);
        out[..m].fill(0.0);
        for (vi, wi) in v.iter().zip(w) {
            for (o, c) in out[..m].iter_mut().zip(&self.coeffs[vi * n..vi * n + m]) {
                *o += wi * c;
            }
        }
    }
}

/// `T_ab = int y_a y_b E` per channel for the piecewise-constant map (`2 x
/// 2` Gauss-Legendre nodes per texel).
#[derive(Clone, Debug)]
pub struct ProductMatrix {
    l_max: usize,
    channels: usize,
    /// `[(a n + b) C + c]`.
    t: Vec<f64>,
}

impl ProductMatrix {
    /// The matrix of `env` up to degree `l_max`.
    ///
    /// # Errors
    /// Degrees beyond the SH code's limit.
    pub fn new(env: &EnvMap, l_max: usize) -> Result<Self> {
        let sh = ShEvaluator::new(l_max)?;
        let n = (l_max + 1) * (l_max + 1);
        let ch = env.channels();
        let nodes = texel_nodes(env);
        let img = env.image();
        // rows of T in parallel: T[a, :] = sum_s w_s E(s) y_a(s) y(s)
        let ys: Vec<f64> = nodes
            .par_iter()
            .flat_map_iter(|(d, _, _)| sh.eval(*d))
            .collect();
        let t: Vec<f64> = (0..n)
            .into_par_iter()
            .flat_map_iter(|a| {
                let mut row = vec![0.0; n * ch];
                for (s, (_, w, texel)) in nodes.iter().enumerate() {
                    let y = &ys[s * n..(s + 1) * n];
                    let ya = w * y[a];
                    for c in 0..ch {
                        let e = ya * f64::from(img.data()[texel * ch + c]);
                        if e == 0.0 {
                            continue;
                        }
                        for (b, yb) in y.iter().enumerate() {
                            row[b * ch + c] += e * yb;
                        }
                    }
                }
                row
            })
            .collect();
        Ok(Self {
            l_max,
            channels: ch,
            t,
        })
    }

    /// Step 2 then 3: `sum_ab rho_a T_ab v_b` per channel, truncated at degree
    /// `l` (`<= L`); `rho` has `kc` channels (1 or `C`), `v` one.
    pub fn apply(&self, rho: &[f64], kc: usize, v: &[f64], l: usize, out: &mut [f64]) {
        let n = (self.l_max + 1) * (self.l_max + 1);
        let m = (l + 1) * (l + 1);
        let ch = self.channels;
        out[..ch].fill(0.0);
        for a in 0..m {
            let row = &self.t[a * n * ch..(a + 1) * n * ch];
            for c in 0..ch {
                let r = rho[a * kc + if kc == 1 { 0 } else { c }];
                if r == 0.0 {
                    continue;
                }
                let mut acc = 0.0;
                for b in 0..m {
                    acc += row[b * ch + c] * v[b];
                }
                out[c] += r * acc;
            }
        }
    }
}

/// A quadrature node of a map: direction, weight (solid angle), texel.
pub type TexelNode = ([f64; 3], f64, usize);

/// Quadrature nodes of the map: direction, weight (solid angle) and texel,
/// `2 x 2` Gauss-Legendre nodes per texel in `(cos theta, phi)`, after the
/// map's rotation.
#[must_use]
pub fn texel_nodes(env: &EnvMap) -> Vec<TexelNode> {
    let img = env.image();
    let (w, h) = (img.width(), img.height());
    let g = 1.0 / 3f64.sqrt();
    let mut out = Vec::with_capacity(4 * w * h);
    for v in 0..h {
        let (z0, z1) = (
            (std::f64::consts::PI * v as f64 / h as f64).cos(),
            (std::f64::consts::PI * (v + 1) as f64 / h as f64).cos(),
        );
        for u in 0..w {
            let (p0, p1) = (
                std::f64::consts::TAU * u as f64 / w as f64 + env.rotation(),
                std::f64::consts::TAU * (u + 1) as f64 / w as f64 + env.rotation(),
            );
            let area = (z0 - z1) * (p1 - p0);
            for a in [-g, g] {
                let z = 0.5 * (z0 + z1) + 0.5 * (z0 - z1) * a;
                let r = (1.0 - z * z).max(0.0).sqrt();
                for b in [-g, g] {
                    let p = 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * b;
                    out.push(([r * p.cos(), r * p.sin(), z], 0.25 * area, v * w + u));
                }
            }
        }
    }
    out
}

/// Eq. 25 at one point by the three steps: `vis` the interpolated
/// visibility SH (degree `>= l`), `l` the degree used.
///
/// # Errors
/// Shading errors of [`Material::world_sh`].
#[allow(clippy::too_many_arguments)]
pub fn shade_visible(
    material: &Material,
    product: &ProductMatrix,
    vis: &[f64],
    frame: &Frame,
    wo: [f64; 3],
    l: usize,
    s: &mut Scratch,
    out: &mut [f64],
) -> Result<()> {
    out[..product.channels].fill(0.0);
    if let Some(rho) = material.world_sh(frame, wo, s)? {
        product.apply(
            rho.data(),
            rho.channels(),
            vis,
            l.min(material.l_max()),
            out,
        );
    }
    Ok(())
}

/// The ray-traced reference of Eq. 25 at point `p`: every quadrature node of
/// the map weighted by the exact slice and its traced visibility (from `p`
/// offset `1e-4` along the normal); `nodes` are the map's [`texel_nodes`],
/// built once for all pixels.
#[allow(clippy::too_many_arguments)]
pub fn reference(
    env: &EnvMap,
    nodes: &[TexelNode],
    brdf: &Brdf,
    mesh: &Mesh,
    p: DVec3,
    frame: &Frame,
    wo: [f64; 3],
    out: &mut [f64],
) {
    let ch = env.channels();
    let kc = brdf.channels();
    let img = env.image();
    let wl = frame.to_local(wo);
    let o = p + 1e-4 * DVec3::from_array(frame.n);
    let mut k = vec![0.0; kc.max(3)];
    out[..ch].fill(0.0);
    for &(d, w, texel) in nodes {
        brdf.slice(frame.to_local(d), wl, &mut k);
        if k[..kc].iter().all(|x| *x == 0.0) {
            continue;
        }
        if mesh.occluded(o, DVec3::from_array(d), f64::INFINITY) {
            continue;
        }
        for c in 0..ch {
            out[c] += w * f64::from(img.data()[texel * ch + c]) * k[if kc == 1 { 0 } else { c }];
        }
    }
}

/// A pixel's point on the mesh: position, vertices, barycentric weights,
/// shading frame, direction to the viewer.
type MeshPoint = (DVec3, [usize; 3], [f64; 3], Frame, [f64; 3]);

/// What the study renders: a mesh seen by a camera under a map.
#[derive(Debug)]
pub struct VisibilityScene<'a> {
    /// The mesh.
    pub mesh: &'a Mesh,
    /// The camera.
    pub camera: crate::camera::Camera,
    /// The environment (piecewise constant; its texels are the reference's
    /// quadrature).
    pub env: &'a EnvMap,
    /// The BRDF.
    pub brdf: &'a Brdf,
}

/// The study's images and errors (ISD Fig. 7).
#[derive(Debug)]
pub struct VisibilityStudy {
    /// Per degree: `(L, relative RMS of ISD with visibility, of ISD
    /// without)` against the reference.
    pub rows: Vec<(usize, f64, f64)>,
    /// The reference.
    pub reference: ifd_image::Image,
    /// ISD with visibility at the highest degree.
    pub shadowed: ifd_image::Image,
    /// ISD without visibility at the highest degree.
    pub unshadowed: ifd_image::Image,
    /// Object pixels.
    pub mask: Vec<bool>,
    /// Seconds: reference, visibility projection, product matrix, ISD frame
    /// at the highest degree.
    pub seconds: [f64; 4],
}

/// Renders the reference once, then ISD with and without visibility at each
/// degree of `degrees` (the material and the visibility are built at the
/// highest and truncated), and measures them over the object.
///
/// # Errors
/// Shading and SH errors; [`RenderError::NothingVisible`].
pub fn study(
    scene: &VisibilityScene<'_>,
    material: &Material,
    n_dirs: usize,
    degrees: &[usize],
    progress: &dyn Fn(&str),
) -> Result<VisibilityStudy> {
    let (w, h) = (scene.camera.width(), scene.camera.height());
    let ch = scene.env.channels();
    let l_max = material.l_max();
    if degrees.iter().any(|l| *l > l_max) {
        return Err(RenderError::Parameter {
            name: "degrees",
            value: format!("{degrees:?}"),
            reason: format!("at most the material's L = {l_max}"),
        });
    }
    // the G-buffer: hit, vertices, weights, frame
    let hits: Vec<Option<MeshPoint>> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..w).map(move |x| {
                let (o, d) = scene.camera.ray(x as f64 + 0.5, y as f64 + 0.5);
                scene.mesh.intersect_vertices(o, d).map(|(hit, v, b)| {
                    (
                        hit.p,
                        v,
                        b,
                        Frame::new(hit.n.to_array(), hit.dpdu.to_array()),
                        (-d).to_array(),
                    )
                })
            })
        })
        .collect();
    let mask: Vec<bool> = hits.iter().map(Option::is_some).collect();
    if !mask.iter().any(|m| *m) {
        return Err(RenderError::NothingVisible(
            "no ray hits the mesh (check the camera)".into(),
        ));
    }
    let img = |data: Vec<f64>| {
        ifd_image::Image::from_vec(w, h, ch, data.into_iter().map(|v| v as f32).collect())
    };
    progress("reference (ray-traced visibility)");
    let t = std::time::Instant::now();
    let nodes = texel_nodes(scene.env);
    let reference: Vec<f64> = hits
        .par_iter()
        .flat_map_iter(|hit| {
            let mut out = vec![0.0; ch];
            if let Some((p, _, _, frame, wo)) = hit {
                reference(
                    scene.env, &nodes, scene.brdf, scene.mesh, *p, frame, *wo, &mut out,
                );
            }
            out
        })
        .collect();
    let t_ref = t.elapsed().as_secs_f64();
    progress("visibility per vertex");
    let t = std::time::Instant::now();
    let vis = VertexVisibility::compute(
        scene.mesh,
        l_max,
        n_dirs.max((l_max + 1) * (l_max + 1)),
        &|_, _| {},
    )?;
    let t_vis = t.elapsed().as_secs_f64();
    progress("product matrix");
    let t = std::time::Instant::now();
    let product = ProductMatrix::new(scene.env, l_max)?;
    let t_prod = t.elapsed().as_secs_f64();
    let n = (l_max + 1) * (l_max + 1);
    let mut rows = Vec::new();
    let (mut shadowed, mut unshadowed) = (Vec::new(), Vec::new());
    let mut t_frame = 0.0;
    for &l in degrees {
        progress(&format!("ISD at L = {l}"));
        let t = std::time::Instant::now();
        let with: Vec<Result<Vec<f64>>> = hits
            .par_iter()
            .map_init(
                || (material.scratch(ch), vec![0.0; n]),
                |(s, v), hit| {
                    let mut out = vec![0.0; ch];
                    if let Some((_, verts, bary, frame, wo)) = hit {
                        vis.interpolate(*verts, *bary, l, v);
                        shade_visible(material, &product, v, frame, *wo, l, s, &mut out)?;
                    }
                    Ok(out)
                },
            )
            .collect();
        let with: Vec<f64> = with.into_iter().collect::<Result<Vec<_>>>()?.concat();
        t_frame = t.elapsed().as_secs_f64();
        // without visibility: the same truncated product with v = 1
        // (its SH: sqrt(4 pi) in y_0^0), i.e. int k_l E_l
        let mut one = vec![0.0; n];
        one[0] = (4.0 * std::f64::consts::PI).sqrt();
        let without: Vec<Result<Vec<f64>>> = hits
            .par_iter()
            .map_init(
                || material.scratch(ch),
                |s, hit| {
                    let mut out = vec![0.0; ch];
                    if let Some((_, _, _, frame, wo)) = hit {
                        shade_visible(material, &product, &one, frame, *wo, l, s, &mut out)?;
                    }
                    Ok(out)
                },
            )
            .collect();
        let without: Vec<f64> = without.into_iter().collect::<Result<Vec<_>>>()?.concat();
        let (a, b, r) = (
            img(with.clone())?,
            img(without.clone())?,
            img(reference.clone())?,
        );
        rows.push((
            l,
            crate::render::relative_rms(&a, &r, &mask),
            crate::render::relative_rms(&b, &r, &mask),
        ));
        shadowed = with;
        unshadowed = without;
    }
    Ok(VisibilityStudy {
        rows,
        reference: img(reference)?,
        shadowed: img(shadowed)?,
        unshadowed: img(unshadowed)?,
        mask,
        seconds: [t_ref, t_vis, t_prod, t_frame],
    })
}
