//! Triangle meshes from OBJ files (read by `tobj`), ray cast through a
//! bounding volume hierarchy.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;

use crate::error::{RenderError, Result};
use crate::hit::Hit;

/// A triangle mesh ready for ray casting.
///
/// Triangle meshes from OBJ files (read by `tobj`), ray cast through a
/// bounding volume hierarchy.
///
/// - Axes: OBJ files are y-up by convention; they are rotated to ifd's z-up
///   (`(x, y, z) -> (x, -z, y)`) unless the file is declared z-up.
/// - Placement: the mesh is centred on its bounding box and scaled so that its
///   bounding sphere has radius 1, like the analytic scenes (documented; the
///   camera defaults frame it).
/// - Normals: the file's, interpolated (smooth shading); when the file has
///   none, area-weighted averages of the face normals at each position.
/// - Tangents: `dP/du` of each triangle from its texture coordinates, for
///   anisotropic BRDFs; a mesh without texture coordinates has none (such a
///   BRDF on it is refused by the renderer).
/// - Extras (glTF assets, [`crate::GltfAsset`]): per-triangle material
///   indices, per-vertex tangents (`xyz` and the handedness `w`), a second set
///   of texture coordinates and vertex colours, each interpolated into the
///   [`Hit`].
/// - BVH: binary, median split of the centroids along the widest axis, at most
///   4 triangles per leaf; slab tests for boxes, Moller-Trumbore for triangles.
#[derive(Debug)]
pub struct Mesh {
    pos: Vec<DVec3>,
    nrm: Vec<DVec3>,
    /// Per-triangle `dP/du` (zero without texture coordinates).
    dpdu: Vec<DVec3>,
    /// Per-vertex texture coordinates (`v` flipped: 0 at the top of an image).
    uv: Option<Vec<[f64; 2]>>,
    tris: Vec<[u32; 3]>,
    has_uv: bool,
    nodes: Vec<Node>,
    /// Per-vertex second texture coordinates (as given: no flip).
    uv1: Option<Vec<[f64; 2]>>,
    /// Per-vertex tangents: unit `xyz` (or zero where unknown), `w = +-1`.
    tan: Option<Vec<[f64; 4]>>,
    /// Per-vertex linear RGB colours.
    col: Option<Vec<[f64; 3]>>,
    /// Per-triangle material indices, in the BVH's triangle order.
    mat: Option<Vec<u32>>,
    /// The placement: a point `p` of the input is at `(p - centre) / radius`.
    centre: DVec3,
    radius: f64,
}

/// What [`Mesh::from_parts`] builds a mesh from: z-up positions, unit or
/// zero normals, and optional per-vertex and per-triangle data.
#[derive(Debug, Default)]
pub(crate) struct MeshParts {
    pub pos: Vec<DVec3>,
    pub nrm: Vec<DVec3>,
    /// Texture coordinates, `v = 0` at the top of an image unless `flip_v`.
    pub uv: Option<Vec<[f64; 2]>>,
    /// OBJ's `v` is 0 at the bottom: flip it (glTF's is not flipped).
    pub flip_v: bool,
    pub uv1: Option<Vec<[f64; 2]>>,
    pub tangents: Option<Vec<[f64; 4]>>,
    pub colors: Option<Vec<[f64; 3]>>,
    pub tris: Vec<[u32; 3]>,
    pub materials: Option<Vec<u32>>,
}

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: first triangle and count; inner: `count == 0`, children at
    /// `start` and `start + 1`.
    start: u32,
    count: u32,
}

impl Mesh {
    /// Reads an OBJ file (polygons triangulated as fans; materials ignored).
    ///
    /// # Errors
    /// [`RenderError::Parameter`] naming the file for unreadable or malformed
    /// files, files without triangles, and non-finite coordinates.
    pub fn load(path: &Path, z_up: bool) -> Result<Self> {
        let bad = |reason: String| RenderError::Parameter {
            name: "--scene",
            value: path.display().to_string(),
            reason,
        };
        let opts = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..Default::default()
        };
        let text =
            std::fs::read(path).map_err(|e| bad(format!("cannot read the OBJ file: {e}")))?;
        check_face_indices(&text).map_err(|e| bad(format!("malformed OBJ file: {e}")))?;
        let (models, _materials) = tobj::load_obj_buf(&mut text.as_slice(), &opts, |_| {
            // Materials are ignored.
            Ok(Default::default())
        })
        .map_err(|e| bad(format!("cannot read the OBJ file: {e}")))?;
        let mut pos = Vec::new();
        let mut nrm = Vec::new();
        let mut uv = Vec::new();
        let mut tris = Vec::new();
        let (mut with_n, mut with_uv, mut total) = (true, true, 0usize);
        for m in &models {
            let mesh = &m.mesh;
            let base = pos.len() as u32;
            let nv = mesh.positions.len() / 3;
            total += nv;
            with_n &= mesh.normals.len() == 3 * nv;
            with_uv &= mesh.texcoords.len() == 2 * nv;
            for i in 0..nv {
                let p = DVec3::new(
                    f64::from(mesh.positions[3 * i]),
                    f64::from(mesh.positions[3 * i + 1]),
                    f64::from(mesh.positions[3 * i + 2]),
                );
                pos.push(p);
                if mesh.normals.len() == 3 * nv {
                    nrm.push(DVec3::new(
                        f64::from(mesh.normals[3 * i]),
                        f64::from(mesh.normals[3 * i + 1]),
                        f64::from(mesh.normals[3 * i + 2]),
                    ));
                }
                if mesh.texcoords.len() == 2 * nv {
                    uv.push([
                        f64::from(mesh.texcoords[2 * i]),
                        f64::from(mesh.texcoords[2 * i + 1]),
                    ]);
                }
            }
            for t in mesh.indices.chunks_exact(3) {
                if t.iter().any(|&i| i as usize >= nv) {
                    let i = t
                        .iter()
                        .copied()
                        .find(|&i| i as usize >= nv)
                        .unwrap_or(t[0]);
                    return Err(bad(format!("a face refers to vertex {i} of {nv}")));
                }
                tris.push([base + t[0], base + t[1], base + t[2]]);
            }
        }
        if tris.is_empty() {
            return Err(bad("no triangles (an OBJ mesh needs `f` faces)".into()));
        }
        if let Some(i) = pos.iter().position(|p| !p.is_finite()) {
            return Err(bad(format!("vertex {i} has non-finite coordinates")));
        }
        let fix = |v: DVec3| if z_up { v } else { DVec3::new(v.x, -v.z, v.y) };
        let pos: Vec<DVec3> = pos.into_iter().map(fix).collect();
        let nrm = if with_n && nrm.len() == total {
            nrm.into_iter().map(fix).collect()
        } else {
            smooth_normals(&pos, &tris)
        };
        let uv = (with_uv && uv.len() == total).then_some(uv);
        Self::build(MeshParts {
            pos,
            nrm,
            uv,
            flip_v: true,
            tris,
            ..MeshParts::default()
        })
    }

    /// A mesh from positions (z-up), vertex normals (computed when `None`),
    /// optional texture coordinates and triangles; placed as [`Self::load`] does.
    ///
    /// # Errors
    /// [`RenderError::Parameter`] without triangles or for out-of-range indices.
    pub fn from_triangles(
        pos: Vec<DVec3>,
        normals: Option<Vec<DVec3>>,
        uv: Option<&[[f64; 2]]>,
        tris: Vec<[u32; 3]>,
    ) -> Result<Self> {
        let lengths_ok = normals.as_ref().is_none_or(|n| n.len() == pos.len())
            && uv.is_none_or(|u| u.len() == pos.len())
            && pos.iter().all(|p| p.is_finite());
        if !lengths_ok || tris.is_empty() || tris.iter().flatten().any(|&i| i as usize >= pos.len())
        {
            return Err(RenderError::Parameter {
                name: "mesh",
                value: format!("{} vertices, {} triangles", pos.len(), tris.len()),
                reason: "needs finite positions, one normal and one texture coordinate per \
                         vertex when given, and triangles whose indices are in range"
                    .into(),
            });
        }
        let nrm = normals.unwrap_or_else(|| smooth_normals(&pos, &tris));
        Self::build(MeshParts {
            pos,
            nrm,
            uv: uv.map(<[_]>::to_vec),
            flip_v: true,
            tris,
            ..MeshParts::default()
        })
    }

    /// A mesh from parts whose lengths and indices the caller checked
    /// (the glTF reader); placed as [`Self::load`] does.
    pub(crate) fn from_parts(parts: MeshParts) -> Result<Self> {
        let n = parts.pos.len();
        let ok = parts.nrm.len() == n
            && parts.uv.as_ref().is_none_or(|u| u.len() == n)
            && parts.uv1.as_ref().is_none_or(|u| u.len() == n)
            && parts.tangents.as_ref().is_none_or(|t| t.len() == n)
            && parts.colors.as_ref().is_none_or(|c| c.len() == n)
            && parts
                .materials
                .as_ref()
                .is_none_or(|m| m.len() == parts.tris.len())
            && parts.pos.iter().all(|p| p.is_finite())
            && !parts.tris.is_empty()
            && parts.tris.iter().flatten().all(|&i| (i as usize) < n);
        if !ok {
            return Err(RenderError::Parameter {
                name: "mesh",
                value: format!("{n} vertices, {} triangles", parts.tris.len()),
                reason: "inconsistent mesh parts (lengths, indices or non-finite positions)".into(),
            });
        }
        Self::build(parts)
    }

    fn build(parts: MeshParts) -> Result<Self> {
        let MeshParts {
            mut pos,
            nrm,
            uv,
            flip_v,
            uv1,
            tangents,
            colors,
            mut tris,
            materials,
        } = parts;
        // centre and scale to the unit bounding sphere
        let (lo, hi) = pos.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(a, b), p| (a.min(*p), b.max(*p)),
        );
        let c = 0.5 * (lo + hi);
        let r = pos.iter().map(|p| (*p - c).length()).fold(0.0, f64::max);
        let (centre, radius) = (c, r);
        if r.is_nan() || r <= 0.0 {
            return Err(RenderError::Parameter {
                name: "mesh",
                value: format!("{} vertices", pos.len()),
                reason: "all vertices coincide".into(),
            });
        }
        for p in &mut pos {
            *p = (*p - c) / r;
        }
        let nrm: Vec<DVec3> = nrm.into_iter().map(DVec3::normalize_or_zero).collect();
        // BVH over triangle centroids; triangles reordered into leaves
        let cent: Vec<DVec3> = tris
            .iter()
            .map(|t| (pos[t[0] as usize] + pos[t[1] as usize] + pos[t[2] as usize]) / 3.0)
            .collect();
        let mut order: Vec<usize> = (0..tris.len()).collect();
        let mut nodes = vec![Node {
            lo: DVec3::ZERO,
            hi: DVec3::ZERO,
            start: 0,
            count: 0,
        }];
        build_node(&pos, &tris, &cent, &mut order, 0, 0, &mut nodes);
        tris = order.iter().map(|&i| tris[i]).collect();
        let mat = materials.map(|m| order.iter().map(|&i| m[i]).collect());
        let has_uv = uv.is_some();
        let dpdu = tris
            .iter()
            .map(|t| {
                let Some(uv) = &uv else { return DVec3::ZERO };
                let [a, b, c] = t.map(|i| i as usize);
                let (e1, e2) = (pos[b] - pos[a], pos[c] - pos[a]);
                let (du1, dv1) = (uv[b][0] - uv[a][0], uv[b][1] - uv[a][1]);
                let (du2, dv2) = (uv[c][0] - uv[a][0], uv[c][1] - uv[a][1]);
                let det = du1 * dv2 - du2 * dv1;
                if det.abs() < 1e-20 {
                    DVec3::ZERO
                } else {
                    (dv2 * e1 - dv1 * e2) / det
                }
            })
            .collect();
        let uv = if flip_v {
            uv.map(|u| u.iter().map(|t| [t[0], 1.0 - t[1]]).collect())
        } else {
            uv
        };
        let tan = tangents.map(|t| {
            t.into_iter()
                .map(|[x, y, z, w]| {
                    let v = DVec3::new(x, y, z).normalize_or_zero();
                    [v.x, v.y, v.z, if w < 0.0 { -1.0 } else { 1.0 }]
                })
                .collect()
        });
        Ok(Self {
            pos,
            nrm,
            dpdu,
            uv,
            tris,
            has_uv,
            nodes,
            uv1,
            tan,
            col: colors,
            mat,
            centre,
            radius,
        })
    }

    /// The placement [`Self::load`] applies to fit the unit bounding sphere:
    /// the centre `c` of the bounding box and the radius `r` of the bounding
    /// sphere around it, in the input's (z-up) coordinates. A point `p` of
    /// the input is at `(p - c) / r` in the mesh; cameras and lights given
    /// with the input move the same way (directions are unchanged).
    #[must_use]
    pub fn placement(&self) -> (DVec3, f64) {
        (self.centre, self.radius)
    }

    /// Per-triangle material indices (in the order of the BVH's triangles,
    /// which [`Hit::material`] reports), `None` for OBJ meshes.
    #[must_use]
    pub fn triangle_materials(&self) -> Option<&[u32]> {
        self.mat.as_deref()
    }

    /// Per-vertex tangents `[x, y, z, w]` (unit `xyz`, zero where unknown;
    /// the handedness `w = +-1`: the bitangent is `w N x T`), `None` when
    /// the mesh has none.
    #[must_use]
    pub fn tangents(&self) -> Option<&[[f64; 4]]> {
        self.tan.as_deref()
    }

    /// Whether the mesh has texture coordinates (tangents).
    #[must_use]
    pub fn has_uv(&self) -> bool {
        self.has_uv
    }

    /// Triangles.
    #[must_use]
    pub fn triangles(&self) -> usize {
        self.tris.len()
    }

    /// The first hit of the ray `o + t d`, `t > 1e-9`.
    #[must_use]
    pub fn intersect(&self, o: DVec3, d: DVec3) -> Option<Hit> {
        self.intersect_vertices(o, d).map(|(h, _, _)| h)
    }

    /// Vertex positions (after centring and scaling).
    #[must_use]
    pub fn positions(&self) -> &[DVec3] {
        &self.pos
    }

    /// Vertex normals (unit).
    #[must_use]
    pub fn normals(&self) -> &[DVec3] {
        &self.nrm
    }

    /// Whether the ray `o + t d` hits anything for `t` in `(1e-9, t_max)`.
    #[must_use]
    pub fn occluded(&self, o: DVec3, d: DVec3, t_max: f64) -> bool {
        self.intersect(o, d).is_some_and(|h| h.t < t_max)
    }

    /// [`Self::intersect`] with the hit triangle's vertex indices and their
    /// barycentric weights (for per-vertex data).
    #[must_use]
    pub fn intersect_vertices(&self, o: DVec3, d: DVec3) -> Option<(Hit, [usize; 3], [f64; 3])> {
        // zero components: a huge finite inverse keeps the slab test free of 0 * inf
        let inv = DVec3::new(
            if d.x == 0.0 { 1e300 } else { 1.0 / d.x },
            if d.y == 0.0 { 1e300 } else { 1.0 / d.y },
            if d.z == 0.0 { 1e300 } else { 1.0 / d.z },
        );
        let mut best: Option<(f64, usize, f64, f64)> = None;
        let mut stack = [0u32; 64];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let node = self.nodes[stack[sp] as usize];
            let tmax = best.map_or(f64::INFINITY, |b| b.0);
            if !slab(node.lo, node.hi, o, inv, tmax) {
                continue;
            }
            if node.count > 0 {
                for i in node.start as usize..(node.start + node.count) as usize {
                    if let Some((t, u, v)) = self.hit_triangle(i, o, d)
                        && best.is_none_or(|b| t < b.0)
                    {
                        best = Some((t, i, u, v));
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.start;
                stack[sp + 1] = node.start + 1;
                sp += 2;
            }
        }
        let (t, i, u, v) = best?;
        let [a, b, c] = self.tris[i].map(|k| k as usize);
        let mut n =
            ((1.0 - u - v) * self.nrm[a] + u * self.nrm[b] + v * self.nrm[c]).normalize_or_zero();
        let geo = (self.pos[b] - self.pos[a])
            .cross(self.pos[c] - self.pos[a])
            .normalize_or_zero();
        if n == DVec3::ZERO {
            n = geo;
        }
        // shade the side the ray sees; the tangent frame turns over with it
        let back = n.dot(d) > 0.0 && geo.dot(d) > 0.0;
        if back {
            n = -n;
        }
        let w = 1.0 - u - v;
        let lerp2 = |t: &Vec<[f64; 2]>| {
            [
                w * t[a][0] + u * t[b][0] + v * t[c][0],
                w * t[a][1] + u * t[b][1] + v * t[c][1],
            ]
        };
        let uv = self.uv.as_ref().map(lerp2);
        let uv1 = self.uv1.as_ref().map(lerp2);
        let tangent = self.tan.as_ref().and_then(|t| {
            let [ta, tb, tc] = [t[a], t[b], t[c]].map(glam::DVec4::from_array);
            let m = w * ta + u * tb + v * tc;
            let xyz = m.truncate().try_normalize()?;
            let s = if m.w < 0.0 { -1.0 } else { 1.0 };
            let t = xyz.extend(s);
            Some(if back { -t } else { t })
        });
        let color = self
            .col
            .as_ref()
            .map(|col| [0, 1, 2].map(|k| w * col[a][k] + u * col[b][k] + v * col[c][k]));
        Some((
            Hit {
                t,
                p: o + t * d,
                n,
                dpdu: self.dpdu[i],
                uv,
                material: self.mat.as_ref().map(|m| m[i]),
                tangent,
                uv1,
                color,
            },
            [a, b, c],
            [1.0 - u - v, u, v],
        ))
    }

    fn hit_triangle(&self, i: usize, o: DVec3, d: DVec3) -> Option<(f64, f64, f64)> {
        let [a, b, c] = self.tris[i].map(|k| self.pos[k as usize]);
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-14 {
            return None;
        }
        let inv = 1.0 / det;
        let s = o - a;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(e1);
        let v = d.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = e2.dot(q) * inv;
        (t > 1e-9).then_some((t, u, v))
    }
}

fn slab(lo: DVec3, hi: DVec3, o: DVec3, inv: DVec3, tmax: f64) -> bool {
    let t0 = (lo - o) * inv;
    let t1 = (hi - o) * inv;
    let tn = t0.min(t1).max_element().max(0.0);
    let tf = t0.max(t1).min_element().min(tmax);
    tn <= tf
}

fn build_node(
    pos: &[DVec3],
    tris: &[[u32; 3]],
    cent: &[DVec3],
    order: &mut [usize],
    offset: usize,
    node: usize,
    nodes: &mut Vec<Node>,
) {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let (mut clo, mut chi) = (lo, hi);
    for &i in order.iter() {
        for &k in &tris[i] {
            lo = lo.min(pos[k as usize]);
            hi = hi.max(pos[k as usize]);
        }
        clo = clo.min(cent[i]);
        chi = chi.max(cent[i]);
    }
    nodes[node].lo = lo;
    nodes[node].hi = hi;
    if order.len() <= 4 {
        nodes[node].start = offset as u32;
        nodes[node].count = order.len() as u32;
        return;
    }
    let ext = chi - clo;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| cent[a][axis].total_cmp(&cent[b][axis]));
    let first = nodes.len();
    nodes[node].start = first as u32;
    nodes[node].count = 0;
    let empty = Node {
        lo: DVec3::ZERO,
        hi: DVec3::ZERO,
        start: 0,
        count: 0,
    };
    nodes.push(empty);
    nodes.push(empty);
    let (left, right) = order.split_at_mut(mid);
    build_node(pos, tris, cent, left, offset, first, nodes);
    build_node(pos, tris, cent, right, offset + mid, first + 1, nodes);
}

/// Area-weighted vertex normals, shared by vertices at the same position.
pub(crate) fn smooth_normals(pos: &[DVec3], tris: &[[u32; 3]]) -> Vec<DVec3> {
    let key = |p: DVec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
    let mut acc: HashMap<(u64, u64, u64), DVec3> = HashMap::new();
    for t in tris {
        let [a, b, c] = t.map(|i| pos[i as usize]);
        let n = (b - a).cross(c - a); // length = twice the area
        for p in [a, b, c] {
            *acc.entry(key(p)).or_insert(DVec3::ZERO) += n;
        }
    }
    pos.iter()
        .map(|p| {
            acc.get(&key(*p))
                .copied()
                .unwrap_or(DVec3::Z)
                .normalize_or_zero()
        })
        .collect()
}

/// Checks every face's vertex references (`f v`, `f v/vt`, `f v//vn`,
/// `f v/vt/vn`, 1-based or negative = relative) against the positions,
/// texture coordinates and normals defined before it, as OBJ requires.
/// `tobj` trusts them: a relative index past the start (`f 1/-1` with no
/// texture coordinate) overflows its index arithmetic and panics (found by
/// fuzzing, `fuzz/regressions/obj/`).
fn check_face_indices(text: &[u8]) -> std::result::Result<(), String> {
    let (mut nv, mut nvt, mut nvn) = (0i64, 0i64, 0i64);
    for (k, line) in text.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => nv += 1,
            Some("vt") => nvt += 1,
            Some("vn") => nvn += 1,
            Some("f" | "l" | "p") => {
                for w in words {
                    for (j, part) in w.split('/').enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let (what, count) = match j {
                            0 => ("position", nv),
                            1 => ("texture coordinate", nvt),
                            2 => ("normal", nvn),
                            _ => {
                                return Err(format!(
                                    "line {}: vertex {w:?} has more than 3 indices",
                                    k + 1
                                ));
                            }
                        };
                        let Ok(i) = part.parse::<i64>() else {
                            return Err(format!(
                                "line {}: index {part:?} is not an integer",
                                k + 1
                            ));
                        };
                        let resolved = if i < 0 { count + i } else { i - 1 };
                        if i == 0 || resolved < 0 || resolved >= count {
                            return Err(format!(
                                "line {}: {what} index {i} refers to none of the {count} defined before it",
                                k + 1
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}
