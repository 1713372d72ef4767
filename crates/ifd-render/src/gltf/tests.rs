//! glTF files built in memory: valid ones read back, and one bad input of
//! each kind refused with a message naming the file and the part.

use std::path::{Path, PathBuf};

use glam::DVec3;
use ifd_image::{Image, MemoryBudget};

use super::GltfAsset;
use crate::hit::Hit;

const BUDGET: MemoryBudget = MemoryBudget::bytes(64 << 20);

/// A glTF file under construction: one buffer, its views and accessors.
#[derive(Default)]
struct Gltf {
    bin: Vec<u8>,
    views: Vec<String>,
    accessors: Vec<String>,
}

impl Gltf {
    /// A buffer view over `bytes` (4-byte aligned); its index.
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let off = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.views.push(format!(
            r#"{{"buffer":0,"byteOffset":{off},"byteLength":{}}}"#,
            bytes.len()
        ));
        self.views.len() - 1
    }

    /// An accessor (`extra`: more JSON members, starting with a comma).
    fn accessor(&mut self, bytes: &[u8], ct: u32, ty: &str, count: usize, extra: &str) -> usize {
        let v = self.view(bytes);
        self.accessors.push(format!(
            r#"{{"bufferView":{v},"componentType":{ct},"type":"{ty}","count":{count}{extra}}}"#
        ));
        self.accessors.len() - 1
    }

    fn floats<const N: usize>(&mut self, v: &[[f32; N]]) -> usize {
        let bytes: Vec<u8> = v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let ty = ["", "SCALAR", "VEC2", "VEC3", "VEC4"][N];
        let extra = if N == 3 {
            let lo = (0..3).map(|c| v.iter().map(|p| p[c]).fold(f32::INFINITY, f32::min));
            let hi = (0..3).map(|c| v.iter().map(|p| p[c]).fold(f32::NEG_INFINITY, f32::max));
            let list = |it: &mut dyn Iterator<Item = f32>| {
                it.map(|x| x.to_string()).collect::<Vec<_>>().join(",")
            };
            format!(
                r#","min":[{}],"max":[{}]"#,
                list(&mut lo.into_iter()),
                list(&mut hi.into_iter())
            )
        } else {
            String::new()
        };
        self.accessor(&bytes, 5126, ty, v.len(), &extra)
    }

    fn indices(&mut self, ix: &[u16]) -> usize {
        let bytes: Vec<u8> = ix.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.accessor(&bytes, 5123, "SCALAR", ix.len(), "")
    }

    /// The JSON: `rest` holds the members after the buffers and accessors
    /// (meshes, nodes, scenes, ...); the buffer's `uri` when given.
    fn json(&self, rest: &str, uri: Option<&str>) -> String {
        let uri = uri.map(|u| format!(r#","uri":"{u}""#)).unwrap_or_default();
        format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":{}{uri}}}],"bufferViews":[{}],"accessors":[{}],{rest}}}"#,
            self.bin.len(),
            self.views.join(","),
            self.accessors.join(",")
        )
    }

    /// Written as `name.gltf` with an external `name.bin`.
    fn write_gltf(&self, dir: &Path, name: &str, rest: &str) -> PathBuf {
        std::fs::write(dir.join(format!("{name}.bin")), &self.bin).unwrap();
        let p = dir.join(format!("{name}.gltf"));
        std::fs::write(&p, self.json(rest, Some(&format!("{name}.bin")))).unwrap();
        p
    }

    /// Written as `name.gltf` with a base64 `data:` URI.
    fn write_data_uri(&self, dir: &Path, name: &str, rest: &str) -> PathBuf {
        use base64::Engine as _;
        let b64 = base64::engine::general_purpose::STANDARD.encode(&self.bin);
        let uri = format!("data:application/octet-stream;base64,{b64}");
        let p = dir.join(format!("{name}.gltf"));
        std::fs::write(&p, self.json(rest, Some(&uri))).unwrap();
        p
    }

    /// Written as `name.glb`.
    fn write_glb(&self, dir: &Path, name: &str, rest: &str) -> PathBuf {
        let p = dir.join(format!("{name}.glb"));
        std::fs::write(&p, glb(&self.json(rest, None), &self.bin)).unwrap();
        p
    }
}

/// A GLB file of a JSON text and a binary chunk.
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

/// The unit quad of glTF's `z = 0` plane facing `+z` (ifd: `y = 0`, facing
/// `-y`), `uv` with `v = 0` at the top (`+y`).
const QUAD: [[f32; 3]; 4] = [[-1., -1., 0.], [1., -1., 0.], [1., 1., 0.], [-1., 1., 0.]];
const QUAD_UV: [[f32; 2]; 4] = [[0., 1.], [1., 1.], [1., 0.], [0., 0.]];
const QUAD_IX: [u16; 6] = [0, 1, 2, 0, 2, 3];

/// A quad mesh (`attrs`: more attributes, `prim`: more primitive members)
/// in one node of one scene.
fn quad(g: &mut Gltf, attrs: &str, prim: &str) -> String {
    let p = g.floats(&QUAD);
    let i = g.indices(&QUAD_IX);
    format!(
        r#""meshes":[{{"primitives":[{{"attributes":{{"POSITION":{p}{attrs}}},"indices":{i}{prim}}}]}}],"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0"#
    )
}

/// The hit of the ray from `(x, -4, z)` along `+y`.
fn hit_at(a: &GltfAsset, x: f64, z: f64) -> Hit {
    a.mesh()
        .intersect(DVec3::new(x, -4.0, z), DVec3::Y)
        .expect("the ray hits the quad")
}

fn err(path: &Path) -> String {
    GltfAsset::load(path, BUDGET).unwrap_err().to_string()
}

/// Asserts the message names the file and contains each of `parts`.
fn assert_names(e: &str, file: &Path, parts: &[&str]) {
    assert!(e.contains(&file.display().to_string()), "{e}");
    for p in parts {
        assert!(e.contains(p), "{p:?} not in {e:?}");
    }
}

fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).length() < tol
}

#[test]
fn quad_with_external_buffer_and_default_material() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let rest = quad(&mut g, "", "");
    let a = GltfAsset::load(&g.write_gltf(dir.path(), "quad", &rest), BUDGET).unwrap();
    assert_eq!(a.mesh().triangles(), 2);
    assert!(a.notes().is_empty(), "{:?}", a.notes());
    assert!(a.camera().is_none());
    // z-up: the quad lies in y = 0 facing -y, centred, radius sqrt 2
    let (c, r) = a.mesh().placement();
    assert!(close(c, DVec3::ZERO, 1e-12) && (r - 2f64.sqrt()).abs() < 1e-12);
    let h = hit_at(&a, 0.2, 0.1);
    assert!(close(h.n, -DVec3::Y, 1e-12), "{}", h.n);
    assert_eq!(
        h.material,
        Some(0),
        "the default material follows the file's (none)"
    );
    assert!(h.uv.is_none() && h.tangent.is_none());
    let p = a.point(&h);
    assert_eq!(p.material.base, [1.0; 3]);
    assert_eq!((p.material.metallic, p.material.roughness), (1.0, 1.0));
    assert_eq!(
        (p.occlusion, p.emissive, p.double_sided),
        (1.0, [0.0; 3], false)
    );
    assert!(close(p.normal, -DVec3::Y, 1e-12));
    assert!(p.tangent.dot(p.normal).abs() < 1e-12 && (p.tangent.length() - 1.0).abs() < 1e-12);
    assert_eq!(a.roughness_range(), (1.0, 1.0));
}

#[test]
fn glb_and_data_uri_read_as_the_external_buffer() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let uv = g.floats(&QUAD_UV);
    let rest = quad(&mut g, &format!(r#","TEXCOORD_0":{uv}"#), "");
    let read = |p: PathBuf| GltfAsset::load(&p, BUDGET).unwrap();
    let a = read(g.write_gltf(dir.path(), "a", &rest));
    let b = read(g.write_glb(dir.path(), "b", &rest));
    let c = read(g.write_data_uri(dir.path(), "c", &rest));
    for other in [&b, &c] {
        assert_eq!(a.mesh().positions(), other.mesh().positions());
        assert_eq!(a.mesh().normals(), other.mesh().normals());
        let (ha, hb) = (hit_at(&a, 0.3, -0.2), hit_at(other, 0.3, -0.2));
        assert_eq!(ha, hb);
    }
    // glTF's uv as given: (0, 0) at the top-left corner (-1, +1) of the
    // quad, which is (-1, 0, 1) / sqrt 2 in ifd's frame
    let s = 2f64.sqrt();
    let uv = hit_at(&a, -0.5 / s, 0.5 / s).uv.unwrap();
    assert!(
        (uv[0] - 0.25).abs() < 1e-9 && (uv[1] - 0.25).abs() < 1e-9,
        "{uv:?}"
    );
}

#[test]
fn strips_fans_and_non_indexed_primitives() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let p = g.floats(&QUAD);
    let strip = g.indices(&[0, 1, 3, 2]);
    let fan = g.indices(&[0, 1, 2, 3]);
    let tri = g.floats(&[QUAD[0], QUAD[1], QUAD[2]]);
    let rest = format!(
        r#""meshes":[{{"primitives":[{{"attributes":{{"POSITION":{p}}},"indices":{strip},"mode":5}},{{"attributes":{{"POSITION":{p}}},"indices":{fan},"mode":6}},{{"attributes":{{"POSITION":{tri}}}}}]}}],"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}]"#
    );
    let a = GltfAsset::load(&g.write_glb(dir.path(), "s", &rest), BUDGET).unwrap();
    assert_eq!(a.mesh().triangles(), 5);
    // every triangle faces glTF's +z (ifd's -y): computed normals agree
    for n in a.mesh().normals() {
        assert!(close(*n, -DVec3::Y, 1e-12), "{n}");
    }
}

/// Reconstructs a vertex's position in the file's (z-up) scene frame.
fn unplaced(a: &GltfAsset) -> Vec<DVec3> {
    let (c, r) = a.mesh().placement();
    a.mesh().positions().iter().map(|p| *p * r + c).collect()
}

fn has(points: &[DVec3], p: DVec3) -> bool {
    points.iter().any(|q| close(*q, p, 1e-9))
}

#[test]
fn node_transforms_compose() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let mut rest = quad(&mut g, "", "");
    // node 0: the quad; node 1: translated and scaled; node 2: a parent
    // turned 90 degrees about y (matrix) whose child translates by x = 1
    rest = rest.replace(
        r#""nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]"#,
        r#""nodes":[{"mesh":0},{"mesh":0,"translation":[1,2,3],"scale":[2,2,2]},{"matrix":[0,0,-1,0, 0,1,0,0, 1,0,0,0, 0,0,0,1],"children":[3]},{"mesh":0,"translation":[1,0,0]}],"scenes":[{"nodes":[0,1,2]}]"#,
    );
    let a = GltfAsset::load(&g.write_gltf(dir.path(), "t", &rest), BUDGET).unwrap();
    assert_eq!(a.mesh().triangles(), 6);
    let z_up = |x: f64, y: f64, z: f64| DVec3::new(x, -z, y);
    let pts = unplaced(&a);
    // node 1: (-1, -1, 0) * 2 + (1, 2, 3) = (-1, 0, 3)
    assert!(has(&pts, z_up(-1.0, 0.0, 3.0)));
    assert!(has(&pts, z_up(3.0, 4.0, 3.0)));
    // node 3 under node 2: (x, y, z) -> R (x + 1, y, z), R turning x to -z
    // (columns: x -> (0, 0, -1), y -> y, z -> (1, 0, 0)): (-1, -1, 0) -> (0, -1, 0)
    assert!(has(&pts, z_up(0.0, -1.0, 0.0)));
    // (1, 1, 0) -> (2, 1, 0) -> (0, 1, -2)
    assert!(has(&pts, z_up(0.0, 1.0, -2.0)));
}

#[test]
fn mirrored_nodes_keep_outward_normals() {
    let dir = tempfile::tempdir().unwrap();
    for attrs in [false, true] {
        let mut g = Gltf::default();
        let extra = if attrs {
            let n = g.floats(&[[0.0f32, 0.0, 1.0]; 4]);
            format!(r#","NORMAL":{n}"#)
        } else {
            String::new()
        };
        let rest = quad(&mut g, &extra, "").replace(
            r#""nodes":[{"mesh":0}]"#,
            r#""nodes":[{"mesh":0,"scale":[-1,1,1]}]"#,
        );
        let a = GltfAsset::load(&g.write_glb(dir.path(), "m", &rest), BUDGET).unwrap();
        // mirroring x leaves the quad facing glTF's +z (ifd's -y)
        for n in a.mesh().normals() {
            assert!(close(*n, -DVec3::Y, 1e-12), "{attrs}: {n}");
        }
        let h = hit_at(&a, 0.1, 0.1);
        assert!(close(h.n, -DVec3::Y, 1e-12));
    }
}

/// PNG bytes of an image, through `ifd_image::write`.
fn png(dir: &Path, img: &Image) -> Vec<u8> {
    let p = dir.join("texture.png");
    ifd_image::write(&p, img).unwrap();
    std::fs::read(&p).unwrap()
}

#[test]
fn textured_quad() {
    let dir = tempfile::tempdir().unwrap();
    // 2x2 RGB: base colour texels (sRGB-encoded values)
    let texels = [
        0.2f32, 0.4, 0.6, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0,
    ];
    let base_png = png(
        dir.path(),
        &Image::from_vec(2, 2, 3, texels.to_vec()).unwrap(),
    );
    // metallic-roughness: G = roughness, B = metallic, one texel each side
    let mr = [
        0.0f32, 0.2, 0.8, 0.0, 0.6, 0.4, 0.0, 0.2, 0.8, 0.0, 0.6, 0.4,
    ];
    let mr_png = png(dir.path(), &Image::from_vec(2, 2, 3, mr.to_vec()).unwrap());
    let mut g = Gltf::default();
    let uv = g.floats(&QUAD_UV);
    let v0 = g.view(&base_png);
    let v1 = g.view(&mr_png);
    let rest = quad(
        &mut g,
        &format!(r#","TEXCOORD_0":{uv}"#),
        r#","material":0"#,
    ) + &format!(
        r#","materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[1,0.5,1,1],"baseColorTexture":{{"index":0}},"metallicFactor":0.5,"roughnessFactor":1,"metallicRoughnessTexture":{{"index":1}}}},"emissiveFactor":[1,0.5,0],"extensions":{{"KHR_materials_emissive_strength":{{"emissiveStrength":2}}}},"doubleSided":true}}],"textures":[{{"source":0,"sampler":0}},{{"source":1}}],"samplers":[{{"wrapS":33071,"wrapT":33071}}],"images":[{{"bufferView":{v0},"mimeType":"image/png"}},{{"bufferView":{v1},"mimeType":"image/png"}}],"extensionsUsed":["KHR_materials_emissive_strength","KHR_texture_transform"],"extensionsRequired":["KHR_materials_emissive_strength"]"#
    );
    let a = GltfAsset::load(&g.write_glb(dir.path(), "tex", &rest), BUDGET).unwrap();
    assert_eq!(a.notes().len(), 1, "{:?}", a.notes());
    assert!(a.notes()[0].contains("KHR_texture_transform"));
    // the top-left texel's centre: uv (0.25, 0.25), glTF (-0.5, 0.5, 0)
    let s = 2f64.sqrt();
    let p = a.point(&hit_at(&a, -0.5 / s, 0.5 / s));
    let lin = |v: f32| f64::from(ifd_image::srgb_to_linear((v * 255.0).round() / 255.0));
    let want = [lin(0.2), 0.5 * lin(0.4), lin(0.6)];
    for (got, want) in p.material.base.iter().zip(want) {
        assert!((got - want).abs() < 1e-6, "{:?}", p.material.base);
    }
    let q = |v: f32| f64::from((v * 255.0).round() / 255.0);
    assert!((p.material.metallic - 0.5 * q(0.8)).abs() < 1e-6);
    assert!((p.material.roughness - q(0.2)).abs() < 1e-6);
    assert_eq!(p.emissive, [2.0, 1.0, 0.0]);
    assert!(p.double_sided);
    // the top-right texel (1, 0, 0)
    let p = a.point(&hit_at(&a, 0.5 / s, 0.5 / s));
    assert!((p.material.base[0] - 1.0).abs() < 1e-6 && p.material.base[1] < 1e-6);
    let (lo, hi) = a.roughness_range();
    assert!(
        (lo - q(0.2)).abs() < 1e-6 && (hi - q(0.6)).abs() < 1e-6,
        "{lo} {hi}"
    );
}

#[test]
fn normal_map_uses_mikktspace_tangents() {
    let dir = tempfile::tempdir().unwrap();
    // a constant normal texture tilted towards +x (the tangent) or +y (up
    // the image)
    for (texel, want) in [
        ([1.0f32, 0.5, 0.5], DVec3::X),
        ([0.5, 1.0, 0.5], DVec3::Z),
        ([0.5, 0.5, 1.0], -DVec3::Y),
    ] {
        let img = png(
            dir.path(),
            &Image::from_vec(1, 1, 3, texel.to_vec()).unwrap(),
        );
        let mut g = Gltf::default();
        let uv = g.floats(&QUAD_UV);
        let v = g.view(&img);
        let rest = quad(
            &mut g,
            &format!(r#","TEXCOORD_0":{uv}"#),
            r#","material":0"#,
        ) + &format!(
            r#","materials":[{{"normalTexture":{{"index":0}}}}],"textures":[{{"source":0}}],"images":[{{"bufferView":{v},"mimeType":"image/png"}}]"#
        );
        let a = GltfAsset::load(&g.write_glb(dir.path(), "n", &rest), BUDGET).unwrap();
        let h = hit_at(&a, 0.1, 0.2);
        // MikkTSpace's tangent runs along +u (glTF +x, ifd +x), handedness
        // +1: the bitangent w n x t = -y x x = +z, up the image
        let t = h.tangent.expect("MikkTSpace tangents");
        assert!(close(t.truncate(), DVec3::X, 1e-6) && t.w == 1.0, "{t}");
        let p = a.point(&h);
        assert!(p.normal.dot(want) > 0.99, "{texel:?}: {}", p.normal);
        assert!(p.tangent.dot(p.normal).abs() < 1e-12);
    }
}

#[test]
fn file_tangents_and_sparse_accessors() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let t = g.floats(&[[0.0f32, 1.0, 0.0, -1.0]; 4]);
    let i = g.indices(&QUAD_IX);
    let bytes = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    // sparse: vertex 2 moved from (1, 1, 0) to (2, 1, 0); no min and max
    // (required by the specification, not needed here)
    let base = g.view(&bytes(QUAD.as_flattened()));
    let si = g.view(&2u16.to_le_bytes());
    let sv = g.view(&bytes(&[2.0, 1.0, 0.0]));
    g.accessors.push(format!(
        r#"{{"bufferView":{base},"componentType":5126,"type":"VEC3","count":4,"sparse":{{"count":1,"indices":{{"bufferView":{si},"componentType":5123}},"values":{{"bufferView":{sv}}}}}}}"#
    ));
    let p = g.accessors.len() - 1;
    let rest = format!(
        r#""meshes":[{{"primitives":[{{"attributes":{{"POSITION":{p},"TANGENT":{t}}},"indices":{i}}}]}}],"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}]"#
    );
    let a = GltfAsset::load(&g.write_glb(dir.path(), "sp", &rest), BUDGET).unwrap();
    let pts = unplaced(&a);
    assert!(has(&pts, DVec3::new(2.0, 0.0, 1.0)), "{pts:?}");
    assert!(!has(&pts, DVec3::new(1.0, 0.0, 1.0)));
    // the file's tangent, glTF +y = ifd +z, handedness -1
    let h = hit_at(&a, 0.0, 0.0);
    let t = h.tangent.unwrap();
    assert!(close(t.truncate(), DVec3::Z, 1e-12) && t.w == -1.0, "{t}");
}

#[test]
fn camera_follows_the_placement() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let rest = quad(&mut g, "", "").replace(
        r#""nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]"#,
        r#""nodes":[{"mesh":0,"children":[1]},{"camera":0,"translation":[0,0,5]}],"scenes":[{"nodes":[0]}],"cameras":[{"type":"perspective","perspective":{"yfov":0.5,"znear":0.1,"aspectRatio":1.5}}]"#,
    );
    let a = GltfAsset::load(&g.write_gltf(dir.path(), "cam", &rest), BUDGET).unwrap();
    let c = a.camera().expect("a camera");
    let r = 2f64.sqrt();
    // glTF (0, 0, 5) is ifd (0, -5, 0), looking down glTF -z = ifd +y
    assert!(
        close(c.eye, DVec3::new(0.0, -5.0 / r, 0.0), 1e-12),
        "{}",
        c.eye
    );
    assert!(close(c.target - c.eye, DVec3::Y, 1e-12));
    assert!(close(c.up, DVec3::Z, 1e-12));
    assert!((c.fov_deg - 0.5f64.to_degrees()).abs() < 1e-6);
    assert_eq!(c.aspect, Some(1.5));
    // the camera sees the quad's centre
    assert!(a.mesh().intersect(c.eye, c.target - c.eye).is_some());
}

#[test]
fn points_and_lines_are_skipped_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let rest = quad(&mut g, "", "");
    let rest = rest.replace(
        r#""indices":1}]"#,
        r#""indices":1},{"attributes":{"POSITION":0},"mode":0},{"attributes":{"POSITION":0},"mode":1}]"#,
    );
    let a = GltfAsset::load(&g.write_gltf(dir.path(), "pts", &rest), BUDGET).unwrap();
    assert_eq!(a.mesh().triangles(), 2);
    assert_eq!(a.notes().len(), 2, "{:?}", a.notes());
    assert!(a.notes()[0].contains("mesh 0 primitive 1: mode POINTS skipped"));
    assert!(a.notes()[1].contains("mesh 0 primitive 2: mode LINES skipped"));
    // only points: nothing to render
    let only = rest.replace(r#""indices":1},"#, r#""indices":1,"mode":0},"#);
    let p = g.write_gltf(dir.path(), "only", &only);
    assert_names(&err(&p), &p, &["scene 0", "no triangles"]);
}

// --- bad input: one of each kind, the message naming the file and the part

#[test]
fn malformed_json_and_glb() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.gltf");
    std::fs::write(&p, b"{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [").unwrap();
    assert_names(&err(&p), &p, &["JSON", "malformed"]);
    std::fs::write(&p, br#"{"asset":{"version":"1.0"}}"#).unwrap();
    assert_names(&err(&p), &p, &["asset.version", "1.0"]);

    let mut g = Gltf::default();
    let rest = quad(&mut g, "", "");
    let good = glb(&g.json(&rest, None), &g.bin);
    let p = dir.path().join("bad.glb");
    let mut bad = good.clone();
    bad[3] = b'X';
    std::fs::write(&p, &bad).unwrap();
    assert_names(&err(&p), &p, &["GLB header", "magic"]);
    let mut bad = good.clone();
    bad[4] = 1;
    std::fs::write(&p, &bad).unwrap();
    assert_names(&err(&p), &p, &["GLB header", "version 1"]);
    let mut bad = good.clone();
    bad[8..12].copy_from_slice(&(good.len() as u32 + 4).to_le_bytes());
    std::fs::write(&p, &bad).unwrap();
    assert_names(&err(&p), &p, &["GLB header", "declares"]);
    let mut bad = good.clone();
    bad[12..16].copy_from_slice(&(good.len() as u32).to_le_bytes());
    std::fs::write(&p, &bad).unwrap();
    assert_names(&err(&p), &p, &["GLB chunk 0 (JSON)", "runs past the end"]);
    // the BIN chunk's length past the end
    let json_len = u32::from_le_bytes([good[12], good[13], good[14], good[15]]) as usize;
    let at = 20 + json_len;
    let mut bad = good.clone();
    bad[at..at + 4].copy_from_slice(&1000u32.to_le_bytes());
    std::fs::write(&p, &bad).unwrap();
    assert_names(&err(&p), &p, &["GLB chunk 1 (BIN)", "runs past the end"]);
    std::fs::write(&p, &good[..good.len() - 4]).unwrap();
    assert_names(&err(&p), &p, &["GLB header", "declares"]);
    std::fs::write(&p, &good[..7]).unwrap();
    assert_names(&err(&p), &p, &["GLB header"]);
}

#[test]
fn missing_and_truncated_buffers() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let rest = quad(&mut g, "", "");
    let p = g.write_gltf(dir.path(), "m", &rest);
    std::fs::remove_file(dir.path().join("m.bin")).unwrap();
    assert_names(&err(&p), &p, &["buffer 0 (\"m.bin\")", "cannot read"]);
    std::fs::write(dir.path().join("m.bin"), &g.bin[..g.bin.len() - 8]).unwrap();
    assert_names(
        &err(&p),
        &p,
        &["buffer 0 (\"m.bin\")", "byteLength", "truncated"],
    );
    // a GLB without a BIN chunk
    let p = dir.path().join("nobin.glb");
    let mut only_json = glb(&g.json(&rest, None), &[]);
    only_json.truncate(only_json.len() - 8);
    let n = only_json.len() as u32;
    only_json[8..12].copy_from_slice(&n.to_le_bytes());
    std::fs::write(&p, &only_json).unwrap();
    assert_names(&err(&p), &p, &["buffer 0 (GLB binary chunk)", "no binary"]);
    // URIs: no network, no absolute paths, valid base64
    for (uri, want) in [
        ("http://example.com/m.bin", "no network"),
        ("file:///tmp/m.bin", "no network"),
        ("/tmp/m.bin", "absolute"),
        ("data:application/octet-stream;base64,@@@@", "base64"),
    ] {
        let p = dir.path().join("uri.gltf");
        std::fs::write(&p, g.json(&rest, Some(uri))).unwrap();
        assert_names(&err(&p), &p, &["buffer 0", want]);
    }
}

#[test]
fn accessors_out_of_range_or_misaligned() {
    let dir = tempfile::tempdir().unwrap();
    let check = |edit: &dyn Fn(&mut Gltf), parts: &[&str]| {
        let mut g = Gltf::default();
        let rest = quad(&mut g, "", "");
        edit(&mut g);
        let p = g.write_glb(dir.path(), "acc", &rest);
        assert_names(&err(&p), &p, parts);
    };
    // too many elements for the view
    check(
        &|g| g.accessors[0] = g.accessors[0].replace(r#""count":4"#, r#""count":5"#),
        &[
            "accessor 0 (POSITION of mesh 0 primitive 0)",
            "run past the end of bufferView 0",
        ],
    );
    // an absurd count: refused from the view's size, nothing allocated
    check(
        &|g| g.accessors[0] = g.accessors[0].replace(r#""count":4"#, r#""count":4000000000000"#),
        &[
            "accessor 0 (POSITION of mesh 0 primitive 0)",
            "run past the end",
        ],
    );
    // misaligned floats
    check(
        &|g| g.accessors[0] = g.accessors[0].replace(r#""count":4"#, r#""count":3,"byteOffset":2"#),
        &["accessor 0 (POSITION of mesh 0 primitive 0)", "misaligned"],
    );
    // a view past its buffer
    check(
        &|g| g.views[1] = g.views[1].replace(r#""byteLength":12"#, r#""byteLength":1200"#),
        &["bufferView 1", "outside buffer 0"],
    );
    // an index out of range
    check(
        &|g| {
            let at = g.bin.len() - 12 + 4;
            g.bin[at..at + 2].copy_from_slice(&7u16.to_le_bytes());
        },
        &[
            "accessor 1 (indices of mesh 0 primitive 0)",
            "index 7",
            "out of range",
        ],
    );
    // a non-finite position
    check(
        &|g| g.bin[0..4].copy_from_slice(&f32::NAN.to_le_bytes()),
        &["accessor 0 (POSITION of mesh 0 primitive 0)", "non-finite"],
    );
    // the wrong type
    check(
        &|g| g.accessors[0] = g.accessors[0].replace("VEC3", "VEC2"),
        &["accessor 0 (POSITION of mesh 0 primitive 0)", "type VEC2"],
    );
    // a reference to nothing (gltf-json's validation)
    check(
        &|g| g.accessors.truncate(1),
        &["meshes[0].primitives[0].indices", "index out of bounds"],
    );
}

#[test]
fn budget_cycles_and_required_extensions() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let rest = quad(&mut g, "", "");
    let p = g.write_glb(dir.path(), "ok", &rest);
    let e = GltfAsset::load(&p, MemoryBudget::bytes(2000))
        .unwrap_err()
        .to_string();
    assert_names(&e, &p, &["budget"]);
    let cyc = rest.replace(
        r#""nodes":[{"mesh":0}]"#,
        r#""nodes":[{"mesh":0,"children":[1]},{"children":[0]}]"#,
    );
    let p = g.write_glb(dir.path(), "cyc", &cyc);
    assert_names(&err(&p), &p, &["node 0", "its own ancestor"]);
    let req = rest.clone()
        + r#","extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"]"#;
    let p = g.write_glb(dir.path(), "req", &req);
    assert_names(
        &err(&p),
        &p,
        &["extensionsRequired", "KHR_draco_mesh_compression"],
    );
    let none = rest
        .replace(r#","scene":0"#, "")
        .replace(r#","scenes":[{"nodes":[0]}]"#, "");
    let p = g.write_glb(dir.path(), "none", &none);
    assert_names(&err(&p), &p, &["scene 0", "no scene"]);
}

#[test]
fn textures_that_are_not_images() {
    let dir = tempfile::tempdir().unwrap();
    for (bytes, mime, want) in [
        (
            &b"not an image at all"[..],
            "image/png",
            "cannot decode PNG",
        ),
        (&b"GIF89a..."[..], "image/gif", "not a PNG or JPEG"),
    ] {
        let mut g = Gltf::default();
        let uv = g.floats(&QUAD_UV);
        let v = g.view(bytes);
        let rest = quad(
            &mut g,
            &format!(r#","TEXCOORD_0":{uv}"#),
            r#","material":0"#,
        ) + &format!(
            r#","materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}}}}}}],"textures":[{{"source":0}}],"images":[{{"bufferView":{v},"mimeType":"{mime}"}}]"#
        );
        let p = g.write_glb(dir.path(), "img", &rest);
        assert_names(&err(&p), &p, &["image 0", want]);
    }
    // a missing image file
    let mut g = Gltf::default();
    let uv = g.floats(&QUAD_UV);
    let rest = quad(
        &mut g,
        &format!(r#","TEXCOORD_0":{uv}"#),
        r#","material":0"#,
    ) + r#","materials":[{"emissiveTexture":{"index":0}}],"textures":[{"source":0}],"images":[{"uri":"gone.png"}]"#;
    let p = g.write_gltf(dir.path(), "gone", &rest);
    assert_names(&err(&p), &p, &["image 0 (\"gone.png\")", "cannot read"]);
}

#[test]
fn deep_node_chains_do_not_recurse() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let n = 20_000;
    let chain: Vec<String> = (1..n).map(|k| format!(r#"{{"children":[{k}]}}"#)).collect();
    let rest = quad(&mut g, "", "").replace(
        r#""nodes":[{"mesh":0}]"#,
        &format!(r#""nodes":[{},{{"mesh":0}}]"#, chain.join(",")),
    );
    let a = GltfAsset::load(&g.write_glb(dir.path(), "deep", &rest), BUDGET).unwrap();
    assert_eq!(a.mesh().triangles(), 2);
}

/// The fuzz seeds (`fuzz/make_seeds.py`): the valid ones load, with what
/// they exercise; the corruptions are refused.
#[test]
fn fuzz_seeds() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/gltf");
    let load = |name: &str| GltfAsset::load(&dir.join(name), BUDGET);
    for name in ["quad.glb", "quad-data-uri.gltf"] {
        let a = load(name).unwrap();
        let p = a.point(&hit_at(&a, 0.0, 0.0));
        assert!((p.material.roughness - 0.6).abs() < 1e-6, "{name}");
    }
    let a = load("textured.glb").unwrap();
    // the quad and the strip, twice (the second instance mirrored)
    assert_eq!(a.mesh().triangles(), 8);
    assert_eq!(a.notes().len(), 2, "{:?}", a.notes());
    assert!(a.camera().is_some() && a.mesh().tangents().is_some());
    for name in [
        "truncated.glb",
        "chunk-length.glb",
        "tail.glb",
        "accessor-past-view.glb",
        "required.gltf",
    ] {
        let e = load(name).unwrap_err().to_string();
        assert!(e.contains(name), "{e}");
    }
}
