//! The default scene's geometry: nodes walked from the scene's roots with
//! their matrices (or translation, rotation, scale) composed, every mesh
//! primitive's triangles (strips and fans converted, points and lines
//! skipped with a note) read, transformed (normals by the inverse
//! transpose, winding flipped under a negative determinant), turned from
//! glTF's y-up to ifd's z-up (`(x, y, z) -> (x, -z, y)`) and gathered into
//! one mesh; the first perspective camera node, moved the same way.

use std::collections::HashMap;
use std::rc::Rc;

use glam::{DMat3, DMat4, DQuat, DVec3};
use gltf::json;
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use super::accessor::{self, Values};
use super::document::{Ctx, Document};
use super::tangents;
use crate::error::Result;
use crate::mesh::{MeshParts, smooth_normals};

/// Node and primitive visits allowed (a node graph that instances its
/// subtrees many times over is refused).
const MAX_NODE_VISITS: usize = 1 << 20;

/// A perspective camera in the scene's z-up coordinates, before the mesh's
/// placement.
#[derive(Clone, Copy, Debug)]
pub(super) struct RawCamera {
    pub eye: DVec3,
    pub forward: DVec3,
    pub up: DVec3,
    pub yfov: f64,
    pub aspect: Option<f64>,
}

/// One primitive as the file stores it (before any node transform).
struct Local {
    pos: Vec<DVec3>,
    nrm: Option<Vec<DVec3>>,
    uv: [Option<Vec<[f64; 2]>>; 2],
    tan: Option<Vec<[f64; 4]>>,
    col: Option<Vec<[f64; 3]>>,
    tris: Vec<[u32; 3]>,
    /// The material's index; `None`: the default material.
    material: Option<usize>,
    /// The label for messages: `mesh 0 primitive 1`.
    label: String,
}

/// What the scene gathers into.
#[derive(Default)]
struct Gather {
    parts: MeshParts,
    /// Vertices so far (the optional attributes' fill count).
    n: usize,
    camera: Option<RawCamera>,
    visits: usize,
    cache: HashMap<(usize, usize), Option<Rc<Local>>>,
}

/// The default scene's triangles as mesh parts (z-up, unplaced; per-triangle
/// materials, `default_material` where a primitive has none) and its first
/// perspective camera. `normal_uv(material)` is the texture coordinate set
/// of the material's normal texture, when it has one: such primitives get
/// `MikkTSpace` tangents when the file has none.
pub(super) fn gather(
    ctx: &mut Ctx,
    doc: &Document,
    notes: &mut Vec<String>,
    default_material: usize,
    normal_uv: &dyn Fn(usize) -> Option<u32>,
) -> Result<(MeshParts, Option<RawCamera>)> {
    let root = &doc.root;
    let scene_index = root.scene.map_or(0, |s| s.value());
    let scene_part = format!("scene {scene_index}");
    let scene = root.scenes.get(scene_index).ok_or_else(|| {
        ctx.err(
            &scene_part,
            if root.scenes.is_empty() {
                "the file has no scene".to_string()
            } else {
                format!("does not exist ({} scenes)", root.scenes.len())
            },
        )
    })?;
    let mut g = Gather::default();
    g.parts.materials = Some(Vec::new());
    let mut on_path = vec![false; root.nodes.len()];
    let walk = Walk {
        doc,
        default_material,
        normal_uv,
    };
    // Depth first, without recursion (a file may nest nodes deeply): a
    // frame per node on the path, with the next child to visit.
    let mut path: Vec<Frame> = Vec::new();
    for n in &scene.nodes {
        let world = walk.enter(ctx, &mut g, notes, &on_path, n.value(), DMat4::IDENTITY)?;
        on_path[n.value()] = true;
        path.push(Frame {
            node: n.value(),
            world,
            next: 0,
        });
        while let Some(top) = path.last_mut() {
            let children = root.nodes[top.node].children.as_deref().unwrap_or_default();
            if let Some(child) = children.get(top.next) {
                top.next += 1;
                let parent = top.world;
                let c = child.value();
                let world = walk.enter(ctx, &mut g, notes, &on_path, c, parent)?;
                on_path[c] = true;
                path.push(Frame {
                    node: c,
                    world,
                    next: 0,
                });
            } else {
                on_path[top.node] = false;
                path.pop();
            }
        }
    }
    if g.parts.tris.is_empty() {
        return Err(ctx.err(
            scene_part,
            "has no triangles (no mesh primitive of mode TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN)",
        ));
    }
    Ok((g.parts, g.camera))
}

/// A node on the path from a root, its world matrix and its next child.
struct Frame {
    node: usize,
    world: DMat4,
    next: usize,
}

struct Walk<'a> {
    doc: &'a Document,
    default_material: usize,
    normal_uv: &'a dyn Fn(usize) -> Option<u32>,
}

impl Walk<'_> {
    /// Visits node `index` under the world matrix `parent`: its camera and
    /// its mesh's primitives. Returns its world matrix.
    fn enter(
        &self,
        ctx: &mut Ctx,
        g: &mut Gather,
        notes: &mut Vec<String>,
        on_path: &[bool],
        index: usize,
        parent: DMat4,
    ) -> Result<DMat4> {
        let part = format!("node {index}");
        let node = self
            .doc
            .root
            .nodes
            .get(index)
            .ok_or_else(|| ctx.err(&part, "does not exist"))?;
        if on_path.get(index).copied().unwrap_or(false) {
            return Err(ctx.err(&part, "is its own ancestor (its children form a cycle)"));
        }
        g.visits += 1;
        if g.visits > MAX_NODE_VISITS {
            return Err(ctx.err(
                &part,
                format!("the node hierarchy instances more than {MAX_NODE_VISITS} nodes"),
            ));
        }
        let world = parent * local_matrix(node);
        if !world.is_finite() {
            return Err(ctx.err(&part, "non-finite transform"));
        }
        if g.camera.is_none()
            && let Some(c) = node.camera
        {
            self.camera(ctx, g, notes, c.value(), world)?;
        }
        if let Some(m) = node.mesh {
            let mesh = m.value();
            let count = self
                .doc
                .root
                .meshes
                .get(mesh)
                .map(|m| m.primitives.len())
                .ok_or_else(|| ctx.err(&part, format!("mesh {mesh} does not exist")))?;
            g.visits = g.visits.saturating_add(count);
            if g.visits > MAX_NODE_VISITS {
                return Err(ctx.err(
                    &part,
                    format!(
                        "the node hierarchy instances more than {MAX_NODE_VISITS} nodes and primitives"
                    ),
                ));
            }
            for p in 0..count {
                let local = if let Some(l) = g.cache.get(&(mesh, p)) {
                    l.clone()
                } else {
                    let l = self.primitive(ctx, notes, mesh, p)?.map(Rc::new);
                    g.cache.insert((mesh, p), l.clone());
                    l
                };
                if let Some(local) = local {
                    self.instance(ctx, g, &local, world)?;
                }
            }
        }
        Ok(world)
    }

    fn camera(
        &self,
        ctx: &Ctx,
        g: &mut Gather,
        notes: &mut Vec<String>,
        index: usize,
        world: DMat4,
    ) -> Result<()> {
        let cam = self
            .doc
            .root
            .cameras
            .get(index)
            .ok_or_else(|| ctx.err(format!("camera {index}"), "does not exist"))?;
        let Some(p) = &cam.perspective else {
            notes.push(format!("camera {index} is not perspective: ignored"));
            return Ok(());
        };
        let eye = world.transform_point3(DVec3::ZERO);
        let forward = world.transform_vector3(-DVec3::Z).try_normalize();
        let up = world.transform_vector3(DVec3::Y).try_normalize();
        let yfov = f64::from(p.yfov).to_degrees();
        match (forward, up) {
            (Some(f), Some(u)) if eye.is_finite() && yfov > 0.0 && yfov < 180.0 => {
                g.camera = Some(RawCamera {
                    eye: z_up(eye),
                    forward: z_up(f),
                    up: z_up(u),
                    yfov,
                    aspect: p
                        .aspect_ratio
                        .map(f64::from)
                        .filter(|a| a.is_finite() && *a > 0.0),
                });
            }
            _ => notes.push(format!(
                "camera {index}: degenerate transform or field of view: ignored"
            )),
        }
        Ok(())
    }

    /// Reads primitive `p` of mesh `mesh`; `None` (with a note) when its mode
    /// is points or lines.
    fn primitive(
        &self,
        ctx: &mut Ctx,
        notes: &mut Vec<String>,
        mesh: usize,
        p: usize,
    ) -> Result<Option<Local>> {
        let label = format!("mesh {mesh} primitive {p}");
        let doc = self.doc;
        let prim = &doc.root.meshes[mesh].primitives[p];
        let Checked::Valid(mode) = prim.mode else {
            return Err(ctx.err(&label, "unknown mode"));
        };
        let mode_name = match mode {
            Mode::Points => "POINTS",
            Mode::Lines => "LINES",
            Mode::LineLoop => "LINE_LOOP",
            Mode::LineStrip => "LINE_STRIP",
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan => "",
        };
        if !mode_name.is_empty() {
            notes.push(format!(
                "{label}: mode {mode_name} skipped (only triangles are rendered)"
            ));
            return Ok(None);
        }
        if prim.targets.as_ref().is_some_and(|t| !t.is_empty()) {
            notes.push(format!(
                "{label}: morph targets ignored (the base shape is rendered)"
            ));
        }
        let attr = |s: Semantic| {
            prim.attributes
                .get(&Checked::Valid(s))
                .map(json::Index::value)
        };
        let Some(pos_index) = attr(Semantic::Positions) else {
            return Err(ctx.err(&label, "has no POSITION attribute"));
        };
        let pos = accessor::read(
            ctx,
            doc,
            pos_index,
            &format!("POSITION of {label}"),
            accessor::POSITION,
        )?;
        let n = pos.count;
        if u32::try_from(n).is_err() {
            return Err(ctx.err(&label, format!("{n} vertices (at most 2^32 - 1)")));
        }
        let read_attr = |ctx: &mut Ctx, s: Semantic, name: &str, want| -> Result<Option<Values>> {
            let Some(i) = attr(s) else { return Ok(None) };
            let what = format!("{name} of {label}");
            let v = accessor::read(ctx, doc, i, &what, want)?;
            if v.count != n {
                return Err(ctx.err(
                    format!("accessor {i} ({what})"),
                    format!("count {} differs from POSITION's {n}", v.count),
                ));
            }
            Ok(Some(v))
        };
        let nrm = read_attr(ctx, Semantic::Normals, "NORMAL", accessor::NORMAL)?;
        let uv0 = read_attr(
            ctx,
            Semantic::TexCoords(0),
            "TEXCOORD_0",
            accessor::TEXCOORD,
        )?;
        let uv1 = read_attr(
            ctx,
            Semantic::TexCoords(1),
            "TEXCOORD_1",
            accessor::TEXCOORD,
        )?;
        let tan = read_attr(ctx, Semantic::Tangents, "TANGENT", accessor::TANGENT)?;
        let col = read_attr(ctx, Semantic::Colors(0), "COLOR_0", accessor::COLOR)?;
        let indices: Vec<u32> = match prim.indices {
            Some(i) => {
                let what = format!("indices of {label}");
                let v = accessor::read(ctx, doc, i.value(), &what, accessor::INDICES)?;
                if let Some(k) = v.data.iter().position(|&x| x >= n as f64) {
                    return Err(ctx.err(
                        format!("accessor {} ({what})", i.value()),
                        format!(
                            "index {} (element {k}) is out of range ({n} vertices)",
                            v.data[k]
                        ),
                    ));
                }
                v.data.iter().map(|&x| x as u32).collect()
            }
            None => (0..n as u32).collect(),
        };
        let tris = triangles(&indices, mode);
        ctx.charge(tris.len() as u64 * 12, &label)?;
        let material = prim.material.map(|m| m.value());
        if let Some(m) = material
            && m >= self.default_material
        {
            return Err(ctx.err(&label, format!("material {m} does not exist")));
        }
        if tan.is_none()
            && let Some(m) = material
            && let Some(set) = (self.normal_uv)(m)
            && !matches!((set, &uv0, &uv1), (0, Some(_), _) | (1, _, Some(_)))
        {
            notes.push(format!(
                "{label}: the normal texture of material {m} uses TEXCOORD_{set}, which the \
                 primitive lacks: normal map ignored"
            ));
        }
        let v3 = |v: Values| (0..v.count).map(|i| DVec3::from_slice(v.get(i))).collect();
        let v2 = |v: Values| (0..v.count).map(|i| [v.get(i)[0], v.get(i)[1]]).collect();
        Ok(Some(Local {
            pos: v3(pos),
            nrm: nrm.map(v3),
            uv: [uv0.map(v2), uv1.map(v2)],
            tan: tan.map(|v| {
                (0..v.count)
                    .map(|i| {
                        let t = v.get(i);
                        [t[0], t[1], t[2], t[3]]
                    })
                    .collect()
            }),
            col: col.map(|v| {
                (0..v.count)
                    .map(|i| {
                        let c = v.get(i);
                        [c[0], c[1], c[2]]
                    })
                    .collect()
            }),
            tris,
            material,
            label,
        }))
    }

    /// Appends a primitive under the node matrix `world`.
    fn instance(&self, ctx: &mut Ctx, g: &mut Gather, local: &Local, world: DMat4) -> Result<()> {
        if local.tris.is_empty() {
            return Ok(());
        }
        let lin = DMat3::from_mat4(world);
        let det = lin.determinant();
        let nmat = if det.abs() > 1e-300 {
            lin.inverse().transpose()
        } else {
            DMat3::ZERO
        };
        let flip = det < 0.0;
        let pos: Vec<DVec3> = local
            .pos
            .iter()
            .map(|p| z_up(world.transform_point3(*p)))
            .collect();
        if let Some(i) = pos.iter().position(|p| !p.is_finite()) {
            return Err(ctx.err(
                &local.label,
                format!("vertex {i} is not finite once transformed"),
            ));
        }
        let mut tris = local.tris.clone();
        if flip {
            for t in &mut tris {
                t.swap(1, 2);
            }
        }
        let nrm: Vec<DVec3> = match &local.nrm {
            Some(nrm) if nmat != DMat3::ZERO => nrm
                .iter()
                .map(|n| z_up(nmat * *n).normalize_or_zero())
                .collect(),
            _ => smooth_normals(&pos, &tris),
        };
        let sign = if flip { -1.0 } else { 1.0 };
        let mut tan: Option<Vec<[f64; 4]>> = local.tan.as_ref().map(|t| {
            t.iter()
                .map(|t| {
                    let v = z_up(lin * DVec3::new(t[0], t[1], t[2])).normalize_or_zero();
                    [v.x, v.y, v.z, if t[3] < 0.0 { -sign } else { sign }]
                })
                .collect()
        });
        let mut pos = pos;
        let mut nrm = nrm;
        let mut uv = local.uv.clone();
        let mut col = local.col.clone();
        if tan.is_none()
            && let Some(m) = local.material
            && let Some(set) = (self.normal_uv)(m)
            && let Some(tc) = uv.get(set as usize).and_then(Option::as_ref)
        {
            ctx.charge(tris.len() as u64 * 3 * 160, &local.label)?;
            let t = tangents::mikktspace(&pos, &nrm, tc, &tris);
            let split = tangents::split_vertices(&t, &mut tris, pos.len());
            // Copies of vertices whose corners got different tangents.
            grow(&mut pos, &split.extra);
            grow(&mut nrm, &split.extra);
            for set in uv.iter_mut().flatten() {
                grow(set, &split.extra);
            }
            if let Some(c) = &mut col {
                grow(c, &split.extra);
            }
            tan = Some(split.tangents);
        }
        let added = pos.len();
        let base = g.n;
        if u32::try_from(base + added).is_err() {
            return Err(ctx.err(&local.label, "the scene has more than 2^32 - 1 vertices"));
        }
        ctx.charge(added as u64 * 200 + tris.len() as u64 * 96, &local.label)?;
        let parts = &mut g.parts;
        parts.pos.extend(pos);
        parts.nrm.extend(nrm);
        let [uv0, uv1] = uv;
        extend(&mut parts.uv, uv0, base, added, [0.0; 2]);
        extend(&mut parts.uv1, uv1, base, added, [0.0; 2]);
        extend(&mut parts.tangents, tan, base, added, [0.0; 4]);
        extend(&mut parts.colors, col, base, added, [1.0; 3]);
        let b = base as u32;
        parts
            .tris
            .extend(tris.iter().map(|t| [t[0] + b, t[1] + b, t[2] + b]));
        let m = local.material.unwrap_or(self.default_material) as u32;
        if let Some(mats) = &mut parts.materials {
            mats.extend(std::iter::repeat_n(m, tris.len()));
        }
        g.n += added;
        Ok(())
    }
}

/// Appends a copy of each vertex `extra` names.
fn grow<T: Copy>(v: &mut Vec<T>, extra: &[(u32, [f64; 4])]) {
    for &(orig, _) in extra {
        let x = v[orig as usize];
        v.push(x);
    }
}

/// Appends `src` (or `fill` when the primitive lacks the attribute) to an
/// optional per-vertex array, creating it (filled for the `base` earlier
/// vertices) when a primitive first has it.
fn extend<T: Copy>(
    dst: &mut Option<Vec<T>>,
    src: Option<Vec<T>>,
    base: usize,
    added: usize,
    fill: T,
) {
    match (dst.as_mut(), src) {
        (Some(d), Some(s)) => d.extend(s),
        (Some(d), None) => d.extend(std::iter::repeat_n(fill, added)),
        (None, Some(s)) => {
            let mut d = vec![fill; base];
            d.extend(s);
            *dst = Some(d);
        }
        (None, None) => {}
    }
}

/// A node's local matrix: `matrix`, or translation * rotation * scale.
fn local_matrix(node: &json::Node) -> DMat4 {
    if let Some(m) = node.matrix {
        return DMat4::from_cols_array(&m.map(f64::from));
    }
    let t = node
        .translation
        .map_or(DVec3::ZERO, |t| DVec3::from(t.map(f64::from)));
    let s = node
        .scale
        .map_or(DVec3::ONE, |s| DVec3::from(s.map(f64::from)));
    let r = node.rotation.map_or(DQuat::IDENTITY, |q| {
        let [x, y, z, w] = q.0.map(f64::from);
        let q = DQuat::from_xyzw(x, y, z, w);
        if q.length() > 1e-12 && q.is_finite() {
            q.normalize()
        } else {
            DQuat::IDENTITY
        }
    });
    DMat4::from_scale_rotation_translation(s, r, t)
}

/// glTF's y-up to ifd's z-up.
pub(super) fn z_up(v: DVec3) -> DVec3 {
    DVec3::new(v.x, -v.z, v.y)
}

/// Triangles of a triangle list, strip or fan (glTF 2.0, 3.7.2.1).
fn triangles(ix: &[u32], mode: Mode) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => (0..ix.len().saturating_sub(2))
            .map(|i| {
                if i % 2 == 0 {
                    [ix[i], ix[i + 1], ix[i + 2]]
                } else {
                    [ix[i + 1], ix[i], ix[i + 2]]
                }
            })
            .collect(),
        Mode::TriangleFan => (1..ix.len().saturating_sub(1))
            .map(|i| [ix[i], ix[i + 1], ix[0]])
            .collect(),
        _ => ix.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans() {
        let ix = [0, 1, 2, 3, 4];
        assert_eq!(
            triangles(&ix, Mode::TriangleStrip),
            vec![[0, 1, 2], [2, 1, 3], [2, 3, 4]]
        );
        assert_eq!(
            triangles(&ix, Mode::TriangleFan),
            vec![[1, 2, 0], [2, 3, 0], [3, 4, 0]]
        );
        assert_eq!(triangles(&ix, Mode::Triangles), vec![[0, 1, 2]]);
        assert!(triangles(&ix[..2], Mode::TriangleStrip).is_empty());
    }
}
