//! Shading with visibility (ISD Sec. 6.1, Eq. 25, Appendix A): self-shadowed
//! environment lighting on a mesh.

use glam::DVec3;
use ifd_shade::Brdf;
use ifd_shade::{Frame, Material, Scratch};
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
        let dirs = ifd_sphere::fibonacci(n_dirs);
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

/// What self-shadowed shading of one mesh under one map needs, built once
/// for every frame: the visibility per vertex, the product matrix, and the
/// quadrature nodes of the ray-traced reference.
///
/// Shading with visibility (ISD Sec. 6.1, Eq. 25, Appendix A): self-shadowed
/// environment lighting on a mesh.
///
/// # The three steps
/// Eq. 25 adds the visibility `v` to Eq. 20: `I = int E(w) v(w) k(w) dw`,
/// `k` the cosine-weighted slice rotated to the world. Appendix A expresses
/// it without SH rotations:
///
/// 1. the slice's world SH coefficients `rho_l^m = pi_l sum_j lambda_l^j
///    y_l^m(R z_j)` from the rotated lobes
///    ([`ifd_shade::Material::world_sh`]);
/// 2. the product with the lighting, `(rho E)_b = sum_a rho_a T_ab` with the
///    precomputed matrix `T_ab = int y_a y_b E` ([`ProductMatrix`]; the paper's
///    `gamma` are the same numbers expressed on rotated zonal harmonics);
/// 3. the inner product with the visibility's SH, `I = sum_b (rho E)_b v_b`
///    (the paper evaluates it as Eq. 22 with `e` replaced by `v` and the
///    lobe weights by `rho E`'s: the same sum, written on RZH).
///
/// `v` is projected per vertex of the mesh by ray casting (spherical
/// Fibonacci directions, [`VertexVisibility`]) in world coordinates and
/// interpolated with the hit's barycentric weights. Everything is truncated at
/// degree `L`: `I_L = int (k_L)(v_L) E`, which converges to Eq. 25 as `L`
/// grows (up to the vertex interpolation of `v`).
///
/// The reference ([`reference()`]) traces the visibility of every quadrature
/// direction at the pixel's own point: `2 x 2` Gauss-Legendre nodes per
/// texel of the (piecewise-constant) map.
///
/// [`Shadows`] holds what a frame needs (the visibility per vertex, the
/// product matrix, the reference's nodes); [`crate::Job::shadows`]
/// renders with it (`ifd render --shadows`): `isd` by the three steps,
/// `quadrature` by the ray-traced reference.
#[derive(Clone, Debug)]
pub struct Shadows {
    mesh: std::sync::Arc<Mesh>,
    visibility: VertexVisibility,
    product: ProductMatrix,
    nodes: Vec<TexelNode>,
}

impl Shadows {
    /// Projects the visibility of every vertex of `mesh` on SH up to `l_max`
    /// with `rays` rays (at least `(L + 1)^2`) and the product matrix of
    /// `env`; `progress(done, total)` over the vertices.
    ///
    /// # Errors
    /// [`RenderError::Parameter`] for fewer rays than `(L + 1)^2`; degrees
    /// beyond the SH code's limit.
    pub fn new(
        mesh: std::sync::Arc<Mesh>,
        env: &EnvMap,
        l_max: usize,
        rays: usize,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self> {
        let visibility = VertexVisibility::compute(&mesh, l_max, rays, progress)?;
        let product = ProductMatrix::new(env, l_max)?;
        Ok(Self {
            mesh,
            visibility,
            product,
            nodes: texel_nodes(env),
        })
    }

    /// What the ray-traced reference alone needs (`quadrature`): the
    /// quadrature nodes, with a visibility and product matrix of degree 0
    /// (one ray per vertex), so `isd` cannot shade with it above `L = 0`.
    ///
    /// # Errors
    /// As [`Self::new`].
    pub fn traced(mesh: std::sync::Arc<Mesh>, env: &EnvMap) -> Result<Self> {
        Self::new(mesh, env, 0, 1, &|_, _| {})
    }

    /// The degree of the visibility and the product matrix.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.visibility.l_max()
    }

    /// The mesh the visibility belongs to.
    #[must_use]
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// Whether these are the shadows of `mesh` (the same mesh, not a copy).
    #[must_use]
    pub fn is_of(&self, mesh: &std::sync::Arc<Mesh>) -> bool {
        std::sync::Arc::ptr_eq(&self.mesh, mesh)
    }

    /// Eq. 25 by the three steps at the point of the ray `o + t d`, truncated
    /// at the material's degree (`<=` [`Self::l_max`]); `vis` holds
    /// `(L + 1)^2` values of scratch. Zero where the ray misses the mesh.
    ///
    /// # Errors
    /// Shading errors of [`Material::world_sh`].
    #[allow(clippy::too_many_arguments)]
    pub fn shade_isd(
        &self,
        material: &Material,
        o: DVec3,
        d: DVec3,
        frame: &Frame,
        wo: [f64; 3],
        s: &mut Scratch,
        vis: &mut [f64],
        out: &mut [f64],
    ) -> Result<()> {
        let l = material.l_max().min(self.l_max());
        if let Some((_, v, b)) = self.mesh.intersect_vertices(o, d) {
            self.visibility.interpolate(v, b, l, vis);
            shade_visible(material, &self.product, vis, frame, wo, l, s, out)
        } else {
            out.fill(0.0);
            Ok(())
        }
    }

    /// The ray-traced reference of Eq. 25 at point `p` ([`reference()`]).
    #[allow(clippy::too_many_arguments)]
    pub fn shade_reference(
        &self,
        env: &EnvMap,
        brdf: &Brdf,
        p: DVec3,
        frame: &Frame,
        wo: [f64; 3],
        out: &mut [f64],
    ) {
        reference(env, &self.nodes, brdf, &self.mesh, p, frame, wo, out);
    }
}
