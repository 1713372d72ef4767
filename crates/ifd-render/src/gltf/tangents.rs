//! `MikkTSpace` tangents (the `bevy_mikktspace` crate) for primitives whose
//! material has a normal texture and whose file has no `TANGENT`, as glTF
//! asks, with vertices split where their corners got different tangents.
//!
//! `MikkTSpace`'s bitangent follows `+v`; glTF's normal textures have `+y` up
//! in the image, where `v` decreases (`v = 0` is the top row). The texture
//! coordinates are handed over as `(u, 1 - v)`, so the handedness it returns
//! is glTF's (`B = w N x T` points up the image), as the tools that write
//! glTF tangents (Blender's exporter) have it.

use std::collections::HashMap;

use bevy_mikktspace::{Geometry, TangentSpace};
use glam::DVec3;

struct Faces<'a> {
    pos: &'a [DVec3],
    nrm: &'a [DVec3],
    uv: &'a [[f64; 2]],
    tris: &'a [[u32; 3]],
    /// One tangent per corner (`3 face + vertex`).
    out: Vec<[f64; 4]>,
}

/// A finite `f32` (`MikkTSpace` works in `f32`; values beyond its range or
/// non-finite ones become 0 rather than poison its sorting).
fn f(x: f64) -> f32 {
    let v = x as f32;
    if v.is_finite() { v } else { 0.0 }
}

impl Geometry for Faces<'_> {
    fn num_faces(&self) -> usize {
        self.tris.len()
    }

    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }

    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        let p = self.pos[self.tris[face][vert] as usize];
        [f(p.x), f(p.y), f(p.z)]
    }

    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        let n = self.nrm[self.tris[face][vert] as usize];
        [f(n.x), f(n.y), f(n.z)]
    }

    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let t = self.uv[self.tris[face][vert] as usize];
        [f(t[0]), f(1.0 - t[1])]
    }

    fn set_tangent(&mut self, tangent_space: Option<TangentSpace>, face: usize, vert: usize) {
        let t = tangent_space.map_or([0.0, 0.0, 0.0, 1.0], |t| t.tangent_encoded().map(f64::from));
        if let Some(slot) = self.out.get_mut(3 * face + vert) {
            *slot = t;
        }
    }
}

/// `MikkTSpace` tangents `[x, y, z, w]` of every corner (`3 face + vertex`);
/// zero `xyz` where it finds none.
pub(super) fn mikktspace(
    pos: &[DVec3],
    nrm: &[DVec3],
    uv: &[[f64; 2]],
    tris: &[[u32; 3]],
) -> Vec<[f64; 4]> {
    let mut faces = Faces {
        pos,
        nrm,
        uv,
        tris,
        out: vec![[0.0, 0.0, 0.0, 1.0]; 3 * tris.len()],
    };
    // Its error type has no variants: it cannot fail.
    let _ = bevy_mikktspace::generate_tangents(&mut faces);
    faces.out
}

/// Per-vertex tangents from per-corner ones.
pub(super) struct Split {
    /// One per vertex, the first `n` followed by the copies.
    pub tangents: Vec<[f64; 4]>,
    /// The copies: the vertex each copies.
    pub extra: Vec<(u32, [f64; 4])>,
}

/// Turns per-corner tangents into per-vertex ones, copying a vertex for each
/// further tangent its corners got (the triangles are re-pointed at the
/// copies); `n` vertices.
pub(super) fn split_vertices(corner: &[[f64; 4]], tris: &mut [[u32; 3]], n: usize) -> Split {
    let mut tangents: Vec<Option<[f64; 4]>> = vec![None; n];
    let mut extra: Vec<(u32, [f64; 4])> = Vec::new();
    let mut copies: HashMap<(u32, [u64; 4]), u32> = HashMap::new();
    for (k, &t) in corner.iter().enumerate() {
        let (face, j) = (k / 3, k % 3);
        let Some(v) = tris.get(face).map(|tri| tri[j]) else {
            break;
        };
        match tangents[v as usize] {
            None => tangents[v as usize] = Some(t),
            Some(existing) if existing == t => {}
            Some(_) => {
                let key = (v, t.map(f64::to_bits));
                let next = (n + extra.len()) as u32;
                let idx = *copies.entry(key).or_insert_with(|| {
                    extra.push((v, t));
                    next
                });
                tris[face][j] = idx;
            }
        }
    }
    let mut out: Vec<[f64; 4]> = tangents
        .into_iter()
        .map(|t| t.unwrap_or([0.0, 0.0, 0.0, 1.0]))
        .collect();
    out.extend(extra.iter().map(|&(_, t)| t));
    Split {
        tangents: out,
        extra,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertices_split_where_corners_differ() {
        let mut tris = vec![[0, 1, 2], [0, 2, 3]];
        let a = [1.0, 0.0, 0.0, 1.0];
        let b = [0.0, 1.0, 0.0, 1.0];
        let corner = [a, a, a, b, a, b];
        let s = split_vertices(&corner, &mut tris, 4);
        assert_eq!(tris, vec![[0, 1, 2], [4, 2, 3]]);
        assert_eq!(s.extra, vec![(0, b)]);
        assert_eq!(s.tangents, vec![a, a, a, b, b]);
    }
}
